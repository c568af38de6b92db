//! Step 1: inside/outside masks of closed surfaces on a regular grid [paper 2.2.2:
//! the blood pools are joined as volumes, so the union has no internal walls].
//! The voxelizer itself lives in `baffle_core::geometry::voxel` (the flow-domain centerline
//! uses it too); the morphological closing is this crate's.

pub use baffle_core::geometry::voxel::{voxelize, Grid};
use rayon::prelude::*;

/// Morphological closing (dilation, then erosion) with a cube of half-width
/// `radius_voxels`: fills gaps narrower than about twice the radius, as the
/// paper's label-map pipeline does before contouring (e.g. the thin wedge where
/// two touching blood pools part at the rim of their contact).
pub fn close_mask(mask: &[bool], grid: &Grid, radius_voxels: usize) -> Vec<bool> {
    if radius_voxels == 0 {
        return mask.to_vec();
    }
    let dilated = (0..3).fold(mask.to_vec(), |m, axis| sweep_axis(&m, grid, axis, radius_voxels, true));
    (0..3).fold(dilated, |m, axis| sweep_axis(&m, grid, axis, radius_voxels, false))
}

/// Running max (`dilate`) or min over `2 r + 1` voxels along one axis; beyond the
/// grid counts as empty for dilation and as full for erosion (no erosion from the border).
fn sweep_axis(mask: &[bool], grid: &Grid, axis: usize, r: usize, dilate: bool) -> Vec<bool> {
    let strides = [1, grid.dims[0], grid.dims[0] * grid.dims[1]];
    let (stride, n) = (strides[axis], grid.dims[axis]);
    (0..mask.len())
        .into_par_iter()
        .map(|idx| {
            let c = (idx / stride) % n;
            let (lo, hi) = (c.saturating_sub(r), (c + r).min(n - 1));
            let base = idx - c * stride;
            if dilate {
                (lo..=hi).any(|q| mask[base + q * stride])
            } else {
                (lo..=hi).all(|q| mask[base + q * stride])
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::{box_mesh, uv_sphere};
    use baffle_core::Vec3;

    #[test]
    fn sphere_volume_matches_voxel_count() {
        let sphere = uv_sphere(Vec3::new(0.1, 0.2, 0.3), 5.0, 48, 96);
        let grid = Grid::covering(Vec3::repeat(-6.0), Vec3::repeat(6.0), 0.25, 2);
        let mask = voxelize(&sphere, &grid);
        let voxel_volume = mask.iter().filter(|&&m| m).count() as f64 * 0.25f64.powi(3);
        let exact = sphere.signed_volume_mm3();
        assert!((voxel_volume / exact - 1.0).abs() < 0.01, "voxels {voxel_volume} vs {exact}");
    }

    #[test]
    fn grid_aligned_box_counts_each_column_once() {
        // Box corners exactly on voxel centres: every shared edge and corner is hit.
        let cube = box_mesh(Vec3::new(0.0, 0.0, 0.0), Vec3::new(2.0, 2.0, 2.0));
        let grid = Grid { origin: Vec3::repeat(-1.0), spacing_mm: 0.5, dims: [9, 9, 9] };
        let mask = voxelize(&cube, &grid);
        for k in 0..9 {
            for j in 0..9 {
                let run: Vec<bool> = (0..9).map(|i| mask[grid.index(i, j, k)]).collect();
                // Inside voxels form one contiguous run (no parity flip-flop).
                let changes = run.windows(2).filter(|w| w[0] != w[1]).count();
                assert!(changes == 0 || changes == 2, "column {j},{k}: {run:?}");
            }
        }
        let count = mask.iter().filter(|&&m| m).count();
        // Centres on the box faces are counted on one side only: 4 of 5 per axis.
        assert_eq!(count, 4 * 4 * 4);
    }

    #[test]
    fn closing_fills_a_narrow_gap_and_keeps_the_rest() {
        // Two slabs one voxel apart along x.
        let grid = Grid { origin: Vec3::zeros(), spacing_mm: 1.0, dims: [12, 6, 6] };
        let slab = |i: usize, j: usize, k: usize| (1..5).contains(&j) && (1..5).contains(&k) && ((2..5).contains(&i) || (6..9).contains(&i));
        let mask: Vec<bool> = (0..grid.voxel_count()).map(|v| slab(v % 12, (v / 12) % 6, v / 72)).collect();
        let closed = close_mask(&mask, &grid, 1);
        assert!(closed[grid.index(5, 2, 2)], "gap voxel filled");
        assert!(!closed[grid.index(1, 2, 2)] && !closed[grid.index(9, 2, 2)], "outside stays outside");
        assert!(mask.iter().zip(&closed).all(|(&m, &c)| !m || c), "closing only adds");
    }

    #[test]
    fn inward_winding_gives_the_same_mask() {
        let sphere = uv_sphere(Vec3::zeros(), 3.0, 24, 48);
        let mut flipped = sphere.clone();
        flipped.triangles.iter_mut().for_each(|t| t.swap(1, 2));
        let grid = Grid::covering(Vec3::repeat(-4.0), Vec3::repeat(4.0), 0.3, 1);
        assert_eq!(voxelize(&sphere, &grid), voxelize(&flipped, &grid));
    }
}
