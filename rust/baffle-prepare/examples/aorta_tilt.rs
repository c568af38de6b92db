//! The aorta-tilt family (`aorta_family`): hearts whose aorta leans from the RV's top
//! toward the VSD, as over a subaortic VSD. For each member, prepare's outcome (the
//! cuts' moves and the openings' gap, or the refusal), `design` on the result and
//! `extend` on the designed domain.
//!
//!     cargo run --release -p baffle-prepare --example aorta_tilt [first seed] [count]

use baffle_core::{design, DesignOptions, TargetArea};
use baffle_prepare::aorta_family::aorta_tilt_member;
use baffle_prepare::{extend, prepare, ExtendOptions, PrepareOptions};

fn main() {
    let args: Vec<u64> = std::env::args().skip(1).filter_map(|a| a.parse().ok()).collect();
    let (first, count) = (args.first().copied().unwrap_or(0), args.get(1).copied().unwrap_or(15));
    let options = PrepareOptions { voxel_mm: 0.3, closing_radius_mm: 0.0, ..PrepareOptions::default() };
    println!("| seed | tilt deg | aorta r mm | prepare | VSD cut into LV mm | aortic cut up mm | gap mm | design | extend |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for seed in first..first + count {
        let m = aorta_tilt_member(seed);
        let row = format!("| {seed} | {:.1} | {:.2} |", m.params.tilt_deg, m.params.aorta_radius_mm);
        match prepare(&m.pools, &options) {
            Ok((mesh, report)) => {
                let s = &report.separation;
                let designed = match design(&mesh, &m.suture_points_mm, &TargetArea::AreaMm2(m.target_area_mm2), &DesignOptions::default(), &mut |_, _| true) {
                    Ok(r) => {
                        let extended = match extend(&r.domain, &m.pools, &ExtendOptions { union: options.clone(), without_baffle: true, ..ExtendOptions::default() }) {
                            Ok(e) => format!("extend ok ({} triangles)", e.report.triangles),
                            Err(e) => format!("extend failed: {e}"),
                        };
                        format!("ok, baffle {:.1} mm2 | {extended}", r.report.baffle_area_mm2)
                    }
                    Err(e) => format!("failed: {e} |"),
                };
                println!(
                    "{row} {} | {:.1} | {:.1} | {:.2} | {designed} |",
                    if s.moved() { "separated" } else { "ok" },
                    s.vsd_cut_moved_into_lv_mm,
                    s.aortic_cut_moved_into_aorta_mm,
                    s.rim_gap_mm
                );
            }
            Err(e) => println!("{row} refused: {e} | | | | | |"),
        }
    }
}
