//! `baffle plan`'s arguments.

use super::at_least_one;
use super::design::DesignArgs;
use super::prepare::PrepareSourceArgs;
use baffle_plan::plan_stages::PlanSettings;
use clap::Args;

super::settings_args! {
    #[derive(Args)]
    #[command(
        mut_arg("surface", |a| a.help("Capped ventricle (.vtp, .vtk or .stl, mm, ModelFaceID); or give --segmentations DIR, --labelmap FILE or --phantom instead")),
        after_help = "Examples:\n  \
        # quick estimate (from rest to the first flow peak) from Slicer's segment surfaces (LV, RV, aorta), CFD on the extended domain\n  \
        baffle plan --segmentations ../shared/data/p2/segmentations --points ../shared/data/p2/design_input/suture_points.mrk.json \\\n      \
        --bsa 0.37 --bp 107/78 --hr 133 --quick --edge-length-mm 1.25 --out out/plan-p2\n  \
        # the paper's pulsatile run with its mesh study, from a capped ventricle\n  \
        baffle plan --surface ../shared/data/p2/design_input/capped_ventricle.vtp --points ../shared/data/p2/design_input/suture_points.mrk.json \\\n      \
        --bsa 0.37 --bp 107/78 --hr 133 --pulsatile --out out/plan-p2-full\n  \
        # the built-in synthetic phantom\n  \
        baffle plan --phantom --bp 107/78 --quick --out out/plan-phantom\n\
    Ends with report.json and report.html in --out; the last line printed is the verdict: PASSES, FAILS or INCONCLUSIVE (with its reason)."
    )]
    pub struct PlanArgs into PlanSettings {
        #[command(flatten)]
        pub design: DesignArgs,
        /// Build the capped ventricle from segmentations or a label map first (a `prepare`
        /// stage), instead of --surface; the CFD then runs on the extended domain (an
        /// `extend` stage after the design: mid-LV inflow cap 20, STJ outflow cap 21, dp
        /// between the VSD and aortic caps as interior planes).
        #[command(flatten)]
        pub prepare: PrepareSourceArgs,
        /// Blood pressure SBP/DBP (mmHg), e.g. 107/78: the outlet resistance R = MAP / Q_mean.
        #[arg(long, value_parser = parse_bp)]
        pub bp: (f64, f64),
        /// Heart rate (beats/min); default: the built-in period of 0.682 s.
        #[arg(long)]
        pub hr: Option<f64>,
        /// Steady run with the inflow held at Q_peak. It may not converge where the peak flow
        /// is not steady (p2's and p3's extended domains); the verdict is then INCONCLUSIVE.
        #[arg(long, conflicts_with_all = ["pulsatile", "quick"])]
        pub steady: bool,
        /// Quick estimate: a pulsatile run from rest up to the first flow peak (a twentieth of
        /// 4 cycles' steps; on p2 and p3 within 0.6 % of the fourth cycle's peak dp).
        #[arg(long, conflicts_with = "pulsatile")]
        pub quick: bool,
        /// Pulsatile run over --cycles cardiac cycles (the default, as the paper).
        #[arg(long)]
        pub pulsatile: bool,
        /// Cardiac cycles of a pulsatile run (the last one is reported).
        #[arg(long, default_value_t = PlanSettings::default().cycles, value_parser = at_least_one)]
        pub cycles: usize,
        /// Largest tetrahedron edge of the nominal mesh (mm); the paper used 0.95.
        #[arg(long, default_value_t = PlanSettings::default().edge_length_mm)]
        pub edge_length_mm: f64,
        /// On an extended domain, coarsen the LV and aortic parts away from the VSD and
        /// aortic caps up to this many times each level's edge (within one cap diameter of
        /// the caps the edge stays); 1: the whole domain at the edge.
        #[arg(long, default_value_t = PlanSettings::default().extension_coarsening)]
        pub extension_coarsening: f64,
        /// The default: also mesh and simulate at the paper's coarse and fine sizes (1.25 /
        /// 0.75 mm, scaled by --edge-length-mm / 0.95), the boundary refined with the volume
        /// (on an extended domain every level is extended again from the designed domain
        /// remeshed at its size); the report gives dp's grid convergence index and judges the
        /// verdict with its band. No single edge length converges dp on every patient (the
        /// dataset's p3 needs about 0.45 mm for 5 %: docs/validation.md).
        #[arg(long, conflicts_with = "single_mesh")]
        pub mesh_study: bool,
        /// The nominal mesh only (about a third of the study's time): the report then cannot
        /// say whether dp is mesh-converged, and warns so.
        #[arg(long)]
        pub single_mesh: bool,
        /// Also simulate the nominal mesh at cardiac index 4.22 L/min/m2.
        #[arg(long)]
        pub elevated_flow: bool,
        /// Cardiac index of the nominal runs (L/min/m2): the mean flow is BSA x cardiac index.
        #[arg(long, default_value_t = PlanSettings::default().cardiac_index)]
        pub cardiac_index: f64,
        /// Target edge of the prepare stage's final isotropic remesh (mm; `baffle prepare
        /// --remesh-edge-mm`, default 0.5). The design remeshes the kept wall at --remesh-edge-mm.
        #[arg(long)]
        pub prepare_remesh_edge_mm: Option<f64>,
        /// How the report names the patient (default: the paper's patient id when the input
        /// lies in one of its patients' folders).
        #[arg(long)]
        pub patient_label: Option<String>,
    }
}

/// --bp: SBP/DBP in mmHg.
pub fn parse_bp(text: &str) -> Result<(f64, f64), String> {
    let parts: Vec<&str> = text.split('/').collect();
    let numbers: Vec<f64> = parts.iter().filter_map(|p| p.trim().parse::<f64>().ok()).filter(|v| v.is_finite()).collect();
    match numbers[..] {
        [sbp, dbp] if parts.len() == 2 && dbp > 0.0 && sbp > dbp => Ok((sbp, dbp)),
        _ => Err(format!("expected SBP/DBP in mmHg with SBP > DBP > 0 (e.g. 107/78), got '{text}'")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blood_pressure_is_sbp_over_dbp() {
        assert_eq!(parse_bp("107/78").unwrap(), (107.0, 78.0));
        for bad in ["78/107", "107", "107/78/1", "a/b", "107/0"] {
            assert!(parse_bp(bad).unwrap_err().contains(bad), "{bad}");
        }
    }
}
