//! Labelling the caps of an unlabelled surface (`.stl`, legacy `.vtk` without
//! `ModelFaceID`). The VSD and aortic-annulus caps are planar; given one point on
//! each, the cap is the planar region grown from the triangle nearest that point:
//! neighbours join while their normal stays within `max_angle_deg` of the seed's and
//! their corners within `max_offset_mm` of the seed's plane. Everything else is wall.

use crate::mesh::{TriMesh, Vec3};
use crate::numerics::pca::{best_fit_plane, Plane};
use crate::spatial::TriangleBvh;

/// A cap is planar when no point is farther from its best-fit plane than this fraction
/// of its equivalent diameter (0.1 mm on a 10 mm cap, below a tenth of a mesh edge).
/// The published caps are planar to 4-16 micrometres (float32 files), not to rounding:
/// an absolute tolerance refused them; a crumpled cap is off by millimetres.
pub const PLANAR_TOLERANCE_OF_DIAMETER: f64 = 0.01;

/// How far the cap labelled `label` is from flat.
#[derive(Clone, Copy, Debug)]
pub struct CapFlatness {
    /// Least-squares plane of the cap's points, normal outward (as the surface is wound).
    pub plane: Plane,
    pub area_mm2: f64,
    /// Largest distance of a cap point from `plane`.
    pub off_plane_mm: f64,
    /// [`PLANAR_TOLERANCE_OF_DIAMETER`] of the cap's equivalent diameter.
    pub tolerance_mm: f64,
}

impl CapFlatness {
    pub fn is_planar(&self) -> bool {
        self.off_plane_mm <= self.tolerance_mm
    }

    /// "the VSD cap is not planar: ..." for an error message.
    pub fn describe(&self, name: &str) -> String {
        format!(
            "the {name} cap is not planar: a point lies {:.3} mm off its plane (tolerance {:.3} mm, 1% of its diameter)",
            self.off_plane_mm, self.tolerance_mm
        )
    }
}

/// The flatness of the cap labelled `label` of `mesh` (None if it has no area).
pub fn cap_flatness(mesh: &TriMesh, label: i32) -> Option<CapFlatness> {
    let (_, outward, area_mm2) = mesh.label_centroid_normal(label)?;
    let mut on_cap = vec![false; mesh.points.len()];
    for (tri, _) in mesh.triangles.iter().zip(&mesh.face_ids).filter(|(_, &f)| f == label) {
        tri.iter().for_each(|&v| on_cap[v as usize] = true);
    }
    let points: Vec<Vec3> = mesh.points.iter().zip(&on_cap).filter(|(_, &c)| c).map(|(p, _)| *p).collect();
    let fitted = best_fit_plane(&points);
    // Turned outward, still right-handed.
    let plane = if fitted.normal.dot(&outward) < 0.0 { Plane { normal: -fitted.normal, axis_v: -fitted.axis_v, ..fitted } } else { fitted };
    let off_plane_mm = points.iter().map(|p| plane.signed_distance_mm(p).abs()).fold(0.0, f64::max);
    let tolerance_mm = PLANAR_TOLERANCE_OF_DIAMETER * 2.0 * (area_mm2 / std::f64::consts::PI).sqrt();
    Some(CapFlatness { plane, area_mm2, off_plane_mm, tolerance_mm })
}

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
    fn phantom_caps_are_flat_and_a_bent_one_is_not() {
        let p = phantom_default();
        for label in [11, 16] {
            let flat = cap_flatness(&p.surface, label).unwrap();
            assert!(flat.is_planar() && flat.off_plane_mm < 1e-9, "{flat:?}");
            assert!(flat.plane.normal.dot(&p.surface.label_centroid_normal(label).unwrap().1) > 0.99, "outward");
            let reversed = TriMesh { triangles: p.surface.triangles.iter().map(|t| [t[0], t[2], t[1]]).collect(), ..p.surface.clone() };
            for plane in [flat.plane, cap_flatness(&reversed, label).unwrap().plane] {
                assert!((plane.axis_u.cross(&plane.axis_v) - plane.normal).norm() < 1e-12, "right-handed either way round");
            }
        }
        let mut bent = p.surface.clone();
        let flat = cap_flatness(&bent, 11).unwrap();
        // Every cap point moved by its squared distance from the centroid: a bowl.
        let on_cap: Vec<u32> = bent.triangles.iter().zip(&bent.face_ids).filter(|(_, &f)| f == 11).flat_map(|(t, _)| *t).collect();
        for v in on_cap.iter().collect::<std::collections::BTreeSet<_>>() {
            let p = bent.points[*v as usize];
            bent.points[*v as usize] += flat.plane.normal * 0.05 * (p - flat.plane.centroid).norm_squared();
        }
        let bowl = cap_flatness(&bent, 11).unwrap();
        assert!(!bowl.is_planar() && bowl.describe("VSD").contains("the VSD cap is not planar"), "{bowl:?}");
        assert!(cap_flatness(&bent, 99).is_none());
    }

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
