//! Step 1, the attachment seam [paper 2.3.3].
//!
//! The surgeon's suture points are ordered by angle in their principal-component
//! plane, a closed parametric cubic spline is fitted through them and resampled at
//! (by default) 600 points evenly spaced in arc length, each sample is projected onto
//! the RV wall, and the resulting curve is inserted into the mesh as an exact edge
//! loop by splitting triangles along its path. The baffle is later attached to these
//! very vertices, so wall and baffle share the seam exactly.

use crate::error::DesignError;
use crate::mesh::{edge_key, FaceLabels, TriMesh, Vec3};
use crate::numerics::pca::best_fit_plane;
use crate::numerics::spline::ClosedSpline;
use crate::spatial::{closest_point_on_segment, TriangleBvh};
use std::collections::HashSet;

/// The seam as projected onto the wall, before it is inserted into the mesh.
#[derive(Clone, Debug)]
pub struct ProjectedSeam {
    /// Suture points in loop order (PCA-plane angle), mm.
    pub ordered_points_mm: Vec<Vec3>,
    /// Resampled spline points projected onto the RV wall, mm.
    pub samples_mm: Vec<Vec3>,
    /// Original triangle holding each projected sample.
    pub sample_triangles: Vec<u32>,
}

/// The surface with the seam inserted as an edge loop.
#[derive(Clone, Debug)]
pub struct ImprintedSeam {
    pub mesh: TriMesh,
    /// The seam as a cycle of vertex indices of `mesh`.
    pub loop_vertices: Vec<u32>,
}

/// Order points by their angle around the centroid in their best-fit plane.
pub fn order_by_pca_angle(points: &[Vec3]) -> Vec<Vec3> {
    let plane = best_fit_plane(points);
    let mut keyed: Vec<(f64, Vec3)> = points
        .iter()
        .map(|p| {
            let (u, v) = plane.project_2d(p);
            (v.atan2(u), *p)
        })
        .collect();
    keyed.sort_by(|a, b| a.0.total_cmp(&b.0));
    keyed.into_iter().map(|(_, p)| p).collect()
}

/// Check the suture points against the surface, order them, fit the closed spline,
/// resample it and project the samples onto the wall.
pub fn project_seam(
    surface: &TriMesh,
    bvh: &TriangleBvh,
    labels: &FaceLabels,
    points: &[Vec3],
    sample_count: usize,
    max_point_distance_mm: f64,
) -> Result<ProjectedSeam, DesignError> {
    if points.len() < 4 {
        return Err(DesignError::SuturePoints(format!(
            "{} point(s) given; a closed seam needs at least 4",
            points.len()
        )));
    }
    check_points_on_wall(surface, bvh, labels, points, max_point_distance_mm)?;
    let ordered = order_by_pca_angle(points);
    let spline = ClosedSpline::fit(&ordered).map_err(DesignError::SuturePoints)?;
    // Project a 4x denser resampling and keep every 4th sample, plus the ones in
    // between where the projected curve leaves the chord between kept samples (across
    // a crease), so the inserted seam follows the projected curve there too.
    let count = sample_count.max(16);
    let dense = spline.resample_uniform_arclength(REFINE * count);
    let mut projected = Vec::with_capacity(dense.len());
    for (i, q) in dense.iter().enumerate() {
        let hit = bvh
            .closest_point_filtered(surface, *q, |t| surface.face_ids[t as usize] == labels.wall)
            .ok_or_else(|| DesignError::Seam(format!("seam sample {i} found no wall triangle")))?;
        projected.push((hit.point, hit.triangle));
    }
    let kept = samples_to_keep(&projected.iter().map(|p| p.0).collect::<Vec<_>>(), REFINE, CREASE_TOLERANCE_MM);
    let samples_mm = kept.iter().map(|&i| projected[i].0).collect();
    let sample_triangles = kept.iter().map(|&i| projected[i].1).collect();
    Ok(ProjectedSeam { ordered_points_mm: ordered, samples_mm, sample_triangles })
}

/// Oversampling of the seam spline before thinning (see `samples_to_keep`).
const REFINE: usize = 4;
/// Largest distance of an in-between projected point from the chord of the kept samples.
const CREASE_TOLERANCE_MM: f64 = 0.005;

/// Indices of the dense projected samples to keep: every `stride`-th, plus those
/// farther than `tolerance_mm` from the chord joining the two regular samples around them.
fn samples_to_keep(dense: &[Vec3], stride: usize, tolerance_mm: f64) -> Vec<usize> {
    let n = dense.len();
    let mut kept = Vec::with_capacity(n / stride + 16);
    for start in (0..n).step_by(stride) {
        kept.push(start);
        let (a, b) = (dense[start], dense[(start + stride) % n]);
        for i in start + 1..(start + stride).min(n) {
            if distance_to_segment(&dense[i], &a, &b) > tolerance_mm {
                kept.push(i);
            }
        }
    }
    kept
}

fn distance_to_segment(p: &Vec3, a: &Vec3, b: &Vec3) -> f64 {
    (p - closest_point_on_segment(p, a, b).0).norm()
}

/// Every suture point must lie on the RV wall (not a cap) within the tolerance.
fn check_points_on_wall(
    surface: &TriMesh,
    bvh: &TriangleBvh,
    labels: &FaceLabels,
    points: &[Vec3],
    max_point_distance_mm: f64,
) -> Result<(), DesignError> {
    for (i, p) in points.iter().enumerate() {
        if !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()) {
            return Err(DesignError::SuturePoints(format!("point {} has a non-finite coordinate", i + 1)));
        }
        let hit = bvh
            .closest_point(surface, *p)
            .ok_or_else(|| DesignError::Surface("the surface has no triangles".into()))?;
        if hit.distance_mm > max_point_distance_mm {
            return Err(DesignError::SuturePoints(format!(
                "point {} ({:.2}, {:.2}, {:.2}) is {:.2} mm from the surface (limit {:.2} mm); \
                 is it in the same coordinate frame (LPS/RAS) as the surface?",
                i + 1,
                p.x,
                p.y,
                p.z,
                hit.distance_mm,
                max_point_distance_mm
            )));
        }
        let label = surface.face_ids[hit.triangle as usize];
        if label != labels.wall {
            return Err(DesignError::SuturePoints(format!(
                "point {} lies on the {} (label {label}), not on the RV wall",
                i + 1,
                cap_name(labels, label)
            )));
        }
    }
    Ok(())
}

fn cap_name(labels: &FaceLabels, label: i32) -> &'static str {
    if label == labels.vsd_cap {
        "VSD cap"
    } else if label == labels.aortic_cap {
        "aortic-annulus cap"
    } else {
        "surface region"
    }
}

/// Insert the projected seam into the surface as an exact, simple edge loop.
pub fn imprint_seam(surface: &TriMesh, seam: &ProjectedSeam, labels: &FaceLabels) -> Result<ImprintedSeam, DesignError> {
    let snap_mm = 1e-3 * surface.mean_edge_length_mm();
    let mut edit = EditMesh::new(surface);
    let n = seam.samples_mm.len();
    let mut loop_vertices: Vec<u32> = Vec::with_capacity(2 * n);
    let mut seam_so_far = SeamSoFar::default();
    let first = edit.insert_point(seam.sample_triangles[0], seam.samples_mm[0], snap_mm);
    let mut current = first;
    seam_so_far.push(&mut loop_vertices, current, 0)?;
    for i in 1..=n {
        let target = if i == n { first } else { edit.insert_point(seam.sample_triangles[i], seam.samples_mm[i], snap_mm) };
        let path = edit.walk(current, target, snap_mm, labels, &seam_so_far, i)?;
        for v in path {
            if i == n && v == first {
                break;
            }
            seam_so_far.push(&mut loop_vertices, v, i)?;
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
    fn push(&mut self, lp: &mut Vec<u32>, v: u32, sample: usize) -> Result<(), DesignError> {
        if lp.last() == Some(&v) {
            return Ok(());
        }
        if !self.vertices.insert(v) {
            return Err(crossing_itself(sample));
        }
        if let Some(&prev) = lp.last() {
            self.edges.insert(edge_key(prev, v));
        }
        lp.push(v);
        Ok(())
    }
}

fn untraceable(sample: usize) -> DesignError {
    DesignError::Seam(format!("could not trace the seam on the surface near sample {sample}"))
}

fn crossing_itself(sample: usize) -> DesignError {
    DesignError::Seam(format!("the seam crosses itself near sample {sample}; check the order of the suture points"))
}

/// A triangle mesh that supports edge and face splits, remembering which original
/// triangle each current triangle came from (all pieces stay in its plane).
struct EditMesh {
    points: Vec<Vec3>,
    tris: Vec<[u32; 3]>,
    labels: Vec<i32>,
    vert_tris: Vec<Vec<u32>>,
    origin: Vec<u32>,
    children: Vec<Vec<u32>>,
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
        EditMesh {
            points: mesh.points.clone(),
            tris: mesh.triangles.clone(),
            labels: mesh.face_ids.clone(),
            vert_tris,
            origin: (0..mesh.triangles.len() as u32).collect(),
            children: (0..mesh.triangles.len() as u32).map(|t| vec![t]).collect(),
        }
    }

    fn into_mesh(self) -> TriMesh {
        TriMesh::new(self.points, self.tris, self.labels)
    }

    fn add_triangle(&mut self, tri: [u32; 3], label: i32, origin: u32) -> u32 {
        let t = self.tris.len() as u32;
        self.tris.push(tri);
        self.labels.push(label);
        self.origin.push(origin);
        self.children[origin as usize].push(t);
        for &v in &tri {
            self.vert_tris[v as usize].push(t);
        }
        t
    }

    fn add_point(&mut self, p: Vec3) -> u32 {
        self.points.push(p);
        self.vert_tris.push(Vec::new());
        (self.points.len() - 1) as u32
    }

    /// Insert `p` (lying on original triangle `orig`) as a vertex: snap to a close
    /// vertex, split a close edge, or split the containing face.
    fn insert_point(&mut self, orig: u32, p: Vec3, snap_mm: f64) -> u32 {
        let t = self.containing_child(orig, p);
        let tri = self.tris[t as usize];
        let corners = tri.map(|v| self.points[v as usize]);
        if let Some(k) = (0..3).find(|&k| (corners[k] - p).norm() <= snap_mm) {
            return tri[k];
        }
        for k in 0..3 {
            let (a, b) = (corners[k], corners[(k + 1) % 3]);
            let foot = closest_point_on_segment(&p, &a, &b).0;
            if (foot - p).norm() <= snap_mm {
                return self.split_edge(tri[k], tri[(k + 1) % 3], foot);
            }
        }
        self.split_face(t, p)
    }

    /// The current piece of original triangle `orig` that contains `p` (the one
    /// whose smallest barycentric coordinate is largest, which is robust on edges).
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
        let w = self.add_point(p);
        let users: Vec<u32> = self.vert_tris[a as usize]
            .iter()
            .copied()
            .filter(|t| self.tris[*t as usize].contains(&b))
            .collect();
        for t in users {
            let tri = self.tris[t as usize];
            // Rotate so the edge is (tri[k], tri[k+1]) in the triangle's own order.
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

    fn has_edge(&self, a: u32, b: u32) -> bool {
        self.vert_tris[a as usize].iter().any(|&t| self.tris[t as usize].contains(&b))
    }

    fn vertex_normal(&self, v: u32) -> Vec3 {
        let mut n = Vec3::zeros();
        for &t in &self.vert_tris[v as usize] {
            let [a, b, c] = self.tris[t as usize].map(|x| self.points[x as usize]);
            n += (b - a).cross(&(c - a));
        }
        n
    }

    /// Walk on the surface from vertex `from` to vertex `to` along the cut of the
    /// plane through both that contains the mean surface normal, splitting every edge
    /// it crosses. Returns the vertices after `from`, ending with `to`.
    fn walk(
        &mut self,
        from: u32,
        to: u32,
        snap_mm: f64,
        labels: &FaceLabels,
        seam_so_far: &SeamSoFar,
        sample: usize,
    ) -> Result<Vec<u32>, DesignError> {
        let mut path = Vec::new();
        let mut current = from;
        let normal = self.vertex_normal(from) + self.vertex_normal(to);
        for _ in 0..10_000 {
            if current == to {
                return Ok(path);
            }
            if self.has_edge(current, to) {
                path.push(to);
                return Ok(path);
            }
            let crossing = match self.next_crossing(current, to, normal, snap_mm, labels, sample)? {
                Some(crossing) => crossing,
                None => self.nearest_link_point(current, to, snap_mm, labels).ok_or_else(|| untraceable(sample))?,
            };
            let next = match crossing {
                Crossing::Vertex(v) => v,
                Crossing::Edge(a, b, p) => {
                    if seam_so_far.edges.contains(&edge_key(a, b)) {
                        return Err(crossing_itself(sample));
                    }
                    self.split_edge(a, b, p)
                }
            };
            if seam_so_far.vertices.contains(&next) && next != to {
                return Err(crossing_itself(sample));
            }
            path.push(next);
            current = next;
        }
        Err(untraceable(sample))
    }

    /// Fallback where the cutting plane finds no way forward (the chord to the next
    /// sample runs along the surface normal across a crease): step to the point of
    /// the wall triangles' opposite edges around `c` nearest the target, if it is
    /// nearer than `c`. The seam stays within the distance between the two samples
    /// of the projected curve.
    fn nearest_link_point(&self, c: u32, to: u32, snap_mm: f64, labels: &FaceLabels) -> Option<Crossing> {
        let target = self.points[to as usize];
        let here = (self.points[c as usize] - target).norm();
        let mut best: Option<(f64, Crossing)> = None;
        for &t in &self.vert_tris[c as usize] {
            if self.labels[t as usize] != labels.wall {
                continue;
            }
            let tri = self.tris[t as usize];
            let k = (0..3).find(|&k| tri[k] == c).unwrap_or(0);
            let (a, b) = (tri[(k + 1) % 3], tri[(k + 2) % 3]);
            let (pa, pb) = (self.points[a as usize], self.points[b as usize]);
            let x = closest_point_on_segment(&target, &pa, &pb).0;
            let d = (x - target).norm();
            if d >= here || best.as_ref().is_some_and(|(bd, _)| *bd <= d) {
                continue;
            }
            let crossing = if (x - pa).norm() <= snap_mm {
                Crossing::Vertex(a)
            } else if (x - pb).norm() <= snap_mm {
                Crossing::Vertex(b)
            } else {
                Crossing::Edge(a, b, x)
            };
            best = Some((d, crossing));
        }
        best.map(|(_, c)| c)
    }

    /// Among the triangles around `c`, the opposite edge (or vertex) that the cutting
    /// plane crosses in the direction of `to`, best aligned with that direction.
    fn next_crossing(
        &self,
        c: u32,
        to: u32,
        normal: Vec3,
        snap_mm: f64,
        labels: &FaceLabels,
        sample: usize,
    ) -> Result<Option<Crossing>, DesignError> {
        let pc = self.points[c as usize];
        let dir = self.points[to as usize] - pc;
        let plane_normal = dir.cross(&normal);
        let plane_normal = if plane_normal.norm() > 0.0 { plane_normal.normalize() } else { plane_normal };
        let mut best: Option<(f64, Crossing, u32)> = None;
        let mut consider = |cos: f64, crossing: Crossing, t: u32| {
            if best.as_ref().map_or(true, |b| cos > b.0) {
                best = Some((cos, crossing, t));
            }
        };
        for &t in &self.vert_tris[c as usize] {
            let tri = self.tris[t as usize];
            let k = (0..3).find(|&k| tri[k] == c).unwrap_or(0);
            let (a, b) = (tri[(k + 1) % 3], tri[(k + 2) % 3]);
            let (pa, pb) = (self.points[a as usize], self.points[b as usize]);
            let (da, db) = (plane_normal.dot(&(pa - pc)), plane_normal.dot(&(pb - pc)));
            if da * db > 0.0 {
                continue;
            }
            let x = if da == db { pa } else { pa + (pb - pa) * (da / (da - db)) };
            let cos = (x - pc).dot(&dir) / ((x - pc).norm() * dir.norm()).max(1e-300);
            if cos <= 0.0 {
                continue;
            }
            if (x - pa).norm() <= snap_mm {
                consider(cos, Crossing::Vertex(a), t);
            } else if (x - pb).norm() <= snap_mm {
                consider(cos, Crossing::Vertex(b), t);
            } else {
                consider(cos, Crossing::Edge(a, b, x), t);
            }
        }
        let Some((_, crossing, t)) = best else { return Ok(None) };
        let label = self.labels[t as usize];
        if label != labels.wall {
            return Err(DesignError::Seam(format!(
                "the seam crosses the {} (label {label}) near sample {sample}; move the suture points \
                 near it away from the cap rim",
                cap_name(labels, label)
            )));
        }
        Ok(Some(crossing))
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::manifold_report;

    /// A closed box [0,4]^3 made of small right triangles, all labelled wall.
    fn grid_box(n: usize) -> TriMesh {
        let mut m = TriMesh::default();
        let s = 4.0 / n as f64;
        // Six faces, each an (n+1)^2 grid; duplicates merged by a coordinate map.
        let mut index = std::collections::HashMap::new();
        let mut vid = |m: &mut TriMesh, p: Vec3| -> u32 {
            let key = ((p.x * 1e6).round() as i64, (p.y * 1e6).round() as i64, (p.z * 1e6).round() as i64);
            *index.entry(key).or_insert_with(|| {
                m.points.push(p);
                (m.points.len() - 1) as u32
            })
        };
        let faces: [(Vec3, Vec3, Vec3); 6] = [
            (Vec3::new(0., 0., 0.), Vec3::new(0., 1., 0.), Vec3::new(1., 0., 0.)),
            (Vec3::new(0., 0., 4.), Vec3::new(1., 0., 0.), Vec3::new(0., 1., 0.)),
            (Vec3::new(0., 0., 0.), Vec3::new(1., 0., 0.), Vec3::new(0., 0., 1.)),
            (Vec3::new(0., 4., 0.), Vec3::new(0., 0., 1.), Vec3::new(1., 0., 0.)),
            (Vec3::new(0., 0., 0.), Vec3::new(0., 0., 1.), Vec3::new(0., 1., 0.)),
            (Vec3::new(4., 0., 0.), Vec3::new(0., 1., 0.), Vec3::new(0., 0., 1.)),
        ];
        for (o, u, v) in faces {
            for i in 0..n {
                for j in 0..n {
                    let p = |a: usize, b: usize| o + u * (a as f64 * s) + v * (b as f64 * s);
                    let q = [p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1)].map(|x| vid(&mut m, x));
                    m.triangles.push([q[0], q[1], q[2]]);
                    m.triangles.push([q[0], q[2], q[3]]);
                }
            }
        }
        m.face_ids = vec![2; m.triangles.len()];
        m
    }

    #[test]
    fn seam_on_a_box_face_is_an_exact_edge_loop() {
        let mesh = grid_box(8);
        assert!(manifold_report(&mesh).is_closed_manifold());
        let bvh = TriangleBvh::new(&mesh).unwrap();
        let labels = FaceLabels::default();
        // A loop on the top face z = 4 around (2, 2).
        let pts: Vec<Vec3> = (0..12)
            .map(|k| {
                let a = k as f64 / 12.0 * std::f64::consts::TAU;
                Vec3::new(2.0 + 1.3 * a.cos(), 2.0 + 1.1 * a.sin(), 4.0)
            })
            .collect();
        let seam = project_seam(&mesh, &bvh, &labels, &pts, 200, 2.0).unwrap();
        let imprinted = imprint_seam(&mesh, &seam, &labels).unwrap();
        let rep = manifold_report(&imprinted.mesh);
        assert!(rep.is_closed_manifold(), "{rep:?}");
        assert_eq!(rep.inconsistently_wound_edges, 0);
        assert!((imprinted.mesh.signed_volume_mm3() - mesh.signed_volume_mm3()).abs() < 1e-9);
        // Consecutive loop vertices are joined by mesh edges, and the loop is simple.
        let edges = imprinted.mesh.edge_triangles();
        let lp = &imprinted.loop_vertices;
        for i in 0..lp.len() {
            let e = edge_key(lp[i], lp[(i + 1) % lp.len()]);
            assert_eq!(edges.get(&e).map(|v| v.len()), Some(2), "seam edge {e:?} missing");
        }
        let distinct: HashSet<u32> = lp.iter().copied().collect();
        assert_eq!(distinct.len(), lp.len());
        // Every seam vertex is on the top face.
        for &v in lp {
            assert!((imprinted.mesh.points[v as usize].z - 4.0).abs() < 1e-12);
        }
    }

    #[test]
    fn seam_over_a_box_edge_is_traced() {
        let mesh = grid_box(8);
        let bvh = TriangleBvh::new(&mesh).unwrap();
        let labels = FaceLabels::default();
        // A loop that wraps over the edge between the top (z=4) and the side x=4.
        let pts: Vec<Vec3> = (0..14)
            .map(|k| {
                let a = k as f64 / 14.0 * std::f64::consts::TAU;
                let (s, t) = (1.5 * a.cos(), 1.2 * a.sin());
                // Unfold: s>0 goes down the side x=4, s<0 stays on top.
                if s >= 0.0 {
                    Vec3::new(4.0, 2.0 + t, 4.0 - s)
                } else {
                    Vec3::new(4.0 + s, 2.0 + t, 4.0)
                }
            })
            .collect();
        let seam = project_seam(&mesh, &bvh, &labels, &pts, 300, 2.0).unwrap();
        let imprinted = imprint_seam(&mesh, &seam, &labels).unwrap();
        assert!(manifold_report(&imprinted.mesh).is_closed_manifold());
        assert!(imprinted.loop_vertices.len() >= 300);
    }

    #[test]
    fn a_seam_that_crosses_itself_is_rejected() {
        // A figure eight on the top face, inserted without the angle ordering.
        let mesh = grid_box(8);
        let bvh = TriangleBvh::new(&mesh).unwrap();
        let samples_mm: Vec<Vec3> = (0..200)
            .map(|k| {
                let a = k as f64 / 200.0 * std::f64::consts::TAU;
                Vec3::new(2.0 + 1.5 * a.sin(), 2.0 + 1.2 * a.sin() * a.cos(), 4.0)
            })
            .collect();
        let sample_triangles = samples_mm.iter().map(|p| bvh.closest_point(&mesh, *p).unwrap().triangle).collect();
        let seam = ProjectedSeam { ordered_points_mm: Vec::new(), samples_mm, sample_triangles };
        let err = imprint_seam(&mesh, &seam, &FaceLabels::default()).unwrap_err();
        assert!(err.to_string().contains("crosses itself"), "{err}");
    }

    #[test]
    fn too_few_or_far_points_are_named() {
        let mesh = grid_box(4);
        let bvh = TriangleBvh::new(&mesh).unwrap();
        let labels = FaceLabels::default();
        let three = vec![Vec3::new(1., 1., 4.), Vec3::new(2., 1., 4.), Vec3::new(2., 2., 4.)];
        let e = project_seam(&mesh, &bvh, &labels, &three, 100, 2.0).unwrap_err();
        assert!(e.to_string().contains("at least 4"), "{e}");
        let mut far = three.clone();
        far.push(Vec3::new(1., 2., 7.5));
        let e = project_seam(&mesh, &bvh, &labels, &far, 100, 2.0).unwrap_err();
        assert!(e.to_string().contains("point 4") && e.to_string().contains("3.50 mm"), "{e}");
    }

    #[test]
    fn seam_across_a_cap_is_rejected() {
        let mut mesh = grid_box(8);
        // Label the triangles of the top face with x in [1.5, 2.5] as a cap.
        for t in 0..mesh.triangles.len() {
            let [a, b, c] = mesh.triangle_points(t);
            let cen = (a + b + c) / 3.0;
            if (cen.z - 4.0).abs() < 1e-9 && (cen.x - 2.0).abs() < 0.5 {
                mesh.face_ids[t] = 11;
            }
        }
        let bvh = TriangleBvh::new(&mesh).unwrap();
        let pts: Vec<Vec3> = (0..12)
            .map(|k| {
                let a = k as f64 / 12.0 * std::f64::consts::TAU;
                Vec3::new(2.0 + 1.5 * a.cos(), 2.0 + 1.5 * a.sin(), 4.0)
            })
            .collect();
        let labels = FaceLabels::default();
        let err = project_seam(&mesh, &bvh, &labels, &pts, 200, 2.0)
            .and_then(|s| imprint_seam(&mesh, &s, &labels).map(|_| ()))
            .unwrap_err();
        assert!(err.to_string().contains("VSD cap"), "{err}");
    }
}
