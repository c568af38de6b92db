//! gmsh's MSH 2.2 ASCII format: the labelled surface we hand gmsh, and the parser for the
//! volume mesh it writes back (`-format msh22`). Only what this crate exchanges is
//! supported: nodes, 3-node triangles, 4-node tets; points and lines are skipped.

use crate::error::MeshError;
use baffle_core::Vec3;
use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::Path;

/// gmsh element type numbers (MSH 2.2).
const MSH_POINT: u32 = 15;
const MSH_LINE: u32 = 1;
const MSH_TRIANGLE: u32 = 2;
const MSH_TET: u32 = 4;

/// A labelled triangle surface written as MSH 2.2: one node per point (tag = index + 1),
/// each triangle with physical tag = elementary tag = its label, so gmsh makes one discrete
/// surface per label.
pub fn surface_msh22_text(points_mm: &[Vec3], triangles: &[[u32; 3]], labels: &[i32]) -> String {
    let mut s = String::with_capacity(64 * (points_mm.len() + triangles.len()) + 128);
    s.push_str("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n");
    let _ = writeln!(s, "{}", points_mm.len());
    for (i, p) in points_mm.iter().enumerate() {
        let _ = writeln!(s, "{} {:e} {:e} {:e}", i + 1, p.x, p.y, p.z);
    }
    s.push_str("$EndNodes\n$Elements\n");
    let _ = writeln!(s, "{}", triangles.len());
    for (k, (t, &label)) in triangles.iter().zip(labels).enumerate() {
        let _ = writeln!(
            s,
            "{} {MSH_TRIANGLE} 2 {label} {label} {} {} {}",
            k + 1,
            t[0] + 1,
            t[1] + 1,
            t[2] + 1
        );
    }
    s.push_str("$EndElements\n");
    s
}

/// What gmsh wrote: node tags and coordinates, triangles with their physical tag, tets.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MshVolume {
    pub node_tags: Vec<u64>,
    pub nodes_mm: Vec<Vec3>,
    /// (physical tag, node tags)
    pub triangles: Vec<(i32, [u64; 3])>,
    pub tets: Vec<[u64; 4]>,
}

impl MshVolume {
    /// Node tag -> index into `nodes_mm`.
    pub fn node_index(&self) -> HashMap<u64, u32> {
        self.node_tags
            .iter()
            .enumerate()
            .map(|(i, &t)| (t, i as u32))
            .collect()
    }
}

pub fn read_msh22(path: &Path) -> Result<MshVolume, MeshError> {
    let text = std::fs::read_to_string(path).map_err(|e| MeshError::file(path, e.to_string()))?;
    parse_msh22(&text).map_err(|message| MeshError::MalformedMsh {
        path: path.to_path_buf(),
        message,
    })
}

/// Parse MSH 2.2 ASCII text; errors name the line.
pub fn parse_msh22(text: &str) -> Result<MshVolume, String> {
    let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l.trim()));
    let mut mesh = MshVolume::default();
    let (mut saw_format, mut saw_nodes, mut saw_elements) = (false, false, false);
    while let Some((no, line)) = lines.next() {
        match line {
            "$MeshFormat" => {
                parse_format(&mut lines)?;
                saw_format = true;
            }
            "$Nodes" => {
                parse_nodes(&mut lines, &mut mesh)?;
                saw_nodes = true;
            }
            "$Elements" => {
                parse_elements(&mut lines, &mut mesh)?;
                saw_elements = true;
            }
            l if l.starts_with("$End") || l.is_empty() => {}
            l if l.starts_with('$') => skip_section(&mut lines, &l[1..], no)?,
            _ => {
                return Err(format!(
                    "line {no}: unexpected '{}' outside a section",
                    short(line)
                ))
            }
        }
    }
    match (saw_format, saw_nodes, saw_elements) {
        (false, _, _) => Err("no $MeshFormat section".into()),
        (_, false, _) => Err("no $Nodes section".into()),
        (_, _, false) => Err("no $Elements section".into()),
        _ => Ok(mesh),
    }
}

type Lines<'a> = dyn Iterator<Item = (usize, &'a str)> + 'a;

fn next_line<'a>(lines: &mut Lines<'a>, what: &str) -> Result<(usize, &'a str), String> {
    lines
        .next()
        .ok_or_else(|| format!("file ends inside {what}"))
}

fn parse_format(lines: &mut Lines<'_>) -> Result<(), String> {
    let (no, line) = next_line(lines, "$MeshFormat")?;
    let fields: Vec<&str> = line.split_whitespace().collect();
    match fields.as_slice() {
        [version, "0", _] if version.starts_with("2.") => Ok(()),
        [version, "1", _] => Err(format!(
            "line {no}: binary MSH {version} is not supported; ask gmsh for ASCII"
        )),
        _ => Err(format!(
            "line {no}: expected ASCII MSH 2.2 ('2.2 0 8'), found '{}'",
            short(line)
        )),
    }
}

fn parse_count(lines: &mut Lines<'_>, what: &str) -> Result<usize, String> {
    let (no, line) = next_line(lines, what)?;
    line.parse().map_err(|_| {
        format!(
            "line {no}: expected the number of {what}, found '{}'",
            short(line)
        )
    })
}

fn parse_nodes(lines: &mut Lines<'_>, mesh: &mut MshVolume) -> Result<(), String> {
    let count = parse_count(lines, "nodes")?;
    mesh.node_tags.reserve(count);
    mesh.nodes_mm.reserve(count);
    for _ in 0..count {
        let (no, line) = next_line(lines, "$Nodes")?;
        let f: Vec<&str> = line.split_whitespace().collect();
        let bad = || format!("line {no}: expected 'tag x y z', found '{}'", short(line));
        if f.len() != 4 {
            return Err(bad());
        }
        let tag: u64 = f[0].parse().map_err(|_| bad())?;
        let mut xyz = [0.0f64; 3];
        for k in 0..3 {
            xyz[k] = f[k + 1].parse().map_err(|_| bad())?;
        }
        if !xyz.iter().all(|v| v.is_finite()) {
            return Err(format!("line {no}: node {tag} has a non-finite coordinate"));
        }
        mesh.node_tags.push(tag);
        mesh.nodes_mm.push(Vec3::new(xyz[0], xyz[1], xyz[2]));
    }
    expect_end(lines, "$EndNodes")
}

fn parse_elements(lines: &mut Lines<'_>, mesh: &mut MshVolume) -> Result<(), String> {
    let count = parse_count(lines, "elements")?;
    for _ in 0..count {
        let (no, line) = next_line(lines, "$Elements")?;
        parse_element(no, line, mesh)?;
    }
    expect_end(lines, "$EndElements")
}

/// `id type ntags tag... node...`; the first tag is the physical group.
fn parse_element(no: usize, line: &str, mesh: &mut MshVolume) -> Result<(), String> {
    let bad = |why: &str| format!("line {no}: {why} in element '{}'", short(line));
    let f: Vec<u64> = line
        .split_whitespace()
        .map(|x| x.parse::<i64>().map(|v| v as u64))
        .collect::<Result<_, _>>()
        .map_err(|_| bad("non-integer field"))?;
    if f.len() < 3 {
        return Err(bad("too few fields"));
    }
    let (kind, ntags) = (f[1] as u32, f[2] as usize);
    let nodes = f.get(3 + ntags..).ok_or_else(|| bad("too few fields"))?;
    let physical = f.get(3).map_or(0, |&t| t as i64 as i32);
    match (kind, nodes.len()) {
        (MSH_TRIANGLE, 3) if ntags > 0 => mesh
            .triangles
            .push((physical, [nodes[0], nodes[1], nodes[2]])),
        (MSH_TET, 4) => mesh.tets.push([nodes[0], nodes[1], nodes[2], nodes[3]]),
        (MSH_POINT, 1) | (MSH_LINE, 2) => {}
        (MSH_TRIANGLE, _) | (MSH_TET, _) => {
            return Err(bad("wrong number of nodes (or no physical tag)"))
        }
        _ => {
            return Err(bad(&format!(
                "element type {kind} is not a linear triangle or tet"
            )))
        }
    }
    Ok(())
}

fn expect_end(lines: &mut Lines<'_>, end: &str) -> Result<(), String> {
    let (no, line) = next_line(lines, end)?;
    if line == end {
        Ok(())
    } else {
        Err(format!(
            "line {no}: expected {end}, found '{}'",
            short(line)
        ))
    }
}

fn skip_section(lines: &mut Lines<'_>, name: &str, start: usize) -> Result<(), String> {
    let end = format!("$End{name}");
    for (_, line) in lines {
        if line == end {
            return Ok(());
        }
    }
    Err(format!("line {start}: section ${name} has no {end}"))
}

fn short(line: &str) -> String {
    line.chars().take(80).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn written_surface_parses_back() {
        let points = vec![Vec3::new(0.1, 0.2, 0.3), Vec3::x(), Vec3::y(), Vec3::z()];
        let tris = vec![[0, 1, 2], [0, 3, 1]];
        let text = surface_msh22_text(&points, &tris, &[2, 16]);
        let mesh = parse_msh22(&text).unwrap();
        assert_eq!(mesh.nodes_mm, points);
        assert_eq!(mesh.node_tags, vec![1, 2, 3, 4]);
        assert_eq!(mesh.triangles, vec![(2, [1, 2, 3]), (16, [1, 4, 2])]);
        assert!(mesh.tets.is_empty());
    }

    #[test]
    fn tets_and_skipped_sections_parse() {
        let text = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n1\n3 1 \"v\"\n$EndPhysicalNames\n\
                    $Nodes\n4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n7 0 0 1\n$EndNodes\n\
                    $Elements\n3\n1 15 2 0 1 1\n2 4 2 1 1 1 2 3 7\n3 1 2 0 4 1 2\n$EndElements\n";
        let mesh = parse_msh22(text).unwrap();
        assert_eq!(mesh.tets, vec![[1, 2, 3, 7]]);
        assert_eq!(mesh.node_index()[&7], 3);
    }

    #[test]
    fn errors_name_the_line() {
        let text = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n1\n1 0 zero 0\n$EndNodes\n";
        let err = parse_msh22(text).unwrap_err();
        assert!(err.starts_with("line 6:"), "{err}");
        let v4 = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n";
        assert!(parse_msh22(v4).unwrap_err().contains("MSH 2.2"));
        let quad = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n0\n$EndNodes\n$Elements\n1\n1 11 2 1 1 1 2 3 4 5 6 7 8 9 10\n$EndElements\n";
        assert!(parse_msh22(quad).unwrap_err().contains("element type 11"));
        assert!(parse_msh22("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n")
            .unwrap_err()
            .contains("$Nodes"));
    }
}
