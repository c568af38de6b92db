//! Everything this crate knows about svMultiPhysics' files, with the format's rules as
//! comments (sources: the SimVascular/svMultiPhysics repository — Parameters.cpp,
//! read_files.cpp, fft.cpp, txt.cpp, output.cpp, vtk_xml.cpp — and its tests/cases/fluid
//! examples). Nothing else in the crate writes or parses svMultiPhysics text.

use std::fmt::Write as _;
use std::path::Path;

use crate::SvmpError;

// ---------------------------------------------------------------------------------------
// Case layout (as SimVascular's "Export Mesh Complete" writes it)
// ---------------------------------------------------------------------------------------

/// `mesh-complete/`: the volume mesh, the exterior and wall surfaces, `mesh-surfaces/`.
pub const MESH_DIR: &str = "mesh-complete";
pub const VOLUME_FILE: &str = "mesh-complete.mesh.vtu";
pub const EXTERIOR_FILE: &str = "mesh-complete.exterior.vtp";
pub const WALLS_FILE: &str = "walls_combined.vtp";
/// One `<face name>.vtp` per face named in `solver.xml` (`Add_face/Face_file_path`).
pub const SURFACES_DIR: &str = "mesh-surfaces";
pub const SOLVER_FILE: &str = "solver.xml";
/// Inflow waveform read through `Temporal_values_file_path`.
pub const INFLOW_FILE: &str = "inflow.flw";
pub const RUN_SCRIPT: &str = "run.sh";
pub const README_FILE: &str = "README.md";
/// `Save_results_in_folder`: without it results go to `<N>-procs/`, which depends on N.
pub const RESULTS_DIR: &str = "results";
/// `Name_prefix_of_saved_VTK_files`.
pub const RESULT_PREFIX: &str = "result";
/// Name of the mesh in `Add_mesh name=...`.
pub const MESH_NAME: &str = "msh";

/// Point array of every mesh file: 1-based node id in the volume mesh (Int32). svMultiPhysics
/// maps face nodes to volume nodes through it (and checks coordinates when it matches faces).
pub const GLOBAL_NODE_ID: &str = "GlobalNodeID";
/// Cell array: on the volume mesh the 1-based tet id; on a face, the 1-based id of the tet
/// the triangle belongs to (Int32). svMultiPhysics orients the face normal outward from
/// that tet, so for an interior plane it decides the sign of the flux it reports.
pub const GLOBAL_ELEMENT_ID: &str = "GlobalElementID";
/// Volume cell array SimVascular writes (one region: all 1).
pub const MODEL_REGION_ID: &str = "ModelRegionID";

// ---------------------------------------------------------------------------------------
// Output files (txt.cpp): boundary integrals, written by the master rank every time step
// ---------------------------------------------------------------------------------------

/// `B_<eq.sym>_<output name>_average.txt` for scalars: integral of p over the face / area.
pub const PRESSURE_AVERAGE_FILE: &str = "B_NS_Pressure_average.txt";
/// `B_<eq.sym>_<output name>_flux.txt` for vectors: integral of u . n over the face, n the
/// outward normal of the face's `GlobalElementID` tet (outward of the domain on boundaries).
pub const VELOCITY_FLUX_FILE: &str = "B_NS_Velocity_flux.txt";

// ---------------------------------------------------------------------------------------
// solver.xml
// ---------------------------------------------------------------------------------------

/// svMultiPhysics' recommended linear solver for CFD: `LS type="NS"` (bi-partitioned
/// GMRES on momentum + CG on the Schur complement of the pressure, FSILS). The inner
/// iteration limits are those of the repository's fluid examples.
pub const NS_MAX_ITERATIONS: usize = 10;
pub const NS_GM_MAX_ITERATIONS: usize = 3;
pub const NS_CG_MAX_ITERATIONS: usize = 500;
pub const NS_KRYLOV_DIMENSION: usize = 50;

/// Inflow on the inlet face: `Type Dir` with `Impose_flux true`, so the value is a flux
/// (mL/s) that svMultiPhysics spreads over the face with the profile (`Flat` or
/// `Parabolic`); `Zero_out_perimeter true` keeps the rim no-slip. The prescribed velocity
/// is value x profile x outward normal: inflow is negative.
#[derive(Clone, Debug, PartialEq)]
pub enum InflowSpec {
    /// `Time_dependence Unsteady` + `Temporal_values_file_path`.
    Unsteady { file: String },
    /// `Time_dependence Steady` + `Value` (flux along the outward normal).
    Steady { flux_out_ml_s: f64 },
}

/// Everything `solver.xml` says, in svMultiPhysics' units (CGS).
#[derive(Clone, Debug, PartialEq)]
pub struct SolverSpec {
    pub n_time_steps: usize,
    pub dt_s: f64,
    /// Generalized-alpha `Spectral_radius_of_infinite_time_step` (rho_infinity).
    pub spectral_radius: f64,
    /// VTK output at steps with `step % increment == 0 && step >= start` (main.cpp).
    pub save_start_step: usize,
    pub save_increment: usize,
    pub density_g_cm3: f64,
    pub viscosity_g_cm_s: f64,
    pub backflow_stabilization: f64,
    pub max_nonlinear_iterations: usize,
    pub nonlinear_tolerance: f64,
    pub linear_tolerance: f64,
    /// (face name, path relative to the case directory), every face of the mesh.
    pub faces: Vec<(String, String)>,
    pub inlet_name: String,
    /// `Flat` or `Parabolic`.
    pub inlet_profile: &'static str,
    pub inflow: InflowSpec,
    /// (face name, resistance dyn s/cm^5): `Type Neu`, `Time_dependence Resistance`,
    /// the resistance in `Value` (read_files.cpp: `lBc.r = bc_params->value`).
    pub outlets: Vec<(String, f64)>,
    /// No-slip faces: `Type Dir`, `Time_dependence Steady`, `Value 0`.
    pub walls: Vec<String>,
}

/// Minimal XML writer: two-space indent, one element per line, values padded with spaces
/// as the repository's examples are (svMultiPhysics trims them).
struct Xml {
    out: String,
    open: Vec<String>,
}

impl Xml {
    fn new() -> Self {
        Xml { out: String::from("<?xml version=\"1.0\" encoding=\"UTF-8\" ?>\n"), open: Vec::new() }
    }

    fn indent(&self) -> String {
        "  ".repeat(self.open.len())
    }

    fn open(&mut self, tag: &str, attributes: &[(&str, &str)]) {
        let attrs: String = attributes.iter().map(|(k, v)| format!(" {k}=\"{}\"", escape(v))).collect();
        let _ = writeln!(self.out, "{}<{tag}{attrs}>", self.indent());
        self.open.push(tag.to_string());
    }

    fn close(&mut self) {
        let tag = self.open.pop().unwrap_or_default();
        let _ = writeln!(self.out, "{}</{tag}>", self.indent());
    }

    fn leaf(&mut self, tag: &str, value: impl std::fmt::Display) {
        let _ = writeln!(self.out, "{}<{tag}> {} </{tag}>", self.indent(), escape(&value.to_string()));
    }
}

fn escape(text: &str) -> String {
    text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// The complete `solver.xml`. Numbers are written in Rust's shortest round-trip form, so
/// parsing them back gives the same `f64`.
pub fn solver_xml_text(spec: &SolverSpec) -> String {
    let mut x = Xml::new();
    x.open("svMultiPhysicsFile", &[("version", "0.1")]);
    general_section(&mut x, spec);
    mesh_section(&mut x, spec);
    x.open("Add_equation", &[("type", "fluid")]);
    fluid_properties(&mut x, spec);
    outputs(&mut x);
    linear_solver(&mut x, spec);
    boundary_conditions(&mut x, spec);
    x.close();
    x.close();
    x.out
}

fn general_section(x: &mut Xml, spec: &SolverSpec) {
    x.open("GeneralSimulationParameters", &[]);
    x.leaf("Continue_previous_simulation", "false");
    x.leaf("Number_of_spatial_dimensions", 3);
    x.leaf("Number_of_time_steps", spec.n_time_steps);
    x.leaf("Time_step_size", spec.dt_s);
    x.leaf("Spectral_radius_of_infinite_time_step", spec.spectral_radius);
    x.leaf("Searched_file_name_to_trigger_stop", "STOP_SIM");
    x.leaf("Save_results_to_VTK_format", "true");
    x.leaf("Name_prefix_of_saved_VTK_files", RESULT_PREFIX);
    x.leaf("Increment_in_saving_VTK_files", spec.save_increment);
    x.leaf("Start_saving_after_time_step", spec.save_start_step);
    x.leaf("Save_results_in_folder", RESULTS_DIR);
    // One restart file at the end (restarts are written when step % increment == 0).
    x.leaf("Increment_in_saving_restart_files", spec.n_time_steps);
    x.leaf("Convert_BIN_to_VTK_format", "false");
    x.leaf("Verbose", "true");
    x.leaf("Warning", "true");
    x.leaf("Debug", "false");
    x.close();
}

fn mesh_section(x: &mut Xml, spec: &SolverSpec) {
    x.open("Add_mesh", &[("name", MESH_NAME)]);
    x.leaf("Mesh_file_path", format!("{MESH_DIR}/{VOLUME_FILE}"));
    for (name, path) in &spec.faces {
        x.open("Add_face", &[("name", name)]);
        x.leaf("Face_file_path", path);
        x.close();
    }
    x.close();
}

fn fluid_properties(x: &mut Xml, spec: &SolverSpec) {
    x.leaf("Coupled", "true");
    x.leaf("Min_iterations", 1);
    x.leaf("Max_iterations", spec.max_nonlinear_iterations);
    x.leaf("Tolerance", spec.nonlinear_tolerance);
    x.leaf("Backflow_stabilization_coefficient", spec.backflow_stabilization);
    x.leaf("Density", spec.density_g_cm3);
    x.open("Viscosity", &[("model", "Constant")]);
    x.leaf("Value", spec.viscosity_g_cm_s);
    x.close();
}

/// `Spatial`: fields in the `result_<step>.vtu` files. `Boundary_integral`: the `B_NS_*`
/// files, one column per face of the mesh (all faces, in `Add_face` order).
fn outputs(x: &mut Xml) {
    x.open("Output", &[("type", "Spatial")]);
    x.leaf("Velocity", "true");
    x.leaf("Pressure", "true");
    x.close();
    x.open("Output", &[("type", "Boundary_integral")]);
    x.leaf("Velocity", "true");
    x.leaf("Pressure", "true");
    x.close();
}

fn linear_solver(x: &mut Xml, spec: &SolverSpec) {
    x.open("LS", &[("type", "NS")]);
    x.open("Linear_algebra", &[("type", "fsils")]);
    x.leaf("Preconditioner", "fsils");
    x.close();
    x.leaf("Max_iterations", NS_MAX_ITERATIONS);
    x.leaf("NS_GM_max_iterations", NS_GM_MAX_ITERATIONS);
    x.leaf("NS_CG_max_iterations", NS_CG_MAX_ITERATIONS);
    x.leaf("Tolerance", spec.linear_tolerance);
    x.leaf("NS_GM_tolerance", spec.linear_tolerance);
    x.leaf("NS_CG_tolerance", spec.linear_tolerance);
    x.leaf("Krylov_space_dimension", NS_KRYLOV_DIMENSION);
    x.close();
}

fn boundary_conditions(x: &mut Xml, spec: &SolverSpec) {
    x.open("Add_BC", &[("name", &spec.inlet_name)]);
    x.leaf("Type", "Dir");
    match &spec.inflow {
        InflowSpec::Unsteady { file } => {
            x.leaf("Time_dependence", "Unsteady");
            x.leaf("Temporal_values_file_path", file);
        }
        InflowSpec::Steady { flux_out_ml_s } => {
            x.leaf("Time_dependence", "Steady");
            x.leaf("Value", flux_out_ml_s);
        }
    }
    x.leaf("Profile", spec.inlet_profile);
    x.leaf("Zero_out_perimeter", "true");
    x.leaf("Impose_flux", "true");
    x.close();
    for (name, resistance) in &spec.outlets {
        x.open("Add_BC", &[("name", name)]);
        x.leaf("Type", "Neu");
        x.leaf("Time_dependence", "Resistance");
        x.leaf("Value", resistance);
        x.close();
    }
    for name in &spec.walls {
        x.open("Add_BC", &[("name", name)]);
        x.leaf("Type", "Dir");
        x.leaf("Time_dependence", "Steady");
        x.leaf("Value", 0.0);
        x.close();
    }
}

// ---------------------------------------------------------------------------------------
// Temporal values file (read_files.cpp: read_temporal_values)
// ---------------------------------------------------------------------------------------

/// The flow file: a header line "<points> <modes>" (points >= 2 rows follow; modes is the
/// number of Fourier modes svMultiPhysics fits, see [`crate::fourier`]), then one
/// "<time> <value>" row per sample. The period is last time - first time, so the last row
/// repeats the first one period later. Values are fluxes along the face's outward normal.
pub fn flow_file_text(times_s: &[f64], flux_out_ml_s: &[f64], modes: usize) -> String {
    let mut text = format!("{} {}\n", times_s.len(), modes);
    for (t, q) in times_s.iter().zip(flux_out_ml_s) {
        let _ = writeln!(text, "{t} {q}");
    }
    text
}

/// Parse a flow file back: (modes, times, values). Errors name the line.
pub fn parse_flow_file(path: &Path, text: &str) -> Result<(usize, Vec<f64>, Vec<f64>), SvmpError> {
    let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty());
    let (_, header) = lines.next().ok_or_else(|| SvmpError::format(path, 1, "empty flow file"))?;
    let head: Vec<usize> = header.split_whitespace().map(str::parse).collect::<Result<_, _>>().map_err(|_| {
        SvmpError::format(path, 1, format!("header '{header}' is not two integers \"points modes\""))
    })?;
    let [points, modes] = head[..] else {
        return Err(SvmpError::format(path, 1, format!("header '{header}' is not \"points modes\"")));
    };
    let (mut times, mut values) = (Vec::new(), Vec::new());
    for (i, line) in lines {
        let row = numbers(path, i + 1, line)?;
        let [t, q] = row[..] else {
            return Err(SvmpError::format(path, i + 1, format!("expected \"time value\", got '{line}'")));
        };
        times.push(t);
        values.push(q);
    }
    if times.len() != points {
        return Err(SvmpError::format(path, 1, format!("header says {points} points, file has {}", times.len())));
    }
    Ok((modes, times, values))
}

fn numbers(path: &Path, line_no: usize, line: &str) -> Result<Vec<f64>, SvmpError> {
    line.split_whitespace()
        .map(|f| f.parse::<f64>().ok().filter(|v| v.is_finite()))
        .collect::<Option<Vec<f64>>>()
        .ok_or_else(|| SvmpError::format(path, line_no, format!("not finite numbers: '{}'", line.trim())))
}

// ---------------------------------------------------------------------------------------
// Boundary integral files (txt.cpp)
// ---------------------------------------------------------------------------------------

/// A `B_*` file as read: face names in column order and one row per written step.
#[derive(Clone, Debug, PartialEq)]
pub struct BoundaryTable {
    pub face_names: Vec<String>,
    /// From the "face areas:" line (cm^2), when the file has one.
    pub face_areas_cm2: Option<Vec<f64>>,
    pub rows: Vec<BoundaryRow>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct BoundaryRow {
    pub step: usize,
    pub time_s: f64,
    pub values: Vec<f64>,
}

/// Parse a `B_*` file. Current svMultiPhysics writes '#' comment lines, a line
/// "face areas: a1 a2 ...", a header "step time name1 name2 ..." and then rows
/// "step time v1 v2 ..." (`%d %.10e` then `%.10e` per face). Older versions (and svFSI)
/// write a header of face names only and rows of values only, one per time step from
/// step 1: for those, time = step x `dt_s`.
pub fn parse_boundary_integral(path: &Path, text: &str, dt_s: f64) -> Result<BoundaryTable, SvmpError> {
    let mut table = BoundaryTable { face_names: Vec::new(), face_areas_cm2: None, rows: Vec::new() };
    let mut with_step_time = false;
    for (i, raw) in text.lines().enumerate() {
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        if let Some(areas) = line.strip_prefix("face areas:") {
            table.face_areas_cm2 = Some(numbers(path, i + 1, areas)?);
        } else if table.face_names.is_empty() {
            let tokens: Vec<&str> = line.split_whitespace().collect();
            with_step_time = tokens.len() >= 2 && tokens[0] == "step" && tokens[1] == "time";
            let names = if with_step_time { &tokens[2..] } else { &tokens[..] };
            if names.is_empty() || names.iter().any(|n| n.parse::<f64>().is_ok()) {
                return Err(SvmpError::format(path, i + 1, format!("expected the face-name header, got '{line}'")));
            }
            table.face_names = names.iter().map(|s| s.to_string()).collect();
        } else {
            let row = boundary_row(path, i + 1, line, &table, with_step_time, dt_s)?;
            table.rows.push(row);
        }
    }
    check_table(path, &table)?;
    Ok(table)
}

fn boundary_row(
    path: &Path,
    line_no: usize,
    line: &str,
    table: &BoundaryTable,
    with_step_time: bool,
    dt_s: f64,
) -> Result<BoundaryRow, SvmpError> {
    let v = numbers(path, line_no, line)?;
    let n = table.face_names.len();
    let expected = n + if with_step_time { 2 } else { 0 };
    if v.len() != expected {
        return Err(SvmpError::format(
            path,
            line_no,
            format!("{} numbers for {n} faces, expected {expected}", v.len()),
        ));
    }
    if !with_step_time {
        let step = table.rows.len() + 1;
        return Ok(BoundaryRow { step, time_s: step as f64 * dt_s, values: v });
    }
    if v[0] < 0.0 || v[0].fract() != 0.0 {
        return Err(SvmpError::format(path, line_no, format!("step {} is not a whole number", v[0])));
    }
    Ok(BoundaryRow { step: v[0] as usize, time_s: v[1], values: v[2..].to_vec() })
}

fn check_table(path: &Path, table: &BoundaryTable) -> Result<(), SvmpError> {
    if table.face_names.is_empty() {
        return Err(SvmpError::format(path, 1, "no face-name header"));
    }
    if let Some(areas) = &table.face_areas_cm2 {
        if areas.len() != table.face_names.len() {
            return Err(SvmpError::format(
                path,
                1,
                format!("{} face areas for {} faces", areas.len(), table.face_names.len()),
            ));
        }
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------
// Step log (output.cpp: output_result), written to stdout and histor.dat
// ---------------------------------------------------------------------------------------

/// One nonlinear iteration line, e.g. " NS 12-3s 4.123e+00  [-62 7.920e-04 ...]  [5 -15 23]":
/// equation symbol, "<time step>-<iteration>" with an "s" when VTK output was saved at this
/// step, then the elapsed wall time (s).
#[derive(Clone, Debug, PartialEq)]
pub struct StepLine {
    pub equation: String,
    pub step: usize,
    pub iteration: usize,
    pub saved: bool,
    pub elapsed_s: f64,
    /// The residual figures that follow (absent on a line cut short).
    pub residual: Option<IterationResidual>,
}

/// The bracketed figures of an iteration line (output.cpp): "[dB R/R_step R/R_run
/// final/initial]" of the nonlinear residual R at this iterate, relative to the step's
/// first iterate and to the run's first, then "[iterations dB %time]" of the linear solve,
/// written "!...!" (and followed by "WARNING: The linear system solution has not
/// converged") when that solve missed its tolerance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IterationResidual {
    pub step_relative: f64,
    pub run_relative: f64,
    pub linear_iterations: usize,
    pub linear_converged: bool,
}

impl IterationResidual {
    /// svMultiPhysics' own test of a Newton iterate (Integrator.cpp): R/R_run or R/R_step at
    /// most the tolerance. A step whose last iterate fails it stopped at Max_iterations.
    pub fn meets(&self, tolerance: f64) -> bool {
        self.run_relative <= tolerance || self.step_relative <= tolerance
    }
}

fn iteration_residual<'a>(mut tokens: impl Iterator<Item = &'a str>) -> Option<IterationResidual> {
    let number = |t: &str| t.trim_matches(|c| c == '[' || c == ']' || c == '!').parse::<f64>().ok();
    let _db = number(tokens.next()?)?;
    let step_relative = number(tokens.next()?)?;
    let run_relative = number(tokens.next()?)?;
    let _ratio = number(tokens.next()?)?;
    let linear = tokens.next()?;
    let linear_iterations = number(linear)? as usize;
    Some(IterationResidual { step_relative, run_relative, linear_iterations, linear_converged: !linear.starts_with('!') })
}

pub fn parse_step_line(line: &str) -> Option<StepLine> {
    let mut tokens = line.split_whitespace();
    let equation = tokens.next()?;
    if !equation.chars().all(|c| c.is_ascii_alphabetic()) {
        return None;
    }
    let counter = tokens.next()?;
    let saved = counter.ends_with('s');
    let (step, iteration) = counter.trim_end_matches('s').split_once('-')?;
    Some(StepLine {
        equation: equation.to_string(),
        step: step.parse().ok()?,
        iteration: iteration.parse().ok()?,
        saved,
        elapsed_s: tokens.next()?.parse().ok()?,
        residual: iteration_residual(tokens),
    })
}

// ---------------------------------------------------------------------------------------
// Result files (vtk_xml.cpp: write_vtus)
// ---------------------------------------------------------------------------------------

/// The step of a result file name: `<prefix>_<step>.vtu`, step zero-padded to 3 digits up
/// to 1000 and plain above (some versions append `_cpp` before `.vtu`).
pub fn result_file_step(file_name: &str) -> Option<usize> {
    let stem = file_name.strip_prefix(RESULT_PREFIX)?.strip_prefix('_')?.strip_suffix(".vtu")?;
    let digits = stem.strip_suffix("_cpp").unwrap_or(stem);
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    digits.parse().ok()
}

/// The result file name svMultiPhysics writes for `step`.
pub fn result_file_name(step: usize) -> String {
    if step > 1000 {
        format!("{RESULT_PREFIX}_{step}.vtu")
    } else {
        format!("{RESULT_PREFIX}_{step:03}.vtu")
    }
}

/// Point arrays of the result files (`Output type="Spatial"` names).
pub const RESULT_VELOCITY: &str = "Velocity";
pub const RESULT_PRESSURE: &str = "Pressure";

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn step_lines_are_parsed_and_others_ignored() {
        let l = parse_step_line(" NS 12-3s 4.123e+00  [-62 7.920e-04 7.920e-04 3.600e-04]  [5 -15 23]").unwrap();
        assert_eq!((l.equation.as_str(), l.step, l.iteration, l.saved, l.elapsed_s), ("NS", 12, 3, true, 4.123));
        let r = l.residual.unwrap();
        assert_eq!((r.step_relative, r.run_relative, r.linear_iterations, r.linear_converged), (7.92e-4, 7.92e-4, 5, true));
        assert!(r.meets(1e-3) && !r.meets(1e-4));
        let l = parse_step_line(" NS 7-1 1.0e-1 [0 1 1 1] [1 2 3]").unwrap();
        assert_eq!((l.step, l.iteration, l.saved), (7, 1, false));
        // A linear solve that missed its tolerance, as output.cpp marks it.
        let line = " NS 164-3 2.5e+02  [-19 1.100e-01 3.000e-02 4.1e-01]  !10 -8 97!  WARNING: The linear system solution has not converged";
        let r = parse_step_line(line).unwrap().residual.unwrap();
        assert_eq!((r.linear_iterations, r.linear_converged), (10, false));
        assert!(!r.meets(1e-3) && r.meets(0.05));
        assert_eq!(parse_step_line(" NS 7-1 1.0e-1").unwrap().residual, None);
        for other in ["", "---------", " Eq     N-i     T       dB  Ri/R1", "Reading mesh msh"] {
            assert_eq!(parse_step_line(other), None, "{other}");
        }
    }

    #[test]
    fn result_names_round_trip() {
        for step in [1, 42, 999, 1000, 1001, 2210] {
            assert_eq!(result_file_step(&result_file_name(step)), Some(step));
        }
        assert_eq!(result_file_name(7), "result_007.vtu");
        assert_eq!(result_file_step("result_2210_cpp.vtu"), Some(2210));
        assert_eq!(result_file_step("result_average.vtu"), None);
        assert_eq!(result_file_step("other_010.vtu"), None);
    }

    #[test]
    fn legacy_boundary_file_takes_time_from_dt() {
        let t = parse_boundary_integral(Path::new("B.txt"), " inflow  outflow \n 1.0 2.0\n 3.0 4.0\n", 0.5).unwrap();
        assert_eq!(t.face_names, ["inflow", "outflow"]);
        assert_eq!(t.rows[1], BoundaryRow { step: 2, time_s: 1.0, values: vec![3.0, 4.0] });
        let e = parse_boundary_integral(Path::new("B.txt"), "a b\n1 2 3\n", 0.5).unwrap_err().to_string();
        assert!(e.contains("B.txt: line 2") && e.contains("3 numbers for 2 faces"), "{e}");
    }
}
