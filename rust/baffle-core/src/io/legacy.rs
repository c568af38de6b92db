//! Legacy VTK (`.vtk`) POLYDATA, ascii or binary, old (`POLYGONS n size`) or 5.x
//! (`OFFSETS`/`CONNECTIVITY`) cell layout. Parsing is vtkio's; this module converts
//! its model and checks it.

use vtkio::model::{Attribute, DataSet, ElementType, IOBuffer, Piece, VertexNumbers};

use super::error::{malformed, IoErrorKind};
use super::polydata::{assemble, CellSections, DataArray, Numbers, PolyData};
use crate::geometry::mesh::Vec3;

/// Parse a whole legacy `.vtk` file holding POLYDATA.
pub(crate) fn parse_legacy(bytes: &[u8]) -> Result<PolyData, IoErrorKind> {
    let vtk = vtkio::Vtk::parse_legacy_be(bytes).map_err(|e| malformed(format!("legacy VTK does not parse: {e}")))?;
    let DataSet::PolyData { pieces, .. } = vtk.data else {
        return Err(IoErrorKind::Unsupported("legacy VTK dataset is not POLYDATA".into()));
    };
    if pieces.len() != 1 {
        return Err(IoErrorKind::Unsupported(format!("{} pieces, expected 1", pieces.len())));
    }
    let Some(Piece::Inline(piece)) = pieces.into_iter().next() else {
        return Err(IoErrorKind::Unsupported("POLYDATA piece is not stored inline".into()));
    };
    let piece = *piece;
    let coords =
        numbers_of(piece.points).ok_or_else(|| IoErrorKind::Unsupported("bit-typed POINTS".into()))?.into_f64();
    if coords.len() % 3 != 0 {
        return Err(malformed(format!("POINTS has {} values, not a multiple of 3", coords.len())));
    }
    let points: Vec<Vec3> = coords.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect();
    let sections = CellSections {
        verts: cells_of("VERTICES", piece.verts)?.len(),
        lines: cells_of("LINES", piece.lines)?,
        polys: cells_of("POLYGONS", piece.polys)?,
        strips: cells_of("TRIANGLE_STRIPS", piece.strips)?,
    };
    let point_data = arrays_of(piece.data.point);
    let cell_data = arrays_of(piece.data.cell);
    assemble(points, sections, point_data, cell_data)
}

/// Numbers of a vtkio buffer; `None` for bit arrays.
fn numbers_of(buffer: IOBuffer) -> Option<Numbers> {
    let ints = |v: Vec<i64>| Some(Numbers::Int(v));
    match buffer {
        IOBuffer::Bit(_) => None,
        IOBuffer::U8(v) => ints(v.into_iter().map(i64::from).collect()),
        IOBuffer::I8(v) => ints(v.into_iter().map(i64::from).collect()),
        IOBuffer::U16(v) => ints(v.into_iter().map(i64::from).collect()),
        IOBuffer::I16(v) => ints(v.into_iter().map(i64::from).collect()),
        IOBuffer::U32(v) => ints(v.into_iter().map(i64::from).collect()),
        IOBuffer::I32(v) => ints(v.into_iter().map(i64::from).collect()),
        // Values beyond i64 cannot be point indices or labels; keep them as floats.
        IOBuffer::U64(v) => match v.iter().map(|&x| i64::try_from(x)).collect::<Result<Vec<_>, _>>() {
            Ok(v) => ints(v),
            Err(_) => Some(Numbers::Float(v.into_iter().map(|x| x as f64).collect())),
        },
        IOBuffer::I64(v) => ints(v),
        IOBuffer::F32(v) => Some(Numbers::Float(v.into_iter().map(f64::from).collect())),
        IOBuffer::F64(v) => Some(Numbers::Float(v)),
    }
}

/// Named arrays from SCALARS/VECTORS/NORMALS/... and FIELD blocks; lookup tables
/// and bit arrays are skipped.
fn arrays_of(attributes: Vec<Attribute>) -> Vec<DataArray> {
    let mut out = Vec::new();
    for attribute in attributes {
        match attribute {
            Attribute::DataArray(a) => {
                if matches!(a.elem, ElementType::LookupTable) {
                    continue;
                }
                let components = a.elem.num_comp() as usize;
                if let Some(n) = numbers_of(a.data) {
                    out.push(n.into_array(&a.name, components));
                }
            }
            Attribute::Field { data_array, .. } => {
                for a in data_array {
                    if let Some(n) = numbers_of(a.data) {
                        out.push(n.into_array(&a.name, a.elem as usize));
                    }
                }
            }
        }
    }
    out
}

/// Cells of one legacy section as point-index lists (indices checked later).
fn cells_of(section: &str, cells: Option<VertexNumbers>) -> Result<Vec<Vec<u32>>, IoErrorKind> {
    match cells {
        None => Ok(Vec::new()),
        Some(VertexNumbers::Legacy { num_cells, vertices }) => counted_cells(section, num_cells as usize, &vertices),
        Some(VertexNumbers::XML { connectivity, offsets }) => offset_cells(section, &connectivity, &offsets),
    }
}

/// `n i_1 .. i_n` records.
fn counted_cells(section: &str, num_cells: usize, list: &[u32]) -> Result<Vec<Vec<u32>>, IoErrorKind> {
    // The count comes from the file: a cell takes at least one value of the list, so
    // the list bounds the allocation (found by the fuzz harness: 50 GB for a bad count).
    let mut cells = Vec::with_capacity(num_cells.min(list.len()));
    let mut pos = 0usize;
    for c in 0..num_cells {
        let n = *list.get(pos).ok_or_else(|| malformed(format!("{section}: list ends before cell {c}")))? as usize;
        let cell = list
            .get(pos + 1..pos + 1 + n)
            .ok_or_else(|| malformed(format!("{section}: cell {c} declares {n} points but the list ends")))?;
        cells.push(cell.to_vec());
        pos += 1 + n;
    }
    if pos != list.len() {
        return Err(malformed(format!("{section}: {} values left after {num_cells} cells", list.len() - pos)));
    }
    Ok(cells)
}

/// Legacy 5.x `OFFSETS` (with the leading 0) and `CONNECTIVITY`.
fn offset_cells(section: &str, connectivity: &[u64], offsets: &[u64]) -> Result<Vec<Vec<u32>>, IoErrorKind> {
    let bounds: Vec<u64> = if offsets.first() == Some(&0) { offsets.to_vec() } else { [&[0], offsets].concat() };
    let mut cells = Vec::with_capacity(bounds.len().saturating_sub(1));
    for (c, w) in bounds.windows(2).enumerate() {
        let (start, end) = (w[0] as usize, w[1] as usize);
        let ids = connectivity.get(start..end).ok_or_else(|| {
            malformed(format!(
                "{section}: cell {c} spans {start}..{end}, beyond connectivity length {}",
                connectivity.len()
            ))
        })?;
        let cell = ids
            .iter()
            .map(|&i| {
                u32::try_from(i).map_err(|_| IoErrorKind::IndexOutOfRange {
                    cell: format!("{section} cell {c}"),
                    index: i,
                    num_points: u32::MAX as usize,
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        cells.push(cell);
    }
    Ok(cells)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counted_cells_detects_truncated_list() {
        assert_eq!(counted_cells("POLYGONS", 2, &[3, 0, 1, 2, 2, 0, 1]).unwrap(), vec![vec![0, 1, 2], vec![0, 1]]);
        let msg = counted_cells("POLYGONS", 2, &[3, 0, 1, 2, 3, 0]).unwrap_err().to_string();
        assert!(msg.contains("cell 1"), "{msg}");
    }

    #[test]
    fn a_huge_cell_count_is_an_error_not_an_allocation() {
        let msg = counted_cells("POLYGONS", usize::MAX / 8, &[3, 0, 1, 2]).unwrap_err().to_string();
        assert!(msg.contains("list ends before cell 1"), "{msg}");
    }

    #[test]
    fn offset_cells_accept_leading_zero_or_not() {
        let expected = vec![vec![0, 1, 2], vec![2, 3]];
        assert_eq!(offset_cells("LINES", &[0, 1, 2, 2, 3], &[0, 3, 5]).unwrap(), expected);
        assert_eq!(offset_cells("LINES", &[0, 1, 2, 2, 3], &[3, 5]).unwrap(), expected);
        assert!(offset_cells("LINES", &[0, 1], &[0, 3]).is_err());
    }
}
