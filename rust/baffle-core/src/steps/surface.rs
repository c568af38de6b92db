//! Step 8, the final surface [paper 2.4.6], and the watertight domain.
//!
//! The baffle is a thin-plate-spline map of the same unit disk as the initial patch,
//! with the seam and the regularized section loops as landmarks. The seam is then
//! restored exactly and the baffle is merged with the kept wall into the closed,
//! labelled VSD-to-aorta domain (wall, VSD cap, aortic cap, baffle).

use crate::geometry::mesh::{FaceLabels, TriMesh, Vec3};
use crate::steps::partition::KeptRegion;
use crate::steps::patch::UnitDisk;

/// The kept wall and a baffle on the unit disk, sharing the seam vertices.
#[derive(Clone, Debug)]
pub struct Domain {
    pub mesh: TriMesh,
    /// Disk vertex of each domain vertex (u32::MAX where the vertex is not on the baffle).
    pub disk_vertex: Vec<u32>,
    /// Domain vertex of each disk vertex.
    pub domain_vertex_of_disk: Vec<u32>,
    /// Index of the first baffle triangle (the baffle's triangles come last).
    pub first_baffle_triangle: usize,
    /// Index of the first interior baffle vertex (the kept wall's vertices come first).
    pub first_baffle_vertex: usize,
}

impl Domain {
    /// Merge the kept region with the disk's triangles placed at `patch_points_mm`,
    /// winding the baffle so every seam edge is used once in each direction.
    pub fn assemble(kept: &KeptRegion, disk: &UnitDisk, patch_points_mm: &[Vec3], labels: &FaceLabels) -> Domain {
        let mut mesh = kept.mesh.clone();
        let mut disk_vertex = vec![u32::MAX; mesh.points.len()];
        let mut domain_vertex_of_disk = vec![u32::MAX; disk.uv.len()];
        for (i, &b) in disk.boundary.iter().enumerate() {
            let v = kept.seam_loop[i];
            domain_vertex_of_disk[b as usize] = v;
            disk_vertex[v as usize] = b;
        }
        for (d, slot) in domain_vertex_of_disk.iter_mut().enumerate() {
            if *slot == u32::MAX {
                *slot = mesh.points.len() as u32;
                mesh.points.push(patch_points_mm[d]);
                disk_vertex.push(d as u32);
            }
        }
        let first_baffle_vertex = kept.mesh.points.len();
        let first_baffle_triangle = mesh.triangles.len();
        let reverse = baffle_runs_with_wall(disk);
        for tri in &disk.triangles {
            let mapped = tri.map(|d| domain_vertex_of_disk[d as usize]);
            mesh.triangles.push(if reverse { [mapped[0], mapped[2], mapped[1]] } else { mapped });
            mesh.face_ids.push(labels.baffle);
        }
        Domain { mesh, disk_vertex, domain_vertex_of_disk, first_baffle_triangle, first_baffle_vertex }
    }

    /// The same domain with the baffle's interior vertices moved to `patch_points_mm`.
    pub fn with_patch_points(&self, patch_points_mm: &[Vec3]) -> Domain {
        let mut out = self.clone();
        for v in self.first_baffle_vertex..self.mesh.points.len() {
            out.mesh.points[v] = patch_points_mm[self.disk_vertex[v] as usize];
        }
        out
    }

    /// The baffle alone (its own vertex numbering), label `labels.baffle`.
    pub fn baffle_mesh(&self) -> TriMesh {
        let keep: Vec<bool> = (0..self.mesh.triangles.len()).map(|t| t >= self.first_baffle_triangle).collect();
        self.mesh.submesh(&keep).0
    }

    /// Disk coordinates of a point on domain edge (a, b) at `fraction` from a, if
    /// both ends are baffle vertices.
    pub fn disk_uv_on_edge(&self, disk: &UnitDisk, (a, b): (u32, u32), fraction: f64) -> Option<(f64, f64)> {
        let (da, db) = (self.disk_vertex[a as usize], self.disk_vertex[b as usize]);
        if da == u32::MAX || db == u32::MAX {
            return None;
        }
        let (ua, ub) = (disk.uv[da as usize], disk.uv[db as usize]);
        Some((ua.0 + fraction * (ub.0 - ua.0), ua.1 + fraction * (ub.1 - ua.1)))
    }
}

/// True when the disk's triangles traverse the seam in the same direction as the
/// kept wall's triangles (then the baffle must be reversed to close the surface).
fn baffle_runs_with_wall(disk: &UnitDisk) -> bool {
    let (b0, b1) = (disk.boundary[0], disk.boundary[1]);
    // The kept region's boundary loop follows its triangles' winding: seam_loop[0] -> seam_loop[1],
    // and disk boundary vertex i sits on seam vertex i.
    disk.triangles.iter().any(|t| (0..3).any(|k| t[k] == b0 && t[(k + 1) % 3] == b1))
}
