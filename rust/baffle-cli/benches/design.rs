//! Benchmark of the whole design (release): median wall time per case and per step,
//! over repeated runs, on the phantom and (when the data is present) p1, p2 and p3 with
//! the paper's BSA. `cargo bench -p baffle-cli --bench design` (15 runs per case);
//! `-- --smoke` runs each case once, as CI does, to keep the benchmark working.

use baffle_core::reference_data::{design_cases, DesignCase};
use baffle_core::{design, DesignOptions, DesignReport};

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
    for case in cases() {
        let reports: Vec<DesignReport> = (0..runs)
            .map(|_| {
                design(&case.surface, &case.points, &case.target, &options, &mut |_, _| true)
                    .unwrap_or_else(|e| panic!("{}: {e}", case.name))
                    .report
            })
            .collect();
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
}
