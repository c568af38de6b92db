//! A hand-made box of tets (no gmsh) and the paper-default case on it.
#![allow(dead_code)]

use std::collections::{BTreeMap, HashMap};
use std::path::PathBuf;

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
