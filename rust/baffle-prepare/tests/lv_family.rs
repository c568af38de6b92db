//! `extend` on the LV family (`lv_family`): LVs long and short, bent toward or away
//! from the RV, VSDs from apex to base, RVs wrapped around the LV, aortas leaning over
//! the LV. Each member's designed domain is the capped ventricle of its pools with the
//! aorta kept clear of the LV (as a hand-made one would be); extend then meets the
//! real pools. Every member must extend (re-measured by `common::check_extended`) or
//! be refused by a message naming the mid-LV plane and each move tried.

use baffle_core::Vec3;
use baffle_prepare::extend::{extend, ExtendOptions};
use baffle_prepare::lv_family::{append, hand_made_domain_pools, lv_family_member, lv_family_pools, LvFamilyParams};
use baffle_prepare::shapes::{capped_tube, uv_sphere};
use baffle_prepare::{prepare, BloodPools, PrepareOptions};

mod common;
use common::check_extended;

/// A 0.4 mm grid keeps the test quick; the union is made as `prepare` makes it.
fn options() -> (PrepareOptions, ExtendOptions) {
    let prepare_options = PrepareOptions { voxel_mm: 0.4, ..PrepareOptions::default() };
    (prepare_options.clone(), ExtendOptions { union: prepare_options, ..ExtendOptions::default() })
}

/// The first members (0-7): LVs long and short, bent both ways, with a second VSD
/// or not. Where a second VSD opens beside the plane through the LV's centroid
/// (seeds 1, 3 and 7), that plane's cut ran over the RV and the inflow cap closed
/// part of it (its rim 1.2-1.8 mm off the LV, which extend did not see): the plane
/// is now moved 2 mm deeper, past the second VSD.
#[test]
fn the_first_members_extend_with_the_plane_moved_past_a_second_vsd() {
    let (prepare_options, extend_options) = options();
    let mut moved = Vec::new();
    for seed in 0..8 {
        let member = lv_family_member(seed);
        let (_, domain_pools) = hand_made_domain_pools(&member.params, 0.9);
        let (domain, _) = prepare(&domain_pools, &prepare_options).unwrap_or_else(|e| panic!("seed {seed}: prepare: {e}"));
        let e = extend(&domain, &member.pools, &extend_options).unwrap_or_else(|e| panic!("seed {seed}: extend: {e}"));
        check_extended(&format!("seed {seed}"), &domain, &member.pools, &e);
        if e.report.mid_lv_plane.moved_from_centroid_mm != 0.0 {
            moved.push(seed);
        }
    }
    assert_eq!(moved, [1, 3, 7], "the members whose mid-LV plane had to move");
}

/// The aorta tilted 10 degrees toward the VSD overlaps the LV by 0.24 mm (the
/// `aorta_tilt` example's radius 6): the union of all three pools had a handle
/// through both caps' rims and the LV part crossed the aortic one ("the extension
/// crosses itself"); each part is now cut from the union of its own two pools.
#[test]
fn an_aorta_touching_the_lv_no_longer_joins_the_parts() {
    let rv_center = Vec3::new(16.0, 0.0, 0.0);
    let tilt = 10f64.to_radians();
    let axis = Vec3::new(-tilt.sin(), 0.0, tilt.cos());
    let pools = BloodPools {
        lv: uv_sphere(Vec3::zeros(), 10.0, 48, 96),
        rv: uv_sphere(rv_center, 9.0, 48, 96),
        aorta: capped_tube(rv_center + axis * 4.0, rv_center + axis * 25.0, 6.0, 20, 64),
    };
    let prepare_options = PrepareOptions { voxel_mm: 0.3, closing_radius_mm: 0.0, ..PrepareOptions::default() };
    let (domain, _) = prepare(&pools, &prepare_options).unwrap();
    let e = extend(&domain, &pools, &ExtendOptions { union: prepare_options, ..ExtendOptions::default() }).unwrap_or_else(|e| panic!("{e}"));
    check_extended("aorta on the LV", &domain, &pools, &e);
}

/// An LV with no room behind the VSD: every move is listed in the refusal.
#[test]
fn an_lv_without_room_behind_the_vsd_is_refused_with_every_move() {
    let (prepare_options, extend_options) = options();
    let p = LvFamilyParams { lv_semi_axes_mm: [8.0, 8.0, 10.0], lv_bend_per_mm: 0.0, vsd_height: 0.0, vsd_overlap_mm: 2.5, rv_semi_axes_mm: [9.0, 10.0], rv_bend_per_mm: 0.0, aorta_radius_mm: 4.0, aorta_tilt: 0.3, second_vsd: None };
    let pools = lv_family_pools(&p);
    let (domain, _) = prepare(&pools, &prepare_options).unwrap();
    // The same domain with a small LV on the RV's side of the VSD plane.
    let moved = BloodPools { lv: uv_sphere(Vec3::new(9.0, 0.0, 0.0), 2.0, 16, 32), ..pools };
    let m = extend(&domain, &moved, &extend_options).unwrap_err().to_string();
    assert!(m.contains("mid-LV plane") && m.contains("+0 mm") && m.contains("+8 mm") && m.contains("beyond the VSD"), "{m}");
}

/// A second VSD 60 degrees round the LV from the first, into an RV pouch reached by
/// an arm of the RV that stays 2 mm off the LV: the union of LV and RV has a handle
/// through the VSD's rim, so no VSD cut separates the LV part (the held-back
/// patient's "the kept surface has 1 openings, expected 2"). No plane move can undo
/// a handle: the refusal lists every move and names the second contact.
#[test]
fn a_second_vsd_beside_the_first_is_refused_naming_it() {
    let (prepare_options, extend_options) = options();
    let rv_center = Vec3::new(16.0, 0.0, 0.0);
    let pools = BloodPools {
        lv: uv_sphere(Vec3::zeros(), 10.0, 48, 96),
        rv: uv_sphere(rv_center, 9.0, 48, 96),
        aorta: capped_tube(rv_center + Vec3::new(0.0, 0.0, 4.0), rv_center + Vec3::new(0.0, 0.0, 25.0), 4.0, 20, 64),
    };
    let (domain, _) = prepare(&pools, &prepare_options).unwrap();
    let at = 60f64.to_radians();
    let out = Vec3::new(at.cos(), at.sin(), 0.0);
    let pouch_center = out * 17.0;
    let arm = capped_tube(rv_center, pouch_center, 2.0, 16, 32);
    let pouch = uv_sphere(pouch_center, 3.0, 16, 32);
    let channel = capped_tube(out * 9.0, out * 15.0, 1.5, 8, 24);
    let mut rv = pools.rv.clone();
    [arm, pouch, channel].iter().for_each(|part| append(&mut rv, part));
    let second = BloodPools { rv, ..pools };
    let m = extend(&domain, &second, &extend_options).unwrap_err().to_string();
    eprintln!("{m}");
    assert!(m.contains("mid-LV plane") && m.contains("+0 mm") && m.contains("+8 mm"), "{m}");
    assert!(m.contains("comes within") && m.contains("of the RV near"), "{m}");
}
