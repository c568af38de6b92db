//! Tetrahedral volume meshes of the labelled baffle domain (issue #4, volume-mesh part):
//! gmsh run as a child process on the caller's closed labelled surface ([`mesh_surface`]),
//! the paper's quality figures ([`QualityReport`], Verdict definitions), and `.vtu` I/O
//! ([`write_vtu`], [`write_faces_vtp`], [`read_vtu`], [`read_simvascular`]).
//!
//! Units: millimetres. Every [`TetMesh`] handed out has positively oriented tets, boundary
//! face sets wound outward that are each the face of exactly one tet, and interior face sets
//! (measurement planes) that are each the face of exactly two.

pub mod error;
pub mod gmsh;
pub mod mesher;
pub mod msh;
pub mod process;
pub mod quality;
pub mod tetmesh;
pub mod vtu;

pub use error::MeshError;
pub use gmsh::{find_gmsh, GmshCommand, GMSH_ENV};
pub use mesher::{check_resolves_flow, expected_tetrahedra, mesh_surface, split_interior_labels, MeshOptions};
pub use process::start_retrying_busy;
pub use quality::{quality_report, QualityReport};
pub use tetmesh::{FaceSet, TetMesh};
pub use vtu::{read_simvascular, read_vtu, write_faces_vtp, write_vtu, VtuData};
