//! Taubin's lambda|mu smoothing (Taubin 1995) with uniform (umbrella) weights: removes
//! high-frequency steps (a voxelized union's, an acquisition's noise) without the
//! shrinkage of plain Laplacian rounds. Shared by `prepare`'s union surface and the
//! smoothed-wall perturbation of the realism families (`baffle-test-support`).

use crate::geometry::mesh::{TriMesh, Vec3};
use rayon::prelude::*;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SmoothingOptions {
    pub iterations: usize,
    pub lambda: f64,
    pub mu: f64,
}

impl Default for SmoothingOptions {
    /// Taubin (1995)'s pass-band 0.1: lambda 0.5, mu -0.53.
    fn default() -> Self {
        SmoothingOptions { iterations: 20, lambda: 0.5, mu: -0.53 }
    }
}

/// Point neighbours through edges, as compressed rows (row starts, neighbour indices).
pub fn point_neighbors(mesh: &TriMesh) -> (Vec<usize>, Vec<u32>) {
    let mut pairs: Vec<(u32, u32)> = mesh.triangles.iter().flat_map(|t| (0..3).flat_map(move |k| [(t[k], t[(k + 1) % 3]), (t[(k + 1) % 3], t[k])])).collect();
    pairs.par_sort_unstable();
    pairs.dedup();
    let mut start = vec![0usize; mesh.points.len() + 1];
    pairs.iter().for_each(|&(a, _)| start[a as usize + 1] += 1);
    for i in 0..mesh.points.len() {
        start[i + 1] += start[i];
    }
    (start, pairs.into_iter().map(|(_, b)| b).collect())
}

/// Taubin smoothing of every point.
pub fn taubin_smooth(mesh: &mut TriMesh, options: &SmoothingOptions) {
    let (start, neighbors) = point_neighbors(mesh);
    taubin_smooth_pinned(mesh, options, &vec![false; mesh.points.len()], (&start, &neighbors));
}

/// Taubin smoothing that leaves the `pinned` points where they are.
pub fn taubin_smooth_pinned(mesh: &mut TriMesh, options: &SmoothingOptions, pinned: &[bool], (start, neighbors): (&[usize], &[u32])) {
    let step = |points: &[Vec3], factor: f64| -> Vec<Vec3> {
        (0..points.len())
            .into_par_iter()
            .map(|i| {
                let ring = &neighbors[start[i]..start[i + 1]];
                if ring.is_empty() || pinned[i] {
                    return points[i];
                }
                let mean = ring.iter().map(|&j| points[j as usize]).sum::<Vec3>() / ring.len() as f64;
                points[i] + factor * (mean - points[i])
            })
            .collect()
    };
    for _ in 0..options.iterations {
        let shrunk = step(&mesh.points, options.lambda);
        mesh.points = step(&shrunk, options.mu);
    }
}
