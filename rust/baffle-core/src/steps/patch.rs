//! Step 3, the initial patch [paper 2.3.3].
//!
//! The seam is split at its points nearest the VSD and aortic caps (of near ties, the
//! point farthest behind the cap along the tunnel's axis, `seam_split_mm`); each side is
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

/// Seam points within this distance (mm) of the least distance to a cap are as near to
/// it as the nearest one: the suture points are clicks on a segmentation (p1-p3's have
/// 0.4 mm triangles), so a seam that follows a cap's rim (p3's, 1.7-2.2 mm from it over
/// 20 mm) is equally near along that whole stretch.
pub const SPLIT_TIE_MM: f64 = 0.5;

/// Where the seam is split at a cap [paper 2.3.3], as an arc length along the seam loop
/// (mm from seam vertex 0): of the seam points nearest to any of `cap` (a cap's
/// vertices) within [`SPLIT_TIE_MM`], the one farthest along `axis` (the tunnel's
/// direction out through this cap, from the other cap's centroid), refined between its
/// neighbours by the parabola through their positions along `axis`. Where the seam runs
/// along the rim, the plain nearest vertex is decided by tenths of a millimetre and
/// jumps along the rim with the triangulation or a small drag (p3: 9 mm, its baffle
/// 6.5 %); the farthest point behind the cap does not, and, being between vertices, does
/// not hop with a vertex the seam gains or loses either.
pub fn seam_split_mm(seam_mm: &[Vec3], cap: &[Vec3], axis: Vec3) -> f64 {
    let n = seam_mm.len();
    let distance: Vec<f64> = seam_mm.iter().map(|s| cap.iter().map(|t| (s - t).norm()).fold(f64::INFINITY, f64::min)).collect();
    let least = distance.iter().copied().fold(f64::INFINITY, f64::min);
    let along = |i: usize| seam_mm[i].dot(&axis);
    let Some(i) = (0..n).filter(|&i| distance[i] <= least + SPLIT_TIE_MM).max_by(|&a, &b| along(a).total_cmp(&along(b))) else {
        return 0.0;
    };
    let (before, after) = ((i + n - 1) % n, (i + 1) % n);
    let (h0, h1) = ((seam_mm[i] - seam_mm[before]).norm(), (seam_mm[after] - seam_mm[i]).norm());
    let (d0, d1) = (along(before) - along(i), along(after) - along(i));
    // f(x) = a x^2 + b x through (-h0, d0), (0, 0), (h1, d1): its peak, where the vertex is
    // a peak of the seam's course along the axis (not only the last near one).
    let a = (d1 * h0 + d0 * h1) / (h0 * h1 * (h0 + h1));
    let peak = d0 <= 0.0 && d1 <= 0.0 && a < 0.0;
    let shift = if peak { (-(d1 - a * h1 * h1) / h1 / (2.0 * a)).clamp(-h0, h1) } else { 0.0 };
    let (arc, total) = arc_positions_mm(seam_mm);
    (arc[i] + shift).rem_euclid(total)
}

/// Arc length of each seam vertex from vertex 0 (mm), and the loop's length.
fn arc_positions_mm(seam_mm: &[Vec3]) -> (Vec<f64>, f64) {
    let n = seam_mm.len();
    let mut arc = Vec::with_capacity(n);
    let mut total = 0.0;
    for i in 0..n {
        arc.push(total);
        total += (seam_mm[(i + 1) % n] - seam_mm[i]).norm();
    }
    (arc, total)
}

/// The point of the seam loop at arc length `at_mm` from vertex 0.
pub fn seam_point_at(seam_mm: &[Vec3], at_mm: f64) -> Vec3 {
    let (arc, total) = arc_positions_mm(seam_mm);
    let at = at_mm.rem_euclid(total.max(f64::MIN_POSITIVE));
    let i = arc.partition_point(|&s| s <= at).saturating_sub(1);
    let (a, b) = (seam_mm[i], seam_mm[(i + 1) % seam_mm.len()]);
    let length = (b - a).norm();
    if length > 0.0 { a + (at - arc[i]) / length * (b - a) } else { a }
}

/// Disk angle of each seam vertex: arc length from the aortic split (angle 0) to the VSD
/// split (angle pi) along the loop's order, then on back to the aortic split (2 pi).
/// The splits are arc lengths along the seam (`seam_split_mm`), between vertices or on
/// one. Angles increase along the seam.
pub fn seam_angles(seam_mm: &[Vec3], vsd_at_mm: f64, aortic_at_mm: f64) -> Vec<f64> {
    let (arc, total) = arc_positions_mm(seam_mm);
    let aortic_side = (vsd_at_mm - aortic_at_mm).rem_euclid(total);
    arc.iter()
        .map(|&s| {
            let x = (s - aortic_at_mm).rem_euclid(total);
            if x <= aortic_side {
                PI * x / aortic_side
            } else {
                PI + PI * (x - aortic_side) / (total - aortic_side)
            }
        })
        .collect()
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
    vsd_at_mm: f64,
    aortic_at_mm: f64,
    interior_control_points: usize,
    target_edge_mm: f64,
) -> Result<InitialPatch, DesignError> {
    let chord = InitialChord { vsd_end_mm: seam_point_at(seam_mm, vsd_at_mm), aortic_end_mm: seam_point_at(seam_mm, aortic_at_mm) };
    // Within one mean seam step of each other, one side of the seam has no vertex.
    let (_, total) = arc_positions_mm(seam_mm);
    let apart = (vsd_at_mm - aortic_at_mm).rem_euclid(total);
    if apart.min(total - apart) < total / seam_mm.len().max(1) as f64 {
        return Err(DesignError::Seam("the seam points nearest the VSD and aortic caps coincide".into()));
    }
    let angles = seam_angles(seam_mm, vsd_at_mm, aortic_at_mm);
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

    /// Arc length of seam vertex `i`.
    fn at(seam: &[Vec3], i: usize) -> f64 {
        arc_positions_mm(seam).0[i]
    }

    #[test]
    fn seam_angles_put_split_points_on_the_diameter() {
        let seam = circle_seam(40, 5.0);
        let a = seam_angles(&seam, at(&seam, 5), at(&seam, 25));
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
        let patch = initial_patch(&seam, at(&seam, 0), at(&seam, 30), 9, 0.8).unwrap();
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
        let reference = initial_patch(&seam, at(&seam, 3), at(&seam, 38), 9, 0.85).unwrap();
        for n in [3, 5, 15, 29] {
            let other = initial_patch(&seam, at(&seam, 3), at(&seam, 38), n, 0.85).unwrap();
            let max_d = reference.points_mm.iter().zip(&other.points_mm).map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
            assert!(max_d < 0.05, "{n} control points moved the patch by {max_d} mm");
        }
    }

    /// A seam running along a cap's rim, 2 mm outside it, with a 0.2 mm wobble: every
    /// point of the arc is as near as the nearest within the tie, so the split is the
    /// point behind the cap along the axis, between vertices, wherever the wobble puts
    /// the nearest vertex.
    #[test]
    fn a_seam_along_a_rim_is_split_behind_the_cap_whatever_its_wobble() {
        let cap: Vec<Vec3> = (0..60).map(|k| { let a = TAU * k as f64 / 60.0; Vec3::new(5.0 * a.cos(), 5.0 * a.sin(), 0.0) }).collect();
        let seam = |phase: f64, count: usize| -> Vec<Vec3> {
            (0..count).map(|k| { let a = TAU * (k as f64 + 0.37) / count as f64; let r = 7.0 + 0.1 * (5.0 * a + phase).sin(); Vec3::new(r * a.cos(), r * a.sin(), 0.0) }).collect()
        };
        // The tunnel leaves the cap toward -x: the split is at angle pi, on the far side.
        let axis = Vec3::new(-1.0, 0.0, 0.0);
        for (phase, count) in [(0.0, 90), (1.3, 90), (2.9, 91), (0.7, 75)] {
            let s = seam(phase, count);
            let split = seam_point_at(&s, seam_split_mm(&s, &cap, axis));
            let angle = split.y.atan2(split.x).rem_euclid(TAU);
            // The wobble itself moves the farthest point by up to r'/r = 0.07 rad.
            assert!((angle - PI).abs() < 0.08, "wobble phase {phase}, {count} points: split at {angle:.3} rad, not behind the cap");
        }
        // The plain nearest vertex hops around the rim with the wobble's phase.
        let nearest = |s: &[Vec3]| {
            let d = |p: &Vec3| cap.iter().map(|c| (p - c).norm()).fold(f64::INFINITY, f64::min);
            s.iter().copied().min_by(|a, b| d(a).total_cmp(&d(b))).unwrap()
        };
        let hops: Vec<f64> = [0.0, 1.3, 2.9].iter().map(|&phase| (nearest(&seam(phase, 90)) - nearest(&seam(0.0, 90))).norm()).collect();
        assert!(hops.iter().any(|&h| h > 3.0), "the wobble should move the nearest vertex: {hops:?}");
    }

    /// Where one seam point is clearly nearest, the split is that point (the paper's rule).
    #[test]
    fn a_clearly_nearest_seam_point_is_the_split() {
        let seam = circle_seam(40, 5.0);
        // 0.2 mm from vertex 10, its neighbours 0.8 mm: beyond the tie.
        let cap = vec![Vec3::new(0.0, 5.2, -0.3)];
        // The axis points elsewhere; the nearest point (angle pi/2, vertex 10) still wins.
        let split = seam_point_at(&seam, seam_split_mm(&seam, &cap, Vec3::new(1.0, 0.0, 0.0)));
        assert!((split - seam[10]).norm() < 1e-12, "{split:?} against {:?}", seam[10]);
    }
}
