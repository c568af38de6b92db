//! Time stepping, boundary conditions and per-step results.
//!
//! The numbers below are the measurements that chose each piece (p2's published mesh:
//! 25,680 nodes, 147,013 tets, 102,720 unknowns; p3's published 1.25 mm mesh: 66,677
//! tets; 2 threads, release); docs/measurements.md keeps the full runs.
//!
//! Linear solver: the coupled Picard (Oseen) system of all (u, v, w, p) is solved at
//! once by GMRES(30), preconditioned on the right with node-block (4x4) ILU(0) on a
//! reverse Cuthill-McKee ordering, split into one row partition per thread (block
//! Jacobi of ILU(0)) so factorization and triangular solves run in parallel: on p2 the
//! 2 partitions need ~20 % more GMRES iterations than one but are 1.45x faster. ILU(0)'s
//! iterations grow with the mesh (tubes of 9.7k / 45k / 150k tets: 49 / 108 / 283 a
//! step), so the default preconditioner is two-level ([`crate::coarse`]): ILU(0), then a
//! Galerkin coarse correction on node aggregates (piecewise-constant u, v, w, p; dense
//! LU of at most 4 x 256 unknowns): 31 / 41 / 45 iterations on the tubes, 15 instead of
//! 40 on p2, the same dp to 0.06 %. A step whose solve stalls is retried down
//! [`RETRY_LADDER`] before the run fails. A Woodbury correction of the preconditioner
//! for the resistance outlets' rank-one terms does not pay (39.6 instead of 40.0
//! iterations a step: the plateau of every solve does not come from the outlets); a
//! pressure-projection scheme and a block (Schur) preconditioner were not tried.
//!
//! Steady solve: the pseudo step grows by switched evolution relaxation
//! (dt_k = dt_0 r_0 / r_k) and the linearization switches to Newton (Galerkin convection
//! Jacobian; SUPG/tau derivatives omitted) below a relative residual of 1e-2. A fixed
//! pseudo dt of 10 ms with one Picard iteration per pseudo step stalls (p2 at Q_peak
//! 70 mL/s: 3.6e-4 after 45 iterations); the switched scheme reaches 6.6e-5 (target
//! 1e-4) in 23 iterations (15 Picard + 8 Newton), dp(11-16) 7.381 mmHg. Newton from the
//! start fails: far from the solution the Jacobian is strongly non-diagonally dominant
//! and GMRES/ILU(0) needs hundreds of iterations while the residual rises. With the
//! Poiseuille inflow profile the scheme does not converge in 60 iterations.
//!
//! Transient: linear extrapolation 2 u_n - u_(n-1) is the initial guess of every step;
//! with one Picard iteration (`NonlinearIterations::Fixed(1)`, backward Euler's default)
//! the step is semi-implicit (one linear solve with the extrapolated convection velocity,
//! no residual re-assembly afterwards): on p2 from rest through peak flow it differs from
//! Picard iterated to 1e-3 by at most ~0.3 % in dp(11-16) and < 0.1 cm/s in v_max, in a
//! third of the time, and it passes the Womersley test (verification.rs: alpha 4,
//! amplitude +1.8 %, phase -0.9 %). Generalized-alpha ([`crate::time_integration`]) runs
//! by default a convergence-controlled Picard loop (`NonlinearIterations::Auto`,
//! [`LoopControl`]): it solves until the update changes velocity and pressure by less
//! than 1e-3 ([`relative_change`]), at most 6 times, with the factors reused across the
//! solves as across steps; this removes the semi-implicit step's oscillation in the VSD
//! jet (p2 at 1 ms: dp 7.272 instead of 7.030 mmHg, 1.9 solves a step).
//!
//! Factors kept over steps ([`FactorsUse`]): the ILU(0) factors and the coarse correction
//! serve several steps, while the f32 operator copy is refreshed at every solve; a solve
//! with old factors has a bounded budget and is redone with new ones when it misses (the
//! step right after an impulsive start does), and renewal follows the iterations aging
//! adds. On p2 from rest to the first peak: 12 factorizations instead of 164, 14.2
//! instead of 13.7 GMRES iterations a step, the same dp and v_max to 4 digits. Fixed
//! reuse for 2-8 solves stalled.
//!
//! Initial guess of a step's solve: the previous step's update (`Solver::initial_guess`),
//! solved to half the tolerance ([`crate::linear::GUESS_TOLERANCE_FACTOR`]): ~15 -> ~12
//! GMRES iterations a step on p3, dp closer to a converged (1e-7) run than without it. At
//! the full tolerance (9 iterations) or extrapolated from two updates (10 iterations) the
//! error against the converged run is 4-5x larger: the better the guess, the more error
//! the residual test leaves where the residual hardly sees it.
//!
//! Mixed precision (`mixed_precision`, default on): the ILU(0) factors are stored in f32
//! and the inner GMRES runs on f32 copies of the matrix and vectors, with the residual
//! re-formed in f64 after each inner solve (`linear::solve_refined`; a stalled round
//! falls back to f64 GMRES, as happens for the steady Stokes systems of the tube tests at
//! tolerance 1e-8). The kernels are memory-bound: on p2 a step takes 1.15 s mixed
//! against 1.38 s in f64, with the same ~40 GMRES iterations and the same dp to 4
//! decimals.
//!
//! Kernels, each kept because it shortened the solver bench with dp unchanged:
//!   - L and U of ILU(0) stored apart in sweep order, U's rows with the nearest column
//!     last (`linear::Triangle`): read from high to low addresses with the dependent
//!     block first, the backward sweep had taken 4x the forward one;
//!   - block products with 4-lane accumulators in the matrix's precision
//!     (`sparse::BlockAcc`), 8-lane dot products; the f32 matrix copy and the ILU storage
//!     reused across steps;
//!   - Gram-Schmidt as unconditional CGS2 in three passes (a DGKS re-orthogonalization
//!     test fired at every iteration anyway);
//!   - row-by-row assembly (`assembly::Assembler`) over the elements in the order of
//!     their lowest (RCM) node, so the scatter into the matrix stays in cache; element
//!     rows written in place, not returned by value (the copies were ~7 % of the CPU);
//!     one pass for both element states; the coarse level's A Z structure kept with the
//!     correction; one element-face map in the set-up;
//!   - the hot kernels (block products, ILU(0) sweeps, Gram-Schmidt, both assembly
//!     passes, the coarse A Z) compiled for AVX2 + FMA as well and chosen at run time
//!     ([`crate::sparse::wide`]; the release build's baseline is SSE2), bit for bit the
//!     same (Rust never fuses a * b + c); the serial stretches (coarse restriction,
//!     coarse LU solves, Dirichlet rows) run in parallel or in lane sums; a step's
//!     residual and its guess's product share one pass over the f64 matrix.
//! On a quiet machine p3's 60 steps from rest take 4.35 s, 45 times faster than
//! svMultiPhysics on the same steps (docs/validation.md). The coarse level's sums in
//! another order move dp by ~1e-10 mmHg; nothing else changes it.
//!
//! Boundary conditions: no-slip on every boundary triangle outside the inlet and
//! outlet faces; plug or Poiseuille inflow (see [`inflow_profile`]); resistance outlets p = R Q as
//! an implicit rank-one term; backflow stabilization at outlets.

use std::collections::HashSet;
use std::time::Instant;

use rayon::prelude::*;

use crate::assembly::{Assembler, Physics};
use crate::boundary::{boundary_triangles, face_geometries, FaceGeometry, FaceKind};
use crate::coarse::{aggregate, aggregate_size, Aggregates, CoarseCorrection, ProlongedOperator};
use crate::linear::{gmres, partitions, solve_refined, BlockIlu, GmresOutcome, Preconditioner};
use crate::flow_mesh::{element_faces, tri_key, Face, FlowMesh};
use crate::settings::{CaseSettings, InflowProfile, NonlinearIterations, RunMode};
use crate::time_integration::TimeIntegration;
use crate::sparse::{convert_into, dot, reverse_cuthill_mckee, split_by, spmv, spmv2, BlockPattern, Scalar, B, BB};
use crate::CfdError;

/// Pressure and flow on one face at one step.
#[derive(Clone, Debug, PartialEq)]
pub struct FaceResult {
    pub id: i32,
    pub name: String,
    pub mean_pressure_dyn_cm2: f64,
    /// Flux along the outward normal (boundary faces) or the triangles' winding normal.
    pub flow_ml_s: f64,
}

/// Results of one time step (or of the final steady iterate).
#[derive(Clone, Debug, PartialEq)]
pub struct StepResult {
    pub step: usize,
    pub time_s: f64,
    /// Prescribed inflow and the computed flux into the domain through the inlet.
    pub prescribed_inflow_ml_s: f64,
    pub inflow_ml_s: f64,
    /// Total flux out through the outlets.
    pub outflow_ml_s: f64,
    pub faces: Vec<FaceResult>,
    pub max_velocity_cm_s: f64,
    pub nonlinear_iterations: usize,
    pub linear_iterations: usize,
    /// Relative nonlinear residual at the last check of the step.
    pub residual: f64,
    /// How many times the step was retried after a stalled linear solve (0: the first
    /// attempt was accepted); see [`RETRY_LADDER`].
    pub retries: usize,
    /// False when the step's convergence-controlled Picard loop
    /// ([`crate::NonlinearIterations::Auto`]) stopped at its cap with the iterate still
    /// changing by more than the tolerance (always true for a fixed iteration count).
    pub nonlinear_converged: bool,
}

impl StepResult {
    pub fn face(&self, id: i32) -> Option<&FaceResult> {
        self.faces.iter().find(|f| f.id == id)
    }
}

/// Wall-clock breakdown (s).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Timings {
    pub setup_s: f64,
    pub assembly_s: f64,
    /// ILU(0) factorization and coarse-level setup; the latter also apart.
    pub preconditioner_s: f64,
    pub coarse_setup_s: f64,
    pub gmres_s: f64,
    pub total_s: f64,
    /// Preconditioner factorizations made (with reuse, fewer than linear solves).
    pub factorizations: usize,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Summary {
    pub steps: Vec<StepResult>,
    /// Final fields at the mesh nodes (input numbering).
    pub velocity_cm_s: Vec<[f64; 3]>,
    pub pressure_dyn_cm2: Vec<f64>,
    /// Steady mode: whether the residual target was reached (always true for transient runs).
    pub converged: bool,
    pub timings: Timings,
}

/// Prepared problem in the solver's (RCM) node numbering.
struct Problem {
    pattern: BlockPattern,
    assembler: Assembler,
    parts: Vec<std::ops::Range<usize>>,
    faces: Vec<FaceGeometry>,
    /// Velocity components of these nodes are prescribed.
    dirichlet: Vec<bool>,
    /// Inlet nodes with the plug velocity and their unit-flux velocity vector.
    inlet_nodes: Vec<(u32, [f64; 3])>,
    inlet_face: usize,
    outlets: Vec<OutletData>,
    /// order[new] = old node.
    order: Vec<u32>,
    /// The diagonal of the mesh's bounding box (cm): the domain's length scale.
    extent_cm: f64,
}

struct OutletData {
    face: usize,
    resistance_dyn_s_cm5: f64,
    /// b = integral of N_i n (cm^2) for free velocity dofs, 4 entries per node.
    flux_weights: Vec<f64>,
    /// Lumped boundary mass (area/3, cm^2) per face node, for backflow stabilization.
    lumped_area: Vec<(u32, f64, [f64; 3])>,
}

fn renumber(mesh: &FlowMesh, new_of_old: &[u32]) -> FlowMesh {
    let n = |i: u32| new_of_old[i as usize];
    let mut points_cm = vec![[0.0; 3]; mesh.points_cm.len()];
    for (old, p) in mesh.points_cm.iter().enumerate() {
        points_cm[new_of_old[old] as usize] = *p;
    }
    FlowMesh {
        points_cm,
        tets: mesh.tets.iter().map(|t| t.map(n)).collect(),
        faces: mesh
            .faces
            .iter()
            .map(|f| Face { id: f.id, name: f.name.clone(), triangles: f.triangles.iter().map(|t| t.map(n)).collect() })
            .collect(),
    }
}

fn boundary_face_index(faces: &[FaceGeometry], id: i32, role: &str) -> Result<usize, CfdError> {
    let k = faces.iter().position(|f| f.id == id).ok_or_else(|| CfdError::Settings(format!("{role} face {id} is not in the mesh")))?;
    if faces[k].kind != FaceKind::Boundary {
        return Err(CfdError::Settings(format!("{role} face {id} '{}' is not on the boundary", faces[k].name)));
    }
    Ok(k)
}

impl Problem {
    fn new(mesh: &FlowMesh, settings: &CaseSettings) -> Result<Self, CfdError> {
        let mut checked = mesh.clone();
        checked.validate()?;
        let n = checked.points_cm.len();
        let order = reverse_cuthill_mckee(&BlockPattern::from_tets(n, &checked.tets));
        let mut new_of_old = vec![0u32; n];
        for (new, &old) in order.iter().enumerate() {
            new_of_old[old as usize] = new as u32;
        }
        let mesh = renumber(&checked, &new_of_old);
        let element = element_faces(&mesh.tets);
        let faces = face_geometries(&mesh, &element)?;
        let inlet_face = boundary_face_index(&faces, settings.inlet_face_id, "inlet")?;
        let outlet_faces: Vec<usize> =
            settings.outlets.iter().map(|o| boundary_face_index(&faces, o.face_id, "outlet")).collect::<Result<_, _>>()?;
        let open: HashSet<[u32; 3]> = std::iter::once(inlet_face)
            .chain(outlet_faces.iter().copied())
            .flat_map(|k| faces[k].triangles.iter().map(|t| tri_key(*t)))
            .collect();
        let mut dirichlet = vec![false; n];
        for tri in boundary_triangles(&mesh, &element) {
            if !open.contains(&tri_key(tri)) {
                tri.iter().for_each(|&i| dirichlet[i as usize] = true);
            }
        }
        let inlet_nodes = inflow_profile(&faces[inlet_face], &dirichlet, &mesh.points_cm, settings.inflow_profile)?;
        for &(i, _) in &inlet_nodes {
            dirichlet[i as usize] = true;
        }
        let outlets = settings
            .outlets
            .iter()
            .zip(&outlet_faces)
            .map(|(o, &k)| outlet_data(&faces[k], k, o.resistance_dyn_s_cm5, &dirichlet, n))
            .collect();
        let pattern = BlockPattern::from_tets(n, &mesh.tets);
        let parts = partitions(&pattern, rayon::current_num_threads().max(1));
        let assembler = Assembler::new(&mesh.points_cm, mesh.tets, &pattern, parts.clone());
        let extent_cm = (0..3)
            .map(|c| {
                let (lo, hi) = mesh.points_cm.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| (lo.min(p[c]), hi.max(p[c])));
                (hi - lo).powi(2)
            })
            .sum::<f64>()
            .sqrt();
        Ok(Problem { pattern, assembler, parts, faces, dirichlet, inlet_nodes, inlet_face, outlets, order, extent_cm })
    }
}

/// Inflow profile on the inlet: a shape value per inlet node not on a wall, along -n
/// (mean inward normal), scaled so that the discrete flux of the P1 field through the
/// inlet is exactly 1 mL/s. Plug: shape 1. Poiseuille: the solution of -lap phi = 1
/// on the cap with phi = 0 on its rim (the fully developed laminar profile of any
/// cross-section; the paraboloid on a circle).
fn inflow_profile(
    face: &FaceGeometry,
    wall: &[bool],
    points_cm: &[[f64; 3]],
    kind: InflowProfile,
) -> Result<Vec<(u32, [f64; 3])>, CfdError> {
    let inward = face.mean_unit_normal().map(|x| -x);
    let weights = face.nodal_flux_weights();
    let mut free: Vec<(u32, f64)> = weights
        .iter()
        .filter(|(&i, _)| !wall[i as usize])
        .map(|(&i, b)| (i, -crate::flow_mesh::dot(inward, *b)))
        .collect();
    free.sort_unstable_by_key(|e| e.0);
    let shape: Vec<f64> = match kind {
        InflowProfile::Plug => vec![1.0; free.len()],
        InflowProfile::Poiseuille => cap_poisson(face, wall, points_cm, &free.iter().map(|e| e.0).collect::<Vec<_>>()),
    };
    // Inflow of the shape along -n: -sum shape_i b_i . (-n) = sum shape_i n . b_i.
    let inflow_per_unit: f64 = free.iter().zip(&shape).map(|(e, s)| e.1 * s).sum::<f64>();
    if !(inflow_per_unit > 0.0) {
        return Err(CfdError::Mesh(format!("inlet face {} '{}' has no node off the wall", face.id, face.name)));
    }
    Ok(free.into_iter().zip(shape).map(|((i, _), s)| (i, inward.map(|x| s * x / inflow_per_unit))).collect())
}

/// P1 solution of -lap phi = 1 on the cap's triangles with phi = 0 at wall nodes, at
/// the `free` nodes (sorted), by conjugate gradients.
fn cap_poisson(face: &FaceGeometry, wall: &[bool], p: &[[f64; 3]], free: &[u32]) -> Vec<f64> {
    let index = |i: u32| free.binary_search(&i).ok();
    let n = free.len();
    let mut entries: std::collections::HashMap<(usize, usize), f64> = std::collections::HashMap::new();
    let mut load = vec![0.0; n];
    for (tri, an) in face.triangles.iter().zip(&face.area_normals_cm2) {
        let area = crate::flow_mesh::dot(*an, *an).sqrt();
        if area == 0.0 {
            continue;
        }
        // Edge opposite vertex a (cyclic): K_ab = e_a . e_b / (4 A).
        let x = tri.map(|i| p[i as usize]);
        let e = [0, 1, 2].map(|a| crate::flow_mesh::sub(x[(a + 2) % 3], x[(a + 1) % 3]));
        for a in 0..3 {
            let Some(ia) = index(tri[a]).filter(|_| !wall[tri[a] as usize]) else { continue };
            load[ia] += area / 3.0;
            for b in 0..3 {
                if let Some(ib) = index(tri[b]).filter(|_| !wall[tri[b] as usize]) {
                    *entries.entry((ia, ib)).or_insert(0.0) += crate::flow_mesh::dot(e[a], e[b]) / (4.0 * area);
                }
            }
        }
    }
    let entries: Vec<((usize, usize), f64)> = entries.into_iter().collect();
    let apply = |v: &[f64]| {
        let mut y = vec![0.0; n];
        for &((i, j), k) in &entries {
            y[i] += k * v[j];
        }
        y
    };
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let mut x = vec![0.0; n];
    let mut r = load.clone();
    let mut d = r.clone();
    let mut rr = dot(&r, &r);
    let target = 1e-24 * rr;
    for _ in 0..10 * n + 100 {
        if rr <= target {
            break;
        }
        let q = apply(&d);
        let alpha = rr / dot(&d, &q);
        x.iter_mut().zip(&d).for_each(|(xi, di)| *xi += alpha * di);
        r.iter_mut().zip(&q).for_each(|(ri, qi)| *ri -= alpha * qi);
        let rr_new = dot(&r, &r);
        d.iter_mut().zip(&r).for_each(|(di, ri)| *di = ri + rr_new / rr * *di);
        rr = rr_new;
    }
    x
}

fn outlet_data(face: &FaceGeometry, k: usize, resistance: f64, dirichlet: &[bool], n: usize) -> OutletData {
    let mut flux_weights = vec![0.0; n * B];
    for (i, b) in face.nodal_flux_weights() {
        if !dirichlet[i as usize] {
            flux_weights[i as usize * B..i as usize * B + 3].copy_from_slice(&b);
        }
    }
    let mut lumped_area = Vec::new();
    for (tri, an) in face.triangles.iter().zip(&face.area_normals_cm2) {
        let area = crate::flow_mesh::dot(*an, *an).sqrt();
        let unit = an.map(|x| x / area);
        for &i in tri {
            if !dirichlet[i as usize] {
                lumped_area.push((i, area / 3.0, unit));
            }
        }
    }
    OutletData { face: k, resistance_dyn_s_cm5: resistance, flux_weights, lumped_area }
}

/// The solver state over a run.
struct Solver<'a> {
    problem: Problem,
    settings: &'a CaseSettings,
    vals: Vec<f64>,
    rhs: Vec<f64>,
    /// f32 copy of `vals` for the mixed-precision inner solves, and the ILU(0) factors
    /// of either precision: kept across steps so refactoring reuses their storage.
    vals_low: Vec<f32>,
    ilu_low: Option<BlockIlu<f32>>,
    ilu: Option<BlockIlu<f64>>,
    /// f64 ILU(0) of the whole matrix in one partition (no couplings dropped), made
    /// only when a stalled step is retried with [`Effort::Strong`].
    ilu_whole: Option<BlockIlu<f64>>,
    /// The two-level preconditioner's aggregates (made on the first solve when enabled).
    aggregates: Option<Aggregates>,
    /// The coarse correction that goes with the current factors.
    coarse: Option<CoarseCorrection>,
    /// How long the current factors have served (transient runs reuse them).
    factors: FactorsUse,
    /// Whether this is a transient run (steady iterations change the matrix too much to reuse factors).
    transient: bool,
    /// The last transient step's first update (empty: none yet), the next one's initial guess.
    previous_update: Vec<f64>,
    timings: Timings,
}

/// Transient runs keep one ILU(0) factorization (and its coarse correction) for several
/// time steps: from one step to the next the matrix changes by little (the convection
/// velocity and tau by one step's change of the flow), and on p2 the factorization and
/// coarse setup cost about as much as 12 GMRES iterations. Aging factors need a few
/// more iterations a step, so they are renewed once the iterations they have added
/// (above the fewest any of their solves needed) reach [`RENEWAL_COST_ITERATIONS`], after
/// `preconditioner_max_age` solves at most, and at once (the solve redone) when a solve
/// with old factors does not converge within [`FactorsUse::reused_budget`]. The rule
/// counts iterations, not seconds, so a run is reproducible.
#[derive(Clone, Copy, Debug, Default)]
struct FactorsUse {
    /// Solves done with the current factors (0: none made yet, or they must be renewed).
    solves: usize,
    /// The fewest GMRES iterations of a solve with them, and the iterations added above it.
    fewest_iterations: usize,
    added_iterations: usize,
}

/// A renewal of the factors and the coarse correction, in GMRES iterations of p2's
/// two-level solve (bench `kernels`: ILU(0) factorization to f32 ~90-140 ms and the
/// coarse setup ~20 ms, against ~8-10 ms an iteration).
const RENEWAL_COST_ITERATIONS: usize = 12;

impl FactorsUse {
    fn reusable(&self, settings: &CaseSettings, transient: bool) -> bool {
        transient && self.solves > 0 && self.solves < settings.preconditioner_max_age && self.added_iterations < RENEWAL_COST_ITERATIONS
    }

    /// GMRES budget of a solve with reused factors: beyond it new factors do better.
    fn reused_budget(&self, restart: usize) -> usize {
        restart.max(2 * self.fewest_iterations + RENEWAL_COST_ITERATIONS)
    }

    fn record(&mut self, reused: bool, effort: Effort, iterations: usize) {
        if effort != Effort::Normal {
            // The Strong effort's factors are other ones: make new Normal factors next time.
            *self = FactorsUse::default();
        } else if reused {
            self.solves += 1;
            // Fewer iterations than before (an easier step) lower the reference from now on.
            self.added_iterations += iterations.saturating_sub(self.fewest_iterations);
            self.fewest_iterations = self.fewest_iterations.min(iterations);
        } else {
            *self = FactorsUse { solves: 1, fewest_iterations: iterations, added_iterations: 0 };
        }
    }
}

/// The ILU(0) factors of `vals` on the row partitions `parts`, refactored in `slot`'s
/// storage (factored anew on the first call).
fn refactored<'s, T: Scalar>(
    slot: &'s mut Option<BlockIlu<T>>,
    pattern: &BlockPattern,
    parts: &[std::ops::Range<usize>],
    vals: &[f64],
) -> Result<&'s BlockIlu<T>, usize> {
    match slot {
        Some(ilu) => ilu.refactor(pattern, vals)?,
        None => *slot = Some(BlockIlu::factor(pattern, vals, parts.to_vec())?),
    }
    Ok(slot.as_ref().expect("factored above"))
}

/// How hard a step's linear solves try.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Effort {
    /// As the settings say (mixed precision, ILU(0) per thread partition).
    Normal,
    /// f64 GMRES with twice the restart length and [`STRONG_BUDGET_FACTOR`] times the
    /// iteration budget, preconditioned by ILU(0) of the whole matrix (one partition,
    /// no couplings dropped; single-threaded) and the coarse correction.
    Strong,
}

/// The Strong effort's GMRES budget, in multiples of `max_linear_iterations`.
const STRONG_BUDGET_FACTOR: usize = 4;

/// One way to attempt a time step: the linear solves' effort and the number of equal
/// sub-steps the step is split into (each a step of the case's scheme; a smaller step makes the
/// system more diagonally dominant through its mass term).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Attempt {
    effort: Effort,
    substeps: usize,
}

/// A time step whose linear solve stalls (or whose ILU(0) meets a singular pivot) is
/// tried again down this ladder before the run fails: first a stronger linear solve
/// at the same step, then the step as 2 and 4 sub-steps with it.
pub const RETRY_LADDER_LEN: usize = 3;
const RETRY_LADDER: [Attempt; RETRY_LADDER_LEN + 1] = [
    Attempt { effort: Effort::Normal, substeps: 1 },
    Attempt { effort: Effort::Strong, substeps: 1 },
    Attempt { effort: Effort::Strong, substeps: 2 },
    Attempt { effort: Effort::Strong, substeps: 4 },
];

impl Attempt {
    fn describe(&self) -> String {
        let solve = match self.effort {
            Effort::Normal => "the configured solve",
            Effort::Strong => "f64 GMRES with whole-matrix ILU(0), the coarse correction and 4x the iterations",
        };
        match self.substeps {
            1 => solve.to_string(),
            n => format!("{solve} on {n} sub-steps of dt/{n}"),
        }
    }
}

/// The outlets' resistance couplings as rank-one terms (coefficient, flux weights).
fn rank_one_terms(problem: &Problem) -> Vec<(f64, &[f64])> {
    problem.outlets.iter().map(|o| (o.resistance_dyn_s_cm5, &o.flux_weights[..])).collect()
}

/// The coarse correction of the two-level preconditioner for the matrix `vals` (None
/// when `aggregate_nodes` is 0); the aggregates are made on the first call.
fn coarse_correction(aggregates: &mut Option<Aggregates>, problem: &Problem, vals: &[f64], aggregate_nodes: usize) -> Option<CoarseCorrection> {
    if aggregate_nodes == 0 {
        return None;
    }
    let size = aggregate_size(problem.pattern.n_rows(), aggregate_nodes);
    let aggregates = aggregates.get_or_insert_with(|| aggregate(&problem.pattern, size)).clone();
    Some(CoarseCorrection::new(&problem.pattern, vals, &rank_one_terms(problem), aggregates, &problem.dirichlet))
}

/// z = M^-1 r: ILU(0), then (two-level) the coarse correction of the residual it leaves,
/// z = z_ilu + Z A_c^-1 Z^T (r - A z_ilu). A z_ilu is formed on the way, so A z for
/// GMRES is A z_ilu + (A Z) e: one fine product an iteration instead of two.
struct TwoLevel<'a, S: Scalar, T> {
    ilu: &'a BlockIlu<S>,
    coarse: Option<(&'a CoarseCorrection, &'a ProlongedOperator<'a>)>,
    apply_a: &'a dyn Fn(&[T], &mut [T]),
}

impl<S: Scalar, T: Scalar> Preconditioner<T> for TwoLevel<'_, S, T> {
    fn apply(&self, r: &[T], z: &mut [T]) {
        match self.coarse {
            None => self.ilu.apply(r, z),
            Some(_) => self.apply_with_product(self.apply_a, r, z, &mut vec![T::default(); r.len()]),
        }
    }

    fn apply_with_product(&self, apply_a: &dyn Fn(&[T], &mut [T]), r: &[T], z: &mut [T], az: &mut [T]) {
        self.ilu.apply(r, z);
        apply_a(z, az);
        if let Some((coarse, prolonged)) = self.coarse {
            let w: Vec<T> = r.par_iter().zip(az.par_iter()).map(|(ri, ai)| T::from_f64(ri.to_f64() - ai.to_f64())).collect();
            coarse.add_correction_and_product(prolonged, &w, z, az);
        }
    }
}

/// Row `row` (its blocks) with its velocity rows made those of the identity; `diag` is
/// the diagonal block's index in it.
fn identity_velocity_rows(row: &mut [f64], diag: usize) {
    for blk in row.chunks_exact_mut(BB) {
        blk[..3 * B].iter_mut().for_each(|v| *v = 0.0);
    }
    for c in 0..3 {
        row[diag * BB + c * B + c] = 1.0;
    }
}

/// x + ratio (x - prev): the linear extrapolation of the state to the end of the next
/// (sub-)step, `ratio` being that step's length over the gap between prev and x.
fn extrapolate(x: &mut [f64], prev: &[f64], ratio: f64) {
    x.iter_mut().zip(prev).for_each(|(xi, pi)| *xi += ratio * (*xi - pi));
}

/// What one step's Picard loop did.
struct StepStats {
    nonlinear_iterations: usize,
    linear_iterations: usize,
    /// Residual before the first solve, absolute, and the last relative check.
    initial_residual: f64,
    residual: f64,
    /// False when a convergence-controlled loop stopped at its cap still changing.
    converged: bool,
}

impl StepStats {
    fn new() -> StepStats {
        StepStats { nonlinear_iterations: 0, linear_iterations: 0, initial_residual: 0.0, residual: 1.0, converged: true }
    }
}

/// When a step's Picard (or Newton) loop stops.
#[derive(Clone, Copy, Debug)]
struct LoopControl {
    /// Linear solves at most.
    max_iterations: usize,
    /// Residual (relative to the step's first) at which the loop stops before a solve.
    residual_tol: f64,
    /// Convergence-controlled loops: the relative update of velocity and pressure at
    /// which the loop has converged; reaching `max_iterations` above it is reported.
    update_tol: Option<f64>,
    /// Assemble once more after the last allowed solve to check the residual.
    check_last: bool,
}

impl LoopControl {
    fn of(nonlinear: NonlinearIterations, tol: f64) -> LoopControl {
        match nonlinear {
            NonlinearIterations::Fixed(n) => LoopControl { max_iterations: n, residual_tol: tol, update_tol: None, check_last: n > 1 },
            // No residual test: its reference (the extrapolated guess's residual) says
            // little about how far the iterate still moves.
            NonlinearIterations::Auto { cap } => LoopControl { max_iterations: cap, residual_tol: 0.0, update_tol: Some(tol), check_last: false },
        }
    }
}

/// How much an update dx changed the iterate x (after the update): the larger of
/// ||du|| / ||u|| and ||dp|| / ||p - mean p|| (2-norms over the nodes; the pressure
/// without its mean, which the outlet's level sets, not the flow). Where a field is
/// smaller than sqrt(nodes) times its floor (`floors`: velocity cm/s, pressure dyn/cm^2;
/// diastole, the start from rest), the change is measured against that instead.
fn relative_change(dx: &[f64], x: &[f64], floors: [f64; 2]) -> f64 {
    let (mut du2, mut u2, mut dp2, mut p2, mut p1) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (k, (d, v)) in dx.iter().zip(x).enumerate() {
        if k % B == 3 {
            (dp2, p2, p1) = (dp2 + d * d, p2 + v * v, p1 + v);
        } else {
            (du2, u2) = (du2 + d * d, u2 + v * v);
        }
    }
    let nodes = (x.len() / B).max(1) as f64;
    let p_dev2 = (p2 - p1 * p1 / nodes).max(0.0);
    let ratio = |d2: f64, v2: f64, floor: f64| if d2 == 0.0 { 0.0 } else { (d2 / v2.max(nodes * floor * floor)).sqrt() };
    ratio(du2, u2, floors[0]).max(ratio(dp2, p_dev2, floors[1]))
}

impl<'a> Solver<'a> {
    fn physics(&self, steady: bool, dt_s: f64) -> Physics {
        Physics {
            density_g_cm3: self.settings.density_g_cm3,
            viscosity_g_cm_s: self.settings.viscosity_g_cm_s,
            inv_dt_per_s: 1.0 / dt_s,
            inv_dt_tau_per_s: if steady || !self.settings.tau_includes_dt { 0.0 } else { 1.0 / dt_s },
            formulation: self.settings.formulation,
        }
    }

    fn set_inflow(&self, x: &mut [f64], q_ml_s: f64) {
        for &i in self.problem.dirichlet.iter().enumerate().filter(|(_, &d)| d).map(|(i, _)| i).collect::<Vec<_>>().iter() {
            x[i * B..i * B + 3].iter_mut().for_each(|v| *v = 0.0);
        }
        for &(i, unit) in &self.problem.inlet_nodes {
            for c in 0..3 {
                x[i as usize * B + c] = q_ml_s * unit[c];
            }
        }
    }

    /// [`relative_change`]'s floors, the scales of the flow the case drives: the mean
    /// inflow velocity at peak flow U (cm/s), and the larger of its dynamic pressure rho U^2
    /// and the Poiseuille drop 8 pi mu U L / A of the inlet's section A over the domain's
    /// extent L (dyn/cm^2; the viscous scale where inertia is small).
    fn change_floors(&self) -> [f64; 2] {
        let (s, problem) = (self.settings, &self.problem);
        let area_cm2 = problem.faces[problem.inlet_face].area_cm2;
        let u_peak = s.inflow.peak().0.abs() / area_cm2;
        let viscous = 8.0 * std::f64::consts::PI * s.viscosity_g_cm_s * u_peak * problem.extent_cm / area_cm2;
        [u_peak, (s.density_g_cm3 * u_peak * u_peak).max(viscous)]
    }

    /// Backflow stabilization (Esmaily Moghadam et al. 2011): beta rho |min(a.n, 0)| on
    /// the outlet velocity diagonal, lumped.
    fn add_backflow(&mut self, a: &[f64]) {
        let beta_rho = self.settings.backflow_stabilization * self.settings.density_g_cm3;
        for o in &self.problem.outlets {
            for &(i, area, n) in &o.lumped_area {
                let i = i as usize;
                let an: f64 = (0..3).map(|c| a[i * B + c] * n[c]).sum();
                if an < 0.0 {
                    let d = self.problem.pattern.diag[i];
                    for c in 0..3 {
                        self.vals[d * BB + c * B + c] += beta_rho * (-an) * area;
                    }
                }
            }
        }
    }

    /// y = K x + sum_o R_o b_o (b_o . x): the implicit resistance coupling as a rank-one term.
    fn apply_operator<M: Scalar, T: Scalar>(problem: &Problem, vals: &[M], x: &[T], y: &mut [T]) {
        spmv(&problem.pattern, vals, x, y);
        for o in &problem.outlets {
            let q = dot(&o.flux_weights, x);
            if q != 0.0 && o.resistance_dyn_s_cm5 > 0.0 {
                crate::sparse::axpy(o.resistance_dyn_s_cm5 * q, &o.flux_weights, y);
            }
        }
    }

    /// [`Self::apply_operator`] of x into y and of v into w in one pass over the matrix.
    fn apply_operator2(problem: &Problem, vals: &[f64], x: &[f64], y: &mut [f64], v: &[f64], w: &mut [f64]) {
        spmv2(&problem.pattern, vals, x, y, v, w);
        for (x, y) in [(x, y), (v, w)] {
            for o in &problem.outlets {
                let q = dot(&o.flux_weights, x);
                if q != 0.0 && o.resistance_dyn_s_cm5 > 0.0 {
                    crate::sparse::axpy(o.resistance_dyn_s_cm5 * q, &o.flux_weights, y);
                }
            }
        }
    }

    /// `av` = K v made the product of the matrix with identity rows for the prescribed
    /// velocity components ([`Self::apply_dirichlet_rows`]; the flux weights are 0 there).
    fn identity_rows_product(&self, v: &[f64], av: &mut [f64]) {
        for (i, _) in self.problem.dirichlet.iter().enumerate().filter(|(_, &d)| d) {
            av[i * B..i * B + 3].copy_from_slice(&v[i * B..i * B + 3]);
        }
    }

    /// Identity rows for prescribed velocity components (the update there is 0), the
    /// thread partitions in parallel (serial, the other core waited).
    fn apply_dirichlet_rows(&mut self, r: &mut [f64]) {
        let (pattern, parts, dirichlet) = (&self.problem.pattern, &self.problem.parts, &self.problem.dirichlet);
        let val_parts = split_by(&mut self.vals, parts.iter().map(|rows| pattern.blocks_in(rows) * BB));
        let r_parts = split_by(r, parts.iter().map(|rows| rows.len() * B));
        val_parts.into_par_iter().zip(r_parts).zip(parts.par_iter()).for_each(|((vals, r), rows)| {
            let base = pattern.row_ptr[rows.start];
            for i in rows.clone().filter(|&i| dirichlet[i]) {
                identity_velocity_rows(&mut vals[(pattern.row_ptr[i] - base) * BB..(pattern.row_ptr[i + 1] - base) * BB], pattern.diag[i] - pattern.row_ptr[i]);
                r[(i - rows.start) * B..][..3].iter_mut().for_each(|v| *v = 0.0);
            }
        });
    }

    /// One implicit step: Picard (or Newton) iterations in defect-correction form
    /// J(x_k) dx = F - K(x_k) x_k, x_{k+1} = x_k + dx, with J = K (Picard) or K plus
    /// the convection Jacobian (Newton). With `check_last` false the step ends right
    /// after the last allowed solve, without assembling again to check the residual
    /// (the semi-implicit transient: one solve per step); `residual` is then the
    /// relative residual of that linear solve. A convergence-controlled loop
    /// (`update_tol`) stops after a solve whose update is below the tolerance. (Stopping
    /// before a solve whose update, predicted from the last one and the residual's
    /// contraction, would be below it was tried: on p2 at dt 1 ms it stopped every step
    /// after one solve and kept the semi-implicit step's oscillation, dp 7.030 mmHg.)
    /// The factors are reused across the loop's solves as across steps ([`FactorsUse`]).
    #[allow(clippy::too_many_arguments)]
    fn step(
        &mut self,
        phys: &Physics,
        x: &mut [f64],
        x_old: &[f64],
        control: LoopControl,
        newton: bool,
        effort: Effort,
        step: usize,
        time_s: f64,
    ) -> Result<StepStats, CfdError> {
        let n = x.len();
        let mut r = vec![0.0; n];
        let mut dx = vec![0.0; n];
        let mut guess_product = vec![0.0; n];
        let mut stats = StepStats::new();
        let max_iterations = control.max_iterations;
        for it in 0..=max_iterations {
            if it == max_iterations && !control.check_last && it > 0 {
                break;
            }
            let t0 = Instant::now();
            self.problem.assembler.assemble(&self.problem.pattern, phys, x, x_old, &mut self.vals, &mut self.rhs);
            self.add_backflow(x);
            let will_solve = it < max_iterations;
            let guess = will_solve && self.initial_guess(it, effort, &mut dx);
            // A Newton matrix differs from K: its product with the guess waits for it.
            let guessed = guess && !newton && dx.iter().any(|&v| v != 0.0);
            match guessed {
                true => Self::apply_operator2(&self.problem, &self.vals, x, &mut r, &dx, &mut guess_product),
                false => Self::apply_operator(&self.problem, &self.vals, x, &mut r),
            }
            r.par_iter_mut().zip(&self.rhs).with_min_len(4096).for_each(|(ri, fi)| *ri = fi - *ri);
            if newton && will_solve {
                self.problem.assembler.add_convection_jacobian(&self.problem.pattern, phys, x, &mut self.vals);
            }
            self.apply_dirichlet_rows(&mut r);
            if guessed {
                self.identity_rows_product(&dx, &mut guess_product);
            }
            self.timings.assembly_s += t0.elapsed().as_secs_f64();
            let res = crate::sparse::norm(&r);
            if !res.is_finite() {
                return Err(CfdError::Diverged { step, time_s, residual: res, reason: "non-finite residual".into() });
            }
            if it == 0 {
                stats.initial_residual = res;
            }
            stats.residual = if stats.initial_residual > 0.0 { res / stats.initial_residual } else { 0.0 };
            if it == max_iterations || (it > 0 && stats.residual <= control.residual_tol) || res == 0.0 {
                break;
            }
            let t1 = Instant::now();
            let singular = |row: usize| CfdError::Diverged { step, time_s, residual: res, reason: format!("singular pivot block at node {row} in ILU(0)") };
            let reused = effort == Effort::Normal && self.factors.reusable(self.settings, self.transient);
            if !reused {
                self.refresh_preconditioner(effort).map_err(singular)?;
            }
            if effort == Effort::Normal && self.settings.mixed_precision {
                convert_into(&self.vals, &mut self.vals_low);
            }
            let t2 = Instant::now();
            let mut out = self.solve_linear(effort, &r, &mut dx, reused, guessed.then_some(&guess_product[..]));
            // A reused factorization that no longer preconditions well is dropped at once.
            if reused && !out.converged {
                let t3 = Instant::now();
                self.refresh_preconditioner(effort).map_err(singular)?;
                self.timings.preconditioner_s += t3.elapsed().as_secs_f64();
                self.initial_guess(it, effort, &mut dx);
                let retry = self.solve_linear(effort, &r, &mut dx, false, None);
                self.factors.record(false, effort, retry.iterations);
                out = GmresOutcome { iterations: out.iterations + retry.iterations, ..retry };
            } else {
                self.factors.record(reused, effort, out.iterations);
            }
            self.timings.preconditioner_s += (t2 - t1).as_secs_f64();
            self.timings.gmres_s += t2.elapsed().as_secs_f64();
            stats.linear_iterations += out.iterations;
            stats.nonlinear_iterations += 1;
            // Accept a solve that missed the target by less than a factor 100 (as
            // svMultiPhysics continues on unconverged linear solves); fail beyond.
            if !(out.relative_residual <= 100.0 * self.settings.linear_tolerance) {
                return Err(CfdError::LinearSolver { step, time_s, iterations: out.iterations, residual: out.relative_residual });
            }
            if guess {
                self.previous_update.clone_from(&dx);
            }
            crate::sparse::axpy(1.0, &dx, x);
            if !control.check_last && it + 1 == max_iterations {
                stats.residual = out.relative_residual;
            }
            if let Some(tol) = control.update_tol {
                let change = relative_change(&dx, x, self.change_floors());
                if change <= tol {
                    break;
                }
                stats.converged = it + 1 < max_iterations;
            }
        }
        Ok(stats)
    }

    /// Sets `dx` to the initial guess of a step's solve and says whether the update is
    /// kept as the next step's: a transient step's first update is the correction of the
    /// extrapolated state, ~dt^2 u'', which changes little from one step to the next,
    /// so the last one starts the solve (its later Picard updates are far smaller: zero).
    /// Only the mixed-precision solve takes a guess ([`solve_refined`]). A resumed run
    /// has no last update, so with `preconditioner_max_age` 1 (new factors every step,
    /// for a resume that continues bit for bit) every solve starts from zero.
    fn initial_guess(&self, it: usize, effort: Effort, dx: &mut [f64]) -> bool {
        let s = self.settings;
        let keep = self.transient && it == 0 && effort == Effort::Normal && s.mixed_precision && s.preconditioner_max_age > 1;
        match keep && self.previous_update.len() == dx.len() {
            true => dx.copy_from_slice(&self.previous_update),
            false => dx.iter_mut().for_each(|v| *v = 0.0),
        }
        keep
    }

    /// New factors (and coarse correction) of the current matrix for `effort`.
    fn refresh_preconditioner(&mut self, effort: Effort) -> Result<(), usize> {
        let t0 = Instant::now();
        self.timings.factorizations += 1;
        let (problem, vals, s) = (&self.problem, &self.vals, self.settings);
        // The Strong effort adds the coarse correction even when the case asked for ILU(0) alone.
        let nodes = match effort {
            Effort::Strong if s.coarse_aggregate_nodes == 0 => crate::settings::TWO_LEVEL_AGGREGATE_NODES,
            _ => s.coarse_aggregate_nodes,
        };
        self.coarse = coarse_correction(&mut self.aggregates, problem, vals, nodes);
        self.timings.coarse_setup_s += t0.elapsed().as_secs_f64();
        let (pattern, parts) = (&problem.pattern, &problem.parts);
        match effort {
            Effort::Normal if s.mixed_precision => refactored(&mut self.ilu_low, pattern, parts, vals).map(|_| ()),
            Effort::Normal => refactored(&mut self.ilu, pattern, parts, vals).map(|_| ()),
            Effort::Strong => refactored(&mut self.ilu_whole, pattern, &[0..pattern.n_rows()], vals).map(|_| ()),
        }
    }

    /// Solve A dx = r with the current factors ([`Self::refresh_preconditioner`]); with
    /// `reused` factors within [`FactorsUse::reused_budget`] iterations. `dx` holds the
    /// initial guess ([`Self::initial_guess`]).
    fn solve_linear(&self, effort: Effort, r: &[f64], dx: &mut [f64], reused: bool, guess_product: Option<&[f64]>) -> GmresOutcome {
        let (problem, vals, s) = (&self.problem, &self.vals, self.settings);
        let apply_a = |v: &[f64], y: &mut [f64]| Self::apply_operator(problem, vals, v, y);
        let (tol, restart) = (s.linear_tolerance, s.gmres_restart);
        let max_iterations = if reused { self.factors.reused_budget(restart).min(s.max_linear_iterations) } else { s.max_linear_iterations };
        let factors = "factored by refresh_preconditioner";
        // A Z of this matrix: the coarse factors may be older than it.
        let prolonged = self.coarse.as_ref().map(|c| c.prolonged_operator(&problem.pattern, vals, &rank_one_terms(problem)));
        let coarse = self.coarse.as_ref().zip(prolonged.as_ref());
        match effort {
            Effort::Normal if s.mixed_precision => {
                let ilu = self.ilu_low.as_ref().expect(factors);
                let vals_low = &self.vals_low;
                let apply_a_low = |v: &[f32], y: &mut [f32]| Self::apply_operator(problem, vals_low, v, y);
                let apply_m = TwoLevel { ilu, coarse, apply_a: &apply_a };
                let apply_m_low = TwoLevel { ilu, coarse, apply_a: &apply_a_low };
                solve_refined(&apply_a, &apply_m, &apply_a_low, &apply_m_low, r, dx, guess_product, tol, restart, max_iterations)
            }
            Effort::Normal => {
                let ilu = self.ilu.as_ref().expect(factors);
                gmres(&apply_a, &TwoLevel { ilu, coarse, apply_a: &apply_a }, r, dx, tol, restart, max_iterations)
            }
            Effort::Strong => {
                let ilu = self.ilu_whole.as_ref().expect(factors);
                let apply_m = TwoLevel { ilu, coarse, apply_a: &apply_a };
                gmres(&apply_a, &apply_m, r, dx, tol, 2 * restart, STRONG_BUDGET_FACTOR * s.max_linear_iterations)
            }
        }
    }

    /// The acceleration a run's state keeps: generalized-alpha's only.
    fn acceleration_kept<'v>(&self, accel: &'v [f64]) -> Option<&'v [f64]> {
        match self.settings.time_integration {
            TimeIntegration::GeneralizedAlpha { .. } => Some(accel),
            TimeIntegration::BackwardEuler => None,
        }
    }

    /// The acceleration to continue a generalized-alpha run from `state` (zero for
    /// backward Euler, which does not use it).
    fn start_acceleration(&self, state: &SolverState) -> Result<Vec<f64>, CfdError> {
        let n = self.problem.order.len();
        match self.settings.time_integration {
            TimeIntegration::BackwardEuler => Ok(vec![0.0; n * B]),
            TimeIntegration::GeneralizedAlpha { .. } if state.acceleration_cm_s2.is_empty() => Err(CfdError::Settings(format!(
                "the start state (step {}) has no acceleration field: it is not of a generalized-alpha run; continue it with backward Euler or start over",
                state.step
            ))),
            TimeIntegration::GeneralizedAlpha { .. } => state_vector(&self.problem.order, &state.acceleration_cm_s2, &state.pressure_rate_dyn_cm2_s, "acceleration/pressure rate"),
        }
    }

    fn face_results(&self, x: &[f64]) -> Vec<FaceResult> {
        self.problem
            .faces
            .iter()
            .map(|f| {
                let mut p_int = 0.0;
                let mut q = 0.0;
                for (tri, an) in f.triangles.iter().zip(&f.area_normals_cm2) {
                    let area = crate::flow_mesh::dot(*an, *an).sqrt();
                    let nodes = tri.map(|i| i as usize * B);
                    p_int += area * nodes.iter().map(|&k| x[k + 3]).sum::<f64>() / 3.0;
                    for c in 0..3 {
                        q += an[c] * nodes.iter().map(|&k| x[k + c]).sum::<f64>() / 3.0;
                    }
                }
                FaceResult { id: f.id, name: f.name.clone(), mean_pressure_dyn_cm2: p_int / f.area_cm2, flow_ml_s: q }
            })
            .collect()
    }

    fn step_result(&self, x: &[f64], step: usize, time_s: f64, q_in: f64, stats: &StepStats, retries: usize) -> Result<StepResult, CfdError> {
        let faces = self.face_results(x);
        let inflow_ml_s = -faces[self.problem.inlet_face].flow_ml_s;
        let outflow_ml_s = self.problem.outlets.iter().map(|o| faces[o.face].flow_ml_s).sum();
        let max_velocity_cm_s =
            x.chunks_exact(B).map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()).fold(0.0, f64::max);
        // 100 m/s is far beyond any cardiovascular flow: the iteration has blown up.
        if !(max_velocity_cm_s < 1e4) {
            let reason = format!("velocity {max_velocity_cm_s:.3e} cm/s");
            return Err(CfdError::Diverged { step, time_s, residual: stats.residual, reason });
        }
        Ok(StepResult {
            step,
            time_s,
            prescribed_inflow_ml_s: q_in,
            inflow_ml_s,
            outflow_ml_s,
            faces,
            max_velocity_cm_s,
            nonlinear_iterations: stats.nonlinear_iterations,
            linear_iterations: stats.linear_iterations,
            residual: stats.residual,
            retries,
            nonlinear_converged: stats.converged,
        })
    }


    /// Time step `step` from x (x_prev: the state one step before), retried down
    /// [`RETRY_LADDER`] when a linear solve stalls or ILU(0) meets a singular pivot.
    /// Returns the accepted attempt's statistics and its rung (0: no retry).
    fn advance(&mut self, x: &mut [f64], x_prev: &[f64], accel: &mut [f64], step: usize, time_s: f64) -> Result<(StepStats, usize), CfdError> {
        let (x_start, accel_start) = (x.to_vec(), accel.to_vec());
        let mut failures = Vec::new();
        for (rung, attempt) in RETRY_LADDER.iter().enumerate() {
            x.copy_from_slice(&x_start);
            accel.copy_from_slice(&accel_start);
            match self.attempt_step(attempt, x, x_prev, accel, step, time_s) {
                Ok(stats) => return Ok((stats, rung)),
                Err(e @ (CfdError::LinearSolver { .. } | CfdError::Diverged { .. })) => failures.push((attempt.describe(), e)),
                Err(e) => return Err(e),
            }
        }
        x.copy_from_slice(&x_start);
        accel.copy_from_slice(&accel_start);
        let tried = failures.iter().map(|(how, e)| format!("{how}: {e}")).collect::<Vec<_>>().join("; ");
        Err(CfdError::StepFailed { step, time_s, tried })
    }

    /// One attempt at the step ending at `time_s`: `attempt.substeps` sub-steps of the
    /// time integration scheme ([`crate::time_integration`]: each solves for the stage
    /// velocity u_{n+af}, which backward Euler's u_{n+1} is), each started from the
    /// linear extrapolation of the states before it. `accel` is the velocity's time
    /// derivative (generalized-alpha's a_n; backward Euler carries it along unused).
    fn attempt_step(&mut self, attempt: &Attempt, x: &mut [f64], x_prev: &[f64], accel: &mut [f64], step: usize, time_s: f64) -> Result<StepStats, CfdError> {
        let s = self.settings;
        let sub_dt = s.dt_s / attempt.substeps as f64;
        let alpha = s.time_integration.coefficients();
        // Time terms with the stage coefficient c; tau keeps the physical step.
        let phys = Physics { inv_dt_per_s: alpha.stage_inv_dt(sub_dt), ..self.physics(false, sub_dt) };
        let control = LoopControl::of(s.nonlinear(), s.nonlinear_tolerance);
        let mut total = StepStats { residual: 0.0, ..StepStats::new() };
        let (mut prev, mut gap) = (x_prev.to_vec(), s.dt_s);
        for k in 1..=attempt.substeps {
            let t = time_s - s.dt_s + k as f64 * sub_dt;
            let x_old = x.to_vec();
            let u_star = crate::time_integration::stage_base(&alpha, &x_old, accel, sub_dt);
            // Initial guess (and, semi-implicit, the convection velocity): linear
            // extrapolation to the stage time t_n + af dt, second-order accurate in dt.
            extrapolate(x, &prev, alpha.alpha_f * sub_dt / gap);
            self.set_inflow(x, s.inflow.flow_ml_s(t));
            // Prescribed velocities enter at their stage value u_{n+af}.
            for (i, _) in self.problem.dirichlet.iter().enumerate().filter(|(_, &d)| d) {
                for c in i * B..i * B + 3 {
                    x[c] = alpha.stage(x_old[c], x[c]);
                }
            }
            let stats = self.step(&phys, x, &u_star, control, false, attempt.effort, step, t)?;
            crate::time_integration::finish(&alpha, &x_old, x, accel, sub_dt);
            total.nonlinear_iterations += stats.nonlinear_iterations;
            total.linear_iterations += stats.linear_iterations;
            total.residual = stats.residual;
            total.converged &= stats.converged;
            (prev, gap) = (x_old, sub_dt);
        }
        Ok(total)
    }

    fn transient(&mut self, start: Option<&SolverState>, observer: &mut Observer) -> Result<Outcome, CfdError> {
        let s = self.settings;
        let n_steps = (s.cycles as f64 * s.inflow.period_s() / s.dt_s).round() as usize;
        let (first, mut x, mut x_prev, mut accel) = match start {
            Some(state) if state.steady.is_some() => {
                return Err(CfdError::Settings("the start state is of a steady solve, not of a transient run".into()));
            }
            Some(state) => {
                let x = state_vector(&self.problem.order, &state.velocity_cm_s, &state.pressure_dyn_cm2, "velocity/pressure")?;
                let x_prev = state_vector(&self.problem.order, &state.previous_velocity_cm_s, &state.previous_pressure_dyn_cm2, "previous velocity/pressure")?;
                let accel = self.start_acceleration(state)?;
                (state.step + 1, x, x_prev, accel)
            }
            // From rest: zero velocity, pressure and acceleration.
            None => (1, vec![0.0; self.problem.order.len() * B], vec![0.0; self.problem.order.len() * B], vec![0.0; self.problem.order.len() * B]),
        };
        let mut results = Vec::with_capacity(n_steps);
        let mut cancelled_at = None;
        for step in first..=n_steps {
            let time_s = step as f64 * s.dt_s;
            let q_in = s.inflow.flow_ml_s(time_s);
            let x_old = x.clone();
            let (stats, retries) = self.advance(&mut x, &x_prev, &mut accel, step, time_s)?;
            x_prev.copy_from_slice(&x_old);
            let result = self.step_result(&x, step, time_s, q_in, &stats, retries)?;
            let retried = if retries > 0 { format!(" (retried: {})", RETRY_LADDER[retries].describe()) } else { String::new() };
            let msg = format!(
                "step {step}/{n_steps} t={time_s:.3} s Q={:.2} mL/s vmax={:.3} m/s picard={}{} gmres={}{retried}",
                result.inflow_ml_s,
                result.max_velocity_cm_s / crate::vtu::CM_S_PER_M_S,
                stats.nonlinear_iterations,
                if stats.converged { "" } else { " (at the cap, not converged)" },
                stats.linear_iterations
            );
            results.push(result);
            let view = StepView {
                fraction: step as f64 / n_steps as f64,
                message: &msg,
                result: results.last(),
                step,
                time_s,
                order: &self.problem.order,
                x: &x,
                x_prev: Some(&x_prev),
                accel: self.acceleration_kept(&accel),
                steady: None,
            };
            if !observer(&view) {
                cancelled_at = Some(time_s);
                break;
            }
        }
        let accel = self.acceleration_kept(&accel).map(<[f64]>::to_vec);
        Ok(Outcome { steps: results, x, x_prev: Some(x_prev), accel, steady: None, last_iteration: 0, converged: true, cancelled_at })
    }

    /// Steady solve by pseudo-transient continuation: one Picard or Newton iteration
    /// per pseudo step. The pseudo step starts at `steady_pseudo_dt_s` (infinite: plain
    /// Picard/Newton) and grows by switched evolution relaxation (Mulder and van Leer
    /// 1985), dt_k = dt_0 r_0 / r_k, capped at `steady_pseudo_dt_max_s`, so the
    /// iteration becomes plain Newton near convergence. At the start of each pseudo
    /// step the time terms cancel, so the residual checked is the steady one.
    fn steady(&mut self, start: Option<&SolverState>, observer: &mut Observer) -> Result<Outcome, CfdError> {
        let s = self.settings;
        let (q_peak, t_peak) = s.inflow.peak();
        // A resumed solve continues the iteration count, the residual reference and the
        // pseudo step of the run it continues, so it takes the same path.
        let (first, mut x, mut progress) = match start {
            Some(state) => {
                let x = state_vector(&self.problem.order, &state.velocity_cm_s, &state.pressure_dyn_cm2, "velocity/pressure")?;
                let progress = state.steady.ok_or_else(|| CfdError::Settings("the start state is of a transient run, not of a steady solve".into()))?;
                (state.step + 1, x, Some(progress))
            }
            None => (1, vec![0.0; self.problem.order.len() * B], None),
        };
        self.set_inflow(&mut x, q_peak);
        let rel_of = |p: &Option<SteadyProgress>| p.map(|p| p.relative_residual);
        let next_pseudo_dt = |rel: Option<f64>| match rel {
            Some(rel) if rel > 0.0 => (s.steady_pseudo_dt_s / rel).min(s.steady_pseudo_dt_max_s),
            _ => s.steady_pseudo_dt_s,
        };
        let mut pseudo_dt = next_pseudo_dt(rel_of(&progress));
        let mut newton = rel_of(&progress).is_some_and(|rel| rel < s.steady_newton_below);
        let mut converged = false;
        let mut stats = StepStats::new();
        let mut cancelled_at = None;
        let mut last_iteration = first - 1;
        for it in first..=s.steady_max_iterations + 1 {
            let x_old = x.clone();
            let last = it > s.steady_max_iterations;
            let phys = self.physics(true, pseudo_dt);
            let control = LoopControl { max_iterations: usize::from(!last), residual_tol: 1.0, update_tol: None, check_last: false };
            let step_stats = self.step(&phys, &mut x, &x_old, control, newton, Effort::Normal, it, t_peak)?;
            last_iteration = it;
            let reference = progress.map_or(step_stats.initial_residual, |p| p.reference_residual);
            let rel = if reference > 0.0 { step_stats.initial_residual / reference } else { 0.0 };
            progress = Some(SteadyProgress { reference_residual: reference, relative_residual: rel });
            pseudo_dt = next_pseudo_dt(Some(rel));
            newton = rel < s.steady_newton_below;
            stats.nonlinear_iterations += step_stats.nonlinear_iterations;
            stats.linear_iterations += step_stats.linear_iterations;
            stats.residual = rel;
            if rel <= s.steady_tolerance {
                converged = true;
                // The check ran before this iteration's solve, which only improved x further.
                break;
            }
            if last {
                break;
            }
            let kind = if newton { "Newton" } else { "Picard" };
            let msg = format!("steady iteration {it}: residual {rel:.2e}, gmres {}, next: {kind}, pseudo dt {pseudo_dt:.3e} s", step_stats.linear_iterations);
            let view = StepView {
                fraction: it as f64 / s.steady_max_iterations as f64,
                message: &msg,
                result: None,
                step: it,
                time_s: t_peak,
                order: &self.problem.order,
                x: &x,
                x_prev: None,
                accel: None,
                steady: progress,
            };
            if !observer(&view) {
                cancelled_at = Some(t_peak);
                break;
            }
        }
        let result = self.step_result(&x, 0, t_peak, q_peak, &stats, 0)?;
        Ok(Outcome { steps: vec![result], x, x_prev: None, accel: None, steady: progress, last_iteration, converged, cancelled_at })
    }
}

/// What [`simulate_from`]'s observer is shown after every time step (or steady iteration).
pub struct StepView<'a> {
    pub fraction: f64,
    pub message: &'a str,
    /// The step's results (transient runs; None between steady iterations).
    pub result: Option<&'a StepResult>,
    /// Time step number (steady: iteration number) and time (steady: the peak time).
    pub step: usize,
    pub time_s: f64,
    order: &'a [u32],
    x: &'a [f64],
    x_prev: Option<&'a [f64]>,
    accel: Option<&'a [f64]>,
    steady: Option<SteadyProgress>,
}

impl StepView<'_> {
    /// Velocity (cm/s) and pressure (dyn/cm^2) at the mesh nodes (input numbering).
    pub fn fields(&self) -> (Vec<[f64; 3]>, Vec<f64>) {
        fields(self.order, self.x)
    }

    /// A steady solve's residual relative to its first one (None in transient runs).
    pub fn relative_residual(&self) -> Option<f64> {
        self.steady.map(|p| p.relative_residual)
    }

    /// The state to continue this run from with [`simulate_from`].
    pub fn state(&self) -> Option<SolverState> {
        Some(solver_state(self.order, self.step, self.time_s, self.x, self.x_prev, self.accel, self.steady))
    }
}

/// A run's state in input numbering; a steady iterate is its own previous state.
fn solver_state(order: &[u32], step: usize, time_s: f64, x: &[f64], x_prev: Option<&[f64]>, accel: Option<&[f64]>, steady: Option<SteadyProgress>) -> SolverState {
    let (velocity_cm_s, pressure_dyn_cm2) = fields(order, x);
    let (previous_velocity_cm_s, previous_pressure_dyn_cm2) = fields(order, x_prev.unwrap_or(x));
    let (acceleration_cm_s2, pressure_rate_dyn_cm2_s) = accel.map(|a| fields(order, a)).unwrap_or_default();
    SolverState {
        step,
        time_s,
        velocity_cm_s,
        pressure_dyn_cm2,
        previous_velocity_cm_s,
        previous_pressure_dyn_cm2,
        acceleration_cm_s2,
        pressure_rate_dyn_cm2_s,
        steady,
    }
}

/// Where a steady solve stands: the absolute residual of its first iteration (the
/// reference of the relative target and of the pseudo time step) and the last
/// relative residual.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SteadyProgress {
    pub reference_residual: f64,
    pub relative_residual: f64,
}

/// A transient run's state after a time step (input node numbering): enough to continue
/// it (the next step's initial guess extrapolates from the previous step), bit for bit
/// with `preconditioner_max_age` 1; with reused factors the continued run starts with
/// new ones, which changes its solves within the linear tolerance.
#[derive(Clone, Debug, PartialEq)]
pub struct SolverState {
    pub step: usize,
    pub time_s: f64,
    pub velocity_cm_s: Vec<[f64; 3]>,
    pub pressure_dyn_cm2: Vec<f64>,
    pub previous_velocity_cm_s: Vec<[f64; 3]>,
    pub previous_pressure_dyn_cm2: Vec<f64>,
    /// Generalized-alpha runs: the velocity's time derivative (cm/s^2) after `step`;
    /// empty for backward Euler and steady solves, which do not need it.
    pub acceleration_cm_s2: Vec<[f64; 3]>,
    /// Generalized-alpha runs: the stage pressure's rate of change (dyn/cm^2/s) that
    /// extrapolates it to the step's time ([`crate::time_integration`]); else empty.
    pub pressure_rate_dyn_cm2_s: Vec<f64>,
    /// Steady solves only (then step counts iterations and previous = current).
    pub steady: Option<SteadyProgress>,
}

/// The result of [`simulate_from`]: the summary of the steps run (after the start
/// state's step), the final state (transient runs), and whether the observer stopped it.
#[derive(Clone, Debug, PartialEq)]
pub struct Run {
    pub summary: Summary,
    pub state: Option<SolverState>,
    /// Time of the last step done when the observer returned false.
    pub cancelled_at_s: Option<f64>,
}

type Observer<'a> = dyn FnMut(&StepView) -> bool + 'a;

struct Outcome {
    steps: Vec<StepResult>,
    x: Vec<f64>,
    x_prev: Option<Vec<f64>>,
    accel: Option<Vec<f64>>,
    steady: Option<SteadyProgress>,
    /// Steady solves: the number of the last iteration done.
    last_iteration: usize,
    converged: bool,
    cancelled_at: Option<f64>,
}

fn fields(order: &[u32], x: &[f64]) -> (Vec<[f64; 3]>, Vec<f64>) {
    let n = order.len();
    let mut velocity = vec![[0.0; 3]; n];
    let mut pressure = vec![0.0; n];
    for (new, &old) in order.iter().enumerate() {
        velocity[old as usize] = [x[new * B], x[new * B + 1], x[new * B + 2]];
        pressure[old as usize] = x[new * B + 3];
    }
    (velocity, pressure)
}

/// Solver vector (RCM numbering) of nodal fields given in input numbering.
fn state_vector(order: &[u32], velocity: &[[f64; 3]], pressure: &[f64], what: &str) -> Result<Vec<f64>, CfdError> {
    let n = order.len();
    if velocity.len() != n || pressure.len() != n {
        return Err(CfdError::Settings(format!("start state {what} has {} / {} values for {n} mesh nodes", velocity.len(), pressure.len())));
    }
    if velocity.iter().flatten().chain(pressure).any(|v| !v.is_finite()) {
        return Err(CfdError::Settings(format!("start state {what} has a non-finite value")));
    }
    let mut x = vec![0.0; n * B];
    for (new, &old) in order.iter().enumerate() {
        x[new * B..new * B + 3].copy_from_slice(&velocity[old as usize]);
        x[new * B + 3] = pressure[old as usize];
    }
    Ok(x)
}

/// Run a case on a mesh. `progress(fraction, message)` is called after every time
/// step (or steady iteration); returning false cancels the run.
pub fn simulate(mesh: &FlowMesh, settings: &CaseSettings, progress: &mut dyn FnMut(f64, &str) -> bool) -> Result<Summary, CfdError> {
    let run = simulate_from(mesh, settings, None, &mut |view| progress(view.fraction, view.message))?;
    match run.cancelled_at_s {
        Some(time_s) => Err(CfdError::Cancelled { time_s }),
        None => Ok(run.summary),
    }
}

/// [`simulate`] with a start state (transient: continue after `start.step`) and an
/// observer that sees each step's results and fields; returning false stops the run
/// at the end of that step with the results so far (`cancelled_at_s` set).
pub fn simulate_from(mesh: &FlowMesh, settings: &CaseSettings, start: Option<&SolverState>, observer: &mut Observer) -> Result<Run, CfdError> {
    let start_time = Instant::now();
    settings.validate()?;
    crate::memory::check_fits(mesh.tets.len(), crate::memory::available_bytes())?;
    let problem = Problem::new(mesh, settings)?;
    let n_blocks = problem.pattern.cols.len();
    let n_dofs = problem.order.len() * B;
    let mut solver = Solver {
        problem,
        settings,
        vals: vec![0.0; n_blocks * BB],
        rhs: vec![0.0; n_dofs],
        vals_low: Vec::new(),
        ilu_low: None,
        ilu: None,
        ilu_whole: None,
        aggregates: None,
        coarse: None,
        factors: FactorsUse::default(),
        transient: settings.mode == RunMode::Transient,
        previous_update: Vec::new(),
        timings: Timings::default(),
    };
    solver.timings.setup_s = start_time.elapsed().as_secs_f64();
    let outcome = match settings.mode {
        RunMode::Transient => solver.transient(start, observer)?,
        RunMode::Steady => solver.steady(start, observer)?,
    };
    let order = &solver.problem.order;
    let (velocity_cm_s, pressure_dyn_cm2) = fields(order, &outcome.x);
    let state = match (&outcome.x_prev, outcome.steady, outcome.steps.last()) {
        (Some(prev), _, Some(last)) => Some(solver_state(order, last.step, last.time_s, &outcome.x, Some(prev), outcome.accel.as_deref(), None)),
        (None, Some(progress), Some(last)) => Some(solver_state(order, outcome.last_iteration, last.time_s, &outcome.x, None, None, Some(progress))),
        _ => start.cloned(),
    };
    let mut timings = solver.timings;
    timings.total_s = start_time.elapsed().as_secs_f64();
    let summary = Summary { steps: outcome.steps, velocity_cm_s, pressure_dyn_cm2, converged: outcome.converged, timings };
    Ok(Run { summary, state, cancelled_at_s: outcome.cancelled_at })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Outlet, Waveform};

    #[test]
    fn the_two_level_product_is_the_operator_applied_to_the_preconditioned_vector() {
        // GMRES takes A z from the preconditioner (A z_ilu + (A Z) e): it must be what the
        // operator gives for z, with older coarse factors (a reused preconditioner) too.
        let n = 60;
        let pattern = crate::sparse::chain_pattern(n, [0, 1, 2, 3]);
        let matrix = |shift: f64| crate::sparse::test_matrix(&pattern, 13, |_| 6.0 + shift);
        let (old, vals) = (matrix(0.0), matrix(0.7));
        let b: Vec<f64> = (0..n * B).map(|k| if k / B >= n - 4 && k % B < 3 { 0.2 } else { 0.0 }).collect();
        let rank_one = [(5.0, &b[..])];
        let dirichlet: Vec<bool> = (0..n).map(|i| i % 9 == 0).collect();
        let coarse = CoarseCorrection::new(&pattern, &old, &rank_one, aggregate(&pattern, 8), &dirichlet);
        let prolonged = coarse.prolonged_operator(&pattern, &vals, &rank_one);
        let ilu = BlockIlu::<f32>::factor(&pattern, &old, partitions(&pattern, 2)).unwrap();
        let apply_a = |x: &[f64], y: &mut [f64]| {
            spmv(&pattern, &vals, x, y);
            let q = dot(&b, x);
            y.iter_mut().zip(&b).for_each(|(yi, bi)| *yi += 5.0 * q * bi);
        };
        let m = TwoLevel { ilu: &ilu, coarse: Some((&coarse, &prolonged)), apply_a: &apply_a };
        let r: Vec<f64> = (0..n * B).map(|i| (i as f64 * 0.41).sin()).collect();
        let (mut z, mut az, mut z_alone, mut expected) = (vec![0.0; n * B], vec![0.0; n * B], vec![0.0; n * B], vec![0.0; n * B]);
        m.apply_with_product(&apply_a, &r, &mut z, &mut az);
        m.apply(&r, &mut z_alone);
        apply_a(&z, &mut expected);
        assert_eq!(z, z_alone, "apply and apply_with_product give the same z");
        assert!(az.iter().zip(&expected).all(|(x, y)| (x - y).abs() <= 1e-10 * (1.0 + y.abs())), "{az:?}\n{expected:?}");
    }

    #[test]
    fn factors_are_renewed_once_aging_has_cost_a_renewal() {
        let mut s = CaseSettings::new(1, Waveform::Ejection { period_s: 0.01, q_mean_ml_s: 1.0 }, vec![Outlet { face_id: 2, resistance_dyn_s_cm5: 1.0 }]);
        let mut use_ = FactorsUse::default();
        assert!(!use_.reusable(&s, true), "no factors yet");
        use_.record(false, Effort::Normal, 10);
        assert!(use_.reusable(&s, true) && !use_.reusable(&s, false), "steady solves always renew");
        // 1 + 2 + 3 + 4 = 10 iterations added above the fewest (10): still cheaper than a renewal.
        for it in [11, 12, 13, 14] {
            use_.record(true, Effort::Normal, it);
        }
        assert!(use_.reusable(&s, true), "{use_:?}");
        // An easier step lowers the reference; 9 -> 12 adds 3 more: 13 >= 12, renew.
        use_.record(true, Effort::Normal, 9);
        assert!(use_.reusable(&s, true), "{use_:?}");
        use_.record(true, Effort::Normal, 12);
        assert!(!use_.reusable(&s, true), "{use_:?}");
        use_.record(false, Effort::Normal, 10);
        s.preconditioner_max_age = 2;
        use_.record(true, Effort::Normal, 10);
        assert!(!use_.reusable(&s, true), "the age cap: {use_:?}");
        s.preconditioner_max_age = 50;
        use_.record(false, Effort::Normal, 10);
        use_.record(false, Effort::Strong, 40);
        assert!(!use_.reusable(&s, true), "after a Strong solve the Normal factors are renewed");
    }
}
