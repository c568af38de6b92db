//! Writer for VTK XML PolyData (`.vtp`): inline base64 binary, uncompressed,
//! UInt64 block headers, Float64 points, Int64 connectivity, as VTK 9 reads it.

use super::polydata::{ArrayValues, DataArray, PolyData};

/// The complete file text for a validated `PolyData`.
pub(crate) fn vtp_text(pd: &PolyData) -> String {
    let mut out = String::with_capacity(64 + pd.points.len() * 36 + pd.polys.len() * 48);
    out.push_str("<?xml version=\"1.0\"?>\n");
    out.push_str("<VTKFile type=\"PolyData\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n");
    out.push_str("  <PolyData>\n");
    out.push_str(&format!(
        "    <Piece NumberOfPoints=\"{}\" NumberOfVerts=\"0\" NumberOfLines=\"{}\" NumberOfStrips=\"0\" NumberOfPolys=\"{}\">\n",
        pd.points.len(),
        pd.lines.len(),
        pd.polys.len()
    ));
    push_attribute_section(&mut out, "PointData", &pd.point_data);
    push_attribute_section(&mut out, "CellData", &pd.cell_data);
    let coords: Vec<u8> = pd.points.iter().flat_map(|p| [p.x, p.y, p.z]).flat_map(f64::to_le_bytes).collect();
    out.push_str("      <Points>\n");
    push_binary_array(&mut out, "Float64", "Points", 3, &coords);
    out.push_str("      </Points>\n");
    // VTK order of the cell sections; vertices and strips are always empty here.
    push_cell_section(&mut out, "Verts", &[]);
    push_cell_section(&mut out, "Lines", &pd.lines);
    push_cell_section(&mut out, "Strips", &[]);
    push_cell_section(&mut out, "Polys", &pd.polys);
    out.push_str("    </Piece>\n  </PolyData>\n</VTKFile>\n");
    out
}

fn push_attribute_section(out: &mut String, tag: &str, arrays: &[DataArray]) {
    out.push_str(&format!("      <{tag}>\n"));
    for a in arrays {
        match &a.values {
            ArrayValues::I32(v) => {
                let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
                push_binary_array(out, "Int32", &a.name, 1, &bytes);
            }
            ArrayValues::F64 { components, values } => {
                let bytes: Vec<u8> = values.iter().flat_map(|x| x.to_le_bytes()).collect();
                push_binary_array(out, "Float64", &a.name, *components, &bytes);
            }
        }
    }
    out.push_str(&format!("      </{tag}>\n"));
}

fn push_cell_section(out: &mut String, tag: &str, cells: &[Vec<u32>]) {
    let connectivity: Vec<u8> = cells.iter().flatten().flat_map(|&i| (i as i64).to_le_bytes()).collect();
    let offsets: Vec<u8> = cells
        .iter()
        .scan(0i64, |end, c| {
            *end += c.len() as i64;
            Some(*end)
        })
        .flat_map(i64::to_le_bytes)
        .collect();
    out.push_str(&format!("      <{tag}>\n"));
    push_binary_array(out, "Int64", "connectivity", 1, &connectivity);
    push_binary_array(out, "Int64", "offsets", 1, &offsets);
    out.push_str(&format!("      </{tag}>\n"));
}

/// One `DataArray`: the byte-count header and the data as a single base64 stream,
/// as VTK writes uncompressed arrays (its reader mis-aligns a separately padded header).
fn push_binary_array(out: &mut String, scalar_type: &str, name: &str, components: usize, bytes: &[u8]) {
    out.push_str(&format!(
        "        <DataArray type=\"{scalar_type}\" Name=\"{}\" NumberOfComponents=\"{components}\" format=\"binary\">\n          ",
        escape_xml(name)
    ));
    let mut block = Vec::with_capacity(8 + bytes.len());
    block.extend_from_slice(&(bytes.len() as u64).to_le_bytes());
    block.extend_from_slice(bytes);
    base64_encode_into(out, &block);
    out.push_str("\n        </DataArray>\n");
}

fn escape_xml(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for ch in text.chars() {
        match ch {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c => out.push(c),
        }
    }
    out
}

const BASE64_ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

fn base64_encode_into(out: &mut String, bytes: &[u8]) {
    out.reserve(bytes.len().div_ceil(3) * 4);
    for chunk in bytes.chunks(3) {
        let b = [chunk[0], *chunk.get(1).unwrap_or(&0), *chunk.get(2).unwrap_or(&0)];
        let word = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(BASE64_ALPHABET[((word >> (18 - 6 * k)) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_rfc4648_examples() {
        for (plain, encoded) in [("", ""), ("f", "Zg=="), ("fo", "Zm8="), ("foo", "Zm9v"), ("foobar", "Zm9vYmFy")] {
            let mut s = String::new();
            base64_encode_into(&mut s, plain.as_bytes());
            assert_eq!(s, encoded);
        }
    }

    #[test]
    fn uncompressed_array_is_one_stream_like_vtk() {
        // VTK 9.7's own encoding of Int32 [7, 10, 11] with a UInt64 header.
        let values: Vec<u8> = [7i32, 10, 11].iter().flat_map(|v| v.to_le_bytes()).collect();
        let mut out = String::new();
        push_binary_array(&mut out, "Int32", "ModelFaceID", 1, &values);
        assert!(out.contains(">\n          DAAAAAAAAAAHAAAACgAAAAsAAAA=\n"), "{out}");
    }

    #[test]
    fn names_are_escaped() {
        assert_eq!(escape_xml("a<b&\"c\""), "a&lt;b&amp;&quot;c&quot;");
    }
}
