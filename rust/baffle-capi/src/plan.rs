//! baffle_plan(): the whole plan (design, centerline, mesh, simulate, report) through the
//! ABI, as `baffle plan` runs it (baffle-plan's pipeline), with a progress and a cancel
//! callback; and baffle_plan_write_case(): the CFD case the plan simulates, for a front end
//! that meshes and runs `baffle simulate` itself, so the case is defined once.

use crate::alloc::malloc_string;
use crate::design::{call_progress, BaffleProgressFn};
use crate::options::read_sized;
use crate::status::{arg_ref, free_handle, guarded, optional_str, out_handle, out_ref, BaffleStatus, CallError};
use baffle_plan::error::PlanError;
use baffle_plan::plan_cmd::{plan_case, run_plan_cancellable, write_case, Cancel, PlanOutcome};
use baffle_plan::plan_stages::{plan_stages, FlowCase, PlanSettings};
use baffle_plan::progress::{Console, Progress, Style};
use baffle_plan::verdict::Verdict;
use std::ffi::{c_char, c_void};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

/// The CFD run of BafflePlanOptions.mode.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BafflePlanMode {
    /// Pulsatile over `cycles` cardiac cycles, the last one reported (the paper's run).
    Pulsatile = 0,
    /// Pulsatile from rest up to the first flow peak (a quick estimate of the peak dp).
    Quick = 1,
    /// Steady at the peak flow (may not converge; the verdict is then inconclusive).
    Steady = 2,
}

/// The verdict of a finished plan on its peak pressure difference.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BaffleVerdict {
    /// A trusted run below the planning threshold.
    Passes = 0,
    /// A trusted run at or above the threshold.
    Fails = 1,
    /// The run cannot be trusted (reasons: baffle_plan_result_reason).
    Inconclusive = 2,
}

/// Options of baffle_plan() and baffle_plan_write_case(). Fill with
/// baffle_plan_options_init(), then set the ventricle, the suture points, the patient's
/// numbers, the target if not the BSA's annulus at z 0, and the output folder. Its first
/// field is the size the caller compiled against, so fields are appended in later
/// versions: a caller's older, shorter struct keeps the defaults of the newer fields. Strings are UTF-8 paths (NULL: not given), lengths in mm.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct BafflePlanOptions {
    /// sizeof(BafflePlanOptions) as the caller compiled it (set by _init).
    pub struct_size: u32,
    /// The capped, labelled ventricle (.vtp, .vtk or .stl; Slicer's LPS frame).
    pub surface_path: *const c_char,
    /// Instead of surface_path: a folder of segment surfaces (LV, RV, aorta), prepared
    /// first; the CFD then runs on the extended domain (mid-LV to the STJ).
    pub segmentations_dir: *const c_char,
    /// Suture points (.mrk.json, .fcsv, .csv or .json).
    pub points_path: *const c_char,
    /// Nonzero: the built-in phantom as ventricle and suture points (BSA 0.37 m2 unless given).
    pub phantom: i32,
    /// Output folder: one subfolder per stage, report.json and report.html.
    pub out_dir: *const c_char,
    /// Body surface area (m2): the target annulus and the flow (BSA x cardiac index);
    /// NaN: the phantom's.
    pub bsa_m2: f64,
    /// Blood pressure (mmHg): the outlet resistance R = MAP / Q_mean. Required.
    pub sbp_mmhg: f64,
    pub dbp_mmhg: f64,
    /// Heart rate (beats/min); NaN: the built-in period of 0.682 s.
    pub heart_rate_bpm: f64,
    /// Cardiac index of the nominal runs (L/min/m2; default the paper's 3.48).
    pub cardiac_index_l_min_m2: f64,
    /// A BafflePlanMode value (default Pulsatile).
    pub mode: i32,
    /// Cardiac cycles of a pulsatile run (default 4).
    pub cycles: u32,
    /// Largest tetrahedron edge of the nominal mesh (mm; default the paper's 0.95).
    pub edge_length_mm: f64,
    /// Nonzero: the nominal mesh only, no mesh study (about a third of the time; the
    /// report then warns that dp's discretization error is not known).
    pub single_mesh: i32,
    /// Nonzero: also simulate the nominal mesh at the elevated cardiac index 4.22.
    pub elevated_flow: i32,
    /// Nonzero: the design also holds the sections normal to the flow at the target
    /// (the command line's --flow-sections).
    pub flow_sections: i32,
    /// How the report names the patient; NULL: the paper's id, or "not named".
    pub patient_label: *const c_char,
    /// Appended after the first layout (a caller compiled against it keeps these
    /// defaults): the design's target, as the command line's --z-score,
    /// --target-area-mm2 and --annulus-diameter-mm. bsa_m2 stays the flow's BSA.
    /// The Boston annulus z-score of the target for bsa_m2; NaN (the default) or 0: z 0.
    pub z_score: f64,
    /// Target cross-section area (mm2) instead of the BSA's annulus; NaN: not given.
    pub target_area_mm2: f64,
    /// Target aortic annulus diameter (mm), A = pi (D/2)^2, instead of the BSA's annulus;
    /// NaN: not given. Both this and target_area_mm2, or either with a nonzero z_score,
    /// are refused (InvalidArgument), as the command line refuses them.
    pub annulus_diameter_mm: f64,
}

impl Default for BafflePlanOptions {
    fn default() -> Self {
        let d = PlanSettings::default();
        BafflePlanOptions {
            struct_size: std::mem::size_of::<BafflePlanOptions>() as u32,
            surface_path: std::ptr::null(),
            segmentations_dir: std::ptr::null(),
            points_path: std::ptr::null(),
            phantom: 0,
            out_dir: std::ptr::null(),
            bsa_m2: f64::NAN,
            sbp_mmhg: d.bp.0,
            dbp_mmhg: d.bp.1,
            heart_rate_bpm: f64::NAN,
            cardiac_index_l_min_m2: d.cardiac_index,
            mode: BafflePlanMode::Pulsatile as i32,
            cycles: d.cycles as u32,
            edge_length_mm: d.edge_length_mm,
            single_mesh: 0,
            elevated_flow: 0,
            flow_sections: 0,
            patient_label: std::ptr::null(),
            z_score: f64::NAN,
            target_area_mm2: f64::NAN,
            annulus_diameter_mm: f64::NAN,
        }
    }
}

/// Size of the first published layout (up to patient_label); any caller struct is at
/// least this long, and the fields after it keep their defaults for such a caller.
const PLAN_V1_SIZE: usize = std::mem::offset_of!(BafflePlanOptions, z_score);

/// Fill `out_options` with the plan's defaults and struct_size (no ventricle, no blood
/// pressure, no output folder: the caller sets them).
///
/// # Safety
/// `out_options` must be NULL or point to writable memory for the struct.
#[no_mangle]
pub unsafe extern "C" fn baffle_plan_options_init(out_options: *mut BafflePlanOptions) -> BaffleStatus {
    guarded(|| {
        *out_ref(out_options, "out_options")? = BafflePlanOptions::default();
        Ok(())
    })
}

fn optional_f64(value: f64) -> Option<f64> {
    (!value.is_nan()).then_some(value)
}

/// # Safety
/// The options' strings must be NULL or NUL-terminated.
unsafe fn optional_path(text: *const c_char, name: &str) -> Result<Option<PathBuf>, CallError> {
    Ok(optional_str(text, name)?.map(PathBuf::from))
}

/// The plan's settings from the caller's options: `baffle plan`'s defaults and the given values.
///
/// # Safety
/// The options' strings must be NULL or NUL-terminated.
unsafe fn plan_settings(o: &BafflePlanOptions) -> Result<PlanSettings, CallError> {
    let mode = o.mode;
    let (quick, steady) = match mode {
        m if m == BafflePlanMode::Pulsatile as i32 => (false, false),
        m if m == BafflePlanMode::Quick as i32 => (true, false),
        m if m == BafflePlanMode::Steady as i32 => (false, true),
        other => return Err(CallError::invalid(format!("options.mode = {other} is not a BafflePlanMode"))),
    };
    if o.cycles == 0 {
        return Err(CallError::invalid("options.cycles is 0; a pulsatile run needs at least one cardiac cycle"));
    }
    let mut s = PlanSettings { bp: (o.sbp_mmhg, o.dbp_mmhg), hr: optional_f64(o.heart_rate_bpm), quick, steady, ..PlanSettings::default() };
    s.design.surface = optional_path(o.surface_path, "options.surface_path")?;
    s.prepare.segmentations = optional_path(o.segmentations_dir, "options.segmentations_dir")?;
    s.design.points = optional_path(o.points_path, "options.points_path")?;
    s.design.phantom = o.phantom != 0;
    s.design.out = optional_path(o.out_dir, "options.out_dir")?.unwrap_or_default();
    s.design.target.bsa = optional_f64(o.bsa_m2);
    // The target as the command line sets it; contradictions are the plan's to refuse
    // (plan_stages, with its own words).
    s.design.target.z_score = optional_f64(o.z_score).unwrap_or(s.design.target.z_score);
    s.design.target.target_area_mm2 = optional_f64(o.target_area_mm2);
    s.design.target.annulus_diameter_mm = optional_f64(o.annulus_diameter_mm);
    s.design.flow_sections = o.flow_sections != 0;
    s.cardiac_index = o.cardiac_index_l_min_m2;
    s.cycles = o.cycles as usize;
    s.edge_length_mm = o.edge_length_mm;
    s.single_mesh = o.single_mesh != 0;
    s.elevated_flow = o.elevated_flow != 0;
    s.patient_label = optional_str(o.patient_label, "options.patient_label")?.map(str::to_string);
    Ok(s)
}

/// Cancel callback of baffle_plan(): called with the caller's user_data between the
/// stages and while the design and the simulation run; return nonzero to stop the plan
/// (which then returns BAFFLE_STATUS_CANCELLED). It runs on the calling thread and must
/// not unwind.
pub type BaffleCancelFn = Option<unsafe extern "C" fn(user_data: *mut c_void) -> i32>;

/// The caller's callbacks as the plan's console (fractions) and its cancel.
struct Callbacks {
    progress: BaffleProgressFn,
    cancel: BaffleCancelFn,
    user_data: *mut c_void,
    /// The progress callback returned 0: stop at the next question.
    stop_asked: AtomicBool,
}

// SAFETY: the plan calls its console and its cancel on the calling thread only (its
// progress style is Fractions, which starts no ticker thread), so the caller's pointers
// are used where the caller passed them.
unsafe impl Send for Callbacks {}
unsafe impl Sync for Callbacks {}

impl Console for Callbacks {
    fn line(&self, _: &str) {}
    fn status(&self, _: &str) {}
    fn status_is_terminal(&self) -> bool {
        false
    }
    fn fraction(&self, overall: f64, stage: &str, _message: &str) {
        // SAFETY: the caller vouched for progress and user_data when calling baffle_plan.
        if !unsafe { call_progress(self.progress, self.user_data, overall, stage) } {
            self.stop_asked.store(true, Ordering::SeqCst);
        }
    }
}

impl Callbacks {
    fn cancelled(&self) -> bool {
        // SAFETY: as for fraction().
        self.stop_asked.load(Ordering::SeqCst) || self.cancel.is_some_and(|cancel| unsafe { cancel(self.user_data) } != 0)
    }
}

/// Opaque, immutable result of baffle_plan().
pub struct BafflePlanResult {
    outcome: PlanOutcome,
}

fn plan_error(e: PlanError) -> CallError {
    let status = match e {
        PlanError::Cancelled(_) => BaffleStatus::Cancelled,
        _ => BaffleStatus::PlanFailed,
    };
    CallError::new(status, e.to_string())
}

/// Run the plan of `options` into options.out_dir: [prepare ->] design -> centerline ->
/// mesh -> simulate (-> the mesh study's levels) -> report.json and report.html, as
/// `baffle plan` does. `progress` (may be NULL) gets the fraction of the whole plan done
/// and the running stage's name (returning 0 cancels, as `cancel` does); `cancel` (may be
/// NULL) is asked between the stages and while the design and the simulation run (the
/// mesh stage stops only at its end). Both get `user_data`. On success `*out_result` is a
/// new handle (free with baffle_plan_result_free). Bad options: InvalidArgument, naming
/// the option, before any stage runs; a failed stage: PlanFailed, the message naming the
/// stage; a cancelled plan: Cancelled. Either way the stages finished before keep their
/// folders (a stopped simulation its results so far).
///
/// # Safety
/// Pointers must be NULL or valid; the callbacks must be safe to call with `user_data`.
#[no_mangle]
pub unsafe extern "C" fn baffle_plan(
    options: *const BafflePlanOptions,
    progress: BaffleProgressFn,
    cancel: BaffleCancelFn,
    user_data: *mut c_void,
    out_result: *mut *mut BafflePlanResult,
) -> BaffleStatus {
    guarded(|| {
        let out = out_handle(out_result, "out_result")?;
        let options = read_sized(options, PLAN_V1_SIZE, "options", "baffle_plan_options_init")?;
        if options.out_dir.is_null() {
            return Err(CallError::null("options.out_dir (the plan's output folder)"));
        }
        let settings = plan_settings(&options)?;
        plan_stages(&settings).map_err(|e| CallError::invalid(e.to_string()))?;
        let callbacks = Arc::new(Callbacks { progress, cancel, user_data, stop_asked: AtomicBool::new(false) });
        let console: Arc<dyn Console> = callbacks.clone();
        let progress = Progress::new(console, Style::Fractions, Instant::now(), (0.0, 1.0));
        let asked = callbacks.clone();
        let cancel: Cancel = Arc::new(move || asked.cancelled());
        let outcome = run_plan_cancellable(&settings, &progress, &cancel).map_err(plan_error)?;
        *out = Box::into_raw(Box::new(BafflePlanResult { outcome }));
        Ok(())
    })
}

/// Free a plan result (NULL is ignored).
///
/// # Safety
/// `result` must be NULL or a handle from this library not yet freed.
#[no_mangle]
pub unsafe extern "C" fn baffle_plan_result_free(result: *mut BafflePlanResult) {
    free_handle(result);
}

/// One value of a result into the caller's `out`.
///
/// # Safety
/// `result` must be NULL or a live handle; `out` NULL or writable.
unsafe fn get<T>(result: *const BafflePlanResult, out: *mut T, name: &str, value: impl FnOnce(&PlanOutcome) -> Result<T, CallError>) -> BaffleStatus {
    guarded(|| {
        let out = out_ref(out, name)?;
        *out = value(&arg_ref(result, "result")?.outcome)?;
        Ok(())
    })
}

/// One text of a result as a new string (free with baffle_free).
///
/// # Safety
/// As for get().
unsafe fn get_text(result: *const BafflePlanResult, out: *mut *mut c_char, text: impl FnOnce(&PlanOutcome) -> Result<String, CallError>) -> BaffleStatus {
    get(result, out, "out_text", |o| malloc_string(&text(o)?))
}

fn path_text(path: &Path) -> Result<String, CallError> {
    path.to_str().map(str::to_string).ok_or_else(|| CallError::new(BaffleStatus::Internal, format!("{} is not UTF-8", path.display())))
}

/// The verdict (a BaffleVerdict value).
///
/// # Safety
/// `result` must be NULL or a live handle; `out_verdict` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn baffle_plan_result_verdict(result: *const BafflePlanResult, out_verdict: *mut i32) -> BaffleStatus {
    get(result, out_verdict, "out_verdict", |o| {
        Ok(match o.verdict {
            Verdict::Passes => BaffleVerdict::Passes,
            Verdict::Fails => BaffleVerdict::Fails,
            Verdict::Inconclusive { .. } => BaffleVerdict::Inconclusive,
        } as i32)
    })
}

/// The nominal run's plane-averaged peak pressure difference (mmHg), as judged.
///
/// # Safety
/// `result` must be NULL or a live handle; `out_dp_mmhg` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn baffle_plan_result_dp_mmhg(result: *const BafflePlanResult, out_dp_mmhg: *mut f64) -> BaffleStatus {
    get(result, out_dp_mmhg, "out_dp_mmhg", |o| Ok(o.dp_mmhg))
}

/// The nominal run's largest speed in the domain at peak flow (m/s).
///
/// # Safety
/// `result` must be NULL or a live handle; `out_v_max_m_s` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn baffle_plan_result_v_max_m_s(result: *const BafflePlanResult, out_v_max_m_s: *mut f64) -> BaffleStatus {
    get(result, out_v_max_m_s, "out_v_max_m_s", |o| Ok(o.v_max_m_s))
}

/// The planning threshold dp was judged against (mmHg): below it passes.
///
/// # Safety
/// `result` must be NULL or a live handle; `out_threshold_mmhg` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn baffle_plan_result_dp_threshold_mmhg(result: *const BafflePlanResult, out_threshold_mmhg: *mut f64) -> BaffleStatus {
    get(result, out_threshold_mmhg, "out_threshold_mmhg", |o| Ok(o.dp_threshold_mmhg))
}

/// How many reasons an inconclusive verdict has (0 for passes or fails).
///
/// # Safety
/// `result` must be NULL or a live handle; `out_count` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn baffle_plan_result_reason_count(result: *const BafflePlanResult, out_count: *mut usize) -> BaffleStatus {
    get(result, out_count, "out_count", |o| Ok(reasons(o).len()))
}

fn reasons(o: &PlanOutcome) -> &[String] {
    match &o.verdict {
        Verdict::Inconclusive { reasons } => reasons,
        _ => &[],
    }
}

/// The `index`th reason of an inconclusive verdict, a new string (free with baffle_free).
///
/// # Safety
/// `result` must be NULL or a live handle; `out_reason` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn baffle_plan_result_reason(result: *const BafflePlanResult, index: usize, out_reason: *mut *mut c_char) -> BaffleStatus {
    get_text(result, out_reason, |o| {
        let all = reasons(o);
        all.get(index).cloned().ok_or_else(|| CallError::invalid(format!("index {index} is out of range: the verdict has {} reasons", all.len())))
    })
}

/// The verdict in one sentence, as the report and the command line say it (free with baffle_free).
///
/// # Safety
/// `result` must be NULL or a live handle; `out_text` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn baffle_plan_result_verdict_text(result: *const BafflePlanResult, out_text: *mut *mut c_char) -> BaffleStatus {
    get_text(result, out_text, |o| Ok(o.verdict_line.clone()))
}

/// The path of the plan's report.json (free with baffle_free).
///
/// # Safety
/// `result` must be NULL or a live handle; `out_path` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn baffle_plan_result_report_json_path(result: *const BafflePlanResult, out_path: *mut *mut c_char) -> BaffleStatus {
    get_text(result, out_path, |o| path_text(&o.report_json))
}

/// The path of the plan's report.html (free with baffle_free).
///
/// # Safety
/// `result` must be NULL or a live handle; `out_path` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn baffle_plan_result_report_html_path(result: *const BafflePlanResult, out_path: *mut *mut c_char) -> BaffleStatus {
    get_text(result, out_path, |o| path_text(&o.report_html))
}

/// Write the CFD case the plan simulates (`baffle simulate`'s case.json) into `case_dir`
/// for the volume mesh `mesh_volume_path` and its labelled faces `mesh_faces_path` (as
/// `baffle mesh` writes them; relative paths are relative to case_dir), from the
/// options' bsa_m2 (or the phantom's), blood pressure, heart rate, cardiac index, mode and
/// cycles; the ventricle, points, out_dir and the design's target are not used. The inflow is the VSD cap and
/// the outflow the aortic cap of the designed domain (the plan's default labels). The
/// case is checked as `baffle simulate` will check it (a bad blood pressure is
/// InvalidArgument, named). `*out_case_path` (may be NULL) gets the written file's path
/// (free with baffle_free).
///
/// # Safety
/// Pointers must be NULL or valid; strings NUL-terminated.
#[no_mangle]
pub unsafe extern "C" fn baffle_plan_write_case(
    options: *const BafflePlanOptions,
    mesh_volume_path: *const c_char,
    mesh_faces_path: *const c_char,
    case_dir: *const c_char,
    out_case_path: *mut *mut c_char,
) -> BaffleStatus {
    guarded(|| {
        let options = read_sized(options, PLAN_V1_SIZE, "options", "baffle_plan_options_init")?;
        let settings = plan_settings(&options)?;
        let required = |text, name| optional_str(text, name)?.ok_or_else(|| CallError::null(name)).map(Path::new);
        let volume = required(mesh_volume_path, "mesh_volume_path")?;
        let faces = required(mesh_faces_path, "mesh_faces_path")?;
        let dir = required(case_dir, "case_dir")?;
        let case = plan_case(&settings, volume, faces, FlowCase::Nominal).map_err(CallError::invalid)?;
        let path = write_case(dir, &case).map_err(|e| CallError::invalid(format!("the case for {}: {e}", dir.display())))?;
        if !out_case_path.is_null() {
            *out_ref(out_case_path, "out_case_path")? = malloc_string(&path_text(&path)?)?;
        }
        Ok(())
    })
}
