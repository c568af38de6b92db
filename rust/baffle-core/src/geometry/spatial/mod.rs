//! Spatial queries on triangle meshes: an AABB tree over the triangles for
//! closest-point, ray, box and triangle-triangle intersection queries.
//!
//! The tree stores triangle indices only; every query takes the mesh it was built
//! from (same triangles, same point positions: rebuild after moving points).

mod primitives;
mod tri_tri;

pub use primitives::{closest_point_on_segment, closest_point_on_triangle, ray_triangle, winding_number, Aabb};
pub use tri_tri::triangles_intersect;

use crate::geometry::mesh::{TriMesh, Vec3};
use rayon::prelude::*;
use tri_tri::{triangles_intersect_sharing, SharedCorners};

/// Triangles per leaf: 8 built and queried faster than 4 or 6 on p2's ventricle.
const MAX_LEAF_TRIANGLES: usize = 8;
/// Bins of the surface-area-heuristic split search.
const SAH_BINS: usize = 16;
/// Intersection tests snap plane distances below this fraction of the mesh's
/// bounding-box diagonal to 0 (well above rounding, far below any real feature).
const INTERSECTION_TOLERANCE_RELATIVE: f64 = 1e-9;

/// The point of a mesh nearest a query point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClosestHit {
    pub triangle: u32,
    pub point: Vec3,
    /// Weights of the triangle's three corners (sum 1) that give `point`.
    pub barycentric: [f64; 3],
    pub distance_mm: f64,
}

#[derive(Clone, Copy, Debug)]
struct BvhNode {
    bounds: Aabb,
    /// Leaf: first slot in `triangle_order`. Interior: index of the left child
    /// (the right child follows it).
    first: u32,
    /// Triangles in a leaf; 0 marks an interior node.
    count: u32,
}

impl BvhNode {
    fn is_leaf(&self) -> bool {
        self.count > 0
    }
}

/// Bounding-volume hierarchy (AABB tree) over a mesh's triangles, stored as a
/// flat node array and built without recursion (binned SAH).
#[derive(Clone, Debug)]
pub struct TriangleBvh {
    nodes: Vec<BvhNode>,
    /// Triangle indices, grouped so every leaf owns a contiguous range.
    triangle_order: Vec<u32>,
    /// Box of each triangle, in `triangle_order`'s order (saves recomputing it
    /// in every box query).
    slot_bounds: Vec<Aabb>,
    point_count: usize,
}

impl TriangleBvh {
    /// Build the tree. Errors name the first triangle with an out-of-range point
    /// index or a non-finite coordinate.
    pub fn new(mesh: &TriMesh) -> Result<Self, String> {
        validate_mesh(mesh)?;
        let mut prims: Vec<BuildPrim> = (0..mesh.triangles.len())
            .map(|t| BuildPrim {
                bounds: Aabb::of_triangle(&mesh.triangle_points(t)),
                triangle: t as u32,
                bin: 0,
            })
            .collect();
        let nodes = build_nodes(&mut prims);
        let triangle_order = prims.iter().map(|p| p.triangle).collect();
        let slot_bounds = prims.iter().map(|p| p.bounds).collect();
        Ok(TriangleBvh {
            nodes,
            triangle_order,
            slot_bounds,
            point_count: mesh.points.len(),
        })
    }

    pub fn triangle_count(&self) -> usize {
        self.triangle_order.len()
    }

    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Box around every triangle (empty for an empty mesh).
    pub fn bounds(&self) -> Aabb {
        self.nodes.first().map_or_else(Aabb::empty, |n| n.bounds)
    }

    /// # Panics
    /// If `mesh` is not the mesh the tree was built from (different triangle or
    /// point count): answering for another mesh would be silently wrong.
    fn assert_built_from(&self, mesh: &TriMesh) {
        assert!(
            mesh.triangles.len() == self.triangle_order.len()
                && mesh.points.len() == self.point_count,
            "TriangleBvh built for {} triangles / {} points queried with a mesh of {} / {}",
            self.triangle_order.len(),
            self.point_count,
            mesh.triangles.len(),
            mesh.points.len()
        );
    }

    fn leaf_triangles(&self, node: &BvhNode) -> &[u32] {
        &self.triangle_order[node.first as usize..(node.first + node.count) as usize]
    }

    /// Nearest point of the mesh to `q`; `None` only for an empty mesh.
    pub fn closest_point(&self, mesh: &TriMesh, q: Vec3) -> Option<ClosestHit> {
        self.closest_point_where(mesh, q, f64::INFINITY, |_| true)
    }

    /// Nearest point no farther than `max_distance_mm` (inclusive).
    pub fn closest_point_within(
        &self,
        mesh: &TriMesh,
        q: Vec3,
        max_distance_mm: f64,
    ) -> Option<ClosestHit> {
        self.closest_point_where(mesh, q, max_distance_mm, |_| true)
    }

    /// Nearest point on the triangles `accept` keeps (e.g. one face label).
    pub fn closest_point_filtered(
        &self,
        mesh: &TriMesh,
        q: Vec3,
        accept: impl Fn(u32) -> bool,
    ) -> Option<ClosestHit> {
        self.closest_point_where(mesh, q, f64::INFINITY, accept)
    }

    /// Nearest point on the accepted triangles within `max_distance_mm` (the bound of
    /// [`Self::nearest_first`]: squared distance).
    pub fn closest_point_where(
        &self,
        mesh: &TriMesh,
        q: Vec3,
        max_distance_mm: f64,
        accept: impl Fn(u32) -> bool,
    ) -> Option<ClosestHit> {
        self.assert_built_from(mesh);
        if max_distance_mm.is_nan() || max_distance_mm < 0.0 || self.nodes.is_empty() {
            return None;
        }
        let mut best: Option<ClosestHit> = None;
        self.nearest_first(
            max_distance_mm * max_distance_mm,
            |bounds, _| Some(bounds.distance_squared_mm2(&q)),
            |triangles, best_d2| {
                for &t in triangles.iter().filter(|&&t| accept(t)) {
                    let (point, barycentric) = closest_point_on_triangle(&q, &mesh.triangle_points(t as usize));
                    let d2 = (point - q).norm_squared();
                    if d2 < *best_d2 || (best.is_none() && d2 <= *best_d2) {
                        *best_d2 = d2;
                        best = Some(ClosestHit { triangle: t, point, barycentric, distance_mm: d2.sqrt() });
                    }
                }
            },
        );
        best
    }

    /// Calls `visit` with every triangle whose own bounding box overlaps `query`
    /// (a conservative candidate set for exact tests).
    pub fn triangles_overlapping_box(
        &self,
        mesh: &TriMesh,
        query: &Aabb,
        mut visit: impl FnMut(u32),
    ) {
        self.assert_built_from(mesh);
        if self.nodes.is_empty() || query.is_empty() {
            return;
        }
        let mut stack: Vec<u32> = Vec::with_capacity(64);
        stack.push(0);
        while let Some(index) = stack.pop() {
            let node = &self.nodes[index as usize];
            if !node.bounds.overlaps(query) {
                continue;
            }
            if node.is_leaf() {
                let slots = node.first as usize..(node.first + node.count) as usize;
                for (t, bounds) in self.triangle_order[slots.clone()]
                    .iter()
                    .zip(&self.slot_bounds[slots])
                {
                    if bounds.overlaps(query) {
                        visit(*t);
                    }
                }
            } else {
                stack.push(node.first + 1);
                stack.push(node.first);
            }
        }
    }

    /// Nearest hit of the ray `origin + t * dir`, `t >= 0`, as `(t, triangle)`;
    /// `t` is in units of `|dir|` (mm for a unit `dir`). Both triangle sides count.
    pub fn ray_cast(&self, mesh: &TriMesh, origin: Vec3, dir: Vec3) -> Option<(f64, u32)> {
        self.assert_built_from(mesh);
        if self.nodes.is_empty() || dir == Vec3::zeros() || !dir.iter().all(|c| c.is_finite()) {
            return None;
        }
        let inv_dir = dir.map(|c| 1.0 / c);
        let mut best: Option<(f64, u32)> = None;
        self.nearest_first(
            f64::INFINITY,
            |bounds, best_t| bounds.ray_entry(&origin, &inv_dir, best_t),
            |triangles, best_t| {
                for &t in triangles {
                    if let Some(hit_t) = ray_triangle(&origin, &dir, &mesh.triangle_points(t as usize)) {
                        if hit_t < *best_t {
                            *best_t = hit_t;
                            best = Some((hit_t, t));
                        }
                    }
                }
            },
        );
        best
    }

    /// Visits the leaves whose subtree may hold something better than `bound`, nearer
    /// first: `lower_bound(box, bound)` is the least a subtree in `box` can give (None:
    /// nothing), `leaf(triangles, bound)` lowers `bound` by what it finds. The farther
    /// child is pushed first, so the nearer one is popped next and the bound tightens
    /// early; a subtree whose lower bound has since passed the bound is skipped.
    fn nearest_first(
        &self,
        mut bound: f64,
        lower_bound: impl Fn(&Aabb, f64) -> Option<f64>,
        mut leaf: impl FnMut(&[u32], &mut f64),
    ) {
        let mut stack: Vec<(u32, f64)> = Vec::with_capacity(64);
        if let Some(root) = lower_bound(&self.nodes[0].bounds, bound) {
            stack.push((0, root));
        }
        while let Some((index, least)) = stack.pop() {
            if least > bound {
                continue;
            }
            let node = &self.nodes[index as usize];
            if node.is_leaf() {
                leaf(self.leaf_triangles(node), &mut bound);
                continue;
            }
            let child = |c: u32| lower_bound(&self.nodes[c as usize].bounds, bound);
            let (left, right) = (node.first, node.first + 1);
            match (child(left), child(right)) {
                (Some(l), Some(r)) if l <= r => stack.extend([(right, r), (left, l)]),
                (Some(l), Some(r)) => stack.extend([(left, l), (right, r)]),
                (Some(l), None) => stack.push((left, l)),
                (None, Some(r)) => stack.push((right, r)),
                (None, None) => {}
            }
        }
    }

    /// Plane-distance tolerance (mm) for intersection tests on this tree's mesh.
    fn intersection_tolerance_mm(&self) -> f64 {
        INTERSECTION_TOLERANCE_RELATIVE * self.bounds().diagonal_mm()
    }

    /// Pairs `(i, j)`, `i < j`, of triangles of `mesh` that intersect, sorted.
    /// Triangles sharing a point (same index or bit-identical coordinates) count
    /// only when they overlap beyond it: sharing one corner, when they cross near
    /// it; sharing an edge, when folded flat onto each other. `candidate_filter(i, j)`
    /// is asked for each pair whose boxes overlap; `false` skips the exact test.
    /// Zero-area triangles are never reported (see `manifold_report`).
    pub fn self_intersections(
        &self,
        mesh: &TriMesh,
        candidate_filter: impl Fn(u32, u32) -> bool,
    ) -> Vec<(u32, u32)> {
        self.assert_built_from(mesh);
        let tolerance_mm = self.intersection_tolerance_mm();
        let mut pairs = Vec::new();
        for t in 0..mesh.triangles.len() as u32 {
            self.collect_self_intersections_of(
                mesh,
                t,
                tolerance_mm,
                &candidate_filter,
                &mut pairs,
            );
        }
        pairs.sort_unstable();
        pairs
    }

    /// [`Self::self_intersections`] spread over the rayon thread pool.
    pub fn self_intersections_par(
        &self,
        mesh: &TriMesh,
        candidate_filter: impl Fn(u32, u32) -> bool + Sync,
    ) -> Vec<(u32, u32)> {
        self.assert_built_from(mesh);
        let tolerance_mm = self.intersection_tolerance_mm();
        let mut pairs: Vec<(u32, u32)> = (0..mesh.triangles.len() as u32)
            .into_par_iter()
            .fold(Vec::new, |mut found, t| {
                self.collect_self_intersections_of(
                    mesh,
                    t,
                    tolerance_mm,
                    &candidate_filter,
                    &mut found,
                );
                found
            })
            .reduce(Vec::new, |mut a, mut b| {
                a.append(&mut b);
                a
            });
        pairs.sort_unstable();
        pairs
    }

    /// Intersections of triangle `t` with higher-numbered triangles, so each pair
    /// is tested once.
    fn collect_self_intersections_of(
        &self,
        mesh: &TriMesh,
        t: u32,
        tolerance_mm: f64,
        candidate_filter: &impl Fn(u32, u32) -> bool,
        found: &mut Vec<(u32, u32)>,
    ) {
        let corners = mesh.triangle_points(t as usize);
        let ids = mesh.triangles[t as usize];
        let query = Aabb::of_triangle(&corners).expanded(tolerance_mm);
        self.triangles_overlapping_box(mesh, &query, |other| {
            if other <= t || !candidate_filter(t, other) {
                return;
            }
            let other_corners = mesh.triangle_points(other as usize);
            let other_ids = mesh.triangles[other as usize];
            let shared =
                SharedCorners::find(&corners, &other_corners, |i, j| ids[i] == other_ids[j]);
            if triangles_intersect_sharing(&corners, &other_corners, &shared, tolerance_mm) {
                found.push((t, other));
            }
        });
    }

    /// Pairs `(triangle of this tree's mesh_a, triangle of mesh_b)` that intersect,
    /// sorted. The meshes share points only by bit-identical coordinates (e.g. a
    /// new baffle stitched to the wall's seam points); triangles touching only at
    /// such shared points are not reported, as in [`Self::self_intersections`].
    pub fn intersects_mesh(&self, mesh_a: &TriMesh, mesh_b: &TriMesh) -> Vec<(u32, u32)> {
        self.assert_built_from(mesh_a);
        let b_bounds = Aabb::from_points(mesh_b.points.iter());
        let tolerance_mm =
            INTERSECTION_TOLERANCE_RELATIVE * self.bounds().merged(&b_bounds).diagonal_mm();
        let mut pairs: Vec<(u32, u32)> = (0..mesh_b.triangles.len())
            .into_par_iter()
            .fold(Vec::new, |mut found, tb| {
                let Some(corners_b) = triangle_points_checked(mesh_b, tb) else {
                    return found;
                };
                let query = Aabb::of_triangle(&corners_b).expanded(tolerance_mm);
                self.triangles_overlapping_box(mesh_a, &query, |ta| {
                    let corners_a = mesh_a.triangle_points(ta as usize);
                    let shared = SharedCorners::find(&corners_a, &corners_b, |_, _| false);
                    if triangles_intersect_sharing(&corners_a, &corners_b, &shared, tolerance_mm) {
                        found.push((ta, tb as u32));
                    }
                });
                found
            })
            .reduce(Vec::new, |mut a, mut b| {
                a.append(&mut b);
                a
            });
        pairs.sort_unstable();
        pairs
    }
}

/// Corners of triangle `t`, or `None` when it points past the point list (so a
/// malformed second mesh is skipped instead of panicking; `TriangleBvh::new`
/// reports such meshes properly).
fn triangle_points_checked(mesh: &TriMesh, t: usize) -> Option<[Vec3; 3]> {
    let ids = mesh.triangles.get(t)?;
    let mut corners = [Vec3::zeros(); 3];
    for k in 0..3 {
        corners[k] = *mesh.points.get(ids[k] as usize)?;
    }
    Some(corners)
}

fn validate_mesh(mesh: &TriMesh) -> Result<(), String> {
    for (t, tri) in mesh.triangles.iter().enumerate() {
        for &p in tri {
            let Some(point) = mesh.points.get(p as usize) else {
                return Err(format!(
                    "triangle {t} uses point {p}, but the mesh has only {} points",
                    mesh.points.len()
                ));
            };
            if !point.iter().all(|c| c.is_finite()) {
                return Err(format!(
                    "triangle {t} uses point {p} with non-finite coordinates {point:?}"
                ));
            }
        }
    }
    Ok(())
}

/// A triangle during the build: kept together (and reordered together) so each
/// pass over a node's range reads memory in order.
#[derive(Clone, Copy)]
struct BuildPrim {
    bounds: Aabb,
    triangle: u32,
    /// SAH bin in the current split.
    bin: u32,
}

impl BuildPrim {
    /// Twice the box centre's coordinate (the factor cancels in binning).
    fn centroid2(&self, axis: usize) -> f64 {
        self.bounds.min[axis] + self.bounds.max[axis]
    }
}

/// Build the flat node array top-down with an explicit work stack; `prims` ends
/// up grouped by leaf.
fn build_nodes(prims: &mut [BuildPrim]) -> Vec<BvhNode> {
    if prims.is_empty() {
        return Vec::new();
    }
    let mut nodes = Vec::with_capacity(2 * prims.len() / MAX_LEAF_TRIANGLES + 1);
    let root_bounds = prims.iter().fold(Aabb::empty(), |b, p| b.merged(&p.bounds));
    nodes.push(BvhNode {
        bounds: root_bounds,
        first: 0,
        count: prims.len() as u32,
    });
    let mut pending = vec![0usize];
    while let Some(index) = pending.pop() {
        let (start, count) = (nodes[index].first as usize, nodes[index].count as usize);
        if count <= MAX_LEAF_TRIANGLES {
            continue;
        }
        let split = split_range(&mut prims[start..start + count], &nodes[index].bounds);
        let left_index = nodes.len();
        nodes.push(BvhNode {
            bounds: split.left_bounds,
            first: start as u32,
            count: split.left_count as u32,
        });
        nodes.push(BvhNode {
            bounds: split.right_bounds,
            first: (start + split.left_count) as u32,
            count: (count - split.left_count) as u32,
        });
        nodes[index].first = left_index as u32;
        nodes[index].count = 0;
        pending.push(left_index);
        pending.push(left_index + 1);
    }
    nodes
}

/// A node's triangles divided in two non-empty groups: the first `left_count` go left.
struct Split {
    left_count: usize,
    left_bounds: Aabb,
    right_bounds: Aabb,
}

/// Reorder `range` (at least 2 triangles) into two non-empty groups along the
/// node box's widest axis, at the binned-SAH-best plane between triangle centres.
fn split_range(range: &mut [BuildPrim], node_bounds: &Aabb) -> Split {
    let axis = (node_bounds.max - node_bounds.min).imax();
    let (low, high) = range
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
            let c = p.centroid2(axis);
            (if c < lo { c } else { lo }, if c > hi { c } else { hi })
        });
    if high <= low {
        return median_split(range, axis); // centres coincide on this axis
    }
    let scale = SAH_BINS as f64 / (high - low);
    let mut bins = [(0usize, Aabb::empty()); SAH_BINS];
    for p in range.iter_mut() {
        p.bin = (((p.centroid2(axis) - low) * scale) as u32).min(SAH_BINS as u32 - 1);
        let bin = &mut bins[p.bin as usize];
        bin.0 += 1;
        bin.1 = bin.1.merged(&p.bounds);
    }
    let split_bin = best_sah_split(&bins, range.len()) as u32;
    let left_count = partition_in_place(range, |p| p.bin <= split_bin);
    let merge = |bins: &[(usize, Aabb)]| bins.iter().fold(Aabb::empty(), |b, bin| b.merged(&bin.1));
    Split {
        left_count,
        left_bounds: merge(&bins[..=split_bin as usize]),
        right_bounds: merge(&bins[split_bin as usize + 1..]),
    }
}

/// Halve `range` at the median centre on `axis` (the fallback when binning cannot separate).
fn median_split(range: &mut [BuildPrim], axis: usize) -> Split {
    let mid = range.len() / 2;
    range.select_nth_unstable_by(mid, |a, b| a.centroid2(axis).total_cmp(&b.centroid2(axis)));
    let bounds_of =
        |prims: &[BuildPrim]| prims.iter().fold(Aabb::empty(), |b, p| b.merged(&p.bounds));
    Split {
        left_count: mid,
        left_bounds: bounds_of(&range[..mid]),
        right_bounds: bounds_of(&range[mid..]),
    }
}

/// Last bin of the left group minimising (left area x count + right area x count).
/// The lowest and highest bins are non-empty, so both groups are.
fn best_sah_split(bins: &[(usize, Aabb); SAH_BINS], total: usize) -> usize {
    // Right-to-left sweep of the cost of everything right of each split.
    let mut right_cost = [0.0; SAH_BINS];
    let (mut right_box, mut right_count) = (Aabb::empty(), 0usize);
    for b in (1..SAH_BINS).rev() {
        right_box = right_box.merged(&bins[b].1);
        right_count += bins[b].0;
        right_cost[b - 1] = right_box.half_area_mm2() * right_count as f64;
    }
    let (mut left_box, mut left_count) = (Aabb::empty(), 0usize);
    let mut best = (f64::INFINITY, 0usize);
    for b in 0..SAH_BINS - 1 {
        left_box = left_box.merged(&bins[b].1);
        left_count += bins[b].0;
        let cost = left_box.half_area_mm2() * left_count as f64 + right_cost[b];
        if left_count > 0 && left_count < total && cost < best.0 {
            best = (cost, b);
        }
    }
    best.1
}

/// Move the elements satisfying `goes_left` to the front; returns their count.
fn partition_in_place(range: &mut [BuildPrim], goes_left: impl Fn(&BuildPrim) -> bool) -> usize {
    let mut next_left = 0;
    for i in 0..range.len() {
        if goes_left(&range[i]) {
            range.swap(i, next_left);
            next_left += 1;
        }
    }
    next_left
}

/// A nearest point whose barycentric weight for a corner is at most this lies on the
/// opposite edge (or, with two such weights, at a corner).
const FEATURE_WEIGHT: f64 = 1e-9;

/// Outside a closed outward surface: on the outer side of the angle-weighted pseudo-normal
/// at the nearest point (Baerentzen and Aanaes 2005), which decides correctly whether that
/// point is inside a triangle, on an edge or at a corner (a single triangle's side does
/// not, where the surface folds between neighbours).
pub fn is_outside(surface: &TriMesh, bvh: &TriangleBvh, q: Vec3) -> bool {
    let Some(hit) = bvh.closest_point(surface, q) else {
        return false;
    };
    let t = hit.triangle as usize;
    let corners = surface.triangles[t];
    let feature: Vec<u32> = (0..3).filter(|&k| hit.barycentric[k] > FEATURE_WEIGHT).map(|k| corners[k]).collect();
    let normal = match feature.len() {
        3 => surface.triangle_normal2(t),
        _ => pseudo_normal(surface, bvh, &feature),
    };
    (q - hit.point).dot(&normal) > 0.0
}

/// Sum of the unit normals of the triangles holding every vertex of `feature` (an edge:
/// its two triangles; a vertex: its fan, each weighted by its angle there).
fn pseudo_normal(surface: &TriMesh, bvh: &TriangleBvh, feature: &[u32]) -> Vec3 {
    let at = surface.points[feature[0] as usize];
    let mut sum = Vec3::zeros();
    bvh.triangles_overlapping_box(surface, &Aabb::from_points([&at]), |t| {
        let corners = surface.triangles[t as usize];
        if !feature.iter().all(|v| corners.contains(v)) {
            return;
        }
        let unit = surface.triangle_normal2(t as usize).normalize();
        let weight = match feature {
            [v] => {
                let k = corners.iter().position(|c| c == v).unwrap_or(0);
                let [a, b, c] = [k, (k + 1) % 3, (k + 2) % 3].map(|i| surface.points[corners[i] as usize]);
                (b - a).angle(&(c - a))
            }
            _ => 1.0,
        };
        if unit.iter().all(|x| x.is_finite()) {
            sum += weight * unit;
        }
    });
    sum
}

#[cfg(test)]
mod tests;
