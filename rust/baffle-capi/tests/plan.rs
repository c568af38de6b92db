//! baffle_plan() through the C ABI as C would call it: a quick phantom plan gives the
//! report's verdict and numbers, cancelling keeps the stages already written (and stops
//! a running simulation), bad options are named before any stage runs, and the case a
//! front end writes with baffle_plan_write_case is the plan's.
//! Set BAFFLE_SKIP_GMSH=1 to skip the parts that mesh.

use baffle::*;
use std::ffi::{c_char, c_void, CStr, CString};
use std::path::{Path, PathBuf};
use std::ptr::null_mut;

fn last_error() -> String {
    unsafe { CStr::from_ptr(baffle_last_error()) }.to_string_lossy().into_owned()
}

fn skip_gmsh() -> bool {
    std::env::var("BAFFLE_SKIP_GMSH").is_ok_and(|v| v == "1")
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("baffle-capi-plan-{}-{name}", std::process::id()));
    std::fs::remove_dir_all(&dir).ok();
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn read_json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))).unwrap()
}

fn c_path(path: &Path) -> CString {
    CString::new(path.to_str().unwrap()).unwrap()
}

/// The phantom at p2's blood pressure, a quick run on one coarse mesh (seconds), into `out`.
fn quick_phantom(out: &CString) -> BafflePlanOptions {
    let mut options = std::mem::MaybeUninit::<BafflePlanOptions>::uninit();
    assert_eq!(unsafe { baffle_plan_options_init(options.as_mut_ptr()) }, BaffleStatus::Ok);
    let mut options = unsafe { options.assume_init() };
    options.phantom = 1;
    (options.sbp_mmhg, options.dbp_mmhg) = (107.0, 78.0);
    options.mode = BafflePlanMode::Quick as i32;
    options.single_mesh = 1;
    options.edge_length_mm = 1.5;
    options.out_dir = out.as_ptr();
    options
}

/// What the callbacks saw and when the cancel says stop.
#[derive(Default)]
struct Watch {
    seen: Vec<(f64, String)>,
    /// Stop once this file exists (and the cancel has been asked `after_asks` more times);
    /// run_quick takes it relative to the plan's folder.
    stop_when: Option<PathBuf>,
    after_asks: usize,
    asked_since: usize,
}

unsafe extern "C" fn record(fraction: f64, stage: *const c_char, user: *mut c_void) -> i32 {
    let watch = &mut *(user as *mut Watch);
    watch.seen.push((fraction, CStr::from_ptr(stage).to_string_lossy().into_owned()));
    1
}

unsafe extern "C" fn cancel_when(user: *mut c_void) -> i32 {
    let watch = &mut *(user as *mut Watch);
    let Some(file) = &watch.stop_when else { return 0 };
    if !file.exists() {
        return 0;
    }
    watch.asked_since += 1;
    i32::from(watch.asked_since > watch.after_asks)
}

/// The quick phantom plan into a fresh folder `name`, watched by `watch`: (folder, status, result).
fn run_quick(name: &str, watch: &mut Watch) -> (PathBuf, BaffleStatus, *mut BafflePlanResult) {
    let out = temp_dir(name);
    let out_c = c_path(&out);
    watch.stop_when = watch.stop_when.as_ref().map(|file| out.join(file));
    let (status, result) = run(&quick_phantom(&out_c), watch);
    (out, status, result)
}

fn run(options: &BafflePlanOptions, watch: &mut Watch) -> (BaffleStatus, *mut BafflePlanResult) {
    let mut result = null_mut();
    let user = watch as *mut Watch as *mut c_void;
    let status = unsafe { baffle_plan(options, Some(record), Some(cancel_when), user, &mut result) };
    (status, result)
}

fn text(get: impl FnOnce(*mut *mut c_char) -> BaffleStatus) -> String {
    let mut ptr: *mut c_char = null_mut();
    assert_eq!(get(&mut ptr), BaffleStatus::Ok, "{}", last_error());
    let text = unsafe { CStr::from_ptr(ptr) }.to_string_lossy().into_owned();
    unsafe { baffle_free(ptr.cast()) };
    text
}

fn number(get: impl FnOnce(*mut f64) -> BaffleStatus) -> f64 {
    let mut value = f64::NAN;
    assert_eq!(get(&mut value), BaffleStatus::Ok, "{}", last_error());
    value
}

#[test]
fn a_quick_phantom_plan_gives_the_reports_verdict_through_the_handle() {
    if skip_gmsh() {
        return;
    }
    let mut watch = Watch::default();
    let (out, status, result) = run_quick("quick", &mut watch);
    assert_eq!(status, BaffleStatus::Ok, "{}", last_error());
    let report = read_json(&out.join("report.json"));
    let v = &report["verdict"];
    let mut verdict = -1;
    assert_eq!(unsafe { baffle_plan_result_verdict(result, &mut verdict) }, BaffleStatus::Ok);
    let key = ["passes", "fails", "inconclusive"][verdict as usize];
    assert_eq!(v["verdict"].as_str(), Some(key), "{v}");
    assert_eq!(Some(number(|o| unsafe { baffle_plan_result_dp_mmhg(result, o) })), v["dp_peak_mmhg"].as_f64());
    assert_eq!(Some(number(|o| unsafe { baffle_plan_result_dp_threshold_mmhg(result, o) })), v["threshold_mmhg"].as_f64());
    assert_eq!(Some(number(|o| unsafe { baffle_plan_result_v_max_m_s(result, o) })), report["quantities"]["max_velocity_m_s"]["value"].as_f64().or(report["runs"][0]["max_velocity_m_s"].as_f64()));
    assert_eq!(text(|o| unsafe { baffle_plan_result_verdict_text(result, o) }), v["text"].as_str().unwrap());
    assert_eq!(PathBuf::from(text(|o| unsafe { baffle_plan_result_report_json_path(result, o) })), out.join("report.json"));
    assert!(PathBuf::from(text(|o| unsafe { baffle_plan_result_report_html_path(result, o) })).is_file());
    let mut reasons = usize::MAX;
    assert_eq!(unsafe { baffle_plan_result_reason_count(result, &mut reasons) }, BaffleStatus::Ok);
    assert_eq!(reasons, v["reason"].as_str().map_or(0, |r| r.split("; ").count()), "{v}");
    let mut reason = null_mut();
    assert_eq!(unsafe { baffle_plan_result_reason(result, reasons, &mut reason) }, BaffleStatus::InvalidArgument);
    assert!(last_error().contains("out of range"), "{}", last_error());
    unsafe { baffle_plan_result_free(result) };
    // Progress: the whole plan's fraction, stage by stage, ending with the report.
    let stages: Vec<&str> = watch.seen.iter().map(|s| s.1.as_str()).collect();
    assert_eq!(stages.first(), Some(&"design"), "{stages:?}");
    assert_eq!(watch.seen.last(), Some(&(1.0, "report".to_string())));
    assert!(stages.contains(&"mesh-nominal") && watch.seen.iter().all(|s| (0.0..=1.0).contains(&s.0)), "{:?}", watch.seen);
}

#[test]
fn a_plan_cancelled_between_stages_keeps_the_finished_ones() {
    if skip_gmsh() {
        return;
    }
    let mut watch = Watch { stop_when: Some(Path::new("design").join("report.json")), ..Watch::default() };
    let (out, status, result) = run_quick("cancel-between", &mut watch);
    assert_eq!(status, BaffleStatus::Cancelled, "{}", last_error());
    assert!(result.is_null());
    assert!(last_error().starts_with("plan cancelled at stage centerline"), "{}", last_error());
    assert!(last_error().contains(&out.join("design").display().to_string()), "{}", last_error());
    assert!(out.join("design").join("domain.vtp").is_file());
    assert!(!out.join("centerline").exists() && !out.join("report.json").exists());
}

#[test]
fn a_cancel_stops_the_running_simulation_with_its_results_so_far() {
    if skip_gmsh() {
        return;
    }
    // The case is written as the stage starts; a few time steps later the cancel says stop.
    let stop_when = Some(Path::new("simulate-nominal").join("case.json"));
    let mut watch = Watch { stop_when, after_asks: 5, ..Watch::default() };
    let (out, status, _) = run_quick("cancel-simulate", &mut watch);
    assert_eq!(status, BaffleStatus::Cancelled, "{}", last_error());
    assert!(last_error().starts_with("plan cancelled at stage simulate-nominal"), "{}", last_error());
    let summary = read_json(&out.join("simulate-nominal").join("summary.json"));
    assert_eq!(summary["status"].as_str(), Some("stopped"), "{summary}");
    assert!(out.join("mesh-nominal").join("mesh.vtu").is_file() && !out.join("report.json").exists());
}

#[test]
fn bad_plan_options_are_named_before_any_stage_runs() {
    let out = temp_dir("bad");
    let out_c = c_path(&out);
    let mut watch = Watch::default();
    let mut options = quick_phantom(&out_c);
    (options.sbp_mmhg, options.dbp_mmhg) = (f64::NAN, f64::NAN);
    assert_eq!(run(&options, &mut watch).0, BaffleStatus::InvalidArgument);
    assert!(last_error().contains("--bp NaN/NaN") && last_error().contains("SBP"), "{}", last_error());
    let mut options = quick_phantom(&out_c);
    options.mode = 9;
    assert_eq!(run(&options, &mut watch).0, BaffleStatus::InvalidArgument);
    assert!(last_error().contains("options.mode = 9"), "{}", last_error());
    let mut options = quick_phantom(&out_c);
    options.out_dir = std::ptr::null();
    assert_eq!(run(&options, &mut watch).0, BaffleStatus::NullPointer);
    assert!(last_error().contains("options.out_dir"), "{}", last_error());
    let mut options = quick_phantom(&out_c);
    options.phantom = 0;
    assert_eq!(run(&options, &mut watch).0, BaffleStatus::InvalidArgument);
    assert!(last_error().contains("needs the ventricle"), "{}", last_error());
    let mut options = quick_phantom(&out_c);
    options.struct_size = 4;
    assert_eq!(run(&options, &mut watch).0, BaffleStatus::UnsupportedVersion);
    assert!(watch.seen.is_empty(), "no stage ran: {:?}", watch.seen);
    assert_eq!(std::fs::read_dir(&out).unwrap().count(), 0, "nothing written");
}

#[test]
fn the_case_a_front_end_writes_is_the_plans() {
    // A folder that does not exist yet (a front end's work folder before its mesh) is made.
    let dir = temp_dir("case").join("work");
    let dir_c = c_path(&dir);
    let mut options = quick_phantom(&dir_c);
    options.phantom = 0;
    options.bsa_m2 = 0.37;
    options.heart_rate_bpm = 120.0;
    let (volume, faces) = (CString::new("volume.vtu").unwrap(), CString::new("volume-faces.vtp").unwrap());
    let written = text(|o| unsafe { baffle_plan_write_case(&options, volume.as_ptr(), faces.as_ptr(), dir_c.as_ptr(), o) });
    assert_eq!(PathBuf::from(&written), dir.join("case.json"));
    let case = read_json(&dir.join("case.json"));
    assert_eq!(case["mesh"]["volume"].as_str(), Some("volume.vtu"), "{case}");
    assert_eq!(case["mesh"]["faces"].as_str(), Some("volume-faces.vtp"), "{case}");
    assert_eq!((case["faces"]["inlet"].as_i64(), case["faces"]["outlets"][0].as_i64()), (Some(11), Some(16)), "{case}");
    assert_eq!(case["time"]["mode"].as_str(), Some("quick"), "{case}");
    assert_eq!(case["inflow"]["bsa_m2"].as_f64(), Some(0.37));
    assert_eq!(case["inflow"]["heart_rate_bpm"].as_f64(), Some(120.0));
    assert_eq!((case["outlet"]["sbp_mmhg"].as_f64(), case["outlet"]["dbp_mmhg"].as_f64()), (Some(107.0), Some(78.0)));
    // A diastolic pressure above the systolic is refused, named, and nothing is written.
    std::fs::remove_file(dir.join("case.json")).unwrap();
    (options.sbp_mmhg, options.dbp_mmhg) = (78.0, 107.0);
    let status = unsafe { baffle_plan_write_case(&options, volume.as_ptr(), faces.as_ptr(), dir_c.as_ptr(), null_mut()) };
    assert_eq!(status, BaffleStatus::InvalidArgument);
    assert!(last_error().contains("DBP 107 mmHg exceeds SBP 78 mmHg"), "{}", last_error());
    assert!(!dir.join("case.json").exists());
    options.bsa_m2 = f64::NAN;
    let status = unsafe { baffle_plan_write_case(&options, volume.as_ptr(), faces.as_ptr(), dir_c.as_ptr(), null_mut()) };
    assert_eq!(status, BaffleStatus::InvalidArgument);
    assert!(last_error().contains("--bsa"), "{}", last_error());
}

/// The quick phantom plan of `edit`, stopped once its design is written: the design
/// report's target area (mm2).
fn designed_target_mm2(name: &str, edit: impl FnOnce(&mut BafflePlanOptions)) -> f64 {
    let out = temp_dir(name);
    let out_c = c_path(&out);
    let mut options = quick_phantom(&out_c);
    edit(&mut options);
    let mut watch = Watch { stop_when: Some(out.join("design").join("report.json")), ..Watch::default() };
    let (status, result) = run(&options, &mut watch);
    assert_eq!(status, BaffleStatus::Cancelled, "{}", last_error());
    assert!(result.is_null());
    let report = read_json(&out.join("design").join("report.json"));
    report["target_area_mm2"].as_f64().unwrap_or_else(|| panic!("no target_area_mm2 in {report}"))
}

#[test]
fn the_target_options_reach_the_design_and_an_older_struct_keeps_the_bsa_target() {
    // NaN/0 z-score, no area, no diameter: the phantom's BSA at z 0, as before.
    let z0 = designed_target_mm2("target-default", |_| {});
    let z1 = designed_target_mm2("target-z1", |o| o.z_score = 1.0);
    assert!(z1 > z0, "z 1 ({z1} mm2) is larger than z 0 ({z0} mm2)");
    assert_eq!(designed_target_mm2("target-z0", |o| o.z_score = 0.0), z0);
    assert_eq!(designed_target_mm2("target-area", |o| (o.bsa_m2, o.target_area_mm2) = (0.37, 120.0)), 120.0);
    let d = 12.0_f64;
    let by_diameter = designed_target_mm2("target-diameter", |o| o.annulus_diameter_mm = d);
    assert!((by_diameter - std::f64::consts::PI * (d / 2.0).powi(2)).abs() < 1e-9, "{by_diameter}");
    // A caller compiled against the first layout (up to patient_label): the bytes after
    // it are not read, so whatever lies there leaves the target at the BSA's z 0.
    let old = std::mem::offset_of!(BafflePlanOptions, z_score) as u32;
    assert_eq!(old as usize, std::mem::offset_of!(BafflePlanOptions, patient_label) + std::mem::size_of::<*const c_char>());
    let older = designed_target_mm2("target-older", |o| (o.struct_size, o.z_score, o.target_area_mm2) = (old, 3.0, 999.0));
    assert_eq!(older, z0);
    // One byte short of the first layout is not a layout this library knows.
    let out = temp_dir("target-short");
    let out_c = c_path(&out);
    let mut options = quick_phantom(&out_c);
    options.struct_size = old - 8;
    assert_eq!(run(&options, &mut Watch::default()).0, BaffleStatus::UnsupportedVersion);
    assert!(last_error().contains(&format!("takes {old}..")), "{}", last_error());
}

#[test]
fn two_targets_are_refused_in_the_plans_words_before_any_stage_runs() {
    let out = temp_dir("two-targets");
    let out_c = c_path(&out);
    let mut watch = Watch::default();
    let refused = |edit: &dyn Fn(&mut BafflePlanOptions), watch: &mut Watch| {
        let mut options = quick_phantom(&out_c);
        edit(&mut options);
        assert_eq!(run(&options, watch).0, BaffleStatus::InvalidArgument);
        last_error()
    };
    let both = refused(&|o| (o.target_area_mm2, o.annulus_diameter_mm) = (120.0, 12.0), &mut watch);
    assert!(both.contains("give one target: --target-area-mm2 or --annulus-diameter-mm, not both"), "{both}");
    let z_and_area = refused(&|o| (o.target_area_mm2, o.z_score) = (120.0, 1.0), &mut watch);
    assert!(z_and_area.contains("--z-score 1 applies to the BSA's annulus"), "{z_and_area}");
    let z_and_diameter = refused(&|o| (o.annulus_diameter_mm, o.z_score) = (12.0, -2.0), &mut watch);
    assert!(z_and_diameter.contains("--z-score -2 applies"), "{z_and_diameter}");
    // A bad area is the design's to name, before any stage too.
    let negative = refused(&|o| o.target_area_mm2 = -5.0, &mut watch);
    assert!(negative.contains("target area: area (mm2) = -5 must be a positive"), "{negative}");
    assert!(watch.seen.is_empty(), "no stage ran: {:?}", watch.seen);
    assert_eq!(std::fs::read_dir(&out).unwrap().count(), 0, "nothing written");
}
