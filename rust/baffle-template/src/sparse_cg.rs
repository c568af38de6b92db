//! A symmetric positive-definite sparse system (row-compressed) and Jacobi-preconditioned
//! conjugate gradients: enough for the template's LSCM normal equations (a few thousand
//! unknowns, about 7 nonzeros a row), where a dense factorization would not fit.

use std::collections::HashMap;

/// Assembles a square matrix entry by entry (repeated entries add up).
pub struct SparseSym {
    n: usize,
    entries: HashMap<(usize, usize), f64>,
}

/// Compressed rows.
pub struct Csr {
    pub n: usize,
    row_start: Vec<usize>,
    cols: Vec<usize>,
    values: Vec<f64>,
}

impl SparseSym {
    pub fn new(n: usize) -> Self {
        SparseSym { n, entries: HashMap::new() }
    }

    pub fn add(&mut self, i: usize, j: usize, value: f64) {
        *self.entries.entry((i, j)).or_insert(0.0) += value;
    }

    pub fn finish(self) -> Csr {
        let mut triplets: Vec<((usize, usize), f64)> = self.entries.into_iter().collect();
        triplets.sort_unstable_by_key(|&(ij, _)| ij);
        let mut row_start = vec![0; self.n + 1];
        for &((i, _), _) in &triplets {
            row_start[i + 1] += 1;
        }
        for i in 0..self.n {
            row_start[i + 1] += row_start[i];
        }
        Csr { n: self.n, row_start, cols: triplets.iter().map(|&((_, j), _)| j).collect(), values: triplets.iter().map(|&(_, v)| v).collect() }
    }
}

impl Csr {
    pub fn mul(&self, x: &[f64], y: &mut [f64]) {
        for i in 0..self.n {
            y[i] = (self.row_start[i]..self.row_start[i + 1]).map(|k| self.values[k] * x[self.cols[k]]).sum();
        }
    }

    pub fn diagonal(&self) -> Vec<f64> {
        (0..self.n).map(|i| (self.row_start[i]..self.row_start[i + 1]).find(|&k| self.cols[k] == i).map_or(0.0, |k| self.values[k])).collect()
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Solve A x = b (A symmetric positive definite) to ||r|| <= rel_tol ||b||.
/// Returns the solution and the iterations taken, or an error naming why it stopped.
pub fn conjugate_gradient(a: &Csr, b: &[f64], rel_tol: f64, max_iterations: usize) -> Result<(Vec<f64>, usize), String> {
    let n = a.n;
    let diag = a.diagonal();
    if let Some(i) = diag.iter().position(|d| !(*d > 0.0)) {
        return Err(format!("row {i} has no positive diagonal (unconstrained unknown)"));
    }
    let b_norm = dot(b, b).sqrt();
    let mut x = vec![0.0; n];
    if b_norm == 0.0 {
        return Ok((x, 0));
    }
    let mut r = b.to_vec();
    let mut z: Vec<f64> = r.iter().zip(&diag).map(|(r, d)| r / d).collect();
    let mut p = z.clone();
    let mut ap = vec![0.0; n];
    let mut rz = dot(&r, &z);
    for it in 1..=max_iterations {
        a.mul(&p, &mut ap);
        let pap = dot(&p, &ap);
        if !(pap > 0.0) {
            return Err(format!("matrix not positive definite (p'Ap = {pap:.3e} at iteration {it})"));
        }
        let alpha = rz / pap;
        for i in 0..n {
            x[i] += alpha * p[i];
            r[i] -= alpha * ap[i];
        }
        if dot(&r, &r).sqrt() <= rel_tol * b_norm {
            return Ok((x, it));
        }
        for i in 0..n {
            z[i] = r[i] / diag[i];
        }
        let rz_new = dot(&r, &z);
        let beta = rz_new / rz;
        rz = rz_new;
        for i in 0..n {
            p[i] = z[i] + beta * p[i];
        }
    }
    Err(format!("no convergence to {rel_tol:.0e} in {max_iterations} iterations"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_a_1d_laplacian() {
        // Tridiagonal (2, -1): x = 1..n solves it with b = (0, ..., 0, n + 1).
        let n = 50;
        let mut m = SparseSym::new(n);
        for i in 0..n {
            m.add(i, i, 2.0);
            if i + 1 < n {
                m.add(i, i + 1, -1.0);
                m.add(i + 1, i, -1.0);
            }
        }
        let mut b = vec![0.0; n];
        b[0] = 0.0;
        b[n - 1] = (n + 1) as f64;
        let (x, _) = conjugate_gradient(&m.finish(), &b, 1e-12, 1000).unwrap();
        for (i, xi) in x.iter().enumerate() {
            assert!((xi - (i + 1) as f64).abs() < 1e-8, "x[{i}] = {xi}");
        }
    }
}
