//! Synthetic "capped ventricle" phantom: an analytic stand-in for the design input
//! (`design_input/capped_ventricle.vtp` + suture points) that tests can tune.
//!
//! The pathway is a curved tube: its centerline is an arc of a circle in the z = 0
//! plane, centred on the origin, starting at (R, 0, 0) (VSD end, sweep angle 0) and
//! sweeping counter-clockwise about +z to the aortic end. Each cross-section is an
//! ellipse in the plane spanned by the outward radial direction (away from the bend
//! centre, section angle 0) and +z (section angle +90 degrees); its semi-axes blend
//! smoothly from the VSD values to the aortic values. Planar caps close both ends.
//! The suture loop sits on the outer side of the bend and encloses most of the wall
//! between the caps, like the old baffle region in the real data.

use crate::geometry::mesh::{FaceLabels, TriMesh, Vec3};
use std::f64::consts::{PI, TAU};

/// Shape, resolution and suture loop of the phantom.
#[derive(Clone, Debug, PartialEq)]
pub struct PhantomParams {
    /// Radius of the centerline arc (mm). Must exceed both in-plane semi-axes.
    pub bend_radius_mm: f64,
    /// Angle the centerline sweeps from the VSD cap to the aortic cap (degrees).
    pub sweep_angle_deg: f64,
    /// VSD-end cross-section semi-axes (mm): (in the bend plane, along +z).
    pub vsd_semi_axes_mm: (f64, f64),
    /// Aortic-end cross-section semi-axes (mm): (in the bend plane, along +z).
    pub aortic_semi_axes_mm: (f64, f64),
    /// Target triangle edge length (mm).
    pub edge_length_mm: f64,
    /// Number of suture points on the loop.
    pub suture_point_count: usize,
    /// Wall distance (mm) from each cap rim to the loop's closest point, measured
    /// along the outermost line of the wall.
    pub suture_rim_margin_mm: f64,
    /// Half-width of the loop around the outer side of the bend, as a section
    /// angle (degrees); 0 is the outermost line of the wall.
    pub suture_half_angle_deg: f64,
    /// Each suture point is moved along the wall by up to this fraction of the point
    /// spacing, in both directions on the wall (a surgeon's uneven hand); 0 = none.
    pub suture_jitter_fraction: f64,
    /// Seed of that jitter (the same seed gives the same points).
    pub suture_jitter_seed: u64,
    /// Patient body surface area (m^2) the phantom claims to belong to.
    pub bsa_m2: f64,
    /// `ModelFaceID`s to write (wall, VSD cap, aortic cap are used).
    pub labels: FaceLabels,
}

impl Default for PhantomParams {
    fn default() -> Self {
        PhantomParams {
            bend_radius_mm: 12.0,
            sweep_angle_deg: 95.0,
            vsd_semi_axes_mm: (5.6, 4.4),
            aortic_semi_axes_mm: (5.4, 4.3),
            edge_length_mm: 0.8,
            suture_point_count: 14,
            suture_rim_margin_mm: 1.2,
            suture_half_angle_deg: 70.0,
            suture_jitter_fraction: 0.0,
            suture_jitter_seed: 0,
            bsa_m2: 0.37,
            labels: FaceLabels::default(),
        }
    }
}

/// The phantom: closed outward-wound surface (wall + two caps) and suture loop.
#[derive(Clone, Debug, PartialEq)]
pub struct Phantom {
    pub surface: TriMesh,
    /// Points exactly on the analytic wall, in loop order, counter-clockwise seen
    /// from outside the surface; the first one is the loop's point nearest the VSD cap.
    pub suture_points_mm: Vec<Vec3>,
    pub bsa_m2: f64,
}

/// Smallest edge length honoured, so silly inputs cannot ask for billions of points.
const MIN_EDGE_LENGTH_MM: f64 = 0.05;
/// Upper bound on any per-direction vertex count, for the same reason.
const MAX_COUNT: usize = 4096;
/// Superellipse exponent of the suture loop in (sweep, section) angles: 4 gives
/// long straight-ish sides with rounded corners, like a surgeon's seam.
const SUTURE_LOOP_EXPONENT: f64 = 4.0;
/// Samples used to measure the loop's length when spacing the suture points.
const SUTURE_LOOP_SAMPLES: usize = 1024;
/// Segments of the tables that map ellipse arc-length fractions to angles.
const ARC_TABLE_SEGMENTS: usize = 64;

impl PhantomParams {
    /// Why the parameters do not describe a sensible phantom, if they do not.
    pub fn check(&self) -> Result<(), String> {
        let positive = [
            ("bend_radius_mm", self.bend_radius_mm),
            ("sweep_angle_deg", self.sweep_angle_deg),
            ("vsd_semi_axes_mm.0", self.vsd_semi_axes_mm.0),
            ("vsd_semi_axes_mm.1", self.vsd_semi_axes_mm.1),
            ("aortic_semi_axes_mm.0", self.aortic_semi_axes_mm.0),
            ("aortic_semi_axes_mm.1", self.aortic_semi_axes_mm.1),
            ("edge_length_mm", self.edge_length_mm),
            ("suture_half_angle_deg", self.suture_half_angle_deg),
        ];
        for (name, value) in positive {
            if !(value.is_finite() && value > 0.0) {
                return Err(format!("{name} must be positive and finite, got {value}"));
            }
        }
        if self.sweep_angle_deg >= 360.0 {
            return Err("sweep_angle_deg must be below 360 (the tube would overlap itself)".into());
        }
        if self.vsd_semi_axes_mm.0.max(self.aortic_semi_axes_mm.0) >= self.bend_radius_mm {
            return Err("in-plane semi-axes must be smaller than bend_radius_mm".into());
        }
        if self.suture_half_angle_deg >= 180.0 {
            return Err("suture_half_angle_deg must be below 180".into());
        }
        if self.suture_point_count < 3 {
            return Err("suture_point_count must be at least 3".into());
        }
        let margin_sweep = self.vsd_margin_sweep_rad() + self.aortic_margin_sweep_rad();
        if !(self.suture_rim_margin_mm >= 0.0 && margin_sweep < self.sweep_angle_rad()) {
            return Err("suture_rim_margin_mm must be non-negative and leave room for the loop".into());
        }
        Ok(())
    }

    pub fn sweep_angle_rad(&self) -> f64 {
        self.sweep_angle_deg.to_radians()
    }

    /// Cross-section semi-axes (mm) at `sweep_fraction` (0 VSD end, 1 aortic end).
    /// Smoothstep blend: zero slope at both caps, so the caps meet the wall squarely.
    pub fn semi_axes_mm(&self, sweep_fraction: f64) -> (f64, f64) {
        let u = sweep_fraction.clamp(0.0, 1.0);
        let w = u * u * (3.0 - 2.0 * u);
        let (v, a) = (self.vsd_semi_axes_mm, self.aortic_semi_axes_mm);
        (v.0 + w * (a.0 - v.0), v.1 + w * (a.1 - v.1))
    }

    /// Analytic area (mm^2) of the planar cross-section at `sweep_fraction`.
    pub fn cross_section_area_mm2(&self, sweep_fraction: f64) -> f64 {
        let (a, b) = self.semi_axes_mm(sweep_fraction);
        PI * a * b
    }

    pub fn centerline_length_mm(&self) -> f64 {
        self.bend_radius_mm * self.sweep_angle_rad()
    }

    /// Straight-line distance (mm) between the VSD and aortic cap centres.
    pub fn vsd_to_aorta_distance_mm(&self) -> f64 {
        2.0 * self.bend_radius_mm * (0.5 * self.sweep_angle_rad()).sin()
    }

    /// Point (mm) of the analytic wall at sweep angle `sweep_rad` and section angle
    /// `section_rad` (0 = outer side of the bend, +pi/2 = +z).
    pub fn wall_point_mm(&self, sweep_rad: f64, section_rad: f64) -> Vec3 {
        let (a, b) = self.semi_axes_mm(sweep_rad / self.sweep_angle_rad());
        self.section_point_mm(sweep_rad, a * section_rad.cos(), b * section_rad.sin())
    }

    /// Point (mm) at in-plane offset `radial_mm` (away from the bend centre) and
    /// out-of-plane offset `z_mm` from the centerline at `sweep_rad`.
    fn section_point_mm(&self, sweep_rad: f64, radial_mm: f64, z_mm: f64) -> Vec3 {
        let radius = self.bend_radius_mm + radial_mm;
        Vec3::new(radius * sweep_rad.cos(), radius * sweep_rad.sin(), z_mm)
    }

    /// Sweep angle (rad) that the rim margin spans on the outermost wall line, VSD end.
    fn vsd_margin_sweep_rad(&self) -> f64 {
        self.suture_rim_margin_mm / (self.bend_radius_mm + self.vsd_semi_axes_mm.0)
    }

    fn aortic_margin_sweep_rad(&self) -> f64 {
        self.suture_rim_margin_mm / (self.bend_radius_mm + self.aortic_semi_axes_mm.0)
    }

    /// Edge length actually used: the requested one, kept above a floor.
    fn effective_edge_length_mm(&self) -> f64 {
        self.edge_length_mm.max(MIN_EDGE_LENGTH_MM)
    }
}

/// The phantom for `params`. Never panics; nonsense parameters (see
/// [`PhantomParams::check`]) give a nonsense but bounded-size mesh.
pub fn phantom(params: &PhantomParams) -> Phantom {
    Phantom { surface: capped_tube(params), suture_points_mm: suture_points_mm(params), bsa_m2: params.bsa_m2 }
}

/// The phantom with [`PhantomParams::default`].
/// The default phantom with its suture loop wrapped `half_angle_deg` round the tunnel
/// from the outermost line (default 70), or why that angle makes no phantom.
pub fn phantom_with_suture_half_angle(half_angle_deg: f64) -> Result<Phantom, String> {
    let params = PhantomParams { suture_half_angle_deg: half_angle_deg, ..PhantomParams::default() };
    params.check()?;
    Ok(phantom(&params))
}

pub fn phantom_default() -> Phantom {
    phantom(&PhantomParams::default())
}

// ---------------------------------------------------------------------------
// Surface

/// A mesh vertex and its position along the strip or ring it belongs to (sweep
/// fraction for wall columns, arc-length fraction for cap rings).
#[derive(Clone, Copy, Debug)]
struct Node {
    id: u32,
    position: f64,
}

/// Wall columns run along the tube at fixed arc-length fraction of the cross-section
/// (so columns are evenly spaced around it); their lengths differ a lot between the
/// inner and outer side of the bend, so each column gets its own vertex count and
/// neighbouring columns are zipped together. That keeps triangles near-equilateral
/// where planar rings would stretch them on the outer side.
fn capped_tube(params: &PhantomParams) -> TriMesh {
    let mut mesh = TriMesh::default();
    let arc_table = ArcTable::new();
    let column_count = wall_column_count(params);
    let columns: Vec<Vec<Node>> =
        (0..column_count).map(|j| wall_column(params, &arc_table, j, column_count, &mut mesh)).collect();
    for j in 0..column_count {
        let next = &columns[(j + 1) % column_count];
        stitch(&columns[j], next, false, params.labels.wall, &mut mesh);
    }
    let vsd_rim: Vec<u32> = columns.iter().filter_map(|c| c.first().map(|n| n.id)).collect();
    let aortic_rim: Vec<u32> = columns.iter().filter_map(|c| c.last().map(|n| n.id)).collect();
    let vsd_cap = CapSpec { sweep_fraction: 0.0, label: params.labels.vsd_cap, flip: false };
    let aortic_cap = CapSpec { sweep_fraction: 1.0, label: params.labels.aortic_cap, flip: true };
    add_cap(params, &arc_table, &vsd_rim, &vsd_cap, &mut mesh);
    add_cap(params, &arc_table, &aortic_rim, &aortic_cap, &mut mesh);
    mesh
}

/// Even number of columns around the tube, spaced one equilateral-triangle height
/// apart on the mid-tube perimeter.
fn wall_column_count(params: &PhantomParams) -> usize {
    let (a, b) = params.semi_axes_mm(0.5);
    let spacing_mm = params.effective_edge_length_mm() * 3f64.sqrt() / 2.0;
    let half = (ellipse_perimeter_mm(a, b) / spacing_mm / 2.0).round();
    2 * clamp_count(half, 3, MAX_COUNT / 2)
}

/// Creates the vertices of wall column `j` (VSD rim to aortic rim) and returns them.
fn wall_column(
    params: &PhantomParams,
    arc_table: &ArcTable,
    j: usize,
    column_count: usize,
    mesh: &mut TriMesh,
) -> Vec<Node> {
    let arc_fraction = j as f64 / column_count as f64;
    let sweep_rad = params.sweep_angle_rad();
    let (a_mid, b_mid) = params.semi_axes_mm(0.5);
    let mid_section_rad = arc_table.angle_at_fraction(a_mid, b_mid, arc_fraction);
    // Length of the column, approximated on the mid-tube ellipse.
    let length_mm = sweep_rad * (params.bend_radius_mm + a_mid * mid_section_rad.cos());
    let segments = clamp_count((length_mm / params.effective_edge_length_mm()).round(), 1, MAX_COUNT);
    column_fractions(segments, j % 2 == 1)
        .into_iter()
        .map(|f| {
            let (a, b) = params.semi_axes_mm(f);
            let section_rad = arc_table.angle_at_fraction(a, b, arc_fraction);
            let point = params.section_point_mm(f * sweep_rad, a * section_rad.cos(), b * section_rad.sin());
            Node { id: push_point(mesh, point), position: f }
        })
        .collect()
}

/// Sweep fractions of a column's vertices: `segments` equal steps, or, when
/// `staggered`, the same steps shifted by half (half steps at both ends) so
/// neighbouring columns interleave into equilateral-ish triangles.
fn column_fractions(segments: usize, staggered: bool) -> Vec<f64> {
    let n = segments as f64;
    if !staggered {
        return (0..=segments).map(|k| k as f64 / n).collect();
    }
    let mut fractions = vec![0.0];
    fractions.extend((0..segments).map(|k| (k as f64 + 0.5) / n));
    fractions.push(1.0);
    fractions
}

struct CapSpec {
    sweep_fraction: f64,
    label: i32,
    /// Reverse triangles: the unflipped winding faces towards decreasing sweep angle.
    flip: bool,
}

/// Closes one tube end with a planar cap made of concentric scaled ellipses, the
/// outermost being the tube's own rim vertices.
fn add_cap(params: &PhantomParams, arc_table: &ArcTable, rim: &[u32], cap: &CapSpec, mesh: &mut TriMesh) {
    let rim_count = rim.len();
    if rim_count < 3 {
        return;
    }
    let (a, b) = params.semi_axes_mm(cap.sweep_fraction);
    let sweep_rad = cap.sweep_fraction * params.sweep_angle_rad();
    // Rings one equilateral-triangle height apart, measured with the rim spacing.
    let rim_spacing_mm = ellipse_perimeter_mm(a, b) / rim_count as f64;
    let ring_count = clamp_count(((a * b).sqrt() / (rim_spacing_mm * 3f64.sqrt() / 2.0)).round(), 1, MAX_COUNT);
    let mut outer: Vec<Node> =
        rim.iter().enumerate().map(|(i, &id)| Node { id, position: i as f64 / rim_count as f64 }).collect();
    close_ring(&mut outer);
    for k in (1..ring_count).rev() {
        let scale = k as f64 / ring_count as f64;
        let count = clamp_count((rim_count as f64 * scale).round(), 3, MAX_COUNT);
        // Alternate rings are shifted half a step so triangles interleave.
        let offset = if (ring_count - k) % 2 == 1 { 0.5 } else { 0.0 };
        let mut inner: Vec<Node> = (0..count)
            .map(|i| {
                let position = (i as f64 + offset) / count as f64;
                let section_rad = arc_table.angle_at_fraction(a, b, position);
                let point =
                    params.section_point_mm(sweep_rad, scale * a * section_rad.cos(), scale * b * section_rad.sin());
                Node { id: push_point(mesh, point), position }
            })
            .collect();
        close_ring(&mut inner);
        stitch(&outer, &inner, cap.flip, cap.label, mesh);
        outer = inner;
    }
    let centre = Node { id: push_point(mesh, params.section_point_mm(sweep_rad, 0.0, 0.0)), position: 0.0 };
    stitch(&outer, &[centre], cap.flip, cap.label, mesh);
}

/// Repeats a ring's first node at the end, one full turn further along.
fn close_ring(ring: &mut Vec<Node>) {
    if let Some(&first) = ring.first() {
        ring.push(Node { id: first.id, position: first.position + 1.0 });
    }
}

/// Triangulates the strip between polylines `a` and `b` that run side by side and
/// share their start and end sections. Each step advances the side whose new
/// cross edge is shorter (the Delaunay-like choice, which avoids slivers where
/// the two sides' steps drift out of phase). Unflipped, triangle (a[i], a[i+1],
/// b[j]) has the normal a-direction x (b - a), which is outward for wall columns
/// and for caps seen from -sweep.
fn stitch(a: &[Node], b: &[Node], flip: bool, label: i32, mesh: &mut TriMesh) {
    if a.is_empty() || b.is_empty() {
        return;
    }
    let (mut i, mut j) = (0, 0);
    while i + 1 < a.len() || j + 1 < b.len() {
        let advance_a = j + 1 == b.len() || (i + 1 < a.len() && shorter_to_advance_a(mesh, a, b, i, j));
        let triangle = if advance_a {
            i += 1;
            [a[i - 1].id, a[i].id, b[j].id]
        } else {
            j += 1;
            [a[i].id, b[j].id, b[j - 1].id]
        };
        let triangle = if flip { [triangle[0], triangle[2], triangle[1]] } else { triangle };
        mesh.triangles.push(triangle);
        mesh.face_ids.push(label);
    }
}

/// Whether cross edge (a[i+1], b[j]) is shorter than (a[i], b[j+1]); ties go to
/// the side whose next node comes first along the strip, so the result is symmetric.
fn shorter_to_advance_a(mesh: &TriMesh, a: &[Node], b: &[Node], i: usize, j: usize) -> bool {
    let point = |node: &Node| mesh.points[node.id as usize];
    let via_a = (point(&a[i + 1]) - point(&b[j])).norm_squared();
    let via_b = (point(&a[i]) - point(&b[j + 1])).norm_squared();
    if via_a != via_b {
        return via_a < via_b;
    }
    a[i + 1].position <= b[j + 1].position
}

fn push_point(mesh: &mut TriMesh, point: Vec3) -> u32 {
    mesh.points.push(point);
    (mesh.points.len() - 1) as u32
}

/// `value` rounded to a count in [min, max]; NaN gives `min`.
fn clamp_count(value: f64, min: usize, max: usize) -> usize {
    if value.is_nan() {
        return min;
    }
    (value.max(0.0).min(max as f64) as usize).clamp(min, max)
}

/// Ramanujan's approximation of an ellipse's perimeter (mm); plenty for spacing.
fn ellipse_perimeter_mm(a: f64, b: f64) -> f64 {
    PI * (3.0 * (a + b) - ((3.0 * a + b) * (a + 3.0 * b)).sqrt())
}

/// Maps a fraction of an ellipse's perimeter to its parametric angle, so vertices
/// spaced evenly in that fraction are spaced evenly along the ellipse. The squared
/// sines and cosines of the sample angles are shared by every ellipse.
struct ArcTable {
    sin2: Vec<f64>,
    cos2: Vec<f64>,
}

impl ArcTable {
    fn new() -> Self {
        let step = TAU / ARC_TABLE_SEGMENTS as f64;
        let mid_angles = (0..ARC_TABLE_SEGMENTS).map(|k| (k as f64 + 0.5) * step);
        let (sin2, cos2) = mid_angles.map(|t| (t.sin().powi(2), t.cos().powi(2))).unzip();
        ArcTable { sin2, cos2 }
    }

    /// Parametric angle (rad, in [0, 2 pi]) of the point a `fraction` of the way
    /// round ellipse (a cos t, b sin t), measured by arc length from t = 0.
    fn angle_at_fraction(&self, a: f64, b: f64, fraction: f64) -> f64 {
        let mut cumulative = [0.0; ARC_TABLE_SEGMENTS + 1];
        for k in 0..ARC_TABLE_SEGMENTS {
            let speed = (a * a * self.sin2[k] + b * b * self.cos2[k]).sqrt();
            cumulative[k + 1] = cumulative[k] + speed;
        }
        let target = fraction.clamp(0.0, 1.0) * cumulative[ARC_TABLE_SEGMENTS];
        let k = cumulative.partition_point(|&c| c <= target).clamp(1, ARC_TABLE_SEGMENTS) - 1;
        let segment = cumulative[k + 1] - cumulative[k];
        let within = if segment > 0.0 { ((target - cumulative[k]) / segment).clamp(0.0, 1.0) } else { 0.0 };
        (k as f64 + within) * TAU / ARC_TABLE_SEGMENTS as f64
    }
}

// ---------------------------------------------------------------------------
// Suture loop

/// Suture points evenly spaced by 3D arc length along a superellipse loop in
/// (sweep, section) angles on the outer side of the bend.
fn suture_points_mm(params: &PhantomParams) -> Vec<Vec3> {
    let count = params.suture_point_count.min(MAX_COUNT);
    let cumulative_mm = suture_loop_cumulative_mm(params);
    let loop_length_mm = cumulative_mm[cumulative_mm.len() - 1];
    let spacing_mm = loop_length_mm / count.max(1) as f64;
    let mut jitter = crate::geometry::numerics::random::SplitMix64::new(params.suture_jitter_seed);
    (0..count)
        .map(|i| {
            let target_mm = loop_length_mm * i as f64 / count as f64;
            let loop_param = loop_param_at_length(&cumulative_mm, target_mm);
            let (sweep, section) = suture_loop_angles(params, loop_param);
            // Jitter in wall angles: the point stays exactly on the analytic wall.
            let along_mm = params.suture_jitter_fraction * spacing_mm * jitter.symmetric_unit();
            let across_mm = params.suture_jitter_fraction * spacing_mm * jitter.symmetric_unit();
            let (a, b) = params.semi_axes_mm(sweep / params.sweep_angle_rad());
            // Clamped to the loop's own sweep range, so the rim margins still hold.
            let (sweep_lo, sweep_hi) = suture_sweep_range(params);
            // max-then-min, not clamp: nonsense parameters (lo > hi) must not panic.
            let sweep = (sweep + along_mm / (params.bend_radius_mm + a * section.cos())).max(sweep_lo).min(sweep_hi);
            params.wall_point_mm(sweep, section + across_mm / a.min(b))
        })
        .collect()
}

/// Cumulative 3D arc length (mm) at the suture loop's evenly spaced parameter samples.
fn suture_loop_cumulative_mm(params: &PhantomParams) -> Vec<f64> {
    let samples: Vec<Vec3> = (0..=SUTURE_LOOP_SAMPLES)
        .map(|k| suture_loop_point_mm(params, TAU * k as f64 / SUTURE_LOOP_SAMPLES as f64))
        .collect();
    let mut cumulative_mm = vec![0.0];
    for pair in samples.windows(2) {
        let last = cumulative_mm[cumulative_mm.len() - 1];
        cumulative_mm.push(last + (pair[1] - pair[0]).norm());
    }
    cumulative_mm
}

impl PhantomParams {
    /// Length of the analytic suture loop the points are spaced along (mm): the seam the
    /// surgeon's points describe, before their jitter.
    pub fn suture_loop_length_mm(&self) -> f64 {
        suture_loop_cumulative_mm(self).last().copied().unwrap_or(0.0)
    }
}

/// Loop parameter (rad) where the sampled loop's arc length reaches `target_mm`.
fn loop_param_at_length(cumulative_mm: &[f64], target_mm: f64) -> f64 {
    let segments = cumulative_mm.len().saturating_sub(1).max(1);
    let k = cumulative_mm.partition_point(|&c| c <= target_mm).clamp(1, segments) - 1;
    let (start, end) = (cumulative_mm[k], cumulative_mm.get(k + 1).copied().unwrap_or(cumulative_mm[k]));
    let within = if end > start { ((target_mm - start) / (end - start)).clamp(0.0, 1.0) } else { 0.0 };
    TAU * (k as f64 + within) / segments as f64
}

/// Loop point at parameter `t` (rad). t = 0 is the point nearest the VSD cap, on
/// the outermost wall line; increasing t runs counter-clockwise seen from outside.
fn suture_loop_point_mm(params: &PhantomParams, t: f64) -> Vec3 {
    let (sweep, section) = suture_loop_angles(params, t);
    params.wall_point_mm(sweep, section)
}

/// (sweep, section) angles (rad) of the loop at parameter `t`.
fn suture_loop_angles(params: &PhantomParams, t: f64) -> (f64, f64) {
    let (sweep_lo, sweep_hi) = suture_sweep_range(params);
    let (sweep_mid, sweep_half) = (0.5 * (sweep_lo + sweep_hi), 0.5 * (sweep_hi - sweep_lo));
    let section_half = params.suture_half_angle_deg.to_radians();
    // (-cos, -sin) in (sweep, section) is counter-clockwise in that order, and the
    // wall's outward normal is d(sweep) x d(section).
    let sweep = sweep_mid - sweep_half * superellipse_coordinate(t.cos());
    let section = -section_half * superellipse_coordinate(t.sin());
    (sweep, section)
}

/// The sweep angles (rad) the loop spans: the rim margins inside each cap.
fn suture_sweep_range(params: &PhantomParams) -> (f64, f64) {
    (params.vsd_margin_sweep_rad(), params.sweep_angle_rad() - params.aortic_margin_sweep_rad())
}

/// Maps a unit-circle coordinate onto the superellipse |x|^p + |y|^p = 1.
fn superellipse_coordinate(c: f64) -> f64 {
    c.signum() * c.abs().powf(2.0 / SUTURE_LOOP_EXPONENT)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::mesh::manifold_report;
    use crate::geometry::spatial::closest_point_on_triangle;
    use std::collections::BTreeSet;

    /// Distance (mm) from `p` to the mesh and the label of the nearest triangle.
    fn distance_to_mesh_mm(mesh: &TriMesh, p: Vec3) -> (f64, i32) {
        (0..mesh.triangles.len())
            .map(|t| {
                let (closest, _) = closest_point_on_triangle(&p, &mesh.triangle_points(t));
                ((p - closest).norm(), mesh.face_ids[t])
            })
            .fold((f64::INFINITY, -1), |best, cur| if cur.0 < best.0 { cur } else { best })
    }

    fn label_area_mm2(mesh: &TriMesh, label: i32) -> f64 {
        (0..mesh.triangles.len()).filter(|&t| mesh.face_ids[t] == label).map(|t| mesh.triangle_area_mm2(t)).sum()
    }

    fn smallest_angle_deg(mesh: &TriMesh, t: usize) -> f64 {
        let p = mesh.triangle_points(t);
        (0..3)
            .map(|k| {
                let (u, v) = (p[(k + 1) % 3] - p[k], p[(k + 2) % 3] - p[k]);
                u.angle(&v).to_degrees()
            })
            .fold(f64::INFINITY, f64::min)
    }

    fn assert_closed_outward(mesh: &TriMesh) {
        let report = manifold_report(mesh);
        assert!(report.is_closed_manifold(), "{report:?}");
        assert_eq!(report.inconsistently_wound_edges, 0, "{report:?}");
        assert!(mesh.signed_volume_mm3() > 0.0);
    }

    #[test]
    fn default_params_are_valid() {
        assert_eq!(PhantomParams::default().check(), Ok(()));
    }

    #[test]
    fn default_is_closed_manifold_and_outward() {
        assert_closed_outward(&phantom_default().surface);
    }

    #[test]
    fn other_shapes_and_resolutions_are_closed_manifold_and_outward() {
        let variants = [
            PhantomParams { edge_length_mm: 0.5, ..Default::default() },
            PhantomParams { edge_length_mm: 1.3, ..Default::default() },
            PhantomParams { sweep_angle_deg: 45.0, bend_radius_mm: 20.0, ..Default::default() },
            PhantomParams { vsd_semi_axes_mm: (3.0, 5.0), aortic_semi_axes_mm: (5.5, 2.5), ..Default::default() },
        ];
        for params in &variants {
            assert_eq!(params.check(), Ok(()));
            let mesh = phantom(params).surface;
            assert_closed_outward(&mesh);
            let worst_deg =
                (0..mesh.triangles.len()).map(|t| smallest_angle_deg(&mesh, t)).fold(f64::INFINITY, f64::min);
            assert!(worst_deg > 20.0, "{params:?}: smallest triangle angle {worst_deg} deg");
        }
    }

    #[test]
    fn volume_matches_pappus() {
        // Each elliptic slice's centroid lies on the centerline, so the enclosed
        // volume is R times the integral of the section area over the sweep angle.
        let params = PhantomParams::default();
        let steps = 1000;
        let integral: f64 =
            (0..steps).map(|k| params.cross_section_area_mm2((k as f64 + 0.5) / steps as f64)).sum::<f64>()
                / steps as f64;
        let expected_mm3 = params.bend_radius_mm * params.sweep_angle_rad() * integral;
        let volume_mm3 = phantom(&params).surface.signed_volume_mm3();
        assert!((volume_mm3 / expected_mm3 - 1.0).abs() < 0.02, "{volume_mm3} vs {expected_mm3}");
    }

    #[test]
    fn labels_are_wall_and_two_caps() {
        let mesh = phantom_default().surface;
        let labels: BTreeSet<i32> = mesh.face_ids.iter().copied().collect();
        assert_eq!(labels, BTreeSet::from([2, 11, 16]));
        assert_eq!(mesh.face_ids.len(), mesh.triangles.len());
    }

    #[test]
    fn cap_areas_match_analytic_ellipses() {
        let params = PhantomParams::default();
        let mesh = phantom(&params).surface;
        for (label, fraction) in [(11, 0.0), (16, 1.0)] {
            let expected_mm2 = params.cross_section_area_mm2(fraction);
            let area_mm2 = label_area_mm2(&mesh, label);
            assert!((area_mm2 / expected_mm2 - 1.0).abs() < 0.01, "label {label}: {area_mm2} vs {expected_mm2}");
        }
    }

    #[test]
    fn caps_are_planar_and_face_outward() {
        let params = PhantomParams::default();
        let mesh = phantom(&params).surface;
        let sweep = params.sweep_angle_rad();
        // Outward normals: -tangent at the VSD end, +tangent at the aortic end.
        let expected = [(11, Vec3::new(0.0, -1.0, 0.0)), (16, Vec3::new(-sweep.sin(), sweep.cos(), 0.0))];
        for (label, outward) in expected {
            for t in (0..mesh.triangles.len()).filter(|&t| mesh.face_ids[t] == label) {
                let normal = mesh.triangle_normal2(t).normalize();
                assert!(normal.dot(&outward) > 1.0 - 1e-9, "label {label} triangle {t}: {normal:?}");
            }
        }
    }

    #[test]
    fn suture_points_lie_on_the_wall() {
        let p = phantom_default();
        assert_eq!(p.suture_points_mm.len(), 14);
        for (i, &point) in p.suture_points_mm.iter().enumerate() {
            let (distance_mm, label) = distance_to_mesh_mm(&p.surface, point);
            assert!(distance_mm < 0.1, "suture point {i} is {distance_mm} mm from the mesh");
            assert_eq!(label, 2, "suture point {i} is nearest a cap");
        }
    }

    #[test]
    fn suture_points_are_evenly_spaced() {
        let points = phantom_default().suture_points_mm;
        let gaps_mm: Vec<f64> =
            (0..points.len()).map(|i| (points[(i + 1) % points.len()] - points[i]).norm()).collect();
        let shortest = gaps_mm.iter().copied().fold(f64::INFINITY, f64::min);
        let longest = gaps_mm.iter().copied().fold(0.0, f64::max);
        assert!(shortest > 0.0 && longest / shortest < 2.0, "{gaps_mm:?}");
    }

    #[test]
    fn suture_loop_is_on_the_outer_side_near_both_rims() {
        let params = PhantomParams::default();
        let points = phantom(&params).suture_points_mm;
        for p in &points {
            let radius_mm = (p.x * p.x + p.y * p.y).sqrt();
            assert!(radius_mm > params.bend_radius_mm, "{p:?} is on the inner side of the bend");
        }
        // Distances to the cap planes: the VSD cap is y = 0 (x > 0); the aortic cap
        // plane contains the z axis at the end sweep angle.
        let sweep = params.sweep_angle_rad();
        let aortic_normal = Vec3::new(-sweep.sin(), sweep.cos(), 0.0);
        let nearest_vsd_mm = points.iter().map(|p| p.y).fold(f64::INFINITY, f64::min);
        let nearest_aortic_mm = points.iter().map(|p| -p.dot(&aortic_normal)).fold(f64::INFINITY, f64::min);
        for nearest_mm in [nearest_vsd_mm, nearest_aortic_mm] {
            assert!((1.0..1.5).contains(&nearest_mm), "nearest rim distance {nearest_mm} mm");
        }
    }

    #[test]
    fn suture_loop_runs_counter_clockwise_seen_from_outside() {
        // Seen from outside the outer wall (along -radial at mid-sweep), the loop's
        // vector area points outward.
        let params = PhantomParams::default();
        let points = phantom(&params).suture_points_mm;
        let mid = 0.5 * params.sweep_angle_rad();
        let outward = Vec3::new(mid.cos(), mid.sin(), 0.0);
        let centre = points.iter().sum::<Vec3>() / points.len() as f64;
        let vector_area: Vec3 =
            (0..points.len()).map(|i| (points[i] - centre).cross(&(points[(i + 1) % points.len()] - centre))).sum();
        assert!(vector_area.dot(&outward) > 0.0);
    }

    #[test]
    fn mean_edge_length_is_near_requested() {
        for edge_length_mm in [0.8, 0.5, 1.2] {
            let params = PhantomParams { edge_length_mm, ..Default::default() };
            let mean_mm = phantom(&params).surface.mean_edge_length_mm();
            assert!((mean_mm / edge_length_mm - 1.0).abs() < 0.15, "requested {edge_length_mm}, got {mean_mm}");
        }
    }

    #[test]
    fn triangles_are_well_shaped() {
        let mesh = phantom_default().surface;
        let worst_deg = (0..mesh.triangles.len()).map(|t| smallest_angle_deg(&mesh, t)).fold(f64::INFINITY, f64::min);
        assert!(worst_deg > 25.0, "smallest triangle angle {worst_deg} deg");
    }

    #[test]
    fn output_is_deterministic() {
        let (first, second) = (phantom_default(), phantom_default());
        let bits = |p: &Phantom| -> Vec<u64> {
            let coords = p.surface.points.iter().chain(&p.suture_points_mm).flat_map(|v| v.iter().copied());
            coords.map(f64::to_bits).collect()
        };
        assert_eq!(bits(&first), bits(&second));
        assert_eq!(first.surface.triangles, second.surface.triangles);
        assert_eq!(first.surface.face_ids, second.surface.face_ids);
    }

    #[test]
    fn default_sections_just_exceed_the_bsa_target_and_geometry_is_as_documented() {
        let params = PhantomParams::default();
        // Target area for BSA 0.37 m^2 is about 69.8 mm^2. Like the patients' caps, the
        // tube's sections exceed it a little; the flat initial patch across the
        // suture loop cuts a segment away, so the design must bulge the baffle back out.
        for k in 0..=20 {
            let area_mm2 = params.cross_section_area_mm2(k as f64 / 20.0);
            assert!((70.0..80.0).contains(&area_mm2), "{area_mm2}");
        }
        let distance_mm = params.vsd_to_aorta_distance_mm();
        assert!((15.0..20.0).contains(&distance_mm), "{distance_mm}");
        assert_eq!(phantom_default().bsa_m2, 0.37);
    }

    #[test]
    fn wall_point_is_on_the_documented_ellipse() {
        let params = PhantomParams::default();
        let (a, b) = params.vsd_semi_axes_mm;
        let outer = params.wall_point_mm(0.0, 0.0);
        let top = params.wall_point_mm(0.0, 0.5 * PI);
        assert!((outer - Vec3::new(params.bend_radius_mm + a, 0.0, 0.0)).norm() < 1e-12);
        assert!((top - Vec3::new(params.bend_radius_mm, 0.0, b)).norm() < 1e-12);
    }

    #[test]
    fn arc_table_spaces_points_evenly_along_an_ellipse() {
        let table = ArcTable::new();
        let (a, b) = (4.5, 2.0);
        let point = |f: f64| {
            let t = table.angle_at_fraction(a, b, f);
            Vec3::new(a * t.cos(), b * t.sin(), 0.0)
        };
        let gaps: Vec<f64> = (0..40).map(|k| (point((k + 1) as f64 / 40.0) - point(k as f64 / 40.0)).norm()).collect();
        let (lo, hi) = (gaps.iter().copied().fold(f64::INFINITY, f64::min), gaps.iter().copied().fold(0.0, f64::max));
        assert!(hi / lo < 1.02, "{gaps:?}");
        assert_eq!(table.angle_at_fraction(a, b, 0.0), 0.0);
    }

    #[test]
    fn bad_params_are_reported_and_do_not_panic() {
        let bad = [
            PhantomParams { edge_length_mm: 0.0, ..Default::default() },
            PhantomParams { edge_length_mm: f64::NAN, ..Default::default() },
            PhantomParams { bend_radius_mm: 3.0, ..Default::default() },
            PhantomParams { suture_point_count: 0, ..Default::default() },
            PhantomParams { suture_rim_margin_mm: 50.0, ..Default::default() },
        ];
        for params in &bad {
            assert!(params.check().is_err(), "{params:?}");
            let p = phantom(params);
            assert!(!p.surface.triangles.is_empty());
        }
    }
}
