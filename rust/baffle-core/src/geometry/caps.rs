//! Labelling the caps of an unlabelled surface (`.stl`, legacy `.vtk` without
//! `ModelFaceID`). The VSD and aortic-annulus caps are planar; given one point on
//! each, the cap is the planar region grown from the triangle nearest that point:
//! neighbours join while their normal stays within `max_angle_deg` of the seed's and
//! their corners within `max_offset_mm` of the seed's plane. Everything else is wall.

use crate::geometry::mesh::{TriMesh, Vec3};
use crate::geometry::numerics::pca::{best_fit_plane, Plane};
use crate::geometry::spatial::TriangleBvh;

/// The section-area error a cap's uncertain plane may cause: the design's default area
/// margin (`DesignOptions::area_margin`, 1.005), the share of a section it keeps for its
/// own numerical error.
pub const CAP_SECTION_AREA_ERROR: f64 = 0.005;

/// Largest tilt (rad) of a section plane at a cap that keeps the section's area within
/// [`CAP_SECTION_AREA_ERROR`]: a plane tilted by theta cuts a tube 1/cos(theta) larger.
pub fn max_cap_tilt_rad() -> f64 {
    (1.0 / (1.0 + CAP_SECTION_AREA_ERROR)).acos()
}

/// How far the cap labelled `label` is from flat, and whether the design can use it.
/// What the method needs from a cap is its rim, centroid and plane (the centerline leaves
/// it along the plane's normal, the sections are cut normal to the centerline, the
/// extension starts at the rim), not micrometre planarity: caps drawn with a plane tool
/// on a segmentation, or cut from a surface of 0.3-0.5 mm triangles, lie a few tenths of
/// a millimetre off their plane. A cap whose points lie up to `d` off their least-squares
/// plane over its radius `R` has a normal known only to within atan(d / R) (the planes
/// through the rim and through the farthest point differ by that), so it is usable while
/// that tilt keeps a section within [`CAP_SECTION_AREA_ERROR`] (5.7 deg: d <= 10 % of the
/// radius, 5 % of the diameter); it is then projected onto its plane
/// ([`project_caps_onto_planes`]).
#[derive(Clone, Copy, Debug)]
pub struct CapFlatness {
    /// Least-squares plane of the cap's points, normal outward (as the surface is wound).
    pub plane: Plane,
    pub area_mm2: f64,
    /// Largest distance of a cap point from `plane`.
    pub off_plane_mm: f64,
    /// The usable limit of `off_plane_mm`: the equivalent radius times tan([`max_cap_tilt_rad`]).
    pub tolerance_mm: f64,
}

impl CapFlatness {
    /// Whether the cap is flat enough for its plane to stand for it (see the type's doc).
    pub fn is_planar(&self) -> bool {
        self.off_plane_mm <= self.tolerance_mm
    }

    pub fn equivalent_radius_mm(&self) -> f64 {
        (self.area_mm2 / std::f64::consts::PI).sqrt()
    }

    /// "the VSD cap is not planar: ..." for an error message.
    pub fn describe(&self, name: &str) -> String {
        format!(
            "the {name} cap is not planar: a point lies {:.3} mm off its plane (limit {:.3} mm: beyond it the cap's normal, over its {:.2} mm radius, is uncertain by more than {:.1} deg, which changes a section's area near it by more than {:.1} %)",
            self.off_plane_mm,
            self.tolerance_mm,
            self.equivalent_radius_mm(),
            max_cap_tilt_rad().to_degrees(),
            100.0 * CAP_SECTION_AREA_ERROR
        )
    }
}

/// The flatness of the cap labelled `label` of `mesh` (None if it has no area).
pub fn cap_flatness(mesh: &TriMesh, label: i32) -> Option<CapFlatness> {
    let (_, outward, area_mm2) = mesh.label_centroid_normal(label)?;
    let points: Vec<Vec3> = cap_point_indices(mesh, label).iter().map(|&v| mesh.points[v as usize]).collect();
    let fitted = best_fit_plane(&points);
    // Turned outward, still right-handed.
    let plane = if fitted.normal.dot(&outward) < 0.0 { Plane { normal: -fitted.normal, axis_v: -fitted.axis_v, ..fitted } } else { fitted };
    let off_plane_mm = points.iter().map(|p| plane.signed_distance_mm(p).abs()).fold(0.0, f64::max);
    let tolerance_mm = (area_mm2 / std::f64::consts::PI).sqrt() * max_cap_tilt_rad().tan();
    Some(CapFlatness { plane, area_mm2, off_plane_mm, tolerance_mm })
}

/// The points of the triangles labelled `label`, each once, in index order.
fn cap_point_indices(mesh: &TriMesh, label: i32) -> Vec<u32> {
    let mut on_cap = vec![false; mesh.points.len()];
    for (tri, _) in mesh.triangles.iter().zip(&mesh.face_ids).filter(|(_, &f)| f == label) {
        tri.iter().for_each(|&v| on_cap[v as usize] = true);
    }
    (0..mesh.points.len() as u32).filter(|&v| on_cap[v as usize]).collect()
}

/// What projecting one cap onto its plane did (report.json `caps`).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize, PartialEq)]
pub struct CapProjection {
    pub label: i32,
    pub name: String,
    /// Largest distance of a cap point from its least-squares plane, before (mm).
    pub off_plane_mm: f64,
    /// The usable limit of `off_plane_mm` ([`CapFlatness::tolerance_mm`]).
    pub limit_mm: f64,
    /// Points moved onto the plane (the cap's, its rim included).
    pub moved_points: usize,
    pub area_before_mm2: f64,
    pub area_after_mm2: f64,
    /// The plane: a point on it and its outward unit normal.
    pub plane_point_mm: [f64; 3],
    pub plane_normal: [f64; 3],
}

/// A cap triangle whose normal, against the cap's plane normal, is below this cosine
/// would be (nearly) edge-on after the projection: the cap folds over itself.
const MIN_PROJECTED_COSINE: f64 = 1e-3;

/// Each cap of `caps` ((label, name)) projected onto its least-squares plane, after
/// checking that it is a cap the method can use: one rim, flat to within
/// [`CapFlatness::tolerance_mm`], no triangle folded over its plane, and no wall triangle
/// folded by the rim's move. A point shared by two caps goes onto both planes. A label
/// with no triangle is skipped (the callers check the labels). The result is re-measured:
/// every projected cap must lie on its plane to rounding.
pub fn project_caps_onto_planes(mesh: &TriMesh, caps: &[(i32, &str)]) -> Result<(TriMesh, Vec<CapProjection>), String> {
    let mut planes: Vec<(i32, &str, CapFlatness, Vec<u32>)> = Vec::new();
    for &(label, name) in caps {
        let Some(flat) = cap_flatness(mesh, label) else { continue };
        check_cap_shape(mesh, label, name, &flat)?;
        planes.push((label, name, flat, cap_point_indices(mesh, label)));
    }
    let mut out = mesh.clone();
    let mut on_planes: Vec<Vec<Plane>> = vec![Vec::new(); mesh.points.len()];
    for (_, _, flat, points) in &planes {
        points.iter().for_each(|&v| on_planes[v as usize].push(flat.plane));
    }
    for (v, planes) in on_planes.iter().enumerate() {
        if !planes.is_empty() {
            out.points[v] = nearest_point_on_planes(mesh.points[v], planes);
        }
    }
    check_no_fold(mesh, &out, &on_planes)?;
    let mut projections = Vec::new();
    for (label, name, flat, points) in planes {
        let after = cap_flatness(&out, label).ok_or_else(|| format!("the {name} cap lost its area when projected onto its plane"))?;
        let rounding_mm = 1e-9 * (1.0 + flat.plane.centroid.amax());
        if after.off_plane_mm > rounding_mm.max(1e-6 * flat.equivalent_radius_mm()) {
            return Err(format!("the {name} cap is still {:.2e} mm off its plane after the projection", after.off_plane_mm));
        }
        let c = flat.plane.centroid;
        let n = flat.plane.normal;
        projections.push(CapProjection {
            label,
            name: name.to_string(),
            off_plane_mm: flat.off_plane_mm,
            limit_mm: flat.tolerance_mm,
            moved_points: points.len(),
            area_before_mm2: flat.area_mm2,
            area_after_mm2: after.area_mm2,
            plane_point_mm: [c.x, c.y, c.z],
            plane_normal: [n.x, n.y, n.z],
        });
    }
    Ok((out, projections))
}

/// One rim, flat enough, and a height field over its plane (no fold).
fn check_cap_shape(mesh: &TriMesh, label: i32, name: &str, flat: &CapFlatness) -> Result<(), String> {
    let (cap, _) = mesh.submesh(&mesh.face_ids.iter().map(|&f| f == label).collect::<Vec<_>>());
    let loops = cap.boundary_loops().map_err(|e| format!("the {name} cap's rim: {e}"))?;
    if loops.len() != 1 {
        return Err(format!("the {name} cap (label {label}) has {} rims, expected one: it is not a single disk", loops.len()));
    }
    if !flat.is_planar() {
        return Err(flat.describe(name));
    }
    for t in (0..mesh.triangles.len()).filter(|&t| mesh.face_ids[t] == label) {
        let n2 = mesh.triangle_normal2(t);
        if n2.dot(&flat.plane.normal) <= MIN_PROJECTED_COSINE * n2.norm() {
            let c = mesh.triangle_points(t).iter().fold(Vec3::zeros(), |s, p| s + p) / 3.0;
            return Err(format!(
                "the {name} cap folds over itself: its triangle {t} at ({:.2}, {:.2}, {:.2}) mm faces {:.0} deg away from the cap's plane normal",
                c.x,
                c.y,
                c.z,
                (n2.dot(&flat.plane.normal) / n2.norm().max(1e-300)).clamp(-1.0, 1.0).acos().to_degrees()
            ));
        }
    }
    Ok(())
}

/// The point nearest `p` on every one of `planes` (one or two planes; two parallel ones
/// fall back to the first).
fn nearest_point_on_planes(p: Vec3, planes: &[Plane]) -> Vec3 {
    let onto = |q: Vec3, pl: &Plane| q - pl.signed_distance_mm(&q) * pl.normal;
    match planes {
        [a, b, ..] => {
            let (na, nb) = (a.normal, b.normal);
            let c = na.dot(&nb);
            let det = 1.0 - c * c;
            if det < 1e-12 {
                return onto(p, a);
            }
            // p - (la na + lb nb) with both signed distances zero.
            let (da, db) = (a.signed_distance_mm(&p), b.signed_distance_mm(&p));
            let la = (da - c * db) / det;
            let lb = (db - c * da) / det;
            p - la * na - lb * nb
        }
        [a] => onto(p, a),
        [] => p,
    }
}

/// No triangle touching a moved point may turn over or collapse.
fn check_no_fold(before: &TriMesh, after: &TriMesh, moved: &[Vec<Plane>]) -> Result<(), String> {
    for t in 0..before.triangles.len() {
        if before.triangles[t].iter().all(|&v| moved[v as usize].is_empty()) {
            continue;
        }
        let (n0, n1) = (before.triangle_normal2(t), after.triangle_normal2(t));
        if n1.dot(&n0) <= MIN_PROJECTED_COSINE * n0.norm() * n1.norm() || n1.norm() <= 1e-12 * n0.norm() {
            let c = before.triangle_points(t).iter().fold(Vec3::zeros(), |s, p| s + p) / 3.0;
            return Err(format!(
                "projecting the caps onto their planes would turn over triangle {t} (label {}) at ({:.2}, {:.2}, {:.2}) mm: the wall beside the rim is shallower than the cap's deviation",
                before.face_ids[t], c.x, c.y, c.z
            ));
        }
    }
    Ok(())
}

/// A point on a cap and the label the cap should get.
#[derive(Clone, Copy, Debug)]
pub struct CapSeed {
    pub point_mm: Vec3,
    pub label: i32,
}

#[derive(Clone, Copy, Debug)]
pub struct CapTolerances {
    pub max_angle_deg: f64,
    pub max_offset_mm: f64,
    /// A seed farther than this from the surface is an error.
    pub max_seed_distance_mm: f64,
}

impl Default for CapTolerances {
    fn default() -> Self {
        CapTolerances { max_angle_deg: 5.0, max_offset_mm: 0.05, max_seed_distance_mm: 2.0 }
    }
}

/// Label every triangle `wall_label`, then grow each seed's planar cap.
pub fn label_planar_caps(mesh: &TriMesh, seeds: &[CapSeed], wall_label: i32, tol: &CapTolerances) -> Result<Vec<i32>, String> {
    let bvh = TriangleBvh::new(mesh)?;
    let neighbors = mesh.triangle_neighbors();
    let mut labels = vec![wall_label; mesh.triangles.len()];
    for (k, seed) in seeds.iter().enumerate() {
        let hit = bvh.closest_point(mesh, seed.point_mm).ok_or("the surface has no triangles")?;
        if hit.distance_mm > tol.max_seed_distance_mm {
            return Err(format!(
                "cap point {} (label {}) is {:.2} mm from the surface (limit {:.2} mm)",
                k + 1,
                seed.label,
                hit.distance_mm,
                tol.max_seed_distance_mm
            ));
        }
        let region = grow_planar_region(mesh, &neighbors, hit.triangle as usize, tol);
        if let Some(&t) = region.iter().find(|&&t| labels[t] != wall_label) {
            return Err(format!("the caps of points {} and another point overlap (triangle {t})", k + 1));
        }
        region.iter().for_each(|&t| labels[t] = seed.label);
    }
    Ok(labels)
}

fn unit_normal(mesh: &TriMesh, t: usize) -> Vec3 {
    let n = mesh.triangle_normal2(t);
    n / n.norm().max(1e-300)
}

fn grow_planar_region(mesh: &TriMesh, neighbors: &[[u32; 3]], seed: usize, tol: &CapTolerances) -> Vec<usize> {
    let normal = unit_normal(mesh, seed);
    let origin = mesh.points[mesh.triangles[seed][0] as usize];
    let min_cos = tol.max_angle_deg.to_radians().cos();
    let in_plane = |t: usize| {
        unit_normal(mesh, t).dot(&normal) >= min_cos
            && mesh.triangles[t].iter().all(|&v| normal.dot(&(mesh.points[v as usize] - origin)).abs() <= tol.max_offset_mm)
    };
    let mut inside = vec![false; mesh.triangles.len()];
    inside[seed] = true;
    let mut stack = vec![seed];
    let mut region = Vec::new();
    while let Some(t) = stack.pop() {
        region.push(t);
        for &nb in &neighbors[t] {
            let nb = nb as usize;
            if nb < inside.len() && !inside[nb] && in_plane(nb) {
                inside[nb] = true;
                stack.push(nb);
            }
        }
    }
    region
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phantom::phantom_default;

    #[test]
    fn phantom_caps_are_flat_and_a_bent_one_is_not() {
        let p = phantom_default();
        for label in [11, 16] {
            let flat = cap_flatness(&p.surface, label).unwrap();
            assert!(flat.is_planar() && flat.off_plane_mm < 1e-9, "{flat:?}");
            assert!(flat.plane.normal.dot(&p.surface.label_centroid_normal(label).unwrap().1) > 0.99, "outward");
            let reversed = TriMesh { triangles: p.surface.triangles.iter().map(|t| [t[0], t[2], t[1]]).collect(), ..p.surface.clone() };
            for plane in [flat.plane, cap_flatness(&reversed, label).unwrap().plane] {
                assert!((plane.axis_u.cross(&plane.axis_v) - plane.normal).norm() < 1e-12, "right-handed either way round");
            }
        }
        let mut bent = p.surface.clone();
        let flat = cap_flatness(&bent, 11).unwrap();
        // Every cap point moved by its squared distance from the centroid: a bowl.
        let on_cap: Vec<u32> = bent.triangles.iter().zip(&bent.face_ids).filter(|(_, &f)| f == 11).flat_map(|(t, _)| *t).collect();
        for v in on_cap.iter().collect::<std::collections::BTreeSet<_>>() {
            let p = bent.points[*v as usize];
            bent.points[*v as usize] += flat.plane.normal * 0.05 * (p - flat.plane.centroid).norm_squared();
        }
        let bowl = cap_flatness(&bent, 11).unwrap();
        assert!(!bowl.is_planar() && bowl.describe("VSD").contains("the VSD cap is not planar"), "{bowl:?}");
        assert!(cap_flatness(&bent, 99).is_none());
    }

    #[test]
    fn phantom_caps_are_recovered_from_one_point_each() {
        let p = phantom_default();
        let unlabelled = TriMesh { face_ids: vec![0; p.surface.triangles.len()], ..p.surface.clone() };
        let centroid = |label: i32| p.surface.label_centroid_normal(label).unwrap().0;
        let seeds = [CapSeed { point_mm: centroid(11), label: 11 }, CapSeed { point_mm: centroid(16), label: 16 }];
        let labels = label_planar_caps(&unlabelled, &seeds, 2, &CapTolerances::default()).unwrap();
        assert_eq!(labels, p.surface.face_ids);
    }

    #[test]
    fn a_seed_off_the_surface_is_named() {
        let p = phantom_default();
        let seeds = [CapSeed { point_mm: Vec3::new(100.0, 0.0, 0.0), label: 11 }];
        let err = label_planar_caps(&p.surface, &seeds, 2, &CapTolerances::default()).unwrap_err();
        assert!(err.contains("cap point 1") && err.contains("mm from the surface"), "{err}");
    }

    #[test]
    fn a_folded_cap_and_a_cap_with_two_rims_are_refused_by_name() {
        let p = phantom_default();
        let caps = [(11, "VSD"), (16, "aortic-annulus")];
        let mut folded = p.surface.clone();
        let t = folded.face_ids.iter().position(|&f| f == 11).unwrap();
        folded.triangles[t].swap(1, 2);
        let err = project_caps_onto_planes(&folded, &caps).unwrap_err();
        assert!(err.contains("the VSD cap"), "{err}");
        // Relabelling the ring of wall triangles round the aortic rim 11 gives the VSD cap more rims.
        let mut two = p.surface.clone();
        let on_16: std::collections::HashSet<u32> = two.triangles.iter().zip(&two.face_ids).filter(|(_, &f)| f == 16).flat_map(|(t, _)| *t).collect();
        let far: Vec<usize> = (0..two.triangles.len()).filter(|&t| two.face_ids[t] == 2 && two.triangles[t].iter().any(|v| on_16.contains(v))).collect();
        assert!(!far.is_empty());
        far.iter().for_each(|&t| two.face_ids[t] = 11);
        let err = project_caps_onto_planes(&two, &caps).unwrap_err();
        assert!(err.contains("the VSD cap") && (err.contains("rims") || err.contains("not planar") || err.contains("rim")), "{err}");
    }
}
