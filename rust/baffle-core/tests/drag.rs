//! A surgeon drags suture points: the design must keep working for nearby seams.

mod common;

use baffle_core::io::{read_points, read_surface, CoordinateSystem};
use baffle_core::phantom::phantom_default;
use baffle_core::geometry::spatial::TriangleBvh;
use baffle_core::{design, DesignError, DesignOptions, TargetArea, TriMesh, Vec3};

fn cases() -> Vec<(String, TriMesh, Vec<Vec3>, f64)> {
    let p = phantom_default();
    let mut out = vec![("phantom".to_string(), p.surface, p.suture_points_mm, p.bsa_m2)];
    if let Some(dir) = common::data_dir() {
        for (name, bsa) in [("p2", 0.37), ("p3", 0.33)] {
            let input = dir.join(name).join("design_input");
            let surface = read_surface(&input.join("capped_ventricle.vtp")).unwrap();
            let points = read_points(&input.join("suture_points.mrk.json")).unwrap().to_frame(CoordinateSystem::Lps);
            out.push((name.to_string(), surface, points, bsa));
        }
    }
    out
}

/// Dragging a point 1 mm along or across the seam keeps a valid design, unless the
/// drag puts the point on a cap or the seam deep over one (p2's seam runs 0.5 mm from
/// the cap rims), or the seam, moved onto a cap's rim, leaves too little room for the
/// tunnel: those must be the named errors (the latter with the largest feasible
/// area), nothing else.
#[test]
fn dragging_any_point_by_a_millimetre_keeps_a_valid_design() {
    let mut failures = Vec::new();
    let (mut designs, mut cap_errors, mut infeasible) = (0, 0, 0);
    for (name, surface, points, bsa_m2) in cases() {
        let bvh = TriangleBvh::new(&surface).unwrap();
        let target = TargetArea::Bsa { bsa_m2, z_score: 0.0 };
        let n = points.len();
        for i in 0..n {
            // Along the seam (towards the next point) and across it, each way.
            let along = (points[(i + 1) % n] - points[(i + n - 1) % n]).normalize();
            let normal = bvh
                .closest_point(&surface, points[i])
                .map(|h| surface.triangle_normal2(h.triangle as usize).normalize())
                .unwrap();
            let across = normal.cross(&along).normalize();
            for step in [along, -along, across, -across] {
                let mut moved = points.clone();
                moved[i] = bvh.closest_point(&surface, points[i] + step).unwrap().point;
                match design(&surface, &moved, &target, &DesignOptions::default(), &mut |_, _| true) {
                    Ok(result) => {
                        designs += 1;
                        let target_mm2 = result.report.target_area_mm2;
                        if result.report.min_constrained_final_area_mm2 < target_mm2 {
                            failures.push(format!("{name}: point {} moved: a section is below the target", i + 1));
                        }
                    }
                    Err(e) if e.to_string().contains(" cap") => cap_errors += 1,
                    Err(DesignError::Infeasible { max_feasible_area_mm2, .. }) if max_feasible_area_mm2 > 0.0 => {
                        infeasible += 1
                    }
                    Err(e) => failures.push(format!(
                        "{name}: point {} moved {:?}: {e}",
                        i + 1,
                        step.map(|x| (x * 10.0).round() / 10.0)
                    )),
                }
            }
        }
    }
    println!("{designs} designs, {cap_errors} drags onto or over a cap rejected, {infeasible} infeasible with their largest area");
    assert!(failures.is_empty(), "{} failures:\n{}", failures.len(), failures.join("\n"));
}
