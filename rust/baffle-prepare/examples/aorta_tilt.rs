//! The synthetic heart with its aorta tilted from the RV's top (+z) towards the VSD
//! (-x): the aortic annulus comes closer to the VSD at each step, as in a subaortic
//! VSD. Prints prepare's outcome and the caps' gap at each tilt.
//!
//!     cargo run --release -p baffle-prepare --example aorta_tilt [aorta radii, mm]

use baffle_core::Vec3;
use baffle_prepare::shapes::{capped_tube, uv_sphere};
use baffle_prepare::{prepare, BloodPools, PrepareOptions};

fn main() {
    let rv_center = Vec3::new(16.0, 0.0, 0.0);
    let radii: Vec<f64> = std::env::args().skip(1).filter_map(|a| a.parse().ok()).collect();
    for &radius_mm in if radii.is_empty() { &[4.0][..] } else { &radii[..] } {
    for tilt_deg in (0..=70).step_by(5) {
        let t = (tilt_deg as f64).to_radians();
        let axis = Vec3::new(-t.sin(), 0.0, t.cos());
        let pools = BloodPools {
            lv: uv_sphere(Vec3::zeros(), 10.0, 48, 96),
            rv: uv_sphere(rv_center, 9.0, 48, 96),
            aorta: capped_tube(rv_center + axis * 4.0, rv_center + axis * 25.0, radius_mm, 20, 64),
        };
        // The tube's axis passes 16 cos(tilt) mm from the LV's centre.
        let gap_mm = 16.0 * t.cos() - radius_mm - 10.0;
        let options = PrepareOptions { voxel_mm: 0.3, closing_radius_mm: 0.0, ..PrepareOptions::default() };
        match prepare(&pools, &options) {
            Ok((_, report)) => println!(
                "aorta r {radius_mm} tilt {tilt_deg:2} deg (LV gap {gap_mm:.2} mm): ok, VSD cap {:.1} mm2, aortic cap {:.1} mm2",
                report.vsd_cap.area_mm2, report.aortic_cap.area_mm2
            ),
            Err(e) => println!("aorta r {radius_mm} tilt {tilt_deg:2} deg (LV gap {gap_mm:.2} mm): {e}"),
        }
    }
    }
}
