//! Edge use, winding and enclosed volume, from the triangle list alone.

use crate::check_mesh;
use baffle_core::TriMesh;
use std::collections::HashMap;

/// How often each undirected edge is traversed in each direction:
/// `[from lower to higher point index, from higher to lower]`.
fn directed_edge_uses(mesh: &TriMesh) -> HashMap<(u32, u32), [u32; 2]> {
    let mut uses: HashMap<(u32, u32), [u32; 2]> =
        HashMap::with_capacity(mesh.triangles.len() * 3 / 2);
    for tri in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            if a == b {
                continue; // a collapsed edge of a degenerate triangle joins nothing
            }
            let key = (a.min(b), a.max(b));
            uses.entry(key).or_default()[usize::from(a > b)] += 1;
        }
    }
    uses
}

/// `(boundary edges, non-manifold edges)`: edges used by one triangle, and by
/// more than two. A closed manifold surface has `(0, 0)`.
pub fn edge_usage_counts(mesh: &TriMesh) -> (usize, usize) {
    let uses = directed_edge_uses(mesh);
    let total = |u: &[u32; 2]| u[0] + u[1];
    let boundary = uses.values().filter(|u| total(u) == 1).count();
    let non_manifold = uses.values().filter(|u| total(u) > 2).count();
    (boundary, non_manifold)
}

/// Every edge shared by two triangles is traversed once in each direction, and
/// no edge is shared by more than two (where winding is undefined).
pub fn is_consistently_oriented(mesh: &TriMesh) -> bool {
    directed_edge_uses(mesh)
        .values()
        .all(|u| u[0] + u[1] == 1 || *u == [1, 1])
}

/// Signed enclosed volume (mm^3) by the divergence theorem, positive for an
/// outward-wound closed surface. Tetrahedra are fanned from the points' mean
/// rather than the coordinate origin to keep the terms small.
pub fn signed_volume_mm3(mesh: &TriMesh) -> Result<f64, String> {
    check_mesh(mesh)?;
    if mesh.points.is_empty() {
        return Ok(0.0);
    }
    let apex = mesh.points.iter().sum::<baffle_core::Vec3>() / mesh.points.len() as f64;
    let six_volume: f64 = mesh
        .triangles
        .iter()
        .map(|&[a, b, c]| {
            let [p, q, r] = [a, b, c].map(|i| mesh.points[i as usize] - apex);
            p.dot(&q.cross(&r))
        })
        .sum();
    Ok(six_volume / 6.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_meshes::{closed_cylinder, inscribed_polygon_area_mm2, tetrahedron};

    #[test]
    fn closed_meshes_have_no_open_or_shared_edges() {
        assert_eq!(edge_usage_counts(&tetrahedron()), (0, 0));
        assert_eq!(
            edge_usage_counts(&closed_cylinder(5.0, 10.0, 24, 4)),
            (0, 0)
        );
    }

    #[test]
    fn removed_and_duplicated_triangles_show_up() {
        let mut open = tetrahedron();
        open.triangles.pop();
        assert_eq!(edge_usage_counts(&open), (3, 0));
        let mut fin = tetrahedron();
        fin.points.push(baffle_core::Vec3::new(1.0, 1.0, 1.0));
        fin.triangles.push([0, 1, 4]);
        assert_eq!(edge_usage_counts(&fin), (2, 1));
        assert!(!is_consistently_oriented(&fin));
    }

    #[test]
    fn winding_and_volume() {
        let tet = tetrahedron();
        assert!(is_consistently_oriented(&tet));
        assert!((signed_volume_mm3(&tet).unwrap() - 1.0 / 6.0).abs() < 1e-15);
        let mut flipped = tet.clone();
        flipped.triangles[2].swap(0, 1);
        assert!(!is_consistently_oriented(&flipped));
        let all_flipped = TriMesh {
            triangles: tet.triangles.iter().map(|&[a, b, c]| [a, c, b]).collect(),
            ..tet
        };
        assert!(is_consistently_oriented(&all_flipped));
        assert!((signed_volume_mm3(&all_flipped).unwrap() + 1.0 / 6.0).abs() < 1e-15);

        // A cylinder of inscribed polygons is exactly a prism.
        let cylinder = closed_cylinder(5.0, 10.0, 32, 5);
        let expected = inscribed_polygon_area_mm2(5.0, 32) * 10.0;
        assert!((signed_volume_mm3(&cylinder).unwrap() - expected).abs() < 1e-9 * expected);
    }

    #[test]
    fn volume_rejects_bad_indices() {
        let mut tet = tetrahedron();
        tet.triangles[1][2] = 7;
        let err = signed_volume_mm3(&tet).unwrap_err();
        assert!(
            err.contains("triangle 1") && err.contains("point 7"),
            "{err}"
        );
    }
}
