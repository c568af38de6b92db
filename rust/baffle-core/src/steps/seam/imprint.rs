//! Inserting the seam's path into the mesh as an exact edge loop.
//!
//! Each path point becomes a vertex (snapped to a vertex or edge closer than a
//! thousandth of the mean edge, else splitting the edge or face it lies on). Two
//! consecutive points always lie in one input triangle, so the straight seam between
//! them is walked inside that (planar) triangle's current pieces, splitting every
//! piece edge it crosses. Working in one plane at a time keeps the walk exact.

use super::{common_triangle, PathPoint, Place, ProjectedSeam};
use crate::error::DesignError;
use crate::geometry::mesh::{edge_key, TriMesh, Vec3};
use crate::geometry::spatial::closest_point_on_segment;
use std::collections::HashSet;

/// The surface with the seam inserted as an edge loop.
#[derive(Clone, Debug)]
pub struct ImprintedSeam {
    pub mesh: TriMesh,
    /// The seam as a cycle of vertex indices of `mesh`.
    pub loop_vertices: Vec<u32>,
}

/// Insert the projected seam into the surface as an exact, simple edge loop.
pub fn imprint_seam(surface: &TriMesh, seam: &ProjectedSeam) -> Result<ImprintedSeam, DesignError> {
    let snap_mm = super::insertion_snap_mm(surface);
    let mut edit = EditMesh::new(surface);
    let vertex_triangles = edit.vert_tris.clone();
    let path = &seam.path;
    if path.len() < 3 {
        return Err(DesignError::Seam("the seam has fewer than 3 points".into()));
    }
    let mut loop_vertices: Vec<u32> = Vec::with_capacity(2 * path.len());
    let mut so_far = SeamSoFar::default();
    let first = edit.insert(&path[0], snap_mm);
    so_far.push(&mut loop_vertices, first, 0)?;
    let mut current = first;
    for i in 1..=path.len() {
        let (from, to) = (&path[i - 1], &path[i % path.len()]);
        let target = if i == path.len() { first } else { edit.insert(to, snap_mm) };
        if target == current {
            continue; // two path points closer than the snap distance
        }
        // The last few path points may coincide with the first vertex: the loop closes there.
        let closing = target == first;
        if closing && i + 3 < path.len() {
            return Err(crossing_itself(i));
        }
        let plane = edit
            .shared_input_triangle(current, target, common_triangle(&from.place, &to.place, &vertex_triangles))
            .ok_or_else(|| DesignError::Seam(format!("seam points {} and {} share no triangle", i - 1, i % path.len())))?;
        for v in edit.walk_in_triangle(plane, current, target, snap_mm, &so_far, i)? {
            if v != first {
                so_far.push(&mut loop_vertices, v, i)?;
            }
        }
        if closing {
            break;
        }
        current = target;
    }
    if loop_vertices.len() < 3 {
        return Err(DesignError::Seam("the seam collapsed to fewer than 3 vertices".into()));
    }
    Ok(ImprintedSeam { mesh: edit.into_mesh(), loop_vertices })
}

/// The seam's vertices and edges inserted so far, to catch a seam that crosses itself.
#[derive(Default)]
struct SeamSoFar {
    vertices: HashSet<u32>,
    edges: HashSet<(u32, u32)>,
}

impl SeamSoFar {
    fn push(&mut self, lp: &mut Vec<u32>, v: u32, point: usize) -> Result<(), DesignError> {
        if lp.last() == Some(&v) {
            return Ok(());
        }
        if !self.vertices.insert(v) {
            return Err(crossing_itself(point));
        }
        if let Some(&prev) = lp.last() {
            self.edges.insert(edge_key(prev, v));
        }
        lp.push(v);
        Ok(())
    }
}

fn crossing_itself(point: usize) -> DesignError {
    DesignError::Seam(format!("the seam crosses itself near seam point {point}; check the order of the suture points"))
}

/// A triangle mesh that supports edge and face splits, remembering which input
/// triangle each current triangle came from (all pieces stay in its plane).
struct EditMesh {
    points: Vec<Vec3>,
    tris: Vec<[u32; 3]>,
    labels: Vec<i32>,
    vert_tris: Vec<Vec<u32>>,
    origin: Vec<u32>,
    children: Vec<Vec<u32>>,
    unit_normals: Vec<Vec3>,
    /// Number of input vertices (they keep their indices).
    input_vertices: usize,
    /// For each vertex created on an input edge, that edge.
    on_input_edge: std::collections::HashMap<u32, (u32, u32)>,
}

/// What a walk step from the current vertex runs into.
enum Crossing {
    Vertex(u32),
    Edge(u32, u32, Vec3),
}

impl EditMesh {
    fn new(mesh: &TriMesh) -> Self {
        let mut vert_tris = vec![Vec::new(); mesh.points.len()];
        for (t, tri) in mesh.triangles.iter().enumerate() {
            for &v in tri {
                vert_tris[v as usize].push(t as u32);
            }
        }
        let unit_normals = (0..mesh.triangles.len())
            .map(|t| {
                let n = mesh.triangle_normal2(t);
                n / n.norm().max(1e-300)
            })
            .collect();
        EditMesh {
            points: mesh.points.clone(),
            tris: mesh.triangles.clone(),
            labels: mesh.face_ids.clone(),
            vert_tris,
            origin: (0..mesh.triangles.len() as u32).collect(),
            children: (0..mesh.triangles.len() as u32).map(|t| vec![t]).collect(),
            unit_normals,
            input_vertices: mesh.points.len(),
            on_input_edge: std::collections::HashMap::new(),
        }
    }

    fn into_mesh(self) -> TriMesh {
        TriMesh::new(self.points, self.tris, self.labels)
    }

    fn insert(&mut self, point: &PathPoint, snap_mm: f64) -> u32 {
        match point.place {
            Place::Vertex(v) => v,
            Place::Face(t) => self.insert_point(t, point.position_mm, snap_mm),
            Place::Edge { triangles, vertices } => self
                .insert_on_input_edge(triangles[0], edge_key(vertices[0], vertices[1]), point.position_mm, snap_mm)
                .unwrap_or_else(|| self.insert_point(triangles[0], point.position_mm, snap_mm)),
        }
    }

    /// The input edge a current edge (a, b) lies on, if any. Only splits create
    /// vertices on input edges, and no new edge ever joins two input vertices.
    fn input_edge(&self, a: u32, b: u32) -> Option<(u32, u32)> {
        let n = self.input_vertices as u32;
        if a < n && b < n {
            return Some(edge_key(a, b));
        }
        let on = |v: u32, e: (u32, u32)| v == e.0 || v == e.1 || self.on_input_edge.get(&v) == Some(&e);
        [a, b].iter().filter_map(|v| self.on_input_edge.get(v)).copied().find(|&e| on(a, e) && on(b, e))
    }

    /// Insert `p`, lying on input edge `edge` of input triangle `orig`, on the piece
    /// of that edge holding it (so it stays shared by both input triangles).
    fn insert_on_input_edge(&mut self, orig: u32, edge: (u32, u32), p: Vec3, snap_mm: f64) -> Option<u32> {
        let mut best: Option<(f64, u32, u32, Vec3)> = None;
        for &t in &self.children[orig as usize] {
            let tri = self.tris[t as usize];
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                if self.input_edge(a, b) != Some(edge) {
                    continue;
                }
                let foot = closest_point_on_segment(&p, &self.points[a as usize], &self.points[b as usize]).0;
                let d = (foot - p).norm();
                if best.is_none_or(|(bd, ..)| d < bd) {
                    best = Some((d, a, b, foot));
                }
            }
        }
        let (_, a, b, foot) = best?;
        for v in [a, b] {
            if (self.points[v as usize] - foot).norm() <= snap_mm {
                return Some(v);
            }
        }
        Some(self.split_edge(a, b, foot))
    }

    fn add_triangle(&mut self, tri: [u32; 3], label: i32, origin: u32) {
        let t = self.tris.len() as u32;
        self.tris.push(tri);
        self.labels.push(label);
        self.origin.push(origin);
        self.children[origin as usize].push(t);
        for &v in &tri {
            self.vert_tris[v as usize].push(t);
        }
    }

    fn add_point(&mut self, p: Vec3) -> u32 {
        self.points.push(p);
        self.vert_tris.push(Vec::new());
        (self.points.len() - 1) as u32
    }

    /// Insert `p` (lying on input triangle `orig`) as a vertex: snap to a close
    /// vertex, split a close edge, or split the containing face.
    fn insert_point(&mut self, orig: u32, p: Vec3, snap_mm: f64) -> u32 {
        let t = self.containing_child(orig, p);
        let tri = self.tris[t as usize];
        let corners = tri.map(|v| self.points[v as usize]);
        if let Some(k) = (0..3).find(|&k| (corners[k] - p).norm() <= snap_mm) {
            return tri[k];
        }
        for k in 0..3 {
            let foot = closest_point_on_segment(&p, &corners[k], &corners[(k + 1) % 3]).0;
            if (foot - p).norm() <= snap_mm {
                return self.split_edge(tri[k], tri[(k + 1) % 3], foot);
            }
        }
        self.split_face(t, p)
    }

    /// The current piece of input triangle `orig` that contains `p` (the one whose
    /// smallest barycentric coordinate is largest, which is robust on edges).
    fn containing_child(&self, orig: u32, p: Vec3) -> u32 {
        let mut best = (f64::NEG_INFINITY, self.children[orig as usize][0]);
        for &t in &self.children[orig as usize] {
            let [a, b, c] = self.tris[t as usize].map(|v| self.points[v as usize]);
            let score = min_barycentric(a, b, c, p);
            if score > best.0 {
                best = (score, t);
            }
        }
        best.1
    }

    fn split_face(&mut self, t: u32, p: Vec3) -> u32 {
        let w = self.add_point(p);
        let [a, b, c] = self.tris[t as usize];
        let (label, orig) = (self.labels[t as usize], self.origin[t as usize]);
        self.tris[t as usize] = [a, b, w];
        self.vert_tris[c as usize].retain(|&x| x != t);
        self.vert_tris[w as usize].push(t);
        self.add_triangle([b, c, w], label, orig);
        self.add_triangle([c, a, w], label, orig);
        w
    }

    /// Split edge (a, b) at `p` in both of its triangles, keeping their winding.
    fn split_edge(&mut self, a: u32, b: u32, p: Vec3) -> u32 {
        let on_edge = self.input_edge(a, b);
        let w = self.add_point(p);
        if let Some(e) = on_edge {
            self.on_input_edge.insert(w, e);
        }
        let users: Vec<u32> =
            self.vert_tris[a as usize].iter().copied().filter(|t| self.tris[*t as usize].contains(&b)).collect();
        for t in users {
            let tri = self.tris[t as usize];
            let k = (0..3).find(|&k| edge_key(tri[k], tri[(k + 1) % 3]) == edge_key(a, b)).unwrap_or(0);
            let (p0, p1, p2) = (tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]);
            let (label, orig) = (self.labels[t as usize], self.origin[t as usize]);
            self.tris[t as usize] = [p0, w, p2];
            self.vert_tris[p1 as usize].retain(|&x| x != t);
            self.vert_tris[w as usize].push(t);
            self.add_triangle([w, p1, p2], label, orig);
        }
        w
    }

    /// An input triangle whose pieces touch both vertices (the `preferred` one if it
    /// does): the straight seam between them runs inside it.
    fn shared_input_triangle(&self, a: u32, b: u32, preferred: Option<u32>) -> Option<u32> {
        let around = |v: u32| self.vert_tris[v as usize].iter().map(|&t| self.origin[t as usize]).collect::<Vec<u32>>();
        let (around_a, around_b) = (around(a), around(b));
        let shared = |t: &u32| around_a.contains(t) && around_b.contains(t);
        preferred.filter(shared).or_else(|| around_a.iter().copied().find(shared))
    }

    fn has_edge(&self, a: u32, b: u32) -> bool {
        self.vert_tris[a as usize].iter().any(|&t| self.tris[t as usize].contains(&b))
    }

    /// Walk straight from vertex `from` to vertex `to` inside input triangle
    /// `plane`, splitting every piece edge crossed. Returns the vertices after
    /// `from`, ending with `to`.
    fn walk_in_triangle(
        &mut self,
        plane: u32,
        from: u32,
        to: u32,
        snap_mm: f64,
        so_far: &SeamSoFar,
        point: usize,
    ) -> Result<Vec<u32>, DesignError> {
        let mut path = Vec::new();
        let mut current = from;
        for _ in 0..10_000 {
            if current == to {
                return Ok(path);
            }
            if self.has_edge(current, to) {
                path.push(to);
                return Ok(path);
            }
            let next = match self.next_crossing(plane, current, to, snap_mm) {
                Some(Crossing::Vertex(v)) => v,
                Some(Crossing::Edge(a, b, p)) => {
                    if so_far.edges.contains(&edge_key(a, b)) {
                        return Err(crossing_itself(point));
                    }
                    self.split_edge(a, b, p)
                }
                None => break,
            };
            if so_far.vertices.contains(&next) && next != to {
                return Err(crossing_itself(point));
            }
            path.push(next);
            current = next;
        }
        Err(DesignError::Seam(format!("could not insert the seam into the mesh near seam point {point}")))
    }

    /// Among the pieces of input triangle `plane` around `c`, the opposite edge (or
    /// vertex) that the straight line to `to` runs into, best aligned with it.
    fn next_crossing(&self, plane: u32, c: u32, to: u32, snap_mm: f64) -> Option<Crossing> {
        let pc = self.points[c as usize];
        let dir = self.points[to as usize] - pc;
        let side = dir.cross(&self.unit_normals[plane as usize]);
        let side = side / side.norm().max(1e-300);
        let mut best: Option<(f64, Crossing)> = None;
        let mut consider = |x: Vec3, crossing: Crossing| {
            let cos = (x - pc).dot(&dir) / ((x - pc).norm() * dir.norm()).max(1e-300);
            if cos > 1e-9 && best.as_ref().is_none_or(|b| cos > b.0) {
                best = Some((cos, crossing));
            }
        };
        for &t in self.vert_tris[c as usize].iter().filter(|&&t| self.origin[t as usize] == plane) {
            let tri = self.tris[t as usize];
            let k = (0..3).find(|&k| tri[k] == c).unwrap_or(0);
            let (a, b) = (tri[(k + 1) % 3], tri[(k + 2) % 3]);
            let (pa, pb) = (self.points[a as usize], self.points[b as usize]);
            let (da, db) = (side.dot(&(pa - pc)), side.dot(&(pb - pc)));
            if da.abs() <= snap_mm {
                consider(pa, Crossing::Vertex(a));
            }
            if db.abs() <= snap_mm {
                consider(pb, Crossing::Vertex(b));
            }
            if da * db < 0.0 {
                let x = pa + (pb - pa) * (da / (da - db));
                if (x - pa).norm() > snap_mm && (x - pb).norm() > snap_mm {
                    consider(x, Crossing::Edge(a, b, x));
                }
            }
        }
        best.map(|(_, crossing)| crossing)
    }
}

/// Smallest barycentric coordinate of `p` (projected into the triangle's plane).
fn min_barycentric(a: Vec3, b: Vec3, c: Vec3, p: Vec3) -> f64 {
    let n = (b - a).cross(&(c - a));
    let nn = n.norm_squared();
    if nn == 0.0 {
        return f64::NEG_INFINITY;
    }
    let wa = (c - b).cross(&(p - b)).dot(&n) / nn;
    let wb = (a - c).cross(&(p - c)).dot(&n) / nn;
    let wc = 1.0 - wa - wb;
    wa.min(wb).min(wc)
}
