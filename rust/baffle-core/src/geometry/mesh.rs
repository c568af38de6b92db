//! Triangle surface meshes in millimetres, with a per-triangle `ModelFaceID` label.
//!
//! This is the one mesh type every step of the design passes around. Connectivity
//! queries (edge adjacency, boundary loops, manifold checks) live here too, because
//! every step needs them and none of them owns them.

use nalgebra::Vector3;
use std::collections::HashMap;

/// A point or vector in 3D, millimetres unless a name says otherwise.
pub type Vec3 = Vector3<f64>;

/// The face labels (`ModelFaceID`) of the design's surfaces. Defaults follow the
/// paper's dataset: 2 RV wall, 10 baffle, 11 VSD cap, 16 aortic-annulus cap.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct FaceLabels {
    pub wall: i32,
    pub baffle: i32,
    pub vsd_cap: i32,
    pub aortic_cap: i32,
}

impl Default for FaceLabels {
    fn default() -> Self {
        FaceLabels { wall: 2, baffle: 10, vsd_cap: 11, aortic_cap: 16 }
    }
}

/// A triangle surface: points (mm), triangles as point indices, one label per triangle.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriMesh {
    pub points: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    /// `ModelFaceID` of each triangle (same length as `triangles`).
    pub face_ids: Vec<i32>,
}

/// A hash map keyed by an undirected edge (`edge_key`). SipHash, the default, is
/// built against adversarial keys; point indices are not, and hashing edges was the
/// largest single cost of a design (18%).
pub type EdgeMap<V> = HashMap<(u32, u32), V, std::hash::BuildHasherDefault<EdgeHasher>>;

/// Multiplicative (Fx-style) hashing of the two u32s of an edge key.
#[derive(Default, Clone, Copy)]
pub struct EdgeHasher(u64);

impl std::hash::Hasher for EdgeHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }
    fn write_u32(&mut self, i: u32) {
        self.write_u64(u64::from(i));
    }
    fn write_u64(&mut self, i: u64) {
        self.0 = (self.0.rotate_left(5) ^ i).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
}

/// The area of a set of triangles, their area-weighted centroid (zero without area) and the
/// sum of their normals weighted by twice their areas (by their winding; not normalized).
pub fn area_centroid_normal(triangles: impl IntoIterator<Item = [Vec3; 3]>) -> (f64, Vec3, Vec3) {
    let (mut area, mut centroid, mut normal) = (0.0, Vec3::zeros(), Vec3::zeros());
    for [a, b, c] in triangles {
        let n2 = (b - a).cross(&(c - a));
        let w = 0.5 * n2.norm();
        area += w;
        centroid += w * (a + b + c) / 3.0;
        normal += n2;
    }
    (area, if area > 0.0 { centroid / area } else { centroid }, normal)
}

/// Two unit axes (u, v) across the unit vector `n`, with (u, v, n) right-handed: the
/// in-plane frame of a plane or a tube section normal to `n`.
pub fn axes_across(n: &Vec3) -> (Vec3, Vec3) {
    // Any vector not near `n`; x unless `n` is close to it.
    let helper = if n.x.abs() < 0.9 { Vec3::x() } else { Vec3::y() };
    let u = n.cross(&helper).normalize();
    (u, n.cross(&u))
}

/// An undirected edge key with the smaller index first.
#[inline]
pub fn edge_key(a: u32, b: u32) -> (u32, u32) {
    if a < b {
        (a, b)
    } else {
        (b, a)
    }
}

impl TriMesh {
    pub fn new(points: Vec<Vec3>, triangles: Vec<[u32; 3]>, face_ids: Vec<i32>) -> Self {
        TriMesh { points, triangles, face_ids }
    }

    pub fn triangle_points(&self, t: usize) -> [Vec3; 3] {
        let [a, b, c] = self.triangles[t];
        [self.points[a as usize], self.points[b as usize], self.points[c as usize]]
    }

    /// Centroid of triangle `t`: where an error names a triangle's place.
    pub fn triangle_centroid(&self, t: usize) -> Vec3 {
        let [p, q, r] = self.triangle_points(t);
        (p + q + r) / 3.0
    }

    /// Area-weighted normal (length = 2 x area) of triangle `t`.
    pub fn triangle_normal2(&self, t: usize) -> Vec3 {
        let [a, b, c] = self.triangle_points(t);
        (b - a).cross(&(c - a))
    }

    pub fn triangle_area_mm2(&self, t: usize) -> f64 {
        0.5 * self.triangle_normal2(t).norm()
    }

    pub fn area_mm2(&self) -> f64 {
        (0..self.triangles.len()).map(|t| self.triangle_area_mm2(t)).sum()
    }

    /// Signed enclosed volume (divergence theorem); positive when the closed
    /// surface is wound with outward normals.
    pub fn signed_volume_mm3(&self) -> f64 {
        self.triangles
            .iter()
            .map(|&[a, b, c]| {
                let (p, q, r) = (self.points[a as usize], self.points[b as usize], self.points[c as usize]);
                p.dot(&q.cross(&r)) / 6.0
            })
            .sum()
    }

    /// Area-weighted centroid and unit normal of the triangles carrying `label`.
    pub fn label_centroid_normal(&self, label: i32) -> Option<(Vec3, Vec3, f64)> {
        let labelled = (0..self.triangles.len()).filter(|&t| self.face_ids[t] == label).map(|t| self.triangle_points(t));
        let (area, centroid, normal) = area_centroid_normal(labelled);
        (area > 0.0).then(|| (centroid, normal.normalize(), area))
    }

    /// For every undirected edge, the triangles that use it.
    pub fn edge_triangles(&self) -> EdgeMap<Vec<u32>> {
        let mut map: EdgeMap<Vec<u32>> = EdgeMap::with_capacity_and_hasher(self.triangles.len() * 3 / 2, Default::default());
        for (t, tri) in self.triangles.iter().enumerate() {
            for k in 0..3 {
                map.entry(edge_key(tri[k], tri[(k + 1) % 3])).or_default().push(t as u32);
            }
        }
        map
    }

    /// Triangle adjacency across each of its three edges (edge k joins corner k and k+1);
    /// `u32::MAX` where the edge is a boundary or non-manifold.
    pub fn triangle_neighbors(&self) -> Vec<[u32; 3]> {
        // Sorting the 3n (edge, triangle, corner) records groups each edge's users
        // without a hash map (this runs on every design step's 10-20k triangles).
        let mut uses: Vec<((u32, u32), u32, u8)> = Vec::with_capacity(3 * self.triangles.len());
        for (t, tri) in self.triangles.iter().enumerate() {
            for k in 0..3 {
                uses.push((edge_key(tri[k], tri[(k + 1) % 3]), t as u32, k as u8));
            }
        }
        uses.sort_unstable();
        let mut neighbors = vec![[u32::MAX; 3]; self.triangles.len()];
        for group in uses.chunk_by(|a, b| a.0 == b.0) {
            if let [(_, t0, k0), (_, t1, k1)] = group {
                neighbors[*t0 as usize][*k0 as usize] = *t1;
                neighbors[*t1 as usize][*k1 as usize] = *t0;
            }
        }
        neighbors
    }

    #[cfg(test)]
    fn triangle_neighbors_by_map(&self) -> Vec<[u32; 3]> {
        let edges = self.edge_triangles();
        self.triangles
            .iter()
            .enumerate()
            .map(|(t, tri)| {
                let mut nb = [u32::MAX; 3];
                for k in 0..3 {
                    let users = &edges[&edge_key(tri[k], tri[(k + 1) % 3])];
                    if users.len() == 2 {
                        nb[k] = if users[0] as usize == t { users[1] } else { users[0] };
                    }
                }
                nb
            })
            .collect()
    }

    /// The triangles whose label passes `keep`, with the points they use (as [`TriMesh::submesh`]).
    pub fn with_labels(&self, keep: impl Fn(i32) -> bool) -> TriMesh {
        let mask: Vec<bool> = self.face_ids.iter().map(|&l| keep(l)).collect();
        self.submesh(&mask).0
    }

    /// Keep only the listed triangles and the points they use, renumbering points.
    /// Returns the sub-mesh and, for each new point, its index in `self`.
    pub fn submesh(&self, keep: &[bool]) -> (TriMesh, Vec<u32>) {
        let mut new_index = vec![u32::MAX; self.points.len()];
        let mut old_of_new = Vec::new();
        let mut out = TriMesh::default();
        for (t, tri) in self.triangles.iter().enumerate() {
            if !keep[t] {
                continue;
            }
            let mut nt = [0u32; 3];
            for k in 0..3 {
                let v = tri[k] as usize;
                if new_index[v] == u32::MAX {
                    new_index[v] = old_of_new.len() as u32;
                    old_of_new.push(v as u32);
                    out.points.push(self.points[v]);
                }
                nt[k] = new_index[v];
            }
            out.triangles.push(nt);
            out.face_ids.push(self.face_ids[t]);
        }
        (out, old_of_new)
    }

    /// Closed boundary loops (each a cycle of point indices, following the
    /// triangles' winding). Errors if the boundary is not a set of simple loops.
    pub fn boundary_loops(&self) -> Result<Vec<Vec<u32>>, String> {
        let edges = self.edge_triangles();
        // Directed boundary edges, as they appear in their single triangle.
        let mut next: HashMap<u32, u32> = HashMap::new();
        for tri in &self.triangles {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                if edges[&edge_key(a, b)].len() == 1 && next.insert(a, b).is_some() {
                    return Err(format!("boundary is pinched at point {a}"));
                }
            }
        }
        let mut loops = Vec::new();
        let mut starts: Vec<u32> = next.keys().copied().collect();
        starts.sort_unstable();
        let mut used = std::collections::HashSet::new();
        for s in starts {
            if used.contains(&s) {
                continue;
            }
            let mut lp = vec![s];
            used.insert(s);
            let mut cur = next[&s];
            while cur != s {
                if !used.insert(cur) {
                    return Err(format!("boundary loop through point {cur} does not close"));
                }
                lp.push(cur);
                cur = *next.get(&cur).ok_or_else(|| format!("boundary stops at point {cur}"))?;
            }
            loops.push(lp);
        }
        Ok(loops)
    }

    /// Axis-aligned bounding box diagonal length (mm).
    pub fn bbox_diagonal_mm(&self) -> f64 {
        let mut lo = Vec3::repeat(f64::INFINITY);
        let mut hi = Vec3::repeat(f64::NEG_INFINITY);
        for p in &self.points {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        (hi - lo).norm()
    }

    /// Mean edge length (mm).
    pub fn mean_edge_length_mm(&self) -> f64 {
        let edges = self.edge_triangles();
        let sum: f64 = edges.keys().map(|&(a, b)| (self.points[a as usize] - self.points[b as usize]).norm()).sum();
        sum / edges.len().max(1) as f64
    }
}

/// What is wrong with a surface that should be closed and manifold.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct ManifoldReport {
    pub boundary_edges: usize,
    pub non_manifold_edges: usize,
    /// One offending edge (point indices) for error messages.
    pub example_edge: Option<(u32, u32)>,
    pub degenerate_triangles: usize,
    /// Edges whose two triangles traverse them in the same direction.
    pub inconsistently_wound_edges: usize,
}

impl ManifoldReport {
    pub fn is_closed_manifold(&self) -> bool {
        self.boundary_edges == 0 && self.non_manifold_edges == 0 && self.degenerate_triangles == 0
    }
}

/// Count boundary, non-manifold and inconsistently wound edges.
pub fn manifold_report(mesh: &TriMesh) -> ManifoldReport {
    let mut directed: HashMap<(u32, u32), i32> = HashMap::new();
    let mut rep = ManifoldReport::default();
    for tri in &mesh.triangles {
        if tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2] {
            rep.degenerate_triangles += 1;
            continue;
        }
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            // +1 for a->b with a<b, +16 for the reverse, to tell windings apart.
            *directed.entry(edge_key(a, b)).or_default() += if a < b { 1 } else { 16 };
        }
    }
    for (&e, &code) in &directed {
        let count = code % 16 + code / 16;
        if count == 1 {
            rep.boundary_edges += 1;
            rep.example_edge.get_or_insert(e);
        } else if count > 2 {
            rep.non_manifold_edges += 1;
            rep.example_edge = Some(e);
        } else if code != 17 {
            rep.inconsistently_wound_edges += 1;
        }
    }
    rep
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axes_across_any_direction_are_a_right_handed_unit_frame() {
        for n in [Vec3::x(), -Vec3::x(), Vec3::y(), Vec3::z(), Vec3::new(0.95, 0.3, 0.1).normalize(), Vec3::new(-1.0, 2.0, 3.0).normalize()] {
            let (u, v) = axes_across(&n);
            assert!((u.norm() - 1.0).abs() < 1e-12 && (v.norm() - 1.0).abs() < 1e-12, "{n:?}");
            assert!(u.dot(&n).abs() < 1e-12 && v.dot(&n).abs() < 1e-12 && u.dot(&v).abs() < 1e-12, "{n:?}");
            assert!((u.cross(&v) - n).norm() < 1e-12, "(u, v, n) right-handed for {n:?}");
        }
    }

    #[test]
    fn sorted_neighbors_match_the_edge_map_on_closed_open_and_non_manifold_meshes() {
        let closed = crate::phantom::phantom_default().surface;
        assert_eq!(closed.triangle_neighbors(), closed.triangle_neighbors_by_map());
        let mut open = closed.clone();
        open.triangles.truncate(open.triangles.len() / 2);
        open.face_ids.truncate(open.triangles.len());
        assert_eq!(open.triangles.len(), open.face_ids.len());
        assert_eq!(open.triangle_neighbors(), open.triangle_neighbors_by_map());
        // Three triangles on one edge: no neighbour across it.
        let fan = TriMesh {
            points: vec![Vec3::zeros(), Vec3::x(), Vec3::y(), Vec3::z(), -Vec3::y()],
            triangles: vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]],
            face_ids: vec![2; 3],
        };
        assert_eq!(fan.triangle_neighbors(), vec![[u32::MAX; 3]; 3]);
        assert_eq!(fan.triangle_neighbors(), fan.triangle_neighbors_by_map());
    }

    fn tetra() -> TriMesh {
        let p = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
        ];
        // Outward winding.
        let t = vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
        TriMesh::new(p, t, vec![2; 4])
    }

    #[test]
    fn tetra_is_closed_with_positive_volume() {
        let m = tetra();
        let r = manifold_report(&m);
        assert!(r.is_closed_manifold(), "{r:?}");
        assert_eq!(r.inconsistently_wound_edges, 0);
        assert!((m.signed_volume_mm3() - 1.0 / 6.0).abs() < 1e-12);
    }

    #[test]
    fn open_mesh_has_one_boundary_loop() {
        let mut m = tetra();
        m.triangles.pop();
        m.face_ids.pop();
        let r = manifold_report(&m);
        assert_eq!(r.boundary_edges, 3);
        let loops = m.boundary_loops().unwrap();
        assert_eq!(loops.len(), 1);
        assert_eq!(loops[0].len(), 3);
    }

    #[test]
    fn flipped_triangle_is_detected() {
        let mut m = tetra();
        m.triangles[0].swap(1, 2);
        assert_eq!(manifold_report(&m).inconsistently_wound_edges, 3);
    }
}
