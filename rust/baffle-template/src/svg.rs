//! The template as SVG: width and height in mm and a viewBox in mm, so one user unit
//! is one millimetre and the file prints 1:1 at 100 %.

use super::drawing::{Rgb, Shape, PAGE_HEIGHT_MM, PAGE_WIDTH_MM};
use std::fmt::Write;

pub fn to_svg(shapes: &[Shape]) -> String {
    let mut out = format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{PAGE_WIDTH_MM}mm\" height=\"{PAGE_HEIGHT_MM}mm\" viewBox=\"0 0 {PAGE_WIDTH_MM} {PAGE_HEIGHT_MM}\">\n<rect width=\"{PAGE_WIDTH_MM}\" height=\"{PAGE_HEIGHT_MM}\" fill=\"white\"/>\n"
    );
    out.push_str("<g id=\"distortion\" stroke=\"none\">\n");
    for shape in shapes.iter().filter(|s| matches!(s, Shape::Triangle { .. })) {
        write_shape(&mut out, shape);
    }
    out.push_str("</g>\n");
    for shape in shapes.iter().filter(|s| !matches!(s, Shape::Triangle { .. })) {
        write_shape(&mut out, shape);
    }
    out.push_str("</svg>\n");
    out
}

fn write_shape(out: &mut String, shape: &Shape) {
    // Writing to a String cannot fail.
    let _ = match shape {
        Shape::Triangle { points, fill } => {
            writeln!(out, "<polygon points=\"{}\" fill=\"{}\"/>", coords(points), hex(*fill))
        }
        Shape::Polyline { points, closed, width_mm, colour, id } => {
            let tag = if *closed { "polygon" } else { "polyline" };
            let id = id.map(|i| format!(" id=\"{i}\"")).unwrap_or_default();
            writeln!(
                out,
                "<{tag}{id} points=\"{}\" fill=\"none\" stroke=\"{}\" stroke-width=\"{width_mm}\" stroke-linejoin=\"round\"/>",
                coords(points),
                hex(*colour)
            )
        }
        Shape::Rect { x, y, w, h, fill, stroke_mm, id } => {
            let fill = fill.map_or("none".to_string(), hex);
            let stroke = stroke_mm.map(|s| format!(" stroke=\"black\" stroke-width=\"{s}\"")).unwrap_or_default();
            writeln!(out, "<rect id=\"{id}\" x=\"{x}\" y=\"{y}\" width=\"{w}\" height=\"{h}\" fill=\"{fill}\"{stroke}/>")
        }
        Shape::Dot { x, y, radius_mm, colour } => {
            writeln!(out, "<circle cx=\"{x:.3}\" cy=\"{y:.3}\" r=\"{radius_mm}\" fill=\"{}\"/>", hex(*colour))
        }
        Shape::Text { x, y, size_mm, text, centred } => {
            let anchor = if *centred { " text-anchor=\"middle\"" } else { "" };
            writeln!(
                out,
                "<text x=\"{x:.3}\" y=\"{y:.3}\" font-family=\"Helvetica, Arial, sans-serif\" font-size=\"{size_mm}\"{anchor}>{}</text>",
                escape(text)
            )
        }
    };
}

fn coords(points: &[(f64, f64)]) -> String {
    points.iter().map(|(x, y)| format!("{x:.3},{y:.3}")).collect::<Vec<_>>().join(" ")
}

fn hex(c: Rgb) -> String {
    let byte = |v: f64| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    format!("#{:02x}{:02x}{:02x}", byte(c.0), byte(c.1), byte(c.2))
}

fn escape(text: &str) -> String {
    text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}
