//! Benchmark of the whole design (release): median wall time per case and per step,
//! over repeated runs, on the phantom and (when the data is present) p1, p2 and p3 with
//! the paper's BSA. `cargo bench -p baffle-cli --bench design` (15 runs per case);
//! `-- --smoke` runs each case once, as CI does, to keep the benchmark working.
//! Then what the reduced-order dp estimate adds to a design (`baffle design
//! --peak-flow-ml-s`, the plan, the C ABI, Python and the Slicer module run it on the
//! designed domain): its median over the same runs, at the paper's peak flow for the
//! case's BSA (CI 3.48).

use baffle_core::analyses::hemodynamics_estimate::{peak_flow_ml_s, Blood, EstimateOutcome};
use baffle_test_support::reference_data::{design_cases, DesignCase};
use baffle_core::{design, DesignOptions, DesignReport, TargetArea};

fn cases() -> Vec<DesignCase> {
    let cases = design_cases();
    if cases.len() == 1 {
        println!("note: benchmarking the phantom only");
    }
    cases
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

fn main() {
    let smoke = std::env::args().any(|a| a == "--smoke");
    let runs = if smoke { 1 } else { 15 };
    let options = DesignOptions::default();
    println!("design benchmark: {runs} run(s) per case, medians in ms");
    let mut estimates = Vec::new();
    for case in cases() {
        let results: Vec<_> = (0..runs)
            .map(|_| design(&case.surface, &case.points, &case.target, &options, &mut |_, _| true).unwrap_or_else(|e| panic!("{}: {e}", case.name)))
            .collect();
        estimates.push((case.name.clone(), estimate_ms(&case, &results[0].domain, &options, runs)));
        let reports: Vec<DesignReport> = results.into_iter().map(|r| r.report).collect();
        let step = |f: fn(&DesignReport) -> f64| median(reports.iter().map(f).collect());
        println!(
            "{:8} total {:7.1} | validate {:5.1} seam {:5.1} partition {:5.1} remesh {:5.1} patch {:5.1} centerline {:4.1} sections {:5.1} amplitudes+envelope+surface {:5.1} checks {:5.1}  (min {:.1}, max {:.1})",
            case.name,
            step(|r| r.timings.total_ms),
            step(|r| r.timings.validate_ms),
            step(|r| r.timings.seam_ms),
            step(|r| r.timings.partition_ms),
            step(|r| r.timings.remesh_ms),
            step(|r| r.timings.patch_ms),
            step(|r| r.timings.centerline_ms),
            step(|r| r.timings.sections_ms),
            step(|r| r.timings.amplitudes_envelope_surface_ms),
            step(|r| r.timings.checks_ms),
            reports.iter().map(|r| r.timings.total_ms).fold(f64::INFINITY, f64::min),
            reports.iter().map(|r| r.timings.total_ms).fold(0.0, f64::max),
        );
    }
    for (name, (times, dp_mmhg)) in estimates {
        let (lo, hi) = (times.iter().copied().fold(f64::INFINITY, f64::min), times.iter().copied().fold(0.0, f64::max));
        println!("{name:8} estimate {:7.1} (min {lo:.1}, max {hi:.1}): dp estimate {dp_mmhg:.2} mmHg", median(times));
    }
}

/// Wall times (ms) of the estimate on `domain`, `runs` times, and its dp (mmHg).
fn estimate_ms(case: &DesignCase, domain: &baffle_core::TriMesh, options: &DesignOptions, runs: usize) -> (Vec<f64>, f64) {
    let &TargetArea::Bsa { bsa_m2, .. } = &case.target else { panic!("{}: the bench's cases are given by BSA", case.name) };
    let q = peak_flow_ml_s(bsa_m2, 3.48).unwrap_or_else(|e| panic!("{}: {e}", case.name));
    let mut dp_mmhg = f64::NAN;
    let times = (0..runs)
        .map(|_| match EstimateOutcome::for_domain(domain, options.labels, Some(q), Blood::default()) {
            EstimateOutcome::Estimated(e) => {
                dp_mmhg = e.dp_estimate_mmhg;
                e.wall_time_ms
            }
            EstimateOutcome::Absent { absent_because } => panic!("{}: no estimate: {absent_because}", case.name),
        })
        .collect();
    (times, dp_mmhg)
}
