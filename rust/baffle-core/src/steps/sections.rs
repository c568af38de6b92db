//! Step 5, cross-sections of the tunnel [paper 2.4.3].
//!
//! The capped domain (kept wall, caps, current baffle) is cut with the plane normal
//! to the centerline tangent at each sample. The closed contour whose centroid is
//! nearest the sample is kept; each contour segment carries the label of the
//! triangle it crosses. Contours that run mostly (> 75 % of their vertices) on the
//! RV wall are dropped: the baffle cannot shape them. The others are split at the two
//! points where they cross the seam; the arc holding the baffle-labelled segments is
//! the baffle arc, the rest is fixed.

use crate::geometry::mesh::{edge_key, FaceLabels, TriMesh, Vec3};
use std::collections::HashMap;

/// A closed planar contour of the mesh. Point i lies on mesh edge `point_edges[i]`
/// at fraction `point_fractions[i]` from its first vertex; segment i (from point i
/// to point i+1) crosses triangle `segment_triangles[i]`.
#[derive(Clone, Debug, Default)]
pub struct Contour {
    pub points: Vec<Vec3>,
    pub point_edges: Vec<(u32, u32)>,
    pub point_fractions: Vec<f64>,
    pub segment_triangles: Vec<u32>,
}

impl Contour {
    pub fn centroid(&self) -> Vec3 {
        self.points.iter().sum::<Vec3>() / self.points.len().max(1) as f64
    }

    /// Signed area in the plane with unit normal `normal` (positive when the
    /// contour runs counter-clockwise about it).
    pub fn signed_area_mm2(&self, normal: &Vec3) -> f64 {
        signed_loop_area_mm2(&self.points, normal)
    }
}

/// Signed area of a closed polygon about `normal` (shoelace on the vector area).
pub fn signed_loop_area_mm2(points: &[Vec3], normal: &Vec3) -> f64 {
    let n = points.len();
    let mut twice = Vec3::zeros();
    for i in 0..n {
        twice += points[i].cross(&points[(i + 1) % n]);
    }
    0.5 * twice.dot(normal)
}

/// All closed contours of `mesh` cut by the plane through `origin` with `normal`.
/// A vertex exactly on the plane counts as above it, so every contour point lies
/// strictly inside an edge.
pub fn cut_mesh(mesh: &TriMesh, origin: Vec3, normal: Vec3) -> Vec<Contour> {
    let side: Vec<f64> = mesh.points.iter().map(|p| normal.dot(&(p - origin))).collect();
    let above = |v: u32| side[v as usize] >= 0.0;
    // Each crossed triangle contributes one segment between two crossed edges,
    // directed so that the region above the plane is on its left.
    let mut segment_from: HashMap<(u32, u32), (u32, (u32, u32))> = HashMap::new();
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let ups = tri.iter().filter(|&&v| above(v)).count();
        if ups == 0 || ups == 3 {
            continue;
        }
        // Rotate so the lone vertex (the one on its own side) is first.
        let lone_is_up = ups == 1;
        let k = (0..3).find(|&k| above(tri[k]) == lone_is_up).unwrap_or(0);
        let (a, b, c) = (tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]);
        let (e_ab, e_ca) = (edge_key(a, b), edge_key(c, a));
        let (from, to) = if lone_is_up { (e_ab, e_ca) } else { (e_ca, e_ab) };
        segment_from.insert(from, (t as u32, to));
    }
    chain_segments(mesh, &side, segment_from)
}

fn chain_segments(mesh: &TriMesh, side: &[f64], mut segment_from: HashMap<(u32, u32), (u32, (u32, u32))>) -> Vec<Contour> {
    let mut contours = Vec::new();
    let mut starts: Vec<(u32, u32)> = segment_from.keys().copied().collect();
    starts.sort_unstable();
    for start in starts {
        if !segment_from.contains_key(&start) {
            continue;
        }
        let mut contour = Contour::default();
        let mut edge = start;
        let closed = loop {
            let Some((t, next)) = segment_from.remove(&edge) else { break edge == start };
            push_edge_point(mesh, side, &mut contour, edge);
            contour.segment_triangles.push(t);
            edge = next;
            if edge == start {
                break true;
            }
        };
        if closed && contour.points.len() >= 3 {
            contours.push(contour);
        }
    }
    contours
}

fn push_edge_point(mesh: &TriMesh, side: &[f64], contour: &mut Contour, (a, b): (u32, u32)) {
    let (da, db) = (side[a as usize], side[b as usize]);
    let f = da / (da - db);
    let (pa, pb) = (mesh.points[a as usize], mesh.points[b as usize]);
    contour.points.push(pa + (pb - pa) * f);
    contour.point_edges.push((a, b));
    contour.point_fractions.push(f);
}

/// The contour whose centroid is nearest `origin`.
pub fn nearest_contour(contours: Vec<Contour>, origin: Vec3) -> Option<Contour> {
    contours.into_iter().min_by(|a, b| (a.centroid() - origin).norm().total_cmp(&(b.centroid() - origin).norm()))
}

/// Where a contour's baffle arc starts and ends (cyclic point indices; the arc is
/// points start, start+1, ..., end, and all its segments cross baffle triangles).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BaffleArc {
    pub start: usize,
    pub end: usize,
}

impl BaffleArc {
    /// Point indices along the arc, in order.
    pub fn indices(&self, n: usize) -> Vec<usize> {
        let len = (self.end + n - self.start) % n + 1;
        (0..len).map(|k| (self.start + k) % n).collect()
    }
}

/// Why a contour takes no part in the area constraint.
#[derive(Clone, Debug, PartialEq)]
pub enum Dropped {
    NoContour,
    MostlyWall { wall_fraction: f64 },
    NoBaffleArc,
}

/// Split a contour at the seam: the longest run of baffle segments is the baffle arc.
/// Returns `Dropped` when more than `max_wall_fraction` of its points are on the wall.
pub fn split_at_seam(
    mesh: &TriMesh,
    contour: &Contour,
    labels: &FaceLabels,
    max_wall_fraction: f64,
) -> Result<BaffleArc, Dropped> {
    let n = contour.points.len();
    let seg_label = |i: usize| mesh.face_ids[contour.segment_triangles[i % n] as usize];
    // Point i is on the wall when both segments meeting there cross wall triangles.
    let wall_points = (0..n).filter(|&i| seg_label(i) == labels.wall && seg_label(i + n - 1) == labels.wall).count();
    let wall_fraction = wall_points as f64 / n as f64;
    if wall_fraction > max_wall_fraction {
        return Err(Dropped::MostlyWall { wall_fraction });
    }
    let is_baffle = |i: usize| seg_label(i) == labels.baffle;
    if (0..n).all(is_baffle) || !(0..n).any(is_baffle) {
        return Err(Dropped::NoBaffleArc);
    }
    // Longest cyclic run of baffle segments.
    let mut best = (0, 0);
    for start in (0..n).filter(|&i| is_baffle(i) && !is_baffle((i + n - 1) % n)) {
        let len = (0..n).take_while(|&k| is_baffle((start + k) % n)).count();
        if len > best.1 {
            best = (start, len);
        }
    }
    Ok(BaffleArc { start: best.0, end: (best.0 + best.1) % n })
}

/// Where two section arcs drawn on the baffle's unit disk (polylines of disk
/// coordinates) cross: positions along each (segment index + fraction). Sections
/// whose planes meet on the baffle (where the centerline bends more sharply than
/// the tunnel is wide) give the final surface two targets for the same baffle point.
pub fn disk_arc_crossings(a: &[(f64, f64)], b: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let bbox = |l: &[(f64, f64)]| {
        l.iter().fold([f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY], |m, p| {
            [m[0].min(p.0), m[1].min(p.1), m[2].max(p.0), m[3].max(p.1)]
        })
    };
    let (ba, bb) = (bbox(a), bbox(b));
    if ba[0] > bb[2] || bb[0] > ba[2] || ba[1] > bb[3] || bb[1] > ba[3] {
        return Vec::new();
    }
    let mut out = Vec::new();
    for (i, sa) in a.windows(2).enumerate() {
        for (j, sb) in b.windows(2).enumerate() {
            if let Some((ta, tb)) = segments_cross_2d(sa[0], sa[1], sb[0], sb[1]) {
                out.push((i as f64 + ta, j as f64 + tb));
            }
        }
    }
    out
}

/// Proper crossing of two segments as fractions along each (touching at an end does
/// not count: neighbouring arcs share their seam end points' neighbourhoods).
fn segments_cross_2d(p1: (f64, f64), p2: (f64, f64), q1: (f64, f64), q2: (f64, f64)) -> Option<(f64, f64)> {
    let orient = |a: (f64, f64), b: (f64, f64), c: (f64, f64)| (b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0);
    let (d1, d2) = (orient(q1, q2, p1), orient(q1, q2, p2));
    let (d3, d4) = (orient(p1, p2, q1), orient(p1, p2, q2));
    (d1 * d2 < 0.0 && d3 * d4 < 0.0).then(|| (d1 / (d1 - d2), d3 / (d3 - d4)))
}

/// Greedy choice of arcs that do not conflict: `order` lists the arcs most important
/// first; an arc is kept unless it crosses an arc kept before it at a crossing
/// where `conflict(arc, kept, position on arc, position on kept)` holds. Returns,
/// for each arc, `None` when kept or `Some(j)` with the kept arc `j` it conflicts with.
pub fn non_conflicting_arcs(
    arcs: &[Vec<(f64, f64)>],
    order: &[usize],
    conflict: impl Fn(usize, usize, f64, f64) -> bool,
) -> Vec<Option<usize>> {
    let mut verdict = vec![None; arcs.len()];
    let mut kept: Vec<usize> = Vec::new();
    for &i in order {
        let clash = kept.iter().find(|&&j| disk_arc_crossings(&arcs[i], &arcs[j]).into_iter().any(|(ti, tj)| conflict(i, j, ti, tj)));
        match clash {
            Some(&j) => verdict[i] = Some(j),
            None => kept.push(i),
        }
    }
    verdict
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A closed cylinder of radius r along z in [0, h], capped by fans, labelled:
    /// wall 2 for x < 0.3 r, baffle 10 on the rest of the side, caps 11 and 16.
    pub(crate) fn labelled_cylinder(r: f64, h: f64, n_around: usize, n_along: usize) -> TriMesh {
        let mut m = TriMesh::default();
        for j in 0..=n_along {
            for i in 0..n_around {
                let a = std::f64::consts::TAU * i as f64 / n_around as f64;
                m.points.push(Vec3::new(r * a.cos(), r * a.sin(), h * j as f64 / n_along as f64));
            }
        }
        let id = |i: usize, j: usize| (j * n_around + i % n_around) as u32;
        for j in 0..n_along {
            for i in 0..n_around {
                let quad = [id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)];
                let a = std::f64::consts::TAU * (i as f64 + 0.5) / n_around as f64;
                let label = if r * a.cos() > 0.3 * r { 10 } else { 2 };
                m.triangles.push([quad[0], quad[1], quad[2]]);
                m.triangles.push([quad[0], quad[2], quad[3]]);
                m.face_ids.extend([label, label]);
            }
        }
        let bottom = m.points.len() as u32;
        m.points.push(Vec3::new(0.0, 0.0, 0.0));
        let top = m.points.len() as u32;
        m.points.push(Vec3::new(0.0, 0.0, h));
        for i in 0..n_around {
            m.triangles.push([bottom, id(i + 1, 0), id(i, 0)]);
            m.face_ids.push(11);
            m.triangles.push([top, id(i, n_along), id(i + 1, n_along)]);
            m.face_ids.push(16);
        }
        m
    }

    #[test]
    fn cylinder_section_area_and_baffle_arc() {
        let m = labelled_cylinder(3.0, 10.0, 64, 20);
        assert!(m.signed_volume_mm3() > 0.0);
        let contours = cut_mesh(&m, Vec3::new(0.0, 0.0, 4.9), Vec3::new(0.0, 0.0, 1.0));
        assert_eq!(contours.len(), 1);
        let c = &contours[0];
        let polygon = 0.5 * 64.0 * 9.0 * (std::f64::consts::TAU / 64.0).sin();
        assert!((c.signed_area_mm2(&Vec3::z()) - polygon).abs() < 1e-9, "{}", c.signed_area_mm2(&Vec3::z()));
        let arc = split_at_seam(&m, c, &FaceLabels::default(), 0.75).unwrap();
        // The baffle arc spans x > 0.3 r: about 2 acos(0.3)/tau of the points.
        let frac = arc.indices(c.points.len()).len() as f64 / c.points.len() as f64;
        assert!((frac - 2.0 * 0.3f64.acos() / std::f64::consts::TAU).abs() < 0.05, "{frac}");
        for i in arc.indices(c.points.len()) {
            assert!(c.points[i].x >= 0.3 * 3.0 * 0.95, "arc point {i} at x {}", c.points[i].x);
        }
    }

    #[test]
    fn plane_through_vertices_still_gives_one_closed_contour() {
        let m = labelled_cylinder(3.0, 10.0, 32, 10);
        // z = 5 passes exactly through a ring of vertices.
        let contours = cut_mesh(&m, Vec3::new(0.0, 0.0, 5.0), Vec3::new(0.0, 0.0, 1.0));
        assert_eq!(contours.len(), 1);
        assert!(contours[0].signed_area_mm2(&Vec3::z()) > 25.0);
    }

    #[test]
    fn mostly_wall_contours_are_dropped() {
        let mut m = labelled_cylinder(3.0, 10.0, 64, 20);
        for l in m.face_ids.iter_mut() {
            if *l == 10 {
                *l = 2;
            }
        }
        let c = cut_mesh(&m, Vec3::new(0.0, 0.0, 4.9), Vec3::z()).remove(0);
        assert!(matches!(split_at_seam(&m, &c, &FaceLabels::default(), 0.75), Err(Dropped::MostlyWall { .. })));
    }

    #[test]
    fn crossing_arcs_are_found_and_the_first_in_order_wins() {
        let horizontal = vec![(-1.0, 0.0), (0.0, 0.0), (1.0, 0.0)];
        let vertical = vec![(0.5, -1.0), (0.5, 1.0)];
        let parallel = vec![(-1.0, 0.3), (1.0, 0.3)];
        let crossings = disk_arc_crossings(&horizontal, &vertical);
        assert_eq!(crossings.len(), 1);
        assert!((crossings[0].0 - 1.5).abs() < 1e-12 && (crossings[0].1 - 0.5).abs() < 1e-12, "{crossings:?}");
        assert!(disk_arc_crossings(&horizontal, &parallel).is_empty());
        // Touching at an end point is not a crossing.
        assert!(disk_arc_crossings(&horizontal, &[(1.0, 0.0), (2.0, 1.0)]).is_empty());
        let arcs = vec![horizontal, vertical, parallel];
        let always = |_: usize, _: usize, _: f64, _: f64| true;
        assert_eq!(non_conflicting_arcs(&arcs, &[1, 0, 2], always), vec![Some(1), None, Some(1)]);
        assert_eq!(non_conflicting_arcs(&arcs, &[0, 2, 1], always), vec![None, Some(0), None]);
        // A crossing that asks for no conflicting targets keeps both arcs.
        assert_eq!(non_conflicting_arcs(&arcs, &[1, 0, 2], |_, _, _, _| false), vec![None, None, None]);
    }
}
