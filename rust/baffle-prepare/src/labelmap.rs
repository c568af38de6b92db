//! Multi-label label maps (NRRD as Slicer writes them, NIfTI-1 as nnU-Net writes
//! them, gzipped or not) and the blood-pool surfaces made from them [paper 2.2.2:
//! per-label binary masks, morphological closing, median filter, marching
//! (tetrahedra), smoothing]. Geometry is returned in LPS millimetres, the frame
//! Slicer writes models in (NIfTI's RAS and NRRD's RAS spaces are converted).

use crate::error::PrepareError;
use crate::input::BloodPools;
use crate::union_surface::{union_surface, SmoothingOptions};
use crate::voxelize::{close_mask, Grid};
use baffle_core::io::ScalarType;
use baffle_core::{TriMesh, Vec3};
use nalgebra::Matrix3;
use rayon::prelude::*;
use std::io::Read;
use std::path::Path;

/// A 3D label volume: `labels[i + nx (j + ny k)]`, and voxel (i, j, k)'s centre at
/// `origin_mm + axes_mm * (i, j, k)` (LPS; the columns of `axes_mm` are the
/// voxel steps, spacing included).
#[derive(Clone, Debug, PartialEq)]
pub struct LabelMap {
    pub dims: [usize; 3],
    pub labels: Vec<i32>,
    pub origin_mm: Vec3,
    pub axes_mm: Matrix3<f64>,
}

/// Which label value is which structure (defaults: LV 1, RV 2, aorta 6, as the
/// issue's label convention LV 1, RV 2, LA 3, RA 4, myo 5, aorta 6, PA 7).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PoolLabels {
    pub lv: i32,
    pub rv: i32,
    pub aorta: i32,
}

impl PoolLabels {
    /// One label per structure: two structures on one label would be one blood pool.
    pub fn check_distinct(&self) -> Result<(), PrepareError> {
        let named = [("LV", self.lv), ("RV", self.rv), ("aorta", self.aorta)];
        for (i, (a, la)) in named.iter().enumerate() {
            if let Some((b, _)) = named[i + 1..].iter().find(|(_, lb)| lb == la) {
                return Err(PrepareError::geometry("label map", format!("the {a} and the {b} have the same label {la}; each structure needs its own")));
            }
        }
        Ok(())
    }
}

impl Default for PoolLabels {
    fn default() -> Self {
        PoolLabels { lv: 1, rv: 2, aorta: 6 }
    }
}

/// Read `.nrrd`, `.nii` or `.nii.gz` by extension.
pub fn read_labelmap(path: &Path) -> Result<LabelMap, PrepareError> {
    let bytes = std::fs::read(path).map_err(|e| PrepareError::Read(format!("{}: {e}", path.display())))?;
    let name = path.file_name().map(|n| n.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    let fail = |m: String| PrepareError::Read(format!("{}: {m}", path.display()));
    if name.ends_with(".nrrd") {
        parse_nrrd(&bytes).map_err(fail)
    } else if name.ends_with(".nii") {
        parse_nifti(&bytes).map_err(fail)
    } else if name.ends_with(".nii.gz") {
        gunzip(&bytes).and_then(|raw| parse_nifti(&raw)).map_err(fail)
    } else {
        Err(fail("unknown label map extension (expected .nrrd, .nii or .nii.gz)".into()))
    }
}

/// Largest decompressed label map (4 GiB): a corrupt or hostile gzip stream must not
/// exhaust memory.
const MAX_GUNZIPPED_BYTES: u64 = 1 << 32;

fn gunzip(bytes: &[u8]) -> Result<Vec<u8>, String> {
    let mut out = Vec::new();
    flate2::read::MultiGzDecoder::new(bytes)
        .take(MAX_GUNZIPPED_BYTES + 1)
        .read_to_end(&mut out)
        .map_err(|e| format!("the gzip stream is truncated or corrupt ({e})"))?;
    if out.len() as u64 > MAX_GUNZIPPED_BYTES {
        return Err(format!("the gzip stream unpacks to more than {MAX_GUNZIPPED_BYTES} bytes"));
    }
    Ok(out)
}

/// Decode `count` samples; float labels are rounded.
fn decode(data: &[u8], sample: ScalarType, count: usize, little_endian: bool) -> Result<Vec<i32>, String> {
    let size = sample.size();
    let needed = count.checked_mul(size).ok_or_else(|| format!("{count} voxels of {size} bytes is more than memory holds"))?;
    if data.len() < needed {
        return Err(format!("{} bytes of voxel data for {count} voxels of {size} bytes", data.len()));
    }
    let word = |c: &[u8]| -> [u8; 8] {
        let mut w = [0u8; 8];
        w[..size].copy_from_slice(c);
        if !little_endian {
            w[..size].reverse();
        }
        w
    };
    Ok(data[..needed]
        .chunks_exact(size)
        .map(|c| {
            let w = word(c);
            match sample {
                ScalarType::I8 => w[0] as i8 as i32,
                ScalarType::U8 => w[0] as i32,
                ScalarType::I16 => i16::from_le_bytes([w[0], w[1]]) as i32,
                ScalarType::U16 => u16::from_le_bytes([w[0], w[1]]) as i32,
                ScalarType::I32 => i32::from_le_bytes([w[0], w[1], w[2], w[3]]),
                ScalarType::U32 => u32::from_le_bytes([w[0], w[1], w[2], w[3]]).min(i32::MAX as u32) as i32,
                ScalarType::F32 => f32::from_le_bytes([w[0], w[1], w[2], w[3]]).round() as i32,
                ScalarType::F64 => f64::from_le_bytes(w).round() as i32,
                // Neither format's header names these; clamped as U32 is.
                ScalarType::I64 => i64::from_le_bytes(w).clamp(i32::MIN as i64, i32::MAX as i64) as i32,
                ScalarType::U64 => u64::from_le_bytes(w).min(i32::MAX as u64) as i32,
            }
        })
        .collect())
}

fn nrrd_sample(name: &str) -> Result<ScalarType, String> {
    Ok(match name {
        "signed char" | "int8" | "int8_t" => ScalarType::I8,
        "uchar" | "unsigned char" | "uint8" | "uint8_t" => ScalarType::U8,
        "short" | "short int" | "signed short" | "signed short int" | "int16" | "int16_t" => ScalarType::I16,
        "ushort" | "unsigned short" | "unsigned short int" | "uint16" | "uint16_t" => ScalarType::U16,
        "int" | "signed int" | "int32" | "int32_t" => ScalarType::I32,
        "uint" | "unsigned int" | "uint32" | "uint32_t" => ScalarType::U32,
        "float" => ScalarType::F32,
        "double" => ScalarType::F64,
        other => return Err(format!("unsupported NRRD type '{other}'")),
    })
}

/// Parse "(a,b,c)" as a vector.
fn nrrd_vector(text: &str) -> Result<Vec3, String> {
    let inner = text.trim().trim_start_matches('(').trim_end_matches(')');
    let v: Vec<f64> = inner.split(',').map(|s| s.trim().parse::<f64>().map_err(|_| format!("bad number in '{text}'"))).collect::<Result<_, _>>()?;
    match v[..] {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(Vec3::new(x, y, z)),
        _ => Err(format!("expected a 3-vector, got '{text}'")),
    }
}

/// Attached-header NRRD (one file), 3D, raw or gzip.
pub fn parse_nrrd(bytes: &[u8]) -> Result<LabelMap, String> {
    if !bytes.starts_with(b"NRRD") {
        return Err("not a NRRD file (no NRRD magic)".into());
    }
    let header_end = bytes.windows(2).position(|w| w == b"\n\n").ok_or("NRRD header has no end (blank line)")?;
    let header = std::str::from_utf8(&bytes[..header_end]).map_err(|_| "NRRD header is not text")?;
    let mut fields = std::collections::HashMap::new();
    for line in header.lines().skip(1).filter(|l| !l.starts_with('#')) {
        if let Some((key, value)) = line.split_once(':') {
            fields.insert(key.trim().to_ascii_lowercase(), value.trim_start_matches('=').trim().to_string());
        }
    }
    let field = |k: &str| fields.get(k).map(String::as_str).ok_or_else(|| format!("NRRD header has no '{k}' field"));
    if fields.contains_key("data file") || fields.contains_key("datafile") {
        return Err("detached NRRD data files (.nhdr) are not supported; save as one .nrrd".into());
    }
    let dimension: usize = field("dimension")?.parse().map_err(|_| "bad NRRD dimension")?;
    if dimension != 3 {
        return Err(format!("NRRD dimension {dimension}: a 3D label map is needed (export the segmentation as a labelmap)"));
    }
    let sizes: Vec<usize> = field("sizes")?.split_whitespace().map(|s| s.parse().map_err(|_| format!("bad NRRD size '{s}'"))).collect::<Result<_, _>>()?;
    let dims: [usize; 3] = sizes.try_into().map_err(|_| "NRRD sizes must be 3 numbers")?;
    let sample = nrrd_sample(field("type")?)?;
    let little_endian = fields.get("endian").is_none_or(|e| e == "little");
    let directions: Vec<Vec3> = field("space directions")?.split_whitespace().map(nrrd_vector).collect::<Result<_, _>>()?;
    if directions.len() != 3 {
        return Err("NRRD space directions must be three vectors".into());
    }
    let origin = fields.get("space origin").map_or(Ok(Vec3::zeros()), |o| nrrd_vector(o))?;
    let ras = match fields.get("space").map(String::as_str) {
        Some("right-anterior-superior") | Some("RAS") => true,
        Some("left-posterior-superior") | Some("LPS") | None => false,
        Some(other) => return Err(format!("unsupported NRRD space '{other}'")),
    };
    let payload = &bytes[header_end + 2..];
    let data = match field("encoding")? {
        "raw" => payload.to_vec(),
        "gzip" | "gz" => gunzip(payload)?,
        other => return Err(format!("unsupported NRRD encoding '{other}'")),
    };
    let labels = decode(&data, sample, voxel_count(&dims)?, little_endian)?;
    let axes = Matrix3::from_columns(&directions);
    Ok(to_lps(LabelMap { dims, labels, origin_mm: origin, axes_mm: axes }, ras))
}

fn voxel_count(dims: &[usize; 3]) -> Result<usize, String> {
    dims.iter().try_fold(1usize, |a, &d| a.checked_mul(d)).ok_or_else(|| format!("image size {dims:?} overflows"))
}

/// Flip RAS coordinates to LPS (x and y change sign).
fn to_lps(mut map: LabelMap, ras: bool) -> LabelMap {
    if ras {
        let flip = Matrix3::from_diagonal(&Vec3::new(-1.0, -1.0, 1.0));
        map.origin_mm = flip * map.origin_mm;
        map.axes_mm = flip * map.axes_mm;
    }
    map
}

fn nifti_sample(code: i16) -> Result<ScalarType, String> {
    Ok(match code {
        2 => ScalarType::U8,
        4 => ScalarType::I16,
        8 => ScalarType::I32,
        16 => ScalarType::F32,
        64 => ScalarType::F64,
        256 => ScalarType::I8,
        512 => ScalarType::U16,
        768 => ScalarType::U32,
        other => return Err(format!("unsupported NIfTI datatype {other}")),
    })
}

/// NIfTI-1 single file (`n+1`), 3D; the sform if set, else the qform, else the
/// voxel sizes alone.
pub fn parse_nifti(bytes: &[u8]) -> Result<LabelMap, String> {
    if bytes.len() < 352 {
        return Err(format!("{} bytes is too short for a NIfTI-1 header", bytes.len()));
    }
    let little_endian = i32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]) == 348;
    if !little_endian && i32::from_be_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]) != 348 {
        return Err("not a NIfTI-1 file (sizeof_hdr is not 348)".into());
    }
    if &bytes[344..347] != b"n+1" {
        return Err("not a single-file NIfTI-1 image (magic is not n+1)".into());
    }
    let i16_at = |o: usize| if little_endian { i16::from_le_bytes([bytes[o], bytes[o + 1]]) } else { i16::from_be_bytes([bytes[o], bytes[o + 1]]) };
    let f32_at = |o: usize| {
        let b = [bytes[o], bytes[o + 1], bytes[o + 2], bytes[o + 3]];
        (if little_endian { f32::from_le_bytes(b) } else { f32::from_be_bytes(b) }) as f64
    };
    let ndim = i16_at(40);
    let extra: Vec<i16> = (4..=7).map(|d| i16_at(40 + 2 * d)).collect();
    if !(3..=7).contains(&ndim) || extra.iter().take(ndim as usize - 3).any(|&d| d > 1) {
        return Err(format!("NIfTI image has {ndim} dimensions: a 3D label map is needed"));
    }
    let dims = [1, 2, 3].map(|d| i16_at(40 + 2 * d).max(0) as usize);
    let sample = nifti_sample(i16_at(70))?;
    let vox_offset = f32_at(108) as usize;
    let data = bytes.get(vox_offset..).ok_or("NIfTI vox_offset is beyond the file")?;
    let raw = decode(data, sample, voxel_count(&dims)?, little_endian)?;
    let (slope, inter) = (f32_at(112), f32_at(116));
    let labels = if slope != 0.0 && (slope != 1.0 || inter != 0.0) {
        raw.iter().map(|&v| (v as f64 * slope + inter).round() as i32).collect()
    } else {
        raw
    };
    let pixdim = [1, 2, 3].map(|d| f32_at(76 + 4 * d));
    let (axes, origin) = if i16_at(254) > 0 {
        let row = |o: usize| [f32_at(o), f32_at(o + 4), f32_at(o + 8), f32_at(o + 12)];
        let (x, y, z) = (row(280), row(296), row(312));
        (Matrix3::new(x[0], x[1], x[2], y[0], y[1], y[2], z[0], z[1], z[2]), Vec3::new(x[3], y[3], z[3]))
    } else if i16_at(252) > 0 {
        qform_axes(f32_at(256), f32_at(260), f32_at(264), f32_at(76), pixdim, Vec3::new(f32_at(268), f32_at(272), f32_at(276)))
    } else {
        (Matrix3::from_diagonal(&Vec3::from(pixdim)), Vec3::zeros())
    };
    Ok(to_lps(LabelMap { dims, labels, origin_mm: origin, axes_mm: axes }, true))
}

/// The qform's voxel axes from its quaternion (b, c, d), qfac (pixdim[0]) and spacing.
fn qform_axes(b: f64, c: f64, d: f64, qfac: f64, pixdim: [f64; 3], offset: Vec3) -> (Matrix3<f64>, Vec3) {
    let a = (1.0 - (b * b + c * c + d * d)).max(0.0).sqrt();
    let r = Matrix3::new(
        a * a + b * b - c * c - d * d,
        2.0 * (b * c - a * d),
        2.0 * (b * d + a * c),
        2.0 * (b * c + a * d),
        a * a + c * c - b * b - d * d,
        2.0 * (c * d - a * b),
        2.0 * (b * d - a * c),
        2.0 * (c * d + a * b),
        a * a + d * d - c * c - b * b,
    );
    let q = if qfac < 0.0 { -1.0 } else { 1.0 };
    (r * Matrix3::from_diagonal(&Vec3::new(pixdim[0], pixdim[1], pixdim[2] * q)), offset)
}

/// Options of the label-map surfaces.
#[derive(Clone, Debug)]
pub struct LabelSurfaceOptions {
    /// Closing radius in voxels of each label's mask.
    pub closing_voxels: usize,
    /// 3x3x3 median (majority) filter of each closed mask.
    pub median: bool,
    pub smoothing: SmoothingOptions,
}

impl Default for LabelSurfaceOptions {
    fn default() -> Self {
        LabelSurfaceOptions { closing_voxels: 1, median: true, smoothing: SmoothingOptions::default() }
    }
}

/// The LV, RV and aorta surfaces of a label map (mm, LPS, outward): per label a
/// binary mask, closing, 3x3x3 median, marching tetrahedra, Taubin smoothing.
/// A label with no voxel is named.
pub fn pools_from_labelmap(map: &LabelMap, labels: &PoolLabels, options: &LabelSurfaceOptions) -> Result<BloodPools, PrepareError> {
    check_map(map)?;
    labels.check_distinct()?;
    let surface = |name: &'static str, value: i32| label_surface(map, name, value, options);
    Ok(BloodPools { lv: surface("LV", labels.lv)?, rv: surface("RV", labels.rv)?, aorta: surface("aorta", labels.aorta)? })
}

/// The pulmonary artery's surface of a label map, made as the pools' are: where the RV
/// outflow ends. None when no voxel has `label` (the label map still prepares; only the
/// RV outflow is then not measured). `label` must not be one of the pools'.
pub fn pulmonary_from_labelmap(map: &LabelMap, pools: &PoolLabels, label: i32, options: &LabelSurfaceOptions) -> Result<Option<TriMesh>, PrepareError> {
    check_map(map)?;
    if let Some((name, _)) = [("LV", pools.lv), ("RV", pools.rv), ("aorta", pools.aorta)].into_iter().find(|&(_, l)| l == label) {
        return Err(PrepareError::geometry("label map", format!("the pulmonary artery and the {name} have the same label {label}; each structure needs its own")));
    }
    if !map.labels.contains(&label) {
        return Ok(None);
    }
    label_surface(map, "pulmonary artery", label, options).map(Some)
}

/// As many labels as voxels, and finite, non-degenerate voxel axes.
fn check_map(map: &LabelMap) -> Result<(), PrepareError> {
    if voxel_count(&map.dims).ok() != Some(map.labels.len()) {
        return Err(PrepareError::geometry("label map", format!("{} labels for a {:?} image", map.labels.len(), map.dims)));
    }
    if !(map.axes_mm.determinant().abs() > 0.0 && map.axes_mm.iter().chain(map.origin_mm.iter()).all(|v| v.is_finite())) {
        return Err(PrepareError::geometry("label map", "the voxel axes are degenerate or not finite"));
    }
    Ok(())
}

/// Voxels padded on every side so the contour closes inside the grid.
const PAD: usize = 3;

fn label_surface(map: &LabelMap, name: &'static str, value: i32, options: &LabelSurfaceOptions) -> Result<TriMesh, PrepareError> {
    let [nx, ny, nz] = map.dims;
    let grid = Grid { origin: Vec3::repeat(-(PAD as f64)), spacing_mm: 1.0, dims: [nx + 2 * PAD, ny + 2 * PAD, nz + 2 * PAD] };
    let mut mask = vec![false; grid.voxel_count()];
    let mut count = 0usize;
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                if map.labels[i + nx * (j + ny * k)] == value {
                    mask[grid.index(i + PAD, j + PAD, k + PAD)] = true;
                    count += 1;
                }
            }
        }
    }
    if count == 0 {
        return Err(PrepareError::geometry("label map", format!("no voxel has the {name} label {value}")));
    }
    let closed = close_mask(&mask, &grid, options.closing_voxels);
    let cleaned = if options.median { median3(&closed, &grid) } else { closed };
    // Contour in voxel index space, then map to millimetres.
    let mut mesh = union_surface(&cleaned, &grid, &options.smoothing).map_err(|m| PrepareError::geometry("label map", format!("{name}: {m}")))?;
    mesh.points.iter_mut().for_each(|p| *p = map.origin_mm + map.axes_mm * *p);
    if map.axes_mm.determinant() < 0.0 {
        mesh.triangles.iter_mut().for_each(|t| t.swap(1, 2));
    }
    Ok(mesh)
}

/// 3x3x3 median (majority) of a binary mask.
fn median3(mask: &[bool], grid: &Grid) -> Vec<bool> {
    let [nx, ny, nz] = grid.dims;
    (0..mask.len())
        .into_par_iter()
        .map(|idx| {
            let [i, j, k] = grid.ijk(idx);
            if i == 0 || j == 0 || k == 0 || i + 1 == nx || j + 1 == ny || k + 1 == nz {
                return mask[idx];
            }
            let mut votes = 0;
            for dk in 0..3 {
                for dj in 0..3 {
                    for di in 0..3 {
                        votes += mask[grid.index(i + di - 1, j + dj - 1, k + dk - 1)] as usize;
                    }
                }
            }
            votes >= 14
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::prepare::{prepare, PrepareOptions};
    use crate::shapes::{capped_tube, uv_sphere};
    use crate::voxelize::voxelize;
    use std::io::Write;

    #[test]
    fn one_label_for_two_structures_is_named() {
        assert!(PoolLabels::default().check_distinct().is_ok());
        let e = PoolLabels { lv: 1, rv: 1, aorta: 2 }.check_distinct().unwrap_err().to_string();
        assert!(e.contains("the LV and the RV have the same label 1"), "{e}");
        let e = PoolLabels { lv: 1, rv: 2, aorta: 2 }.check_distinct().unwrap_err().to_string();
        assert!(e.contains("the RV and the aorta"), "{e}");
    }

    fn gzip(data: &[u8]) -> Vec<u8> {
        let mut z = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        z.write_all(data).unwrap();
        z.finish().unwrap()
    }

    /// NRRD as Slicer writes a labelmap (LPS, attached header), u16 samples.
    fn nrrd_bytes(map: &LabelMap, encoding: &str) -> Vec<u8> {
        let a = &map.axes_mm;
        let col = |c: usize| format!("({},{},{})", a[(0, c)], a[(1, c)], a[(2, c)]);
        let o = map.origin_mm;
        let header = format!(
            "NRRD0004\n# test\ntype: unsigned short\ndimension: 3\nspace: left-posterior-superior\nsizes: {} {} {}\nspace directions: {} {} {}\nkinds: domain domain domain\nendian: little\nencoding: {encoding}\nspace origin: ({},{},{})\n\n",
            map.dims[0], map.dims[1], map.dims[2], col(0), col(1), col(2), o.x, o.y, o.z
        );
        let raw: Vec<u8> = map.labels.iter().flat_map(|&l| (l as u16).to_le_bytes()).collect();
        let mut out = header.into_bytes();
        out.extend(if encoding == "gzip" { gzip(&raw) } else { raw });
        out
    }

    /// NIfTI-1 (RAS sform), u8 samples.
    fn nifti_bytes(map: &LabelMap) -> Vec<u8> {
        let mut h = vec![0u8; 352];
        h[0..4].copy_from_slice(&348i32.to_le_bytes());
        let dims = [3i16, map.dims[0] as i16, map.dims[1] as i16, map.dims[2] as i16, 1, 1, 1, 1];
        dims.iter().enumerate().for_each(|(d, v)| h[40 + 2 * d..42 + 2 * d].copy_from_slice(&v.to_le_bytes()));
        h[70..72].copy_from_slice(&2i16.to_le_bytes());
        h[72..74].copy_from_slice(&8i16.to_le_bytes());
        h[108..112].copy_from_slice(&352f32.to_le_bytes());
        h[254..256].copy_from_slice(&1i16.to_le_bytes());
        let flip = Matrix3::from_diagonal(&Vec3::new(-1.0, -1.0, 1.0));
        let (axes, origin) = (flip * map.axes_mm, flip * map.origin_mm);
        for r in 0..3 {
            for c in 0..4 {
                let v = if c < 3 { axes[(r, c)] } else { origin[r] } as f32;
                let o = 280 + 16 * r + 4 * c;
                h[o..o + 4].copy_from_slice(&v.to_le_bytes());
            }
        }
        h[344..348].copy_from_slice(b"n+1\0");
        h.extend(map.labels.iter().map(|&l| l as u8));
        h
    }

    fn small_map() -> LabelMap {
        let axes = Matrix3::new(0.0, 0.5, 0.0, -0.4, 0.0, 0.0, 0.0, 0.0, 0.7);
        let labels = (0..4 * 3 * 2).map(|v| (v % 7) as i32).collect();
        LabelMap { dims: [4, 3, 2], labels, origin_mm: Vec3::new(10.0, -20.0, 30.0), axes_mm: axes }
    }

    fn assert_same(a: &LabelMap, b: &LabelMap) {
        assert_eq!((a.dims, &a.labels), (b.dims, &b.labels));
        assert!((a.origin_mm - b.origin_mm).norm() < 1e-5 && (a.axes_mm - b.axes_mm).norm() < 1e-5, "{a:?} vs {b:?}");
    }

    #[test]
    fn the_median_removes_a_speck_and_fills_a_pinhole() {
        let grid = Grid { origin: Vec3::zeros(), spacing_mm: 1.0, dims: [7, 7, 7] };
        let mut speck = vec![false; grid.voxel_count()];
        speck[grid.index(3, 3, 3)] = true;
        assert!(median3(&speck, &grid).iter().all(|&m| !m));
        let mut block = vec![true; grid.voxel_count()];
        block[grid.index(3, 3, 3)] = false;
        assert!(median3(&block, &grid).iter().all(|&m| m));
    }

    #[test]
    fn nrrd_and_nifti_round_trip_in_lps() {
        let map = small_map();
        assert_same(&parse_nrrd(&nrrd_bytes(&map, "raw")).unwrap(), &map);
        assert_same(&parse_nrrd(&nrrd_bytes(&map, "gzip")).unwrap(), &map);
        assert_same(&parse_nifti(&nifti_bytes(&map)).unwrap(), &map);
        let dir = std::env::temp_dir().join(format!("baffle-labelmap-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("seg.nii.gz");
        std::fs::write(&path, gzip(&nifti_bytes(&map))).unwrap();
        assert_same(&read_labelmap(&path).unwrap(), &map);
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn bad_label_maps_are_named_errors() {
        let map = small_map();
        let mut truncated = nrrd_bytes(&map, "raw");
        truncated.truncate(truncated.len() - 5);
        assert!(parse_nrrd(&truncated).unwrap_err().contains("bytes of voxel data"));
        let four_d = String::from_utf8(nrrd_bytes(&map, "raw")).unwrap().replace("dimension: 3", "dimension: 4");
        assert!(parse_nrrd(four_d.as_bytes()).unwrap_err().contains("3D label map"));
        assert!(parse_nifti(&[0u8; 400]).unwrap_err().contains("NIfTI"));
        let huge = String::from_utf8(nrrd_bytes(&map, "raw")).unwrap().replace("sizes: 4 3 2", "sizes: 4000000000 4000000000 4000000000");
        assert!(parse_nrrd(huge.as_bytes()).unwrap_err().contains("overflows"));
        assert!(read_labelmap(Path::new("/nonexistent/seg.nrrd")).unwrap_err().to_string().contains("seg.nrrd"));
        let dir = std::env::temp_dir().join(format!("baffle-labelmap-cut-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let cut = dir.join("cut.nii.gz");
        let gz = gzip(&nifti_bytes(&map));
        std::fs::write(&cut, &gz[..gz.len() / 2]).unwrap();
        let msg = read_labelmap(&cut).unwrap_err().to_string();
        assert!(msg.contains("cut.nii.gz") && msg.contains("truncated or corrupt"), "{msg}");
        std::fs::remove_dir_all(&dir).ok();
        let short = LabelMap { labels: vec![1; 5], ..map.clone() };
        assert!(pools_from_labelmap(&short, &PoolLabels::default(), &LabelSurfaceOptions::default()).unwrap_err().to_string().contains("5 labels"));
        let err = pools_from_labelmap(&map, &PoolLabels { lv: 42, ..PoolLabels::default() }, &LabelSurfaceOptions::default());
        assert!(err.unwrap_err().to_string().contains("LV label 42"));
    }

    /// The synthetic heart of tests/synthetic.rs as a label map: RV (2) wins where
    /// pools overlap, the LV (1) touches it on a spherical cap, the aorta (6)
    /// leaves the RV.
    fn synthetic_labelmap(voxel_mm: f64) -> LabelMap {
        let lv = uv_sphere(Vec3::zeros(), 10.0, 48, 96);
        let rv = uv_sphere(Vec3::new(16.0, 0.0, 0.0), 9.0, 48, 96);
        let aorta = capped_tube(Vec3::new(16.0, 0.0, 4.0), Vec3::new(16.0, 0.0, 25.0), 4.0, 20, 64);
        let grid = Grid::covering(Vec3::new(-11.0, -11.0, -11.0), Vec3::new(26.0, 11.0, 26.0), voxel_mm, 2);
        let [m_lv, m_rv, m_ao] = [&lv, &rv, &aorta].map(|m| voxelize(m, &grid));
        let labels = (0..grid.voxel_count()).map(|v| if m_rv[v] { 2 } else if m_lv[v] { 1 } else if m_ao[v] { 6 } else { 0 }).collect();
        LabelMap { dims: grid.dims, labels, origin_mm: grid.origin, axes_mm: Matrix3::from_diagonal(&Vec3::repeat(voxel_mm)) }
    }

    #[test]
    fn the_pulmonary_label_gives_its_surface_or_none() {
        let mut map = synthetic_labelmap(0.5);
        let pools = PoolLabels::default();
        let options = LabelSurfaceOptions::default();
        assert_eq!(pulmonary_from_labelmap(&map, &pools, 7, &options).unwrap(), None, "no voxel has label 7");
        // A pulmonary box on the RV, beside the aorta (outside the RV only: the RV keeps its voxels).
        let grid = Grid { origin: map.origin_mm, spacing_mm: 0.5, dims: map.dims };
        let in_box = |p: Vec3| (20.0..24.0).contains(&p.x) && p.y.abs() < 3.0 && (5.0..11.0).contains(&p.z);
        let mut box_mm3 = 0.0;
        for v in 0..map.labels.len() {
            if map.labels[v] == 0 && in_box(grid.centre(v)) {
                map.labels[v] = 7;
                box_mm3 += 0.125;
            }
        }
        let pa = pulmonary_from_labelmap(&map, &pools, 7, &options).unwrap().expect("a pulmonary surface");
        // Outward, about the labelled volume (the smoothing rounds its edges), and where it was labelled.
        let volume_mm3 = pa.signed_volume_mm3();
        assert!((volume_mm3 / box_mm3 - 1.0).abs() < 0.25, "{volume_mm3} vs {box_mm3} mm3");
        assert!(pa.points.iter().all(|&p| (19.0..25.0).contains(&p.x) && p.y.abs() < 4.0 && (4.0..12.0).contains(&p.z)));
        let e = pulmonary_from_labelmap(&map, &pools, 2, &options).unwrap_err().to_string();
        assert!(e.contains("the pulmonary artery and the RV have the same label 2"), "{e}");
    }

    #[test]
    fn a_synthetic_labelmap_gives_the_exact_caps() {
        let map = synthetic_labelmap(0.4);
        // No median and no closing: each of them fills part of the wedge where
        // the synthetic pools part at their rims, and widens the exact openings.
        let label_options = LabelSurfaceOptions { median: false, ..LabelSurfaceOptions::default() };
        let pools = pools_from_labelmap(&map, &PoolLabels::default(), &label_options).unwrap();
        let (mesh, _) = prepare(&pools, &PrepareOptions { closing_radius_mm: 0.0, ..PrepareOptions::default() }).unwrap();
        let (x0, a) = (8.59375, (100.0f64 - 8.59375 * 8.59375).sqrt());
        for (label, center, radius) in [(11, Vec3::new(x0, 0.0, 0.0), a), (16, Vec3::new(16.0, 0.0, 65f64.sqrt()), 4.0)] {
            let (c, _, area) = mesh.label_centroid_normal(label).unwrap();
            let exact = std::f64::consts::PI * radius * radius;
            assert!((c - center).norm() < 0.6, "cap {label}: {c:?} vs {center:?}");
            assert!((area / exact - 1.0).abs() < 0.15, "cap {label}: {area:.1} vs {exact:.1} mm2");
        }
    }
}
