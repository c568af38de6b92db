//! `baffle centerline`: the flow-domain centerline of a closed lumen between two
//! measurement planes [paper 2.5] (`baffle_core::analyses::flow_centerline`), its length and
//! inscribed radii, and with `--results` the pressure and speed of a `baffle simulate`
//! result sampled along it (v_max along the centerline).

use crate::error::PlanError;
use crate::sampling::{PeakFields, Profile};
use crate::files::write_atomic;
use crate::progress::Progress;
use baffle_core::analyses::flow_centerline::{flow_centerline, flow_normal_section_shapes, smallest_section, CenterlineOptions, FlowCenterline, Lumen, MeasurementPlane};
use baffle_core::analyses::hemodynamics_estimate::{estimate, plane_area_mm2, Blood, TunnelSections};
use baffle_core::io::{read_surface_labeled, write_vtp, DataArray, PolyData};
use baffle_core::{FaceLabels, TriMesh};
use serde::Deserialize;
use serde_json::json;
use std::path::{Path, PathBuf};
use std::time::Instant;

documented_settings! {
#[derive(Clone)]
pub struct CenterlineSettings {
    /// Closed lumen surface with ModelFaceID (e.g. domain.vtp of `baffle design`).
    pub surface: PathBuf,
    /// The measurement planes, inflow first, as ModelFaceIDs: caps of --surface, or
    /// face sets of --plane-faces.
    pub planes: Vec<i32>,
    /// The end caps of --surface the path runs between (inflow first), when the planes
    /// are not caps of it (an extended domain, e.g. `baffle extend`'s 20,21); default: the
    /// planes. Plane triangles of --surface that are not end caps are taken as interior.
    pub ends: Option<Vec<i32>>,
    /// A face file holding the planes' triangles (e.g. mesh-faces.vtp of `baffle mesh`,
    /// whose interior face sets are the measurement planes).
    pub plane_faces: Option<PathBuf>,
    /// Factor from the files' units to mm (10 for the paper's published files, in cm).
    pub scale: f64,
    /// A `baffle simulate` result (peak.vtu: mm, velocity_m_s, pressure_mmhg) to sample along the centerline.
    pub results: Option<PathBuf>,
    /// Voxel size of the distance field (mm).
    pub voxel_mm: f64,
    /// Largest distance between centerline points (mm); the paper used 0.5.
    pub spacing_mm: f64,
    /// Half-width of the moving average smoothing the path (mm).
    pub smoothing_mm: f64,
    /// Largest re-centring shift of a path point in its normal plane, as a fraction of
    /// its inscribed radius (0: the minimal path as found on the voxels, smoothed).
    pub recenter_fraction: f64,
    /// The peak flow (ml/s): <stem>.json then holds hemodynamics_estimate, dp at peak flow
    /// between the planes and the peak velocity from the sections normal to the centerline
    /// (baffle_core::analyses::hemodynamics_estimate; the planes' areas from their triangles).
    pub peak_flow_ml_s: Option<f64>,
    /// Output centerline (.vtp, point arrays s_mm, radius_mm and, with --results,
    /// pressure_mmhg and speed_m_s); <stem>.json beside it holds the figures.
    pub out: PathBuf,
}
}

impl Default for CenterlineSettings {
    fn default() -> Self {
        let labels = FaceLabels::default();
        let o = CenterlineOptions::default();
        CenterlineSettings {
            surface: PathBuf::new(),
            planes: vec![labels.vsd_cap, labels.aortic_cap],
            ends: None,
            plane_faces: None,
            scale: 1.0,
            results: None,
            voxel_mm: o.voxel_mm,
            spacing_mm: o.spacing_mm,
            smoothing_mm: o.smoothing_mm,
            recenter_fraction: o.recenter_fraction,
            peak_flow_ml_s: None,
            out: PathBuf::new(),
        }
    }
}

fn read_mm(path: &Path, scale: f64) -> Result<TriMesh, String> {
    let labeled = read_surface_labeled(path).map_err(|e| e.to_string())?;
    if !labeled.has_model_face_id {
        return Err(format!("{}: no ModelFaceID cell array; the caps and planes need labels", path.display()));
    }
    let mut mesh = labeled.mesh;
    mesh.points.iter_mut().for_each(|p| *p *= scale);
    Ok(mesh)
}

fn two(labels: &[i32], flag: &str) -> Result<[i32; 2], String> {
    <[i32; 2]>::try_from(labels).map_err(|_| format!("{flag}: give two labels (inflow,outflow), got {labels:?}"))
}

/// What `baffle centerline` measures: the centerline, the lumen's sections normal to it
/// (mm2, None where none was found) and, with --results, the profile along it.
pub struct Measured {
    pub line: FlowCenterline,
    /// The sections along it (area and aspect ratio) and the measurement planes' areas.
    pub tunnel: TunnelSections,
    pub profile: Option<Profile>,
}

/// The centerline of `args`, its flow-normal sections, and its profile when --results is given.
pub fn compute(args: &CenterlineSettings) -> Result<Measured, PlanError> {
    measure(args).map_err(PlanError::Centerline)
}

/// The measurement of `args` (its errors as messages; [`compute`] names the stage).
fn measure(args: &CenterlineSettings) -> Result<Measured, String> {
    if !(args.scale > 0.0) {
        return Err(format!("--scale must be positive, got {}", args.scale));
    }
    if let Some(q) = args.peak_flow_ml_s.filter(|q| !(q.is_finite() && *q > 0.0)) {
        return Err(format!("--peak-flow-ml-s must be positive and finite, got {q}"));
    }
    let options = CenterlineOptions { voxel_mm: args.voxel_mm, spacing_mm: args.spacing_mm, smoothing_mm: args.smoothing_mm, recenter_fraction: args.recenter_fraction };
    options.validate()?;
    let surface = read_mm(&args.surface, args.scale)?;
    let planes = two(&args.planes, "--planes")?;
    let ends = two(args.ends.as_deref().unwrap_or(&planes), "--ends")?;
    let faces = match &args.plane_faces {
        Some(path) => read_mm(path, args.scale)?,
        None => surface.clone(),
    };
    let source = args.plane_faces.as_ref().unwrap_or(&args.surface).display().to_string();
    let plane = |label| MeasurementPlane::from_label(&faces, label).ok_or_else(|| format!("{source}: no triangles labelled {label} (measurement plane)"));
    let measurement = [plane(planes[0])?, plane(planes[1])?];
    // Plane triangles that are not end caps lie inside the lumen (the extended surface of
    // `baffle extend` keeps the designed caps 11 and 16 there): not part of its boundary.
    let interior: Vec<i32> = planes.iter().filter(|l| !ends.contains(l)).copied().collect();
    let boundary = surface.with_labels(|l| !interior.contains(&l));
    let lumen = Lumen::with_end_caps(&boundary, ends[0], ends[1], measurement).map_err(|e| format!("{}: {e}", args.surface.display()))?;
    let line = flow_centerline(&lumen, &options).map_err(|e| format!("{}: {e}", args.surface.display()))?;
    let shapes = flow_normal_section_shapes(&boundary, &line.points, &lumen.planes);
    let tunnel = TunnelSections::from_shapes(line.s_mm.clone(), &shapes, plane_area_mm2(&lumen.planes[0]), plane_area_mm2(&lumen.planes[1]));
    let profile = match &args.results {
        Some(path) => Some(PeakFields::read(path)?.profile(&line.points)),
        None => None,
    };
    Ok(Measured { line, tunnel, profile })
}

fn nan_for_none(v: &[Option<f64>]) -> Vec<f64> {
    v.iter().map(|x| x.unwrap_or(f64::NAN)).collect()
}

fn polydata(m: &Measured) -> PolyData {
    let (line, profile) = (&m.line, m.profile.as_ref());
    let mut point_data = vec![
        DataArray::f64("s_mm", 1, line.s_mm.clone()),
        DataArray::f64("radius_mm", 1, line.radius_mm.clone()),
        DataArray::f64("section_area_mm2", 1, nan_for_none(&m.tunnel.area_mm2)),
        DataArray::f64("section_aspect_ratio", 1, nan_for_none(&m.tunnel.aspect_ratio)),
    ];
    if let Some(p) = profile {
        point_data.push(DataArray::f64("pressure_mmhg", 1, nan_for_none(&p.pressure_mmhg)));
        point_data.push(DataArray::f64("speed_m_s", 1, nan_for_none(&p.speed_m_s)));
    }
    PolyData { points: line.points.clone(), lines: vec![(0..line.points.len() as u32).collect()], point_data, ..PolyData::default() }
}

/// The figures of <stem>.json that the plan's report reads back (the file holds more).
#[derive(Clone, Debug, Deserialize)]
pub struct CenterlineFigures {
    pub length_mm: f64,
    /// The smallest section normal to the centerline and its arc length (mm2, mm; null
    /// when no section was measured).
    #[serde(deserialize_with = "crate::files::nullable")]
    pub min_section_mm2: Option<f64>,
    #[serde(deserialize_with = "crate::files::nullable")]
    pub min_section_at_mm: Option<f64>,
}

/// The smallest and largest inscribed radius along the centerline (mm).
fn radius_range(line: &FlowCenterline) -> (f64, f64) {
    line.radius_mm.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &r| (a.min(r), b.max(r)))
}

/// The figures written to <stem>.json (also read back by the plan's report).
fn summary(args: &CenterlineSettings, m: &Measured, wall_time_s: f64) -> serde_json::Value {
    let (line, profile) = (&m.line, m.profile.as_ref());
    let smallest = smallest_section(&line.s_mm, &m.tunnel.area_mm2);
    let (r_min, r_max) = radius_range(line);
    let mut doc = json!({
        "surface": args.surface, "planes": args.planes, "ends": args.ends.as_ref().unwrap_or(&args.planes),
        "plane_faces": args.plane_faces, "scale_to_mm": args.scale,
        "method": "minimal path (cost 1/R^2) on the exact wall-distance field of a voxelized lumen, smoothed, re-centred in normal planes, trimmed at the planes (baffle_core::analyses::flow_centerline)",
        "length_mm": line.length_mm, "spacing_mm": args.spacing_mm, "smoothing_mm": args.smoothing_mm, "recenter_fraction": args.recenter_fraction, "voxel_mm": line.voxel_mm, "inside_voxels": line.inside_voxels,
        "points": line.points.len(), "radius_min_mm": r_min, "radius_max_mm": r_max,
        "radius_mean_mm": line.radius_mm.iter().sum::<f64>() / line.radius_mm.len().max(1) as f64,
        "wall_time_s": wall_time_s,
        "timings_ms": line.timings_ms.iter().map(|(k, v)| (k.to_string(), json!(v))).collect::<serde_json::Map<_, _>>(),
        "s_mm": line.s_mm, "radius_mm": line.radius_mm,
        "section_area_mm2": m.tunnel.area_mm2,
        "section_aspect_ratio": m.tunnel.aspect_ratio,
        "min_section_mm2": smallest.map(|x| x.0), "min_section_at_mm": smallest.map(|x| x.1),
        "sections_measured": m.tunnel.area_mm2.iter().flatten().count(),
        "sections_method": "the piece of the plane normal to the centerline (its chord over 1 mm each side) inside the lumen that holds the point, rasterized at 0.1 mm (its aspect ratio: minor over major radius of gyration of the pixels); not measured (null) where that plane crosses the VSD or aortic plane (baffle_core::analyses::flow_centerline::flow_normal_sections)",
        "points_mm": line.points.iter().map(|p| [p.x, p.y, p.z]).collect::<Vec<_>>(),
    });
    if let Some(q) = args.peak_flow_ml_s {
        doc["hemodynamics_estimate"] = match estimate(&m.tunnel, q, Blood::default()) {
            Ok(e) => json!(e),
            Err(why) => json!({ "absent_because": why }),
        };
    }
    if let Some(p) = profile {
        let v_max = p.v_max_m_s();
        doc["results"] = json!(args.results);
        doc["v_max_m_s"] = if v_max.is_finite() { json!(v_max) } else { serde_json::Value::Null };
        doc["sampled_points"] = json!(p.speed_m_s.iter().flatten().count());
        doc["pressure_mmhg"] = json!(p.pressure_mmhg);
        doc["speed_m_s"] = json!(p.speed_m_s);
    }
    doc
}

/// Where the centerline and its figures go: `<stem>.vtp` and `<stem>.json`.
pub fn output_paths(out: &Path) -> (PathBuf, PathBuf) {
    (out.with_extension("vtp"), out.with_extension("json"))
}

/// `baffle centerline`, its computation shown and its figures said on `progress` (a
/// stage of `baffle plan`, or the command).
pub fn run_centerline(args: &CenterlineSettings, progress: &Progress) -> Result<(), PlanError> {
    centerline_and_write(args, progress).map_err(PlanError::Centerline)
}

/// The centerline of `args` and its figures written.
fn centerline_and_write(args: &CenterlineSettings, progress: &Progress) -> Result<(), String> {
    let start = Instant::now();
    let measured = progress.while_running("centerline", || compute(args))?;
    let wall_time_s = start.elapsed().as_secs_f64();
    let (vtp, json_path) = output_paths(&args.out);
    crate::files::create_parent_dir(&vtp)?;
    write_vtp(&vtp, &polydata(&measured)).map_err(|e| e.to_string())?;
    let doc = summary(args, &measured, wall_time_s);
    let (line, profile) = (&measured.line, &measured.profile);
    write_atomic(&json_path, serde_json::to_string_pretty(&doc).map_err(|e| e.to_string())?.as_bytes())?;
    let (r_min, r_max) = radius_range(line);
    let mut said = format!("flow-domain centerline {:.2} mm between planes {:?} ({} points, inscribed radius {r_min:.2}-{r_max:.2} mm, {wall_time_s:.2} s)", line.length_mm, args.planes, line.points.len());
    if let Some((a, at)) = smallest_section(&line.s_mm, &measured.tunnel.area_mm2) {
        said += &format!("; smallest section normal to it {a:.1} mm2 at s = {at:.1} mm");
    }
    if let Some(p) = &profile {
        said += &format!("; v_max along it {:.3} m/s", p.v_max_m_s());
    }
    progress.say(&said);
    progress.say(&format!("wrote {} and {}", vtp.display(), json_path.display()));
    Ok(())
}
