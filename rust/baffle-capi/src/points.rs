//! Suture points from files (Slicer markups and the other formats baffle-core
//! reads), and the built-in synthetic phantom, for callers without a reader.

use crate::alloc::malloc_copy;
use crate::mesh_handle::BaffleMesh;
use crate::status::{guarded, out_handle, out_ref, BaffleStatus, CallError};
use baffle_core::io::{read_points, CoordinateSystem};
use baffle_core::phantom::{phantom_default, phantom_with_suture_half_angle, Phantom};
use baffle_core::Vec3;
use std::ffi::{c_char, CStr};

/// Patient frame to express points in (files say which frame they are in).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BaffleFrame {
    Lps = 0,
    Ras = 1,
}

/// Read suture points (.mrk.json, .json, .fcsv, .csv, .txt), converted into
/// `frame` (a BaffleFrame value; Slicer's model files are LPS). On success
/// `*out_points_mm` is a new double[*out_points_len] array (free with baffle_free).
///
/// # Safety
/// `path` must be NULL or a NUL-terminated string; the outputs NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn baffle_read_suture_points(
    path: *const c_char,
    frame: i32,
    out_points_mm: *mut *mut f64,
    out_points_len: *mut usize,
) -> BaffleStatus {
    guarded(|| {
        let out_points = out_ref(out_points_mm, "out_points_mm")?;
        let out_len = out_ref(out_points_len, "out_points_len")?;
        (*out_points, *out_len) = (std::ptr::null_mut(), 0);
        if path.is_null() {
            return Err(CallError::null("path"));
        }
        let path = CStr::from_ptr(path).to_str().map_err(|_| CallError::invalid("path is not UTF-8"))?;
        let frame = match frame {
            0 => CoordinateSystem::Lps,
            1 => CoordinateSystem::Ras,
            other => return Err(CallError::invalid(format!("frame = {other} is not a BaffleFrame"))),
        };
        let points = read_points(std::path::Path::new(path)).map_err(|e| CallError::new(BaffleStatus::Io, e.to_string()))?;
        let flat = flatten(&points.to_frame(frame));
        *out_points = malloc_copy(&flat)?;
        *out_len = flat.len();
        Ok(())
    })
}

/// The built-in synthetic phantom: a closed labelled surface (new handle), its
/// suture points (new double[*out_points_len] array, free with baffle_free) and
/// the body surface area it is sized for (m2).
///
/// # Safety
/// The outputs must be NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn baffle_phantom(
    out_surface: *mut *mut BaffleMesh,
    out_points_mm: *mut *mut f64,
    out_points_len: *mut usize,
    out_bsa_m2: *mut f64,
) -> BaffleStatus {
    guarded(|| write_phantom(Ok(phantom_default()), out_surface, out_points_mm, out_points_len, out_bsa_m2))
}

/// The phantom with its suture loop wrapped `suture_half_angle_deg` round the tunnel
/// from its outermost line (the default phantom's is 70 degrees; a wider loop leaves
/// less baffle near the caps, so large targets become infeasible). Outputs as
/// baffle_phantom; an angle outside (0, 180) is BAFFLE_STATUS_INVALID_ARGUMENT.
///
/// # Safety
/// The outputs must be NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn baffle_phantom_with_suture_half_angle(
    suture_half_angle_deg: f64,
    out_surface: *mut *mut BaffleMesh,
    out_points_mm: *mut *mut f64,
    out_points_len: *mut usize,
    out_bsa_m2: *mut f64,
) -> BaffleStatus {
    guarded(|| {
        let phantom = phantom_with_suture_half_angle(suture_half_angle_deg).map_err(|e| CallError::invalid(format!("suture_half_angle_deg: {e}")));
        write_phantom(phantom, out_surface, out_points_mm, out_points_len, out_bsa_m2)
    })
}

unsafe fn write_phantom(
    phantom: Result<Phantom, CallError>,
    out_surface: *mut *mut BaffleMesh,
    out_points_mm: *mut *mut f64,
    out_points_len: *mut usize,
    out_bsa_m2: *mut f64,
) -> Result<(), CallError> {
    let out_surface = out_handle(out_surface, "out_surface")?;
    let out_points = out_ref(out_points_mm, "out_points_mm")?;
    let out_len = out_ref(out_points_len, "out_points_len")?;
    (*out_points, *out_len) = (std::ptr::null_mut(), 0);
    let out_bsa = out_ref(out_bsa_m2, "out_bsa_m2")?;
    let phantom = phantom?;
    let flat = flatten(&phantom.suture_points_mm);
    *out_points = malloc_copy(&flat)?;
    *out_len = flat.len();
    *out_bsa = phantom.bsa_m2;
    *out_surface = BaffleMesh::boxed(phantom.surface);
    Ok(())
}

fn flatten(points: &[Vec3]) -> Vec<f64> {
    points.iter().flat_map(|p| [p.x, p.y, p.z]).collect()
}
