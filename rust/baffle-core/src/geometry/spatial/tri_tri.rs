//! Triangle-triangle intersection (Möller 1997, "A Fast Triangle-Triangle
//! Intersection Test") with the mesh cases a surface check needs: triangles that
//! share a corner or an edge always touch there, so they count as intersecting
//! only when they overlap beyond what they share.
//!
//! Distances below `tolerance_mm` from a plane are snapped to 0 so that
//! coplanar-up-to-rounding triangles take the exact 2D path.

use crate::geometry::mesh::Vec3;
use std::f64::consts::PI;

/// Two wedges at a shared corner overlap only if they share more than this angle
/// (rad): wedges that merely touch along a ray are neighbours in a flat fan.
const WEDGE_OVERLAP_TOLERANCE_RAD: f64 = 1e-9;

/// Two segments from a shared corner that should both lie on the planes' common line
/// and are further from parallel than this (sine of their angle) show planes too near
/// parallel to have one: a corner snapped by the tolerance moves its segment by about
/// tolerance / (edge x sine of the planes' angle), under 1e-3 unless the planes are
/// within about 0.01 deg of each other (for the 1e-7 mm tolerance of a 100 mm scene).
const COMMON_LINE_SIN_TOLERANCE: f64 = 1e-3;

/// Corner pairs `(corner of first, corner of second)` at the same point.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct SharedCorners {
    pairs: [(usize, usize); 3],
    count: usize,
}

impl SharedCorners {
    /// Corners are shared when `same_vertex(i, j)` says so (e.g. same point index)
    /// or when their coordinates are bit-identical.
    pub(crate) fn find(
        t1: &[Vec3; 3],
        t2: &[Vec3; 3],
        same_vertex: impl Fn(usize, usize) -> bool,
    ) -> Self {
        let mut shared = SharedCorners::default();
        let mut used = [false; 3];
        for (i, corner) in t1.iter().enumerate() {
            for j in 0..3 {
                if !used[j] && (same_vertex(i, j) || bit_identical(corner, &t2[j])) {
                    used[j] = true;
                    shared.pairs[shared.count] = (i, j);
                    shared.count += 1;
                    break;
                }
            }
        }
        shared
    }
}

fn bit_identical(a: &Vec3, b: &Vec3) -> bool {
    a.x.to_bits() == b.x.to_bits()
        && a.y.to_bits() == b.y.to_bits()
        && a.z.to_bits() == b.z.to_bits()
}

/// Whether two triangles intersect, treating corners at bit-identical positions
/// as shared (see the module doc). Zero-area triangles never intersect here.
pub fn triangles_intersect(t1: &[Vec3; 3], t2: &[Vec3; 3], tolerance_mm: f64) -> bool {
    let shared = SharedCorners::find(t1, t2, |_, _| false);
    triangles_intersect_sharing(t1, t2, &shared, tolerance_mm)
}

pub(crate) fn triangles_intersect_sharing(
    t1: &[Vec3; 3],
    t2: &[Vec3; 3],
    shared: &SharedCorners,
    tolerance_mm: f64,
) -> bool {
    if is_degenerate(t1) || is_degenerate(t2) {
        return false;
    }
    match shared.count {
        0 => disjoint_triangles_intersect(t1, t2, tolerance_mm),
        1 => {
            let (i, j) = shared.pairs[0];
            corner_sharing_triangles_overlap(&rotated(t1, i), &rotated(t2, j), tolerance_mm)
        }
        2 => {
            let [(i1, j1), (i2, j2)] = [shared.pairs[0], shared.pairs[1]];
            let apex1 = t1[3 - i1 - i2];
            let apex2 = t2[3 - j1 - j2];
            edge_sharing_triangles_folded(&t1[i1], &t1[i2], &apex1, &apex2, tolerance_mm)
        }
        // Same three points: the triangles coincide.
        _ => true,
    }
}

/// Zero area up to rounding: no plane, so no reliable plane-based test.
fn is_degenerate(t: &[Vec3; 3]) -> bool {
    let longest2 = (0..3)
        .map(|k| (t[(k + 1) % 3] - t[k]).norm_squared())
        .fold(0.0, f64::max);
    (t[1] - t[0]).cross(&(t[2] - t[0])).norm() <= 1e-12 * longest2
}

fn rotated(t: &[Vec3; 3], first: usize) -> [Vec3; 3] {
    [t[first], t[(first + 1) % 3], t[(first + 2) % 3]]
}

fn unit_normal(t: &[Vec3; 3]) -> Vec3 {
    (t[1] - t[0]).cross(&(t[2] - t[0])).normalize()
}

fn snap(d: f64, tolerance_mm: f64) -> f64 {
    if d.abs() <= tolerance_mm {
        0.0
    } else {
        d
    }
}

fn signed_distances(
    t: &[Vec3; 3],
    plane_point: &Vec3,
    unit_normal: &Vec3,
    tolerance_mm: f64,
) -> [f64; 3] {
    [0, 1, 2].map(|k| snap(unit_normal.dot(&(t[k] - plane_point)), tolerance_mm))
}

fn strictly_one_side(d: &[f64; 3]) -> bool {
    d.iter().all(|&x| x > 0.0) || d.iter().all(|&x| x < 0.0)
}

/// Möller's test for triangles with no common corner.
fn disjoint_triangles_intersect(t1: &[Vec3; 3], t2: &[Vec3; 3], tolerance_mm: f64) -> bool {
    let n1 = unit_normal(t1);
    let n2 = unit_normal(t2);
    let d1 = signed_distances(t1, &t2[0], &n2, tolerance_mm);
    if strictly_one_side(&d1) {
        return false;
    }
    let d2 = signed_distances(t2, &t1[0], &n1, tolerance_mm);
    if strictly_one_side(&d2) {
        return false;
    }
    if d1 == [0.0; 3] {
        return coplanar_triangles_overlap(t1, t2, &n2);
    }
    if d2 == [0.0; 3] {
        return coplanar_triangles_overlap(t1, t2, &n1);
    }
    let line = n1.cross(&n2);
    if line.norm() < 1e-12 {
        // Parallel planes that both cross each other cannot be told apart from coplanar.
        return coplanar_triangles_overlap(t1, t2, &n1);
    }
    let dir = line.normalize();
    let (lo1, hi1) = plane_crossing_interval(t1, &d1, &dir);
    let (lo2, hi2) = plane_crossing_interval(t2, &d2, &dir);
    lo1 <= hi2 && lo2 <= hi1
}

/// Where the triangle meets the other plane, as an interval along the planes'
/// common line `dir`. The triangle must touch the plane (not strictly one side).
fn plane_crossing_interval(t: &[Vec3; 3], d: &[f64; 3], dir: &Vec3) -> (f64, f64) {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    let mut include = |p: Vec3| {
        let s = dir.dot(&p);
        lo = lo.min(s);
        hi = hi.max(s);
    };
    for i in 0..3 {
        let j = (i + 1) % 3;
        if d[i] == 0.0 {
            include(t[i]);
        }
        if d[i] * d[j] < 0.0 {
            include(t[i] + (t[j] - t[i]) * (d[i] / (d[i] - d[j])));
        }
    }
    (lo, hi)
}

/// Closed overlap test of two coplanar triangles, in the 2D projection that drops
/// the normal's largest axis.
fn coplanar_triangles_overlap(t1: &[Vec3; 3], t2: &[Vec3; 3], normal: &Vec3) -> bool {
    let drop = normal.iamax();
    let (u, v) = ((drop + 1) % 3, (drop + 2) % 3);
    let flat = |t: &[Vec3; 3]| [0, 1, 2].map(|k| [t[k][u], t[k][v]]);
    let (a, b) = (flat(t1), flat(t2));
    for i in 0..3 {
        for j in 0..3 {
            if segments_intersect_2d(&a[i], &a[(i + 1) % 3], &b[j], &b[(j + 1) % 3]) {
                return true;
            }
        }
    }
    point_in_triangle_2d(&a[0], &b) || point_in_triangle_2d(&b[0], &a)
}

fn orient_2d(a: &[f64; 2], b: &[f64; 2], c: &[f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

/// `c`, known to be collinear with `a`-`b`, lies within the segment's box.
fn within_segment_box(a: &[f64; 2], b: &[f64; 2], c: &[f64; 2]) -> bool {
    (0..2).all(|k| a[k].min(b[k]) <= c[k] && c[k] <= a[k].max(b[k]))
}

fn segments_intersect_2d(p1: &[f64; 2], p2: &[f64; 2], q1: &[f64; 2], q2: &[f64; 2]) -> bool {
    let o1 = orient_2d(p1, p2, q1);
    let o2 = orient_2d(p1, p2, q2);
    let o3 = orient_2d(q1, q2, p1);
    let o4 = orient_2d(q1, q2, p2);
    if o1 * o2 < 0.0 && o3 * o4 < 0.0 {
        return true;
    }
    (o1 == 0.0 && within_segment_box(p1, p2, q1))
        || (o2 == 0.0 && within_segment_box(p1, p2, q2))
        || (o3 == 0.0 && within_segment_box(q1, q2, p1))
        || (o4 == 0.0 && within_segment_box(q1, q2, p2))
}

fn point_in_triangle_2d(p: &[f64; 2], t: &[[f64; 2]; 3]) -> bool {
    let s = [0, 1, 2].map(|k| orient_2d(&t[k], &t[(k + 1) % 3], p));
    s.iter().all(|&x| x >= 0.0) || s.iter().all(|&x| x <= 0.0)
}

/// Triangles `[v, a, b]` and `[v, c, e]` sharing corner `v`. Away from the
/// coplanar case, each triangle meets the other's plane in a segment starting at
/// `v` along the planes' common line (or only in `v`); they overlap beyond `v`
/// exactly when both segments exist and point the same way.
fn corner_sharing_triangles_overlap(t1: &[Vec3; 3], t2: &[Vec3; 3], tolerance_mm: f64) -> bool {
    let v = t1[0];
    let n1 = unit_normal(t1);
    let n2 = unit_normal(t2);
    let da = snap(n2.dot(&(t1[1] - v)), tolerance_mm);
    let db = snap(n2.dot(&(t1[2] - v)), tolerance_mm);
    if da == 0.0 && db == 0.0 {
        return coplanar_wedges_overlap(&v, t1, t2, &n2);
    }
    let dc = snap(n1.dot(&(t2[1] - v)), tolerance_mm);
    let de = snap(n1.dot(&(t2[2] - v)), tolerance_mm);
    if dc == 0.0 && de == 0.0 {
        return coplanar_wedges_overlap(&v, t1, t2, &n1);
    }
    let (Some(u1), Some(u2)) = (
        crossing_direction(&v, &t1[1], &t1[2], da, db),
        crossing_direction(&v, &t2[1], &t2[2], dc, de),
    ) else {
        return false;
    };
    // Both segments lie on the planes' common line, so they are parallel, unless a
    // corner snapped onto the other plane made its edge the segment while the planes
    // are too near parallel for a common line (p1's extension: two wedges of a flat
    // fan 2e-5 deg apart, one corner of each within 1e-7 mm of the other's plane).
    // Such triangles are coplanar to the tolerance: compare their wedges instead.
    let sin_between = u1.cross(&u2).norm() / (u1.norm() * u2.norm());
    if sin_between > COMMON_LINE_SIN_TOLERANCE {
        return coplanar_wedges_overlap(&v, t1, t2, &n1);
    }
    u1.dot(&u2) > 0.0
}

/// Direction from `v` to where edge `a`-`b` (signed distances `da`, `db`) meets
/// the other plane; `None` when the triangle touches that plane only at `v`.
fn crossing_direction(v: &Vec3, a: &Vec3, b: &Vec3, da: f64, db: f64) -> Option<Vec3> {
    if (da > 0.0 && db > 0.0) || (da < 0.0 && db < 0.0) {
        return None;
    }
    if da == 0.0 {
        return Some(a - v);
    }
    if db == 0.0 {
        return Some(b - v);
    }
    Some(a + (b - a) * (da / (da - db)) - v)
}

/// Coplanar triangles sharing corner `v` overlap beyond it iff their angular
/// wedges at `v` (measured in the plane with `normal`) share an open arc.
fn coplanar_wedges_overlap(v: &Vec3, t1: &[Vec3; 3], t2: &[Vec3; 3], normal: &Vec3) -> bool {
    let ea = t1[1] - v;
    let in_plane = ea - normal * normal.dot(&ea);
    let Some(x_axis) = in_plane.try_normalize(0.0) else {
        return false;
    };
    let y_axis = normal.cross(&x_axis);
    let angle = |p: &Vec3| {
        let d = p - v;
        d.dot(&y_axis).atan2(d.dot(&x_axis))
    };
    let arc1 = arc_between(angle(&t1[1]), angle(&t1[2]));
    let arc2 = arc_between(angle(&t2[1]), angle(&t2[2]));
    arc_overlap_rad(arc1, arc2) > WEDGE_OVERLAP_TOLERANCE_RAD
}

/// The shorter arc between two angles, as (start, length), length in [0, pi].
fn arc_between(theta1: f64, theta2: f64) -> (f64, f64) {
    let mut len = (theta2 - theta1).rem_euclid(2.0 * PI);
    if len > PI {
        len -= 2.0 * PI;
    }
    if len < 0.0 {
        (theta2, -len)
    } else {
        (theta1, len)
    }
}

/// Length (rad) of the common part of two arcs on the circle.
fn arc_overlap_rad((start1, len1): (f64, f64), (start2, len2): (f64, f64)) -> f64 {
    let offset = (start2 - start1).rem_euclid(2.0 * PI);
    let direct = (len1.min(offset + len2) - offset).max(0.0);
    let wrapped = len1.min(offset + len2 - 2.0 * PI).max(0.0);
    direct + wrapped
}

/// Triangles `[v, w, a]` and `[v, w, b]` sharing edge `v`-`w` meet only along it
/// unless folded onto each other: `a` and `b` on the same side of the edge in
/// (numerically) the same plane.
fn edge_sharing_triangles_folded(
    v: &Vec3,
    w: &Vec3,
    a: &Vec3,
    b: &Vec3,
    tolerance_mm: f64,
) -> bool {
    let Some(edge_dir) = (w - v).try_normalize(0.0) else {
        return false;
    };
    let perpendicular = |p: &Vec3| {
        let d = p - v;
        d - edge_dir * edge_dir.dot(&d)
    };
    let (pa, pb) = (perpendicular(a), perpendicular(b));
    if pa.dot(&pb) <= 0.0 {
        return false;
    }
    let shorter = pa.norm().min(pb.norm());
    // |pa x pb| / shorter = how far the longer flap's tip is off the other's plane.
    shorter > 0.0 && pa.cross(&pb).norm() / shorter <= tolerance_mm
}

#[cfg(test)]
mod tests {
    use super::*;

    const TOL: f64 = 1e-9;

    fn v(x: f64, y: f64, z: f64) -> Vec3 {
        Vec3::new(x, y, z)
    }

    #[test]
    fn piercing_triangles_intersect_and_separated_ones_do_not() {
        let t1 = [v(0.0, 0.0, 0.0), v(2.0, 0.0, 0.0), v(0.0, 2.0, 0.0)];
        let pierce = [v(0.5, 0.5, -1.0), v(0.5, 0.5, 1.0), v(3.0, 3.0, 0.5)];
        assert!(triangles_intersect(&t1, &pierce, TOL));
        let above = [v(0.5, 0.5, 0.1), v(0.5, 0.5, 1.0), v(3.0, 3.0, 0.5)];
        assert!(!triangles_intersect(&t1, &above, TOL));
        // Crosses the plane of t1, but outside t1.
        let beside = [v(5.0, 5.0, -1.0), v(5.0, 5.0, 1.0), v(6.0, 6.0, 0.0)];
        assert!(!triangles_intersect(&t1, &beside, TOL));
    }

    #[test]
    fn coplanar_overlap_and_separation() {
        let t1 = [v(0.0, 0.0, 1.0), v(2.0, 0.0, 1.0), v(0.0, 2.0, 1.0)];
        let overlapping = [v(0.5, 0.5, 1.0), v(3.0, 0.5, 1.0), v(0.5, 3.0, 1.0)];
        let inside = [v(0.1, 0.1, 1.0), v(0.3, 0.1, 1.0), v(0.1, 0.3, 1.0)];
        let apart = [v(2.0, 2.0, 1.0), v(3.0, 2.0, 1.0), v(2.0, 3.0, 1.0)];
        assert!(triangles_intersect(&t1, &overlapping, TOL));
        assert!(triangles_intersect(&t1, &inside, TOL));
        assert!(triangles_intersect(&inside, &t1, TOL));
        assert!(!triangles_intersect(&t1, &apart, TOL));
    }

    #[test]
    fn shared_corner_counts_only_overlap_beyond_it() {
        let t1 = [v(0.0, 0.0, 0.0), v(2.0, 0.0, 0.0), v(0.0, 2.0, 0.0)];
        // Non-coplanar, touching only at the shared corner.
        let hinge = [v(0.0, 0.0, 0.0), v(-1.0, 0.0, 1.0), v(0.0, -1.0, 1.0)];
        assert!(!triangles_intersect(&t1, &hinge, TOL));
        // Non-coplanar, passing through t1's interior from the shared corner.
        let through = [v(0.0, 0.0, 0.0), v(1.0, 1.0, 1.0), v(1.0, 1.0, -1.0)];
        assert!(triangles_intersect(&t1, &through, TOL));
        // Crosses t1's plane along the common line, but on the far side of the corner.
        let opposite = [v(0.0, 0.0, 0.0), v(-1.0, -1.0, 1.0), v(-1.0, -1.0, -1.0)];
        assert!(!triangles_intersect(&t1, &opposite, TOL));
        // Coplanar: neighbouring wedge vs overlapping wedge.
        let neighbour = [v(0.0, 0.0, 0.0), v(-1e-3, 2.0, 0.0), v(-2.0, 0.0, 0.0)];
        assert!(!triangles_intersect(&t1, &neighbour, TOL));
        let overlapping = [v(0.0, 0.0, 0.0), v(1.0, 1.0, 0.0), v(-1.0, 1.0, 0.0)];
        assert!(triangles_intersect(&t1, &overlapping, TOL));
    }

    #[test]
    fn near_coplanar_wedges_of_a_fan_do_not_cross_at_any_tolerance() {
        // Two wedges of a flat fan in p1's extended domain (mm), 2e-5 deg apart, one
        // corner of each within 1e-7 mm of the other's plane: at that tolerance the
        // snapped corners' edges were taken for the common line and the pair for a
        // crossing, while 0, 1e-9 and 1e-5 mm said apart.
        let shared = v(38.62943962952906, -118.15786968753523, -133.52430403340153);
        let t1 = [v(38.56898150925144, -118.19481798384076, -133.99216904745688), shared, v(38.3395286006125, -117.88967949810163, -133.69240710020355)];
        let t2 = [shared, v(38.532913445302384, -117.95328683793184, -133.04302402995935), v(38.351150302247206, -117.81915062642898, -133.3069010012375)];
        for tolerance_mm in [0.0, 1e-9, 1e-8, 1e-7, 3e-7, 1e-6, 1e-5, 1e-3] {
            assert!(!triangles_intersect(&t1, &t2, tolerance_mm), "at {tolerance_mm} mm");
        }
        // The same snapping on wedges that do overlap still finds them.
        let base = [v(0.0, 0.0, 0.0), v(2.0, 0.0, 0.0), v(0.0, 2.0, 0.0)];
        let over = [v(0.0, 0.0, 0.0), v(1.0, 1.0, 0.5e-7), v(-1.0, 1.0, 3e-7)];
        for tolerance_mm in [1e-7, 1e-5] {
            assert!(triangles_intersect(&base, &over, tolerance_mm), "at {tolerance_mm} mm");
        }
    }

    #[test]
    fn shared_edge_counts_only_folds() {
        let (a, b) = (v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0));
        let t1 = [a, b, v(0.5, 1.0, 0.0)];
        let flat_neighbour = [b, a, v(0.5, -1.0, 0.0)];
        let bent_neighbour = [b, a, v(0.5, 0.3, 0.9)];
        let folded = [b, a, v(0.2, 0.6, 0.0)];
        assert!(!triangles_intersect(&t1, &flat_neighbour, TOL));
        assert!(!triangles_intersect(&t1, &bent_neighbour, TOL));
        assert!(triangles_intersect(&t1, &folded, TOL));
        assert!(
            triangles_intersect(&t1, &t1, TOL),
            "coincident triangles overlap"
        );
    }

    #[test]
    fn arcs_overlap_across_the_wrap() {
        assert!(
            (arc_overlap_rad((3.0, 0.5), (-3.0, 0.5)) - (0.5 - (2.0 * PI - 6.0))).abs() < 1e-12
        );
        assert_eq!(arc_overlap_rad((0.0, 1.0), (1.0, 1.0)), 0.0);
        assert!((arc_overlap_rad((0.0, 1.0), (0.5, 1.0)) - 0.5).abs() < 1e-12);
    }
}
