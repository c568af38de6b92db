//! A seeded family of hearts whose aorta leans from the RV's top toward the VSD, as
//! over a subaortic VSD in DORV: LV and RV spheres overlapping at the VSD (which faces
//! -x), the aorta a tube leaving the RV tilted by 0-70 degrees toward the VSD and up to
//! 20 degrees sideways. From about 25 degrees the aorta meets the LV, the VSD and the
//! annulus share a rim on the union of the pools, and `prepare` must move its cuts
//! apart (or refuse, saying why). Each member carries suture points around both
//! openings and a target below its smaller opening, for `design`.

use crate::input::BloodPools;
use crate::shapes::{capped_tube, shaped_suture_ring, suture_ring, tapered_suture_ring, uv_sphere};
use baffle_core::geometry::numerics::random::SplitMix64;
use baffle_core::Vec3;

/// The shape of one member (mm, degrees).
#[derive(Clone, Debug, serde::Serialize)]
pub struct AortaTiltParams {
    pub lv_radius_mm: f64,
    pub rv_radius_mm: f64,
    /// How far the RV sphere reaches into the LV sphere along x (mm).
    pub vsd_overlap_mm: f64,
    pub aorta_radius_mm: f64,
    /// Tilt of the aorta from +z toward the VSD (-x).
    pub tilt_deg: f64,
    /// Turn of the tilt's direction round z, toward +y.
    pub sideways_deg: f64,
}

#[derive(Clone, Debug)]
pub struct AortaTiltMember {
    pub seed: u64,
    pub params: AortaTiltParams,
    pub pools: BloodPools,
    /// 18 points on the RV sphere around both openings.
    pub suture_points_mm: Vec<Vec3>,
    /// Target tunnel area (mm2): 60% of the aorta's cross-section.
    pub target_area_mm2: f64,
}

impl AortaTiltParams {
    pub fn rv_center(&self) -> Vec3 {
        Vec3::new(self.lv_radius_mm + self.rv_radius_mm - self.vsd_overlap_mm, 0.0, 0.0)
    }

    pub fn aorta_axis(&self) -> Vec3 {
        let (t, s) = (self.tilt_deg.to_radians(), self.sideways_deg.to_radians());
        Vec3::new(-t.sin() * s.cos(), t.sin() * s.sin(), t.cos())
    }

    /// The VSD: the spheres' circle of intersection, its centre on x and its radius (mm).
    pub fn vsd_circle(&self) -> (Vec3, f64) {
        let (d, a, b) = (self.rv_center().x, self.lv_radius_mm, self.rv_radius_mm);
        let x0 = (d * d + a * a - b * b) / (2.0 * d);
        (Vec3::new(x0, 0.0, 0.0), (a * a - x0 * x0).max(0.0).sqrt())
    }

    /// The VSD's and the aortic opening's half-angles on the RV sphere, seen from its
    /// centre (radians).
    pub fn opening_half_angles(&self) -> (f64, f64) {
        let (vsd_center, vsd_radius) = self.vsd_circle();
        let vsd_half = vsd_radius.atan2(self.rv_center().x - vsd_center.x);
        let aorta_half = (self.aorta_radius_mm / self.rv_radius_mm).min(1.0).asin();
        (vsd_half, aorta_half)
    }

    /// The VSD overlap at which the VSD's half-angle on the RV sphere is `max_vsd_half`
    /// (radians), kept between `min_overlap_mm` and this member's own: the VSD narrows as
    /// the spheres overlap less.
    pub fn vsd_overlap_for_half_angle(&self, max_vsd_half: f64, min_overlap_mm: f64) -> f64 {
        let half_at = |overlap: f64| AortaTiltParams { vsd_overlap_mm: overlap, ..self.clone() }.opening_half_angles().0;
        let (mut lo, mut hi) = (min_overlap_mm.min(self.vsd_overlap_mm), self.vsd_overlap_mm);
        if half_at(hi) <= max_vsd_half {
            return hi;
        }
        if half_at(lo) >= max_vsd_half {
            return lo;
        }
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if half_at(mid) > max_vsd_half {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        lo
    }

    /// The annulus: where the tube's axis meets the RV sphere (the tube starts inside it).
    pub fn annulus_center(&self) -> Vec3 {
        let rise = (self.rv_radius_mm.powi(2) - self.aorta_radius_mm.powi(2)).max(0.0).sqrt();
        self.rv_center() + self.aorta_axis() * rise
    }
}

/// The member for `seed`: tilts spread evenly over 0-70 degrees by the seed (so any 15
/// consecutive seeds cover the range), the rest drawn.
pub fn aorta_tilt_member(seed: u64) -> AortaTiltMember {
    let mut rng = SplitMix64::new(seed.wrapping_mul(0xD1B5_4A32_D192_ED03) ^ 0x5EED_A0A7_1170_0001);
    let params = AortaTiltParams {
        lv_radius_mm: rng.between(9.0, 11.0),
        rv_radius_mm: rng.between(8.0, 10.0),
        vsd_overlap_mm: rng.between(2.0, 4.0),
        aorta_radius_mm: rng.between(3.5, 6.0),
        tilt_deg: 5.0 * (seed % 15) as f64 + rng.between(0.0, 5.0),
        sideways_deg: rng.between(-20.0, 20.0),
    };
    aorta_tilt_from(seed, params)
}

/// The member with `params` (the pools, points and target are derived).
pub fn aorta_tilt_from(seed: u64, params: AortaTiltParams) -> AortaTiltMember {
    let (rv_center, axis) = (params.rv_center(), params.aorta_axis());
    let pools = BloodPools {
        lv: uv_sphere(Vec3::zeros(), params.lv_radius_mm, 48, 96),
        rv: uv_sphere(rv_center, params.rv_radius_mm, 48, 96),
        aorta: capped_tube(rv_center + axis * 4.0, rv_center + axis * 25.0, params.aorta_radius_mm, 20, 64),
    };
    // The ring clears the wider opening's half-angle on the RV sphere by 12 degrees.
    let (vsd_half, aorta_half) = params.opening_half_angles();
    let rho = vsd_half.max(aorta_half) + 12f64.to_radians();
    let suture_points_mm = suture_ring(rv_center, params.rv_radius_mm, -Vec3::x(), axis, rho);
    let target_area_mm2 = 0.6 * std::f64::consts::PI * params.aorta_radius_mm.powi(2);
    AortaTiltMember { seed, params, pools, suture_points_mm, target_area_mm2 }
}

/// Suture points that follow each opening `margin_mm` (along the RV sphere) outside its
/// rim, the sides going linearly from the VSD's distance to the aorta's, instead of the
/// member's ring, 12 degrees outside the wider opening all along. With a wide aortic root
/// that ring is as wide as the root over the whole tunnel, so the tunnel's throat is about
/// the root's size; this one narrows toward the smaller opening, as a suture line along
/// both rims does, so the aortic plane can be wider than the throat before it.
pub fn rim_following_suture_points(params: &AortaTiltParams, margin_mm: f64) -> Vec<Vec3> {
    waisted_suture_points(params, margin_mm, 0.0)
}

/// `rim_following_suture_points` pinched between the openings, as a suture line along a
/// protruding conal septum narrows the tunnel midway: the kth side point's distance from the
/// arc is the linear taper's times 1 - `waist` sin(pi k / 5), but never nearer than
/// `margin_mm` to either opening's rim: on the sphere a point s along the arc from an
/// opening's centre and r to its side lies acos(cos s cos r) from that centre, so it keeps
/// a + margin from an opening of half-angle a while r >= acos(cos(a + margin) / cos s). A waist
/// of 0 gives `rim_following_suture_points`' points.
pub fn waisted_suture_points(params: &AortaTiltParams, margin_mm: f64, waist: f64) -> Vec<Vec3> {
    let (vsd_half, aorta_half) = params.opening_half_angles();
    let margin = margin_mm / params.rv_radius_mm;
    let (rho_vsd, rho_aorta) = (vsd_half + margin, aorta_half + margin);
    // Without a waist, the rim-following line as it was: its linear taper keeps only part of
    // the margin beside the wider opening, and the clearance below would move those points
    // (on 48 of the aorta family's first 100 shapes), and with them the earlier families.
    if waist == 0.0 {
        return tapered_suture_ring(params.rv_center(), params.rv_radius_mm, -Vec3::x(), params.aorta_axis(), rho_vsd, rho_aorta);
    }
    let span = (-Vec3::x()).dot(&params.aorta_axis()).clamp(-1.0, 1.0).acos();
    let clear_of = |reach: f64, s: f64| if s < reach { (reach.cos() / s.cos()).clamp(-1.0, 1.0).acos() } else { 0.0 };
    let side_rho = |k: usize| {
        let t = k as f64 / 5.0;
        let pinched = (rho_vsd + (rho_aorta - rho_vsd) * t) * (1.0 - waist * (std::f64::consts::PI * t).sin());
        pinched.max(clear_of(rho_vsd, span * t)).max(clear_of(rho_aorta, span * (1.0 - t)))
    };
    shaped_suture_ring(params.rv_center(), params.rv_radius_mm, -Vec3::x(), params.aorta_axis(), rho_vsd, rho_aorta, &side_rho)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An LV of 10 mm and an RV of 9 mm, with the given VSD overlap, aorta, tilt and turn.
    fn heart(vsd_overlap_mm: f64, aorta_radius_mm: f64, tilt_deg: f64, sideways_deg: f64) -> AortaTiltParams {
        AortaTiltParams { lv_radius_mm: 10.0, rv_radius_mm: 9.0, vsd_overlap_mm, aorta_radius_mm, tilt_deg, sideways_deg }
    }

    #[test]
    fn members_are_seeded_and_cover_the_tilts() {
        let a = aorta_tilt_member(7);
        let b = aorta_tilt_member(7);
        assert_eq!(a.pools.aorta.points, b.pools.aorta.points, "the same seed gives the same member");
        let tilts: Vec<f64> = (0..15).map(|s| aorta_tilt_member(s).params.tilt_deg).collect();
        assert!(tilts.iter().any(|&t| t < 5.0) && tilts.iter().any(|&t| t >= 70.0 - 5.0), "{tilts:?}");
        for s in 0..15 {
            let m = aorta_tilt_member(s);
            let (c, r) = m.params.vsd_circle();
            assert!(r > 3.0, "seed {s}: the spheres overlap in a VSD of radius {r:.2}");
            assert!(c.x > 0.0 && c.x < m.params.lv_radius_mm);
        }
    }

    #[test]
    fn rim_following_points_keep_their_margin_from_both_openings() {
        // A wide root (the aorta 0.65 of the RV) leaning away from a VSD of about 39 degrees.
        let params = heart(3.5, 5.85, -20.0, 10.0);
        let (vsd_half, aorta_half) = params.opening_half_angles();
        let (center, margin) = (params.rv_center(), 1.0 / params.rv_radius_mm);
        let points = rim_following_suture_points(&params, 1.0);
        assert_eq!(points.len(), 18);
        let from = |p: &Vec3, d: Vec3| ((p - center) / params.rv_radius_mm).dot(&d).clamp(-1.0, 1.0).acos();
        for (i, p) in points.iter().enumerate() {
            assert!(((p - center).norm() - params.rv_radius_mm).abs() < 1e-9, "point {i} is on the RV sphere");
            // Between the ends the ring is nearer one opening than its own margin only by the
            // taper, a part of the margin.
            let (to_vsd, to_aorta) = (from(p, -Vec3::x()) - vsd_half, from(p, params.aorta_axis()) - aorta_half);
            assert!(to_vsd > 0.5 * margin && to_aorta > 0.5 * margin, "point {i}: {to_vsd:.3} {to_aorta:.3} rad outside the rims");
        }
        // The ends: the first point is beside the VSD's centre at its margin, the sixth
        // beside the aorta's at its own.
        assert!((from(&points[0], -Vec3::x()) - (vsd_half + margin)).abs() < 1e-9);
        assert!((from(&points[5], params.aorta_axis()) - (aorta_half + margin)).abs() < 1e-9);
        // Narrower across the tunnel (points 2 and 12 face each other across the arc, two
        // fifths along it) than the member's ring, 12 degrees outside the wider opening.
        let even = aorta_tilt_from(0, params.clone()).suture_points_mm;
        let across = |ps: &[Vec3]| (ps[2] - ps[12]).norm();
        assert!(across(&points) < across(&even) - 1.0, "{:.2} against {:.2} mm", across(&points), across(&even));
    }

    #[test]
    fn a_waist_pinches_the_tunnel_midway_and_keeps_off_both_rims() {
        // Openings about 80 degrees apart (tilt -35), so the sides between them are free to pinch.
        let params = heart(3.0, 5.5, -35.0, 5.0);
        let (vsd_half, aorta_half) = params.opening_half_angles();
        let (center, margin) = (params.rv_center(), 1.2 / params.rv_radius_mm);
        let straight = rim_following_suture_points(&params, 1.2);
        assert_eq!(waisted_suture_points(&params, 1.2, 0.0), straight, "no waist, the rim-following points");
        let waisted = waisted_suture_points(&params, 1.2, 0.5);
        let from = |p: &Vec3, d: Vec3| ((p - center) / params.rv_radius_mm).dot(&d).clamp(-1.0, 1.0).acos();
        // Pinched, a point keeps the margin from both rims, or the straight line's own distance
        // where that is less (the taper's sides between the ends).
        for (i, (p, q)) in waisted.iter().zip(&straight).enumerate() {
            assert!(((p - center).norm() - params.rv_radius_mm).abs() < 1e-9, "point {i} is on the RV sphere");
            for (axis, half) in [(-Vec3::x(), vsd_half), (params.aorta_axis(), aorta_half)] {
                let (pinched, unpinched) = (from(p, axis) - half, from(q, axis) - half);
                assert!(pinched > margin.min(unpinched) - 1e-9, "point {i}: {pinched:.4} rad outside a rim, straight {unpinched:.4}");
            }
        }
        // The ends and the points round them stay; across the middle (points 2 and 12, 3 and
        // 11) the line is narrower.
        for i in [0, 5, 6, 7, 8, 9, 14, 15, 16, 17] {
            assert!((waisted[i] - straight[i]).norm() < 1e-9, "point {i} moved");
        }
        let across = |ps: &[Vec3], a: usize, b: usize| (ps[a] - ps[b]).norm();
        for (a, b) in [(2, 12), (3, 11)] {
            assert!(across(&waisted, a, b) < across(&straight, a, b) - 2.0, "points {a}, {b}: {:.2} against {:.2} mm", across(&waisted, a, b), across(&straight, a, b));
        }
    }

    #[test]
    fn the_vsd_narrows_to_a_half_angle_within_the_overlaps_bounds() {
        let params = heart(3.5, 5.0, -20.0, 0.0);
        let half = |overlap: f64| AortaTiltParams { vsd_overlap_mm: overlap, ..params.clone() }.opening_half_angles().0;
        let (at_2, at_3_5) = (half(2.0), half(3.5));
        assert!(at_2 < at_3_5, "less overlap, a narrower VSD: {at_2} {at_3_5}");
        let between = 0.5 * (at_2 + at_3_5);
        let overlap = params.vsd_overlap_for_half_angle(between, 2.0);
        assert!(overlap > 2.0 && overlap < 3.5 && (half(overlap) - between).abs() < 1e-9, "{overlap}");
        assert_eq!(params.vsd_overlap_for_half_angle(at_3_5 + 0.01, 2.0), 3.5, "already narrow enough: unchanged");
        assert_eq!(params.vsd_overlap_for_half_angle(at_2 - 0.01, 2.0), 2.0, "not below the least overlap");
    }
}
