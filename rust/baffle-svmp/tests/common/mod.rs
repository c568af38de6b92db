//! A hand-made box of tets (no gmsh), the paper-default case on it, and a stand-in
//! svMultiPhysics with recorded outputs. Also compiled into baffle-cli's tests (through
//! `#[path]`), so paths to this crate's test data go through [`test_data`].
#![allow(dead_code)]

use std::collections::{BTreeMap, HashMap};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use baffle_cfd::{CaseSettings, Outlet, Waveform};
use baffle_core::Vec3;
use baffle_mesh::tetmesh::{face_key, tet_faces, tet_signed_volume_mm3};
use baffle_mesh::{FaceSet, TetMesh};
use baffle_svmp::ExportOptions;

pub const WALL_A: i32 = 1;
pub const INLET: i32 = 2;
pub const OUTLET: i32 = 3;
pub const WALL_B: i32 = 4;
pub const PLANE_1: i32 = 10;
pub const PLANE_2: i32 = 11;
/// Cube edge (mm) and cube counts of the box; planes at z = 2 h and 4 h.
pub const H_MM: f64 = 2.5;
pub const N: [usize; 3] = [2, 2, 6];

/// A 5 x 5 x 15 mm box of 144 Kuhn tets: inlet z = 0, outlet z = 15, walls split in two
/// faces, and two interior planes wound along +z.
pub fn box_mesh() -> TetMesh {
    let [nx, ny, nz] = N;
    let index = |i: usize, j: usize, k: usize| (i + (nx + 1) * (j + (ny + 1) * k)) as u32;
    let mut points_mm = Vec::new();
    for k in 0..=nz {
        for j in 0..=ny {
            for i in 0..=nx {
                points_mm.push(Vec3::new(i as f64 * H_MM, j as f64 * H_MM, k as f64 * H_MM));
            }
        }
    }
    let mut tets = Vec::new();
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                for axes in [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]] {
                    let mut c = [i, j, k];
                    let mut tet = [index(c[0], c[1], c[2]); 4];
                    for (n, &axis) in axes.iter().enumerate() {
                        c[axis] += 1;
                        tet[n + 1] = index(c[0], c[1], c[2]);
                    }
                    if tet_signed_volume_mm3(&tet.map(|v| points_mm[v as usize])) < 0.0 {
                        tet.swap(2, 3);
                    }
                    tets.push(tet);
                }
            }
        }
    }
    let faces = box_faces(&points_mm, &tets);
    let mesh = TetMesh { points_mm, tets, faces };
    mesh.validate().expect("box mesh is valid");
    mesh
}

fn box_faces(points: &[Vec3], tets: &[[u32; 4]]) -> Vec<FaceSet> {
    let mut uses: HashMap<[u32; 3], (usize, [u32; 3])> = HashMap::new();
    for tet in tets {
        for f in tet_faces(tet) {
            uses.entry(face_key(&f)).or_insert((0, f)).0 += 1;
        }
    }
    let length = N[2] as f64 * H_MM;
    let mut sets: BTreeMap<i32, FaceSet> = BTreeMap::new();
    let mut add = |id: i32, tri: [u32; 3], interior: bool| {
        sets.entry(id).or_insert(FaceSet { id, triangles: Vec::new(), interior }).triangles.push(tri);
    };
    let mut keys: Vec<_> = uses.into_iter().collect();
    keys.sort();
    for (_, (count, tri)) in keys {
        let p = tri.map(|v| points[v as usize]);
        let centroid = (p[0] + p[1] + p[2]) / 3.0;
        let flat_z = p.iter().all(|q| (q.z - p[0].z).abs() < 1e-12);
        if count == 2 {
            let plane = if flat_z && (p[0].z - 2.0 * H_MM).abs() < 1e-12 {
                PLANE_1
            } else if flat_z && (p[0].z - 4.0 * H_MM).abs() < 1e-12 {
                PLANE_2
            } else {
                continue;
            };
            let up = (p[1] - p[0]).cross(&(p[2] - p[0])).z > 0.0;
            add(plane, if up { tri } else { [tri[0], tri[2], tri[1]] }, true);
        } else if centroid.z < 1e-12 {
            add(INLET, tri, false);
        } else if centroid.z > length - 1e-12 {
            add(OUTLET, tri, false);
        } else if centroid.x < 1e-12 || centroid.y < 1e-12 {
            add(WALL_A, tri, false);
        } else {
            add(WALL_B, tri, false);
        }
    }
    sets.into_values().collect()
}

/// Paper defaults (p2's mean flow and resistance, Table 4) on the box.
pub fn settings() -> CaseSettings {
    let inflow = Waveform::default_for_mean(21.46).unwrap();
    CaseSettings::new(INLET, inflow, vec![Outlet { face_id: OUTLET, resistance_dyn_s_cm5: 5467.0 }])
}

pub fn options() -> ExportOptions {
    let names = [(WALL_A, "wall_a"), (INLET, "inflow"), (OUTLET, "outflow"), (WALL_B, "wall_b"), (PLANE_1, "plane_1"), (PLANE_2, "plane_2")];
    let names = names.into_iter().map(|(id, n)| (id, n.to_string())).collect();
    ExportOptions::new(names, vec![PLANE_1, PLANE_2])
}

/// A fresh directory under the target's tmp dir.
pub fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("baffle-svmp-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `rust/baffle-svmp/tests/data`, from this crate's tests or a sibling crate's.
pub fn test_data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../baffle-svmp/tests/data")
}

/// `mpiexec --version` of Open MPI 4 (Debian 12's) and of MPICH.
pub const OPEN_MPI_VERSION: &str = "mpiexec (OpenRTE) 4.1.4";
pub const MPICH_VERSION: &str = "HYDRA build details:";

/// How the stand-in engine of `tests/data/standin` behaves.
pub struct StandIn<'a> {
    /// Time steps in its log (default: all of solver.xml's).
    pub steps: Option<usize>,
    pub exit_code: i32,
    /// A directory of recorded svMultiPhysics outputs it copies into the results folder.
    pub recorded: Option<&'a Path>,
    /// What its mpiexec answers to `--version`.
    pub mpi_version: &'a str,
    /// From this time step on, its log shows the steps stopped at the Newton cap with a
    /// linear solve that did not converge (output.cpp's "!" marks and WARNING).
    pub unconverged_from_step: Option<usize>,
}

impl Default for StandIn<'_> {
    fn default() -> Self {
        StandIn { steps: None, exit_code: 0, recorded: None, mpi_version: OPEN_MPI_VERSION, unconverged_from_step: None }
    }
}

/// A bin directory with `mpiexec` and `svMultiPhysics`: wrappers that set the stand-in's
/// parameters and run `tests/data/standin/{mpiexec,svmultiphysics}`.
pub fn standin_bin(name: &str, standin: &StandIn) -> PathBuf {
    let bin = scratch(name).join("bin");
    std::fs::create_dir_all(&bin).unwrap();
    let scripts = test_data().join("standin");
    let mpiexec = format!("STANDIN_MPI_VERSION='{}'", standin.mpi_version);
    write_wrapper(&bin.join("mpiexec"), &mpiexec, &scripts.join("mpiexec"));
    let mut svmp = format!("STANDIN_EXIT={}", standin.exit_code);
    if let Some(steps) = standin.steps {
        let _ = write!(svmp, " STANDIN_STEPS={steps}");
    }
    if let Some(step) = standin.unconverged_from_step {
        let _ = write!(svmp, " STANDIN_UNCONVERGED_FROM={step}");
    }
    if let Some(dir) = standin.recorded {
        let _ = write!(svmp, " STANDIN_RECORDED='{}'", dir.display());
    }
    write_wrapper(&bin.join("svMultiPhysics"), &svmp, &scripts.join("svmultiphysics"));
    bin
}

fn write_wrapper(path: &Path, env: &str, script: &Path) {
    std::fs::write(path, format!("#!/bin/sh\nexport {env}\nexec '{}' \"$@\"\n", script.display())).unwrap();
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
}

/// Recorded `B_NS_Pressure_average.txt` and `B_NS_Velocity_flux.txt` in svMultiPhysics'
/// current layout (txt.cpp): '#' comments, "face areas:", a "step time names" header, then
/// rows "step time values" in `%d %.10e` / `%.10e`, for steps 1..=steps at t = step dt.
/// `values(t)` gives (pressure dyn/cm^2, outward flux mL/s) per column.
pub fn write_boundary_files(
    dir: &Path,
    columns: &[&str],
    dt_s: f64,
    steps: usize,
    values: impl Fn(f64) -> (Vec<f64>, Vec<f64>),
) {
    std::fs::create_dir_all(dir).unwrap();
    for (file, which) in [("B_NS_Pressure_average.txt", 0), ("B_NS_Velocity_flux.txt", 1)] {
        let mut text = String::from(
            "# svMultiPhysics boundary integral results file. \n# Format \n# ------ \n\
             # face areas: [list of mesh face areas]  \n# step time [list of mesh face names] \n",
        );
        text.push_str("face areas: ");
        columns.iter().for_each(|_| text.push_str(" 2.500e-01 "));
        text.push_str("\nstep   time  ");
        columns.iter().for_each(|c| text.push_str(&format!(" {c} ")));
        text.push('\n');
        for step in 1..=steps {
            let t = step as f64 * dt_s;
            let (p, q) = values(t);
            let row = if which == 0 { p } else { q };
            assert_eq!(row.len(), columns.len());
            let _ = write!(text, " {step}   {t:.10e} ");
            row.iter().for_each(|v| text.push_str(&format!(" {v:.10e} ")));
            text.push('\n');
        }
        std::fs::write(dir.join(file), text).unwrap();
    }
}

/// The value a recorded `%.10e` field reads back as.
pub fn as_recorded(v: f64) -> f64 {
    format!("{v:.10e}").parse().unwrap()
}
