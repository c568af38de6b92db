//! Inside/outside masks of closed triangle surfaces on a regular grid.
//!
//! Each grid column along x is a ray; every triangle adds a signed crossing to
//! the columns its (y, z) shadow covers, and a voxel centre is inside when the
//! winding number of the crossings before it is not zero. Shadow edges follow
//! the rasterizer's top-left rule, so a column through a shared edge or corner
//! is crossed exactly once: the count is exact, not a ray-parity guess.
//! Used by `baffle-prepare` (joining blood pools) and [`crate::flow_centerline`].

use crate::mesh::{TriMesh, Vec3};
use rayon::prelude::*;

/// A regular grid of voxel centres: `origin + spacing_mm * (i, j, k)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grid {
    pub origin: Vec3,
    pub spacing_mm: f64,
    pub dims: [usize; 3],
}

impl Grid {
    /// A grid covering `lo..hi` with `margin_voxels` empty voxels on every side.
    pub fn covering(lo: Vec3, hi: Vec3, spacing_mm: f64, margin_voxels: usize) -> Grid {
        let margin = spacing_mm * margin_voxels as f64;
        let origin = lo - Vec3::repeat(margin);
        let extent = hi - lo + Vec3::repeat(2.0 * margin);
        let dims = [0, 1, 2].map(|a| (extent[a] / spacing_mm).ceil() as usize + 1);
        Grid { origin, spacing_mm, dims }
    }

    pub fn voxel_count(&self) -> usize {
        self.dims[0] * self.dims[1] * self.dims[2]
    }

    #[inline]
    pub fn index(&self, i: usize, j: usize, k: usize) -> usize {
        i + self.dims[0] * (j + self.dims[1] * k)
    }

    #[inline]
    pub fn position(&self, i: usize, j: usize, k: usize) -> Vec3 {
        self.origin + self.spacing_mm * Vec3::new(i as f64, j as f64, k as f64)
    }
}

/// One crossing of a grid column by a triangle.
#[derive(Clone, Copy, Debug)]
struct Crossing {
    column: usize,
    x_mm: f64,
    /// +1 entering the solid along +x for an outward-wound surface, -1 leaving.
    winding: i8,
}

/// Voxels of `grid` whose centre lies inside the closed surface `mesh`
/// (non-zero winding number, so either winding of the surface works).
pub fn voxelize(mesh: &TriMesh, grid: &Grid) -> Vec<bool> {
    let mut crossings: Vec<Crossing> =
        (0..mesh.triangles.len()).into_par_iter().flat_map_iter(|t| triangle_crossings(&mesh.triangle_points(t), grid)).collect();
    crossings.par_sort_unstable_by(|a, b| a.column.cmp(&b.column).then(a.x_mm.total_cmp(&b.x_mm)));
    let mut mask = vec![false; grid.voxel_count()];
    let nx = grid.dims[0];
    for run in crossings.chunk_by(|a, b| a.column == b.column) {
        let column = run[0].column;
        let row = &mut mask[column * nx..(column + 1) * nx];
        fill_column(row, run, grid.origin.x, grid.spacing_mm);
    }
    mask
}

/// Mark the voxels of one x-row whose winding number is not zero.
fn fill_column(row: &mut [bool], sorted: &[Crossing], x0: f64, h: f64) {
    let mut winding = 0i32;
    let mut next = 0;
    for (i, cell) in row.iter_mut().enumerate() {
        let x = x0 + h * i as f64;
        while next < sorted.len() && sorted[next].x_mm < x {
            winding += sorted[next].winding as i32;
            next += 1;
        }
        *cell = winding != 0;
    }
}

/// 2D edge function: twice the signed area of (a, b, p).
#[inline]
fn edge_function(a: (f64, f64), b: (f64, f64), p: (f64, f64)) -> f64 {
    (b.0 - a.0) * (p.1 - a.1) - (b.1 - a.1) * (p.0 - a.0)
}

/// Top-left rule for a counter-clockwise triangle: an edge owns the points on it
/// when it is a "left" edge (going down) or a horizontal "top" edge (going left).
#[inline]
fn owns_edge(a: (f64, f64), b: (f64, f64)) -> bool {
    let (dy, dz) = (b.0 - a.0, b.1 - a.1);
    dz < 0.0 || (dz == 0.0 && dy < 0.0)
}

fn triangle_crossings(tri: &[Vec3; 3], grid: &Grid) -> Vec<Crossing> {
    let n = (tri[1] - tri[0]).cross(&(tri[2] - tri[0]));
    if n.x == 0.0 || !n.x.is_finite() {
        return Vec::new();
    }
    // Shadow in (y, z), counter-clockwise.
    let mut s = tri.map(|p| (p.y, p.z));
    if n.x < 0.0 {
        s.swap(1, 2);
    }
    let winding = if n.x < 0.0 { 1 } else { -1 };
    let h = grid.spacing_mm;
    let (oy, oz) = (grid.origin.y, grid.origin.z);
    let lo_y = s.iter().map(|p| p.0).fold(f64::INFINITY, f64::min);
    let hi_y = s.iter().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max);
    let lo_z = s.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
    let hi_z = s.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max);
    let range = |lo: f64, hi: f64, o: f64, n: usize| {
        let first = ((lo - o) / h).ceil().max(0.0) as i64;
        let last = ((hi - o) / h).floor().min(n as f64 - 1.0) as i64;
        first..=last
    };
    let owned = [owns_edge(s[1], s[2]), owns_edge(s[2], s[0]), owns_edge(s[0], s[1])];
    let mut out = Vec::new();
    for k in range(lo_z, hi_z, oz, grid.dims[2]) {
        for j in range(lo_y, hi_y, oy, grid.dims[1]) {
            let (j, k) = (j as usize, k as usize);
            let p = (oy + h * j as f64, oz + h * k as f64);
            let w = [edge_function(s[1], s[2], p), edge_function(s[2], s[0], p), edge_function(s[0], s[1], p)];
            let inside = (0..3).all(|e| w[e] > 0.0 || (w[e] == 0.0 && owned[e]));
            if !inside {
                continue;
            }
            // x where the triangle's plane meets the column.
            let x_mm = tri[0].x - (n.y * (p.0 - tri[0].y) + n.z * (p.1 - tri[0].z)) / n.x;
            out.push(Crossing { column: j + grid.dims[1] * k, x_mm, winding });
        }
    }
    out
}

