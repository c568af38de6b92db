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
        // --segmentations or --labelmap instead of --surface (PlanSettings::prepare).
        #[command(flatten)]
        pub prepare: PrepareSourceArgs,
        #[arg(long, value_parser = parse_bp)]
        pub bp: (f64, f64),
        #[arg(long)]
        pub hr: Option<f64>,
        #[arg(long, conflicts_with_all = ["pulsatile", "quick"])]
        pub steady: bool,
        #[arg(long, conflicts_with = "pulsatile")]
        pub quick: bool,
        #[arg(long)]
        pub pulsatile: bool,
        #[arg(long, default_value_t = PlanSettings::default().cycles, value_parser = at_least_one)]
        pub cycles: usize,
        #[arg(long, default_value_t = PlanSettings::default().edge_length_mm)]
        pub edge_length_mm: f64,
        #[arg(long, default_value_t = PlanSettings::default().extension_coarsening)]
        pub extension_coarsening: f64,
        #[arg(long, conflicts_with = "single_mesh")]
        pub mesh_study: bool,
        #[arg(long)]
        pub single_mesh: bool,
        #[arg(long)]
        pub elevated_flow: bool,
        #[arg(long, default_value_t = PlanSettings::default().cardiac_index)]
        pub cardiac_index: f64,
        #[arg(long)]
        pub prepare_remesh_edge_mm: Option<f64>,
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
