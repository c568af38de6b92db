//! The design result handle and its getters (counts, then copies into caller
//! buffers; the report as a JSON string the caller frees with baffle_free).

use crate::alloc::malloc_string;
use crate::mesh_handle::{copy_points, BaffleMesh};
use crate::status::{arg_ref, free_handle, guarded, out_handle, out_ref, out_slice, BaffleStatus, CallError};
use baffle_core::DesignResult;
use std::ffi::c_char;

/// Opaque, immutable result of baffle_design().
pub struct BaffleResult {
    result: DesignResult,
    report_json: String,
}

impl BaffleResult {
    pub(crate) fn boxed(result: DesignResult) -> Result<*mut BaffleResult, CallError> {
        let report_json = serde_json::to_string(&result.report)
            .map_err(|e| CallError::new(BaffleStatus::Internal, format!("cannot serialise the report: {e}")))?;
        Ok(Box::into_raw(Box::new(BaffleResult { result, report_json })))
    }
}

/// Free a result (NULL is ignored).
///
/// # Safety
/// `result` must be NULL or a handle from this library not yet freed.
#[no_mangle]
pub unsafe extern "C" fn baffle_result_free(result: *mut BaffleResult) {
    free_handle(result);
}

/// The closed, outward-wound VSD-to-aorta domain (labels: wall, baffle, VSD cap,
/// aortic cap) as a new mesh handle (free with baffle_mesh_free).
///
/// # Safety
/// `result` must be NULL or a live handle; `out_mesh` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn baffle_result_domain(result: *const BaffleResult, out_mesh: *mut *mut BaffleMesh) -> BaffleStatus {
    guarded(|| {
        let out = out_handle(out_mesh, "out_mesh")?;
        *out = BaffleMesh::boxed(arg_ref(result, "result")?.result.domain.clone());
        Ok(())
    })
}

/// The baffle surface alone as a new mesh handle (free with baffle_mesh_free).
///
/// # Safety
/// `result` must be NULL or a live handle; `out_mesh` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn baffle_result_baffle(result: *const BaffleResult, out_mesh: *mut *mut BaffleMesh) -> BaffleStatus {
    guarded(|| {
        let out = out_handle(out_mesh, "out_mesh")?;
        *out = BaffleMesh::boxed(arg_ref(result, "result")?.result.baffle.clone());
        Ok(())
    })
}

/// The target cross-section area the design met (mm2).
///
/// # Safety
/// `result` must be NULL or a live handle; `out_area_mm2` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn baffle_result_target_area_mm2(result: *const BaffleResult, out_area_mm2: *mut f64) -> BaffleStatus {
    guarded(|| {
        *out_ref(out_area_mm2, "out_area_mm2")? = arg_ref(result, "result")?.result.report.target_area_mm2;
        Ok(())
    })
}

/// The design report as a NUL-terminated JSON object (target, areas, per-section
/// s_mm / origin_mm / normal / status / final_area_mm2, timings); free it with
/// baffle_free.
///
/// # Safety
/// `result` must be NULL or a live handle; `out_json` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn baffle_result_report_json(result: *const BaffleResult, out_json: *mut *mut c_char) -> BaffleStatus {
    guarded(|| {
        let out = out_handle(out_json, "out_json")?;
        *out = malloc_string(&arg_ref(result, "result")?.report_json)?;
        Ok(())
    })
}

/// Number of centerline samples (VSD cap to aortic cap).
///
/// # Safety
/// `result` must be NULL or a live handle; `out_count` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn baffle_result_centerline_count(result: *const BaffleResult, out_count: *mut usize) -> BaffleStatus {
    guarded(|| {
        *out_ref(out_count, "out_count")? = arg_ref(result, "result")?.result.centerline.samples.len();
        Ok(())
    })
}

/// Copy the centerline samples: points (double[3 capacity]), unit tangents
/// (double[3 capacity]) and arc length from the VSD cap (double[capacity]);
/// `capacity` is in samples.
///
/// # Safety
/// `result` must be NULL or a live handle; each buffer NULL or sized as above.
#[no_mangle]
pub unsafe extern "C" fn baffle_result_copy_centerline(
    result: *const BaffleResult,
    out_points_mm: *mut f64,
    out_tangents: *mut f64,
    out_s_mm: *mut f64,
    capacity: usize,
) -> BaffleStatus {
    guarded(|| {
        let samples = &arg_ref(result, "result")?.result.centerline.samples;
        let n = samples.len();
        let points = out_slice(out_points_mm, 3 * capacity, 3 * n, "out_points_mm")?;
        let tangents = out_slice(out_tangents, 3 * capacity, 3 * n, "out_tangents")?;
        let s_mm = out_slice(out_s_mm, capacity, n, "out_s_mm")?;
        for (k, sample) in samples.iter().enumerate() {
            points[3 * k..3 * k + 3].copy_from_slice(sample.point.as_slice());
            tangents[3 * k..3 * k + 3].copy_from_slice(sample.unit_tangent.as_slice());
            s_mm[k] = sample.s_mm;
        }
        Ok(())
    })
}

/// Number of seam points (vertices shared by the wall and the baffle, in loop order).
///
/// # Safety
/// `result` must be NULL or a live handle; `out_count` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn baffle_result_seam_count(result: *const BaffleResult, out_count: *mut usize) -> BaffleStatus {
    guarded(|| {
        *out_ref(out_count, "out_count")? = arg_ref(result, "result")?.result.seam_mm.len();
        Ok(())
    })
}

/// Copy the seam points into `out_points_mm` (`capacity` doubles, 3 per point).
///
/// # Safety
/// `result` must be NULL or a live handle; `out_points_mm` NULL or `capacity` writable doubles.
#[no_mangle]
pub unsafe extern "C" fn baffle_result_copy_seam(result: *const BaffleResult, out_points_mm: *mut f64, capacity: usize) -> BaffleStatus {
    guarded(|| {
        let seam = &arg_ref(result, "result")?.result.seam_mm;
        copy_points(seam, out_slice(out_points_mm, capacity, 3 * seam.len(), "out_points_mm")?);
        Ok(())
    })
}

/// Number of centerline sections in the report (constrained or dropped).
///
/// # Safety
/// `result` must be NULL or a live handle; `out_count` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn baffle_result_section_count(result: *const BaffleResult, out_count: *mut usize) -> BaffleStatus {
    guarded(|| {
        *out_ref(out_count, "out_count")? = arg_ref(result, "result")?.result.report.sections.len();
        Ok(())
    })
}

/// Copy the sections: arc length (double[capacity]), plane origin and unit normal
/// (double[3 capacity] each), constrained flag (int32[capacity]: 1 when the
/// section's area is held >= the target, 0 when the design dropped it; the
/// report JSON says why) and the final area (double[capacity], NaN where not
/// measured). `capacity` is in sections.
///
/// # Safety
/// `result` must be NULL or a live handle; each buffer NULL or sized as above.
#[no_mangle]
pub unsafe extern "C" fn baffle_result_copy_sections(
    result: *const BaffleResult,
    out_s_mm: *mut f64,
    out_origins_mm: *mut f64,
    out_normals: *mut f64,
    out_constrained: *mut i32,
    out_final_area_mm2: *mut f64,
    capacity: usize,
) -> BaffleStatus {
    guarded(|| {
        let sections = &arg_ref(result, "result")?.result.report.sections;
        let n = sections.len();
        let s_mm = out_slice(out_s_mm, capacity, n, "out_s_mm")?;
        let origins = out_slice(out_origins_mm, 3 * capacity, 3 * n, "out_origins_mm")?;
        let normals = out_slice(out_normals, 3 * capacity, 3 * n, "out_normals")?;
        let constrained = out_slice(out_constrained, capacity, n, "out_constrained")?;
        let areas = out_slice(out_final_area_mm2, capacity, n, "out_final_area_mm2")?;
        for (k, s) in sections.iter().enumerate() {
            s_mm[k] = s.s_mm;
            origins[3 * k..3 * k + 3].copy_from_slice(&s.origin_mm);
            normals[3 * k..3 * k + 3].copy_from_slice(&s.normal);
            constrained[k] = i32::from(s.status == "constrained");
            areas[k] = s.final_area_mm2.unwrap_or(f64::NAN);
        }
        Ok(())
    })
}
