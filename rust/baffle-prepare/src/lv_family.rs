//! A seeded family of LV / RV / aorta blood pools built to stress `extend`'s mid-LV
//! plane: the LV is an ellipsoid, long or short, bent like a banana toward or away
//! from the RV, with the VSD anywhere from base to apex; the RV is an ellipsoid
//! wrapped around the LV (its ends may touch the LV a second time, as a thin septum
//! merged by the segmentation or a second muscular VSD does); the aorta leaves the
//! RV upward, tilted away from the LV or leaning over it (it may touch the LV). The plane through the LV's centroid parallel
//! to the VSD then misses the LV, cuts it in two loops, or lies beyond a second
//! LV-RV contact, which is what the plane moves of `extend` are for.

use crate::input::BloodPools;
use crate::shapes::{capped_tube, uv_sphere};
use baffle_core::geometry::numerics::random::SplitMix64;
use baffle_core::geometry::spatial::{winding_number, TriangleBvh};
use baffle_core::{TriMesh, Vec3};

/// The shape of one member (mm, radians per mm).
#[derive(Clone, Debug)]
pub struct LvFamilyParams {
    /// LV ellipsoid semi-axes before bending: across (x toward the RV, y) and long (z).
    pub lv_semi_axes_mm: [f64; 3],
    /// Curvature of the LV's long axis in the x-z plane; negative bends both ends
    /// toward the RV (+x), positive away from it.
    pub lv_bend_per_mm: f64,
    /// Where the VSD lies along the LV's long axis, as a fraction of the long
    /// semi-axis (-1 apex, +1 base).
    pub vsd_height: f64,
    /// How far the RV ellipsoid reaches into the LV at the VSD (mm).
    pub vsd_overlap_mm: f64,
    /// RV semi-axes: across and along the LV's long axis.
    pub rv_semi_axes_mm: [f64; 2],
    /// Curvature of the RV's long axis; positive wraps its ends around the LV (-x),
    /// where they may touch it a second and third time.
    pub rv_bend_per_mm: f64,
    pub aorta_radius_mm: f64,
    /// A second, muscular VSD: a channel from the LV to the RV beside the first.
    pub second_vsd: Option<SecondVsd>,
    /// Tilt of the aorta from the LV's long axis away from the LV (radians; negative
    /// tilts lean it over the LV, where it may touch it, as over a subaortic VSD).
    pub aorta_tilt: f64,
}

/// The LV-RV gap a second VSD crosses (mm): a muscular VSD through the septum.
const MIN_SECOND_VSD_LENGTH_MM: f64 = 1.0;
const MAX_SECOND_VSD_LENGTH_MM: f64 = 10.0;

/// A channel joining the LV and the RV where they are 1-10 mm apart: on the LV at
/// `height_offset` (fraction of the long semi-axis) from the VSD's height and
/// `around_deg` round the LV's long axis (toward `side` y), to the nearest RV point.
#[derive(Clone, Debug)]
pub struct SecondVsd {
    pub side: f64,
    pub height_offset: f64,
    /// Angle round the LV's long axis from the first VSD (degrees).
    pub around_deg: f64,
    pub radius_mm: f64,
}

#[derive(Clone, Debug)]
pub struct LvFamilyMember {
    pub seed: u64,
    pub params: LvFamilyParams,
    pub pools: BloodPools,
}

/// The member for `seed`: infant to adolescent LVs (semi-axes 6-10 mm across,
/// 1-2 times that long), bent up to a radius of 1.4 times the LV's half-width.
pub fn lv_family_member(seed: u64) -> LvFamilyMember {
    let mut rng = SplitMix64::new(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0x1F0D_3A5C_77E1_B2A9);
    let across = rng.between(6.0, 10.0);
    let lv_semi_axes_mm = [across, across * rng.between(0.8, 1.1), across * rng.between(1.0, 2.0)];
    // Bent at most to a radius of 1.4 half-widths (the surface stays one-to-one)
    // and through at most 100 degrees over the LV's length.
    let max_bend = (1.0 / (1.4 * across)).min(100f64.to_radians() / (2.0 * lv_semi_axes_mm[2]));
    let rv_across = rng.between(7.0, 11.0);
    let rv_long = rv_across * rng.between(1.0, 1.8);
    let max_rv_bend = (1.0 / (1.4 * rv_across)).min(120f64.to_radians() / (2.0 * rv_long));
    let params = LvFamilyParams {
        lv_semi_axes_mm,
        lv_bend_per_mm: rng.between(-max_bend, max_bend),
        vsd_height: rng.between(-0.7, 0.7),
        vsd_overlap_mm: rng.between(1.5, 3.5),
        rv_semi_axes_mm: [rv_across, rv_long],
        rv_bend_per_mm: rng.between(0.0, max_rv_bend),
        aorta_radius_mm: rng.between(3.0, 6.0),
        aorta_tilt: rng.between(-25f64.to_radians(), 40f64.to_radians()),
        second_vsd: None,
    };
    let second_vsd = (rng.unit() < 0.5).then(|| SecondVsd {
        side: if rng.unit() < 0.5 { -1.0 } else { 1.0 },
        height_offset: rng.between(-0.3, 0.3),
        around_deg: rng.between(60.0, 100.0),
        radius_mm: rng.between(1.0, 2.0),
    });
    let params = LvFamilyParams { second_vsd, ..params };
    LvFamilyMember { seed, pools: lv_family_pools(&params), params }
}

/// The pools a capped ventricle "made by hand" would come from (`prepare` refuses
/// pools whose union has a second LV-RV or an LV-aorta contact, by name): no second
/// VSD, and the aorta's radius reduced in 0.25 mm steps until it stays
/// `clearance_mm` off the LV. The designed domain then meets the member's pools as a
/// published one meets its segmentation.
pub fn hand_made_domain_pools(p: &LvFamilyParams, clearance_mm: f64) -> (LvFamilyParams, BloodPools) {
    let mut clear = LvFamilyParams { second_vsd: None, ..p.clone() };
    loop {
        let pools = lv_family_pools(&clear);
        if clear.aorta_radius_mm <= 1.0 || aorta_clearance_mm(&pools) >= clearance_mm {
            return (clear, pools);
        }
        clear.aorta_radius_mm -= 0.25;
    }
}

/// Smallest distance of an aorta point from the LV surface; 0 when one lies inside the LV.
fn aorta_clearance_mm(pools: &BloodPools) -> f64 {
    let Ok(bvh) = TriangleBvh::new(&pools.lv) else { return 0.0 };
    let inside = pools.aorta.points.iter().any(|q| winding_number(&pools.lv, *q) > 0.5);
    let nearest = pools.aorta.points.iter().filter_map(|q| bvh.closest_point(&pools.lv, *q)).map(|h| h.distance_mm).fold(f64::INFINITY, f64::min);
    if inside { 0.0 } else { nearest }
}

/// The blood pools of `p`: the RV ellipsoid is centred on the VSD's outward normal
/// so that it reaches `vsd_overlap_mm` into the LV there.
pub fn lv_family_pools(p: &LvFamilyParams) -> BloodPools {
    let lv_point = |s: Vec3| bend(Vec3::new(s.x * p.lv_semi_axes_mm[0], s.y * p.lv_semi_axes_mm[1], s.z * p.lv_semi_axes_mm[2]), p.lv_bend_per_mm);
    let mut lv = uv_sphere(Vec3::zeros(), 1.0, 48, 96);
    lv.points.iter_mut().for_each(|s| *s = lv_point(*s));
    // The VSD's centre on the LV's +x side at `vsd_height`, and the outward normal there.
    let h = p.vsd_height;
    let on_sphere = |height: f64, angle: f64| Vec3::new((1.0 - height * height).sqrt() * angle.cos(), (1.0 - height * height).sqrt() * angle.sin(), height);
    let vsd = lv_point(on_sphere(h, 0.0));
    let d = 1e-4;
    let along = lv_point(on_sphere(h + d, 0.0)) - lv_point(on_sphere(h - d, 0.0));
    let around = lv_point(on_sphere(h, d)) - lv_point(on_sphere(h, -d));
    // On the sphere, (around x along) points outward; the bend keeps orientation.
    let normal = around.cross(&along).normalize();
    let [r, long] = p.rv_semi_axes_mm;
    let reach = 1.0 / ((normal.x * normal.x + normal.y * normal.y) / (r * r) + normal.z * normal.z / (long * long)).sqrt();
    let rv_center = vsd + normal * (reach - p.vsd_overlap_mm);
    let mut rv = uv_sphere(Vec3::zeros(), 1.0, 48, 96);
    rv.points.iter_mut().for_each(|s| *s = rv_center + bend(Vec3::new(s.x * r, s.y * r, s.z * long), p.rv_bend_per_mm));
    if let Some(channel) = p.second_vsd.as_ref().and_then(|second| second_vsd_channel(second, h, &rv, &|height, angle| lv_point(on_sphere(height, angle)))) {
        append(&mut rv, &channel);
    }
    let axis = Vec3::new(p.aorta_tilt.sin(), 0.0, p.aorta_tilt.cos());
    let aorta = capped_tube(rv_center + axis * (0.4 * long), rv_center + axis * (long + 6.0 * p.aorta_radius_mm), p.aorta_radius_mm, 24, 64);
    BloodPools { lv, rv, aorta }
}

/// The second VSD's channel (a tube 1 mm into each pool), or none when the RV lies
/// more than `MAX_SECOND_VSD_LENGTH_MM` off the LV all around.
fn second_vsd_channel(second: &SecondVsd, vsd_height: f64, rv: &TriMesh, lv_at: &dyn Fn(f64, f64) -> Vec3) -> Option<TriMesh> {
    let bvh = TriangleBvh::new(rv).ok()?;
    let height = (vsd_height + second.height_offset).clamp(-0.8, 0.8);
    let gap_at = |deg: f64| {
        let q = lv_at(height, second.side * deg.to_radians());
        let hit = bvh.closest_point(rv, q)?;
        (winding_number(rv, q) < 0.5).then_some((q, hit))
    };
    let (q, hit) = gap_at(second.around_deg)?;
    if !(MIN_SECOND_VSD_LENGTH_MM..=MAX_SECOND_VSD_LENGTH_MM).contains(&hit.distance_mm) {
        return None;
    }
    let dir = (hit.point - q).normalize();
    Some(capped_tube(q - dir, hit.point + dir, second.radius_mm, 8, 24))
}

/// `other`'s points and triangles added to `mesh` (a second closed component).
pub fn append(mesh: &mut TriMesh, other: &TriMesh) {
    let offset = mesh.points.len() as u32;
    mesh.points.extend_from_slice(&other.points);
    mesh.triangles.extend(other.triangles.iter().map(|t| t.map(|v| v + offset)));
    mesh.face_ids.extend_from_slice(&other.face_ids);
}

/// Bend the z axis into an arc of curvature `kappa` in the x-z plane (lengths along
/// the axis kept; `kappa < 0` turns both ends toward +x).
fn bend(q: Vec3, kappa: f64) -> Vec3 {
    if kappa.abs() < 1e-9 {
        return q;
    }
    let theta = kappa * q.z;
    Vec3::new(q.x * theta.cos() + (theta.cos() - 1.0) / kappa, q.y, (1.0 / kappa + q.x) * theta.sin())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bend_keeps_lengths_along_the_axis_and_turns_the_ends() {
        let kappa = -0.05;
        let a = bend(Vec3::new(0.0, 0.0, 10.0), kappa);
        // An arc of length 10 on radius 20: the end moves toward +x by 20 (1 - cos 0.5).
        assert!((a.x - 20.0 * (1.0 - 0.5f64.cos())).abs() < 1e-9 && (a.z - 20.0 * 0.5f64.sin()).abs() < 1e-9, "{a:?}");
        assert_eq!(bend(Vec3::new(1.0, 2.0, 3.0), 0.0), Vec3::new(1.0, 2.0, 3.0));
    }

    #[test]
    fn members_are_closed_outward_and_the_rv_reaches_into_the_lv() {
        for seed in 0..8 {
            let m = lv_family_member(seed);
            for (name, mesh) in [("LV", &m.pools.lv), ("RV", &m.pools.rv), ("aorta", &m.pools.aorta)] {
                assert!(baffle_core::geometry::mesh::manifold_report(mesh).is_closed_manifold() && mesh.signed_volume_mm3() > 0.0, "seed {seed}: {name}");
            }
            let inside_lv = m.pools.rv.points.iter().filter(|p| baffle_core::geometry::spatial::winding_number(&m.pools.lv, **p) > 0.5).count();
            assert!(inside_lv > 0, "seed {seed}: the RV does not reach into the LV: {:?}", m.params);
        }
    }
}
