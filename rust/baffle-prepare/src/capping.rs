//! Step 5: close each opening with a planar cap with its own label [paper 2.2.2].
//! The clipped wall is first remeshed isotropically (the core remesher, rims
//! resampled along their planar polylines), then each cap is built from rings
//! shrunk toward its centroid, so cap and wall triangles are alike.

use crate::clip::Clipped;
use crate::planar_cap::refine_planar_cap;
use crate::polygon2d::orient;
use baffle_core::geometry::numerics::pca::Plane;
use baffle_core::geometry::remesh::{remesh_isotropic, RemeshOptions, SizeGrading};
use baffle_core::{TriMesh, Vec3};

/// Ear-clipping triangulation of a simple planar polygon (indices into `uv`),
/// wound like the polygon.
pub fn ear_clip(polygon: &[u32], uv: &[(f64, f64)]) -> Result<Vec<[u32; 3]>, String> {
    let p = |v: u32| uv[v as usize];
    let cross = |a: u32, b: u32, c: u32| orient(p(a), p(b), p(c));
    let area2: f64 = (0..polygon.len()).map(|i| {
        let (a, b) = (p(polygon[i]), p(polygon[(i + 1) % polygon.len()]));
        a.0 * b.1 - b.0 * a.1
    }).sum();
    if area2 == 0.0 || !area2.is_finite() {
        return Err(format!("the cap outline of {} points encloses no area", polygon.len()));
    }
    let sense = area2.signum();
    let mut remaining = polygon.to_vec();
    let mut triangles = Vec::with_capacity(polygon.len().saturating_sub(2));
    while remaining.len() > 3 {
        let n = remaining.len();
        let is_ear = |i: usize| {
            let (a, b, c) = (remaining[(i + n - 1) % n], remaining[i], remaining[(i + 1) % n]);
            if sense * cross(a, b, c) <= 0.0 {
                return false;
            }
            remaining.iter().all(|&q| {
                q == a || q == b || q == c || !(sense * cross(a, b, q) >= 0.0 && sense * cross(b, c, q) >= 0.0 && sense * cross(c, a, q) >= 0.0)
            })
        };
        let ear = (0..n).find(|&i| is_ear(i)).ok_or_else(|| format!("the cap outline of {n} points is not a simple polygon"))?;
        triangles.push([remaining[(ear + n - 1) % n], remaining[ear], remaining[(ear + 1) % n]]);
        remaining.remove(ear);
    }
    if remaining.len() == 3 {
        triangles.push([remaining[0], remaining[1], remaining[2]]);
    }
    Ok(triangles)
}

/// Remesh the clipped wall isotropically at `edge_mm` (or graded from there): its rims
/// are resampled along their original (planar) polylines, so they stay in their planes.
pub fn remesh_wall(clipped: &Clipped, planes: &[Plane], edge_mm: f64, grading: Option<SizeGrading>) -> Result<Clipped, String> {
    let options = RemeshOptions { target_edge_mm: edge_mm, split_boundary: true, grading, ..RemeshOptions::default() };
    let mesh = remesh_isotropic(&clipped.mesh, &options)?;
    let loops = mesh.boundary_loops()?;
    if loops.len() != planes.len() {
        return Err(format!("the remeshed wall has {} openings, expected {}", loops.len(), planes.len()));
    }
    let offset = |lp: &Vec<u32>, plane: &Plane| lp.iter().map(|&v| plane.signed_distance_mm(&mesh.points[v as usize]).abs()).sum::<f64>() / lp.len() as f64;
    let rims = planes
        .iter()
        .map(|plane| loops.iter().min_by(|a, b| offset(a, plane).total_cmp(&offset(b, plane))).cloned().unwrap_or_default())
        .collect();
    Ok(Clipped { mesh, rims })
}

/// Close the clipped surface: every triangle gets `wall_label`, and each rim a flat
/// cap labelled `cap_labels[k]`, wound to match the wall (outward overall).
pub fn close_with_caps(clipped: &Clipped, planes: &[Plane], wall_label: i32, cap_labels: &[i32]) -> Result<TriMesh, String> {
    let mut mesh = clipped.mesh.clone();
    mesh.face_ids.iter_mut().for_each(|l| *l = wall_label);
    for ((rim, plane), &label) in clipped.rims.iter().zip(planes).zip(cap_labels) {
        // The wall runs a->b along its rim; the cap must run b->a.
        let reversed: Vec<u32> = rim.iter().rev().copied().collect();
        let triangles = ring_cap(&mut mesh.points, &reversed, plane)?;
        mesh.face_ids.extend(std::iter::repeat_n(label, triangles.len()));
        mesh.triangles.extend(triangles);
    }
    Ok(mesh)
}

/// A flat cap inside `outline` (wound as the cap should be) made of rings shrunk
/// toward the centroid about one rim edge apart, zipped together: near-isotropic
/// triangles. Outlines that are not star-shaped about their centroid are ear-clipped
/// and refined to the same edge (`planar_cap`).
fn ring_cap(points: &mut Vec<Vec3>, outline: &[u32], plane: &Plane) -> Result<Vec<[u32; 3]>, String> {
    let rim: Vec<Vec3> = outline.iter().map(|&v| points[v as usize]).collect();
    let center = rim.iter().sum::<Vec3>() / rim.len() as f64;
    let uv = |p: &Vec3| plane.project_2d(p);
    let c2 = uv(&center);
    let turn = |a: &Vec3, b: &Vec3| {
        let (pa, pb) = (uv(a), uv(b));
        (pa.0 - c2.0) * (pb.1 - c2.1) - (pa.1 - c2.1) * (pb.0 - c2.0)
    };
    let turns: Vec<f64> = (0..rim.len()).map(|i| turn(&rim[i], &rim[(i + 1) % rim.len()])).collect();
    let sense = turns.iter().sum::<f64>().signum();
    let perimeter: f64 = (0..rim.len()).map(|i| (rim[(i + 1) % rim.len()] - rim[i]).norm()).sum();
    let edge = perimeter / rim.len() as f64;
    if turns.iter().any(|t| t * sense <= 0.0) {
        let local_uv: Vec<(f64, f64)> = rim.iter().map(uv).collect();
        let local: Vec<u32> = (0..rim.len() as u32).collect();
        let fan: Vec<[usize; 3]> = ear_clip(&local, &local_uv)?.iter().map(|t| t.map(|v| v as usize)).collect();
        return Ok(refine_planar_cap(points, outline, &fan, plane, edge));
    }
    let mean_radius = rim.iter().map(|p| (p - center).norm()).sum::<f64>() / rim.len() as f64;
    let rings = ((mean_radius / edge).round() as usize).max(1);
    let mut outer: Vec<u32> = outline.to_vec();
    let mut triangles = Vec::new();
    for k in 1..rings {
        let s = 1.0 - k as f64 / rings as f64;
        let count = ((s * perimeter / edge).round() as usize).max(3);
        let inner: Vec<u32> = resample_closed(&rim, count)
            .into_iter()
            .map(|p| {
                points.push(center + s * (p - center));
                (points.len() - 1) as u32
            })
            .collect();
        zip_rings(points, &outer, &inner, &mut triangles);
        outer = inner;
    }
    points.push(center);
    let apex = (points.len() - 1) as u32;
    triangles.extend((0..outer.len()).map(|i| [outer[i], outer[(i + 1) % outer.len()], apex]));
    Ok(triangles)
}

/// `count` points evenly spaced in arc length along the closed polyline.
fn resample_closed(polyline: &[Vec3], count: usize) -> Vec<Vec3> {
    let n = polyline.len();
    let lengths: Vec<f64> = (0..n).map(|i| (polyline[(i + 1) % n] - polyline[i]).norm()).collect();
    let total: f64 = lengths.iter().sum();
    let (mut seg, mut seg_start) = (0, 0.0);
    (0..count)
        .map(|k| {
            let s = total * k as f64 / count as f64;
            while seg + 1 < n && seg_start + lengths[seg] < s {
                seg_start += lengths[seg];
                seg += 1;
            }
            let t = if lengths[seg] > 0.0 { ((s - seg_start) / lengths[seg]).clamp(0.0, 1.0) } else { 0.0 };
            polyline[seg] + t * (polyline[(seg + 1) % n] - polyline[seg])
        })
        .collect()
}

/// Triangulate the band between two closed rings running the same way (outer
/// first in each triangle's winding), always advancing along the shorter diagonal.
pub(crate) fn zip_rings(points: &[Vec3], outer: &[u32], inner: &[u32], out: &mut Vec<[u32; 3]>) {
    let p = |v: u32| points[v as usize];
    let (n, m) = (outer.len(), inner.len());
    let start = (0..m).min_by(|&a, &b| (p(inner[a]) - p(outer[0])).norm().total_cmp(&(p(inner[b]) - p(outer[0])).norm())).unwrap_or(0);
    let inner_at = |j: usize| inner[(start + j) % m];
    let (mut i, mut j) = (0, 0);
    while i < n || j < m {
        let advance_outer = j == m
            || (i < n && (p(outer[(i + 1) % n]) - p(inner_at(j))).norm() <= (p(outer[i % n]) - p(inner_at(j + 1))).norm());
        if advance_outer {
            out.push([outer[i % n], outer[(i + 1) % n], inner_at(j)]);
            i += 1;
        } else {
            out.push([outer[i % n], inner_at(j + 1), inner_at(j)]);
            j += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_concave_polygon_is_triangulated_with_its_winding() {
        // An L shape, counter-clockwise.
        let uv = vec![(0.0, 0.0), (2.0, 0.0), (2.0, 1.0), (1.0, 1.0), (1.0, 2.0), (0.0, 2.0)];
        let polygon: Vec<u32> = (0..6).collect();
        let tris = ear_clip(&polygon, &uv).unwrap();
        assert_eq!(tris.len(), 4);
        let area: f64 = tris
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| uv[v as usize]);
                0.5 * ((b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0))
            })
            .inspect(|&a| assert!(a > 0.0))
            .sum();
        assert!((area - 3.0).abs() < 1e-12);
    }

    #[test]
    fn an_outline_without_area_is_an_error() {
        let uv = vec![(0.0, 0.0), (1.0, 1.0), (1.0, 0.0), (0.0, 1.0)];
        assert!(ear_clip(&[0, 1, 2, 3], &uv).is_err());
    }
}
