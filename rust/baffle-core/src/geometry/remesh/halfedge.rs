//! A compact, Vec-based half-edge structure for triangle meshes, with the three
//! local operators isotropic remeshing needs (edge split, collapse, flip).
//!
//! Face `f` owns half-edges `3f`, `3f+1`, `3f+2`; half-edge `3f+k` runs from
//! corner `k` to corner `k+1` of the face. Boundary edges have no twin
//! (`NONE`). Deleted faces and vertices stay in the arrays (flagged) until
//! `to_trimesh` compacts them, so indices stay stable during a pass.

use crate::geometry::mesh::{TriMesh, Vec3};

pub const NONE: u32 = u32::MAX;

/// Pair each half-edge with its reverse by sorting undirected edge keys
/// (faster than hashing at these sizes).
fn match_twins(triangles: &[[u32; 3]]) -> Result<Vec<u32>, String> {
    let mut keys: Vec<(u32, u32, u32)> = Vec::with_capacity(3 * triangles.len());
    for (f, tri) in triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            keys.push((a.min(b), a.max(b), (3 * f + k) as u32));
        }
    }
    keys.sort_unstable();
    let mut twin = vec![NONE; keys.len()];
    let origin = |h: u32| triangles[(h / 3) as usize][(h % 3) as usize];
    let mut i = 0;
    while i < keys.len() {
        let (a, b, h) = keys[i];
        let mut j = i + 1;
        while j < keys.len() && keys[j].0 == a && keys[j].1 == b {
            j += 1;
        }
        match j - i {
            1 => {}
            2 => {
                let g = keys[i + 1].2;
                if origin(h) == origin(g) {
                    return Err(format!("edge ({a}, {b}) is used twice in the same direction (inconsistent winding)"));
                }
                twin[h as usize] = g;
                twin[g as usize] = h;
            }
            n => return Err(format!("edge ({a}, {b}) is shared by {n} triangles (non-manifold)")),
        }
        i = j;
    }
    Ok(twin)
}

#[derive(Clone, Debug)]
pub struct HalfEdgeMesh {
    pub pos: Vec<Vec3>,
    /// Corner vertices of each face, in the input's winding.
    pub corners: Vec<[u32; 3]>,
    pub label: Vec<i32>,
    /// Twin half-edge, or `NONE` on the boundary.
    pub twin: Vec<u32>,
    /// Some outgoing half-edge of each vertex (any one; circulation copes).
    pub out: Vec<u32>,
    pub face_alive: Vec<bool>,
    pub vertex_alive: Vec<bool>,
}

#[inline]
pub fn face_of(h: u32) -> usize {
    (h / 3) as usize
}

#[inline]
pub fn next(h: u32) -> u32 {
    if h % 3 == 2 {
        h - 2
    } else {
        h + 1
    }
}

#[inline]
pub fn prev(h: u32) -> u32 {
    if h.is_multiple_of(3) {
        h + 2
    } else {
        h - 1
    }
}

impl HalfEdgeMesh {
    /// Build from an indexed mesh. Errors name the first non-manifold or
    /// inconsistently wound edge, or pinched vertex. Unreferenced points are
    /// kept but flagged dead.
    pub fn from_trimesh(mesh: &TriMesh) -> Result<Self, String> {
        let twin = match_twins(&mesh.triangles)?;
        let mut out = vec![NONE; mesh.points.len()];
        let mut incident = vec![0u32; mesh.points.len()];
        for (f, tri) in mesh.triangles.iter().enumerate() {
            for k in 0..3 {
                out[tri[k] as usize] = (3 * f + k) as u32;
                incident[tri[k] as usize] += 1;
            }
        }
        let vertex_alive: Vec<bool> = out.iter().map(|&h| h != NONE).collect();
        let he = HalfEdgeMesh {
            pos: mesh.points.clone(),
            corners: mesh.triangles.clone(),
            label: mesh.face_ids.clone(),
            twin,
            out,
            face_alive: vec![true; mesh.triangles.len()],
            vertex_alive,
        };
        he.check_vertex_fans(&incident)?;
        Ok(he)
    }

    /// A vertex whose incident faces do not form one fan (a "bow-tie") breaks
    /// circulation; reject it up front.
    fn check_vertex_fans(&self, incident: &[u32]) -> Result<(), String> {
        let mut ring = Vec::new();
        for (v, &faces) in incident.iter().enumerate() {
            if !self.vertex_alive[v] {
                continue;
            }
            self.outgoing(v as u32, &mut ring);
            if ring.len() != faces as usize {
                return Err(format!("point {v} is non-manifold (its triangles form more than one fan)"));
            }
        }
        Ok(())
    }

    #[inline]
    pub fn origin(&self, h: u32) -> u32 {
        self.corners[face_of(h)][(h % 3) as usize]
    }

    #[inline]
    pub fn target(&self, h: u32) -> u32 {
        self.corners[face_of(h)][((h + 1) % 3) as usize]
    }

    #[inline]
    pub fn is_boundary_edge(&self, h: u32) -> bool {
        self.twin[h as usize] == NONE
    }

    /// Feature edge: on the boundary or between two labels.
    #[inline]
    pub fn is_feature_edge(&self, h: u32) -> bool {
        let t = self.twin[h as usize];
        t == NONE || self.label[face_of(h)] != self.label[face_of(t)]
    }

    pub fn edge_length_sq(&self, h: u32) -> f64 {
        (self.pos[self.origin(h) as usize] - self.pos[self.target(h) as usize]).norm_squared()
    }

    /// Outgoing half-edges of `v` in rotation order. On the boundary the list
    /// starts at the half-edge whose face is first after the boundary gap.
    pub fn outgoing(&self, v: u32, ring: &mut Vec<u32>) {
        ring.clear();
        let start = self.out[v as usize];
        if start == NONE {
            return;
        }
        // Rotate forwards; interior vertices come back to the start in one sweep.
        let mut h = start;
        loop {
            ring.push(h);
            let t = self.twin[h as usize];
            if t == NONE {
                break;
            }
            h = next(t);
            if h == start || ring.len() > self.corners.len() {
                return;
            }
        }
        // Hit the boundary: pick up the faces before `start`, then put them first.
        let forward = ring.len();
        let mut h = start;
        loop {
            let back = self.twin[prev(h) as usize];
            if back == NONE || ring.len() > self.corners.len() {
                break;
            }
            ring.push(back);
            h = back;
        }
        let backward = ring.len() - forward;
        ring.rotate_right(backward);
        ring[..backward].reverse();
    }

    /// Neighbouring vertices of `v` (one-ring), using `ring` as scratch.
    pub fn neighbours(&self, v: u32, ring: &mut Vec<u32>, out: &mut Vec<u32>) {
        self.outgoing(v, ring);
        out.clear();
        out.extend(ring.iter().map(|&h| self.target(h)));
        if let Some(&first) = ring.first() {
            if self.twin[prev(first) as usize] == NONE {
                out.push(self.origin(prev(first)));
            }
        }
    }

    /// Squared length of face f's longest edge.
    pub fn longest_edge_sq(&self, f: usize) -> f64 {
        let [a, b, c] = self.corners[f].map(|v| self.pos[v as usize]);
        (b - a).norm_squared().max((c - b).norm_squared()).max((a - c).norm_squared())
    }

    pub fn face_normal2(&self, f: usize) -> Vec3 {
        let [a, b, c] = self.corners[f];
        let (pa, pb, pc) = (self.pos[a as usize], self.pos[b as usize], self.pos[c as usize]);
        (pb - pa).cross(&(pc - pa))
    }

    #[inline]
    fn link(&mut self, x: u32, y: u32) {
        if x != NONE {
            self.twin[x as usize] = y;
        }
        if y != NONE {
            self.twin[y as usize] = x;
        }
    }

    /// Write face `f` with corners `v` and the twins of its three half-edges.
    fn set_face(&mut self, f: usize, v: [u32; 3], twins: [u32; 3]) {
        self.corners[f] = v;
        for (k, &t) in twins.iter().enumerate() {
            self.link((3 * f + k) as u32, t);
        }
    }

    fn push_face(&mut self, label: i32) -> usize {
        let f = self.corners.len();
        self.corners.push([NONE; 3]);
        self.label.push(label);
        self.twin.extend_from_slice(&[NONE; 3]);
        self.face_alive.push(true);
        f
    }

    pub fn push_vertex(&mut self, p: Vec3) -> u32 {
        self.pos.push(p);
        self.out.push(NONE);
        self.vertex_alive.push(true);
        (self.pos.len() - 1) as u32
    }

    /// Split the edge of half-edge `h` at the new vertex `m` (already pushed).
    /// Each split triangle becomes two carrying its label; winding is kept.
    pub fn split_edge(&mut self, h: u32, m: u32) {
        let t = self.twin[h as usize];
        let f = face_of(h);
        let (a, b, c) = (self.origin(h), self.target(h), self.target(next(h)));
        let bc_twin = self.twin[next(h) as usize];
        let ca_twin = self.twin[prev(h) as usize];
        let g = self.push_face(self.label[f]);
        // f = (a, m, c), g = (m, b, c); inner edge m-c joins them.
        self.set_face(f, [a, m, c], [NONE, NONE, ca_twin]);
        self.set_face(g, [m, b, c], [NONE, bc_twin, NONE]);
        self.link((3 * f + 1) as u32, (3 * g + 2) as u32);
        self.out[m as usize] = (3 * g) as u32;
        self.out[a as usize] = (3 * f) as u32;
        self.out[b as usize] = (3 * g + 1) as u32;
        self.out[c as usize] = (3 * f + 2) as u32;
        if t == NONE {
            return;
        }
        let f2 = face_of(t);
        let d = self.target(next(t));
        let ad_twin = self.twin[next(t) as usize];
        let db_twin = self.twin[prev(t) as usize];
        let g2 = self.push_face(self.label[f2]);
        // f2 = (b, m, d), g2 = (m, a, d); outer halves pair with f and g.
        self.set_face(f2, [b, m, d], [(3 * g) as u32, NONE, db_twin]);
        self.set_face(g2, [m, a, d], [(3 * f) as u32, ad_twin, NONE]);
        self.link((3 * f2 + 1) as u32, (3 * g2 + 2) as u32);
        self.out[d as usize] = (3 * f2 + 2) as u32;
    }

    /// Flip the interior edge of `h`: triangles (a,b,c) and (b,a,d) become
    /// (a,d,c) and (d,b,c).
    pub fn flip_edge(&mut self, h: u32) {
        let t = self.twin[h as usize];
        let (f, f2) = (face_of(h), face_of(t));
        let (a, b, c) = (self.origin(h), self.target(h), self.target(next(h)));
        let d = self.target(next(t));
        let bc = self.twin[next(h) as usize];
        let ca = self.twin[prev(h) as usize];
        let ad = self.twin[next(t) as usize];
        let db = self.twin[prev(t) as usize];
        self.set_face(f, [a, d, c], [ad, NONE, ca]);
        self.set_face(f2, [d, b, c], [db, bc, NONE]);
        self.link((3 * f + 1) as u32, (3 * f2 + 2) as u32);
        self.out[a as usize] = (3 * f) as u32;
        self.out[d as usize] = (3 * f + 1) as u32;
        self.out[c as usize] = (3 * f + 2) as u32;
        self.out[b as usize] = (3 * f2 + 1) as u32;
    }

    /// Collapse the edge of half-edge `h`: its end `remove` disappears into the
    /// other end, which keeps its position. The caller has checked the link
    /// condition and that neither triangle of the edge is an ear.
    pub fn collapse_edge(&mut self, h: u32, remove: u32, ring: &mut Vec<u32>) {
        let t = self.twin[h as usize];
        let keep = if remove == self.origin(h) { self.target(h) } else { self.origin(h) };
        let c = self.target(next(h));
        self.outgoing(remove, ring);
        for &g in ring.iter() {
            self.corners[face_of(g)][(g % 3) as usize] = keep;
        }
        // The two remaining sides of each removed triangle become one edge.
        let (o1, o2) = (self.twin[next(h) as usize], self.twin[prev(h) as usize]);
        self.link(o1, o2);
        self.kill_face(face_of(h));
        self.out[c as usize] = if o1 != NONE { o1 } else { next(o2) };
        self.out[keep as usize] = if o2 != NONE { o2 } else { next(o1) };
        if t != NONE {
            let d = self.target(next(t));
            let (o3, o4) = (self.twin[next(t) as usize], self.twin[prev(t) as usize]);
            self.link(o3, o4);
            self.kill_face(face_of(t));
            self.out[d as usize] = if o3 != NONE { o3 } else { next(o4) };
            if o4 != NONE {
                self.out[keep as usize] = o4;
            }
        }
        self.vertex_alive[remove as usize] = false;
        self.out[remove as usize] = NONE;
    }

    fn kill_face(&mut self, f: usize) {
        self.face_alive[f] = false;
        for k in 0..3 {
            self.twin[3 * f + k] = NONE;
        }
    }

    /// Compact live faces and vertices into an indexed mesh.
    pub fn to_trimesh(&self) -> TriMesh {
        let mut new_index = vec![NONE; self.pos.len()];
        let mut out = TriMesh::default();
        for f in (0..self.corners.len()).filter(|&f| self.face_alive[f]) {
            let mut tri = [0u32; 3];
            for (k, &v) in self.corners[f].iter().enumerate() {
                if new_index[v as usize] == NONE {
                    new_index[v as usize] = out.points.len() as u32;
                    out.points.push(self.pos[v as usize]);
                }
                tri[k] = new_index[v as usize];
            }
            out.triangles.push(tri);
            out.face_ids.push(self.label[f]);
        }
        out
    }
}
