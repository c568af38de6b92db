//! The whole of paper section 2.2.2: blood pools in, capped ventricle out.

use crate::cap_checks::{prepared_cap_checks, BridgedGap};
use crate::capping::{close_with_caps, remesh_wall};
use crate::error::PrepareError;
use crate::input::BloodPools;
use crate::interfaces::{interface_edges, interface_loop, label_by_nearest, InterfaceLoop, LoopOptions, Structure};
use crate::separation::{min_distance_mm, separate_by_moves, separate_openings, CutSeparation, Separated, MAX_MOVE_MM};
use crate::union_surface::{union_surface, SmoothingOptions};
use crate::voxelize::{close_mask, voxelize, Grid};
use baffle_core::geometry::mesh::manifold_report;
use baffle_core::analyses::self_check::SelfCheck;
use baffle_core::geometry::spatial::{Aabb, TriangleBvh};
use baffle_core::{FaceLabels, TriMesh, Vec3};
use rayon::prelude::*;
use std::time::Instant;

/// Labels of the blood pools while the union is labelled (the segmentations' `ModelFaceID`s).
const LV: i32 = 1;
const RV: i32 = 2;
const AORTA: i32 = 6;
/// The union within this fraction of the crop margin of the RV is kept for the
/// loops and the clip (the crop faces lie at the full margin).
const RV_NEIGHBOURHOOD: f64 = 0.6;
/// Smallest crop margin (mm): the kept neighbourhood must hold the rims.
const MIN_CROP_MARGIN_MM: f64 = 3.0;
/// Empty voxels around the structures (the blur and the contour need two).
const GRID_MARGIN_VOXELS: usize = 4;
/// Crop margin (mm) of the union the cut moves search: its kept neighbourhood of the RV
/// must reach past the farthest move into the LV and up the aorta.
const MOVE_CROP_MARGIN_MM: f64 = (MAX_MOVE_MM + 3.0) / RV_NEIGHBOURHOOD;
/// Largest grid `prepare` allocates (one byte per voxel, a few times over).
const MAX_VOXELS: usize = 300_000_000;

#[derive(Clone, Debug)]
pub struct PrepareOptions {
    /// Voxel edge of the union grid (mm).
    pub voxel_mm: f64,
    /// The grid covers the RV with this margin (mm); the LV and aorta beyond it
    /// are cut off (they are clipped away anyway).
    pub crop_margin_mm: f64,
    /// Radius of the morphological closing of the union mask (mm, rounded to voxels).
    pub closing_radius_mm: f64,
    pub smoothing: SmoothingOptions,
    pub loops: LoopOptions,
    /// Target edge of the final isotropic remesh (mm); `None` keeps the contour's triangles.
    pub remesh_edge_mm: Option<f64>,
    /// Output labels: `wall`, `vsd_cap` and `aortic_cap` are used.
    pub labels: FaceLabels,
}

impl Default for PrepareOptions {
    fn default() -> Self {
        PrepareOptions {
            voxel_mm: 0.3,
            crop_margin_mm: 5.0,
            closing_radius_mm: 0.6,
            smoothing: SmoothingOptions::default(),
            loops: LoopOptions::default(),
            remesh_edge_mm: Some(0.5),
            labels: FaceLabels::default(),
        }
    }
}

/// One planar cap of the result.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct CapReport {
    pub label: i32,
    pub centroid_mm: [f64; 3],
    pub normal: [f64; 3],
    pub area_mm2: f64,
}

#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct PrepareTimings {
    pub voxelize_ms: f64,
    pub union_surface_ms: f64,
    pub loops_ms: f64,
    pub clip_ms: f64,
    pub caps_ms: f64,
    pub total_ms: f64,
}

#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct PrepareReport {
    pub voxel_mm: f64,
    /// Voxels of the union grid along its axes (the RV's box plus the crop margin, in the
    /// anatomy's frame: toward the LV, toward the aorta, across both).
    pub grid_dims: [usize; 3],
    /// Triangles of the smoothed union kept around the RV (before the clip).
    pub union_triangles: usize,
    /// Triangles of the capped ventricle.
    pub triangles: usize,
    pub area_mm2: f64,
    pub volume_mm3: f64,
    pub vsd_cap: CapReport,
    pub aortic_cap: CapReport,
    /// How far apart the two openings are, and how far their cuts were moved to keep them so.
    pub separation: CutSeparation,
    /// The caps re-measured against the openings traced on the segmentations (all passed).
    pub checks: Vec<SelfCheck>,
    pub timings: PrepareTimings,
}

/// The capped ventricle: closed, manifold, outward-wound, labelled RV wall, VSD cap
/// and aortic-annulus cap.
pub fn prepare(pools: &BloodPools, options: &PrepareOptions) -> Result<(TriMesh, PrepareReport), PrepareError> {
    validate(options)?;
    let start = Instant::now();
    let bvhs = [&pools.lv, &pools.rv, &pools.aorta].map(|m| TriangleBvh::new(m).map_err(|e| PrepareError::geometry("structures", e)));
    let [lv_bvh, rv_bvh, aorta_bvh] = bvhs;
    let (lv_bvh, rv_bvh, aorta_bvh) = (lv_bvh?, rv_bvh?, aorta_bvh?);
    let structures = [
        Structure { label: RV, surface: &pools.rv, bvh: &rv_bvh },
        Structure { label: LV, surface: &pools.lv, bvh: &lv_bvh },
        Structure { label: AORTA, surface: &pools.aorta, bvh: &aorta_bvh },
    ];
    let mut timings = PrepareTimings::default();
    let clearance_mm = options.remesh_edge_mm.unwrap_or(2.0 * options.voxel_mm);
    let rv_center = pools.rv.points.iter().sum::<Vec3>() / pools.rv.points.len().max(1) as f64;
    let snap_mm = 0.05 * options.voxel_mm;
    // The cuts in the loops' own planes first; where they cannot be kept apart, the
    // moves, on a union reaching far enough into the LV and the aorta to hold them.
    let mut around = AroundRv::new(pools, &structures, options.crop_margin_mm, options, &mut timings)?;
    let mut lap = lap_timer();
    let beyond = [&structures[1], &structures[2]];
    let mut separated = separate_openings(&around.union, [&around.vsd, &around.aortic], beyond, rv_center, &[(0.0, 0.0)], clearance_mm, snap_mm);
    timings.clip_ms += lap();
    if separated.is_err() {
        let margin_mm = options.crop_margin_mm.max(MOVE_CROP_MARGIN_MM);
        around = AroundRv::new(pools, &structures, margin_mm, options, &mut timings)?;
        lap();
        separated = separate_by_moves(&around.union, [&around.vsd, &around.aortic], beyond, rv_center, clearance_mm, snap_mm);
        timings.clip_ms += lap();
    }
    let why = |m: String| PrepareError::geometry("clip", m + &around.aorta_over_lv() + &aorta_on_lv(&pools.aorta, &structures[1], options.voxel_mm));
    let Separated { clipped, planes, report: mut separation } = separated.map_err(why)?;

    let l = &options.labels;
    let wall = match options.remesh_edge_mm {
        Some(edge) => remesh_wall(&clipped, &planes, edge, None).map_err(|m| PrepareError::geometry("remesh", m))?,
        None => clipped,
    };
    let capped = close_with_caps(&wall, &planes, l.wall, &[l.vsd_cap, l.aortic_cap]).map_err(|m| PrepareError::geometry("caps", m))?;
    check_result(&capped)?;
    // The gap as the result has it (the remesh resamples the rims).
    separation.rim_gap_mm = cap_gap_mm(&capped, l.vsd_cap, l.aortic_cap);
    let gap = BridgedGap { voxel_mm: options.voxel_mm, closing_radius_mm: options.closing_radius_mm };
    let checks = prepared_cap_checks(&capped, pools, &rv_bvh, (l.vsd_cap, l.aortic_cap), &separation, gap);
    if let Some(failed) = checks.iter().find(|c| !c.passed) {
        return Err(PrepareError::SelfCheck { check: failed.describe(), summary: separation.summary() });
    }
    timings.caps_ms = lap();
    timings.total_ms = start.elapsed().as_secs_f64() * 1e3;

    let report = PrepareReport {
        voxel_mm: options.voxel_mm,
        grid_dims: around.grid.dims,
        union_triangles: around.union.triangles.len(),
        triangles: capped.triangles.len(),
        area_mm2: capped.area_mm2(),
        volume_mm3: capped.signed_volume_mm3(),
        vsd_cap: cap_report(&capped, l.vsd_cap)?,
        aortic_cap: cap_report(&capped, l.aortic_cap)?,
        separation,
        checks,
        timings,
    };
    Ok((capped, report))
}

/// The union of the pools kept around the RV, its labels' VSD and aortic loops, its grid.
struct AroundRv {
    union: TriMesh,
    grid: Grid,
    vsd: InterfaceLoop,
    aortic: InterfaceLoop,
    /// Length of the aorta's boundary on the union against the LV and against the RV (mm).
    aorta_on_lv_mm: f64,
    aorta_on_rv_mm: f64,
}

impl AroundRv {
    /// The union on a grid over the RV with `margin_mm`, kept within `RV_NEIGHBOURHOOD`
    /// of that margin of the RV; its times are added to `timings`.
    fn new(pools: &BloodPools, structures: &[Structure; 3], margin_mm: f64, options: &PrepareOptions, timings: &mut PrepareTimings) -> Result<Self, PrepareError> {
        let mut lap = lap_timer();
        let frame = AnatomyFrame::of(pools);
        let bounds = frame.bounds_of(&pools.rv.points).expanded(margin_mm);
        let (union, grid, voxelize_ms) = union_in_frame(&frame, &[(&pools.lv, &everywhere), (&pools.rv, &everywhere), (&pools.aorta, &everywhere)], &bounds, options)?;
        timings.voxelize_ms += voxelize_ms;
        timings.union_surface_ms += lap() - voxelize_ms;
        // Only the RV's neighbourhood can be kept: the rest (and the grid's crop
        // faces, farther out) is dropped before the loops and the clip.
        let near = label_by_nearest(&union, structures, RV_NEIGHBOURHOOD * margin_mm);
        let keep: Vec<bool> = near.iter().map(Option::is_some).collect();
        let labels: Vec<i32> = near.into_iter().flatten().collect();
        let union = union.submesh(&keep).0;
        let union_bvh = TriangleBvh::new(&union).map_err(|e| PrepareError::geometry("union surface", e))?;
        let find_loop = |pair: (i32, i32), names: (&'static str, &'static str), what: &'static str, a: &TriMesh| {
            interface_loop(&union, &union_bvh, &labels, pair, &options.loops).ok_or_else(|| PrepareError::NoContact {
                a: names.0,
                b: names.1,
                what,
                distance_mm: closest_approach(a, &structures[0]).0,
            })
        };
        let vsd = find_loop((LV, RV), ("LV", "RV"), "VSD", &pools.lv)?;
        let aortic = find_loop((RV, AORTA), ("RV", "aorta"), "aortic annulus", &pools.aorta)?;
        let length = |other: i32| {
            interface_edges(&union, &labels, AORTA, other).iter().map(|&(a, b)| (union.points[a as usize] - union.points[b as usize]).norm()).sum::<f64>()
        };
        let (aorta_on_lv_mm, aorta_on_rv_mm) = (length(LV), length(RV));
        timings.loops_ms += lap();
        Ok(AroundRv { union, grid, vsd, aortic, aorta_on_lv_mm, aorta_on_rv_mm })
    }

    /// How much of the aorta's boundary on the union borders the LV: over half, the
    /// aorta arises from the LV (the 50% rule that defines DORV) and no cut can leave
    /// the RV between a VSD cap and an annulus cap. Empty when it borders only the RV.
    fn aorta_over_lv(&self) -> String {
        if self.aorta_on_lv_mm <= 0.0 {
            return String::new();
        }
        let fraction = self.aorta_on_lv_mm / (self.aorta_on_lv_mm + self.aorta_on_rv_mm);
        let verdict = if fraction > 0.5 { ": the aorta arises mostly from the LV, which is not a double-outlet RV (the 50% rule)" } else { "" };
        format!(
            "; the aorta borders the LV along {:.1} mm and the RV along {:.1} mm of its rim on the union ({:.0}% over the LV){verdict}",
            self.aorta_on_lv_mm, self.aorta_on_rv_mm, 100.0 * fraction
        )
    }
}

/// The frame the union is voxelized in, fixed to the anatomy: origin at the RV's
/// centroid, first axis toward the LV's, second toward the aorta's. The grid then turns
/// and moves with the scene, and a rigidly moved scene gives the same union, loops and
/// caps moved with it (on an axis-aligned grid p1's caps changed by 3.3 % when the scene
/// was turned 37 degrees: each rim falls on other voxels; `extend`'s parts crossed the
/// designed domain on p2 so turned).
pub(crate) struct AnatomyFrame {
    origin: Vec3,
    /// Rows: the frame's axes in the input's coordinates.
    axes: nalgebra::Matrix3<f64>,
}

impl AnatomyFrame {
    pub(crate) fn of(pools: &BloodPools) -> Self {
        let centroid = |m: &TriMesh| m.points.iter().sum::<Vec3>() / m.points.len().max(1) as f64;
        let origin = centroid(&pools.rv);
        let toward_lv = (centroid(&pools.lv) - origin).try_normalize(1e-9).unwrap_or_else(Vec3::x);
        let toward_aorta = centroid(&pools.aorta) - origin;
        let across = toward_aorta - toward_lv * toward_lv.dot(&toward_aorta);
        // An aorta in line with the LV leaves the turn about that line free: any will do.
        let second = across.try_normalize(1e-6 * toward_aorta.norm().max(1e-9)).unwrap_or_else(|| baffle_core::geometry::mesh::axes_across(&toward_lv).0);
        let axes = nalgebra::Matrix3::from_rows(&[toward_lv.transpose(), second.transpose(), toward_lv.cross(&second).transpose()]);
        AnatomyFrame { origin, axes }
    }

    fn to_local(&self, p: &Vec3) -> Vec3 {
        self.axes * (p - self.origin)
    }

    fn to_world(&self, q: &Vec3) -> Vec3 {
        self.axes.transpose() * q + self.origin
    }

    fn mesh_to_local(&self, mesh: &TriMesh) -> TriMesh {
        TriMesh { points: mesh.points.iter().map(|p| self.to_local(p)).collect(), ..mesh.clone() }
    }

    /// The box, in this frame, around `points` (given in the input's coordinates).
    pub(crate) fn bounds_of<'a>(&self, points: impl IntoIterator<Item = &'a Vec3>) -> Aabb {
        Aabb::from_points(points.into_iter().map(|p| self.to_local(p)).collect::<Vec<_>>().iter())
    }
}

/// [`union_within`] on a grid laid in `frame`: the pools and their regions in the input's
/// coordinates, `local_bounds` in the frame's, the union returned in the input's.
pub(crate) fn union_in_frame(frame: &AnatomyFrame, pools: &[(&TriMesh, Within)], local_bounds: &Aabb, options: &PrepareOptions) -> Result<(TriMesh, Grid, f64), PrepareError> {
    let local: Vec<TriMesh> = pools.iter().map(|(mesh, _)| frame.mesh_to_local(mesh)).collect();
    let regions: Vec<Box<dyn Fn(&Vec3) -> bool + Sync>> = pools
        .iter()
        .map(|&(_, within)| Box::new(move |q: &Vec3| within(&frame.to_world(q))) as Box<dyn Fn(&Vec3) -> bool + Sync>)
        .collect();
    let local_pools: Vec<(&TriMesh, Within)> = local.iter().zip(&regions).map(|(mesh, region)| (mesh, region.as_ref() as Within)).collect();
    let (mut union, grid, voxelize_ms) = union_within(&local_pools, local_bounds, options)?;
    union.points.iter_mut().for_each(|p| *p = frame.to_world(p));
    Ok((union, grid, voxelize_ms))
}

/// Smallest distance between a rim point of cap `a` and one of cap `b` (mm).
fn cap_gap_mm(mesh: &TriMesh, a: i32, b: i32) -> f64 {
    let rim = |label: i32| -> Vec<Vec3> {
        let cap = mesh.with_labels(|l| l == label);
        let loops = cap.boundary_loops().unwrap_or_default();
        loops.concat().iter().map(|&v| cap.points[v as usize]).collect()
    };
    min_distance_mm(&rim(a), &rim(b))
}

pub(crate) fn lap_timer() -> impl FnMut() -> f64 {
    let mut last = Instant::now();
    move || {
        let now = Instant::now();
        let ms = (now - last).as_secs_f64() * 1e3;
        last = now;
        ms
    }
}

pub(crate) fn validate(options: &PrepareOptions) -> Result<(), PrepareError> {
    let positive = |v: f64| v.is_finite() && v > 0.0;
    if !(options.crop_margin_mm.is_finite() && options.crop_margin_mm >= MIN_CROP_MARGIN_MM) {
        return Err(PrepareError::Option(format!("crop margin must be at least {MIN_CROP_MARGIN_MM} mm, got {}", options.crop_margin_mm)));
    }
    if !(options.closing_radius_mm.is_finite() && options.closing_radius_mm >= 0.0) {
        return Err(PrepareError::Option(format!("closing radius must be a number of mm >= 0, got {}", options.closing_radius_mm)));
    }
    if !positive(options.voxel_mm) {
        return Err(PrepareError::Option(format!("voxel size must be a positive number of mm, got {}", options.voxel_mm)));
    }
    if let Some(e) = options.remesh_edge_mm.filter(|&e| !positive(e)) {
        return Err(PrepareError::Option(format!("remesh edge must be a positive number of mm, got {e}")));
    }
    let l = &options.labels;
    if l.wall == l.vsd_cap || l.wall == l.aortic_cap || l.vsd_cap == l.aortic_cap {
        return Err(PrepareError::Option(format!("the wall, VSD and aortic labels must differ, got {}, {}, {}", l.wall, l.vsd_cap, l.aortic_cap)));
    }
    Ok(())
}

/// Where a pool counts in a union: a voxel of it is in the union where this holds at
/// the voxel's centre (mm).
pub(crate) type Within<'a> = &'a (dyn Fn(&Vec3) -> bool + Sync);

/// A pool that counts everywhere.
pub(crate) fn everywhere(_: &Vec3) -> bool {
    true
}

/// The smoothed union surface of the blood pools `pools`, each where its region holds,
/// within `bounds` (mm), made with `options`' voxel, closing and smoothing (the pools
/// beyond `bounds` are cut off, the cut closed flat at the grid's edge); also its grid
/// and the voxelizing time (ms).
fn union_within(pools: &[(&TriMesh, Within)], bounds: &Aabb, options: &PrepareOptions) -> Result<(TriMesh, Grid, f64), PrepareError> {
    let start = Instant::now();
    let grid = union_grid(bounds, options.voxel_mm)?;
    let closing_voxels = (options.closing_radius_mm / options.voxel_mm).round() as usize;
    let mask = close_mask(&union_mask(pools, &grid), &grid, closing_voxels);
    let voxelize_ms = start.elapsed().as_secs_f64() * 1e3;
    let union = union_surface(&mask, &grid, &options.smoothing).map_err(|m| PrepareError::geometry("union surface", m))?;
    Ok((union, grid, voxelize_ms))
}

/// A grid over `bounds`; its outer voxels are left empty so the union closes inside it.
fn union_grid(bounds: &Aabb, voxel_mm: f64) -> Result<Grid, PrepareError> {
    let grid = Grid::covering(bounds.min, bounds.max, voxel_mm, GRID_MARGIN_VOXELS);
    let voxels = grid.dims.iter().try_fold(1usize, |acc, &d| acc.checked_mul(d));
    match voxels {
        Some(n) if n <= MAX_VOXELS => Ok(grid),
        _ => Err(PrepareError::Option(format!(
            "a {voxel_mm} mm grid over the structures ({:.0} x {:.0} x {:.0} mm) has more than {MAX_VOXELS} voxels; use a coarser voxel",
            bounds.max.x - bounds.min.x,
            bounds.max.y - bounds.min.y,
            bounds.max.z - bounds.min.z
        ))),
    }
}

fn union_mask(pools: &[(&TriMesh, Within)], grid: &Grid) -> Vec<bool> {
    let masks: Vec<Vec<bool>> = pools.par_iter().map(|(m, _)| voxelize(m, grid)).collect();
    let m = GRID_MARGIN_VOXELS;
    let interior = |i: usize| grid.ijk(i).iter().zip(grid.dims).all(|(&c, n)| c >= m && c + m < n);
    let counts = |i: usize| masks.iter().zip(pools).any(|(mask, (_, within))| mask[i] && within(&grid.centre(i)));
    (0..grid.voxel_count()).into_par_iter().map(|i| interior(i) && counts(i)).collect()
}

/// Smallest distance (mm) from a point of `a` to the surface of `b`, and that point of `a`.
fn closest_approach(a: &TriMesh, b: &Structure) -> (f64, Vec3) {
    a.points
        .par_iter()
        .filter_map(|&p| b.bvh.closest_point(b.surface, p).map(|h| (h.distance_mm, p)))
        .reduce(|| (f64::INFINITY, Vec3::zeros()), |x, y| if y.0 < x.0 { y } else { x })
}

/// Why the cuts fail where the aorta meets the LV (as over a subaortic VSD): the
/// union of the pools then joins the VSD and the annulus, and neither plane cuts the
/// surface along its own loop. Empty when the aorta stays two voxels clear of the LV.
fn aorta_on_lv(aorta: &TriMesh, lv: &Structure, voxel_mm: f64) -> String {
    let (gap_mm, at) = closest_approach(aorta, lv);
    if gap_mm > 2.0 * voxel_mm {
        return String::new();
    }
    format!(
        "; the aorta comes within {gap_mm:.2} mm of the LV near ({:.1}, {:.1}, {:.1}), so the VSD and the aortic \
         annulus meet there: the capped ventricle needs the two openings apart (check the segmentations there, \
         or design on a capped ventricle made by hand)",
        at.x, at.y, at.z
    )
}

fn check_result(mesh: &TriMesh) -> Result<(), PrepareError> {
    check_closed_outward(mesh, "result", "the capped surface")
}

/// `mesh` must be closed, consistently wound and outward (a lumen the later steps can cut
/// and mesh); otherwise an error of `step` saying which, `subject` naming the surface.
pub(crate) fn check_closed_outward(mesh: &TriMesh, step: &'static str, subject: &str) -> Result<(), PrepareError> {
    let report = manifold_report(mesh);
    if !report.is_closed_manifold() || report.inconsistently_wound_edges > 0 {
        return Err(PrepareError::geometry(step, format!("{subject} is not closed and consistently wound: {report:?}")));
    }
    if mesh.signed_volume_mm3() <= 0.0 {
        return Err(PrepareError::geometry(step, format!("{subject} is wound inward")));
    }
    Ok(())
}

pub(crate) fn cap_report(mesh: &TriMesh, label: i32) -> Result<CapReport, PrepareError> {
    let (c, n, area_mm2) = mesh.label_centroid_normal(label).ok_or_else(|| PrepareError::geometry("caps", format!("no triangle carries label {label}")))?;
    let arr = |v: Vec3| [v.x, v.y, v.z];
    Ok(CapReport { label, centroid_mm: arr(c), normal: arr(n), area_mm2 })
}
