//! `baffle centerline`'s arguments.

use baffle_plan::centerline_cmd::CenterlineSettings;
use clap::Args;
use std::path::PathBuf;

super::settings_args! {
    #[derive(Args, Clone)]
    pub struct CenterlineArgs into CenterlineSettings {
        #[arg(long)]
        pub surface: PathBuf,
        #[arg(long, value_delimiter = ',', default_values_t = CenterlineSettings::default().planes)]
        pub planes: Vec<i32>,
        #[arg(long, value_delimiter = ',')]
        pub ends: Option<Vec<i32>>,
        #[arg(long)]
        pub plane_faces: Option<PathBuf>,
        #[arg(long, default_value_t = CenterlineSettings::default().scale)]
        pub scale: f64,
        #[arg(long)]
        pub results: Option<PathBuf>,
        #[arg(long, default_value_t = CenterlineSettings::default().voxel_mm)]
        pub voxel_mm: f64,
        #[arg(long, default_value_t = CenterlineSettings::default().spacing_mm)]
        pub spacing_mm: f64,
        #[arg(long, default_value_t = CenterlineSettings::default().smoothing_mm)]
        pub smoothing_mm: f64,
        #[arg(long, default_value_t = CenterlineSettings::default().recenter_fraction)]
        pub recenter_fraction: f64,
        #[arg(long, allow_hyphen_values = true)]
        pub peak_flow_ml_s: Option<f64>,
        #[arg(long)]
        pub out: PathBuf,
    }
}
