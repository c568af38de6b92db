//! The template as a one-page PDF written by hand: an A4 page (595.28 x 841.89 pt), the
//! content drawn in millimetres under one `cm` of 72/25.4 pt per mm, vector paths and
//! Helvetica (a standard Type1 font every reader has), so it prints 1:1 at 100 %.

use super::drawing::{helvetica_width_mm, Rgb, Shape, PAGE_HEIGHT_MM, PAGE_WIDTH_MM};
use std::fmt::Write;

const PT_PER_MM: f64 = 72.0 / 25.4;

pub fn to_pdf(shapes: &[Shape]) -> Vec<u8> {
    let content = content_stream(shapes);
    let (w_pt, h_pt) = (PAGE_WIDTH_MM * PT_PER_MM, PAGE_HEIGHT_MM * PT_PER_MM);
    let objects = [
        "<< /Type /Catalog /Pages 2 0 R >>".to_string(),
        "<< /Type /Pages /Kids [3 0 R] /Count 1 >>".to_string(),
        format!("<< /Type /Page /Parent 2 0 R /MediaBox [0 0 {w_pt:.4} {h_pt:.4}] /Resources << /Font << /F1 4 0 R >> >> /Contents 5 0 R >>"),
        "<< /Type /Font /Subtype /Type1 /BaseFont /Helvetica /Encoding /WinAnsiEncoding >>".to_string(),
        format!("<< /Length {} >>\nstream\n{content}endstream", content.len()),
    ];
    let mut pdf = b"%PDF-1.4\n%\xe2\xe3\xcf\xd3\n".to_vec();
    let mut offsets = Vec::new();
    for (k, body) in objects.iter().enumerate() {
        offsets.push(pdf.len());
        pdf.extend_from_slice(format!("{} 0 obj\n{body}\nendobj\n", k + 1).as_bytes());
    }
    let xref = pdf.len();
    let mut table = format!("xref\n0 {}\n0000000000 65535 f \n", objects.len() + 1);
    for off in offsets {
        let _ = write!(table, "{off:010} 00000 n \n");
    }
    let _ = write!(table, "trailer\n<< /Size {} /Root 1 0 R >>\nstartxref\n{xref}\n%%EOF\n", objects.len() + 1);
    pdf.extend_from_slice(table.as_bytes());
    pdf
}

/// Page coordinates are mm with y down; PDF's are y up: flip once here.
fn content_stream(shapes: &[Shape]) -> String {
    let mut s = format!("{PT_PER_MM:.6} 0 0 {PT_PER_MM:.6} 0 0 cm\n1 J 1 j\n");
    let y = |v: f64| PAGE_HEIGHT_MM - v;
    for shape in shapes {
        let _ = match shape {
            Shape::Triangle { points, fill } => {
                let [a, b, c] = points;
                writeln!(s, "{} {:.3} {:.3} m {:.3} {:.3} l {:.3} {:.3} l h f", fill_op(*fill), a.0, y(a.1), b.0, y(b.1), c.0, y(c.1))
            }
            Shape::Polyline { points, closed, width_mm, colour, .. } => {
                let path: Vec<String> =
                    points.iter().enumerate().map(|(k, p)| format!("{:.3} {:.3} {}", p.0, y(p.1), if k == 0 { "m" } else { "l" })).collect();
                writeln!(s, "{} {width_mm} w {} {}", stroke_op(*colour), path.join(" "), if *closed { "h S" } else { "S" })
            }
            Shape::Rect { x, y: top, w, h, fill, stroke_mm, .. } => {
                let rect = format!("{x:.3} {:.3} {w:.3} {h:.3} re", y(top + h));
                let mut ops = String::new();
                if let Some(f) = fill {
                    let _ = write!(ops, "{} {rect} f ", fill_op(*f));
                }
                if let Some(width) = stroke_mm {
                    let _ = write!(ops, "0 0 0 RG {width} w 0 J {rect} S 1 J");
                }
                writeln!(s, "{ops}")
            }
            Shape::Dot { x, y: cy, radius_mm, colour } => {
                // A zero-length stroke with round caps is a filled disk.
                writeln!(s, "{} {} w {x:.3} {:.3} m {x:.3} {:.3} l S", stroke_op(*colour), 2.0 * radius_mm, y(*cy), y(*cy))
            }
            Shape::Text { x, y: base, size_mm, text, centred } => {
                let x0 = if *centred { x - helvetica_width_mm(text, *size_mm) / 2.0 } else { *x };
                writeln!(s, "0 0 0 rg BT /F1 {size_mm} Tf {x0:.3} {:.3} Td ({}) Tj ET", y(*base), pdf_string(text))
            }
        };
    }
    s
}

fn fill_op(c: Rgb) -> String {
    format!("{:.3} {:.3} {:.3} rg", c.0, c.1, c.2)
}

fn stroke_op(c: Rgb) -> String {
    format!("{:.3} {:.3} {:.3} RG", c.0, c.1, c.2)
}

/// A PDF literal string: backslash-escape the delimiters; the page text is ASCII.
fn pdf_string(text: &str) -> String {
    text.chars()
        .map(|c| match c {
            '(' | ')' | '\\' => format!("\\{c}"),
            c if c.is_ascii() && !c.is_ascii_control() => c.to_string(),
            _ => "?".to_string(),
        })
        .collect()
}
