//! The template as a PNG: the same page's shapes rasterized (tiny-skia) at a chosen
//! resolution, with that resolution stored in the file's pHYs chunk (pixels per metre),
//! so an image viewer or printer that honours it prints the page 1:1.
//!
//! Text uses the public-domain 8x8 bitmap glyphs (font8x8), each glyph pixel a block of
//! the right size in mm: no font file to ship or find on the machine.

use super::drawing::{Rgb, Shape, PAGE_HEIGHT_MM, PAGE_WIDTH_MM};
use tiny_skia::{FillRule, LineCap, LineJoin, Paint, PathBuilder, Pixmap, Rect, Stroke, Transform};

pub const DEFAULT_DPI: f64 = 300.0;
/// Beyond this the A4 page would not fit comfortably in memory (1200 dpi: 560 MB).
pub const MAX_DPI: f64 = 1200.0;
const MM_PER_INCH: f64 = 25.4;
/// A glyph's advance and its cell height as fractions of the text size (em): close to
/// Helvetica's average letter width and cap height, so the lines fit where the PDF's do.
const GLYPH_ADVANCE_EM: f64 = 0.5;
const GLYPH_HEIGHT_EM: f64 = 0.82;

/// Pixels per millimetre at `dpi`.
pub fn px_per_mm(dpi: f64) -> f64 {
    dpi / MM_PER_INCH
}

/// The page's size in pixels at `dpi`.
pub fn page_px(dpi: f64) -> (u32, u32) {
    let k = px_per_mm(dpi);
    ((PAGE_WIDTH_MM * k).round() as u32, (PAGE_HEIGHT_MM * k).round() as u32)
}

/// Rasterize the page at `dpi` and encode it as an RGB PNG with pHYs = `dpi`.
pub fn to_png(shapes: &[Shape], dpi: f64) -> Result<Vec<u8>, String> {
    if !(dpi.is_finite() && (10.0..=MAX_DPI).contains(&dpi)) {
        return Err(format!("dpi = {dpi}: the PNG template needs 10 to {MAX_DPI} dpi"));
    }
    let pixmap = rasterize(shapes, dpi)?;
    encode(&pixmap, dpi)
}

/// The page as pixels: white, the distortion map first, everything else over it.
pub fn rasterize(shapes: &[Shape], dpi: f64) -> Result<Pixmap, String> {
    let (w, h) = page_px(dpi);
    let mut pixmap = Pixmap::new(w, h).ok_or_else(|| format!("cannot allocate a {w} x {h} px page"))?;
    pixmap.fill(tiny_skia::Color::WHITE);
    let mm = Transform::from_scale(px_per_mm(dpi) as f32, px_per_mm(dpi) as f32);
    let triangles_first = shapes.iter().filter(|s| matches!(s, Shape::Triangle { .. })).chain(shapes.iter().filter(|s| !matches!(s, Shape::Triangle { .. })));
    for shape in triangles_first {
        draw(&mut pixmap, shape, mm);
    }
    Ok(pixmap)
}

fn draw(pixmap: &mut Pixmap, shape: &Shape, mm: Transform) {
    match shape {
        // Without anti-aliasing: neighbouring triangles then leave no light seams.
        Shape::Triangle { points, fill } => fill_path(pixmap, polygon(points, true), *fill, false, mm),
        Shape::Polyline { points, closed, width_mm, colour, .. } => {
            stroke_path(pixmap, polygon(points, *closed), *colour, *width_mm, LineCap::Round, LineJoin::Round, mm)
        }
        Shape::Rect { x, y, w, h, fill, stroke_mm, .. } => {
            let rect = Rect::from_xywh(*x as f32, *y as f32, *w as f32, *h as f32).map(PathBuilder::from_rect);
            if let Some(f) = fill {
                // Crisp edges: the scale bar's length in pixels is then exact to a pixel.
                fill_path(pixmap, rect.clone(), *f, false, mm);
            }
            if let Some(width) = stroke_mm {
                stroke_path(pixmap, rect, Rgb(0.0, 0.0, 0.0), *width, LineCap::Butt, LineJoin::Miter, mm);
            }
        }
        Shape::Dot { x, y, radius_mm, colour } => fill_path(pixmap, PathBuilder::from_circle(*x as f32, *y as f32, *radius_mm as f32), *colour, true, mm),
        Shape::Text { x, y, size_mm, text, centred } => {
            let x0 = if *centred { x - text_width_mm(text, *size_mm) / 2.0 } else { *x };
            fill_path(pixmap, text_path(text, x0, *y, *size_mm), Rgb(0.0, 0.0, 0.0), false, mm);
        }
    }
}

fn paint(colour: Rgb, anti_alias: bool) -> Paint<'static> {
    let mut paint = Paint::default();
    let byte = |v: f64| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    paint.set_color_rgba8(byte(colour.0), byte(colour.1), byte(colour.2), 255);
    paint.anti_alias = anti_alias;
    paint
}

fn fill_path(pixmap: &mut Pixmap, path: Option<tiny_skia::Path>, colour: Rgb, anti_alias: bool, mm: Transform) {
    if let Some(path) = path {
        pixmap.fill_path(&path, &paint(colour, anti_alias), FillRule::Winding, mm, None);
    }
}

fn stroke_path(pixmap: &mut Pixmap, path: Option<tiny_skia::Path>, colour: Rgb, width_mm: f64, line_cap: LineCap, line_join: LineJoin, mm: Transform) {
    if let Some(path) = path {
        let stroke = Stroke { width: width_mm as f32, line_cap, line_join, ..Stroke::default() };
        pixmap.stroke_path(&path, &paint(colour, true), &stroke, mm, None);
    }
}

/// Page points (mm) as a path; `None` for fewer than two points.
fn polygon(points: &[(f64, f64)], closed: bool) -> Option<tiny_skia::Path> {
    let mut pb = PathBuilder::new();
    let (first, rest) = points.split_first()?;
    pb.move_to(first.0 as f32, first.1 as f32);
    for p in rest {
        pb.line_to(p.0 as f32, p.1 as f32);
    }
    if closed {
        pb.close();
    }
    pb.finish()
}

/// The width (mm) of `text` in the bitmap font at `size_mm`.
pub fn text_width_mm(text: &str, size_mm: f64) -> f64 {
    text.chars().count() as f64 * GLYPH_ADVANCE_EM * size_mm
}

/// Every set glyph pixel of `text` as a small square (mm), left end at `x`, baseline at
/// `y`: the glyphs' eighth row is below the baseline (descenders).
fn text_path(text: &str, x: f64, y: f64, size_mm: f64) -> Option<tiny_skia::Path> {
    let (cell_w, cell_h) = (GLYPH_ADVANCE_EM * size_mm / 8.0, GLYPH_HEIGHT_EM * size_mm / 8.0);
    let top = y - 7.0 * cell_h;
    let mut pb = PathBuilder::new();
    for (k, c) in text.chars().enumerate() {
        let glyph = font8x8::legacy::BASIC_LEGACY.get(c as usize).copied().unwrap_or(font8x8::legacy::BASIC_LEGACY[b'?' as usize]);
        for (row, bits) in glyph.iter().enumerate() {
            // Bit 0 is the glyph's leftmost pixel.
            for col in (0..8).filter(|col| bits >> col & 1 == 1) {
                let px = x + (8 * k + col) as f64 * cell_w;
                if let Some(r) = Rect::from_xywh(px as f32, (top + row as f64 * cell_h) as f32, cell_w as f32, cell_h as f32) {
                    pb.push_rect(r);
                }
            }
        }
    }
    pb.finish()
}

/// RGB PNG with the resolution as pixels per metre in pHYs.
fn encode(pixmap: &Pixmap, dpi: f64) -> Result<Vec<u8>, String> {
    let rgb: Vec<u8> = pixmap.data().chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect();
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, pixmap.width(), pixmap.height());
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let ppm = (dpi / MM_PER_INCH * 1000.0).round() as u32;
    encoder.set_pixel_dims(Some(png::PixelDimensions { xppu: ppm, yppu: ppm, unit: png::Unit::Meter }));
    let mut writer = encoder.write_header().map_err(|e| format!("PNG header: {e}"))?;
    writer.write_image_data(&rgb).map_err(|e| format!("PNG data: {e}"))?;
    writer.finish().map_err(|e| format!("PNG end: {e}"))?;
    Ok(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::drawing::{CHECK_SQUARE_MM, CHECK_SQUARE_SIDE_MM, SCALE_BAR_LENGTH_MM, SCALE_BAR_MM};

    /// The page's scale bar, check square and a label, as the layout draws them.
    fn furniture() -> Vec<Shape> {
        vec![
            Shape::Rect { x: SCALE_BAR_MM.0, y: SCALE_BAR_MM.1 - 0.5, w: SCALE_BAR_LENGTH_MM, h: 1.0, fill: Some(Rgb(0.0, 0.0, 0.0)), stroke_mm: None, id: "scale-bar" },
            Shape::Rect { x: CHECK_SQUARE_MM.0, y: CHECK_SQUARE_MM.1, w: CHECK_SQUARE_SIDE_MM, h: CHECK_SQUARE_SIDE_MM, fill: None, stroke_mm: Some(0.2), id: "check-square" },
            Shape::Text { x: 15.0, y: 20.0, size_mm: 5.0, text: "Template p2".into(), centred: false },
        ]
    }

    #[test]
    fn dpi_out_of_range_is_refused() {
        assert!(to_png(&furniture(), 5.0).unwrap_err().contains("dpi = 5"));
        assert!(to_png(&furniture(), f64::NAN).is_err());
    }

    #[test]
    fn text_is_drawn_and_its_width_is_the_advance() {
        let pixmap = rasterize(&furniture(), 100.0).unwrap();
        let k = px_per_mm(100.0);
        let dark = |x: u32, y: u32| pixmap.pixel(x, y).unwrap().red() < 128;
        let (x0, x1) = ((15.0 * k) as u32, ((15.0 + text_width_mm("Template p2", 5.0)) * k) as u32);
        let (y0, y1) = ((16.0 * k) as u32, (21.0 * k) as u32);
        let inked = (x0..x1).flat_map(|x| (y0..y1).map(move |y| (x, y))).filter(|&(x, y)| dark(x, y)).count();
        assert!(inked > 100, "{inked} dark pixels in the label");
        assert!(!(x1 + 2..x1 + 40).any(|x| (y0..y1).any(|y| dark(x, y))), "ink right of the label's width");
    }
}
