//! The design's input checks on perturbed phantoms: a bent cap is projected back onto its
//! plane (or refused past the limit), and a wall pushed through itself is refused where it
//! crosses. Here rather than beside the code because the perturbations live in
//! `baffle-test-support`, a dev-dependency that sees baffle-core only from outside.

use baffle_core::geometry::caps::{cap_flatness, project_caps_onto_planes};
use baffle_core::phantom::phantom_default;
use baffle_core::geometry::remesh::{remesh_isotropic, RemeshOptions};
use baffle_test_support::perturb::{bend_cap, bump_wall};

#[test]
fn a_cap_bent_by_up_to_five_percent_of_its_diameter_is_projected_and_more_is_refused() {
    let p = phantom_default();
    let caps = [(11, "VSD"), (16, "aortic-annulus")];
    for fraction in [0.005, 0.015, 0.03] {
        let bent = bend_cap(&bend_cap(&p.surface, 11, fraction), 16, fraction);
        let before = cap_flatness(&bent, 11).unwrap();
        assert!(before.off_plane_mm > 0.3 * fraction * 2.0 * before.equivalent_radius_mm(), "{before:?}");
        let (flat, report) = project_caps_onto_planes(&bent, &caps).unwrap();
        assert_eq!(report.len(), 2);
        for (label, r) in [11, 16].iter().zip(&report) {
            let after = cap_flatness(&flat, *label).unwrap();
            assert!(after.off_plane_mm < 1e-9, "{after:?}");
            assert!((r.off_plane_mm - cap_flatness(&bent, *label).unwrap().off_plane_mm).abs() < 1e-12);
            assert!((r.area_after_mm2 / r.area_before_mm2 - 1.0).abs() < 0.01, "{r:?}");
        }
        assert!(baffle_core::geometry::mesh::manifold_report(&flat).is_closed_manifold());
        assert_eq!(flat.triangles, bent.triangles);
    }
    let err = project_caps_onto_planes(&bend_cap(&p.surface, 11, 0.15), &caps).unwrap_err();
    assert!(err.contains("the VSD cap is not planar") && err.contains("limit") && err.contains("5.7 deg"), "{err}");
}

#[test]
fn a_closed_surface_that_crosses_itself_is_refused_where_it_crosses() {
    // The phantom's wall with a patch pushed 30 mm inward, through the opposite wall.
    let surface = phantom_default().surface;
    let wall_vertex = surface.triangles[surface.face_ids.iter().position(|&f| f == 2).unwrap()][0] as usize;
    let folded = bump_wall(&surface, wall_vertex, 60, -30.0, 2);
    let err = remesh_isotropic(&folded, &RemeshOptions { target_edge_mm: 1.0, ..RemeshOptions::default() }).unwrap_err();
    assert!(err.contains("crosses itself near (") && err.contains("triangles"), "{err}");
    // The phantom as it is does not cross itself and remeshes.
    assert!(remesh_isotropic(&surface, &RemeshOptions { target_edge_mm: 1.0, ..RemeshOptions::default() }).is_ok());
}
