//! `baffle prepare`'s arguments and the blood pools' source (also `plan`'s, `extend`'s and `sweep`'s).

use baffle_plan::prepare_cmd::{PrepareSettings, PrepareSource};
use clap::Args;
use std::path::PathBuf;

super::settings_args! {
    /// Where the blood pools come from: per-structure surfaces or a label map (also
    /// `baffle plan`'s arguments for its prepare stage).
    #[derive(Args, Clone, Debug)]
    pub struct PrepareSourceArgs into PrepareSource {
        #[arg(long, conflicts_with = "labelmap")]
        pub segmentations: Option<PathBuf>,
        #[arg(long)]
        pub labelmap: Option<PathBuf>,
        #[arg(long, default_value_t = PrepareSource::default().lv_label)]
        pub lv_label: i32,
        #[arg(long, default_value_t = PrepareSource::default().rv_label)]
        pub rv_label: i32,
        #[arg(long, default_value_t = PrepareSource::default().aorta_label)]
        pub aorta_label: i32,
        #[arg(long, default_value_t = PrepareSource::default().pulmonary_label)]
        pub pulmonary_label: i32,
        #[arg(long)]
        pub no_median: bool,
    }
}

super::settings_args! {
    #[derive(Args)]
    #[command(after_help = "Example (LV.vtp, RV.vtp and aorta.vtp exported from Slicer's segments):\n  \
        baffle prepare --segmentations ../shared/data/p2/segmentations --out out/p2/capped_ventricle.vtp\n\
    Example (a label map, the aorta labelled 8):\n  \
        baffle prepare --labelmap heart.nii.gz --aorta-label 8 --out out/capped_ventricle.vtp\n\
    Then: baffle design --surface out/p2/capped_ventricle.vtp --points P.mrk.json --bsa 0.37 --out out/p2/design")]
    pub struct PrepareArgs into PrepareSettings {
        #[command(flatten)]
        pub source: PrepareSourceArgs,
        #[arg(long)]
        pub out: PathBuf,
        #[arg(long, default_value_t = PrepareSettings::default().voxel_mm)]
        pub voxel_mm: f64,
        #[arg(long, default_value_t = PrepareSettings::default().crop_margin_mm)]
        pub crop_margin_mm: f64,
        #[arg(long, default_value_t = PrepareSettings::default().closing_radius_mm)]
        pub closing_radius_mm: f64,
        #[arg(long, default_value_t = PrepareSettings::default().remesh_edge_mm)]
        pub remesh_edge_mm: f64,
        #[arg(long)]
        pub no_remesh: bool,
        #[arg(long, default_value_t = PrepareSettings::default().smoothing_iterations)]
        pub smoothing_iterations: usize,
    }
}
