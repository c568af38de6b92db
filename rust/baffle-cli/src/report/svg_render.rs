//! Orthographic pictures of a closed labelled surface as SVG: back faces culled,
//! front faces drawn far to near (painter's order) and shaded flat by how squarely
//! they face the viewer; each ModelFaceID in its own colour.

use baffle_core::{TriMesh, Vec3};
use std::fmt::Write;

/// A view: the direction the viewer looks in, and the screen's right and up axes.
#[derive(Clone)]
pub struct View {
    pub name: String,
    pub look: Vec3,
    pub right: Vec3,
    pub up: Vec3,
}

/// The anatomical views, named in the patient's terms whatever the file's frame:
/// anterior, left lateral and inferior (as axial images are shown: the patient's left on
/// the right, anterior up). `ras`: the surface is in RAS (x right, y anterior), not LPS.
pub fn anatomical_views(ras: bool) -> [View; 3] {
    // Defined in LPS (x left, y posterior, z superior); an RAS file negates x and y.
    let to_file = |x: f64, y: f64, z: f64| if ras { Vec3::new(-x, -y, z) } else { Vec3::new(x, y, z) };
    let view = |name: &str, look: Vec3, right: Vec3, up: Vec3| View { name: name.into(), look, right, up };
    [
        view("anterior (patient's left on the right, superior up)", to_file(0.0, 1.0, 0.0), to_file(1.0, 0.0, 0.0), to_file(0.0, 0.0, 1.0)),
        view("left lateral (posterior on the right, superior up)", to_file(-1.0, 0.0, 0.0), to_file(0.0, 1.0, 0.0), to_file(0.0, 0.0, 1.0)),
        view("inferior, as axial images (patient's left on the right, anterior up)", to_file(0.0, 0.0, 1.0), to_file(1.0, 0.0, 0.0), to_file(0.0, -1.0, 0.0)),
    ]
}

/// A view straight at the face labelled `label` from outside (its area-weighted outward
/// normal), superior kept up where it can be; None when `mesh` has no such face.
pub fn face_on_view(mesh: &TriMesh, label: i32, name: &str, superior: Vec3) -> Option<View> {
    let normal: Vec3 = mesh
        .triangles
        .iter()
        .zip(&mesh.face_ids)
        .filter(|(_, &id)| id == label)
        .map(|(t, _)| {
            let [a, b, c] = t.map(|i| mesh.points[i as usize]);
            (b - a).cross(&(c - a))
        })
        .sum();
    let look = -normal.try_normalize(1e-12)?;
    let up = (superior - look * superior.dot(&look)).try_normalize(1e-6).unwrap_or_else(|| look.cross(&Vec3::x()).normalize());
    Some(View { name: name.into(), look, right: look.cross(&up), up })
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
    scale_bar(&mut s, scale);
    s.push_str("</svg>");
    s
}

/// A round length (1, 2, 5 or 10 x a power of ten mm) about a fifth of the picture, drawn
/// at its bottom left with its length written under it.
pub(super) fn scale_bar(s: &mut String, px_per_mm: f64) {
    let target_mm = 0.2 * SIZE_PX / px_per_mm;
    let magnitude = 10f64.powf(target_mm.log10().floor());
    let length_mm = [1.0, 2.0, 5.0, 10.0].iter().map(|m| m * magnitude).rfind(|l| *l <= target_mm).unwrap_or(magnitude);
    let (x, y, w) = (MARGIN_PX + 4.0, SIZE_PX - MARGIN_PX - 12.0, length_mm * px_per_mm);
    let _ = write!(
        s,
        r##"<line x1="{x:.1}" y1="{y:.1}" x2="{:.1}" y2="{y:.1}" stroke="#111" stroke-width="2.5"/><text x="{x:.1}" y="{:.1}" font-family="sans-serif" font-size="10">{} mm</text>"##,
        x + w,
        y + 11.0,
        length_mm
    );
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
        for view in anatomical_views(false) {
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
        let view = View { name: "diagonal".into(), look: d, right: Vec3::new(1.0, -1.0, 0.0).normalize(), up: Vec3::new(-1.0, -1.0, 2.0).normalize() };
        let svg = render_view(&tetrahedron(), &view, &palette, &[]);
        assert!(svg.contains(r##"fill="#0000fa""##), "{svg}");
    }

    #[test]
    fn views_are_anatomical_in_either_frame_and_a_face_can_be_seen_face_on() {
        let (lps, ras) = (anatomical_views(false), anatomical_views(true));
        // The anterior view looks towards posterior: +y in LPS, -y in RAS; superior is up in both.
        assert_eq!((lps[0].look, ras[0].look), (Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.0, -1.0, 0.0)));
        for v in lps.iter().chain(&ras) {
            assert!((v.look.cross(&v.up) - v.right).norm() < 1e-12, "{}: right-handed screen", v.name);
        }
        // The slanted face (outward normal (1,1,1)) is seen along -(1,1,1), and drawn.
        let view = face_on_view(&tetrahedron(), 10, "slanted face", Vec3::z()).unwrap();
        assert!((view.look + Vec3::new(1.0, 1.0, 1.0).normalize()).norm() < 1e-12);
        let svg = render_view(&tetrahedron(), &view, &Palette(&[(2, [200, 120, 120]), (10, [0, 0, 250])]), &[]);
        assert!(svg.contains(r##"fill="#0000fa""##) && svg.contains(" mm</text>"), "{svg}");
        assert!(face_on_view(&tetrahedron(), 99, "none", Vec3::z()).is_none());
    }
}
