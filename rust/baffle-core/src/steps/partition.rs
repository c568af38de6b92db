//! Step 2, partition [paper 2.3.3]: cut the surface along the seam, keep the region
//! that holds both caps (the wall of the new VSD-to-aorta tunnel) and discard the
//! other (where the baffle goes); then remesh the kept region isotropically.

use crate::error::DesignError;
use crate::geometry::mesh::{edge_key, FaceLabels, TriMesh};
use crate::geometry::remesh::{remesh_isotropic, RemeshOptions};
use std::collections::HashSet;

/// The kept region: an open surface whose one boundary loop is the seam.
#[derive(Clone, Debug)]
pub struct KeptRegion {
    pub mesh: TriMesh,
    /// The seam as the kept region's boundary loop (vertex indices of `mesh`), in
    /// the direction the kept triangles traverse it.
    pub seam_loop: Vec<u32>,
    /// Area of the discarded region (mm2), for the report.
    pub discarded_area_mm2: f64,
}

/// Split the imprinted surface along the seam loop and keep the side with both caps.
pub fn keep_capped_side(mesh: &TriMesh, seam_loop: &[u32], labels: &FaceLabels) -> Result<KeptRegion, DesignError> {
    let neighbors = mesh.triangle_neighbors();
    check_connected(mesh, &neighbors)?;
    let seam_edges: HashSet<(u32, u32)> =
        (0..seam_loop.len()).map(|i| edge_key(seam_loop[i], seam_loop[(i + 1) % seam_loop.len()])).collect();
    let component = components_across(mesh, &neighbors, &seam_edges);
    let count = component.iter().copied().max().map_or(0, |c| c + 1);
    if count != 2 {
        return Err(DesignError::Seam(format!(
            "the seam should split the surface into 2 regions but splits it into {count}"
        )));
    }
    let side_of = |label: i32| -> HashSet<u32> {
        (0..mesh.triangles.len()).filter(|&t| mesh.face_ids[t] == label).map(|t| component[t]).collect()
    };
    let (vsd_sides, aortic_sides) = (side_of(labels.vsd_cap), side_of(labels.aortic_cap));
    if vsd_sides.len() != 1 || aortic_sides.len() != 1 || vsd_sides != aortic_sides {
        return Err(DesignError::Seam(
            "the seam separates the VSD cap from the aortic-annulus cap; both must lie on the same side \
             (the suture line must run around the region the baffle replaces, not between the caps)"
                .into(),
        ));
    }
    let kept_side = *vsd_sides.iter().next().unwrap_or(&0);
    let keep: Vec<bool> = component.iter().map(|&c| c == kept_side).collect();
    let discarded_area_mm2: f64 = (0..mesh.triangles.len()).filter(|&t| !keep[t]).map(|t| mesh.triangle_area_mm2(t)).sum();
    if discarded_area_mm2 <= 0.0 {
        return Err(DesignError::Seam("the seam encloses no wall region to replace".into()));
    }
    let (sub, _) = mesh.submesh(&keep);
    region_from_mesh(sub, discarded_area_mm2)
}

/// A second part (a stray shell, a detached cap) would show up only as a seam that
/// "splits the surface into 3": name it as what it is.
fn check_connected(mesh: &TriMesh, neighbors: &[[u32; 3]]) -> Result<(), DesignError> {
    let component = components_across(mesh, neighbors, &HashSet::new());
    let count = component.iter().copied().max().map_or(0, |c| c as usize + 1);
    if count <= 1 {
        return Ok(());
    }
    let mut sizes = vec![0usize; count];
    component.iter().for_each(|&c| sizes[c as usize] += 1);
    Err(DesignError::Surface(format!(
        "the surface has {count} disconnected parts ({sizes:?} triangles); the design needs one closed ventricle surface"
    )))
}

/// Remesh the kept region isotropically, preserving the seam (bit-identical
/// vertices), the cap rims and the labels.
pub fn remesh_kept(region: &KeptRegion, target_edge_mm: f64) -> Result<KeptRegion, DesignError> {
    let opts = RemeshOptions { target_edge_mm, ..RemeshOptions::default() };
    let remeshed = remesh_isotropic(&region.mesh, &opts).map_err(|m| DesignError::numerical("remesh", m))?;
    region_from_mesh(remeshed, region.discarded_area_mm2)
}

fn region_from_mesh(mesh: TriMesh, discarded_area_mm2: f64) -> Result<KeptRegion, DesignError> {
    let loops = mesh.boundary_loops().map_err(DesignError::Seam)?;
    if loops.len() != 1 {
        return Err(DesignError::Seam(format!("the kept region has {} boundary loops instead of 1", loops.len())));
    }
    let seam_loop = loops.into_iter().next().unwrap_or_default();
    Ok(KeptRegion { mesh, seam_loop, discarded_area_mm2 })
}

/// Connected components of triangles, joined across every edge that is not a seam
/// edge (and is shared by exactly two triangles).
fn components_across(mesh: &TriMesh, neighbors: &[[u32; 3]], seam_edges: &HashSet<(u32, u32)>) -> Vec<u32> {
    let mut component = vec![u32::MAX; mesh.triangles.len()];
    let mut next_id = 0;
    let mut stack = Vec::new();
    for start in 0..mesh.triangles.len() {
        if component[start] != u32::MAX {
            continue;
        }
        component[start] = next_id;
        stack.push(start);
        while let Some(t) = stack.pop() {
            let tri = mesh.triangles[t];
            for k in 0..3 {
                let nb = neighbors[t][k];
                if nb == u32::MAX || seam_edges.contains(&edge_key(tri[k], tri[(k + 1) % 3])) {
                    continue;
                }
                if component[nb as usize] == u32::MAX {
                    component[nb as usize] = next_id;
                    stack.push(nb as usize);
                }
            }
        }
        next_id += 1;
    }
    component
}
