//! Where the projected spline jumps between two wall triangles that share no corner
//! even after the samples were bisected to a few micrometres apart, the closest-point
//! projection is discontinuous: the spline passes over a crease or a thin fold of the
//! wall (segmented trabeculae, a cleft next to a cap rim), and nearby spline points
//! project onto two different sheets of it. The seam must still run on the wall, so
//! it follows the shortest chain of wall edges between the two triangles, as long as
//! that chain is short: a long way round means the suture points straddle a real
//! fold and the seam is refused with the distances named.

use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashMap};

use crate::geometry::mesh::TriMesh;
use crate::geometry::spatial::ClosestHit;

/// The walk along the wall may be this many times the straight jump...
const DETOUR_RATIO: f64 = 4.0;
/// ...or this many mean wall edges...
const DETOUR_EDGES: f64 = 3.0;
/// ...or this long, whichever is longest: about one suture bite, a correction the
/// surgeon's stitches cannot follow anyway.
const DETOUR_MM: f64 = 3.0;

/// The wall's vertex neighbourhoods (through wall triangles only), built once per seam.
pub(super) struct WallGraph {
    neighbors: Vec<Vec<u32>>,
    mean_edge_mm: f64,
}

impl WallGraph {
    pub(super) fn new(surface: &TriMesh, wall_label: i32) -> Self {
        let mut neighbors = vec![Vec::new(); surface.points.len()];
        let (mut edge_sum_mm, mut edge_count) = (0.0, 0usize);
        for (tri, _) in surface.triangles.iter().zip(&surface.face_ids).filter(|(_, &id)| id == wall_label) {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                if !neighbors[a as usize].contains(&b) {
                    neighbors[a as usize].push(b);
                    neighbors[b as usize].push(a);
                    edge_sum_mm += (surface.points[a as usize] - surface.points[b as usize]).norm();
                    edge_count += 1;
                }
            }
        }
        WallGraph { neighbors, mean_edge_mm: edge_sum_mm / edge_count.max(1) as f64 }
    }

    /// The wall vertices from a corner of `a`'s triangle to a corner of `b`'s, in
    /// order, along the shortest chain of wall edges (Dijkstra, with the straight
    /// distances from `a` and to `b` included); `Err` gives the length the walk would
    /// need (infinite: none within reach) when it exceeds the allowance.
    pub(super) fn detour(&self, surface: &TriMesh, a: &ClosestHit, b: &ClosestHit) -> Result<Vec<u32>, f64> {
        let allowance_mm =
            (DETOUR_RATIO * (a.point - b.point).norm()).max(DETOUR_EDGES * self.mean_edge_mm).max(DETOUR_MM);
        let position = |v: u32| surface.points[v as usize];
        let targets = surface.triangles[b.triangle as usize];
        let mut dist: HashMap<u32, f64> = HashMap::new();
        let mut previous: HashMap<u32, u32> = HashMap::new();
        let mut heap = BinaryHeap::new();
        for v in surface.triangles[a.triangle as usize] {
            let d = (position(v) - a.point).norm();
            dist.insert(v, d);
            heap.push(Reverse((Ordered(d), v)));
        }
        let mut best: Option<(f64, u32)> = None;
        while let Some(Reverse((Ordered(d), v))) = heap.pop() {
            if d > dist[&v] || d > allowance_mm || best.is_some_and(|(total, _)| d >= total) {
                continue;
            }
            if targets.contains(&v) {
                let total = d + (position(v) - b.point).norm();
                if best.map_or(true, |(t, _)| total < t) {
                    best = Some((total, v));
                }
            }
            for &w in &self.neighbors[v as usize] {
                let dw = d + (position(w) - position(v)).norm();
                if dist.get(&w).map_or(true, |&old| dw < old) {
                    dist.insert(w, dw);
                    previous.insert(w, v);
                    heap.push(Reverse((Ordered(dw), w)));
                }
            }
        }
        match best {
            Some((total, end)) if total <= allowance_mm => Ok(chain_back(end, &previous)),
            Some((total, _)) => Err(total),
            None => Err(f64::INFINITY),
        }
    }
}

/// The vertices from the walk's start to `end`, following `previous` back.
fn chain_back(end: u32, previous: &HashMap<u32, u32>) -> Vec<u32> {
    let mut chain = vec![end];
    while let Some(&v) = previous.get(chain.last().unwrap_or(&end)) {
        chain.push(v);
    }
    chain.reverse();
    chain
}

/// f64 ordered by `total_cmp`, for the heap (distances are finite and non-negative).
#[derive(Clone, Copy, PartialEq)]
struct Ordered(f64);

impl Eq for Ordered {}

impl PartialOrd for Ordered {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Ordered {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&other.0)
    }
}

/// The straight jump between the two hits, for the error message.
pub(super) fn jump_mm(a: &ClosestHit, b: &ClosestHit) -> f64 {
    (a.point - b.point).norm()
}
