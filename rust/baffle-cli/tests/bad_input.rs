//! Bad input to the `baffle` command, one test per case of issue 16: each must end in
//! a named error (exit code 1, the problem and where it is on stderr), never an
//! abort, a hang or a silent success. Controls that must succeed are marked so.

use baffle_core::io::{read_surface_labeled, write_trimesh_vtp};
use baffle_test_support::perturb::bump_wall;
use baffle_test_support::reference_data::reference_data_if_present;
use baffle_core::TriMesh;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn baffle(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_baffle")).args(args).output().expect("run baffle")
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("baffle-bad-input-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The run failed cleanly (exit code 1, not a signal) with every needle in its message.
fn assert_named_error(out: &Output, needles: &[&str]) -> String {
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    assert_eq!(out.status.code(), Some(1), "expected a clean failure, got {:?}: {stderr}", out.status);
    for needle in needles {
        assert!(stderr.contains(needle), "'{stderr}' does not mention '{needle}'");
    }
    stderr
}

/// `baffle phantom` inputs in a fresh folder: (surface, points).
fn phantom_files(name: &str) -> (PathBuf, PathBuf) {
    let dir = temp_dir(name);
    let out = baffle(&["phantom", "--out", s(&dir)]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    (dir.join("capped_ventricle.vtp"), dir.join("suture_points.mrk.json"))
}

fn design_phantom_with(name: &str, extra: &[&str]) -> Output {
    let out = temp_dir(name).join("out");
    let mut args = vec!["design", "--phantom", "--out", s(&out)];
    args.extend_from_slice(extra);
    baffle(&args)
}

fn read_mesh(path: &Path) -> TriMesh {
    read_surface_labeled(path).unwrap().mesh
}

/// `baffle design` on p2 with the 55 wall vertices nearest to point 0 pushed out by
/// `height_mm`, into `dir`.
fn design_bumped_p2(data: &Path, height_mm: f64, dir: &Path) -> Output {
    let input = data.join("p2/design_input");
    let bumped = bump_wall(&read_mesh(&input.join("capped_ventricle.vtp")), 0, 55, height_mm, 2);
    let surface = dir.join("bumped.vtp");
    write_trimesh_vtp(&surface, &bumped).unwrap();
    let points = input.join("suture_points.mrk.json");
    baffle(&["design", "--surface", s(&surface), "--points", s(&points), "--bsa", "0.37", "--out", s(&dir.join("out"))])
}

#[test]
fn control_a_3_7_mm_bump_of_p2_designs() {
    // This aborted allocating 1.6 GB in the remesher (flat triangles split forever).
    let Some(data) = reference_data_if_present() else { return };
    let dir = temp_dir("bump-3.7");
    let out = design_bumped_p2(&data, 3.7, &dir);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("out/report.json")).unwrap()).unwrap();
    let area = report["baffle_area_mm2"].as_f64().unwrap();
    assert!((area - 245.6).abs() < 5.0, "baffle area {area} mm2 (unbumped p2: 245.6)");
}

#[test]
fn a_6_mm_bump_of_p2_is_a_named_error_not_an_out_of_memory_abort() {
    let Some(data) = reference_data_if_present() else { return };
    let dir = temp_dir("bump-6");
    let out = design_bumped_p2(&data, 6.0, &dir);
    // The bump folds the kept wall through itself; the remesher names where before it splits.
    assert_named_error(&out, &["remesh: the surface crosses itself near", "crossing pairs", "splitting long edges cannot converge"]);
    assert!(!dir.join("out/domain.vtp").exists(), "a failed design wrote its domain");
}

#[test]
fn a_tiny_remesh_edge_is_refused_up_front() {
    let out = design_phantom_with("remesh-edge", &["--remesh-edge-mm", "1e-6"]);
    assert_named_error(&out, &["remesh_edge_mm = 0.000001 is outside [0.05, 20]"]);
}

#[test]
fn a_nan_point_distance_does_not_switch_the_check_off() {
    let out = design_phantom_with("nan-distance", &["--max-point-distance-mm", "NaN"]);
    assert_named_error(&out, &["max_point_distance_mm = NaN is outside"]);
}

#[test]
fn zero_seam_samples_are_refused_by_name() {
    let out = design_phantom_with("seam-samples", &["--seam-samples", "0"]);
    assert_named_error(&out, &["seam_samples = 0 is outside [16, 100000]"]);
}

#[test]
fn one_label_for_both_caps_is_named() {
    let out = design_phantom_with("same-label", &["--vsd-label", "16"]);
    assert_named_error(&out, &["the VSD cap and the aortic cap have the same label 16"]);
}

#[test]
fn control_a_negative_z_score_after_a_space_is_accepted() {
    let out = design_phantom_with("z-score", &["--z-score", "-2"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
}

#[test]
fn a_bad_target_says_target_area_once() {
    let out = design_phantom_with("bsa", &["--bsa", "9"]);
    let stderr = assert_named_error(&out, &["target area: BSA (m2) = 9"]);
    assert_eq!(stderr.matches("target area:").count(), 1, "{stderr}");
}

#[test]
fn a_vtp_cut_before_its_closing_tags_is_truncated() {
    let (surface, points) = phantom_files("truncated");
    let text = std::fs::read_to_string(&surface).unwrap();
    let cut = text.rfind("</PolyData>").unwrap();
    let truncated = surface.with_file_name("truncated.vtp");
    std::fs::write(&truncated, &text[..cut]).unwrap();
    let out = baffle(&["design", "--surface", s(&truncated), "--points", s(&points), "--bsa", "0.37", "--out", s(&temp_dir("truncated-out"))]);
    assert_named_error(&out, &["truncated.vtp", "without </VTKFile>: it is truncated"]);
}

#[test]
fn two_disjoint_surfaces_are_named_as_such() {
    let (surface, points) = phantom_files("disjoint");
    let one = read_mesh(&surface);
    let mut two = one.clone();
    let offset = one.points.len() as u32;
    two.points.extend(one.points.iter().map(|p| p + baffle_core::Vec3::new(200.0, 0.0, 0.0)));
    two.triangles.extend(one.triangles.iter().map(|t| t.map(|v| v + offset)));
    two.face_ids.extend(one.face_ids.iter().map(|_| 2));
    let path = surface.with_file_name("two.vtp");
    write_trimesh_vtp(&path, &two).unwrap();
    let out = baffle(&["design", "--surface", s(&path), "--points", s(&points), "--bsa", "0.37", "--out", s(&temp_dir("disjoint-out"))]);
    assert_named_error(&out, &["the surface has 2 disconnected parts"]);
}

#[test]
fn a_mesh_edge_of_a_micrometre_is_refused_from_the_tetrahedron_estimate() {
    let (surface, _) = phantom_files("mesh-edge");
    let start = std::time::Instant::now();
    let out = baffle(&["mesh", "--surface", s(&surface), "--edge-length-mm", "1e-6", "--gmsh", "/nonexistent/gmsh", "--out", s(&temp_dir("mesh-out").join("m.vtu"))]);
    assert_named_error(&out, &["an edge length of 0.000001 mm would need about", "tetrahedra"]);
    assert!(start.elapsed().as_secs() < 30, "the refusal took {:?}", start.elapsed());
}

#[test]
fn zero_simulation_steps_are_refused() {
    let dir = temp_dir("steps");
    let case = dir.join("case.json");
    let example = baffle(&["simulate", "--help"]);
    let help = String::from_utf8_lossy(&example.stdout).to_string();
    let json = &help[help.find('{').unwrap()..=help.rfind('}').unwrap()];
    std::fs::write(&case, json).unwrap();
    let out = baffle(&["simulate", s(&case), "--steps", "0", "--out", s(&dir.join("out"))]);
    assert_named_error(&out, &["time.steps (or --steps) is 0"]);
}

#[test]
fn a_centerline_of_an_open_surface_is_refused() {
    let (surface, _) = phantom_files("open");
    let mut open = read_mesh(&surface);
    let wall = open.face_ids.iter().position(|&l| l == 2).unwrap();
    open.triangles.remove(wall);
    open.face_ids.remove(wall);
    let path = surface.with_file_name("open.vtp");
    write_trimesh_vtp(&path, &open).unwrap();
    let out = baffle(&["centerline", "--surface", s(&path), "--planes", "11,16", "--out", s(&temp_dir("open-out").join("c"))]);
    assert_named_error(&out, &["open.vtp", "the surface is open: 3 boundary edges"]);
}

#[test]
fn a_truncated_gzip_label_map_names_the_file() {
    let dir = temp_dir("nii");
    let path = dir.join("seg.nii.gz");
    // A gzip header and the start of a deflate stream, cut off.
    std::fs::write(&path, [0x1f, 0x8b, 0x08, 0x00, 0, 0, 0, 0, 0x00, 0x03, 0xed, 0xc1]).unwrap();
    let out = baffle(&["prepare", "--labelmap", s(&path), "--out", s(&dir.join("cv.vtp"))]);
    assert_named_error(&out, &["seg.nii.gz", "the gzip stream is truncated or corrupt"]);
}
