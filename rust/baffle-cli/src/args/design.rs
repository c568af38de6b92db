//! `baffle design`'s arguments: the design options and the target.

use baffle_plan::design_cmd::{DesignSettings, FaceLabels, Frame as PlanFrame, TargetSettings, Vec3};
use clap::Args;
use std::path::PathBuf;

// Required-ness of --surface/--points is checked at run time (read_inputs), so that
// `baffle plan` can offer other sources of the surface.
super::settings_args! {
    #[derive(Args, Clone)]
    pub struct DesignArgs into DesignSettings {
        #[arg(long)]
        pub surface: Option<PathBuf>,
        #[arg(long)]
        pub points: Option<PathBuf>,
        #[arg(long, conflicts_with_all = ["surface", "points"])]
        pub phantom: bool,
        #[arg(long)]
        pub out: PathBuf,
        #[command(flatten)]
        pub target: TargetArgs,
        #[arg(long, value_enum, default_value_t = Frame::from(DesignSettings::default().surface_frame))]
        pub surface_frame: Frame,
        #[arg(long, default_value_t = DesignSettings::default().remesh_edge_mm)]
        pub remesh_edge_mm: f64,
        #[arg(long)]
        pub no_remesh: bool,
        #[arg(long, default_value_t = DesignSettings::default().baffle_edge_mm)]
        pub baffle_edge_mm: f64,
        #[arg(long, default_value_t = DesignSettings::default().seam_samples)]
        pub seam_samples: usize,
        #[arg(long, default_value_t = DesignSettings::default().centerline_spacing_mm)]
        pub centerline_spacing_mm: f64,
        #[arg(long, default_value_t = DesignSettings::default().control_points)]
        pub control_points: usize,
        #[arg(long, default_value_t = DesignSettings::default().max_point_distance_mm)]
        pub max_point_distance_mm: f64,
        // --wall-label, --baffle-label, --vsd-label, --aortic-label.
        #[command(flatten)]
        pub labels: FaceLabelArgs,
        #[arg(long, value_parser = parse_point, requires = "aortic_cap_point", allow_hyphen_values = true)]
        pub vsd_cap_point: Option<Vec3>,
        #[arg(long, value_parser = parse_point, requires = "vsd_cap_point", allow_hyphen_values = true)]
        pub aortic_cap_point: Option<Vec3>,
        #[arg(long)]
        pub reference_baffle: Option<PathBuf>,
        #[arg(long, default_value_t = DesignSettings::default().reference_scale)]
        pub reference_scale: f64,
        #[arg(long)]
        pub pulmonary: Option<PathBuf>,
        #[arg(long)]
        pub flow_sections: bool,
        #[arg(long, allow_hyphen_values = true)]
        pub peak_flow_ml_s: Option<f64>,
        #[arg(long)]
        pub progress_tags: bool,
    }
}

/// The ModelFaceIDs `baffle design` reads and gives (also `baffle extend`'s, which
/// words their help for the designed domain it reads).
#[derive(Args, Clone)]
pub struct FaceLabelArgs {
    /// ModelFaceID of the RV wall.
    #[arg(long, default_value_t = DesignSettings::default().labels.wall)]
    pub wall_label: i32,
    /// ModelFaceID given to the baffle.
    #[arg(long, default_value_t = DesignSettings::default().labels.baffle)]
    pub baffle_label: i32,
    /// ModelFaceID of the VSD cap.
    #[arg(long, default_value_t = DesignSettings::default().labels.vsd_cap)]
    pub vsd_label: i32,
    /// ModelFaceID of the aortic-annulus cap.
    #[arg(long, default_value_t = DesignSettings::default().labels.aortic_cap)]
    pub aortic_label: i32,
}

impl From<FaceLabelArgs> for FaceLabels {
    fn from(a: FaceLabelArgs) -> Self {
        FaceLabels { wall: a.wall_label, baffle: a.baffle_label, vsd_cap: a.vsd_label, aortic_cap: a.aortic_label }
    }
}

super::settings_args! {
    #[derive(Args, Clone)]
    pub struct TargetArgs into TargetSettings {
        #[arg(long, group = "target_kind")]
        pub target_area_mm2: Option<f64>,
        #[arg(long, group = "target_kind")]
        pub annulus_diameter_mm: Option<f64>,
        #[arg(long, group = "target_kind")]
        pub bsa: Option<f64>,
        #[arg(long, requires = "weight_kg", group = "target_kind")]
        pub height_cm: Option<f64>,
        #[arg(long, requires = "height_cm")]
        pub weight_kg: Option<f64>,
        #[arg(long, default_value_t = TargetSettings::default().z_score, allow_negative_numbers = true, conflicts_with_all = ["target_area_mm2", "annulus_diameter_mm"])]
        pub z_score: f64,
    }
}

super::value_enum! {
    /// The frame a surface's coordinates are in (the points are converted into it).
    Frame mirrors PlanFrame { Lps, Ras }
}

/// A point x,y,z (mm) of --vsd-cap-point and --aortic-cap-point.
fn parse_point(text: &str) -> Result<Vec3, String> {
    let values: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse::<f64>().map_err(|_| format!("'{v}' is not a number")))
        .collect::<Result<_, _>>()?;
    match values[..] {
        [x, y, z] if values.iter().all(|v| v.is_finite()) => Ok(Vec3::new(x, y, z)),
        _ => Err(format!("expected x,y,z (three finite numbers), got '{text}'")),
    }
}
