//! `baffle prepare`'s arguments and the blood pools' source (also `plan`'s, `extend`'s and `sweep`'s).

use baffle_plan::prepare_cmd::{PrepareSettings, PrepareSource};
use clap::Args;
use std::path::PathBuf;

super::settings_args! {
    /// Where the blood pools come from: per-structure surfaces or a label map (also
    /// `baffle plan`'s arguments for its prepare stage).
    #[derive(Args, Clone, Debug)]
    pub struct PrepareSourceArgs into PrepareSource {
        /// Folder of closed per-structure surfaces in mm: LV, RV and aorta (.vtp, .vtk or .stl).
        #[arg(long, conflicts_with = "labelmap")]
        pub segmentations: Option<PathBuf>,
        /// Multi-label label map (.nrrd, .nii, .nii.gz); labels LV 1, RV 2, LA 3, RA 4,
        /// myo 5, aorta 6, PA 7 unless remapped. Surfaces are made in LPS mm.
        #[arg(long)]
        pub labelmap: Option<PathBuf>,
        /// Label value of the LV blood pool in --labelmap.
        #[arg(long, default_value_t = PrepareSource::default().lv_label)]
        pub lv_label: i32,
        /// Label value of the RV blood pool in --labelmap.
        #[arg(long, default_value_t = PrepareSource::default().rv_label)]
        pub rv_label: i32,
        /// Label value of the aorta in --labelmap.
        #[arg(long, default_value_t = PrepareSource::default().aorta_label)]
        pub aorta_label: i32,
        /// Label value of the pulmonary artery in --labelmap: its surface is written beside
        /// the capped ventricle (<stem>-pulmonary.vtp) and ends the RV outflow path. A label
        /// map without it still prepares; the RV outflow is then not measured.
        #[arg(long, default_value_t = PrepareSource::default().pulmonary_label)]
        pub pulmonary_label: i32,
        /// Skip the 3x3x3 median filter of each --labelmap label mask.
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
        /// Output capped ventricle (.vtp): ModelFaceID 2 RV wall, 11 VSD cap, 16 aortic cap.
        /// A report (<stem>-report.json) is written beside it.
        #[arg(long)]
        pub out: PathBuf,
        /// Voxel edge of the union grid (mm).
        #[arg(long, default_value_t = PrepareSettings::default().voxel_mm)]
        pub voxel_mm: f64,
        /// Margin of the union grid around the RV (mm); the LV and aorta beyond it are cut off.
        #[arg(long, default_value_t = PrepareSettings::default().crop_margin_mm)]
        pub crop_margin_mm: f64,
        /// Radius of the morphological closing of the union mask (mm).
        #[arg(long, default_value_t = PrepareSettings::default().closing_radius_mm)]
        pub closing_radius_mm: f64,
        /// Target edge of the final isotropic remesh (mm).
        #[arg(long, default_value_t = PrepareSettings::default().remesh_edge_mm)]
        pub remesh_edge_mm: f64,
        /// Keep the contour's triangles (no final remesh).
        #[arg(long)]
        pub no_remesh: bool,
        /// Taubin smoothing iterations of the union surface.
        #[arg(long, default_value_t = PrepareSettings::default().smoothing_iterations)]
        pub smoothing_iterations: usize,
    }
}
