//! Orthographic pictures of a closed labelled surface as SVG: back faces culled,
//! front faces drawn far to near (painter's order) and shaded flat by how squarely
//! they face the viewer; each ModelFaceID in its own colour.

use baffle_core::{TriMesh, Vec3};
use std::fmt::Write;

/// A view: the direction the viewer looks in, and the screen's right and up axes.
#[derive(Clone, Copy)]
pub struct View {
    pub name: &'static str,
    pub look: Vec3,
    pub right: Vec3,
    pub up: Vec3,
}

/// Views along the three coordinate axes of the surface's frame.
pub fn axis_views() -> [View; 3] {
    [
        View { name: "along +y (x right, z up)", look: Vec3::new(0.0, 1.0, 0.0), right: Vec3::new(1.0, 0.0, 0.0), up: Vec3::new(0.0, 0.0, 1.0) },
        View { name: "along -x (y right, z up)", look: Vec3::new(-1.0, 0.0, 0.0), right: Vec3::new(0.0, 1.0, 0.0), up: Vec3::new(0.0, 0.0, 1.0) },
        View { name: "along +z (x right, y down)", look: Vec3::new(0.0, 0.0, 1.0), right: Vec3::new(1.0, 0.0, 0.0), up: Vec3::new(0.0, -1.0, 0.0) },
    ]
}

/// Fill colour (RGB) of each ModelFaceID; others get the first.
pub struct Palette<'a>(pub &'a [(i32, [u8; 3])]);

impl Palette<'_> {
    fn color(&self, id: i32) -> [u8; 3] {
        self.0.iter().find(|(l, _)| *l == id).or(self.0.first()).map_or([180, 180, 180], |(_, c)| *c)
    }
}

const SIZE_PX: f64 = 300.0;
const MARGIN_PX: f64 = 8.0;

/// One view of `mesh` (mm) as an SVG `size` px square, the overlay polyline drawn on top.
pub fn render_view(mesh: &TriMesh, view: &View, palette: &Palette, overlay: &[Vec3]) -> String {
    let project = |p: &Vec3| (p.dot(&view.right), p.dot(&view.up));
    let (mut u0, mut u1, mut v0, mut v1) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
    for p in &mesh.points {
        let (u, v) = project(p);
        (u0, u1, v0, v1) = (u0.min(u), u1.max(u), v0.min(v), v1.max(v));
    }
    let span = (u1 - u0).max(v1 - v0).max(1e-9);
    let scale = (SIZE_PX - 2.0 * MARGIN_PX) / span;
    // Centre the picture in the square.
    let (cu, cv) = ((u0 + u1) / 2.0, (v0 + v1) / 2.0);
    let screen = |p: &Vec3| {
        let (u, v) = project(p);
        (SIZE_PX / 2.0 + (u - cu) * scale, SIZE_PX / 2.0 - (v - cv) * scale)
    };
    let mut front: Vec<(f64, usize, f64)> = Vec::new();
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let [a, b, c] = tri.map(|i| mesh.points[i as usize]);
        let Some(n) = (b - a).cross(&(c - a)).try_normalize(1e-300) else { continue };
        let facing = -n.dot(&view.look);
        if facing > 0.0 {
            front.push((((a + b + c) / 3.0).dot(&view.look), t, facing));
        }
    }
    front.sort_by(|x, y| y.0.total_cmp(&x.0));
    let mut s = String::new();
    let _ = write!(s, r#"<svg xmlns="http://www.w3.org/2000/svg" width="{SIZE_PX}" height="{SIZE_PX}" viewBox="0 0 {SIZE_PX} {SIZE_PX}">"#);
    for (_, t, facing) in front {
        let shade = 0.35 + 0.65 * facing;
        let [r, g, b] = palette.color(mesh.face_ids[t]).map(|c| (c as f64 * shade).round() as u8);
        let pts: Vec<String> = mesh.triangles[t]
            .iter()
            .map(|&i| {
                let (x, y) = screen(&mesh.points[i as usize]);
                format!("{x:.1},{y:.1}")
            })
            .collect();
        // A stroke of the fill colour hides the hairline gaps between neighbours.
        let _ = write!(s, r##"<polygon points="{}" fill="#{r:02x}{g:02x}{b:02x}" stroke="#{r:02x}{g:02x}{b:02x}" stroke-width="0.4"/>"##, pts.join(" "));
    }
    if overlay.len() > 1 {
        let pts: Vec<String> = overlay.iter().map(screen).map(|(x, y)| format!("{x:.1},{y:.1}")).collect();
        let _ = write!(s, r##"<polyline points="{}" fill="none" stroke="#111" stroke-width="1.5" stroke-dasharray="4 3"/>"##, pts.join(" "));
    }
    s.push_str("</svg>");
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A closed, outward tetrahedron with two labels.
    fn tetrahedron() -> TriMesh {
        TriMesh {
            points: vec![Vec3::new(0.0, 0.0, 0.0), Vec3::new(10.0, 0.0, 0.0), Vec3::new(0.0, 10.0, 0.0), Vec3::new(0.0, 0.0, 10.0)],
            triangles: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
            face_ids: vec![2, 2, 2, 10],
        }
    }

    fn numbers_in(svg: &str, attribute: &str) -> Vec<f64> {
        svg.split(&format!("{attribute}=\"")).skip(1).flat_map(|rest| {
            let value = &rest[..rest.find('"').unwrap()];
            value.split([' ', ',']).map(|v| v.parse::<f64>().unwrap()).collect::<Vec<_>>()
        }).collect()
    }

    #[test]
    fn the_picture_parses_and_stays_inside_its_view_box() {
        let palette = Palette(&[(2, [200, 120, 120]), (10, [60, 120, 220])]);
        for view in axis_views() {
            let svg = render_view(&tetrahedron(), &view, &palette, &[Vec3::new(1.0, 1.0, 1.0), Vec3::new(2.0, 2.0, 2.0)]);
            let doc = roxmltree::Document::parse(&svg).expect("well-formed SVG");
            let root = doc.root_element();
            assert_eq!(root.tag_name().name(), "svg");
            assert_eq!(root.attribute("viewBox"), Some("0 0 300 300"));
            let coordinates = numbers_in(&svg, "points");
            assert!(!coordinates.is_empty());
            assert!(coordinates.iter().all(|c| (0.0..=300.0).contains(c)), "{coordinates:?}");
            // Back faces are culled: a closed tetrahedron shows at most three faces.
            let polygons = root.children().filter(|n| n.has_tag_name("polygon")).count();
            assert!((1..=3).contains(&polygons), "{polygons} polygons {}", view.name);
        }
    }

    #[test]
    fn the_slanted_face_is_drawn_in_the_baffle_colour_when_it_faces_the_viewer() {
        let palette = Palette(&[(2, [200, 120, 120]), (10, [0, 0, 250])]);
        // Looking along -(1,1,1) the slanted face (label 10) faces the viewer squarely.
        let d = -Vec3::new(1.0, 1.0, 1.0).normalize();
        let view = View { name: "diagonal", look: d, right: Vec3::new(1.0, -1.0, 0.0).normalize(), up: Vec3::new(-1.0, -1.0, 2.0).normalize() };
        let svg = render_view(&tetrahedron(), &view, &palette, &[]);
        assert!(svg.contains(r##"fill="#0000fa""##), "{svg}");
    }
}
