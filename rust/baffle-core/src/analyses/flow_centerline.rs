//! The flow-domain centerline [paper 2.5]: the medial line of the lumen between the
//! two measurement planes. Its length is the paper's "flow-domain centerline length"
//! and the CFD's v_max is sampled along it. (Not the design centerline of
//! [`crate::steps::centerline`], which runs through the cap centroids by construction.)
//!
//! VMTK (Antiga et al. 2003, "Computational geometry for patient-specific
//! reconstruction and meshing of blood vessels from MR and CT angiography") finds the
//! centerline as the minimal path between the two end seeds on the Voronoi diagram of
//! the wall, with speed equal to the maximal inscribed sphere radius R. We use the
//! same idea on a continuous distance field instead of the Voronoi diagram:
//!
//! 1. the lumen is voxelized (exact winding number, [`crate::geometry::voxel`]) and every inside
//!    voxel centre gets R = exact distance to the wall triangles (BVH; the cap
//!    triangles are not wall, so R near an open end is the lumen's, not 0);
//! 2. Dijkstra's minimal path over the 26-connected inside voxels from the voxel
//!    nearest the inflow seed to the one nearest the outflow seed, step cost
//!    `|step| (1/R_a^2 + 1/R_b^2) / 2`: the path keeps to the middle as VMTK's does;
//! 3. the voxel path is resampled at the voxel size and smoothed (moving average,
//!    half-width `smoothing_mm`, ends fixed), which removes the grid's staircase;
//! 4. the curve is resampled at half the output spacing and each point re-centred in
//!    the plane normal to the curve: compass search for the largest R within
//!    `recenter_fraction` of R (the centre of the largest inscribed circle of the
//!    cross-section, where the Voronoi medial line runs), then smoothed again with the
//!    same moving average; twice. This takes the curve off the voxel grid (the raw
//!    1/R^2 path wanders on the flat medial sheet of a wide chamber: on p3 it is about
//!    1.5 mm longer than the re-centred one);
//! 5. the curve, extended a little past both ends along its end tangents, is trimmed
//!    at the measurement planes (the crossing with each plane's triangles: the last
//!    crossing of the inflow plane before the first crossing of the outflow plane),
//!    resampled in equal steps no longer than `spacing_mm` (0.5 mm in the paper), and
//!    each point gets its maximal inscribed sphere radius, re-measured exactly.
//!
//! The planes are triangle sets: a cap of the surface (our designed domain, the
//! published one) or an interior face set of the volume mesh (the extended domain, whose
//! own end caps are then the seeds). Millimetres throughout.
//!
//! All five steps run in the lumen's own frame (`LumenFrame`: from the inflow seed toward
//! the outflow seed, and the inflow plane's normal), not the scene's axes, so that a scene
//! rotated in Slicer gives the same centerline, rotated, and the same sections: on the
//! scene's axes the voxel staircase fell differently and moved the throat's area by
//! 0.4-2 % on p1-p3 rotated by (37, -23, 61) degrees.

use crate::geometry::mesh::{area_centroid_normal, axes_across, manifold_report, TriMesh, Vec3};
use crate::geometry::spatial::{ray_triangle, Aabb, TriangleBvh};
use crate::geometry::voxel::{best_first_search, voxelize, Grid};
use crate::geometry::plane_section::SectionShape;
use rayon::prelude::*;

/// Centerline spacing of the paper (mm).
pub const PAPER_SPACING_MM: f64 = 0.5;
/// Largest grid built; a coarser voxel is used beyond it (said in the result).
const MAX_VOXELS: usize = 40_000_000;
/// Re-centring and smoothing rounds (the second moves the points by a few hundredths of a mm).
const RECENTER_PASSES: usize = 2;
/// Compass search stops at this step (mm).
const RECENTER_TOLERANCE_MM: f64 = 1e-3;

/// A measurement plane as the triangles of its disc (mm).
#[derive(Clone, Debug)]
pub struct MeasurementPlane {
    pub label: i32,
    pub triangles: Vec<[Vec3; 3]>,
}

impl MeasurementPlane {
    /// The triangles of `mesh` labelled `label`; None when there are none.
    pub fn from_label(mesh: &TriMesh, label: i32) -> Option<MeasurementPlane> {
        let triangles: Vec<[Vec3; 3]> = (0..mesh.triangles.len()).filter(|&t| mesh.face_ids[t] == label).map(|t| mesh.triangle_points(t)).collect();
        (!triangles.is_empty()).then_some(MeasurementPlane { label, triangles })
    }

    /// Area-weighted centroid (zero for a disc without area).
    pub fn centroid(&self) -> Vec3 {
        area_centroid_normal(self.triangles.iter().copied()).1
    }

    /// Area-weighted normal (unit; zero for a degenerate disc), by the triangles' winding.
    pub fn normal(&self) -> Vec3 {
        let sum = area_centroid_normal(self.triangles.iter().copied()).2;
        if sum.norm() > 0.0 { sum.normalize() } else { sum }
    }

    /// Parameters `t` in [0, 1] where the segment `a -> b` crosses the disc.
    fn crossings(&self, a: Vec3, b: Vec3) -> impl Iterator<Item = f64> + '_ {
        self.triangles.iter().filter_map(move |tri| ray_triangle(&a, &(b - a), tri)).filter(|&t| t <= 1.0)
    }
}

/// What the centerline is computed on.
#[derive(Clone, Debug)]
pub struct Lumen<'a> {
    /// Closed surface of the lumen (either winding), mm.
    pub surface: &'a TriMesh,
    /// Labels of the surface's open ends (caps): not wall.
    pub open_labels: Vec<i32>,
    /// Where the path starts and ends (the end caps' centroids).
    pub inflow_seed: Vec3,
    pub outflow_seed: Vec3,
    /// Trimming planes, inflow first.
    pub planes: [MeasurementPlane; 2],
}

impl<'a> Lumen<'a> {
    /// The measurement planes are the surface's caps `inflow` and `outflow` (our
    /// designed domain: 11 and 16).
    pub fn between_caps(surface: &'a TriMesh, inflow: i32, outflow: i32) -> Result<Lumen<'a>, String> {
        let plane = |label| MeasurementPlane::from_label(surface, label).ok_or_else(|| format!("the surface has no triangles labelled {label}"));
        Lumen::with_end_caps(surface, inflow, outflow, [plane(inflow)?, plane(outflow)?])
    }

    /// The path runs between the end caps `inflow_cap` and `outflow_cap` of the surface
    /// and is trimmed at `planes` (e.g. interior face sets of the extended domain's mesh).
    pub fn with_end_caps(surface: &'a TriMesh, inflow_cap: i32, outflow_cap: i32, planes: [MeasurementPlane; 2]) -> Result<Lumen<'a>, String> {
        check_closed(surface)?;
        let cap = |label| MeasurementPlane::from_label(surface, label).ok_or_else(|| format!("the surface has no end cap labelled {label}"));
        let (inflow_seed, outflow_seed) = (cap(inflow_cap)?.centroid(), cap(outflow_cap)?.centroid());
        Ok(Lumen { surface, open_labels: vec![inflow_cap, outflow_cap], inflow_seed, outflow_seed, planes })
    }
}

/// The voxelized inside of an open surface leaks out through its holes; a centerline
/// of it would be a path through whatever the flood fill found.
fn check_closed(surface: &TriMesh) -> Result<(), String> {
    let report = manifold_report(surface);
    if report.boundary_edges == 0 {
        return Ok(());
    }
    let at = report.example_edge.map(|(a, b)| format!(", e.g. between points {a} and {b}")).unwrap_or_default();
    Err(format!("the surface is open: {} boundary edges{at}; the lumen must be closed", report.boundary_edges))
}

#[derive(Clone, Copy, Debug)]
pub struct CenterlineOptions {
    pub voxel_mm: f64,
    pub spacing_mm: f64,
    /// Half-width of the moving average (mm).
    pub smoothing_mm: f64,
    /// Largest re-centring shift, as a fraction of the point's inscribed radius.
    pub recenter_fraction: f64,
}

impl Default for CenterlineOptions {
    fn default() -> Self {
        CenterlineOptions { voxel_mm: 0.2, spacing_mm: PAPER_SPACING_MM, smoothing_mm: 1.0, recenter_fraction: 0.25 }
    }
}

#[derive(Clone, Debug)]
pub struct FlowCenterline {
    pub points: Vec<Vec3>,
    /// Maximal inscribed sphere radius at each point (mm).
    pub radius_mm: Vec<f64>,
    /// Arc length from the inflow plane (mm).
    pub s_mm: Vec<f64>,
    pub length_mm: f64,
    /// Voxel size used (larger than asked when the grid would exceed `MAX_VOXELS`).
    pub voxel_mm: f64,
    pub inside_voxels: usize,
    /// Wall time of each step (ms).
    pub timings_ms: Vec<(&'static str, f64)>,
}

/// Exact distance to the wall (every triangle not of an open label).
struct WallDistance<'a> {
    surface: &'a TriMesh,
    bvh: TriangleBvh,
    is_wall: Vec<bool>,
}

impl<'a> WallDistance<'a> {
    fn new(lumen: &Lumen<'a>) -> Result<WallDistance<'a>, String> {
        let surface = lumen.surface;
        let is_wall: Vec<bool> = surface.face_ids.iter().map(|id| !lumen.open_labels.contains(id)).collect();
        if !is_wall.contains(&true) {
            return Err("the surface has no wall triangles".into());
        }
        Ok(WallDistance { surface, bvh: TriangleBvh::new(surface)?, is_wall })
    }

    fn at(&self, p: Vec3) -> f64 {
        self.bvh.closest_point_filtered(self.surface, p, |t| self.is_wall[t as usize]).map_or(0.0, |h| h.distance_mm)
    }
}

impl CenterlineOptions {
    /// Each option in its range, named as the command's flag: a zero spacing would
    /// resample forever, a re-centring beyond the inscribed radius would leave the lumen.
    pub fn validate(&self) -> Result<(), String> {
        let checks = [
            ("voxel-mm", self.voxel_mm, 0.01, 5.0),
            ("spacing-mm", self.spacing_mm, 0.01, 20.0),
            ("smoothing-mm", self.smoothing_mm, 0.0, 50.0),
            ("recenter-fraction", self.recenter_fraction, 0.0, 1.0),
        ];
        match checks.iter().find(|(_, v, lo, hi)| !(v.is_finite() && (*lo..=*hi).contains(v))) {
            Some((name, v, lo, hi)) => Err(format!("--{name} = {v} is outside [{lo}, {hi}]")),
            None => Ok(()),
        }
    }
}

pub fn flow_centerline(lumen: &Lumen, opts: &CenterlineOptions) -> Result<FlowCenterline, String> {
    opts.validate()?;
    let frame = LumenFrame::new(lumen.inflow_seed, lumen.outflow_seed - lumen.inflow_seed, &lumen.planes);
    let surface = frame.mesh_to_local(lumen.surface);
    let local = frame.lumen_to_local(lumen, &surface);
    let line = centerline_in_own_frame(&local, opts)?;
    Ok(FlowCenterline { points: line.points.iter().map(|&p| frame.to_world(p)).collect(), ..line })
}

/// An orthonormal frame set by the lumen itself: the origin at its start, the first axis
/// toward its end, the second the inflow plane's normal across it (the outflow plane's, or
/// any, where the normal runs along the first axis). Rotating and moving the lumen moves
/// the frame with it, so what is voxelized or rastered in it does not change.
struct LumenFrame {
    origin: Vec3,
    /// The axes as rows: local = axes (world - origin).
    axes: nalgebra::Matrix3<f64>,
}

impl LumenFrame {
    fn new(origin: Vec3, along: Vec3, planes: &[MeasurementPlane]) -> LumenFrame {
        let first = if along.norm() > 0.0 { along.normalize() } else { Vec3::x() };
        let across = |n: Vec3| {
            let a = n - first * n.dot(&first);
            // A normal within about 6 degrees of the first axis sets no direction across it.
            (a.norm() > 0.1 * n.norm()).then(|| a.normalize())
        };
        let second = planes.iter().find_map(|p| across(p.normal())).unwrap_or_else(|| axes_across(&first).0);
        let third = first.cross(&second);
        LumenFrame { origin, axes: nalgebra::Matrix3::from_rows(&[first.transpose(), second.transpose(), third.transpose()]) }
    }

    fn to_local(&self, p: Vec3) -> Vec3 {
        self.axes * (p - self.origin)
    }

    fn to_world(&self, p: Vec3) -> Vec3 {
        self.axes.transpose() * p + self.origin
    }

    fn mesh_to_local(&self, mesh: &TriMesh) -> TriMesh {
        TriMesh { points: mesh.points.iter().map(|&p| self.to_local(p)).collect(), ..mesh.clone() }
    }

    fn plane_to_local(&self, plane: &MeasurementPlane) -> MeasurementPlane {
        MeasurementPlane { label: plane.label, triangles: plane.triangles.iter().map(|t| t.map(|p| self.to_local(p))).collect() }
    }

    fn lumen_to_local<'a>(&self, lumen: &Lumen, surface: &'a TriMesh) -> Lumen<'a> {
        Lumen {
            surface,
            open_labels: lumen.open_labels.clone(),
            inflow_seed: self.to_local(lumen.inflow_seed),
            outflow_seed: self.to_local(lumen.outflow_seed),
            planes: [self.plane_to_local(&lumen.planes[0]), self.plane_to_local(&lumen.planes[1])],
        }
    }
}

/// Steps 1-5 of the module's doc on a lumen in its own frame.
fn centerline_in_own_frame(lumen: &Lumen, opts: &CenterlineOptions) -> Result<FlowCenterline, String> {
    let mut clock = Clock { last: std::time::Instant::now(), laps: Vec::new() };
    let wall = WallDistance::new(lumen)?;
    let grid = lumen_grid(lumen.surface, opts.voxel_mm)?;
    let inside = voxelize(lumen.surface, &grid);
    clock.lap("voxelize");
    let radius = voxel_radii(&grid, &inside, &wall);
    let inside_voxels = radius.iter().filter(|&&r| r > 0.0).count();
    clock.lap("distance");
    let from = nearest_inside_voxel(&grid, &radius, lumen.inflow_seed).ok_or("no voxel inside the lumen")?;
    let to = nearest_inside_voxel(&grid, &radius, lumen.outflow_seed).ok_or("no voxel inside the lumen")?;
    let path = minimal_path(&grid, &radius, from, to).ok_or("the two ends are not connected inside the lumen")?;
    clock.lap("minimal_path");
    let h = grid.spacing_mm;
    let curve = moving_average(&resample(&path, h), (opts.smoothing_mm / h).round() as usize);
    // Re-centred and smoothed at a step tied to the output spacing, not to the grid:
    // a flat ridge leaves each point's maximum a little uncertain, and that jitter,
    // if taken per voxel, would lengthen the curve as the voxels shrink.
    let step = 0.5 * opts.spacing_mm;
    let mut curve = resample(&curve, step);
    for _ in 0..RECENTER_PASSES {
        curve = moving_average(&recenter(&curve, &wall, opts.recenter_fraction, h), (opts.smoothing_mm / step).round() as usize);
    }
    let trimmed = trim_between(&extend_ends(&curve, 4.0 * h + 1.0), &lumen.planes)?;
    let points = resample(&trimmed, opts.spacing_mm);
    let s_mm = arc_lengths(&points);
    let radius_mm = points.iter().map(|&p| wall.at(p)).collect();
    clock.lap("recenter_trim");
    Ok(FlowCenterline { length_mm: *s_mm.last().unwrap_or(&0.0), points, radius_mm, s_mm, voxel_mm: h, inside_voxels, timings_ms: clock.laps })
}

/// Half-width of the chord that gives a section plane's normal (mm): the smoothed path's
/// direction over about the tunnel's radius, not a point's local wobble.
const SECTION_TANGENT_HALF_WIDTH_MM: f64 = 1.0;

impl MeasurementPlane {
    /// Whether the plane through `origin` normal to `normal` crosses this disc (its
    /// corners on both sides).
    fn is_crossed_by(&self, origin: Vec3, normal: Vec3) -> bool {
        let sides = self.triangles.iter().flatten().map(|p| (p - origin).dot(&normal));
        let (lo, hi) = sides.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), d| (lo.min(d), hi.max(d)));
        lo < 0.0 && hi > 0.0
    }
}

/// Sections of the tunnel normal to the flow: at each centerline point, the area (mm2) of
/// the piece of the plane normal to the centerline inside `boundary` (the lumen's closed
/// wall and end caps, interior planes left out) that holds the point. None where the
/// plane crosses a measurement plane (near the VSD and aortic planes, which lie oblique to
/// the flow, it would measure part of the LV or aorta with the tunnel) or finds no inside.
/// The paper constrains sections normal to its PCHIP centerline between the cap centroids
/// (2.4.2); these are the flow's own, and can be smaller (issue 13: up to 25% on p3).
/// Each section is rastered in the line's own frame (`LumenFrame`), so that a rotated scene
/// gives the same areas.
pub fn flow_normal_sections(boundary: &TriMesh, points: &[Vec3], planes: &[MeasurementPlane]) -> Vec<Option<f64>> {
    sections_along(boundary, points, planes, |b, p, t| crate::geometry::plane_section::section_area(b, None, p, t))
}

/// [`flow_normal_sections`] with each section's shape (its aspect ratio) beside its area,
/// the same pieces' pixels (the design's area-only sections do not pay for the moments).
pub fn flow_normal_section_shapes(boundary: &TriMesh, points: &[Vec3], planes: &[MeasurementPlane]) -> Vec<Option<SectionShape>> {
    sections_along(boundary, points, planes, crate::geometry::plane_section::section_shape)
}

/// `measure(boundary, point, tangent)` at each point of the line, in the line's own frame.
fn sections_along<T: Send>(
    boundary: &TriMesh,
    points: &[Vec3],
    planes: &[MeasurementPlane],
    measure: impl Fn(&TriMesh, Vec3, Vec3) -> Option<T> + Sync,
) -> Vec<Option<T>> {
    let (Some(&first), Some(&last)) = (points.first(), points.last()) else { return Vec::new() };
    let frame = LumenFrame::new(first, last - first, planes);
    let boundary = frame.mesh_to_local(boundary);
    let points: Vec<Vec3> = points.iter().map(|&p| frame.to_local(p)).collect();
    let planes: Vec<MeasurementPlane> = planes.iter().map(|p| frame.plane_to_local(p)).collect();
    let s = arc_lengths(&points);
    (0..points.len())
        .into_par_iter()
        .map(|k| {
            // The chord over the half-width each side, at least to the neighbours.
            let before = s.iter().position(|&x| x >= s[k] - SECTION_TANGENT_HALF_WIDTH_MM).unwrap_or(k).min(k.saturating_sub(1));
            let after = s.iter().rposition(|&x| x <= s[k] + SECTION_TANGENT_HALF_WIDTH_MM).unwrap_or(k).max((k + 1).min(points.len().saturating_sub(1)));
            let tangent = (points[after] - points[before]).try_normalize(0.0)?;
            if planes.iter().any(|p| p.is_crossed_by(points[k], tangent)) {
                return None;
            }
            measure(&boundary, points[k], tangent)
        })
        .collect()
}

/// The smallest of the measured sections and its arc length (mm2, mm); None when none was measured.
pub fn smallest_section(s_mm: &[f64], areas: &[Option<f64>]) -> Option<(f64, f64)> {
    s_mm.iter().zip(areas).filter_map(|(&s, a)| Some(((*a)?, s))).min_by(|a, b| a.0.total_cmp(&b.0))
}

/// Wall time of each step (ms).
struct Clock {
    last: std::time::Instant,
    laps: Vec<(&'static str, f64)>,
}

impl Clock {
    fn lap(&mut self, name: &'static str) {
        let now = std::time::Instant::now();
        self.laps.push((name, (now - self.last).as_secs_f64() * 1e3));
        self.last = now;
    }
}

fn lumen_grid(surface: &TriMesh, voxel_mm: f64) -> Result<Grid, String> {
    if !(voxel_mm > 0.0) {
        return Err(format!("voxel size must be positive, got {voxel_mm}"));
    }
    let Aabb { min: lo, max: hi } = Aabb::from_points(&surface.points);
    let mut h = voxel_mm;
    loop {
        // Voxel centres off round coordinates: a cap plane exactly through a row of
        // centres lies on the silhouette of the wall's shadow, where column crossings
        // are not counted exactly (an axis-aligned test tube hits that).
        let mut grid = Grid::covering(lo, hi, h, 2);
        grid.origin -= h * Vec3::new(0.137, 0.291, 0.419);
        if grid.voxel_count() <= MAX_VOXELS {
            return Ok(grid);
        }
        h *= 1.25;
    }
}

/// Distance to the wall at every inside voxel centre; 0 outside.
fn voxel_radii(grid: &Grid, inside: &[bool], wall: &WallDistance) -> Vec<f32> {
    (0..inside.len())
        .into_par_iter()
        .map(|v| if inside[v] { wall.at(grid.centre(v)).max(1e-6) as f32 } else { 0.0 })
        .collect()
}

fn nearest_inside_voxel(grid: &Grid, radius: &[f32], seed: Vec3) -> Option<usize> {
    (0..radius.len()).filter(|&v| radius[v] > 0.0).min_by(|&a, &b| (grid.centre(a) - seed).norm_squared().total_cmp(&(grid.centre(b) - seed).norm_squared()))
}

/// Dijkstra over the 26-connected inside voxels, cost `|step| mean(1/R^2)`; the voxel
/// centres from `from` to `to`.
fn minimal_path(grid: &Grid, radius: &[f32], from: usize, to: usize) -> Option<Vec<Vec3>> {
    let inv_r2 = |v: usize| 1.0 / (radius[v] as f64 * radius[v] as f64);
    let search = best_first_search(grid, &[from], |w| radius[w] > 0.0, |c, v, w, len| c + len * 0.5 * (inv_r2(v) + inv_r2(w)), |v| v == to);
    search.reached?;
    Some(search.path_to(to).into_iter().map(|v| grid.centre(v)).collect())
}

pub fn arc_lengths(points: &[Vec3]) -> Vec<f64> {
    let mut s = vec![0.0];
    for w in points.windows(2) {
        s.push(s.last().unwrap() + (w[1] - w[0]).norm());
    }
    s
}

/// The polyline through `points` at equal arc-length steps no longer than `step`,
/// both ends kept.
pub fn resample(points: &[Vec3], step: f64) -> Vec<Vec3> {
    let s = arc_lengths(points);
    let length = *s.last().unwrap_or(&0.0);
    if points.len() < 2 || length == 0.0 {
        return points.to_vec();
    }
    let n = (length / step).ceil().max(1.0) as usize;
    let mut out = Vec::with_capacity(n + 1);
    let mut k = 0;
    for i in 0..=n {
        let target = length * i as f64 / n as f64;
        while k + 2 < s.len() && s[k + 1] < target {
            k += 1;
        }
        let f = ((target - s[k]) / (s[k + 1] - s[k]).max(1e-300)).clamp(0.0, 1.0);
        out.push(points[k] + f * (points[k + 1] - points[k]));
    }
    out
}

/// Centred moving average over `2 half + 1` points, narrowed near the ends so that
/// the ends stay where they are.
pub(crate) fn moving_average(points: &[Vec3], half: usize) -> Vec<Vec3> {
    let n = points.len();
    (0..n)
        .map(|i| {
            let w = half.min(i).min(n - 1 - i);
            points[i - w..=i + w].iter().sum::<Vec3>() / (2 * w + 1) as f64
        })
        .collect()
}

/// Move each point, by at most `fraction` of its inscribed radius in the plane normal
/// to the curve, to where the wall is farthest (compass search from step `h`). The
/// bound scales with the lumen: in a wide chamber the medial ridge is flat and a bound
/// tied to the voxel would leave the result depending on the grid.
fn recenter(points: &[Vec3], wall: &WallDistance, fraction: f64, h: f64) -> Vec<Vec3> {
    let n = points.len();
    if n < 2 {
        return points.to_vec();
    }
    (0..n)
        .into_par_iter()
        .map(|i| {
            // One-sided at the ends: they are re-centred too (in their cap's region the
            // caps are not wall, so the largest R is still the lumen's centre).
            let t = (points[(i + 1).min(n - 1)] - points[i.saturating_sub(1)]).normalize();
            let (u, v) = axes_across(&t);
            compass_search(points[i], [u, v], |p| wall.at(p), fraction * wall.at(points[i]), h)
        })
        .collect()
}

/// Maximize `f` over `origin + a u + b v`, |(a, b)| <= `max_shift`.
fn compass_search(origin: Vec3, [u, v]: [Vec3; 2], f: impl Fn(Vec3) -> f64, max_shift: f64, h: f64) -> Vec3 {
    let directions = [u, -u, v, -v, (u + v) / 2f64.sqrt(), (u - v) / 2f64.sqrt(), (-u + v) / 2f64.sqrt(), (-u - v) / 2f64.sqrt()];
    let (mut p, mut best) = (origin, f(origin));
    let mut step = h;
    while step > RECENTER_TOLERANCE_MM {
        let candidate = directions.iter().map(|d| p + step * d).filter(|q| (q - origin).norm() <= max_shift).map(|q| (q, f(q))).max_by(|a, b| a.1.total_cmp(&b.1));
        match candidate {
            Some((q, value)) if value > best => (p, best) = (q, value),
            _ => step *= 0.5,
        }
    }
    p
}

/// The curve with a straight piece of `length` added at each end along its end tangent
/// (so that an end just short of a cap still meets it).
fn extend_ends(points: &[Vec3], length: f64) -> Vec<Vec3> {
    let n = points.len();
    if n < 2 {
        return points.to_vec();
    }
    // Tangents over a few points (about 0.75 mm), steadier than the last segment alone.
    let k = 3.min(n - 1);
    let start = (points[0] - points[k]).normalize();
    let end = (points[n - 1] - points[n - 1 - k]).normalize();
    let mut out = vec![points[0] + length * start];
    out.extend_from_slice(points);
    out.push(points[n - 1] + length * end);
    out
}

/// The part of the polyline between the measurement planes: from the last crossing of
/// the first plane before the first crossing of the second.
fn trim_between(points: &[Vec3], planes: &[MeasurementPlane; 2]) -> Result<Vec<Vec3>, String> {
    let s = arc_lengths(points);
    let crossings = |plane: &MeasurementPlane| -> Vec<f64> {
        let mut c = Vec::new();
        for (k, w) in points.windows(2).enumerate() {
            c.extend(plane.crossings(w[0], w[1]).map(|t| s[k] + t * (s[k + 1] - s[k])));
        }
        c.sort_by(f64::total_cmp);
        c
    };
    let (a, b) = (crossings(&planes[0]), crossings(&planes[1]));
    let s_b = *b.first().ok_or_else(|| format!("the centerline does not cross measurement plane {}", planes[1].label))?;
    let s_a = *a.iter().filter(|&&x| x < s_b).last().ok_or_else(|| format!("the centerline does not cross measurement plane {} before plane {}", planes[0].label, planes[1].label))?;
    let at = |target: f64| {
        let k = s.partition_point(|&x| x <= target).clamp(1, s.len() - 1) - 1;
        let f = ((target - s[k]) / (s[k + 1] - s[k]).max(1e-300)).clamp(0.0, 1.0);
        points[k] + f * (points[k + 1] - points[k])
    };
    let mut out = vec![at(s_a)];
    out.extend((0..points.len()).filter(|&k| s[k] > s_a && s[k] < s_b).map(|k| points[k]));
    out.push(at(s_b));
    Ok(out)
}

#[cfg(test)]
mod tests;
