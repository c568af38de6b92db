//! `baffle design`'s arguments: the design options and the target.

use baffle_plan::design_cmd::{DesignSettings, FaceLabels, Frame as PlanFrame, TargetSettings, Vec3};
use clap::Args;
use std::path::PathBuf;

// Required-ness of --surface/--points is checked at run time (read_inputs), so that
// `baffle plan` can offer other sources of the surface.
super::settings_args! {
    #[derive(Args, Clone)]
    pub struct DesignArgs into DesignSettings {
        /// Closed, labelled ventricle surface (.vtp, .vtk or .stl), in mm (required unless --phantom).
        #[arg(long)]
        pub surface: Option<PathBuf>,
        /// Suture points: Slicer markups (.mrk.json), .fcsv, CSV (x,y,z per line) or JSON (required unless --phantom).
        #[arg(long)]
        pub points: Option<PathBuf>,
        /// Use the built-in synthetic phantom as surface and points (BSA 0.37 m2 unless given).
        #[arg(long, conflicts_with_all = ["surface", "points"])]
        pub phantom: bool,
        /// Output directory.
        #[arg(long)]
        pub out: PathBuf,
        #[command(flatten)]
        pub target: TargetArgs,
        /// Frame of the surface file; suture points are converted into it. Slicer writes
        /// models in LPS.
        #[arg(long, value_enum, default_value_t = Frame::from(DesignSettings::default().surface_frame))]
        pub surface_frame: Frame,
        /// Target edge length of the isotropic remeshing of the kept wall (mm).
        #[arg(long, default_value_t = DesignSettings::default().remesh_edge_mm)]
        pub remesh_edge_mm: f64,
        /// Keep the input's wall triangles (no isotropic remeshing).
        #[arg(long)]
        pub no_remesh: bool,
        /// Target edge length of the baffle (mm).
        #[arg(long, default_value_t = DesignSettings::default().baffle_edge_mm)]
        pub baffle_edge_mm: f64,
        /// Points the seam spline is resampled at.
        #[arg(long, default_value_t = DesignSettings::default().seam_samples)]
        pub seam_samples: usize,
        /// Centerline section spacing (mm).
        #[arg(long, default_value_t = DesignSettings::default().centerline_spacing_mm)]
        pub centerline_spacing_mm: f64,
        /// Interior TPS control points of the initial patch.
        #[arg(long, default_value_t = DesignSettings::default().control_points)]
        pub control_points: usize,
        /// Largest distance of a suture point from the surface (mm).
        #[arg(long, default_value_t = DesignSettings::default().max_point_distance_mm)]
        pub max_point_distance_mm: f64,
        // --wall-label, --baffle-label, --vsd-label, --aortic-label.
        #[command(flatten)]
        pub labels: FaceLabelArgs,
        /// A point (x,y,z in the surface's frame, mm) on the VSD cap: labels the planar
        /// cap around it. Needed for surfaces without ModelFaceID (.stl, plain .vtk).
        #[arg(long, value_parser = parse_point, requires = "aortic_cap_point", allow_hyphen_values = true)]
        pub vsd_cap_point: Option<Vec3>,
        /// A point on the aortic-annulus cap (see --vsd-cap-point).
        #[arg(long, value_parser = parse_point, requires = "vsd_cap_point", allow_hyphen_values = true)]
        pub aortic_cap_point: Option<Vec3>,
        /// A reference baffle to compare with (area ratio, symmetric surface distance),
        /// written to reference_comparison.json; e.g. the paper's published_baffle.vtp.
        #[arg(long)]
        pub reference_baffle: Option<PathBuf>,
        /// Scale of the reference's coordinates to mm (10 for the published files, in cm).
        #[arg(long, default_value_t = DesignSettings::default().reference_scale)]
        pub reference_scale: f64,
        /// Closed surface of the pulmonary artery (mm, the surface's frame), e.g. a
        /// segmentation's pulmonary.vtp: measures the smallest section of the RV-to-pulmonary
        /// pathway before and after the baffle (report.json rv_outflow_*). Taken from
        /// --segmentations by `baffle plan` and `baffle sweep`.
        #[arg(long)]
        pub pulmonary: Option<PathBuf>,
        /// Apply the target to the tunnel's sections normal to the flow too: the paper
        /// constrains sections normal to its centerline between the cap centroids, which runs
        /// oblique to the flow near the caps, so the flow's own sections can be smaller (up to
        /// 25% on p3). The design is run again at a raised target until the smallest section
        /// normal to the flow-domain centerline reaches the target (report.json flow_sections).
        #[arg(long)]
        pub flow_sections: bool,
        /// The patient's peak flow (ml/s; the paper's is 3.26 x CI x BSA): report.json then
        /// holds hemodynamics_estimate, dp at peak flow and the peak velocity from the tunnel's
        /// flow-normal sections (baffle_core::analyses::hemodynamics_estimate, docs/hemodynamics_estimate.md).
        #[arg(long, allow_hyphen_values = true)]
        pub peak_flow_ml_s: Option<f64>,
        /// Print Slicer CLI progress tags (<filter-progress>) instead of a summary.
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
        /// Target cross-section area (mm2).
        #[arg(long, group = "target_kind")]
        pub target_area_mm2: Option<f64>,
        /// Target aortic annulus diameter (mm): A = pi (D/2)^2.
        #[arg(long, group = "target_kind")]
        pub annulus_diameter_mm: Option<f64>,
        /// Body surface area (m2): Boston (Colan 2006) aortic annulus at --z-score.
        #[arg(long, group = "target_kind")]
        pub bsa: Option<f64>,
        /// Height (cm), with --weight-kg: Haycock BSA, then the Boston annulus.
        #[arg(long, requires = "weight_kg", group = "target_kind")]
        pub height_cm: Option<f64>,
        /// Weight (kg), with --height-cm.
        #[arg(long, requires = "height_cm")]
        pub weight_kg: Option<f64>,
        /// Annulus z-score for --bsa or --height-cm/--weight-kg (not with a given area or diameter,
        /// which it would not change).
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
