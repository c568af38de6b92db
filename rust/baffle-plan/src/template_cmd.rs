//! `baffle template`: the true-scale patch template the surgeon cuts the baffle from
//! (issue 17): the designed baffle flattened (LSCM, scaled to the seam length), the
//! suture points numbered, the VSD and aortic rims, a 10 mm scale bar and check square,
//! the area distortion as a colour map; an A4 PDF or SVG that prints 1:1 at 100 %, or a
//! PNG with its resolution in the file (pHYs).

use crate::error::PlanError;
use crate::progress::Progress;
use crate::files::write_atomic;
use crate::design_cmd::Frame;
use baffle_core::io::{read_points, read_surface, CoordinateSystem};
use baffle_core::FaceLabels;
use baffle_template::drawing::{today_utc, TemplateText};
use baffle_template::raster::DEFAULT_DPI;
use baffle_template::{template_from_domain, FlattenMethod, PageFormat};
use std::path::PathBuf;

documented_settings! {
pub struct TemplateSettings {
    /// Designed domain (domain.vtp from `baffle design`): ModelFaceID baffle, VSD and aortic caps.
    pub domain: PathBuf,
    /// The surgeon's suture points (.mrk.json, .fcsv, CSV or JSON), numbered on the template.
    pub points: PathBuf,
    /// Output: .pdf (A4, vector), .svg (A4, viewBox in mm) or .png (A4 at --dpi, the DPI
    /// stored in the file). A JSON report with the perimeter and distortion figures is
    /// written beside it (<stem>-report.json).
    pub out: PathBuf,
    /// Resolution of a .png template (dots per inch).
    pub dpi: f64,
    /// Patient label printed on the template.
    pub label: String,
    /// Date printed on the template (default: today, UTC).
    pub date: Option<String>,
    /// Frame of the domain (the points are converted into it), as for `baffle design`.
    pub surface_frame: Frame,
    /// Flattening: lscm (conformal; keeps the seam's angles and edge lengths best) or
    /// arap (LSCM then as-rigid-as-possible; smaller largest area change).
    pub method: TemplateMethod,
    /// ModelFaceIDs of the domain's baffle, VSD and aortic-annulus caps.
    pub labels: FaceLabels,
}
}

#[derive(Clone, Copy, Default)]
pub enum TemplateMethod {
    #[default]
    Lscm,
    Arap,
}

impl Default for TemplateSettings {
    fn default() -> Self {
        TemplateSettings {
            domain: PathBuf::new(),
            points: PathBuf::new(),
            out: PathBuf::new(),
            dpi: DEFAULT_DPI,
            label: String::new(),
            date: None,
            surface_frame: Frame::default(),
            method: TemplateMethod::default(),
            labels: FaceLabels::default(),
        }
    }
}

/// `baffle template`, its figures said on `progress`.
pub fn run_template(args: &TemplateSettings, progress: &Progress) -> Result<(), PlanError> {
    template(args, progress).map_err(PlanError::Template)
}

/// The template of `args` and its report written.
fn template(args: &TemplateSettings, progress: &Progress) -> Result<(), String> {
    let format = PageFormat::from_path(&args.out, args.dpi)?;
    let domain = read_surface(&args.domain).map_err(|e| e.to_string())?;
    let points = read_points(&args.points).map_err(|e| e.to_string())?;
    let frame = CoordinateSystem::from(args.surface_frame);
    let labels = args.labels;
    let text = TemplateText { patient_label: args.label.clone(), date: args.date.clone().unwrap_or_else(today_utc) };
    let method = match args.method {
        TemplateMethod::Lscm => FlattenMethod::Lscm,
        TemplateMethod::Arap => FlattenMethod::LscmArap,
    };
    let template = template_from_domain(&domain, &labels, &points.to_frame(frame), &points.labels, &text, method)
        .map_err(|e| format!("{}: {e}", args.domain.display()))?;
    let bytes = format.render(&template.shapes)?;
    crate::files::create_parent_dir(&args.out)?;
    write_atomic(&args.out, &bytes)?;
    let report = serde_json::json!({
        "flattening": template.flat.report,
        "suture_point_to_seam_mm": template.suture_offsets_mm,
        "vsd_rim_seam_vertices": template.vsd_rim_vertices,
        "aortic_rim_seam_vertices": template.aortic_rim_vertices,
        "seam_to_vsd_cap_mm": template.seam_to_vsd_cap_mm,
        "seam_to_aortic_cap_mm": template.seam_to_aortic_cap_mm,
        "page": match format {
            PageFormat::Png { dpi } => format!("A4 portrait 210 x 297 mm at {dpi} dpi (in the PNG's pHYs), 1:1 when printed at that resolution"),
            _ => "A4 portrait 210 x 297 mm, 1:1 at 100 %".to_string(),
        },
    });
    let stem = args.out.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let report_path = args.out.with_file_name(format!("{stem}-report.json"));
    write_atomic(&report_path, serde_json::to_string_pretty(&report).map_err(|e| e.to_string())?.as_bytes())?;
    let r = &template.flat.report;
    progress.say(&format!(
        "{}: seam {:.2} mm, perimeter {:.2} mm (error {:.1e}, map scaled by {:.4}); area change median {:.2} % max {:.2} %; angle change median {:.2} max {:.2} deg",
        args.out.display(),
        r.seam_length_3d_mm,
        r.perimeter_mm,
        r.perimeter_error,
        r.scale,
        100.0 * r.area_distortion_median,
        100.0 * r.area_distortion_max,
        r.angle_distortion_median_deg,
        r.angle_distortion_max_deg
    ));
    Ok(())
}
