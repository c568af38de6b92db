//! The planning verdict in three states. The paper's criterion is the peak pressure
//! difference against 10 mmHg; a number is only called passing or failing when the run
//! that gave it can be trusted: otherwise the verdict is inconclusive, with its reasons
//! in plain words (an unconverged or stopped solve, cycles that have not settled, a
//! mesh study whose finer mesh changes dp, a design check that failed). `baffle simulate`
//! writes its run's doubts into summary.json (`doubts`), so the Slicer module shows the
//! same verdict without a second copy of these rules.

use crate::mesh_convergence::{grid_convergence, Convergence, Level};
use crate::run_summary::RunSummary;
use baffle_mesh::QualityReport;

/// The planning threshold of the peak pressure difference (mmHg): below it passes.
pub const DP_THRESHOLD_MMHG: f64 = 10.0;
/// Largest normalized RMS difference of the last two cycles' dp for a settled run.
pub const PERIODICITY_LIMIT: f64 = 1e-2;
/// Largest |inflow - outflow| / inflow over the reported cycle.
pub const MASS_IMBALANCE_LIMIT: f64 = 1e-2;
/// Largest grid convergence index of dp (on the finest mesh of a study) for a dp called
/// mesh-converged.
pub const MESH_GCI_LIMIT: f64 = 0.05;
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

/// Why one run's dp cannot be trusted, from its summary.json (empty: no doubt).
pub fn run_doubts(summary: &RunSummary) -> Vec<String> {
    let mut doubts = Vec::new();
    if summary.status != "completed" {
        doubts.push(format!("the CFD run {}{}", summary.status, summary.message.as_ref().map_or(String::new(), |m| format!(" ({m})"))));
    }
    let steady = summary.is_steady();
    if !summary.converged {
        doubts.push(if steady {
            "the steady solve did not reach its residual target (it stopped at the iteration cap): rerun with --quick (from rest to the first flow peak) or pulsatile".into()
        } else {
            "the solve did not converge".into()
        });
    }
    if summary.unconverged_nonlinear_steps > 0 {
        doubts.push(format!(
            "{} time steps stopped at the Picard iteration cap with the velocity still changing (time.nonlinear_iterations \"auto\"): use a smaller time step",
            summary.unconverged_nonlinear_steps
        ));
    }
    // A quick run ends at the first flow peak by design: no cycles to settle.
    let quick = summary.is_quick();
    if let Some(planned) = summary.steps_planned.filter(|&planned| !steady && summary.last_step < planned) {
        let end = if quick { "the first flow peak" } else { "its last cycle" };
        doubts.push(format!("the run stopped at time step {} of {planned}, before {end}", summary.last_step));
    }
    if !steady && !quick {
        match summary.periodicity_nrmsd {
            Some(p) if p > PERIODICITY_LIMIT => {
                doubts.push(format!("the last two cycles differ (periodicity NRMSD {p:.3} > {PERIODICITY_LIMIT}): run more cycles"))
            }
            Some(_) => {}
            None => doubts.push("the cycles' periodicity could not be measured (fewer than two complete cycles)".into()),
        }
    }
    if let Some(m) = summary.mass_imbalance.filter(|m| *m > MASS_IMBALANCE_LIMIT) {
        doubts.push(format!("inflow and outflow differ by {:.1} % (limit {:.0} %)", 100.0 * m, 100.0 * MASS_IMBALANCE_LIMIT));
    }
    doubts
}

/// A mesh study's doubt: the mesh can decide the verdict. The nominal dp and the finest
/// mesh's dp with its uncertainty band (the grid convergence index of the three levels,
/// `mesh_convergence`) must lie on one side of the threshold; a study that could not
/// estimate the band (a level without dp, equal values) is a doubt too.
pub fn mesh_study_doubt(nominal_dp_mmhg: f64, study: &Result<MeshStudy, String>) -> Option<String> {
    let study = match study {
        Ok(study) => study,
        Err(e) => return Some(format!("the mesh study could not estimate the discretization error ({e})")),
    };
    let (fine, band) = (study.fine_dp_mmhg, study.dp.band);
    let (low, high) = (nominal_dp_mmhg.min(fine - band), nominal_dp_mmhg.max(fine + band));
    (low < DP_THRESHOLD_MMHG && high >= DP_THRESHOLD_MMHG).then(|| {
        format!(
            "the mesh decides the verdict: dp is {nominal_dp_mmhg:.2} mmHg on the nominal mesh and {fine:.2} +- {band:.2} mmHg on the fine mesh \
({:.2} mm; grid convergence index {:.0} %), a range that contains the {DP_THRESHOLD_MMHG} mmHg threshold: refine the mesh",
            study.fine_edge_length_mm,
            100.0 * study.dp.gci_fine
        )
    })
}

/// A three-level mesh study of dp: the fine level and the grid convergence of dp.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshStudy {
    pub fine_edge_length_mm: f64,
    pub fine_dp_mmhg: f64,
    pub dp: Convergence,
}

impl MeshStudy {
    /// The study of three levels (any order); an error names a level without dp.
    pub fn of(levels: &[Level]) -> Result<MeshStudy, String> {
        let three: &[Level; 3] = levels.try_into().map_err(|_| format!("{} mesh levels, the study needs 3", levels.len()))?;
        if let Some(l) = three.iter().find(|l| !l.value.is_finite()) {
            return Err(format!("the {:.2} mm mesh gave no pressure difference", l.edge_length_mm));
        }
        let fine = three.iter().min_by(|a, b| a.h_mm().total_cmp(&b.h_mm())).copied().unwrap_or(three[0]);
        Ok(MeshStudy { fine_edge_length_mm: fine.edge_length_mm, fine_dp_mmhg: fine.value, dp: grid_convergence(three)? })
    }

    /// A warning beside the verdict when dp is not converged to [`MESH_GCI_LIMIT`] (the
    /// verdict may still stand: the band can lie clear of the threshold).
    pub fn warning(&self) -> Option<String> {
        (self.dp.gci_fine > MESH_GCI_LIMIT).then(|| format!("dp is not mesh-converged to {:.0} %: {}", 100.0 * MESH_GCI_LIMIT, self.text()))
    }

    /// The study in words: the fine dp with its band, the order, the extrapolation.
    pub fn text(&self) -> String {
        let c = &self.dp;
        let order = if c.asymptotic {
            format!("observed order {:.2}, extrapolated {:.2} mmHg", c.observed_order, c.extrapolated)
        } else {
            format!("no credible observed order ({:.2}{}): conservative band at order 2", c.observed_order, if c.oscillatory { ", the levels oscillate" } else { "" })
        };
        format!(
            "grid convergence index {:.1} % on the fine mesh ({:.2} mm: {:.2} +- {:.2} mmHg; {order})",
            100.0 * c.gci_fine,
            self.fine_edge_length_mm,
            self.fine_dp_mmhg,
            c.band
        )
    }
}

/// The design's check: every constrained section reaches the target area (the design
/// report's `min_constrained_final_area_mm2` and `target_area_mm2`).
pub fn design_doubt(smallest: f64, target: f64) -> Option<String> {
    (smallest < target).then(|| format!("a design check failed: the smallest constrained section is {smallest:.1} mm², below the target {target:.1} mm²"))
}

/// A warning on the mesh, shown beside the verdict (quality alone does not decide it).
pub fn mesh_warning(quality: &QualityReport) -> Option<String> {
    let sj = quality.min_scaled_jacobian;
    (sj < POOR_SCALED_JACOBIAN).then(|| {
        format!("the mesh has poorly shaped elements (smallest scaled Jacobian {sj:.3} < {POOR_SCALED_JACOBIAN}): check dp on a finer mesh (--mesh-study)")
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::run_summary::completed_run as run;

    fn steady(converged: bool) -> RunSummary {
        RunSummary { converged, mass_imbalance: Some(1e-6), ..run("steady") }
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
        let mut s = RunSummary { last_step: 2728, steps_planned: Some(2728), periodicity_nrmsd: Some(2.8e-7), ..run("transient") };
        assert!(run_doubts(&s).is_empty());
        s.last_step = 100;
        s.message = Some("step limit 100 reached".into());
        s.periodicity_nrmsd = None;
        let doubts = run_doubts(&s);
        assert!(doubts.iter().any(|d| d.contains("step 100 of 2728")) && doubts.iter().any(|d| d.contains("periodicity")), "{doubts:?}");
        s.last_step = 2728;
        s.periodicity_nrmsd = Some(0.05);
        assert!(run_doubts(&s)[0].contains("0.050 > 0.01"));
        s.periodicity_nrmsd = Some(1e-4);
        s.status = "stopped".into();
        assert!(run_doubts(&s)[0].starts_with("the CFD run stopped"));
    }

    #[test]
    fn steps_whose_picard_loop_hit_its_cap_make_the_run_inconclusive() {
        let mut s = run("quick");
        assert!(run_doubts(&s).is_empty());
        s.unconverged_nonlinear_steps = 3;
        let v = Verdict::of(1.47, run_doubts(&s));
        assert_eq!(v.key(), "inconclusive");
        assert!(v.text(1.47).contains("3 time steps stopped at the Picard iteration cap"), "{}", v.text(1.47));
    }

    #[test]
    fn a_quick_run_is_judged_at_its_first_peak_without_cycles() {
        let mut s = run("quick");
        assert!(run_doubts(&s).is_empty(), "{:?}", run_doubts(&s));
        assert_eq!(Verdict::of(1.47, run_doubts(&s)), Verdict::Passes);
        s.last_step = 60;
        s.status = "stopped".into();
        let doubts = run_doubts(&s);
        assert!(doubts.iter().any(|d| d.contains("step 60 of 109, before the first flow peak")), "{doubts:?}");
        assert!(!doubts.iter().any(|d| d.contains("periodicity")), "{doubts:?}");
    }

    #[test]
    fn a_poor_mesh_and_a_design_check_are_reported() {
        assert!(design_doubt(99.0, 100.0).unwrap().contains("below the target"));
        assert_eq!(design_doubt(100.5, 100.0), None);
        let quality = QualityReport {
            tetrahedra: 1000,
            points: 300,
            volume_mm3: 500.0,
            min_scaled_jacobian: 0.026,
            p1_scaled_jacobian: 0.2,
            mean_scaled_jacobian: 0.6,
            p99_aspect_ratio: 4.4,
            max_aspect_ratio: 9.0,
            p99_radius_ratio: 3.0,
            min_dihedral_deg: 5.0,
            max_dihedral_deg: 170.0,
            min_edge_length_mm: 0.3,
            mean_edge_length_mm: 1.0,
            max_edge_length_mm: 2.0,
        };
        assert!(mesh_warning(&quality).unwrap().contains("0.026"));
        assert_eq!(mesh_warning(&QualityReport { min_scaled_jacobian: 0.2, ..quality }), None);
    }

    /// Levels at 1.25, 0.95 and 0.75 mm (V = 1 mm³, N = h^-3) with dp = limit + c h^2.
    fn study(limit: f64, c: f64) -> Result<MeshStudy, String> {
        let levels = [1.25, 0.95, 0.75].map(|h: f64| Level { edge_length_mm: h, tetrahedra: 1, volume_mm3: h.powi(3), value: limit + c * h * h });
        MeshStudy::of(&levels)
    }

    #[test]
    fn the_mesh_makes_it_inconclusive_only_when_its_band_reaches_the_threshold() {
        // p3-like: 6.4 -> 5.3 mmHg, far below 10: not converged to 5 %, but the verdict stands.
        let clear = study(4.5, 1.2);
        assert_eq!(mesh_study_doubt(4.5 + 1.2 * 0.9025, &clear), None);
        let warning = clear.as_ref().unwrap().warning().unwrap();
        assert!(warning.contains("not mesh-converged") && warning.contains("observed order 2.00") && warning.contains("extrapolated 4.50"), "{warning}");
        // Converging towards the threshold: the fine band reaches 10 mmHg.
        let near = study(9.8, -2.0);
        let doubt = mesh_study_doubt(9.8 - 2.0 * 0.9025, &near).unwrap();
        assert!(doubt.contains("the mesh decides the verdict") && doubt.contains("10 mmHg"), "{doubt}");
        assert_eq!(Verdict::of(8.0, vec![doubt]).key(), "inconclusive");
        // A converged study raises neither.
        let converged = study(3.0, 0.01);
        assert_eq!(mesh_study_doubt(3.01, &converged), None);
        assert_eq!(converged.unwrap().warning(), None);
    }

    #[test]
    fn an_incomplete_mesh_study_is_a_doubt() {
        let mut levels = [1.25, 0.95, 0.75].map(|h: f64| Level { edge_length_mm: h, tetrahedra: 1, volume_mm3: h.powi(3), value: 2.0 + h });
        levels[2].value = f64::NAN;
        let doubt = mesh_study_doubt(2.95, &MeshStudy::of(&levels)).unwrap();
        assert!(doubt.contains("0.75 mm mesh gave no pressure difference"), "{doubt}");
        assert!(MeshStudy::of(&levels[..2]).unwrap_err().contains("2 mesh levels"));
    }
}
