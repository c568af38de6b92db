//! Line charts as inline SVG, written by hand: a few dozen lines against a plotting
//! crate and its font handling, and the report stays free of external references.

use std::fmt::Write;

pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
    pub color: &'static str,
    pub dashed: bool,
    /// Draw a dot at every point (for few, measured points).
    pub markers: bool,
}

impl Series {
    pub fn line(label: &str, points: Vec<(f64, f64)>, color: &'static str) -> Series {
        Series { label: label.into(), points, color, dashed: false, markers: false }
    }
}

const WIDTH: f64 = 560.0;
const HEIGHT: f64 = 300.0;
const LEFT: f64 = 64.0;
const RIGHT: f64 = 16.0;
const TOP: f64 = 44.0;
const BOTTOM: f64 = 44.0;

pub fn escape(text: &str) -> String {
    text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// The round spacing of about five ticks over [lo, hi].
fn tick_step(lo: f64, hi: f64) -> f64 {
    let raw = (hi - lo) / 5.0;
    let magnitude = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 2.5, 5.0, 10.0].iter().map(|m| m * magnitude).find(|s| *s >= raw).unwrap_or(10.0 * magnitude)
}

/// [lo, hi] widened to whole ticks, so the data's lowest and highest values (a dip below
/// zero too) lie between labelled ticks.
fn to_whole_ticks((lo, hi): (f64, f64)) -> (f64, f64) {
    let step = tick_step(lo, hi);
    ((lo / step).floor() * step, (hi / step).ceil() * step)
}

/// About five round tick values covering [lo, hi].
fn ticks(lo: f64, hi: f64) -> Vec<f64> {
    let step = tick_step(lo, hi);
    let first = (lo / step).ceil() as i64;
    let last = (hi / step).floor() as i64;
    (first..=last).map(|k| k as f64 * step).collect()
}

/// Range of `values` padded so that flat data still gets an axis.
fn range(values: impl Iterator<Item = f64>, include_zero: bool) -> (f64, f64) {
    let (mut lo, mut hi) = values.filter(|v| v.is_finite()).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    if include_zero {
        lo = lo.min(0.0);
        hi = hi.max(0.0);
    }
    let pad = if hi > lo { 0.05 * (hi - lo) } else { lo.abs().max(1.0) * 0.1 };
    (lo - pad, hi + pad)
}

fn label(v: f64) -> String {
    let text = format!("{:.4}", v);
    let text = text.trim_end_matches('0').trim_end_matches('.');
    if text == "-0" { "0".into() } else { text.into() }
}

/// A chart of `series` (non-finite points are gaps), the y axis from zero when `y_from_zero`.
pub fn line_chart(title: &str, x_label: &str, y_label: &str, series: &[Series], y_from_zero: bool) -> String {
    let all = || series.iter().flat_map(|s| s.points.iter());
    let (x0, x1) = range(all().map(|p| p.0), false);
    let (y0, y1) = to_whole_ticks(range(all().map(|p| p.1), y_from_zero));
    let (pw, ph) = (WIDTH - LEFT - RIGHT, HEIGHT - TOP - BOTTOM);
    let sx = |x: f64| LEFT + (x - x0) / (x1 - x0) * pw;
    let sy = |y: f64| TOP + (y1 - y) / (y1 - y0) * ph;
    let mut s = String::new();
    let _ = write!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{HEIGHT}" viewBox="0 0 {WIDTH} {HEIGHT}" font-family="sans-serif" font-size="11">"#
    );
    let _ = write!(s, r#"<text x="{}" y="17" text-anchor="middle" font-size="13" font-weight="bold">{}</text>"#, WIDTH / 2.0, escape(title));
    let _ = write!(s, r##"<rect x="{LEFT}" y="{TOP}" width="{pw}" height="{ph}" fill="none" stroke="#444"/>"##);
    for x in ticks(x0, x1) {
        let _ = write!(s, r##"<line x1="{0:.1}" y1="{TOP}" x2="{0:.1}" y2="{1}" stroke="#ddd"/><text x="{0:.1}" y="{2}" text-anchor="middle">{3}</text>"##, sx(x), TOP + ph, TOP + ph + 14.0, label(x));
    }
    for y in ticks(y0, y1) {
        let _ = write!(s, r##"<line x1="{LEFT}" y1="{0:.1}" x2="{1}" y2="{0:.1}" stroke="#ddd"/><text x="{2}" y="{3:.1}" text-anchor="end">{4}</text>"##, sy(y), LEFT + pw, LEFT - 4.0, sy(y) + 4.0, label(y));
    }
    if y0 < 0.0 && y1 > 0.0 {
        // Zero drawn darker when the data cross it (a pressure below the reference).
        let _ = write!(s, r##"<line x1="{LEFT}" y1="{0:.1}" x2="{1}" y2="{0:.1}" stroke="#888"/>"##, sy(0.0), LEFT + pw);
    }
    let _ = write!(s, r#"<text x="{}" y="{}" text-anchor="middle">{}</text>"#, LEFT + pw / 2.0, HEIGHT - 8.0, escape(x_label));
    let _ = write!(s, r#"<text transform="translate(14 {}) rotate(-90)" text-anchor="middle">{}</text>"#, TOP + ph / 2.0, escape(y_label));
    for (k, series) in series.iter().enumerate() {
        let dash = if series.dashed { r#" stroke-dasharray="6 4""# } else { "" };
        for run in series.points.split(|p| !(p.0.is_finite() && p.1.is_finite())).filter(|r| !r.is_empty()) {
            let path: Vec<String> = run.iter().map(|&(x, y)| format!("{:.1},{:.1}", sx(x), sy(y))).collect();
            let _ = write!(s, r#"<polyline points="{}" fill="none" stroke="{}" stroke-width="1.8"{dash}/>"#, path.join(" "), series.color);
            if series.markers {
                for &(x, y) in run {
                    let _ = write!(s, r#"<circle cx="{:.1}" cy="{:.1}" r="3" fill="{}"/>"#, sx(x), sy(y), series.color);
                }
            }
        }
        // The legend is one row between the title and the plot, clear of the data.
        let lx = LEFT + 150.0 * k as f64;
        let _ = write!(
            s,
            r#"<line x1="{lx}" y1="32" x2="{}" y2="32" stroke="{}" stroke-width="2"{dash}/><text x="{}" y="36">{}</text>"#,
            lx + 20.0,
            series.color,
            lx + 25.0,
            escape(&series.label)
        );
    }
    s.push_str("</svg>");
    s
}

/// `chart` with a one-line note at the top of its plot area (why values are missing),
/// cut to what fits the width.
pub fn with_note(chart: &str, note: &str) -> String {
    let fits = ((WIDTH - LEFT - RIGHT - 8.0) / 5.0) as usize;
    let text: String = if note.chars().count() > fits { note.chars().take(fits - 3).chain("...".chars()).collect() } else { note.into() };
    let line = format!(r##"<text class="note" x="{}" y="{}" font-size="10" fill="#555">{}</text>"##, LEFT + 4.0, TOP + 12.0, escape(&text));
    match chart.rfind("</svg>") {
        Some(end) => format!("{}{line}</svg>", &chart[..end]),
        None => chart.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_round_and_cover_the_range() {
        assert_eq!(ticks(0.0, 10.0), vec![0.0, 2.0, 4.0, 6.0, 8.0, 10.0]);
        let t = ticks(-0.013, 0.047);
        assert!(t.len() >= 3 && t.len() <= 7 && t.iter().all(|v| (-0.013..=0.047).contains(v)), "{t:?}");
    }

    #[test]
    fn a_dip_below_zero_gets_a_negative_tick_label() {
        let series = [Series::line("p", vec![(0.0, 3.1), (5.0, 1.0), (9.0, -0.2), (10.0, 0.0)], "#1f77b4")];
        let svg = line_chart("p", "s (mm)", "p (mmHg)", &series, false);
        let labels: Vec<f64> = svg
            .split(r#"text-anchor="end">"#)
            .skip(1)
            .map(|t| t[..t.find('<').unwrap()].parse().unwrap())
            .collect();
        assert!(labels.iter().any(|&v| v < 0.0 && v <= -0.2), "{labels:?}");
        assert!(labels.iter().any(|&v| v >= 3.1), "{labels:?}");
        assert!(labels.contains(&0.0), "{labels:?}");
    }

    #[test]
    fn a_chart_is_one_svg_with_every_series_and_escaped_labels() {
        let series = [
            Series::line("area <mm2>", vec![(0.0, 1.0), (1.0, 2.0), (f64::NAN, 0.0), (2.0, 1.5), (3.0, 1.0)], "#1f77b4"),
            Series { label: "target".into(), points: vec![(0.0, 1.2), (3.0, 1.2)], color: "#d62728", dashed: true, markers: true },
        ];
        let svg = line_chart("A & B", "s (mm)", "A (mm2)", &series, true);
        assert!(svg.starts_with("<svg") && svg.ends_with("</svg>"));
        assert_eq!(svg.matches("<polyline").count(), 3, "the NaN splits the first series in two");
        assert!(svg.contains("A &amp; B") && svg.contains("area &lt;mm2&gt;") && !svg.contains("<mm2>"));
        assert!(!svg.contains("NaN") && !svg.contains("inf"));
    }
}
