//! Status codes, the thread-local last error, and the guard every exported
//! function runs its body in (argument errors and panics become status codes).

use std::cell::{Cell, RefCell};
use std::ffi::{c_char, CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};
use baffle_core::Vec3;

/// What a call did. 0 is success; every other value has a message in
/// baffle_last_error().
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BaffleStatus {
    Ok = 0,
    /// A required pointer argument was NULL.
    NullPointer = 1,
    /// An argument is malformed: wrong length, non-finite coordinate, index out of
    /// range, option outside its range.
    InvalidArgument = 2,
    /// The caller's buffer is smaller than the data (query the size first).
    BufferTooSmall = 3,
    /// The options struct's struct_size is one this library does not know.
    UnsupportedVersion = 4,
    /// The design rejected its input: open or mislabelled surface, unusable
    /// suture points, invalid target.
    InvalidInput = 5,
    /// The geometry cannot give a valid baffle (seam, area constraint, numerics).
    DesignFailed = 6,
    /// The progress callback asked to stop.
    Cancelled = 7,
    /// A file could not be read.
    Io = 8,
    /// A bug inside the library (a caught panic); the handles passed in are intact.
    Internal = 9,
    /// A stage of baffle_plan() failed: the message names it, and the stages finished
    /// before it keep their folders.
    PlanFailed = 10,
}

/// A failed call: its status and what to tell the caller.
#[derive(Debug)]
pub(crate) struct CallError {
    pub status: BaffleStatus,
    pub message: String,
}

impl CallError {
    pub fn new(status: BaffleStatus, message: impl Into<String>) -> Self {
        CallError { status, message: message.into() }
    }
    pub fn null(name: &str) -> Self {
        CallError::new(BaffleStatus::NullPointer, format!("{name} is NULL"))
    }
    pub fn invalid(message: impl Into<String>) -> Self {
        CallError::new(BaffleStatus::InvalidArgument, message)
    }
}

thread_local! {
    static LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
    static LAST_MAX_FEASIBLE_AREA_MM2: Cell<f64> = const { Cell::new(f64::NAN) };
}

/// Record the largest target (mm2) the seam admits, for the failed call underway.
pub(crate) fn set_last_max_feasible_area_mm2(area_mm2: f64) {
    LAST_MAX_FEASIBLE_AREA_MM2.with(|a| a.set(area_mm2));
}

/// When the last call on this thread failed because the target area cannot be
/// reached on the seam (status DesignFailed), the largest target area (mm2) the
/// seam admits (0 when it admits no tunnel); NaN after any other outcome.
#[no_mangle]
pub extern "C" fn baffle_last_max_feasible_area_mm2() -> f64 {
    LAST_MAX_FEASIBLE_AREA_MM2.with(|a| a.get())
}

fn set_last_error(message: &str) {
    // Interior NULs would truncate the C string; they never carry meaning here.
    let text = CString::new(message.replace('\0', " ")).unwrap_or_default();
    LAST_ERROR.with(|e| *e.borrow_mut() = text);
}

/// Message of the last failed call on this thread ("" after a successful one).
/// The pointer stays valid until the next baffle_* call on this thread.
#[no_mangle]
pub extern "C" fn baffle_last_error() -> *const c_char {
    LAST_ERROR.with(|e| e.borrow().as_ptr())
}

/// Run an exported function's body: clear the last error, catch panics, and turn
/// the outcome into a status (recording the message on failure).
pub(crate) fn guarded(body: impl FnOnce() -> Result<(), CallError>) -> BaffleStatus {
    set_last_error("");
    set_last_max_feasible_area_mm2(f64::NAN);
    let outcome = catch_unwind(AssertUnwindSafe(body)).unwrap_or_else(|payload| {
        let what = payload
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown panic".into());
        Err(CallError::new(BaffleStatus::Internal, format!("internal error: {what}")))
    });
    match outcome {
        Ok(()) => BaffleStatus::Ok,
        Err(e) => {
            set_last_error(&e.message);
            e.status
        }
    }
}

/// A shared reference from a caller's pointer, or an error naming the argument.
///
/// # Safety
/// `ptr` must be NULL or point to a live, properly initialised `T`.
pub(crate) unsafe fn arg_ref<'a, T>(ptr: *const T, name: &str) -> Result<&'a T, CallError> {
    ptr.as_ref().ok_or_else(|| CallError::null(name))
}

/// An output location from a caller's pointer, or an error naming the argument.
///
/// # Safety
/// `ptr` must be NULL or point to writable memory for a `T`.
pub(crate) unsafe fn out_ref<'a, T>(ptr: *mut T, name: &str) -> Result<&'a mut T, CallError> {
    if ptr.is_null() {
        return Err(CallError::null(name));
    }
    if !ptr.is_aligned() {
        return Err(CallError::invalid(format!("{name} is not aligned for its type")));
    }
    Ok(&mut *ptr)
}

/// An output handle location from a caller's pointer (as [`out_ref`]), set to NULL so that
/// a call that fails leaves no stale handle there.
///
/// # Safety
/// `ptr` must be NULL or point to writable memory for a handle pointer.
pub(crate) unsafe fn out_handle<'a, T>(ptr: *mut *mut T, name: &str) -> Result<&'a mut *mut T, CallError> {
    let out = out_ref(ptr, name)?;
    *out = std::ptr::null_mut();
    Ok(out)
}

/// Free a handle this library boxed (NULL is ignored): the body of every `baffle_*_free`.
///
/// # Safety
/// `handle` must be NULL or a `Box` of this library's turned into a raw pointer, not yet freed.
pub(crate) unsafe fn free_handle<T>(handle: *mut T) {
    if !handle.is_null() {
        drop(Box::from_raw(handle));
    }
}

/// A caller's input array of `len` elements (NULL is accepted only when `len` is 0).
///
/// # Safety
/// `ptr` must be NULL or point to `len` readable, initialised elements.
pub(crate) unsafe fn in_slice<'a, T>(ptr: *const T, len: usize, name: &str) -> Result<&'a [T], CallError> {
    if len == 0 {
        return Ok(&[]);
    }
    checked_array(ptr, len, name)?;
    Ok(std::slice::from_raw_parts(ptr, len))
}

/// A caller's output buffer of `capacity` elements that must hold `needed`.
///
/// # Safety
/// `ptr` must be NULL or point to `capacity` writable elements.
pub(crate) unsafe fn out_slice<'a, T>(ptr: *mut T, capacity: usize, needed: usize, name: &str) -> Result<&'a mut [T], CallError> {
    if capacity < needed {
        return Err(CallError::new(
            BaffleStatus::BufferTooSmall,
            format!("{name} holds {capacity} elements, {needed} are needed"),
        ));
    }
    if needed == 0 {
        return Ok(&mut []);
    }
    checked_array(ptr, needed, name)?;
    Ok(std::slice::from_raw_parts_mut(ptr, needed))
}

fn checked_array<T>(ptr: *const T, len: usize, name: &str) -> Result<(), CallError> {
    if ptr.is_null() {
        return Err(CallError::null(name));
    }
    if !ptr.is_aligned() {
        return Err(CallError::invalid(format!("{name} is not aligned for its element type")));
    }
    if len.checked_mul(std::mem::size_of::<T>()).is_none_or(|bytes| bytes > isize::MAX as usize) {
        return Err(CallError::invalid(format!("{name}: length {len} is too large")));
    }
    Ok(())
}

/// `len` as a whole number of xyz triples, or an error naming the array.
fn xyz_count(len: usize, name: &str) -> Result<usize, CallError> {
    if !len.is_multiple_of(3) {
        return Err(CallError::invalid(format!("{name} has {len} values, not a multiple of 3 (x, y, z per point)")));
    }
    Ok(len / 3)
}

/// The caller's flat array `values` (x, y, z per point) as points, or an error naming the
/// array `name`: a length that is not whole triples, or a non-finite coordinate.
pub(crate) fn xyz_points(values: &[f64], name: &str) -> Result<Vec<Vec3>, CallError> {
    xyz_count(values.len(), name)?;
    check_finite(values, name)?;
    Ok(values.chunks_exact(3).map(|p| Vec3::new(p[0], p[1], p[2])).collect())
}

/// Error if any coordinate is NaN or infinite, naming the first such point.
fn check_finite(values: &[f64], name: &str) -> Result<(), CallError> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(i) => Err(CallError::invalid(format!("{name}: point {} has a non-finite coordinate ({})", i / 3, values[i]))),
        None => Ok(()),
    }
}

/// A caller's optional string argument (NULL: None), or an error naming it.
///
/// # Safety
/// `text` must be NULL or a NUL-terminated string.
pub(crate) unsafe fn optional_str<'a>(text: *const c_char, name: &str) -> Result<Option<&'a str>, CallError> {
    if text.is_null() {
        return Ok(None);
    }
    CStr::from_ptr(text).to_str().map(Some).map_err(|_| CallError::invalid(format!("{name} is not UTF-8")))
}
