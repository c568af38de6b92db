//! Mesh a labelled domain surface at one or more edge lengths and print the quality figures:
//! `cargo run --release -p baffle-mesh --example mesh_domain -- domain.vtp OUT_DIR 1.25 0.95 0.75`
//! Writes OUT_DIR/mesh_<h>.vtu (cell arrays ScaledJacobian, AspectRatio) and
//! OUT_DIR/mesh_<h>_faces.vtp. Set BAFFLE_REMESH_SURFACE=1 to remesh the boundary at h too.

use baffle_core::io::{read_surface, DataArray};
use baffle_mesh::quality::tet_measures;
use baffle_mesh::{mesh_surface, write_faces_vtp, write_vtu, MeshOptions};
use std::path::PathBuf;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 3 {
        return Err("usage: mesh_domain SURFACE.vtp OUT_DIR EDGE_MM...".into());
    }
    let surface = read_surface(&PathBuf::from(&args[0]))?;
    let out = PathBuf::from(&args[1]);
    std::fs::create_dir_all(&out)?;
    let remesh_surface = std::env::var("BAFFLE_REMESH_SURFACE").as_deref() == Ok("1");
    for h in &args[2..] {
        let edge_length_mm: f64 = h.parse()?;
        let opts = MeshOptions {
            edge_length_mm,
            remesh_surface,
            ..Default::default()
        };
        let start = Instant::now();
        let (mesh, report) = mesh_surface(&surface, &opts)?;
        let seconds = start.elapsed().as_secs_f64();
        let m = tet_measures(&mesh);
        let cells = [
            DataArray::f64("ScaledJacobian", 1, m.scaled_jacobian),
            DataArray::f64("AspectRatio", 1, m.aspect_ratio),
        ];
        write_vtu(&out.join(format!("mesh_{h}.vtu")), &mesh, &[], &cells)?;
        write_faces_vtp(&out.join(format!("mesh_{h}_faces.vtp")), &mesh)?;
        println!(
            "h {h} mm: {} tets, {} points, {seconds:.2} s, min SJ {:.3}, p1 SJ {:.3}, p99 AR {:.2}, min dihedral {:.1} deg",
            report.tetrahedra, report.points, report.min_scaled_jacobian, report.p1_scaled_jacobian, report.p99_aspect_ratio, report.min_dihedral_deg
        );
    }
    Ok(())
}
