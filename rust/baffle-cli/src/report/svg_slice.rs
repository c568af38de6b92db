//! A cut plane through a tetrahedral result as SVG: each tet the plane crosses gives a
//! triangle or quad, coloured by the speed interpolated (linearly, as the P1 field is)
//! at its corners and averaged; seen face-on, with a colour bar and a scale bar. The
//! wall's speed is zero (no slip), so the flow shows on a cut, not on the surface.

use super::svg_render::{scale_bar, View};
use baffle_core::Vec3;
use std::fmt::Write;

const SIZE_PX: f64 = 300.0;
const BAR_PX: f64 = 46.0;
const MARGIN_PX: f64 = 8.0;

/// The polygons where the plane through `origin` with normal `normal` cuts the tets,
/// each with its corners (mm) and the speed at them.
pub fn cut(points_mm: &[Vec3], tets: &[[u32; 4]], speed: &[f64], origin: Vec3, normal: Vec3) -> Vec<Vec<(Vec3, f64)>> {
    let distance = |p: &Vec3| (p - origin).dot(&normal);
    let mut polygons = Vec::new();
    for tet in tets {
        let d: Vec<f64> = tet.iter().map(|&i| distance(&points_mm[i as usize])).collect();
        if d.iter().all(|&x| x > 0.0) || d.iter().all(|&x| x <= 0.0) {
            continue;
        }
        let mut corners = Vec::new();
        for (a, b) in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
            if (d[a] > 0.0) != (d[b] > 0.0) {
                let t = d[a] / (d[a] - d[b]);
                let (ia, ib) = (tet[a] as usize, tet[b] as usize);
                corners.push((points_mm[ia] + (points_mm[ib] - points_mm[ia]) * t, speed[ia] + (speed[ib] - speed[ia]) * t));
            }
        }
        polygons.push(corners);
    }
    polygons
}

/// Blue (slow) to red (fast) through green and yellow: `f` in [0, 1].
fn color(f: f64) -> [u8; 3] {
    const STOPS: [[f64; 3]; 5] = [[40.0, 60.0, 190.0], [40.0, 170.0, 220.0], [80.0, 190.0, 80.0], [240.0, 210.0, 50.0], [210.0, 40.0, 40.0]];
    let x = f.clamp(0.0, 1.0) * (STOPS.len() - 1) as f64;
    let (k, t) = ((x.floor() as usize).min(STOPS.len() - 2), x - x.floor().min((STOPS.len() - 2) as f64));
    std::array::from_fn(|c| (STOPS[k][c] + (STOPS[k + 1][c] - STOPS[k][c]) * t).round() as u8)
}

/// The cut seen along `view.look` (its normal), coloured from 0 to the largest speed on it.
pub fn render_cut(polygons: &[Vec<(Vec3, f64)>], view: &View) -> String {
    let project = |p: &Vec3| (p.dot(&view.right), p.dot(&view.up));
    let (mut u0, mut u1, mut v0, mut v1) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
    let mut v_max = 0.0f64;
    for (p, s) in polygons.iter().flatten() {
        let (u, v) = project(p);
        (u0, u1, v0, v1) = (u0.min(u), u1.max(u), v0.min(v), v1.max(v));
        v_max = v_max.max(*s);
    }
    let width = SIZE_PX + BAR_PX;
    let mut s = String::new();
    let _ = write!(s, r#"<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{SIZE_PX}" viewBox="0 0 {width} {SIZE_PX}" font-family="sans-serif" font-size="10">"#);
    if polygons.is_empty() {
        let _ = write!(s, r#"<text x="10" y="20">the plane misses the mesh</text></svg>"#);
        return s;
    }
    let scale = (SIZE_PX - 2.0 * MARGIN_PX) / (u1 - u0).max(v1 - v0).max(1e-9);
    let (cu, cv) = ((u0 + u1) / 2.0, (v0 + v1) / 2.0);
    for polygon in polygons {
        let (cx, cy) = polygon.iter().fold((0.0, 0.0), |(x, y), (p, _)| (x + project(p).0, y + project(p).1));
        let centre = (cx / polygon.len() as f64, cy / polygon.len() as f64);
        // Corners in order around the centre, so a quad is not drawn as a bow tie.
        let mut corners: Vec<(f64, f64, f64)> = polygon.iter().map(|(p, sp)| (project(p).0, project(p).1, *sp)).collect();
        corners.sort_by(|a, b| (a.1 - centre.1).atan2(a.0 - centre.0).total_cmp(&(b.1 - centre.1).atan2(b.0 - centre.0)));
        let speed = corners.iter().map(|c| c.2).sum::<f64>() / corners.len() as f64;
        let [r, g, b] = color(if v_max > 0.0 { speed / v_max } else { 0.0 });
        let pts: Vec<String> = corners.iter().map(|c| format!("{:.1},{:.1}", SIZE_PX / 2.0 + (c.0 - cu) * scale, SIZE_PX / 2.0 - (c.1 - cv) * scale)).collect();
        let _ = write!(s, r##"<polygon points="{}" fill="#{r:02x}{g:02x}{b:02x}" stroke="#{r:02x}{g:02x}{b:02x}" stroke-width="0.3"/>"##, pts.join(" "));
    }
    scale_bar(&mut s, scale);
    // The colour bar: 0 at the bottom, the largest speed on the cut at the top.
    let (x, top, bottom) = (SIZE_PX + 6.0, 20.0, SIZE_PX - 30.0);
    let steps = 20;
    for k in 0..steps {
        let h = (bottom - top) / steps as f64;
        let [r, g, b] = color((k as f64 + 0.5) / steps as f64);
        let _ = write!(s, r##"<rect x="{x:.1}" y="{:.1}" width="12" height="{:.1}" fill="#{r:02x}{g:02x}{b:02x}"/>"##, bottom - (k + 1) as f64 * h, h + 0.3);
    }
    let _ = write!(s, r#"<text x="{x:.1}" y="{:.1}">{v_max:.2}</text><text x="{x:.1}" y="{:.1}">0 m/s</text>"#, top - 6.0, bottom + 12.0);
    s.push_str("</svg>");
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit cube (mm) in 6 tets around its main diagonal.
    fn cube() -> (Vec<Vec3>, Vec<[u32; 4]>) {
        let points = (0..8).map(|i| Vec3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64)).collect();
        (points, vec![[0, 1, 3, 7], [0, 3, 2, 7], [0, 2, 6, 7], [0, 6, 4, 7], [0, 4, 5, 7], [0, 5, 1, 7]])
    }

    fn area(polygon: &[(Vec3, f64)]) -> f64 {
        let c = polygon.iter().map(|(p, _)| *p).sum::<Vec3>() / polygon.len() as f64;
        let mut points: Vec<Vec3> = polygon.iter().map(|(p, _)| *p).collect();
        points.sort_by(|a, b| (a.y - c.y).atan2(a.x - c.x).total_cmp(&(b.y - c.y).atan2(b.x - c.x)));
        (0..points.len()).map(|k| (points[k] - c).cross(&(points[(k + 1) % points.len()] - c)).norm() / 2.0).sum()
    }

    #[test]
    fn a_cut_through_the_cube_covers_its_section_with_the_linear_field() {
        let (points, tets) = cube();
        let speed: Vec<f64> = points.iter().map(|p| 2.0 * p.x + p.z).collect();
        let polygons = cut(&points, &tets, &speed, Vec3::new(0.0, 0.0, 0.3), Vec3::z());
        assert_eq!(polygons.len(), 6, "the plane crosses every tet");
        let total: f64 = polygons.iter().map(|p| area(p)).sum();
        assert!((total - 1.0).abs() < 1e-12, "section area {total}");
        for (p, s) in polygons.iter().flatten() {
            assert!((p.z - 0.3).abs() < 1e-12 && (s - (2.0 * p.x + p.z)).abs() < 1e-12, "{p:?} {s}");
        }
        assert!(cut(&points, &tets, &speed, Vec3::new(0.0, 0.0, 2.0), Vec3::z()).is_empty());
    }

    #[test]
    fn the_cut_is_drawn_with_its_colour_bar_inside_the_picture() {
        let (points, tets) = cube();
        let speed: Vec<f64> = points.iter().map(|p| p.x).collect();
        let view = View { name: "down".into(), look: -Vec3::z(), right: Vec3::x(), up: -Vec3::y() };
        let svg = render_cut(&cut(&points, &tets, &speed, Vec3::new(0.5, 0.5, 0.5), Vec3::z()), &view);
        let doc = roxmltree::Document::parse(&svg).expect("well-formed SVG");
        assert_eq!(doc.root_element().children().filter(|n| n.has_tag_name("polygon")).count(), 6);
        assert!(svg.contains(">1.00</text>") && svg.contains(">0 m/s</text>") && svg.contains(" mm</text>"), "{svg}");
        assert_eq!(color(0.0), [40, 60, 190]);
        assert_eq!(color(1.0), [210, 40, 40]);
    }
}
