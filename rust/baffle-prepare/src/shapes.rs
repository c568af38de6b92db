//! Closed, outward-wound test shapes (spheres, capped tubes, boxes) for the
//! synthetic LV / RV / aorta case the tests use when no patient data is present.

use baffle_core::geometry::mesh::axes_across;
use baffle_core::{TriMesh, Vec3};
use std::f64::consts::PI;

/// A latitude-longitude sphere: `rings` bands pole to pole, `segments` around.
pub fn uv_sphere(center: Vec3, radius_mm: f64, rings: usize, segments: usize) -> TriMesh {
    let circles: Vec<Vec<Vec3>> = (1..rings)
        .map(|r| {
            let theta = PI * r as f64 / rings as f64;
            (0..segments)
                .map(|s| {
                    let phi = 2.0 * PI * s as f64 / segments as f64;
                    center + radius_mm * Vec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos())
                })
                .collect()
        })
        .collect();
    let pole = Vec3::new(0.0, 0.0, radius_mm);
    ring_stack(center + pole, &circles, center - pole)
}

/// A closed tube of radius `radius_mm` from `start` to `end`, flat ends.
pub fn capped_tube(start: Vec3, end: Vec3, radius_mm: f64, rings: usize, segments: usize) -> TriMesh {
    let axis = end - start;
    let w = axis.normalize();
    let (u, v) = axes_across(&w);
    let circles: Vec<Vec<Vec3>> = (0..=rings)
        .map(|r| {
            let c = start + axis * (r as f64 / rings as f64);
            (0..segments)
                .map(|s| {
                    let phi = 2.0 * PI * s as f64 / segments as f64;
                    c + radius_mm * (phi.cos() * u + phi.sin() * v)
                })
                .collect()
        })
        .collect();
    ring_stack(start, &circles, end)
}

/// A closed surface through equal-sized rings, fanned to `first` and `last`,
/// wound outward.
fn ring_stack(first: Vec3, rings: &[Vec<Vec3>], last: Vec3) -> TriMesh {
    let segments = rings[0].len();
    let mut points = vec![first];
    rings.iter().for_each(|r| points.extend(r));
    points.push(last);
    let last_index = (points.len() - 1) as u32;
    let at = |r: usize, s: usize| (1 + r * segments + s % segments) as u32;
    let mut triangles = Vec::new();
    for s in 0..segments {
        triangles.push([0, at(0, s), at(0, s + 1)]);
        triangles.push([last_index, at(rings.len() - 1, s + 1), at(rings.len() - 1, s)]);
        for r in 0..rings.len() - 1 {
            let (a, b, c, d) = (at(r, s), at(r, s + 1), at(r + 1, s), at(r + 1, s + 1));
            triangles.push([a, c, d]);
            triangles.push([a, d, b]);
        }
    }
    let n = triangles.len();
    let mut mesh = TriMesh::new(points, triangles, vec![0; n]);
    if mesh.signed_volume_mm3() < 0.0 {
        mesh.triangles.iter_mut().for_each(|t| t.swap(1, 2));
    }
    mesh
}

/// An axis-aligned box, outward-wound.
pub fn box_mesh(lo: Vec3, hi: Vec3) -> TriMesh {
    let points: Vec<Vec3> =
        (0..8).map(|c| Vec3::new(if c & 1 == 0 { lo.x } else { hi.x }, if c & 2 == 0 { lo.y } else { hi.y }, if c & 4 == 0 { lo.z } else { hi.z })).collect();
    let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
    let triangles: Vec<[u32; 3]> = quads.iter().flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]).collect();
    TriMesh::new(points, triangles, vec![0; 12])
}

#[cfg(test)]
mod tests {
    use super::*;
    use baffle_core::geometry::mesh::manifold_report;

    #[test]
    fn shapes_are_closed_and_outward() {
        for mesh in [
            uv_sphere(Vec3::zeros(), 2.0, 12, 24),
            capped_tube(Vec3::zeros(), Vec3::new(1.0, 2.0, 3.0), 1.0, 4, 16),
            box_mesh(Vec3::zeros(), Vec3::new(1.0, 2.0, 3.0)),
        ] {
            let r = manifold_report(&mesh);
            assert!(r.is_closed_manifold() && r.inconsistently_wound_edges == 0, "{r:?}");
            assert!(mesh.signed_volume_mm3() > 0.0);
        }
        assert!((box_mesh(Vec3::zeros(), Vec3::new(1.0, 2.0, 3.0)).signed_volume_mm3() - 6.0).abs() < 1e-12);
    }
}

/// A synthetic heart as segment surfaces, for the sample run and the tests: LV and RV
/// spheres overlapping (the VSD faces -x at x = 8.6 mm), an aorta tube of radius 4 mm
/// leaving the RV's top (the aortic cap at z = 8.1 mm), and 18 suture points on the RV
/// sphere, 46 degrees around the quarter circle from the VSD's direction (-x) to the
/// aorta's (+z), so that they enclose both caps. All in one frame (taken as LPS).
pub struct SyntheticHeart {
    pub lv: TriMesh,
    pub rv: TriMesh,
    pub aorta: TriMesh,
    pub suture_points_mm: Vec<Vec3>,
    /// 0.2 m2: a 37.7 mm2 target area, below the 52 mm2 aortic cap of the 4 mm tube.
    pub bsa_m2: f64,
}

pub fn synthetic_heart() -> SyntheticHeart {
    let (rv_center, rv_radius) = (Vec3::new(16.0, 0.0, 0.0), 9.0);
    SyntheticHeart {
        lv: uv_sphere(Vec3::zeros(), 10.0, 32, 64),
        rv: uv_sphere(rv_center, rv_radius, 32, 64),
        aorta: capped_tube(Vec3::new(16.0, 0.0, 4.0), Vec3::new(16.0, 0.0, 25.0), 4.0, 12, 48),
        suture_points_mm: suture_ring(rv_center, rv_radius, -Vec3::x(), Vec3::z(), 46f64.to_radians()),
        bsa_m2: 0.2,
    }
}

/// 18 points on the sphere (`center`, `radius_mm`) enclosing the directions `vsd` and
/// `aorta` (unit vectors from the centre, not parallel): `rho` (radians) to either side
/// of the great-circle arc between them (6 points each side) and around each end beyond
/// it (3 points each).
pub fn suture_ring(center: Vec3, radius_mm: f64, vsd: Vec3, aorta: Vec3, rho: f64) -> Vec<Vec3> {
    tapered_suture_ring(center, radius_mm, vsd, aorta, rho, rho)
}

/// `suture_ring` with its own distance at each end: `rho_vsd` round the VSD's end,
/// `rho_aorta` round the aorta's, the side points in between going linearly from one to the
/// other, so that the ring can follow two openings of different sizes.
pub fn tapered_suture_ring(center: Vec3, radius_mm: f64, vsd: Vec3, aorta: Vec3, rho_vsd: f64, rho_aorta: f64) -> Vec<Vec3> {
    shaped_suture_ring(center, radius_mm, vsd, aorta, rho_vsd, rho_aorta, &|k| rho_vsd + (rho_aorta - rho_vsd) * k as f64 / 5.0)
}

/// `tapered_suture_ring` whose kth side point (k = 0 at the VSD's end to 5 at the aorta's, at
/// k / 5 of the arc) lies `side_rho(k)` (radians) to either side of the arc (k = 0 and 5
/// should give the ends' own distances), so that the suture line can pinch the tunnel
/// between the openings.
pub fn shaped_suture_ring(center: Vec3, radius_mm: f64, vsd: Vec3, aorta: Vec3, rho_vsd: f64, rho_aorta: f64, side_rho: &dyn Fn(usize) -> f64) -> Vec<Vec3> {
    let toward = (aorta - vsd * vsd.dot(&aorta)).normalize();
    let span = vsd.dot(&aorta).clamp(-1.0, 1.0).acos();
    let side = vsd.cross(&toward);
    let arc = |t: f64| vsd * t.cos() + toward * t.sin();
    let beyond_aorta = toward * span.cos() - vsd * span.sin();
    let around = |end: Vec3, away: Vec3, phi: f64, rho: f64| end * rho.cos() + (away * phi.cos() + side * phi.sin()) * rho.sin();
    let quarter = PI / 2.0;
    let mut directions: Vec<Vec3> = (0..=5).map(|k| arc(span * k as f64 / 5.0) * side_rho(k).cos() + side * side_rho(k).sin()).collect();
    directions.extend((1..4).map(|k| around(aorta, beyond_aorta, quarter - PI * k as f64 / 4.0, rho_aorta)));
    directions.extend((0..=5).rev().map(|k| arc(span * k as f64 / 5.0) * side_rho(k).cos() - side * side_rho(k).sin()));
    directions.extend((1..4).map(|k| around(vsd, -toward, -quarter + PI * k as f64 / 4.0, rho_vsd)));
    directions.iter().map(|d| center + d.normalize() * radius_mm).collect()
}
