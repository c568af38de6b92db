//! STL (ascii or binary) to an indexed triangle mesh. STL stores every triangle's
//! corners separately; corners with bit-identical coordinates are merged into one point.
//! STL has no labels and no units (millimetres are assumed).

use std::collections::HashMap;

use super::error::{malformed, IoErrorKind};
use crate::geometry::mesh::{TriMesh, Vec3};

/// Parse a whole STL file.
pub(crate) fn parse_stl(bytes: &[u8]) -> Result<TriMesh, IoErrorKind> {
    let corners = if is_binary_stl(bytes) { binary_corners(bytes)? } else { ascii_corners(bytes)? };
    Ok(index_corners(&corners))
}

/// Binary when the size matches the triangle count in the header, or when the file
/// is not "solid ..." text: binary files often start with "solid" too.
fn is_binary_stl(bytes: &[u8]) -> bool {
    if bytes.len() >= 84 {
        let count = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as u64;
        if 84 + 50 * count == bytes.len() as u64 {
            return true;
        }
    }
    let looks_ascii = bytes.trim_ascii_start().starts_with(b"solid") && std::str::from_utf8(bytes).is_ok();
    !looks_ascii
}

fn binary_corners(bytes: &[u8]) -> Result<Vec<[Vec3; 3]>, IoErrorKind> {
    if bytes.len() < 84 {
        return Err(malformed(format!("binary STL of {} bytes is shorter than its 84-byte header", bytes.len())));
    }
    let count = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as usize;
    let expected = 84 + 50 * count;
    if bytes.len() != expected {
        return Err(malformed(format!(
            "binary STL header says {count} triangles ({expected} bytes), file has {}",
            bytes.len()
        )));
    }
    let read_f32 = |at: usize| f32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]]) as f64;
    let corners = (0..count)
        .map(|t| {
            // 12 bytes of normal, then three corners of 3 x f32, then 2 attribute bytes.
            let base = 84 + 50 * t + 12;
            let corner = |k: usize| {
                let at = base + 12 * k;
                Vec3::new(read_f32(at), read_f32(at + 4), read_f32(at + 8))
            };
            [corner(0), corner(1), corner(2)]
        })
        .collect();
    Ok(corners)
}

fn ascii_corners(bytes: &[u8]) -> Result<Vec<[Vec3; 3]>, IoErrorKind> {
    let text = std::str::from_utf8(bytes).map_err(|_| malformed("ascii STL is not valid UTF-8"))?;
    let mut corners = Vec::new();
    let mut facet: Vec<Vec3> = Vec::with_capacity(3);
    for (line_no, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("vertex") => facet.push(parse_vertex(words, line_no + 1)?),
            Some("endfacet") => {
                let corner: [Vec3; 3] = facet.as_slice().try_into().map_err(|_| {
                    malformed(format!("line {}: facet has {} vertices, expected 3", line_no + 1, facet.len()))
                })?;
                corners.push(corner);
                facet.clear();
            }
            _ => {}
        }
    }
    if !facet.is_empty() {
        return Err(malformed("ascii STL ends inside a facet"));
    }
    Ok(corners)
}

fn parse_vertex<'a>(words: impl Iterator<Item = &'a str>, line_no: usize) -> Result<Vec3, IoErrorKind> {
    let coords = words
        .map(|w| w.parse::<f64>().map_err(|_| malformed(format!("line {line_no}: '{w}' is not a number"))))
        .collect::<Result<Vec<_>, _>>()?;
    match coords.as_slice() {
        [x, y, z] => Ok(Vec3::new(*x, *y, *z)),
        _ => Err(malformed(format!("line {line_no}: vertex has {} coordinates, expected 3", coords.len()))),
    }
}

/// Merge bit-identical corners into shared points.
fn index_corners(corners: &[[Vec3; 3]]) -> TriMesh {
    let mut index_of: HashMap<[u64; 3], u32> = HashMap::with_capacity(corners.len() / 2 + 3);
    let mut points = Vec::new();
    let mut triangles = Vec::with_capacity(corners.len());
    for tri in corners {
        let ids = tri.map(|p| {
            let key = [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()];
            *index_of.entry(key).or_insert_with(|| {
                points.push(p);
                (points.len() - 1) as u32
            })
        });
        triangles.push(ids);
    }
    let face_ids = vec![0; triangles.len()];
    TriMesh::new(points, triangles, face_ids)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn facet_with_two_vertices_names_the_line() {
        let text =
            "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nendloop\nendfacet\nendsolid x\n";
        let msg = parse_stl(text.as_bytes()).unwrap_err().to_string();
        assert!(msg.contains("line 7") && msg.contains("2 vertices"), "{msg}");
    }

    #[test]
    fn binary_with_solid_header_is_detected_by_size() {
        let mut bytes = b"solid but binary".to_vec();
        bytes.resize(80, b' ');
        bytes.extend_from_slice(&0u32.to_le_bytes());
        assert!(is_binary_stl(&bytes));
        assert!(parse_stl(&bytes).unwrap().triangles.is_empty());
    }
}
