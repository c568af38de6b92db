//! The flow family for issue 31's validation of the reduced-order dp estimate against
//! the 3D CFD: synthetic hearts of the aorta-tilt family (`aorta_family`; tilts kept to
//! 0-15 degrees: from about 15-25, by the aorta's radius, it meets the LV and `prepare` must move or
//! refuse its cuts; the aorta's radius from the body size and a drawn z-score) with a drawn
//! body size, target z-score and cardiac index, so that the designed tunnels run from
//! narrow to wide and the first-peak dp from about 1 to 20 mmHg. Writes one folder per
//! member, as `baffle phantom --heart` does (LV.vtp, RV.vtp, aorta.vtp,
//! suture_points.mrk.json), plus member.json with its shape and the plan's inputs, for
//! `scripts/validation/flow_family.py` to plan.
//!
//!     cargo run --release -p baffle-prepare --example flow_family OUT [first seed] [count] [tilt from] [tilt to] [aortic z from] [aortic z to] [wide-root]
//!
//! The tilt's range (degrees, default 0 to 15) sets the tunnel's length: a negative tilt
//! leans the aorta away from the VSD, so the tunnel runs over the RV's top and its throat
//! can lie well before the annulus, as in p1-p3 (`-35 0`: the long-tunnel family).
//! The aorta's Boston z-score range (default -2.5 to 2.5) sets how much wider than the
//! tunnel's target the aortic plane is: p1-p3's aortic roots lie at about +2.5 to +5, their
//! aortic plane 1.5-3.2 times their throat. The RV's radius is raised where needed so that
//! the aorta's is at most `MAX_AORTA_TO_RV` of it (never in the defaults' first 100 seeds,
//! so those members are unchanged).
//!
//! A wide root alone does not widen the tunnel's end: the aorta family's suture ring keeps
//! 12 degrees outside the wider opening all along, so the whole tunnel widens with the root
//! (aortic z 2-5, tilt -35 to 0, seeds 0-11 designed: throat 59-98 mm2, above the target on
//! all, the aortic plane 1.0-1.6 times it and 0-7.3 mm after it, 3.4-4.4 on 10 of 12).
//! `wide-root` makes p1-p3's shape: the suture points follow each opening's rim
//! `WIDE_ROOT_SUTURE_MARGIN_MM` outside it and the VSD is made narrower than the root
//! (`WIDE_ROOT_VSD_HALF_ANGLE`), so the tunnel narrows toward the VSD and widens into the
//! root. The wide-root family:
//!
//!     cargo run --release -p baffle-prepare --example flow_family /work/famW 0 100 -35 0 3 5 wide-root
//!
//! Every member so far feeds its VSD from an LV sphere whose centre lies on the VSD's axis, so
//! the flow reaches the VSD head on; in p1-p3 the mid-LV inflow plane's centre lies 49-60 degrees
//! off the VSD plane's normal (the VSD sits at the LV's base, the LV's bulk toward the apex), and
//! p2's flow crosses its VSD plane at 39 degrees against the families' 13-25. `oblique-lv` (alone
//! or as `wide-root,oblique-lv`) swells the LV toward a drawn apex direction away from the VSD
//! (`oblique_lv`), drawn after every other draw and outside the VSD's cone: the RV, the aorta,
//! the VSD and the suture points are those of the same seed without it. The designs still
//! differ (`prepare` meets another union on its voxels: throats -24 % to +20 % against the
//! wide-root family's, docs/hemodynamics_estimate.md), so the family tests new designs with
//! oblique inflow, not the inflow's effect on one tunnel:
//!
//!     cargo run --release -p baffle-prepare --example flow_family /work/famO 0 100 -35 0 3 5 wide-root,oblique-lv
//!
//! Arguments 8 and 9 set the swelling's range (default 0 to 2: the inflow cap's centre up to
//! about 41 degrees off the VSD's normal; p1-p3's lie at 49-60).
//!
//! In p1 the throat lies 10-18 mm along the tunnel and the aortic plane is 2-3.2 times it; the
//! wide-root family's tunnel narrows toward its VSD, its throat 3-4 mm past the VSD plane.
//! `waisted` (with `wide-root`) pinches the suture line's sides midway between the openings
//! (`waisted_suture_points`, by a drawn 30-60 % of their distance from the arc, never nearer
//! either rim than the wide-root margin), as a suture line along a protruding conal septum
//! does, so the tunnel narrows between the VSD and a wide root:
//!
//!     cargo run --release -p baffle-prepare --example flow_family /work/famV 600 40 -35 -10 4 7 wide-root,waisted
//!
//! `turned-lv-triangles` (with the others) turns the LV sphere's triangles about its centre by
//! (1.9, 2.3) degrees: the same sphere on other triangles, a null replicate that shows how far
//! the plan and its 3D dp move when nothing physical does:
//!
//!     cargo run --release -p baffle-prepare --example flow_family /work/famN 0 24 -35 0 3 5 wide-root,turned-lv-triangles

use baffle_core::geometry::numerics::random::SplitMix64;
use baffle_core::target::boston_aortic_annulus_diameter_cm;
use baffle_core::io::{write_markups_closed_curve, write_trimesh_vtp, CoordinateSystem};
use baffle_core::{TriMesh, Vec3};
use baffle_prepare::aorta_family::{aorta_tilt_from, rim_following_suture_points, waisted_suture_points, AortaTiltParams};
use std::path::{Path, PathBuf};

/// The largest aorta-to-RV radius ratio: the largest of the first two families' 200 members
/// (0.646, all planned). On the RV sphere the aortic opening's half-angle is then at most
/// asin 0.65 = 40.5 degrees, which with the VSD's (at most about 46 degrees, at an RV of 8 mm)
/// stays inside the 90 degrees between their centres at tilt 0 and more so at negative tilts
/// (the openings apart, so `prepare`'s two cuts do not touch); the tube's start cap, 4 mm
/// along its axis, stays inside the RV (the annulus lies sqrt(1 - 0.65^2) R = 0.76 R >= 6.1 mm
/// out); and at tilt <= 0 the tube's rim reaches into the LV sphere by at most 0.42 mm (LV 11,
/// RV 8, overlap 4 mm, tilt 0), less than the first family's seed 30 (0.60 mm), which planned.
const MAX_AORTA_TO_RV: f64 = 0.65;

/// `wide-root`'s suture points lie 1.2 mm (along the RV sphere) outside each opening's rim:
/// `prepare`'s own tolerance for its caps' rims against the segmentations' openings
/// (closing radius 0.6 mm + 2 voxels of 0.3), so a cap that passes its checks does not reach
/// the points. At 1 mm one of the 100 designs (seed 31, overlap 2 mm, VSD cap rim 0.85 mm
/// outside the opening's) found a point on the VSD cap, at 4 degrees (0.56-0.70 mm, before
/// the VSD rule below) 13 of 24; at 1.2 mm none of 100, and the tunnel stays narrow (at 1.5 mm the aortic plane was at
/// least 1.5 times the throat on 63 of 100 designs, at 1.2 mm on 82).
const WIDE_ROOT_SUTURE_MARGIN_MM: f64 = 1.2;

/// `wide-root`'s VSD half-angle on the RV sphere is at most 0.85 of the aortic opening's
/// where lowering the drawn overlap, not below its range's 2 mm, can make it so. p1-p3's
/// aortic plane is 1.45-1.97 times their VSD plane (1.2-1.4 in diameter). Where the VSD was
/// the wider opening the tunnel narrowed toward the annulus and the throat lay 2.5-3.5 mm
/// before it; where the root was the wider, 7-10 mm (24 designs of seeds 0-23 before this
/// rule, 1 mm margin). With it the throat lies 7 mm or more before the plane on 70 of the
/// 100 designs.
const WIDE_ROOT_VSD_HALF_ANGLE: f64 = 0.85;

/// `waisted`'s range: the suture line's sides pinch midway by this fraction of their
/// distance from the arc between the openings (`waisted_suture_points`), never nearer either
/// rim than the wide-root margin.
const WAIST: (f64, f64) = (0.3, 0.6);

/// The plan's inputs drawn for one member: body size (sets the target and the flow),
/// target z-score and cardiac index (scales the flow).
#[derive(serde::Serialize)]
struct PlanInputs {
    bsa_m2: f64,
    z_score: f64,
    cardiac_index_l_min_m2: f64,
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(out) = args.first().map(PathBuf::from) else {
        eprintln!("usage: flow_family OUT [first seed] [count] [tilt from] [tilt to] [aortic z from] [aortic z to] [modes: wide-root,oblique-lv,turned-lv-triangles,waisted] [swelling from] [swelling to]");
        std::process::exit(2);
    };
    let first = argument(&args, 1, 0u64);
    let count = argument(&args, 2, 100u64);
    let number = |i: usize, default: f64| argument(&args, i, default);
    let ranges = Ranges {
        tilt_deg: (number(3, 0.0), number(4, 15.0)),
        aortic_z_score: (number(5, -2.5), number(6, 2.5)),
        swelling: (number(8, 0.0), number(9, 2.0)),
        wide_root: false,
        oblique_lv: false,
        turned_lv_triangles: false,
        waisted: false,
    };
    let ranges = match args.get(7) {
        None => ranges,
        Some(modes) => modes.split(',').fold(ranges, |r, mode| match mode {
            "wide-root" => Ranges { wide_root: true, ..r },
            "oblique-lv" => Ranges { oblique_lv: true, ..r },
            "turned-lv-triangles" => Ranges { turned_lv_triangles: true, ..r },
            "waisted" => Ranges { waisted: true, ..r },
            other => {
                eprintln!("flow_family: argument 7's {other} is not `wide-root`, `oblique-lv`, `turned-lv-triangles` or `waisted`");
                std::process::exit(2)
            }
        }),
    };
    for seed in first..first + count {
        if let Err(e) = write_member(&out.join(format!("m{seed:03}")), seed, &ranges) {
            eprintln!("member {seed}: {e}");
            std::process::exit(1);
        }
    }
    println!("wrote {count} members to {}", out.display());
}

/// The `i`th argument, `default` when it is not given; a malformed one stops the run
/// rather than falling back to the default unseen.
fn argument<T: std::str::FromStr>(args: &[String], i: usize, default: T) -> T {
    args.get(i).map_or(default, |a| {
        a.parse().unwrap_or_else(|_| {
            eprintln!("flow_family: argument {i} ({a}) is not a number of the expected kind");
            std::process::exit(2)
        })
    })
}

/// The drawn ranges the command line sets, whether the members have p1-p3's wide
/// root (a narrower VSD and suture points along both rims) or the aorta family's shape, and
/// whether their LV swells toward an apex off the VSD's axis (`oblique_lv`).
struct Ranges {
    tilt_deg: (f64, f64),
    aortic_z_score: (f64, f64),
    /// `oblique-lv`'s swelling k is drawn from this range.
    swelling: (f64, f64),
    wide_root: bool,
    oblique_lv: bool,
    turned_lv_triangles: bool,
    waisted: bool,
}

/// `oblique-lv`'s apex: the LV sphere's radius grows as R (1 + k s^2) toward the apex
/// direction u, s = (cos(angle to u) - cos g) / (1 - cos g) within g = 40 degrees of u and 0
/// beyond, so the surface stays star-shaped about the LV's centre (no fold) and smooth. u is
/// normal to the VSD's axis (x), so the swelling starts 50 degrees from it, past the VSD's
/// cone (at most about 31 degrees from the LV's centre in these ranges), and the LV meets the
/// RV exactly where the sphere did. Measured on the plans: k 0-2 (an apex at up to 3 R) puts the
/// mid-LV inflow cap's centre 2-41 degrees off the VSD's normal, k 2.5-4.5 53-69 degrees.
struct ObliqueLv {
    apex_direction: Vec3,
    swelling: f64,
}

const OBLIQUE_LV_CONE_DEG: f64 = 40.0;

impl ObliqueLv {
    /// u drawn within 60 degrees of -z about the VSD's axis (the aorta leaves the RV toward +z,
    /// the apex points away from it), k from `swelling`'s range.
    fn draw(rng: &mut SplitMix64, swelling: (f64, f64)) -> ObliqueLv {
        let azimuth = rng.between(-60.0f64, 60.0).to_radians();
        ObliqueLv { apex_direction: Vec3::new(0.0, azimuth.sin(), -azimuth.cos()), swelling: rng.between(swelling.0, swelling.1) }
    }

    /// The LV sphere (centred at the origin) swollen toward the apex.
    fn apply(&self, sphere: &TriMesh) -> TriMesh {
        let cos_cone = OBLIQUE_LV_CONE_DEG.to_radians().cos();
        let points = sphere
            .points
            .iter()
            .map(|p| {
                let s = ((p.normalize().dot(&self.apex_direction) - cos_cone) / (1.0 - cos_cone)).max(0.0);
                p * (1.0 + self.swelling * s * s)
            })
            .collect();
        TriMesh { points, ..sphere.clone() }
    }
}

fn write_member(dir: &Path, seed: u64, ranges: &Ranges) -> Result<(), String> {
    let mut rng = SplitMix64::new(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0xF10F_A111_0031);
    let inputs = PlanInputs {
        bsa_m2: rng.between(0.15, 0.35),
        z_score: rng.between(-2.0, 2.0),
        cardiac_index_l_min_m2: rng.between(2.5, 4.5),
    };
    // The aorta is the body size's own (its Boston z-score drawn), so the flow per area of the
    // annulus, and with it dp, is that of a child rather than of an aorta drawn apart from the
    // body: a free draw gave 3D dp of 5-58 mmHg.
    let aortic_z_score = rng.between(ranges.aortic_z_score.0, ranges.aortic_z_score.1);
    // Half the diameter, cm to mm.
    let aorta_radius_mm = 5.0 * boston_aortic_annulus_diameter_cm(inputs.bsa_m2, aortic_z_score);
    let mut params = AortaTiltParams {
        lv_radius_mm: rng.between(9.0, 11.0),
        rv_radius_mm: rng.between(8.0, 10.0).max(aorta_radius_mm / MAX_AORTA_TO_RV),
        vsd_overlap_mm: rng.between(2.0, 4.0),
        aorta_radius_mm,
        tilt_deg: rng.between(ranges.tilt_deg.0, ranges.tilt_deg.1),
        sideways_deg: rng.between(-20.0, 20.0),
    };
    let drawn_vsd_overlap_mm = params.vsd_overlap_mm;
    if ranges.wide_root {
        let aorta_half = params.opening_half_angles().1;
        params.vsd_overlap_mm = params.vsd_overlap_for_half_angle(WIDE_ROOT_VSD_HALF_ANGLE * aorta_half, 2.0);
    }
    let mut member = aorta_tilt_from(seed, params);
    if ranges.wide_root {
        member.suture_points_mm = rim_following_suture_points(&member.params, WIDE_ROOT_SUTURE_MARGIN_MM);
    }
    // Drawn last, so that the seed's other draws, and with them its tunnel, are unchanged.
    let oblique_lv = ranges.oblique_lv.then(|| ObliqueLv::draw(&mut rng, ranges.swelling));
    if let Some(apex) = &oblique_lv {
        member.pools.lv = apex.apply(&member.pools.lv);
    }
    // Drawn after the LV's swelling, so that a seed's other draws stay those without it.
    let waist = ranges.waisted.then(|| rng.between(WAIST.0, WAIST.1));
    if let Some(waist) = waist {
        member.suture_points_mm = waisted_suture_points(&member.params, WIDE_ROOT_SUTURE_MARGIN_MM, waist);
    }
    if ranges.turned_lv_triangles {
        // About the LV's centre, the origin: the sphere stays, its triangles move.
        let turn = nalgebra::Rotation3::from_axis_angle(&Vec3::x_axis(), 1.9f64.to_radians()) * nalgebra::Rotation3::from_axis_angle(&Vec3::z_axis(), 2.3f64.to_radians());
        member.pools.lv.points.iter_mut().for_each(|p| *p = turn * *p);
    }
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let pools = &member.pools;
    for (name, surface) in [("LV.vtp", &pools.lv), ("RV.vtp", &pools.rv), ("aorta.vtp", &pools.aorta)] {
        write_trimesh_vtp(&dir.join(name), surface).map_err(|e| e.to_string())?;
    }
    write_markups_closed_curve(&dir.join("suture_points.mrk.json"), "BC", &member.suture_points_mm, CoordinateSystem::Lps)
        .map_err(|e| e.to_string())?;
    let mut json = serde_json::json!({ "seed": seed, "shape": member.params, "aortic_z_score": aortic_z_score, "plan": inputs });
    if ranges.wide_root {
        json["wide_root"] = serde_json::json!({
            "suture_margin_mm": WIDE_ROOT_SUTURE_MARGIN_MM,
            "vsd_to_aortic_half_angle_at_most": WIDE_ROOT_VSD_HALF_ANGLE,
            "drawn_vsd_overlap_mm": drawn_vsd_overlap_mm,
        });
    }
    if let Some(waist) = waist {
        json["waist"] = serde_json::json!({ "waist": waist, "suture_margin_mm": WIDE_ROOT_SUTURE_MARGIN_MM });
    }
    if let Some(apex) = &oblique_lv {
        let u = apex.apex_direction;
        json["oblique_lv"] = serde_json::json!({ "apex_direction": [u.x, u.y, u.z], "swelling": apex.swelling, "cone_deg": OBLIQUE_LV_CONE_DEG });
    }
    let text = serde_json::to_string_pretty(&json).map_err(|e| e.to_string())?;
    std::fs::write(dir.join("member.json"), text).map_err(|e| format!("{}: {e}", dir.display()))
}
