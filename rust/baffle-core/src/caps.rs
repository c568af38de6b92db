//! Labelling the caps of an unlabelled surface (`.stl`, legacy `.vtk` without
//! `ModelFaceID`). The VSD and aortic-annulus caps are planar; given one point on
//! each, the cap is the planar region grown from the triangle nearest that point:
//! neighbours join while their normal stays within `max_angle_deg` of the seed's and
//! their corners within `max_offset_mm` of the seed's plane. Everything else is wall.

use crate::mesh::{TriMesh, Vec3};
use crate::spatial::TriangleBvh;

/// A point on a cap and the label the cap should get.
#[derive(Clone, Copy, Debug)]
pub struct CapSeed {
    pub point_mm: Vec3,
    pub label: i32,
}

#[derive(Clone, Copy, Debug)]
pub struct CapTolerances {
    pub max_angle_deg: f64,
    pub max_offset_mm: f64,
    /// A seed farther than this from the surface is an error.
    pub max_seed_distance_mm: f64,
}

impl Default for CapTolerances {
    fn default() -> Self {
        CapTolerances { max_angle_deg: 5.0, max_offset_mm: 0.05, max_seed_distance_mm: 2.0 }
    }
}

/// Label every triangle `wall_label`, then grow each seed's planar cap.
pub fn label_planar_caps(mesh: &TriMesh, seeds: &[CapSeed], wall_label: i32, tol: &CapTolerances) -> Result<Vec<i32>, String> {
    let bvh = TriangleBvh::new(mesh)?;
    let neighbors = mesh.triangle_neighbors();
    let mut labels = vec![wall_label; mesh.triangles.len()];
    for (k, seed) in seeds.iter().enumerate() {
        let hit = bvh.closest_point(mesh, seed.point_mm).ok_or("the surface has no triangles")?;
        if hit.distance_mm > tol.max_seed_distance_mm {
            return Err(format!(
                "cap point {} (label {}) is {:.2} mm from the surface (limit {:.2} mm)",
                k + 1,
                seed.label,
                hit.distance_mm,
                tol.max_seed_distance_mm
            ));
        }
        let region = grow_planar_region(mesh, &neighbors, hit.triangle as usize, tol);
        if let Some(&t) = region.iter().find(|&&t| labels[t] != wall_label) {
            return Err(format!("the caps of points {} and another point overlap (triangle {t})", k + 1));
        }
        region.iter().for_each(|&t| labels[t] = seed.label);
    }
    Ok(labels)
}

fn unit_normal(mesh: &TriMesh, t: usize) -> Vec3 {
    let n = mesh.triangle_normal2(t);
    n / n.norm().max(1e-300)
}

fn grow_planar_region(mesh: &TriMesh, neighbors: &[[u32; 3]], seed: usize, tol: &CapTolerances) -> Vec<usize> {
    let normal = unit_normal(mesh, seed);
    let origin = mesh.points[mesh.triangles[seed][0] as usize];
    let min_cos = tol.max_angle_deg.to_radians().cos();
    let in_plane = |t: usize| {
        unit_normal(mesh, t).dot(&normal) >= min_cos
            && mesh.triangles[t].iter().all(|&v| normal.dot(&(mesh.points[v as usize] - origin)).abs() <= tol.max_offset_mm)
    };
    let mut inside = vec![false; mesh.triangles.len()];
    inside[seed] = true;
    let mut stack = vec![seed];
    let mut region = Vec::new();
    while let Some(t) = stack.pop() {
        region.push(t);
        for &nb in &neighbors[t] {
            let nb = nb as usize;
            if nb < inside.len() && !inside[nb] && in_plane(nb) {
                inside[nb] = true;
                stack.push(nb);
            }
        }
    }
    region
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phantom::phantom_default;

    #[test]
    fn phantom_caps_are_recovered_from_one_point_each() {
        let p = phantom_default();
        let unlabelled = TriMesh { face_ids: vec![0; p.surface.triangles.len()], ..p.surface.clone() };
        let centroid = |label: i32| p.surface.label_centroid_normal(label).unwrap().0;
        let seeds = [CapSeed { point_mm: centroid(11), label: 11 }, CapSeed { point_mm: centroid(16), label: 16 }];
        let labels = label_planar_caps(&unlabelled, &seeds, 2, &CapTolerances::default()).unwrap();
        assert_eq!(labels, p.surface.face_ids);
    }

    #[test]
    fn a_seed_off_the_surface_is_named() {
        let p = phantom_default();
        let seeds = [CapSeed { point_mm: Vec3::new(100.0, 0.0, 0.0), label: 11 }];
        let err = label_planar_caps(&p.surface, &seeds, 2, &CapTolerances::default()).unwrap_err();
        assert!(err.contains("cap point 1") && err.contains("mm from the surface"), "{err}");
    }
}
