//! The synthetic heart with its aorta tilted from the RV's top (+z) towards the VSD
//! (-x): the aortic annulus comes closer to the VSD at each step, as in a subaortic
//! VSD. Prints prepare's outcome and the caps' gap at each tilt.
//!
//!     cargo run --release -p baffle-prepare --example aorta_tilt

use baffle_core::Vec3;
use baffle_prepare::shapes::{capped_tube, uv_sphere};
use baffle_prepare::{prepare, BloodPools, PrepareOptions};

fn main() {
    let rv_center = Vec3::new(16.0, 0.0, 0.0);
    for tilt_deg in (0..=70).step_by(5) {
        let t = (tilt_deg as f64).to_radians();
        let axis = Vec3::new(-t.sin(), 0.0, t.cos());
        let pools = BloodPools {
            lv: uv_sphere(Vec3::zeros(), 10.0, 48, 96),
            rv: uv_sphere(rv_center, 9.0, 48, 96),
            aorta: capped_tube(rv_center + axis * 4.0, rv_center + axis * 25.0, 4.0, 20, 64),
        };
        let options = PrepareOptions { voxel_mm: 0.3, closing_radius_mm: 0.0, ..PrepareOptions::default() };
        match prepare(&pools, &options) {
            Ok((_, report)) => println!(
                "tilt {tilt_deg:2} deg: ok, VSD cap {:.1} mm2, aortic cap {:.1} mm2",
                report.vsd_cap.area_mm2, report.aortic_cap.area_mm2
            ),
            Err(e) => println!("tilt {tilt_deg:2} deg: {e}"),
        }
    }
}
