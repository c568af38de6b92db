//! `.vtu` (VTK XML UnstructuredGrid) I/O with vtkio, face `.vtp` output with baffle-core's
//! writer, and SimVascular-style `.vtu` + face `.vtp` sets (the paper's published meshes).

use crate::error::MeshError;
use crate::tetmesh::{tet_signed_volume_mm3, FaceSet, TetMesh};
use baffle_core::io::{read_polydata, write_vtp, ArrayValues, DataArray, PolyData, MODEL_FACE_ID};
use baffle_core::Vec3;
use std::collections::BTreeMap;
use std::path::Path;
use vtkio::model::{
    Attribute, Attributes, ByteOrder, CellType, Cells, DataSet, IOBuffer,
    UnstructuredGridPiece, Version, VertexNumbers, Vtk,
};

/// SimVascular's point array of 1-based volume node ids on face files.
pub const GLOBAL_NODE_ID: &str = "GlobalNodeID";
/// Cell array on face `.vtp` files marking interior (measurement-plane) faces with 1.
pub const INTERIOR_FACE: &str = "InteriorFace";

/// A `.vtu` as read: the tets (no face sets), and its numeric point and cell arrays.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VtuData {
    pub mesh: TetMesh,
    pub point_data: Vec<DataArray>,
    pub cell_data: Vec<DataArray>,
}

/// Write `mesh`'s points and tets as `.vtu` (vtkio; Float64 points), with the given
/// arrays (one tuple per point / per tet). Written atomically (`baffle_core::io::write_atomic`).
pub fn write_vtu(
    path: &Path,
    mesh: &TetMesh,
    point_data: &[DataArray],
    cell_data: &[DataArray],
) -> Result<(), MeshError> {
    check_arrays(path, point_data, mesh.points_mm.len(), "point")?;
    check_arrays(path, cell_data, mesh.tets.len(), "cell")?;
    let piece = UnstructuredGridPiece {
        points: IOBuffer::F64(
            mesh.points_mm
                .iter()
                .flat_map(|p| [p.x, p.y, p.z])
                .collect(),
        ),
        cells: Cells {
            cell_verts: VertexNumbers::XML {
                connectivity: mesh.tets.iter().flatten().map(|&i| u64::from(i)).collect(),
                offsets: (1..=mesh.tets.len() as u64).map(|k| 4 * k).collect(),
            },
            types: vec![CellType::Tetra; mesh.tets.len()],
        },
        data: Attributes {
            point: point_data.iter().map(to_attribute).collect(),
            cell: cell_data.iter().map(to_attribute).collect(),
        },
    };
    let vtk = Vtk {
        version: Version::new_xml(1, 0),
        byte_order: ByteOrder::LittleEndian,
        title: String::new(),
        file_path: None,
        data: DataSet::inline(piece),
    };
    let mut bytes = Vec::new();
    vtk.write_xml(&mut bytes)
        .map_err(|e| MeshError::file(path, format!("vtkio could not write it: {e}")))?;
    baffle_core::io::write_atomic(path, &bytes).map_err(|e| MeshError::file(path, e.to_string()))
}

fn check_arrays(
    path: &Path,
    arrays: &[DataArray],
    expected: usize,
    what: &str,
) -> Result<(), MeshError> {
    for a in arrays {
        if a.values.num_tuples() != expected || a.values.components() == 0 {
            return Err(MeshError::file(
                path,
                format!(
                    "{what} array '{}' has {} tuples, expected {expected}",
                    a.name,
                    a.values.num_tuples()
                ),
            ));
        }
    }
    Ok(())
}

fn to_attribute(a: &DataArray) -> Attribute {
    match &a.values {
        ArrayValues::I32(v) => {
            Attribute::scalars(a.name.clone(), 1).with_data(IOBuffer::I32(v.clone()))
        }
        ArrayValues::F64 { components, values } => {
            Attribute::generic(a.name.clone(), *components as u32)
                .with_data(IOBuffer::F64(values.clone()))
        }
    }
}

/// Write the face sets as one `.vtp` in SimVascular style: the used points with point
/// array `GlobalNodeID` (1-based volume node ids), cell arrays `ModelFaceID` and
/// `InteriorFace` (1 on interior measurement planes).
pub fn write_faces_vtp(path: &Path, mesh: &TetMesh) -> Result<(), MeshError> {
    let mut used: BTreeMap<u32, u32> = BTreeMap::new();
    let all = mesh.faces.iter().flat_map(|f| f.triangles.iter().flatten());
    for &i in all {
        let next = used.len() as u32;
        used.entry(i).or_insert(next);
    }
    let mut points = vec![Vec3::zeros(); used.len()];
    let mut global_ids = vec![0i32; used.len()];
    for (&volume_index, &local) in &used {
        points[local as usize] = mesh.points_mm[volume_index as usize];
        global_ids[local as usize] = volume_index as i32 + 1;
    }
    let (mut polys, mut ids, mut interior) = (Vec::new(), Vec::new(), Vec::new());
    for set in &mesh.faces {
        polys.extend(
            set.triangles
                .iter()
                .map(|t| t.iter().map(|i| used[i]).collect::<Vec<u32>>()),
        );
        ids.extend(std::iter::repeat_n(set.id, set.triangles.len()));
        interior.extend(std::iter::repeat_n(
            i32::from(set.interior),
            set.triangles.len(),
        ));
    }
    let data = PolyData {
        points,
        polys,
        lines: Vec::new(),
        point_data: vec![DataArray::i32(GLOBAL_NODE_ID, global_ids)],
        cell_data: vec![
            DataArray::i32(MODEL_FACE_ID, ids),
            DataArray::i32(INTERIOR_FACE, interior),
        ],
    };
    Ok(write_vtp(path, &data)?)
}

/// Read a `.vtu` of linear tets (`baffle_core::io::read_vtu`, coordinates as stored). Any
/// other cell type is an error naming the cell; a vtkio panic is turned into an error.
pub fn read_vtu(path: &Path) -> Result<VtuData, MeshError> {
    let grid = baffle_core::io::read_vtu(path)?;
    Ok(VtuData {
        mesh: TetMesh {
            points_mm: grid.points,
            tets: grid.tets,
            faces: Vec::new(),
        },
        point_data: grid.point_data,
        cell_data: grid.cell_data,
    })
}

/// Read a SimVascular-style mesh: `vtu_path` (tets) and `surface_vtp_path` (its boundary
/// triangles with cell `ModelFaceID` and point `GlobalNodeID` = 1-based volume node id),
/// coordinates multiplied by `scale_to_mm` (10 for the paper's cm files). Tets are kept
/// as stored and must be positively oriented; boundary triangles are wound outward.
pub fn read_simvascular(
    vtu_path: &Path,
    surface_vtp_path: &Path,
    scale_to_mm: f64,
) -> Result<TetMesh, MeshError> {
    if !(scale_to_mm.is_finite() && scale_to_mm > 0.0) {
        return Err(MeshError::InvalidInput(format!(
            "scale to mm must be positive, got {scale_to_mm}"
        )));
    }
    let mut mesh = read_vtu(vtu_path)?.mesh;
    mesh.points_mm.iter_mut().for_each(|p| *p *= scale_to_mm);
    mesh.faces = simvascular_faces(surface_vtp_path, mesh.points_mm.len())?;
    if let Some(t) =
        (0..mesh.tets.len()).find(|&t| tet_signed_volume_mm3(&mesh.tet_points(t)) <= 0.0)
    {
        return Err(MeshError::file(
            vtu_path,
            format!("tet {t} {:?} is inverted or degenerate", mesh.tets[t]),
        ));
    }
    mesh.orient_boundary_outward()?;
    mesh.validate()?;
    Ok(mesh)
}

/// Face sets from a SimVascular surface: triangles mapped to volume nodes via `GlobalNodeID`.
fn simvascular_faces(path: &Path, num_volume_points: usize) -> Result<Vec<FaceSet>, MeshError> {
    let surface = read_polydata(path)?;
    let global = named_i32(path, &surface.point_data, GLOBAL_NODE_ID)?;
    let labels = named_i32(path, &surface.cell_data, MODEL_FACE_ID)?;
    let volume_index = |local: u32| -> Result<u32, MeshError> {
        let id = *global.get(local as usize).ok_or_else(|| {
            MeshError::file(
                path,
                format!("polygon uses point {local} beyond the point array"),
            )
        })?;
        if id < 1 || id as usize > num_volume_points {
            return Err(MeshError::file(
                path,
                format!("point {local} has {GLOBAL_NODE_ID} {id}, outside 1..={num_volume_points}"),
            ));
        }
        Ok(id as u32 - 1)
    };
    let mut sets: BTreeMap<i32, Vec<[u32; 3]>> = BTreeMap::new();
    for (c, poly) in surface.polys.iter().enumerate() {
        if poly.len() != 3 {
            return Err(MeshError::file(
                path,
                format!("polygon {c} has {} points; triangles expected", poly.len()),
            ));
        }
        let tri = [
            volume_index(poly[0])?,
            volume_index(poly[1])?,
            volume_index(poly[2])?,
        ];
        sets.entry(labels[c]).or_default().push(tri);
    }
    Ok(sets
        .into_iter()
        .map(|(id, triangles)| FaceSet {
            id,
            triangles,
            interior: false,
        })
        .collect())
}

fn named_i32<'a>(path: &Path, arrays: &'a [DataArray], name: &str) -> Result<&'a [i32], MeshError> {
    arrays
        .iter()
        .find(|a| a.name == name)
        .and_then(|a| a.as_i32())
        .ok_or_else(|| MeshError::file(path, format!("has no Int32 array '{name}'")))
}
