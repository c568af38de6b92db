//! `baffle extend`'s arguments.

use super::design::FaceLabelArgs;
use super::prepare::PrepareSourceArgs;
use baffle_plan::extend_cmd::ExtendSettings;
use clap::Args;
use std::path::PathBuf;

super::settings_args! {
    #[derive(Args)]
    // The labels are `baffle design`'s (the same defaults), named as the domain's here.
    #[command(
        mut_arg("wall_label", |a| a.help("ModelFaceID of the domain's walls (the extension's walls get it too)")),
        mut_arg("baffle_label", |a| a.help("ModelFaceID of the domain's baffle")),
        mut_arg("vsd_label", |a| a.help("ModelFaceID of the domain's VSD cap")),
        mut_arg("aortic_label", |a| a.help("ModelFaceID of the domain's aortic-annulus cap")),
    )]
    pub struct ExtendArgs into ExtendSettings {
        #[arg(long)]
        pub domain: PathBuf,
        // --segmentations or --labelmap: the LV and aorta blood pools (ExtendSettings::source).
        #[command(flatten)]
        pub source: PrepareSourceArgs,
        #[arg(long)]
        pub out: PathBuf,
        #[arg(long, default_value_t = ExtendSettings::default().inflow_label)]
        pub inflow_label: i32,
        #[arg(long, default_value_t = ExtendSettings::default().outflow_label)]
        pub outflow_label: i32,
        // --wall-label, --baffle-label, --vsd-label, --aortic-label.
        #[command(flatten)]
        pub labels: FaceLabelArgs,
        #[arg(long, default_value_t = ExtendSettings::default().voxel_mm)]
        pub voxel_mm: f64,
        #[arg(long)]
        pub remesh_edge_mm: Option<f64>,
        #[arg(long)]
        pub remesh_domain_edge_mm: Option<f64>,
        #[arg(long, default_value_t = ExtendSettings::default().extension_coarsening)]
        pub extension_coarsening: f64,
        #[arg(long, allow_hyphen_values = true)]
        pub inflow_offset_mm: Option<f64>,
        #[arg(long)]
        pub outflow_diameters: Option<f64>,
        #[arg(long)]
        pub no_baffle: bool,
    }
}
