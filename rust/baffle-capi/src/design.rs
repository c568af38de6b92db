//! baffle_design(): the whole design through the ABI, with a C progress callback.

use crate::mesh_handle::BaffleMesh;
use crate::options::read_options;
use crate::result::BaffleResult;
use crate::status::{arg_ref, guarded, in_slice, out_handle, set_last_max_feasible_area_mm2, xyz_points, BaffleStatus, CallError};
use baffle_core::analyses::hemodynamics_estimate::{Blood, EstimateOutcome};
use baffle_core::{DesignError, Vec3};
use baffle_plan::design_cmd::design_by_rule;
use std::ffi::{c_char, c_void, CString};

/// Progress callback: called with the fraction done (0..1), the stage's name and
/// the caller's user_data; return nonzero to go on, 0 to cancel the call (which
/// then returns BAFFLE_STATUS_CANCELLED). It runs on the calling thread and must
/// not unwind (a C++ callback must catch its exceptions).
pub type BaffleProgressFn = Option<unsafe extern "C" fn(fraction: f64, stage: *const c_char, user_data: *mut c_void) -> i32>;

/// Design the area-constrained baffle on `surface` (closed, labelled; either
/// winding) for the suture points (double[suture_points_len], in the surface's
/// frame, in loop order). `progress` may be NULL. On success `*out_result` is a
/// new handle (free with baffle_result_free).
///
/// # Safety
/// Pointers must be NULL or valid for their lengths; `user_data` is passed through.
#[no_mangle]
pub unsafe extern "C" fn baffle_design(
    surface: *const BaffleMesh,
    suture_points_mm: *const f64,
    suture_points_len: usize,
    options: *const crate::options::BaffleDesignOptions,
    progress: BaffleProgressFn,
    user_data: *mut c_void,
    out_result: *mut *mut BaffleResult,
) -> BaffleStatus {
    guarded(|| {
        let out = out_handle(out_result, "out_result")?;
        let surface = arg_ref(surface, "surface")?;
        let points = suture_points(in_slice(suture_points_mm, suture_points_len, "suture_points_mm")?)?;
        let options = read_options(options)?;
        let target = options.target()?;
        let core_options = options.design_options()?;
        let peak_flow_ml_s = options.peak_flow_ml_s()?;
        let mut report = |fraction: f64, stage: &str| call_progress(progress, user_data, fraction, stage);
        // The command line's design, checked by a second method before the caller sees it
        // (report.json `checks`); with flow_sections, until the flow's own sections reach the target.
        let flow_sections = options.flow_sections != 0;
        let mut result = design_by_rule(flow_sections, &surface.mesh, &points, &target, &core_options, &mut report).map_err(design_error)?;
        result.report.hemodynamics_estimate = Some(match peak_flow_ml_s {
            Some(q) => EstimateOutcome::for_domain(&result.domain, core_options.labels, Some(q), Blood::default()),
            None => EstimateOutcome::Absent { absent_because: "no peak flow given (options.peak_flow_ml_s is 0 or NaN)".into() },
        });
        *out = BaffleResult::boxed(result)?;
        Ok(())
    })
}

fn suture_points(values: &[f64]) -> Result<Vec<Vec3>, CallError> {
    if values.is_empty() {
        return Err(CallError::null("suture_points_mm (no points given)"));
    }
    xyz_points(values, "suture_points_mm")
}

/// # Safety
/// `progress`, if set, must be safe to call with `user_data`.
pub(crate) unsafe fn call_progress(progress: BaffleProgressFn, user_data: *mut c_void, fraction: f64, stage: &str) -> bool {
    let Some(callback) = progress else { return true };
    let name = CString::new(stage.replace('\0', " ")).unwrap_or_default();
    callback(fraction, name.as_ptr(), user_data) != 0
}

fn design_error(e: DesignError) -> CallError {
    if let DesignError::Infeasible { max_feasible_area_mm2, .. } = e {
        set_last_max_feasible_area_mm2(max_feasible_area_mm2);
    }
    let status = match e {
        DesignError::Surface(_) | DesignError::MissingLabel { .. } | DesignError::SuturePoints(_) | DesignError::Target(_) => {
            BaffleStatus::InvalidInput
        }
        DesignError::Options(_) => BaffleStatus::InvalidArgument,
        DesignError::Cancelled(_) => BaffleStatus::Cancelled,
        DesignError::Seam(_) | DesignError::Baffle(_) | DesignError::Infeasible { .. } | DesignError::Numerical { .. } => BaffleStatus::DesignFailed,
    };
    CallError::new(status, e.to_string())
}
