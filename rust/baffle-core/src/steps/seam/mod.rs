//! Step 1, the attachment seam [paper 2.3.3].
//!
//! The surgeon's suture points are ordered by angle in their principal-component
//! plane, a closed parametric cubic spline is fitted through them and resampled at
//! (by default) 600 points evenly spaced in arc length, and each sample is projected
//! onto the RV wall. Between consecutive samples the seam runs straight across the
//! triangles of the input surface (unfolded about the edge they share; where two
//! samples are not in neighbouring triangles, the spline's projected midpoint is
//! added first). `imprint` then inserts this path into the mesh as an exact edge
//! loop, so the baffle and the wall share the seam's vertices exactly.

mod detour;
mod imprint;

pub use imprint::{imprint_seam, ImprintedSeam};

use crate::error::DesignError;
use crate::geometry::mesh::{FaceLabels, TriMesh, Vec3};
use crate::geometry::numerics::pca::best_fit_plane;
use crate::geometry::numerics::spline::ClosedSpline;
use crate::geometry::spatial::{ClosestHit, TriangleBvh};
use detour::WallGraph;
use std::cell::OnceCell;

/// Where a point of the seam's path lies on the input surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Place {
    /// Inside an input triangle.
    Face(u32),
    /// On the edge between two input triangles (and its two input vertices).
    Edge { triangles: [u32; 2], vertices: [u32; 2] },
    /// At an input vertex.
    Vertex(u32),
}

#[derive(Clone, Copy, Debug)]
pub struct PathPoint {
    pub position_mm: Vec3,
    pub place: Place,
}

/// The seam projected onto the wall, before it is inserted into the mesh.
#[derive(Clone, Debug)]
pub struct ProjectedSeam {
    /// Suture points in loop order ([`seam_on_wall`]), mm.
    pub ordered_points_mm: Vec<Vec3>,
    /// Spline samples projected onto the RV wall (with any midpoints added), mm.
    pub samples_mm: Vec<Vec3>,
    /// The closed path on the input surface: samples and edge crossings, in order.
    pub path: Vec<PathPoint>,
}

/// Midpoints added between two samples at most this deep before giving up.
const MAX_BISECTION_DEPTH: usize = 6;
/// A sample whose nearest surface point is on a cap, nearer than the wall by more
/// than this, means the spline passes over the cap.
const CAP_MARGIN_MM: f64 = 0.05;

/// Whether `ordered` runs round `given`'s cycle (any start, either direction).
fn is_rotation_or_reversal(given: &[Vec3], ordered: &[Vec3]) -> bool {
    let n = given.len();
    let position: Option<Vec<usize>> = ordered.iter().map(|q| given.iter().position(|p| p == q)).collect();
    let Some(position) = position.filter(|p| p.len() == n && n > 0) else { return false };
    let step = |k: usize| (position[(k + 1) % n] + n - position[k]) % n;
    (0..n).all(|k| step(k) == 1) || (0..n).all(|k| step(k) == n - 1)
}

/// Order points by their angle around the centroid in their best-fit plane, starting at
/// the surgeon's first point and running toward whichever of its two neighbours was
/// placed first. The plane's axes are a fit's (their signs follow the scanner frame), so
/// the angle alone would start the loop, and the seam's samples, at a point that depends
/// on how the scene lies; the numbering does not.
pub fn order_by_pca_angle(points: &[Vec3]) -> Vec<Vec3> {
    let plane = best_fit_plane(points);
    let mut keyed: Vec<(f64, usize)> = points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let (u, v) = plane.project_2d(p);
            (v.atan2(u), i)
        })
        .collect();
    keyed.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let mut order: Vec<usize> = keyed.into_iter().map(|(_, i)| i).collect();
    let n = order.len();
    if n > 2 {
        let first = order.iter().position(|&i| i == 0).unwrap_or(0);
        order.rotate_left(first);
        if order[n - 1] < order[1] {
            order[1..].reverse();
        }
    }
    order.into_iter().map(|i| points[i]).collect()
}

/// The seam on the wall, projected and inserted as an edge loop: with the points in the
/// paper's angle order, or in the given order (a Slicer closed curve's) where the angle
/// order jumps across the loop or its seam fails. A loop bent round a strongly curved wall
/// (a long tunnel) is not star-shaped in its plane, and there the angle order zigzags.
pub fn seam_on_wall(projector: WallProjector, points: &[Vec3], sample_count: usize) -> Result<(ProjectedSeam, ImprintedSeam), DesignError> {
    let in_order = |ordered: &[Vec3]| {
        let projected = project_ordered_seam(projector, ordered, sample_count)?;
        let imprinted = imprint_seam(projector.surface, &projected)?;
        Ok((projected, imprinted))
    };
    check_suture_points(&projector, points)?;
    let by_angle = order_by_pca_angle(points);
    if is_rotation_or_reversal(points, &by_angle) {
        return in_order(&by_angle);
    }
    if jumps_across_the_loop(points, &by_angle) {
        return in_order(points);
    }
    match in_order(&by_angle) {
        Err(DesignError::Seam(why)) => in_order(points).map_err(|_: DesignError| DesignError::Seam(why)),
        result => result,
    }
}

/// Whether the angle order jumps across the loop where the given order runs round it: its
/// closed polygon is longer by more than half the mean spacing of the points. Swapping two
/// neighbouring clicks changes the perimeter by less; a jump across the loop and back adds
/// about twice the loop's width.
fn jumps_across_the_loop(given: &[Vec3], by_angle: &[Vec3]) -> bool {
    let perimeter_mm = |p: &[Vec3]| -> f64 { (0..p.len()).map(|i| (p[(i + 1) % p.len()] - p[i]).norm()).sum() };
    let given_mm = perimeter_mm(given);
    perimeter_mm(by_angle) - given_mm > 0.5 * given_mm / given.len().max(1) as f64
}

/// [`project_ordered_seam`] with the points in the paper's angle order.
pub fn project_seam(projector: WallProjector, points: &[Vec3], sample_count: usize) -> Result<ProjectedSeam, DesignError> {
    check_suture_points(&projector, points)?;
    project_ordered_seam(projector, &order_by_pca_angle(points), sample_count)
}

/// The suture points as given (numbered as the surgeon placed them): at least 4, each
/// on the wall (within the projector's tolerance), distinct, enclosing an area.
fn check_suture_points(projector: &WallProjector, points: &[Vec3]) -> Result<(), DesignError> {
    if points.len() < 4 {
        return Err(DesignError::SuturePoints(format!(
            "{} point(s) given; a closed seam needs at least 4",
            points.len()
        )));
    }
    check_points_on_wall(projector, points)?;
    check_points_distinct(points)?;
    check_points_enclose(points)
}

/// Fit the closed spline through the checked suture points in loop order, resample it,
/// project the samples onto the wall and trace the path between them.
fn project_ordered_seam(projector: WallProjector, points: &[Vec3], sample_count: usize) -> Result<ProjectedSeam, DesignError> {
    let spline = ClosedSpline::fit(points).map_err(DesignError::SuturePoints)?;
    let samples = spline
        .resample_uniform_arclength(sample_count.max(16))
        .iter()
        .enumerate()
        .map(|(i, q)| projector.project(*q, i))
        .collect::<Result<Vec<_>, _>>()?;
    let tracer = PathTracer { projector, neighbors: projector.surface.triangle_neighbors(), wall: OnceCell::new() };
    let (path, samples_mm) = tracer.trace_closed(&samples)?;
    Ok(ProjectedSeam { ordered_points_mm: points.to_vec(), samples_mm, path })
}

/// Projects points onto the RV wall. A spline sample over a cap is moved onto the
/// cap's rim, the nearest wall, when it is at most the suture-point tolerance inside
/// it: the surgeon's points lie along the VSD rim, where the baffle is sewn, and the
/// spline between two of them may bulge over the cap. Deeper inside, the points do
/// not describe a seam on the wall and the sample is refused.
#[derive(Clone, Copy)]
pub struct WallProjector<'a> {
    surface: &'a TriMesh,
    bvh: &'a TriangleBvh,
    labels: &'a FaceLabels,
    max_rim_shift_mm: f64,
}

impl<'a> WallProjector<'a> {
    /// The wall of `surface` (its `labels.wall` triangles, `bvh` its hierarchy): a suture
    /// point may lie up to `max_point_distance_mm` off it, and a spline sample that far
    /// inside a cap's rim is moved onto the rim.
    pub fn new(surface: &'a TriMesh, bvh: &'a TriangleBvh, labels: &'a FaceLabels, max_point_distance_mm: f64) -> Self {
        WallProjector { surface, bvh, labels, max_rim_shift_mm: max_point_distance_mm }
    }

    fn project(&self, q: Vec3, sample: usize) -> Result<ClosestHit, DesignError> {
        let labels = self.labels;
        let wall = self
            .wall_hit(q)
            .ok_or_else(|| DesignError::Seam(format!("seam sample {sample} found no wall triangle")))?;
        if let Some((label, inside_cap_mm)) = self.over_cap(q, &wall) {
            if inside_cap_mm > self.max_rim_shift_mm {
                return Err(DesignError::Seam(format!(
                    "the seam crosses the {} (label {label}) near sample {sample} ({:.2}, {:.2}, {:.2}), \
                     {inside_cap_mm:.2} mm inside its rim (at most {:.2} mm is moved onto the rim); move the \
                     suture points near it onto the wall around the cap",
                    cap_name(labels, label),
                    q.x,
                    q.y,
                    q.z,
                    self.max_rim_shift_mm
                )));
            }
        }
        Ok(wall)
    }

    fn wall_hit(&self, q: Vec3) -> Option<ClosestHit> {
        let surface = self.surface;
        self.bvh.closest_point_filtered(surface, q, |t| surface.face_ids[t as usize] == self.labels.wall)
    }

    /// The cap `q` lies over (nearer to it than to the wall, `wall` being q's wall
    /// projection), and how much nearer.
    fn over_cap(&self, q: Vec3, wall: &ClosestHit) -> Option<(i32, f64)> {
        let nearest = self.bvh.closest_point(self.surface, q)?;
        self.cap_nearer_than_wall(&nearest, wall.distance_mm)
    }

    /// The cap of `nearest` (a point's closest surface point) when the point is nearer
    /// that cap than the wall (`wall_distance_mm` away) by more than the margin, and by
    /// how much: a point on a cap's rim is as near the wall as the cap.
    fn cap_nearer_than_wall(&self, nearest: &ClosestHit, wall_distance_mm: f64) -> Option<(i32, f64)> {
        let label = self.surface.face_ids[nearest.triangle as usize];
        let inside_cap_mm = wall_distance_mm - nearest.distance_mm;
        (label != self.labels.wall && inside_cap_mm > CAP_MARGIN_MM).then_some((label, inside_cap_mm))
    }
}

/// Traces the seam between projected samples across the input triangles.
struct PathTracer<'a> {
    projector: WallProjector<'a>,
    neighbors: Vec<[u32; 3]>,
    /// Built on the first detour only: most seams never need one.
    wall: OnceCell<WallGraph>,
}

impl PathTracer<'_> {
    fn trace_closed(&self, samples: &[ClosestHit]) -> Result<(Vec<PathPoint>, Vec<Vec3>), DesignError> {
        let n = samples.len();
        let mut path = Vec::with_capacity(2 * n);
        let mut samples_mm = Vec::with_capacity(n);
        for i in 0..n {
            let (a, b) = (&samples[i], &samples[(i + 1) % n]);
            path.push(PathPoint { position_mm: a.point, place: Place::Face(a.triangle) });
            samples_mm.push(a.point);
            self.connect(a, b, 0, i, &mut path, &mut samples_mm)?;
        }
        Ok((snap_to_vertices(self.projector.surface, path), samples_mm))
    }

    /// Append the path points strictly between samples `a` and `b`.
    fn connect(
        &self,
        a: &ClosestHit,
        b: &ClosestHit,
        depth: usize,
        sample: usize,
        path: &mut Vec<PathPoint>,
        samples_mm: &mut Vec<Vec3>,
    ) -> Result<(), DesignError> {
        if a.triangle == b.triangle {
            return Ok(());
        }
        let surface = self.projector.surface;
        let tri_a = surface.triangles[a.triangle as usize];
        if let Some(k) = (0..3).find(|&k| self.neighbors[a.triangle as usize][k] == b.triangle) {
            let edge = [tri_a[k], tri_a[(k + 1) % 3]];
            match edge_crossing(surface, a, b, edge) {
                PathPoint { place: Place::Vertex(v), position_mm } => push_vertex(path, v, position_mm),
                crossing => path.push(crossing),
            }
            return Ok(());
        }
        if depth < MAX_BISECTION_DEPTH {
            let mid = self.projector.project(0.5 * (a.point + b.point), sample)?;
            self.connect(a, &mid, depth + 1, sample, path, samples_mm)?;
            path.push(PathPoint { position_mm: mid.point, place: Place::Face(mid.triangle) });
            samples_mm.push(mid.point);
            return self.connect(&mid, b, depth + 1, sample, path, samples_mm);
        }
        // Bisected to micrometres and still not adjacent: the projection jumps (see
        // `detour`); the seam follows the wall's edges across the gap.
        let wall = self.wall.get_or_init(|| WallGraph::new(surface, self.projector.labels.wall));
        match wall.detour(surface, a, b) {
            Ok(chain) => {
                chain.into_iter().for_each(|v| push_vertex(path, v, surface.points[v as usize]));
                Ok(())
            }
            Err(walk_mm) => Err(self.untraceable(a, b, sample, walk_mm)),
        }
    }

    /// Why the seam cannot go from `a` to `b` on the wall: it crosses a cap (the
    /// midpoint lies over one), or it jumps across a fold whose way round is `walk_mm`.
    fn untraceable(&self, a: &ClosestHit, b: &ClosestHit, sample: usize, walk_mm: f64) -> DesignError {
        let (p, midpoint) = (a.point, 0.5 * (a.point + b.point));
        let cap = self.projector.wall_hit(midpoint).and_then(|wall| self.projector.over_cap(midpoint, &wall));
        DesignError::Seam(match cap {
            Some((label, _)) => format!(
                "the seam crosses the {} near sample {sample} ({:.2}, {:.2}, {:.2}): it enters the cap on one side \
                 and leaves it on another; move the suture points so the seam goes around the cap",
                cap_name(self.projector.labels, label),
                p.x,
                p.y,
                p.z
            ),
            None => format!(
                "could not trace the seam on the wall near sample {sample} ({:.2}, {:.2}, {:.2}): its projection \
                 jumps {:.2} mm across a fold of the wall, and the way round on the wall is {}; move the suture \
                 points near it onto one side of the fold",
                p.x,
                p.y,
                p.z,
                detour::jump_mm(a, b),
                if walk_mm.is_finite() { format!("{walk_mm:.1} mm long") } else { "not within reach".to_string() }
            ),
        })
    }
}

/// Snap distance of the mesh insertion: a thousandth of the mean edge.
pub(crate) fn insertion_snap_mm(surface: &TriMesh) -> f64 {
    1e-3 * surface.mean_edge_length_mm()
}

/// Path points closer than ten insertion snaps to an input vertex of their triangle
/// move onto it. The insertion snaps nearby points together; near a vertex such
/// points can lie in triangles that share only that vertex, so the seam must pass
/// through the vertex itself to stay inside a common triangle.
fn snap_to_vertices(surface: &TriMesh, path: Vec<PathPoint>) -> Vec<PathPoint> {
    let radius_mm = 10.0 * insertion_snap_mm(surface);
    let mut out: Vec<PathPoint> = Vec::with_capacity(path.len());
    for point in path {
        let corners: Vec<u32> = match point.place {
            Place::Face(t) => surface.triangles[t as usize].to_vec(),
            Place::Edge { vertices, .. } => vertices.to_vec(),
            Place::Vertex(v) => vec![v],
        };
        let near = corners.into_iter().find(|&v| (surface.points[v as usize] - point.position_mm).norm() <= radius_mm);
        match near {
            Some(v) if out.last().map(|p| p.place) == Some(Place::Vertex(v)) => {}
            Some(v) => push_vertex(&mut out, v, surface.points[v as usize]),
            None => out.push(point),
        }
    }
    out
}

/// How far back a path may return to a vertex it passed, as a short excursion.
const LOOP_WINDOW: usize = 64;

/// Append vertex `v`; if the path passed through it a few points ago (the projected
/// spline skirted a sharp vertex and came back to it), drop that excursion instead,
/// so the seam goes through the vertex once.
fn push_vertex(path: &mut Vec<PathPoint>, v: u32, position_mm: Vec3) {
    let start = path.len().saturating_sub(LOOP_WINDOW);
    if let Some(k) = (start..path.len()).rev().find(|&k| path[k].place == Place::Vertex(v)) {
        path.truncate(k + 1);
        return;
    }
    path.push(PathPoint { position_mm, place: Place::Vertex(v) });
}

/// Where the straight path from `a` to `b` crosses their shared edge, with `b`'s
/// triangle unfolded about that edge into `a`'s plane (the geodesic across the edge).
fn edge_crossing(surface: &TriMesh, a: &ClosestHit, b: &ClosestHit, edge: [u32; 2]) -> PathPoint {
    let (e0, e1) = (surface.points[edge[0] as usize], surface.points[edge[1] as usize]);
    let length = (e1 - e0).norm();
    let along_edge = (e1 - e0) / length;
    let tri_a = surface.triangles[a.triangle as usize];
    let third = tri_a.iter().find(|v| !edge.contains(v)).map_or(e0, |&v| surface.points[v as usize]);
    // In a's plane, the unit normal to the edge pointing away from a's third corner.
    let normal_a = surface.triangle_normal2(a.triangle as usize);
    let mut away = along_edge.cross(&normal_a).normalize();
    if away.dot(&(third - e0)) > 0.0 {
        away = -away;
    }
    let (a_along, a_across) = ((a.point - e0).dot(&along_edge), (a.point - e0).dot(&away));
    let rel_b = b.point - e0;
    let b_along = rel_b.dot(&along_edge);
    let b_across = (rel_b - b_along * along_edge).norm();
    // a lies on or behind the edge (a_across <= 0), b beyond it; rounding can put a
    // a hair past it, so the crossing's fraction is clamped to the segment.
    let lambda = if b_across - a_across > 0.0 { (-a_across / (b_across - a_across)).clamp(0.0, 1.0) } else { 0.5 };
    let along = (a_along + lambda * (b_along - a_along)).clamp(0.0, length);
    let at_end = 1e-9 * length;
    let place = if along <= at_end {
        Place::Vertex(edge[0])
    } else if along >= length - at_end {
        Place::Vertex(edge[1])
    } else {
        Place::Edge { triangles: [a.triangle, b.triangle], vertices: edge }
    };
    let position_mm = match place {
        Place::Vertex(v) => surface.points[v as usize],
        _ => e0 + along * along_edge,
    };
    PathPoint { position_mm, place }
}

/// Suture points spread this much less across their main direction than along it
/// (RMS; the published seams: 0.69-0.71, the phantom 0.45) lie along a line or a
/// shallow arc and go around nothing: their angle order is then arbitrary and the
/// seam would only be reported as crossing itself.
const MIN_SPREAD_RATIO: f64 = 0.2;

/// The suture points must spread in two directions, around the VSD and the annulus.
/// Two suture points closer than this (mm) are one point clicked twice.
const MIN_POINT_SEPARATION_MM: f64 = 0.05;

/// No two points coincide, named in the surgeon's numbering (the spline sees them
/// reordered around the loop).
fn check_points_distinct(points: &[Vec3]) -> Result<(), DesignError> {
    for (i, p) in points.iter().enumerate() {
        if let Some(j) = (i + 1..points.len()).find(|&j| (points[j] - p).norm() < MIN_POINT_SEPARATION_MM) {
            return Err(DesignError::SuturePoints(format!(
                "points {} and {} are {:.3} mm apart at ({:.2}, {:.2}, {:.2}): one point given twice; remove the duplicate",
                i + 1,
                j + 1,
                (points[j] - p).norm(),
                p.x,
                p.y,
                p.z
            )));
        }
    }
    Ok(())
}

fn check_points_enclose(points: &[Vec3]) -> Result<(), DesignError> {
    let [along, across, _] = best_fit_plane(points).singular_values.map(|s| s / (points.len() as f64).sqrt());
    if across < MIN_SPREAD_RATIO * along {
        return Err(DesignError::SuturePoints(format!(
            "the {} points lie almost on a line (RMS spread {across:.2} mm across it against {along:.2} mm along \
             it): place them around the VSD and the aortic annulus, which the seam must enclose",
            points.len()
        )));
    }
    Ok(())
}

/// Every suture point must lie on the RV wall (not a cap) within the tolerance.
fn check_points_on_wall(projector: &WallProjector, points: &[Vec3]) -> Result<(), DesignError> {
    let (surface, labels, max_point_distance_mm) = (projector.surface, projector.labels, projector.max_rim_shift_mm);
    for (i, p) in points.iter().enumerate() {
        if !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()) {
            return Err(DesignError::SuturePoints(format!("point {} has a non-finite coordinate", i + 1)));
        }
        let hit = projector
            .bvh
            .closest_point(surface, *p)
            .ok_or_else(|| DesignError::Surface("the surface has no triangles".into()))?;
        if hit.distance_mm > max_point_distance_mm {
            return Err(DesignError::SuturePoints(format!(
                "point {} ({:.2}, {:.2}, {:.2}) is {:.2} mm from the surface (limit {:.2} mm); \
                 is it in the same coordinate frame (LPS/RAS) as the surface?",
                i + 1,
                p.x,
                p.y,
                p.z,
                hit.distance_mm,
                max_point_distance_mm
            )));
        }
        // The wall is looked up only when the nearest triangle is not wall.
        let on_cap = (surface.face_ids[hit.triangle as usize] != labels.wall)
            .then(|| projector.wall_hit(*p).map_or(f64::INFINITY, |w| w.distance_mm))
            .and_then(|wall_distance_mm| projector.cap_nearer_than_wall(&hit, wall_distance_mm));
        if let Some((label, _)) = on_cap {
            return Err(DesignError::SuturePoints(format!(
                "point {} lies on the {} (label {label}), not on the RV wall",
                i + 1,
                cap_name(labels, label)
            )));
        }
    }
    Ok(())
}

fn cap_name(labels: &FaceLabels, label: i32) -> &'static str {
    if label == labels.vsd_cap {
        "VSD cap"
    } else if label == labels.aortic_cap {
        "aortic-annulus cap"
    } else {
        "surface region"
    }
}

/// The input triangles a path point lies in.
fn home_triangles(place: &Place, vertex_triangles: &[Vec<u32>]) -> Vec<u32> {
    match *place {
        Place::Face(t) => vec![t],
        Place::Edge { triangles, .. } => triangles.to_vec(),
        Place::Vertex(v) => vertex_triangles[v as usize].clone(),
    }
}

/// An input triangle holding both path points (the straight seam between them lies in it).
fn common_triangle(a: &Place, b: &Place, vertex_triangles: &[Vec<u32>]) -> Option<u32> {
    let home_a = home_triangles(a, vertex_triangles);
    home_triangles(b, vertex_triangles).into_iter().find(|t| home_a.contains(t))
}

#[cfg(test)]
mod tests;
