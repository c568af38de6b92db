//! Speed of the linear-algebra kernels of one time step (issue #4), on the block
//! pattern of patient p2's published mesh (25,680 nodes, 147,013 tets, reverse
//! Cuthill-McKee order, 2 row partitions) with synthetic diagonally dominant values:
//! the kernels' cost depends on the pattern, not on the values.
//!
//!   cargo bench -p baffle-cfd --bench kernels -- [--reps N]
//!
//! Prints the minimum and the median of N repetitions (15) of: the assembly of the
//! stabilized element systems into the f64 matrix (and the element systems alone, to
//! show what the scatter costs), block SpMV, ILU(0) factorization, ILU(0) application
//! and 40 GMRES iterations (one restart cycle with its Gram-Schmidt), in f64 and in
//! the mixed-precision f32 form. The minimum is the
//! figure to compare between builds on this shared machine: other jobs only add time.
//! Data: $BAFFLE_DATA_DIR or ../shared/data.

mod support;
use support::process_cpu_s;

use std::time::Instant;

use baffle_cfd::assembly::{element_system, Assembler, Physics};
use baffle_cfd::linear::{gmres, partitions, BlockIlu};
use baffle_cfd::sparse::{convert, reverse_cuthill_mckee, spmv, BlockPattern, B, BB};
use baffle_cfd::vtu::read_simvascular_mesh;
use rayon::prelude::*;

/// Min and median of `reps` timings of `f`, in ms.
fn time_ms(reps: usize, mut f: impl FnMut()) -> (f64, f64) {
    let mut t: Vec<f64> = (0..reps)
        .map(|_| {
            let start = Instant::now();
            f();
            start.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    t.sort_by(f64::total_cmp);
    (t[0], t[reps / 2])
}

fn report(name: &str, (min, median): (f64, f64)) {
    println!("  {name:<34} min {min:8.2} ms   median {median:8.2} ms");
}

/// p2's mesh (points, tets) and block pattern in RCM order, as the solver builds them.
fn p2_pattern() -> Result<(Vec<[f64; 3]>, Vec<[u32; 4]>, BlockPattern), Box<dyn std::error::Error>> {
    let p2 = baffle_test_support::reference_data::reference_data_dir().join("p2");
    let mesh = read_simvascular_mesh(&p2.join("published_M_final.vtu"), &p2.join("published_M_final.vtp"))?;
    let n = mesh.points_cm.len();
    let order = reverse_cuthill_mckee(&BlockPattern::from_tets(n, &mesh.tets));
    let mut new_of_old = vec![0u32; n];
    for (new, &old) in order.iter().enumerate() {
        new_of_old[old as usize] = new as u32;
    }
    let tets: Vec<[u32; 4]> = mesh.tets.iter().map(|t| t.map(|i| new_of_old[i as usize])).collect();
    let points: Vec<[f64; 3]> = order.iter().map(|&old| mesh.points_cm[old as usize]).collect();
    let pattern = BlockPattern::from_tets(n, &tets);
    Ok((points, tets, pattern))
}

/// Values with a dominant diagonal block, deterministic.
fn values(pattern: &BlockPattern) -> Vec<f64> {
    let mut vals = vec![0.0; pattern.cols.len() * BB];
    for (k, v) in vals.iter_mut().enumerate() {
        *v = ((k * 7919) % 101) as f64 / 101.0 - 0.5;
    }
    for i in 0..pattern.n_rows() {
        for c in 0..B {
            vals[pattern.diag[i] * BB + c * B + c] += 40.0;
        }
    }
    vals
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut reps = 15;
    // --assembly-only: the assembly alone (e.g. under `perf stat`, whose CPU counts
    // are what a loaded machine still measures reliably).
    let mut assembly_only = false;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--reps" => reps = args.next().ok_or("--reps needs a value")?.parse()?,
            "--bench" => {}
            "--assembly-only" => assembly_only = true,
            other => return Err(format!("unknown argument {other}").into()),
        }
    }
    let (points, tets, pattern) = p2_pattern()?;
    let n = pattern.n_rows() * B;
    let vals = values(&pattern);
    let vals_low: Vec<f32> = convert(&vals);
    let parts = partitions(&pattern, rayon::current_num_threads());
    let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
    let x_low: Vec<f32> = convert(&x);
    let (mut y, mut y_low) = (vec![0.0; n], vec![0.0f32; n]);
    let mut assembler = Assembler::new(&points, tets.clone(), &pattern, parts.clone());
    let physics = Physics { density_g_cm3: 1.06, viscosity_g_cm_s: 0.04, inv_dt_per_s: 1000.0, inv_dt_tau_per_s: 1000.0, formulation: baffle_cfd::assembly::Formulation { tau_metric: baffle_cfd::assembly::TauMetric::Invariant, exact_convection: false, vms_advection: false, stress_viscosity: false, gauss_stabilization: false, vms_reynolds_stress: false } };
    let velocity: Vec<f64> = (0..n).map(|i| if i % B == 3 { 0.0 } else { 100.0 * (i as f64 * 0.01).sin() }).collect();
    let (mut asm_vals, mut asm_rhs) = (vec![0.0; pattern.cols.len() * BB], vec![0.0; n]);
    println!("p2 pattern: {} block rows, {} blocks, {} threads, {reps} repetitions", pattern.n_rows(), pattern.cols.len(), rayon::current_num_threads());
    let cpu_before = process_cpu_s();
    report("assembly (element systems + scatter)", time_ms(reps, || assembler.assemble(&pattern, &physics, &velocity, &velocity, &mut asm_vals, &mut asm_rhs)));
    if assembly_only {
        println!("  assembly CPU time (all threads) {:.1} ms per assembly", 1e3 * (process_cpu_s() - cpu_before) / reps as f64);
        return Ok(());
    }
    let element_systems_only = || {
        assembler.tets.par_iter().zip(&assembler.geometry).for_each(|(t, geometry)| {
            let nodal = t.map(|k| [0, 1, 2].map(|c| velocity[k as usize * B + c]));
            std::hint::black_box(element_system(geometry, &nodal, &nodal, &physics));
        });
    };
    report("element systems alone (no scatter)", time_ms(reps, element_systems_only));
    report("SpMV f64", time_ms(reps, || spmv(&pattern, &vals, &x, &mut y)));
    report("SpMV f32", time_ms(reps, || spmv(&pattern, &vals_low, &x_low, &mut y_low)));
    report("ILU(0) factor -> f64", time_ms(reps, || drop(BlockIlu::<f64>::factor(&pattern, &vals, parts.clone()).unwrap())));
    report("ILU(0) factor -> f32", time_ms(reps, || drop(BlockIlu::<f32>::factor(&pattern, &vals, parts.clone()).unwrap())));
    let ilu = BlockIlu::<f64>::factor(&pattern, &vals, parts.clone()).unwrap();
    let ilu_low = BlockIlu::<f32>::factor(&pattern, &vals, parts.clone()).unwrap();
    report("ILU(0) apply f64", time_ms(reps, || ilu.apply(&x, &mut y)));
    report("ILU(0) apply f32", time_ms(reps, || ilu_low.apply(&x_low, &mut y_low)));
    let gmres_reps = reps.div_ceil(3);
    report(
        "40 GMRES iterations f64",
        time_ms(gmres_reps, || {
            gmres(&|v, w| spmv(&pattern, &vals, v, w), &ilu, &x, &mut y, 0.0, 40, 40);
        }),
    );
    report(
        "40 GMRES iterations f32",
        time_ms(gmres_reps, || {
            gmres(&|v, w| spmv(&pattern, &vals_low, v, w), &ilu_low, &x_low, &mut y_low, 0.0, 40, 40);
        }),
    );
    Ok(())
}
