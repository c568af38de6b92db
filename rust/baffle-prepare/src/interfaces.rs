//! Step 3: face labels by nearest structure, and the VSD (LV-RV) and aortic
//! (RV-aorta) loops from the label interfaces [paper 2.2.2]. Each loop is
//! regularized as the paper does: rays are cast in the best-fit plane of the raw
//! interface from its provisional centroid, the interface radius along each ray is
//! smoothed around the loop, and the points are reprojected onto the surface.

use baffle_core::geometry::numerics::pca::{best_fit_plane, Plane};
use baffle_core::geometry::spatial::TriangleBvh;
use baffle_core::{TriMesh, Vec3};
use rayon::prelude::*;
use std::f64::consts::PI;

/// A segmented structure: its label and its closed surface.
pub struct Structure<'a> {
    pub label: i32,
    pub surface: &'a TriMesh,
    pub bvh: &'a TriangleBvh,
}

/// The label of the structure nearest each triangle's centroid, for the
/// triangles within `keep_within_mm` of the first structure (the RV: only its
/// neighbourhood can end up in the capped ventricle); `None` for the others.
pub fn label_by_nearest(mesh: &TriMesh, structures: &[Structure], keep_within_mm: f64) -> Vec<Option<i32>> {
    (0..mesh.triangles.len())
        .into_par_iter()
        .map(|t| {
            let [a, b, c] = mesh.triangle_points(t);
            let centroid = (a + b + c) / 3.0;
            let (first, others) = structures.split_first()?;
            let hit = first.bvh.closest_point_within(first.surface, centroid, keep_within_mm)?;
            let mut best = (hit.distance_mm, first.label);
            for s in others {
                // Bounded by the best so far: most queries prune to a few leaves.
                if let Some(hit) = s.bvh.closest_point_within(s.surface, centroid, best.0) {
                    if hit.distance_mm < best.0 {
                        best = (hit.distance_mm, s.label);
                    }
                }
            }
            Some(best.1)
        })
        .collect()
}

#[derive(Clone, Debug)]
pub struct LoopOptions {
    /// Rays cast around the provisional centroid.
    pub rays: usize,
    /// Passes of [1 2 1] smoothing of the ray radii around the loop.
    pub smoothing_passes: usize,
}

impl Default for LoopOptions {
    fn default() -> Self {
        LoopOptions { rays: 96, smoothing_passes: 4 }
    }
}

/// A regularized interface loop on the surface.
#[derive(Clone, Debug)]
pub struct InterfaceLoop {
    /// Closed loop on the surface, in ray order.
    pub points_mm: Vec<Vec3>,
    /// Best-fit plane of `points_mm`: where the opening is clipped and capped.
    pub plane: Plane,
}

/// The mesh edges between a triangle labelled `a` and one labelled `b`.
pub fn interface_edges(mesh: &TriMesh, labels: &[i32], a: i32, b: i32) -> Vec<(u32, u32)> {
    let neighbors = mesh.triangle_neighbors();
    let mut edges = Vec::new();
    for (t, tri) in mesh.triangles.iter().enumerate() {
        if labels[t] != a {
            continue;
        }
        for k in 0..3 {
            let nb = neighbors[t][k];
            if nb != u32::MAX && labels[nb as usize] == b {
                edges.push((tri[k], tri[(k + 1) % 3]));
            }
        }
    }
    edges
}

/// The connected set of edges with the greatest total length (the main loop;
/// islands of the other label give small separate ones).
fn longest_edge_component(mesh: &TriMesh, edges: &[(u32, u32)]) -> Vec<(u32, u32)> {
    let mut parent: std::collections::HashMap<u32, u32> = std::collections::HashMap::new();
    fn find(parent: &mut std::collections::HashMap<u32, u32>, x: u32) -> u32 {
        let p = *parent.entry(x).or_insert(x);
        if p == x {
            return x;
        }
        let root = find(parent, p);
        parent.insert(x, root);
        root
    }
    for &(a, b) in edges {
        let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
        parent.insert(ra.max(rb), ra.min(rb));
    }
    let mut length: std::collections::HashMap<u32, f64> = std::collections::HashMap::new();
    let roots: Vec<u32> = edges.iter().map(|&(a, _)| find(&mut parent, a)).collect();
    for (&(a, b), &r) in edges.iter().zip(&roots) {
        *length.entry(r).or_default() += (mesh.points[a as usize] - mesh.points[b as usize]).norm();
    }
    let best = length.into_iter().max_by(|x, y| x.1.total_cmp(&y.1).then(y.0.cmp(&x.0))).map(|(r, _)| r);
    edges.iter().zip(&roots).filter(|(_, &r)| Some(r) == best).map(|(&e, _)| e).collect()
}

/// The regularized loop between the regions labelled `a` and `b`, or `None`
/// when they do not touch.
pub fn interface_loop(
    mesh: &TriMesh,
    bvh: &TriangleBvh,
    labels: &[i32],
    (a, b): (i32, i32),
    options: &LoopOptions,
) -> Option<InterfaceLoop> {
    let edges = interface_edges(mesh, labels, a, b);
    if edges.len() < 3 {
        return None;
    }
    let main = longest_edge_component(mesh, &edges);
    let raw: Vec<Vec3> = main.iter().map(|&(p, q)| 0.5 * (mesh.points[p as usize] + mesh.points[q as usize])).collect();
    let provisional = best_fit_plane(&raw);
    let radii = smoothed_ray_radii(&provisional, &raw, options);
    let points_mm: Vec<Vec3> = radii
        .iter()
        .enumerate()
        .map(|(k, &r)| {
            let angle = 2.0 * PI * k as f64 / radii.len() as f64;
            let p = provisional.point_at(r * angle.cos(), r * angle.sin());
            bvh.closest_point(mesh, p).map_or(p, |hit| hit.point)
        })
        .collect();
    let plane = best_fit_plane(&points_mm);
    Some(InterfaceLoop { points_mm, plane })
}

/// Radius of the raw interface along each of `options.rays` rays from the plane's
/// centroid (the farthest interface point within the ray's angular sector), gaps
/// filled from the neighbouring rays, then smoothed around the loop.
fn smoothed_ray_radii(plane: &Plane, raw: &[Vec3], options: &LoopOptions) -> Vec<f64> {
    let n = options.rays.max(8);
    let mut radii = vec![f64::NAN; n];
    for p in raw {
        let (u, v) = plane.project_2d(p);
        let sector = ((v.atan2(u).rem_euclid(2.0 * PI)) / (2.0 * PI) * n as f64).round() as usize % n;
        let r = u.hypot(v);
        if radii[sector].is_nan() || r > radii[sector] {
            radii[sector] = r;
        }
    }
    fill_gaps_circular(&mut radii);
    for _ in 0..options.smoothing_passes {
        let prev = radii.clone();
        for k in 0..n {
            radii[k] = 0.25 * prev[(k + n - 1) % n] + 0.5 * prev[k] + 0.25 * prev[(k + 1) % n];
        }
    }
    radii
}

/// Replace NaN entries by linear interpolation between the nearest known entries
/// on either side (around the circle).
fn fill_gaps_circular(values: &mut [f64]) {
    let n = values.len();
    let known: Vec<usize> = (0..n).filter(|&k| !values[k].is_nan()).collect();
    if known.is_empty() {
        values.iter_mut().for_each(|v| *v = 0.0);
        return;
    }
    for k in 0..n {
        if !values[k].is_nan() {
            continue;
        }
        let after = known.iter().copied().find(|&i| i > k).unwrap_or(known[0] + n);
        let before = known.iter().rev().copied().find(|&i| i < k).map_or(known[known.len() - 1] as i64 - n as i64, |i| i as i64);
        let (va, vb) = (values[after % n], values[before.rem_euclid(n as i64) as usize]);
        let w = (k as i64 - before) as f64 / (after as i64 - before) as f64;
        values[k] = vb + w * (va - vb);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::uv_sphere;

    #[test]
    fn gaps_are_filled_around_the_circle() {
        let mut v = vec![f64::NAN, 2.0, f64::NAN, 4.0, f64::NAN, f64::NAN];
        fill_gaps_circular(&mut v);
        assert_eq!(v[2], 3.0);
        // Between index 3 (4.0) and index 1 + 6 (2.0), in quarters.
        assert_eq!([v[4], v[5], v[0]], [3.5, 3.0, 2.5], "{v:?}");
    }

    #[test]
    fn the_equator_between_two_labelled_hemispheres_is_recovered() {
        let sphere = uv_sphere(Vec3::new(1.0, 2.0, 3.0), 5.0, 40, 80);
        let labels: Vec<i32> = (0..sphere.triangles.len())
            .map(|t| if sphere.triangle_points(t).iter().map(|p| p.z).sum::<f64>() > 9.0 { 1 } else { 2 })
            .collect();
        let bvh = TriangleBvh::new(&sphere).unwrap();
        let lp = interface_loop(&sphere, &bvh, &labels, (1, 2), &LoopOptions::default()).unwrap();
        assert!(lp.plane.normal.z.abs() > 0.999, "{:?}", lp.plane.normal);
        assert!((lp.plane.centroid - Vec3::new(1.0, 2.0, 3.0)).norm() < 0.05, "{:?}", lp.plane.centroid);
        assert!(interface_loop(&sphere, &bvh, &labels, (1, 6), &LoopOptions::default()).is_none());
    }

    #[test]
    fn nearest_structure_labels() {
        let a = uv_sphere(Vec3::zeros(), 1.0, 8, 16);
        let b = uv_sphere(Vec3::new(10.0, 0.0, 0.0), 1.0, 8, 16);
        let (ba, bb) = (TriangleBvh::new(&a).unwrap(), TriangleBvh::new(&b).unwrap());
        let probe = uv_sphere(Vec3::new(7.0, 0.0, 0.0), 0.5, 4, 8);
        let first_a = [Structure { label: 1, surface: &a, bvh: &ba }, Structure { label: 2, surface: &b, bvh: &bb }];
        assert!(label_by_nearest(&probe, &first_a, 7.0).iter().all(|&l| l == Some(2)));
        assert!(label_by_nearest(&probe, &first_a, 5.0).iter().all(|&l| l.is_none()), "beyond 5 mm of the first structure");
        let first_b = [Structure { label: 2, surface: &b, bvh: &bb }, Structure { label: 1, surface: &a, bvh: &ba }];
        assert!(label_by_nearest(&probe, &first_b, 5.0).iter().all(|&l| l == Some(2)));
    }
}
