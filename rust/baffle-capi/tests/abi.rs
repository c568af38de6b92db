//! The C ABI called as C would call it: argument errors become status codes with
//! messages, the phantom design round-trips through the getters, cancellation and
//! concurrent calls work.

use baffle::*;
use std::ffi::{c_char, c_void, CStr};
use std::ptr::{null, null_mut};

fn last_error() -> String {
    unsafe { CStr::from_ptr(baffle_last_error()) }.to_string_lossy().into_owned()
}

/// A unit tetrahedron, labelled so each cap label is present.
fn tetra() -> (Vec<f64>, Vec<i64>, Vec<i32>) {
    let points = vec![0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
    let tris = vec![0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3];
    (points, tris, vec![2, 2, 11, 16])
}

fn new_mesh(points: &[f64], tris: &[i64], labels: &[i32]) -> (BaffleStatus, *mut BaffleMesh) {
    let mut mesh = null_mut();
    let status = unsafe {
        baffle_mesh_new(points.as_ptr(), points.len(), tris.as_ptr(), tris.len(), labels.as_ptr(), labels.len(), &mut mesh)
    };
    (status, mesh)
}

struct Phantom {
    surface: *mut BaffleMesh,
    points: Vec<f64>,
    bsa_m2: f64,
}

impl Drop for Phantom {
    fn drop(&mut self) {
        unsafe { baffle_mesh_free(self.surface) };
    }
}

fn phantom() -> Phantom {
    phantom_from(|surface, points, len, bsa_m2| unsafe { baffle_phantom(surface, points, len, bsa_m2) })
}

/// The phantom with its suture loop wrapped `half_angle_deg` round the tunnel.
fn wrapped_phantom(half_angle_deg: f64) -> Phantom {
    phantom_from(|surface, points, len, bsa_m2| unsafe { baffle_phantom_with_suture_half_angle(half_angle_deg, surface, points, len, bsa_m2) })
}

fn phantom_from(make: impl FnOnce(*mut *mut BaffleMesh, *mut *mut f64, *mut usize, *mut f64) -> BaffleStatus) -> Phantom {
    let (mut surface, mut points, mut len, mut bsa_m2) = (null_mut(), null_mut(), 0usize, 0.0);
    assert_eq!(make(&mut surface, &mut points, &mut len, &mut bsa_m2), BaffleStatus::Ok, "{}", last_error());
    let copy = unsafe { std::slice::from_raw_parts(points, len) }.to_vec();
    unsafe { baffle_free(points.cast()) };
    Phantom { surface, points: copy, bsa_m2 }
}

fn bsa_options(bsa_m2: f64) -> BaffleDesignOptions {
    let mut options = std::mem::MaybeUninit::<BaffleDesignOptions>::uninit();
    assert_eq!(unsafe { baffle_design_options_init(options.as_mut_ptr()) }, BaffleStatus::Ok);
    let mut options = unsafe { options.assume_init() };
    options.target_kind = BaffleTargetKind::Bsa as i32;
    options.bsa_m2 = bsa_m2;
    options
}

fn run_design(p: &Phantom, options: &BaffleDesignOptions, progress: BaffleProgressFn, user: *mut c_void) -> (BaffleStatus, *mut BaffleResult) {
    design_with_points(p.surface, &p.points, options, progress, user)
}

fn design_with_points(
    surface: *const BaffleMesh,
    points: &[f64],
    options: &BaffleDesignOptions,
    progress: BaffleProgressFn,
    user: *mut c_void,
) -> (BaffleStatus, *mut BaffleResult) {
    let mut result = null_mut();
    let status = unsafe { baffle_design(surface, points.as_ptr(), points.len(), options, progress, user, &mut result) };
    (status, result)
}

#[test]
fn versions_are_reported() {
    assert_eq!(baffle_abi_version(), BAFFLE_ABI_VERSION);
    let version = unsafe { CStr::from_ptr(baffle_version()) }.to_str().unwrap();
    assert_eq!(version, env!("CARGO_PKG_VERSION"));
}

#[test]
fn mesh_round_trips_through_plain_and_vtk_layouts() {
    let (points, tris, labels) = tetra();
    let (status, mesh) = new_mesh(&points, &tris, &labels);
    assert_eq!(status, BaffleStatus::Ok, "{}", last_error());
    let offsets = [0i64, 3, 6, 9, 12];
    let mut vtk = null_mut();
    let status = unsafe {
        baffle_mesh_new_vtk(points.as_ptr(), 12, offsets.as_ptr(), 5, tris.as_ptr(), 12, labels.as_ptr(), 4, &mut vtk)
    };
    assert_eq!(status, BaffleStatus::Ok, "{}", last_error());
    for handle in [mesh, vtk] {
        let (mut np, mut nt) = (0, 0);
        unsafe {
            assert_eq!(baffle_mesh_point_count(handle, &mut np), BaffleStatus::Ok);
            assert_eq!(baffle_mesh_triangle_count(handle, &mut nt), BaffleStatus::Ok);
        }
        assert_eq!((np, nt), (4, 4));
        let (mut p, mut t, mut l) = (vec![0.0; 12], vec![0i64; 12], vec![0i32; 4]);
        unsafe {
            assert_eq!(baffle_mesh_copy_points(handle, p.as_mut_ptr(), p.len()), BaffleStatus::Ok);
            assert_eq!(baffle_mesh_copy_triangles(handle, t.as_mut_ptr(), t.len()), BaffleStatus::Ok);
            assert_eq!(baffle_mesh_copy_labels(handle, l.as_mut_ptr(), l.len()), BaffleStatus::Ok);
            baffle_mesh_free(handle);
        }
        assert_eq!((p, t, l), (points.clone(), tris.clone(), labels.clone()));
    }
}

#[test]
fn malformed_meshes_are_rejected_with_a_message() {
    let (points, tris, labels) = tetra();
    let mut nan_points = points.clone();
    nan_points[4] = f64::NAN;
    let mut far_tris = tris.clone();
    far_tris[5] = 4;
    let mut negative_tris = tris.clone();
    negative_tris[0] = -1;
    type Case<'a> = (&'a [f64], &'a [i64], &'a [i32], &'a str);
    let cases: [Case; 5] = [
        (&nan_points, &tris, &labels, "point 1 has a non-finite coordinate"),
        (&points, &far_tris, &labels, "triangle 1 refers to point 4"),
        (&points, &negative_tris, &labels, "triangle 0 refers to point -1"),
        (&points[..11], &tris, &labels, "not a multiple of 3"),
        (&points, &tris, &labels[..3], "3 labels for 4 triangles"),
    ];
    for (p, t, l, expected) in cases {
        let (status, mesh) = new_mesh(p, t, l);
        assert_eq!(status, BaffleStatus::InvalidArgument);
        assert!(mesh.is_null());
        assert!(last_error().contains(expected), "{:?} lacks {expected:?}", last_error());
    }
}

#[test]
fn non_triangle_vtk_cells_are_rejected() {
    let (points, tris, labels) = tetra();
    let offsets = [0i64, 4, 6, 9, 12];
    let mut mesh = null_mut();
    let status = unsafe {
        baffle_mesh_new_vtk(points.as_ptr(), 12, offsets.as_ptr(), 5, tris.as_ptr(), 12, labels.as_ptr(), 4, &mut mesh)
    };
    assert_eq!(status, BaffleStatus::InvalidArgument);
    assert!(last_error().contains("cell 0 has 4 points"), "{}", last_error());
}

#[test]
fn null_pointers_are_errors_not_crashes() {
    let (points, tris, labels) = tetra();
    let mut mesh = null_mut();
    let status = unsafe { baffle_mesh_new(null(), 12, tris.as_ptr(), 12, labels.as_ptr(), 4, &mut mesh) };
    assert_eq!(status, BaffleStatus::NullPointer);
    assert_eq!(last_error(), "points_mm is NULL");
    let status = unsafe { baffle_mesh_new(points.as_ptr(), 12, tris.as_ptr(), 12, labels.as_ptr(), 4, null_mut()) };
    assert_eq!(status, BaffleStatus::NullPointer);
    let mut count = 0;
    assert_eq!(unsafe { baffle_mesh_point_count(null(), &mut count) }, BaffleStatus::NullPointer);
    assert_eq!(last_error(), "mesh is NULL");
    let options = bsa_options(0.37);
    let mut result = null_mut();
    let status = unsafe { baffle_design(null(), points.as_ptr(), 12, &options, None, null_mut(), &mut result) };
    assert_eq!(status, BaffleStatus::NullPointer);
    assert!(result.is_null());
    assert_eq!(unsafe { baffle_design_options_init(null_mut()) }, BaffleStatus::NullPointer);
    unsafe {
        baffle_mesh_free(null_mut());
        baffle_result_free(null_mut());
        baffle_free(null_mut());
    }
}

#[test]
fn open_surface_and_too_few_points_are_invalid_input() {
    let (points, tris, labels) = tetra();
    // Dropping one wall triangle leaves a hole but every label present.
    let (status, open) = new_mesh(&points, &tris[3..], &labels[1..]);
    assert_eq!(status, BaffleStatus::Ok);
    let options = bsa_options(0.37);
    let mut result = null_mut();
    let status = unsafe { baffle_design(open, points.as_ptr(), 12, &options, None, null_mut(), &mut result) };
    assert_eq!(status, BaffleStatus::InvalidInput, "{}", last_error());
    assert!(last_error().contains("not a closed manifold"), "{}", last_error());
    unsafe { baffle_mesh_free(open) };

    let p = phantom();
    let (status, result) = design_with_points(p.surface, &p.points[..6], &options, None, null_mut());
    assert_eq!(status, BaffleStatus::InvalidInput, "{}", last_error());
    assert!(result.is_null());
    assert!(last_error().starts_with("suture points:"), "{}", last_error());
}

#[test]
fn options_are_checked() {
    let p = phantom();
    let mut options = bsa_options(p.bsa_m2);
    options.struct_size = 8;
    assert_eq!(run_design(&p, &options, None, null_mut()).0, BaffleStatus::UnsupportedVersion);
    let mut options = bsa_options(p.bsa_m2);
    options.seam_samples = 0;
    assert_eq!(run_design(&p, &options, None, null_mut()).0, BaffleStatus::InvalidArgument);
    assert!(last_error().contains("seam_samples"), "{}", last_error());
    let mut options = bsa_options(p.bsa_m2);
    options.target_kind = 42;
    assert_eq!(run_design(&p, &options, None, null_mut()).0, BaffleStatus::InvalidArgument);
    let options = bsa_options(f64::NAN);
    assert_eq!(run_design(&p, &options, None, null_mut()).0, BaffleStatus::InvalidInput);
    assert!(last_error().contains("target area"), "{}", last_error());
}

fn report(result: *const BaffleResult) -> serde_json::Value {
    let mut json: *mut c_char = null_mut();
    assert_eq!(unsafe { baffle_result_report_json(result, &mut json) }, BaffleStatus::Ok);
    let text = unsafe { CStr::from_ptr(json) }.to_str().unwrap().to_owned();
    unsafe { baffle_free(json.cast()) };
    serde_json::from_str(&text).unwrap()
}

#[test]
fn phantom_design_results_are_copied_out() {
    let p = phantom();
    let (status, result) = run_design(&p, &bsa_options(p.bsa_m2), None, null_mut());
    assert_eq!(status, BaffleStatus::Ok, "{}", last_error());
    let report = report(result);
    let mut target = 0.0;
    assert_eq!(unsafe { baffle_result_target_area_mm2(result, &mut target) }, BaffleStatus::Ok);
    assert_eq!(report["target_area_mm2"].as_f64(), Some(target));
    // No peak flow by default: no estimate, and the report says why.
    let why = report["hemodynamics_estimate"]["absent_because"].as_str().unwrap_or_default();
    assert!(why.contains("options.peak_flow_ml_s"), "{}", report["hemodynamics_estimate"]);

    let mut n = 0;
    assert_eq!(unsafe { baffle_result_section_count(result, &mut n) }, BaffleStatus::Ok);
    let (mut s, mut o, mut nn, mut c, mut a) = (vec![0.0; n], vec![0.0; 3 * n], vec![0.0; 3 * n], vec![0; n], vec![0.0; n]);
    let status = unsafe {
        baffle_result_copy_sections(result, s.as_mut_ptr(), o.as_mut_ptr(), nn.as_mut_ptr(), c.as_mut_ptr(), a.as_mut_ptr(), n)
    };
    assert_eq!(status, BaffleStatus::Ok);
    assert_eq!(c.iter().sum::<i32>() as u64, report["constrained_sections"].as_u64().unwrap());
    for k in (0..n).filter(|&k| c[k] == 1) {
        assert!(a[k] >= target, "section {k} at s = {} mm has {} < {target} mm2", s[k], a[k]);
    }

    let mut samples = 0;
    assert_eq!(unsafe { baffle_result_centerline_count(result, &mut samples) }, BaffleStatus::Ok);
    assert_eq!(samples, n, "one section per centerline sample");
    let (mut pts, mut tan, mut s_mm) = (vec![0.0; 3 * n], vec![0.0; 3 * n], vec![0.0; n]);
    let status = unsafe { baffle_result_copy_centerline(result, pts.as_mut_ptr(), tan.as_mut_ptr(), s_mm.as_mut_ptr(), n) };
    assert_eq!(status, BaffleStatus::Ok);
    assert_eq!((pts, s_mm), (o, s));

    let mut domain = null_mut();
    assert_eq!(unsafe { baffle_result_domain(result, &mut domain) }, BaffleStatus::Ok);
    let mut triangles = 0;
    unsafe { baffle_mesh_triangle_count(domain, &mut triangles) };
    assert_eq!(Some(triangles as u64), report["domain_triangles"].as_u64());
    unsafe {
        baffle_mesh_free(domain);
        baffle_result_free(result);
    }
}

/// options.peak_flow_ml_s, appended after the first layout: the estimate with it; a
/// caller compiled against the first layout (struct_size up to tps_regularization) keeps
/// working and gets no estimate, whatever lies in its memory after the struct.
#[test]
fn a_peak_flow_adds_the_estimate_and_first_layout_callers_keep_working() {
    let p = phantom();
    let mut options = bsa_options(p.bsa_m2);
    assert!(options.peak_flow_ml_s.is_nan(), "no peak flow by default");
    for bad in [-1.0, f64::INFINITY] {
        options.peak_flow_ml_s = bad;
        assert_eq!(run_design(&p, &options, None, null_mut()).0, BaffleStatus::InvalidArgument);
        assert!(last_error().contains("options.peak_flow_ml_s"), "{}", last_error());
    }
    options.peak_flow_ml_s = 70.0;
    let (status, result) = run_design(&p, &options, None, null_mut());
    assert_eq!(status, BaffleStatus::Ok, "{}", last_error());
    let e = report(result)["hemodynamics_estimate"].clone();
    unsafe { baffle_result_free(result) };
    assert_eq!(e["peak_flow_ml_s"].as_f64(), Some(70.0), "{e}");
    assert!(e["dp_estimate_mmhg"].as_f64().unwrap().is_finite() && e["v_max_estimate_m_s"].as_f64().unwrap() > 0.0, "{e}");
    let first_layout = std::mem::offset_of!(BaffleDesignOptions, peak_flow_ml_s);
    assert_eq!(first_layout, 144, "the first published layout's size");
    options.struct_size = first_layout as u32;
    let (status, result) = run_design(&p, &options, None, null_mut());
    assert_eq!(status, BaffleStatus::Ok, "{}", last_error());
    let e = report(result)["hemodynamics_estimate"].clone();
    unsafe { baffle_result_free(result) };
    assert!(e["absent_because"].is_string() && e.get("dp_estimate_mmhg").is_none(), "{e}");
}

/// options.flow_sections (the command line's --flow-sections): the design holds the
/// flow-normal sections at the target too, and its report says how (flow_sections);
/// without it the report has none.
#[test]
fn flow_sections_reach_the_design_through_its_options() {
    let p = phantom();
    let mut options = bsa_options(p.bsa_m2);
    assert_eq!(options.flow_sections, 0, "the paper's sections only by default");
    let (status, result) = run_design(&p, &options, None, null_mut());
    assert_eq!(status, BaffleStatus::Ok, "{}", last_error());
    assert!(report(result)["flow_sections"].is_null());
    unsafe { baffle_result_free(result) };
    options.flow_sections = 1;
    let (status, result) = run_design(&p, &options, None, null_mut());
    assert_eq!(status, BaffleStatus::Ok, "{}", last_error());
    let flow = report(result)["flow_sections"].clone();
    unsafe { baffle_result_free(result) };
    assert!(flow["goal_area_mm2"].as_f64().is_some_and(|a| a > 0.0) && !flow["rounds"].as_array().unwrap().is_empty(), "{flow}");
}

/// The flow a front end without a CFD case gives the estimate: the paper's 3.26 x BSA x
/// cardiac index, the 3D run's peak; bad values are named, a NULL output is an error.
#[test]
fn the_peak_flow_for_the_estimate_is_the_papers() {
    let mut q = f64::NAN;
    assert_eq!(unsafe { baffle_peak_flow_ml_s(0.37, 3.48, &mut q) }, BaffleStatus::Ok);
    assert!((q - 69.96).abs() < 0.01, "p2's Table 4 peak flow, got {q}");
    assert_eq!(unsafe { baffle_peak_flow_ml_s(0.0, 3.48, &mut q) }, BaffleStatus::InvalidArgument);
    assert!(last_error().contains("BSA"), "{}", last_error());
    assert_eq!(unsafe { baffle_peak_flow_ml_s(0.37, f64::NAN, &mut q) }, BaffleStatus::InvalidArgument);
    assert!(last_error().contains("cardiac index"), "{}", last_error());
    assert_eq!(unsafe { baffle_peak_flow_ml_s(0.37, 3.48, null_mut()) }, BaffleStatus::NullPointer);
}

#[test]
fn small_buffers_are_reported_not_overrun() {
    let p = phantom();
    let mut buffer = [0.0f64; 6];
    assert_eq!(unsafe { baffle_mesh_copy_points(p.surface, buffer.as_mut_ptr(), buffer.len()) }, BaffleStatus::BufferTooSmall);
    assert!(last_error().contains("holds 6 elements"), "{}", last_error());
}

unsafe extern "C" fn stop_at_sections(fraction: f64, stage: *const c_char, user: *mut c_void) -> i32 {
    let seen = &mut *(user as *mut Vec<(f64, String)>);
    seen.push((fraction, CStr::from_ptr(stage).to_string_lossy().into_owned()));
    i32::from(seen.last().unwrap().1 != "sections")
}

#[test]
fn progress_callback_cancels() {
    let p = phantom();
    let mut seen: Vec<(f64, String)> = Vec::new();
    let user = &mut seen as *mut Vec<(f64, String)> as *mut c_void;
    let (status, result) = run_design(&p, &bsa_options(p.bsa_m2), Some(stop_at_sections), user);
    assert_eq!(status, BaffleStatus::Cancelled);
    assert!(result.is_null());
    assert_eq!(last_error(), "cancelled during sections");
    assert_eq!(seen.first().map(|s| s.1.as_str()), Some("validate"));
    assert!(seen.windows(2).all(|w| w[0].0 <= w[1].0), "fractions increase: {seen:?}");
}

#[test]
fn designs_run_concurrently_on_separate_handles() {
    let areas: Vec<f64> = std::thread::scope(|scope| {
        let jobs: Vec<_> = (0..2)
            .map(|_| {
                scope.spawn(|| {
                    let p = phantom();
                    let (status, result) = run_design(&p, &bsa_options(p.bsa_m2), None, null_mut());
                    assert_eq!(status, BaffleStatus::Ok, "{}", last_error());
                    let area = report(result)["baffle_area_mm2"].as_f64().unwrap();
                    unsafe { baffle_result_free(result) };
                    area
                })
            })
            .collect();
        jobs.into_iter().map(|j| j.join().unwrap()).collect()
    });
    assert_eq!(areas[0], areas[1], "the design is deterministic");
}

#[test]
fn an_unreachable_target_reports_the_largest_feasible_one() {
    // A suture loop wrapped 100 degrees round the tunnel leaves too little baffle near the caps.
    let p = wrapped_phantom(100.0);
    let mut options = bsa_options(p.bsa_m2);
    options.target_kind = BaffleTargetKind::AreaMm2 as i32;
    options.target_area_mm2 = 300.0;
    let (status, result) = run_design(&p, &options, None, null_mut());
    assert_eq!(status, BaffleStatus::DesignFailed, "{}", last_error());
    assert!(result.is_null());
    let largest = baffle_last_max_feasible_area_mm2();
    assert!(largest > 100.0 && largest < 300.0, "{largest}");
    assert!(last_error().contains(&format!("at most {largest:.1} mm2")), "{}", last_error());
    // An angle that makes no phantom is an argument error, not a panic.
    let (mut surface, mut points, mut len, mut bsa_m2) = (null_mut(), null_mut(), 0usize, 0.0);
    let status = unsafe { baffle_phantom_with_suture_half_angle(190.0, &mut surface, &mut points, &mut len, &mut bsa_m2) };
    assert_eq!(status, BaffleStatus::InvalidArgument);
    assert!(last_error().contains("below 180") && surface.is_null() && points.is_null(), "{}", last_error());
    // A call that succeeds clears it.
    let (status, result) = run_design(&p, &bsa_options(p.bsa_m2), None, null_mut());
    assert_eq!(status, BaffleStatus::Ok);
    assert!(baffle_last_max_feasible_area_mm2().is_nan());
    unsafe { baffle_result_free(result) };
}

#[test]
fn the_template_of_a_phantom_design_is_flat_true_scale_and_printable() {
    let p = phantom();
    let (status, result) = run_design(&p, &bsa_options(p.bsa_m2), None, null_mut());
    assert_eq!(status, BaffleStatus::Ok, "{}", last_error());
    let baffle_area_mm2 = report(result)["baffle_area_mm2"].as_f64().unwrap();
    let mut domain = null_mut();
    assert_eq!(unsafe { baffle_result_domain(result, &mut domain) }, BaffleStatus::Ok);
    let (names, patient, date) = (c"A\n\nC", c"phantom", c"2026-12-02");
    let mut template = null_mut();
    let status = unsafe {
        baffle_template(domain, p.points.as_ptr(), p.points.len(), names.as_ptr(), patient.as_ptr(), date.as_ptr(), null(), BaffleFlattenMethod::Lscm as i32, &mut template)
    };
    assert_eq!(status, BaffleStatus::Ok, "{}", last_error());

    let mut json: *mut c_char = null_mut();
    assert_eq!(unsafe { baffle_template_report_json(template, &mut json) }, BaffleStatus::Ok);
    let doc: serde_json::Value = serde_json::from_str(unsafe { CStr::from_ptr(json) }.to_str().unwrap()).unwrap();
    unsafe { baffle_free(json.cast()) };
    let flattening = &doc["flattening"];
    assert!(flattening["perimeter_error"].as_f64().unwrap() <= 0.01, "{flattening}");
    assert!((flattening["area_3d_mm2"].as_f64().unwrap() - baffle_area_mm2).abs() < 1e-6 * baffle_area_mm2);
    assert_eq!(doc["suture_point_to_seam_mm"].as_array().unwrap().len(), p.points.len() / 3);

    // The flat mesh: z = 0, one area ratio per triangle, and its area the report's flat area.
    let mut flat = null_mut();
    assert_eq!(unsafe { baffle_template_flat_mesh(template, &mut flat) }, BaffleStatus::Ok);
    let (mut np, mut nt) = (0, 0);
    unsafe { baffle_mesh_point_count(flat, &mut np) };
    unsafe { baffle_mesh_triangle_count(flat, &mut nt) };
    let (mut pts, mut tris) = (vec![0.0; 3 * np], vec![0i64; 3 * nt]);
    assert_eq!(unsafe { baffle_mesh_copy_points(flat, pts.as_mut_ptr(), pts.len()) }, BaffleStatus::Ok);
    assert_eq!(unsafe { baffle_mesh_copy_triangles(flat, tris.as_mut_ptr(), tris.len()) }, BaffleStatus::Ok);
    assert!(pts.chunks(3).all(|q| q[2] == 0.0));
    assert_eq!(doc["area_ratio"].as_array().unwrap().len(), nt);
    let flat_area: f64 = tris
        .chunks(3)
        .map(|t| {
            let q = |k: usize| [pts[3 * t[k] as usize], pts[3 * t[k] as usize + 1]];
            let (a, b, c) = (q(0), q(1), q(2));
            0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])).abs()
        })
        .sum();
    assert!((flat_area - flattening["area_flat_mm2"].as_f64().unwrap()).abs() < 1e-9 * flat_area);

    for (format, magic) in [(BaffleTemplateFormat::Pdf, b"%PDF".as_slice()), (BaffleTemplateFormat::Svg, b"<?xml".as_slice()), (BaffleTemplateFormat::Png, b"\x89PNG".as_slice())] {
        let (mut bytes, mut len) = (null_mut(), 0usize);
        assert_eq!(unsafe { baffle_template_document(template, format as i32, &mut bytes, &mut len) }, BaffleStatus::Ok);
        let page = unsafe { std::slice::from_raw_parts(bytes, len) }.to_vec();
        unsafe { baffle_free(bytes.cast()) };
        assert!(page.starts_with(magic) || (format == BaffleTemplateFormat::Svg && page.starts_with(b"<svg")), "{:?}", &page[..8]);
        if format != BaffleTemplateFormat::Png {
            assert!(page.windows(7).any(|w| w == b"phantom"), "the patient label is on the page");
        }
    }
    // The PNG at another resolution: a smaller file; an impossible one is named.
    let png_bytes = |dpi: f64| {
        let (mut bytes, mut len) = (null_mut(), 0usize);
        let status = unsafe { baffle_template_png(template, dpi, &mut bytes, &mut len) };
        let page = if bytes.is_null() { Vec::new() } else { unsafe { std::slice::from_raw_parts(bytes, len) }.to_vec() };
        unsafe { baffle_free(bytes.cast()) };
        (status, page)
    };
    let (status, small) = png_bytes(72.0);
    assert!(status == BaffleStatus::Ok && small.starts_with(b"\x89PNG"), "{status:?}");
    // pHYs: 72 dpi = 2835 px per metre.
    assert!(small.windows(13).any(|w| w == [b'p', b'H', b'Y', b's', 0, 0, 0x0b, 0x13, 0, 0, 0x0b, 0x13, 1]), "no 72 dpi pHYs");
    assert_eq!(png_bytes(f64::NAN).0, BaffleStatus::InvalidArgument);
    assert!(last_error().contains("dpi = NaN"), "{}", last_error());
    let (mut bytes, mut len) = (null_mut(), 0usize);
    assert_eq!(unsafe { baffle_template_document(template, 7, &mut bytes, &mut len) }, BaffleStatus::InvalidArgument);
    assert!(last_error().contains("format = 7"), "{}", last_error());

    // A domain without a baffle is named, not a crash.
    let (tp, tt, tl) = tetra();
    let (_, tetra_mesh) = new_mesh(&tp, &tt, &tl);
    let mut none = null_mut();
    let status = unsafe { baffle_template(tetra_mesh, null(), 0, null(), null(), null(), null(), 0, &mut none) };
    assert_eq!(status, BaffleStatus::InvalidInput);
    assert!(none.is_null() && last_error().contains("no baffle triangles"), "{}", last_error());
    unsafe {
        baffle_mesh_free(tetra_mesh);
        baffle_mesh_free(flat);
        baffle_template_free(template);
        baffle_mesh_free(domain);
        baffle_result_free(result);
    }
}
