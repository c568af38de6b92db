//! Isotropic surface remeshing with preserved features (paper section 2.3.3),
//! after Botsch & Kobbelt, "A remeshing approach to multiresolution modeling" (2004).
//!
//! Each iteration splits long edges, collapses short ones, flips edges toward
//! valence 6 (4 on the boundary), then smooths tangentially and projects back
//! onto the ORIGINAL surface (triangles of the vertex's own label).
//!
//! Features are boundary edges (the seam) and label-boundary edges (cap rims).
//! Feature edges are never flipped, feature vertices never smoothed, and
//! collapses only run along a feature line or pull a free vertex onto one, so
//! the seam keeps bit-identical input coordinates and no triangle spans a rim.

mod grading;
mod halfedge;
mod projection;
#[cfg(test)]
mod tests;

use crate::geometry::mesh::{area_centroid_normal, TriMesh, Vec3};
use halfedge::{face_of, next, prev, HalfEdgeMesh, NONE};
use projection::{feature_key, FeatureKey, FeaturePolylines, SurfaceProjector};
pub use grading::{SizeGrading, MAX_GROWTH};

#[derive(Clone, Debug, PartialEq)]
pub struct RemeshOptions {
    /// Target edge length L (mm); the paper uses 0.85 mm.
    pub target_edge_mm: f64,
    /// Split/collapse/flip/smooth rounds at the target (after the rounds that approach it
    /// from a much coarser input, see `approach_targets_mm`).
    pub iterations: usize,
    /// Allow splitting boundary (seam) edges; off keeps every boundary vertex an input vertex.
    pub split_boundary: bool,
    /// Never split slivers (height below [`SLIVER_HEIGHT_REL`] of their longest edge, at
    /// any target) and skip a smoothing move that turns a face over: what refining a
    /// finished domain far below its own edge needs (extend's mesh-study levels, the
    /// synthetic heart's design at 0.42-0.3 mm, p2's at 0.6 mm). Off, the design's remesh
    /// of the seam-imprinted wall runs as it was validated (the p1-p3 drag family: with the
    /// guards, three p3 drags no longer designed).
    pub guard_slivers: bool,
    /// A target edge growing away from a disc (`None`: `target_edge_mm` everywhere, the
    /// isotropic remesh); `target_edge_mm` is then the smallest edge.
    pub grading: Option<SizeGrading>,
}

impl Default for RemeshOptions {
    fn default() -> Self {
        RemeshOptions { target_edge_mm: 0.85, iterations: 5, split_boundary: false, guard_slivers: false, grading: None }
    }
}

/// Remesh `mesh` isotropically at `opts.target_edge_mm` (or at the edge of its
/// `grading`, growing from there), keeping boundary and label-boundary edges as features. Errors name the offending point, triangle or edge.
pub fn remesh_isotropic(mesh: &TriMesh, opts: &RemeshOptions) -> Result<TriMesh, String> {
    validate_input(mesh, opts)?;
    let budget = TriangleBudget::new(mesh, opts.target_edge_mm)?;
    let mut remesher = Remesher::new(mesh, opts)?;
    let approach = approach_targets_mm(mesh.mean_edge_length_mm(), opts.target_edge_mm);
    let rounds = approach.iter().copied().chain(std::iter::repeat_n(opts.target_edge_mm, opts.iterations));
    for target_mm in rounds {
        remesher.target_mm = target_mm;
        remesher.split_long_edges(&budget).map_err(|e| where_it_crosses_itself(mesh).map_or(e, |c| format!("{c}: splitting long edges cannot converge on it")))?;
        remesher.collapse_short_edges();
        remesher.flip_toward_regular_valence();
        remesher.smooth_tangentially();
    }
    Ok(remesher.mesh.to_trimesh())
}

/// The targets of the rounds that come before those at `target_mm`, coarsest first: twice,
/// four times ... the target, until one midpoint split of the input's mean edge reaches the
/// next. A split pass halves an edge until it is below 4/3 of the target, splitting every
/// new inner edge too; needing more than one halving, it overshoots the isotropic count by
/// far more than the rounding its budget allows (p3's 0.85 mm domain split for 0.26 mm:
/// 5.1 times it before the first collapse), so far below the input's edge the remesh is
/// approached in halvings (each round still projects onto the input).
fn approach_targets_mm(input_mean_edge_mm: f64, target_mm: f64) -> Vec<f64> {
    let one_halving = |t: f64| 2.0 * 4.0 / 3.0 * t;
    let mut targets = Vec::new();
    let mut t = target_mm;
    while input_mean_edge_mm > one_halving(t) && targets.len() < 16 {
        t *= 2.0;
        targets.push(t);
    }
    targets.reverse();
    targets
}

/// Where `mesh` crosses itself, said: a surface through itself has no isotropic remesh
/// (the projection onto it runs between the sheets, and splitting does not converge),
/// so a remesh that fails names the crossing, if there is one, rather than the split.
/// Asked of every closed input before remeshing (a closed surface is a whole domain a
/// user gave), and of an open one only on failure (the test costs about a remesh round).
pub fn where_it_crosses_itself(mesh: &TriMesh) -> Option<String> {
    let bvh = crate::geometry::spatial::TriangleBvh::new(mesh).ok()?;
    let crossings = bvh.self_intersections_par(mesh, |_, _| true);
    let &(a, b) = crossings.first()?;
    let c = mesh.triangle_centroid(a as usize);
    Some(format!(
        "the surface crosses itself near ({:.2}, {:.2}, {:.2}) mm (triangles {a} and {b}, {} crossing pairs in all)",
        c.x, c.y, c.z, crossings.len()
    ))
}

fn validate_input(mesh: &TriMesh, opts: &RemeshOptions) -> Result<(), String> {
    if !(opts.target_edge_mm.is_finite() && opts.target_edge_mm > 0.0) {
        return Err(format!("target edge length must be a positive number of mm, got {}", opts.target_edge_mm));
    }
    if let Some(grading) = &opts.grading {
        grading.validate(opts.target_edge_mm)?;
    }
    if mesh.triangles.is_empty() {
        return Err("mesh has no triangles".into());
    }
    if mesh.face_ids.len() != mesh.triangles.len() {
        return Err(format!(
            "mesh has {} face ids for {} triangles",
            mesh.face_ids.len(),
            mesh.triangles.len()
        ));
    }
    if let Some((i, p)) = mesh.points.iter().enumerate().find(|(_, p)| !p.iter().all(|c| c.is_finite())) {
        return Err(format!("point {i} has a non-finite coordinate ({}, {}, {})", p.x, p.y, p.z));
    }
    let n = mesh.points.len() as u32;
    for (t, &[a, b, c]) in mesh.triangles.iter().enumerate() {
        if a >= n || b >= n || c >= n {
            return Err(format!("triangle {t} refers to a point beyond the {n} points"));
        }
        if a == b || b == c || a == c {
            return Err(format!("triangle {t} repeats a point ({a}, {b}, {c})"));
        }
    }
    if crate::geometry::mesh::manifold_report(mesh).is_closed_manifold() {
        if let Some(crossing) = where_it_crosses_itself(mesh) {
            return Err(format!("{crossing}: it has no remesh; repair it there"));
        }
    }
    Ok(())
}

/// Most triangles a remesh may need (about 100 MB of half-edge mesh, 4 times that
/// while splitting): a design never needs more, and a tiny target edge must be
/// refused up front, not run out of memory.
pub const MAX_REMESH_TRIANGLES: usize = 2_000_000;

/// The work bound of one remesh: an isotropic mesh of the input's area at the target
/// edge has A / (sqrt(3)/4 L^2) triangles; splitting may overshoot that by the
/// rounding at short features, so allow a few times it (and the input's own count).
struct TriangleBudget {
    max_triangles: usize,
    area_mm2: f64,
    target_edge_mm: f64,
}

impl TriangleBudget {
    fn new(mesh: &TriMesh, target_edge_mm: f64) -> Result<Self, String> {
        let area_mm2 = mesh.area_mm2();
        let isotropic = area_mm2 / (3f64.sqrt() / 4.0 * target_edge_mm * target_edge_mm);
        let needed = isotropic + mesh.triangles.len() as f64;
        if needed > MAX_REMESH_TRIANGLES as f64 {
            return Err(format!(
                "the remesher would need more than {MAX_REMESH_TRIANGLES} triangles (about {needed:.0} for {area_mm2:.1} mm2 \
                 at a target edge of {target_edge_mm} mm); use a longer edge"
            ));
        }
        let max_triangles = (4.0 * needed) as usize + 1024;
        Ok(TriangleBudget { max_triangles, area_mm2, target_edge_mm })
    }

    /// A named error when `triangles` exceeds the budget; `near` is where the remesher was working.
    fn check(&self, triangles: usize, near: Vec3) -> Result<(), String> {
        if triangles <= self.max_triangles {
            return Ok(());
        }
        Err(format!(
            "the remesher would need more than {} triangles ({:.1} mm2 at a target edge of {} mm) and stopped: \
             splitting long edges does not converge near ({:.2}, {:.2}, {:.2}) mm",
            self.max_triangles, self.area_mm2, self.target_edge_mm, near.x, near.y, near.z
        ))
    }
}

/// Largest allowed normal change of a triangle moved by a collapse, and largest
/// dihedral a flip may create (cos 60 deg).
const MIN_NORMAL_COS: f64 = 0.5;
/// Triangles with |normal| = 2 x area below this fraction of L^2 count as degenerate.
const DEGENERATE_NORMAL_REL: f64 = 1e-4;
/// A triangle whose height over its longest edge is below this is a sliver at any target
/// edge (1 um on a 1 mm edge): splitting it only makes more slivers, and the midpoints of
/// its two long edges land within microns of each other, which the crossing test then
/// finds as the surface through itself (the synthetic heart's baffle at 0.35 mm and
/// below, where the L^2-relative bound above no longer called its slivers flat).
pub const SLIVER_HEIGHT_REL: f64 = 1e-3;

struct Remesher {
    mesh: HalfEdgeMesh,
    target_mm: f64,
    grading: Option<SizeGrading>,
    split_boundary: bool,
    guard_slivers: bool,
    projector: SurfaceProjector,
    polylines: FeaturePolylines,
    /// Feature edges at each vertex: 0 free, 2 on a feature line, else a locked corner.
    feature_edges: Vec<u8>,
    ring: Vec<u32>,
    ring2: Vec<u32>,
    nbrs_a: Vec<u32>,
    nbrs_b: Vec<u32>,
}

impl Remesher {
    fn new(mesh: &TriMesh, opts: &RemeshOptions) -> Result<Self, String> {
        let he = HalfEdgeMesh::from_trimesh(mesh)?;
        let polylines = FeaturePolylines::new(feature_segments(&he));
        let mut remesher = Remesher {
            projector: SurfaceProjector::new(mesh, opts.target_edge_mm),
            polylines,
            mesh: he,
            target_mm: opts.target_edge_mm,
            grading: opts.grading,
            split_boundary: opts.split_boundary,
            guard_slivers: opts.guard_slivers,
            feature_edges: Vec::new(),
            ring: Vec::new(),
            ring2: Vec::new(),
            nbrs_a: Vec::new(),
            nbrs_b: Vec::new(),
        };
        remesher.count_feature_edges();
        remesher.check_boundary_resolvable()?;
        Ok(remesher)
    }

    /// A boundary edge that may not be split and is longer than twice the longest
    /// allowed edge can never be resolved: every split of its triangle leaves a new
    /// apex nearer to it, one of whose edges to its ends stays longer than 4/3 L, so
    /// splitting would go on until memory runs out.
    fn check_boundary_resolvable(&self) -> Result<(), String> {
        if self.split_boundary {
            return Ok(());
        }
        let limit_sq = 4.0 * self.high_sq();
        let m = &self.mesh;
        match live_halfedges(m).find(|&h| m.is_boundary_edge(h) && m.edge_length_sq(h) > limit_sq) {
            None => Ok(()),
            Some(h) => {
                let [a, b] = [m.origin(h), m.target(h)].map(|v| m.pos[v as usize]);
                Err(format!(
                    "the boundary (seam) edge from ({:.2}, {:.2}, {:.2}) to ({:.2}, {:.2}, {:.2}) mm is {:.2} mm long; \
                     with the seam kept, the remesher resolves at most {:.2} mm (8/3 of the {} mm target edge)",
                    a.x, a.y, a.z, b.x, b.y, b.z, (b - a).norm(), limit_sq.sqrt(), self.target_mm
                ))
            }
        }
    }

    /// The target edge (mm) between `a` and `b`: at their midpoint.
    fn target_between(&self, a: &Vec3, b: &Vec3) -> f64 {
        match &self.grading {
            None => self.target_mm,
            Some(g) => g.edge_mm(self.target_mm, &(0.5 * (a + b))),
        }
    }

    /// Split above 4/3 of the target (squared), at the smallest target.
    fn high_sq(&self) -> f64 {
        (4.0 / 3.0 * self.target_mm).powi(2)
    }

    /// Whether the edge of `h` is longer than 4/3 of its target.
    fn is_long(&self, h: u32) -> bool {
        let m = &self.mesh;
        let length_sq = m.edge_length_sq(h);
        length_sq > self.high_sq() && {
            let target = self.target_between(&m.pos[m.origin(h) as usize], &m.pos[m.target(h) as usize]);
            length_sq > (4.0 / 3.0 * target).powi(2)
        }
    }

    /// Whether the edge of `h` is shorter than 4/5 of its target.
    fn is_short(&self, h: u32) -> bool {
        let m = &self.mesh;
        let target = self.target_between(&m.pos[m.origin(h) as usize], &m.pos[m.target(h) as usize]);
        m.edge_length_sq(h) < (0.8 * target).powi(2)
    }

    fn min_normal_len(&self) -> f64 {
        DEGENERATE_NORMAL_REL * self.target_mm * self.target_mm
    }

    /// Recount feature edges per vertex (each edge once).
    fn count_feature_edges(&mut self) {
        let m = &self.mesh;
        let mut count = vec![0u8; m.pos.len()];
        for h in live_halfedges(m) {
            let t = m.twin[h as usize];
            if (t == NONE || h < t) && m.is_feature_edge(h) {
                for v in [m.origin(h), m.target(h)] {
                    count[v as usize] = count[v as usize].saturating_add(1);
                }
            }
        }
        self.feature_edges = count;
    }

    fn is_free(&self, v: u32) -> bool {
        self.feature_edges[v as usize] == 0
    }

    // ---- split -------------------------------------------------------------

    fn split_long_edges(&mut self, budget: &TriangleBudget) -> Result<(), String> {
        loop {
            // Splitting only appends faces; collapses of earlier rounds left dead ones in
            // the arrays, which the budget must not count (at 0.33 mm on the synthetic
            // heart they were most of the 58k "triangles" a converging split was refused at).
            let dead = self.mesh.face_alive.iter().filter(|&&alive| !alive).count();
            let mut splits = 0;
            let mut f = 0;
            // New faces are appended, so this also visits the halves of split edges.
            while f < self.mesh.corners.len() {
                for k in 0..3 {
                    let h = (3 * f + k) as u32;
                    if self.mesh.face_alive[f] && self.is_long(h) && self.may_split(h) {
                        self.split(h);
                        splits += 1;
                    }
                }
                f += 1;
                budget.check(self.mesh.corners.len() - dead, self.mesh.pos[self.mesh.corners[f - 1][0] as usize])?;
            }
            if splits == 0 {
                return Ok(());
            }
        }
    }

    /// Flat triangles (the ear-clipped slivers where the seam was imprinted, and
    /// whatever a bump of the wall stretches out of them; 2 x area below 1e-4 L^2, or with
    /// `guard_slivers` height below 1e-3 of the longest edge) are never split: a flat
    /// triangle has no area for the split to converge on, and splitting it at
    /// midpoints only makes more flat triangles (a 3.7 mm bump on p2 grew 40,000 of
    /// them before running out of memory). Collapses and flips remove them instead.
    fn may_split(&self, h: u32) -> bool {
        let m = &self.mesh;
        let t = m.twin[h as usize];
        let flat = |f: usize| {
            let twice_area = m.face_normal2(f).norm();
            twice_area < self.min_normal_len() || (self.guard_slivers && twice_area < SLIVER_HEIGHT_REL * m.longest_edge_sq(f))
        };
        (self.split_boundary || t != NONE) && !flat(face_of(h)) && (t == NONE || !flat(face_of(t)))
    }

    fn split(&mut self, h: u32) {
        let m = &self.mesh;
        let (a, b) = (m.origin(h), m.target(h));
        let midpoint = 0.5 * (m.pos[a as usize] + m.pos[b as usize]);
        let is_feature = m.is_feature_edge(h);
        // A feature midpoint goes back onto the original rim/seam polyline.
        let p = if is_feature { self.polylines.project(midpoint, self.edge_feature_key(h)) } else { midpoint };
        let v = self.mesh.push_vertex(p);
        self.feature_edges.push(if is_feature { 2 } else { 0 });
        self.mesh.split_edge(h, v);
    }

    fn edge_feature_key(&self, h: u32) -> FeatureKey {
        let m = &self.mesh;
        let t = m.twin[h as usize];
        feature_key(m.label[face_of(h)], (t != NONE).then(|| m.label[face_of(t)]))
    }

    // ---- collapse ----------------------------------------------------------

    fn collapse_short_edges(&mut self) {
        self.count_feature_edges();
        for f in 0..self.mesh.corners.len() {
            for k in 0..3 {
                if !self.mesh.face_alive[f] {
                    break;
                }
                let h = (3 * f + k) as u32;
                if !self.is_short(h) {
                    continue;
                }
                let (a, b) = (self.mesh.origin(h), self.mesh.target(h));
                if self.may_collapse(h, a, b) {
                    self.mesh.collapse_edge(h, a, &mut self.ring);
                } else if self.may_collapse(h, b, a) {
                    self.mesh.collapse_edge(h, b, &mut self.ring);
                }
            }
        }
    }

    /// May `remove` (an end of the edge of `h`) merge into the other end `keep`?
    fn may_collapse(&mut self, h: u32, remove: u32, keep: u32) -> bool {
        if !self.respects_features(h, remove) || self.leaves_dangling_triangle(h) {
            return false;
        }
        self.load_rings(remove, keep);
        self.satisfies_link_condition(h) && self.keeps_geometry_sound(h, keep)
    }

    /// A free vertex may go anywhere; a feature-line vertex only along its own
    /// line (its edge `h` is then one of its two feature edges); corners never.
    fn respects_features(&self, h: u32, remove: u32) -> bool {
        match self.feature_edges[remove as usize] {
            0 => true,
            2 => self.mesh.is_feature_edge(h),
            _ => false,
        }
    }

    /// Collapsing an edge of a triangle whose other two edges are both on the
    /// boundary would leave a dangling edge.
    fn leaves_dangling_triangle(&self, h: u32) -> bool {
        let m = &self.mesh;
        let ear = |g: u32| m.is_boundary_edge(next(g)) && m.is_boundary_edge(prev(g));
        let t = m.twin[h as usize];
        ear(h) || (t != NONE && ear(t))
    }

    /// Fill `ring`/`nbrs_a` (outgoing half-edges, neighbours) of `remove` and
    /// `ring2`/`nbrs_b` of `keep`, for the collapse checks.
    fn load_rings(&mut self, remove: u32, keep: u32) {
        self.mesh.neighbours(remove, &mut self.ring, &mut self.nbrs_a);
        self.mesh.neighbours(keep, &mut self.ring2, &mut self.nbrs_b);
    }

    /// Manifold-preserving: the ends may share only the apexes of the edge's triangles.
    fn satisfies_link_condition(&self, h: u32) -> bool {
        let m = &self.mesh;
        let shared = self.nbrs_a.iter().filter(|v| self.nbrs_b.contains(v)).count();
        let apexes = if m.is_boundary_edge(h) { 1 } else { 2 };
        shared == apexes
    }

    /// After moving `remove` onto `keep`, no edge is longer than 4/3 L and no
    /// surviving triangle degenerates or turns by more than 60 degrees.
    /// Uses the rings of the removed vertex from `load_rings`.
    fn keeps_geometry_sound(&self, h: u32, keep: u32) -> bool {
        let m = &self.mesh;
        let p_keep = m.pos[keep as usize];
        let too_long = |x: &Vec3| (x - p_keep).norm_squared() > (4.0 / 3.0 * self.target_between(x, &p_keep)).powi(2);
        if self.nbrs_a.iter().any(|&x| x != keep && too_long(&m.pos[x as usize])) {
            return false;
        }
        let t = m.twin[h as usize];
        let removed = [face_of(h), if t == NONE { usize::MAX } else { face_of(t) }];
        let min_normal = self.min_normal_len();
        let vertex_normal: Vec3 = self.ring.iter().map(|&g| m.face_normal2(face_of(g))).sum();
        for &g in &self.ring {
            let f = face_of(g);
            if removed.contains(&f) {
                continue;
            }
            let old = m.face_normal2(f);
            let [x, y] = [m.target(g), m.target(next(g))].map(|v| m.pos[v as usize]);
            let new = (x - p_keep).cross(&(y - p_keep));
            let new_len = new.norm();
            if new_len < min_normal {
                return false;
            }
            // A sliver's own normal is noise; judge it against the vertex normal.
            let reference = if old.norm() < min_normal { vertex_normal } else { old };
            if new.dot(&reference) < MIN_NORMAL_COS * new_len * reference.norm() {
                return false;
            }
        }
        true
    }

    // ---- flip --------------------------------------------------------------

    fn flip_toward_regular_valence(&mut self) {
        let (mut valence, on_boundary) = self.valences();
        for f in 0..self.mesh.corners.len() {
            for k in 0..3 {
                let h = (3 * f + k) as u32;
                if !self.mesh.face_alive[f] {
                    break;
                }
                let t = self.mesh.twin[h as usize];
                if t == NONE || t < h || self.mesh.is_feature_edge(h) {
                    continue;
                }
                let quad = self.flip_quad(h);
                if self.flip_improves_valence(quad, &valence, &on_boundary) && self.may_flip(h, quad) {
                    self.mesh.flip_edge(h);
                    let [a, b, c, d] = quad.map(|v| v as usize);
                    valence[a] -= 1;
                    valence[b] -= 1;
                    valence[c] += 1;
                    valence[d] += 1;
                }
            }
        }
    }

    /// Edge ends a, b and apexes c (own side), d (twin side) of interior `h`.
    fn flip_quad(&self, h: u32) -> [u32; 4] {
        let m = &self.mesh;
        let t = m.twin[h as usize];
        [m.origin(h), m.target(h), m.target(next(h)), m.target(next(t))]
    }

    fn valences(&mut self) -> (Vec<i32>, Vec<bool>) {
        let m = &self.mesh;
        let mut valence = vec![0i32; m.pos.len()];
        let mut on_boundary = vec![false; m.pos.len()];
        for h in live_halfedges(m) {
            valence[m.origin(h) as usize] += 1;
            if m.is_boundary_edge(h) {
                // Seen from one side only: count it at the target too.
                valence[m.target(h) as usize] += 1;
                on_boundary[m.origin(h) as usize] = true;
                on_boundary[m.target(h) as usize] = true;
            }
        }
        (valence, on_boundary)
    }

    fn flip_improves_valence(&self, [a, b, c, d]: [u32; 4], valence: &[i32], on_boundary: &[bool]) -> bool {
        if c == d {
            return false;
        }
        let ideal = |v: u32| if on_boundary[v as usize] { 4 } else { 6 };
        let minimum = |v: u32| if on_boundary[v as usize] { 2 } else { 3 };
        let dev = |v: u32, delta: i32| (valence[v as usize] + delta - ideal(v)).abs();
        if valence[a as usize] - 1 < minimum(a) || valence[b as usize] - 1 < minimum(b) {
            return false;
        }
        let before = dev(a, 0) + dev(b, 0) + dev(c, 0) + dev(d, 0);
        let after = dev(a, -1) + dev(b, -1) + dev(c, 1) + dev(d, 1);
        after < before
    }

    /// The new edge c-d must not exist yet, and the new triangles must not fold.
    fn may_flip(&mut self, h: u32, [a, b, c, d]: [u32; 4]) -> bool {
        let m = &self.mesh;
        m.neighbours(c, &mut self.ring, &mut self.nbrs_a);
        if self.nbrs_a.contains(&d) {
            return false;
        }
        let p = |v: u32| m.pos[v as usize];
        let old = m.face_normal2(face_of(h)) + m.face_normal2(face_of(m.twin[h as usize]));
        let n1 = (p(d) - p(a)).cross(&(p(c) - p(a)));
        let n2 = (p(b) - p(d)).cross(&(p(c) - p(d)));
        let min_normal = self.min_normal_len();
        let (l1, l2) = (n1.norm(), n2.norm());
        l1 > min_normal
            && l2 > min_normal
            && n1.dot(&old) > 0.0
            && n2.dot(&old) > 0.0
            && n1.dot(&n2) >= MIN_NORMAL_COS * l1 * l2
    }

    // ---- smooth and project --------------------------------------------------

    /// Move each free vertex toward the area-weighted centroid of its triangles,
    /// within its tangent plane, then onto the original surface of its label.
    fn smooth_tangentially(&mut self) {
        self.count_feature_edges();
        let mut moves = Vec::with_capacity(self.mesh.pos.len());
        for v in 0..self.mesh.pos.len() as u32 {
            if self.mesh.vertex_alive[v as usize] && self.is_free(v) {
                if let Some(p) = self.smoothed_position(v) {
                    moves.push((v, p));
                }
            }
        }
        for (v, p) in moves {
            let label = self.mesh.label[face_of(self.mesh.out[v as usize])];
            let projected = self.projector.project(p, label).unwrap_or(p);
            if !self.guard_slivers || self.move_keeps_faces_oriented(v, projected) {
                self.mesh.pos[v as usize] = projected;
            }
        }
    }

    /// Whether moving `v` to `p` keeps every face around it facing the way it did: none
    /// turns against the vertex's normal, and none that had an area turns by more than
    /// 60 deg. Moves are applied one by one, so this holds against the neighbours' new
    /// positions too; without it, smoothing next to slivers folded the synthetic heart's
    /// baffle through itself at 0.3-0.35 mm (hundreds of crossing pairs after one round).
    fn move_keeps_faces_oriented(&mut self, v: u32, p: Vec3) -> bool {
        let m = &self.mesh;
        m.outgoing(v, &mut self.ring);
        let vertex_normal: Vec3 = self.ring.iter().map(|&g| m.face_normal2(face_of(g))).sum();
        let min_normal = self.min_normal_len();
        self.ring.iter().all(|&g| {
            let f = face_of(g);
            let old = m.face_normal2(f);
            let [a, b, c] = m.corners[f].map(|x| if x == v { p } else { m.pos[x as usize] });
            let new = (b - a).cross(&(c - a));
            let turned = old.norm() >= min_normal && new.dot(&old) < MIN_NORMAL_COS * new.norm() * old.norm();
            new.dot(&vertex_normal) > 0.0 && !turned
        })
    }

    fn smoothed_position(&mut self, v: u32) -> Option<Vec3> {
        let m = &self.mesh;
        m.outgoing(v, &mut self.ring);
        let ring = self.ring.iter().map(|&g| m.corners[face_of(g)].map(|x| m.pos[x as usize]));
        let (area, centroid, normal) = area_centroid_normal(ring);
        let normal_len = normal.norm();
        if area <= 0.0 || normal_len <= 0.0 {
            return None;
        }
        let (p, n) = (m.pos[v as usize], normal / normal_len);
        let shift = centroid - p;
        Some(p + shift - n * n.dot(&shift))
    }
}

/// Half-edges of live faces.
fn live_halfedges(m: &HalfEdgeMesh) -> impl Iterator<Item = u32> + '_ {
    (0..m.corners.len()).filter(|&f| m.face_alive[f]).flat_map(|f| (0..3).map(move |k| (3 * f + k) as u32))
}

/// The input's feature edges as segments keyed by their feature line.
fn feature_segments(m: &HalfEdgeMesh) -> Vec<(Vec3, Vec3, FeatureKey)> {
    live_halfedges(m)
        .filter(|&h| {
            let t = m.twin[h as usize];
            (t == NONE || h < t) && m.is_feature_edge(h)
        })
        .map(|h| {
            let t = m.twin[h as usize];
            let key = feature_key(m.label[face_of(h)], (t != NONE).then(|| m.label[face_of(t)]));
            (m.pos[m.origin(h) as usize], m.pos[m.target(h) as usize], key)
        })
        .collect()
}
