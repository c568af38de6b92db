//! Perturbations of a valid surface for robustness tests and the fuzz harness: a
//! patch of wall pushed out (a bump, as a hypertrophied trabecula or a segmentation
//! leak would), noise, flipped triangles; and what real acquisitions do to an ideal
//! anatomy: a cap bent out of its plane (drawn with a plane tool on a segmentation, or
//! cut from a surface of 0.3-0.5 mm triangles), the scene in another pose, a smoothed
//! or a subdivided wall. Each but `subdivide` keeps the triangles' connectivity.

pub use baffle_core::geometry::numerics::random::SplitMix64;
use baffle_core::geometry::mesh::{TriMesh, Vec3};

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

/// The cap labelled `label` bent out of its plane by a smooth bump of height
/// `fraction_of_diameter` times its equivalent diameter, along its outward normal; the
/// rim stays where it is. The bump follows the distance to the rim d as h (d/d_max)(2 -
/// d/d_max): zero at the rim, `h` at the point farthest from it.
pub fn bend_cap(mesh: &TriMesh, label: i32, fraction_of_diameter: f64) -> TriMesh {
    let Some((_, normal, area_mm2)) = mesh.label_centroid_normal(label) else { return mesh.clone() };
    let height_mm = fraction_of_diameter * 2.0 * (area_mm2 / std::f64::consts::PI).sqrt();
    let (mut on_cap, mut on_other) = (vec![false; mesh.points.len()], vec![false; mesh.points.len()]);
    for (tri, &f) in mesh.triangles.iter().zip(&mesh.face_ids) {
        let marks = if f == label { &mut on_cap } else { &mut on_other };
        tri.iter().for_each(|&v| marks[v as usize] = true);
    }
    let rim: Vec<Vec3> = (0..mesh.points.len()).filter(|&v| on_cap[v] && on_other[v]).map(|v| mesh.points[v]).collect();
    let rim_distance = |p: &Vec3| rim.iter().map(|r| (r - p).norm()).fold(f64::INFINITY, f64::min);
    let inner: Vec<(usize, f64)> = (0..mesh.points.len()).filter(|&v| on_cap[v] && !on_other[v]).map(|v| (v, rim_distance(&mesh.points[v]))).collect();
    let d_max = inner.iter().map(|&(_, d)| d).fold(0.0, f64::max);
    let mut out = mesh.clone();
    for (v, d) in inner {
        let x = d / d_max.max(1e-300);
        out.points[v] += normal * height_mm * x * (2.0 - x);
    }
    out
}

/// The whole scene moved rigidly: rotated by `angle_rad` about the unit `axis` through
/// the origin, then translated by `translation_mm`.
pub fn rigid_motion(mesh: &TriMesh, axis: Vec3, angle_rad: f64, translation_mm: Vec3) -> TriMesh {
    let mut out = mesh.clone();
    out.points.iter_mut().for_each(|p| *p = rigid_motion_point(*p, axis, angle_rad, translation_mm));
    out
}

/// One point moved as [`rigid_motion`] moves the surface.
pub fn rigid_motion_point(p: Vec3, axis: Vec3, angle_rad: f64, translation_mm: Vec3) -> Vec3 {
    let rotation = nalgebra::Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), angle_rad);
    rotation * p + translation_mm
}

/// The wall smoothed as a segmentation tool smooths it: `iterations` Taubin rounds
/// (`smoothing`'s default lambda|mu) on the vertices whose triangles are all
/// `wall_label`, so the caps and their rims stay.
pub fn smooth_wall(mesh: &TriMesh, iterations: usize, wall_label: i32) -> TriMesh {
    let (_, wall_only) = vertex_normals_and_wall(mesh, wall_label);
    let pinned: Vec<bool> = wall_only.iter().map(|w| !w).collect();
    let mut out = mesh.clone();
    let options = baffle_core::geometry::smoothing::SmoothingOptions { iterations, ..Default::default() };
    let (start, neighbors) = baffle_core::geometry::smoothing::point_neighbors(mesh);
    baffle_core::geometry::smoothing::taubin_smooth_pinned(&mut out, &options, &pinned, (&start, &neighbors));
    out
}

/// Every triangle split into four at its edges' midpoints (labels kept): the same
/// surface with edges half as long, as a finer acquisition or export would give it.
pub fn subdivide(mesh: &TriMesh) -> TriMesh {
    let mut points = mesh.points.clone();
    let mut midpoint: std::collections::HashMap<(u32, u32), u32> = std::collections::HashMap::new();
    let mut mid = |a: u32, b: u32, points: &mut Vec<Vec3>| {
        *midpoint.entry(baffle_core::geometry::mesh::edge_key(a, b)).or_insert_with(|| {
            points.push(0.5 * (points[a as usize] + points[b as usize]));
            (points.len() - 1) as u32
        })
    };
    let (mut triangles, mut face_ids) = (Vec::new(), Vec::new());
    for (&[a, b, c], &f) in mesh.triangles.iter().zip(&mesh.face_ids) {
        let (ab, bc, ca) = (mid(a, b, &mut points), mid(b, c, &mut points), mid(c, a, &mut points));
        triangles.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
        face_ids.extend([f; 4]);
    }
    TriMesh::new(points, triangles, face_ids)
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
    use baffle_core::phantom::phantom_default;

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

    #[test]
    fn a_bent_cap_keeps_its_rim_and_rises_by_its_fraction_of_the_diameter() {
        let surface = phantom_default().surface;
        let (_, normal, area) = surface.label_centroid_normal(11).unwrap();
        let bent = bend_cap(&surface, 11, 0.02);
        let rise = surface.points.iter().zip(&bent.points).map(|(a, b)| (b - a).dot(&normal)).fold(0.0, f64::max);
        let diameter = 2.0 * (area / std::f64::consts::PI).sqrt();
        assert!(rise > 0.015 * diameter && rise <= 0.02 * diameter + 1e-9, "{rise} of {diameter}");
        let off_cap: std::collections::HashSet<u32> = surface.triangles.iter().zip(&surface.face_ids).filter(|(_, &f)| f != 11).flat_map(|(t, _)| *t).collect();
        assert!(off_cap.iter().all(|&v| surface.points[v as usize] == bent.points[v as usize]), "rim and wall fixed");
    }

    #[test]
    fn rigid_motion_keeps_shape_and_subdivision_keeps_the_surface() {
        let surface = phantom_default().surface;
        let moved = rigid_motion(&surface, Vec3::new(1.0, 2.0, 3.0), 0.7, Vec3::new(40.0, -120.0, 900.0));
        assert!((moved.signed_volume_mm3() / surface.signed_volume_mm3() - 1.0).abs() < 1e-9);
        assert!((moved.area_mm2() / surface.area_mm2() - 1.0).abs() < 1e-9);
        let fine = subdivide(&surface);
        assert_eq!(fine.triangles.len(), 4 * surface.triangles.len());
        assert!((fine.signed_volume_mm3() / surface.signed_volume_mm3() - 1.0).abs() < 1e-12);
        assert!(baffle_core::geometry::mesh::manifold_report(&fine).is_closed_manifold());
        let smooth = smooth_wall(&surface, 5, 2);
        assert!((smooth.signed_volume_mm3() / surface.signed_volume_mm3() - 1.0).abs() < 0.05);
    }
}
