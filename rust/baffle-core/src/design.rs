//! The whole area-constrained baffle design [paper 2.3-2.4], step by step, with a
//! progress/cancel callback and the time each step took.

use crate::steps::amplitudes::{arc_displacement, ArcDisplacement};
use crate::geometry::caps::{project_caps_onto_planes, CapProjection};
use crate::steps::centerline::{build_centerline, CapFrame, Centerline};
use crate::steps::envelope::regularize_amplitudes;
use crate::error::DesignError;
use crate::geometry::mesh::{edge_key, manifold_report, FaceLabels, TriMesh, Vec3};
use crate::steps::partition::{keep_capped_side, remesh_kept, KeptRegion};
use crate::steps::patch::{initial_patch, seam_split_mm, DiskMap, InitialPatch, UnitDisk};
use crate::steps::sections::{cut_mesh, nearest_contour, non_conflicting_arcs, split_at_seam, BaffleArc, Contour, Dropped};
use crate::analyses::rv_cost::{rv_cost, RvCost};
use crate::steps::seam::{seam_on_wall, WallProjector};
use crate::geometry::spatial::{Aabb, TriangleBvh};
use crate::steps::surface::Domain;
use crate::target::TargetArea;
use serde::Serialize;
use std::time::Instant;

/// Every tunable of the design, with the paper's values as defaults.
#[derive(Clone, Debug, Serialize, serde::Deserialize)]
#[serde(default)]
pub struct DesignOptions {
    pub labels: FaceLabels,
    /// Points the seam spline is resampled at [2.3.3].
    pub seam_samples: usize,
    /// Largest allowed distance of a suture point from the surface (mm).
    pub max_point_distance_mm: f64,
    /// Isotropic remeshing of the kept region (mm); `None` keeps the input triangles.
    pub remesh_edge_mm: Option<f64>,
    /// Target edge of the baffle's structured disk (mm).
    pub baffle_edge_mm: f64,
    /// Interior TPS control points on R_init for the initial patch [2.3.3].
    pub interior_control_points: usize,
    /// Centerline sample spacing (mm) [2.4.2].
    pub centerline_spacing_mm: f64,
    /// Sections are sized to this multiple of the target area [2.4.4].
    pub area_margin: f64,
    /// Sections with more than this fraction of vertices on the RV wall are dropped [2.4.3].
    pub max_wall_fraction: f64,
    /// Smoothing of the final TPS (0 interpolates the landmarks exactly).
    pub tps_regularization: f64,
    /// Rounds of re-measuring the final surface and raising deficient amplitudes.
    pub max_correction_rounds: usize,
}

impl Default for DesignOptions {
    fn default() -> Self {
        DesignOptions {
            labels: FaceLabels::default(),
            seam_samples: 600,
            max_point_distance_mm: 2.0,
            remesh_edge_mm: Some(0.85),
            baffle_edge_mm: 0.85,
            interior_control_points: 9,
            centerline_spacing_mm: 0.5,
            area_margin: 1.005,
            max_wall_fraction: 0.75,
            tps_regularization: 0.0,
            max_correction_rounds: 6,
        }
    }
}

/// One centerline section and what the design did with it.
#[derive(Clone, Debug, Serialize, serde::Deserialize)]
pub struct SectionRecord {
    pub s_mm: f64,
    pub origin_mm: [f64; 3],
    pub normal: [f64; 3],
    /// "constrained", or why the section was dropped.
    pub status: String,
    pub wall_fraction: Option<f64>,
    pub raw_area_mm2: Option<f64>,
    pub alpha_mm: Option<f64>,
    pub alpha_regularized_mm: Option<f64>,
    pub final_area_mm2: Option<f64>,
}

/// Wall-clock time of each step (ms).
#[derive(Clone, Debug, Default, Serialize, serde::Deserialize)]
pub struct StepTimes {
    pub validate_ms: f64,
    pub seam_ms: f64,
    pub partition_ms: f64,
    pub remesh_ms: f64,
    pub patch_ms: f64,
    pub centerline_ms: f64,
    pub sections_ms: f64,
    pub amplitudes_envelope_surface_ms: f64,
    pub checks_ms: f64,
    pub total_ms: f64,
}

#[derive(Clone, Debug, Serialize, serde::Deserialize)]
pub struct DesignReport {
    pub target_area_mm2: f64,
    pub target: String,
    pub centerline_length_mm: f64,
    pub baffle_area_mm2: f64,
    pub baffle_triangles: usize,
    pub initial_baffle_area_mm2: f64,
    pub domain_triangles: usize,
    pub domain_volume_mm3: f64,
    pub seam_vertices: usize,
    pub discarded_area_mm2: f64,
    pub constrained_sections: usize,
    /// Sections whose baffle arcs cross a constrained one's: checked, not constrained.
    pub checked_only_sections: usize,
    /// Smallest final area over the constrained and the checked-only sections.
    pub min_constrained_final_area_mm2: f64,
    pub correction_rounds: usize,
    pub input_was_inward_wound: bool,
    /// The VSD and aortic caps as found and projected onto their planes.
    pub caps: Vec<CapProjection>,
    /// RV volume before and after the baffle (`rv_volume_before_ml`, ... at the top level).
    #[serde(flatten)]
    pub rv_cost: RvCost,
    pub sections: Vec<SectionRecord>,
    pub timings: StepTimes,
    /// The checks of the result by a second method (`baffle_verify::design_checks`),
    /// filled in by the front end that ran them; empty when none ran.
    pub checks: Vec<crate::analyses::self_check::SelfCheck>,
    /// With the flow-section rule only (`crate::flow_target`): the target applied to the
    /// tunnel's sections normal to the flow, and the design rounds that met it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub flow_sections: Option<FlowSections>,
    /// dp at peak flow and the peak velocity from the reduced-order model
    /// (`crate::analyses::hemodynamics_estimate`), or why there is none; filled in by the front end
    /// that knows the patient's flow (`baffle design --peak-flow-ml-s`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub hemodynamics_estimate: Option<crate::analyses::hemodynamics_estimate::EstimateOutcome>,
}

/// One design round: the target it was run at and the flow-normal section it gave.
#[derive(Clone, Debug, Serialize, serde::Deserialize)]
pub struct FlowRound {
    pub design_target_mm2: f64,
    pub min_flow_section_mm2: f64,
    /// Arc length of that section along the flow-domain centerline, from the VSD plane.
    pub min_flow_section_at_mm: f64,
}

/// What the flow-section rule (`crate::flow_target`) did: the requested area, whether the
/// last round met it, every round, and why it stopped short when it did.
#[derive(Clone, Debug, Serialize, serde::Deserialize)]
pub struct FlowSections {
    pub goal_area_mm2: f64,
    pub met: bool,
    pub rounds: Vec<FlowRound>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stopped_because: Option<String>,
}

/// Everything the design produces.
#[derive(Clone, Debug)]
pub struct DesignResult {
    /// Closed, outward-wound, labelled VSD-to-aorta surface.
    pub domain: TriMesh,
    pub baffle: TriMesh,
    pub initial_baffle: TriMesh,
    /// Seam vertices shared by the wall and the baffle, in loop order (mm).
    pub seam_mm: Vec<Vec3>,
    /// The spline samples projected onto the wall (before insertion).
    pub projected_seam_mm: Vec<Vec3>,
    /// The seam as inserted into the wall: the projected samples plus the points
    /// where it crosses mesh edges between them. Remeshing keeps a subset of these.
    pub imprinted_seam_mm: Vec<Vec3>,
    pub centerline: Centerline,
    /// Closed section loops of the constrained sections as cut on the initial patch,
    /// and with the baffle arc displaced by the regularized amplitude (the targets of
    /// the final TPS).
    pub raw_loops_mm: Vec<Vec<Vec3>>,
    pub regularized_loops_mm: Vec<Vec<Vec3>>,
    pub report: DesignReport,
}

/// Progress callback: (fraction done, stage name) -> keep going?
pub type Progress<'a> = &'a mut dyn FnMut(f64, &str) -> bool;

/// Run the whole design on a closed labelled surface and the surgeon's points.
pub fn design(
    surface: &TriMesh,
    suture_points_mm: &[Vec3],
    target: &TargetArea,
    options: &DesignOptions,
    progress: Progress,
) -> Result<DesignResult, DesignError> {
    let mut clock = Clock::new(progress);
    let labels = options.labels;
    clock.stage(0.0, "validate")?;
    options.validate()?;
    let target_area_mm2 = target.area_mm2().map_err(DesignError::Target)?;
    let ValidatedSurface { surface, input_was_inward_wound, caps } = validated_surface(surface, &labels)?;
    let validate_ms = clock.lap();

    clock.stage(0.05, "seam")?;
    let bvh = TriangleBvh::new(&surface).map_err(DesignError::Surface)?;
    let wall = WallProjector::new(&surface, &bvh, &labels, options.max_point_distance_mm);
    let (projected, imprinted) = seam_on_wall(wall, suture_points_mm, options.seam_samples)?;
    let imprinted_seam_mm: Vec<Vec3> = imprinted.loop_vertices.iter().map(|&v| imprinted.mesh.points[v as usize]).collect();
    let seam_ms = clock.lap();

    clock.stage(0.2, "partition")?;
    let kept = keep_capped_side(&imprinted.mesh, &imprinted.loop_vertices, &labels)?;
    let partition_ms = clock.lap();
    clock.stage(0.3, "remesh")?;
    let kept = match options.remesh_edge_mm {
        Some(edge) => remesh_kept(&kept, edge)?,
        None => kept,
    };
    let remesh_ms = clock.lap();

    clock.stage(0.5, "initial patch")?;
    let seam_mm: Vec<Vec3> = kept.seam_loop.iter().map(|&v| kept.mesh.points[v as usize]).collect();
    let patch = build_initial_patch(&kept, &seam_mm, options)?;
    let initial_domain = Domain::assemble(&kept, &patch.disk, &patch.points_mm, &labels);
    check_watertight(&initial_domain.mesh, "the initial patch joined with the wall")?;
    let patch_ms = clock.lap();

    clock.stage(0.6, "centerline")?;
    let centerline = build_centerline(
        cap_frame(&initial_domain.mesh, labels.vsd_cap)?,
        cap_frame(&initial_domain.mesh, labels.aortic_cap)?,
        &patch.chord,
        options.centerline_spacing_mm,
    )?;
    let centerline_ms = clock.lap();

    clock.stage(0.65, "sections")?;
    let mut sections = measure_sections(&initial_domain, &centerline, &labels, options.max_wall_fraction);
    let sections_ms = clock.lap();

    clock.stage(0.75, "amplitudes, envelope, surface and checks")?;
    let fit = FitInputs { initial: &initial_domain, patch: &patch, seam_mm: &seam_mm, options };
    let fitted = match fit.fit_checked(&mut sections, target_area_mm2) {
        Ok(fitted) => fitted,
        Err(DesignError::Baffle(reason)) => {
            clock.stage(0.9, "largest feasible target")?;
            let max_feasible_area_mm2 = fit.max_feasible_area_mm2(&sections, target_area_mm2);
            return Err(DesignError::Infeasible {
                target_area_mm2,
                max_feasible_area_mm2,
                max_feasible_z_score: target.z_score_of_area(max_feasible_area_mm2),
                reason,
            });
        }
        Err(e) => return Err(e),
    };
    let checks_ms = fitted.checks_ms;
    let surface_ms = clock.lap() - checks_ms;

    let baffle = fitted.domain.baffle_mesh();
    let initial_baffle = initial_domain.baffle_mesh();
    let constrained: Vec<&SectionState> = sections.iter().filter(|s| s.is_constrained()).collect();
    let report = DesignReport {
        target_area_mm2,
        target: target.describe(),
        centerline_length_mm: centerline.length_mm,
        baffle_area_mm2: baffle.area_mm2(),
        baffle_triangles: baffle.triangles.len(),
        initial_baffle_area_mm2: initial_baffle.area_mm2(),
        domain_triangles: fitted.domain.mesh.triangles.len(),
        domain_volume_mm3: fitted.domain.mesh.signed_volume_mm3(),
        seam_vertices: seam_mm.len(),
        discarded_area_mm2: kept.discarded_area_mm2,
        constrained_sections: constrained.len(),
        checked_only_sections: sections.iter().filter(|s| s.is_checked() && !s.is_constrained()).count(),
        min_constrained_final_area_mm2: sections.iter().filter(|s| s.is_checked()).filter_map(|s| s.final_area_mm2).fold(f64::INFINITY, f64::min),
        correction_rounds: fitted.rounds,
        input_was_inward_wound,
        caps,
        rv_cost: rv_cost(&surface, &bvh, &fitted.domain.mesh, &baffle),
        sections: sections.iter().map(SectionState::record).collect(),
        flow_sections: None,
        hemodynamics_estimate: None,
        checks: Vec::new(),
        timings: StepTimes {
            validate_ms,
            seam_ms,
            partition_ms,
            remesh_ms,
            patch_ms,
            centerline_ms,
            sections_ms,
            amplitudes_envelope_surface_ms: surface_ms,
            checks_ms,
            total_ms: clock.total(),
        },
    };
    clock.stage(1.0, "done")?;
    Ok(DesignResult {
        domain: fitted.domain.mesh,
        baffle,
        initial_baffle,
        seam_mm,
        projected_seam_mm: projected.samples_mm,
        imprinted_seam_mm,
        centerline,
        raw_loops_mm: constrained.iter().map(|s| s.loop_points(0.0)).collect(),
        regularized_loops_mm: constrained.iter().map(|s| s.loop_points(s.alpha_regularized_mm)).collect(),
        report,
    })
}

/// Times steps and reports progress; a `false` from the callback cancels.
struct Clock<'a> {
    progress: Progress<'a>,
    start: Instant,
    last: Instant,
}

impl<'a> Clock<'a> {
    fn new(progress: Progress<'a>) -> Self {
        let now = Instant::now();
        Clock { progress, start: now, last: now }
    }
    fn stage(&mut self, fraction: f64, name: &str) -> Result<(), DesignError> {
        if (self.progress)(fraction, name) {
            Ok(())
        } else {
            Err(DesignError::Cancelled(name.to_string()))
        }
    }
    fn lap(&mut self) -> f64 {
        let now = Instant::now();
        let ms = (now - self.last).as_secs_f64() * 1e3;
        self.last = now;
        ms
    }
    fn total(&self) -> f64 {
        self.start.elapsed().as_secs_f64() * 1e3
    }
}

/// No coordinate of a heart lies this far (mm) from the origin of any scanner frame;
/// one that does is a broken number (1e30, a unit error of 10^6) that a design would
/// otherwise carry silently.
const MAX_COORDINATE_MM: f64 = 1.0e5;

/// The input must be a closed manifold with the three labels; an inward-wound
/// surface (as SimVascular writes them) is reversed, and each cap is projected onto its
/// plane once it is shown to be a cap the method can use (`caps::CapFlatness`).
fn validated_surface(surface: &TriMesh, labels: &FaceLabels) -> Result<ValidatedSurface, DesignError> {
    if surface.face_ids.len() != surface.triangles.len() {
        return Err(DesignError::Surface(format!(
            "{} labels for {} triangles",
            surface.face_ids.len(),
            surface.triangles.len()
        )));
    }
    if let Some(i) = surface.points.iter().position(|p| !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite())) {
        return Err(DesignError::Surface(format!("point {i} has a non-finite coordinate")));
    }
    let n = surface.points.len() as u32;
    if let Some(t) = surface.triangles.iter().position(|tri| tri.iter().any(|&v| v >= n)) {
        return Err(DesignError::Surface(format!("triangle {t} refers to a point beyond the {n} points")));
    }
    if let Some(i) = surface.points.iter().position(|p| p.amax() > MAX_COORDINATE_MM) {
        let p = surface.points[i];
        return Err(DesignError::Surface(format!(
            "point {i} lies at ({:.3e}, {:.3e}, {:.3e}) mm, beyond {MAX_COORDINATE_MM} mm of the origin: a broken coordinate, not anatomy",
            p.x, p.y, p.z
        )));
    }
    check_labels(surface, labels)?;
    let rep = manifold_report(surface);
    if !rep.is_closed_manifold() {
        let at = rep.example_edge.map(|(a, b)| {
            let (p, q) = (surface.points[a as usize], surface.points[b as usize]);
            format!(" (e.g. the edge between points {a} and {b} at ({:.2}, {:.2}, {:.2})-({:.2}, {:.2}, {:.2}))", p.x, p.y, p.z, q.x, q.y, q.z)
        });
        return Err(DesignError::Surface(format!(
            "not a closed manifold: {} boundary edges, {} non-manifold edges, {} degenerate triangles{}",
            rep.boundary_edges,
            rep.non_manifold_edges,
            rep.degenerate_triangles,
            at.unwrap_or_default()
        )));
    }
    if rep.inconsistently_wound_edges > 0 {
        return Err(DesignError::Surface(format!(
            "triangles are not consistently wound ({} edges are used twice in the same direction)",
            rep.inconsistently_wound_edges
        )));
    }
    let inward = surface.signed_volume_mm3() < 0.0;
    let mut outward = surface.clone();
    if inward {
        outward.triangles.iter_mut().for_each(|t| t.swap(1, 2));
    }
    let caps = [(labels.vsd_cap, "VSD"), (labels.aortic_cap, "aortic-annulus")];
    let (flat, projections) = project_caps_onto_planes(&outward, &caps).map_err(DesignError::Surface)?;
    Ok(ValidatedSurface { surface: flat, input_was_inward_wound: inward, caps: projections })
}

/// The input as the design uses it: outward, its caps on their planes.
struct ValidatedSurface {
    surface: TriMesh,
    input_was_inward_wound: bool,
    caps: Vec<CapProjection>,
}

/// The three labels must be present, and no other: a stray label is a face the design
/// would silently take as wall (a mislabelled cap, a leftover of an editor).
fn check_labels(surface: &TriMesh, labels: &FaceLabels) -> Result<(), DesignError> {
    let mut present: Vec<i32> = surface.face_ids.clone();
    present.sort_unstable();
    present.dedup();
    let expected = [(labels.wall, "RV wall"), (labels.vsd_cap, "VSD cap"), (labels.aortic_cap, "aortic-annulus cap")];
    for (label, what) in expected {
        if !present.contains(&label) {
            return Err(DesignError::MissingLabel { label, what, present: present.clone() });
        }
    }
    let Some(&stray) = present.iter().find(|l| !expected.iter().any(|(e, _)| e == *l)) else { return Ok(()) };
    let triangles: Vec<usize> = (0..surface.triangles.len()).filter(|&t| surface.face_ids[t] == stray).collect();
    let at = surface.triangle_points(triangles[0]).iter().fold(Vec3::zeros(), |s, p| s + p) / 3.0;
    Err(DesignError::Surface(format!(
        "{} triangle(s) are labelled {stray} (e.g. at ({:.2}, {:.2}, {:.2})), which is none of wall {}, VSD cap {} and aortic cap {}: relabel them, or give the labels (--wall-label, --vsd-label, --aortic-label)",
        triangles.len(), at.x, at.y, at.z, labels.wall, labels.vsd_cap, labels.aortic_cap
    )))
}

fn build_initial_patch(kept: &KeptRegion, seam_mm: &[Vec3], options: &DesignOptions) -> Result<InitialPatch, DesignError> {
    let cap_points = |label: i32| -> Vec<Vec3> {
        let mut pts = Vec::new();
        for (t, tri) in kept.mesh.triangles.iter().enumerate() {
            if kept.mesh.face_ids[t] == label {
                pts.extend(tri.iter().map(|&v| kept.mesh.points[v as usize]));
            }
        }
        pts
    };
    let (vsd, aortic) = (cap_frame(&kept.mesh, options.labels.vsd_cap)?.centroid_mm, cap_frame(&kept.mesh, options.labels.aortic_cap)?.centroid_mm);
    let axis = (vsd - aortic).normalize();
    let vsd_at_mm = seam_split_mm(seam_mm, &cap_points(options.labels.vsd_cap), axis);
    let aortic_at_mm = seam_split_mm(seam_mm, &cap_points(options.labels.aortic_cap), -axis);
    initial_patch(seam_mm, vsd_at_mm, aortic_at_mm, options.interior_control_points, options.baffle_edge_mm)
}

/// A cap's centroid and its inward normal (the domain is wound outward).
fn cap_frame(mesh: &TriMesh, label: i32) -> Result<CapFrame, DesignError> {
    let (centroid_mm, outward, _) = mesh
        .label_centroid_normal(label)
        .ok_or_else(|| DesignError::Surface(format!("the cap labelled {label} has no area")))?;
    Ok(CapFrame { centroid_mm, inward_normal: -outward })
}

/// A centerline section during the design.
#[derive(Clone)]
struct SectionState {
    s_mm: f64,
    origin: Vec3,
    normal: Vec3,
    contour: Option<Contour>,
    dropped: Option<Dropped>,
    wall_fraction: Option<f64>,
    displacement: Option<ArcDisplacement>,
    /// A wall edge on the section's fixed arc: the wall does not move, so the same
    /// section of the final surface is the contour through this edge.
    anchor_edge: Option<(u32, u32)>,
    /// The constrained section (index, s in mm) whose baffle arc this one's crosses:
    /// then this section is only checked, not constrained (`drop_crossing_sections`).
    crosses: Option<(usize, f64)>,
    alpha_mm: f64,
    alpha_regularized_mm: f64,
    final_area_mm2: Option<f64>,
}

impl SectionState {
    /// The section takes part in the area constraint (its loop is a TPS landmark).
    fn is_constrained(&self) -> bool {
        self.displacement.is_some() && self.crosses.is_none()
    }

    /// The section's final area is checked against the target.
    fn is_checked(&self) -> bool {
        self.displacement.is_some()
    }

    fn record(&self) -> SectionRecord {
        let status = match (&self.dropped, &self.displacement, self.crosses) {
            (_, Some(_), Some((_, s))) => format!("checked only: its baffle arc crosses the constrained section at s = {s:.1} mm"),
            (_, Some(_), None) => "constrained".to_string(),
            (Some(Dropped::NoContour), _, _) => "dropped: no closed contour".to_string(),
            (Some(Dropped::MostlyWall { wall_fraction }), _, _) => format!("dropped: {:.0}% of vertices on the RV wall", wall_fraction * 100.0),
            (Some(Dropped::NoBaffleArc), _, _) => "dropped: no baffle arc".to_string(),
            (None, None, _) => "dropped: degenerate baffle arc".to_string(),
        };
        let constrained = self.is_constrained();
        SectionRecord {
            s_mm: self.s_mm,
            origin_mm: self.origin.into(),
            normal: self.normal.into(),
            status,
            wall_fraction: self.wall_fraction,
            raw_area_mm2: self.displacement.as_ref().map(|d| d.area0_mm2),
            alpha_mm: constrained.then_some(self.alpha_mm),
            alpha_regularized_mm: constrained.then_some(self.alpha_regularized_mm),
            final_area_mm2: self.final_area_mm2,
        }
    }

    /// Area of the same section on `mesh` (the initial domain with its baffle moved):
    /// the contour through the fixed wall edge, or failing one the contour nearest
    /// the centerline point. The nearest contour alone can be a small loop of a
    /// wrinkled baffle and would read the section as empty.
    fn measured_area_mm2(&self, mesh: &TriMesh) -> Option<f64> {
        let contours = cut_mesh(mesh, self.origin, self.normal);
        let anchored = self.anchor_edge.and_then(|e| contours.iter().position(|c| c.point_edges.iter().any(|&pe| edge_key(pe.0, pe.1) == edge_key(e.0, e.1))));
        let contour = match anchored {
            Some(i) => contours.into_iter().nth(i),
            None => nearest_contour(contours, self.origin),
        };
        contour.map(|c| c.signed_area_mm2(&self.normal).abs())
    }

    /// The baffle arc in disk coordinates, point for point (empty unless the section
    /// has one and every arc point lies on a baffle edge).
    fn disk_arc(&self, initial: &Domain, disk: &UnitDisk) -> Vec<(f64, f64)> {
        let (Some(c), Some(d)) = (&self.contour, &self.displacement) else { return Vec::new() };
        d.arc_indices.iter().map(|&i| initial.disk_uv_on_edge(disk, c.point_edges[i], c.point_fractions[i])).collect::<Option<Vec<_>>>().unwrap_or_default()
    }

    /// Where the regularized loop puts the arc point at `position` (arc point index
    /// plus fraction towards the next one).
    fn target_on_arc(&self, position: f64) -> Option<Vec3> {
        let (Some(c), Some(d)) = (&self.contour, &self.displacement) else { return None };
        let last = d.arc_indices.len().checked_sub(1)?;
        let k = (position.floor().max(0.0) as usize).min(last);
        let f = (position - k as f64).clamp(0.0, 1.0);
        let at = |m: usize| c.points[d.arc_indices[m]] + self.alpha_regularized_mm * d.weights[m] * d.direction;
        Some(at(k) + f * (at((k + 1).min(last)) - at(k)))
    }

    /// The section loop with its baffle arc displaced by `alpha_mm`.
    fn loop_points(&self, alpha_mm: f64) -> Vec<Vec3> {
        match (&self.contour, &self.displacement) {
            (Some(c), Some(d)) => {
                let mut points = c.points.clone();
                for (p, &i) in d.displaced_arc(&c.points, alpha_mm).into_iter().zip(&d.arc_indices) {
                    points[i] = p;
                }
                points
            }
            _ => Vec::new(),
        }
    }
}

/// Cut the initial domain at every centerline sample and set up each baffle arc's
/// displacement [2.4.3, 2.4.4].
fn measure_sections(domain: &Domain, centerline: &Centerline, labels: &FaceLabels, max_wall_fraction: f64) -> Vec<SectionState> {
    use rayon::prelude::*;
    centerline
        .samples
        .par_iter()
        .map(|sample| {
            let mut state = SectionState {
                s_mm: sample.s_mm,
                origin: sample.point,
                normal: sample.unit_tangent,
                contour: None,
                dropped: None,
                wall_fraction: None,
                displacement: None,
                anchor_edge: None,
                crosses: None,
                alpha_mm: 0.0,
                alpha_regularized_mm: 0.0,
                final_area_mm2: None,
            };
            let Some(contour) = nearest_contour(cut_mesh(&domain.mesh, sample.point, sample.unit_tangent), sample.point) else {
                state.dropped = Some(Dropped::NoContour);
                return state;
            };
            match split_at_seam(&domain.mesh, &contour, labels, max_wall_fraction) {
                Ok(arc) => {
                    state.displacement = arc_displacement(&contour.points, &arc, &sample.unit_tangent);
                    state.anchor_edge = fixed_anchor_edge(&contour, &arc, domain.first_baffle_vertex);
                }
                Err(why) => {
                    if let Dropped::MostlyWall { wall_fraction } = why {
                        state.wall_fraction = Some(wall_fraction);
                    }
                    state.dropped = Some(why);
                }
            }
            state.contour = Some(contour);
            state
        })
        .collect()
}

struct FittedBaffle {
    domain: Domain,
    rounds: usize,
    /// Time of the final domain's checks (ms).
    checks_ms: f64,
}

/// What the fit of the final surface works on, fixed for every target tried.
#[derive(Clone, Copy)]
struct FitInputs<'a> {
    initial: &'a Domain,
    patch: &'a InitialPatch,
    seam_mm: &'a [Vec3],
    options: &'a DesignOptions,
}

/// Bisection steps of the largest feasible target: 1/256 of the target (the error
/// text quotes that resolution).
const FEASIBILITY_BISECTIONS: usize = 8;

impl FitInputs<'_> {
    /// The final surface for `target_area_mm2` and the checks of the domain it makes.
    fn fit_checked(&self, sections: &mut [SectionState], target_area_mm2: f64) -> Result<FittedBaffle, DesignError> {
        let mut fitted = fit_baffle(self, sections, target_area_mm2)?;
        let start = Instant::now();
        check_domain(&fitted.domain.mesh, &fitted.domain, &self.options.labels)?;
        fitted.checks_ms = start.elapsed().as_secs_f64() * 1e3;
        Ok(fitted)
    }

    /// The largest target (mm2, within 1/256 of `target_area_mm2`) for which the fit
    /// and its checks succeed: what the surgeon's seam admits when the target fails.
    fn max_feasible_area_mm2(&self, sections: &[SectionState], target_area_mm2: f64) -> f64 {
        let (mut feasible, mut infeasible) = (0.0, target_area_mm2);
        for _ in 0..FEASIBILITY_BISECTIONS {
            let trial_mm2 = 0.5 * (feasible + infeasible);
            if self.fit_checked(&mut sections.to_vec(), trial_mm2).is_ok() {
                feasible = trial_mm2;
            } else {
                infeasible = trial_mm2;
            }
        }
        feasible
    }
}

/// Amplitudes, envelope and final surface [2.4.4-2.4.6], re-measured on the result:
/// where a section of the final surface falls short of the target (the TPS passes
/// near, not exactly through, every loop), its amplitude is raised by the shortfall
/// and the envelope and surface are rebuilt.
fn fit_baffle(fit: &FitInputs, sections: &mut [SectionState], target_area_mm2: f64) -> Result<FittedBaffle, DesignError> {
    let FitInputs { initial, patch, seam_mm, options } = *fit;
    let required_mm2 = options.area_margin * target_area_mm2;
    for s in sections.iter_mut() {
        s.crosses = None;
        s.final_area_mm2 = None;
        if let Some(d) = &s.displacement {
            s.alpha_mm = d.required_alpha_mm(required_mm2);
        }
    }
    drop_crossing_sections(initial, &patch.disk, sections, options.baffle_edge_mm)?;
    // Sections are 0.5 mm apart; one landmark every two baffle edges along each arc
    // already puts about as many landmarks as the baffle has vertices.
    let sites = loop_sites(initial, &patch.disk, sections, 2.0 * options.baffle_edge_mm);
    let params: Vec<(f64, f64)> = sites.iter().map(|s| s.uv).collect();
    let map = DiskMap::new(&patch.disk, &params, options.tps_regularization)
        .map_err(|m| DesignError::numerical("final surface TPS", m))?;
    let mut boost = vec![0.0; sections.len()];
    for round in 0..=options.max_correction_rounds {
        regularize(sections, &boost)?;
        let targets: Vec<Vec3> = sites.iter().map(|site| site.target_mm(sections)).collect();
        let points = map.points(seam_mm, &targets).map_err(|m| DesignError::numerical("final surface TPS", m))?;
        let domain = initial.with_patch_points(&points);
        let mut short = false;
        for k in 0..sections.len() {
            let s = &mut sections[k];
            let Some(d) = &s.displacement else { continue };
            let area = s.measured_area_mm2(&domain.mesh);
            s.final_area_mm2 = area;
            let area = area.unwrap_or(0.0);
            if area < target_area_mm2 {
                short = true;
                // A checked-only section is raised through the constrained section
                // whose arc it crosses: they share those baffle points.
                let owner = s.crosses.map_or(k, |(j, _)| j);
                boost[owner] += (required_mm2 - area) / d.slope_mm;
            }
        }
        if !short {
            return Ok(FittedBaffle { domain, rounds: round, checks_ms: 0.0 });
        }
    }
    let worst = sections
        .iter()
        .filter(|s| s.is_checked())
        .min_by(|a, b| a.final_area_mm2.unwrap_or(0.0).total_cmp(&b.final_area_mm2.unwrap_or(0.0)));
    Err(DesignError::Baffle(match worst {
        Some(s) => format!(
            "could not reach the target area {target_area_mm2:.1} mm2 at s = {:.1} mm along the centerline (reached {:.1} mm2)",
            s.s_mm,
            s.final_area_mm2.unwrap_or(0.0)
        ),
        None => "could not reach the target area".to_string(),
    }))
}

/// Two section loops may ask the same baffle point to be this far apart (a
/// fraction of the baffle edge) before one of them gives way: below it the final
/// TPS folds less than a quarter of a triangle.
const MAX_TARGET_CONFLICT_EDGES: f64 = 0.25;

/// Keep as constrained only sections whose displaced loops agree where their baffle
/// arcs cross. Where the centerline bends more sharply than the tunnel is wide, the
/// planes of sections before and after the bend meet on the baffle; constraining
/// both would ask the final TPS to move the same baffle point to two targets
/// millimetres apart, and the surface wrinkles (p1). The sections needing the
/// largest amplitude (then the narrowest) are kept first; the others are only
/// checked. The paper constrains every section [2.4.4]; where amplitudes are zero
/// or the arcs do not cross, so do we.
fn drop_crossing_sections(initial: &Domain, disk: &UnitDisk, sections: &mut [SectionState], baffle_edge_mm: f64) -> Result<(), DesignError> {
    regularize(sections, &vec![0.0; sections.len()])?;
    let candidates: Vec<usize> = (0..sections.len()).filter(|&k| sections[k].displacement.is_some()).collect();
    let arcs: Vec<Vec<(f64, f64)>> = candidates.iter().map(|&k| sections[k].disk_arc(initial, disk)).collect();
    let key = |i: usize| {
        let s = &sections[candidates[i]];
        (s.alpha_mm, s.displacement.as_ref().map_or(f64::INFINITY, |d| d.area0_mm2))
    };
    let mut order: Vec<usize> = (0..candidates.len()).collect();
    order.sort_by(|&a, &b| {
        let (ka, kb) = (key(a), key(b));
        kb.0.total_cmp(&ka.0).then(ka.1.total_cmp(&kb.1))
    });
    let tolerance_mm = MAX_TARGET_CONFLICT_EDGES * baffle_edge_mm;
    let conflict = |i: usize, j: usize, ti: f64, tj: f64| {
        let (a, b) = (&sections[candidates[i]], &sections[candidates[j]]);
        match (a.target_on_arc(ti), b.target_on_arc(tj)) {
            (Some(pa), Some(pb)) => (pa - pb).norm() > tolerance_mm,
            _ => false,
        }
    };
    let verdicts = non_conflicting_arcs(&arcs, &order, conflict);
    for (i, crossed) in verdicts.into_iter().enumerate() {
        if let Some(j) = crossed {
            let kept = candidates[j];
            sections[candidates[i]].crosses = Some((kept, sections[kept].s_mm));
        }
    }
    Ok(())
}

/// Least concave majorant of (alpha + boost) over the constrained sections.
fn regularize(sections: &mut [SectionState], boost: &[f64]) -> Result<(), DesignError> {
    let idx: Vec<usize> = (0..sections.len()).filter(|&k| sections[k].is_constrained()).collect();
    if idx.is_empty() {
        return Err(DesignError::Baffle(
            "no centerline section crosses the baffle; the suture line may not surround the tunnel between the caps".into(),
        ));
    }
    let s: Vec<f64> = idx.iter().map(|&k| sections[k].s_mm).collect();
    let a: Vec<f64> = idx.iter().map(|&k| sections[k].alpha_mm + boost[k]).collect();
    let reg = regularize_amplitudes(&s, &a)?;
    for (&k, r) in idx.iter().zip(reg) {
        sections[k].alpha_regularized_mm = r;
    }
    Ok(())
}

/// An interior landmark of the final surface: point `arc_position` of section
/// `section`'s baffle arc, at disk coordinates `uv` (taken on the initial patch).
struct LoopSite {
    section: usize,
    arc_position: usize,
    uv: (f64, f64),
}

impl LoopSite {
    /// Where the regularized loop puts this point.
    fn target_mm(&self, sections: &[SectionState]) -> Vec3 {
        let s = &sections[self.section];
        match (&s.contour, &s.displacement) {
            (Some(c), Some(d)) => {
                let i = d.arc_indices[self.arc_position];
                c.points[i] + s.alpha_regularized_mm * d.weights[self.arc_position] * d.direction
            }
            _ => Vec3::zeros(),
        }
    }
}

/// The landmark sites: interior points of every constrained baffle arc, about one
/// per `spacing_mm` (the arc endpoints lie on the seam, already a landmark), at most
/// one per tiny disk neighbourhood (two loops meeting at nearly the same disk point
/// would make the TPS system singular).
fn loop_sites(initial: &Domain, disk: &UnitDisk, sections: &[SectionState], spacing_mm: f64) -> Vec<LoopSite> {
    let mut sites: Vec<LoopSite> = Vec::new();
    let mut taken = DiskGrid::new(1e-3);
    for (k, s) in sections.iter().enumerate() {
        let (Some(contour), Some(d), true) = (&s.contour, &s.displacement, s.is_constrained()) else { continue };
        let arc: Vec<Vec3> = d.arc_indices.iter().map(|&i| contour.points[i]).collect();
        for arc_position in spaced_interior_points(&arc, spacing_mm) {
            let i = d.arc_indices[arc_position];
            let Some(uv) = initial.disk_uv_on_edge(disk, contour.point_edges[i], contour.point_fractions[i]) else { continue };
            if taken.insert(uv) {
                sites.push(LoopSite { section: k, arc_position, uv });
            }
        }
    }
    sites
}

/// Disk points kept at least `min_gap` apart (a hash grid of that cell size).
struct DiskGrid {
    min_gap: f64,
    cells: std::collections::HashMap<(i64, i64), Vec<(f64, f64)>>,
}

impl DiskGrid {
    fn new(min_gap: f64) -> Self {
        DiskGrid { min_gap, cells: std::collections::HashMap::new() }
    }

    /// Keep `uv` unless a kept point is closer than `min_gap`; true if kept.
    fn insert(&mut self, uv: (f64, f64)) -> bool {
        let key = ((uv.0 / self.min_gap).floor() as i64, (uv.1 / self.min_gap).floor() as i64);
        let near = (-1..=1).flat_map(|dx| (-1..=1).map(move |dy| (key.0 + dx, key.1 + dy))).any(|k| {
            self.cells.get(&k).is_some_and(|pts| pts.iter().any(|q| (q.0 - uv.0).hypot(q.1 - uv.1) < self.min_gap))
        });
        if !near {
            self.cells.entry(key).or_default().push(uv);
        }
        !near
    }
}

/// Indices of interior points of a polyline, each at least `spacing_mm` (along the
/// line) after the previous one and before the end: the arc is sampled about as
/// finely as the baffle mesh, which keeps the TPS system small.
fn spaced_interior_points(line: &[Vec3], spacing_mm: f64) -> Vec<usize> {
    let n = line.len();
    let mut out = Vec::new();
    let total: f64 = line.windows(2).map(|w| (w[1] - w[0]).norm()).sum();
    let (mut run, mut since_last) = (0.0, 0.0);
    for k in 1..n.saturating_sub(1) {
        let step = (line[k] - line[k - 1]).norm();
        run += step;
        since_last += step;
        if since_last >= spacing_mm && total - run >= 0.5 * spacing_mm {
            out.push(k);
            since_last = 0.0;
        }
    }
    out
}

/// A point of the section's fixed arc that lies on an edge between two wall (or
/// cap) vertices, which the final surface does not move: its edge identifies the
/// same section on every later surface.
fn fixed_anchor_edge(contour: &Contour, arc: &BaffleArc, first_baffle_vertex: usize) -> Option<(u32, u32)> {
    let n = contour.points.len();
    let on_arc = arc.indices(n);
    let fixed: Vec<usize> = (0..n)
        .filter(|i| !on_arc.contains(i))
        .filter(|&i| {
            let (a, b) = contour.point_edges[i];
            (a as usize) < first_baffle_vertex && (b as usize) < first_baffle_vertex
        })
        .collect();
    fixed.get(fixed.len() / 2).map(|&i| contour.point_edges[i])
}

/// Closed, manifold, consistently wound and connected (one component).
fn check_watertight(mesh: &TriMesh, what: &str) -> Result<(), DesignError> {
    let rep = manifold_report(mesh);
    if !rep.is_closed_manifold() || rep.inconsistently_wound_edges > 0 {
        return Err(DesignError::Baffle(format!("{what} is not watertight: {rep:?}")));
    }
    let neighbors = mesh.triangle_neighbors();
    let mut seen = vec![false; mesh.triangles.len()];
    let mut stack = vec![0usize];
    seen[0] = true;
    while let Some(t) = stack.pop() {
        for &nb in &neighbors[t] {
            if !seen[nb as usize] {
                seen[nb as usize] = true;
                stack.push(nb as usize);
            }
        }
    }
    if let Some(t) = seen.iter().position(|s| !s) {
        return Err(DesignError::Baffle(format!("{what} is not connected (triangle {t} is cut off)")));
    }
    Ok(())
}

/// The bounding box of the domain's kept wall and caps (every triangle before the baffle's).
fn wall_bounds(mesh: &TriMesh, domain: &Domain) -> Aabb {
    Aabb::from_points(mesh.triangles[..domain.first_baffle_triangle].iter().flatten().map(|&v| &mesh.points[v as usize]))
}

/// The final domain must be closed, manifold, outward and free of self-intersections.
fn check_domain(mesh: &TriMesh, domain: &Domain, labels: &FaceLabels) -> Result<(), DesignError> {
    check_watertight(mesh, "the merged domain")?;
    if mesh.signed_volume_mm3() <= 0.0 {
        return Err(DesignError::Baffle("the merged domain encloses no positive volume".into()));
    }
    let bvh = TriangleBvh::new(mesh).map_err(DesignError::Surface)?;
    // Every pair, the wall's with itself too: a kept wall that folds through itself
    // (a dented or badly smoothed ventricle) gives a domain no mesher can fill, even
    // when the baffle is clear of it.
    let pairs = bvh.self_intersections_par(mesh, |_, _| true);
    if let Some(&(a, b)) = pairs.iter().find(|(a, b)| {
        (*a as usize) >= domain.first_baffle_triangle || (*b as usize) >= domain.first_baffle_triangle
    }) {
        let t = if (a as usize) >= domain.first_baffle_triangle { b } else { a };
        let label = mesh.face_ids[t as usize];
        let c = mesh.triangle_centroid(t as usize);
        let what = if label == labels.baffle { "itself" } else { "the ventricle wall" };
        // A baffle blown far out of the ventricle meets itself out there too: naming
        // that place would send the user looking where no anatomy is.
        let beyond_mm = wall_bounds(mesh, domain).distance_squared_mm2(&c).sqrt();
        if beyond_mm > 1.0 {
            return Err(DesignError::Baffle(format!(
                "reaching the target area pushes the baffle out of the ventricle ({beyond_mm:.0} mm beyond its \
                 walls, where it passes through {what}); the suture line leaves too little room for the required tunnel"
            )));
        }
        return Err(DesignError::Baffle(format!(
            "reaching the target area makes the baffle pass through {what} near ({:.1}, {:.1}, {:.1}); \
             the suture line leaves too little room for the required tunnel",
            c.x, c.y, c.z
        )));
    }
    // No baffle triangle in the pair: the input surface folds through itself, whatever the
    // target. A surface error, so no search for a feasible target blames the suture points.
    if let Some(&(a, _)) = pairs.first() {
        let c = mesh.triangle_centroid(a as usize);
        return Err(DesignError::Surface(format!(
            "the ventricle wall kept in the domain crosses itself near ({:.1}, {:.1}, {:.1}) mm ({} crossing pairs); \
             the ventricle surface folds there: smooth or re-segment it",
            c.x, c.y, c.z,
            pairs.len()
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The unit cube with its top face a fan to a centre point at height `apex_z`: below
    /// 0 the fan passes through the bottom face (closed, connected, outward, crossing).
    fn cube_with_top_apex(apex_z: f64) -> TriMesh {
        let corners = [[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.], [0., 0., 1.], [1., 0., 1.], [1., 1., 1.], [0., 1., 1.]];
        let mut points: Vec<Vec3> = corners.iter().map(|c| Vec3::new(c[0], c[1], c[2])).collect();
        points.push(Vec3::new(0.5, 0.5, apex_z));
        let triangles = vec![[0, 2, 1], [0, 3, 2], [0, 1, 5], [0, 5, 4], [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7], [4, 5, 8], [5, 6, 8], [6, 7, 8], [7, 4, 8]];
        let face_ids = vec![2; triangles.len()];
        TriMesh { points, triangles, face_ids }
    }

    fn wall_only(mesh: &TriMesh) -> Domain {
        let first = mesh.triangles.len();
        Domain { mesh: mesh.clone(), disk_vertex: vec![], domain_vertex_of_disk: vec![], first_baffle_triangle: first, first_baffle_vertex: mesh.points.len() }
    }

    #[test]
    fn a_kept_wall_through_itself_is_refused_though_no_baffle_triangle_crosses() {
        let folded = cube_with_top_apex(-0.5);
        let err = check_domain(&folded, &wall_only(&folded), &FaceLabels::default()).unwrap_err();
        assert!(matches!(err, DesignError::Surface(_)), "the input's fault, not the target's: {err:?}");
        let err = err.to_string();
        assert!(err.contains("the ventricle wall kept in the domain crosses itself near") && err.contains("crossing pairs"), "{err}");
        let sound = cube_with_top_apex(1.5);
        assert!(check_domain(&sound, &wall_only(&sound), &FaceLabels::default()).is_ok());
    }
}
