//! `baffle prepare` end to end on a synthetic heart written as segment files:
//! the capped ventricle and its report are written, and a missing segment is
//! named with a nonzero exit code.

use baffle_core::io::{read_surface_labeled, write_trimesh_vtp};
use baffle_core::Vec3;
use baffle_prepare::shapes::{capped_tube, uv_sphere};
use std::path::PathBuf;
use std::process::Command;

fn baffle(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_baffle")).args(args).output().expect("run baffle")
}

/// LV and RV spheres overlapping, an aorta tube leaving the RV.
fn synthetic_segmentations(name: &str, with_aorta: bool) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("baffle-cli-prepare-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    write_trimesh_vtp(&dir.join("LV.vtp"), &uv_sphere(Vec3::zeros(), 10.0, 32, 64)).unwrap();
    write_trimesh_vtp(&dir.join("RV.vtp"), &uv_sphere(Vec3::new(16.0, 0.0, 0.0), 9.0, 32, 64)).unwrap();
    if with_aorta {
        let tube = capped_tube(Vec3::new(16.0, 0.0, 4.0), Vec3::new(16.0, 0.0, 25.0), 4.0, 12, 48);
        write_trimesh_vtp(&dir.join("aorta.vtp"), &tube).unwrap();
    }
    dir
}

#[test]
fn prepare_writes_a_labelled_capped_ventricle_and_its_report() {
    let dir = synthetic_segmentations("ok", true);
    let out = dir.join("out/capped_ventricle.vtp");
    let run = baffle(&["prepare", "--segmentations", dir.to_str().unwrap(), "--out", out.to_str().unwrap(), "--closing-radius-mm", "0"]);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let surface = read_surface_labeled(&out).unwrap();
    assert!(surface.has_model_face_id);
    let mut labels = surface.mesh.face_ids.clone();
    labels.sort_unstable();
    labels.dedup();
    assert_eq!(labels, vec![2, 11, 16]);
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("out/capped_ventricle-report.json")).unwrap()).unwrap();
    assert!(report["vsd_cap"]["area_mm2"].as_f64().unwrap() > 0.0);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_missing_segment_is_named() {
    let dir = synthetic_segmentations("missing", false);
    let out = dir.join("capped.vtp");
    let run = baffle(&["prepare", "--segmentations", dir.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert!(!run.status.success());
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(err.contains("aorta") && err.contains("aorta.vtp"), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}
