//! Perturbations of a valid surface for robustness tests and the fuzz harness: a
//! patch of wall pushed out (a bump, as a hypertrophied trabecula or a segmentation
//! leak would), noise, flipped triangles. Each keeps the triangles' connectivity.

pub use crate::numerics::random::SplitMix64;
use crate::mesh::{TriMesh, Vec3};

/// Move the `count` wall vertices nearest to point `center` (only vertices whose
/// triangles are all labelled `wall_label`, so cap rims stay planar) by `height_mm`
/// along their area-weighted normals.
pub fn bump_wall(mesh: &TriMesh, center: usize, count: usize, height_mm: f64, wall_label: i32) -> TriMesh {
    let (normals, wall_only) = vertex_normals_and_wall(mesh, wall_label);
    let c = mesh.points[center.min(mesh.points.len().saturating_sub(1))];
    let mut patch: Vec<usize> = (0..mesh.points.len()).filter(|&v| wall_only[v]).collect();
    patch.sort_by(|&a, &b| (mesh.points[a] - c).norm_squared().total_cmp(&(mesh.points[b] - c).norm_squared()));
    let mut out = mesh.clone();
    for &v in patch.iter().take(count) {
        if let Some(n) = normals[v].try_normalize(0.0) {
            out.points[v] += n * height_mm;
        }
    }
    out
}

/// Move every vertex by `amplitude_mm` times a pseudo-random vector of each
/// component in [-1, 1] (deterministic in `seed`).
pub fn jitter(mesh: &TriMesh, amplitude_mm: f64, seed: u64) -> TriMesh {
    let mut rng = SplitMix64::new(seed);
    let mut out = mesh.clone();
    for p in &mut out.points {
        *p += Vec3::new(rng.symmetric_unit(), rng.symmetric_unit(), rng.symmetric_unit()) * amplitude_mm;
    }
    out
}

/// Reverse the winding of triangle `t`.
pub fn flip_triangle(mesh: &TriMesh, t: usize) -> TriMesh {
    let mut out = mesh.clone();
    if let Some(tri) = out.triangles.get_mut(t) {
        tri.swap(1, 2);
    }
    out
}

fn vertex_normals_and_wall(mesh: &TriMesh, wall_label: i32) -> (Vec<Vec3>, Vec<bool>) {
    let mut normals = vec![Vec3::zeros(); mesh.points.len()];
    let mut wall_only = vec![true; mesh.points.len()];
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let n = mesh.triangle_normal2(t);
        for &v in tri {
            normals[v as usize] += n;
            wall_only[v as usize] &= mesh.face_ids[t] == wall_label;
        }
    }
    (normals, wall_only)
}


#[cfg(test)]
mod tests {
    use super::*;
    use crate::phantom::phantom_default;

    #[test]
    fn a_bump_moves_only_wall_vertices_by_its_height() {
        let surface = phantom_default().surface;
        let bumped = bump_wall(&surface, 0, 30, 2.0, 2);
        let moved: Vec<f64> = surface.points.iter().zip(&bumped.points).map(|(a, b)| (a - b).norm()).filter(|d| *d > 0.0).collect();
        assert_eq!(moved.len(), 30);
        assert!(moved.iter().all(|d| (d - 2.0).abs() < 1e-9), "{moved:?}");
        assert_eq!(bumped.triangles, surface.triangles);
    }

    #[test]
    fn jitter_is_deterministic_and_bounded() {
        let surface = phantom_default().surface;
        let (a, b) = (jitter(&surface, 0.1, 7), jitter(&surface, 0.1, 7));
        assert_eq!(a.points, b.points);
        assert!(surface.points.iter().zip(&a.points).all(|(p, q)| (p - q).amax() <= 0.1 + 1e-12));
    }
}
