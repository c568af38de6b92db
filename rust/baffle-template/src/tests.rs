use super::*;

/// A grid of `n` x `n` quads on `surface(s, t)`, s and t in [0, 1], split into triangles.
fn grid(n: usize, surface: impl Fn(f64, f64) -> Vec3) -> TriMesh {
    let mut points = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            points.push(surface(i as f64 / n as f64, j as f64 / n as f64));
        }
    }
    let id = |i: usize, j: usize| (j * (n + 1) + i) as u32;
    let mut triangles = Vec::new();
    for j in 0..n {
        for i in 0..n {
            triangles.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            triangles.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    let count = triangles.len();
    TriMesh::new(points, triangles, vec![10; count])
}

/// 1.5 rad of a cylinder of radius 12 mm, 25 mm high: developable.
fn cylinder_piece() -> TriMesh {
    grid(24, |s, t| {
        let a = 1.5 * s;
        Vec3::new(12.0 * a.cos(), 12.0 * a.sin(), 25.0 * t)
    })
}

#[test]
fn a_cylinder_piece_flattens_without_distortion() {
    for method in [FlattenMethod::Lscm, FlattenMethod::LscmArap] {
        let flat = flatten(&cylinder_piece(), method).unwrap();
        let r = &flat.report;
        assert!(r.perimeter_error < 1e-3, "{r:?}");
        assert!(r.area_distortion_max < 1e-6, "{r:?}");
        assert!(r.angle_distortion_max_deg < 1e-4, "{r:?}");
        assert!(r.seam_edge_error_max < 1e-6, "{r:?}");
        // The unrolled rectangle: 18 mm (arc) by 25 mm.
        assert!((r.area_flat_mm2 - r.area_3d_mm2).abs() < 1e-6 * r.area_3d_mm2);
    }
}

#[test]
fn a_sphere_cap_shows_its_distortion() {
    // A 60-degree-wide patch of a 15 mm sphere cannot be flattened isometrically.
    let cap = grid(20, |s, t| {
        let (a, b) = ((s - 0.5) * 1.0, (t - 0.5) * 1.0);
        Vec3::new(15.0 * a.sin() * b.cos(), 15.0 * b.sin(), 15.0 * a.cos() * b.cos())
    });
    let lscm = flatten(&cap, FlattenMethod::Lscm).unwrap().report;
    assert!(lscm.area_distortion_max > 0.02, "{lscm:?}");
    assert!(lscm.angle_distortion_median_deg < 1.0, "conformal: angles nearly kept, {lscm:?}");
    assert!(lscm.perimeter_error < 1e-9, "{lscm:?}");
    // ARAP trades angles for areas.
    let arap = flatten(&cap, FlattenMethod::LscmArap).unwrap().report;
    assert!(arap.arap_iterations > 0 && arap.area_distortion_max < lscm.area_distortion_max, "{arap:?} vs {lscm:?}");
}

#[test]
fn the_flat_patch_keeps_the_winding() {
    let flat = flatten(&cylinder_piece(), FlattenMethod::LscmArap).unwrap();
    assert!(flat.area_ratio.iter().all(|r| *r > 0.0));
}

#[test]
fn a_tube_is_refused_with_its_boundary_count() {
    let tube = grid(12, |s, t| {
        let a = std::f64::consts::TAU * s;
        Vec3::new(10.0 * a.cos(), 10.0 * a.sin(), 20.0 * t)
    });
    // Weld the seam at s = 1 onto s = 0 so the tube is closed around.
    let n = 12;
    let mut welded = tube.clone();
    for tri in &mut welded.triangles {
        for v in tri.iter_mut() {
            if (*v as usize) % (n + 1) == n {
                *v -= n as u32;
            }
        }
    }
    let err = flatten(&welded, FlattenMethod::Lscm).unwrap_err();
    assert!(err.contains("one boundary loop") && err.contains("2"), "{err}");
}
