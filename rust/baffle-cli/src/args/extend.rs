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
        /// Designed domain (domain.vtp from `baffle design`): closed, mm, ModelFaceID.
        #[arg(long)]
        pub domain: PathBuf,
        /// The LV and aorta blood pools (the RV is read too, as `prepare` reads them).
        #[command(flatten)]
        pub source: PrepareSourceArgs,
        /// Output extended surface (.vtp): the designed domain's faces unchanged (its VSD and
        /// aortic caps now inside: mesh with `baffle mesh --interior-labels 11,16`), the LV
        /// and aortic walls (wall label), the inflow and outflow caps. The report
        /// (<stem>-report.json) is written beside it.
        #[arg(long)]
        pub out: PathBuf,
        /// ModelFaceID of the new inflow cap (mid-LV plane).
        #[arg(long, default_value_t = ExtendSettings::default().inflow_label)]
        pub inflow_label: i32,
        /// ModelFaceID of the new outflow cap (sinotubular junction).
        #[arg(long, default_value_t = ExtendSettings::default().outflow_label)]
        pub outflow_label: i32,
        // --wall-label, --baffle-label, --vsd-label, --aortic-label.
        #[command(flatten)]
        pub labels: FaceLabelArgs,
        /// Voxel edge of the union grid the LV and aorta are cut from (mm).
        #[arg(long, default_value_t = ExtendSettings::default().voxel_mm)]
        pub voxel_mm: f64,
        /// Target edge of the extension's triangles (mm); default: the designed caps' rim edge.
        #[arg(long)]
        pub remesh_edge_mm: Option<f64>,
        /// Remesh the designed domain at this edge (mm; labels and rims kept, as `baffle mesh
        /// --remesh-surface`) before extending, and the extension at the same edge unless
        /// --remesh-edge-mm says otherwise: the whole boundary at one size with the measurement
        /// planes conforming, for a mesh study that refines the boundary too (the interior caps
        /// share their rims with the boundary, so `baffle mesh` cannot remesh an extended domain).
        #[arg(long)]
        pub remesh_domain_edge_mm: Option<f64>,
        /// Coarsen the LV and aortic parts away from the designed caps, up to this many times
        /// the edge (within one cap diameter of each cap the edge stays, then grows 0.2 mm
        /// per mm); 1: the edge everywhere. Mesh the result with `baffle mesh
        /// --largest-edge-mm` at this many times the edge length.
        #[arg(long, default_value_t = ExtendSettings::default().extension_coarsening)]
        pub extension_coarsening: f64,
        /// Move the inflow cap (mid-LV plane) this far (mm) from the LV volume centroid along
        /// the VSD normal (positive: away from the VSD, toward the apex), for a sensitivity
        /// study; an offset that leaves no clean cut of the LV is an error (no fallback).
        /// Default: through the centroid, moved only when that cut is not clean.
        #[arg(long, allow_hyphen_values = true)]
        pub inflow_offset_mm: Option<f64>,
        /// Put the outflow cap this many annulus diameters above the annulus instead of at the
        /// sinotubular junction (the STJ search still runs and is reported), for a sensitivity
        /// study of the outflow length; a height past the aortic root's sections is an error.
        #[arg(long)]
        pub outflow_diameters: Option<f64>,
        /// The domain has no baffle (no triangle of --baffle-label), and is to be extended
        /// as it is (e.g. a capped ventricle, for a pre-repair flow). Without it such a
        /// domain is refused: `baffle extend` expects `baffle design`'s domain.
        #[arg(long)]
        pub no_baffle: bool,
    }
}
