//! Comparing a designed baffle with a reference surface (e.g. the paper's published
//! baffle): area ratio and symmetric vertex-to-surface distances. A report line,
//! never a target the design is tuned to.

use crate::geometry::mesh::TriMesh;
use crate::geometry::spatial::TriangleBvh;
use serde::Serialize;

#[derive(Clone, Debug, Serialize)]
pub struct SurfaceComparison {
    pub area_mm2: f64,
    pub reference_area_mm2: f64,
    pub area_ratio: f64,
    /// Mean over both directions of the vertex-to-surface distances (mm).
    pub mean_distance_mm: f64,
    /// Largest vertex-to-surface distance either way (mm).
    pub max_distance_mm: f64,
}

/// Compare `surface` with `reference` (both in mm).
pub fn compare_surfaces(surface: &TriMesh, reference: &TriMesh) -> Result<SurfaceComparison, String> {
    let (ab_mean, ab_max) = one_sided_distance(surface, reference)?;
    let (ba_mean, ba_max) = one_sided_distance(reference, surface)?;
    let (area_mm2, reference_area_mm2) = (surface.area_mm2(), reference.area_mm2());
    Ok(SurfaceComparison {
        area_mm2,
        reference_area_mm2,
        area_ratio: area_mm2 / reference_area_mm2,
        mean_distance_mm: 0.5 * (ab_mean + ba_mean),
        max_distance_mm: ab_max.max(ba_max),
    })
}

/// Mean and max distance from the vertices of `a` to the surface `b`.
fn one_sided_distance(a: &TriMesh, b: &TriMesh) -> Result<(f64, f64), String> {
    let bvh = TriangleBvh::new(b)?;
    let mut distances = Vec::with_capacity(a.points.len());
    for p in &a.points {
        distances.push(bvh.closest_point(b, *p).ok_or("the reference surface is empty")?.distance_mm);
    }
    if distances.is_empty() {
        return Err("the compared surface has no points".into());
    }
    let mean = distances.iter().sum::<f64>() / distances.len() as f64;
    Ok((mean, distances.iter().copied().fold(0.0, f64::max)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::mesh::Vec3;

    fn square(z: f64, side: f64) -> TriMesh {
        let p = vec![Vec3::new(0.0, 0.0, z), Vec3::new(side, 0.0, z), Vec3::new(side, side, z), Vec3::new(0.0, side, z)];
        TriMesh::new(p, vec![[0, 1, 2], [0, 2, 3]], vec![10, 10])
    }

    #[test]
    fn parallel_squares_are_their_gap_apart() {
        let c = compare_surfaces(&square(0.5, 2.0), &square(0.0, 2.0)).unwrap();
        assert!((c.mean_distance_mm - 0.5).abs() < 1e-12 && (c.max_distance_mm - 0.5).abs() < 1e-12);
        assert!((c.area_ratio - 1.0).abs() < 1e-12);
        let c = compare_surfaces(&square(0.0, 1.0), &square(0.0, 2.0)).unwrap();
        assert!((c.area_ratio - 0.25).abs() < 1e-12);
        // Reference corners (2,2) etc. are up to sqrt(2) from the small square.
        assert!((c.max_distance_mm - 2f64.sqrt()).abs() < 1e-12);
    }
}
