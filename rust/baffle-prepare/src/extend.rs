//! The extended CFD domain [paper 2.5]: the designed domain (VSD cap to aortic-annulus
//! cap), plus the LV cavity from the VSD back to a plane through the mid-LV cavity, plus
//! the aortic root from the annulus up to the sinotubular junction (STJ), each closed by
//! a new flat cap (inflow, outflow). The VSD and aortic-annulus caps stay, unchanged, as
//! interior surfaces (measurement planes); nothing of the designed domain is moved.
//!
//! Choices:
//! - The mid-LV plane is parallel to the VSD cap's plane, through the LV blood pool's
//!   volume centroid. Parallel planes never cross, so the inflow cap cannot touch the VSD
//!   cap, and the inflow faces the VSD as the LV's outflow does in DORV; a short-axis
//!   plane would need the LV's long axis, ill-defined on small rounded LVs, and can cross
//!   a large VSD.
//! - The STJ: cross-sections of the aorta surface parallel to the annulus cap, every
//!   `step_mm` along the cap's outward normal (each section the one nearest the previous
//!   one's centroid), smoothed; the first area minimum after the first maximum (the
//!   sinuses) that lies `min_drop` below that maximum; the sections end where one step
//!   changes the area by more than `max_step_change` (a branch or the arch). Without
//!   such a minimum, the outflow cap is
//!   `fallback_diameters` annulus diameters above the annulus, and the report says so.
//! - The LV part is cut from the union of the LV pool and the RV over the VSD (the RV
//!   within `VSD_FOOTPRINT_MARGIN_MM` of the VSD cap seen along its normal), the
//!   aortic part from that of the RV and aorta (each made as `prepare` makes the union,
//!   on a grid covering the part; an aorta touching the LV would join the parts), by
//!   the same clip as `prepare`, along the designed caps' own planes. The RV counts
//!   only over the VSD because anywhere else where the LV meets it (a second,
//!   muscular VSD; a septum thinner than the closing, which fuses the pools) the union
//!   has a handle through the VSD's rim: no VSD cut then separates the LV part ("the
//!   kept surface has 1 openings, expected 2"), and no plane move removes a handle.
//!   Such a contact is wall in the extension, and the report names it. Beside the rim
//!   the RV counts only from the closing radius and a voxel on the RV's side of the cap's
//!   plane: where the designed wall there rises onto the LV's side (a VSD in a dimple of
//!   the septum, a cap projected onto its plane by hand), that RV is inside the designed
//!   domain, and the LV part would lie on the designed wall. Each part is remeshed at the designed rims' edge
//!   length, its first row of triangles at the designed cap is dropped and the gap is
//!   zipped to the designed cap's rim, so that rim is shared (3 faces meet there: the
//!   designed wall, the interior cap, the extension).
//!
//! The extension's walls carry the wall label. The result's first points and triangles
//! are the designed domain's, bit-identical.

use crate::capping::{close_with_caps, remesh_wall, zip_rings};
use crate::polygon2d::{distance_to_polygon_mm, inside_polygon};
use crate::clip::{clip_between, Clipped, Cut};
use crate::error::PrepareError;
use crate::input::BloodPools;
use crate::prepare::{cap_report, check_closed_outward, everywhere, lap_timer, union_in_frame, validate, AnatomyFrame, CapReport, PrepareOptions};
use baffle_core::geometry::caps::{cap_flatness, project_caps_onto_planes, CapFlatness, CapProjection};
use baffle_core::geometry::mesh::edge_key;
use baffle_core::geometry::remesh::{remesh_isotropic, where_it_crosses_itself, RemeshOptions};
use baffle_core::geometry::numerics::pca::Plane;
use baffle_core::steps::sections::{cut_mesh, Contour};
use baffle_core::analyses::self_check::{first_failure, SelfCheck};
use baffle_core::geometry::remesh::{SizeGrading, MAX_GROWTH};
use baffle_core::geometry::spatial::{winding_number, Aabb, TriangleBvh};
use baffle_core::{FaceLabels, TriMesh, Vec3};
use rayon::prelude::*;
use std::collections::{HashMap, HashSet};

/// Default `ModelFaceID` of the inflow cap (the mid-LV plane).
pub const INFLOW_CAP_LABEL: i32 = 20;
/// Default `ModelFaceID` of the outflow cap (the STJ).
pub const OUTFLOW_CAP_LABEL: i32 = 21;
/// The mid-LV plane must lie at least this far beyond the VSD cap (mm).
const MIN_LV_DEPTH_MM: f64 = 1.0;
/// Where the cut through the LV's centroid cannot be separated from the VSD cut on
/// the LV surface (a curved or pinched LV), the mid-LV plane is moved along the VSD
/// normal by these distances (mm), in order: deeper into the LV first, then back.
const MID_LV_MOVES_MM: [f64; 7] = [0.0, 2.0, 4.0, 6.0, -2.0, -4.0, 8.0];
/// A mid-LV section loop counts (a second arm of a curved LV) when its area is
/// above this fraction of the largest loop's.
const MIN_SECOND_LOOP_FRACTION: f64 = 0.02;
/// The union follows each pool within the closing and the smoothing (0.1-0.2 mm
/// measured on the LV family); a far cut farther than this (mm) from its pool runs
/// over another pool joined to it.
const FAR_RIM_OFF_POOL_MM: f64 = 1.0;
/// The RV joins the LV part only within this distance (mm) of the VSD cap's rim, seen
/// along the cap's normal: wide enough for the closing's fillet where the pools part
/// at the rim (0.6 mm closing: about 2 mm), narrow enough to leave out the septum
/// around the VSD.
const VSD_FOOTPRINT_MARGIN_MM: f64 = 3.0;
/// ... and from this far (mm) on the RV's side of the VSD cap's plane: the union's
/// section in that plane, which the VSD cut follows, then stays the designed one.
const RV_BEHIND_VSD_MM: f64 = 6.0;

#[derive(Clone, Debug)]
pub struct StjOptions {
    /// Spacing of the aortic cross-sections (mm).
    pub step_mm: f64,
    /// Sections are searched up to this many annulus diameters above the annulus.
    pub search_diameters: f64,
    /// The STJ minimum must lie this fraction below the sinus maximum.
    pub min_drop: f64,
    /// Half-width of the window a maximum or minimum must dominate (mm).
    pub window_mm: f64,
    /// Without a minimum, the outflow cap lies this many annulus diameters above the annulus.
    pub fallback_diameters: f64,
    /// The outflow cap this many annulus diameters above the annulus wherever the STJ is
    /// (a sensitivity study of the outflow length); the search still runs and is reported.
    pub fixed_diameters: Option<f64>,
    /// The search stops where one step changes the section area by more than this
    /// fraction (a branch or the arch enters the plane): a minimum needs a gradual rise after it.
    pub max_step_change: f64,
}

impl Default for StjOptions {
    fn default() -> Self {
        StjOptions { step_mm: 0.25, search_diameters: 2.5, min_drop: 0.05, window_mm: 1.5, fallback_diameters: 1.0, max_step_change: 0.1, fixed_diameters: None }
    }
}

#[derive(Clone, Debug)]
pub struct ExtendOptions {
    /// How the union of the pools is made (voxel, closing, smoothing; `crop_margin_mm`
    /// around the extension): `prepare`'s defaults.
    pub union: PrepareOptions,
    /// The designed domain's labels; the extension's walls get `labels.wall`.
    pub labels: FaceLabels,
    pub inflow_label: i32,
    pub outflow_label: i32,
    /// Target edge of the extension's remesh (mm); `None`: the designed caps' mean rim edge.
    pub remesh_edge_mm: Option<f64>,
    /// Remesh the designed domain itself at this edge (mm) first, after flattening its caps
    /// (a mesh study's level); `None`: keep its triangles.
    pub remesh_domain_edge_mm: Option<f64>,
    pub stj: StjOptions,
    /// The mid-LV plane this far (mm) from the LV centroid along the VSD normal (positive:
    /// away from the VSD), and only there (a sensitivity study of the inflow position);
    /// `None`: through the centroid, moved by `MID_LV_MOVES_MM` until a cut is clean.
    pub inflow_offset_mm: Option<f64>,
    /// The domain has no baffle (no triangle of `labels.baffle`), as the user says: a
    /// capped ventricle extended as it is. Without it such a domain is refused, since
    /// the designed domain `extend` expects is `design`'s, with its baffle.
    pub without_baffle: bool,
    /// Coarsen each part away from its designed cap (`None`: the edge everywhere).
    pub grading: Option<ExtensionGrading>,
}

/// How each part of the extension coarsens away from the designed cap it joins (a
/// [`SizeGrading`] from the cap's disc): the edge stays the designed rims' within
/// `margin_diameters` of the cap's equivalent diameters, where the flow converges into
/// the VSD or the jet leaves the annulus and sets the plane's pressure, then grows by
/// `growth` mm per mm, up to `largest_ratio` times the edge.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ExtensionGrading {
    pub margin_diameters: f64,
    pub growth: f64,
    pub largest_ratio: f64,
}

impl ExtensionGrading {
    /// A named error for a grading no remesh can follow (refused up front: an extension
    /// that fails with it would otherwise be made again at one edge).
    fn validate(&self) -> Result<(), PrepareError> {
        let margin_ok = self.margin_diameters.is_finite() && self.margin_diameters >= 0.0;
        let growth_ok = self.growth.is_finite() && (0.0..=MAX_GROWTH).contains(&self.growth);
        if margin_ok && growth_ok && self.largest_ratio.is_finite() && self.largest_ratio >= 1.0 {
            return Ok(());
        }
        Err(PrepareError::Option(format!(
            "the extension's grading needs a margin >= 0 diameters, a growth in [0, {MAX_GROWTH}] mm per mm and a largest ratio >= 1, got {self:?}"
        )))
    }

    /// The grading of a part at `edge_mm` from `cap`.
    fn from_cap(&self, cap: &DesignedCap, edge_mm: f64) -> SizeGrading {
        let radius_mm = (cap.area_mm2 / std::f64::consts::PI).sqrt();
        SizeGrading {
            center: cap.plane.centroid,
            normal: cap.plane.normal,
            radius_mm,
            margin_mm: self.margin_diameters * 2.0 * radius_mm,
            growth: self.growth,
            largest_edge_mm: self.largest_ratio * edge_mm,
        }
    }
}

impl Default for ExtendOptions {
    fn default() -> Self {
        ExtendOptions {
            union: PrepareOptions::default(),
            labels: FaceLabels::default(),
            inflow_label: INFLOW_CAP_LABEL,
            outflow_label: OUTFLOW_CAP_LABEL,
            remesh_edge_mm: None,
            remesh_domain_edge_mm: None,
            stj: StjOptions::default(),
            inflow_offset_mm: None,
            without_baffle: false,
            grading: None,
        }
    }
}

#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct MidLvPlaneReport {
    pub rule: String,
    pub point_mm: [f64; 3],
    /// Unit normal, from the VSD toward the LV.
    pub normal: [f64; 3],
    /// Distance of the plane beyond the VSD cap's plane (mm).
    pub distance_from_vsd_mm: f64,
    /// How far the plane was moved from the LV centroid along its normal (mm; 0 when
    /// the cut through the centroid was clean).
    pub moved_from_centroid_mm: f64,
    /// Which part of the RV the LV part was cut with.
    pub rv_in_lv_part: String,
    /// Where the LV meets the RV (or comes within twice the closing radius of it)
    /// away from the VSD: a second VSD or a thin septum, wall in the extension; `None`
    /// when there is no such place.
    pub other_lv_rv_contact: Option<String>,
}

#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct StjReport {
    /// Whether an area minimum was found; if not, the outflow cap is at the fallback height.
    pub found: bool,
    pub note: String,
    /// Height of the outflow cap above the annulus cap's plane (mm).
    pub distance_from_annulus_mm: f64,
    /// Equivalent diameter of the annulus cap (mm).
    pub annulus_diameter_mm: f64,
    pub sinus_max_area_mm2: f64,
    pub sinus_max_distance_mm: f64,
    pub stj_area_mm2: f64,
    /// (height mm, smoothed section area mm2) of each searched section.
    pub profile: Vec<[f64; 2]>,
}

#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct ExtendTimings {
    pub planes_ms: f64,
    pub union_ms: f64,
    pub extensions_ms: f64,
    pub checks_ms: f64,
}

#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct ExtendReport {
    /// The first `designed_triangles` triangles (and their points) are the designed domain's.
    pub designed_triangles: usize,
    pub triangles: usize,
    pub lv_extension_triangles: usize,
    pub aortic_extension_triangles: usize,
    pub designed_volume_mm3: f64,
    pub volume_mm3: f64,
    pub baffle_area_before_mm2: f64,
    pub baffle_area_after_mm2: f64,
    /// (after - before) / before.
    pub baffle_area_relative_change: f64,
    /// The designed caps, now interior measurement planes: their labels.
    pub interior_labels: [i32; 2],
    pub vsd_cap: CapReport,
    pub aortic_cap: CapReport,
    pub inflow_cap: CapReport,
    pub outflow_cap: CapReport,
    pub mid_lv_plane: MidLvPlaneReport,
    /// Largest distance of a designed VSD / aortic cap point from its plane as given, before
    /// the projection (mm).
    pub vsd_cap_off_plane_mm: f64,
    pub aortic_cap_off_plane_mm: f64,
    /// The designed caps as given, and their projection onto their planes (the designed
    /// part of the extended domain carries the projected caps).
    pub cap_projections: Vec<CapProjection>,
    pub stj: StjReport,
    pub remesh_edge_mm: f64,
    /// How the LV and aortic parts coarsened away from the designed caps (`None`: not).
    #[serde(default)]
    pub grading: Option<ExtensionGrading>,
    /// Why the asked grading was not used (the graded extension failed; `grading` is then
    /// `None`).
    #[serde(default)]
    pub grading_dropped: Option<String>,
    /// The checks of the extended domain by a second method (each passed).
    pub checks: Vec<SelfCheck>,
    pub timings: ExtendTimings,
}

/// The extended domain: designed domain first (unchanged but for its caps, projected onto
/// their planes), then the LV and aortic parts.
#[derive(Clone, Debug)]
pub struct Extended {
    pub surface: TriMesh,
    pub report: ExtendReport,
}

/// One planar cap of the designed domain.
struct DesignedCap {
    /// Best-fit plane, normal outward (out of the designed domain).
    plane: Plane,
    /// Rim as domain point indices, in the cap triangles' winding.
    rim: Vec<u32>,
    area_mm2: f64,
}

/// The extended domain of `domain` (a closed, outward designed domain in mm with the
/// VSD and aortic caps of `options.labels`) with the LV and aorta of `pools`. A graded
/// extension that fails (coarse triangles can cut across a wall that comes close, as
/// p1's LV does beside its designed domain at 2.5x) is made again at one edge, and the
/// report says why (`grading_dropped`).
pub fn extend(domain: &TriMesh, pools: &BloodPools, options: &ExtendOptions) -> Result<Extended, PrepareError> {
    // Bad options are the caller's to mend, not a reason to drop the grading.
    validate_options(options)?;
    check_domain(domain)?;
    // The caps are flattened before any remesh: the remesh keeps flat caps on their planes,
    // whereas projecting them after it can turn over a sliver the remesh left beside a rim
    // (p3's chain at 0.3 mm, caps 4 micrometres off plane).
    let (flattened, cap_projections) = flatten_designed_caps(domain, &options.labels)?;
    let domain = &match options.remesh_domain_edge_mm {
        Some(edge_mm) => remeshed_designed_domain(&flattened, edge_mm)?,
        None => flattened,
    };
    match (extend_as_asked(domain, &cap_projections, pools, options), options.grading) {
        (Err(graded), Some(_)) => {
            let mut extended = extend_as_asked(domain, &cap_projections, pools, &ExtendOptions { grading: None, ..options.clone() })?;
            extended.report.grading_dropped = Some(format!("the graded extension failed ({graded}); extended at one edge instead"));
            Ok(extended)
        }
        (result, _) => result,
    }
}

/// [`extend`] with `options` (validated) as given, on the checked `domain` whose caps
/// `cap_projections` flattened.
fn extend_as_asked(domain: &TriMesh, cap_projections: &[CapProjection], pools: &BloodPools, options: &ExtendOptions) -> Result<Extended, PrepareError> {
    let mut lap = lap_timer();
    let l = &options.labels;
    let vsd = designed_cap(domain, l.vsd_cap, "VSD")?;
    let annulus = designed_cap(domain, l.aortic_cap, "aortic-annulus")?;
    check_baffle(domain, l.baffle, options.without_baffle)?;
    let centroid_plane = lv_centroid_plane(&pools.lv, &vsd.plane)?;
    let (stj, stj_report, stj_loop) = sinotubular_junction(&pools.aorta, &annulus, &options.stj)?;
    let planes_ms = lap();

    let moves_mm = mid_lv_moves_mm(options.inflow_offset_mm);
    let deepest_move_mm = moves_mm.iter().copied().fold(0.0, f64::max);
    let deepest = parallel_plane(&centroid_plane, centroid_plane.centroid + deepest_move_mm * centroid_plane.normal);
    // Each part is cut from the union of the two pools its designed cap joins: where
    // the aorta also touches the LV, the union of all three has a handle through
    // both caps' rims, and neither cut then separates its part.
    // On a grid fixed to the anatomy, so a rigidly moved scene extends the same.
    let frame = AnatomyFrame::of(pools);
    let margin_mm = options.union.crop_margin_mm;
    let lv_bounds = part_bounds(&frame, domain, &vsd, &pools.lv, &deepest, margin_mm);
    let footprint = VsdFootprint::new(domain, &vsd, vsd.plane.signed_distance_mm(&deepest.centroid) + margin_mm);
    let inset_mm = options.union.voxel_mm;
    let beside_rim_below_mm = options.union.closing_radius_mm + options.union.voxel_mm;
    let over_vsd = |q: &Vec3| footprint.joins_lv_part(q, inset_mm, beside_rim_below_mm);
    let (lv_union, _, _) = union_in_frame(&frame, &[(&pools.lv, &everywhere), (&pools.rv, &over_vsd)], &lv_bounds, &options.union)?;
    let ao_bounds = part_bounds(&frame, domain, &annulus, &pools.aorta, &stj, margin_mm);
    let (ao_union, _, _) = union_in_frame(&frame, &[(&pools.rv, &everywhere), (&pools.aorta, &everywhere)], &ao_bounds, &options.union)?;
    let union_ms = lap();

    let edge_mm = options.remesh_edge_mm.unwrap_or_else(|| mean_rim_edge_mm(domain, &[&vsd.rim, &annulus.rim]));
    let snap_mm = 0.05 * options.union.voxel_mm;
    let mut surface = domain.clone();
    let lv_part = LvPart {
        union: &lv_union,
        pools,
        vsd: &vsd,
        footprint: &footprint,
        centroid_plane,
        moves_mm,
        fixed: options.inflow_offset_mm.is_some(),
        inflow_label: options.inflow_label,
        closing_radius_mm: options.union.closing_radius_mm,
    };
    let (lv_triangles, mid_lv, moved_mm) = lv_part.attach(&mut surface, (edge_mm, snap_mm, l.wall), options.grading)?;
    let ao_part = Extension { name: "aortic", near: &annulus, near_name: "aortic annulus", far: stj, far_name: "STJ", far_loop: &stj_loop, far_label: options.outflow_label, far_pool: ("aorta", &pools.aorta) };
    let ao_triangles = ao_part.attach(&mut surface, &ao_union, (edge_mm, snap_mm, l.wall), options.grading)?;
    let extensions_ms = lap();

    let mut checks = vec![check_extended(&surface, domain.triangles.len(), &[l.vsd_cap, l.aortic_cap])?];
    checks.extend(cap_in_pool_checks(&surface, options.inflow_label, "inflow", ("LV", &pools.lv))?);
    checks.extend(cap_in_pool_checks(&surface, options.outflow_label, "outflow", ("aorta", &pools.aorta))?);
    first_failure(&checks).map_err(|m| PrepareError::geometry("extended domain", m))?;
    let baffle_area = |m: &TriMesh| (0..m.triangles.len()).filter(|&t| m.face_ids[t] == l.baffle).map(|t| m.triangle_area_mm2(t)).sum::<f64>();
    let (before, after) = (baffle_area(domain), baffle_area(&surface));
    let report = ExtendReport {
        designed_triangles: domain.triangles.len(),
        triangles: surface.triangles.len(),
        lv_extension_triangles: lv_triangles,
        aortic_extension_triangles: ao_triangles,
        designed_volume_mm3: domain.signed_volume_mm3(),
        volume_mm3: surface.with_labels(|f| f != l.vsd_cap && f != l.aortic_cap).signed_volume_mm3(),
        baffle_area_before_mm2: before,
        baffle_area_after_mm2: after,
        baffle_area_relative_change: if before > 0.0 { (after - before) / before } else { 0.0 },
        interior_labels: [l.vsd_cap, l.aortic_cap],
        vsd_cap: cap_report(&surface, l.vsd_cap)?,
        aortic_cap: cap_report(&surface, l.aortic_cap)?,
        inflow_cap: cap_report(&surface, options.inflow_label)?,
        outflow_cap: cap_report(&surface, options.outflow_label)?,
        mid_lv_plane: MidLvPlaneReport {
            rule: mid_lv_rule(options.inflow_offset_mm),
            point_mm: arr(mid_lv.centroid),
            normal: arr(mid_lv.normal),
            distance_from_vsd_mm: vsd.plane.signed_distance_mm(&mid_lv.centroid),
            moved_from_centroid_mm: moved_mm,
            rv_in_lv_part: format!(
                "the RV only over the VSD: within {VSD_FOOTPRINT_MARGIN_MM} mm of the VSD cap's rim seen along its normal, from {RV_BEHIND_VSD_MM} mm on the RV's side of its plane to {:.1} mm into the LV",
                footprint.depth_mm[1]
            ),
            other_lv_rv_contact: lv_part.other_contact().map(|w| format!("{w}: left out of the LV part, which takes the RV only over the VSD, so it is wall in the extended domain")),
        },
        vsd_cap_off_plane_mm: off_plane_as_given_mm(cap_projections, l.vsd_cap),
        aortic_cap_off_plane_mm: off_plane_as_given_mm(cap_projections, l.aortic_cap),
        cap_projections: cap_projections.to_vec(),
        stj: stj_report,
        remesh_edge_mm: edge_mm,
        grading: options.grading,
        grading_dropped: None,
        checks,
        timings: ExtendTimings { planes_ms, union_ms, extensions_ms, checks_ms: lap() },
    };
    Ok(Extended { surface, report })
}

/// The designed domain with its VSD and aortic caps projected onto their least-squares
/// planes: the method needs each cap's rim and plane, not micrometre planarity
/// (`CapFlatness`).
fn flatten_designed_caps(domain: &TriMesh, labels: &FaceLabels) -> Result<(TriMesh, Vec<CapProjection>), PrepareError> {
    let caps = [(labels.vsd_cap, "VSD"), (labels.aortic_cap, "aortic-annulus")];
    project_caps_onto_planes(domain, &caps).map_err(|e| PrepareError::geometry("designed domain", e))
}

/// The designed domain remeshed at `edge_mm`, checked as the domain given is. Flat caps
/// stay flat: the remesher keeps label boundaries and projects every point back onto its
/// label's faces. On a tightly curved baffle that projection can fold the result through
/// itself, which no later stage could mesh.
fn remeshed_designed_domain(domain: &TriMesh, edge_mm: f64) -> Result<TriMesh, PrepareError> {
    let fail = |m: String| PrepareError::geometry("designed domain", m);
    let options = RemeshOptions { target_edge_mm: edge_mm, guard_slivers: true, ..RemeshOptions::default() };
    let remeshed = remesh_isotropic(domain, &options).map_err(|e| fail(format!("remeshing the designed domain at {edge_mm} mm: {e}")))?;
    if let Some(crossing) = where_it_crosses_itself(&remeshed) {
        return Err(fail(format!("remeshing the designed domain at {edge_mm} mm made it cross itself: {crossing} (try another --remesh-domain-edge-mm)")));
    }
    check_domain(&remeshed)?;
    Ok(remeshed)
}

/// How far the cap labelled `label` was off its plane before the projection.
/// (Every cap `designed_cap` accepted was projected, so each label has its record.)
fn off_plane_as_given_mm(projections: &[CapProjection], label: i32) -> f64 {
    projections.iter().find(|p| p.label == label).map_or(0.0, |p| p.off_plane_mm)
}

/// The moves of the mid-LV plane from the LV centroid to try, in order (mm along the VSD normal).
fn mid_lv_moves_mm(offset_mm: Option<f64>) -> Vec<f64> {
    offset_mm.map_or_else(|| MID_LV_MOVES_MM.to_vec(), |o| vec![o])
}

fn mid_lv_rule(offset_mm: Option<f64>) -> String {
    let rule = "parallel to the VSD cap, through the LV blood pool's volume centroid";
    match offset_mm {
        Some(o) => format!("{rule} moved {o:+.2} mm along the VSD normal (positive: away from the VSD), as asked"),
        None => rule.to_string(),
    }
}

fn arr(v: Vec3) -> [f64; 3] {
    [v.x, v.y, v.z]
}

fn validate_options(options: &ExtendOptions) -> Result<(), PrepareError> {
    validate(&options.union)?;
    if let Some(edge_mm) = options.remesh_domain_edge_mm.filter(|e| !(e.is_finite() && *e > 0.0)) {
        return Err(PrepareError::Option(format!("remeshing the designed domain at {edge_mm} mm: the edge must be a positive length")));
    }
    let l = &options.labels;
    let used = [l.wall, l.baffle, l.vsd_cap, l.aortic_cap];
    for (name, label) in [("inflow", options.inflow_label), ("outflow", options.outflow_label)] {
        if used.contains(&label) || label <= 0 {
            return Err(PrepareError::Option(format!("the {name} cap label must be positive and differ from the domain's labels {used:?}, got {label}")));
        }
    }
    if options.inflow_label == options.outflow_label {
        return Err(PrepareError::Option(format!("the inflow and outflow cap labels must differ, both are {}", options.inflow_label)));
    }
    if let Some(g) = &options.grading {
        g.validate()?;
    }
    let s = &options.stj;
    let positive = [s.step_mm, s.search_diameters, s.window_mm, s.fallback_diameters, s.max_step_change, s.fixed_diameters.unwrap_or(1.0), options.remesh_edge_mm.unwrap_or(1.0)];
    if positive.iter().any(|v| !(v.is_finite() && *v > 0.0)) || !(0.0..1.0).contains(&s.min_drop) {
        return Err(PrepareError::Option(format!("STJ search and remesh settings must be positive (min drop in [0, 1)), got {s:?}, edge {:?}", options.remesh_edge_mm)));
    }
    if !options.inflow_offset_mm.unwrap_or(0.0).is_finite() {
        return Err(PrepareError::Option(format!("the inflow cap offset must be finite, got {:?}", options.inflow_offset_mm)));
    }
    Ok(())
}

fn check_domain(domain: &TriMesh) -> Result<(), PrepareError> {
    check_closed_outward(domain, "designed domain", "it")
}

/// A designed domain has a baffle: without one it is most likely the capped ventricle
/// (`prepare`'s output) given in place of `design`'s domain, and its extension would
/// be a CFD domain of no repair. The user may say it has none.
fn check_baffle(domain: &TriMesh, baffle: i32, without_baffle: bool) -> Result<(), PrepareError> {
    if without_baffle || domain.face_ids.contains(&baffle) {
        return Ok(());
    }
    Err(PrepareError::geometry(
        "designed domain",
        format!("it has no baffle (no triangle labelled {baffle}): is it the capped ventricle rather than `baffle design`'s domain.vtp? Say --no-baffle to extend a domain without one"),
    ))
}

/// The cap labelled `label`, already projected onto its plane: one disk with a single rim.
fn designed_cap(domain: &TriMesh, label: i32, name: &str) -> Result<DesignedCap, PrepareError> {
    let keep: Vec<bool> = domain.face_ids.iter().map(|&l| l == label).collect();
    let (cap, old_of_new) = domain.submesh(&keep);
    if cap.triangles.is_empty() {
        return Err(PrepareError::geometry("designed domain", format!("it has no {name} cap (no triangle labelled {label})")));
    }
    let loops = cap.boundary_loops().map_err(|e| PrepareError::geometry("designed domain", format!("the {name} cap: {e}")))?;
    let [rim] = &loops[..] else {
        return Err(PrepareError::geometry("designed domain", format!("the {name} cap has {} rims, expected 1", loops.len())));
    };
    // Flat to rounding: `extend` projected the caps onto their planes before this.
    let CapFlatness { plane, area_mm2, .. } = cap_flatness(&cap, label).ok_or_else(|| PrepareError::geometry("designed domain", format!("the {name} cap has no area")))?;
    Ok(DesignedCap { plane, rim: rim.iter().map(|&v| old_of_new[v as usize]).collect(), area_mm2 })
}

/// A plane with `normal` through `point`, axes from `like`.
fn parallel_plane(like: &Plane, point: Vec3) -> Plane {
    Plane { centroid: point, ..*like }
}

/// Centroid of the volume a closed, consistently wound surface encloses.
fn volume_centroid(mesh: &TriMesh) -> Option<Vec3> {
    let (mut volume, mut moment) = (0.0, Vec3::zeros());
    for t in 0..mesh.triangles.len() {
        let [a, b, c] = mesh.triangle_points(t);
        let v = a.dot(&b.cross(&c)) / 6.0;
        volume += v;
        moment += v * (a + b + c) / 4.0;
    }
    (volume.abs() > 0.0 && volume.is_finite()).then(|| moment / volume)
}

/// What the LV part is cut from: the LV-RV union, the pools, the VSD cap and the
/// plane through the LV's centroid parallel to it.
struct LvPart<'a> {
    union: &'a TriMesh,
    pools: &'a BloodPools,
    vsd: &'a DesignedCap,
    footprint: &'a VsdFootprint,
    centroid_plane: Plane,
    /// The moves from the centroid plane to try (mm, along its normal), in order.
    moves_mm: Vec<f64>,
    /// Whether the move was asked for (one plane, no fallback).
    fixed: bool,
    inflow_label: i32,
    closing_radius_mm: f64,
}

impl LvPart<'_> {
    /// The LV part between the VSD cap and the mid-LV plane, attached to `surface`:
    /// the plane through the LV's centroid (or at the asked offset), or failing a clean
    /// cut there, the first of `MID_LV_MOVES_MM` that gives one. Returns the part's triangles, the plane used
    /// and how far it was moved (mm); the error lists each move and why it failed.
    fn attach(&self, surface: &mut TriMesh, sizes: (f64, f64, i32), grading: Option<ExtensionGrading>) -> Result<(usize, Plane, f64), PrepareError> {
        let mut tried = Vec::new();
        for &moved_mm in &self.moves_mm {
            let plane = parallel_plane(&self.centroid_plane, self.centroid_plane.centroid + moved_mm * self.centroid_plane.normal);
            let attached = self.section(&plane).and_then(|lv_loop| {
                let part = Extension { name: "LV", near: self.vsd, near_name: "VSD", far: plane, far_name: "mid-LV", far_loop: &lv_loop, far_label: self.inflow_label, far_pool: ("LV", &self.pools.lv) };
                part.attach(surface, self.union, sizes, grading).map_err(|e| e.to_string())
            });
            match attached {
                Ok(triangles) => return Ok((triangles, plane, moved_mm)),
                Err(why) => tried.push(format!("{moved_mm:+.0} mm ({:.1} mm beyond the VSD): {why}", self.vsd.plane.signed_distance_mm(&plane.centroid))),
            }
        }
        let c = self.centroid_plane.centroid;
        if self.fixed {
            return Err(PrepareError::geometry(
                "mid-LV plane",
                format!("the inflow cap offset leaves no valid cut of the LV: moved from the LV centroid ({:.1}, {:.1}, {:.1}) by {}", c.x, c.y, c.z, tried.join("; ")),
            ));
        }
        Err(PrepareError::geometry(
            "mid-LV plane",
            format!(
                "no plane parallel to the VSD cap cuts the LV part cleanly; moved from the LV centroid ({:.1}, {:.1}, {:.1}) along the VSD normal by {}{}",
                c.x, c.y, c.z, tried.join("; "), self.other_contact().map_or_else(String::new, |w| format!("; {w}"))
            ),
        ))
    }

    /// The LV's section in `plane` (the far cut's loop): the plane must lie
    /// `MIN_LV_DEPTH_MM` beyond the VSD cap and cut the LV in one loop (a curved LV
    /// cut in two would leave one arm open to the other).
    fn section(&self, plane: &Plane) -> Result<Vec<Vec3>, String> {
        let depth = self.vsd.plane.signed_distance_mm(&plane.centroid);
        if depth < MIN_LV_DEPTH_MM {
            return Err(format!("the plane lies {depth:.1} mm beyond the VSD cap's plane, need {MIN_LV_DEPTH_MM} mm toward the LV"));
        }
        let mut contours = cut_mesh(&self.pools.lv, plane.centroid, plane.normal);
        contours.sort_by(|a, b| b.signed_area_mm2(&plane.normal).abs().total_cmp(&a.signed_area_mm2(&plane.normal).abs()));
        let Some(largest) = contours.first() else { return Err("the plane misses the LV surface".into()) };
        let largest_mm2 = largest.signed_area_mm2(&plane.normal).abs();
        let loops = contours.iter().filter(|c| c.signed_area_mm2(&plane.normal).abs() > MIN_SECOND_LOOP_FRACTION * largest_mm2).count();
        if loops > 1 {
            return Err(format!("the plane cuts the LV in {loops} loops (a curved LV): one inflow cap would leave the others open"));
        }
        Ok(contours.swap_remove(0).points)
    }

    /// Where the LV comes near the RV outside the VSD's footprint, where the full union
    /// would join them too: the nearest such LV point, said. (Where the pools overlap,
    /// LV points lie on the RV surface to within an edge; no winding test is needed.)
    fn other_contact(&self) -> Option<String> {
        let rv_bvh = TriangleBvh::new(&self.pools.rv).ok()?;
        let joined_within_mm = 2.0 * self.closing_radius_mm + 0.1;
        let away: Vec<&Vec3> = self.pools.lv.points.iter().filter(|p| !self.footprint.contains(p)).collect();
        let (d, p) = away
            .par_iter()
            .filter_map(|p| rv_bvh.closest_point(&self.pools.rv, **p).map(|h| (h.distance_mm, **p)))
            .filter(|(d, _)| *d <= joined_within_mm)
            .min_by(|a, b| a.0.total_cmp(&b.0))?;
        Some(format!(
            "the LV also comes within {d:.2} mm of the RV near ({:.1}, {:.1}, {:.1}), {:.1} mm from the VSD cap's centre (a second VSD, or a septum thinner than the closing)",
            p.x, p.y, p.z, (p - self.vsd.plane.centroid).norm()
        ))
    }
}

/// The part of space where the RV joins the LV part: within `VSD_FOOTPRINT_MARGIN_MM`
/// of the VSD cap's rim polygon seen along the cap's normal, between `depth_mm`
/// along that normal (negative: the RV's side).
struct VsdFootprint {
    plane: Plane,
    /// The rim in the plane's (u, v) coordinates (mm).
    polygon: Vec<(f64, f64)>,
    /// No point of the footprint lies farther than this from the plane's centroid, in the plane (mm).
    reach_mm: f64,
    depth_mm: [f64; 2],
}

impl VsdFootprint {
    /// The footprint of `vsd` (rim points in `domain`) from `RV_BEHIND_VSD_MM` behind
    /// its plane to `depth_mm` into the LV.
    fn new(domain: &TriMesh, vsd: &DesignedCap, depth_mm: f64) -> Self {
        let polygon: Vec<(f64, f64)> = vsd.rim.iter().map(|&v| vsd.plane.project_2d(&domain.points[v as usize])).collect();
        let rim_reach_mm = polygon.iter().map(|&(u, v)| u.hypot(v)).fold(0.0, f64::max);
        VsdFootprint { plane: vsd.plane, polygon, reach_mm: rim_reach_mm + VSD_FOOTPRINT_MARGIN_MM, depth_mm: [-RV_BEHIND_VSD_MM, depth_mm] }
    }

    /// Where the RV joins the LV part's union: the footprint, but beside the rim only
    /// from `below_mm` on the RV's side of the plane, and from there on into the LV only
    /// within the rim polygon shrunk by `inset_mm`. The designed domain's wall beside
    /// the rim may rise onto the LV's side of the cap's plane (a VSD in a dimple of the
    /// septum, a rim projected onto its plane by hand): the RV beside the rim there is
    /// inside the designed domain, and the union's surface around it would lie on the
    /// designed wall, crossing it. The column over the cap then meets the plane inside
    /// the rim (the grid moves a surface by up to half a voxel: `inset_mm` a voxel), and
    /// the closing's fillet at the column's foot stays below the plane (`below_mm`: the
    /// closing radius and a voxel).
    fn joins_lv_part(&self, q: &Vec3, inset_mm: f64, below_mm: f64) -> bool {
        if !self.contains(q) {
            return false;
        }
        if self.plane.signed_distance_mm(q) <= -below_mm {
            return true;
        }
        let uv = self.plane.project_2d(q);
        inside_polygon(&self.polygon, uv) && distance_to_polygon_mm(&self.polygon, uv) >= inset_mm
    }

    fn contains(&self, q: &Vec3) -> bool {
        let depth = self.plane.signed_distance_mm(q);
        let (u, v) = self.plane.project_2d(q);
        if depth < self.depth_mm[0] || depth > self.depth_mm[1] || u.hypot(v) > self.reach_mm {
            return false;
        }
        inside_polygon(&self.polygon, (u, v)) || distance_to_polygon_mm(&self.polygon, (u, v)) <= VSD_FOOTPRINT_MARGIN_MM
    }
}

/// The plane through the LV blood pool's volume centroid, parallel to the VSD cap.
fn lv_centroid_plane(lv: &TriMesh, vsd: &Plane) -> Result<Plane, PrepareError> {
    let centroid = volume_centroid(lv).ok_or_else(|| PrepareError::geometry("mid-LV plane", "the LV surface encloses no volume"))?;
    Ok(parallel_plane(vsd, centroid))
}

/// The STJ plane (parallel to the annulus cap), its report and the aorta's section there.
fn sinotubular_junction(aorta: &TriMesh, annulus: &DesignedCap, opts: &StjOptions) -> Result<(Plane, StjReport, Vec<Vec3>), PrepareError> {
    let diameter_mm = 2.0 * (annulus.area_mm2 / std::f64::consts::PI).sqrt();
    let n = annulus.plane.normal;
    let reach = opts.search_diameters.max(opts.fixed_diameters.unwrap_or(0.0));
    let steps = (reach * diameter_mm / opts.step_mm).ceil() as usize;
    let mut track = annulus.plane.centroid;
    let mut heights = Vec::new();
    let mut sections: Vec<Contour> = Vec::new();
    for k in 1..=steps {
        let h = k as f64 * opts.step_mm;
        let origin = annulus.plane.centroid + h * n;
        let reference = track + (origin - track).dot(&n) * n;
        let nearest = cut_mesh(aorta, origin, n).into_iter().min_by(|a, b| (a.centroid() - reference).norm().total_cmp(&(b.centroid() - reference).norm()));
        let Some(section) = nearest.filter(|c| (c.centroid() - reference).norm() < diameter_mm) else { break };
        track = section.centroid();
        heights.push(h);
        sections.push(section);
    }
    if sections.is_empty() {
        return Err(PrepareError::geometry("STJ", "the aorta surface has no section just above the aortic-annulus cap: does the aorta leave the designed domain there?"));
    }
    let raw: Vec<f64> = sections.iter().map(|c| c.signed_area_mm2(&n).abs()).collect();
    let mut areas = moving_average(&raw, 2);
    let window = ((opts.window_mm / opts.step_mm).round() as usize).max(1);
    // Above the sinuses, the root ends where a step jumps in area (a branch, the arch
    // entering the plane): a minimum needs a gradual rise after it.
    let first_max = first_maximum(&areas, window).unwrap_or(0);
    // The root's sections: up to the first jump (no cap is placed beyond it).
    let root = (first_max + 1..raw.len()).find(|&k| (raw[k] / raw[k - 1] - 1.0).abs() > opts.max_step_change).unwrap_or(raw.len());
    let search_end = root.min((opts.search_diameters * diameter_mm / opts.step_mm).ceil() as usize);
    areas.truncate(root);
    heights.truncate(root);
    let found = area_minimum_after_maximum(&areas[..search_end], window, opts.min_drop);
    let profile: Vec<[f64; 2]> = heights.iter().zip(&areas).map(|(&h, &a)| [h, a]).collect();
    let top_mm = heights.last().copied().unwrap_or(0.0);
    let at_height = |h: f64, what: &str| {
        heights.iter().position(|&x| x >= h - 0.5 * opts.step_mm).ok_or_else(|| {
            let found_note = if found.is_some() { "" } else { "no section-area minimum above the sinuses, and " };
            PrepareError::geometry("STJ", format!("{found_note}the aorta surface's root sections end {top_mm:.1} mm above the annulus (a branch, the arch or the surface's end), below the {what} height {h:.1} mm"))
        })
    };
    let (index, note) = match (opts.fixed_diameters, found) {
        (Some(k), _) => {
            let i = at_height(k * diameter_mm, "asked outflow")?;
            let stj = found.map_or("not found".to_string(), |(_, m)| format!("found at {:.2} mm", heights[m]));
            (i, format!("outflow cap fixed at {k} annulus diameter(s) = {:.2} mm above the annulus, as asked (STJ {stj})", heights[i]))
        }
        (None, Some((_, m))) => (m, format!("first section-area minimum above the sinus maximum, at {:.2} mm above the annulus", heights[m])),
        (None, None) => {
            let i = at_height(opts.fallback_diameters * diameter_mm, "fallback")?;
            (i, format!("STJ not found (no section-area minimum {:.0}% below a maximum in the root's sections up to {:.1} mm): outflow cap at the fallback, {} annulus diameter(s) = {:.2} mm above the annulus", opts.min_drop * 100.0, heights[search_end.max(1) - 1], opts.fallback_diameters, heights[i]))
        }
    };
    let max_k = found.map_or_else(|| (0..=index).max_by(|&a, &b| areas[a].total_cmp(&areas[b])).unwrap_or(0), |(m, _)| m);
    let plane = parallel_plane(&annulus.plane, annulus.plane.centroid + heights[index] * n);
    let report = StjReport {
        found: found.is_some(),
        note,
        distance_from_annulus_mm: heights[index],
        annulus_diameter_mm: diameter_mm,
        sinus_max_area_mm2: areas[max_k],
        sinus_max_distance_mm: heights[max_k],
        stj_area_mm2: areas[index],
        profile,
    };
    Ok((plane, report, sections.swap_remove(index).points))
}

/// Centred moving average over `half` samples either side (fewer at the ends).
fn moving_average(values: &[f64], half: usize) -> Vec<f64> {
    (0..values.len())
        .map(|k| {
            let (lo, hi) = (k.saturating_sub(half), (k + half + 1).min(values.len()));
            values[lo..hi].iter().sum::<f64>() / (hi - lo) as f64
        })
        .collect()
}

/// (maximum, minimum) indices: the first sample that is the largest within `window`
/// samples either side, then the first later one that is the smallest within
/// `window` either side and at least `min_drop` below the maximum.
fn area_minimum_after_maximum(areas: &[f64], window: usize, min_drop: f64) -> Option<(usize, usize)> {
    let around = |k: usize| &areas[k.saturating_sub(window)..(k + window + 1).min(areas.len())];
    let is_min = |k: usize| k + window < areas.len() && around(k).iter().all(|&a| a >= areas[k]);
    let max_k = first_maximum(areas, window)?;
    let min_k = (max_k + 1..areas.len()).find(|&k| is_min(k) && areas[k] <= (1.0 - min_drop) * areas[max_k])?;
    Some((max_k, min_k))
}

/// The first sample that is the largest within `window` samples either side (and has
/// `window` samples after it).
fn first_maximum(areas: &[f64], window: usize) -> Option<usize> {
    let around = |k: usize| &areas[k.saturating_sub(window)..(k + window + 1).min(areas.len())];
    (0..areas.len()).find(|&k| k + window < areas.len() && around(k).iter().all(|&a| a <= areas[k]))
}

/// The box, in `frame`, one part's union must cover: the designed cap's rim and the pool
/// beyond it up to the far plane (with `margin_mm`), all grown by `margin_mm`.
fn part_bounds(frame: &AnatomyFrame, domain: &TriMesh, cap: &DesignedCap, pool: &TriMesh, far: &Plane, margin_mm: f64) -> Aabb {
    let rim = cap.rim.iter().map(|&v| &domain.points[v as usize]);
    let part = pool.points.iter().filter(|p| far.signed_distance_mm(p) <= margin_mm);
    frame.bounds_of(rim.chain(part)).expanded(margin_mm)
}

fn mean_rim_edge_mm(mesh: &TriMesh, rims: &[&Vec<u32>]) -> f64 {
    let (mut sum, mut count) = (0.0, 0usize);
    for rim in rims {
        for i in 0..rim.len() {
            sum += (mesh.points[rim[i] as usize] - mesh.points[rim[(i + 1) % rim.len()] as usize]).norm();
            count += 1;
        }
    }
    sum / count.max(1) as f64
}

/// One part of the extension: from a designed cap (`near`) to a new cap in `far`.
struct Extension<'a> {
    name: &'static str,
    near: &'a DesignedCap,
    near_name: &'static str,
    far: Plane,
    far_name: &'static str,
    far_loop: &'a [Vec3],
    far_label: i32,
    /// The pool the far cap closes (name, surface): its rim must lie on that surface.
    far_pool: (&'static str, &'a TriMesh),
}

impl Extension<'_> {
    /// Cut the part from `union`, cap its far end and zip it to the near cap's rim in
    /// `surface`; returns the triangles added.
    fn attach(&self, surface: &mut TriMesh, union: &TriMesh, (edge_mm, snap_mm, wall): (f64, f64, i32), grading: Option<ExtensionGrading>) -> Result<usize, PrepareError> {
        let step = |m: String| PrepareError::geometry("extension", format!("the {} part: {m}", self.name));
        let near_loop: Vec<Vec3> = self.near.rim.iter().map(|&v| surface.points[v as usize]).collect();
        let cuts = [
            Cut { name: self.near_name, plane: self.near.plane, loop_mm: &near_loop },
            Cut { name: self.far_name, plane: self.far, loop_mm: self.far_loop },
        ];
        let clipped = clip_between(union, &cuts, snap_mm).map_err(step)?;
        self.far_rim_on_pool(&clipped.mesh, &clipped.rims[1]).map_err(step)?;
        let planes = [self.near.plane, self.far];
        let grading = grading.map(|g| g.from_cap(self.near, edge_mm));
        let remeshed = remesh_wall(&clipped, &planes, edge_mm, grading).map_err(step)?;
        let (retracted, near_boundary, far_rim) = retract_rim(&remeshed.mesh, &remeshed.rims[0], &self.far).map_err(step)?;
        let capped = close_with_caps(&Clipped { mesh: retracted, rims: vec![far_rim] }, &[self.far], wall, &[self.far_label]).map_err(step)?;
        let before = surface.triangles.len();
        let offset = surface.points.len() as u32;
        surface.points.extend_from_slice(&capped.points);
        surface.triangles.extend(capped.triangles.iter().map(|t| t.map(|v| v + offset)));
        surface.face_ids.extend_from_slice(&capped.face_ids);
        let inner: Vec<u32> = near_boundary.iter().map(|&v| v + offset).collect();
        let mut band = Vec::new();
        zip_rings(&surface.points, &self.near.rim, &inner, &mut band);
        surface.face_ids.extend(std::iter::repeat_n(wall, band.len()));
        surface.triangles.extend(band);
        Ok(surface.triangles.len() - before)
    }

    /// The far cut's rim must follow the far pool's surface: where the union joins
    /// that pool to another one near the far plane (a septum thinner than the closing,
    /// a second VSD), the cut runs over both, and the cap would close the other too.
    fn far_rim_on_pool(&self, mesh: &TriMesh, rim: &[u32]) -> Result<(), String> {
        let (pool_name, pool) = self.far_pool;
        let bvh = TriangleBvh::new(pool)?;
        let farthest = rim
            .iter()
            .map(|&v| mesh.points[v as usize])
            .filter_map(|p| bvh.closest_point(pool, p).map(|h| (h.distance_mm, p)))
            .max_by(|a, b| a.0.total_cmp(&b.0));
        match farthest {
            Some((d, p)) if d > FAR_RIM_OFF_POOL_MM => Err(format!(
                "the {} cut runs {d:.2} mm off the {} surface near ({:.1}, {:.1}, {:.1}) (over another pool joined to it there; at most {FAR_RIM_OFF_POOL_MM} mm)",
                self.far_name, pool_name, p.x, p.y, p.z
            )),
            _ => Ok(()),
        }
    }
}

/// Drop the triangles touching `rim` (and any left with a pinched boundary): the part
/// then ends one row short of the near plane. Returns it, its new near boundary and
/// its far rim (the loop nearest `far`), both in the part's winding.
fn retract_rim(mesh: &TriMesh, rim: &[u32], far: &Plane) -> Result<(TriMesh, Vec<u32>, Vec<u32>), String> {
    let rim: HashSet<u32> = rim.iter().copied().collect();
    let mut keep: Vec<bool> = mesh.triangles.iter().map(|t| !t.iter().any(|v| rim.contains(v))).collect();
    for _ in 0..8 {
        let (sub, _) = mesh.submesh(&keep);
        if let Ok(loops) = sub.boundary_loops() {
            if loops.len() != 2 {
                return Err(format!("{} openings after dropping the row at the designed cap, expected 2", loops.len()));
            }
            let offset = |lp: &Vec<u32>| lp.iter().map(|&v| far.signed_distance_mm(&sub.points[v as usize]).abs()).sum::<f64>() / lp.len() as f64;
            let far_index = if offset(&loops[0]) <= offset(&loops[1]) { 0 } else { 1 };
            let (far_rim, near) = (loops[far_index].clone(), loops[1 - far_index].clone());
            return Ok((sub, near, far_rim));
        }
        drop_pinches(mesh, &mut keep);
    }
    Err("the row at the designed cap could not be dropped cleanly (pinched boundary)".into())
}

/// Unkeep the triangles with two boundary edges or a corner where the boundary pinches.
fn drop_pinches(mesh: &TriMesh, keep: &mut [bool]) {
    let mut count: HashMap<(u32, u32), usize> = HashMap::new();
    for (_, tri) in mesh.triangles.iter().enumerate().filter(|(t, _)| keep[*t]) {
        for k in 0..3 {
            *count.entry(edge_key(tri[k], tri[(k + 1) % 3])).or_default() += 1;
        }
    }
    let mut degree: HashMap<u32, usize> = HashMap::new();
    for (&(a, b), _) in count.iter().filter(|(_, &c)| c == 1) {
        *degree.entry(a).or_default() += 1;
        *degree.entry(b).or_default() += 1;
    }
    for (t, tri) in mesh.triangles.iter().enumerate() {
        if !keep[t] {
            continue;
        }
        let boundary_edges = (0..3).filter(|&k| count[&edge_key(tri[k], tri[(k + 1) % 3])] == 1).count();
        let pinched = tri.iter().any(|v| degree.get(v).copied().unwrap_or(0) > 2);
        if boundary_edges >= 2 || pinched {
            keep[t] = false;
        }
    }
}

/// The extended surface less its interior caps must be closed, consistently wound and
/// outward; each interior cap edge is shared by 2 triangles inside it and 3 on its rim;
/// no added triangle may cross another.
fn check_extended(surface: &TriMesh, designed_triangles: usize, interior: &[i32]) -> Result<SelfCheck, PrepareError> {
    let fail = |m: String| Err(PrepareError::geometry("extended domain", m));
    let wall = surface.with_labels(|l| !interior.contains(&l));
    check_closed_outward(&wall, "extended domain", "without its interior caps it")?;
    let edges = surface.edge_triangles();
    for (t, tri) in surface.triangles.iter().enumerate().filter(|(t, _)| interior.contains(&surface.face_ids[*t])) {
        for k in 0..3 {
            let n = edges[&edge_key(tri[k], tri[(k + 1) % 3])].len();
            if n != 2 && n != 3 {
                return fail(format!("an edge of interior cap triangle {t} is shared by {n} triangles (expected 2 inside the cap, 3 on its rim)"));
            }
        }
    }
    let bvh = TriangleBvh::new(surface).map_err(|e| PrepareError::geometry("extended domain", e))?;
    let first = designed_triangles as u32;
    let crossings = bvh.self_intersections_par(surface, |_, _| true);
    // The designed domain is input, but the output is the whole surface: a designed
    // domain through itself is named as such, not passed on.
    if let Some(&(a, b)) = crossings.iter().find(|&&(a, b)| a < first && b < first) {
        let [p, q, s] = surface.triangle_points(a as usize);
        let c = (p + q + s) / 3.0;
        return Err(PrepareError::geometry("designed domain", format!("it crosses itself near ({:.1}, {:.1}, {:.1}) mm (triangles {a}, {b})", c.x, c.y, c.z)));
    }
    if let Some(&(a, b)) = crossings.first() {
        let [p, q, s] = surface.triangle_points(a.max(b) as usize);
        let c = (p + q + s) / 3.0;
        return fail(format!("the extension crosses itself or the designed domain near ({:.1}, {:.1}, {:.1}) mm (triangles {a}, {b})", c.x, c.y, c.z));
    }
    let added = surface.triangles.len() - designed_triangles;
    Ok(SelfCheck::at_most("surface crossing itself", 0.0, 0.0, "count", format!("pairs of crossing triangles in the whole surface, {added} of them added (triangle-triangle test over a BVH)")))
}

/// The new cap `label` against the pool it closes, re-measured on the output: its rim
/// on the pool's surface (within `FAR_RIM_OFF_POOL_MM`, what the union's closing and
/// smoothing allow) and its centroid inside the pool (winding number, not the cut that
/// made it).
fn cap_in_pool_checks(surface: &TriMesh, label: i32, name: &str, (pool_name, pool): (&str, &TriMesh)) -> Result<[SelfCheck; 2], PrepareError> {
    let fail = |m: String| PrepareError::geometry("extended domain", m);
    let cap = surface.with_labels(|l| l == label);
    let rim = cap.boundary_loops().map_err(|e| fail(format!("the {name} cap: {e}")))?.concat();
    let bvh = TriangleBvh::new(pool).map_err(fail)?;
    let (off_mm, at) = rim
        .iter()
        .map(|&v| cap.points[v as usize])
        .filter_map(|p| bvh.closest_point(pool, p).map(|h| (h.distance_mm, p)))
        .fold((f64::NAN, Vec3::zeros()), |best, x| if best.0.is_nan() || x.0 > best.0 { x } else { best });
    let rim_check = SelfCheck::at_most(
        &format!("{name} cap rim on the {pool_name} surface"),
        off_mm,
        FAR_RIM_OFF_POOL_MM,
        "mm",
        format!("largest distance of a rim point from the {pool_name} pool's surface, at ({:.1}, {:.1}, {:.1}) mm", at.x, at.y, at.z),
    );
    let (centroid, _, _) = cap.label_centroid_normal(label).ok_or_else(|| fail(format!("the {name} cap has no area")))?;
    let inside = winding_number(pool, centroid).abs();
    let centroid_check = SelfCheck::at_least(
        &format!("{name} cap centroid inside the {pool_name} pool"),
        inside,
        0.5,
        "winding number",
        format!("the {pool_name} surface's winding number at the cap's centroid ({:.1}, {:.1}, {:.1}) mm (1 inside, 0 outside)", centroid.x, centroid.y, centroid.z),
    );
    Ok([rim_check, centroid_check])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_stj_is_the_first_minimum_after_the_sinus_maximum() {
        // Rises to the sinuses at 4, falls to the STJ at 10, widens again.
        let areas: Vec<f64> = (0..30).map(|k| {
            let s = k as f64;
            if s <= 4.0 { 50.0 + 5.0 * s } else if s <= 10.0 { 70.0 - 4.0 * (s - 4.0) } else { 46.0 + 0.5 * (s - 10.0) }
        }).collect();
        assert_eq!(area_minimum_after_maximum(&areas, 2, 0.05), Some((4, 10)));
    }

    #[test]
    fn a_straight_tube_has_no_stj() {
        let areas = vec![50.0; 40];
        // Every sample is a maximum and a minimum, but none lies below the first.
        assert_eq!(area_minimum_after_maximum(&areas, 3, 0.05), None);
        let shallow: Vec<f64> = (0..40).map(|k| 50.0 - 0.01 * (k as f64 - 20.0).abs()).collect();
        assert_eq!(area_minimum_after_maximum(&shallow, 3, 0.05), None);
    }

    #[test]
    fn the_vsd_footprint_is_the_cap_grown_by_the_margin_between_its_depths() {
        // A square cap 4 mm wide in the plane x = 0, normal +x (toward the LV).
        let rim = [(2.0, 2.0), (-2.0, 2.0), (-2.0, -2.0), (2.0, -2.0)];
        let plane = Plane { centroid: Vec3::zeros(), normal: Vec3::x(), axis_u: Vec3::y(), axis_v: Vec3::z(), singular_values: [1.0, 1.0, 0.0] };
        let polygon: Vec<(f64, f64)> = rim.to_vec();
        let f = VsdFootprint { plane, polygon, reach_mm: 2.0 * 2f64.sqrt() + VSD_FOOTPRINT_MARGIN_MM, depth_mm: [-RV_BEHIND_VSD_MM, 10.0] };
        assert!(f.contains(&Vec3::new(5.0, 0.0, 0.0)) && f.contains(&Vec3::new(-5.9, 1.0, 1.0)));
        // Within the margin of an edge, not of the corner's diagonal beyond it.
        assert!(f.contains(&Vec3::new(1.0, 2.0 + 0.99 * VSD_FOOTPRINT_MARGIN_MM, 0.0)));
        assert!(!f.contains(&Vec3::new(1.0, 2.0 + 1.01 * VSD_FOOTPRINT_MARGIN_MM, 0.0)));
        let d = 0.99 * VSD_FOOTPRINT_MARGIN_MM / 2f64.sqrt();
        assert!(f.contains(&Vec3::new(1.0, 2.0 + d, 2.0 + d)) && !f.contains(&Vec3::new(1.0, 2.0 + 1.5 * d, 2.0 + 1.5 * d)));
        // Depth limits: behind the plane on the RV's side, beyond the far depth.
        assert!(!f.contains(&Vec3::new(-RV_BEHIND_VSD_MM - 0.1, 0.0, 0.0)) && !f.contains(&Vec3::new(10.1, 0.0, 0.0)));
    }

    #[test]
    fn the_volume_centroid_of_a_sphere_is_its_centre() {
        let sphere = crate::shapes::uv_sphere(Vec3::new(3.0, -2.0, 5.0), 4.0, 24, 48);
        let c = volume_centroid(&sphere).unwrap();
        assert!((c - Vec3::new(3.0, -2.0, 5.0)).norm() < 1e-9, "{c:?}");
    }
}
