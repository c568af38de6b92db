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
        /// Closed, labelled surface (e.g. domain.vtp from `baffle design`), mm.
        #[arg(long)]
        pub surface: PathBuf,
        /// Largest tetrahedron edge length (mm); the paper used 1.25 / 0.95 / 0.75.
        #[arg(long, default_value_t = MeshSettings::default().edge_length_mm)]
        pub edge_length_mm: f64,
        /// Largest tetrahedron edge where the boundary's triangles are longer (an extended
        /// domain made with `baffle extend --extension-coarsening R`: give R x the edge
        /// length); default: the edge length everywhere.
        #[arg(long)]
        pub largest_edge_mm: Option<f64>,
        /// Output volume mesh (.vtu). Beside it: <stem>-faces.vtp (ModelFaceID,
        /// GlobalNodeID) and <stem>-quality.json.
        #[arg(long)]
        pub out: PathBuf,
        /// Remesh the boundary at the edge length first (labels and rims kept).
        #[arg(long)]
        pub remesh_surface: bool,
        /// ModelFaceIDs of the surface that lie inside the domain (measurement planes, e.g.
        /// 11,16 in `baffle extend`'s output): meshed as conforming interior face sets.
        #[arg(long, value_delimiter = ',')]
        pub interior_labels: Vec<i32>,
        /// gmsh executable (default: $BAFFLE_GMSH, then gmsh on PATH, then the Python wheel).
        #[arg(long)]
        pub gmsh: Option<PathBuf>,
    }
}
