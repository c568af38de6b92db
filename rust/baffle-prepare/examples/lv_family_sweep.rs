//! `extend` over the LV family (`lv_family`): how many members extend (and with
//! which move of the mid-LV plane), how many are refused and by which error, each
//! success re-measured by the tests' independent check.
//!
//!     cargo run --release -p baffle-prepare --example lv_family_sweep [first] [count] [voxel mm]

#[path = "../tests/common/mod.rs"]
mod common;

use baffle_prepare::extend::{extend, ExtendOptions};
use baffle_prepare::lv_family::{hand_made_domain_pools, lv_family_member};
use baffle_prepare::{prepare, PrepareOptions};
use std::collections::BTreeMap;
use std::time::Instant;

/// A member whose aorta must shrink more than this (mm) to clear the LV has its
/// axis in the LV: no hand-made domain either, so it is not counted.
const MAX_AORTA_SHRINK_MM: f64 = 1.0;

fn main() {
    let args: Vec<f64> = std::env::args().skip(1).filter_map(|a| a.parse().ok()).collect();
    let first = args.first().copied().unwrap_or(0.0) as u64;
    let count = args.get(1).copied().unwrap_or(40.0) as u64;
    let prepare_options = PrepareOptions { voxel_mm: args.get(2).copied().unwrap_or(0.4), ..PrepareOptions::default() };
    let extend_options = ExtendOptions { union: prepare_options.clone(), without_baffle: true, ..ExtendOptions::default() };
    let start = Instant::now();
    let mut outcomes: BTreeMap<String, Vec<u64>> = BTreeMap::new();
    std::panic::set_hook(Box::new(|_| {}));
    for seed in first..first + count {
        let member = lv_family_member(seed);
        let (clear, domain_pools) = hand_made_domain_pools(&member.params, 0.9);
        let shrink_mm = member.params.aorta_radius_mm - clear.aorta_radius_mm;
        let has_second_vsd = member.pools.rv.triangles.len() > domain_pools.rv.triangles.len();
        let t = Instant::now();
        let outcome = if shrink_mm > MAX_AORTA_SHRINK_MM {
            "not counted: the aorta's axis runs into the LV".to_string()
        } else {
            match prepare(&domain_pools, &prepare_options) {
                Err(e) => format!("not counted: no capped ventricle ({})", kind(&e.to_string())),
                Ok((domain, _)) => match extend(&domain, &member.pools, &extend_options) {
                    Err(e) => {
                        println!("seed {seed}: refused: {e}");
                        format!("refused: {}{}", kind(&e.to_string()), features(shrink_mm, has_second_vsd))
                    }
                    Ok(e) => {
                        let moved = e.report.mid_lv_plane.moved_from_centroid_mm;
                        let checked = std::panic::catch_unwind(|| common::check_extended(&format!("seed {seed}"), &domain, &member.pools, &e));
                        match checked {
                            Ok(()) => format!("extended, mid-LV plane moved {moved:+.0} mm{}", features(shrink_mm, has_second_vsd)),
                            Err(p) => format!("extended but the check fails: {}", p.downcast_ref::<String>().cloned().unwrap_or_default()),
                        }
                    }
                },
            }
        };
        println!("seed {seed} ({:.1} s, aorta {:.2} mm, {:.2} mm in the domain): {outcome}", t.elapsed().as_secs_f64(), member.params.aorta_radius_mm, clear.aorta_radius_mm);
        outcomes.entry(outcome).or_default().push(seed);
    }
    println!("\n{count} members in {:.0} s:", start.elapsed().as_secs_f64());
    for (outcome, seeds) in &outcomes {
        println!("  {:3}  {outcome}  (seeds {seeds:?})", seeds.len());
    }
}

/// What the member holds that its hand-made domain does not.
fn features(shrink_mm: f64, has_second_vsd: bool) -> String {
    let aorta = if shrink_mm > 0.0 { " [aorta on the LV]" } else { "" };
    let second = if has_second_vsd { " [second VSD]" } else { "" };
    format!("{aorta}{second}")
}

/// An error's kind: its step and the message up to the first place or number.
fn kind(message: &str) -> String {
    let cut = message.find(|c: char| c.is_ascii_digit() || c == '(').unwrap_or(message.len());
    message[..cut].trim_end_matches([' ', ',', ';']).to_string()
}
