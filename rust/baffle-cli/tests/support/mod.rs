//! Helpers shared by the `baffle simulate` tests of both engines.
#![allow(dead_code)]

use std::io::{BufRead, BufReader, Read};
use std::process::{Command, ExitStatus, Stdio};

/// Start `command` with piped output, wait for `tags` Slicer progress tags on its stdout,
/// send SIGTERM (not SIGKILL: the run must stop cleanly), and return its exit status once
/// it has written everything.
pub fn sigterm_after_progress_tags(command: &mut Command, tags: usize) -> ExitStatus {
    // Tags are printed only when asked for (as Slicer does).
    let mut child = command.arg("--progress-tags").stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().expect("start baffle");
    let mut stdout = BufReader::new(child.stdout.take().unwrap());
    let (mut seen, mut line) = (0, String::new());
    while seen < tags {
        line.clear();
        assert!(stdout.read_line(&mut line).unwrap() > 0, "baffle simulate ended early");
        seen += usize::from(line.contains("<filter-progress>"));
    }
    assert_eq!(unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGTERM) }, 0);
    let mut rest = String::new();
    stdout.read_to_string(&mut rest).unwrap();
    child.wait().unwrap()
}

/// Write `mesh` (cm) as `baffle mesh` writes its output, in mm: `<dir>/mesh.vtu` and
/// `<dir>/mesh-faces.vtp`, so a case with `"units": "mm"` reads it through the CLI's own
/// reader. Faces with ids from `baffle_cfd::test_meshes::PLANE` up are interior planes.
pub fn write_flow_mesh(dir: &std::path::Path, mesh: &baffle_cfd::FlowMesh) {
    use baffle_mesh::{FaceSet, TetMesh};
    let faces = mesh.faces.iter().map(|f| FaceSet { id: f.id, triangles: f.triangles.clone(), interior: f.id >= baffle_cfd::test_meshes::PLANE });
    let tet_mesh = TetMesh {
        points_mm: mesh.points_cm.iter().map(|p| baffle_core::Vec3::new(10.0 * p[0], 10.0 * p[1], 10.0 * p[2])).collect(),
        tets: mesh.tets.clone(),
        faces: faces.collect(),
    };
    baffle_mesh::write_vtu(&dir.join("mesh.vtu"), &tet_mesh, &[], &[]).expect("write mesh.vtu");
    baffle_mesh::write_faces_vtp(&dir.join("mesh-faces.vtp"), &tet_mesh).expect("write mesh-faces.vtp");
}
