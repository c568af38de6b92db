//! baffle_template(): the true-scale patch template of a designed domain (the baffle
//! flattened, suture points, rims) as a handle; its flat mesh, its report and the
//! printable A4 page (PDF, SVG or PNG) are copied out of it.

use crate::alloc::{malloc_copy, malloc_string};
use crate::mesh_handle::BaffleMesh;
use crate::status::{arg_ref, free_handle, guarded, in_slice, optional_str, out_handle, out_ref, xyz_points, BaffleStatus, CallError};
use baffle_core::{FaceLabels, TriMesh, Vec3};
use baffle_template::drawing::{today_utc, TemplateText};
use baffle_template::raster::DEFAULT_DPI;
use baffle_template::{template_from_domain, FlattenMethod, PageFormat, Template};
use std::ffi::c_char;

/// How the baffle is flattened.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BaffleFlattenMethod {
    /// Least-squares conformal map, scaled to the seam length (the default).
    Lscm = 0,
    /// LSCM, then as-rigid-as-possible iterations (smaller largest area change).
    LscmArap = 1,
}

/// The page's file format.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BaffleTemplateFormat {
    /// A4 portrait, drawn in mm: prints 1:1 at 100 %.
    Pdf = 0,
    /// A4 portrait, width/height and viewBox in mm.
    Svg = 1,
    /// A4 portrait raster at 300 dpi, stored in its pHYs chunk (other resolutions:
    /// baffle_template_png).
    Png = 2,
}

/// Opaque, immutable patch template from baffle_template().
pub struct BaffleTemplate {
    template: Template,
    report_json: String,
}

/// Flatten the baffle of a designed `domain` (closed, labelled as baffle_design
/// writes it) into a patch template. `suture_points_mm` (double[suture_points_len],
/// the domain's frame) are drawn at their nearest seam vertex and named by
/// `point_labels` (NULL, or one label per line, '\n'-separated; an empty line or a
/// missing one numbers the point 1, 2, ...). `patient_label` and `date` (NULL: today,
/// UTC) are printed on the page. `labels` is NULL (baffle 10, VSD cap 11, aortic cap
/// 16) or int32[3]: the baffle's, the VSD cap's and the aortic cap's ModelFaceID.
/// `method` is a BaffleFlattenMethod. On success `*out_template` is a new handle (free
/// with baffle_template_free).
///
/// # Safety
/// Pointers must be NULL or valid (strings NUL-terminated, arrays for their lengths).
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn baffle_template(
    domain: *const BaffleMesh,
    suture_points_mm: *const f64,
    suture_points_len: usize,
    point_labels: *const c_char,
    patient_label: *const c_char,
    date: *const c_char,
    labels: *const i32,
    method: i32,
    out_template: *mut *mut BaffleTemplate,
) -> BaffleStatus {
    guarded(|| {
        let out = out_handle(out_template, "out_template")?;
        let domain = arg_ref(domain, "domain")?;
        let points = xyz_points(in_slice(suture_points_mm, suture_points_len, "suture_points_mm")?, "suture_points_mm")?;
        let names: Vec<String> = optional_str(point_labels, "point_labels")?.map_or_else(Vec::new, |s| s.split('\n').map(str::to_string).collect());
        let text = TemplateText {
            patient_label: optional_str(patient_label, "patient_label")?.unwrap_or_default().to_string(),
            date: optional_str(date, "date")?.map_or_else(today_utc, str::to_string),
        };
        let labels = face_labels(labels)?;
        let method = match method {
            0 => FlattenMethod::Lscm,
            1 => FlattenMethod::LscmArap,
            other => return Err(CallError::invalid(format!("method = {other} is not a BaffleFlattenMethod (0 LSCM, 1 LSCM+ARAP)"))),
        };
        let template = template_from_domain(&domain.mesh, &labels, &points, &names, &text, method)
            .map_err(|e| CallError::new(BaffleStatus::InvalidInput, format!("template: {e}")))?;
        let report_json = report_json(&template)?;
        *out = Box::into_raw(Box::new(BaffleTemplate { template, report_json }));
        Ok(())
    })
}

/// # Safety
/// `labels` must be NULL or valid for three int32.
unsafe fn face_labels(labels: *const i32) -> Result<FaceLabels, CallError> {
    if labels.is_null() {
        return Ok(FaceLabels::default());
    }
    // NULL was handled above; in_slice checks the alignment.
    let values = in_slice(labels, 3, "labels")?;
    Ok(FaceLabels { baffle: values[0], vsd_cap: values[1], aortic_cap: values[2], ..FaceLabels::default() })
}

/// The flattening's figures, where each suture point and rim sits, and the per-triangle
/// area ratio and angle change (for a colour map in the caller's view).
fn report_json(t: &Template) -> Result<String, CallError> {
    let doc = serde_json::json!({
        "flattening": t.flat.report,
        "suture_point_to_seam_mm": t.suture_offsets_mm,
        "vsd_rim_seam_vertices": t.vsd_rim_vertices,
        "aortic_rim_seam_vertices": t.aortic_rim_vertices,
        "seam_to_vsd_cap_mm": t.seam_to_vsd_cap_mm,
        "seam_to_aortic_cap_mm": t.seam_to_aortic_cap_mm,
        "area_ratio": t.flat.area_ratio,
        "angle_error_deg": t.flat.angle_error_deg,
        "page": "A4 portrait 210 x 297 mm, 1:1 at 100 %",
    });
    serde_json::to_string(&doc).map_err(|e| CallError::new(BaffleStatus::Internal, format!("cannot serialise the template report: {e}")))
}

/// Free a template (NULL is ignored).
///
/// # Safety
/// `template` must be NULL or a handle from this library not yet freed.
#[no_mangle]
pub unsafe extern "C" fn baffle_template_free(template: *mut BaffleTemplate) {
    free_handle(template);
}

/// The flattened baffle as a new mesh handle (free with baffle_mesh_free): points
/// (u, v, 0) in mm at true scale, the baffle's triangles, every label the baffle's.
///
/// # Safety
/// `template` must be NULL or a live handle; `out_mesh` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn baffle_template_flat_mesh(template: *const BaffleTemplate, out_mesh: *mut *mut BaffleMesh) -> BaffleStatus {
    guarded(|| {
        let out = out_handle(out_mesh, "out_mesh")?;
        let flat = &arg_ref(template, "template")?.template.flat;
        let points = flat.uv_mm.iter().map(|p| Vec3::new(p.x, p.y, 0.0)).collect();
        let label = FaceLabels::default().baffle;
        *out = BaffleMesh::boxed(TriMesh::new(points, flat.triangles.clone(), vec![label; flat.triangles.len()]));
        Ok(())
    })
}

/// The template's report as a NUL-terminated JSON object ("flattening": seam length,
/// perimeter and its error, area and angle distortion median / max; per suture point
/// its distance to the seam; per triangle "area_ratio" and "angle_error_deg"); free it
/// with baffle_free.
///
/// # Safety
/// `template` must be NULL or a live handle; `out_json` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn baffle_template_report_json(template: *const BaffleTemplate, out_json: *mut *mut c_char) -> BaffleStatus {
    guarded(|| {
        let out = out_handle(out_json, "out_json")?;
        *out = malloc_string(&arg_ref(template, "template")?.report_json)?;
        Ok(())
    })
}

/// The printable page (`format`: a BaffleTemplateFormat) as a new byte array
/// (uint8_t[*out_len], free with baffle_free), to be written to a file as it is.
///
/// # Safety
/// `template` must be NULL or a live handle; the outputs NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn baffle_template_document(
    template: *const BaffleTemplate,
    format: i32,
    out_bytes: *mut *mut u8,
    out_len: *mut usize,
) -> BaffleStatus {
    guarded(|| {
        let format = match format {
            0 => PageFormat::Pdf,
            1 => PageFormat::Svg,
            2 => PageFormat::Png { dpi: DEFAULT_DPI },
            other => return Err(CallError::invalid(format!("format = {other} is not a BaffleTemplateFormat (0 PDF, 1 SVG, 2 PNG)"))),
        };
        copy_page(template, format, out_bytes, out_len)
    })
}

/// The page as a PNG at `dpi` (10 to 1200; stored in the file's pHYs chunk), as a new
/// byte array (uint8_t[*out_len], free with baffle_free).
///
/// # Safety
/// `template` must be NULL or a live handle; the outputs NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn baffle_template_png(template: *const BaffleTemplate, dpi: f64, out_bytes: *mut *mut u8, out_len: *mut usize) -> BaffleStatus {
    guarded(|| copy_page(template, PageFormat::Png { dpi }, out_bytes, out_len))
}

/// Render the page and hand the bytes to the caller (the outputs NULL until it succeeds).
unsafe fn copy_page(template: *const BaffleTemplate, format: PageFormat, out_bytes: *mut *mut u8, out_len: *mut usize) -> Result<(), CallError> {
    let out = out_ref(out_bytes, "out_bytes")?;
    let len = out_ref(out_len, "out_len")?;
    (*out, *len) = (std::ptr::null_mut(), 0);
    let bytes = format.render(&arg_ref(template, "template")?.template.shapes).map_err(CallError::invalid)?;
    *out = malloc_copy(&bytes)?;
    *len = bytes.len();
    Ok(())
}
