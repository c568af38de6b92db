//! Step 6, per-section amplitudes [paper 2.4.4].
//!
//! The baffle arc of a section is displaced in the section's plane by the parabolic
//! profile alpha * 4 s (1 - s) * v, where s in [0, 1] is normalized arc length along
//! the arc and v is the in-plane unit normal to the arc's endpoint chord, oriented so
//! the displacement increases the enclosed area. The loop is planar by construction,
//! so its SVD best-fit plane is the cutting plane, which we use directly (this stays
//! well defined when the arc is nearly straight). The shoelace area of the displaced
//! loop is exactly linear in alpha (the v x v term vanishes), so the smallest
//! alpha >= 0 reaching the target is found in closed form.

use crate::geometry::mesh::Vec3;
use crate::steps::sections::{signed_loop_area_mm2, BaffleArc};

/// How a section's area responds to the amplitude alpha: area(alpha) =
/// area0 + slope * alpha, for the displacement alpha * weight_i * direction of arc point i.
#[derive(Clone, Debug)]
pub struct ArcDisplacement {
    /// Unit in-plane displacement direction v (mm per mm of alpha).
    pub direction: Vec3,
    /// 4 s (1 - s) for each arc point, in arc order.
    pub weights: Vec<f64>,
    /// Point indices of the arc in the contour.
    pub arc_indices: Vec<usize>,
    pub area0_mm2: f64,
    pub slope_mm: f64,
}

impl ArcDisplacement {
    /// The arc's points displaced by amplitude `alpha_mm`.
    pub fn displaced_arc(&self, points: &[Vec3], alpha_mm: f64) -> Vec<Vec3> {
        self.arc_indices.iter().zip(&self.weights).map(|(&i, &w)| points[i] + alpha_mm * w * self.direction).collect()
    }

    /// Smallest alpha >= 0 for which the area reaches `required_area_mm2`.
    pub fn required_alpha_mm(&self, required_area_mm2: f64) -> f64 {
        if self.area0_mm2 >= required_area_mm2 {
            return 0.0;
        }
        (required_area_mm2 - self.area0_mm2) / self.slope_mm
    }

    pub fn area_mm2(&self, alpha_mm: f64) -> f64 {
        self.area0_mm2 + self.slope_mm * alpha_mm
    }
}

/// Set up the parabolic displacement of a section's baffle arc. `None` when the arc
/// is degenerate (coincident endpoints or no area response).
pub fn arc_displacement(points: &[Vec3], arc: &BaffleArc, plane_normal: &Vec3) -> Option<ArcDisplacement> {
    let arc_indices = arc.indices(points.len());
    let (first, last) = (points[arc_indices[0]], points[*arc_indices.last()?]);
    let chord = last - first;
    let in_plane_chord = chord - plane_normal * plane_normal.dot(&chord);
    if in_plane_chord.norm() <= 1e-9 {
        return None;
    }
    let weights = parabolic_weights(points, &arc_indices);
    // Orient the loop so its area is positive about `normal`.
    let orientation = signed_loop_area_mm2(points, plane_normal).signum();
    let normal = plane_normal * orientation;
    let area0_mm2 = signed_loop_area_mm2(points, &normal);
    let mut direction = normal.cross(&in_plane_chord).normalize();
    let mut disp = ArcDisplacement { direction, weights, arc_indices, area0_mm2, slope_mm: 0.0 };
    let slope = displaced_area_mm2(points, &disp, 1.0, &normal) - area0_mm2;
    if slope.abs() <= 1e-12 {
        return None;
    }
    if slope < 0.0 {
        direction = -direction;
    }
    disp.direction = direction;
    disp.slope_mm = slope.abs();
    Some(disp)
}

/// 4 s (1 - s) with s the normalized arc length of each arc point.
fn parabolic_weights(points: &[Vec3], arc_indices: &[usize]) -> Vec<f64> {
    let mut lengths = vec![0.0];
    for w in arc_indices.windows(2) {
        lengths.push(lengths.last().copied().unwrap_or(0.0) + (points[w[1]] - points[w[0]]).norm());
    }
    let total = lengths.last().copied().unwrap_or(0.0).max(1e-300);
    lengths.iter().map(|l| {
        let s = l / total;
        4.0 * s * (1.0 - s)
    }).collect()
}

fn displaced_area_mm2(points: &[Vec3], disp: &ArcDisplacement, alpha_mm: f64, normal: &Vec3) -> f64 {
    let mut moved = points.to_vec();
    for (p, &i) in disp.displaced_arc(points, alpha_mm).into_iter().zip(&disp.arc_indices) {
        moved[i] = p;
    }
    signed_loop_area_mm2(&moved, normal)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A square loop of side 4 in the z = 0 plane, with 5 points per side; the baffle
    /// arc is the top side (y = 4), from (4,4) to (0,4).
    fn square() -> (Vec<Vec3>, BaffleArc) {
        let corners = [(0.0, 0.0), (4.0, 0.0), (4.0, 4.0), (0.0, 4.0)];
        let mut pts = Vec::new();
        for k in 0..4 {
            let (a, b) = (corners[k], corners[(k + 1) % 4]);
            for i in 0..4 {
                let f = i as f64 / 4.0;
                pts.push(Vec3::new(a.0 + f * (b.0 - a.0), a.1 + f * (b.1 - a.1), 0.0));
            }
        }
        (pts, BaffleArc { start: 8, end: 12 })
    }

    #[test]
    fn area_is_linear_in_alpha_and_bulges_outward() {
        let (pts, arc) = square();
        let disp = arc_displacement(&pts, &arc, &Vec3::z()).unwrap();
        assert!((disp.area0_mm2 - 16.0).abs() < 1e-12);
        // Outward from the square's top side is +y.
        assert!((disp.direction - Vec3::y()).norm() < 1e-12);
        // Discrete parabola on 5 points at s = 0, .25, .5, .75, 1: weights 0, .75, 1, .75, 0;
        // trapezoid area of the bulge over the 4 mm chord: 1 mm * (0.75 + 1 + 0.75) per alpha.
        assert!((disp.slope_mm - 2.5).abs() < 1e-12, "{}", disp.slope_mm);
        for alpha in [0.5, 1.0, 3.0] {
            let direct = displaced_area_mm2(&pts, &disp, alpha, &Vec3::z());
            assert!((direct - disp.area_mm2(alpha)).abs() < 1e-9);
        }
        let alpha = disp.required_alpha_mm(20.0);
        assert!((disp.area_mm2(alpha) - 20.0).abs() < 1e-12);
        assert_eq!(disp.required_alpha_mm(10.0), 0.0);
    }

    #[test]
    fn reversed_loop_and_flipped_normal_give_the_same_answer() {
        let (mut pts, _) = square();
        pts.reverse();
        // Reversed, the top side runs from index 3 ((0,4)) to 7 ((4,4)).
        let arc = BaffleArc { start: 3, end: 7 };
        let disp = arc_displacement(&pts, &arc, &(-Vec3::z())).unwrap();
        assert!((disp.area0_mm2 - 16.0).abs() < 1e-12);
        assert!((disp.direction - Vec3::y()).norm() < 1e-12);
        assert!((disp.slope_mm - 2.5).abs() < 1e-12);
    }
}
