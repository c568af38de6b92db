//! Boxes and exact point/ray-vs-triangle primitives used by the BVH queries.

use crate::geometry::mesh::Vec3;

/// Axis-aligned bounding box (mm). An empty box has `min > max`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: Vec3,
    pub max: Vec3,
}

impl Aabb {
    /// The box containing nothing: growing it by a point gives that point's box.
    pub fn empty() -> Self {
        Aabb {
            min: Vec3::repeat(f64::INFINITY),
            max: Vec3::repeat(f64::NEG_INFINITY),
        }
    }

    pub fn from_points<'a>(points: impl IntoIterator<Item = &'a Vec3>) -> Self {
        let mut b = Aabb::empty();
        for p in points {
            b.grow(p);
        }
        b
    }

    pub fn of_triangle(corners: &[Vec3; 3]) -> Self {
        let [a, b, c] = corners;
        Aabb {
            min: Vec3::new(
                lesser(lesser(a.x, b.x), c.x),
                lesser(lesser(a.y, b.y), c.y),
                lesser(lesser(a.z, b.z), c.z),
            ),
            max: Vec3::new(
                greater(greater(a.x, b.x), c.x),
                greater(greater(a.y, b.y), c.y),
                greater(greater(a.z, b.z), c.z),
            ),
        }
    }

    pub fn is_empty(&self) -> bool {
        (0..3).any(|k| self.min[k] > self.max[k])
    }

    // Componentwise min/max written out with `lesser`/`greater`: nalgebra's
    // inf/sup and f64::min/max handle NaN and cost several times more in the
    // BVH build (coordinates are checked finite there).
    pub fn grow(&mut self, p: &Vec3) {
        self.min = Vec3::new(
            lesser(self.min.x, p.x),
            lesser(self.min.y, p.y),
            lesser(self.min.z, p.z),
        );
        self.max = Vec3::new(
            greater(self.max.x, p.x),
            greater(self.max.y, p.y),
            greater(self.max.z, p.z),
        );
    }

    pub fn merged(&self, other: &Aabb) -> Aabb {
        let (a, b) = (self, other);
        Aabb {
            min: Vec3::new(
                lesser(a.min.x, b.min.x),
                lesser(a.min.y, b.min.y),
                lesser(a.min.z, b.min.z),
            ),
            max: Vec3::new(
                greater(a.max.x, b.max.x),
                greater(a.max.y, b.max.y),
                greater(a.max.z, b.max.z),
            ),
        }
    }

    /// The box grown by `margin_mm` on every side.
    pub fn expanded(&self, margin_mm: f64) -> Aabb {
        Aabb {
            min: self.min - Vec3::repeat(margin_mm),
            max: self.max + Vec3::repeat(margin_mm),
        }
    }

    pub fn center(&self) -> Vec3 {
        0.5 * (self.min + self.max)
    }

    /// Diagonal length (mm); 0 for an empty box.
    pub fn diagonal_mm(&self) -> f64 {
        if self.is_empty() {
            0.0
        } else {
            (self.max - self.min).norm()
        }
    }

    /// Closed-interval overlap on all three axes (touching boxes overlap).
    pub fn overlaps(&self, other: &Aabb) -> bool {
        let (a, b) = (self, other);
        a.min.x <= b.max.x
            && b.min.x <= a.max.x
            && a.min.y <= b.max.y
            && b.min.y <= a.max.y
            && a.min.z <= b.max.z
            && b.min.z <= a.max.z
    }

    /// Squared distance (mm^2) from `q` to the box; 0 inside.
    pub fn distance_squared_mm2(&self, q: &Vec3) -> f64 {
        let dx = (self.min.x - q.x).max(q.x - self.max.x).max(0.0);
        let dy = (self.min.y - q.y).max(q.y - self.max.y).max(0.0);
        let dz = (self.min.z - q.z).max(q.z - self.max.z).max(0.0);
        dx * dx + dy * dy + dz * dz
    }

    /// Half the surface area: the SAH only compares areas, so the factor 2 is dropped.
    pub(crate) fn half_area_mm2(&self) -> f64 {
        if self.is_empty() {
            return 0.0;
        }
        let e = self.max - self.min;
        e.x * e.y + e.y * e.z + e.z * e.x
    }

    /// Ray parameter where the ray `origin + t * dir` enters the box, if it does so
    /// within `[0, t_max]`. `inv_dir` is the componentwise reciprocal of `dir`.
    pub(crate) fn ray_entry(&self, origin: &Vec3, inv_dir: &Vec3, t_max: f64) -> Option<f64> {
        let mut t_enter = 0.0f64;
        let mut t_exit = t_max;
        for k in 0..3 {
            let t1 = (self.min[k] - origin[k]) * inv_dir[k];
            let t2 = (self.max[k] - origin[k]) * inv_dir[k];
            // f64::min/max skip a NaN (0 * inf when the origin lies on a slab plane).
            t_enter = t_enter.max(t1.min(t2));
            t_exit = t_exit.min(t1.max(t2));
        }
        (t_enter <= t_exit).then_some(t_enter)
    }
}

/// `a.min(b)` for non-NaN input, as a single compare-and-select.
#[inline(always)]
fn lesser(a: f64, b: f64) -> f64 {
    if a < b {
        a
    } else {
        b
    }
}

#[inline(always)]
fn greater(a: f64, b: f64) -> f64 {
    if a > b {
        a
    } else {
        b
    }
}

/// Closest point of segment `a`-`b` to `p`, and its parameter along the segment.
pub fn closest_point_on_segment(p: &Vec3, a: &Vec3, b: &Vec3) -> (Vec3, f64) {
    let ab = b - a;
    let len2 = ab.norm_squared();
    if len2 == 0.0 {
        return (*a, 0.0);
    }
    let t = ((p - a).dot(&ab) / len2).clamp(0.0, 1.0);
    (a + t * ab, t)
}

/// Closest point of triangle `abc` to `p` and its barycentric coordinates
/// (weights of a, b, c). Ericson, Real-Time Collision Detection, 5.1.5: classify
/// `p` against the Voronoi regions of the corners, then the edges, then the face.
pub fn closest_point_on_triangle(p: &Vec3, tri: &[Vec3; 3]) -> (Vec3, [f64; 3]) {
    let [a, b, c] = tri;
    let ab = b - a;
    let ac = c - a;
    // The face formula divides by |ab x ac|^2: a (near-)collinear triangle is
    // handled as its three edges instead.
    let cross2 = ab.cross(&ac).norm_squared();
    if cross2 <= 1e-24 * ab.norm_squared() * ac.norm_squared() {
        return closest_point_on_degenerate_triangle(p, tri);
    }
    let ap = p - a;
    let d1 = ab.dot(&ap);
    let d2 = ac.dot(&ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return (*a, [1.0, 0.0, 0.0]);
    }
    let bp = p - b;
    let d3 = ab.dot(&bp);
    let d4 = ac.dot(&bp);
    if d3 >= 0.0 && d4 <= d3 {
        return (*b, [0.0, 1.0, 0.0]);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        // d1 - d3 = |ab|^2 > 0 for a non-degenerate triangle.
        let v = d1 / (d1 - d3);
        return (a + v * ab, [1.0 - v, v, 0.0]);
    }
    let cp = p - c;
    let d5 = ab.dot(&cp);
    let d6 = ac.dot(&cp);
    if d6 >= 0.0 && d5 <= d6 {
        return (*c, [0.0, 0.0, 1.0]);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (a + w * ac, [1.0 - w, 0.0, w]);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (b + w * (c - b), [0.0, 1.0 - w, w]);
    }
    let denom = 1.0 / (va + vb + vc);
    let v = vb * denom;
    let w = vc * denom;
    (a + v * ab + w * ac, [1.0 - v - w, v, w])
}

fn closest_point_on_degenerate_triangle(p: &Vec3, tri: &[Vec3; 3]) -> (Vec3, [f64; 3]) {
    let mut best = (tri[0], [1.0, 0.0, 0.0]);
    let mut best_d2 = f64::INFINITY;
    for k in 0..3 {
        let (i, j) = (k, (k + 1) % 3);
        let (point, t) = closest_point_on_segment(p, &tri[i], &tri[j]);
        let d2 = (point - p).norm_squared();
        if d2 < best_d2 {
            best_d2 = d2;
            let mut bary = [0.0; 3];
            bary[i] = 1.0 - t;
            bary[j] = t;
            best = (point, bary);
        }
    }
    best
}

/// Möller-Trumbore ray/triangle test, two-sided. Returns the ray parameter `t >= 0`
/// (in units of `|dir|`) of the hit; rays parallel to the triangle's plane miss.
pub fn ray_triangle(origin: &Vec3, dir: &Vec3, tri: &[Vec3; 3]) -> Option<f64> {
    let e1 = tri[1] - tri[0];
    let e2 = tri[2] - tri[0];
    let pvec = dir.cross(&e2);
    let det = e1.dot(&pvec);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv_det = 1.0 / det;
    let tvec = origin - tri[0];
    let u = tvec.dot(&pvec) * inv_det;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let qvec = tvec.cross(&e1);
    let v = dir.dot(&qvec) * inv_det;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = e2.dot(&qvec) * inv_det;
    (t >= 0.0).then_some(t)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_triangle() -> [Vec3; 3] {
        [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ]
    }

    #[test]
    fn closest_point_covers_every_voronoi_region() {
        let tri = unit_triangle();
        let cases = [
            (Vec3::new(0.2, 0.2, 3.0), Vec3::new(0.2, 0.2, 0.0)), // face
            (Vec3::new(-1.0, -1.0, 0.5), Vec3::new(0.0, 0.0, 0.0)), // corner a
            (Vec3::new(2.0, -0.5, 0.0), Vec3::new(1.0, 0.0, 0.0)), // corner b
            (Vec3::new(-0.5, 2.0, 0.0), Vec3::new(0.0, 1.0, 0.0)), // corner c
            (Vec3::new(0.5, -1.0, 1.0), Vec3::new(0.5, 0.0, 0.0)), // edge ab
            (Vec3::new(-1.0, 0.5, 0.0), Vec3::new(0.0, 0.5, 0.0)), // edge ac
            (Vec3::new(1.0, 1.0, 0.0), Vec3::new(0.5, 0.5, 0.0)), // edge bc
        ];
        for (q, expected) in cases {
            let (p, bary) = closest_point_on_triangle(&q, &tri);
            assert!(
                (p - expected).norm() < 1e-12,
                "query {q:?}: got {p:?}, expected {expected:?}"
            );
            let rebuilt = bary[0] * tri[0] + bary[1] * tri[1] + bary[2] * tri[2];
            assert!(
                (rebuilt - p).norm() < 1e-12,
                "barycentric {bary:?} do not rebuild {p:?}"
            );
        }
    }

    #[test]
    fn degenerate_triangle_falls_back_to_its_edges() {
        let tri = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(2.0, 0.0, 0.0),
        ];
        let (p, bary) = closest_point_on_triangle(&Vec3::new(1.5, 1.0, 0.0), &tri);
        assert!((p - Vec3::new(1.5, 0.0, 0.0)).norm() < 1e-12, "{p:?}");
        assert!(bary.iter().all(|w| w.is_finite()));
    }

    #[test]
    fn ray_hits_from_both_sides_and_misses_outside() {
        let tri = unit_triangle();
        let down = ray_triangle(
            &Vec3::new(0.25, 0.25, 2.0),
            &Vec3::new(0.0, 0.0, -1.0),
            &tri,
        );
        assert_eq!(down, Some(2.0));
        let up = ray_triangle(
            &Vec3::new(0.25, 0.25, -3.0),
            &Vec3::new(0.0, 0.0, 2.0),
            &tri,
        );
        assert_eq!(up, Some(1.5));
        assert_eq!(
            ray_triangle(&Vec3::new(0.9, 0.9, 2.0), &Vec3::new(0.0, 0.0, -1.0), &tri),
            None
        );
        assert_eq!(
            ray_triangle(&Vec3::new(0.25, 0.25, 2.0), &Vec3::new(0.0, 0.0, 1.0), &tri),
            None
        );
    }

    #[test]
    fn box_distance_and_ray_entry() {
        let b = Aabb {
            min: Vec3::new(0.0, 0.0, 0.0),
            max: Vec3::new(1.0, 1.0, 1.0),
        };
        assert_eq!(b.distance_squared_mm2(&Vec3::new(0.5, 0.5, 0.5)), 0.0);
        assert!((b.distance_squared_mm2(&Vec3::new(2.0, 3.0, 0.5)) - 5.0).abs() < 1e-12);
        let dir = Vec3::new(1.0, 0.0, 0.0);
        let inv = dir.map(|c| 1.0 / c);
        assert_eq!(
            b.ray_entry(&Vec3::new(-2.0, 0.5, 0.5), &inv, f64::INFINITY),
            Some(2.0)
        );
        assert_eq!(
            b.ray_entry(&Vec3::new(-2.0, 1.5, 0.5), &inv, f64::INFINITY),
            None
        );
        assert_eq!(b.ray_entry(&Vec3::new(-2.0, 0.5, 0.5), &inv, 1.0), None);
        assert!(Aabb::empty().is_empty());
    }
}

/// Generalized winding number of the closed triangle surface `mesh` around `q`: the sum of
/// the triangles' signed solid angles (Van Oosterom and Strackee 1983) over 4 pi; 1 inside
/// an outward surface, 0 outside, -1 inside an inward one. An inside test independent of
/// ray or column crossings, so tests can re-check what a voxelizer or a ray cast built.
pub fn winding_number(mesh: &crate::geometry::mesh::TriMesh, q: Vec3) -> f64 {
    let total: f64 = (0..mesh.triangles.len())
        .map(|t| {
            let [a, b, c] = mesh.triangle_points(t).map(|p| p - q);
            let (la, lb, lc) = (a.norm(), b.norm(), c.norm());
            let numerator = a.dot(&b.cross(&c));
            let denominator = la * lb * lc + a.dot(&b) * lc + a.dot(&c) * lb + b.dot(&c) * la;
            2.0 * numerator.atan2(denominator)
        })
        .sum();
    total / (4.0 * std::f64::consts::PI)
}
