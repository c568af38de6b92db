//! Writing a design's results: `domain.vtp`, `baffle.vtp`, `centerline.vtp`,
//! `sections.vtp`, `seam.vtp` and `report.json`. Each file is written atomically
//! (temporary name, then rename), so a failed run never leaves half a file.

use crate::design::DesignResult;
use crate::io::{write_trimesh_vtp, write_vtp, DataArray, IoError, IoErrorKind, PolyData};
use crate::geometry::mesh::Vec3;
use std::path::Path;

/// Write every output of a design into `dir` (created if missing).
pub fn write_design_outputs(dir: &Path, result: &DesignResult) -> Result<(), IoError> {
    std::fs::create_dir_all(dir).map_err(|e| IoError::new(dir, IoErrorKind::Os(e)))?;
    write_trimesh_vtp(&dir.join("domain.vtp"), &result.domain)?;
    write_trimesh_vtp(&dir.join("baffle.vtp"), &result.baffle)?;
    write_vtp(&dir.join("centerline.vtp"), &centerline_polydata(result))?;
    write_vtp(&dir.join("sections.vtp"), &sections_polydata(result))?;
    write_vtp(&dir.join("seam.vtp"), &closed_polyline(&result.seam_mm))?;
    write_report(&dir.join("report.json"), result)
}

/// The centerline as one polyline with point arrays `s_mm` (arc length from the VSD
/// cap) and `tangent` (unit).
pub fn centerline_polydata(result: &DesignResult) -> PolyData {
    let samples = &result.centerline.samples;
    let points: Vec<Vec3> = samples.iter().map(|s| s.point).collect();
    let tangents: Vec<Vec3> = samples.iter().map(|s| s.unit_tangent).collect();
    PolyData {
        lines: vec![(0..points.len() as u32).collect()],
        point_data: vec![
            DataArray::f64("s_mm", 1, samples.iter().map(|s| s.s_mm).collect()),
            DataArray::vectors("tangent", &tangents),
        ],
        points,
        ..PolyData::default()
    }
}

/// Raw (cut on the initial patch) and regularized loops of every constrained
/// section, as closed polylines with cell arrays `regularized` (0 raw, 1 regularized)
/// and `section` (index among the report's constrained sections).
pub fn sections_polydata(result: &DesignResult) -> PolyData {
    let mut pd = PolyData::default();
    let (mut kind, mut section) = (Vec::new(), Vec::new());
    for (flag, loops) in [(0, &result.raw_loops_mm), (1, &result.regularized_loops_mm)] {
        for (k, arc) in loops.iter().enumerate().filter(|(_, l)| !l.is_empty()) {
            let first = pd.points.len() as u32;
            pd.points.extend_from_slice(arc);
            let mut line: Vec<u32> = (first..pd.points.len() as u32).collect();
            line.push(first);
            pd.lines.push(line);
            kind.push(flag);
            section.push(k as i32);
        }
    }
    pd.cell_data = vec![DataArray::i32("regularized", kind), DataArray::i32("section", section)];
    pd
}

fn closed_polyline(points: &[Vec3]) -> PolyData {
    let mut line: Vec<u32> = (0..points.len() as u32).collect();
    line.push(0);
    PolyData { points: points.to_vec(), lines: vec![line], ..PolyData::default() }
}

fn write_report(path: &Path, result: &DesignResult) -> Result<(), IoError> {
    let text = serde_json::to_string_pretty(&result.report).map_err(|e| IoError::new(path, IoErrorKind::Malformed(e.to_string())))?;
    crate::io::write_atomic(path, text.as_bytes()).map_err(|e| IoError::new(path, IoErrorKind::Os(e)))
}
