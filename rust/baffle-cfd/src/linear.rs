//! Linear algebra for the coupled (u, v, w, p) system: block ILU(0) in parallel
//! partitions and right-preconditioned restarted GMRES.

use std::ops::Range;

use rayon::prelude::*;

use crate::sparse::{axpy, invert4, mul4, mulv4, norm, BlockPattern, B, BB};

/// Block-Jacobi over contiguous row partitions of block ILU(0): each partition is
/// factored and solved independently (couplings between partitions are dropped),
/// so factorization and triangular solves run in parallel on the 2 cores.
pub struct BlockIlu {
    parts: Vec<Range<usize>>,
    lu: Vec<f64>,
    diag_inv: Vec<[f64; BB]>,
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

/// Disjoint mutable slices of `data` for row partitions (`stride` values per unit of `bounds`).
fn split_by<'a, T>(mut data: &'a mut [T], bounds: &[usize], stride: usize) -> Vec<&'a mut [T]> {
    let mut out = Vec::with_capacity(bounds.len() - 1);
    for w in bounds.windows(2) {
        let (head, tail) = data.split_at_mut((w[1] - w[0]) * stride);
        out.push(head);
        data = tail;
    }
    out
}

impl BlockIlu {
    /// Factor. Err(row) if a pivot block is singular.
    pub fn factor(pattern: &BlockPattern, vals: &[f64], parts: Vec<Range<usize>>) -> Result<Self, usize> {
        let mut lu = vals.to_vec();
        let mut diag_inv = vec![[0.0; BB]; pattern.n_rows()];
        let block_bounds: Vec<usize> = std::iter::once(0).chain(parts.iter().map(|r| pattern.row_ptr[r.end])).collect();
        let row_bounds: Vec<usize> = std::iter::once(0).chain(parts.iter().map(|r| r.end)).collect();
        let lu_parts = split_by(&mut lu, &block_bounds, BB);
        let inv_parts = split_by(&mut diag_inv, &row_bounds, 1);
        lu_parts
            .into_par_iter()
            .zip(inv_parts)
            .zip(parts.par_iter())
            .map(|((lu_p, inv_p), rows)| factor_part(pattern, lu_p, inv_p, rows.clone()))
            .collect::<Result<Vec<()>, usize>>()?;
        Ok(BlockIlu { parts, lu, diag_inv })
    }

    /// z = M^-1 r.
    pub fn apply(&self, pattern: &BlockPattern, r: &[f64], z: &mut [f64]) {
        let row_bounds: Vec<usize> = std::iter::once(0).chain(self.parts.iter().map(|r| r.end)).collect();
        let z_parts = split_by(z, &row_bounds, B);
        z_parts.into_par_iter().zip(self.parts.par_iter()).for_each(|(z_p, rows)| {
            solve_part(pattern, &self.lu, &self.diag_inv, rows.clone(), r, z_p);
        });
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
            let l = mul4(&lu[(p - base) * BB..(p - base + 1) * BB], &inv[k - rows.start]);
            lu[(p - base) * BB..(p - base + 1) * BB].copy_from_slice(&l);
            for q in pattern.diag[k] + 1..pattern.row_ptr[k + 1] {
                let j = pattern.cols[q] as usize;
                if j >= rows.end || marker[j - rows.start] == usize::MAX {
                    continue;
                }
                let target = marker[j - rows.start];
                let update = mul4(&l, &lu[(q - base) * BB..(q - base + 1) * BB]);
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

fn solve_part(pattern: &BlockPattern, lu: &[f64], inv: &[[f64; BB]], rows: Range<usize>, r: &[f64], z: &mut [f64]) {
    let r0 = rows.start;
    for i in rows.clone() {
        let mut y = [r[i * B], r[i * B + 1], r[i * B + 2], r[i * B + 3]];
        for p in pattern.row_ptr[i]..pattern.diag[i] {
            let k = pattern.cols[p] as usize;
            if k >= r0 {
                let lz = mulv4(&lu[p * BB..(p + 1) * BB], &z[(k - r0) * B..(k - r0 + 1) * B]);
                for c in 0..B {
                    y[c] -= lz[c];
                }
            }
        }
        z[(i - r0) * B..(i - r0 + 1) * B].copy_from_slice(&y);
    }
    for i in rows.clone().rev() {
        let mut y = [0.0; B];
        y.copy_from_slice(&z[(i - r0) * B..(i - r0 + 1) * B]);
        for p in pattern.diag[i] + 1..pattern.row_ptr[i + 1] {
            let j = pattern.cols[p] as usize;
            if j < rows.end {
                let ux = mulv4(&lu[p * BB..(p + 1) * BB], &z[(j - r0) * B..(j - r0 + 1) * B]);
                for c in 0..B {
                    y[c] -= ux[c];
                }
            }
        }
        let x = mulv4(&inv[i], &y);
        z[(i - r0) * B..(i - r0 + 1) * B].copy_from_slice(&x);
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
/// the residual it monitors is the true one: ||b - A x|| <= tol ||b||.
pub fn gmres(
    apply_a: &dyn Fn(&[f64], &mut [f64]),
    apply_m: &dyn Fn(&[f64], &mut [f64]),
    b: &[f64],
    x: &mut [f64],
    tol: f64,
    restart: usize,
    max_iterations: usize,
) -> GmresOutcome {
    let n = b.len();
    x.iter_mut().for_each(|v| *v = 0.0);
    let b_norm = norm(b);
    if b_norm == 0.0 {
        return GmresOutcome { iterations: 0, relative_residual: 0.0, converged: true };
    }
    let mut r = b.to_vec();
    let mut work = vec![0.0; n];
    let mut z = vec![0.0; n];
    let mut iterations = 0;
    let mut rel = 1.0;
    while iterations < max_iterations {
        let beta = norm(&r);
        rel = beta / b_norm;
        if !rel.is_finite() || rel <= tol {
            break;
        }
        let mut basis: Vec<Vec<f64>> = vec![r.iter().map(|v| v / beta).collect()];
        let mut h = vec![vec![0.0; restart]; restart + 1];
        let (mut cs, mut sn) = (vec![0.0; restart], vec![0.0; restart]);
        let mut g = vec![0.0; restart + 1];
        g[0] = beta;
        let mut k_used = 0;
        for k in 0..restart.min(max_iterations - iterations) {
            apply_m(&basis[k], &mut z);
            apply_a(&z, &mut work);
            // Classical Gram-Schmidt in fused passes (all dot products in one sweep
            // over the basis, all updates in another), repeated once when the vector
            // lost more than 30% of its norm (Daniel-Gragg-Kaufman-Stewart criterion):
            // about half the memory traffic of modified Gram-Schmidt at the same
            // orthogonality.
            let before = norm(&work);
            let c = orthogonalize(&basis, &mut work);
            (0..=k).for_each(|j| h[j][k] = c[j]);
            let mut next_norm = norm(&work);
            if next_norm < 0.7 * before {
                let c = orthogonalize(&basis, &mut work);
                (0..=k).for_each(|j| h[j][k] += c[j]);
                next_norm = norm(&work);
            }
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
            basis.push(work.iter().map(|v| v / next_norm).collect());
        }
        // y = H^-1 g, x += M^-1 (V y)
        let mut y = vec![0.0; k_used];
        for i in (0..k_used).rev() {
            let s: f64 = (i + 1..k_used).map(|j| h[i][j] * y[j]).sum();
            y[i] = if h[i][i] != 0.0 { (g[i] - s) / h[i][i] } else { 0.0 };
        }
        let mut update = vec![0.0; n];
        for (j, yj) in y.iter().enumerate() {
            axpy(*yj, &basis[j], &mut update);
        }
        apply_m(&update, &mut z);
        axpy(1.0, &z, x);
        apply_a(x, &mut work);
        r.par_iter_mut().zip(b.par_iter().zip(&work)).for_each(|(ri, (bi, ai))| *ri = bi - ai);
        rel = norm(&r) / b_norm;
        if !rel.is_finite() || rel <= tol {
            break;
        }
    }
    GmresOutcome { iterations, relative_residual: rel, converged: rel <= tol }
}

/// w -= V (V^T w) for the orthonormal columns V = `basis`; returns V^T w.
fn orthogonalize(basis: &[Vec<f64>], w: &mut [f64]) -> Vec<f64> {
    const CHUNK: usize = 8192;
    let k = basis.len();
    let c = w
        .par_chunks(CHUNK)
        .enumerate()
        .map(|(ci, wc)| {
            let off = ci * CHUNK;
            basis.iter().map(|v| v[off..off + wc.len()].iter().zip(wc).map(|(a, b)| a * b).sum::<f64>()).collect::<Vec<f64>>()
        })
        .reduce(|| vec![0.0; k], |mut a, b| {
            a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
            a
        });
    w.par_chunks_mut(CHUNK).enumerate().for_each(|(ci, wc)| {
        let off = ci * CHUNK;
        for (v, cj) in basis.iter().zip(&c) {
            let len = wc.len();
            wc.iter_mut().zip(&v[off..off + len]).for_each(|(x, y)| *x -= cj * y);
        }
    });
    c
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sparse::spmv;

    /// A 1D chain of nodes with diagonally dominant nonsymmetric 4x4 blocks.
    fn chain(n: usize) -> (BlockPattern, Vec<f64>) {
        let tets: Vec<[u32; 4]> = (0..n as u32 - 3).map(|i| [i, i + 1, i + 2, i + 3]).collect();
        let pattern = BlockPattern::from_tets(n, &tets);
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
            let ilu = BlockIlu::factor(&pattern, &vals, partitions(&pattern, parts)).unwrap();
            let mut x = vec![0.0; n * B];
            let out = gmres(
                &|v, y| spmv(&pattern, &vals, v, y),
                &|r, z| ilu.apply(&pattern, r, z),
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
    fn ilu_of_a_full_pattern_is_the_exact_inverse() {
        // 4 nodes of one tet: the block pattern is full, so ILU(0) = LU per partition.
        let (pattern, vals) = chain(4);
        let ilu = BlockIlu::factor(&pattern, &vals, partitions(&pattern, 1)).unwrap();
        let x_true: Vec<f64> = (0..16).map(|i| 1.0 + i as f64).collect();
        let mut b = vec![0.0; 16];
        spmv(&pattern, &vals, &x_true, &mut b);
        let mut x = vec![0.0; 16];
        ilu.apply(&pattern, &b, &mut x);
        assert!(x.iter().zip(&x_true).all(|(a, b)| (a - b).abs() < 1e-10), "{x:?}");
    }

    #[test]
    fn second_partition_uses_its_own_pivots() {
        // Two decoupled halves: block Jacobi of exact LUs solves exactly in one application.
        let tets = vec![[0, 1, 2, 3], [4, 5, 6, 7]];
        let pattern = BlockPattern::from_tets(8, &tets);
        let mut vals = vec![0.0; pattern.cols.len() * BB];
        for (k, v) in vals.iter_mut().enumerate() {
            *v = ((k * 7919) % 13) as f64 / 13.0 - 0.5;
        }
        for i in 0..8 {
            for c in 0..B {
                vals[pattern.diag[i] * BB + c * B + c] += 4.0 + i as f64;
            }
        }
        let parts = partitions(&pattern, 2);
        assert_eq!(parts, vec![0..4, 4..8]);
        let ilu = BlockIlu::factor(&pattern, &vals, parts).unwrap();
        let x_true: Vec<f64> = (0..32).map(|i| (i as f64).cos()).collect();
        let mut b = vec![0.0; 32];
        spmv(&pattern, &vals, &x_true, &mut b);
        let mut x = vec![0.0; 32];
        ilu.apply(&pattern, &b, &mut x);
        assert!(x.iter().zip(&x_true).all(|(a, b)| (a - b).abs() < 1e-10), "{x:?}");
    }

    #[test]
    fn singular_pivot_is_reported() {
        let (pattern, mut vals) = chain(10);
        for p in pattern.row_ptr[4]..pattern.row_ptr[5] {
            vals[p * BB..(p + 1) * BB].iter_mut().for_each(|v| *v = 0.0);
        }
        assert_eq!(BlockIlu::factor(&pattern, &vals, partitions(&pattern, 1)).err(), Some(4));
    }
}
