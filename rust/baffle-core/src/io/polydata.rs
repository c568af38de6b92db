//! In-memory VTK PolyData (points, polylines, polygons, named arrays), shared by the
//! readers and the writer, and its conversion to a labelled triangle mesh.

use super::error::{malformed, IoErrorKind};
use crate::geometry::mesh::{TriMesh, Vec3};

/// Name of the per-triangle face label array (SimVascular / Martinez et al. convention).
pub const MODEL_FACE_ID: &str = "ModelFaceID";

/// Values of one named array, stored tuple after tuple.
#[derive(Clone, Debug, PartialEq)]
pub enum ArrayValues {
    /// One Int32 component per point/cell.
    I32(Vec<i32>),
    /// `components` Float64 values per point/cell (1 for scalars, 3 for vectors).
    F64 { components: usize, values: Vec<f64> },
}

impl ArrayValues {
    pub fn components(&self) -> usize {
        match self {
            ArrayValues::I32(_) => 1,
            ArrayValues::F64 { components, .. } => *components,
        }
    }

    /// Number of scalar values (tuples x components).
    pub fn num_values(&self) -> usize {
        match self {
            ArrayValues::I32(v) => v.len(),
            ArrayValues::F64 { values, .. } => values.len(),
        }
    }

    /// Number of tuples (points or cells covered); 0 for a zero-component array.
    pub fn num_tuples(&self) -> usize {
        self.num_values().checked_div(self.components()).unwrap_or(0)
    }

    /// The tuples at `rows`, in that order (used to re-index cell data).
    fn gather(&self, rows: &[usize]) -> ArrayValues {
        match self {
            ArrayValues::I32(v) => ArrayValues::I32(rows.iter().map(|&r| v[r]).collect()),
            ArrayValues::F64 { components, values } => {
                let c = *components;
                let picked = rows.iter().flat_map(|&r| values[r * c..(r + 1) * c].iter().copied()).collect();
                ArrayValues::F64 { components: c, values: picked }
            }
        }
    }
}

/// A named point or cell array.
#[derive(Clone, Debug, PartialEq)]
pub struct DataArray {
    pub name: String,
    pub values: ArrayValues,
}

impl DataArray {
    pub fn i32(name: &str, values: Vec<i32>) -> Self {
        DataArray { name: name.to_string(), values: ArrayValues::I32(values) }
    }

    pub fn f64(name: &str, components: usize, values: Vec<f64>) -> Self {
        DataArray { name: name.to_string(), values: ArrayValues::F64 { components, values } }
    }

    /// A 3-component Float64 array from vectors (normals, displacements...).
    pub fn vectors(name: &str, vectors: &[Vec3]) -> Self {
        let values = vectors.iter().flat_map(|v| [v.x, v.y, v.z]).collect();
        DataArray::f64(name, 3, values)
    }

    pub fn as_i32(&self) -> Option<&[i32]> {
        match &self.values {
            ArrayValues::I32(v) => Some(v),
            ArrayValues::F64 { .. } => None,
        }
    }

    /// The values and their component count, if this is a Float64 array.
    pub fn as_f64(&self) -> Option<(usize, &[f64])> {
        match &self.values {
            ArrayValues::F64 { components, values } => Some((*components, values)),
            ArrayValues::I32(_) => None,
        }
    }
}

/// VTK PolyData restricted to what the design uses: polylines and polygons.
///
/// Cell arrays hold one tuple per cell in VTK order: all `lines` first, then all
/// `polys`. Readers drop vertex cells (and their cell data) and turn triangle
/// strips into triangles appended after the polygons (cell data repeated per triangle).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PolyData {
    pub points: Vec<Vec3>,
    pub polys: Vec<Vec<u32>>,
    pub lines: Vec<Vec<u32>>,
    pub point_data: Vec<DataArray>,
    pub cell_data: Vec<DataArray>,
}

/// The name the writer's brief used; same type as the reader's.
pub type PolyDataOut = PolyData;

/// A triangle surface as read from a file, and whether the file had labels.
#[derive(Clone, Debug, PartialEq)]
pub struct LabeledSurface {
    /// `face_ids` are the file's `ModelFaceID` values, or all 0 when it had none.
    pub mesh: TriMesh,
    /// False when the file had no `ModelFaceID` cell array (STL, unlabelled VTK).
    pub has_model_face_id: bool,
}

impl PolyData {
    pub fn num_cells(&self) -> usize {
        self.lines.len() + self.polys.len()
    }

    /// Index in the cell arrays of polygon `poly`.
    pub fn poly_cell_index(&self, poly: usize) -> usize {
        self.lines.len() + poly
    }

    pub fn point_array(&self, name: &str) -> Option<&DataArray> {
        self.point_data.iter().find(|a| a.name == name)
    }

    pub fn cell_array(&self, name: &str) -> Option<&DataArray> {
        self.cell_data.iter().find(|a| a.name == name)
    }

    /// Check finite coordinates, point indices in range and array lengths.
    pub fn validate(&self) -> Result<(), IoErrorKind> {
        check_finite_points(&self.points)?;
        check_cell_indices("line", &self.lines, self.points.len())?;
        check_cell_indices("polygon", &self.polys, self.points.len())?;
        check_array_lengths("point", &self.point_data, self.points.len())?;
        check_array_lengths("cell", &self.cell_data, self.num_cells())
    }

    /// Triangulate the polygons (fans from their first point) into a mesh labelled
    /// with `ModelFaceID`; lines are ignored.
    pub fn to_labeled_surface(&self) -> Result<LabeledSurface, IoErrorKind> {
        self.validate()?;
        let labels = self.poly_labels()?;
        let mut triangles = Vec::with_capacity(self.polys.len());
        let mut face_ids = Vec::with_capacity(self.polys.len());
        for (p, poly) in self.polys.iter().enumerate() {
            if poly.len() < 3 {
                return Err(malformed(format!("polygon {p} has only {} points", poly.len())));
            }
            let label = labels.as_ref().map_or(0, |l| l[p]);
            for k in 1..poly.len() - 1 {
                triangles.push([poly[0], poly[k], poly[k + 1]]);
                face_ids.push(label);
            }
        }
        let mesh = TriMesh::new(self.points.clone(), triangles, face_ids);
        Ok(LabeledSurface { mesh, has_model_face_id: labels.is_some() })
    }

    /// `ModelFaceID` of each polygon, if the file has that cell array.
    fn poly_labels(&self) -> Result<Option<Vec<i32>>, IoErrorKind> {
        let Some(array) = self.cell_array(MODEL_FACE_ID) else { return Ok(None) };
        let first = self.lines.len();
        match &array.values {
            ArrayValues::I32(v) => Ok(Some(v[first..].to_vec())),
            ArrayValues::F64 { components: 1, values } => values[first..]
                .iter()
                .enumerate()
                .map(|(p, &x)| integral_label(p, x))
                .collect::<Result<_, _>>()
                .map(Some),
            ArrayValues::F64 { components, .. } => {
                Err(malformed(format!("cell array {MODEL_FACE_ID} has {components} components, expected 1")))
            }
        }
    }
}

/// A floating-point label that is an exact 32-bit integer.
fn integral_label(poly: usize, x: f64) -> Result<i32, IoErrorKind> {
    if x.fract() == 0.0 && x >= i32::MIN as f64 && x <= i32::MAX as f64 {
        Ok(x as i32)
    } else {
        Err(malformed(format!("{MODEL_FACE_ID} of polygon {poly} is {x}, not a 32-bit integer")))
    }
}

pub(crate) fn check_finite_points(points: &[Vec3]) -> Result<(), IoErrorKind> {
    for (i, p) in points.iter().enumerate() {
        if let Some(&value) = p.iter().find(|c| !c.is_finite()) {
            return Err(IoErrorKind::NonFiniteCoordinate { point: i, value });
        }
    }
    Ok(())
}

fn check_cell_indices(kind: &str, cells: &[Vec<u32>], num_points: usize) -> Result<(), IoErrorKind> {
    for (c, cell) in cells.iter().enumerate() {
        if let Some(&index) = cell.iter().find(|&&i| i as usize >= num_points) {
            return Err(IoErrorKind::IndexOutOfRange { cell: format!("{kind} {c}"), index: index as u64, num_points });
        }
    }
    Ok(())
}

fn check_array_lengths(location: &str, arrays: &[DataArray], tuples: usize) -> Result<(), IoErrorKind> {
    for a in arrays {
        let components = a.values.components();
        if components == 0 {
            return Err(malformed(format!("{location} array '{}' has 0 components", a.name)));
        }
        if a.values.num_values() != tuples * components {
            return Err(IoErrorKind::ArrayLength {
                array: a.name.clone(),
                expected: tuples * components,
                found: a.values.num_values(),
            });
        }
    }
    Ok(())
}

/// Numbers as parsed from a file, before choosing `ArrayValues`.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Numbers {
    Int(Vec<i64>),
    Float(Vec<f64>),
}

impl Numbers {
    pub fn into_f64(self) -> Vec<f64> {
        match self {
            Numbers::Int(v) => v.into_iter().map(|x| x as f64).collect(),
            Numbers::Float(v) => v,
        }
    }

    /// Point indices / offsets: non-negative integers below 2^32.
    pub fn into_indices(self, array: &str) -> Result<Vec<u64>, IoErrorKind> {
        let Numbers::Int(v) = self else {
            return Err(malformed(format!("array '{array}' holds floating-point values, expected integers")));
        };
        v.into_iter()
            .enumerate()
            .map(|(i, x)| {
                u64::try_from(x).map_err(|_| malformed(format!("array '{array}' has negative value {x} at entry {i}")))
            })
            .collect()
    }

    /// Single-component integer arrays that fit Int32 stay integers; all else is Float64.
    pub fn into_array(self, name: &str, components: usize) -> DataArray {
        match self {
            Numbers::Int(v) if components == 1 && v.iter().all(|&x| i32::try_from(x).is_ok()) => {
                DataArray::i32(name, v.into_iter().map(|x| x as i32).collect())
            }
            other => DataArray::f64(name, components, other.into_f64()),
        }
    }
}

/// Cells of a file in VTK order, before vertices are dropped and strips split.
#[derive(Debug, Default)]
pub(crate) struct CellSections {
    pub verts: usize,
    pub lines: Vec<Vec<u32>>,
    pub polys: Vec<Vec<u32>>,
    pub strips: Vec<Vec<u32>>,
}

impl CellSections {
    fn total(&self) -> usize {
        self.verts + self.lines.len() + self.polys.len() + self.strips.len()
    }
}

/// Triangles of a strip, alternating winding so all match the first; degenerate
/// triangles (strips restart by repeating a point) are skipped.
pub(crate) fn strip_triangles(strip: &[u32]) -> Vec<[u32; 3]> {
    (0..strip.len().saturating_sub(2))
        .map(|k| {
            let (a, b, c) = (strip[k], strip[k + 1], strip[k + 2]);
            if k % 2 == 0 {
                [a, b, c]
            } else {
                [b, a, c]
            }
        })
        .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
        .collect()
}

/// Build a validated `PolyData` from a file's sections: drop vertex cells, append
/// strip triangles after the polygons, and re-index the cell arrays to match.
pub(crate) fn assemble(
    points: Vec<Vec3>,
    sections: CellSections,
    point_data: Vec<DataArray>,
    cell_data: Vec<DataArray>,
) -> Result<PolyData, IoErrorKind> {
    check_array_lengths("cell", &cell_data, sections.total())?;
    let CellSections { verts, lines, mut polys, strips } = sections;
    let first_poly = verts + lines.len();
    let first_strip = first_poly + polys.len();
    let mut rows: Vec<usize> = (verts..first_strip).collect();
    for (s, strip) in strips.iter().enumerate() {
        for t in strip_triangles(strip) {
            polys.push(t.to_vec());
            rows.push(first_strip + s);
        }
    }
    let unchanged = verts == 0 && strips.is_empty();
    let cell_data = if unchanged {
        cell_data
    } else {
        cell_data.into_iter().map(|a| DataArray { values: a.values.gather(&rows), name: a.name }).collect()
    };
    let out = PolyData { points, polys, lines, point_data, cell_data };
    out.validate()?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> PolyData {
        let points = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ];
        PolyData {
            points,
            polys: vec![vec![0, 1, 2, 3]],
            lines: vec![vec![0, 2]],
            point_data: vec![],
            cell_data: vec![DataArray::i32(MODEL_FACE_ID, vec![99, 7])],
        }
    }

    #[test]
    fn quad_becomes_fan_with_label_skipping_lines() {
        let s = square().to_labeled_surface().unwrap();
        assert!(s.has_model_face_id);
        assert_eq!(s.mesh.triangles, vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(s.mesh.face_ids, vec![7, 7]);
    }

    #[test]
    fn missing_labels_are_reported_as_absent() {
        let mut pd = square();
        pd.cell_data.clear();
        let s = pd.to_labeled_surface().unwrap();
        assert!(!s.has_model_face_id);
        assert_eq!(s.mesh.face_ids, vec![0, 0]);
    }

    #[test]
    fn validation_names_the_problem() {
        let mut pd = square();
        pd.polys[0][2] = 4;
        let msg = pd.validate().unwrap_err().to_string();
        assert!(msg.contains("polygon 0") && msg.contains("point 4"), "{msg}");

        let mut pd = square();
        pd.points[3].y = f64::NAN;
        let msg = pd.validate().unwrap_err().to_string();
        assert!(msg.contains("point 3"), "{msg}");

        let mut pd = square();
        pd.cell_data.push(DataArray::f64("area", 1, vec![1.0]));
        let msg = pd.validate().unwrap_err().to_string();
        assert!(msg.contains("'area'") && msg.contains("expected 2"), "{msg}");
    }

    #[test]
    fn strips_alternate_winding_and_skip_degenerates() {
        assert_eq!(strip_triangles(&[0, 1, 2, 3]), vec![[0, 1, 2], [2, 1, 3]]);
        assert_eq!(strip_triangles(&[0, 1, 1, 2]), Vec::<[u32; 3]>::new());
        assert!(strip_triangles(&[0, 1]).is_empty());
    }

    #[test]
    fn assemble_drops_verts_and_splits_strips_with_cell_data() {
        let points = vec![Vec3::zeros(), Vec3::x(), Vec3::y(), Vec3::new(1.0, 1.0, 0.0)];
        let sections = CellSections {
            verts: 1,
            lines: vec![vec![0, 1]],
            polys: vec![vec![0, 1, 2]],
            strips: vec![vec![0, 1, 2, 3]],
        };
        let cell = vec![DataArray::i32("id", vec![100, 101, 102, 103])];
        let pd = assemble(points, sections, vec![], cell).unwrap();
        assert_eq!(pd.polys.len(), 3);
        assert_eq!(pd.cell_array("id").unwrap().as_i32().unwrap(), &[101, 102, 103, 103]);
    }

    #[test]
    fn integer_arrays_choose_i32_only_when_they_fit() {
        assert_eq!(Numbers::Int(vec![1, 2]).into_array("a", 1), DataArray::i32("a", vec![1, 2]));
        let big = Numbers::Int(vec![1 << 40]).into_array("b", 1);
        assert_eq!(big, DataArray::f64("b", 1, vec![(1u64 << 40) as f64]));
        assert!(Numbers::Int(vec![-1]).into_indices("offsets").is_err());
    }
}
