//! The smallest section of the RV-to-pulmonary-artery pathway, before and after the
//! baffle (issue 17: what the tunnel leaves the right ventricle's outflow).
//!
//! On a voxel grid ([`GRID_MM`]) over the capped ventricle:
//! 1. the region: inside the capped ventricle, and (after) outside the designed domain;
//! 2. the outflow end: region voxels next to the pulmonary artery, i.e. next to a voxel
//!    outside the ventricle whose centre is inside the pulmonary segmentation or within
//!    [`CONTACT_MM`] of it (the RV's interface with the pulmonary label). Without such
//!    voxels there is no interface and the figure is unavailable, with the gap in mm;
//! 3. the radius R of each region voxel: its distance to the nearest wall voxel (neither
//!    region nor pulmonary: the interface is an opening, not a wall), exact Euclidean
//!    distance transform;
//! 4. the start: the apex region is the quarter of the region farthest from the outflow
//!    end along the region ([`APEX_FRACTION`] of the largest such distance); the path
//!    starts at its widest voxel (largest R), not at the tip, whose sections shrink to 0;
//! 5. the path: the widest one (its narrowest R as large as any path's, a bottleneck
//!    search), and among those the centred one (Dijkstra with cost |step| / R^2, as the
//!    flow centerline), smoothed and resampled every [`SAMPLE_MM`];
//! 6. at every sample the region is cut by the plane normal to the path: both closed
//!    surfaces' cut segments are filled on a [`PIXEL_MM`](crate::geometry::plane_section::PIXEL_MM) raster (even-odd) and the
//!    4-connected piece holding the sample is the section. The smallest is reported
//!    with its place along the path.
//! 7. what the baffle costs the outflow: along the path after the baffle, each plane is
//!    also filled without the domain, and the piece of the capped ventricle holding the
//!    same pixel is that plane's section before the baffle. The section with the
//!    smallest ratio after / before is the one the baffle narrows most
//!    ([`NarrowedSection`]). The smallest section itself often sits at the pulmonary end,
//!    where the baffle does not act, and is then the same before and after.

use crate::analyses::flow_centerline::{arc_lengths, moving_average, resample};
use crate::geometry::mesh::{TriMesh, Vec3};
use crate::geometry::plane_section::{section_areas, SectionAreas};
use crate::geometry::spatial::{is_outside, Aabb, TriangleBvh};
use crate::geometry::voxel::{best_first_search, squared_distance_transform, voxelize, Grid};
use rayon::prelude::*;
use serde::Serialize;

/// Voxel edge of the path search (mm).
pub const GRID_MM: f64 = 0.5;
/// A voxel outside the RV this close to the pulmonary segmentation (mm) is pulmonary.
pub const CONTACT_MM: f64 = 0.5;
/// The apex region: region voxels at least this fraction of the largest distance from
/// the outflow end (along the region).
pub const APEX_FRACTION: f64 = 0.75;
/// Path samples, and the half-width of its smoothing (mm).
pub const SAMPLE_MM: f64 = 0.5;
const SMOOTHING_MM: f64 = 2.0;

/// The path through one region and its smallest section.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct OutflowPath {
    pub min_section_mm2: f64,
    /// Arc length from the apex end of the path to the smallest section.
    pub min_section_s_mm: f64,
    pub min_section_point_mm: [f64; 3],
    pub min_section_normal: [f64; 3],
    pub path_length_mm: f64,
    /// Sections measured (one every SAMPLE_MM).
    pub sections: usize,
    /// The path's narrowest inscribed radius on the grid (mm).
    pub bottleneck_radius_mm: f64,
}

/// The section of the outflow path after the baffle that the baffle narrows most: the
/// same plane's section of the capped ventricle before the baffle and of what the
/// domain leaves of it after.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct NarrowedSection {
    pub area_before_mm2: f64,
    pub area_after_mm2: f64,
    /// area_after_mm2 / area_before_mm2 (1: the baffle does not narrow the path).
    pub after_over_before: f64,
    /// Along the path from its pulmonary end (the RV's interface with the pulmonary artery).
    pub distance_from_pulmonary_end_mm: f64,
    pub point_mm: [f64; 3],
    pub normal: [f64; 3],
}

/// The RV-to-pulmonary figures of a design, or why there are none.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct RvOutflow {
    /// The smallest section after the baffle (null when unavailable).
    pub rv_outflow_min_section_mm2: Option<f64>,
    pub rv_outflow_min_section_before_mm2: Option<f64>,
    pub rv_outflow_before: Option<OutflowPath>,
    pub rv_outflow_after: Option<OutflowPath>,
    /// Where along the path after the baffle the baffle narrows the outflow most (null
    /// when the path after is not measured).
    pub rv_outflow_most_narrowed: Option<NarrowedSection>,
    /// Why the figures are missing (null when measured).
    pub rv_outflow_unavailable: Option<String>,
    /// Area of the capped ventricle's surface inside the pulmonary segmentation or within
    /// CONTACT_MM of it: the interface the path ends at (null without a pulmonary surface).
    pub rv_pulmonary_interface_mm2: Option<f64>,
}

impl RvOutflow {
    pub fn unavailable(reason: impl Into<String>) -> Self {
        RvOutflow {
            rv_outflow_min_section_mm2: None,
            rv_outflow_min_section_before_mm2: None,
            rv_outflow_before: None,
            rv_outflow_after: None,
            rv_outflow_most_narrowed: None,
            rv_outflow_unavailable: Some(reason.into()),
            rv_pulmonary_interface_mm2: None,
        }
    }
}

impl Default for RvOutflow {
    fn default() -> Self {
        RvOutflow::unavailable("no pulmonary artery surface given (baffle design --pulmonary, --segmentations with pulmonary.vtp, or --labelmap with the pulmonary label, --pulmonary-label, default 7)")
    }
}

/// The smallest RV-to-pulmonary section of the capped `ventricle` before and after the
/// designed `domain` (closed surfaces, mm), the interface taken from `pulmonary`
/// (closed). Errors only on unusable input; no interface is an unavailable figure.
pub fn rv_outflow(ventricle: &TriMesh, domain: &TriMesh, pulmonary: &TriMesh) -> Result<RvOutflow, String> {
    let interface_mm2 = interface_area_mm2(ventricle, pulmonary)?;
    Ok(RvOutflow { rv_pulmonary_interface_mm2: Some(interface_mm2), ..outflow_paths(ventricle, domain, pulmonary)? })
}

/// The capped ventricle's surface area inside the pulmonary surface or within CONTACT_MM
/// of it (by triangle centroids).
fn interface_area_mm2(ventricle: &TriMesh, pulmonary: &TriMesh) -> Result<f64, String> {
    let bvh = TriangleBvh::new(pulmonary)?;
    Ok((0..ventricle.triangles.len())
        .into_par_iter()
        .filter(|&t| {
            let [a, b, c] = ventricle.triangle_points(t);
            let centroid = (a + b + c) / 3.0;
            bvh.closest_point_within(pulmonary, centroid, CONTACT_MM).is_some() || !is_outside(pulmonary, &bvh, centroid)
        })
        .map(|t| ventricle.triangle_area_mm2(t))
        .sum::<f64>()
        .max(0.0))
}

/// The paths before and after the baffle, their smallest sections and, after, the
/// section the baffle narrows most; what is missing after the baffle is said (the
/// figure before stays).
fn outflow_paths(ventricle: &TriMesh, domain: &TriMesh, pulmonary: &TriMesh) -> Result<RvOutflow, String> {
    let field = VoxelField::new(ventricle, domain, pulmonary)?;
    let sections = Sections { ventricle, domain };
    let before = match field.path(false) {
        Ok(path) => sections.along(&path, false).smallest().ok_or("no section of the RV along the path before the baffle")?,
        Err(PathFailure::NoInterface) => return Ok(RvOutflow::unavailable(no_interface_reason(ventricle, pulmonary)?)),
        Err(PathFailure::Other(reason)) => return Ok(RvOutflow::unavailable(reason)),
    };
    let (after, most_narrowed) = match field.path(true) {
        Ok(path) => {
            let measured = sections.along(&path, true);
            (measured.smallest().ok_or_else(|| "no section of the RV along the path after the baffle".to_string()), measured.most_narrowed())
        }
        Err(PathFailure::NoInterface) => (Err("the designed domain covers the RV's interface with the pulmonary artery".to_string()), None),
        Err(PathFailure::Other(reason)) => (Err(reason), None),
    };
    Ok(RvOutflow {
        rv_outflow_min_section_mm2: after.as_ref().ok().map(|a| a.min_section_mm2),
        rv_outflow_min_section_before_mm2: Some(before.min_section_mm2),
        rv_outflow_before: Some(before),
        rv_outflow_unavailable: after.as_ref().err().cloned(),
        rv_outflow_after: after.ok(),
        rv_outflow_most_narrowed: most_narrowed,
        rv_pulmonary_interface_mm2: None,
    })
}

/// "no interface" with the closest approach of the two surfaces (at their vertices).
fn no_interface_reason(ventricle: &TriMesh, pulmonary: &TriMesh) -> Result<String, String> {
    let bvh = TriangleBvh::new(pulmonary)?;
    let gap = ventricle.points.par_iter().filter_map(|&p| bvh.closest_point(pulmonary, p)).map(|h| h.distance_mm).reduce(|| f64::INFINITY, f64::min);
    Ok(format!(
        "the pulmonary artery segmentation does not touch the RV: it is {gap:.1} mm from the capped ventricle (no voxel outside the RV within {CONTACT_MM} mm of it), so there is no RV-pulmonary interface to end the path at (the RV's boundary nearest it need not be its outflow tract: an RV-outflow segment or a marked pulmonary valve plane is needed)"
    ))
}

enum PathFailure {
    NoInterface,
    Other(String),
}

/// The grid's masks: inside the ventricle, inside the domain, pulmonary (outside the RV).
struct VoxelField {
    grid: Grid,
    ventricle: Vec<bool>,
    domain: Vec<bool>,
    pulmonary: Vec<bool>,
}

impl VoxelField {
    fn new(ventricle: &TriMesh, domain: &TriMesh, pulmonary: &TriMesh) -> Result<Self, String> {
        if pulmonary.triangles.is_empty() {
            return Err("the pulmonary artery surface has no triangles".into());
        }
        let bounds = Aabb::from_points(&ventricle.points);
        let mut grid = Grid::covering(bounds.min, bounds.max, GRID_MM, 3);
        // Voxel centres off round coordinates, as for the flow centerline (a plane of the
        // surface through a row of centres is not counted exactly).
        grid.origin -= GRID_MM * Vec3::new(0.137, 0.291, 0.419);
        let inside_ventricle = voxelize(ventricle, &grid);
        let inside_domain = voxelize(domain, &grid);
        let pulmonary_mask = pulmonary_voxels(&grid, &inside_ventricle, pulmonary)?;
        Ok(VoxelField { grid, ventricle: inside_ventricle, domain: inside_domain, pulmonary: pulmonary_mask })
    }

    /// The widest, centred voxel path from the apex region to the pulmonary interface,
    /// smoothed and resampled, with its bottleneck radius.
    fn path(&self, after: bool) -> Result<(Vec<Vec3>, f64), PathFailure> {
        let grid = &self.grid;
        let region: Vec<bool> = (0..grid.voxel_count()).map(|v| self.ventricle[v] && !(after && self.domain[v])).collect();
        let outflow: Vec<usize> = (0..grid.voxel_count()).filter(|&v| region[v] && grid.neighbours26(v).any(|(w, _)| self.pulmonary[w])).collect();
        if outflow.is_empty() {
            return Err(PathFailure::NoInterface);
        }
        let wall: Vec<bool> = (0..grid.voxel_count()).map(|v| !region[v] && !self.pulmonary[v]).collect();
        let radius: Vec<f64> = squared_distance_transform(grid, &wall).into_iter().map(f64::sqrt).collect();
        let start = apex_start(grid, &region, &outflow, &radius).ok_or_else(|| PathFailure::Other("the RV region has no voxel away from the pulmonary interface".into()))?;
        let is_outflow = membership(grid, &outflow);
        // Widest: minimize the running maximum of (R at the start - R), so maximize the
        // narrowest R (the costs stay >= 0 as the search needs).
        let top = radius[start];
        let widest = best_first_search(grid, &[start], |w| region[w], |c, _, w, _| c.max(top - radius[w]), |v| is_outflow[v]);
        let end = widest.reached.ok_or_else(|| PathFailure::Other("the apex region is not connected to the pulmonary interface inside the RV".into()))?;
        let bottleneck = top - widest.cost[end];
        let inv_r2 = |v: usize| 1.0 / (radius[v] * radius[v]);
        // The bottleneck came through a subtraction: compare with a round-off margin.
        let centred = best_first_search(grid, &[start], |w| region[w] && radius[w] >= bottleneck - 1e-9, |c, v, w, len| c + len * 0.5 * (inv_r2(v) + inv_r2(w)), |v| is_outflow[v]);
        let end = centred.reached.ok_or_else(|| PathFailure::Other("no centred path at the bottleneck radius".into()))?;
        let voxels: Vec<Vec3> = centred.path_to(end).into_iter().map(|v| grid.centre(v)).collect();
        let smooth = moving_average(&resample(&voxels, GRID_MM), (SMOOTHING_MM / GRID_MM).round() as usize);
        Ok((resample(&smooth, SAMPLE_MM), bottleneck))
    }
}

fn membership(grid: &Grid, voxels: &[usize]) -> Vec<bool> {
    let mut mask = vec![false; grid.voxel_count()];
    voxels.iter().for_each(|&v| mask[v] = true);
    mask
}

/// Voxels outside the ventricle whose centre is inside the pulmonary surface or within
/// CONTACT_MM of it.
fn pulmonary_voxels(grid: &Grid, inside_ventricle: &[bool], pulmonary: &TriMesh) -> Result<Vec<bool>, String> {
    let inside = voxelize(pulmonary, grid);
    let bvh = TriangleBvh::new(pulmonary)?;
    let near = Aabb::from_points(&pulmonary.points).expanded(CONTACT_MM);
    let near_box = |p: Vec3| (0..3).all(|a| p[a] >= near.min[a] && p[a] <= near.max[a]);
    Ok((0..grid.voxel_count())
        .into_par_iter()
        .map(|v| {
            let p = grid.centre(v);
            !inside_ventricle[v] && (inside[v] || (near_box(p) && bvh.closest_point_within(pulmonary, p, CONTACT_MM).is_some()))
        })
        .collect())
}

/// The widest voxel of the apex region: region voxels at least APEX_FRACTION of the
/// largest distance (along the region) from the outflow end.
fn apex_start(grid: &Grid, region: &[bool], outflow: &[usize], radius: &[f64]) -> Option<usize> {
    let along = best_first_search(grid, outflow, |w| region[w], |c, _, _, len| c + len, |_| false);
    let farthest = along.cost.iter().copied().filter(|c| c.is_finite()).fold(0.0, f64::max);
    if !(farthest > 0.0) {
        return None;
    }
    (0..grid.voxel_count()).filter(|&v| along.cost[v].is_finite() && along.cost[v] >= APEX_FRACTION * farthest).max_by(|&a, &b| radius[a].total_cmp(&radius[b]))
}

/// Sections of the region (the ventricle, less the domain after the baffle).
struct Sections<'a> {
    ventricle: &'a TriMesh,
    domain: &'a TriMesh,
}

impl Sections<'_> {
    /// The sections along `path` (samples, bottleneck radius), each plane filled with
    /// and, after the baffle, without the domain.
    fn along<'p>(&self, (path, bottleneck): &'p (Vec<Vec3>, f64), after: bool) -> Measured<'p> {
        let samples = (0..path.len())
            .into_par_iter()
            .filter_map(|k| {
                let normal = tangent(path, k)?;
                let areas = section_areas(self.ventricle, after.then_some(self.domain), path[k], normal)?;
                Some(Sample { k, normal, areas })
            })
            .collect();
        Measured { path, s: arc_lengths(path), bottleneck_radius_mm: *bottleneck, samples }
    }
}

struct Sample {
    k: usize,
    normal: Vec3,
    areas: SectionAreas,
}

/// The sections measured along one path.
struct Measured<'p> {
    path: &'p [Vec3],
    s: Vec<f64>,
    bottleneck_radius_mm: f64,
    samples: Vec<Sample>,
}

impl Measured<'_> {
    /// The smallest section of the region; None without any.
    fn smallest(&self) -> Option<OutflowPath> {
        let best = self.samples.iter().min_by(|a, b| a.areas.region_mm2.total_cmp(&b.areas.region_mm2))?;
        Some(OutflowPath {
            min_section_mm2: best.areas.region_mm2,
            min_section_s_mm: self.s[best.k],
            min_section_point_mm: self.path[best.k].into(),
            min_section_normal: best.normal.into(),
            path_length_mm: self.length_mm(),
            sections: self.samples.len(),
            bottleneck_radius_mm: self.bottleneck_radius_mm,
        })
    }

    /// The section with the smallest ratio of its area after to before the baffle (the
    /// first of equals, from the apex end).
    fn most_narrowed(&self) -> Option<NarrowedSection> {
        let ratio = |a: &SectionAreas| a.region_mm2 / a.solid_mm2;
        let best = self.samples.iter().filter(|m| m.areas.solid_mm2 > 0.0).min_by(|a, b| ratio(&a.areas).total_cmp(&ratio(&b.areas)))?;
        Some(NarrowedSection {
            area_before_mm2: best.areas.solid_mm2,
            area_after_mm2: best.areas.region_mm2,
            after_over_before: ratio(&best.areas),
            distance_from_pulmonary_end_mm: self.length_mm() - self.s[best.k],
            point_mm: self.path[best.k].into(),
            normal: best.normal.into(),
        })
    }

    fn length_mm(&self) -> f64 {
        *self.s.last().unwrap_or(&0.0)
    }
}

/// Unit tangent of the path at sample k: the chord over SMOOTHING_MM each side (one-sided
/// at the ends, where the smoothing leaves the last voxel steps and their grid directions).
fn tangent(path: &[Vec3], k: usize) -> Option<Vec3> {
    let w = (SMOOTHING_MM / SAMPLE_MM).round() as usize;
    let (a, b) = (k.saturating_sub(w), (k + w).min(path.len().checked_sub(1)?));
    let t = path[b] - path[a];
    (t.norm() > 0.0).then(|| t.normalize())
}

#[cfg(test)]
mod tests;
