//! The openings between two blood pools measured on the segmentations themselves, not
//! on the union `prepare` cuts: the second method of prepare's check of its own caps.
//! Where pool `a` reaches into pool `b`, the curve on `a`'s surface where it enters `b`
//! (the zero level of the signed distance to `b`, traced on `a`'s triangles) is the rim
//! of the opening between them; the flat disc it spans is the opening a cap must close.

use baffle_core::geometry::spatial::{closest_point_on_segment, is_outside, TriangleBvh};
use baffle_core::{TriMesh, Vec3};
use rayon::prelude::*;
use std::collections::HashMap;

/// Points of `a` farther than this from `b` (mm) are not traced: they are outside by
/// far more than any opening's rim lies (the trace needs signs only near the rim).
const TRACE_WITHIN_MM: f64 = 5.0;

/// The flat disc an opening's rim spans.
#[derive(Clone, Debug)]
pub struct Opening {
    /// Area centroid of the rim's flat projection (mm), at the rim's mean height.
    pub centroid_mm: Vec3,
    /// Unit normal of the rim's vector area.
    pub normal: Vec3,
    /// Area of the rim's projection on the plane normal to `normal` (mm2).
    pub area_mm2: f64,
    /// Length of the rim (mm).
    pub perimeter_mm: f64,
    /// The rim as segments on `a`'s surface (mm).
    pub rim_mm: Vec<[Vec3; 2]>,
}

impl Opening {
    /// Smallest distance from `p` to the rim (mm).
    pub fn distance_to_rim_mm(&self, p: &Vec3) -> f64 {
        self.rim_mm.iter().map(|[a, b]| (closest_point_on_segment(p, a, b).0 - p).norm()).fold(f64::INFINITY, f64::min)
    }
}

/// The largest opening between pools `a` and `b` (closed, outward): the rim where `a`'s
/// surface enters `b`, or `None` where `a` nowhere reaches into `b`. Of several rims
/// (a second VSD, an island), the one spanning the largest area.
pub fn largest_opening(a: &TriMesh, b: &TriMesh, b_bvh: &TriangleBvh, reach_mm: f64) -> Option<Opening> {
    let signed: Vec<f64> = a
        .points
        .par_iter()
        .map(|&p| match b_bvh.closest_point_within(b, p, TRACE_WITHIN_MM) {
            Some(hit) if !is_outside(b, b_bvh, p) => -hit.distance_mm,
            Some(hit) => hit.distance_mm,
            None => TRACE_WITHIN_MM,
        })
        .map(|s| s - reach_mm)
        .collect();
    let segments = rim_segments(a, &signed);
    rims(&segments).into_iter().map(|rim| flat_disc(&rim)).max_by(|x, y| x.area_mm2.total_cmp(&y.area_mm2))
}

/// A rim segment between two crossing points, each named by the edge of `a` it lies on.
type Segment = [((u32, u32), Vec3); 2];

/// The zero level of `signed` on `a`'s triangles, each segment oriented so that the part
/// inside `b` lies to its left seen from outside (it then runs round the inside part
/// with `a`'s winding, and its vector area points out of `a` into `b`).
fn rim_segments(a: &TriMesh, signed: &[f64]) -> Vec<Segment> {
    let inside = |v: u32| signed[v as usize] < 0.0;
    let crossing = |u: u32, v: u32| {
        let (su, sv) = (signed[u as usize], signed[v as usize]);
        let (pu, pv) = (a.points[u as usize], a.points[v as usize]);
        (baffle_core::geometry::mesh::edge_key(u, v), pu + (su / (su - sv)) * (pv - pu))
    };
    let mut segments = Vec::new();
    for tri in &a.triangles {
        let edges = [0, 1, 2].map(|k| (tri[k], tri[(k + 1) % 3]));
        // Going round the triangle, the edge entering the inside part and the one leaving it.
        let entering = edges.iter().find(|&&(u, v)| !inside(u) && inside(v));
        let leaving = edges.iter().find(|&&(u, v)| inside(u) && !inside(v));
        if let (Some(&(u0, v0)), Some(&(u1, v1))) = (entering, leaving) {
            // The inside part's boundary runs entering -> inside corners -> leaving, then
            // back along the rim: leaving -> entering.
            segments.push([crossing(u1, v1), crossing(u0, v0)]);
        }
    }
    segments
}

/// The segments grouped into connected rims (crossing points shared by edge).
fn rims(segments: &[Segment]) -> Vec<Vec<[Vec3; 2]>> {
    let mut parent: HashMap<(u32, u32), (u32, u32)> = HashMap::new();
    fn root(parent: &mut HashMap<(u32, u32), (u32, u32)>, x: (u32, u32)) -> (u32, u32) {
        let mut r = x;
        while let Some(&p) = parent.get(&r).filter(|&&p| p != r) {
            r = p;
        }
        parent.insert(x, r);
        r
    }
    for [(ka, _), (kb, _)] in segments {
        let (ra, rb) = (root(&mut parent, *ka), root(&mut parent, *kb));
        if ra != rb {
            parent.insert(ra.max(rb), ra.min(rb));
        }
    }
    let mut by_root: HashMap<(u32, u32), Vec<[Vec3; 2]>> = HashMap::new();
    for [(ka, pa), (_, pb)] in segments {
        let r = root(&mut parent, *ka);
        by_root.entry(r).or_default().push([*pa, *pb]);
    }
    let mut out: Vec<(u32, u32, Vec<[Vec3; 2]>)> = by_root.into_iter().map(|(k, v)| (k.0, k.1, v)).collect();
    out.sort_by_key(|r| (r.0, r.1));
    out.into_iter().map(|r| r.2).collect()
}

/// The flat disc a closed rim of oriented segments spans: vector area, and the area
/// centroid of its projection, summed segment by segment (no ordering needed).
fn flat_disc(rim: &[[Vec3; 2]]) -> Opening {
    let n_points = 2.0 * rim.len() as f64;
    let origin = rim.iter().flat_map(|s| s.iter()).sum::<Vec3>() / n_points;
    let vector_area = 0.5 * rim.iter().map(|[p, q]| (p - origin).cross(&(q - origin))).sum::<Vec3>();
    let area_mm2 = vector_area.norm();
    let normal = if area_mm2 > 0.0 { vector_area / area_mm2 } else { Vec3::zeros() };
    let mut weighted = Vec3::zeros();
    for [p, q] in rim {
        let (dp, dq) = (p - origin, q - origin);
        let signed_area = 0.5 * normal.dot(&dp.cross(&dq));
        // The triangle (origin, p, q) projected onto the plane through the origin.
        let flat = |d: Vec3| d - normal * normal.dot(&d);
        weighted += signed_area * (flat(dp) + flat(dq)) / 3.0;
    }
    let centroid_mm = if area_mm2 > 0.0 { origin + weighted / area_mm2 } else { origin };
    let perimeter_mm = rim.iter().map(|[p, q]| (q - p).norm()).sum();
    Opening { centroid_mm, normal, area_mm2, perimeter_mm, rim_mm: rim.to_vec() }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::{capped_tube, uv_sphere};
    use std::f64::consts::PI;

    #[test]
    fn two_overlapping_spheres_open_onto_their_circle_of_intersection() {
        // Radical plane x0 = (16^2 + 10^2 - 9^2) / 32 = 8.59, circle radius sqrt(100 - x0^2).
        let lv = uv_sphere(Vec3::zeros(), 10.0, 96, 192);
        let rv = uv_sphere(Vec3::new(16.0, 0.0, 0.0), 9.0, 96, 192);
        let bvh = TriangleBvh::new(&rv).unwrap();
        let o = largest_opening(&lv, &rv, &bvh, 0.0).unwrap();
        let x0: f64 = (256.0 + 100.0 - 81.0) / 32.0;
        let radius: f64 = (100.0 - x0 * x0).sqrt();
        assert!((o.centroid_mm - Vec3::new(x0, 0.0, 0.0)).norm() < 0.02, "{:?}", o.centroid_mm);
        assert!(o.normal.x > 0.9999, "points out of the LV into the RV: {:?}", o.normal);
        assert!((o.area_mm2 / (PI * radius * radius) - 1.0).abs() < 0.005, "{} vs {}", o.area_mm2, PI * radius * radius);
        assert!((o.perimeter_mm / (2.0 * PI * radius) - 1.0).abs() < 0.005, "{}", o.perimeter_mm);
        assert!(o.distance_to_rim_mm(&Vec3::new(x0, radius, 0.0)) < 0.02);
    }

    #[test]
    fn a_tube_entering_a_sphere_opens_onto_its_section_and_apart_pools_have_none() {
        let rv = uv_sphere(Vec3::zeros(), 9.0, 96, 192);
        let aorta = capped_tube(Vec3::new(0.0, 0.0, 4.0), Vec3::new(0.0, 0.0, 25.0), 4.0, 40, 96);
        let bvh = TriangleBvh::new(&rv).unwrap();
        let o = largest_opening(&aorta, &rv, &bvh, 0.0).unwrap();
        let z = 65f64.sqrt();
        assert!((o.centroid_mm - Vec3::new(0.0, 0.0, z)).norm() < 0.05, "{:?}", o.centroid_mm);
        assert!(o.normal.z < -0.9999 && (o.area_mm2 / (PI * 16.0) - 1.0).abs() < 0.01, "{:?} {}", o.normal, o.area_mm2);
        let far = uv_sphere(Vec3::new(30.0, 0.0, 0.0), 2.0, 16, 32);
        assert!(largest_opening(&far, &rv, &bvh, 0.0).is_none());
    }
}
