//! The section of a closed surface by a plane, as an area: the piece of {inside a solid,
//! outside an optional hole} in the plane that holds a given point. Both surfaces' cut
//! segments are filled on a [`PIXEL_MM`] raster (even-odd) and the 4-connected piece
//! holding the point is counted (and, for its shape, its pixels' second moments). Used by
//! the RV outflow (`crate::analyses::rv_outflow`) and by the flow-normal sections of a lumen
//! (`crate::analyses::flow_centerline`).

use crate::geometry::mesh::{axes_across, TriMesh, Vec3};

/// Pixel of the section raster (mm).
pub const PIXEL_MM: f64 = 0.1;

/// Area (mm2) of the piece of {inside `solid`, outside `hole`} in the plane through
/// `point` normal to `normal` that holds `point` (4-connected on a PIXEL_MM raster);
/// None when the point is not inside.
pub fn section_area(solid: &TriMesh, hole: Option<&TriMesh>, point: Vec3, normal: Vec3) -> Option<f64> {
    section_areas(solid, hole, point, normal).map(|a| a.region_mm2)
}

/// One plane's section with and without the hole.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SectionAreas {
    /// The piece of {inside solid, outside hole} holding the point.
    pub region_mm2: f64,
    /// The piece of the solid alone holding the same pixel (the section before the hole).
    pub solid_mm2: f64,
}

/// [`section_area`], and the solid's piece through the same pixel without the hole.
pub fn section_areas(solid: &TriMesh, hole: Option<&TriMesh>, point: Vec3, normal: Vec3) -> Option<SectionAreas> {
    let r = Rasterized::new(solid, hole, point, normal)?;
    let region_mm2 = pixels_mm2(r.raster.flood_count(&r.inside, r.seed));
    let solid_mm2 = if hole.is_some() { pixels_mm2(r.raster.flood_count(&r.solid_fill, r.seed)) } else { region_mm2 };
    Some(SectionAreas { region_mm2, solid_mm2 })
}

/// One plane's cut of the solid (and hole) filled on the raster, and the inside pixel
/// nearest the point that the pieces are flooded from.
struct Rasterized {
    raster: Raster,
    solid_fill: Vec<bool>,
    /// Inside the solid and outside the hole.
    inside: Vec<bool>,
    seed: usize,
}

impl Rasterized {
    fn new(solid: &TriMesh, hole: Option<&TriMesh>, point: Vec3, normal: Vec3) -> Option<Self> {
        let plane = PlaneFrame::new(point, normal);
        let solid_cut = plane.cut(solid);
        let hole_cut = hole.map(|h| plane.cut(h)).unwrap_or_default();
        let (lo, hi) = segment_bounds(&solid_cut)?;
        let raster = Raster::new(lo, hi);
        let solid_fill = raster.fill(&solid_cut);
        let inside: Vec<bool> = solid_fill.iter().zip(raster.fill(&hole_cut)).map(|(&s, h)| s && !h).collect();
        let seed = raster.nearest_inside(&inside, (0.0, 0.0))?;
        Some(Rasterized { raster, solid_fill, inside, seed })
    }
}

/// A section's area and shape.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SectionShape {
    pub area_mm2: f64,
    /// Minor over major principal radius of gyration of the piece: 1 for a disc or a square,
    /// b / a for an a x b ellipse or rectangle.
    pub aspect_ratio: f64,
}

/// The area and shape of the piece of `solid` in the plane through `point` normal to
/// `normal` that holds `point` ([`section_area`]'s piece, no hole); None when not inside.
pub fn section_shape(solid: &TriMesh, point: Vec3, normal: Vec3) -> Option<SectionShape> {
    let r = Rasterized::new(solid, None, point, normal)?;
    let mut moments = PixelMoments::default();
    let count = r.raster.flood(&r.inside, r.seed, |i, j| moments.add(i as f64, j as f64));
    Some(SectionShape { area_mm2: pixels_mm2(count), aspect_ratio: moments.aspect_ratio() })
}

/// The area of `count` raster pixels (mm2), one rounding for every caller, so that a piece's
/// area is the same number whether its shape is measured or not.
fn pixels_mm2(count: usize) -> f64 {
    count as f64 * (PIXEL_MM * PIXEL_MM)
}

/// Running sums of pixel coordinates for a region's second moments.
#[derive(Default)]
struct PixelMoments {
    n: f64,
    x: f64,
    y: f64,
    xx: f64,
    yy: f64,
    xy: f64,
}

impl PixelMoments {
    fn add(&mut self, x: f64, y: f64) {
        self.n += 1.0;
        (self.x, self.y) = (self.x + x, self.y + y);
        (self.xx, self.yy, self.xy) = (self.xx + x * x, self.yy + y * y, self.xy + x * y);
    }

    /// sqrt(lambda_min / lambda_max) of the covariance, each pixel a unit square (its own
    /// 1/12 on the diagonal, so a single pixel is round).
    fn aspect_ratio(&self) -> f64 {
        let (mx, my) = (self.x / self.n, self.y / self.n);
        let (a, c, b) = (self.xx / self.n - mx * mx + 1.0 / 12.0, self.yy / self.n - my * my + 1.0 / 12.0, self.xy / self.n - mx * my);
        let (mean, half_gap) = (0.5 * (a + c), (0.25 * (a - c).powi(2) + b * b).sqrt());
        ((mean - half_gap).max(0.0) / (mean + half_gap)).sqrt()
    }
}

type Segment = [(f64, f64); 2];

/// In-plane coordinates: origin at the point, axes u and v across the normal.
struct PlaneFrame {
    origin: Vec3,
    normal: Vec3,
    u: Vec3,
    v: Vec3,
}

impl PlaneFrame {
    fn new(origin: Vec3, normal: Vec3) -> Self {
        let normal = normal.normalize();
        let (u, v) = axes_across(&normal);
        PlaneFrame { origin, normal, u, v }
    }

    fn to_2d(&self, p: Vec3) -> (f64, f64) {
        let d = p - self.origin;
        (d.dot(&self.u), d.dot(&self.v))
    }

    /// The plane's cut through every triangle of a closed surface, as 2D segments.
    fn cut(&self, mesh: &TriMesh) -> Vec<Segment> {
        (0..mesh.triangles.len())
            .filter_map(|t| {
                let corners = mesh.triangle_points(t);
                let d = corners.map(|p| (p - self.origin).dot(&self.normal));
                let crossings: Vec<Vec3> = (0..3)
                    .filter(|&e| (d[e] > 0.0) != (d[(e + 1) % 3] > 0.0))
                    .map(|e| {
                        let (a, b) = (corners[e], corners[(e + 1) % 3]);
                        a + (b - a) * (d[e] / (d[e] - d[(e + 1) % 3]))
                    })
                    .collect();
                (crossings.len() == 2).then(|| [self.to_2d(crossings[0]), self.to_2d(crossings[1])])
            })
            .collect()
    }
}

fn segment_bounds(segments: &[Segment]) -> Option<((f64, f64), (f64, f64))> {
    let points = segments.iter().flatten();
    let lo = points.clone().fold((f64::INFINITY, f64::INFINITY), |a, p| (a.0.min(p.0), a.1.min(p.1)));
    let hi = points.fold((f64::NEG_INFINITY, f64::NEG_INFINITY), |a, p| (a.0.max(p.0), a.1.max(p.1)));
    lo.0.is_finite().then_some((lo, hi))
}

/// A pixel grid over the section's bounding box (pixel centres at lo + (i + 0.5) px).
struct Raster {
    lo: (f64, f64),
    width: usize,
    height: usize,
}

impl Raster {
    fn new(lo: (f64, f64), hi: (f64, f64)) -> Self {
        let size = |a: f64, b: f64| ((b - a) / PIXEL_MM).ceil() as usize + 1;
        Raster { lo, width: size(lo.0, hi.0), height: size(lo.1, hi.1) }
    }

    /// Even-odd fill of closed loops given as segments, row by row.
    fn fill(&self, segments: &[Segment]) -> Vec<bool> {
        let mut inside = vec![false; self.width * self.height];
        let mut xs = Vec::new();
        for j in 0..self.height {
            let y = self.lo.1 + (j as f64 + 0.5) * PIXEL_MM;
            xs.clear();
            // Half-open in y: a row through a shared end point counts it once.
            for &[a, b] in segments.iter().filter(|[a, b]| (a.1 <= y) != (b.1 <= y)) {
                xs.push(a.0 + (y - a.1) * (b.0 - a.0) / (b.1 - a.1));
            }
            xs.sort_by(f64::total_cmp);
            for pair in xs.chunks_exact(2) {
                let first = ((pair[0] - self.lo.0) / PIXEL_MM - 0.5).ceil().max(0.0) as usize;
                let last = (((pair[1] - self.lo.0) / PIXEL_MM - 0.5).floor().min(self.width as f64 - 1.0)) as i64;
                for i in first as i64..=last {
                    inside[j * self.width + i as usize] = true;
                }
            }
        }
        inside
    }

    /// The inside pixel nearest to `p` (within 3 pixels).
    fn nearest_inside(&self, inside: &[bool], p: (f64, f64)) -> Option<usize> {
        let i0 = ((p.0 - self.lo.0) / PIXEL_MM - 0.5).round() as i64;
        let j0 = ((p.1 - self.lo.1) / PIXEL_MM - 0.5).round() as i64;
        let mut best: Option<(i64, usize)> = None;
        for dj in -3..=3i64 {
            for di in -3..=3i64 {
                let (i, j) = (i0 + di, j0 + dj);
                if i < 0 || j < 0 || i >= self.width as i64 || j >= self.height as i64 {
                    continue;
                }
                let index = j as usize * self.width + i as usize;
                if inside[index] && best.is_none_or(|(d, _)| di * di + dj * dj < d) {
                    best = Some((di * di + dj * dj, index));
                }
            }
        }
        best.map(|(_, index)| index)
    }

    /// Pixels 4-connected to `seed` inside.
    fn flood_count(&self, inside: &[bool], seed: usize) -> usize {
        self.flood(inside, seed, |_, _| ())
    }

    /// Visit (column, row) of every pixel 4-connected to `seed` inside; their count.
    fn flood(&self, inside: &[bool], seed: usize, mut visit: impl FnMut(usize, usize)) -> usize {
        let mut seen = vec![false; inside.len()];
        let mut stack = vec![seed];
        seen[seed] = true;
        let mut count = 0;
        while let Some(p) = stack.pop() {
            count += 1;
            let (i, j) = (p % self.width, p / self.width);
            visit(i, j);
            let neighbours = [(i > 0).then(|| p - 1), (i + 1 < self.width).then(|| p + 1), (j > 0).then(|| p - self.width), (j + 1 < self.height).then(|| p + self.width)];
            for q in neighbours.into_iter().flatten() {
                if inside[q] && !seen[q] {
                    seen[q] = true;
                    stack.push(q);
                }
            }
        }
        count
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A closed prism of `n` sides around the z axis, radius 1, its cross-section the polygon
    /// scaled by (`rx`, `ry`), from z = 0 to 10.
    fn prism(rx: f64, ry: f64, n: usize) -> TriMesh {
        let ring = |z: f64| (0..n).map(move |k| {
            let t = 2.0 * std::f64::consts::PI * k as f64 / n as f64;
            Vec3::new(rx * t.cos(), ry * t.sin(), z)
        });
        let mut points: Vec<Vec3> = ring(0.0).chain(ring(10.0)).collect();
        points.extend([Vec3::new(0.0, 0.0, 0.0), Vec3::new(0.0, 0.0, 10.0)]);
        let (n32, bottom, top) = (n as u32, 2 * n as u32, 2 * n as u32 + 1);
        let mut triangles = Vec::new();
        for k in 0..n32 {
            let k1 = (k + 1) % n32;
            triangles.extend([[k, k1, n32 + k1], [k, n32 + k1, n32 + k], [bottom, k1, k], [top, n32 + k, n32 + k1]]);
        }
        let face_ids = vec![2; triangles.len()];
        TriMesh::new(points, triangles, face_ids)
    }

    #[test]
    fn a_disc_is_round_and_an_ellipse_has_its_axes_ratio() {
        let disc = section_shape(&prism(4.0, 4.0, 256), Vec3::new(0.0, 0.0, 5.0), Vec3::z()).unwrap();
        assert!((disc.area_mm2 - std::f64::consts::PI * 16.0).abs() < 0.01 * disc.area_mm2 && disc.aspect_ratio > 0.99, "{disc:?}");
        // Cut across the axis at a tilt the shape is the ellipse's, and the area the section's.
        let ellipse = section_shape(&prism(6.0, 2.0, 256), Vec3::new(0.0, 0.0, 5.0), Vec3::z()).unwrap();
        assert!((ellipse.aspect_ratio - 2.0 / 6.0).abs() < 0.01, "{ellipse:?}");
        let tilted = section_shape(&prism(4.0, 4.0, 256), Vec3::new(0.0, 0.0, 5.0), Vec3::new(1.0, 0.0, 1.0)).unwrap();
        assert!((tilted.aspect_ratio - 45f64.to_radians().cos()).abs() < 0.01, "{tilted:?}");
        // The same piece as section_area's.
        assert_eq!(Some(ellipse.area_mm2), section_area(&prism(6.0, 2.0, 256), None, Vec3::new(0.0, 0.0, 5.0), Vec3::z()));
    }
}
