//! `baffle template` end to end: designed domains -> SVG and PDF templates, the SVG's
//! scale bar and check square read back in mm, the PDF rendered by poppler's pdftoppm
//! at 254 dpi (10 px per mm) and its scale bar and check square measured in pixels, and
//! the PNG decoded, its pHYs read and the same two measured at that resolution.

use std::path::{Path, PathBuf};
use std::process::Command;

fn baffle(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_baffle")).args(args).output().expect("run baffle")
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("baffle-template-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn ok(out: std::process::Output, what: &str) -> String {
    assert!(out.status.success(), "{what}: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Design the phantom from files and return (domain.vtp, suture points file).
fn phantom_design(dir: &Path) -> (PathBuf, PathBuf) {
    ok(baffle(&["phantom", "--out", dir.to_str().unwrap()]), "phantom");
    let (surface, points) = (dir.join("capped_ventricle.vtp"), dir.join("suture_points.mrk.json"));
    let design = dir.join("design");
    ok(
        baffle(&["design", "--surface", surface.to_str().unwrap(), "--points", points.to_str().unwrap(), "--bsa", "0.37", "--out", design.to_str().unwrap()]),
        "design",
    );
    (design.join("domain.vtp"), points)
}

/// Design patient `name` with its BSA from patients.json, or None without the data.
fn patient_design(name: &str, dir: &Path) -> Option<(PathBuf, PathBuf)> {
    let data = baffle_test_support::reference_data::reference_data_if_present()?;
    let table: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(data.join("patients.json")).unwrap()).unwrap();
    let bsa = table["patients"][name]["bsa_m2"].as_f64().unwrap().to_string();
    let input = data.join(name).join("design_input");
    let (surface, points) = (input.join("capped_ventricle.vtp"), input.join("suture_points.mrk.json"));
    let design = dir.join("design");
    ok(
        baffle(&["design", "--surface", surface.to_str().unwrap(), "--points", points.to_str().unwrap(), "--bsa", &bsa, "--out", design.to_str().unwrap()]),
        name,
    );
    Some((design.join("domain.vtp"), points))
}

fn template(domain: &Path, points: &Path, out: &Path, label: &str, method: &str) -> serde_json::Value {
    let stdout = ok(
        baffle(&[
            "template",
            "--domain",
            domain.to_str().unwrap(),
            "--points",
            points.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--label",
            label,
            "--method",
            method,
        ]),
        "template",
    );
    println!("{label}: {stdout}");
    let stem = out.file_stem().unwrap().to_string_lossy().into_owned();
    serde_json::from_str(&std::fs::read_to_string(out.with_file_name(format!("{stem}-report.json"))).unwrap()).unwrap()
}

fn attr_mm(node: &roxmltree::Node, name: &str) -> f64 {
    node.attribute(name).unwrap_or_else(|| panic!("no {name}")).parse().unwrap()
}

#[test]
fn the_svg_is_in_mm_with_a_10_mm_bar_and_square_and_the_seam_length_outline() {
    let dir = temp_dir("svg");
    let (domain, points) = phantom_design(&dir);
    let svg_path = dir.join("template.svg");
    let report = template(&domain, &points, &svg_path, "phantom", "lscm");
    let text = std::fs::read_to_string(&svg_path).unwrap();
    let doc = roxmltree::Document::parse(&text).unwrap();
    let root = doc.root_element();
    assert_eq!(root.attribute("width"), Some("210mm"));
    assert_eq!(root.attribute("height"), Some("297mm"));
    assert_eq!(root.attribute("viewBox"), Some("0 0 210 297"));
    let by_id = |id: &str| doc.descendants().find(|n| n.attribute("id") == Some(id)).unwrap_or_else(|| panic!("no #{id}"));
    let bar = by_id("scale-bar");
    assert_eq!(attr_mm(&bar, "width"), 10.0);
    let square = by_id("check-square");
    assert_eq!((attr_mm(&square, "width"), attr_mm(&square, "height")), (10.0, 10.0));
    // The outline drawn is as long as the 3D seam.
    let outline: Vec<(f64, f64)> = by_id("outline")
        .attribute("points")
        .unwrap()
        .split_whitespace()
        .map(|p| {
            let (x, y) = p.split_once(',').unwrap();
            (x.parse().unwrap(), y.parse().unwrap())
        })
        .collect();
    let n = outline.len();
    let perimeter: f64 = (0..n).map(|k| ((outline[(k + 1) % n].0 - outline[k].0).powi(2) + (outline[(k + 1) % n].1 - outline[k].1).powi(2)).sqrt()).sum();
    let seam = report["flattening"]["seam_length_3d_mm"].as_f64().unwrap();
    assert!((perimeter - seam).abs() <= 0.01 * seam, "outline {perimeter:.2} mm vs seam {seam:.2} mm");
    // One marker per suture point, named as in the markups file.
    let labels = baffle_core::io::read_points(&points).unwrap().labels;
    assert_eq!(report["suture_point_to_seam_mm"].as_array().unwrap().len(), labels.len());
    let texts: Vec<String> = doc.descendants().filter(|n| n.has_tag_name("text")).filter_map(|n| n.text().map(str::to_string)).collect();
    for label in &labels {
        assert!(!label.is_empty() && texts.contains(label), "suture point {label:?} is not on the template");
    }
    std::fs::remove_dir_all(dir).ok();
}

/// A binary PGM (P5, 8 bit) as (width, height, pixels).
fn read_pgm(path: &Path) -> (usize, usize, Vec<u8>) {
    let bytes = std::fs::read(path).unwrap();
    let mut fields = Vec::new();
    let mut pos = 0;
    while fields.len() < 4 {
        while bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        let start = pos;
        while !bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        fields.push(String::from_utf8_lossy(&bytes[start..pos]).into_owned());
    }
    assert_eq!(fields[0], "P5", "{}: not a binary PGM", path.display());
    let (w, h): (usize, usize) = (fields[1].parse().unwrap(), fields[2].parse().unwrap());
    let pixels = bytes[pos + 1..].to_vec();
    assert_eq!(pixels.len(), w * h);
    (w, h, pixels)
}

/// Render page 1 at 254 dpi (10 px per mm) in grey.
fn render(pdf: &Path) -> (usize, usize, Vec<u8>) {
    let prefix = pdf.with_file_name(format!("{}-render", pdf.file_stem().unwrap().to_string_lossy()));
    let status = Command::new("pdftoppm")
        .args(["-r", "254", "-gray", "-f", "1", "-l", "1", "-singlefile"])
        .arg(pdf)
        .arg(&prefix)
        .status()
        .expect("pdftoppm not found: install poppler-utils (.ci/run does)");
    assert!(status.success(), "pdftoppm failed on {}", pdf.display());
    read_pgm(&prefix.with_file_name(format!("{}.pgm", prefix.file_name().unwrap().to_string_lossy())))
}

/// The longest run of dark pixels along a row (or a column) inside [from, to).
fn dark_run(img: &(usize, usize, Vec<u8>), fixed: usize, from: usize, to: usize, along_row: bool) -> usize {
    let (w, _, px) = img;
    let (mut best, mut run) = (0, 0);
    for k in from..to {
        let v = if along_row { px[fixed * w + k] } else { px[k * w + fixed] };
        run = if v < 128 { run + 1 } else { 0 };
        best = best.max(run);
    }
    best
}

/// The PDF's scale bar and check square, rendered at 254 dpi (10 px per mm).
fn measure_pdf(pdf: &Path, name: &str) {
    // pdftoppm rounds the page up by a pixel; a 2 px tolerance covers its edge rounding.
    measure_page(&render(pdf), 254.0, name, 2.0);
}

/// The scale bar and the check square measured on a page image at `dpi`: both 10 mm
/// within `tol_px`.
fn measure_page(img: &(usize, usize, Vec<u8>), dpi: f64, name: &str, tol_px: f64) {
    use baffle_template::drawing::{CHECK_SQUARE_MM, CHECK_SQUARE_SIDE_MM, PAGE_HEIGHT_MM, PAGE_WIDTH_MM, SCALE_BAR_LENGTH_MM, SCALE_BAR_MM};
    let k = dpi / 25.4;
    let px = |mm: f64| (mm * k).round() as usize;
    assert!(img.0.abs_diff(px(PAGE_WIDTH_MM)) <= 1 && img.1.abs_diff(px(PAGE_HEIGHT_MM)) <= 1, "{name}: page {} x {} px at {dpi} dpi", img.0, img.1);
    let margin = px(5.0);
    let bar = dark_run(img, px(SCALE_BAR_MM.1), px(SCALE_BAR_MM.0) - margin, px(SCALE_BAR_MM.0 + SCALE_BAR_LENGTH_MM) + margin, true);
    let expected = SCALE_BAR_LENGTH_MM * k;
    println!("{name}: scale bar {bar} px at {dpi} dpi (10 mm = {expected:.2} px)");
    assert!((bar as f64 - expected).abs() <= tol_px, "{name}: scale bar {bar} px, expected {expected:.2} +- {tol_px}");
    // The square's edges: their centre lines (ink-weighted) are 10 mm apart across and down.
    let (sx, sy, side) = (CHECK_SQUARE_MM.0, CHECK_SQUARE_MM.1, CHECK_SQUARE_SIDE_MM);
    let across = edge_centre(img, px(sy + side / 2.0), px(sx + side), margin / 2, true) - edge_centre(img, px(sy + side / 2.0), px(sx), margin / 2, true);
    let down = edge_centre(img, px(sx + side / 2.0), px(sy + side), margin / 2, false) - edge_centre(img, px(sx + side / 2.0), px(sy), margin / 2, false);
    let expected = side * k;
    println!("{name}: check square {across:.2} x {down:.2} px between its edges' centre lines (expected {expected:.2})");
    for got in [across, down] {
        assert!((got - expected).abs() <= tol_px, "{name}: check square {across:.2} x {down:.2} px, expected {expected:.2} +- {tol_px}");
    }
}

/// The ink-weighted centre of a line crossing a row (or column) within `half` px of `around`.
fn edge_centre(img: &(usize, usize, Vec<u8>), fixed: usize, around: usize, half: usize, along_row: bool) -> f64 {
    let (w, _, px) = img;
    let ink = |k: usize| 255.0 - f64::from(if along_row { px[fixed * w + k] } else { px[k * w + fixed] });
    let window = around - half..around + half + 1;
    let total: f64 = window.clone().map(ink).sum();
    assert!(total > 0.0, "no line near pixel {around}");
    // Pixel k covers [k, k + 1): its centre is k + 0.5.
    window.map(|k| (k as f64 + 0.5) * ink(k)).sum::<f64>() / total
}

/// A PNG's pixels in grey (w, h, luma) and its pHYs resolution in dpi.
fn read_png(path: &Path) -> ((usize, usize, Vec<u8>), f64) {
    let decoder = png::Decoder::new(std::fs::File::open(path).unwrap());
    let mut reader = decoder.read_info().unwrap();
    let dims = reader.info().pixel_dims.unwrap_or_else(|| panic!("{}: no pHYs chunk", path.display()));
    assert!(matches!(dims.unit, png::Unit::Meter) && dims.xppu == dims.yppu, "{}: pHYs {dims:?}", path.display());
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb);
    let grey = buf[..info.buffer_size()].chunks_exact(3).map(|p| ((p[0] as u32 + p[1] as u32 + p[2] as u32) / 3) as u8).collect();
    ((info.width as usize, info.height as usize, grey), dims.xppu as f64 * 0.0254)
}

#[test]
fn png_templates_store_their_dpi_and_draw_the_scale_bar_at_10_mm() {
    let dir = temp_dir("png");
    let (domain, points) = phantom_design(&dir);
    for dpi in [300.0, 150.0] {
        let png_path = dir.join(format!("template-{dpi}.png"));
        let mut args = vec!["template", "--domain", domain.to_str().unwrap(), "--points", points.to_str().unwrap(), "--out", png_path.to_str().unwrap()];
        let dpi_text = dpi.to_string();
        if dpi != 300.0 {
            args.extend(["--dpi", &dpi_text]);
        }
        ok(baffle(&args), "template png");
        let (img, stored_dpi) = read_png(&png_path);
        // pHYs holds whole pixels per metre, 0.0254 dpi apart: 300 dpi is 11811 px/m.
        assert!((stored_dpi - dpi).abs() <= 0.0127 + 1e-9, "pHYs {stored_dpi} dpi, asked {dpi}");
        measure_page(&img, dpi, &format!("phantom png {dpi} dpi"), 1.0);
        // The distortion map and outline are drawn: the patch box is not blank.
        let inked = img.2.iter().filter(|&&v| v < 250).count();
        assert!(inked > 1000, "{inked} non-white pixels");
    }
    let out = baffle(&["template", "--domain", domain.to_str().unwrap(), "--points", points.to_str().unwrap(), "--out", dir.join("t.png").to_str().unwrap(), "--dpi", "5"]);
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("dpi = 5"), "{}", String::from_utf8_lossy(&out.stderr));
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn pdf_templates_print_the_scale_bar_at_10_mm() {
    let dir = temp_dir("pdf");
    let mut cases = vec![("phantom".to_string(), phantom_design(&dir.join("phantom")))];
    for name in ["p1", "p2", "p3"] {
        let d = dir.join(name);
        if let Some(files) = patient_design(name, &d) {
            cases.push((name.to_string(), files));
        }
    }
    for ((name, (domain, points)), method) in cases.iter().zip(["lscm", "arap"].iter().cycle()) {
        let pdf = dir.join(format!("{name}.pdf"));
        let report = template(domain, points, &pdf, name, method);
        assert!(report["flattening"]["method"].as_str().unwrap().to_lowercase().contains(method), "{name}: {report}");
        let bytes = std::fs::read(&pdf).unwrap();
        assert!(bytes.starts_with(b"%PDF-1.4") && bytes.ends_with(b"%%EOF\n"));
        let f = &report["flattening"];
        assert!(f["perimeter_error"].as_f64().unwrap() <= 0.01, "{name}: {f}");
        assert!(f["area_distortion_median"].as_f64().unwrap().is_finite(), "{name}: {f}");
        measure_pdf(&pdf, name);
    }
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn a_wrong_extension_and_a_domain_without_a_baffle_are_named() {
    let dir = temp_dir("errors");
    let (domain, points) = phantom_design(&dir);
    let out = baffle(&["template", "--domain", domain.to_str().unwrap(), "--points", points.to_str().unwrap(), "--out", dir.join("t.jpg").to_str().unwrap()]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("must end in .pdf, .svg or .png"));
    let out = baffle(&[
        "template",
        "--domain",
        domain.to_str().unwrap(),
        "--points",
        points.to_str().unwrap(),
        "--out",
        dir.join("t.svg").to_str().unwrap(),
        "--baffle-label",
        "99",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("domain.vtp") && err.contains("ModelFaceID 99"), "{err}");
    std::fs::remove_dir_all(dir).ok();
}
