//! Linear algebra for the coupled (u, v, w, p) system: block ILU(0) in parallel
//! partitions, right-preconditioned restarted GMRES, and mixed-precision iterative
//! refinement around it (f32 inner solves, f64 residuals).

use std::ops::Range;

use rayon::prelude::*;

use crate::sparse::{axpy, block, dot_serial, invert4, mul4, norm, split_by, wide, BlockAcc, BlockPattern, Scalar, B, BB};

/// Block-Jacobi over contiguous row partitions of block ILU(0): each partition is
/// factored and solved independently (couplings between partitions are dropped),
/// so factorization and triangular solves run in parallel on the 2 cores. The
/// factorization runs in f64; the factors are stored in precision T.
pub struct BlockIlu<T: Scalar = f64> {
    parts: Vec<Range<usize>>,
    lower: Triangle<T>,
    upper: Triangle<T>,
    /// Inverses of the pivot blocks, in the backward sweep's order (as `upper`'s rows).
    diag_inv: Vec<[T; BB]>,
    /// The f64 factorization's working copy, kept so refactoring every step does not
    /// allocate (and page-fault in) a fresh copy of the matrix.
    work: Vec<f64>,
    work_inv: Vec<[f64; BB]>,
}

/// The strictly lower (or upper) blocks of the factors that lie inside their row's
/// partition, stored in the order a triangular sweep reads them: the forward sweep
/// then streams L alone and the backward sweep U alone, instead of each dragging the
/// whole matrix through the cache, and both read their memory in ascending order.
///
/// Within a row the block of the nearest column comes last. That block multiplies the
/// unknown the sweep solved just before (RCM neighbours are adjacent rows), so the
/// rest of the row's sum can proceed while the previous row is still being solved.
/// Stored the other way round (U's columns ascending, rows descending) the backward
/// sweep took 4x the forward sweep's time on p2's pattern (12.0 against 2.7 ms, f32).
struct Triangle<T> {
    /// The s-th row the sweep visits has blocks `row_ptr[s]..row_ptr[s + 1]`: for L row
    /// s is global row s, for U see [`backward_order`].
    row_ptr: Vec<usize>,
    cols: Vec<u32>,
    /// Position of each block in the full pattern, to refill `vals` after refactoring.
    source: Vec<usize>,
    vals: Vec<T>,
}

impl<T: Scalar> Triangle<T> {
    fn new(pattern: &BlockPattern, parts: &[Range<usize>], lower: bool) -> Self {
        let (mut row_ptr, mut source) = (vec![0], Vec::new());
        for rows in parts {
            let inside = |p: &usize| rows.contains(&(pattern.cols[*p] as usize));
            if lower {
                for i in rows.clone() {
                    source.extend((pattern.row_ptr[i]..pattern.diag[i]).filter(inside));
                    row_ptr.push(source.len());
                }
            } else {
                for i in rows.clone().rev() {
                    source.extend((pattern.diag[i] + 1..pattern.row_ptr[i + 1]).rev().filter(inside));
                    row_ptr.push(source.len());
                }
            }
        }
        let cols = source.iter().map(|&p| pattern.cols[p]).collect();
        Triangle { row_ptr, cols, source, vals: Vec::new() }
    }

    fn fill(&mut self, lu: &[f64]) {
        self.vals.resize(self.source.len() * BB, T::default());
        self.vals.par_chunks_mut(BB).zip(&self.source).with_min_len(1024).for_each(|(v, &p)| {
            v.iter_mut().zip(&lu[p * BB..(p + 1) * BB]).for_each(|(a, b)| *a = T::from_f64(*b));
        });
    }

    /// sum over the s-th swept row's blocks of block x z_col (z holds the partition
    /// starting at row r0).
    #[inline(always)]
    fn row_product<V: Scalar>(&self, s: usize, z: &[V], r0: usize) -> [f64; B] {
        let mut acc = BlockAcc::<T>::default();
        for p in self.row_ptr[s]..self.row_ptr[s + 1] {
            let k = self.cols[p] as usize - r0;
            acc.add(block(&self.vals, p), &z[k * B..(k + 1) * B]);
        }
        acc.sum()
    }
}

/// Global rows in the backward sweep's order: each partition from its last row to its
/// first, partitions in order, so the s-th row swept in partition `rows` is stored at
/// `rows.start + s`.
fn backward_order(parts: &[Range<usize>]) -> impl Iterator<Item = usize> + '_ {
    parts.iter().flat_map(|rows| rows.clone().rev())
}

/// Split rows into `n` contiguous ranges of about equal block count.
pub fn partitions(pattern: &BlockPattern, n: usize) -> Vec<Range<usize>> {
    let rows = pattern.n_rows();
    let total = pattern.cols.len();
    let mut out = Vec::with_capacity(n);
    let mut start = 0;
    for p in 1..=n {
        let target = total * p / n;
        let mut end = start;
        while end < rows && (pattern.row_ptr[end] < target || p == n) {
            end += 1;
        }
        out.push(start..end);
        start = end;
    }
    out.retain(|r| !r.is_empty());
    out
}

impl<T: Scalar> BlockIlu<T> {
    /// Factor on `parts`, contiguous row ranges that cover the rows in order (as
    /// [`partitions`] makes them). Err(row) if a pivot block is singular.
    pub fn factor(pattern: &BlockPattern, vals: &[f64], parts: Vec<Range<usize>>) -> Result<Self, usize> {
        debug_assert!(parts.first().is_none_or(|r| r.start == 0) && parts.windows(2).all(|w| w[0].end == w[1].start));
        debug_assert_eq!(parts.last().map_or(0, |r| r.end), pattern.n_rows());
        let (lower, upper) = (Triangle::new(pattern, &parts, true), Triangle::new(pattern, &parts, false));
        let mut ilu = BlockIlu { parts, lower, upper, diag_inv: Vec::new(), work: Vec::new(), work_inv: Vec::new() };
        ilu.refactor(pattern, vals)?;
        Ok(ilu)
    }

    /// Factor new values on the same pattern and partitions, reusing the storage.
    pub fn refactor(&mut self, pattern: &BlockPattern, vals: &[f64]) -> Result<(), usize> {
        self.work.clear();
        self.work.extend_from_slice(vals);
        self.work_inv.resize(pattern.n_rows(), [0.0; BB]);
        let parts = &self.parts;
        let lu_parts = split_by(&mut self.work, parts.iter().map(|r| pattern.blocks_in(r) * BB));
        let inv_parts = split_by(&mut self.work_inv, parts.iter().map(|r| r.len()));
        lu_parts
            .into_par_iter()
            .zip(inv_parts)
            .zip(parts.par_iter())
            .map(|((lu_p, inv_p), rows)| factor_part(pattern, lu_p, inv_p, rows.clone()))
            .collect::<Result<Vec<()>, usize>>()?;
        self.lower.fill(&self.work);
        self.upper.fill(&self.work);
        self.diag_inv.clear();
        self.diag_inv.extend(backward_order(&self.parts).map(|i| self.work_inv[i].map(T::from_f64)));
        Ok(())
    }

    /// z = M^-1 r.
    pub fn apply<V: Scalar>(&self, r: &[V], z: &mut [V]) {
        let z_parts = split_by(z, self.parts.iter().map(|r| r.len() * B));
        z_parts.into_par_iter().zip(self.parts.par_iter()).for_each(|(z_p, rows)| wide(#[inline(always)] || self.solve_part(rows.clone(), r, z_p)));
    }

    /// Forward then backward sweep of one partition; `z` holds that partition's rows.
    #[inline(always)]
    fn solve_part<V: Scalar>(&self, rows: Range<usize>, r: &[V], z: &mut [V]) {
        let r0 = rows.start;
        // Forward: z_i = r_i - sum_(k<i) L_ik z_k (unit lower blocks).
        for i in rows.clone() {
            let s = self.lower.row_product(i, z, r0);
            for c in 0..B {
                z[(i - r0) * B + c] = V::from_f64(r[i * B + c].to_f64() - s[c]);
            }
        }
        // Backward: z_i = D_i^-1 (z_i - sum_(j>i) U_ij z_j).
        for (swept, i) in (r0..).zip(rows.rev()) {
            let s = self.upper.row_product(swept, z, r0);
            let y: [f64; B] = [0, 1, 2, 3].map(|c| z[(i - r0) * B + c].to_f64() - s[c]);
            let mut d = BlockAcc::<T>::default();
            d.add(&self.diag_inv[swept], &y);
            z[(i - r0) * B..(i - r0 + 1) * B].copy_from_slice(&d.sum().map(V::from_f64));
        }
    }
}

fn factor_part(pattern: &BlockPattern, lu: &mut [f64], inv: &mut [[f64; BB]], rows: Range<usize>) -> Result<(), usize> {
    let base = pattern.row_ptr[rows.start];
    let mut marker = vec![usize::MAX; rows.len()];
    for i in rows.clone() {
        let row = pattern.row_ptr[i]..pattern.row_ptr[i + 1];
        for p in row.clone() {
            let j = pattern.cols[p] as usize;
            if rows.contains(&j) {
                marker[j - rows.start] = p;
            }
        }
        for p in pattern.row_ptr[i]..pattern.diag[i] {
            let k = pattern.cols[p] as usize;
            if k < rows.start {
                continue;
            }
            let l = mul4(block(lu, p - base), &inv[k - rows.start]);
            lu[(p - base) * BB..(p - base + 1) * BB].copy_from_slice(&l);
            for q in pattern.diag[k] + 1..pattern.row_ptr[k + 1] {
                let j = pattern.cols[q] as usize;
                if j >= rows.end || marker[j - rows.start] == usize::MAX {
                    continue;
                }
                let target = marker[j - rows.start];
                let update = mul4(&l, block(lu, q - base));
                for (t, u) in lu[(target - base) * BB..(target - base + 1) * BB].iter_mut().zip(update) {
                    *t -= u;
                }
            }
        }
        let d = pattern.diag[i] - base;
        inv[i - rows.start] = invert4(&lu[d * BB..(d + 1) * BB]).ok_or(i)?;
        for p in row {
            let j = pattern.cols[p] as usize;
            if rows.contains(&j) {
                marker[j - rows.start] = usize::MAX;
            }
        }
    }
    Ok(())
}

/// The preconditioner M of GMRES: z = M^-1 v, and with it the product A z the Arnoldi
/// step needs next. A preconditioner that forms most of A z on its way (the two-level
/// one: `solver::TwoLevel`) gives it for less than another product.
pub trait Preconditioner<T> {
    fn apply(&self, v: &[T], z: &mut [T]);

    /// z = M^-1 v and az = A z (A applied by `apply_a`).
    fn apply_with_product(&self, apply_a: &dyn Fn(&[T], &mut [T]), v: &[T], z: &mut [T], az: &mut [T]) {
        self.apply(v, z);
        apply_a(z, az);
    }
}

impl<S: Scalar, V: Scalar> Preconditioner<V> for BlockIlu<S> {
    fn apply(&self, v: &[V], z: &mut [V]) {
        BlockIlu::apply(self, v, z);
    }
}

/// Outcome of a GMRES solve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GmresOutcome {
    pub iterations: usize,
    /// Final ||b - A x|| / ||b|| (true residual, recomputed at each restart and at the end).
    pub relative_residual: f64,
    pub converged: bool,
}

/// Solve A x = b (x starts at 0) by GMRES(restart) preconditioned on the right, so
/// the residual it monitors is the true one: ||b - A x|| <= tol ||b||. Vectors are
/// stored in precision T; the Hessenberg least-squares problem is in f64.
pub fn gmres<T: Scalar>(
    apply_a: &dyn Fn(&[T], &mut [T]),
    apply_m: &dyn Preconditioner<T>,
    b: &[T],
    x: &mut [T],
    tol: f64,
    restart: usize,
    max_iterations: usize,
) -> GmresOutcome {
    let n = b.len();
    x.iter_mut().for_each(|v| *v = T::default());
    let b_norm = norm(b);
    if b_norm == 0.0 {
        return GmresOutcome { iterations: 0, relative_residual: 0.0, converged: true };
    }
    let mut r = b.to_vec();
    let mut work = vec![T::default(); n];
    let mut z = vec![T::default(); n];
    let mut iterations = 0;
    let mut rel = 1.0;
    while iterations < max_iterations {
        let beta = norm(&r);
        rel = beta / b_norm;
        if !rel.is_finite() || rel <= tol {
            break;
        }
        let mut basis: Vec<Vec<T>> = vec![scaled(&r, 1.0 / beta)];
        let mut h = vec![vec![0.0; restart]; restart + 1];
        let (mut cs, mut sn) = (vec![0.0; restart], vec![0.0; restart]);
        let mut g = vec![0.0; restart + 1];
        g[0] = beta;
        let mut k_used = 0;
        for k in 0..restart.min(max_iterations - iterations) {
            apply_m.apply_with_product(apply_a, &basis[k], &mut z, &mut work);
            let (c, next_norm) = orthogonalize_twice(&basis, &mut work);
            (0..=k).for_each(|j| h[j][k] = c[j]);
            h[k + 1][k] = next_norm;
            for j in 0..k {
                let t = cs[j] * h[j][k] + sn[j] * h[j + 1][k];
                h[j + 1][k] = -sn[j] * h[j][k] + cs[j] * h[j + 1][k];
                h[j][k] = t;
            }
            let d = (h[k][k] * h[k][k] + h[k + 1][k] * h[k + 1][k]).sqrt();
            (cs[k], sn[k]) = if d > 0.0 { (h[k][k] / d, h[k + 1][k] / d) } else { (1.0, 0.0) };
            h[k][k] = d;
            h[k + 1][k] = 0.0;
            g[k + 1] = -sn[k] * g[k];
            g[k] *= cs[k];
            iterations += 1;
            k_used = k + 1;
            let estimate = g[k + 1].abs() / b_norm;
            if std::env::var_os("BAFFLE_CFD_GMRES_TRACE").is_some() {
                eprintln!("gmres {iterations}: {estimate:.3e}");
            }
            if estimate <= tol || !estimate.is_finite() || next_norm == 0.0 {
                break;
            }
            basis.push(scaled(&work, 1.0 / next_norm));
        }
        // y = H^-1 g, x += M^-1 (V y)
        let mut y = vec![0.0; k_used];
        for i in (0..k_used).rev() {
            let s: f64 = (i + 1..k_used).map(|j| h[i][j] * y[j]).sum();
            y[i] = if h[i][i] != 0.0 { (g[i] - s) / h[i][i] } else { 0.0 };
        }
        let mut update = vec![T::default(); n];
        for (j, yj) in y.iter().enumerate() {
            axpy(*yj, &basis[j], &mut update);
        }
        apply_m.apply(&update, &mut z);
        axpy(1.0, &z, x);
        apply_a(x, &mut work);
        r.par_iter_mut().zip(b.par_iter().zip(&work)).for_each(|(ri, (bi, ai))| *ri = T::from_f64(bi.to_f64() - ai.to_f64()));
        rel = norm(&r) / b_norm;
        if !rel.is_finite() || rel <= tol {
            break;
        }
    }
    GmresOutcome { iterations, relative_residual: rel, converged: rel <= tol }
}

/// s v, stored in precision T.
fn scaled<S: Scalar, T: Scalar>(v: &[S], s: f64) -> Vec<T> {
    v.par_iter().with_min_len(4096).map(|x| T::from_f64(x.to_f64() * s)).collect()
}

/// Vector length each thread works on at a time in [`orthogonalize_twice`]: the f64
/// accumulator of a chunk (16 KB) then stays in L1 while the basis streams past it.
const GS_CHUNK: usize = 2048;

/// w -= V (V^T w), twice, for the orthonormal columns V = `basis` (CGS2: classical
/// Gram-Schmidt with one full reorthogonalization, orthogonal to working precision;
/// Giraud, Langou and Rozloznik 2005). Returns the summed coefficients V^T w of both
/// rounds and the final ||w||.
///
/// Three passes over the basis instead of four: the first round's update and the
/// second round's dot products work chunk by chunk in one pass (a chunk of w is final
/// for round one once its own update is done), and the second update also sums
/// ||w||^2. The reorthogonalization used to be conditional (Daniel-Gragg-Kaufman-Stewart,
/// 0.7), but on p2's systems it was taken at every iteration.
fn orthogonalize_twice<T: Scalar>(basis: &[Vec<T>], w: &mut [T]) -> (Vec<f64>, f64) {
    let k = basis.len();
    let add = |mut a: Vec<f64>, b: Vec<f64>| {
        a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
        a
    };
    let first = w.par_chunks(GS_CHUNK).enumerate().map(|(ci, wc)| wide(#[inline(always)] || chunk_dots(basis, ci * GS_CHUNK, wc))).reduce(|| vec![0.0; k], add);
    let second = w
        .par_chunks_mut(GS_CHUNK)
        .enumerate()
        .map(|(ci, wc)| {
            wide(#[inline(always)] || {
                subtract_chunk(basis, ci * GS_CHUNK, wc, &first);
                chunk_dots(basis, ci * GS_CHUNK, wc)
            })
        })
        .reduce(|| vec![0.0; k], add);
    let norm_sq: f64 = w
        .par_chunks_mut(GS_CHUNK)
        .enumerate()
        .map(|(ci, wc)| {
            wide(#[inline(always)] || {
                subtract_chunk(basis, ci * GS_CHUNK, wc, &second);
                dot_serial(wc, wc)
            })
        })
        .sum();
    (add(first, second), norm_sq.sqrt())
}

/// The dot products of chunk `wc` (starting at `off`) with each basis vector's chunk.
#[inline(always)]
fn chunk_dots<T: Scalar>(basis: &[Vec<T>], off: usize, wc: &[T]) -> Vec<f64> {
    basis.iter().map(|v| dot_serial(&v[off..off + wc.len()], wc)).collect()
}

/// wc -= sum_j c_j v_j on one chunk, accumulated in f64 and rounded once.
#[inline(always)]
fn subtract_chunk<T: Scalar>(basis: &[Vec<T>], off: usize, wc: &mut [T], c: &[f64]) {
    let mut acc = [0.0f64; GS_CHUNK];
    let acc = &mut acc[..wc.len()];
    acc.iter_mut().zip(wc.iter()).for_each(|(a, x)| *a = x.to_f64());
    for (v, cj) in basis.iter().zip(c) {
        acc.iter_mut().zip(&v[off..off + wc.len()]).for_each(|(a, y)| *a -= cj * y.to_f64());
    }
    wc.iter_mut().zip(acc.iter()).for_each(|(x, a)| *x = T::from_f64(*a));
}

/// A solve that starts from a guess stops at this fraction of the tolerance. Its
/// residual leaves more error in what the residual hardly sees: on p3's 1.25 mm mesh
/// (60 steps, previous step's update as the guess) dp's error against a converged
/// (1e-7) run was 8e-6 rms over steps 10-60 at the full tolerance 1e-4, against 1.7e-6
/// from zero; at half of it 1.4e-6, with 12 instead of 15 GMRES iterations a step.
pub const GUESS_TOLERANCE_FACTOR: f64 = 0.5;

/// How many f32 GMRES solves [`solve_refined`] may chain.
const MAX_REFINEMENT_ROUNDS: usize = 4;
/// The smallest relative residual asked of one f32 GMRES solve: f32 has ~7 digits, and
/// rounding in the f32 operator stops the residual decreasing somewhere below 1e-5.
const LOW_PRECISION_FLOOR: f64 = 1e-5;
/// A refinement round must cut the f64 residual at least this much, or the f32 copy
/// of the operator is too coarse for this system (eps_f32 x condition >~ 1).
const MIN_ROUND_REDUCTION: f64 = 0.5;

/// Solve A x = b to ||b - A x|| <= tol ||b|| by mixed-precision iterative refinement
/// (Carson and Higham 2018, GMRES-IR): GMRES runs on f32 copies of the operator and
/// vectors (`apply_a_low`, `apply_m_low`: half the memory traffic), then the true
/// residual of the accumulated f64 solution is formed with the f64 operator `apply_a`;
/// while it misses the tolerance, GMRES solves again for the correction. When a round
/// stalls (ill-conditioned systems such as steady Stokes flow, where f32 rounding of
/// the operator is amplified beyond the tolerance), the rest is solved by f64 GMRES
/// (`apply_m`). The returned residual is always the f64 one.
///
/// `x` holds the initial guess (zeros: none). The target stays relative to ||b||, and
/// from a guess it is [`GUESS_TOLERANCE_FACTOR`] times tighter; a guess whose residual
/// is not below ||b|| is dropped for zero. `guess_product` is A x of that guess when the
/// caller has it (the solver forms it in the same pass over the matrix as its residual).
#[allow(clippy::too_many_arguments)]
pub fn solve_refined(
    apply_a: &dyn Fn(&[f64], &mut [f64]),
    apply_m: &dyn Preconditioner<f64>,
    apply_a_low: &dyn Fn(&[f32], &mut [f32]),
    apply_m_low: &dyn Preconditioner<f32>,
    b: &[f64],
    x: &mut [f64],
    guess_product: Option<&[f64]>,
    tol: f64,
    restart: usize,
    max_iterations: usize,
) -> GmresOutcome {
    let b_norm = norm(b);
    if b_norm == 0.0 {
        x.iter_mut().for_each(|v| *v = 0.0);
        return GmresOutcome { iterations: 0, relative_residual: 0.0, converged: true };
    }
    let mut residual = b.to_vec();
    let mut work = vec![0.0; b.len()];
    let mut iterations = 0;
    let mut r_norm = b_norm;
    if x.iter().any(|&v| v != 0.0) {
        match guess_product {
            Some(ax) => work.copy_from_slice(ax),
            None => apply_a(x, &mut work),
        }
        residual.par_iter_mut().zip(b.par_iter().zip(&work)).for_each(|(ri, (bi, ai))| *ri = bi - ai);
        r_norm = norm(&residual);
        if !(r_norm < b_norm) {
            x.iter_mut().for_each(|v| *v = 0.0);
            residual.copy_from_slice(b);
            r_norm = b_norm;
        }
    }
    let tol = if r_norm < b_norm { tol * GUESS_TOLERANCE_FACTOR } else { tol };
    for _ in 0..MAX_REFINEMENT_ROUNDS {
        if r_norm <= tol * b_norm || iterations >= max_iterations {
            break;
        }
        // Scale to unit norm so the f32 copy keeps its full range whatever the units.
        let rhs: Vec<f32> = scaled(&residual, 1.0 / r_norm);
        let mut dx = vec![0.0f32; b.len()];
        let inner_tol = (tol * b_norm / r_norm).max(LOW_PRECISION_FLOOR);
        // One restart cycle at most: an f32 solve that stalls above its target is
        // caught by the f64 residual check below instead of burning the budget.
        let out = gmres(apply_a_low, apply_m_low, &rhs, &mut dx, inner_tol, restart, restart.min(max_iterations - iterations));
        iterations += out.iterations;
        axpy(r_norm, &dx, x);
        apply_a(x, &mut work);
        residual.par_iter_mut().zip(b.par_iter().zip(&work)).for_each(|(ri, (bi, ai))| *ri = bi - ai);
        let previous = r_norm;
        r_norm = norm(&residual);
        if !(r_norm <= MIN_ROUND_REDUCTION * previous) {
            break;
        }
    }
    if r_norm <= tol * b_norm || !r_norm.is_finite() || iterations >= max_iterations {
        let rel = r_norm / b_norm;
        return GmresOutcome { iterations, relative_residual: rel, converged: rel <= tol };
    }
    let mut dx = vec![0.0; b.len()];
    let out = gmres(apply_a, apply_m, &residual, &mut dx, tol * b_norm / r_norm, restart, max_iterations - iterations);
    axpy(1.0, &dx, x);
    let rel = out.relative_residual * r_norm / b_norm;
    GmresOutcome { iterations: iterations + out.iterations, relative_residual: rel, converged: rel <= tol }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sparse::{convert, spmv};

    /// A 1D chain of nodes with diagonally dominant nonsymmetric 4x4 blocks.
    fn chain(n: usize) -> (BlockPattern, Vec<f64>) {
        let pattern = crate::sparse::chain_pattern(n, [0, 1, 2, 3]);
        let mut vals = vec![0.0; pattern.cols.len() * BB];
        for i in 0..n {
            for p in pattern.row_ptr[i]..pattern.row_ptr[i + 1] {
                let j = pattern.cols[p] as usize;
                for r in 0..B {
                    for c in 0..B {
                        let v = if i == j && r == c { 10.0 } else { 0.3 * ((i + 2 * j + r + 3 * c) % 5) as f64 - 0.5 };
                        vals[p * BB + r * B + c] = v;
                    }
                }
            }
        }
        (pattern, vals)
    }

    #[test]
    fn ilu_gmres_solves_block_system() {
        let n = 200;
        let (pattern, vals) = chain(n);
        let x_true: Vec<f64> = (0..n * B).map(|i| (i as f64 * 0.37).sin()).collect();
        let mut b = vec![0.0; n * B];
        spmv(&pattern, &vals, &x_true, &mut b);
        for parts in [1, 2] {
            let ilu = BlockIlu::<f64>::factor(&pattern, &vals, partitions(&pattern, parts)).unwrap();
            let mut x = vec![0.0; n * B];
            let out = gmres(
                &|v, y| spmv(&pattern, &vals, v, y),
                &ilu,
                &b,
                &mut x,
                1e-10,
                30,
                300,
            );
            assert!(out.converged, "{parts} partitions: {out:?}");
            let err = x.iter().zip(&x_true).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
            assert!(err < 1e-8, "{parts} partitions: error {err}");
        }
    }

    #[test]
    fn mixed_precision_refinement_reaches_an_f64_tolerance() {
        // f32 inner solves alone stall near 1e-6..1e-7; the f64 residual and repeated
        // corrections reach 1e-11, and the reported residual is the f64 one.
        let n = 300;
        let (pattern, vals) = chain(n);
        let vals_low: Vec<f32> = convert(&vals);
        let x_true: Vec<f64> = (0..n * B).map(|i| 1e3 * (i as f64 * 0.37).sin()).collect();
        let mut b = vec![0.0; n * B];
        spmv(&pattern, &vals, &x_true, &mut b);
        let ilu = BlockIlu::<f32>::factor(&pattern, &vals, partitions(&pattern, 2)).unwrap();
        let mut x = vec![0.0; n * B];
        let out = solve_refined(
            &|v, y| spmv(&pattern, &vals, v, y),
            &ilu,
            &|v, y| spmv(&pattern, &vals_low, v, y),
            &ilu,
            &b,
            &mut x,
            None,
            1e-11,
            30,
            500,
        );
        let mut ax = vec![0.0; n * B];
        spmv(&pattern, &vals, &x, &mut ax);
        let true_rel = norm(&b.iter().zip(&ax).map(|(p, q)| p - q).collect::<Vec<f64>>()) / norm(&b);
        assert!(out.converged && out.relative_residual <= 1e-11, "{out:?}");
        assert!((true_rel - out.relative_residual).abs() <= 1e-3 * out.relative_residual.max(1e-16) + 1e-15, "{true_rel} vs {out:?}");
        let err = x.iter().zip(&x_true).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(err < 1e-6, "max error {err}");
        // A zero right-hand side needs no iteration.
        let out = solve_refined(&|v, y| spmv(&pattern, &vals, v, y), &ilu, &|v, y| spmv(&pattern, &vals_low, v, y), &ilu, &vec![0.0; n * B], &mut x, None, 1e-8, 30, 500);
        assert_eq!((out.iterations, out.converged), (0, true));
        assert!(x.iter().all(|&v| v == 0.0));
    }

    #[test]
    fn refinement_from_a_guess_meets_the_tightened_target_and_drops_a_bad_guess() {
        let n = 300;
        let (pattern, vals) = chain(n);
        let vals_low: Vec<f32> = convert(&vals);
        let x_true: Vec<f64> = (0..n * B).map(|i| (i as f64 * 0.37).sin()).collect();
        let mut b = vec![0.0; n * B];
        spmv(&pattern, &vals, &x_true, &mut b);
        let ilu = BlockIlu::<f32>::factor(&pattern, &vals, partitions(&pattern, 2)).unwrap();
        let solve = |x: &mut Vec<f64>| {
            solve_refined(&|v, y| spmv(&pattern, &vals, v, y), &ilu, &|v, y| spmv(&pattern, &vals_low, v, y), &ilu, &b, x, None, 1e-4, 30, 500)
        };
        let true_rel = |x: &[f64]| {
            let mut ax = vec![0.0; n * B];
            spmv(&pattern, &vals, x, &mut ax);
            norm(&b.iter().zip(&ax).map(|(p, q)| p - q).collect::<Vec<f64>>()) / norm(&b)
        };
        let mut from_zero = vec![0.0; n * B];
        let zero = solve(&mut from_zero);
        // A guess near the solution: fewer iterations, the tighter target, the true residual.
        let mut guessed: Vec<f64> = x_true.iter().enumerate().map(|(i, v)| v * (1.0 + 1e-2 * (i as f64 * 1.3).cos())).collect();
        let near = solve(&mut guessed);
        assert!(near.converged && near.relative_residual <= 1e-4 * GUESS_TOLERANCE_FACTOR, "{near:?}");
        assert!((true_rel(&guessed) - near.relative_residual).abs() <= 1e-6, "{near:?}");
        assert!(near.iterations < zero.iterations, "{near:?} vs {zero:?}");
        // A guess worse than zero is dropped: the solve is the one from zero.
        let mut bad: Vec<f64> = x_true.iter().map(|v| -3.0 * v).collect();
        let dropped = solve(&mut bad);
        assert_eq!((dropped, &bad), (zero, &from_zero));
    }

    #[test]
    fn f32_factors_precondition_as_well_as_f64_factors() {
        let (pattern, vals) = chain(200);
        let r: Vec<f64> = (0..200 * B).map(|i| (i as f64 * 0.11).cos()).collect();
        let (mut z64, mut z32) = (vec![0.0; r.len()], vec![0.0; r.len()]);
        BlockIlu::<f64>::factor(&pattern, &vals, partitions(&pattern, 2)).unwrap().apply(&r, &mut z64);
        BlockIlu::<f32>::factor(&pattern, &vals, partitions(&pattern, 2)).unwrap().apply(&r, &mut z32);
        let diff = z64.iter().zip(&z32).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        let scale = z64.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(diff < 1e-6 * scale, "{diff} vs {scale}");
    }

    #[test]
    fn ilu_of_a_full_pattern_is_the_exact_inverse() {
        // 4 nodes of one tet: the block pattern is full, so ILU(0) = LU per partition.
        let (pattern, vals) = chain(4);
        let ilu = BlockIlu::<f64>::factor(&pattern, &vals, partitions(&pattern, 1)).unwrap();
        let x_true: Vec<f64> = (0..16).map(|i| 1.0 + i as f64).collect();
        let mut b = vec![0.0; 16];
        spmv(&pattern, &vals, &x_true, &mut b);
        let mut x = vec![0.0; 16];
        ilu.apply(&b, &mut x);
        assert!(x.iter().zip(&x_true).all(|(a, b)| (a - b).abs() < 1e-10), "{x:?}");
    }

    /// Scalar ILU(0) of the dense expansion of `vals`, keeping only blocks inside the
    /// same partition, then the unit-lower and upper solves: the textbook IKJ
    /// algorithm (Saad, Iterative Methods, alg. 10.4), written independently of the
    /// block code.
    fn dense_ilu0_solve(pattern: &BlockPattern, vals: &[f64], parts: &[Range<usize>], r: &[f64]) -> Vec<f64> {
        let n = pattern.n_rows() * B;
        let part_of = |row: usize| parts.iter().position(|p| p.contains(&(row / B))).unwrap();
        let mut a = vec![vec![None::<f64>; n]; n];
        for i in 0..pattern.n_rows() {
            for p in pattern.row_ptr[i]..pattern.row_ptr[i + 1] {
                let j = pattern.cols[p] as usize;
                for (rc, v) in vals[p * BB..(p + 1) * BB].iter().enumerate() {
                    let (row, col) = (i * B + rc / B, j * B + rc % B);
                    if part_of(row) == part_of(col) {
                        a[row][col] = Some(*v);
                    }
                }
            }
        }
        for i in 0..n {
            for k in 0..i {
                let Some(aik) = a[i][k] else { continue };
                let lik = aik / a[k][k].unwrap();
                a[i][k] = Some(lik);
                for j in k + 1..n {
                    if let (Some(aij), Some(akj)) = (a[i][j], a[k][j]) {
                        a[i][j] = Some(aij - lik * akj);
                    }
                }
            }
        }
        let mut z = r.to_vec();
        for i in 0..n {
            z[i] -= (0..i).filter_map(|k| a[i][k].map(|l| l * z[k])).sum::<f64>();
        }
        for i in (0..n).rev() {
            z[i] = (z[i] - (i + 1..n).filter_map(|j| a[i][j].map(|u| u * z[j])).sum::<f64>()) / a[i][i].unwrap();
        }
        z
    }

    #[test]
    fn block_ilu_equals_the_scalar_ilu0_of_its_partitions() {
        // Tets that skip nodes leave holes in the pattern, so ILU(0) drops fill, and
        // three partitions drop their couplings: both must be dropped exactly as in
        // the scalar definition, whatever order the sweeps store the factors in.
        let n_nodes = 30;
        let pattern = crate::sparse::chain_pattern(n_nodes, [0, 1, 5, 7]);
        let vals = crate::sparse::test_matrix(&pattern, 17, |_| 6.0);
        let r: Vec<f64> = (0..n_nodes * B).map(|i| (i as f64 * 0.61).sin()).collect();
        for n_parts in [1, 3] {
            let parts = partitions(&pattern, n_parts);
            assert_eq!(parts.len(), n_parts);
            let expected = dense_ilu0_solve(&pattern, &vals, &parts, &r);
            let ilu = BlockIlu::<f64>::factor(&pattern, &vals, parts).unwrap();
            let mut z = vec![0.0; r.len()];
            ilu.apply(&r, &mut z);
            let err = z.iter().zip(&expected).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
            assert!(err < 1e-11, "{n_parts} partitions: max difference {err:e}");
            let mut a_z = vec![0.0; r.len()];
            spmv(&pattern, &vals, &z, &mut a_z);
            let off = a_z.iter().zip(&r).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
            assert!(off > 1e-6, "the test pattern must make ILU(0) inexact ({off:e})");
        }
    }

    #[test]
    fn second_partition_uses_its_own_pivots() {
        // Two decoupled halves: block Jacobi of exact LUs solves exactly in one application.
        let tets = vec![[0, 1, 2, 3], [4, 5, 6, 7]];
        let pattern = BlockPattern::from_tets(8, &tets);
        let vals = crate::sparse::test_matrix(&pattern, 13, |node| 4.0 + node as f64);
        let parts = partitions(&pattern, 2);
        assert_eq!(parts, vec![0..4, 4..8]);
        let ilu = BlockIlu::<f64>::factor(&pattern, &vals, parts).unwrap();
        let x_true: Vec<f64> = (0..32).map(|i| (i as f64).cos()).collect();
        let mut b = vec![0.0; 32];
        spmv(&pattern, &vals, &x_true, &mut b);
        let mut x = vec![0.0; 32];
        ilu.apply(&b, &mut x);
        assert!(x.iter().zip(&x_true).all(|(a, b)| (a - b).abs() < 1e-10), "{x:?}");
    }

    #[test]
    fn refactoring_in_place_equals_a_fresh_factorization() {
        let (pattern, vals) = chain(120);
        let scaled_vals: Vec<f64> = vals.iter().enumerate().map(|(k, v)| v * (1.0 + 0.01 * (k % 7) as f64)).collect();
        let mut reused = BlockIlu::<f32>::factor(&pattern, &vals, partitions(&pattern, 2)).unwrap();
        reused.refactor(&pattern, &scaled_vals).unwrap();
        let fresh = BlockIlu::<f32>::factor(&pattern, &scaled_vals, partitions(&pattern, 2)).unwrap();
        let r: Vec<f64> = (0..120 * B).map(|i| (i as f64 * 0.23).sin()).collect();
        let (mut a, mut b) = (vec![0.0; r.len()], vec![0.0; r.len()]);
        reused.apply(&r, &mut a);
        fresh.apply(&r, &mut b);
        assert_eq!(a, b);
    }

    #[test]
    fn singular_pivot_is_reported() {
        let (pattern, mut vals) = chain(10);
        for p in pattern.row_ptr[4]..pattern.row_ptr[5] {
            vals[p * BB..(p + 1) * BB].iter_mut().for_each(|v| *v = 0.0);
        }
        assert_eq!(BlockIlu::<f64>::factor(&pattern, &vals, partitions(&pattern, 1)).err(), Some(4));
    }
}
