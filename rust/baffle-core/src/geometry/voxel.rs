//! Inside/outside masks of closed triangle surfaces on a regular grid.
//!
//! Each grid column along x is a ray; every triangle adds a signed crossing to
//! the columns its (y, z) shadow covers, and a voxel centre is inside when the
//! winding number of the crossings before it is not zero. Shadow edges follow
//! the rasterizer's top-left rule, so a column through a shared edge or corner
//! is crossed exactly once: the count is exact, not a ray-parity guess.
//! Used by `baffle-prepare` (joining blood pools) and [`crate::analyses::flow_centerline`].

use crate::geometry::mesh::{TriMesh, Vec3};
use rayon::prelude::*;
use std::cmp::Ordering;
use std::collections::BinaryHeap;

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

    /// (i, j, k) of the voxel with linear index `v`.
    #[inline]
    pub fn ijk(&self, v: usize) -> [usize; 3] {
        let (nx, ny) = (self.dims[0], self.dims[1]);
        [v % nx, (v / nx) % ny, v / (nx * ny)]
    }

    /// Centre of the voxel with linear index `v`.
    #[inline]
    pub fn centre(&self, v: usize) -> Vec3 {
        let [i, j, k] = self.ijk(v);
        self.position(i, j, k)
    }

    /// The (up to 26) voxels sharing a face, edge or corner with `v`, each with the
    /// distance between the centres (mm).
    pub fn neighbours26(&self, v: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        let ijk = self.ijk(v).map(|c| c as i64);
        let d = self.dims.map(|n| n as i64);
        (0..27).filter(|&o| o != 13).filter_map(move |o| {
            let off = [o % 3 - 1, (o / 3) % 3 - 1, o / 9 - 1];
            let n = [ijk[0] + off[0], ijk[1] + off[1], ijk[2] + off[2]];
            if (0..3).any(|a| n[a] < 0 || n[a] >= d[a]) {
                return None;
            }
            let len = self.spacing_mm * ((off[0] * off[0] + off[1] * off[1] + off[2] * off[2]) as f64).sqrt();
            Some(((n[0] + d[0] * (n[1] + d[1] * n[2])) as usize, len))
        })
    }
}

/// What a best-first search found: per voxel its cost (infinite where not reached) and
/// the voxel it was reached from.
pub struct Search {
    pub cost: Vec<f64>,
    previous: Vec<u32>,
    /// The first voxel settled that met the stop test.
    pub reached: Option<usize>,
}

impl Search {
    /// The voxels from a source to `v` (empty when `v` was not reached).
    pub fn path_to(&self, v: usize) -> Vec<usize> {
        if !self.cost[v].is_finite() {
            return Vec::new();
        }
        let mut path = vec![v];
        while let Some(&p) = self.previous.get(*path.last().unwrap_or(&v)).filter(|&&p| p != u32::MAX) {
            path.push(p as usize);
        }
        path.reverse();
        path
    }
}

/// A queued voxel, ordered so that the heap pops the lowest cost (then the lowest index).
#[derive(PartialEq)]
struct Queued(f64, usize);

impl Eq for Queued {}

impl Ord for Queued {
    fn cmp(&self, other: &Self) -> Ordering {
        other.0.total_cmp(&self.0).then(other.1.cmp(&self.1))
    }
}

impl PartialOrd for Queued {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

/// Dijkstra's search over the 26-connected voxels where `passable`, from `sources`
/// (cost 0). `step(cost at v, v, w, centre distance mm)` is the cost at w through v and
/// must not be below the cost at v (sums of non-negative steps, running maxima). Stops
/// when it settles a voxel for which `stop` holds.
pub fn best_first_search(
    grid: &Grid,
    sources: &[usize],
    passable: impl Fn(usize) -> bool,
    step: impl Fn(f64, usize, usize, f64) -> f64,
    stop: impl Fn(usize) -> bool,
) -> Search {
    let mut cost = vec![f64::INFINITY; grid.voxel_count()];
    let mut previous = vec![u32::MAX; grid.voxel_count()];
    let mut heap = BinaryHeap::new();
    for &s in sources {
        cost[s] = 0.0;
        heap.push(Queued(0.0, s));
    }
    let mut reached = None;
    while let Some(Queued(c, v)) = heap.pop() {
        if c > cost[v] {
            continue;
        }
        if stop(v) {
            reached = Some(v);
            break;
        }
        for (w, len) in grid.neighbours26(v) {
            if !passable(w) {
                continue;
            }
            let next = step(c, v, w, len);
            if next < cost[w] {
                cost[w] = next;
                previous[w] = v as u32;
                heap.push(Queued(next, w));
            }
        }
    }
    Search { cost, previous, reached }
}

/// Squared Euclidean distance (mm2) from every voxel centre to the nearest centre of a
/// `feature` voxel; exact, separable along x, y and z (Felzenszwalb and Huttenlocher
/// 2012, "Distance transforms of sampled functions"). Without features it is huge
/// (1e30) everywhere.
pub fn squared_distance_transform(grid: &Grid, feature: &[bool]) -> Vec<f64> {
    const FAR: f64 = 1e30;
    let mut d: Vec<f64> = feature.iter().map(|&f| if f { 0.0 } else { FAR }).collect();
    let [nx, ny, nz] = grid.dims;
    let strides = [1, nx, nx * ny];
    for axis in 0..3 {
        let n = grid.dims[axis];
        let mut line = vec![0.0; n];
        let mut envelope = LowerEnvelope::new(n);
        for start in (0..nx * ny * nz).filter(|&v| grid.ijk(v)[axis] == 0) {
            for (q, value) in line.iter_mut().enumerate() {
                *value = d[start + q * strides[axis]];
            }
            envelope.transform(&mut line);
            for (q, value) in line.iter().enumerate() {
                d[start + q * strides[axis]] = *value;
            }
        }
    }
    let h2 = grid.spacing_mm * grid.spacing_mm;
    d.iter_mut().for_each(|x| *x = (*x * h2).min(FAR));
    d
}

/// The 1D pass of the distance transform: f(q) <- min_p (q - p)^2 + f(p), through the
/// lower envelope of the parabolas rooted at each p.
struct LowerEnvelope {
    roots: Vec<usize>,
    bounds: Vec<f64>,
    out: Vec<f64>,
}

impl LowerEnvelope {
    fn new(n: usize) -> Self {
        LowerEnvelope { roots: vec![0; n], bounds: vec![0.0; n + 1], out: vec![0.0; n] }
    }

    fn transform(&mut self, f: &mut [f64]) {
        let n = f.len();
        let crossing = |f: &[f64], q: usize, p: usize| ((f[q] + (q * q) as f64) - (f[p] + (p * p) as f64)) / (2.0 * (q as f64 - p as f64));
        let mut k = 0;
        self.roots[0] = 0;
        self.bounds[0] = f64::NEG_INFINITY;
        self.bounds[1] = f64::INFINITY;
        for q in 1..n {
            // bounds[0] is -infinity: the loop stops at k = 0.
            let mut s = crossing(f, q, self.roots[k]);
            while s <= self.bounds[k] {
                k -= 1;
                s = crossing(f, q, self.roots[k]);
            }
            k += 1;
            self.roots[k] = q;
            self.bounds[k] = s;
            self.bounds[k + 1] = f64::INFINITY;
        }
        k = 0;
        for q in 0..n {
            while self.bounds[k + 1] < q as f64 {
                k += 1;
            }
            let p = self.roots[k];
            self.out[q] = (q as f64 - p as f64).powi(2) + f[p];
        }
        f.copy_from_slice(&self.out[..n]);
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


#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_distance_transform_is_the_brute_force_minimum() {
        let grid = Grid { origin: Vec3::zeros(), spacing_mm: 0.5, dims: [9, 7, 5] };
        let feature: Vec<bool> = (0..grid.voxel_count()).map(|v| v % 17 == 3 || v == 200).collect();
        let d2 = squared_distance_transform(&grid, &feature);
        for v in 0..grid.voxel_count() {
            let brute = (0..grid.voxel_count()).filter(|&f| feature[f]).map(|f| (grid.centre(v) - grid.centre(f)).norm_squared()).fold(f64::INFINITY, f64::min);
            assert!((d2[v] - brute).abs() < 1e-9, "voxel {v}: {} vs {brute}", d2[v]);
        }
    }

    #[test]
    fn neighbours_stay_on_the_grid() {
        let grid = Grid { origin: Vec3::zeros(), spacing_mm: 2.0, dims: [3, 3, 3] };
        assert_eq!(grid.neighbours26(13).count(), 26);
        let corner: Vec<(usize, f64)> = grid.neighbours26(0).collect();
        assert_eq!(corner.len(), 7);
        for (w, len) in corner {
            assert!((len - (grid.centre(w) - grid.centre(0)).norm()).abs() < 1e-12);
        }
    }
}
