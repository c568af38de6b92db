//! A target edge that grows away from a disc: the CFD domain's extensions (the LV cavity
//! behind the VSD, the aortic root beyond the annulus) carry slow or leaving flow, and
//! need the fine edge only near the measurement plane they join; each tetrahedron
//! saved there buys resolution in the tunnel, where dp is made.

use crate::geometry::mesh::Vec3;

/// t(x) = clamp(L + growth (d(x) - margin), L, largest): L (the remesh's target edge)
/// within `margin_mm` of the disc (centre, unit normal, radius: a cap's plane and its
/// equivalent radius), then growing by `growth` mm of edge per mm of distance, up to
/// `largest_edge_mm`. Growth below about 0.3 keeps neighbouring triangles within a
/// third of each other's size, which the split/collapse thresholds (4/3 L, 4/5 L) need
/// to settle without a jump in size.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SizeGrading {
    pub center: Vec3,
    pub normal: Vec3,
    pub radius_mm: f64,
    pub margin_mm: f64,
    pub growth: f64,
    pub largest_edge_mm: f64,
}

/// Largest growth a grading may ask for (see [`SizeGrading`]).
pub const MAX_GROWTH: f64 = 0.5;

impl SizeGrading {
    /// Distance (mm) from `p` to the disc.
    pub fn distance_mm(&self, p: &Vec3) -> f64 {
        let offset = p - self.center;
        let axial = offset.dot(&self.normal);
        let radial = (offset - axial * self.normal).norm();
        let beyond_rim = (radial - self.radius_mm).max(0.0);
        (beyond_rim * beyond_rim + axial * axial).sqrt()
    }

    /// The target edge (mm) at `p` for a remesh at `nominal_mm`.
    pub fn edge_mm(&self, nominal_mm: f64, p: &Vec3) -> f64 {
        let grown = nominal_mm + self.growth * (self.distance_mm(p) - self.margin_mm);
        grown.clamp(nominal_mm, self.largest_edge_mm.max(nominal_mm))
    }

    /// A named error for a grading no remesh can follow.
    pub fn validate(&self, nominal_mm: f64) -> Result<(), String> {
        let finite = self.center.iter().chain(self.normal.iter()).all(|c| c.is_finite());
        if !finite || (self.normal.norm() - 1.0).abs() > 1e-6 {
            return Err(format!("size grading: the disc needs a finite centre and a unit normal, got {self:?}"));
        }
        let lengths_ok = [self.radius_mm, self.margin_mm].iter().all(|x| x.is_finite() && *x >= 0.0);
        if !lengths_ok || !(self.largest_edge_mm.is_finite() && self.largest_edge_mm >= nominal_mm) {
            return Err(format!(
                "size grading: radius and margin must be lengths >= 0 and the largest edge at least the target {nominal_mm} mm, got {self:?}"
            ));
        }
        if !(self.growth.is_finite() && (0.0..=MAX_GROWTH).contains(&self.growth)) {
            return Err(format!("size grading: growth must lie in [0, {MAX_GROWTH}] mm per mm, got {}", self.growth));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grading() -> SizeGrading {
        SizeGrading { center: Vec3::zeros(), normal: Vec3::z(), radius_mm: 5.0, margin_mm: 2.0, growth: 0.25, largest_edge_mm: 2.0 }
    }

    #[test]
    fn the_edge_is_nominal_near_the_disc_and_grows_beyond_the_margin_up_to_the_largest() {
        let g = grading();
        // On the disc, and off its rim within the margin: nominal.
        assert_eq!(g.edge_mm(0.8, &Vec3::new(3.0, 0.0, 0.0)), 0.8);
        assert_eq!(g.edge_mm(0.8, &Vec3::new(6.0, 0.0, 1.0)), 0.8);
        // 6 mm above the disc's centre: 4 mm past the margin, 0.8 + 0.25 x 4 = 1.8 mm.
        assert!((g.edge_mm(0.8, &Vec3::new(0.0, 0.0, -6.0)) - 1.8).abs() < 1e-12);
        // 3 mm beyond the rim in plane and 4 mm off it: 5 mm away, 3 past the margin.
        assert!((g.distance_mm(&Vec3::new(8.0, 0.0, 4.0)) - 5.0).abs() < 1e-12);
        assert!((g.edge_mm(0.8, &Vec3::new(8.0, 0.0, 4.0)) - 1.55).abs() < 1e-12);
        // Far away: capped.
        assert_eq!(g.edge_mm(0.8, &Vec3::new(0.0, 0.0, 100.0)), 2.0);
    }

    #[test]
    fn gradings_no_remesh_can_follow_are_named() {
        assert!(grading().validate(0.8).is_ok());
        let bad = [
            SizeGrading { normal: Vec3::new(0.0, 0.0, 2.0), ..grading() },
            SizeGrading { radius_mm: -1.0, ..grading() },
            SizeGrading { largest_edge_mm: 0.5, ..grading() },
            SizeGrading { growth: 0.9, ..grading() },
            SizeGrading { center: Vec3::new(f64::NAN, 0.0, 0.0), ..grading() },
        ];
        for g in bad {
            let e = g.validate(0.8).unwrap_err();
            assert!(e.starts_with("size grading"), "{e}");
        }
    }
}
