//! A seeded family of hearts whose aorta leans from the RV's top toward the VSD, as
//! over a subaortic VSD in DORV: LV and RV spheres overlapping at the VSD (which faces
//! -x), the aorta a tube leaving the RV tilted by 0-70 degrees toward the VSD and up to
//! 20 degrees sideways. From about 25 degrees the aorta meets the LV, the VSD and the
//! annulus share a rim on the union of the pools, and `prepare` must move its cuts
//! apart (or refuse, saying why). Each member carries suture points around both
//! openings and a target below its smaller opening, for `design`.

use crate::input::BloodPools;
use crate::shapes::{capped_tube, suture_ring, uv_sphere};
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
    let (vsd_center, vsd_radius) = params.vsd_circle();
    let vsd_half = vsd_radius.atan2(rv_center.x - vsd_center.x);
    let aorta_half = (params.aorta_radius_mm / params.rv_radius_mm).min(1.0).asin();
    let rho = vsd_half.max(aorta_half) + 12f64.to_radians();
    let suture_points_mm = suture_ring(rv_center, params.rv_radius_mm, -Vec3::x(), axis, rho);
    let target_area_mm2 = 0.6 * std::f64::consts::PI * params.aorta_radius_mm.powi(2);
    AortaTiltMember { seed, params, pools, suture_points_mm, target_area_mm2 }
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
