//! A flat cap inside an outline that is not star-shaped about its centroid (a cut
//! through a bent or pinched chamber), with near-isotropic triangles of about one rim
//! edge instead of an ear-clipped fan.
//!
//! An ear-clipped cap is a fan of slivers whose edges span the whole outline (up to
//! 47 mm, quality 0, on p1's mid-LV cut at 0.6 mm): gmsh cannot recover such a
//! boundary without Steiner points and its Delaunay refinement then did not finish in
//! 21 min. So the fan only seeds the cap: points of a triangular lattice at the rim's
//! edge length, at least 0.6 of it inside the rim, are inserted one by one with Lawson
//! flips (a constrained Delaunay triangulation: the rim edges are never flipped), and
//! the inserted points are then smoothed. Rim vertices are the wall's and never move,
//! so the cap still closes the wall.

use crate::polygon2d::{distance_to_polygon_mm, inside_polygon, orient};
use baffle_core::geometry::numerics::pca::Plane;
use baffle_core::Vec3;
use std::collections::HashMap;

/// Lattice points closer than this fraction of the edge to the rim are left out, so
/// no triangle between them and the rim is much shorter than the rim's own edges.
const RIM_CLEARANCE: f64 = 0.6;
/// Rounds of smoothing of the inserted points (each followed by Delaunay flips).
const SMOOTHING_ROUNDS: usize = 3;

/// The cap's working triangulation: rim vertices first (`rim_count` of them, fixed),
/// then the inserted points; `edges` maps each directed edge (a, b) to its triangle.
struct CapMesh {
    uv: Vec<(f64, f64)>,
    triangles: Vec<[usize; 3]>,
    edges: HashMap<(usize, usize), usize>,
    rim_count: usize,
    /// +1 when the cap runs counter-clockwise in the plane's (u, v).
    sense: f64,
    /// Round-off allowance of the in-circle test (a length^4).
    in_circle_tolerance: f64,
    /// The larger side of the cap's bounding box in the plane (mm).
    extent_mm: f64,
}

/// Triangulate the cap inside `outline` (wound as the cap should be) seeded by `fan`
/// (its ear-clipping, over local indices into `outline`), at about `edge_mm`. New
/// points are appended to `points`; returns the cap's triangles in `points`' indices.
pub(crate) fn refine_planar_cap(points: &mut Vec<Vec3>, outline: &[u32], fan: &[[usize; 3]], plane: &Plane, edge_mm: f64) -> Vec<[u32; 3]> {
    let rim: Vec<(f64, f64)> = outline.iter().map(|&v| plane.project_2d(&points[v as usize])).collect();
    let mut cap = CapMesh::new(rim.clone(), fan);
    cap.make_delaunay();
    for p in lattice_inside(&rim, edge_mm) {
        cap.insert(p);
    }
    for _ in 0..SMOOTHING_ROUNDS {
        cap.smooth_inserted_points();
        cap.make_delaunay();
    }
    let global: Vec<u32> = outline
        .iter()
        .copied()
        .chain(cap.uv[cap.rim_count..].iter().map(|&(u, v)| {
            points.push(plane.point_at(u, v));
            (points.len() - 1) as u32
        }))
        .collect();
    cap.triangles.iter().map(|t| t.map(|v| global[v])).collect()
}

/// Points of a triangular lattice of spacing `edge_mm` inside the closed polygon
/// `rim`, each at least `RIM_CLEARANCE * edge_mm` from it.
fn lattice_inside(rim: &[(f64, f64)], edge_mm: f64) -> Vec<(f64, f64)> {
    let (lo, hi) = bounds(rim);
    let row_step = edge_mm * 3f64.sqrt() / 2.0;
    let rows = ((hi.1 - lo.1) / row_step).ceil() as usize;
    let columns = ((hi.0 - lo.0) / edge_mm).ceil() as usize + 1;
    (0..=rows)
        .flat_map(|r| {
            let shift = if r % 2 == 1 { edge_mm / 2.0 } else { 0.0 };
            (0..=columns).map(move |c| (lo.0 + shift + c as f64 * edge_mm, lo.1 + r as f64 * row_step))
        })
        .filter(|&p| inside_polygon(rim, p) && distance_to_polygon_mm(rim, p) >= RIM_CLEARANCE * edge_mm)
        .collect()
}

fn bounds(points: &[(f64, f64)]) -> ((f64, f64), (f64, f64)) {
    points.iter().fold(((f64::MAX, f64::MAX), (f64::MIN, f64::MIN)), |(lo, hi), p| {
        ((lo.0.min(p.0), lo.1.min(p.1)), (hi.0.max(p.0), hi.1.max(p.1)))
    })
}

/// Positive when `d` lies inside the circumcircle of the counter-clockwise (a, b, c).
fn in_circle(a: (f64, f64), b: (f64, f64), c: (f64, f64), d: (f64, f64)) -> f64 {
    let row = |p: (f64, f64)| (p.0 - d.0, p.1 - d.1, (p.0 - d.0).powi(2) + (p.1 - d.1).powi(2));
    let (a, b, c) = (row(a), row(b), row(c));
    a.0 * (b.1 * c.2 - c.1 * b.2) - a.1 * (b.0 * c.2 - c.0 * b.2) + a.2 * (b.0 * c.1 - c.0 * b.1)
}

impl CapMesh {
    fn new(rim: Vec<(f64, f64)>, fan: &[[usize; 3]]) -> Self {
        let sense = fan.iter().map(|&[a, b, c]| orient(rim[a], rim[b], rim[c])).sum::<f64>().signum();
        let (lo, hi) = bounds(&rim);
        let extent = (hi.0 - lo.0).max(hi.1 - lo.1).max(1e-3);
        let mut cap = CapMesh {
            rim_count: rim.len(),
            uv: rim,
            triangles: Vec::with_capacity(fan.len()),
            edges: HashMap::new(),
            sense,
            in_circle_tolerance: 1e-12 * extent.powi(4),
            extent_mm: extent,
        };
        for &t in fan {
            cap.push_triangle(t);
        }
        cap
    }

    fn push_triangle(&mut self, tri: [usize; 3]) {
        self.triangles.push([usize::MAX; 3]);
        self.set_triangle(self.triangles.len() - 1, tri);
    }

    fn set_triangle(&mut self, t: usize, tri: [usize; 3]) {
        let old = self.triangles[t];
        if old[0] != usize::MAX {
            for k in 0..3 {
                // A flip hands one directed edge from one triangle to the other.
                let edge = (old[k], old[(k + 1) % 3]);
                if self.edges.get(&edge) == Some(&t) {
                    self.edges.remove(&edge);
                }
            }
        }
        for k in 0..3 {
            self.edges.insert((tri[k], tri[(k + 1) % 3]), t);
        }
        self.triangles[t] = tri;
    }

    /// The corner of triangle `t` opposite its directed edge (a, b).
    fn apex(&self, t: usize, a: usize, b: usize) -> usize {
        self.triangles[t].into_iter().find(|&v| v != a && v != b).unwrap_or(a)
    }

    /// Flip the edge (a, b) of triangle `t` when it is not locally Delaunay (its
    /// opposite apex inside the circumcircle). A locally non-Delaunay edge always has a
    /// convex quadrilateral, so the flip is valid. Returns the quadrilateral's four
    /// sides, which may then need a flip, or none.
    fn flip_if_illegal(&mut self, t: usize, a: usize, b: usize) -> Option<[(usize, usize, usize); 4]> {
        let u = *self.edges.get(&(b, a))?;
        let c = self.apex(t, a, b);
        let d = self.apex(u, b, a);
        let (pa, pb, pc, pd) = (self.uv[a], self.uv[b], self.uv[c], self.uv[d]);
        if self.sense * orient(pa, pb, pc) <= 0.0 || self.sense * in_circle(pa, pb, pc, pd) <= self.in_circle_tolerance {
            return None;
        }
        // (a, b, c) + (b, a, d) -> (c, a, d) + (d, b, c): the same winding.
        self.set_triangle(t, [c, a, d]);
        self.set_triangle(u, [d, b, c]);
        Some([(t, c, a), (t, a, d), (u, d, b), (u, b, c)])
    }

    /// Lawson flips over every edge until all are locally Delaunay.
    fn make_delaunay(&mut self) {
        let mut stack: Vec<(usize, usize, usize)> =
            (0..self.triangles.len()).flat_map(|t| (0..3).map(move |k| (t, k))).map(|(t, k)| (t, self.triangles[t][k], self.triangles[t][(k + 1) % 3])).collect();
        self.legalize(&mut stack);
    }

    fn legalize(&mut self, stack: &mut Vec<(usize, usize, usize)>) {
        // Each flip strictly increases the triangulation's smallest angles (Lawson), so
        // this ends; the cap is a guard against round-off cycling.
        let mut budget = 100 * (self.triangles.len() + 10) * (self.triangles.len() + 10).ilog2() as usize;
        while let Some((t, a, b)) = stack.pop() {
            // The triangle may have changed since this edge was pushed.
            if self.edges.get(&(a, b)) != Some(&t) || budget == 0 {
                continue;
            }
            budget -= 1;
            if let Some(next) = self.flip_if_illegal(t, a, b) {
                stack.extend(next);
            }
        }
    }

    /// Insert `p` into the triangle that contains it (three new triangles) and restore
    /// the Delaunay property around it. A point on an edge is left out: the lattice
    /// has others about an edge away.
    fn insert(&mut self, p: (f64, f64)) {
        let margin = 1e-9 * self.extent_mm * self.extent_mm;
        let Some(t) = (0..self.triangles.len()).find(|&t| {
            let [a, b, c] = self.triangles[t];
            [(a, b), (b, c), (c, a)].iter().all(|&(x, y)| self.sense * orient(self.uv[x], self.uv[y], p) > margin)
        }) else {
            return;
        };
        let [a, b, c] = self.triangles[t];
        self.uv.push(p);
        let v = self.uv.len() - 1;
        self.set_triangle(t, [a, b, v]);
        self.push_triangle([b, c, v]);
        self.push_triangle([c, a, v]);
        let (t_bc, t_ca) = (self.triangles.len() - 2, self.triangles.len() - 1);
        let mut stack = vec![(t, a, b), (t_bc, b, c), (t_ca, c, a)];
        self.legalize(&mut stack);
    }

    /// Move each inserted point to the mean of its neighbours (Laplacian smoothing in
    /// the plane) unless that would turn one of its triangles over.
    fn smooth_inserted_points(&mut self) {
        let mut neighbours: Vec<Vec<usize>> = vec![Vec::new(); self.uv.len()];
        let mut incident: Vec<Vec<usize>> = vec![Vec::new(); self.uv.len()];
        for (t, tri) in self.triangles.iter().enumerate() {
            for k in 0..3 {
                neighbours[tri[k]].push(tri[(k + 1) % 3]);
                incident[tri[k]].push(t);
            }
        }
        for v in self.rim_count..self.uv.len() {
            let ring = &neighbours[v];
            if ring.is_empty() {
                continue;
            }
            let n = ring.len() as f64;
            let mean = ring.iter().fold((0.0, 0.0), |s, &w| (s.0 + self.uv[w].0 / n, s.1 + self.uv[w].1 / n));
            let keeps_orientation = incident[v].iter().all(|&t| {
                let corner = |w: usize| if w == v { mean } else { self.uv[w] };
                let [a, b, c] = self.triangles[t];
                self.sense * orient(corner(a), corner(b), corner(c)) > 0.0
            });
            if keeps_orientation {
                self.uv[v] = mean;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::capping::ear_clip;

    fn square_plane() -> Plane {
        Plane { centroid: Vec3::zeros(), normal: Vec3::z(), axis_u: Vec3::x(), axis_v: Vec3::y(), singular_values: [1.0, 1.0, 0.0] }
    }

    /// A crescent (not star-shaped about its centroid) of rim edges about 1 mm.
    fn crescent() -> Vec<Vec3> {
        let arc = |r: f64, from: f64, to: f64, n: usize| -> Vec<Vec3> {
            (0..n).map(|i| from + (to - from) * i as f64 / n as f64).map(|a| Vec3::new(r * a.cos(), r * a.sin(), 0.0)).collect()
        };
        let (outer_r, inner_r) = (20.0, 14.0);
        let span = 1.5 * std::f64::consts::PI;
        // Outer arc, radial side, inner arc back, radial side: 1 mm apart everywhere.
        let radial = |angle: f64, from: f64, to: f64| -> Vec<Vec3> {
            let n = (to - from).abs().round() as usize;
            (0..n).map(|i| from + (to - from) * i as f64 / n as f64).map(|r| Vec3::new(r * angle.cos(), r * angle.sin(), 0.0)).collect()
        };
        let mut rim = arc(outer_r, 0.0, span, (outer_r * span).round() as usize);
        rim.extend(radial(span, outer_r, inner_r));
        rim.extend(arc(inner_r, span, 0.0, (inner_r * span).round() as usize));
        rim.extend(radial(0.0, inner_r, outer_r));
        rim
    }

    fn quality(p: &[Vec3], [a, b, c]: [u32; 3]) -> f64 {
        let (a, b, c) = (p[a as usize], p[b as usize], p[c as usize]);
        let area = 0.5 * (b - a).cross(&(c - a)).norm();
        4.0 * 3f64.sqrt() * area / ((b - a).norm_squared() + (c - b).norm_squared() + (a - c).norm_squared())
    }

    #[test]
    fn a_crescent_fan_is_refined_to_isotropic_triangles_on_the_same_rim() {
        let mut points = crescent();
        let n = points.len();
        let outline: Vec<u32> = (0..n as u32).collect();
        let plane = square_plane();
        let uv: Vec<(f64, f64)> = points.iter().map(|p| plane.project_2d(p)).collect();
        let fan: Vec<[usize; 3]> = ear_clip(&outline, &uv).unwrap().iter().map(|t| t.map(|v| v as usize)).collect();
        let fan_worst = fan.iter().map(|t| quality(&points, t.map(|v| v as u32))).fold(1.0, f64::min);
        assert!(fan_worst < 0.05, "the ear-clipped fan is the bad case ({fan_worst})");
        let rim_before = points.clone();
        let cap = refine_planar_cap(&mut points, &outline, &fan, &plane, 1.0);
        assert_eq!(&points[..n], &rim_before[..], "rim vertices unchanged");
        // Same area, same winding, every triangle fair, every new vertex in the plane.
        let area = |t: &[u32; 3]| {
            let [a, b, c] = t.map(|v| points[v as usize]);
            0.5 * (b - a).cross(&(c - a)).z
        };
        let fan_area: f64 = fan.iter().map(|t| area(&t.map(|v| v as u32))).sum();
        let cap_area: f64 = cap.iter().map(area).sum();
        assert!((cap_area - fan_area).abs() < 1e-9 * fan_area.abs(), "{cap_area} vs {fan_area}");
        assert!(cap.iter().all(|t| area(t) * fan_area > 0.0), "a triangle turned over");
        let worst = cap.iter().map(|&t| quality(&points, t)).fold(1.0, f64::min);
        assert!(worst > 0.5, "worst triangle quality {worst}");
        eprintln!("crescent cap: {} triangles, worst quality {worst:.3}", cap.len());
        assert!(points[n..].iter().all(|p| p.z.abs() < 1e-12));
        // Closed against the rim: each rim edge once, every other edge twice.
        let mut count: HashMap<(u32, u32), i32> = HashMap::new();
        for t in &cap {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                *count.entry((a.min(b), a.max(b))).or_default() += 1;
            }
        }
        let rim_edges: Vec<(u32, u32)> = (0..n as u32).map(|i| (i.min((i + 1) % n as u32), i.max((i + 1) % n as u32))).collect();
        for (e, c) in &count {
            assert_eq!(*c, if rim_edges.contains(e) { 1 } else { 2 }, "edge {e:?}");
        }
        let longest = count.keys().map(|&(a, b)| (points[a as usize] - points[b as usize]).norm()).fold(0.0, f64::max);
        assert!(longest <= 1.5, "longest edge {longest} mm (fan: tens of mm)");
        eprintln!("crescent cap: longest edge {longest:.2} mm");
    }
}
