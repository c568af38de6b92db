//! The one place the design's tunables are range-checked, shared by `design`, the
//! CLI and the C ABI: no value may make a step allocate without bound, loop forever
//! or switch a check off (a NaN distance compares false with everything).

use crate::design::DesignOptions;
use crate::error::DesignError;

/// Allowed range of each real-valued option (inclusive), by its public name.
pub const MAX_POINT_DISTANCE_MM: (f64, f64) = (0.0, 100.0);
pub const REMESH_EDGE_MM: (f64, f64) = (0.05, 20.0);
pub const BAFFLE_EDGE_MM: (f64, f64) = (0.05, 20.0);
pub const CENTERLINE_SPACING_MM: (f64, f64) = (0.01, 20.0);
pub const AREA_MARGIN: (f64, f64) = (1.0, 2.0);
pub const MAX_WALL_FRACTION: (f64, f64) = (0.0, 1.0);
pub const TPS_REGULARIZATION: (f64, f64) = (0.0, 1e6);
/// Allowed range of each count option (inclusive). The seam needs enough samples to
/// be a loop at all; beyond 100,000 it only costs time.
pub const SEAM_SAMPLES: (usize, usize) = (16, 100_000);
pub const INTERIOR_CONTROL_POINTS: (usize, usize) = (1, 1_000);
pub const MAX_CORRECTION_ROUNDS: (usize, usize) = (0, 100);

impl DesignOptions {
    /// Every option inside its range and the four face labels distinct; the error
    /// names the option, its value and the range.
    pub fn validate(&self) -> Result<(), DesignError> {
        real("max_point_distance_mm", self.max_point_distance_mm, MAX_POINT_DISTANCE_MM)?;
        if let Some(edge) = self.remesh_edge_mm {
            real("remesh_edge_mm", edge, REMESH_EDGE_MM)?;
        }
        real("baffle_edge_mm", self.baffle_edge_mm, BAFFLE_EDGE_MM)?;
        real("centerline_spacing_mm", self.centerline_spacing_mm, CENTERLINE_SPACING_MM)?;
        real("area_margin", self.area_margin, AREA_MARGIN)?;
        real("max_wall_fraction", self.max_wall_fraction, MAX_WALL_FRACTION)?;
        real("tps_regularization", self.tps_regularization, TPS_REGULARIZATION)?;
        count("seam_samples", self.seam_samples, SEAM_SAMPLES)?;
        count("interior_control_points", self.interior_control_points, INTERIOR_CONTROL_POINTS)?;
        count("max_correction_rounds", self.max_correction_rounds, MAX_CORRECTION_ROUNDS)?;
        distinct_labels(self)
    }
}

fn real(name: &str, value: f64, (min, max): (f64, f64)) -> Result<(), DesignError> {
    if value.is_finite() && (min..=max).contains(&value) {
        Ok(())
    } else {
        Err(DesignError::Options(format!("{name} = {value} is outside [{min}, {max}]")))
    }
}

fn count(name: &str, value: usize, (min, max): (usize, usize)) -> Result<(), DesignError> {
    if (min..=max).contains(&value) {
        Ok(())
    } else {
        Err(DesignError::Options(format!("{name} = {value} is outside [{min}, {max}]")))
    }
}

/// Two roles on one label would make one cap serve as both ends, or the baffle
/// indistinguishable from the wall.
fn distinct_labels(options: &DesignOptions) -> Result<(), DesignError> {
    let l = options.labels;
    let named = [("wall", l.wall), ("baffle", l.baffle), ("VSD cap", l.vsd_cap), ("aortic cap", l.aortic_cap)];
    for i in 0..named.len() {
        for j in i + 1..named.len() {
            if named[i].1 == named[j].1 {
                return Err(DesignError::Options(format!(
                    "the {} and the {} have the same label {}; the four labels must differ",
                    named[i].0, named[j].0, named[i].1
                )));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn refused(change: impl FnOnce(&mut DesignOptions), needle: &str) {
        let mut o = DesignOptions::default();
        change(&mut o);
        let e = o.validate().expect_err("a bad option was accepted");
        assert!(matches!(e, DesignError::Options(_)), "{e}");
        assert!(e.to_string().contains(needle), "'{e}' does not name '{needle}'");
    }

    #[test]
    fn defaults_are_valid() {
        DesignOptions::default().validate().unwrap();
    }

    #[test]
    fn non_finite_and_tiny_lengths_are_refused_by_name() {
        refused(|o| o.max_point_distance_mm = f64::NAN, "max_point_distance_mm = NaN");
        refused(|o| o.remesh_edge_mm = Some(1e-6), "remesh_edge_mm = 0.000001");
        refused(|o| o.baffle_edge_mm = f64::INFINITY, "baffle_edge_mm = inf");
        refused(|o| o.centerline_spacing_mm = 0.0, "centerline_spacing_mm = 0");
        refused(|o| o.area_margin = -1.0, "area_margin = -1");
    }

    #[test]
    fn counts_outside_their_range_are_refused() {
        refused(|o| o.seam_samples = 0, "seam_samples = 0 is outside [16, 100000]");
        refused(|o| o.max_correction_rounds = 1000, "max_correction_rounds");
    }

    #[test]
    fn shared_labels_are_named() {
        refused(|o| o.labels.vsd_cap = o.labels.aortic_cap, "the VSD cap and the aortic cap have the same label 16");
    }
}
