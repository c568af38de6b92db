//! The realism family of `extend` (issue 27): a designed domain as a user may give
//! it, not as `design` writes it: its walls subdivided (finer triangles than the
//! union's voxels), noisy (a segmentation's jitter), smoothed; the whole scene
//! moved rigidly; a VSD cap that was bowed and projected back onto its plane by
//! hand (as the held-back patient's). Every perturbation keeps the caps planar
//! and the surface closed; none moves a cap point off its plane.

use baffle_core::geometry::numerics::pca::best_fit_plane;
use baffle_core::geometry::numerics::random::SplitMix64;
use baffle_core::{TriMesh, Vec3};
use baffle_prepare::BloodPools;
use nalgebra::{Rotation3, Unit};
use std::collections::HashSet;
use std::path::Path;

/// The paper's designed domain: cm -> mm, wound outward.
pub fn published_domain(path: &Path) -> TriMesh {
    let mut domain = baffle_core::io::read_surface(path).expect("published domain");
    domain.points.iter_mut().for_each(|p| *p *= 10.0);
    if domain.signed_volume_mm3() < 0.0 {
        domain.triangles.iter_mut().for_each(|t| t.swap(1, 2));
    }
    domain
}

/// Each triangle split in 4 at its edges' midpoints (labels kept): planar caps stay planar.
pub fn subdivided(mesh: &TriMesh) -> TriMesh {
    baffle_test_support::perturb::subdivide(mesh)
}

/// The points that no triangle of `caps` uses (they may move without bending a cap).
fn free_points(mesh: &TriMesh, caps: &[i32]) -> Vec<bool> {
    let on_cap: HashSet<u32> = mesh.triangles.iter().zip(&mesh.face_ids).filter(|(_, l)| caps.contains(l)).flat_map(|(t, _)| *t).collect();
    (0..mesh.points.len() as u32).map(|v| !on_cap.contains(&v)).collect()
}

/// Every wall point (not on a cap) moved by up to `amplitude_mm` along each axis.
pub fn noisy_walls(mesh: &TriMesh, caps: &[i32], amplitude_mm: f64, seed: u64) -> TriMesh {
    let free = free_points(mesh, caps);
    let mut rng = SplitMix64::new(seed);
    let mut out = mesh.clone();
    for (p, _) in out.points.iter_mut().zip(&free).filter(|(_, &f)| f) {
        *p += amplitude_mm * Vec3::new(rng.symmetric_unit(), rng.symmetric_unit(), rng.symmetric_unit());
    }
    out
}

/// Taubin smoothing (lambda 0.5, mu -0.53) of the wall points, caps and their rims fixed.
pub fn smoothed_walls(mesh: &TriMesh, caps: &[i32], iterations: usize) -> TriMesh {
    let free = free_points(mesh, caps);
    let mut neighbours: Vec<HashSet<u32>> = vec![HashSet::new(); mesh.points.len()];
    for t in &mesh.triangles {
        for k in 0..3 {
            neighbours[t[k] as usize].insert(t[(k + 1) % 3]);
            neighbours[t[(k + 1) % 3] as usize].insert(t[k]);
        }
    }
    let mut out = mesh.clone();
    for _ in 0..iterations {
        for factor in [0.5, -0.53] {
            let moved: Vec<Vec3> = (0..out.points.len())
                .map(|v| {
                    let ring = &neighbours[v];
                    if !free[v] || ring.is_empty() {
                        return out.points[v];
                    }
                    let mean = ring.iter().map(|&w| out.points[w as usize]).sum::<Vec3>() / ring.len() as f64;
                    out.points[v] + factor * (mean - out.points[v])
                })
                .collect();
            out.points = moved;
        }
    }
    out
}

/// The rotation by `angle_deg` about `axis` then the shift, applied to a point.
pub struct RigidMotion {
    pub rotation: Rotation3<f64>,
    pub shift_mm: Vec3,
}

impl RigidMotion {
    pub fn new(axis: Vec3, angle_deg: f64, shift_mm: Vec3) -> Self {
        RigidMotion { rotation: Rotation3::from_axis_angle(&Unit::new_normalize(axis), angle_deg.to_radians()), shift_mm }
    }

    pub fn point(&self, p: &Vec3) -> Vec3 {
        self.rotation * p + self.shift_mm
    }

    pub fn mesh(&self, mesh: &TriMesh) -> TriMesh {
        TriMesh { points: mesh.points.iter().map(|p| self.point(p)).collect(), ..mesh.clone() }
    }

    pub fn pools(&self, pools: &BloodPools) -> BloodPools {
        BloodPools { lv: self.mesh(&pools.lv), rv: self.mesh(&pools.rv), aorta: self.mesh(&pools.aorta) }
    }
}

/// The VSD cap bowed by `sag_mm` at its centre (a dome toward the LV, the wall within
/// a cap radius of the rim carried along smoothly) and then projected back onto its
/// best-fit plane by hand: the wall next to the rim keeps the bend.
pub fn bowed_then_projected_cap(mesh: &TriMesh, label: i32, sag_mm: f64) -> TriMesh {
    let cap_points: HashSet<u32> = mesh.triangles.iter().zip(&mesh.face_ids).filter(|(_, &l)| l == label).flat_map(|(t, _)| *t).collect();
    let pts: Vec<Vec3> = cap_points.iter().map(|&v| mesh.points[v as usize]).collect();
    let plane = best_fit_plane(&pts);
    let radius_mm = pts.iter().map(|p| (p - plane.centroid).norm()).fold(0.0, f64::max);
    let (_, toward_lv, _) = mesh.label_centroid_normal(label).expect("cap");
    let mut out = mesh.clone();
    for p in out.points.iter_mut() {
        let r = (*p - plane.centroid - (*p - plane.centroid).dot(&plane.normal) * plane.normal).norm() / radius_mm;
        // 1 at the centre, 0 at twice the cap's radius, smooth between.
        let w = if r < 2.0 { let s = r / 2.0; (1.0 - s * s).powi(2) } else { 0.0 };
        *p += sag_mm * w * toward_lv;
    }
    let refit = best_fit_plane(&cap_points.iter().map(|&v| out.points[v as usize]).collect::<Vec<_>>());
    for &v in &cap_points {
        let p = out.points[v as usize];
        out.points[v as usize] = p - refit.signed_distance_mm(&p) * refit.normal;
    }
    out
}
