//! C ABI of the baffle design, for C/C++ (VTK, Slicer), Python (ctypes) and CMake
//! projects. The header `include/baffle.h` is generated from this crate by
//! cbindgen (see `build.rs`).
//!
//! Every exported function returns a [`BaffleStatus`] and never unwinds: argument
//! errors (null pointers, wrong sizes, non-finite coordinates, out-of-range
//! indices) and panics become status codes with a thread-local message
//! ([`baffle_last_error`]). Handles are immutable after creation, so they may be
//! shared between threads.

mod alloc;
mod design;
mod flow;
mod mesh_handle;
mod options;
mod plan;
mod points;
mod result;
mod status;
mod template;

pub use alloc::baffle_free;
pub use design::{baffle_design, BaffleProgressFn};
pub use flow::baffle_peak_flow_ml_s;
pub use mesh_handle::{
    baffle_mesh_copy_labels, baffle_mesh_copy_points, baffle_mesh_copy_triangles, baffle_mesh_free, baffle_mesh_new,
    baffle_mesh_new_vtk, baffle_mesh_point_count, baffle_mesh_triangle_count, BaffleMesh,
};
pub use options::{baffle_design_options_init, BaffleDesignOptions, BaffleTargetKind};
pub use plan::{
    baffle_plan, baffle_plan_options_init, baffle_plan_result_dp_mmhg, baffle_plan_result_dp_threshold_mmhg, baffle_plan_result_free,
    baffle_plan_result_reason, baffle_plan_result_reason_count, baffle_plan_result_report_html_path, baffle_plan_result_report_json_path,
    baffle_plan_result_v_max_m_s, baffle_plan_result_verdict, baffle_plan_result_verdict_text, baffle_plan_write_case, BaffleCancelFn,
    BafflePlanMode, BafflePlanOptions, BafflePlanResult, BaffleVerdict,
};
pub use points::{baffle_phantom, baffle_phantom_with_suture_half_angle, baffle_read_suture_points, BaffleFrame};
pub use result::{
    baffle_result_baffle, baffle_result_centerline_count, baffle_result_copy_centerline, baffle_result_copy_sections,
    baffle_result_copy_seam, baffle_result_domain, baffle_result_free, baffle_result_report_json,
    baffle_result_section_count, baffle_result_seam_count, baffle_result_target_area_mm2, BaffleResult,
};
pub use template::{
    baffle_template, baffle_template_document, baffle_template_flat_mesh, baffle_template_free, baffle_template_png, baffle_template_report_json, BaffleFlattenMethod,
    BaffleTemplate, BaffleTemplateFormat,
};
pub use status::{baffle_last_error, baffle_last_max_feasible_area_mm2, BaffleStatus};

use std::ffi::c_char;

/// Version of the binary interface: bumped when a function's signature or a
/// struct's existing fields change (growing BaffleDesignOptions does not bump it).
pub const BAFFLE_ABI_VERSION: u32 = 1;

/// The library's version ("major.minor.patch"), a static string.
#[no_mangle]
pub extern "C" fn baffle_version() -> *const c_char {
    concat!(env!("CARGO_PKG_VERSION"), "\0").as_ptr().cast()
}

/// The ABI version the library was built with (compare with BAFFLE_ABI_VERSION).
#[no_mangle]
pub extern "C" fn baffle_abi_version() -> u32 {
    BAFFLE_ABI_VERSION
}
