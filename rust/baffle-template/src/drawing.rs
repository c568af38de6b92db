//! The template's page, laid out once in millimetres (A4 portrait, origin top left,
//! y down) as a list of shapes that the SVG and PDF writers both draw: the two files
//! cannot disagree on where anything is.

use super::{FlatPatch, Vec2};

pub const PAGE_WIDTH_MM: f64 = 210.0;
pub const PAGE_HEIGHT_MM: f64 = 297.0;
/// The 10 mm scale bar: a filled bar, 1 mm thick, left end at this point.
pub const SCALE_BAR_MM: (f64, f64) = (20.0, 265.0);
pub const SCALE_BAR_LENGTH_MM: f64 = 10.0;
pub const SCALE_BAR_THICKNESS_MM: f64 = 1.0;
/// The 10 mm check square (outlined), top-left corner.
pub const CHECK_SQUARE_MM: (f64, f64) = (60.0, 258.0);
pub const CHECK_SQUARE_SIDE_MM: f64 = 10.0;
/// Where the patch may go: it is centred in this box and must fit inside it.
const PATCH_BOX_MM: (f64, f64, f64, f64) = (15.0, 45.0, 195.0, 245.0);
/// Area distortion at which the colour map saturates (+-10 %).
pub const COLOUR_RANGE: f64 = 0.10;
/// Suture point and rim labels: small, as a baffle is only 20-35 mm across.
const TEXT_MM: f64 = 2.2;

/// A suture point as the surgeon placed it: its number and its place on the template.
#[derive(Clone, Debug)]
pub struct Marker {
    pub label: String,
    pub uv_mm: Vec2,
}

/// What goes on the page besides the patch.
#[derive(Clone, Debug, Default)]
pub struct TemplateText {
    pub patient_label: String,
    pub date: String,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rgb(pub f64, pub f64, pub f64);

pub const BLACK: Rgb = Rgb(0.0, 0.0, 0.0);

#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    Triangle {
        points: [(f64, f64); 3],
        fill: Rgb,
    },
    Polyline {
        points: Vec<(f64, f64)>,
        closed: bool,
        width_mm: f64,
        colour: Rgb,
        id: Option<&'static str>,
    },
    Rect {
        x: f64,
        y: f64,
        w: f64,
        h: f64,
        fill: Option<Rgb>,
        stroke_mm: Option<f64>,
        id: &'static str,
    },
    Dot {
        x: f64,
        y: f64,
        radius_mm: f64,
        colour: Rgb,
    },
    /// Left-anchored text, baseline at y; `centred` shifts it left by half its width.
    Text {
        x: f64,
        y: f64,
        size_mm: f64,
        text: String,
        centred: bool,
    },
}

/// A named part of the seam (boundary positions, in loop order) drawn over the outline.
#[derive(Clone, Debug)]
pub struct Rim {
    pub name: &'static str,
    pub colour: Rgb,
    pub boundary_positions: Vec<usize>,
}

/// Lay out the page. Errors if the patch does not fit the printable box at 1:1.
pub fn layout(flat: &FlatPatch, markers: &[Marker], rims: &[Rim], text: &TemplateText) -> Result<Vec<Shape>, String> {
    let to_page = page_transform(flat)?;
    let mut shapes = Vec::new();
    for (t, tri) in flat.triangles.iter().enumerate() {
        shapes.push(Shape::Triangle { points: tri.map(|i| to_page(flat.uv_mm[i as usize])), fill: colour(flat.area_ratio[t] - 1.0) });
    }
    let outline: Vec<(f64, f64)> = flat.boundary.iter().map(|&i| to_page(flat.uv_mm[i as usize])).collect();
    shapes.push(Shape::Polyline { points: outline.clone(), closed: true, width_mm: 0.3, colour: BLACK, id: Some("outline") });
    let centre = centroid(&outline);
    for rim in rims {
        shapes.extend(rim_shapes(rim, &outline, centre));
    }
    for m in markers {
        let p = to_page(m.uv_mm);
        shapes.push(Shape::Dot { x: p.0, y: p.1, radius_mm: 0.6, colour: BLACK });
        let (x, y) = pushed_out(p, centre, 4.0);
        shapes.push(Shape::Text { x, y: y + 0.35 * TEXT_MM, size_mm: TEXT_MM, text: m.label.clone(), centred: true });
    }
    shapes.extend(page_furniture(flat, text));
    Ok(shapes)
}

/// uv (mm, y up) -> page (mm, y down), the patch's bounding box centred in the patch box.
fn page_transform(flat: &FlatPatch) -> Result<impl Fn(Vec2) -> (f64, f64), String> {
    let (mut lo, mut hi) = (Vec2::repeat(f64::INFINITY), Vec2::repeat(f64::NEG_INFINITY));
    for p in &flat.uv_mm {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    let (x0, y0, x1, y1) = PATCH_BOX_MM;
    let size = hi - lo;
    if size.x > x1 - x0 || size.y > y1 - y0 {
        return Err(format!(
            "the flattened baffle ({:.1} x {:.1} mm) does not fit the A4 template's {:.0} x {:.0} mm patch area at 1:1",
            size.x,
            size.y,
            x1 - x0,
            y1 - y0
        ));
    }
    let mid = (lo + hi) / 2.0;
    let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
    Ok(move |p: Vec2| (cx + p.x - mid.x, cy - (p.y - mid.y)))
}

/// Blue where the patch is smaller than the baffle, white where equal, red where larger.
pub fn colour(area_change: f64) -> Rgb {
    let s = (area_change / COLOUR_RANGE).clamp(-1.0, 1.0);
    if s >= 0.0 {
        Rgb(1.0, 1.0 - 0.6 * s, 1.0 - 0.6 * s)
    } else {
        Rgb(1.0 + 0.6 * s, 1.0 + 0.6 * s, 1.0)
    }
}

fn centroid(points: &[(f64, f64)]) -> (f64, f64) {
    let n = points.len() as f64;
    (points.iter().map(|p| p.0).sum::<f64>() / n, points.iter().map(|p| p.1).sum::<f64>() / n)
}

/// `p` moved `by_mm` further from `centre`: labels sit outside the outline.
fn pushed_out(p: (f64, f64), centre: (f64, f64), by_mm: f64) -> (f64, f64) {
    let (dx, dy) = (p.0 - centre.0, p.1 - centre.1);
    let len = (dx * dx + dy * dy).sqrt().max(1e-9);
    (p.0 + by_mm * dx / len, p.1 + by_mm * dy / len)
}

/// The rim as runs of consecutive seam edges, thick and coloured, named at the middle
/// of its longest run.
fn rim_shapes(rim: &Rim, outline: &[(f64, f64)], centre: (f64, f64)) -> Vec<Shape> {
    let on: Vec<bool> = (0..outline.len()).map(|k| rim.boundary_positions.contains(&k)).collect();
    let runs = runs(&on);
    let mut shapes: Vec<Shape> = runs
        .iter()
        .filter(|run| run.len() >= 2)
        .map(|run| Shape::Polyline { points: run.iter().map(|&k| outline[k]).collect(), closed: false, width_mm: 1.0, colour: rim.colour, id: None })
        .collect();
    if let Some(longest) = runs.iter().max_by_key(|run| run.len()) {
        let (x, y) = pushed_out(outline[longest[longest.len() / 2]], centre, 8.0);
        shapes.push(Shape::Text { x, y, size_mm: TEXT_MM, text: rim.name.to_string(), centred: true });
    }
    shapes
}

/// Maximal runs of `true` around a closed loop, each as positions in order.
fn runs(on: &[bool]) -> Vec<Vec<usize>> {
    let n = on.len();
    let Some(start) = (0..n).find(|&k| !on[k]) else {
        return vec![(0..=n).map(|k| k % n).collect()];
    };
    let mut out: Vec<Vec<usize>> = Vec::new();
    let mut current: Vec<usize> = Vec::new();
    for step in 1..=n {
        let k = (start + step) % n;
        if on[k] {
            current.push(k);
        } else if !current.is_empty() {
            out.push(std::mem::take(&mut current));
        }
    }
    out
}

/// Title, scale bar, check square, colour legend and the flattening's numbers.
fn page_furniture(flat: &FlatPatch, text: &TemplateText) -> Vec<Shape> {
    let r = &flat.report;
    let line = |y: f64, s: String, size: f64| Shape::Text { x: 15.0, y, size_mm: size, text: s, centred: false };
    let mut shapes = vec![
        line(20.0, format!("Baffle patch template - {}", text.patient_label), 5.0),
        line(27.0, format!("{}   A4, print at 100 % (actual size): the bar and the square must measure 10 mm", text.date), 3.0),
        line(
            33.0,
            format!(
                "Seam {:.1} mm, template perimeter {:.1} mm; area change median {:.1} %, max {:.1} %; angle change median {:.1}, max {:.1} deg",
                r.seam_length_3d_mm,
                r.perimeter_mm,
                100.0 * r.area_distortion_median,
                100.0 * r.area_distortion_max,
                r.angle_distortion_median_deg,
                r.angle_distortion_max_deg
            ),
            2.6,
        ),
        line(38.0, "Seen from the right ventricle (outside of the pathway). Numbers: suture points as in the markups.".into(), 2.6),
        Shape::Rect {
            x: SCALE_BAR_MM.0,
            y: SCALE_BAR_MM.1 - SCALE_BAR_THICKNESS_MM / 2.0,
            w: SCALE_BAR_LENGTH_MM,
            h: SCALE_BAR_THICKNESS_MM,
            fill: Some(BLACK),
            stroke_mm: None,
            id: "scale-bar",
        },
        line(SCALE_BAR_MM.1 + 6.0, "10 mm".into(), 3.0),
        Shape::Rect {
            x: CHECK_SQUARE_MM.0,
            y: CHECK_SQUARE_MM.1,
            w: CHECK_SQUARE_SIDE_MM,
            h: CHECK_SQUARE_SIDE_MM,
            fill: None,
            stroke_mm: Some(0.2),
            id: "check-square",
        },
        Shape::Text { x: CHECK_SQUARE_MM.0, y: CHECK_SQUARE_MM.1 + CHECK_SQUARE_SIDE_MM + 6.0, size_mm: 3.0, text: "10 x 10 mm".into(), centred: false },
    ];
    shapes.extend(legend());
    shapes
}

/// The colour map's key: five swatches from -10 % to +10 % area change.
fn legend() -> Vec<Shape> {
    let (x0, y0) = (100.0, 258.0);
    let mut shapes = vec![Shape::Text { x: x0, y: y0 - 2.0, size_mm: 3.0, text: "Area change, template vs baffle".into(), centred: false }];
    for (k, change) in [-1.0, -0.5, 0.0, 0.5, 1.0].iter().map(|s| s * COLOUR_RANGE).enumerate() {
        let x = x0 + 16.0 * k as f64;
        shapes.push(Shape::Rect { x, y: y0, w: 14.0, h: 6.0, fill: Some(colour(change)), stroke_mm: Some(0.1), id: "legend" });
        shapes.push(Shape::Text { x: x + 7.0, y: y0 + 10.0, size_mm: 2.6, text: format!("{:+.0} %", 100.0 * change), centred: true });
    }
    shapes
}

/// The width of `text` in Helvetica at `size_mm` (its AFM widths for the characters the
/// template uses; other characters count as an average letter), to centre labels in PDF.
pub fn helvetica_width_mm(text: &str, size_mm: f64) -> f64 {
    let units: f64 = text
        .chars()
        .map(|c| match c {
            '0'..='9' | 'o' => 556.0,
            '+' => 584.0,
            '-' => 333.0,
            ' ' => 278.0,
            '%' => 889.0,
            'A' | 'B' | 'V' | 'S' => 667.0,
            'C' | 'D' => 722.0,
            _ => 556.0,
        })
        .sum();
    units / 1000.0 * size_mm
}

/// Today's date (UTC) as YYYY-MM-DD, from the system clock.
pub fn today_utc() -> String {
    let days = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs() / 86_400) as i64;
    let (y, m, d) = civil_from_days(days);
    format!("{y:04}-{m:02}-{d:02}")
}

/// Days since 1970-01-01 -> (year, month, day), proleptic Gregorian (H. Hinnant's algorithm).
fn civil_from_days(z: i64) -> (i64, u32, u32) {
    let z = z + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let m = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    (yoe + era * 400 + i64::from(m <= 2), m, d)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn civil_dates() {
        assert_eq!(civil_from_days(0), (1970, 1, 1));
        assert_eq!(civil_from_days(19_723), (2024, 1, 1));
        assert_eq!(civil_from_days(19_782), (2024, 2, 29));
    }

    #[test]
    fn runs_wrap_around_the_loop() {
        let on = [true, false, true, true, false, true];
        assert_eq!(runs(&on), vec![vec![2, 3], vec![5, 0]]);
    }
}
