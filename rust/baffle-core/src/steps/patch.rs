//! Step 3, the initial patch [paper 2.3.3].
//!
//! The seam is split at its points nearest the VSD and aortic caps; each side is
//! mapped by arc length onto half the perimeter of a structured unit disk, so the
//! split points land at (-1, 0) and (1, 0). Interior thin-plate-spline control points
//! on the disk's diameter are mapped to evenly spaced points of R_init, the straight
//! segment joining the two split points. The TPS map of the disk is the initial patch;
//! its boundary vertices are then restored to the seam vertices exactly.
//!
//! The disk parameterization is kept: the final surface (step 8) is a second TPS map
//! of the same disk.

use crate::error::DesignError;
use crate::geometry::mesh::Vec3;
use crate::geometry::numerics::tps::TpsSolver;
use crate::geometry::spatial::closest_point_on_segment;
use std::f64::consts::{PI, TAU};

/// A structured triangulation of the unit disk: a centre vertex and concentric rings,
/// the outer ring being the seam (one disk vertex per seam vertex, same order).
#[derive(Clone, Debug)]
pub struct UnitDisk {
    pub uv: Vec<(f64, f64)>,
    /// Counter-clockwise in (u, v).
    pub triangles: Vec<[u32; 3]>,
    /// Disk vertex of seam vertex i (the outer ring).
    pub boundary: Vec<u32>,
}

/// The straight segment R_init joining the seam points nearest the two caps.
#[derive(Clone, Copy, Debug)]
pub struct InitialChord {
    pub vsd_end_mm: Vec3,
    pub aortic_end_mm: Vec3,
    /// Seam indices of the two ends.
    pub vsd_index: usize,
    pub aortic_index: usize,
}

impl InitialChord {
    /// Closest point of the segment to `p`.
    pub fn closest_point(&self, p: Vec3) -> Vec3 {
        closest_point_on_segment(&p, &self.vsd_end_mm, &self.aortic_end_mm).0
    }
}

/// The initial patch: disk parameterization and the 3D position of each disk vertex.
#[derive(Clone, Debug)]
pub struct InitialPatch {
    pub disk: UnitDisk,
    pub points_mm: Vec<Vec3>,
    pub chord: InitialChord,
}

/// Index of the seam point nearest to any of `targets` (e.g. a cap's vertices).
pub fn nearest_seam_index(seam_mm: &[Vec3], targets: &[Vec3]) -> usize {
    let mut best = (f64::INFINITY, 0);
    for (i, s) in seam_mm.iter().enumerate() {
        for t in targets {
            let d = (s - t).norm_squared();
            if d < best.0 {
                best = (d, i);
            }
        }
    }
    best.1
}

/// Disk angle of each seam vertex: arc length from the VSD split point (angle pi)
/// to the aortic split point (angle 2 pi = 0) along the loop's order, then on back
/// to the VSD split point (angle pi). Angles increase along the seam.
pub fn seam_angles(seam_mm: &[Vec3], vsd_index: usize, aortic_index: usize) -> Vec<f64> {
    let n = seam_mm.len();
    let mut angles = vec![0.0; n];
    let assign_side = |angles: &mut Vec<f64>, from: usize, to: usize, start_angle: f64| {
        let mut lengths = vec![0.0];
        let mut i = from;
        while i != to {
            let j = (i + 1) % n;
            lengths.push(lengths.last().copied().unwrap_or(0.0) + (seam_mm[j] - seam_mm[i]).norm());
            i = j;
        }
        let total = lengths.last().copied().unwrap_or(1.0).max(1e-300);
        let mut i = from;
        for l in &lengths {
            angles[i] = start_angle + PI * l / total;
            i = (i + 1) % n;
        }
    };
    assign_side(&mut angles, aortic_index, vsd_index, 0.0);
    assign_side(&mut angles, vsd_index, aortic_index, PI);
    angles[aortic_index] = 0.0;
    angles
}

/// Build the structured disk: `rings` rings (the last is the seam with the given
/// angles), inner ring j holding `max(6, round(outer_count * j / rings))` uniform
/// vertices, alternate rings offset by half a step.
pub fn unit_disk(boundary_angles: &[f64], rings: usize, outer_count: usize) -> UnitDisk {
    let n_b = boundary_angles.len();
    let rings = rings.max(2);
    let mut uv = vec![(0.0, 0.0)];
    let mut ring_vertices: Vec<Vec<(f64, u32)>> = vec![vec![(0.0, 0)]];
    for j in 1..rings {
        let r = j as f64 / rings as f64;
        let count = ((outer_count as f64 * r).round() as usize).max(6);
        let offset = if j % 2 == 1 { 0.5 } else { 0.0 };
        let ring = (0..count)
            .map(|k| {
                let a = TAU * (k as f64 + offset) / count as f64;
                uv.push((r * a.cos(), r * a.sin()));
                (a, (uv.len() - 1) as u32)
            })
            .collect();
        ring_vertices.push(ring);
    }
    let mut boundary = Vec::with_capacity(n_b);
    let mut outer: Vec<(f64, u32)> = boundary_angles
        .iter()
        .map(|&a| {
            uv.push((a.cos(), a.sin()));
            boundary.push((uv.len() - 1) as u32);
            (a.rem_euclid(TAU), (uv.len() - 1) as u32)
        })
        .collect();
    outer.sort_by(|a, b| a.0.total_cmp(&b.0));
    ring_vertices.push(outer);
    let mut triangles = Vec::new();
    let first = &ring_vertices[1];
    for k in 0..first.len() {
        triangles.push([0, first[k].1, first[(k + 1) % first.len()].1]);
    }
    for j in 1..rings {
        zip_rings(&ring_vertices[j], &ring_vertices[j + 1], &mut triangles);
    }
    UnitDisk { uv, triangles, boundary }
}

/// Triangulate the annulus between two rings (each sorted by angle in [0, 2 pi)),
/// always advancing on the ring whose next vertex has the smaller angle.
fn zip_rings(inner: &[(f64, u32)], outer: &[(f64, u32)], triangles: &mut Vec<[u32; 3]>) {
    let (ni, no) = (inner.len(), outer.len());
    let start_angle = inner[0].0;
    // Outer start: the vertex nearest in angle to the inner start.
    let k0 = (0..no)
        .min_by(|&a, &b| angle_gap(outer[a].0, start_angle).total_cmp(&angle_gap(outer[b].0, start_angle)))
        .unwrap_or(0);
    let rel = |a: f64| (a - start_angle + PI).rem_euclid(TAU) - PI;
    let inner_angle = |i: usize| inner[i % ni].0 - start_angle + if i >= ni { TAU } else { 0.0 };
    let outer0 = rel(outer[k0].0);
    let outer_angle = |k: usize| outer0 + (outer[(k0 + k) % no].0 - outer[k0].0).rem_euclid(TAU) + if k >= no { TAU } else { 0.0 };
    let (mut i, mut k) = (0, 0);
    while i < ni || k < no {
        let advance_inner = k >= no || (i < ni && inner_angle(i + 1) < outer_angle(k + 1));
        let (a, b) = (inner[i % ni].1, outer[(k0 + k) % no].1);
        if advance_inner {
            triangles.push([a, b, inner[(i + 1) % ni].1]);
            i += 1;
        } else {
            triangles.push([a, b, outer[(k0 + k + 1) % no].1]);
            k += 1;
        }
    }
}

fn angle_gap(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(TAU);
    d.min(TAU - d)
}

/// Build the initial patch on the seam (paper step 3).
pub fn initial_patch(
    seam_mm: &[Vec3],
    vsd_index: usize,
    aortic_index: usize,
    interior_control_points: usize,
    target_edge_mm: f64,
) -> Result<InitialPatch, DesignError> {
    if vsd_index == aortic_index {
        return Err(DesignError::Seam("the seam points nearest the VSD and aortic caps coincide".into()));
    }
    let chord = InitialChord {
        vsd_end_mm: seam_mm[vsd_index],
        aortic_end_mm: seam_mm[aortic_index],
        vsd_index,
        aortic_index,
    };
    let angles = seam_angles(seam_mm, vsd_index, aortic_index);
    // Ring spacing ~ the target edge: radially over the patch's half-width, and
    // around the outer ring over the seam's length (whatever its vertex count).
    let half_width_mm = 0.5 * (chord.aortic_end_mm - chord.vsd_end_mm).norm();
    let seam_length_mm: f64 = (0..seam_mm.len()).map(|i| (seam_mm[(i + 1) % seam_mm.len()] - seam_mm[i]).norm()).sum();
    let rings = ((half_width_mm / target_edge_mm).ceil() as usize).max(2);
    let outer_count = ((seam_length_mm / target_edge_mm).round() as usize).max(6);
    let disk = unit_disk(&angles, rings, outer_count);
    let n_ctrl = interior_control_points.max(1);
    let fractions: Vec<f64> = (1..=n_ctrl).map(|k| k as f64 / (n_ctrl + 1) as f64).collect();
    let params: Vec<(f64, f64)> = fractions.iter().map(|f| (-1.0 + 2.0 * f, 0.0)).collect();
    let on_chord: Vec<Vec3> = fractions.iter().map(|&f| chord.vsd_end_mm + f * (chord.aortic_end_mm - chord.vsd_end_mm)).collect();
    let points_mm = DiskMap::new(&disk, &params, 0.0)
        .and_then(|map| map.points(seam_mm, &on_chord))
        .map_err(|m| DesignError::numerical("initial patch TPS", m))?;
    Ok(InitialPatch { disk, points_mm, chord })
}

/// Thin-plate-spline map of the disk with the seam on its boundary and interior
/// landmarks at fixed disk parameters, factored once so new landmark positions (the
/// design's correction rounds) cost only a solve. Boundary vertices are set to the
/// seam exactly, so the patch and the wall share them bit for bit.
pub struct DiskMap<'a> {
    disk: &'a UnitDisk,
    solver: TpsSolver,
}

impl<'a> DiskMap<'a> {
    pub fn new(disk: &'a UnitDisk, interior_params: &[(f64, f64)], regularization: f64) -> Result<Self, String> {
        let mut params: Vec<(f64, f64)> = disk.boundary.iter().map(|&b| disk.uv[b as usize]).collect();
        params.extend_from_slice(interior_params);
        Ok(DiskMap { disk, solver: TpsSolver::new(&params, regularization)? })
    }

    /// Positions of every disk vertex for the seam and the interior landmark positions.
    pub fn points(&self, seam_mm: &[Vec3], interior_mm: &[Vec3]) -> Result<Vec<Vec3>, String> {
        let values: Vec<Vec3> = seam_mm.iter().chain(interior_mm).copied().collect();
        let mut points = self.solver.fit(&values)?.eval_many(&self.disk.uv);
        for (&b, &p) in self.disk.boundary.iter().zip(seam_mm) {
            points[b as usize] = p;
        }
        Ok(points)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::mesh::{manifold_report, TriMesh};

    fn circle_seam(n: usize, r: f64) -> Vec<Vec3> {
        (0..n).map(|i| {
            let a = TAU * i as f64 / n as f64;
            Vec3::new(r * a.cos(), r * a.sin(), 0.3 * (2.0 * a).cos())
        }).collect()
    }

    #[test]
    fn disk_is_a_manifold_disk_with_ccw_triangles() {
        let angles: Vec<f64> = (0..37).map(|i| TAU * (i as f64 + 0.3 * (i as f64).sin()) / 37.0).collect();
        let disk = unit_disk(&angles, 6, 37);
        let mesh = TriMesh::new(
            disk.uv.iter().map(|&(u, v)| Vec3::new(u, v, 0.0)).collect(),
            disk.triangles.clone(),
            vec![10; disk.triangles.len()],
        );
        let rep = manifold_report(&mesh);
        assert_eq!(rep.non_manifold_edges, 0);
        assert_eq!(rep.inconsistently_wound_edges, 0);
        assert_eq!(rep.boundary_edges, 37);
        for t in 0..mesh.triangles.len() {
            assert!(mesh.triangle_normal2(t).z > 0.0, "triangle {t} is not counter-clockwise");
        }
        // The disk covers the inscribed polygon of its boundary.
        let poly_area: f64 = (0..37).map(|i| {
            let (a, b) = (disk.uv[disk.boundary[i] as usize], disk.uv[disk.boundary[(i + 1) % 37] as usize]);
            0.5 * (a.0 * b.1 - a.1 * b.0)
        }).sum();
        assert!((mesh.area_mm2() - poly_area).abs() < 1e-9);
        let loops = mesh.boundary_loops().unwrap();
        assert_eq!(loops.len(), 1);
    }

    #[test]
    fn seam_angles_put_split_points_on_the_diameter() {
        let seam = circle_seam(40, 5.0);
        let a = seam_angles(&seam, 5, 25);
        assert!((a[5] - PI).abs() < 1e-12 && a[25] == 0.0);
        for i in 0..40 {
            let (x, y) = (i, (i + 1) % 40);
            if x != 25 && y != 25 {
                assert!(a[y].rem_euclid(TAU) > a[x].rem_euclid(TAU) || y == 25, "angles must increase at {x}");
            }
        }
    }

    #[test]
    fn initial_patch_restores_the_seam_and_spans_it() {
        let seam = circle_seam(60, 5.0);
        let patch = initial_patch(&seam, 0, 30, 9, 0.8).unwrap();
        for (i, &v) in patch.disk.boundary.iter().enumerate() {
            assert_eq!(patch.points_mm[v as usize], seam[i]);
        }
        // The centre of the disk maps near the chord's midpoint (the TPS passes
        // through the interior control points on R_init).
        let mid = 0.5 * (seam[0] + seam[30]);
        assert!((patch.points_mm[0] - mid).norm() < 0.05, "{}", (patch.points_mm[0] - mid).norm());
    }

    #[test]
    fn interior_control_point_count_barely_changes_the_patch() {
        // Paper's robustness check: 3 to 29 interior control points change the
        // initial surface by < 0.05 mm.
        let seam = circle_seam(70, 6.0);
        let reference = initial_patch(&seam, 3, 38, 9, 0.85).unwrap();
        for n in [3, 5, 15, 29] {
            let other = initial_patch(&seam, 3, 38, n, 0.85).unwrap();
            let max_d = reference.points_mm.iter().zip(&other.points_mm).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
            assert!(max_d < 0.05, "{n} control points moved the patch by {max_d} mm");
        }
    }
}
