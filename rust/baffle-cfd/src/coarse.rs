//! Two-level preconditioner: the block ILU(0) followed by a coarse-grid correction on
//! node aggregates (Galerkin coarse operator of piecewise-constant u, v, w and p per
//! aggregate, solved by dense LU). ILU(0) removes the local error; the few smooth,
//! global error modes it leaves (the plateau of every GMRES solve) are what a coarse
//! space of aggregates captures, the idea behind aggregation AMG and deflation
//! (Nicolaides 1987; Vanek, Mandel and Brezina 1996), here with a single coarse level.

use rayon::prelude::*;

use crate::sparse::{split_by, wide, BlockAcc, BlockPattern, Scalar, B, BB};

/// Most aggregates the coarse level is given: its dense LU (4 unknowns per aggregate)
/// then costs at most ~1 GFLOP a solve, whatever the mesh.
pub const MAX_AGGREGATES: usize = 256;

/// The aggregate size for `n_nodes` nodes: `size`, or larger so that there are at most
/// about [`MAX_AGGREGATES`].
pub fn aggregate_size(n_nodes: usize, size: usize) -> usize {
    size.max(n_nodes.div_ceil(MAX_AGGREGATES))
}

/// Nodes grouped into connected aggregates of about `size` nodes each.
#[derive(Clone, Debug)]
pub struct Aggregates {
    /// Aggregate of each node.
    pub of_node: Vec<u32>,
    pub count: usize,
}

/// Greedy breadth-first aggregation on the node graph, seeds taken in node order (RCM:
/// aggregates come out compact). Each aggregate grows until it holds `size` nodes or
/// has no unassigned neighbour left.
pub fn aggregate(pattern: &BlockPattern, size: usize) -> Aggregates {
    let n = pattern.n_rows();
    let mut of_node = vec![u32::MAX; n];
    let mut count = 0u32;
    let mut queue = std::collections::VecDeque::new();
    for seed in 0..n {
        if of_node[seed] != u32::MAX {
            continue;
        }
        let mut members = 0;
        of_node[seed] = count;
        queue.clear();
        queue.push_back(seed);
        'grow: while let Some(i) = queue.pop_front() {
            members += 1;
            for &j in &pattern.cols[pattern.row_ptr[i]..pattern.row_ptr[i + 1]] {
                let j = j as usize;
                if of_node[j] == u32::MAX {
                    if members + queue.len() >= size {
                        break 'grow;
                    }
                    of_node[j] = count;
                    queue.push_back(j);
                }
            }
        }
        count += 1;
    }
    Aggregates { of_node, count: count as usize }
}

/// The coarse correction: Z (Z^T A Z)^-1 Z^T with Z the aggregates' indicator vectors
/// per component, restricted to the free unknowns (prescribed velocity components take
/// no correction).
pub struct CoarseCorrection {
    aggregates: Aggregates,
    /// Whether unknown 4 i + c is free (not a prescribed velocity component).
    free: Vec<bool>,
    /// Where the blocks of A Z are, for every solve's [`ProlongedOperator`].
    prolonged: ProlongedPattern,
    /// LU factors of the coarse matrix (row-major, unit lower L below the diagonal) and
    /// the row permutation of partial pivoting.
    lu: Vec<f64>,
    perm: Vec<usize>,
}

/// The block structure of A Z: each node row's (row, aggregate) blocks, in the order
/// the row first reaches each aggregate, and the A Z block each pattern block is summed
/// into. The aggregates are fixed, so it is made once with the coarse correction and
/// every solve's A Z is a sum into it (made anew each solve, the per-row lists were
/// about a tenth of a step on p3's 1.25 mm mesh).
struct ProlongedPattern {
    row_ptr: Vec<usize>,
    aggregate: Vec<u32>,
    slot: Vec<u32>,
}

/// Node rows per parallel task when A Z's blocks are summed.
const PROLONGED_ROWS_PER_TASK: usize = 512;

impl ProlongedPattern {
    fn new(pattern: &BlockPattern, aggregates: &Aggregates) -> Self {
        let (mut row_ptr, mut aggregate, mut slot) = (vec![0], Vec::new(), vec![0u32; pattern.cols.len()]);
        for i in 0..pattern.n_rows() {
            let first = aggregate.len();
            for p in pattern.row_ptr[i]..pattern.row_ptr[i + 1] {
                let agg = aggregates.of_node[pattern.cols[p] as usize];
                slot[p] = match aggregate[first..].iter().position(|&a| a == agg) {
                    Some(k) => first + k,
                    None => {
                        aggregate.push(agg);
                        aggregate.len() - 1
                    }
                } as u32;
            }
            row_ptr.push(aggregate.len());
        }
        ProlongedPattern { row_ptr, aggregate, slot }
    }

    /// The blocks of K Z for the block matrix `vals`: each pattern block's free columns
    /// summed into its slot, in the pattern's order.
    fn blocks(&self, pattern: &BlockPattern, vals: &[f64], free: &[bool]) -> Vec<[f64; BB]> {
        let n = pattern.n_rows();
        let tasks: Vec<std::ops::Range<usize>> = (0..n).step_by(PROLONGED_ROWS_PER_TASK).map(|s| s..(s + PROLONGED_ROWS_PER_TASK).min(n)).collect();
        let mut blocks = vec![[0.0; BB]; self.aggregate.len()];
        let pieces = split_by(&mut blocks, tasks.iter().map(|r| self.row_ptr[r.end] - self.row_ptr[r.start]));
        pieces.into_par_iter().zip(&tasks).for_each(|(piece, rows)| wide(#[inline(always)] || {
            let base = self.row_ptr[rows.start];
            for p in pattern.row_ptr[rows.start]..pattern.row_ptr[rows.end] {
                let (j, block) = (pattern.cols[p] as usize, &mut piece[self.slot[p] as usize - base]);
                let (free_j, src) = (&free[j * B..(j + 1) * B], &vals[p * BB..(p + 1) * BB]);
                // A select, not a skipped column, so that the loop has no branch to stop
                // it vectorizing.
                for (k, (d, v)) in block.iter_mut().zip(src).enumerate() {
                    *d += if free_j[k % B] { *v } else { 0.0 };
                }
            }
        }));
        blocks
    }
}

/// Node rows per call of [`wide`] in [`ProlongedOperator::add_product`].
const PRODUCT_ROWS_PER_CALL: usize = 64;

/// A Z for the block matrix K plus rank-one terms c b b^T, so that the product of a
/// corrected vector, A (z + Z e), is A z + (A Z) e without another fine product: K Z
/// as blocks (node row, aggregate reached), the rank-one terms as (c, b, Z^T b). Made
/// of the current matrix for each solve (the coarse factors may be older).
pub struct ProlongedOperator<'a> {
    structure: &'a ProlongedPattern,
    blocks: Vec<[f64; BB]>,
    rank_one: Vec<(f64, &'a [f64], Vec<f64>)>,
}

impl<'a> ProlongedOperator<'a> {
    fn new(structure: &'a ProlongedPattern, pattern: &BlockPattern, vals: &[f64], rank_one: &[(f64, &'a [f64])], aggregates: &Aggregates, free: &[bool]) -> Self {
        let blocks = structure.blocks(pattern, vals, free);
        let rank_one = rank_one.iter().map(|&(c, b)| (c, b, restrict(b, aggregates, free))).collect();
        ProlongedOperator { structure, blocks, rank_one }
    }

    /// az += (A Z) e.
    fn add_product<V: Scalar>(&self, e: &[f64], az: &mut [V]) {
        let along: Vec<f64> = self.rank_one.iter().map(|(c, _, zb)| c * zb.iter().zip(e).map(|(x, y)| x * y).sum::<f64>()).collect();
        let (row_ptr, aggregate) = (&self.structure.row_ptr, &self.structure.aggregate);
        az.par_chunks_mut(B * PRODUCT_ROWS_PER_CALL).enumerate().with_min_len(4).for_each(|(c, azc)| {
            wide(#[inline(always)] || {
                for (i, azi) in (c * PRODUCT_ROWS_PER_CALL..).zip(azc.chunks_exact_mut(B)) {
                    // Lane sums, as the block SpMV: one horizontal sum per row, not per block.
                    let mut lanes = BlockAcc::<f64>::default();
                    for k in row_ptr[i]..row_ptr[i + 1] {
                        lanes.add(&self.blocks[k], &e[aggregate[k] as usize * B..][..B]);
                    }
                    let acc = lanes.sum();
                    for (r, a) in acc.iter().enumerate() {
                        let rank_one: f64 = self.rank_one.iter().zip(&along).map(|((_, b, _), s)| s * b[i * B + r]).sum();
                        azi[r] = V::from_f64(azi[r].to_f64() + a + rank_one);
                    }
                }
            })
        });
    }

    /// Z^T (A Z) restricted to the free rows: the coarse matrix (nc = 4 x aggregates,
    /// row-major), summed from A Z's blocks instead of from the pattern again.
    fn restricted(&self, aggregates: &Aggregates, free: &[bool]) -> Vec<f64> {
        let nc = aggregates.count * B;
        let mut a = vec![0.0; nc * nc];
        let (row_ptr, aggregate) = (&self.structure.row_ptr, &self.structure.aggregate);
        for (i, &agg) in aggregates.of_node.iter().enumerate() {
            let ai = agg as usize * B;
            for k in row_ptr[i]..row_ptr[i + 1] {
                let aj = aggregate[k] as usize * B;
                for r in (0..B).filter(|&r| free[i * B + r]) {
                    for c in 0..B {
                        a[(ai + r) * nc + aj + c] += self.blocks[k][r * B + c];
                    }
                }
            }
        }
        for (coefficient, _, cv) in &self.rank_one {
            for (r, cr) in cv.iter().enumerate().filter(|(_, c)| **c != 0.0) {
                for (c, cc) in cv.iter().enumerate() {
                    a[r * nc + c] += coefficient * cr * cc;
                }
            }
        }
        a
    }
}

/// Z^T v: `v`'s free unknowns summed per aggregate and component. Nodes in chunks of
/// [`RESTRICT_NODES_PER_TASK`] in parallel, the chunks' sums added in order: serial, it
/// left the other core idle (1.0 % of p3 1.25 mm's CPU samples, on the main thread).
fn restrict<V: Scalar>(v: &[V], aggregates: &Aggregates, free: &[bool]) -> Vec<f64> {
    let nc = aggregates.count * B;
    let chunk = |(vc, (fc, ac)): (&[V], (&[bool], &[u32]))| {
        let mut rc = vec![0.0; nc];
        for ((vi, fi), &agg) in vc.chunks_exact(B).zip(fc.chunks_exact(B)).zip(ac) {
            let at = agg as usize * B;
            for c in (0..B).filter(|&c| fi[c]) {
                rc[at + c] += vi[c].to_f64();
            }
        }
        rc
    };
    let n = RESTRICT_NODES_PER_TASK;
    let tasks = v.par_chunks(n * B).zip(free.par_chunks(n * B).zip(aggregates.of_node.par_chunks(n)));
    let partial: Vec<Vec<f64>> = tasks.map(chunk).collect();
    partial.into_iter().reduce(|mut a, b| {
        a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
        a
    }).unwrap_or_else(|| vec![0.0; nc])
}

/// Nodes per parallel task of [`restrict`].
const RESTRICT_NODES_PER_TASK: usize = 4096;

impl CoarseCorrection {
    /// Coarse matrix Z^T A Z of the block matrix `vals` plus the rank-one terms
    /// `rank_one` (coefficient, vector over the fine unknowns), factored.
    pub fn new(pattern: &BlockPattern, vals: &[f64], rank_one: &[(f64, &[f64])], aggregates: Aggregates, dirichlet: &[bool]) -> Self {
        let free: Vec<bool> = (0..pattern.n_rows() * B).map(|k| k % B == 3 || !dirichlet[k / B]).collect();
        let nc = aggregates.count * B;
        let prolonged = ProlongedPattern::new(pattern, &aggregates);
        let mut a = ProlongedOperator::new(&prolonged, pattern, vals, rank_one, &aggregates, &free).restricted(&aggregates, &free);
        // A coarse unknown with no free fine unknown (an aggregate of wall nodes only)
        // has an empty row and column: an identity row keeps the matrix regular.
        for k in 0..nc {
            if (0..nc).all(|c| a[k * nc + c] == 0.0) {
                a[k * nc + k] = 1.0;
            }
        }
        let perm = lu_in_place(&mut a, nc);
        CoarseCorrection { aggregates, free, prolonged, lu: a, perm }
    }

    /// A Z of the block matrix `vals` and the rank-one terms `rank_one`.
    pub fn prolonged_operator<'a>(&'a self, pattern: &BlockPattern, vals: &[f64], rank_one: &[(f64, &'a [f64])]) -> ProlongedOperator<'a> {
        ProlongedOperator::new(&self.prolonged, pattern, vals, rank_one, &self.aggregates, &self.free)
    }

    /// z += Z A_c^-1 Z^T w; returns the coarse solution e = A_c^-1 Z^T w.
    pub fn add_correction<V: Scalar>(&self, w: &[V], z: &mut [V]) -> Vec<f64> {
        let e = lu_solve(&self.lu, &self.perm, &restrict(w, &self.aggregates, &self.free));
        let nodes = z.par_chunks_mut(B).zip(self.free.par_chunks(B)).zip(self.aggregates.of_node.par_iter());
        nodes.with_min_len(1024).for_each(|((zi, fi), &agg)| {
            for c in (0..B).filter(|&c| fi[c]) {
                zi[c] = V::from_f64(zi[c].to_f64() + e[agg as usize * B + c]);
            }
        });
        e
    }

    /// As [`Self::add_correction`], and az += A Z e, so that az = A z stays true of the
    /// corrected z when it held before (A being the operator `prolonged` was made of).
    pub fn add_correction_and_product<V: Scalar>(&self, prolonged: &ProlongedOperator, w: &[V], z: &mut [V], az: &mut [V]) {
        let e = self.add_correction(w, z);
        prolonged.add_product(&e, az);
    }
}

/// Dense LU with partial pivoting of the n x n row-major `a`, in place; returns the
/// permutation (row k of the factors is row perm[k] of a). A zero pivot column is
/// left as is (its unknown gets no correction).
fn lu_in_place(a: &mut [f64], n: usize) -> Vec<usize> {
    let mut perm: Vec<usize> = (0..n).collect();
    for k in 0..n {
        let pivot = (k..n).max_by(|&x, &y| a[x * n + k].abs().total_cmp(&a[y * n + k].abs())).unwrap_or(k);
        if pivot != k {
            for c in 0..n {
                a.swap(k * n + c, pivot * n + c);
            }
            perm.swap(k, pivot);
        }
        let d = a[k * n + k];
        if d == 0.0 {
            continue;
        }
        let (done, rest) = a.split_at_mut((k + 1) * n);
        let row_k = &done[k * n..];
        rest.par_chunks_exact_mut(n).with_min_len(16).for_each(|row| {
            let l = row[k] / d;
            row[k] = l;
            if l != 0.0 {
                row[k + 1..].iter_mut().zip(&row_k[k + 1..]).for_each(|(x, y)| *x -= l * y);
            }
        });
    }
    perm
}

/// Solve with [`lu_in_place`]'s factors. The row sums run in [`LU_LANES`] partial sums:
/// one running sum waited on each add's latency, serial (1.3 % of p3 1.25 mm's CPU samples).
fn lu_solve(lu: &[f64], perm: &[usize], b: &[f64]) -> Vec<f64> {
    let n = perm.len();
    let mut x: Vec<f64> = perm.iter().map(|&p| b[p]).collect();
    for i in 0..n {
        x[i] -= lane_dot(&lu[i * n..i * n + i], &x[..i]);
    }
    for i in (0..n).rev() {
        let s = lane_dot(&lu[i * n + i + 1..(i + 1) * n], &x[i + 1..]);
        let d = lu[i * n + i];
        x[i] = if d != 0.0 { (x[i] - s) / d } else { 0.0 };
    }
    x
}

const LU_LANES: usize = 4;

/// a . b with [`LU_LANES`] independent partial sums.
fn lane_dot(a: &[f64], b: &[f64]) -> f64 {
    let mut lanes = [0.0; LU_LANES];
    let (ac, bc) = (a.chunks_exact(LU_LANES), b.chunks_exact(LU_LANES));
    let tail: f64 = ac.remainder().iter().zip(bc.remainder()).map(|(x, y)| x * y).sum();
    for (x, y) in ac.zip(bc) {
        for l in 0..LU_LANES {
            lanes[l] += x[l] * y[l];
        }
    }
    (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]) + tail
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dense_lu_solves_with_pivoting() {
        // Needs a row swap: the first pivot is 0.
        let mut a = vec![0.0, 2.0, 1.0, 1.0, 1.0, 0.0, 3.0, 0.0, 1.0];
        let x_true = [1.0, -2.0, 0.5];
        let b: Vec<f64> = (0..3).map(|i| (0..3).map(|j| a[i * 3 + j] * x_true[j]).sum()).collect();
        let perm = lu_in_place(&mut a, 3);
        let x = lu_solve(&a, &perm, &b);
        assert!(x.iter().zip(x_true).all(|(a, b)| (a - b).abs() < 1e-12), "{x:?}");
    }

    #[test]
    fn aggregates_are_connected_and_about_the_asked_size() {
        let n = 40;
        let pattern = crate::sparse::chain_pattern(n, [0, 1, 2, 3]);
        let agg = aggregate(&pattern, 8);
        assert!(agg.of_node.iter().all(|&a| (a as usize) < agg.count));
        let sizes: Vec<usize> = (0..agg.count).map(|a| agg.of_node.iter().filter(|&&x| x as usize == a).count()).collect();
        assert!(sizes.iter().all(|&s| s <= 8) && sizes.iter().filter(|&&s| s == 8).count() >= 4, "{sizes:?}");
        // On a chain every aggregate is a run of consecutive nodes.
        assert!(agg.of_node.windows(2).all(|w| w[1] == w[0] || w[1] == w[0] + 1), "{:?}", agg.of_node);
    }

    #[test]
    fn the_corrected_product_is_the_operators_product_of_the_corrected_vector() {
        // Several aggregates, prescribed unknowns and a rank-one outlet term: az = A z
        // before the correction stays az = A z after it (A = K + c b b^T).
        let n = 40;
        let pattern = crate::sparse::chain_pattern(n, [0, 1, 2, 3]);
        let vals: Vec<f64> = (0..pattern.cols.len() * BB).map(|k| ((k * 7919) % 13) as f64 / 13.0 - 0.5 + if k % (BB + 1) == 0 { 4.0 } else { 0.0 }).collect();
        let dirichlet: Vec<bool> = (0..n).map(|i| i % 7 == 0).collect();
        let b: Vec<f64> = (0..n * B).map(|k| if k / B >= n - 5 && k % B < 3 { 0.1 * (k % 5) as f64 } else { 0.0 }).collect();
        let rank_one = [(3.0, &b[..])];
        let coarse = CoarseCorrection::new(&pattern, &vals, &rank_one, aggregate(&pattern, 6), &dirichlet);
        let operator = |x: &[f64]| {
            let mut y = vec![0.0; x.len()];
            crate::sparse::spmv(&pattern, &vals, x, &mut y);
            let q: f64 = b.iter().zip(x).map(|(p, q)| p * q).sum();
            y.iter_mut().zip(&b).for_each(|(yi, bi)| *yi += 3.0 * q * bi);
            y
        };
        let mut z: Vec<f64> = (0..n * B).map(|i| (i as f64 * 0.7).cos()).collect();
        let mut az = operator(&z);
        let w: Vec<f64> = (0..n * B).map(|i| (i as f64 * 0.3).sin()).collect();
        coarse.add_correction_and_product(&coarse.prolonged_operator(&pattern, &vals, &rank_one), &w, &mut z, &mut az);
        let expected = operator(&z);
        assert!(az.iter().zip(&expected).all(|(a, e)| (a - e).abs() < 1e-12 * (1.0 + e.abs())), "{az:?}\n{expected:?}");
    }

    #[test]
    fn the_restricted_prolonged_operator_is_the_galerkin_product() {
        // Z^T (A Z) from A Z's blocks equals Z^T A Z formed densely from the pattern,
        // with prescribed unknowns (no row or column of Z) and a rank-one term.
        let n = 30;
        let tets: Vec<[u32; 4]> = (0..n as u32 - 3).map(|i| [i, (i + 1) % n as u32, (i + 2) % n as u32, (i * 7 + 3) % n as u32]).filter(|t| {
            let mut s = *t;
            s.sort_unstable();
            s.windows(2).all(|w| w[0] != w[1])
        }).collect();
        let pattern = BlockPattern::from_tets(n, &tets);
        let vals = crate::sparse::test_matrix(&pattern, 17, |_| 0.0);
        let dirichlet: Vec<bool> = (0..n).map(|i| i % 5 == 0).collect();
        let b: Vec<f64> = (0..n * B).map(|k| if k / B >= n - 4 && k % B < 3 { 0.1 + 0.01 * k as f64 } else { 0.0 }).collect();
        let aggregates = aggregate(&pattern, 4);
        let free: Vec<bool> = (0..n * B).map(|k| k % B == 3 || !dirichlet[k / B]).collect();
        let structure = ProlongedPattern::new(&pattern, &aggregates);
        let got = ProlongedOperator::new(&structure, &pattern, &vals, &[(2.5, &b[..])], &aggregates, &free).restricted(&aggregates, &free);
        let (nf, nc) = (n * B, aggregates.count * B);
        let mut a = vec![0.0; nf * nf];
        for i in 0..n {
            for p in pattern.row_ptr[i]..pattern.row_ptr[i + 1] {
                let j = pattern.cols[p] as usize;
                (0..BB).for_each(|rc| a[(i * B + rc / B) * nf + j * B + rc % B] += vals[p * BB + rc]);
            }
        }
        (0..nf).for_each(|r| (0..nf).for_each(|c| a[r * nf + c] += 2.5 * b[r] * b[c]));
        let z = |k: usize, m: usize| if free[k] && aggregates.of_node[k / B] as usize * B + k % B == m { 1.0 } else { 0.0 };
        for r in 0..nc {
            for c in 0..nc {
                let expected: f64 = (0..nf).flat_map(|k| (0..nf).map(move |l| (k, l))).map(|(k, l)| z(k, r) * a[k * nf + l] * z(l, c)).sum();
                assert!((got[r * nc + c] - expected).abs() < 1e-12, "({r}, {c}): {} against {expected}", got[r * nc + c]);
            }
        }
    }

    #[test]
    fn the_coarse_correction_is_exact_on_the_coarse_space() {
        // With one aggregate per node Z = I: the correction is A^-1 itself.
        let n = 6;
        let pattern = crate::sparse::chain_pattern(n, [0, 1, 2, 3]);
        let vals = crate::sparse::test_matrix(&pattern, 13, |_| 5.0);
        let single = Aggregates { of_node: (0..n as u32).collect(), count: n };
        let coarse = CoarseCorrection::new(&pattern, &vals, &[], single, &vec![false; n]);
        let x_true: Vec<f64> = (0..n * B).map(|i| (i as f64 * 0.3).sin()).collect();
        let mut b = vec![0.0; n * B];
        crate::sparse::spmv(&pattern, &vals, &x_true, &mut b);
        let mut x = vec![0.0; n * B];
        coarse.add_correction(&b, &mut x);
        assert!(x.iter().zip(&x_true).all(|(a, b)| (a - b).abs() < 1e-10), "{x:?}");
    }
}
