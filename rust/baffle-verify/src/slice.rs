//! Plane sections of a triangle mesh.
//!
//! Each triangle that the plane crosses gives one segment between two crossed
//! edges; segments are chained into polylines through the edges they share (by
//! point indices, never by comparing coordinates). A point lying exactly on the
//! plane counts as above it (symbolic perturbation), so every triangle is crossed
//! on exactly zero or two edges and contours stay closed even through vertices.

use crate::check_mesh;
use baffle_core::{TriMesh, Vec3};
use std::collections::HashMap;

/// One connected piece of a plane section.
#[derive(Clone, Debug, PartialEq)]
pub struct Contour {
    /// On the plane, in order along the contour (mm).
    pub points: Vec<Vec3>,
    /// The last point joins the first (always, for a closed surface).
    pub closed: bool,
    /// The triangle cut by segment `i` (from `points[i]` to the next point).
    pub triangle_of_segment: Vec<u32>,
}

/// A triangle's piece of the section: the two crossed edges it joins.
struct Segment {
    edges: [u32; 2],
    triangle: u32,
}

/// The crossed edges, numbered in order of discovery, with the segments using them.
#[derive(Default)]
struct CrossedEdges {
    id_of: HashMap<(u32, u32), u32>,
    endpoints: Vec<(u32, u32)>,
    users: Vec<Vec<u32>>,
}

impl CrossedEdges {
    fn id(&mut self, a: u32, b: u32) -> u32 {
        let key = (a.min(b), a.max(b));
        *self.id_of.entry(key).or_insert_with(|| {
            self.endpoints.push(key);
            self.users.push(Vec::with_capacity(2));
            self.endpoints.len() as u32 - 1
        })
    }
}

/// Intersect `mesh` with the plane through `origin` with normal `normal`.
/// Errors on a zero or non-finite normal, bad point indices, or a crossed edge
/// shared by more than two triangles (where chaining would be ambiguous).
/// Triangles repeating a point index have no area and are skipped.
pub fn slice_by_plane(mesh: &TriMesh, origin: Vec3, normal: Vec3) -> Result<Vec<Contour>, String> {
    check_mesh(mesh)?;
    let unit_normal = unit_plane_normal(&normal)?;
    let heights: Vec<f64> = mesh
        .points
        .iter()
        .map(|p| unit_normal.dot(&(p - origin)))
        .collect();
    let (segments, crossed) = cut_triangles(mesh, &heights)?;
    let edge_point = |e: u32| {
        let (a, b) = crossed.endpoints[e as usize];
        let (ha, hb) = (heights[a as usize], heights[b as usize]);
        // Signs differ (one >= 0, the other < 0), so ha - hb != 0. Computed per
        // edge, so both triangles sharing it get the same point.
        let (pa, pb) = (mesh.points[a as usize], mesh.points[b as usize]);
        pa + (pb - pa) * (ha / (ha - hb))
    };
    Ok(chain_segments(&segments, &crossed, edge_point))
}

fn unit_plane_normal(normal: &Vec3) -> Result<Vec3, String> {
    if !normal.iter().all(|c| c.is_finite()) {
        return Err(format!("plane normal {normal:?} is not finite"));
    }
    normal
        .try_normalize(0.0)
        .ok_or_else(|| "plane normal is the zero vector".to_string())
}

/// One segment per crossed triangle, and the crossed edges they join.
fn cut_triangles(mesh: &TriMesh, heights: &[f64]) -> Result<(Vec<Segment>, CrossedEdges), String> {
    let above = |p: u32| heights[p as usize] >= 0.0;
    let mut crossed = CrossedEdges::default();
    let mut segments: Vec<Segment> = Vec::new();
    for (t, tri) in mesh.triangles.iter().enumerate() {
        if tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2] {
            continue;
        }
        let mut edges = [0u32; 2];
        let mut found = 0;
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            if above(a) != above(b) {
                edges[found] = crossed.id(a, b);
                found += 1;
            }
        }
        // With every point strictly on one side, a crossed triangle has exactly two crossed edges.
        if found == 2 {
            let s = segments.len() as u32;
            for e in edges {
                let users = &mut crossed.users[e as usize];
                users.push(s);
                if users.len() > 2 {
                    let (a, b) = crossed.endpoints[e as usize];
                    return Err(format!(
                        "the plane crosses edge ({a}, {b}), which is shared by more than two triangles \
                         (at least triangles {:?} and {t})",
                        users[..2].iter().map(|&u| segments[u as usize].triangle).collect::<Vec<u32>>()
                    ));
                }
            }
            segments.push(Segment {
                edges,
                triangle: t as u32,
            });
        }
    }
    Ok((segments, crossed))
}

/// Walk the segments into polylines: open ones from the crossed boundary edges
/// (used by one segment) first, then the closed loops.
fn chain_segments(
    segments: &[Segment],
    crossed: &CrossedEdges,
    edge_point: impl Fn(u32) -> Vec3,
) -> Vec<Contour> {
    let mut used = vec![false; segments.len()];
    let mut contours = Vec::new();
    for (e, users) in crossed.users.iter().enumerate() {
        if users.len() == 1 && !used[users[0] as usize] {
            contours.push(walk(
                e as u32,
                users[0],
                segments,
                crossed,
                &mut used,
                &edge_point,
            ));
        }
    }
    for s in 0..segments.len() {
        if !used[s] {
            contours.push(walk(
                segments[s].edges[0],
                s as u32,
                segments,
                crossed,
                &mut used,
                &edge_point,
            ));
        }
    }
    contours
}

/// Follow segments from `start_edge` through `first`, crossing from segment to
/// segment over shared edges, until back at `start_edge` or at an open end.
fn walk(
    start_edge: u32,
    first: u32,
    segments: &[Segment],
    crossed: &CrossedEdges,
    used: &mut [bool],
    edge_point: &impl Fn(u32) -> Vec3,
) -> Contour {
    let mut contour = Contour {
        points: vec![edge_point(start_edge)],
        closed: false,
        triangle_of_segment: Vec::new(),
    };
    let (mut edge, mut seg) = (start_edge, first);
    loop {
        used[seg as usize] = true;
        let segment = &segments[seg as usize];
        contour.triangle_of_segment.push(segment.triangle);
        let next_edge = if segment.edges[0] == edge {
            segment.edges[1]
        } else {
            segment.edges[0]
        };
        if next_edge == start_edge {
            contour.closed = true;
            return contour;
        }
        contour.points.push(edge_point(next_edge));
        let onward = crossed.users[next_edge as usize]
            .iter()
            .copied()
            .find(|&s| s != seg && !used[s as usize]);
        match onward {
            Some(s) => (edge, seg) = (next_edge, s),
            None => return contour,
        }
    }
}

/// Area (mm^2) of the polygon through the contour's points (an open contour is
/// closed by its chord), projected along `normal`: |vector area . unit normal|.
/// NaN for a zero normal.
pub fn contour_area_mm2(contour: &Contour, normal: Vec3) -> f64 {
    let Some(unit_normal) = normal.try_normalize(0.0) else {
        return f64::NAN;
    };
    let Some(&base) = contour.points.first() else {
        return 0.0;
    };
    // Measured from the first point, so the terms stay small far from the origin.
    let twice_area: Vec3 = contour
        .points
        .windows(2)
        .map(|w| (w[0] - base).cross(&(w[1] - base)))
        .sum();
    0.5 * twice_area.dot(&unit_normal).abs()
}

/// Area of the section through `origin`: the innermost closed contour that
/// encloses `origin` in the plane, or, if none does, the closed contour whose
/// point average is nearest to `origin`. `None` when the plane cuts no closed contour.
pub fn section_area_nearest(
    mesh: &TriMesh,
    origin: Vec3,
    normal: Vec3,
) -> Result<Option<f64>, String> {
    let contours = slice_by_plane(mesh, origin, normal)?;
    let closed: Vec<&Contour> = contours.iter().filter(|c| c.closed).collect();
    let (u_axis, v_axis) = plane_axes(&normal.normalize());
    let flat = |c: &Contour| -> Vec<[f64; 2]> {
        c.points
            .iter()
            .map(|p| [(p - origin).dot(&u_axis), (p - origin).dot(&v_axis)])
            .collect()
    };
    let innermost_enclosing = closed
        .iter()
        .filter(|c| encloses_origin_2d(&flat(c)))
        .map(|c| contour_area_mm2(c, normal))
        .min_by(f64::total_cmp);
    if innermost_enclosing.is_some() {
        return Ok(innermost_enclosing);
    }
    let distance_to_mean =
        |c: &Contour| (c.points.iter().sum::<Vec3>() / c.points.len() as f64 - origin).norm();
    Ok(closed
        .iter()
        .min_by(|a, b| distance_to_mean(a).total_cmp(&distance_to_mean(b)))
        .map(|c| contour_area_mm2(c, normal)))
}

/// Two unit vectors spanning the plane with unit normal `n`.
fn plane_axes(n: &Vec3) -> (Vec3, Vec3) {
    let helper = if n.x.abs() < 0.9 {
        Vec3::x()
    } else {
        Vec3::y()
    };
    let u = n.cross(&helper).normalize();
    (u, n.cross(&u))
}

/// Even-odd rule for the point (0, 0) against the closed polygon `poly`.
fn encloses_origin_2d(poly: &[[f64; 2]]) -> bool {
    let mut inside = false;
    for i in 0..poly.len() {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        if (a[1] > 0.0) != (b[1] > 0.0) {
            let x_at_axis = a[0] + (b[0] - a[0]) * (0.0 - a[1]) / (b[1] - a[1]);
            if x_at_axis > 0.0 {
                inside = !inside;
            }
        }
    }
    inside
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_meshes::{closed_cylinder, inscribed_polygon_area_mm2, tetrahedron, Rng};
    use std::f64::consts::PI;

    fn assert_chained(contour: &Contour) {
        let segments = if contour.closed {
            contour.points.len()
        } else {
            contour.points.len() - 1
        };
        assert_eq!(contour.triangle_of_segment.len(), segments);
    }

    #[test]
    fn oblique_cylinder_sections_match_the_ellipse() {
        let (radius, segments) = (10.0, 128);
        let cylinder = closed_cylinder(radius, 60.0, segments, 7);
        let mut rng = Rng(7);
        for _ in 0..40 {
            let tilt = 0.8 * rng.unit(); // < 46 degrees: the plane stays on the side wall
            let azimuth = 2.0 * PI * rng.unit();
            let normal = Vec3::new(
                tilt.sin() * azimuth.cos(),
                tilt.sin() * azimuth.sin(),
                tilt.cos(),
            );
            let origin = Vec3::new(0.0, 0.0, 20.0 + 20.0 * rng.unit());
            let contours = slice_by_plane(&cylinder, origin, normal).unwrap();
            assert_eq!(contours.len(), 1);
            assert!(contours[0].closed);
            assert_chained(&contours[0]);
            let analytic = PI * radius * radius / tilt.cos();
            let area = contour_area_mm2(&contours[0], normal);
            assert!(
                (area / analytic - 1.0).abs() < 0.005,
                "tilt {tilt}: {area} vs {analytic}"
            );
            // Sections of a prism are exact affine images of its polygon.
            let polygon = inscribed_polygon_area_mm2(radius, segments) / tilt.cos();
            assert!(
                (area / polygon - 1.0).abs() < 1e-9,
                "tilt {tilt}: {area} vs {polygon}"
            );
            assert_eq!(
                section_area_nearest(&cylinder, origin, normal).unwrap(),
                Some(area)
            );
        }
    }

    #[test]
    fn planes_through_vertices_still_give_closed_contours() {
        let (radius, segments) = (4.0, 16);
        let cylinder = closed_cylinder(radius, 30.0, segments, 4); // rings at z = 0, 10, 20, 30
        let polygon = inscribed_polygon_area_mm2(radius, segments);
        // Through a whole ring of points.
        let contours = slice_by_plane(&cylinder, Vec3::new(0.0, 0.0, 10.0), Vec3::z()).unwrap();
        assert_eq!(contours.len(), 1);
        assert!(contours[0].closed);
        assert!((contour_area_mm2(&contours[0], Vec3::z()) - polygon).abs() < 1e-9);
        // Tilted, through exactly one ring point.
        let vertex = cylinder.points[(segments + 3) as usize];
        let normal = Vec3::new(0.3, -0.2, 1.0);
        let contours = slice_by_plane(&cylinder, vertex, normal).unwrap();
        assert_eq!(contours.len(), 1);
        assert!(contours[0].closed);
        assert_chained(&contours[0]);
        let expected = polygon * normal.norm() / normal.z;
        assert!((contour_area_mm2(&contours[0], normal) - expected).abs() < 1e-9 * expected);
        // Along a cap's plane, the cap counts as above: nothing is cut.
        assert!(slice_by_plane(&cylinder, Vec3::zeros(), Vec3::z())
            .unwrap()
            .is_empty());
    }

    #[test]
    fn tetrahedron_sections_are_the_analytic_triangles() {
        let tet = tetrahedron();
        for h in [0.1, 0.25, 0.5, 0.9] {
            let contours = slice_by_plane(&tet, Vec3::new(0.2, 0.2, h), Vec3::z()).unwrap();
            assert_eq!(contours.len(), 1);
            assert_eq!(contours[0].points.len(), 3);
            let expected = 0.5 * (1.0 - h) * (1.0 - h);
            assert!((contour_area_mm2(&contours[0], Vec3::z()) - expected).abs() < 1e-14);
            // Oblique plane x + y + z = s: an equilateral triangle of side s * sqrt(2).
            let n = Vec3::new(1.0, 1.0, 1.0);
            let area = section_area_nearest(&tet, Vec3::new(h, 0.0, 0.0), n)
                .unwrap()
                .unwrap();
            assert!(
                (area - 3f64.sqrt() / 2.0 * h * h).abs() < 1e-14,
                "s = {h}: {area}"
            );
        }
    }

    #[test]
    fn open_surfaces_give_open_contours() {
        let mut tet = tetrahedron();
        tet.triangles.remove(2); // the x = 0 face
        let contours = slice_by_plane(&tet, Vec3::new(0.0, 0.0, 0.5), Vec3::z()).unwrap();
        assert_eq!(contours.len(), 1);
        assert!(!contours[0].closed);
        assert_eq!(contours[0].points.len(), 3);
        assert_chained(&contours[0]);
        assert_eq!(
            section_area_nearest(&tet, Vec3::new(0.0, 0.0, 0.5), Vec3::z()).unwrap(),
            None
        );
    }

    #[test]
    fn two_tubes_give_two_contours_and_the_enclosing_one_is_chosen() {
        let small = closed_cylinder(2.0, 10.0, 64, 3);
        let large = closed_cylinder(5.0, 10.0, 64, 3);
        let offset = small.points.len() as u32;
        let mut both = small.clone();
        both.points
            .extend(large.points.iter().map(|p| p + Vec3::new(20.0, 0.0, 0.0)));
        both.triangles
            .extend(large.triangles.iter().map(|t| t.map(|i| i + offset)));
        both.face_ids.extend(&large.face_ids);
        assert_eq!(
            slice_by_plane(&both, Vec3::new(0.0, 0.0, 5.0), Vec3::z())
                .unwrap()
                .len(),
            2
        );
        let at_large = section_area_nearest(&both, Vec3::new(21.0, 1.0, 5.0), Vec3::z())
            .unwrap()
            .unwrap();
        assert!((at_large - inscribed_polygon_area_mm2(5.0, 64)).abs() < 1e-9);
        // Outside both: the nearer one (by point average) is used.
        let near_small = section_area_nearest(&both, Vec3::new(-4.0, 0.0, 5.0), Vec3::z())
            .unwrap()
            .unwrap();
        assert!((near_small - inscribed_polygon_area_mm2(2.0, 64)).abs() < 1e-9);
    }

    #[test]
    fn bad_input_is_reported() {
        let tet = tetrahedron();
        assert!(slice_by_plane(&tet, Vec3::zeros(), Vec3::zeros())
            .unwrap_err()
            .contains("zero"));
        let mut fin = tet.clone();
        fin.points.push(Vec3::new(1.0, 1.0, 1.0));
        fin.triangles.push([1, 3, 4]); // a third triangle on edge (1, 3)
        let err = slice_by_plane(&fin, Vec3::new(0.0, 0.0, 0.5), Vec3::z()).unwrap_err();
        assert!(err.contains("edge (1, 3)"), "{err}");
        let mut broken = tet;
        broken.triangles[0][0] = 9;
        assert!(slice_by_plane(&broken, Vec3::zeros(), Vec3::z())
            .unwrap_err()
            .contains("point 9"));
    }
}
