//! The one `.vtu` reader: a VTK XML UnstructuredGrid of linear tetrahedra, read with vtkio
//! (the volume meshes `baffle mesh` writes, the solutions `baffle simulate` writes, and
//! SimVascular's volumes; none holds the empty zlib arrays that make vtkio 0.7.0-rc2
//! panic on `.vtp` files, and a vtkio panic is turned into an error naming the file).

use super::error::{malformed, IoError, IoErrorKind};
use super::polydata::DataArray;
use crate::geometry::mesh::Vec3;
use std::path::Path;
use vtkio::model::{Attribute, CellType, Cells, DataSet, IOBuffer, Piece, UnstructuredGridPiece, Vtk};

/// A `.vtu` of linear tetrahedra as stored: points (file units), tets, and its numeric
/// point and cell arrays.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TetGrid {
    pub points: Vec<Vec3>,
    pub tets: Vec<[u32; 4]>,
    pub point_data: Vec<DataArray>,
    pub cell_data: Vec<DataArray>,
}

impl TetGrid {
    /// The point array `name`, when it holds one Int32 value a point.
    pub fn point_i32(&self, name: &str) -> Option<&[i32]> {
        self.point_data.iter().find(|a| a.name == name).and_then(|a| a.as_i32())
    }
}

/// Read a `.vtu` of linear tets (coordinates as stored). Any other cell type, a point
/// outside the points, a non-finite coordinate or more than one piece is an error naming
/// the file and the cell or point.
pub fn read_vtu(path: &Path) -> Result<TetGrid, IoError> {
    let at = |kind: IoErrorKind| IoError::new(path, kind);
    let vtk = import_vtk(path).map_err(at)?;
    let piece = unstructured_piece(vtk).map_err(at)?;
    let points = points_of(&piece.points).map_err(at)?;
    let tets = tets_of(piece.cells, points.len()).map_err(at)?;
    let point_data = piece.data.point.iter().filter_map(from_attribute).collect();
    let cell_data = piece.data.cell.iter().filter_map(from_attribute).collect();
    Ok(TetGrid { points, tets, point_data, cell_data })
}

fn import_vtk(path: &Path) -> Result<Vtk, IoErrorKind> {
    if !path.is_file() {
        return Err(IoErrorKind::NotFound);
    }
    let owned = path.to_path_buf();
    match std::panic::catch_unwind(move || Vtk::import(&owned)) {
        Ok(Ok(vtk)) => Ok(vtk),
        Ok(Err(e)) => Err(malformed(format!("vtkio could not read it: {e}"))),
        Err(panic) => {
            let msg = panic.downcast_ref::<String>().cloned().or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()));
            Err(malformed(format!("vtkio panicked reading it: {}", msg.unwrap_or_default())))
        }
    }
}

fn unstructured_piece(mut vtk: Vtk) -> Result<UnstructuredGridPiece, IoErrorKind> {
    vtk.load_all_pieces().map_err(|e| malformed(format!("vtkio could not load its pieces: {e}")))?;
    let DataSet::UnstructuredGrid { mut pieces, .. } = vtk.data else {
        return Err(IoErrorKind::Unsupported("not an UnstructuredGrid".into()));
    };
    if pieces.len() != 1 {
        return Err(IoErrorKind::Unsupported(format!("{} pieces; one is supported", pieces.len())));
    }
    match pieces.remove(0) {
        Piece::Inline(p) => Ok(*p),
        _ => Err(malformed("piece data is not inline")),
    }
}

fn points_of(buffer: &IOBuffer) -> Result<Vec<Vec3>, IoErrorKind> {
    let coords: Vec<f64> = buffer.cast_into().ok_or_else(|| malformed("points are not numeric"))?;
    if !coords.len().is_multiple_of(3) {
        return Err(malformed(format!("{} point coordinates is not a multiple of 3", coords.len())));
    }
    if let Some(k) = coords.iter().position(|c| !c.is_finite()) {
        return Err(IoErrorKind::NonFiniteCoordinate { point: k / 3, value: coords[k] });
    }
    Ok(coords.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect())
}

fn tets_of(cells: Cells, num_points: usize) -> Result<Vec<[u32; 4]>, IoErrorKind> {
    if let Some(c) = cells.types.iter().position(|t| *t != CellType::Tetra) {
        return Err(IoErrorKind::Unsupported(format!("cell {c} is a {:?}; only linear tets are supported", cells.types[c])));
    }
    let (connectivity, offsets) = cells.cell_verts.into_xml();
    if offsets.len() != cells.types.len() || connectivity.len() != 4 * offsets.len() {
        return Err(malformed("cell connectivity does not hold 4 points per cell"));
    }
    let mut tets = Vec::with_capacity(offsets.len());
    for (c, chunk) in connectivity.chunks_exact(4).enumerate() {
        if offsets[c] != 4 * (c as u64 + 1) {
            return Err(malformed(format!("cell {c} has offset {}, expected {}", offsets[c], 4 * (c + 1))));
        }
        if let Some(&i) = chunk.iter().find(|&&i| i as usize >= num_points) {
            return Err(IoErrorKind::IndexOutOfRange { cell: format!("cell {c}"), index: i, num_points });
        }
        tets.push([chunk[0] as u32, chunk[1] as u32, chunk[2] as u32, chunk[3] as u32]);
    }
    Ok(tets)
}

/// A vtkio array as a [`DataArray`]: floats as f64, single-component integers as i32
/// (dropped when a value does not fit), other integers as f64.
fn from_attribute(a: &Attribute) -> Option<DataArray> {
    let Attribute::DataArray(d) = a else {
        return None;
    };
    let components = d.num_comp();
    match &d.data {
        IOBuffer::F32(_) | IOBuffer::F64(_) => Some(DataArray::f64(&d.name, components, d.data.cast_into()?)),
        _ if components == 1 => {
            let values: Vec<i64> = d.data.cast_into()?;
            let values: Option<Vec<i32>> = values.into_iter().map(|v| i32::try_from(v).ok()).collect();
            Some(DataArray::i32(&d.name, values?))
        }
        _ => Some(DataArray::f64(&d.name, components, d.data.cast_into()?)),
    }
}
