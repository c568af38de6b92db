//! The section of a closed surface by a plane, as an area: the piece of {inside a solid,
//! outside an optional hole} in the plane that holds a given point. Both surfaces' cut
//! segments are filled on a [`PIXEL_MM`] raster (even-odd) and the 4-connected piece
//! holding the point is counted. Used by the RV outflow (`crate::analyses::rv_outflow`) and by the
//! flow-normal sections of a lumen (`crate::analyses::flow_centerline`).

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
    let plane = PlaneFrame::new(point, normal);
    let solid_cut = plane.cut(solid);
    let hole_cut = hole.map(|h| plane.cut(h)).unwrap_or_default();
    let (lo, hi) = segment_bounds(&solid_cut)?;
    let raster = Raster::new(lo, hi);
    let solid_fill = raster.fill(&solid_cut);
    let inside: Vec<bool> = solid_fill.iter().zip(raster.fill(&hole_cut)).map(|(&s, h)| s && !h).collect();
    let seed = raster.nearest_inside(&inside, (0.0, 0.0))?;
    let pixel_mm2 = PIXEL_MM * PIXEL_MM;
    let region_mm2 = raster.flood_count(&inside, seed) as f64 * pixel_mm2;
    let solid_mm2 = if hole.is_some() { raster.flood_count(&solid_fill, seed) as f64 * pixel_mm2 } else { region_mm2 };
    Some(SectionAreas { region_mm2, solid_mm2 })
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
        let mut seen = vec![false; inside.len()];
        let mut stack = vec![seed];
        seen[seed] = true;
        let mut count = 0;
        while let Some(p) = stack.pop() {
            count += 1;
            let (i, j) = (p % self.width, p / self.width);
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
