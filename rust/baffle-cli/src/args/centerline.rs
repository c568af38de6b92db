//! `baffle centerline`'s arguments.

use baffle_plan::centerline_cmd::CenterlineSettings;
use clap::Args;
use std::path::PathBuf;

super::settings_args! {
    #[derive(Args, Clone)]
    pub struct CenterlineArgs into CenterlineSettings {
        /// Closed lumen surface with ModelFaceID (e.g. domain.vtp of `baffle design`).
        #[arg(long)]
        pub surface: PathBuf,
        /// The measurement planes, inflow first, as ModelFaceIDs: caps of --surface, or
        /// face sets of --plane-faces.
        #[arg(long, value_delimiter = ',', default_values_t = CenterlineSettings::default().planes)]
        pub planes: Vec<i32>,
        /// The end caps of --surface the path runs between (inflow first), when the planes
        /// are not caps of it (an extended domain, e.g. `baffle extend`'s 20,21); default: the
        /// planes. Plane triangles of --surface that are not end caps are taken as interior.
        #[arg(long, value_delimiter = ',')]
        pub ends: Option<Vec<i32>>,
        /// A face file holding the planes' triangles (e.g. mesh-faces.vtp of `baffle mesh`,
        /// whose interior face sets are the measurement planes).
        #[arg(long)]
        pub plane_faces: Option<PathBuf>,
        /// Factor from the files' units to mm (10 for the paper's published files, in cm).
        #[arg(long, default_value_t = CenterlineSettings::default().scale)]
        pub scale: f64,
        /// A `baffle simulate` result (peak.vtu: mm, velocity_m_s, pressure_mmhg) to sample along the centerline.
        #[arg(long)]
        pub results: Option<PathBuf>,
        /// Voxel size of the distance field (mm).
        #[arg(long, default_value_t = CenterlineSettings::default().voxel_mm)]
        pub voxel_mm: f64,
        /// Largest distance between centerline points (mm); the paper used 0.5.
        #[arg(long, default_value_t = CenterlineSettings::default().spacing_mm)]
        pub spacing_mm: f64,
        /// Half-width of the moving average smoothing the path (mm).
        #[arg(long, default_value_t = CenterlineSettings::default().smoothing_mm)]
        pub smoothing_mm: f64,
        /// Largest re-centring shift of a path point in its normal plane, as a fraction of
        /// its inscribed radius (0: the minimal path as found on the voxels, smoothed).
        #[arg(long, default_value_t = CenterlineSettings::default().recenter_fraction)]
        pub recenter_fraction: f64,
        /// The peak flow (ml/s): <stem>.json then holds hemodynamics_estimate, dp at peak flow
        /// between the planes and the peak velocity from the sections normal to the centerline
        /// (baffle_core::analyses::hemodynamics_estimate; the planes' areas from their triangles).
        #[arg(long, allow_hyphen_values = true)]
        pub peak_flow_ml_s: Option<f64>,
        /// Output centerline (.vtp, point arrays s_mm, radius_mm and, with --results,
        /// pressure_mmhg and speed_m_s); <stem>.json beside it holds the figures.
        #[arg(long)]
        pub out: PathBuf,
    }
}
