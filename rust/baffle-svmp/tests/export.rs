//! The exported case read back: solver.xml parsed with quick-xml and checked against the
//! settings, mesh files read with the team's readers, the inflow file's Fourier fit.

mod common;

use std::collections::HashMap;
use std::path::Path;

use baffle_cfd::{RunMode, Waveform};
use baffle_core::io::{read_polydata, PolyData, MODEL_FACE_ID};
use baffle_mesh::tetmesh::{face_key, tet_faces};
use baffle_mesh::{read_vtu, TetMesh};
use baffle_svmp::format::{parse_flow_file, GLOBAL_ELEMENT_ID, GLOBAL_NODE_ID, MODEL_REGION_ID};
use baffle_svmp::fourier::fit;
use baffle_svmp::{export_case, FaceRole};
use common::*;
use quick_xml::events::Event;

/// A parsed XML element: name, attributes, trimmed text, children.
#[derive(Debug, Default)]
struct Element {
    name: String,
    attrs: HashMap<String, String>,
    text: String,
    children: Vec<Element>,
}

impl Element {
    fn all(&self, name: &str) -> Vec<&Element> {
        self.children.iter().filter(|c| c.name == name).collect()
    }

    fn child(&self, name: &str) -> &Element {
        let found = self.all(name);
        assert_eq!(found.len(), 1, "<{}> has {} <{name}>", self.name, found.len());
        found[0]
    }

    fn with_attr(&self, name: &str, key: &str, value: &str) -> &Element {
        let found: Vec<_> = self.all(name).into_iter().filter(|c| c.attrs.get(key).map(String::as_str) == Some(value)).collect();
        assert_eq!(found.len(), 1, "<{}> has {} <{name} {key}=\"{value}\">", self.name, found.len());
        found[0]
    }

    fn text_of(&self, name: &str) -> &str {
        &self.child(name).text
    }

    fn f64_of(&self, name: &str) -> f64 {
        self.text_of(name).parse().unwrap_or_else(|_| panic!("<{name}> '{}' is not a number", self.text_of(name)))
    }
}

fn parse_xml(text: &str) -> Element {
    let mut reader = quick_xml::Reader::from_str(text);
    reader.config_mut().trim_text(true);
    let mut stack = vec![Element::default()];
    loop {
        match reader.read_event().expect("well-formed XML") {
            Event::Start(e) => {
                let mut el = Element { name: String::from_utf8(e.name().as_ref().to_vec()).unwrap(), ..Default::default() };
                for a in e.attributes() {
                    let a = a.unwrap();
                    el.attrs.insert(String::from_utf8(a.key.as_ref().to_vec()).unwrap(), a.unescape_value().unwrap().into_owned());
                }
                stack.push(el);
            }
            Event::Text(t) => stack.last_mut().unwrap().text = t.unescape().unwrap().trim().to_string(),
            Event::End(_) => {
                let el = stack.pop().unwrap();
                stack.last_mut().unwrap().children.push(el);
            }
            Event::Eof => break,
            Event::Decl(_) | Event::Comment(_) => {}
            other => panic!("unexpected XML event {other:?}"),
        }
    }
    assert_eq!(stack.len(), 1, "unclosed elements");
    stack.pop().unwrap().children.pop().expect("a root element")
}

#[test]
fn solver_xml_states_every_setting_of_the_case() {
    let dir = scratch("solver-xml");
    let (mesh, settings, options) = (box_mesh(), settings(), options());
    let case = export_case(&dir, &mesh, &settings, &options).unwrap();
    let root = parse_xml(&std::fs::read_to_string(dir.join("solver.xml")).unwrap());
    assert_eq!(root.name, "svMultiPhysicsFile");

    let general = root.child("GeneralSimulationParameters");
    let period = settings.inflow.period_s();
    let steps = (settings.cycles as f64 * period / settings.dt_s).round();
    assert_eq!(steps, 2728.0);
    assert_eq!(general.f64_of("Number_of_time_steps"), steps);
    assert_eq!(general.f64_of("Time_step_size"), settings.dt_s);
    assert_eq!(general.f64_of("Spectral_radius_of_infinite_time_step"), options.spectral_radius);
    // Spatial output only at the peak of cycle 4 (2.21 s; later multiples are beyond the end).
    let peak_step = ((3.0 * period + settings.inflow.peak().1) / settings.dt_s).round();
    assert_eq!(peak_step, 2210.0);
    assert_eq!(general.f64_of("Start_saving_after_time_step"), peak_step);
    assert_eq!(general.f64_of("Increment_in_saving_VTK_files"), peak_step);
    assert_eq!(general.text_of("Save_results_in_folder"), "results");
    assert_eq!(case.manifest.peak_step, 2210);

    let mesh_el = root.child("Add_mesh");
    assert!(dir.join(mesh_el.text_of("Mesh_file_path")).is_file());
    for (id, name) in &options.face_names {
        let face = mesh_el.with_attr("Add_face", "name", name);
        let path = dir.join(face.text_of("Face_file_path"));
        assert!(path.is_file() && path.ends_with(format!("mesh-surfaces/{name}.vtp")), "face {id}: {path:?}");
    }
    assert_eq!(mesh_el.all("Add_face").len(), mesh.faces.len());

    let eq = root.with_attr("Add_equation", "type", "fluid");
    assert_eq!(eq.f64_of("Density"), settings.density_g_cm3);
    let viscosity = eq.with_attr("Viscosity", "model", "Constant");
    assert_eq!(viscosity.f64_of("Value"), settings.viscosity_g_cm_s);
    assert_eq!(eq.f64_of("Backflow_stabilization_coefficient"), settings.backflow_stabilization);
    assert_eq!(eq.f64_of("Max_iterations"), settings.nonlinear().max_iterations().max(baffle_svmp::export::SVMP_MIN_NEWTON_ITERATIONS) as f64);
    assert_eq!(eq.f64_of("Tolerance"), settings.nonlinear_tolerance);
    for kind in ["Spatial", "Boundary_integral"] {
        let out = eq.with_attr("Output", "type", kind);
        assert_eq!((out.text_of("Velocity"), out.text_of("Pressure")), ("true", "true"), "{kind}");
    }
    let ls = eq.with_attr("LS", "type", "NS");
    assert_eq!(ls.f64_of("Tolerance"), 1e-4);
    assert_eq!(ls.f64_of("Tolerance"), settings.linear_tolerance);
    assert_eq!(ls.with_attr("Linear_algebra", "type", "fsils").text_of("Preconditioner"), "fsils");

    let inlet = eq.with_attr("Add_BC", "name", "inflow");
    assert_eq!(inlet.text_of("Type"), "Dir");
    assert_eq!(inlet.text_of("Time_dependence"), "Unsteady");
    assert_eq!(inlet.text_of("Profile"), "Flat");
    assert_eq!(inlet.text_of("Impose_flux"), "true");
    assert_eq!(inlet.text_of("Zero_out_perimeter"), "true");
    assert!(dir.join(inlet.text_of("Temporal_values_file_path")).is_file());
    let outlet = eq.with_attr("Add_BC", "name", "outflow");
    assert_eq!((outlet.text_of("Type"), outlet.text_of("Time_dependence")), ("Neu", "Resistance"));
    assert_eq!(outlet.f64_of("Value"), settings.outlets[0].resistance_dyn_s_cm5);
    for wall in ["wall_a", "wall_b"] {
        let bc = eq.with_attr("Add_BC", "name", wall);
        assert_eq!((bc.text_of("Type"), bc.text_of("Time_dependence"), bc.f64_of("Value")), ("Dir", "Steady", 0.0));
    }
    // Measurement planes carry no boundary condition; every other face exactly one.
    assert_eq!(eq.all("Add_BC").len(), 4);
    let roles: Vec<FaceRole> = case.manifest.faces.iter().map(|f| f.role).collect();
    assert_eq!(roles, [FaceRole::Wall, FaceRole::Inlet, FaceRole::Outlet, FaceRole::Wall, FaceRole::Plane, FaceRole::Plane]);
}

#[test]
fn steady_mode_prescribes_the_peak_flux_inward_for_the_set_duration() {
    let dir = scratch("steady");
    let mut settings = settings();
    settings.mode = RunMode::Steady;
    let case = export_case(&dir, &box_mesh(), &settings, &options()).unwrap();
    let root = parse_xml(&std::fs::read_to_string(dir.join("solver.xml")).unwrap());
    let inlet = root.child("Add_equation").with_attr("Add_BC", "name", "inflow");
    assert_eq!(inlet.text_of("Time_dependence"), "Steady");
    assert_eq!(inlet.f64_of("Value"), -settings.inflow.peak().0);
    assert_eq!(root.child("GeneralSimulationParameters").f64_of("Number_of_time_steps"), 1000.0);
    assert_eq!((case.manifest.peak_step, case.inflow_file.is_none()), (1000, true));
}

#[test]
fn a_step_limit_stops_the_run_there_with_its_fields_at_its_own_largest_inflow() {
    // 170 steps of 1 ms: the first cycle's peak (164 ms) is inside, cycle 4's is not.
    let (settings, mut options) = (settings(), options());
    options.max_time_steps = Some(170);
    let dir = scratch("step-limit");
    let case = export_case(&dir, &box_mesh(), &settings, &options).unwrap();
    let root = parse_xml(&std::fs::read_to_string(dir.join("solver.xml")).unwrap());
    let general = root.child("GeneralSimulationParameters");
    assert_eq!(general.f64_of("Number_of_time_steps"), 170.0);
    let first_peak = (settings.inflow.peak().1 / settings.dt_s).round() as usize;
    assert!(first_peak <= 170, "{first_peak}");
    assert_eq!((case.manifest.n_time_steps, case.manifest.peak_step), (170, first_peak));
    assert_eq!(general.f64_of("Start_saving_after_time_step"), first_peak as f64);
    // Before the first peak: the last step has the largest inflow of the run.
    options.max_time_steps = Some(40);
    let early = export_case(&scratch("step-limit-early"), &box_mesh(), &settings, &options).unwrap();
    assert_eq!((early.manifest.n_time_steps, early.manifest.peak_step), (40, 40));
    // A limit beyond the cycles changes nothing; 0 is refused.
    options.max_time_steps = Some(1_000_000);
    assert_eq!(export_case(&scratch("step-limit-long"), &box_mesh(), &settings, &options).unwrap().manifest.n_time_steps, 2728);
    options.max_time_steps = Some(0);
    let err = export_case(&scratch("step-limit-zero"), &box_mesh(), &settings, &options).unwrap_err().to_string();
    assert!(err.contains("step limit is 0"), "{err}");
}

fn i32_array<'a>(arrays: &'a [baffle_core::io::DataArray], name: &str, what: &str) -> &'a [i32] {
    arrays.iter().find(|a| a.name == name).and_then(|a| a.as_i32()).unwrap_or_else(|| panic!("{what}: no Int32 '{name}'"))
}

#[test]
fn volume_file_holds_the_tets_in_cm_with_one_based_ids() {
    let dir = scratch("volume");
    let mesh = box_mesh();
    export_case(&dir, &mesh, &settings(), &options()).unwrap();
    let vtu = read_vtu(&dir.join("mesh-complete/mesh-complete.mesh.vtu")).unwrap();
    // The same tets, in slabs along the longest axis (svMultiPhysics' initial blocks per
    // rank are then compact, which ParMETIS needs: p2's mesh in its own order hung it).
    let sorted = |t: &[[u32; 4]]| {
        let mut t = t.to_vec();
        t.sort();
        t
    };
    assert_eq!(sorted(&vtu.mesh.tets), sorted(&mesh.tets));
    let bounds = baffle_core::geometry::spatial::Aabb::from_points(&mesh.points_mm);
    let axis = (bounds.max - bounds.min).imax();
    let along: Vec<f64> = vtu.mesh.tets.iter().map(|t| t.iter().map(|&i| vtu.mesh.points_mm[i as usize][axis]).sum()).collect();
    assert!(along.windows(2).all(|w| w[0] <= w[1]), "tets not in slabs along axis {axis}");
    for (p, q) in vtu.mesh.points_mm.iter().zip(&mesh.points_mm) {
        assert!((p * 10.0 - q).norm() < 1e-12, "{p} cm vs {q} mm");
    }
    let n = mesh.points_mm.len() as i32;
    let m = mesh.tets.len() as i32;
    assert_eq!(i32_array(&vtu.point_data, GLOBAL_NODE_ID, "vtu"), (1..=n).collect::<Vec<_>>());
    assert_eq!(i32_array(&vtu.cell_data, GLOBAL_ELEMENT_ID, "vtu"), (1..=m).collect::<Vec<_>>());
    assert!(i32_array(&vtu.cell_data, MODEL_REGION_ID, "vtu").iter().all(|&r| r == 1));
}

/// Check a face file against the volume: points bit-identical to their GlobalNodeID node,
/// each triangle a face of its GlobalElementID tet; return the triangles in volume ids.
fn check_face_file(path: &Path, volume: &TetMesh, interior: bool) -> (PolyData, Vec<[u32; 3]>) {
    let face = read_polydata(path).unwrap();
    let what = path.display().to_string();
    let nodes = i32_array(&face.point_data, GLOBAL_NODE_ID, &what);
    let elements = i32_array(&face.cell_data, GLOBAL_ELEMENT_ID, &what);
    assert_eq!((nodes.len(), elements.len()), (face.points.len(), face.polys.len()), "{what}");
    for (p, &id) in face.points.iter().zip(nodes) {
        assert!(id >= 1 && id as usize <= volume.points_mm.len(), "{what}: node id {id}");
        let v = volume.points_mm[id as usize - 1];
        assert_eq!(p.map(f64::to_bits), v.map(f64::to_bits), "{what}: node {id} coordinates differ");
    }
    let mut tris = Vec::new();
    for (poly, &element) in face.polys.iter().zip(elements) {
        let tri = [0, 1, 2].map(|k| nodes[poly[k] as usize] as u32 - 1);
        assert!(element >= 1 && element as usize <= volume.tets.len(), "{what}: element id {element}");
        let tet = volume.tets[element as usize - 1];
        let has_it = tet_faces(&tet).iter().any(|f| face_key(f) == face_key(&tri));
        assert!(has_it, "{what}: triangle {tri:?} is not a face of tet {element} {tet:?}");
        // svMultiPhysics orients the normal outward of that tet: it must be the winding
        // normal (outward of the domain on boundaries, +z on the planes here).
        let apex = tet.iter().copied().find(|v| !tri.contains(v)).unwrap();
        let [a, b, c] = tri.map(|v| volume.points_mm[v as usize]);
        let normal = (b - a).cross(&(c - a));
        assert!(normal.dot(&(volume.points_mm[apex as usize] - a)) < 0.0, "{what}: {tri:?} winds into tet {element}");
        if interior {
            assert!(normal.z > 0.0, "{what}: plane triangle {tri:?} lost its winding");
        }
        tris.push(tri);
    }
    (face, tris)
}

#[test]
fn face_files_match_the_volume_nodes_and_their_tets() {
    let dir = scratch("faces");
    let mesh = box_mesh();
    let options = options();
    export_case(&dir, &mesh, &settings(), &options).unwrap();
    let volume = read_vtu(&dir.join("mesh-complete/mesh-complete.mesh.vtu")).unwrap().mesh;
    for set in &mesh.faces {
        let path = dir.join(format!("mesh-complete/mesh-surfaces/{}.vtp", options.face_names[&set.id]));
        let (face, tris) = check_face_file(&path, &volume, set.interior);
        let mut got: Vec<_> = tris.iter().map(face_key).collect();
        let mut want: Vec<_> = set.triangles.iter().map(face_key).collect();
        got.sort();
        want.sort();
        assert_eq!(got, want, "face {}", set.id);
        assert!(i32_array(&face.cell_data, MODEL_FACE_ID, "face").iter().all(|&id| id == set.id));
    }
    let boundary: usize = mesh.faces.iter().filter(|f| !f.interior).map(|f| f.triangles.len()).sum();
    let (exterior, _) = check_face_file(&dir.join("mesh-complete/mesh-complete.exterior.vtp"), &volume, false);
    assert_eq!(exterior.polys.len(), boundary);
    let (walls, _) = check_face_file(&dir.join("mesh-complete/walls_combined.vtp"), &volume, false);
    let wall_count: usize = mesh.faces.iter().filter(|f| f.id == WALL_A || f.id == WALL_B).map(|f| f.triangles.len()).sum();
    assert_eq!(walls.polys.len(), wall_count);
    let mut wall_ids: Vec<i32> = i32_array(&walls.cell_data, MODEL_FACE_ID, "walls").to_vec();
    wall_ids.dedup();
    assert_eq!(wall_ids, [WALL_A, WALL_B]);
}

/// Largest |inflow from the file's Fourier fit - our waveform| over the file samples and
/// every time step of the run, as svMultiPhysics fits and evaluates it.
fn fit_deviation(path: &Path, waveform: &Waveform, dt_s: f64, steps: usize, modes_override: Option<usize>) -> f64 {
    let (modes, times, flux_out) = parse_flow_file(path, &std::fs::read_to_string(path).unwrap()).unwrap();
    let series = fit(&times, &flux_out, modes_override.unwrap_or(modes)).unwrap();
    let step_times = (0..=steps).map(|k| k as f64 * dt_s);
    times.iter().copied().chain(step_times).map(|t| (-series.evaluate(t) - waveform.flow_ml_s(t)).abs()).fold(0.0, f64::max)
}

#[test]
fn inflow_file_fourier_fit_matches_the_default_waveform_within_one_percent() {
    let dir = scratch("fourier");
    let settings = settings();
    let case = export_case(&dir, &box_mesh(), &settings, &options()).unwrap();
    let path = case.inflow_file.clone().unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let (modes, times, flux_out) = parse_flow_file(&path, &text).unwrap();
    assert_eq!(Some(modes), case.fourier_modes);
    // Periodic: the last sample repeats the first one period later; inflow is negative.
    assert_eq!(times[times.len() - 1] - times[0], settings.inflow.period_s());
    assert_eq!(flux_out[0], flux_out[flux_out.len() - 1]);
    assert!(flux_out.iter().all(|&q| q <= 0.0) && flux_out.iter().any(|&q| q < -60.0));
    let (peak, _) = settings.inflow.peak();
    let deviation = fit_deviation(&path, &settings.inflow, settings.dt_s, case.manifest.n_time_steps, None);
    assert!(deviation <= 0.01 * peak, "fit deviates {deviation} mL/s with {modes} modes (peak {peak})");
    // The check has teeth: a few modes do not reproduce the ejection.
    let coarse = fit_deviation(&path, &settings.inflow, settings.dt_s, case.manifest.n_time_steps, Some(4));
    assert!(coarse > 0.01 * peak, "4 modes deviate only {coarse}");
}

#[test]
fn tabulated_waveform_is_exported_with_its_own_samples() {
    let dir = scratch("table");
    let mut settings = settings();
    settings.inflow = Waveform::parse("0 0\n0.1 30\n0.2 80\n0.3 40\n0.4 5\n0.5 0\n0.6 0\n0.7 0\n").unwrap();
    settings.cycles = 2;
    let case = export_case(&dir, &box_mesh(), &settings, &options()).unwrap();
    let path = case.inflow_file.unwrap();
    let (_, times, flux_out) = parse_flow_file(&path, &std::fs::read_to_string(&path).unwrap()).unwrap();
    assert_eq!(times, [0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7]);
    assert_eq!(flux_out[2], -80.0);
    let deviation = fit_deviation(&path, &settings.inflow, settings.dt_s, case.manifest.n_time_steps, None);
    assert!(deviation <= 0.01 * 80.0, "{deviation}");
}

#[test]
fn run_script_and_readme_say_how_to_run_it() {
    let dir = scratch("script");
    let mut options = options();
    options.mpi_processes = 16;
    export_case(&dir, &box_mesh(), &settings(), &options).unwrap();
    let script = std::fs::read_to_string(dir.join("run.sh")).unwrap();
    assert!(script.starts_with("#!/bin/sh") && script.contains(r#"mpiexec $ROOT_OPTION -n "${NP:-16}" "$SVMP" solver.xml"#), "{script}");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        assert_ne!(std::fs::metadata(dir.join("run.sh")).unwrap().permissions().mode() & 0o111, 0);
    }
    let readme = std::fs::read_to_string(dir.join("README.md")).unwrap();
    assert!(readme.contains("sbatch --ntasks=16"), "{readme}");
}

/// run.sh run for real with the stand-in engine on PATH: NP, and Open MPI's root option
/// exactly when root (MPICH never gets it).
#[cfg(unix)]
#[test]
fn run_script_runs_the_case_with_the_processes_and_root_option() {
    let root = unsafe { libc::geteuid() } == 0;
    for (version, open_mpi) in [(OPEN_MPI_VERSION, true), (MPICH_VERSION, false)] {
        let dir = scratch(if open_mpi { "script-run-ompi" } else { "script-run-mpich" });
        let mut settings = settings();
        settings.cycles = 1;
        settings.dt_s = 0.01;
        export_case(&dir, &box_mesh(), &settings, &options()).unwrap();
        let bin = standin_bin(if open_mpi { "script-bin-ompi" } else { "script-bin-mpich" }, &StandIn { mpi_version: version, ..StandIn::default() });
        let path = format!("{}:{}", bin.display(), std::env::var("PATH").unwrap_or_default());
        let out = baffle_mesh::start_retrying_busy(|| std::process::Command::new(dir.join("run.sh")).env("PATH", &path).env("NP", "7").output()).unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        assert!(String::from_utf8_lossy(&out.stdout).contains(" NS 68-2"));
        let args = std::fs::read_to_string(dir.join("mpiexec.args")).unwrap();
        let option = if root && open_mpi { "--allow-run-as-root " } else { "" };
        assert_eq!(args, format!("{option}-n 7 {} solver.xml\n", bin.join("svMultiPhysics").display()));
    }
}

#[test]
fn inconsistent_cases_are_refused_by_name() {
    let dir = scratch("refused");
    let mut options = options();
    options.face_names.remove(&WALL_B);
    let e = export_case(&dir, &box_mesh(), &settings(), &options).unwrap_err().to_string();
    assert!(e.contains("face 4 has no name"), "{e}");

    let mut options = common::options();
    options.measurement_face_ids = vec![PLANE_1, 99];
    let e = export_case(&dir, &box_mesh(), &settings(), &options).unwrap_err().to_string();
    assert!(e.contains("measurement face 99 is not a face of the mesh"), "{e}");

    let mut options = common::options();
    options.face_names.insert(WALL_B, "bad/name".into());
    let e = export_case(&dir, &box_mesh(), &settings(), &options).unwrap_err().to_string();
    assert!(e.contains("'bad/name'"), "{e}");

    let mut options = common::options();
    options.peak_time_s = Some(99.0);
    let e = export_case(&dir, &box_mesh(), &settings(), &options).unwrap_err().to_string();
    assert!(e.contains("peak time 99 s"), "{e}");

    let mut mesh = box_mesh();
    mesh.tets[0].swap(0, 1);
    let e = export_case(&dir, &mesh, &settings(), &common::options()).unwrap_err().to_string();
    assert!(e.contains("tet 0") && e.contains("inverted"), "{e}");
}
