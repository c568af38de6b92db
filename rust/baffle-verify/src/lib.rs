//! Independent re-measurement of baffle designs: for tests, and for the design's checks
//! of its own output ([`design_checks`]).
//!
//! Uses only the `TriMesh` data type from `baffle-core`: every measurement here
//! (plane sections, enclosed volume, edge use, winding) is computed with its own
//! code, so a test that compares these numbers with what the design reports
//! checks the construction with a second implementation.

mod design_checks;
mod slice;
mod topology;

pub use design_checks::{checked_design, design_checks};
pub use slice::{contour_area_mm2, section_area_nearest, slice_by_plane, Contour};
pub use topology::{edge_usage_counts, is_consistently_oriented, signed_volume_mm3};

use baffle_core::TriMesh;

/// Every triangle refers to existing points and every point is finite.
fn check_mesh(mesh: &TriMesh) -> Result<(), String> {
    if let Some((p, point)) = mesh
        .points
        .iter()
        .enumerate()
        .find(|(_, p)| !p.iter().all(|c| c.is_finite()))
    {
        return Err(format!("point {p} has non-finite coordinates {point:?}"));
    }
    for (t, tri) in mesh.triangles.iter().enumerate() {
        if let Some(&p) = tri.iter().find(|&&p| p as usize >= mesh.points.len()) {
            return Err(format!(
                "triangle {t} uses point {p}, but the mesh has {} points",
                mesh.points.len()
            ));
        }
    }
    Ok(())
}

/// Meshes shared by the unit tests.
#[cfg(test)]
pub(crate) mod test_meshes {
    use baffle_core::{TriMesh, Vec3};
    use std::f64::consts::PI;

    /// Closed, outward-wound cylinder on the z axis from z = 0 to `height_mm`:
    /// `segments` points per ring, `rings` rings, caps fanned to a centre point.
    pub fn closed_cylinder(radius_mm: f64, height_mm: f64, segments: u32, rings: u32) -> TriMesh {
        let mut points = Vec::new();
        for r in 0..rings {
            let z = height_mm * r as f64 / (rings - 1) as f64;
            for s in 0..segments {
                let a = 2.0 * PI * s as f64 / segments as f64;
                points.push(Vec3::new(radius_mm * a.cos(), radius_mm * a.sin(), z));
            }
        }
        let ring = |r: u32, s: u32| r * segments + s % segments;
        let mut triangles = Vec::new();
        for r in 0..rings - 1 {
            for s in 0..segments {
                triangles.push([ring(r, s), ring(r, s + 1), ring(r + 1, s + 1)]);
                triangles.push([ring(r, s), ring(r + 1, s + 1), ring(r + 1, s)]);
            }
        }
        let bottom = points.len() as u32;
        points.push(Vec3::new(0.0, 0.0, 0.0));
        let top = points.len() as u32;
        points.push(Vec3::new(0.0, 0.0, height_mm));
        for s in 0..segments {
            triangles.push([bottom, ring(0, s + 1), ring(0, s)]);
            triangles.push([top, ring(rings - 1, s), ring(rings - 1, s + 1)]);
        }
        let n = triangles.len();
        TriMesh::new(points, triangles, vec![2; n])
    }

    /// Area of the regular `segments`-gon inscribed in a circle of `radius_mm`.
    pub fn inscribed_polygon_area_mm2(radius_mm: f64, segments: u32) -> f64 {
        0.5 * segments as f64 * radius_mm * radius_mm * (2.0 * PI / segments as f64).sin()
    }

    /// Unit tetrahedron (corners at the origin and the unit axes), outward wound.
    pub fn tetrahedron() -> TriMesh {
        let points = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
        ];
        TriMesh::new(
            points,
            vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
            vec![2; 4],
        )
    }

    /// xorshift64*: deterministic test randomness without a dependency.
    pub struct Rng(pub u64);

    impl Rng {
        pub fn unit(&mut self) -> f64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
        }
    }
}
