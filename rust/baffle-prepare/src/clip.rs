//! Step 4: clip along both loops and keep the component bounded by both [paper
//! 2.2.2]. The surface is split exactly along each loop's best-fit plane (points
//! within `snap_mm` of the plane are moved onto it, crossing edges get a point on
//! it), so each opening's rim is planar and its cap can be flat. Of the plane's
//! section curves, the one nearest the regularized loop is the cut; the kept
//! region is the part of the surface that touches both cuts.

use baffle_core::geometry::mesh::{edge_key, EdgeMap};
use baffle_core::geometry::numerics::pca::Plane;
use baffle_core::{TriMesh, Vec3};
use std::collections::HashMap;

/// A cut: the plane it lies in and the loop it should follow.
pub struct Cut<'a> {
    pub name: &'a str,
    pub plane: Plane,
    pub loop_mm: &'a [Vec3],
}

/// The kept region: an open surface whose two boundary loops lie in the cuts' planes.
#[derive(Clone, Debug)]
pub struct Clipped {
    pub mesh: TriMesh,
    /// For each cut, its boundary loop in `mesh` (point indices, kept triangles' winding).
    pub rims: Vec<Vec<u32>>,
}

/// A mesh being split by planes; bit `k` of `on_plane[p]` says point `p` lies on plane `k`.
struct SplitMesh {
    mesh: TriMesh,
    on_plane: Vec<u8>,
}

pub fn clip_between(mesh: &TriMesh, cuts: &[Cut], snap_mm: f64) -> Result<Clipped, String> {
    let mut split = SplitMesh { mesh: mesh.clone(), on_plane: vec![0; mesh.points.len()] };
    for (k, cut) in cuts.iter().enumerate() {
        split_by_plane(&mut split, &cut.plane, 1 << k, snap_mm);
    }
    let edges = split.mesh.edge_triangles();
    let mut cut_edges = Vec::new();
    for (k, cut) in cuts.iter().enumerate() {
        let sides = triangle_sides(&split, &cut.plane, 1 << k);
        let curves = section_curves(&split, &edges, &sides, 1 << k);
        let chosen = nearest_curve(&split.mesh, &curves, cut.loop_mm)
            .ok_or_else(|| format!("the {} plane does not cut the surface along its loop", cut.name))?;
        cut_edges.push(chosen);
    }
    keep_between(&split.mesh, &edges, &cut_edges, cuts)
}

fn split_by_plane(split: &mut SplitMesh, plane: &Plane, bit: u8, snap_mm: f64) {
    let mesh = &mut split.mesh;
    let mut s: Vec<f64> = mesh.points.iter().map(|p| plane.signed_distance_mm(p)).collect();
    for (p, d) in mesh.points.iter_mut().zip(s.iter_mut()) {
        if d.abs() < snap_mm {
            *p -= *d * plane.normal;
            *d = 0.0;
        }
    }
    for (flag, d) in split.on_plane.iter_mut().zip(&s) {
        if *d == 0.0 {
            *flag |= bit;
        }
    }
    let mut crossing: HashMap<(u32, u32), u32> = HashMap::new();
    let mut point_on = |a: u32, b: u32, mesh: &mut TriMesh, on_plane: &mut Vec<u8>| -> u32 {
        *crossing.entry(edge_key(a, b)).or_insert_with(|| {
            let (sa, sb) = (s[a as usize], s[b as usize]);
            let (pa, pb) = (mesh.points[a as usize], mesh.points[b as usize]);
            mesh.points.push(pa + (sa / (sa - sb)) * (pb - pa));
            on_plane.push(bit | (on_plane[a as usize] & on_plane[b as usize]));
            (mesh.points.len() - 1) as u32
        })
    };
    let old_triangles = std::mem::take(&mut mesh.triangles);
    let old_labels = std::mem::take(&mut mesh.face_ids);
    for (tri, label) in old_triangles.into_iter().zip(old_labels) {
        let sign = tri.map(|v| s[v as usize].total_cmp(&0.0) as i8);
        if !(sign.contains(&1) && sign.contains(&-1)) {
            mesh.triangles.push(tri);
            mesh.face_ids.push(label);
            continue;
        }
        let pieces: Vec<[u32; 3]> = if let Some(z) = sign.iter().position(|&g| g == 0) {
            // One corner on the plane: split the opposite edge.
            let [v0, v1, v2] = [tri[z], tri[(z + 1) % 3], tri[(z + 2) % 3]];
            let x = point_on(v1, v2, mesh, &mut split.on_plane);
            vec![[v0, v1, x], [v0, x, v2]]
        } else {
            // One corner alone on its side: cut off its corner.
            let lone = (0..3).find(|&k| sign[k] != sign[(k + 1) % 3] && sign[k] != sign[(k + 2) % 3]).unwrap_or(0);
            let [v0, v1, v2] = [tri[lone], tri[(lone + 1) % 3], tri[(lone + 2) % 3]];
            let x1 = point_on(v0, v1, mesh, &mut split.on_plane);
            let x2 = point_on(v0, v2, mesh, &mut split.on_plane);
            vec![[v0, x1, x2], [x1, v1, v2], [x1, v2, x2]]
        };
        for piece in pieces {
            mesh.triangles.push(piece);
            mesh.face_ids.push(label);
        }
    }
}

/// Side (+1 / -1) of each triangle with respect to the plane, from its corner
/// farthest from it (every triangle is on one side once split).
fn triangle_sides(split: &SplitMesh, plane: &Plane, bit: u8) -> Vec<i8> {
    split
        .mesh
        .triangles
        .iter()
        .map(|tri| {
            let d = tri
                .iter()
                .filter(|&&v| split.on_plane[v as usize] & bit == 0)
                .map(|&v| plane.signed_distance_mm(&split.mesh.points[v as usize]))
                .max_by(|a, b| a.abs().total_cmp(&b.abs()))
                .unwrap_or(0.0);
            if d >= 0.0 {
                1
            } else {
                -1
            }
        })
        .collect()
}

/// The plane's section curves: connected sets of edges on the plane between
/// triangles on opposite sides.
fn section_curves(split: &SplitMesh, edges: &EdgeMap<Vec<u32>>, sides: &[i8], bit: u8) -> Vec<Vec<(u32, u32)>> {
    let on = |v: u32| split.on_plane[v as usize] & bit != 0;
    let curve: Vec<(u32, u32)> = edges
        .iter()
        .filter(|(&(a, b), tris)| on(a) && on(b) && tris.len() == 2 && sides[tris[0] as usize] != sides[tris[1] as usize])
        .map(|(&e, _)| e)
        .collect();
    let mut by_point: HashMap<u32, Vec<usize>> = HashMap::new();
    for (i, &(a, b)) in curve.iter().enumerate() {
        by_point.entry(a).or_default().push(i);
        by_point.entry(b).or_default().push(i);
    }
    let mut seen = vec![false; curve.len()];
    let mut components = Vec::new();
    for start in 0..curve.len() {
        if seen[start] {
            continue;
        }
        seen[start] = true;
        let (mut stack, mut component) = (vec![start], Vec::new());
        while let Some(e) = stack.pop() {
            component.push(curve[e]);
            for p in [curve[e].0, curve[e].1] {
                for &f in &by_point[&p] {
                    if !seen[f] {
                        seen[f] = true;
                        stack.push(f);
                    }
                }
            }
        }
        components.push(component);
    }
    components
}

/// The closed curve whose points are nearest the loop on average.
fn nearest_curve(mesh: &TriMesh, curves: &[Vec<(u32, u32)>], loop_mm: &[Vec3]) -> Option<Vec<(u32, u32)>> {
    let is_closed = |c: &Vec<(u32, u32)>| {
        let mut degree: HashMap<u32, u32> = HashMap::new();
        c.iter().for_each(|&(a, b)| [a, b].iter().for_each(|&p| *degree.entry(p).or_default() += 1));
        degree.values().all(|&d| d == 2)
    };
    let mean_distance = |c: &Vec<(u32, u32)>| {
        let pts: Vec<Vec3> = c.iter().map(|&(a, _)| mesh.points[a as usize]).collect();
        loop_mm.iter().map(|q| pts.iter().map(|p| (p - q).norm()).fold(f64::INFINITY, f64::min)).sum::<f64>() / loop_mm.len() as f64
    };
    curves.iter().filter(|c| is_closed(c)).map(|c| (mean_distance(c), c)).min_by(|a, b| a.0.total_cmp(&b.0)).map(|(_, c)| c.clone())
}

/// Triangle components across every edge except the cuts; keep the one touching
/// all cuts.
fn keep_between(mesh: &TriMesh, edges: &EdgeMap<Vec<u32>>, cut_edges: &[Vec<(u32, u32)>], cuts: &[Cut]) -> Result<Clipped, String> {
    let blocked: std::collections::HashSet<(u32, u32)> = cut_edges.iter().flatten().copied().collect();
    let component = components_across(mesh, edges, &blocked);
    let components_at = |curve: &Vec<(u32, u32)>| -> std::collections::HashSet<usize> {
        curve.iter().flat_map(|e| edges[e].iter().map(|&t| component[t as usize])).collect()
    };
    let mut common = components_at(&cut_edges[0]);
    for curve in &cut_edges[1..] {
        let next = components_at(curve);
        common.retain(|c| next.contains(c));
    }
    let names: Vec<&str> = cuts.iter().map(|c| c.name).collect();
    let touching = format!("do the {} cuts touch each other on the surface?", names.join(" and "));
    let kept = match common.len() {
        1 => *common.iter().next().unwrap_or(&0),
        0 => return Err(format!("no part of the surface lies between the {} cuts", names.join(" and "))),
        n => return Err(format!("{n} parts of the surface lie between the {} cuts, expected 1 ({touching})", names.join(" and "))),
    };
    let keep: Vec<bool> = component.iter().map(|&c| c == kept).collect();
    let (sub, old_of_new) = mesh.submesh(&keep);
    let loops = sub.boundary_loops()?;
    if loops.len() != cut_edges.len() {
        return Err(format!("the kept surface has {} openings, expected {} ({touching})", loops.len(), cut_edges.len()));
    }
    let rims = cut_edges
        .iter()
        .zip(cuts)
        .map(|(curve, cut)| {
            let a = curve[0].0;
            loops
                .iter()
                .find(|l| l.iter().any(|&v| old_of_new[v as usize] == a))
                .cloned()
                .ok_or_else(|| format!("the {} cut is not an opening of the kept surface ({touching})", cut.name))
        })
        .collect::<Result<Vec<_>, String>>()?;
    Ok(Clipped { mesh: sub, rims })
}

fn components_across(mesh: &TriMesh, edges: &EdgeMap<Vec<u32>>, blocked: &std::collections::HashSet<(u32, u32)>) -> Vec<usize> {
    let mut component = vec![usize::MAX; mesh.triangles.len()];
    let mut count = 0;
    for seed in 0..mesh.triangles.len() {
        if component[seed] != usize::MAX {
            continue;
        }
        component[seed] = count;
        let mut stack = vec![seed];
        while let Some(t) = stack.pop() {
            let tri = mesh.triangles[t];
            for k in 0..3 {
                let e = edge_key(tri[k], tri[(k + 1) % 3]);
                if blocked.contains(&e) {
                    continue;
                }
                for &n in &edges[&e] {
                    if component[n as usize] == usize::MAX {
                        component[n as usize] = count;
                        stack.push(n as usize);
                    }
                }
            }
        }
        count += 1;
    }
    component
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::capped_tube;
    use baffle_core::geometry::numerics::pca::best_fit_plane;

    /// A loop on the tube in the plane z = z0 + slope * y.
    fn tilted_ring(z0: f64, slope: f64) -> Vec<Vec3> {
        (0..16)
            .map(|k| {
                let a = k as f64 * std::f64::consts::PI / 8.0;
                Vec3::new(2.0 * a.cos(), 2.0 * a.sin(), z0 + slope * 2.0 * a.sin())
            })
            .collect()
    }

    fn ring(z: f64) -> Vec<Vec3> {
        tilted_ring(z, 0.0)
    }

    /// A tube along z clipped by the planes of two loops on it.
    fn clip_tube_loops(loops: [Vec<Vec3>; 2], names: [&str; 2]) -> Result<Clipped, String> {
        let tube = capped_tube(Vec3::zeros(), Vec3::new(0.0, 0.0, 10.0), 2.0, 10, 32);
        let cuts: Vec<Cut> = loops.iter().zip(names).map(|(l, name)| Cut { name, plane: best_fit_plane(l), loop_mm: l }).collect();
        clip_between(&tube, &cuts, 1e-6)
    }

    /// A tube along z clipped by planes at heights `z`.
    fn clip_tube(z: [f64; 2], names: [&str; 2]) -> Result<Clipped, String> {
        clip_tube_loops(z.map(ring), names)
    }

    #[test]
    fn cuts_that_cross_on_the_surface_are_an_error() {
        // z = 3 + 0.6 y and z = 5 - 0.6 y meet at y = 1.67, on the tube (radius 2).
        let err = clip_tube_loops([tilted_ring(3.0, 0.6), tilted_ring(5.0, -0.6)], ["VSD", "aortic"]).unwrap_err();
        assert!(err.contains("touch"), "{err}");
    }

    #[test]
    fn a_tube_clipped_at_two_planes_keeps_the_middle() {
        let clipped = clip_tube([2.3, 7.1], ["low", "high"]).unwrap();
        assert_eq!(clipped.rims.len(), 2);
        for (rim, z) in clipped.rims.iter().zip([2.3, 7.1]) {
            assert!(rim.iter().all(|&v| (clipped.mesh.points[v as usize].z - z).abs() < 1e-9));
        }
        let lateral = 2.0 * 32.0 * (std::f64::consts::PI / 32.0).sin() * 2.0 * 4.8;
        assert!((clipped.mesh.area_mm2() - lateral).abs() < 1e-6, "{}", clipped.mesh.area_mm2());
    }

    #[test]
    fn a_plane_missing_the_surface_is_named() {
        let err = clip_tube([2.3, 20.0], ["VSD", "aortic"]).unwrap_err();
        assert!(err.contains("aortic plane"), "{err}");
    }
}
