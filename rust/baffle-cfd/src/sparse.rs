//! Node-block sparse matrix (4x4 blocks: u, v, w, p per node) in block CSR form.

use rayon::prelude::*;

pub const B: usize = 4;
pub const BB: usize = B * B;

/// Block CSR pattern of the node graph (a node couples with itself and its tet neighbours).
#[derive(Clone, Debug)]
pub struct BlockPattern {
    pub row_ptr: Vec<usize>,
    pub cols: Vec<u32>,
    pub diag: Vec<usize>,
}

impl BlockPattern {
    pub fn from_tets(n_nodes: usize, tets: &[[u32; 4]]) -> Self {
        let mut adjacency: Vec<Vec<u32>> = vec![Vec::new(); n_nodes];
        for t in tets {
            for &a in t {
                for &b in t {
                    adjacency[a as usize].push(b);
                }
            }
        }
        let mut row_ptr = Vec::with_capacity(n_nodes + 1);
        row_ptr.push(0);
        let mut cols = Vec::new();
        let mut diag = Vec::with_capacity(n_nodes);
        for (i, adj) in adjacency.iter_mut().enumerate() {
            if adj.is_empty() {
                adj.push(i as u32); // isolated node: keep a diagonal block
            }
            adj.sort_unstable();
            adj.dedup();
            diag.push(cols.len() + adj.binary_search(&(i as u32)).unwrap_or(0));
            cols.extend_from_slice(adj);
            row_ptr.push(cols.len());
        }
        BlockPattern { row_ptr, cols, diag }
    }

    pub fn n_rows(&self) -> usize {
        self.row_ptr.len() - 1
    }

    /// Number of blocks in the block rows `rows`.
    pub fn blocks_in(&self, rows: &std::ops::Range<usize>) -> usize {
        self.row_ptr[rows.end] - self.row_ptr[rows.start]
    }

    /// Position of block (row, col), if in the pattern.
    pub fn position(&self, row: usize, col: u32) -> Option<usize> {
        let range = self.row_ptr[row]..self.row_ptr[row + 1];
        self.cols[range.clone()].binary_search(&col).ok().map(|k| range.start + k)
    }
}

/// Storage precision of matrix values and Krylov vectors. The inner linear solves run
/// in f32 (half the memory traffic of the bandwidth-bound kernels: block SpMV, ILU
/// triangular solves, Gram-Schmidt), while residuals and the solution stay in f64
/// (see `linear::solve_refined`). Reductions (dot products) always accumulate in f64;
/// block products compute in the precision of the matrix (see [`BlockAcc`]).
pub trait Scalar:
    Copy
    + Default
    + Send
    + Sync
    + PartialEq
    + std::fmt::Debug
    + std::ops::Add<Output = Self>
    + std::ops::Sub<Output = Self>
    + std::ops::Mul<Output = Self>
    + 'static
{
    fn from_f64(v: f64) -> Self;
    fn to_f64(self) -> f64;
    /// `v` in this precision (exact when S is this type: LLVM folds f32 -> f64 -> f32).
    #[inline]
    fn from_scalar<S: Scalar>(v: S) -> Self {
        Self::from_f64(v.to_f64())
    }
}

impl Scalar for f64 {
    #[inline]
    fn from_f64(v: f64) -> Self {
        v
    }
    #[inline]
    fn to_f64(self) -> f64 {
        self
    }
}

impl Scalar for f32 {
    #[inline]
    fn from_f64(v: f64) -> Self {
        v as f32
    }
    #[inline]
    fn to_f64(self) -> f64 {
        self as f64
    }
}

/// Running sum of 4x4 block times 4-vector products along a block row, in the
/// matrix's precision M. Each output row keeps four lane partial sums
/// (`lanes[r][c] += a[r][c] x[c]`) that are added only once, at the end of the
/// row: the inner loop is then four independent 4-wide multiply-adds that the
/// compiler maps to SIMD, instead of a horizontal sum per block. For f32 blocks
/// (the inner solves of the mixed-precision refinement) this computes in f32; the
/// refinement's f64 residual absorbs the rounding.
#[derive(Clone, Copy, Default)]
pub struct BlockAcc<M: Scalar> {
    lanes: [[M; B]; B],
}

impl<M: Scalar> BlockAcc<M> {
    #[inline(always)]
    pub fn add<T: Scalar>(&mut self, a: &[M; BB], x: &[T]) {
        let x: [M; B] = [M::from_scalar(x[0]), M::from_scalar(x[1]), M::from_scalar(x[2]), M::from_scalar(x[3])];
        for r in 0..B {
            for c in 0..B {
                self.lanes[r][c] = self.lanes[r][c] + a[r * B + c] * x[c];
            }
        }
    }

    /// The four row sums, in f64.
    #[inline(always)]
    pub fn sum(&self) -> [f64; B] {
        self.lanes.map(|l| (l[0] + l[1]).to_f64() + (l[2] + l[3]).to_f64())
    }
}

/// Block k of `vals` as a fixed-size array (one bounds check instead of sixteen).
#[inline(always)]
pub fn block<M>(vals: &[M], k: usize) -> &[M; BB] {
    vals[k * BB..(k + 1) * BB].try_into().expect("16 values per block")
}

/// Runs `f` compiled for AVX2 and FMA where the CPU has them (checked at run time, so
/// the binary still runs on any x86-64; the build's baseline has only SSE2). What `f`
/// calls must be inlined into it (`#[inline(always)]`) to be compiled so. The results
/// are the same bit for bit: Rust never contracts a * b + c into an FMA, so the wider
/// registers only change how many lanes an operation works on at once.
#[inline(always)]
pub(crate) fn wide<R>(f: impl FnOnce() -> R) -> R {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        // SAFETY: the CPU has the features `wide_x86` is compiled for.
        return unsafe { wide_x86(f) };
    }
    f()
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn wide_x86<R>(f: impl FnOnce() -> R) -> R {
    f()
}

/// Block rows per call of [`wide`] in the products.
const ROWS_PER_CALL: usize = 64;

/// y = A x for block values `vals` (row-major 4x4 per block) on `pattern`.
pub fn spmv<M: Scalar, T: Scalar>(pattern: &BlockPattern, vals: &[M], x: &[T], y: &mut [T]) {
    y.par_chunks_mut(B * ROWS_PER_CALL).enumerate().with_min_len(4).for_each(|(c, yc)| {
        wide(#[inline(always)] || {
            for (i, yi) in (c * ROWS_PER_CALL..).zip(yc.chunks_exact_mut(B)) {
                let mut acc = BlockAcc::<M>::default();
                for k in pattern.row_ptr[i]..pattern.row_ptr[i + 1] {
                    let j = pattern.cols[k] as usize;
                    acc.add(block(vals, k), &x[j * B..(j + 1) * B]);
                }
                let s = acc.sum();
                for r in 0..B {
                    yi[r] = T::from_f64(s[r]);
                }
            }
        })
    });
}

/// y = A x and w = A v in one pass over A, bit for bit two [`spmv`]s: reading the
/// matrix is most of a product's cost.
pub fn spmv2<M: Scalar, T: Scalar>(pattern: &BlockPattern, vals: &[M], x: &[T], y: &mut [T], v: &[T], w: &mut [T]) {
    let n = B * ROWS_PER_CALL;
    y.par_chunks_mut(n).zip(w.par_chunks_mut(n)).enumerate().with_min_len(4).for_each(|(c, (yc, wc))| {
        wide(#[inline(always)] || {
            for (i, (yi, wi)) in (c * ROWS_PER_CALL..).zip(yc.chunks_exact_mut(B).zip(wc.chunks_exact_mut(B))) {
                let (mut ax, mut av) = (BlockAcc::<M>::default(), BlockAcc::<M>::default());
                for k in pattern.row_ptr[i]..pattern.row_ptr[i + 1] {
                    let j = pattern.cols[k] as usize;
                    ax.add(block(vals, k), &x[j * B..(j + 1) * B]);
                    av.add(block(vals, k), &v[j * B..(j + 1) * B]);
                }
                let (sx, sv) = (ax.sum(), av.sum());
                for r in 0..B {
                    yi[r] = T::from_f64(sx[r]);
                    wi[r] = T::from_f64(sv[r]);
                }
            }
        })
    });
}

/// Number of independent partial sums in [`dot`]: breaks the serial dependency of a
/// floating-point sum so the products vectorize (8 lanes = 4 SSE2 f64 adds in flight).
const DOT_LANES: usize = 8;

/// a . b over one slice pair, in f64 with [`DOT_LANES`] partial sums.
#[inline(always)]
pub fn dot_serial<S: Scalar, T: Scalar>(a: &[S], b: &[T]) -> f64 {
    let mut lanes = [0.0f64; DOT_LANES];
    let (ac, bc) = (a.chunks_exact(DOT_LANES), b.chunks_exact(DOT_LANES));
    let tail: f64 = ac.remainder().iter().zip(bc.remainder()).map(|(x, y)| x.to_f64() * y.to_f64()).sum();
    for (x, y) in ac.zip(bc) {
        for l in 0..DOT_LANES {
            lanes[l] += x[l].to_f64() * y[l].to_f64();
        }
    }
    lanes.iter().sum::<f64>() + tail
}

pub fn dot<S: Scalar, T: Scalar>(a: &[S], b: &[T]) -> f64 {
    const CHUNK: usize = 8192;
    a.par_chunks(CHUNK).zip(b.par_chunks(CHUNK)).map(|(x, y)| dot_serial(x, y)).sum()
}

pub fn norm<T: Scalar>(a: &[T]) -> f64 {
    dot(a, a).sqrt()
}

/// y += alpha x
pub fn axpy<S: Scalar, T: Scalar>(alpha: f64, x: &[S], y: &mut [T]) {
    y.par_iter_mut().zip(x).with_min_len(4096).for_each(|(yi, xi)| *yi = T::from_f64(yi.to_f64() + alpha * xi.to_f64()));
}

/// A copy of `v` in precision T.
pub fn convert<S: Scalar, T: Scalar>(v: &[S]) -> Vec<T> {
    v.par_iter().with_min_len(4096).map(|x| T::from_f64(x.to_f64())).collect()
}

/// `out` = `v` in precision T, reusing `out`'s storage.
pub fn convert_into<S: Scalar, T: Scalar>(v: &[S], out: &mut Vec<T>) {
    out.resize(v.len(), T::default());
    out.par_iter_mut().zip(v).with_min_len(4096).for_each(|(o, x)| *o = T::from_scalar(*x));
}

/// Consecutive disjoint mutable slices of `data` of the given lengths (one per row
/// partition), so that threads can write them in parallel.
pub(crate) fn split_by<'a, T>(mut data: &'a mut [T], lengths: impl Iterator<Item = usize>) -> Vec<&'a mut [T]> {
    let mut out = Vec::new();
    for len in lengths {
        let (head, tail) = data.split_at_mut(len);
        out.push(head);
        data = tail;
    }
    out
}

/// Invert a 4x4 block (row-major) by Gauss-Jordan with partial pivoting; None if singular.
pub fn invert4(a: &[f64]) -> Option<[f64; BB]> {
    let mut m = [[0.0; 2 * B]; B];
    for r in 0..B {
        for c in 0..B {
            m[r][c] = a[r * B + c];
        }
        m[r][B + r] = 1.0;
    }
    let scale = a.iter().fold(0.0f64, |s, v| s.max(v.abs()));
    for c in 0..B {
        let p = (c..B).max_by(|&i, &j| m[i][c].abs().total_cmp(&m[j][c].abs()))?;
        if !(m[p][c].abs() > 1e-300 && m[p][c].abs() > 1e-14 * scale) {
            return None;
        }
        m.swap(c, p);
        let inv = 1.0 / m[c][c];
        for k in 0..2 * B {
            m[c][k] *= inv;
        }
        for r in 0..B {
            if r != c {
                let f = m[r][c];
                if f != 0.0 {
                    for k in 0..2 * B {
                        m[r][k] -= f * m[c][k];
                    }
                }
            }
        }
    }
    let mut out = [0.0; BB];
    for r in 0..B {
        for c in 0..B {
            out[r * B + c] = m[r][B + c];
        }
    }
    Some(out)
}

/// c = a * b for 4x4 blocks.
#[inline]
pub fn mul4(a: &[f64; BB], b: &[f64; BB]) -> [f64; BB] {
    let mut c = [0.0; BB];
    for r in 0..B {
        for k in 0..B {
            let ark = a[r * B + k];
            for j in 0..B {
                c[r * B + j] += ark * b[k * B + j];
            }
        }
    }
    c
}

/// Reverse Cuthill-McKee order of the node graph: `order[new] = old`. Bandwidth
/// reduction makes ILU(0) far more effective and keeps the row blocks of the
/// parallel partitions mostly self-contained.
pub fn reverse_cuthill_mckee(pattern: &BlockPattern) -> Vec<u32> {
    let n = pattern.n_rows();
    let degree = |i: usize| pattern.row_ptr[i + 1] - pattern.row_ptr[i];
    let mut visited = vec![false; n];
    let mut order: Vec<u32> = Vec::with_capacity(n);
    let mut by_degree: Vec<usize> = (0..n).collect();
    by_degree.sort_by_key(|&i| degree(i));
    for &seed in &by_degree {
        if visited[seed] {
            continue;
        }
        let start = pseudo_peripheral(pattern, seed);
        let begin = order.len();
        visited[start] = true;
        order.push(start as u32);
        let mut head = begin;
        while head < order.len() {
            let i = order[head] as usize;
            head += 1;
            let mut next: Vec<usize> = pattern.cols[pattern.row_ptr[i]..pattern.row_ptr[i + 1]]
                .iter()
                .map(|&j| j as usize)
                .filter(|&j| !visited[j])
                .collect();
            next.sort_by_key(|&j| degree(j));
            for j in next {
                visited[j] = true;
                order.push(j as u32);
            }
        }
    }
    order.reverse();
    order
}

/// Last node of a BFS from `seed`, repeated twice: a node far from the others.
fn pseudo_peripheral(pattern: &BlockPattern, seed: usize) -> usize {
    let mut start = seed;
    for _ in 0..2 {
        let n = pattern.n_rows();
        let mut level = vec![usize::MAX; n];
        let mut queue = std::collections::VecDeque::from([start]);
        level[start] = 0;
        let mut last = start;
        while let Some(i) = queue.pop_front() {
            last = i;
            for &j in &pattern.cols[pattern.row_ptr[i]..pattern.row_ptr[i + 1]] {
                if level[j as usize] == usize::MAX {
                    level[j as usize] = level[i] + 1;
                    queue.push_back(j as usize);
                }
            }
        }
        start = last;
    }
    start
}

/// A test pattern of `n` nodes: a tet at each node i with the nodes i + `offsets`
/// (`offsets[0]` = 0, the largest last), as far as they exist.
#[cfg(test)]
pub(crate) fn chain_pattern(n: usize, offsets: [u32; 4]) -> BlockPattern {
    let tets: Vec<[u32; 4]> = (0..n as u32 - offsets[3]).map(|i| offsets.map(|o| i + o)).collect();
    BlockPattern::from_tets(n, &tets)
}

/// A test matrix on `pattern`: every entry a fixed pseudo-random value in [-0.5, 0.5)
/// (repeating every `period` entries), plus `diagonal(node)` on each node block's
/// diagonal, large enough to make the matrix factor without pivoting.
#[cfg(test)]
pub(crate) fn test_matrix(pattern: &BlockPattern, period: usize, diagonal: impl Fn(usize) -> f64) -> Vec<f64> {
    let mut vals: Vec<f64> = (0..pattern.cols.len() * BB).map(|k| ((k * 7919) % period) as f64 / period as f64 - 0.5).collect();
    for (node, &d) in pattern.diag.iter().enumerate() {
        for c in 0..B {
            vals[d * BB + c * B + c] += diagonal(node);
        }
    }
    vals
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lane_sums_equal_the_plain_sums() {
        // Lengths that are and are not multiples of the lane count, across chunk borders.
        for n in [0, 1, 7, 8, 9, 8192 + 13] {
            let a: Vec<f32> = (0..n).map(|i| ((i * 37) % 11) as f32 - 5.0).collect();
            let b: Vec<f64> = (0..n).map(|i| ((i * 13) % 7) as f64 * 0.5).collect();
            let plain: f64 = a.iter().zip(&b).map(|(x, y)| *x as f64 * y).sum();
            assert_eq!(dot(&a, &b), plain, "n = {n}");
        }
    }

    #[test]
    fn block_products_match_the_row_major_definition() {
        let a: [f64; BB] = std::array::from_fn(|k| k as f64 - 7.5);
        let x = [1.0, -2.0, 0.5, 3.0];
        let mut acc = BlockAcc::<f64>::default();
        acc.add(&a, &x);
        acc.add(&a, &x);
        let expected: [f64; B] = std::array::from_fn(|r| 2.0 * (0..B).map(|c| a[r * B + c] * x[c]).sum::<f64>());
        assert_eq!(acc.sum(), expected);
        let a32: [f32; BB] = a.map(|v| v as f32);
        let mut acc32 = BlockAcc::<f32>::default();
        acc32.add(&a32, &x);
        let single: [f64; B] = expected.map(|v| v / 2.0);
        assert_eq!(acc32.sum(), single, "small integers and halves are exact in f32");
    }
}
