//! Best-fit plane of a point set by principal component analysis, and polygon areas.
//!
//! The paper fits a plane to the suture points (and to the annulus rim) to get a
//! 2D parameter domain for the baffle; the signed 2D area tells the loop's winding.

use crate::geometry::mesh::Vec3;
use nalgebra::{DMatrix, SVD};

/// A plane through `centroid` with orthonormal in-plane axes and unit normal,
/// right-handed: `axis_u x axis_v = normal`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    pub centroid: Vec3,
    /// Unit normal: the direction of least variance.
    pub normal: Vec3,
    /// Unit direction of greatest variance.
    pub axis_u: Vec3,
    /// Unit direction of the second-greatest variance, `normal x axis_u`.
    pub axis_v: Vec3,
    /// Singular values of the centred point matrix, largest first (mm). The third is
    /// the out-of-plane spread; a second one near zero means the points are collinear.
    pub singular_values: [f64; 3],
}

impl Plane {
    /// In-plane coordinates (mm) of `p` relative to the centroid along (axis_u, axis_v).
    pub fn project_2d(&self, p: &Vec3) -> (f64, f64) {
        let d = p - self.centroid;
        (d.dot(&self.axis_u), d.dot(&self.axis_v))
    }

    /// The 3D point with in-plane coordinates (u, v): the inverse of `project_2d` on the plane.
    pub fn point_at(&self, u: f64, v: f64) -> Vec3 {
        self.centroid + u * self.axis_u + v * self.axis_v
    }

    /// Signed distance (mm) of `p` from the plane, positive on the normal's side.
    pub fn signed_distance_mm(&self, p: &Vec3) -> f64 {
        (p - self.centroid).dot(&self.normal)
    }
}

/// Least-squares plane through `points` by SVD of the centred points.
///
/// Never panics. Degenerate input still yields a right-handed orthonormal frame:
/// no points give centroid 0 and the canonical axes; collinear or coincident points
/// give `singular_values[1]` (or all) equal to zero, with arbitrary but orthonormal
/// axes where the data do not determine them; a non-finite coordinate gives NaN
/// centroid and singular values with the canonical axes. Use
/// [`best_fit_plane_checked`] to reject such input instead.
pub fn best_fit_plane(points: &[Vec3]) -> Plane {
    if points.is_empty() {
        return Plane {
            centroid: Vec3::zeros(),
            normal: Vec3::z(),
            axis_u: Vec3::x(),
            axis_v: Vec3::y(),
            singular_values: [0.0; 3],
        };
    }
    let centroid = points.iter().sum::<Vec3>() / points.len() as f64;
    let canonical = |singular_value: f64| Plane {
        centroid,
        normal: Vec3::z(),
        axis_u: Vec3::x(),
        axis_v: Vec3::y(),
        singular_values: [singular_value; 3],
    };
    if !centroid.iter().all(|c| c.is_finite()) {
        return canonical(f64::NAN);
    }
    // Pad to at least 3 rows (zeros do not change the right singular vectors) so the
    // SVD always returns 3 right singular vectors.
    let rows = points.len().max(3);
    let centred = DMatrix::from_fn(rows, 3, |r, c| points.get(r).map_or(0.0, |p| p[c] - centroid[c]));
    // Bounded iterations: SVD::new would loop without limit on pathological input.
    let Some(svd) = SVD::try_new(centred, false, true, f64::EPSILON, 1000) else {
        return canonical(f64::NAN);
    };
    let Some(v_t) = svd.v_t else {
        return canonical(f64::NAN);
    };
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| svd.singular_values[b].total_cmp(&svd.singular_values[a]));
    let right_singular_vector = |k: usize| Vec3::new(v_t[(k, 0)], v_t[(k, 1)], v_t[(k, 2)]);
    let axis_u = right_singular_vector(order[0]).normalize();
    let second = right_singular_vector(order[1]);
    // Re-orthogonalise and build the normal from the cross product so the frame is
    // right-handed whatever signs the SVD chose.
    let axis_v = (second - axis_u * axis_u.dot(&second)).normalize();
    let normal = axis_u.cross(&axis_v);
    Plane { centroid, normal, axis_u, axis_v, singular_values: order.map(|i| svd.singular_values[i]) }
}

/// Like [`best_fit_plane`] but rejects fewer than 3 points, non-finite coordinates and
/// (near-)collinear points (second singular value below 1e-9 of the first).
pub fn best_fit_plane_checked(points: &[Vec3]) -> Result<Plane, String> {
    if points.len() < 3 {
        return Err(format!("best-fit plane needs at least 3 points, got {}", points.len()));
    }
    if let Some(i) = points.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        return Err(format!("best-fit plane: point {i} has a non-finite coordinate {:?}", points[i]));
    }
    let plane = best_fit_plane(points);
    let [s0, s1, _] = plane.singular_values;
    if s0 == 0.0 || s1 <= 1e-9 * s0 {
        return Err(format!(
            "best-fit plane: the {} points are collinear or coincident (singular values {:?})",
            points.len(),
            plane.singular_values
        ));
    }
    Ok(plane)
}

/// Signed area (shoelace) of a closed 2D polygon given without repeating the first
/// vertex: positive when counter-clockwise.
pub fn polygon_area_2d(polygon: &[(f64, f64)]) -> f64 {
    let n = polygon.len();
    let twice_area: f64 = (0..n)
        .map(|i| {
            let (x0, y0) = polygon[i];
            let (x1, y1) = polygon[(i + 1) % n];
            x0 * y1 - x1 * y0
        })
        .sum();
    0.5 * twice_area
}

/// Vector area of a closed 3D polygon (first vertex not repeated): half the sum of
/// p_i x p_(i+1). Its length is the area of a planar polygon and its direction the
/// normal by the right-hand rule; for a non-planar loop it is the area of the
/// projection onto the plane it is normal to (independent of the origin).
pub fn polygon_vector_area(polygon: &[Vec3]) -> Vec3 {
    let n = polygon.len();
    0.5 * (0..n).map(|i| polygon[i].cross(&polygon[(i + 1) % n])).sum::<Vec3>()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An ellipse with semi-axes 5 and 2 mm, tilted and shifted, with small out-of-plane noise.
    fn tilted_ellipse(n: usize) -> (Vec<Vec3>, Vec3, Vec3, Vec3) {
        let centre = Vec3::new(10.0, -3.0, 7.0);
        let e1 = Vec3::new(1.0, 1.0, 0.0).normalize();
        let e2 = Vec3::new(-1.0, 1.0, 1.0).normalize();
        let e3 = e1.cross(&e2);
        let points = (0..n)
            .map(|i| {
                let a = 2.0 * std::f64::consts::PI * i as f64 / n as f64;
                centre + 5.0 * a.cos() * e1 + 2.0 * a.sin() * e2 + 0.01 * (3.0 * a).sin() * e3
            })
            .collect();
        (points, centre, e1, e3)
    }

    #[test]
    fn plane_recovers_axes_and_is_right_handed() {
        let (points, centre, e1, e3) = tilted_ellipse(64);
        let plane = best_fit_plane(&points);
        assert!((plane.centroid - centre).norm() < 1e-12);
        assert!(plane.axis_u.dot(&e1).abs() > 1.0 - 1e-6);
        assert!(plane.normal.dot(&e3).abs() > 1.0 - 1e-6);
        assert!((plane.axis_u.cross(&plane.axis_v) - plane.normal).norm() < 1e-12);
        let [s0, s1, s2] = plane.singular_values;
        assert!(s0 > s1 && s1 > s2 && s2 > 0.0);
    }

    #[test]
    fn projection_round_trips_in_plane_points() {
        let (points, ..) = tilted_ellipse(16);
        let plane = best_fit_plane(&points);
        let p = plane.point_at(1.5, -2.0);
        let (u, v) = plane.project_2d(&p);
        assert!((u - 1.5).abs() < 1e-12 && (v + 2.0).abs() < 1e-12);
        assert!(plane.signed_distance_mm(&p).abs() < 1e-12);
    }

    #[test]
    fn projected_ellipse_area_matches_pi_a_b() {
        let n = 2000;
        let (points, ..) = tilted_ellipse(n);
        let plane = best_fit_plane(&points);
        let polygon: Vec<(f64, f64)> = points.iter().map(|p| plane.project_2d(p)).collect();
        let area = polygon_area_2d(&polygon).abs();
        let exact = std::f64::consts::PI * 5.0 * 2.0;
        assert!((area - exact).abs() < 1e-3 * exact, "{area} vs {exact}");
        let vector_area = polygon_vector_area(&points);
        assert!((vector_area.norm() - area).abs() < 1e-9 * area);
        assert!(vector_area.normalize().dot(&plane.normal).abs() > 1.0 - 1e-9);
    }

    #[test]
    fn shoelace_sign_follows_winding() {
        let ccw = [(0.0, 0.0), (2.0, 0.0), (2.0, 3.0), (0.0, 3.0)];
        assert_eq!(polygon_area_2d(&ccw), 6.0);
        let cw: Vec<_> = ccw.iter().rev().copied().collect();
        assert_eq!(polygon_area_2d(&cw), -6.0);
    }

    #[test]
    fn degenerate_input_is_reported_not_panicked() {
        assert_eq!(best_fit_plane(&[]).normal, Vec3::z());
        let line: Vec<Vec3> = (0..5).map(|i| Vec3::new(i as f64, 2.0 * i as f64, 0.0)).collect();
        let plane = best_fit_plane(&line);
        assert!(plane.singular_values[1] < 1e-12);
        assert!((plane.axis_u.cross(&plane.axis_v) - plane.normal).norm() < 1e-12);
        let err = best_fit_plane_checked(&line).unwrap_err();
        assert!(err.contains("collinear"), "{err}");
        let err = best_fit_plane_checked(&line[..2]).unwrap_err();
        assert!(err.contains("at least 3"), "{err}");
        let mut bad = line.clone();
        bad[3].y = f64::NAN;
        assert!(best_fit_plane_checked(&bad).unwrap_err().contains("point 3"));
    }
}
