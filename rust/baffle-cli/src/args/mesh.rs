//! `baffle mesh`'s arguments.

use baffle_plan::mesh_cmd::MeshSettings;
use clap::Args;
use std::path::PathBuf;

super::settings_args! {
    #[derive(Args)]
    #[command(after_help = "Example (the designed domain, the paper's nominal size):\n  \
        baffle mesh --surface out/p2/domain.vtp --edge-length-mm 0.95 --remesh-surface --out out/p2/mesh.vtu\n\
    Example (an extended domain, its VSD and aortic caps kept inside as measurement planes):\n  \
        baffle mesh --surface out/p2/extended.vtp --interior-labels 11,16 --edge-length-mm 1.25 --out out/p2/mesh.vtu")]
    pub struct MeshArgs into MeshSettings {
        #[arg(long)]
        pub surface: PathBuf,
        #[arg(long, default_value_t = MeshSettings::default().edge_length_mm)]
        pub edge_length_mm: f64,
        #[arg(long)]
        pub largest_edge_mm: Option<f64>,
        #[arg(long)]
        pub out: PathBuf,
        #[arg(long)]
        pub remesh_surface: bool,
        #[arg(long, value_delimiter = ',')]
        pub interior_labels: Vec<i32>,
        #[arg(long)]
        pub gmsh: Option<PathBuf>,
    }
}
