//! What the baffle costs the right ventricle: the trade-off between a larger tunnel and
//! the room it takes from the RV, which the paper names as future work.
//!
//! From what the design has: the capped ventricle it was given (closed, outward) and
//! the designed VSD-to-aorta domain. Before the baffle the RV cavity is the volume the
//! capped ventricle encloses; after it, the part of that volume outside the domain,
//! V(input) - V(domain) (divergence theorem on both closed surfaces). That difference
//! is the remaining cavity only where the baffle runs inside the input, so the baffle
//! area outside it is reported beside the volumes: 0 on a capped ventricle made from
//! the segmentations (the whole RV between the VSD and aortic planes, `baffle
//! prepare`); on the published design inputs, which enclose only the published
//! pathway, it is not, and the volumes there are not the RV's.
//!
//! The kept wall is remeshed (0.85 mm), so its volume changes by about the sagitta of
//! an edge times the wall area (~0.01 mL on p2), below the figures' last digit.

use crate::geometry::mesh::TriMesh;
use crate::analyses::rv_outflow::RvOutflow;
use crate::geometry::spatial::{is_outside, TriangleBvh};
use serde::Serialize;

const MM3_PER_ML: f64 = 1000.0;

#[derive(Clone, Debug, Default, PartialEq, Serialize, serde::Deserialize)]
pub struct RvCost {
    /// Volume enclosed by the capped ventricle (the design input).
    pub rv_volume_before_ml: f64,
    /// The capped ventricle's volume outside the designed domain.
    pub rv_volume_after_ml: f64,
    /// The designed domain's volume: what the pathway takes.
    pub rv_volume_taken_ml: f64,
    /// Baffle area outside the capped ventricle; where it is not 0 the volumes above
    /// are net figures, not a cavity.
    pub baffle_area_outside_ventricle_mm2: f64,
    /// The smallest RV-to-pulmonary section before and after the baffle, or why it is
    /// unavailable (`rv_outflow_min_section_mm2`, ... at the top level); measured only
    /// where the pulmonary artery is known ([`crate::analyses::rv_outflow::rv_outflow`]).
    #[serde(flatten)]
    pub rv_outflow: RvOutflow,
}

/// RV cost of `domain` (with its `baffle`) designed in `ventricle` (closed, outward;
/// `bvh` over it).
pub fn rv_cost(ventricle: &TriMesh, bvh: &TriangleBvh, domain: &TriMesh, baffle: &TriMesh) -> RvCost {
    let before = ventricle.signed_volume_mm3();
    let taken = domain.signed_volume_mm3();
    let outside_mm2: f64 = (0..baffle.triangles.len())
        .filter(|&t| {
            let [a, b, c] = baffle.triangle_points(t);
            is_outside(ventricle, bvh, (a + b + c) / 3.0)
        })
        .map(|t| baffle.triangle_area_mm2(t))
        // Not sum(): an empty f64 sum is -0.0, which the report would print.
        .fold(0.0, |total, a| total + a);
    RvCost {
        rv_volume_before_ml: before / MM3_PER_ML,
        rv_volume_after_ml: (before - taken) / MM3_PER_ML,
        rv_volume_taken_ml: taken / MM3_PER_ML,
        baffle_area_outside_ventricle_mm2: outside_mm2,
        rv_outflow: RvOutflow::default(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::mesh::Vec3;
    use crate::phantom::phantom_default;
    use crate::{design, DesignOptions, TargetArea};

    /// Unit cube [0,1]^3 scaled by `s`, outward.
    fn cube(s: f64) -> TriMesh {
        let p: Vec<Vec3> = (0..8).map(|i| s * Vec3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64)).collect();
        let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
        let triangles = quads.iter().flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]).collect::<Vec<_>>();
        TriMesh::new(p, triangles, vec![2; 12])
    }

    #[test]
    fn a_domain_inside_the_ventricle_leaves_the_difference() {
        let ventricle = cube(10.0);
        let mut domain = cube(2.0);
        domain.points.iter_mut().for_each(|p| *p += Vec3::repeat(4.0));
        let bvh = TriangleBvh::new(&ventricle).unwrap();
        let cost = rv_cost(&ventricle, &bvh, &domain, &domain);
        assert!((cost.rv_volume_before_ml - 1.0).abs() < 1e-12, "{cost:?}");
        assert!((cost.rv_volume_taken_ml - 0.008).abs() < 1e-12, "{cost:?}");
        assert!((cost.rv_volume_after_ml - 0.992).abs() < 1e-12, "{cost:?}");
        assert!(cost.baffle_area_outside_ventricle_mm2 == 0.0 && cost.baffle_area_outside_ventricle_mm2.is_sign_positive());
    }

    #[test]
    fn a_baffle_beyond_the_ventricle_is_measured() {
        // The domain's cube [9, 11] x [4, 6]^2 pokes 1 mm out of the ventricle's +x face.
        // Outside: its +x face (4 mm2) and, of each of its four side faces, the one
        // triangle (2 mm2) whose centroid is at x = 9 + 4/3; the other's is at 9 + 2/3.
        let ventricle = cube(10.0);
        let mut domain = cube(2.0);
        domain.points.iter_mut().for_each(|p| *p += Vec3::new(9.0, 4.0, 4.0));
        let bvh = TriangleBvh::new(&ventricle).unwrap();
        let cost = rv_cost(&ventricle, &bvh, &domain, &domain);
        assert!((cost.baffle_area_outside_ventricle_mm2 - 12.0).abs() < 1e-9, "{cost:?}");
    }

    #[test]
    fn the_inside_test_agrees_with_the_winding_number_near_corners_edges_and_faces() {
        use crate::geometry::numerics::random::SplitMix64;
        use crate::geometry::spatial::winding_number;
        let ventricle = phantom_default().surface;
        let bvh = TriangleBvh::new(&ventricle).unwrap();
        let mut rng = SplitMix64::new(17);
        let mut outside = 0;
        for k in 0..2000 {
            // Near a vertex, in a random direction, within about an edge length.
            let v = ventricle.points[k * 7919 % ventricle.points.len()];
            let d = Vec3::new(rng.symmetric_unit(), rng.symmetric_unit(), rng.symmetric_unit());
            let q = v + d * rng.between(0.1, 1.5);
            let by_winding = winding_number(&ventricle, q) < 0.5;
            assert_eq!(is_outside(&ventricle, &bvh, q), by_winding, "at {q:?}");
            outside += by_winding as usize;
        }
        assert!(outside > 500 && outside < 1500, "{outside} of 2000 outside");
        // A cube's corner and edge regions: the nearest point is a vertex or an edge there.
        let cube = cube(10.0);
        let bvh = TriangleBvh::new(&cube).unwrap();
        for (q, out) in [([11.0, 11.0, 11.0], true), ([11.0, 5.0, 11.0], true), ([-0.5, -0.5, 5.0], true), ([9.9, 9.9, 9.9], false), ([5.0, 5.0, 5.0], false)] {
            assert_eq!(is_outside(&cube, &bvh, Vec3::from(q)), out, "{q:?}");
        }
    }

    #[test]
    fn the_phantom_design_takes_its_domain_from_the_ventricle() {
        let p = phantom_default();
        let target = TargetArea::Bsa { bsa_m2: p.bsa_m2, z_score: 0.0 };
        let result = design(&p.surface, &p.suture_points_mm, &target, &DesignOptions::default(), &mut |_, _| true).unwrap();
        let r = &result.report.rv_cost;
        let input_ml = p.surface.signed_volume_mm3().abs() / MM3_PER_ML;
        assert!((r.rv_volume_before_ml - input_ml).abs() < 1e-12, "{r:?}");
        assert!((r.rv_volume_taken_ml - result.domain.signed_volume_mm3() / MM3_PER_ML).abs() < 1e-12);
        assert!(r.rv_volume_taken_ml > 0.0 && r.rv_volume_after_ml > 0.0, "{r:?}");
        assert!((r.rv_volume_before_ml - r.rv_volume_after_ml - r.rv_volume_taken_ml).abs() < 1e-12);
    }
}
