//! The bad-input campaign of issue 16, rerun as a test: about 180 bad inputs of every
//! class the issue tried (corrupted, truncated and garbage surface files, bad topology,
//! bad points files, bad numbers, bad cases, bad segmentations and label maps) and 11
//! controls, each a separate `baffle` process under a 60 s limit. Every bad input must
//! end in a named error: exit code 1 (not a signal, not a panic's 101), "baffle: error:"
//! and the case's needles (the file, option or place at fault) on stderr, in at most a
//! few lines, no "X: X:" stutter, and no file left in its output folder. Every control
//! must succeed. One test, so the whole table is printed before it fails.

#[path = "support/inputs.rs"]
mod inputs;

use baffle_core::io::{read_surface_labeled, write_markups_closed_curve, write_trimesh_vtp, CoordinateSystem};
use baffle_test_support::perturb::bump_wall;
use baffle_core::phantom::phantom_default;
use baffle_test_support::reference_data::reference_data_if_present;
use baffle_core::{TriMesh, Vec3};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const TIME_LIMIT: Duration = Duration::from_secs(60);
/// A named error is a sentence or two, not a tool's log.
const MAX_ERROR_LINES: usize = 4;

#[derive(PartialEq)]
enum Expect {
    NamedError,
    Success,
}

struct Case {
    name: String,
    /// The case's own output folder (`{out}` in its arguments).
    out_dir: PathBuf,
    args: Vec<String>,
    needles: Vec<String>,
    expect: Expect,
}

/// Where every input and output of the campaign lives.
struct Bench {
    dir: PathBuf,
    surface: TriMesh,
    points: Vec<Vec3>,
    cases: Vec<Case>,
}

impl Bench {
    fn new() -> Self {
        let dir = std::env::temp_dir().join(format!("baffle-campaign-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("in")).unwrap();
        let phantom = phantom_default();
        Bench { dir, surface: phantom.surface, points: phantom.suture_points_mm, cases: Vec::new() }
    }

    fn input(&self, file: &str) -> String {
        self.dir.join("in").join(file).to_string_lossy().into_owned()
    }

    fn write(&self, file: &str, bytes: &[u8]) -> String {
        let path = self.input(file);
        std::fs::write(&path, bytes).unwrap();
        path
    }

    fn write_surface(&self, file: &str, mesh: &TriMesh) -> String {
        let path = self.input(file);
        write_trimesh_vtp(Path::new(&path), mesh).unwrap();
        path
    }

    fn write_points(&self, file: &str, points: &[Vec3]) -> String {
        let path = self.input(file);
        write_markups_closed_curve(Path::new(&path), "BC", points, CoordinateSystem::Lps).unwrap();
        path
    }

    /// A case's output folder: its name made a plain folder name.
    fn out(&self, name: &str) -> String {
        let folder: String = name.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' { c } else { '_' }).collect();
        self.dir.join("out").join(folder).to_string_lossy().into_owned()
    }

    fn add(&mut self, expect: Expect, name: &str, args: &[&str], needles: &[&str]) {
        let out = self.out(name);
        let args = args.iter().map(|a| a.replace("{out}", &out)).collect();
        let needles = needles.iter().map(|s| s.to_string()).collect();
        self.cases.push(Case { name: name.to_string(), out_dir: PathBuf::from(out), args, needles, expect });
    }

    fn bad(&mut self, name: &str, args: &[&str], needles: &[&str]) {
        self.add(Expect::NamedError, name, args, needles);
    }

    fn control(&mut self, name: &str, args: &[&str]) {
        self.add(Expect::Success, name, args, &[]);
    }
}

/// The outcome of one run, as the issue classified them.
enum Outcome {
    Named,
    Success,
    Crash(String),
    Hang,
    SilentPass,
    Unclear(String),
    LeftFiles(usize),
}

/// Run one case: its outcome, wall time and the first line of its error message.
fn run(case: &Case) -> (Outcome, Duration, String) {
    let start = Instant::now();
    let mut child = Command::new(env!("CARGO_BIN_EXE_baffle"))
        .args(&case.args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start baffle");
    let stderr_pipe = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || std::io::read_to_string(stderr_pipe).unwrap_or_default());
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break Some(status);
        }
        if start.elapsed() > TIME_LIMIT {
            child.kill().ok();
            child.wait().ok();
            break None;
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    let stderr = reader.join().unwrap();
    let outcome = match status {
        None => Outcome::Hang,
        Some(status) => classify(case, status.code(), &stderr),
    };
    let first_error_line = stderr.lines().find(|l| l.contains("error:")).unwrap_or("").to_string();
    (outcome, start.elapsed(), first_error_line)
}

fn classify(case: &Case, code: Option<i32>, stderr: &str) -> Outcome {
    let last_line = stderr.lines().last().unwrap_or("").to_string();
    match (code, &case.expect) {
        (Some(0), Expect::Success) => Outcome::Success,
        (Some(0), Expect::NamedError) => Outcome::SilentPass,
        (Some(1), Expect::Success) => Outcome::Unclear(format!("a control failed: {last_line}")),
        // Exit code 2: the argument parser refused an option, naming it and its value.
        (Some(1 | 2), Expect::NamedError) => match unclear(case, stderr) {
            Some(why) => Outcome::Unclear(why),
            None => match files_left(case) {
                0 => Outcome::Named,
                n => Outcome::LeftFiles(n),
            },
        },
        (code, _) => Outcome::Crash(format!("exit {code:?}: {}", stderr.lines().take(3).collect::<Vec<_>>().join(" / "))),
    }
}

/// Why a clean failure's message does not name the problem, if it does not. Progress
/// lines before it are not part of the message.
fn unclear(case: &Case, stderr: &str) -> Option<String> {
    let Some(at) = stderr.find("baffle: error:").or_else(|| stderr.find("error:")) else {
        return Some(format!("no error message: {stderr}"));
    };
    // The message ends at the first blank line (the argument parser adds its usage after).
    let message = stderr[at..].split("\n\n").next().unwrap_or("").trim();
    if message.lines().count() > MAX_ERROR_LINES {
        return Some(format!("{} lines of output", message.lines().count()));
    }
    if let Some(n) = case.needles.iter().find(|n| !message.contains(n.as_str())) {
        return Some(format!("does not mention '{n}': {message}"));
    }
    stutter(message).map(|s| format!("says '{s}' twice: {message}"))
}

/// A prefix repeated back to back ("target area: target area: ...").
fn stutter(message: &str) -> Option<&str> {
    let parts: Vec<&str> = message.split(": ").collect();
    parts.windows(2).find(|w| w[0] == w[1] && w[0].len() > 2).map(|w| w[0])
}

/// Files a failed run left in its output folder (it must leave none but the record of
/// an infeasible target, which the report and the Slicer module read).
fn files_left(case: &Case) -> usize {
    let entries = std::fs::read_dir(&case.out_dir).map(|d| d.flatten().map(|e| e.file_name()).collect()).unwrap_or_else(|_| Vec::new());
    entries.iter().filter(|n| *n != "infeasible.json").count()
}

// ---- the inputs -------------------------------------------------------------------

fn mesh_with(surface: &TriMesh, edit: impl FnOnce(&mut TriMesh)) -> TriMesh {
    let mut m = surface.clone();
    edit(&mut m);
    m
}

/// Corrupted, truncated, garbage and wrong-format surface files given to `design`.
fn surface_files(b: &mut Bench) {
    let pts = b.write_points("phantom.mrk.json", &b.points.clone());
    let good = std::fs::read(b.write_surface("good.vtp", &b.surface.clone())).unwrap();
    let closing = String::from_utf8_lossy(&good).rfind("</PolyData>").unwrap();
    let mut cuts: Vec<(String, usize)> =
        [0.0, 0.01, 0.05, 0.1, 0.25, 0.4, 0.5, 0.6, 0.75, 0.9, 0.99].iter().map(|f| (format!("{:.0}pct", f * 100.0), (f * good.len() as f64) as usize)).collect();
    cuts.push(("before-closing-tags".into(), closing));
    for (label, at) in cuts {
        let file = format!("truncated-{label}.vtp");
        let path = b.write(&file, &good[..at]);
        b.bad(&format!("vtp truncated at {label}"), &["design", "--surface", &path, "--points", &pts, "--bsa", "0.37", "--out", "{out}"], &[&file]);
    }
    let garbage: [(&str, Vec<u8>); 6] = [
        ("empty.vtp", vec![]),
        ("random-bytes.vtp", (0..2048u32).map(|i| (i.wrapping_mul(2654435761) >> 13) as u8).collect()),
        ("png-header.vtp", b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR".to_vec()),
        ("json.vtp", br#"{"not": "a surface"}"#.to_vec()),
        ("utf16.vtp", "<?xml version=\"1.0\"?>".encode_utf16().flat_map(|u| u.to_le_bytes()).collect()),
        ("unclosed-xml.vtp", b"<?xml version=\"1.0\"?><VTKFile type=\"PolyData\"><PolyData><Piece".to_vec()),
    ];
    for (file, bytes) in garbage {
        let path = b.write(file, &bytes);
        b.bad(&format!("garbage {file}"), &["design", "--surface", &path, "--points", &pts, "--bsa", "0.37", "--out", "{out}"], &[file]);
    }
    let text = String::from_utf8_lossy(&good).into_owned();
    let edits: [(&str, String); 4] = [
        ("wrong-type.vtp", text.replacen("type=\"PolyData\"", "type=\"UnstructuredGrid\"", 1)),
        ("no-piece.vtp", text.replacen("<Piece", "<Peace", 1).replacen("</Piece>", "</Peace>", 1)),
        ("points-count-lie.vtp", text.replacen("NumberOfPoints=\"", "NumberOfPoints=\"9", 1)),
        ("polys-count-lie.vtp", text.replacen("NumberOfPolys=\"", "NumberOfPolys=\"9", 1)),
    ];
    for (file, content) in edits {
        let path = b.write(file, content.as_bytes());
        b.bad(&format!("edited {file}"), &["design", "--surface", &path, "--points", &pts, "--bsa", "0.37", "--out", "{out}"], &[file]);
    }
    other_surface_formats(b, &pts);
}

/// Legacy VTK, STL and paths that are not surface files.
fn other_surface_formats(b: &mut Bench, pts: &str) {
    let small = inputs::first_triangles(&b.surface, 60);
    let vtk = inputs::legacy_vtk(&b.surface, false);
    let stl = inputs::binary_stl(&small);
    let files: [(&str, Vec<u8>); 7] = [
        ("truncated.vtk", vtk[..vtk.len() / 2].to_vec()),
        ("bad-keyword.vtk", String::from_utf8_lossy(&vtk).replacen("POLYGONS", "POLYGONZ", 1).into_bytes()),
        ("binary-lie.vtk", String::from_utf8_lossy(&vtk).replacen("ASCII", "BINARY", 1).into_bytes()),
        ("truncated-binary.stl", stl[..stl.len() - 30].to_vec()),
        ("count-lie.stl", [&stl[..80], &u32::MAX.to_le_bytes()[..], &stl[84..]].concat()),
        ("garbage-ascii.stl", b"solid x\nfacet normal a b c\nouter loop\nvertex 1 2\nendsolid".to_vec()),
        ("surface.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n".to_vec()),
    ];
    for (file, bytes) in files {
        let path = b.write(file, &bytes);
        b.bad(&format!("format {file}"), &["design", "--surface", &path, "--points", pts, "--bsa", "0.37", "--out", "{out}"], &[file]);
    }
    let dir = b.dir.join("in").to_string_lossy().into_owned();
    b.bad("a folder as the surface", &["design", "--surface", &dir, "--points", pts, "--bsa", "0.37", "--out", "{out}"], &["in"]);
    b.bad("a missing surface", &["design", "--surface", &b.input("missing.vtp"), "--points", pts, "--bsa", "0.37", "--out", "{out}"], &["missing.vtp", "not found"]);
}

/// Valid files of surfaces that are not a capped ventricle: bad numbers, bad topology,
/// bad labels, bad shapes.
fn surface_contents(b: &mut Bench) {
    let pts = b.write_points("phantom-c.mrk.json", &b.points.clone());
    let s = b.surface.clone();
    let n = s.points.len() as u32;
    let wall_vertex = s.triangles[s.face_ids.iter().position(|&f| f == 2).unwrap()][0] as usize;
    let far = s.points.iter().map(|p| p.x).fold(f64::MIN, f64::max);
    let shapes: Vec<(&str, TriMesh, &[&str])> = vec![
        ("nan-point", mesh_with(&s, |m| m.points[3].y = f64::NAN), &["nan-point.vtk"]),
        ("inf-point", mesh_with(&s, |m| m.points[7].z = f64::INFINITY), &["inf-point.vtk"]),
        ("huge-point", mesh_with(&s, |m| m.points[5].x = 1e30), &["huge-point.vtk", "point 5"]),
        ("index-out-of-range", mesh_with(&s, |m| m.triangles[4][1] = n + 10), &["polygon 4", "1487"]),
        ("no-points", TriMesh { points: vec![], triangles: vec![], face_ids: vec![] }, &["no triangles"]),
        ("degenerate-triangle", mesh_with(&s, |m| m.triangles[9] = [m.triangles[9][0]; 3]), &["degenerate-triangle.vtk", "1 degenerate"]),
        ("hole", mesh_with(&s, |m| remove_triangles(m, &[12])), &["hole.vtk", "3 boundary edges"]),
        ("big-hole", mesh_with(&s, |m| remove_triangles(m, &(100..160).collect::<Vec<_>>())), &["big-hole.vtk", "boundary edges"]),
        ("duplicate-triangle", mesh_with(&s, |m| duplicate_triangle(m, 20)), &["triangle"]),
        ("non-manifold-fin", mesh_with(&s, |m| add_fin(m, 30)), &["edge"]),
        ("all-wall", mesh_with(&s, |m| m.face_ids.iter_mut().for_each(|f| *f = 2)), &["VSD"]),
        ("no-aortic-cap", mesh_with(&s, |m| relabel(m, 16, 2)), &["16"]),
        ("no-vsd-cap", mesh_with(&s, |m| relabel(m, 11, 2)), &["11"]),
        ("caps-swapped-to-one", mesh_with(&s, |m| relabel(m, 16, 11)), &["11"]),
        ("unknown-label", mesh_with(&s, |m| m.face_ids[40] = 77), &["unknown-label.vtk", "labelled 77"]),
        ("two-components", two_components(&s), &["two-components.vtk", "2 disconnected parts"]),
        ("spike", bump_wall(&s, wall_vertex, 3, 25.0, 2), &[]),
        ("fold", bump_wall(&s, wall_vertex, 60, -30.0, 2), &[]),
        ("crumpled-cap", mesh_with(&s, |m| crumple_cap(m, 11)), &["crumpled-cap.vtk", "VSD cap is not planar"]),
        ("centimetres", mesh_with(&s, |m| m.points.iter_mut().for_each(|p| *p *= 0.1)), &[]),
        ("shifted-away", mesh_with(&s, |m| m.points.iter_mut().for_each(|p| p.x += 4.0 * far.abs() + 100.0)), &["point 1"]),
    ];
    for (stem, mesh, needles) in shapes {
        // Legacy ASCII VTK: our .vtp writer refuses non-finite points.
        let path = b.write(&format!("{stem}.vtk"), &inputs::legacy_vtk(&mesh, false));
        b.bad(&format!("surface {stem}"), &["design", "--surface", &path, "--points", &pts, "--bsa", "0.37", "--out", "{out}"], needles);
    }
}

/// Drop triangles `ts`, keeping every point so the hole's rim stays where it was.
fn remove_triangles(m: &mut TriMesh, ts: &[usize]) {
    let keep = |t: &usize| !ts.contains(t);
    m.triangles = m.triangles.iter().enumerate().filter(|(t, _)| keep(t)).map(|(_, tri)| *tri).collect();
    m.face_ids = m.face_ids.iter().enumerate().filter(|(t, _)| keep(t)).map(|(_, f)| *f).collect();
}

fn duplicate_triangle(m: &mut TriMesh, t: usize) {
    m.triangles.push(m.triangles[t]);
    m.face_ids.push(m.face_ids[t]);
}

/// A third triangle on an edge of triangle `t`, sticking out of the surface.
fn add_fin(m: &mut TriMesh, t: usize) {
    let [a, b, c] = m.triangles[t];
    let apex = m.points[c as usize] + (m.points[a as usize] - m.points[c as usize]).cross(&(m.points[b as usize] - m.points[c as usize])).normalize() * 3.0;
    m.points.push(apex);
    m.triangles.push([a, b, m.points.len() as u32 - 1]);
    m.face_ids.push(m.face_ids[t]);
}

fn relabel(m: &mut TriMesh, from: i32, to: i32) {
    m.face_ids.iter_mut().filter(|f| **f == from).for_each(|f| *f = to);
}

/// The surface and a copy of it moved 200 mm away: a closed surface in two pieces.
fn two_components(s: &TriMesh) -> TriMesh {
    let mut m = s.clone();
    let n = s.points.len() as u32;
    m.points.extend(s.points.iter().map(|p| p + Vec3::new(200.0, 0.0, 0.0)));
    m.triangles.extend(s.triangles.iter().map(|t| [t[0] + n, t[1] + n, t[2] + n]));
    m.face_ids.extend(s.face_ids.iter().map(|_| 2)); // the copy is a closed blob of wall
    m
}

/// Push the interior vertices of cap `label` off its plane by 2 mm, alternately out and in.
fn crumple_cap(m: &mut TriMesh, label: i32) {
    let (_, normal, _) = m.label_centroid_normal(label).unwrap();
    let on_wall: std::collections::HashSet<u32> = m.triangles.iter().zip(&m.face_ids).filter(|(_, &f)| f != label).flat_map(|(t, _)| *t).collect();
    let cap: std::collections::HashSet<u32> = m.triangles.iter().zip(&m.face_ids).filter(|(_, &f)| f == label).flat_map(|(t, _)| *t).collect();
    for (i, v) in cap.difference(&on_wall).enumerate() {
        m.points[*v as usize] += normal * if i % 2 == 0 { 2.0 } else { -2.0 };
    }
}

/// Bad suture-point files given to `design` on the phantom.
fn points_files(b: &mut Bench) {
    let surface = b.write_surface("phantom.vtp", &b.surface.clone());
    let p = b.points.clone();
    let good = String::from_utf8(inputs::markups_bytes(&p)).unwrap();
    let mut on_a_line = p.clone();
    on_a_line.iter_mut().enumerate().for_each(|(i, q)| *q = p[0] + (p[1] - p[0]) * i as f64);
    let mut far_off = p.clone();
    far_off[4] += Vec3::new(0.0, 0.0, 15.0);
    let mut doubled = p.clone();
    doubled[3] = doubled[2];
    let files: Vec<(&str, Vec<u8>, &[&str])> = vec![
        ("empty.mrk.json", vec![], &["empty.mrk.json"]),
        ("not-json.mrk.json", b"markups: yes".to_vec(), &["not-json.mrk.json"]),
        ("truncated.mrk.json", good.as_bytes()[..good.len() / 2].to_vec(), &["truncated.mrk.json"]),
        ("no-markups.mrk.json", b"{\"markups\": []}".to_vec(), &["no-markups.mrk.json"]),
        ("no-control-points.mrk.json", good.replacen("\"controlPoints\"", "\"controlPointz\"", 1).into_bytes(), &["no-control-points.mrk.json"]),
        ("string-position.mrk.json", replace_first_number_after(&good, "\"position\"", "\"a\""), &["string-position.mrk.json"]),
        ("nan-position.mrk.json", replace_first_number_after(&good, "\"position\"", "NaN"), &["nan-position.mrk.json"]),
        ("two-coordinates.mrk.json", two_coordinate_position(&good), &["two-coordinates.mrk.json"]),
        ("bad-frame.mrk.json", good.replacen("\"LPS\"", "\"XYZ\"", 1).into_bytes(), &["XYZ"]),
        ("two-points.mrk.json", inputs::markups_bytes(&p[..2]), &["2 "]),
        ("three-points.mrk.json", inputs::markups_bytes(&p[..3]), &["3 "]),
        ("collinear.mrk.json", inputs::markups_bytes(&on_a_line), &["point", "from the surface"]),
        ("all-same.mrk.json", inputs::markups_bytes(&vec![p[0]; 12]), &["point"]),
        ("doubled.mrk.json", inputs::markups_bytes(&doubled), &["points 3 and 4"]),
        ("far-off.mrk.json", inputs::markups_bytes(&far_off), &["point 5", "mm"]),
        ("binary.mrk.json", vec![0xff, 0xfe, 0, 1, 2, 3], &["binary.mrk.json"]),
        ("header-only.fcsv", b"# Markups fiducial file version = 4.11\n# CoordinateSystem = LPS\n".to_vec(), &["header-only.fcsv"]),
        ("text.fcsv", b"# CoordinateSystem = LPS\nid,a,b,c\nvtk_0,x,y,z,0,0,0,1,1,1,0,F-0,,\n".to_vec(), &["text.fcsv"]),
        ("short-rows.fcsv", b"# CoordinateSystem = LPS\nvtk_0,1\nvtk_1,2\n".to_vec(), &["short-rows.fcsv"]),
        ("two-columns.csv", b"1,2\n3,4\n5,6\n".to_vec(), &["two-columns.csv"]),
        ("words.csv", b"x,y,z\nleft,right,up\n".to_vec(), &["words.csv"]),
        ("empty.csv", vec![], &["empty.csv"]),
        ("points.txt", good.clone().into_bytes(), &["points.txt"]),
    ];
    for (file, bytes, needles) in files {
        let path = b.write(file, &bytes);
        b.bad(&format!("points {file}"), &["design", "--surface", &surface, "--points", &path, "--bsa", "0.37", "--out", "{out}"], needles);
    }
    b.bad("points missing", &["design", "--surface", &surface, "--points", &b.input("none.mrk.json"), "--bsa", "0.37", "--out", "{out}"], &["none.mrk.json"]);
}

fn replace_first_number_after(text: &str, key: &str, value: &str) -> Vec<u8> {
    let at = text.find(key).unwrap();
    let open = at + text[at..].find('[').unwrap() + 1;
    let end = open + text[open..].find(',').unwrap();
    format!("{}{value}{}", &text[..open], &text[end..]).into_bytes()
}

fn two_coordinate_position(text: &str) -> Vec<u8> {
    let at = text.find("\"position\"").unwrap();
    let open = at + text[at..].find('[').unwrap();
    let close = open + text[open..].find(']').unwrap();
    format!("{}[1.0, 2.0]{}", &text[..open], &text[close + 1..]).into_bytes()
}

/// Bad numbers and labels for `design --phantom`, each naming its option.
fn design_numbers(b: &mut Bench) {
    let options: [(&str, &str, &str); 37] = [
        ("--bsa", "-1", "BSA"),
        ("--bsa", "0", "BSA"),
        ("--bsa", "NaN", "BSA"),
        ("--bsa", "inf", "BSA"),
        ("--bsa", "100", "BSA"),
        ("--bsa", "abc", "--bsa"),
        ("--z-score", "NaN", "z"),
        ("--z-score", "50", "z"),
        ("--z-score", "-50", "z"),
        ("--target-area-mm2", "0", "target area"),
        ("--target-area-mm2", "-5", "target area"),
        ("--target-area-mm2", "NaN", "target area"),
        ("--target-area-mm2", "1e9", "target area"),
        ("--annulus-diameter-mm", "0", "annulus"),
        ("--annulus-diameter-mm", "-3", "annulus"),
        ("--height-cm", "-1", "height"),
        ("--weight-kg", "0", "weight"),
        ("--remesh-edge-mm", "0", "remesh"),
        ("--remesh-edge-mm", "1e-6", "remesh"),
        ("--remesh-edge-mm", "1000", "remesh"),
        ("--remesh-edge-mm", "NaN", "remesh"),
        ("--baffle-edge-mm", "0", "baffle_edge_mm"),
        ("--baffle-edge-mm", "-1", "baffle_edge_mm"),
        ("--seam-samples", "0", "seam"),
        ("--seam-samples", "1", "seam"),
        ("--seam-samples", "1000000000", "seam"),
        ("--seam-samples", "-4", "--seam-samples"),
        ("--centerline-spacing-mm", "0", "centerline"),
        ("--centerline-spacing-mm", "1e9", "centerline"),
        ("--control-points", "0", "control_points"),
        ("--max-point-distance-mm", "NaN", "max_point_distance_mm"),
        ("--max-point-distance-mm", "-1", "max_point_distance_mm"),
        ("--vsd-label", "16", "16"),
        ("--wall-label", "11", "11"),
        ("--vsd-label", "99", "99"),
        ("--surface-frame", "xyz", "xyz"),
        ("--vsd-cap-point", "1,2", "--vsd-cap-point"),
    ];
    for (flag, value, needle) in options {
        // A weight needs a height to make a body size, and a height a weight.
        let partner: &[&str] = match flag {
            "--weight-kg" => &["--height-cm", "100"],
            "--height-cm" => &["--weight-kg", "15"],
            _ => &[],
        };
        b.bad(&format!("design {flag} {value}"), &[&["design", "--phantom", "--out", "{out}", flag, value], partner].concat(), &[needle]);
    }
    b.bad("design with two targets", &["design", "--phantom", "--out", "{out}", "--target-area-mm2", "50", "--z-score", "1"], &["--target-area-mm2"]);
    b.bad("design without points", &["design", "--surface", &b.input("phantom.vtp"), "--bsa", "0.37", "--out", "{out}"], &["--points"]);
    b.bad("design an unknown option", &["design", "--phantom", "--out", "{out}", "--speed", "11"], &["--speed"]);
}

/// `baffle mesh`, `centerline` and `template` on a designed phantom domain, with bad
/// numbers and bad surfaces.
fn mesh_centerline_template(b: &mut Bench, domain: &str) {
    let open = b.write_surface("open-domain.vtp", &mesh_with(&read_surface_labeled(Path::new(domain)).unwrap().mesh, |m| remove_triangles(m, &[0, 1])));
    for (flag, value, needle) in [("--edge-length-mm", "1e-6", "edge"), ("--edge-length-mm", "0", "edge"), ("--edge-length-mm", "-1", "edge"), ("--edge-length-mm", "NaN", "edge"), ("--edge-length-mm", "1e6", "edge"), ("--interior-labels", "abc", "--interior-labels"), ("--interior-labels", "99", "99"), ("--gmsh", "/nonexistent/gmsh", "gmsh")] {
        let edge: &[&str] = if flag == "--edge-length-mm" { &[] } else { &["--edge-length-mm", "1.5"] };
        b.bad(&format!("mesh {flag} {value}"), &[&["mesh", "--surface", domain, flag, value, "--out", "{out}/mesh.vtu"], edge].concat(), &[needle]);
    }
    b.bad("mesh an open surface", &["mesh", "--surface", &open, "--edge-length-mm", "1.5", "--out", "{out}/mesh.vtu"], &["open-domain.vtp", "open"]);
    b.bad("mesh a missing surface", &["mesh", "--surface", &b.input("nothing.vtp"), "--edge-length-mm", "1.5", "--out", "{out}/mesh.vtu"], &["nothing.vtp"]);
    b.bad("centerline of an open surface", &["centerline", "--surface", &open, "--out", "{out}/c.vtp"], &["open"]);
    for (flag, value, needle) in [("--voxel-mm", "0", "voxel"), ("--voxel-mm", "NaN", "voxel"), ("--spacing-mm", "0", "spacing"), ("--smoothing-mm", "-1", "smoothing"), ("--planes", "11,99", "99"), ("--planes", "11", "--planes"), ("--plane-faces", &b.input("random-bytes.vtp"), "random-bytes.vtp"), ("--recenter-fraction", "7", "recenter"), ("--scale", "0", "scale"), ("--results", &b.input("empty.vtp"), "empty.vtp"), ("--peak-flow-ml-s", "0", "--peak-flow-ml-s"), ("--peak-flow-ml-s", "NaN", "--peak-flow-ml-s"), ("--peak-flow-ml-s", "-3", "--peak-flow-ml-s")] {
        b.bad(&format!("centerline {flag} {value}"), &["centerline", "--surface", domain, flag, value, "--out", "{out}/c.vtp"], &[needle]);
    }
    let pts = b.input("phantom.mrk.json");
    b.bad("template of a surface without a baffle", &["template", "--domain", &b.input("phantom.vtp"), "--points", &pts, "--out", "{out}/t.pdf"], &["10"]);
    b.bad("template to a .docx", &["template", "--domain", domain, "--points", &pts, "--out", "{out}/t.docx"], &["docx"]);
    b.bad("template with bad points", &["template", "--domain", domain, "--points", &b.input("empty.mrk.json"), "--out", "{out}/t.pdf"], &["empty.mrk.json"]);
    b.bad("template of a garbage domain", &["template", "--domain", &b.input("random-bytes.vtp"), "--points", &pts, "--out", "{out}/t.pdf"], &["random-bytes.vtp"]);
}

/// Bad cases and options for `baffle simulate` on a meshed phantom domain.
fn simulate_cases(b: &mut Bench, mesh_dir: &str) {
    let good = baffle_plan::case::EXAMPLE.replace("mesh.vtu", &format!("{mesh_dir}/mesh.vtu")).replace("mesh-faces.vtp", &format!("{mesh_dir}/mesh-faces.vtp"));
    let edits: [(&str, &str, &str, &str); 18] = [
        ("negative-viscosity", "\"viscosity_g_cm_s\": 0.04", "\"viscosity_g_cm_s\": -0.04", "viscosity"),
        ("zero-density", "\"density_g_cm3\": 1.06", "\"density_g_cm3\": 0", "density"),
        ("zero-dt", "\"dt_s\": 0.001", "\"dt_s\": 0", "dt"),
        ("huge-dt", "\"dt_s\": 0.001", "\"dt_s\": 5", "dt"),
        ("zero-cycles", "\"cycles\": 4", "\"cycles\": 0", "cycles"),
        ("zero-period", "\"period_s\": 0.682", "\"period_s\": 0", "period"),
        ("negative-bsa", "\"bsa_m2\": 0.37", "\"bsa_m2\": -0.37", "bsa"),
        ("pressures-swapped", "\"sbp_mmhg\": 107", "\"sbp_mmhg\": 60", "mmHg"),
        ("unknown-profile", "\"plug\"", "\"spiral\"", "spiral"),
        ("unknown-mode", "\"transient\"", "\"sometimes\"", "sometimes"),
        ("unknown-units", "\"units\": \"mm\"", "\"units\": \"furlong\"", "furlong"),
        ("unknown-format", "\"format\": \"baffle\"", "\"format\": \"ansys\"", "ansys"),
        ("inlet-not-a-face", "\"inlet\": 11", "\"inlet\": 42", "42"),
        ("outlet-not-a-face", "\"outlets\": [16]", "\"outlets\": [43]", "43"),
        ("inlet-is-outlet", "\"outlets\": [16]", "\"outlets\": [11]", "11"),
        ("unknown-field", "\"fluid\": {", "\"fluid\": { \"colour\": \"red\",", "colour"),
        ("missing-volume", "mesh.vtu", "no-such-mesh.vtu", "no-such-mesh.vtu"),
        ("string-for-number", "\"cycles\": 4", "\"cycles\": \"four\"", "line 7"),
    ];
    for (stem, from, to, needle) in edits {
        assert!(good.contains(from), "case example has no {from}");
        let path = b.write(&format!("{stem}.json"), good.replacen(from, to, 1).as_bytes());
        b.bad(&format!("case {stem}"), &["simulate", &path, "--out", "{out}"], &[needle]);
    }
    for (file, bytes) in [("empty-case.json", String::new()), ("truncated-case.json", good[..good.len() / 2].to_string()), ("array-case.json", "[1, 2, 3]".to_string())] {
        let path = b.write(file, bytes.as_bytes());
        b.bad(&format!("case {file}"), &["simulate", &path, "--out", "{out}"], &[file]);
    }
    let case = b.write("case.json", good.as_bytes());
    for (flag, value, needle) in [("--steps", "0", "steps"), ("--steps", "-1", "--steps"), ("--dt-s", "0", "dt"), ("--dt-s", "NaN", "dt"), ("--cycles", "0", "cycles"), ("--preconditioner", "magic", "magic"), ("--engine", "fortran", "fortran"), ("--mpi-processes", "0", "mpi")] {
        b.bad(&format!("simulate {flag} {value}"), &["simulate", &case, flag, value, "--out", "{out}"], &[needle]);
    }
    b.bad("simulate --resume with nothing to resume", &["simulate", &case, "--resume", "--steps", "2", "--out", "{out}"], &["resume"]);
    b.bad("simulate a missing case", &["simulate", &b.input("no-case.json"), "--out", "{out}"], &["no-case.json"]);
}

/// Bad segmentations (folders of surfaces) and label maps for `prepare`, `extend` and
/// `plan`.
fn segmentations_and_labelmaps(b: &mut Bench, data: Option<&Path>, domain: &str) {
    let seg_dir = |name: &str| {
        let d = b.dir.join("in").join(name);
        std::fs::create_dir_all(&d).unwrap();
        d
    };
    let empty = seg_dir("seg-empty");
    let only_lv = seg_dir("seg-only-lv");
    let garbage = seg_dir("seg-garbage");
    // A closed surface stands in for a blood pool, so the reader reaches the bad one.
    let closed = inputs::vtp_bytes(&b.surface);
    std::fs::write(only_lv.join("LV.vtp"), &closed).unwrap();
    for s in ["LV", "RV", "aorta"] {
        std::fs::write(garbage.join(format!("{s}.vtp")), if s == "RV" { b"garbage".to_vec() } else { closed.clone() }).unwrap();
    }
    let path = |p: &Path| p.to_string_lossy().into_owned();
    b.bad("prepare an empty folder", &["prepare", "--segmentations", &path(&empty), "--out", "{out}"], &["seg-empty", "LV"]);
    b.bad("prepare without RV and aorta", &["prepare", "--segmentations", &path(&only_lv), "--out", "{out}"], &["RV"]);
    b.bad("prepare with a garbage RV", &["prepare", "--segmentations", &path(&garbage), "--out", "{out}"], &["RV.vtp"]);
    b.bad("prepare a missing folder", &["prepare", "--segmentations", &b.input("no-segs"), "--out", "{out}"], &["no-segs"]);
    let nrrd = inputs::nrrd(false);
    let nii = inputs::nifti();
    let maps: [(&str, Vec<u8>, &str); 9] = [
        ("truncated.nrrd", nrrd[..nrrd.len() - 20].to_vec(), "truncated.nrrd"),
        ("no-header-end.nrrd", nrrd[..60].to_vec(), "no-header-end.nrrd"),
        ("bad-sizes.nrrd", String::from_utf8_lossy(&nrrd).replacen("sizes: 6 5 4", "sizes: 6 5", 1).into_bytes(), "bad-sizes.nrrd"),
        ("bad-type.nrrd", String::from_utf8_lossy(&nrrd).replacen("unsigned char", "complex", 1).into_bytes(), "bad-type.nrrd"),
        ("truncated.nii", nii[..nii.len() - 30].to_vec(), "truncated.nii"),
        ("bad-magic.nii", [&nii[..344], b"xxxx", &nii[348..]].concat(), "bad-magic.nii"),
        ("truncated.nii.gz", { let g = inputs::gzip(&nii); g[..g.len() / 2].to_vec() }, "truncated.nii.gz"),
        ("not-gzip.nii.gz", nii.clone(), "not-gzip.nii.gz"),
        ("labels-absent.nrrd", nrrd.clone(), "label"),
    ];
    for (file, bytes, needle) in maps {
        let p = b.write(file, &bytes);
        b.bad(&format!("labelmap {file}"), &["prepare", "--labelmap", &p, "--lv-label", "21", "--rv-label", "22", "--aorta-label", "23", "--out", "{out}"], &[needle]);
    }
    let map = b.input("labels-absent.nrrd");
    b.bad("labelmap same label twice", &["prepare", "--labelmap", &map, "--lv-label", "1", "--rv-label", "1", "--aorta-label", "2", "--out", "{out}"], &["same label 1"]);
    if let Some(data) = data {
        let segs = data.join("p2/segmentations").to_string_lossy().into_owned();
        for (flag, value, needle) in [("--voxel-mm", "0", "voxel"), ("--voxel-mm", "NaN", "voxel"), ("--closing-radius-mm", "-1", "closing"), ("--remesh-edge-mm", "1e-6", "remesh"), ("--crop-margin-mm", "-5", "crop"), ("--smoothing-iterations", "-1", "--smoothing-iterations")] {
            b.bad(&format!("prepare {flag} {value}"), &["prepare", "--segmentations", &segs, flag, value, "--out", "{out}"], &[needle]);
        }
        b.bad("extend the phantom with p2's segmentations", &["extend", "--domain", domain, "--segmentations", &segs, "--out", "{out}"], &[]);
        b.bad("extend with a garbage RV", &["extend", "--domain", domain, "--segmentations", &path(&garbage), "--out", "{out}"], &["RV.vtp"]);
    }
}

/// Bad physiology for `plan` and bad target lists for `sweep`.
fn plan_and_sweep(b: &mut Bench) {
    for (flag, value, needle) in [("--bp", "abc", "abc"), ("--bp", "80/120", "80/120"), ("--bp", "107", "107"), ("--hr", "0", "heart rate"), ("--hr", "NaN", "heart rate"), ("--hr", "900", "heart rate"), ("--cardiac-index", "-1", "--cardiac-index"), ("--edge-length-mm", "0", "edge"), ("--cycles", "0", "cycles")] {
        let physiology: Vec<&str> = [("--bp", "100/60"), ("--hr", "120")].iter().filter(|(f, _)| *f != flag).flat_map(|(f, v)| [*f, *v]).collect();
        b.bad(&format!("plan {flag} {value}"), &[&["plan", "--phantom", "--quick", flag, value, "--out", "{out}"], &physiology[..]].concat(), &[needle]);
    }
    for (flag, value, needle) in [("--z-scores", "", "--z-scores"), ("--z-scores", "a,b", "a"), ("--z-scores", "1,NaN", "NaN"), ("--areas-mm2", "-1", "-1"), ("--areas-mm2", "0,10", "0")] {
        b.bad(&format!("sweep {flag} '{value}'"), &["sweep", "--phantom", &format!("{flag}={value}"), "--out", "{out}"], &[needle]);
    }
}

/// The 11 controls: the same commands on valid input must succeed.
fn controls(b: &mut Bench, data: Option<&Path>) -> (String, String) {
    let design = b.out("control-design");
    let mesh = b.out("control-mesh");
    let pts = b.write_points("control.mrk.json", &b.points.clone());
    let surface = b.write_surface("control.vtp", &b.surface.clone());
    let ras: Vec<Vec3> = b.points.iter().map(|p| Vec3::new(-p.x, -p.y, p.z)).collect();
    let ras_path = b.input("control-ras.mrk.json");
    write_markups_closed_curve(Path::new(&ras_path), "BC", &ras, CoordinateSystem::Ras).unwrap();
    b.control("control-design", &["design", "--surface", &surface, "--points", &pts, "--bsa", "0.37", "--out", &design]);
    b.control("control-design-ras-points", &["design", "--surface", &surface, "--points", &ras_path, "--bsa", "0.37", "--out", "{out}"]);
    b.control("control-z-score -2", &["design", "--phantom", "--z-score", "-2", "--out", "{out}"]);
    b.control("control-phantom", &["phantom", "--out", "{out}"]);
    let domain = format!("{design}/domain.vtp");
    b.control("control-mesh", &["mesh", "--surface", &domain, "--edge-length-mm", "1.5", "--out", &format!("{mesh}/mesh.vtu")]);
    b.control("control-centerline", &["centerline", "--surface", &domain, "--out", "{out}/c.vtp"]);
    b.control("control-template", &["template", "--domain", &domain, "--points", &pts, "--out", "{out}/t.pdf"]);
    b.control("control-sweep", &["sweep", "--phantom", "--z-scores=-1,0", "--out", "{out}"]);
    let case = b.write(
        "control-case.json",
        baffle_plan::case::EXAMPLE.replace("mesh.vtu", &format!("{mesh}/mesh.vtu")).replace("mesh-faces.vtp", &format!("{mesh}/mesh-faces.vtp")).as_bytes(),
    );
    b.control("control-simulate", &["simulate", &case, "--steps", "2", "--out", "{out}"]);
    match data {
        Some(data) => {
            let segs = data.join("p2/segmentations").to_string_lossy().into_owned();
            b.control("control-prepare-p2", &["prepare", "--segmentations", &segs, "--out", "{out}"]);
            let input = data.join("p2/design_input");
            let (s, p) = (input.join("capped_ventricle.vtp"), input.join("suture_points.mrk.json"));
            b.control("control-design-p2", &["design", "--surface", s.to_str().unwrap(), "--points", p.to_str().unwrap(), "--bsa", "0.37", "--out", "{out}"]);
        }
        None => b.control("control-design-fcsv", &["design", "--surface", &surface, "--points", &b.write("control.fcsv", &inputs::fcsv(&b.points.clone())), "--bsa", "0.37", "--out", "{out}"]),
    }
    (domain, mesh)
}

/// Outcomes counted over the campaign, and the cases that failed.
#[derive(Default)]
struct Report {
    tally: [usize; 7],
    failures: Vec<String>,
    runs: usize,
}

impl Report {
    fn run(&mut self, cases: &[Case]) {
        for case in cases {
            let (outcome, took, message) = run(case);
            let (slot, problem) = match &outcome {
                Outcome::Named => (0, None),
                Outcome::Success => (1, None),
                Outcome::Crash(why) => (2, Some(format!("CRASH {why}"))),
                Outcome::Hang => (3, Some("HANG".to_string())),
                Outcome::SilentPass => (4, Some("SILENT PASS (exit 0)".to_string())),
                Outcome::Unclear(why) => (5, Some(format!("UNCLEAR {why}"))),
                Outcome::LeftFiles(n) => (6, Some(format!("LEFT {n} FILES in its output folder"))),
            };
            self.tally[slot] += 1;
            self.runs += 1;
            let shown: String = message.chars().take(160).collect();
            println!("{:>3} {:<55} {:>6.2} s {} | {shown}", self.runs, case.name, took.as_secs_f64(), problem.as_deref().unwrap_or("ok"));
            if let Some(p) = problem {
                self.failures.push(format!("{}: {p}", case.name));
            }
        }
    }
}

#[test]
fn every_bad_input_of_the_campaign_is_a_named_error_and_every_control_succeeds() {
    let data = reference_data_if_present();
    let mut b = Bench::new();
    // The controls run first: the cases after them use their outputs.
    let (domain, mesh) = controls(&mut b, data.as_deref());
    let mut report = Report::default();
    report.run(&b.cases);
    assert!(report.failures.is_empty(), "a control failed: {:?}", report.failures);
    let control_count = b.cases.len();
    surface_files(&mut b);
    surface_contents(&mut b);
    points_files(&mut b);
    design_numbers(&mut b);
    mesh_centerline_template(&mut b, &domain);
    simulate_cases(&mut b, &mesh);
    segmentations_and_labelmaps(&mut b, data.as_deref(), &domain);
    plan_and_sweep(&mut b);
    report.run(&b.cases[control_count..]);

    let bad = b.cases.len() - control_count;
    let t = report.tally;
    println!(
        "campaign: {bad} bad inputs, {control_count} controls: {} named errors, {} controls succeeded, {} crashes, {} hangs, {} silent passes, {} unclear, {} left files",
        t[0], t[1], t[2], t[3], t[4], t[5], t[6]
    );
    std::fs::remove_dir_all(&b.dir).ok();
    assert!(report.failures.is_empty(), "{} of {} cases failed:\n{}", report.failures.len(), b.cases.len(), report.failures.join("\n"));
    assert!(bad >= 175 || data.is_none(), "the campaign has {bad} bad inputs, fewer than the issue's 175");
}
