//! The `mesh-complete/` directory: the volume mesh and one `.vtp` per face in centimetres,
//! with the id arrays svMultiPhysics needs (see [`crate::format`] for their rules).

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

use baffle_core::io::{write_vtp, DataArray, PolyData, MODEL_FACE_ID};
use baffle_core::geometry::spatial::Aabb;
use baffle_core::Vec3;
use baffle_mesh::tetmesh::face_key;
use baffle_mesh::{write_vtu, FaceSet, TetMesh};

use crate::format::{
    EXTERIOR_FILE, GLOBAL_ELEMENT_ID, GLOBAL_NODE_ID, MESH_DIR, MODEL_REGION_ID, SURFACES_DIR, VOLUME_FILE,
    WALLS_FILE,
};
use crate::SvmpError;

pub const CM_PER_MM: f64 = 0.1;

/// The mesh with every coordinate converted to cm once, so the volume file and every face
/// file hold the very same `f64` bits for a node, and its tetrahedra in slabs along the
/// longest axis ([`in_slabs`]).
pub(crate) fn mesh_in_cm(mesh: &TetMesh) -> TetMesh {
    let points_cm: Vec<Vec3> = mesh.points_mm.iter().map(|p| p * CM_PER_MM).collect();
    let tets = in_slabs(&points_cm, &mesh.tets);
    TetMesh { points_mm: points_cm, tets, faces: mesh.faces.clone() }
}

/// The tetrahedra sorted by their centroid along the mesh's longest extent. svMultiPhysics
/// hands rank k the k-th block of elements in file order before ParMETIS partitions them;
/// with p2's published SimVascular mesh in its own order, each rank's block was scattered
/// over the domain and ParMETIS_V3_PartMeshKway recursed in Global_Partition without end
/// at 2 ranks (no output after 5 min; sorted, 3 steps in 20 s). Node numbers, and so every
/// nodal result read back, are unchanged.
fn in_slabs(points: &[Vec3], tets: &[[u32; 4]]) -> Vec<[u32; 4]> {
    let bounds = Aabb::from_points(points);
    let axis = (bounds.max - bounds.min).imax();
    let centroid = |t: &[u32; 4]| t.iter().map(|&i| points[i as usize][axis]).sum::<f64>();
    let mut sorted = tets.to_vec();
    sorted.sort_by(|a, b| centroid(a).total_cmp(&centroid(b)));
    sorted
}

/// Paths of the written mesh files, relative to the case directory.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshFiles {
    pub volume: PathBuf,
    pub exterior: PathBuf,
    pub walls: PathBuf,
    /// (face id, face name, path) in `mesh.faces` order.
    pub faces: Vec<(i32, String, PathBuf)>,
}

/// Write `mesh-complete/` under `dir` for a validated mesh already in cm. `names` maps
/// every face id to its file stem; `wall_ids` are the faces merged into `walls_combined`.
pub(crate) fn write_mesh_complete(
    dir: &Path,
    mesh_cm: &TetMesh,
    names: &BTreeMap<i32, String>,
    wall_ids: &[i32],
) -> Result<MeshFiles, SvmpError> {
    let surfaces = dir.join(MESH_DIR).join(SURFACES_DIR);
    std::fs::create_dir_all(&surfaces).map_err(|e| SvmpError::io(&surfaces, e))?;
    let volume = Path::new(MESH_DIR).join(VOLUME_FILE);
    write_volume(&dir.join(&volume), mesh_cm)?;
    let elements = FaceElements::new(mesh_cm);
    let mut faces = Vec::new();
    for set in &mesh_cm.faces {
        let name = &names[&set.id];
        let path = Path::new(MESH_DIR).join(SURFACES_DIR).join(format!("{name}.vtp"));
        write_vtp(&dir.join(&path), &face_polydata(mesh_cm, &[set], &elements)?)?;
        faces.push((set.id, name.clone(), path));
    }
    let boundary: Vec<&FaceSet> = mesh_cm.faces.iter().filter(|f| !f.interior).collect();
    let walls: Vec<&FaceSet> = boundary.iter().copied().filter(|f| wall_ids.contains(&f.id)).collect();
    let exterior = Path::new(MESH_DIR).join(EXTERIOR_FILE);
    write_vtp(&dir.join(&exterior), &face_polydata(mesh_cm, &boundary, &elements)?)?;
    let walls_path = Path::new(MESH_DIR).join(WALLS_FILE);
    write_vtp(&dir.join(&walls_path), &face_polydata(mesh_cm, &walls, &elements)?)?;
    Ok(MeshFiles { volume, exterior, walls: walls_path, faces })
}

fn write_volume(path: &Path, mesh_cm: &TetMesh) -> Result<(), SvmpError> {
    let node_ids = one_based(mesh_cm.points_mm.len(), path)?;
    let element_ids = one_based(mesh_cm.tets.len(), path)?;
    let regions = vec![1; mesh_cm.tets.len()];
    write_vtu(
        path,
        mesh_cm,
        &[DataArray::i32(GLOBAL_NODE_ID, node_ids)],
        &[DataArray::i32(GLOBAL_ELEMENT_ID, element_ids), DataArray::i32(MODEL_REGION_ID, regions)],
    )?;
    Ok(())
}

/// 1, 2, ..., n as Int32; errs when n does not fit.
fn one_based(n: usize, path: &Path) -> Result<Vec<i32>, SvmpError> {
    if n >= i32::MAX as usize {
        return Err(SvmpError::io(path, format!("{n} ids do not fit the Int32 id arrays")));
    }
    Ok((1..=n as i32).collect())
}

/// For every tet face, the tets having it, to find each triangle's `GlobalElementID`.
pub(crate) struct FaceElements {
    tets_of_face: HashMap<[u32; 3], Vec<u32>>,
}

impl FaceElements {
    pub(crate) fn new(mesh: &TetMesh) -> Self {
        FaceElements { tets_of_face: mesh.face_tets() }
    }

    /// The 0-based tet a triangle of `set` belongs to: the only one for a boundary face;
    /// for an interior face the one the triangle's winding normal points out of, so
    /// svMultiPhysics' flux through the plane is along the winding normal.
    pub(crate) fn element_of(&self, mesh: &TetMesh, set: &FaceSet, tri: &[u32; 3]) -> Result<u32, SvmpError> {
        let tets = self.tets_of_face.get(&face_key(tri)).map(Vec::as_slice).unwrap_or(&[]);
        let bad = |what: &str| {
            SvmpError::InvalidCase(format!("triangle {tri:?} of face {} {what}", set.id))
        };
        match (set.interior, tets) {
            (false, [t]) => Ok(*t),
            (true, [a, b]) => {
                let out_of_a = winding_points_out_of(mesh, tri, *a);
                if out_of_a == winding_points_out_of(mesh, tri, *b) {
                    return Err(bad("has both of its tets on the same side"));
                }
                Ok(if out_of_a { *a } else { *b })
            }
            _ => Err(bad(&format!("is the face of {} tets", tets.len()))),
        }
    }
}

/// Whether the normal (b - a) x (c - a) of `tri` points away from tet `t`'s other corner.
fn winding_points_out_of(mesh: &TetMesh, tri: &[u32; 3], t: u32) -> bool {
    let tet = mesh.tets[t as usize];
    let apex = tet.iter().copied().find(|i| !tri.contains(i)).unwrap_or(tet[0]);
    let [a, b, c] = tri.map(|i| mesh.points_mm[i as usize]);
    (b - a).cross(&(c - a)).dot(&(mesh.points_mm[apex as usize] - a)) < 0.0
}

/// The triangles of `sets` as PolyData on their own points (numbered in order of first
/// use), with point `GlobalNodeID` and cell `GlobalElementID` and `ModelFaceID`.
pub(crate) fn face_polydata(
    mesh_cm: &TetMesh,
    sets: &[&FaceSet],
    elements: &FaceElements,
) -> Result<PolyData, SvmpError> {
    let mut local: HashMap<u32, u32> = HashMap::new();
    let (mut points, mut node_ids): (Vec<Vec3>, Vec<i32>) = (Vec::new(), Vec::new());
    let (mut polys, mut element_ids, mut face_ids) = (Vec::new(), Vec::new(), Vec::new());
    for set in sets {
        for tri in &set.triangles {
            let poly = tri.map(|v| {
                *local.entry(v).or_insert_with(|| {
                    points.push(mesh_cm.points_mm[v as usize]);
                    node_ids.push(v as i32 + 1);
                    points.len() as u32 - 1
                })
            });
            polys.push(poly.to_vec());
            element_ids.push(elements.element_of(mesh_cm, set, tri)? as i32 + 1);
            face_ids.push(set.id);
        }
    }
    Ok(PolyData {
        points,
        polys,
        lines: Vec::new(),
        point_data: vec![DataArray::i32(GLOBAL_NODE_ID, node_ids)],
        cell_data: vec![DataArray::i32(GLOBAL_ELEMENT_ID, element_ids), DataArray::i32(MODEL_FACE_ID, face_ids)],
    })
}
