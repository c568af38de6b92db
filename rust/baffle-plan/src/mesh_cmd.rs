//! `baffle mesh`: tetrahedral mesh of a closed labelled surface, by gmsh run as a
//! separate process, with the paper's quality figures.

use crate::error::PlanError;
use baffle_core::io::read_surface_labeled;
use baffle_mesh::{check_resolves_flow, mesh_surface, split_interior_labels, write_faces_vtp, write_vtu, MeshError, MeshOptions};
use crate::progress::Progress;
use std::path::PathBuf;

documented_settings! {
pub struct MeshSettings {
    /// Closed, labelled surface (e.g. domain.vtp from `baffle design`), mm.
    pub surface: PathBuf,
    /// Largest tetrahedron edge length (mm); the paper used 1.25 / 0.95 / 0.75.
    pub edge_length_mm: f64,
    /// Largest tetrahedron edge where the boundary's triangles are longer (an extended
    /// domain made with `baffle extend --extension-coarsening R`: give R x the edge
    /// length); default: the edge length everywhere.
    pub largest_edge_mm: Option<f64>,
    /// Output volume mesh (.vtu). Beside it: <stem>-faces.vtp (ModelFaceID,
    /// GlobalNodeID) and <stem>-quality.json.
    pub out: PathBuf,
    /// Remesh the boundary at the edge length first (labels and rims kept).
    pub remesh_surface: bool,
    /// ModelFaceIDs of the surface that lie inside the domain (measurement planes, e.g.
    /// 11,16 in `baffle extend`'s output): meshed as conforming interior face sets.
    pub interior_labels: Vec<i32>,
    /// gmsh executable (default: $BAFFLE_GMSH, then gmsh on PATH, then the Python wheel).
    pub gmsh: Option<PathBuf>,
}
}

impl Default for MeshSettings {
    fn default() -> Self {
        let o = MeshOptions::default();
        MeshSettings { surface: PathBuf::new(), edge_length_mm: o.edge_length_mm, largest_edge_mm: o.largest_edge_mm, out: PathBuf::new(), remesh_surface: o.remesh_surface, interior_labels: Vec::new(), gmsh: None }
    }
}

/// `baffle mesh`, gmsh's run shown and the mesh's figures said on `progress` (a stage of
/// `baffle plan`, or the command).
pub fn run_mesh(args: &MeshSettings, progress: &Progress) -> Result<(), PlanError> {
    mesh_and_write(args, progress).map_err(PlanError::Mesh)
}

/// The volume mesh of `args` and its faces and quality files.
fn mesh_and_write(args: &MeshSettings, progress: &Progress) -> Result<(), String> {
    let labeled = read_surface_labeled(&args.surface).map_err(|e| e.to_string())?;
    if !labeled.has_model_face_id {
        return Err(format!("{}: no ModelFaceID cell array; the faces need labels", args.surface.display()));
    }
    let (boundary, interior_surfaces) = split_interior_labels(&labeled.mesh, &args.interior_labels).map_err(|e| format!("{}: {e}", args.surface.display()))?;
    let options = MeshOptions {
        edge_length_mm: args.edge_length_mm,
        largest_edge_mm: args.largest_edge_mm,
        interior_surfaces,
        gmsh_executable: args.gmsh.clone(),
        remesh_surface: args.remesh_surface,
        ..MeshOptions::default()
    };
    check_resolves_flow(&boundary, args.edge_length_mm).map_err(|e| format!("{}: {e}", args.surface.display()))?;
    let (mesh, quality) = progress.while_running("mesh (gmsh)", || mesh_surface(&boundary, &options)).map_err(|e| match e {
        // The surface's own fault: say which file.
        MeshError::InvalidInput(_) => format!("{}: {e}", args.surface.display()),
        e => e.to_string(),
    })?;
    crate::files::create_parent_dir(&args.out)?;
    write_vtu(&args.out, &mesh, &[], &[]).map_err(|e| e.to_string())?;
    let stem = args.out.with_extension("");
    let faces_path = PathBuf::from(format!("{}-faces.vtp", stem.display()));
    write_faces_vtp(&faces_path, &mesh).map_err(|e| e.to_string())?;
    let quality_path = PathBuf::from(format!("{}-quality.json", stem.display()));
    let text = serde_json::to_string_pretty(&quality).map_err(|e| e.to_string())?;
    crate::files::write_atomic(&quality_path, text.as_bytes())?;
    progress.say(&format!(
        "{} tetrahedra; scaled Jacobian min {:.3}, 1st percentile {:.3}; aspect ratio 99th percentile {:.2}",
        quality.tetrahedra, quality.min_scaled_jacobian, quality.p1_scaled_jacobian, quality.p99_aspect_ratio
    ));
    progress.say(&format!("wrote {}, {}, {}", args.out.display(), faces_path.display(), quality_path.display()));
    Ok(())
}
