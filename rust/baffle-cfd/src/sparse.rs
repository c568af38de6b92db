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

    /// Position of block (row, col), if in the pattern.
    pub fn position(&self, row: usize, col: u32) -> Option<usize> {
        let range = self.row_ptr[row]..self.row_ptr[row + 1];
        self.cols[range.clone()].binary_search(&col).ok().map(|k| range.start + k)
    }
}

/// Storage precision of matrix values and Krylov vectors. The inner linear solves run
/// in f32 (half the memory traffic of the bandwidth-bound kernels: block SpMV, ILU
/// triangular solves, Gram-Schmidt), while residuals and the solution stay in f64
/// (see `linear::solve_refined`). Reductions always accumulate in f64.
pub trait Scalar: Copy + Default + Send + Sync + PartialEq + std::fmt::Debug + 'static {
    fn from_f64(v: f64) -> Self;
    fn to_f64(self) -> f64;
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

/// y = A x for block values `vals` (row-major 4x4 per block) on `pattern`.
pub fn spmv<M: Scalar, T: Scalar>(pattern: &BlockPattern, vals: &[M], x: &[T], y: &mut [T]) {
    y.par_chunks_mut(B).enumerate().for_each(|(i, yi)| {
        let mut acc = [0.0; B];
        for k in pattern.row_ptr[i]..pattern.row_ptr[i + 1] {
            let j = pattern.cols[k] as usize;
            let ax = mulv4(&vals[k * BB..(k + 1) * BB], &x[j * B..(j + 1) * B]);
            for r in 0..B {
                acc[r] += ax[r];
            }
        }
        for r in 0..B {
            yi[r] = T::from_f64(acc[r]);
        }
    });
}

pub fn dot<S: Scalar, T: Scalar>(a: &[S], b: &[T]) -> f64 {
    a.par_iter().zip(b).with_min_len(4096).map(|(x, y)| x.to_f64() * y.to_f64()).sum()
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
pub fn mul4(a: &[f64], b: &[f64]) -> [f64; BB] {
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

/// y = a x for a 4x4 block, in f64 whatever the storage precision.
#[inline]
pub fn mulv4<M: Scalar, T: Scalar>(a: &[M], x: &[T]) -> [f64; B] {
    let x = [x[0].to_f64(), x[1].to_f64(), x[2].to_f64(), x[3].to_f64()];
    let mut y = [0.0; B];
    for r in 0..B {
        y[r] = a[r * B].to_f64() * x[0] + a[r * B + 1].to_f64() * x[1] + a[r * B + 2].to_f64() * x[2] + a[r * B + 3].to_f64() * x[3];
    }
    y
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
