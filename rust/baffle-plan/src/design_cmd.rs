//! `baffle design`: its arguments, the target from them, the design run with its
//! progress and summary lines (also the plan's design stage and the sweep's rows).

use crate::error::PlanError;
use crate::progress::Progress;
use baffle_core::io::{read_points, read_surface_labeled, write_markups_closed_curve, write_trimesh_vtp, CoordinateSystem};
use baffle_core::geometry::caps::{label_planar_caps, CapSeed, CapTolerances};
use baffle_core::io::outputs::write_design_outputs;
use baffle_core::analyses::hemodynamics_estimate::{Blood, EstimateOutcome};
use baffle_core::phantom::phantom_default;
use baffle_core::analyses::rv_outflow::{rv_outflow, RvOutflow};
use baffle_core::{design, DesignError, DesignOptions, DesignResult, TargetArea, TriMesh};
/// The point type of `DesignSettings`' cap points, and the face labels it and the other commands' settings hold.
pub use baffle_core::{FaceLabels, Vec3};
use crate::{feasibility, files};
use std::path::{Path, PathBuf};

// Required-ness of --surface/--points is checked at run time (read_inputs), so that
// `baffle plan` can offer other sources of the surface.
documented_settings! {
#[derive(Clone)]
pub struct DesignSettings {
    /// Closed, labelled ventricle surface (.vtp, .vtk or .stl), in mm (required unless --phantom).
    pub surface: Option<PathBuf>,
    /// Suture points: Slicer markups (.mrk.json), .fcsv, CSV (x,y,z per line) or JSON (required unless --phantom).
    pub points: Option<PathBuf>,
    /// Use the built-in synthetic phantom as surface and points (BSA 0.37 m2 unless given).
    pub phantom: bool,
    /// Output directory.
    pub out: PathBuf,
    pub target: TargetSettings,
    /// Frame of the surface file; suture points are converted into it. Slicer writes
    /// models in LPS.
    pub surface_frame: Frame,
    /// Target edge length of the isotropic remeshing of the kept wall (mm).
    pub remesh_edge_mm: f64,
    /// Keep the input's wall triangles (no isotropic remeshing).
    pub no_remesh: bool,
    /// Target edge length of the baffle (mm).
    pub baffle_edge_mm: f64,
    /// Points the seam spline is resampled at.
    pub seam_samples: usize,
    /// Centerline section spacing (mm).
    pub centerline_spacing_mm: f64,
    /// Interior TPS control points of the initial patch.
    pub control_points: usize,
    /// Largest distance of a suture point from the surface (mm).
    pub max_point_distance_mm: f64,
    /// ModelFaceIDs of the RV wall, the VSD and aortic-annulus caps, and the one given to the baffle.
    pub labels: FaceLabels,
    /// A point (x,y,z in the surface's frame, mm) on the VSD cap: labels the planar
    /// cap around it. Needed for surfaces without ModelFaceID (.stl, plain .vtk).
    pub vsd_cap_point: Option<Vec3>,
    /// A point on the aortic-annulus cap (see --vsd-cap-point).
    pub aortic_cap_point: Option<Vec3>,
    /// A reference baffle to compare with (area ratio, symmetric surface distance),
    /// written to reference_comparison.json; e.g. the paper's published_baffle.vtp.
    pub reference_baffle: Option<PathBuf>,
    /// Scale of the reference's coordinates to mm (10 for the published files, in cm).
    pub reference_scale: f64,
    /// Closed surface of the pulmonary artery (mm, the surface's frame), e.g. a
    /// segmentation's pulmonary.vtp: measures the smallest section of the RV-to-pulmonary
    /// pathway before and after the baffle (report.json rv_outflow_*). Taken from
    /// --segmentations by `baffle plan` and `baffle sweep`.
    pub pulmonary: Option<PathBuf>,
    /// Apply the target to the tunnel's sections normal to the flow too: the paper
    /// constrains sections normal to its centerline between the cap centroids, which runs
    /// oblique to the flow near the caps, so the flow's own sections can be smaller (up to
    /// 25% on p3). The design is run again at a raised target until the smallest section
    /// normal to the flow-domain centerline reaches the target (report.json flow_sections).
    pub flow_sections: bool,
    /// The patient's peak flow (ml/s; the paper's is 3.26 x CI x BSA): report.json then
    /// holds hemodynamics_estimate, dp at peak flow and the peak velocity from the tunnel's
    /// flow-normal sections (baffle_core::analyses::hemodynamics_estimate, docs/hemodynamics_estimate.md).
    pub peak_flow_ml_s: Option<f64>,
    /// Print Slicer CLI progress tags (<filter-progress>) instead of a summary.
    pub progress_tags: bool,
}
}

documented_settings! {
#[derive(Clone, Default)]
pub struct TargetSettings {
    /// Target cross-section area (mm2).
    pub target_area_mm2: Option<f64>,
    /// Target aortic annulus diameter (mm): A = pi (D/2)^2.
    pub annulus_diameter_mm: Option<f64>,
    /// Body surface area (m2): Boston (Colan 2006) aortic annulus at --z-score.
    pub bsa: Option<f64>,
    /// Height (cm), with --weight-kg: Haycock BSA, then the Boston annulus.
    pub height_cm: Option<f64>,
    /// Weight (kg), with --height-cm.
    pub weight_kg: Option<f64>,
    /// Annulus z-score for --bsa or --height-cm/--weight-kg (not with a given area or diameter,
    /// which it would not change).
    pub z_score: f64,
}
}

/// The defaults are `baffle_core`'s (`DesignOptions::default()`, `FaceLabels::default()`).
impl Default for DesignSettings {
    fn default() -> Self {
        let o = DesignOptions::default();
        DesignSettings {
            surface: None,
            points: None,
            phantom: false,
            out: PathBuf::new(),
            target: TargetSettings::default(),
            surface_frame: Frame::default(),
            remesh_edge_mm: o.remesh_edge_mm.unwrap_or_default(),
            no_remesh: o.remesh_edge_mm.is_none(),
            baffle_edge_mm: o.baffle_edge_mm,
            seam_samples: o.seam_samples,
            centerline_spacing_mm: o.centerline_spacing_mm,
            control_points: o.interior_control_points,
            max_point_distance_mm: o.max_point_distance_mm,
            labels: o.labels,
            vsd_cap_point: None,
            aortic_cap_point: None,
            reference_baffle: None,
            reference_scale: 1.0,
            pulmonary: None,
            flow_sections: false,
            peak_flow_ml_s: None,
            progress_tags: false,
        }
    }
}

/// The frame a surface's coordinates are in (the points are converted into it).
#[derive(Clone, Copy, Default)]
pub enum Frame {
    #[default]
    Lps,
    Ras,
}

impl From<Frame> for CoordinateSystem {
    fn from(f: Frame) -> Self {
        match f {
            Frame::Lps => CoordinateSystem::Lps,
            Frame::Ras => CoordinateSystem::Ras,
        }
    }
}

/// The target area the arguments give (`default_bsa_m2`, the phantom's, when none does).
/// A given area or diameter is the target (a BSA beside it is then the flow's only, in
/// `baffle plan`); both of them, or either with a nonzero z-score (which would not change
/// it), contradict each other and are refused, as the command line's argument groups do,
/// for the callers that fill the settings themselves (the C ABI).
pub fn target_from(args: &TargetSettings, default_bsa_m2: Option<f64>) -> Result<TargetArea, String> {
    let z_score = args.z_score;
    if args.target_area_mm2.is_some() && args.annulus_diameter_mm.is_some() {
        return Err("give one target: --target-area-mm2 or --annulus-diameter-mm, not both".into());
    }
    if z_score != 0.0 && (args.target_area_mm2.is_some() || args.annulus_diameter_mm.is_some()) {
        return Err(format!(
            "--z-score {z_score} applies to the BSA's annulus; it would not change a given --target-area-mm2 or --annulus-diameter-mm (give one target)"
        ));
    }
    if let Some(a) = args.target_area_mm2 {
        return Ok(TargetArea::AreaMm2(a));
    }
    if let Some(d) = args.annulus_diameter_mm {
        return Ok(TargetArea::AnnulusDiameterMm(d));
    }
    if let (Some(height_cm), Some(weight_kg)) = (args.height_cm, args.weight_kg) {
        return Ok(TargetArea::HeightWeight { height_cm, weight_kg, z_score });
    }
    match args.bsa.or(default_bsa_m2) {
        Some(bsa_m2) => Ok(TargetArea::Bsa { bsa_m2, z_score }),
        None => Err("give the target: --bsa, --height-cm and --weight-kg, --target-area-mm2 or --annulus-diameter-mm".into()),
    }
}

/// `baffle design`: its lines said on `progress`, with --progress-tags Slicer's progress
/// tags too.
pub fn run_design(args: &DesignSettings, progress: &Progress) -> Result<(), PlanError> {
    let tags = args.progress_tags;
    design_reporting(args, progress, &mut |fraction, stage| {
        if tags {
            progress.say(&progress_tag(fraction, stage));
        }
        true
    })
}

/// A Slicer CLI progress tag and the stage it is in (two lines).
fn progress_tag(fraction: f64, stage: &str) -> String {
    format!("<filter-progress>{fraction:.3}</filter-progress>\n<filter-stage>{stage}</filter-stage>")
}

/// `baffle design`, its summary lines said on `progress` and each step's fraction sent to `on_step`.
pub fn design_reporting(args: &DesignSettings, progress: &Progress, on_step: &mut dyn FnMut(f64, &str) -> bool) -> Result<(), PlanError> {
    design_and_write(args, progress, on_step).map_err(PlanError::Design)
}

/// The design of `args`, its files written and its summary said on `progress`.
fn design_and_write(args: &DesignSettings, progress: &Progress, on_step: &mut dyn FnMut(f64, &str) -> bool) -> Result<(), String> {
    // Options first: a bad number is refused before any file is read.
    let options = design_options(args)?;
    if let Some(q) = args.peak_flow_ml_s.filter(|q| !(q.is_finite() && *q > 0.0)) {
        return Err(format!("--peak-flow-ml-s must be positive and finite, got {q}"));
    }
    let (surface, points, default_bsa) = design_inputs(args)?;
    let target = target_from(&args.target, default_bsa)?;
    let mut result = design_by_rule(args.flow_sections, &surface, &points, &target, &options, on_step).map_err(|e| match e {
        // A fault of the surface file: say which file.
        DesignError::Surface(_) | DesignError::MissingLabel { .. } => match &args.surface {
            Some(path) => format!("{}: {e}", path.display()),
            None => e.to_string(),
        },
        e => feasibility::design_failure(&args.out, e),
    })?;
    measure_rv_outflow(&surface, &mut result, args.pulmonary.as_deref())?;
    let estimate = EstimateOutcome::for_domain(&result.domain, options.labels, args.peak_flow_ml_s, Blood::default());
    result.report.hemodynamics_estimate = Some(estimate);
    write_design_outputs(&args.out, &result).map_err(|e| e.to_string())?;
    let r = &result.report;
    progress.say(&format!(
        "target {:.1} mm2 ({}); centerline {:.2} mm; baffle {:.1} mm2, {} triangles; {} constrained sections, smallest {:.1} mm2; {:.0} ms",
        r.target_area_mm2,
        r.target,
        r.centerline_length_mm,
        r.baffle_area_mm2,
        r.baffle_triangles,
        r.constrained_sections,
        r.min_constrained_final_area_mm2,
        r.timings.total_ms
    ));
    if let Some(f) = &r.flow_sections {
        progress.say(&flow_sections_line(f));
    }
    if let Some(EstimateOutcome::Estimated(e)) = &r.hemodynamics_estimate {
        progress.say(&estimate_line(e));
    }
    progress.say(&rv_cost_line(&r.rv_cost));
    progress.say(&rv_outflow_line(&r.rv_cost.rv_outflow));
    if let Some(path) = &args.reference_baffle {
        progress.say(&compare_with_reference(&result.baffle, path, args.reference_scale, &args.out)?);
    }
    progress.say(&format!("wrote {}", args.out.display()));
    Ok(())
}

/// The design, with the target applied to the flow-normal sections too when `flow_sections`
/// (--flow-sections; `baffle_core::flow_target`), else the paper's sections only; checked
/// by `baffle_verify::design_checks` (report.json `checks`) before anything is written.
pub fn design_by_rule(
    flow_sections: bool,
    surface: &TriMesh,
    points: &[Vec3],
    target: &TargetArea,
    options: &DesignOptions,
    progress: &mut dyn FnMut(f64, &str) -> bool,
) -> Result<DesignResult, DesignError> {
    let result = match flow_sections {
        true => baffle_core::flow_target::design_to_flow_target(surface, points, target, options, progress),
        false => design(surface, points, target, options, progress),
    }?;
    baffle_verify::checked_design(result)
}

/// The reduced-order estimate in one line.
pub fn estimate_line(e: &baffle_core::analyses::hemodynamics_estimate::HemodynamicsEstimate) -> String {
    format!(
        "estimate at peak flow {:.1} ml/s: dp {:.2} mmHg ({:.3} x throat {:.2} - {:.3} x VSD plane {:.2} dynamic pressure, B at contraction ratio {:.2} and aspect ratio {:.2}; derived stenosis model {:.2}), v_max {:.2} m/s, throat {:.1} mm2 at {:.1} mm; {:.0} ms",
        e.peak_flow_ml_s,
        e.dp_estimate_mmhg,
        e.throat_coefficient_b,
        e.k_throat_mmhg,
        e.vsd_plane_coefficient_a,
        e.k_vsd_mmhg,
        e.contraction_ratio,
        e.mean_section_aspect_ratio,
        e.stenosis_model_dp_mmhg,
        e.v_max_estimate_m_s,
        e.throat_area_mm2,
        e.throat_at_mm,
        e.wall_time_ms
    )
}

/// The flow-section rule's outcome in one line.
fn flow_sections_line(f: &baffle_core::flow_target::FlowSections) -> String {
    let last = &f.rounds[f.rounds.len() - 1];
    let outcome = if f.met { "meets" } else { "still below" };
    let stopped = f.stopped_because.as_ref().map_or(String::new(), |why| format!(" (stopped: {why})"));
    format!(
        "sections normal to the flow: smallest {:.1} mm2 at {:.1} mm from the VSD plane {outcome} the target {:.1} mm2 after {} design round(s), the last at {:.1} mm2{stopped}",
        last.min_flow_section_mm2, last.min_flow_section_at_mm, f.goal_area_mm2, f.rounds.len(), last.design_target_mm2
    )
}

/// Surface, suture points (in the surface's frame) and the BSA that comes with the
/// phantom (None for files).
pub fn design_inputs(args: &DesignSettings) -> Result<(TriMesh, Vec<Vec3>, Option<f64>), String> {
    if args.phantom {
        let p = phantom_default();
        return Ok((p.surface, p.suture_points_mm, Some(p.bsa_m2)));
    }
    let (surface, points) = read_inputs(args)?;
    Ok((surface, points, None))
}

/// The RV cost in one line, saying when the baffle leaves the capped ventricle (then the
/// volumes are net figures, e.g. on an input that encloses only the pathway).
pub fn rv_cost_line(c: &baffle_core::analyses::rv_cost::RvCost) -> String {
    let line = format!(
        "RV (capped ventricle) {:.2} mL before, {:.2} mL after the baffle (the pathway takes {:.2} mL)",
        c.rv_volume_before_ml, c.rv_volume_after_ml, c.rv_volume_taken_ml
    );
    match c.baffle_area_outside_ventricle_mm2 {
        a if a > 0.0 => format!("{line}; {a:.1} mm2 of the baffle lies outside the capped ventricle, so these are net volumes, not the RV cavity"),
        _ => line,
    }
}

/// The smallest RV-to-pulmonary section of a design, where the pulmonary artery's
/// surface is given; without it the report keeps the reason it is not measured.
pub fn measure_rv_outflow(ventricle: &TriMesh, result: &mut DesignResult, pulmonary: Option<&Path>) -> Result<(), String> {
    let Some(path) = pulmonary else {
        return Ok(());
    };
    let pa = baffle_core::io::read_surface(path).map_err(|e| format!("{}: {e}", path.display()))?;
    result.report.rv_cost.rv_outflow = rv_outflow(ventricle, &result.domain, &pa).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(())
}

/// The RV outflow's smallest section before and after and where the baffle narrows it
/// most, or why it is not measured.
pub fn rv_outflow_line(o: &RvOutflow) -> String {
    let place = |p: &Option<baffle_core::analyses::rv_outflow::OutflowPath>| p.as_ref().map(|p| format!(" at {:.1} of {:.1} mm along the path", p.min_section_s_mm, p.path_length_mm)).unwrap_or_default();
    match (o.rv_outflow_min_section_before_mm2, o.rv_outflow_min_section_mm2) {
        (Some(before), Some(after)) => format!(
            "RV outflow (apex region to the pulmonary interface): smallest section {before:.1} mm2{} before, {after:.1} mm2{} after the baffle; {}",
            place(&o.rv_outflow_before),
            place(&o.rv_outflow_after),
            most_narrowed_text(o.rv_outflow_most_narrowed.as_ref())
        ),
        _ => format!("RV outflow smallest section not measured: {}", o.rv_outflow_unavailable.as_deref().unwrap_or("no reason given")),
    }
}

/// Where the baffle narrows the outflow path most, in words.
pub fn most_narrowed_text(n: Option<&baffle_core::analyses::rv_outflow::NarrowedSection>) -> String {
    match n {
        Some(n) if n.after_over_before < 1.0 => format!(
            "the baffle narrows the path most {:.1} mm from its pulmonary end: {:.1} mm2 before, {:.1} mm2 after ({:.0} % left)",
            n.distance_from_pulmonary_end_mm,
            n.area_before_mm2,
            n.area_after_mm2,
            100.0 * n.after_over_before
        ),
        Some(_) => "the baffle narrows no section of the path".into(),
        None => "where the baffle narrows the path is not measured".into(),
    }
}

/// The design options of the command line, range-checked in the one place the C ABI also uses.
pub fn design_options(args: &DesignSettings) -> Result<DesignOptions, String> {
    let options = DesignOptions {
        labels: args.labels,
        seam_samples: args.seam_samples,
        max_point_distance_mm: args.max_point_distance_mm,
        remesh_edge_mm: (!args.no_remesh).then_some(args.remesh_edge_mm),
        baffle_edge_mm: args.baffle_edge_mm,
        interior_control_points: args.control_points,
        centerline_spacing_mm: args.centerline_spacing_mm,
        ..DesignOptions::default()
    };
    options.validate().map_err(|e| e.to_string())?;
    Ok(options)
}

/// Compare the baffle with the reference baffle at `path` (reference_comparison.json); the comparison's line.
fn compare_with_reference(baffle: &TriMesh, path: &Path, scale: f64, out: &Path) -> Result<String, String> {
    let mut reference = baffle_core::io::read_surface(path).map_err(|e| e.to_string())?;
    reference.points.iter_mut().for_each(|p| *p *= scale);
    let c = baffle_core::analyses::compare::compare_surfaces(baffle, &reference).map_err(|e| format!("{}: {e}", path.display()))?;
    let line = format!(
        "reference {}: area {:.1} vs {:.1} mm2 (ratio {:.3}); symmetric surface distance mean {:.2} mm, max {:.2} mm",
        path.display(),
        c.area_mm2,
        c.reference_area_mm2,
        c.area_ratio,
        c.mean_distance_mm,
        c.max_distance_mm
    );
    let file = out.join("reference_comparison.json");
    let text = serde_json::to_string_pretty(&c).map_err(|e| e.to_string())?;
    files::write_atomic(&file, text.as_bytes())?;
    Ok(line)
}

fn read_inputs(args: &DesignSettings) -> Result<(TriMesh, Vec<Vec3>), String> {
    let (Some(surface_path), Some(points_path)) = (&args.surface, &args.points) else {
        return Err("--surface and --points are required (or --phantom)".into());
    };
    let labeled = read_surface_labeled(surface_path).map_err(|e| e.to_string())?;
    let mut mesh = labeled.mesh;
    if let (Some(vsd), Some(aortic)) = (args.vsd_cap_point, args.aortic_cap_point) {
        let seeds = [CapSeed { point_mm: vsd, label: args.labels.vsd_cap }, CapSeed { point_mm: aortic, label: args.labels.aortic_cap }];
        mesh.face_ids = label_planar_caps(&mesh, &seeds, args.labels.wall, &CapTolerances::default())
            .map_err(|e| format!("{}: {e}", surface_path.display()))?;
    } else if !labeled.has_model_face_id {
        return Err(format!(
            "{}: no ModelFaceID cell array; give --vsd-cap-point and --aortic-cap-point to label the caps",
            surface_path.display()
        ));
    }
    let points = read_points(points_path).map_err(|e| e.to_string())?;
    Ok((mesh, points.to_frame(args.surface_frame.into())))
}


/// `baffle phantom`: the built-in synthetic phantom's capped ventricle and suture points.
pub fn write_phantom(out: &Path, suture_half_angle_deg: Option<f64>, progress: &Progress) -> Result<(), PlanError> {
    phantom_files(out, suture_half_angle_deg, progress).map_err(PlanError::Phantom)
}

/// The phantom's files in `out`, said on `progress`.
fn phantom_files(out: &Path, suture_half_angle_deg: Option<f64>, progress: &Progress) -> Result<(), String> {
    let p = match suture_half_angle_deg {
        None => phantom_default(),
        Some(angle) => baffle_core::phantom::phantom_with_suture_half_angle(angle).map_err(|e| format!("--suture-half-angle-deg: {e}"))?,
    };
    std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    write_trimesh_vtp(&out.join("capped_ventricle.vtp"), &p.surface).map_err(|e| e.to_string())?;
    write_markups_closed_curve(&out.join("suture_points.mrk.json"), "BC", &p.suture_points_mm, CoordinateSystem::Lps)
        .map_err(|e| e.to_string())?;
    progress.say(&format!("wrote {} (BSA {} m2)", out.display(), p.bsa_m2));
    Ok(())
}
