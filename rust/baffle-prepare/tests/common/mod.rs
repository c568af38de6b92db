//! The independent check of an extended domain, shared by the extend tests and the
//! LV family's sweep example: baffle-verify's edge use, winding and volume, the caps
//! re-fitted here, the new caps' centroids tested inside their pools.

use baffle_core::geometry::spatial::{winding_number, TriangleBvh};
use baffle_core::TriMesh;
use baffle_prepare::extend::Extended;
use baffle_prepare::BloodPools;
use baffle_verify::{edge_usage_counts, is_consistently_oriented, signed_volume_mm3};
use std::collections::HashMap;

/// Triangles of `label` as sets of corner coordinates (bit patterns).
fn cap_triangles(mesh: &TriMesh, label: i32) -> Vec<[[u64; 3]; 3]> {
    let mut tris: Vec<[[u64; 3]; 3]> = (0..mesh.triangles.len())
        .filter(|&t| mesh.face_ids[t] == label)
        .map(|t| {
            let mut c = mesh.triangle_points(t).map(|p| [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()]);
            c.sort_unstable();
            c
        })
        .collect();
    tris.sort_unstable();
    tris
}

fn max_plane_offset_mm(mesh: &TriMesh, label: i32) -> f64 {
    let cap = mesh.with_labels(|l| l == label);
    let (c, n, _) = cap.label_centroid_normal(label).expect("cap");
    cap.points.iter().map(|p| (p - c).dot(&n).abs()).fold(0.0, f64::max)
}

/// Largest distance of a point of cap `label`'s rim from the surface of `pool` (mm).
fn rim_off_pool_mm(mesh: &TriMesh, label: i32, pool: &TriMesh) -> f64 {
    let bvh = TriangleBvh::new(pool).unwrap();
    let cap = mesh.with_labels(|l| l == label);
    let rim = cap.boundary_loops().unwrap().concat();
    rim.iter().filter_map(|&v| bvh.closest_point(pool, cap.points[v as usize])).map(|h| h.distance_mm).fold(0.0, f64::max)
}

/// Smallest distance of an inflow-cap (20) point beyond the VSD cap's (11) plane,
/// toward the LV (mm; negative: on the RV's side).
pub fn inflow_clearance_mm(extended: &TriMesh) -> f64 {
    let (c_vsd, n_vsd, _) = extended.with_labels(|l| l == 11).label_centroid_normal(11).expect("VSD cap");
    let (c_in, _, _) = extended.with_labels(|l| l == 20).label_centroid_normal(20).expect("inflow cap");
    // The VSD cap's normal may point either way: toward the LV is toward the inflow cap.
    let toward_lv = if (c_in - c_vsd).dot(&n_vsd) >= 0.0 { n_vsd } else { -n_vsd };
    let inflow = extended.with_labels(|l| l == 20);
    inflow.points.iter().map(|p| (p - c_vsd).dot(&toward_lv)).fold(f64::INFINITY, f64::min)
}

/// What the issue promises, re-measured on `extended` of `domain`.
pub fn check_extended(name: &str, domain: &TriMesh, pools: &BloodPools, extended: &Extended) {
    let s = &extended.surface;
    let walls = s.with_labels(|l| l != 11 && l != 16);
    assert_eq!(edge_usage_counts(&walls), (0, 0), "{name}: the walls and new caps are not closed and manifold");
    assert!(is_consistently_oriented(&walls), "{name}: inconsistent winding");
    // Interior caps: their edges are used twice inside them, 3 times on their rims.
    let mut uses: HashMap<(u32, u32), usize> = HashMap::new();
    for tri in &s.triangles {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            *uses.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    let counts: Vec<usize> = uses.values().copied().collect();
    assert!(counts.iter().all(|&c| c == 2 || c == 3), "{name}: an edge is used {:?} times", counts.iter().max());
    let rim_edges = counts.iter().filter(|&&c| c == 3).count();
    let designed_rims = edge_usage_counts(&domain.with_labels(|l| l == 11)).0 + edge_usage_counts(&domain.with_labels(|l| l == 16)).0;
    assert_eq!(rim_edges, designed_rims, "{name}: 3 faces meet exactly along the interior caps' rims");
    // The designed caps are kept, as projected onto their planes (the extend report's
    // `cap_projections`), to the bit.
    let (projected, _) = baffle_core::geometry::caps::project_caps_onto_planes(domain, &[(11, "VSD"), (16, "aortic-annulus")]).expect("usable caps");
    for label in [11, 16] {
        assert_eq!(cap_triangles(s, label), cap_triangles(&projected, label), "{name}: cap {label} changed");
    }
    for label in [20, 21] {
        let off = max_plane_offset_mm(s, label);
        assert!(off < 1e-6, "{name}: cap {label} is {off:.2e} mm off planar");
    }
    let volume = signed_volume_mm3(&walls).unwrap();
    let designed = signed_volume_mm3(domain).unwrap();
    assert!(volume > designed, "{name}: extended volume {volume:.0} <= designed {designed:.0} mm3");
    let (inflow, _, inflow_area) = s.label_centroid_normal(20).unwrap();
    let (outflow, _, outflow_area) = s.label_centroid_normal(21).unwrap();
    assert!(winding_number(&pools.lv, inflow) > 0.5, "{name}: the inflow cap's centroid is not inside the LV");
    let inflow_far = rim_off_pool_mm(s, 20, &pools.lv);
    assert!(inflow_far < 1.0, "{name}: the inflow cap's rim is up to {inflow_far:.2} mm off the LV surface");
    let far = rim_off_pool_mm(s, 21, &pools.aorta);
    assert!(far < 1.0, "{name}: the outflow cap's rim is up to {far:.2} mm off the aorta surface");
    assert!(winding_number(&pools.aorta, outflow) > 0.5, "{name}: the outflow cap's centroid is not inside the aorta");
    let vsd_clearance = inflow_clearance_mm(s);
    assert!(vsd_clearance >= 1.0 - 1e-9, "{name}: the inflow cap comes within {vsd_clearance:.2} mm of the VSD cap's plane (at least 1 mm)");
    let r = &extended.report;
    assert!(r.baffle_area_relative_change.abs() < 1e-3, "{name}: baffle area change {}", r.baffle_area_relative_change);
    eprintln!(
        "{name}: {} triangles ({} designed, LV part {}, aortic part {}); volume {volume:.0} vs {designed:.0} mm3; inflow cap {inflow_area:.1} mm2 at {:.2} mm beyond the VSD (all of it >= {vsd_clearance:.2} mm), \
         outflow cap {outflow_area:.1} mm2 at {:.2} mm above the annulus (STJ found: {}; {}), inflow / outflow rims within {inflow_far:.2} / {far:.2} mm of the LV / aorta surface; \
         baffle {:.2} -> {:.2} mm2 ({:+.2e}); edge {:.2} mm; {:.0} ms",
        r.triangles, r.designed_triangles, r.lv_extension_triangles, r.aortic_extension_triangles, r.mid_lv_plane.distance_from_vsd_mm,
        r.stj.distance_from_annulus_mm, r.stj.found, r.stj.note, r.baffle_area_before_mm2, r.baffle_area_after_mm2, r.baffle_area_relative_change,
        r.remesh_edge_mm, r.timings.planes_ms + r.timings.union_ms + r.timings.extensions_ms + r.timings.checks_ms
    );
}

