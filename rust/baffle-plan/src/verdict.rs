//! The planning verdict in three states. The paper's criterion is the peak pressure
//! difference against 10 mmHg; a number is only called passing or failing when the run
//! that gave it can be trusted: otherwise the verdict is inconclusive, with its reasons
//! in plain words (an unconverged or stopped solve, cycles that have not settled, a
//! mesh study whose finer mesh changes dp, a design check that failed). `baffle simulate`
//! writes its run's doubts into summary.json (`doubts`), so the Slicer module shows the
//! same verdict without a second copy of these rules.

use serde_json::Value;

/// The planning threshold of the peak pressure difference (mmHg): below it passes.
pub const DP_THRESHOLD_MMHG: f64 = 10.0;
/// Largest normalized RMS difference of the last two cycles' dp for a settled run.
pub const PERIODICITY_LIMIT: f64 = 1e-2;
/// Largest |inflow - outflow| / inflow over the reported cycle.
pub const MASS_IMBALANCE_LIMIT: f64 = 1e-2;
/// Largest relative change of dp from the nominal to the fine mesh of a mesh study.
pub const MESH_DP_CHANGE_LIMIT: f64 = 0.05;
/// Smallest scaled Jacobian below which a mesh is flagged (not a reason by itself).
pub const POOR_SCALED_JACOBIAN: f64 = 0.1;

#[derive(Clone, Debug, PartialEq)]
pub enum Verdict {
    Passes,
    Fails,
    Inconclusive { reasons: Vec<String> },
}

impl Verdict {
    /// The verdict on `dp_mmhg` given the doubts about the run that produced it.
    pub fn of(dp_mmhg: f64, mut doubts: Vec<String>) -> Verdict {
        if !dp_mmhg.is_finite() {
            doubts.insert(0, "the run gave no pressure difference".into());
        }
        match (doubts.is_empty(), dp_mmhg < DP_THRESHOLD_MMHG) {
            (false, _) => Verdict::Inconclusive { reasons: doubts },
            (true, true) => Verdict::Passes,
            (true, false) => Verdict::Fails,
        }
    }

    /// "passes", "fails" or "inconclusive" (report.json, CSS class).
    pub fn key(&self) -> &'static str {
        match self {
            Verdict::Passes => "passes",
            Verdict::Fails => "fails",
            Verdict::Inconclusive { .. } => "inconclusive",
        }
    }

    /// The reasons joined into one sentence (None unless inconclusive).
    pub fn reason(&self) -> Option<String> {
        match self {
            Verdict::Inconclusive { reasons } => Some(reasons.join("; ")),
            _ => None,
        }
    }

    /// The verdict line of the report and of the command line.
    pub fn text(&self, dp_mmhg: f64) -> String {
        let dp = format!("peak pressure difference {dp_mmhg:.2} mmHg");
        match self {
            Verdict::Passes => format!("PASSES: {dp} is below the {DP_THRESHOLD_MMHG} mmHg planning threshold"),
            Verdict::Fails => format!("FAILS: {dp} is not below the {DP_THRESHOLD_MMHG} mmHg planning threshold"),
            Verdict::Inconclusive { reasons } => {
                format!("INCONCLUSIVE: {dp} cannot be judged against the {DP_THRESHOLD_MMHG} mmHg threshold because {}", reasons.join("; "))
            }
        }
    }
}

fn number(doc: &Value, key: &str) -> Option<f64> {
    doc.pointer(key).and_then(Value::as_f64).filter(|v| v.is_finite())
}

/// Why one run's dp cannot be trusted, from its summary.json (empty: no doubt).
pub fn run_doubts(summary: &Value) -> Vec<String> {
    let mut doubts = Vec::new();
    let status = summary["status"].as_str().unwrap_or("unknown");
    let message = summary["message"].as_str();
    if status != "completed" {
        doubts.push(format!("the CFD run {status}{}", message.map_or(String::new(), |m| format!(" ({m})"))));
    }
    let steady = summary["mode"] == "steady";
    if summary["converged"] != true {
        doubts.push(if steady {
            "the steady solve did not reach its residual target (it stopped at the iteration cap): rerun with --quick (from rest to the first flow peak) or pulsatile".into()
        } else {
            "the solve did not converge".into()
        });
    }
    // A quick run ends at the first flow peak by design: no cycles to settle.
    let quick = summary["mode"] == crate::case::QUICK_MODE;
    if !steady {
        if let (Some(done), Some(planned)) = (number(summary, "/last_step"), number(summary, "/steps_planned")) {
            if done < planned {
                let end = if quick { "the first flow peak" } else { "its last cycle" };
                doubts.push(format!("the run stopped at time step {done:.0} of {planned:.0}, before {end}"));
            }
        }
    }
    if !steady && !quick {
        match number(summary, "/periodicity_nrmsd") {
            Some(p) if p > PERIODICITY_LIMIT => {
                doubts.push(format!("the last two cycles differ (periodicity NRMSD {p:.3} > {PERIODICITY_LIMIT}): run more cycles"))
            }
            Some(_) => {}
            None => doubts.push("the cycles' periodicity could not be measured (fewer than two complete cycles)".into()),
        }
    }
    if let Some(m) = number(summary, "/mass_imbalance").filter(|m| *m > MASS_IMBALANCE_LIMIT) {
        doubts.push(format!("inflow and outflow differ by {:.1} % (limit {:.0} %)", 100.0 * m, 100.0 * MASS_IMBALANCE_LIMIT));
    }
    doubts
}

/// A mesh study's doubt: dp changes by more than [`MESH_DP_CHANGE_LIMIT`] from the
/// nominal to the fine mesh (or the fine run gave none).
pub fn mesh_study_doubt(nominal_dp_mmhg: f64, fine: Option<(f64, f64)>) -> Option<String> {
    let (edge_mm, fine_dp) = fine?;
    if !fine_dp.is_finite() {
        return Some(format!("the mesh study's fine mesh ({edge_mm:.2} mm) gave no pressure difference"));
    }
    let change = (fine_dp - nominal_dp_mmhg).abs() / fine_dp.abs().max(1e-9);
    (change > MESH_DP_CHANGE_LIMIT).then(|| {
        format!(
            "the mesh is not converged: dp is {fine_dp:.2} mmHg on the fine mesh ({edge_mm:.2} mm) against {nominal_dp_mmhg:.2} mmHg, a {:.0} % change (limit {:.0} %)",
            100.0 * change,
            100.0 * MESH_DP_CHANGE_LIMIT
        )
    })
}

/// The design's check: every constrained section reaches the target area.
pub fn design_doubt(design: &Value) -> Option<String> {
    let (smallest, target) = (number(design, "/min_constrained_final_area_mm2")?, number(design, "/target_area_mm2")?);
    (smallest < target).then(|| format!("a design check failed: the smallest constrained section is {smallest:.1} mm², below the target {target:.1} mm²"))
}

/// A warning on the mesh, shown beside the verdict (quality alone does not decide it).
pub fn mesh_warning(quality: &Value) -> Option<String> {
    let sj = number(quality, "/min_scaled_jacobian")?;
    (sj < POOR_SCALED_JACOBIAN).then(|| {
        format!("the mesh has poorly shaped elements (smallest scaled Jacobian {sj:.3} < {POOR_SCALED_JACOBIAN}): check dp on a finer mesh (--mesh-study)")
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn steady(converged: bool) -> Value {
        json!({ "status": "completed", "mode": "steady", "converged": converged, "mass_imbalance": 1e-6, "message": null })
    }

    #[test]
    fn an_unconverged_solve_is_inconclusive_whatever_its_dp() {
        for dp in [1.72, 25.0] {
            let v = Verdict::of(dp, run_doubts(&steady(false)));
            assert_eq!(v.key(), "inconclusive", "{dp}");
            let text = v.text(dp);
            assert!(text.starts_with("INCONCLUSIVE") && text.contains("residual target") && !text.contains("PASSES"), "{text}");
        }
    }

    #[test]
    fn a_trusted_run_passes_or_fails_at_the_threshold() {
        assert_eq!(Verdict::of(9.99, run_doubts(&steady(true))), Verdict::Passes);
        assert_eq!(Verdict::of(10.0, run_doubts(&steady(true))), Verdict::Fails);
        assert!(Verdict::of(1.0, vec![]).text(1.0).starts_with("PASSES: peak pressure difference 1.00 mmHg"));
        assert_eq!(Verdict::of(f64::NAN, vec![]).key(), "inconclusive");
    }

    #[test]
    fn a_pulsatile_run_must_finish_its_cycles_and_settle() {
        let mut s = json!({ "status": "completed", "mode": "transient", "converged": true, "last_step": 2728, "steps_planned": 2728,
            "periodicity_nrmsd": 2.8e-7, "mass_imbalance": 1e-5, "message": null });
        assert!(run_doubts(&s).is_empty());
        s["last_step"] = json!(100);
        s["message"] = json!("step limit 100 reached");
        s["periodicity_nrmsd"] = Value::Null;
        let doubts = run_doubts(&s);
        assert!(doubts.iter().any(|d| d.contains("step 100 of 2728")) && doubts.iter().any(|d| d.contains("periodicity")), "{doubts:?}");
        s["last_step"] = json!(2728);
        s["periodicity_nrmsd"] = json!(0.05);
        assert!(run_doubts(&s)[0].contains("0.050 > 0.01"));
        s["periodicity_nrmsd"] = json!(1e-4);
        s["status"] = json!("stopped");
        assert!(run_doubts(&s)[0].starts_with("the CFD run stopped"));
    }

    #[test]
    fn a_quick_run_is_judged_at_its_first_peak_without_cycles() {
        let mut s = json!({ "status": "completed", "mode": "quick", "converged": true, "last_step": 109, "steps_planned": 109,
            "periodicity_nrmsd": null, "mass_imbalance": 1e-5, "message": null });
        assert!(run_doubts(&s).is_empty(), "{:?}", run_doubts(&s));
        assert_eq!(Verdict::of(1.47, run_doubts(&s)), Verdict::Passes);
        s["last_step"] = json!(60);
        s["status"] = json!("stopped");
        let doubts = run_doubts(&s);
        assert!(doubts.iter().any(|d| d.contains("step 60 of 109, before the first flow peak")), "{doubts:?}");
        assert!(!doubts.iter().any(|d| d.contains("periodicity")), "{doubts:?}");
    }

    #[test]
    fn a_mesh_study_and_a_design_check_can_make_it_inconclusive() {
        assert_eq!(mesh_study_doubt(7.0, None), None);
        assert_eq!(mesh_study_doubt(7.0, Some((0.75, 7.2))), None);
        assert!(mesh_study_doubt(7.0, Some((0.75, 8.0))).unwrap().contains("not converged"));
        let design = json!({ "min_constrained_final_area_mm2": 99.0, "target_area_mm2": 100.0 });
        assert!(design_doubt(&design).unwrap().contains("below the target"));
        assert_eq!(design_doubt(&json!({ "min_constrained_final_area_mm2": 100.5, "target_area_mm2": 100.0 })), None);
        assert!(mesh_warning(&json!({ "min_scaled_jacobian": 0.026 })).unwrap().contains("0.026"));
    }
}
