//! Arrays and strings handed to the caller are allocated with the C allocator, so
//! one function (`baffle_free`) frees them whatever their type or length.

use crate::status::{BaffleStatus, CallError};
use std::ffi::{c_char, c_void};

extern "C" {
    fn malloc(size: usize) -> *mut c_void;
    fn free(ptr: *mut c_void);
}

/// Free an array or string the library handed out (NULL is ignored).
///
/// # Safety
/// `ptr` must be NULL or a pointer this library returned and not yet freed.
#[no_mangle]
pub unsafe extern "C" fn baffle_free(ptr: *mut c_void) {
    if !ptr.is_null() {
        free(ptr);
    }
}

/// A malloc'ed copy of `values` (at least one byte, so the pointer is never NULL).
pub(crate) fn malloc_copy<T: Copy>(values: &[T]) -> Result<*mut T, CallError> {
    let bytes = std::mem::size_of_val(values);
    // SAFETY: malloc returns memory aligned for any fundamental type, or NULL.
    let ptr = unsafe { malloc(bytes.max(1)) }.cast::<T>();
    if ptr.is_null() {
        return Err(CallError::new(BaffleStatus::Internal, format!("out of memory allocating {bytes} bytes")));
    }
    // SAFETY: ptr has room for values.len() elements and does not overlap values.
    unsafe { std::ptr::copy_nonoverlapping(values.as_ptr(), ptr, values.len()) };
    Ok(ptr)
}

/// A malloc'ed NUL-terminated copy of `text` (interior NULs become spaces).
pub(crate) fn malloc_string(text: &str) -> Result<*mut c_char, CallError> {
    let mut bytes: Vec<u8> = text.bytes().map(|b| if b == 0 { b' ' } else { b }).collect();
    bytes.push(0);
    Ok(malloc_copy(&bytes)?.cast())
}
