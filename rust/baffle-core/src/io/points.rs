//! Suture point lists: 3D Slicer markups (`.mrk.json`, `.fcsv`), plain tables
//! (`.csv`, `.txt`) and plain JSON; and writing a Slicer closed-curve markup.

use std::path::Path;

use serde_json::{json, Value};

use super::atomic::write_atomic;
use super::error::{malformed, read_bytes, IoError, IoErrorKind};
use crate::geometry::mesh::Vec3;

/// Patient frame of coordinates: Slicer stores LPS in files, works in RAS internally.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum CoordinateSystem {
    Lps,
    Ras,
}

impl CoordinateSystem {
    pub fn as_str(self) -> &'static str {
        match self {
            CoordinateSystem::Lps => "LPS",
            CoordinateSystem::Ras => "RAS",
        }
    }

    fn parse(text: &str) -> Option<Self> {
        match text.trim().to_ascii_uppercase().as_str() {
            "LPS" => Some(CoordinateSystem::Lps),
            "RAS" => Some(CoordinateSystem::Ras),
            _ => None,
        }
    }
}

/// Points placed along the intended suture line, in millimetres.
#[derive(Clone, Debug, PartialEq)]
pub struct SuturePoints {
    pub points_mm: Vec<Vec3>,
    /// The frame `points_mm` are expressed in (as stored in the file).
    pub coordinate_system: CoordinateSystem,
    /// True for a Slicer closed curve (or plain JSON with `"closed": true`); point
    /// lists, open curves and plain tables say nothing, so they read as open.
    pub closed: bool,
    /// One label per point; empty strings when the format has none.
    pub labels: Vec<String>,
}

impl SuturePoints {
    /// The points in `target` frame (LPS <-> RAS negates x and y).
    pub fn to_frame(&self, target: CoordinateSystem) -> Vec<Vec3> {
        if target == self.coordinate_system {
            return self.points_mm.clone();
        }
        self.points_mm.iter().map(|p| Vec3::new(-p.x, -p.y, p.z)).collect()
    }
}

/// Read suture points, choosing the format from the file name:
/// `.mrk.json` (Slicer markups), `.json` (markups, or a plain `[[x,y,z],...]` array or
/// `{"points": [...], "coordinate_system": "LPS"|"RAS", "closed": bool}`), `.fcsv`
/// (Slicer fiducial CSV), `.csv`/`.txt` (x,y,z per line, optional header).
///
/// For markups files with several markups, the first ClosedCurve, Curve or Fiducial
/// markup that has at least one defined control point is used; control points whose
/// `positionStatus` is "undefined" are skipped. Files without a frame are taken as LPS,
/// except `.fcsv` without a `CoordinateSystem` line, which older Slicer wrote in RAS.
pub fn read_points(path: &Path) -> Result<SuturePoints, IoError> {
    let name = path.file_name().map(|n| n.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    let bytes = read_bytes(path)?;
    let parsed = text_of(&bytes).and_then(|text| {
        if name.ends_with(".json") {
            parse_json_points(text)
        } else if name.ends_with(".fcsv") {
            parse_fcsv(text)
        } else if name.ends_with(".csv") || name.ends_with(".txt") {
            parse_table(text)
        } else {
            Err(IoErrorKind::Unsupported("point files must end in .mrk.json, .json, .fcsv, .csv or .txt".into()))
        }
    });
    // A file with a header and no rows parses; it still holds no seam.
    let parsed = parsed.and_then(|p| match p.points_mm.is_empty() {
        true => Err(IoErrorKind::Malformed("the file holds no points".into())),
        false => Ok(p),
    });
    parsed.map_err(|kind| IoError::new(path, kind))
}

/// Write a Slicer markups closed curve (`.mrk.json`, schema v1.0.3).
pub fn write_markups_closed_curve(
    path: &Path,
    name: &str,
    points_mm: &[Vec3],
    coordinate_system: CoordinateSystem,
) -> Result<(), IoError> {
    if let Some((point, value)) =
        points_mm.iter().enumerate().find_map(|(i, p)| p.iter().find(|c| !c.is_finite()).map(|&v| (i, v)))
    {
        return Err(IoError::new(path, IoErrorKind::NonFiniteCoordinate { point, value }));
    }
    let control_points: Vec<Value> = points_mm
        .iter()
        .enumerate()
        .map(|(i, p)| {
            json!({
                "id": (i + 1).to_string(),
                "label": format!("{name}-{}", i + 1),
                "position": [p.x, p.y, p.z],
                "positionStatus": "defined",
            })
        })
        .collect();
    let doc = json!({
        "@schema": "https://raw.githubusercontent.com/slicer/slicer/master/Modules/Loadable/Markups/Resources/Schema/markups-schema-v1.0.3.json#",
        "markups": [{
            "type": "ClosedCurve",
            "coordinateSystem": coordinate_system.as_str(),
            "coordinateUnits": "mm",
            "name": name,
            "controlPoints": control_points,
        }],
    });
    let text = serde_json::to_string_pretty(&doc).map_err(|e| IoError::new(path, malformed(e.to_string())))?;
    write_atomic(path, text.as_bytes()).map_err(|e| IoError::new(path, IoErrorKind::Os(e)))
}

fn text_of(bytes: &[u8]) -> Result<&str, IoErrorKind> {
    let text =
        std::str::from_utf8(bytes).map_err(|e| malformed(format!("not UTF-8 text (byte {})", e.valid_up_to())))?;
    Ok(text.strip_prefix('\u{feff}').unwrap_or(text))
}

fn parse_json_points(text: &str) -> Result<SuturePoints, IoErrorKind> {
    let root: Value = serde_json::from_str(text)
        .map_err(|e| malformed(format!("JSON error at line {}, column {}: {e}", e.line(), e.column())))?;
    if root.get("markups").is_some() {
        return parse_markups(&root);
    }
    let (list, frame, closed) = match &root {
        Value::Array(_) => (&root, CoordinateSystem::Lps, false),
        Value::Object(map) => {
            let list = map.get("points").ok_or_else(|| malformed("JSON object has neither 'markups' nor 'points'"))?;
            let frame = match map.get("coordinate_system") {
                None => CoordinateSystem::Lps,
                Some(v) => v
                    .as_str()
                    .and_then(CoordinateSystem::parse)
                    .ok_or_else(|| malformed(format!("coordinate_system {v} is neither \"LPS\" nor \"RAS\"")))?,
            };
            let closed = map.get("closed").and_then(Value::as_bool).unwrap_or(false);
            (list, frame, closed)
        }
        _ => return Err(malformed("JSON must be an array of [x,y,z] or an object")),
    };
    let items = list.as_array().ok_or_else(|| malformed("'points' is not an array"))?;
    let points_mm =
        items.iter().enumerate().map(|(i, v)| json_xyz(v, &format!("point {i}"))).collect::<Result<Vec<_>, _>>()?;
    let labels = vec![String::new(); points_mm.len()];
    Ok(SuturePoints { points_mm, coordinate_system: frame, closed, labels })
}

/// A `[x, y, z]` JSON array; `what` names it in errors.
fn json_xyz(value: &Value, what: &str) -> Result<Vec3, IoErrorKind> {
    let coords = value.as_array().ok_or_else(|| malformed(format!("{what} is not an array of 3 numbers")))?;
    if coords.len() != 3 {
        return Err(malformed(format!("{what} has {} coordinates", coords.len())));
    }
    let mut xyz = [0.0; 3];
    for (k, c) in coords.iter().enumerate() {
        xyz[k] = c.as_f64().ok_or_else(|| malformed(format!("{what}: coordinate {k} ({c}) is not a number")))?;
    }
    Ok(Vec3::new(xyz[0], xyz[1], xyz[2]))
}

const POINT_MARKUP_TYPES: [&str; 3] = ["ClosedCurve", "Curve", "Fiducial"];

fn parse_markups(root: &Value) -> Result<SuturePoints, IoErrorKind> {
    let markups = root["markups"].as_array().ok_or_else(|| malformed("'markups' is not an array"))?;
    let mut seen = Vec::new();
    for (m, markup) in markups.iter().enumerate() {
        let kind = markup["type"].as_str().unwrap_or("(no type)");
        seen.push(kind.to_string());
        if !POINT_MARKUP_TYPES.contains(&kind) {
            continue;
        }
        let (points_mm, labels) = defined_control_points(markup, m)?;
        if points_mm.is_empty() {
            continue;
        }
        let coordinate_system = markup_frame(markup, m)?;
        check_markup_units(markup, m)?;
        return Ok(SuturePoints { points_mm, coordinate_system, closed: kind == "ClosedCurve", labels });
    }
    Err(malformed(format!(
        "no ClosedCurve, Curve or Fiducial markup with a defined control point (markups found: [{}])",
        seen.join(", ")
    )))
}

fn markup_frame(markup: &Value, m: usize) -> Result<CoordinateSystem, IoErrorKind> {
    match markup.get("coordinateSystem") {
        None => Ok(CoordinateSystem::Lps),
        Some(v) => v
            .as_str()
            .and_then(CoordinateSystem::parse)
            .ok_or_else(|| malformed(format!("markup {m}: coordinateSystem {v} is neither \"LPS\" nor \"RAS\""))),
    }
}

fn check_markup_units(markup: &Value, m: usize) -> Result<(), IoErrorKind> {
    match markup.get("coordinateUnits") {
        None => Ok(()),
        Some(Value::String(u)) if u == "mm" => Ok(()),
        Some(v) => Err(IoErrorKind::Unsupported(format!("markup {m}: coordinateUnits {v}, only \"mm\" is supported"))),
    }
}

/// Positions and labels of the control points that are not "undefined".
fn defined_control_points(markup: &Value, m: usize) -> Result<(Vec<Vec3>, Vec<String>), IoErrorKind> {
    let Some(list) = markup.get("controlPoints") else { return Ok((Vec::new(), Vec::new())) };
    let list = list.as_array().ok_or_else(|| malformed(format!("markup {m}: controlPoints is not an array")))?;
    let mut points = Vec::with_capacity(list.len());
    let mut labels = Vec::with_capacity(list.len());
    for (i, cp) in list.iter().enumerate() {
        if cp.get("positionStatus").and_then(Value::as_str) == Some("undefined") {
            continue;
        }
        let position = cp.get("position").ok_or_else(|| malformed(format!("control point {i} has no position")))?;
        points.push(json_xyz(position, &format!("control point {i}"))?);
        labels.push(cp.get("label").and_then(Value::as_str).unwrap_or_default().to_string());
    }
    Ok((points, labels))
}

/// Column positions of a `.fcsv` (Slicer's default order unless a `# columns` line says otherwise).
struct FcsvColumns {
    x: usize,
    y: usize,
    z: usize,
    label: Option<usize>,
}

fn fcsv_columns(header: &str) -> Result<FcsvColumns, IoErrorKind> {
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let find = |n: &str| names.iter().position(|&c| c == n);
    match (find("x"), find("y"), find("z")) {
        (Some(x), Some(y), Some(z)) => Ok(FcsvColumns { x, y, z, label: find("label") }),
        _ => Err(malformed(format!("'# columns = {header}' lacks x, y or z"))),
    }
}

fn parse_fcsv(text: &str) -> Result<SuturePoints, IoErrorKind> {
    let mut frame = CoordinateSystem::Ras;
    let mut columns = FcsvColumns { x: 1, y: 2, z: 3, label: Some(11) };
    let mut points_mm = Vec::new();
    let mut labels = Vec::new();
    for (line_no, line) in text.lines().enumerate().map(|(i, l)| (i + 1, l.trim())) {
        if let Some(comment) = line.strip_prefix('#') {
            if let Some((key, value)) = comment.split_once('=') {
                match key.trim() {
                    "CoordinateSystem" => frame = fcsv_frame(value.trim(), line_no)?,
                    "columns" => columns = fcsv_columns(value.trim())?,
                    _ => {}
                }
            }
            continue;
        }
        if line.is_empty() {
            continue;
        }
        let fields = split_csv_line(line);
        let number = |col: usize, axis: &str| -> Result<f64, IoErrorKind> {
            let field =
                fields.get(col).ok_or_else(|| malformed(format!("line {line_no}: no {axis} column ({col})")))?;
            parse_number(field, line_no, col)
        };
        points_mm.push(Vec3::new(number(columns.x, "x")?, number(columns.y, "y")?, number(columns.z, "z")?));
        labels.push(columns.label.and_then(|c| fields.get(c)).cloned().unwrap_or_default());
    }
    Ok(SuturePoints { points_mm, coordinate_system: frame, closed: false, labels })
}

/// `CoordinateSystem` of an fcsv: a name, or Slicer's numeric code (0 RAS, 1 LPS).
fn fcsv_frame(value: &str, line_no: usize) -> Result<CoordinateSystem, IoErrorKind> {
    match value {
        "0" => Ok(CoordinateSystem::Ras),
        "1" => Ok(CoordinateSystem::Lps),
        other => CoordinateSystem::parse(other)
            .ok_or_else(|| malformed(format!("line {line_no}: unknown CoordinateSystem '{other}'"))),
    }
}

/// Comma-separated fields; double quotes protect commas ("" is a literal quote).
fn split_csv_line(line: &str) -> Vec<String> {
    let mut fields = vec![String::new()];
    let mut quoted = false;
    let mut chars = line.chars().peekable();
    while let Some(ch) = chars.next() {
        match ch {
            '"' if quoted && chars.peek() == Some(&'"') => {
                chars.next();
                fields.last_mut().unwrap().push('"');
            }
            '"' => quoted = !quoted,
            ',' if !quoted => fields.push(String::new()),
            c => fields.last_mut().unwrap().push(c),
        }
    }
    fields
}

fn parse_number(field: &str, line_no: usize, col: usize) -> Result<f64, IoErrorKind> {
    let value = field
        .trim()
        .parse::<f64>()
        .map_err(|_| malformed(format!("line {line_no}: field {col} '{field}' is not a number")))?;
    if value.is_finite() {
        Ok(value)
    } else {
        Err(malformed(format!("line {line_no}: field {col} '{field}' is not finite")))
    }
}

/// x y z per line, separated by commas, semicolons or whitespace; an optional
/// header line (no numeric field) first; '#' starts a comment line.
fn parse_table(text: &str) -> Result<SuturePoints, IoErrorKind> {
    let mut points_mm = Vec::new();
    let mut first_content_line = true;
    for (line_no, line) in text.lines().enumerate().map(|(i, l)| (i + 1, l.trim())) {
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> =
            line.split(|c: char| c == ',' || c == ';' || c.is_whitespace()).filter(|f| !f.is_empty()).collect();
        let is_header = first_content_line && fields.iter().all(|f| f.parse::<f64>().is_err());
        first_content_line = false;
        if is_header {
            continue;
        }
        if fields.len() != 3 {
            return Err(malformed(format!("line {line_no}: expected 3 values x, y, z, found {}", fields.len())));
        }
        let xyz =
            fields.iter().enumerate().map(|(col, f)| parse_number(f, line_no, col)).collect::<Result<Vec<_>, _>>()?;
        points_mm.push(Vec3::new(xyz[0], xyz[1], xyz[2]));
    }
    let labels = vec![String::new(); points_mm.len()];
    Ok(SuturePoints { points_mm, coordinate_system: CoordinateSystem::Lps, closed: false, labels })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp_file(name: &str, content: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("baffle-io-points-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(name);
        std::fs::write(&path, content).unwrap();
        path
    }

    #[test]
    fn markups_skip_undefined_and_empty_markups() {
        let text = r#"{"markups": [
            {"type": "Fiducial", "controlPoints": []},
            {"type": "Line", "controlPoints": [{"position": [9, 9, 9]}]},
            {"type": "Curve", "coordinateSystem": "RAS", "controlPoints": [
                {"label": "a", "position": [1, 2, 3]},
                {"label": "b", "position": [0, 0, 0], "positionStatus": "undefined"},
                {"label": "c", "position": [4, 5, 6], "positionStatus": "defined"}]}]}"#;
        let sp = parse_json_points(text).unwrap();
        assert_eq!(sp.points_mm, vec![Vec3::new(1.0, 2.0, 3.0), Vec3::new(4.0, 5.0, 6.0)]);
        assert_eq!(sp.labels, vec!["a", "c"]);
        assert_eq!(sp.coordinate_system, CoordinateSystem::Ras);
        assert!(!sp.closed);
    }

    #[test]
    fn markups_errors_name_the_point_and_units() {
        let bad = r#"{"markups": [{"type": "ClosedCurve", "controlPoints": [
            {"position": [1, 2, 3]}, {"position": [1, 2, 3]}, {"position": [1, 2, 3]}, {"position": [1, 2]}]}]}"#;
        let msg = parse_json_points(bad).unwrap_err().to_string();
        assert!(msg.contains("control point 3 has 2 coordinates"), "{msg}");
        let um = r#"{"markups": [{"type": "ClosedCurve", "coordinateUnits": "um", "controlPoints": [{"position": [1, 2, 3]}]}]}"#;
        let msg = parse_json_points(um).unwrap_err().to_string();
        assert!(msg.contains("um"), "{msg}");
        let none = r#"{"markups": [{"type": "Line", "controlPoints": [{"position": [1, 2, 3]}]}]}"#;
        assert!(parse_json_points(none).unwrap_err().to_string().contains("Line"));
    }

    #[test]
    fn plain_json_forms() {
        let sp = parse_json_points("[[1,2,3],[4,5,6]]").unwrap();
        assert_eq!((sp.points_mm.len(), sp.coordinate_system, sp.closed), (2, CoordinateSystem::Lps, false));
        let sp = parse_json_points(r#"{"points": [[1,2,3]], "coordinate_system": "RAS", "closed": true}"#).unwrap();
        assert_eq!((sp.coordinate_system, sp.closed), (CoordinateSystem::Ras, true));
        assert!(parse_json_points(r#"{"points": [[1,"x",3]]}"#).unwrap_err().to_string().contains("point 0"));
    }

    #[test]
    fn fcsv_with_frame_code_and_quoted_label() {
        let text = "# Markups fiducial file version = 4.11\n# CoordinateSystem = 0\n\
                    # columns = id,x,y,z,ow,ox,oy,oz,vis,sel,lock,label,desc,associatedNodeID\n\
                    vtkMRMLMarkupsFiducialNode_0,1.5,-2,3,0,0,0,1,1,1,0,\"F,1\",,\n";
        let sp = parse_fcsv(text).unwrap();
        assert_eq!(sp.coordinate_system, CoordinateSystem::Ras);
        assert_eq!(sp.points_mm, vec![Vec3::new(1.5, -2.0, 3.0)]);
        assert_eq!(sp.labels, vec!["F,1"]);
        let lps = parse_fcsv("# CoordinateSystem = LPS\nid,1,2,3\n").unwrap();
        assert_eq!(lps.coordinate_system, CoordinateSystem::Lps);
        let msg = parse_fcsv("# CoordinateSystem = LPS\nid,1,abc,3\n").unwrap_err().to_string();
        assert!(msg.contains("line 2") && msg.contains("abc"), "{msg}");
    }

    #[test]
    fn table_with_header_and_mixed_separators() {
        let sp = parse_table("x;y;z\n1;2;3\n4 5 6\n\n7,8, 9\n").unwrap();
        assert_eq!(sp.points_mm.len(), 3);
        assert_eq!(sp.points_mm[2], Vec3::new(7.0, 8.0, 9.0));
        let msg = parse_table("1,2,3\n4,5\n").unwrap_err().to_string();
        assert!(msg.contains("line 2") && msg.contains("found 2"), "{msg}");
    }

    #[test]
    fn to_frame_flips_x_and_y() {
        let sp = SuturePoints {
            points_mm: vec![Vec3::new(1.0, 2.0, 3.0)],
            coordinate_system: CoordinateSystem::Lps,
            closed: true,
            labels: vec![String::new()],
        };
        assert_eq!(sp.to_frame(CoordinateSystem::Ras), vec![Vec3::new(-1.0, -2.0, 3.0)]);
        assert_eq!(sp.to_frame(CoordinateSystem::Lps), sp.points_mm);
    }

    #[test]
    fn closed_curve_round_trips_through_markups_file() {
        let path = temp_file("seam.mrk.json", "");
        let pts = vec![Vec3::new(1.25, -2.5, 3.0), Vec3::new(0.1, 0.2, 0.3), Vec3::new(-7.0, 8.0, 1e-3)];
        write_markups_closed_curve(&path, "seam", &pts, CoordinateSystem::Ras).unwrap();
        let sp = read_points(&path).unwrap();
        assert_eq!(sp.points_mm, pts);
        assert_eq!(sp.coordinate_system, CoordinateSystem::Ras);
        assert!(sp.closed);
        assert_eq!(sp.labels[2], "seam-3");
        let bad = write_markups_closed_curve(&path, "seam", &[Vec3::new(f64::NAN, 0.0, 0.0)], CoordinateSystem::Lps);
        assert!(bad.unwrap_err().to_string().contains("point 0"));
    }

    #[test]
    fn read_errors_name_the_file() {
        let um = temp_file(
            "units.mrk.json",
            r#"{"markups": [{"type": "ClosedCurve", "coordinateUnits": "um", "controlPoints": [{"position": [1,2,3]}]}]}"#,
        );
        let msg = read_points(&um).unwrap_err().to_string();
        assert!(msg.contains("units.mrk.json") && msg.contains("um"), "{msg}");
        let csv = temp_file("bad.csv", "x,y,z\n1,2,3\n1,two,3\n");
        let msg = read_points(&csv).unwrap_err().to_string();
        assert!(msg.contains("bad.csv") && msg.contains("line 3") && msg.contains("two"), "{msg}");
        let other = temp_file("points.xyz", "1 2 3\n");
        assert!(read_points(&other).unwrap_err().to_string().contains("points.xyz"));
        let missing = std::env::temp_dir().join("baffle-io-no-such-file.fcsv");
        let msg = read_points(&missing).unwrap_err().to_string();
        assert!(msg.contains("baffle-io-no-such-file.fcsv") && msg.contains("not found"), "{msg}");
    }
}
