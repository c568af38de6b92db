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
//!     cargo run --release -p baffle-prepare --example flow_family OUT [first seed] [count] [tilt from] [tilt to]
//!
//! The tilt's range (degrees, default 0 to 15) sets the tunnel's length: a negative tilt
//! leans the aorta away from the VSD, so the tunnel runs over the RV's top and its throat
//! can lie well before the annulus, as in p1-p3 (`-35 0`: the long-tunnel family).

use baffle_core::geometry::numerics::random::SplitMix64;
use baffle_core::target::boston_aortic_annulus_diameter_cm;
use baffle_core::io::{write_markups_closed_curve, write_trimesh_vtp, CoordinateSystem};
use baffle_prepare::aorta_family::{aorta_tilt_from, AortaTiltParams};
use std::path::{Path, PathBuf};

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
        eprintln!("usage: flow_family OUT [first seed] [count]");
        std::process::exit(2);
    };
    let first: u64 = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(0);
    let count: u64 = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(100);
    let tilt_deg = (args.get(3).and_then(|a| a.parse().ok()).unwrap_or(0.0), args.get(4).and_then(|a| a.parse().ok()).unwrap_or(15.0));
    for seed in first..first + count {
        if let Err(e) = write_member(&out.join(format!("m{seed:03}")), seed, tilt_deg) {
            eprintln!("member {seed}: {e}");
            std::process::exit(1);
        }
    }
    println!("wrote {count} members to {}", out.display());
}

fn write_member(dir: &Path, seed: u64, tilt_deg: (f64, f64)) -> Result<(), String> {
    let mut rng = SplitMix64::new(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0xF10F_A111_0031);
    let inputs = PlanInputs {
        bsa_m2: rng.between(0.15, 0.35),
        z_score: rng.between(-2.0, 2.0),
        cardiac_index_l_min_m2: rng.between(2.5, 4.5),
    };
    // The aorta is the body size's own (its Boston z-score drawn), so the flow per area of the
    // annulus, and with it dp, is that of a child rather than of an aorta drawn apart from the
    // body: a free draw gave 3D dp of 5-58 mmHg.
    let aortic_z_score = rng.between(-2.5, 2.5);
    let params = AortaTiltParams {
        lv_radius_mm: rng.between(9.0, 11.0),
        rv_radius_mm: rng.between(8.0, 10.0),
        vsd_overlap_mm: rng.between(2.0, 4.0),
        // Half the diameter, cm to mm.
        aorta_radius_mm: 5.0 * boston_aortic_annulus_diameter_cm(inputs.bsa_m2, aortic_z_score),
        tilt_deg: rng.between(tilt_deg.0, tilt_deg.1),
        sideways_deg: rng.between(-20.0, 20.0),
    };
    let member = aorta_tilt_from(seed, params);
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let pools = &member.pools;
    for (name, surface) in [("LV.vtp", &pools.lv), ("RV.vtp", &pools.rv), ("aorta.vtp", &pools.aorta)] {
        write_trimesh_vtp(&dir.join(name), surface).map_err(|e| e.to_string())?;
    }
    write_markups_closed_curve(&dir.join("suture_points.mrk.json"), "BC", &member.suture_points_mm, CoordinateSystem::Lps)
        .map_err(|e| e.to_string())?;
    let json = serde_json::json!({ "seed": seed, "shape": member.params, "aortic_z_score": aortic_z_score, "plan": inputs });
    let text = serde_json::to_string_pretty(&json).map_err(|e| e.to_string())?;
    std::fs::write(dir.join("member.json"), text).map_err(|e| format!("{}: {e}", dir.display()))
}
