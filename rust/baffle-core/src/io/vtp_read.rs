//! Reader for VTK XML PolyData (`.vtp`) as VTK 5-9, SimVascular and 3D Slicer write
//! it: ascii, inline base64 binary, appended raw or base64 data; uncompressed or
//! zlib-compressed; UInt32 or UInt64 block headers; either byte order.
//!
//! Own reader rather than vtkio 0.7.0-rc2, whose XML importer panics (capacity
//! overflow) on the empty zlib-compressed cell arrays the patient files contain.

use std::collections::HashMap;
use std::io::Read;

use quick_xml::events::{BytesStart, Event};
use quick_xml::Reader;

use super::error::{malformed, IoErrorKind};
use super::polydata::{assemble, CellSections, Numbers, PolyData};
use crate::geometry::mesh::Vec3;

/// Parse a whole `.vtp` file.
pub(crate) fn parse_vtp(bytes: &[u8]) -> Result<PolyData, IoErrorKind> {
    check_complete(bytes)?;
    let appended_start = find(bytes, b"<AppendedData");
    let xml_part = &bytes[..appended_start.unwrap_or(bytes.len())];
    let doc = scan_document(xml_part)?;
    let appended = match appended_start {
        Some(start) => Some(appended_section(bytes, start)?),
        None => None,
    };
    build_polydata(&doc, appended.as_ref())
}

/// How binary blocks are laid out (from the `VTKFile` element).
#[derive(Clone, Copy, Debug)]
struct Encoding {
    little_endian: bool,
    header_u64: bool,
    zlib: bool,
}

/// Section of a `Piece` a `DataArray` belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Section {
    PointData,
    CellData,
    Points,
    Verts,
    Lines,
    Polys,
    Strips,
}

/// A `DataArray` element as found in the XML, not yet decoded.
#[derive(Debug)]
struct ArrayElement {
    section: Section,
    name: String,
    scalar_type: String,
    components: usize,
    format: String,
    offset: Option<usize>,
    text: Vec<u8>,
}

#[derive(Debug, Default)]
struct PieceCounts {
    points: usize,
    verts: usize,
    lines: usize,
    polys: usize,
    strips: usize,
}

/// What the XML part of the file holds.
#[derive(Debug)]
struct Document {
    encoding: Encoding,
    counts: PieceCounts,
    arrays: Vec<ArrayElement>,
}

/// The data after `<AppendedData ...>_`, with its encoding.
struct Appended<'a> {
    base64: bool,
    data: &'a [u8],
}

/// A file cut short (an interrupted copy or write) can still hold whole arrays; only
/// its missing closing tag shows it is not the whole surface.
fn check_complete(bytes: &[u8]) -> Result<(), IoErrorKind> {
    let end = bytes.iter().rposition(|b| !b.is_ascii_whitespace() && *b != 0).map_or(0, |i| i + 1);
    if bytes[..end].ends_with(b"</VTKFile>") {
        Ok(())
    } else {
        Err(malformed(format!("the file ends after {end} bytes without </VTKFile>: it is truncated")))
    }
}

fn find(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    haystack.windows(needle.len()).position(|w| w == needle)
}

fn rfind(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    haystack.windows(needle.len()).rposition(|w| w == needle)
}

/// Locate the appended data: raw bytes may contain '<', so it is cut out by hand.
fn appended_section(bytes: &[u8], tag_start: usize) -> Result<Appended<'_>, IoErrorKind> {
    let rest = &bytes[tag_start..];
    let tag_end = find(rest, b">").ok_or_else(|| malformed("unterminated <AppendedData> tag"))?;
    let attrs = attributes_of_tag(&rest[..=tag_end])?;
    let base64 = match attrs.get("encoding").map(String::as_str) {
        Some("base64") => true,
        Some("raw") | None => false,
        Some(other) => return Err(IoErrorKind::Unsupported(format!("AppendedData encoding '{other}'"))),
    };
    let body = &rest[tag_end + 1..];
    let underscore = find(body, b"_").ok_or_else(|| malformed("AppendedData lacks the '_' start marker"))?;
    let data = &body[underscore + 1..];
    let end = rfind(data, b"</AppendedData>").unwrap_or(data.len());
    Ok(Appended { base64, data: &data[..end] })
}

fn attributes_of_tag(tag: &[u8]) -> Result<HashMap<String, String>, IoErrorKind> {
    let mut reader = Reader::from_reader(tag);
    match reader.read_event() {
        Ok(Event::Start(e)) | Ok(Event::Empty(e)) => attributes(&e),
        other => Err(malformed(format!("cannot parse tag {:?}: {other:?}", String::from_utf8_lossy(tag)))),
    }
}

fn attributes(e: &BytesStart) -> Result<HashMap<String, String>, IoErrorKind> {
    let tag = String::from_utf8_lossy(e.name().as_ref()).into_owned();
    let mut out = HashMap::new();
    for attr in e.attributes() {
        let attr = attr.map_err(|err| malformed(format!("bad attribute in <{tag}>: {err}")))?;
        let key = String::from_utf8_lossy(attr.key.as_ref()).into_owned();
        let value = attr.unescape_value().map_err(|err| malformed(format!("bad value of {tag}.{key}: {err}")))?;
        out.insert(key, value.into_owned());
    }
    Ok(out)
}

fn parse_count(attrs: &HashMap<String, String>, key: &str) -> Result<usize, IoErrorKind> {
    match attrs.get(key) {
        None => Ok(0),
        Some(v) => v.trim().parse().map_err(|_| malformed(format!("Piece attribute {key}=\"{v}\" is not a count"))),
    }
}

fn section_of(tag: &[u8]) -> Option<Section> {
    Some(match tag {
        b"PointData" => Section::PointData,
        b"CellData" => Section::CellData,
        b"Points" => Section::Points,
        b"Verts" => Section::Verts,
        b"Lines" => Section::Lines,
        b"Polys" => Section::Polys,
        b"Strips" => Section::Strips,
        _ => return None,
    })
}

/// The `DataArray` whose content is being read, if any.
enum OpenArray {
    None,
    Reading(ArrayElement),
    /// An array outside the piece sections (FieldData): its content is dropped.
    Skipping,
}

/// Walk the XML (up to any appended data) collecting header info and arrays.
fn scan_document(xml: &[u8]) -> Result<Document, IoErrorKind> {
    let mut reader = Reader::from_reader(xml);
    let mut encoding = None;
    let mut counts = None;
    let mut section = None;
    let mut arrays = Vec::new();
    let mut open = OpenArray::None;
    let mut depth_in_array = 0usize; // elements nested in a DataArray (InformationKey...)
    loop {
        let event = reader
            .read_event()
            .map_err(|e| malformed(format!("XML error near byte {}: {e}", reader.error_position())))?;
        let in_array = !matches!(open, OpenArray::None);
        match event {
            Event::Start(_) if in_array => depth_in_array += 1,
            Event::Empty(_) if in_array => {}
            Event::Start(ref e) | Event::Empty(ref e) => {
                let is_empty = matches!(event, Event::Empty(_));
                match e.name().as_ref() {
                    b"VTKFile" => encoding = Some(file_encoding(&attributes(e)?)?),
                    b"Piece" => {
                        if counts.is_some() {
                            return Err(IoErrorKind::Unsupported("more than one Piece".into()));
                        }
                        counts = Some(piece_counts(&attributes(e)?)?);
                    }
                    b"DataArray" => match (array_element(section, &attributes(e)?)?, is_empty) {
                        (Some(a), true) => arrays.push(a),
                        (Some(a), false) => open = OpenArray::Reading(a),
                        (None, false) => open = OpenArray::Skipping,
                        (None, true) => {}
                    },
                    tag if !is_empty => {
                        if let Some(s) = section_of(tag) {
                            section = Some(s);
                        }
                    }
                    _ => {}
                }
            }
            Event::Text(t) => {
                if let (OpenArray::Reading(a), 0) = (&mut open, depth_in_array) {
                    a.text.extend_from_slice(&t);
                }
            }
            Event::End(e) => {
                if depth_in_array > 0 {
                    depth_in_array -= 1;
                } else if e.name().as_ref() == b"DataArray" {
                    if let OpenArray::Reading(a) = std::mem::replace(&mut open, OpenArray::None) {
                        arrays.push(a);
                    }
                } else if section_of(e.name().as_ref()).is_some() {
                    section = None;
                }
            }
            Event::Eof => break,
            _ => {}
        }
    }
    let encoding = encoding.ok_or_else(|| malformed("no <VTKFile> element"))?;
    let counts = counts.ok_or_else(|| malformed("no <Piece> element"))?;
    Ok(Document { encoding, counts, arrays })
}

fn file_encoding(attrs: &HashMap<String, String>) -> Result<Encoding, IoErrorKind> {
    match attrs.get("type").map(String::as_str) {
        Some("PolyData") => {}
        other => return Err(IoErrorKind::Unsupported(format!("VTKFile type {other:?}, expected PolyData"))),
    }
    let little_endian = match attrs.get("byte_order").map(String::as_str) {
        Some("LittleEndian") | None => true,
        Some("BigEndian") => false,
        Some(other) => return Err(malformed(format!("unknown byte_order '{other}'"))),
    };
    let header_u64 = match attrs.get("header_type").map(String::as_str) {
        Some("UInt32") | None => false,
        Some("UInt64") => true,
        Some(other) => return Err(IoErrorKind::Unsupported(format!("header_type '{other}'"))),
    };
    let zlib = match attrs.get("compressor").map(String::as_str) {
        None | Some("") => false,
        Some("vtkZLibDataCompressor") => true,
        Some(other) => return Err(IoErrorKind::Unsupported(format!("compressor '{other}' (only zlib is supported)"))),
    };
    Ok(Encoding { little_endian, header_u64, zlib })
}

fn piece_counts(attrs: &HashMap<String, String>) -> Result<PieceCounts, IoErrorKind> {
    Ok(PieceCounts {
        points: parse_count(attrs, "NumberOfPoints")?,
        verts: parse_count(attrs, "NumberOfVerts")?,
        lines: parse_count(attrs, "NumberOfLines")?,
        polys: parse_count(attrs, "NumberOfPolys")?,
        strips: parse_count(attrs, "NumberOfStrips")?,
    })
}

/// Describe a `DataArray`; `None` when it is outside the sections we read.
fn array_element(
    section: Option<Section>,
    attrs: &HashMap<String, String>,
) -> Result<Option<ArrayElement>, IoErrorKind> {
    let Some(section) = section else { return Ok(None) };
    let name = attrs.get("Name").cloned().unwrap_or_default();
    let components = match attrs.get("NumberOfComponents") {
        None => 1,
        Some(v) => {
            v.trim().parse().map_err(|_| malformed(format!("DataArray '{name}': NumberOfComponents=\"{v}\"")))?
        }
    };
    let offset = match attrs.get("offset") {
        None => None,
        Some(v) => Some(v.trim().parse().map_err(|_| malformed(format!("DataArray '{name}': offset=\"{v}\"")))?),
    };
    Ok(Some(ArrayElement {
        section,
        scalar_type: attrs.get("type").cloned().unwrap_or_default(),
        format: attrs.get("format").cloned().unwrap_or_else(|| "ascii".into()),
        name,
        components,
        offset,
        text: Vec::new(),
    }))
}

/// Decode every array and put the piece together, checking counts against the header.
fn build_polydata(doc: &Document, appended: Option<&Appended>) -> Result<PolyData, IoErrorKind> {
    let counts = &doc.counts;
    let mut point_data = Vec::new();
    let mut cell_data = Vec::new();
    let mut points = Vec::new();
    let mut topology: HashMap<(Section, &str), Numbers> = HashMap::new();
    for a in &doc.arrays {
        let numbers = match decode_array(a, doc.encoding, appended)? {
            Some(n) => n,
            None => continue, // non-numeric array (String, Bit): not used by the design
        };
        match a.section {
            Section::PointData => point_data.push(numbers.into_array(&a.name, a.components)),
            Section::CellData => cell_data.push(numbers.into_array(&a.name, a.components)),
            Section::Points => points = to_points(numbers, counts.points)?,
            s => {
                topology.insert((s, a.name.as_str()), numbers);
            }
        }
    }
    if points.len() != counts.points {
        return Err(IoErrorKind::ArrayLength {
            array: "Points".into(),
            expected: 3 * counts.points,
            found: 3 * points.len(),
        });
    }
    let mut cells = |s: Section, n: usize, label: &str| -> Result<Vec<Vec<u32>>, IoErrorKind> {
        let connectivity = topology.remove(&(s, "connectivity"));
        let offsets = topology.remove(&(s, "offsets"));
        to_cells(label, connectivity, offsets, n, counts.points)
    };
    let sections = CellSections {
        verts: cells(Section::Verts, counts.verts, "Verts")?.len(),
        lines: cells(Section::Lines, counts.lines, "Lines")?,
        polys: cells(Section::Polys, counts.polys, "Polys")?,
        strips: cells(Section::Strips, counts.strips, "Strips")?,
    };
    assemble(points, sections, point_data, cell_data)
}

fn to_points(numbers: Numbers, expected_points: usize) -> Result<Vec<Vec3>, IoErrorKind> {
    let coords = numbers.into_f64();
    if coords.len() != 3 * expected_points {
        return Err(IoErrorKind::ArrayLength {
            array: "Points".into(),
            expected: 3 * expected_points,
            found: coords.len(),
        });
    }
    Ok(coords.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect())
}

/// Split `connectivity` by end `offsets` (a leading 0 is tolerated) into `n` cells.
fn to_cells(
    label: &str,
    connectivity: Option<Numbers>,
    offsets: Option<Numbers>,
    n: usize,
    num_points: usize,
) -> Result<Vec<Vec<u32>>, IoErrorKind> {
    let (connectivity, mut offsets) = match (connectivity, offsets) {
        (Some(c), Some(o)) => {
            (c.into_indices(&format!("{label}/connectivity"))?, o.into_indices(&format!("{label}/offsets"))?)
        }
        (None, None) if n == 0 => return Ok(Vec::new()),
        _ => return Err(malformed(format!("{label} needs both 'connectivity' and 'offsets' arrays for {n} cells"))),
    };
    if offsets.len() == n + 1 && offsets.first() == Some(&0) {
        offsets.remove(0);
    }
    if offsets.len() != n {
        return Err(IoErrorKind::ArrayLength { array: format!("{label}/offsets"), expected: n, found: offsets.len() });
    }
    let mut cells = Vec::with_capacity(n);
    let mut start = 0usize;
    for (c, &end) in offsets.iter().enumerate() {
        let end = end as usize;
        if end < start || end > connectivity.len() {
            return Err(malformed(format!(
                "{label}/offsets[{c}] = {end} is outside {start}..={} (connectivity length)",
                connectivity.len()
            )));
        }
        let cell = connectivity[start..end]
            .iter()
            .map(|&i| {
                u32::try_from(i).ok().filter(|&i| (i as usize) < num_points).ok_or_else(|| {
                    IoErrorKind::IndexOutOfRange { cell: format!("{label} cell {c}"), index: i, num_points }
                })
            })
            .collect::<Result<Vec<u32>, _>>()?;
        cells.push(cell);
        start = end;
    }
    Ok(cells)
}

/// Decode one array's values; `None` for non-numeric types.
fn decode_array(a: &ArrayElement, enc: Encoding, appended: Option<&Appended>) -> Result<Option<Numbers>, IoErrorKind> {
    let Some(scalar) = ScalarType::parse(&a.scalar_type) else { return Ok(None) };
    let context = |e: IoErrorKind| malformed(format!("DataArray '{}': {e}", a.name));
    let numbers = match a.format.as_str() {
        "ascii" => parse_ascii(&a.text, scalar).map_err(context)?,
        "binary" => {
            let bytes = read_block(&mut Base64Source::new(&a.text, 0), enc).map_err(context)?;
            scalar.decode(&bytes, enc.little_endian).map_err(context)?
        }
        "appended" => {
            let appended = appended.ok_or_else(|| context(malformed("format=appended but no <AppendedData>")))?;
            let offset = a.offset.ok_or_else(|| context(malformed("format=appended without an offset")))?;
            let bytes = if appended.base64 {
                read_block(&mut Base64Source::new(appended.data, offset), enc)
            } else {
                read_block(&mut RawSource { bytes: appended.data, pos: offset }, enc)
            }
            .map_err(context)?;
            scalar.decode(&bytes, enc.little_endian).map_err(context)?
        }
        other => return Err(context(IoErrorKind::Unsupported(format!("format '{other}'")))),
    };
    Ok(Some(numbers))
}

/// The binary sample types of VTK arrays and of image voxels (NRRD, NIfTI), by size and
/// signedness.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ScalarType {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    I64,
    U64,
    F32,
    F64,
}

impl ScalarType {
    fn parse(name: &str) -> Option<Self> {
        use ScalarType::*;
        Some(match name {
            "Int8" | "Char" => I8,
            "UInt8" | "UnsignedChar" => U8,
            "Int16" => I16,
            "UInt16" => U16,
            "Int32" => I32,
            "UInt32" => U32,
            "Int64" => I64,
            "UInt64" => U64,
            "Float32" => F32,
            "Float64" => F64,
            _ => return None,
        })
    }

    /// Bytes a sample.
    pub fn size(self) -> usize {
        use ScalarType::*;
        match self {
            I8 | U8 => 1,
            I16 | U16 => 2,
            I32 | U32 | F32 => 4,
            I64 | U64 | F64 => 8,
        }
    }

    fn is_float(self) -> bool {
        matches!(self, ScalarType::F32 | ScalarType::F64)
    }

    /// Decode packed values of this type.
    fn decode(self, bytes: &[u8], little_endian: bool) -> Result<Numbers, IoErrorKind> {
        let size = self.size();
        if !bytes.len().is_multiple_of(size) {
            return Err(malformed(format!("{} bytes is not a whole number of {self:?} values", bytes.len())));
        }
        let word = |chunk: &[u8]| -> [u8; 8] {
            let mut w = [0u8; 8];
            if little_endian {
                w[..size].copy_from_slice(chunk);
            } else {
                for (k, b) in chunk.iter().rev().enumerate() {
                    w[k] = *b;
                }
            }
            w // little-endian, zero-extended
        };
        let chunks = bytes.chunks_exact(size);
        use ScalarType::*;
        Ok(match self {
            F32 => {
                Numbers::Float(chunks.map(|c| f32::from_le_bytes(word(c)[..4].try_into().unwrap()) as f64).collect())
            }
            F64 => Numbers::Float(chunks.map(|c| f64::from_le_bytes(word(c))).collect()),
            I8 => Numbers::Int(chunks.map(|c| c[0] as i8 as i64).collect()),
            U8 => Numbers::Int(chunks.map(|c| c[0] as i64).collect()),
            I16 => Numbers::Int(chunks.map(|c| i16::from_le_bytes(word(c)[..2].try_into().unwrap()) as i64).collect()),
            U16 => Numbers::Int(chunks.map(|c| u16::from_le_bytes(word(c)[..2].try_into().unwrap()) as i64).collect()),
            I32 => Numbers::Int(chunks.map(|c| i32::from_le_bytes(word(c)[..4].try_into().unwrap()) as i64).collect()),
            U32 => Numbers::Int(chunks.map(|c| u32::from_le_bytes(word(c)[..4].try_into().unwrap()) as i64).collect()),
            I64 => Numbers::Int(chunks.map(|c| i64::from_le_bytes(word(c))).collect()),
            U64 => {
                let values = chunks.map(|c| u64::from_le_bytes(word(c))).collect::<Vec<_>>();
                Numbers::Int(values.into_iter().map(u64_to_i64).collect::<Result<_, _>>()?)
            }
        })
    }
}

fn u64_to_i64(x: u64) -> Result<i64, IoErrorKind> {
    i64::try_from(x).map_err(|_| malformed(format!("UInt64 value {x} is too large")))
}

fn parse_ascii(text: &[u8], scalar: ScalarType) -> Result<Numbers, IoErrorKind> {
    let text = std::str::from_utf8(text).map_err(|_| malformed("ascii data is not UTF-8"))?;
    let tokens = text.split_ascii_whitespace().enumerate();
    let bad = |i: usize, tok: &str| malformed(format!("value {i} '{tok}' is not a {scalar:?} number"));
    if scalar.is_float() {
        tokens.map(|(i, tok)| tok.parse::<f64>().map_err(|_| bad(i, tok))).collect::<Result<_, _>>().map(Numbers::Float)
    } else if scalar == ScalarType::U64 {
        tokens
            .map(|(i, tok)| tok.parse::<u64>().map_err(|_| bad(i, tok)).and_then(u64_to_i64))
            .collect::<Result<_, _>>()
            .map(Numbers::Int)
    } else {
        tokens.map(|(i, tok)| tok.parse::<i64>().map_err(|_| bad(i, tok))).collect::<Result<_, _>>().map(Numbers::Int)
    }
}

/// Sequential access to encoded bytes (raw appended data, or base64 text).
trait ByteSource {
    fn take(&mut self, n: usize) -> Result<Vec<u8>, IoErrorKind>;
}

struct RawSource<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl ByteSource for RawSource<'_> {
    fn take(&mut self, n: usize) -> Result<Vec<u8>, IoErrorKind> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.bytes.len()).ok_or_else(|| {
            malformed(format!("appended data ends at byte {}, needed {n} bytes from {}", self.bytes.len(), self.pos))
        })?;
        let out = self.bytes[self.pos..end].to_vec();
        self.pos = end;
        Ok(out)
    }
}

/// Base64 decoded group by group: VTK encodes header and data as separately padded
/// streams, so '=' may appear mid-text and each 4-character group stands alone.
struct Base64Source<'a> {
    text: &'a [u8],
    pos: usize,
    carry: Vec<u8>,
}

impl<'a> Base64Source<'a> {
    fn new(text: &'a [u8], pos: usize) -> Self {
        Base64Source { text, pos, carry: Vec::new() }
    }

    /// Next 4 non-whitespace characters decoded (1-3 bytes), or `None` at the end.
    fn next_group(&mut self) -> Result<Option<([u8; 3], usize)>, IoErrorKind> {
        let mut sextets = [0u32; 4];
        let mut padding = 0;
        let mut filled = 0;
        while filled < 4 {
            let Some(&ch) = self.text.get(self.pos) else {
                return if filled == 0 { Ok(None) } else { Err(malformed("base64 data ends mid-group")) };
            };
            self.pos += 1;
            if ch.is_ascii_whitespace() {
                continue;
            }
            sextets[filled] = match ch {
                b'=' => {
                    padding += 1;
                    0
                }
                _ if padding > 0 => return Err(malformed(format!("base64 data has '{}' after padding", ch as char))),
                _ => base64_value(ch).ok_or_else(|| malformed(format!("invalid base64 character '{}'", ch as char)))?,
            };
            filled += 1;
        }
        if padding > 2 {
            return Err(malformed("base64 group with more than 2 padding characters"));
        }
        let word = (sextets[0] << 18) | (sextets[1] << 12) | (sextets[2] << 6) | sextets[3];
        Ok(Some(([(word >> 16) as u8, (word >> 8) as u8, word as u8], 3 - padding)))
    }
}

impl ByteSource for Base64Source<'_> {
    fn take(&mut self, n: usize) -> Result<Vec<u8>, IoErrorKind> {
        let mut out = std::mem::take(&mut self.carry);
        // Capacity bounded by the text left, so a corrupt header cannot force a huge allocation.
        out.reserve(n.min((self.text.len() - self.pos.min(self.text.len())) / 4 * 3 + 3));
        while out.len() < n {
            let (bytes, len) =
                self.next_group()?.ok_or_else(|| malformed(format!("base64 data ends early: needed {n} bytes")))?;
            out.extend_from_slice(&bytes[..len]);
        }
        self.carry = out.split_off(n);
        Ok(out)
    }
}

fn base64_value(ch: u8) -> Option<u32> {
    Some(match ch {
        b'A'..=b'Z' => ch - b'A',
        b'a'..=b'z' => ch - b'a' + 26,
        b'0'..=b'9' => ch - b'0' + 52,
        b'+' => 62,
        b'/' => 63,
        _ => return None,
    } as u32)
}

fn read_header_word(src: &mut dyn ByteSource, enc: Encoding) -> Result<usize, IoErrorKind> {
    let size = if enc.header_u64 { 8 } else { 4 };
    let bytes = src.take(size)?;
    let mut w = [0u8; 8];
    if enc.little_endian {
        w[..size].copy_from_slice(&bytes);
    } else {
        for (k, b) in bytes.iter().rev().enumerate() {
            w[k] = *b;
        }
    }
    usize::try_from(u64::from_le_bytes(w)).map_err(|_| malformed("block header value too large"))
}

/// One array's bytes: `[n][data]`, or zlib `[nblocks][block size][last size][sizes...][blocks]`.
fn read_block(src: &mut dyn ByteSource, enc: Encoding) -> Result<Vec<u8>, IoErrorKind> {
    if !enc.zlib {
        let n = read_header_word(src, enc)?;
        return src.take(n);
    }
    let num_blocks = read_header_word(src, enc)?;
    let block_size = read_header_word(src, enc)?;
    let last_size = read_header_word(src, enc)?;
    let compressed_sizes = (0..num_blocks).map(|_| read_header_word(src, enc)).collect::<Result<Vec<_>, _>>()?;
    let mut out = Vec::new();
    for (b, &compressed) in compressed_sizes.iter().enumerate() {
        let is_last = b + 1 == num_blocks;
        let expected = if is_last && last_size != 0 { last_size } else { block_size };
        let block = src.take(compressed)?;
        let before = out.len();
        flate2::read::ZlibDecoder::new(&block[..])
            .take(expected as u64 + 1)
            .read_to_end(&mut out)
            .map_err(|e| malformed(format!("zlib block {b}: {e}")))?;
        if out.len() - before != expected {
            return Err(malformed(format!(
                "zlib block {b} inflates to {} bytes, header says {expected}",
                out.len() - before
            )));
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_groups_decode_across_separate_padded_streams() {
        // "AQ==" is [1], "AgM=" is [2, 3]: two streams back to back.
        let mut src = Base64Source::new(b"AQ==\n AgM=", 0);
        assert_eq!(src.take(3).unwrap(), vec![1, 2, 3]);
        assert!(src.take(1).is_err());
    }

    #[test]
    fn zlib_block_header_is_honoured() {
        let data: Vec<u8> = (0..100u8).collect();
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        std::io::Write::write_all(&mut z, &data).unwrap();
        let compressed = z.finish().unwrap();
        let mut raw = Vec::new();
        for w in [1u32, 100, 100, compressed.len() as u32] {
            raw.extend_from_slice(&w.to_le_bytes());
        }
        raw.extend_from_slice(&compressed);
        let enc = Encoding { little_endian: true, header_u64: false, zlib: true };
        assert_eq!(read_block(&mut RawSource { bytes: &raw, pos: 0 }, enc).unwrap(), data);
        // Zero blocks: an empty array (what crashed vtkio).
        let empty: Vec<u8> = [0u32, 32768, 0].iter().flat_map(|w| w.to_le_bytes()).collect();
        assert!(read_block(&mut RawSource { bytes: &empty, pos: 0 }, enc).unwrap().is_empty());
        // A header claiming more data than present is an error, not a panic.
        raw.truncate(raw.len() - 1);
        assert!(read_block(&mut RawSource { bytes: &raw, pos: 0 }, enc).is_err());
    }

    #[test]
    fn big_endian_values_decode() {
        let bytes = 1.5f64.to_be_bytes();
        assert_eq!(ScalarType::F64.decode(&bytes, false).unwrap(), Numbers::Float(vec![1.5]));
        let bytes = (-7i32).to_be_bytes();
        assert_eq!(ScalarType::I32.decode(&bytes, false).unwrap(), Numbers::Int(vec![-7]));
    }

    #[test]
    fn ascii_vtp_with_all_cell_kinds_parses() {
        let xml = br#"<?xml version="1.0"?>
<VTKFile type="PolyData" version="0.1" byte_order="LittleEndian">
  <PolyData>
    <Piece NumberOfPoints="4" NumberOfVerts="1" NumberOfLines="1" NumberOfStrips="1" NumberOfPolys="1">
      <PointData><DataArray type="Float32" Name="s" format="ascii">0 1 2 3</DataArray></PointData>
      <CellData><DataArray type="UInt8" Name="ModelFaceID" format="ascii">1 2 3 4</DataArray></CellData>
      <Points><DataArray type="Float32" NumberOfComponents="3" format="ascii">
        0 0 0  1 0 0  0 1 0  1 1 0
        <InformationKey name="L2_NORM_RANGE"><Value index="0">0</Value></InformationKey>
      </DataArray></Points>
      <Verts><DataArray type="Int32" Name="connectivity" format="ascii">0</DataArray>
             <DataArray type="Int32" Name="offsets" format="ascii">1</DataArray></Verts>
      <Lines><DataArray type="Int32" Name="connectivity" format="ascii">0 3</DataArray>
             <DataArray type="Int32" Name="offsets" format="ascii">2</DataArray></Lines>
      <Strips><DataArray type="Int32" Name="connectivity" format="ascii">0 1 2 3</DataArray>
             <DataArray type="Int32" Name="offsets" format="ascii">4</DataArray></Strips>
      <Polys><DataArray type="Int32" Name="connectivity" format="ascii">0 1 2</DataArray>
             <DataArray type="Int32" Name="offsets" format="ascii">3</DataArray></Polys>
    </Piece>
  </PolyData>
</VTKFile>"#;
        let pd = parse_vtp(xml).unwrap();
        assert_eq!(pd.lines, vec![vec![0, 3]]);
        assert_eq!(pd.polys, vec![vec![0, 1, 2], vec![0, 1, 2], vec![2, 1, 3]]);
        assert_eq!(pd.cell_array("ModelFaceID").unwrap().as_i32().unwrap(), &[2, 3, 4, 4]);
        assert_eq!(pd.point_array("s").unwrap().as_f64().unwrap(), (1, &[0.0, 1.0, 2.0, 3.0][..]));
    }

    #[test]
    fn wrong_point_count_is_reported() {
        let xml = br#"<VTKFile type="PolyData"><PolyData><Piece NumberOfPoints="2">
            <Points><DataArray type="Float64" NumberOfComponents="3" format="ascii">0 0 0</DataArray></Points>
            </Piece></PolyData></VTKFile>"#;
        let msg = parse_vtp(xml).unwrap_err().to_string();
        assert!(msg.contains("Points") && msg.contains("expected 6"), "{msg}");
    }

    #[test]
    fn a_file_cut_before_its_closing_tags_is_truncated() {
        let xml = br#"<VTKFile type="PolyData"><PolyData><Piece NumberOfPoints="1">
            <Points><DataArray type="Float64" NumberOfComponents="3" format="ascii">0 0 0</DataArray></Points>
            </Piece>"#;
        let msg = parse_vtp(xml).unwrap_err().to_string();
        assert!(msg.contains("without </VTKFile>: it is truncated"), "{msg}");
        let mut whole = xml.to_vec();
        whole.extend_from_slice(b"</PolyData></VTKFile>\n\0");
        parse_vtp(&whole).unwrap();
    }
}
