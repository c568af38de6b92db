//! Element matrices of the stabilized P1-P1 formulation and their parallel assembly.
//!
//! Formulation (Tezduyar 1992; Bazilevs et al. 2007 VMS as in svMultiPhysics, reduced
//! to SUPG/PSPG/LSIC for linear elements), backward Euler in time, Picard (Oseen)
//! linearization with the advecting velocity a = the latest iterate:
//!
//!   momentum:  (rho (u - u_n)/dt + rho a.grad u, w) + (mu grad u, grad w) - (p, div w)
//!              + sum_e (tau a.grad w, r_M) + sum_e (nu_C rho div w, div u) + outlet terms
//!   continuity: (q, div u) + sum_e (tau/rho grad q, r_M)
//!   r_M = rho (u - u_n)/dt + rho a.grad u + grad p   (the viscous term vanishes on P1)
//!
//! tau = [ (2/dt)^2 + a.G.a + C_I nu^2 G:G ]^(-1/2), nu_C = 1 / (tau tr G), with the
//! node-numbering-invariant metric G = 2 sum_a grad N_a (x) grad N_a, which on a regular
//! tet of edge h gives a.G.a = (2|a|/h)^2; C_I = 3 gives the diffusive limit
//! 9 (4 nu / h^2)^2 of Shakib et al. The advecting velocity and the stabilization
//! terms use one-point (centroid) quadrature; the Galerkin mass matrix is consistent.
//! The viscous term is the Laplacian form, whose natural condition at outlets is
//! mu du/dn - p n = -P n (traction-free up to the outlet pressure P).

use rayon::prelude::*;

use crate::sparse::{BlockPattern, B, BB};

/// Constant data of one tetrahedron.
#[derive(Clone, Copy, Debug)]
pub struct ElementGeometry {
    pub grads_per_cm: [[f64; 3]; 4],
    pub volume_cm3: f64,
}

pub fn element_geometry(p: &[[f64; 3]], t: &[u32; 4]) -> ElementGeometry {
    let x = t.map(|i| p[i as usize]);
    let d = |k: usize| [x[k][0] - x[0][0], x[k][1] - x[0][1], x[k][2] - x[0][2]];
    let (e1, e2, e3) = (d(1), d(2), d(3));
    let c23 = crate::mesh::cross(e2, e3);
    let c31 = crate::mesh::cross(e3, e1);
    let c12 = crate::mesh::cross(e1, e2);
    let det = crate::mesh::dot(e1, c23);
    let g1 = c23.map(|v| v / det);
    let g2 = c31.map(|v| v / det);
    let g3 = c12.map(|v| v / det);
    let g0 = [0, 1, 2].map(|k| -(g1[k] + g2[k] + g3[k]));
    ElementGeometry { grads_per_cm: [g0, g1, g2, g3], volume_cm3: det / 6.0 }
}

/// Fluid and time-step constants of an assembly.
#[derive(Clone, Copy, Debug)]
pub struct Physics {
    pub density_g_cm3: f64,
    pub viscosity_g_cm_s: f64,
    /// 1/dt of the time terms (1/s); 0 for a steady solve.
    pub inv_dt_per_s: f64,
    /// 1/dt inside tau: 0 for steady or pseudo-time runs, so that the converged
    /// pseudo-transient solution is the steady discrete solution.
    pub inv_dt_tau_per_s: f64,
}

const C_INVERSE_ESTIMATE: f64 = 3.0;

/// Element matrix (4x4 node blocks of 4x4 (u,v,w,p) entries) and right-hand side.
pub struct ElementSystem {
    pub k: [[[f64; BB]; 4]; 4],
    pub f: [[f64; B]; 4],
}

fn mean3(v: &[[f64; 3]; 4]) -> [f64; 3] {
    [0, 1, 2].map(|k| 0.25 * (v[0][k] + v[1][k] + v[2][k] + v[3][k]))
}

/// Stabilization parameters (tau in s, nu_C in cm^2/s) at the element centroid.
pub fn stabilization(geo: &ElementGeometry, a_bar: [f64; 3], phys: &Physics) -> (f64, f64) {
    let mut g = [[0.0; 3]; 3];
    for grad in &geo.grads_per_cm {
        for i in 0..3 {
            for j in 0..3 {
                g[i][j] += 2.0 * grad[i] * grad[j];
            }
        }
    }
    let mut aga = 0.0;
    let mut gg = 0.0;
    for i in 0..3 {
        for j in 0..3 {
            aga += a_bar[i] * g[i][j] * a_bar[j];
            gg += g[i][j] * g[i][j];
        }
    }
    let nu = phys.viscosity_g_cm_s / phys.density_g_cm3;
    let transient = 2.0 * phys.inv_dt_tau_per_s;
    let tau = 1.0 / (transient * transient + aga + C_INVERSE_ESTIMATE * nu * nu * gg).sqrt();
    let trace = g[0][0] + g[1][1] + g[2][2];
    (tau, 1.0 / (tau * trace))
}

/// Element system for advecting velocity `a` and previous-step velocity `u_old` at the nodes.
pub fn element_system(geo: &ElementGeometry, a: &[[f64; 3]; 4], u_old: &[[f64; 3]; 4], phys: &Physics) -> ElementSystem {
    let rho = phys.density_g_cm3;
    let mu = phys.viscosity_g_cm_s;
    let idt = phys.inv_dt_per_s;
    let v = geo.volume_cm3;
    let g = &geo.grads_per_cm;
    let a_bar = mean3(a);
    let u_old_bar = mean3(u_old);
    let (tau, nu_c) = stabilization(geo, a_bar, phys);
    let s: [f64; 4] = g.map(|ga| crate::mesh::dot(a_bar, ga));
    let mut k = [[[0.0; BB]; 4]; 4];
    let mut f = [[0.0; B]; 4];
    for ai in 0..4 {
        for bi in 0..4 {
            let mass = if ai == bi { v / 10.0 } else { v / 20.0 };
            let diag = rho * idt * mass
                + rho * 0.25 * v * s[bi]
                + mu * v * crate::mesh::dot(g[ai], g[bi])
                + tau * v * s[ai] * rho * (0.25 * idt + s[bi]);
            let blk = &mut k[ai][bi];
            for i in 0..3 {
                blk[i * B + i] += diag;
                for j in 0..3 {
                    blk[i * B + j] += nu_c * rho * v * g[ai][i] * g[bi][j];
                }
                // pressure column: -(p, div w) + SUPG grad p
                blk[i * B + 3] = -0.25 * v * g[ai][i] + tau * v * s[ai] * g[bi][i];
                // continuity row: (q, div u) + PSPG
                blk[3 * B + i] = 0.25 * v * g[bi][i] + tau * v * g[ai][i] * (0.25 * idt + s[bi]);
            }
            blk[3 * B + 3] = tau / rho * v * crate::mesh::dot(g[ai], g[bi]);
            for i in 0..3 {
                f[ai][i] += rho * idt * mass * u_old[bi][i];
            }
        }
        for i in 0..3 {
            f[ai][i] += tau * v * s[ai] * rho * idt * u_old_bar[i];
        }
        f[ai][3] = tau * v * idt * crate::mesh::dot(g[ai], u_old_bar);
    }
    ElementSystem { k, f }
}

/// Mesh data for assembly: element geometry, block positions of each element's 16
/// node pairs, and for each row partition the elements touching it.
pub struct Assembler {
    pub tets: Vec<[u32; 4]>,
    pub geometry: Vec<ElementGeometry>,
    positions: Vec<[u32; 16]>,
    parts: Vec<std::ops::Range<usize>>,
    part_elements: Vec<Vec<u32>>,
}

impl Assembler {
    pub fn new(points_cm: &[[f64; 3]], tets: Vec<[u32; 4]>, pattern: &BlockPattern, parts: Vec<std::ops::Range<usize>>) -> Self {
        let geometry: Vec<ElementGeometry> = tets.par_iter().map(|t| element_geometry(points_cm, t)).collect();
        let positions: Vec<[u32; 16]> = tets
            .par_iter()
            .map(|t| {
                let mut pos = [0u32; 16];
                for a in 0..4 {
                    for b in 0..4 {
                        // Every node pair of a tet is in the pattern built from the tets.
                        pos[a * 4 + b] = pattern.position(t[a] as usize, t[b]).unwrap_or(0) as u32;
                    }
                }
                pos
            })
            .collect();
        // Elements in the order of their lowest node: with the nodes in reverse
        // Cuthill-McKee order, consecutive elements then add into nearby block rows,
        // so the scatter into the matrix mostly hits cache instead of memory.
        let mut by_lowest_node: Vec<u32> = (0..tets.len() as u32).collect();
        by_lowest_node.sort_by_key(|&e| tets[e as usize].iter().min().copied());
        let part_elements = parts
            .iter()
            .map(|r| by_lowest_node.iter().copied().filter(|&e| tets[e as usize].iter().any(|&n| r.contains(&(n as usize)))).collect())
            .collect();
        Assembler { tets, geometry, positions, parts, part_elements }
    }

    /// `vals` split into the disjoint runs of blocks whose rows each partition owns,
    /// so threads can write them in parallel.
    fn block_values_by_partition<'v>(&self, pattern: &BlockPattern, vals: &'v mut [f64]) -> Vec<&'v mut [f64]> {
        let block_bounds: Vec<usize> = std::iter::once(0).chain(self.parts.iter().map(|r| pattern.row_ptr[r.end])).collect();
        let mut val_parts = Vec::with_capacity(self.parts.len());
        let mut rest = vals;
        for w in block_bounds.windows(2) {
            let (h, t) = rest.split_at_mut((w[1] - w[0]) * BB);
            val_parts.push(h);
            rest = t;
        }
        val_parts
    }

    /// Add the Newton term of the Galerkin convection to the velocity blocks of `vals`:
    /// the derivative of (rho a.grad u, w) with respect to the advecting velocity a,
    /// evaluated at a = u = `x` with the same one-point (centroid) rule as the Picard
    /// term: block (a, b) gets rho V/16 grad u (grad u constant on P1). The derivatives
    /// of the SUPG/PSPG terms and of tau are not included (inexact Newton).
    pub fn add_convection_jacobian(&self, pattern: &BlockPattern, phys: &Physics, x: &[f64], vals: &mut [f64]) {
        let val_parts = self.block_values_by_partition(pattern, vals);
        val_parts.into_par_iter().enumerate().for_each(|(p, vals_p)| {
            let rows = &self.parts[p];
            let base = pattern.row_ptr[rows.start];
            for &e in &self.part_elements[p] {
                let t = &self.tets[e as usize];
                let geo = &self.geometry[e as usize];
                let mut grad_u = [[0.0; 3]; 3];
                for (a, &n) in t.iter().enumerate() {
                    for i in 0..3 {
                        for j in 0..3 {
                            grad_u[i][j] += x[n as usize * B + i] * geo.grads_per_cm[a][j];
                        }
                    }
                }
                let c = phys.density_g_cm3 * geo.volume_cm3 / 16.0;
                let pos = &self.positions[e as usize];
                for ai in 0..4 {
                    if !rows.contains(&(t[ai] as usize)) {
                        continue;
                    }
                    for bi in 0..4 {
                        let k = pos[ai * 4 + bi] as usize - base;
                        let blk = &mut vals_p[k * BB..(k + 1) * BB];
                        for i in 0..3 {
                            for j in 0..3 {
                                blk[i * B + j] += c * grad_u[i][j];
                            }
                        }
                    }
                }
            }
        });
    }

    /// Assemble K and F into `vals` / `rhs` (overwritten). `a` and `u_old` are nodal
    /// velocities, 4 values per node (u, v, w, p). Each partition owns its rows, so
    /// threads write disjoint memory; elements on partition borders are computed twice.
    pub fn assemble(&self, pattern: &BlockPattern, phys: &Physics, a: &[f64], u_old: &[f64], vals: &mut [f64], rhs: &mut [f64]) {
        let val_parts = self.block_values_by_partition(pattern, vals);
        let mut rhs_parts = Vec::new();
        let mut rest = &mut rhs[..];
        for r in &self.parts {
            let (h, t) = rest.split_at_mut(r.len() * B);
            rhs_parts.push(h);
            rest = t;
        }
        val_parts.into_par_iter().zip(rhs_parts).enumerate().for_each(|(p, (vals_p, rhs_p))| {
            vals_p.iter_mut().for_each(|v| *v = 0.0);
            rhs_p.iter_mut().for_each(|v| *v = 0.0);
            let rows = &self.parts[p];
            let base = pattern.row_ptr[rows.start];
            for &e in &self.part_elements[p] {
                let t = &self.tets[e as usize];
                let nodal = |field: &[f64]| t.map(|n| [0, 1, 2].map(|c| field[n as usize * B + c]));
                let es = element_system(&self.geometry[e as usize], &nodal(a), &nodal(u_old), phys);
                let pos = &self.positions[e as usize];
                for ai in 0..4 {
                    let row = t[ai] as usize;
                    if !rows.contains(&row) {
                        continue;
                    }
                    for bi in 0..4 {
                        let k = pos[ai * 4 + bi] as usize - base;
                        for (dst, src) in vals_p[k * BB..(k + 1) * BB].iter_mut().zip(&es.k[ai][bi]) {
                            *dst += src;
                        }
                    }
                    let r = (row - rows.start) * B;
                    for c in 0..B {
                        rhs_p[r + c] += es.f[ai][c];
                    }
                }
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gradients_sum_to_zero_and_reproduce_linear_fields() {
        let p = [[0.1, 0.0, 0.0], [1.0, 0.2, 0.0], [0.0, 1.0, 0.3], [0.2, 0.1, 1.0]];
        let geo = element_geometry(&p, &[0, 1, 2, 3]);
        let f = |x: [f64; 3]| 2.0 * x[0] - 3.0 * x[1] + 0.5 * x[2];
        for k in 0..3 {
            let grad: f64 = (0..4).map(|a| geo.grads_per_cm[a][k] * f(p[a])).sum();
            assert!((grad - [2.0, -3.0, 0.5][k]).abs() < 1e-12);
            assert!((0..4).map(|a| geo.grads_per_cm[a][k]).sum::<f64>().abs() < 1e-12);
        }
        assert!(geo.volume_cm3 > 0.0);
    }

    #[test]
    fn element_rows_annihilate_constant_pressure_and_rigid_flow() {
        // A constant pressure exerts no net force inside; a uniform velocity has no
        // divergence; with a = 0 and dt = inf the viscous rows vanish on constants.
        let p = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let geo = element_geometry(&p, &[0, 1, 2, 3]);
        let phys = Physics { density_g_cm3: 1.06, viscosity_g_cm_s: 0.04, inv_dt_per_s: 0.0, inv_dt_tau_per_s: 0.0 };
        let es = element_system(&geo, &[[0.0; 3]; 4], &[[0.0; 3]; 4], &phys);
        let x = [0.3, -0.2, 0.7, 0.0];
        for a in 0..4 {
            let mut row = [0.0; 4];
            for b in 0..4 {
                for r in 0..4 {
                    for c in 0..4 {
                        row[r] += es.k[a][b][r * 4 + c] * x[c];
                    }
                }
            }
            assert!(row.iter().all(|v| v.abs() < 1e-12), "node {a}: {row:?}");
        }
        let mut sum_p = [0.0; 3];
        for a in 0..4 {
            for b in 0..4 {
                for i in 0..3 {
                    sum_p[i] += es.k[a][b][i * 4 + 3];
                }
            }
        }
        assert!(sum_p.iter().all(|v| v.abs() < 1e-12), "{sum_p:?}");
    }

    #[test]
    fn convection_jacobian_is_the_derivative_of_the_galerkin_convection() {
        // The Galerkin convection c(a, u) is bilinear, so its derivative in a at a = u,
        // applied to v, equals c(v, u) = [K(a = v) - K(a = 0)] u. A huge viscosity makes
        // the SUPG/PSPG terms (which the Jacobian omits) negligible: tau ~ h^2 / nu.
        let p = [[0.0, 0.0, 0.0], [1.0, 0.1, 0.0], [0.2, 1.0, 0.1], [0.1, 0.3, 1.2], [1.0, 1.0, 1.0]];
        let tets = vec![[0, 1, 2, 3], [1, 2, 3, 4]];
        let pattern = BlockPattern::from_tets(5, &tets);
        let asm = Assembler::new(&p, tets, &pattern, vec![0..5]);
        let phys = Physics { density_g_cm3: 1.0, viscosity_g_cm_s: 1e6, inv_dt_per_s: 0.0, inv_dt_tau_per_s: 0.0 };
        let field = |s: f64| (0..5 * B).map(|k| if k % B == 3 { 0.0 } else { ((k as f64 + s) * 0.7).sin() }).collect::<Vec<f64>>();
        let (u, v) = (field(0.0), field(1.3));
        let n_vals = pattern.cols.len() * BB;
        let matvec = |vals: &[f64], x: &[f64]| {
            let mut y = vec![0.0; x.len()];
            crate::sparse::spmv(&pattern, vals, x, &mut y);
            y
        };
        let (mut k1, mut k0, mut rhs) = (vec![0.0; n_vals], vec![0.0; n_vals], vec![0.0; 5 * B]);
        asm.assemble(&pattern, &phys, &v, &u, &mut k1, &mut rhs);
        asm.assemble(&pattern, &phys, &vec![0.0; 5 * B], &u, &mut k0, &mut rhs);
        let expected: Vec<f64> = matvec(&k1, &u).iter().zip(matvec(&k0, &u)).map(|(a, b)| a - b).collect();
        let mut jac = vec![0.0; n_vals];
        asm.add_convection_jacobian(&pattern, &phys, &u, &mut jac);
        let got = matvec(&jac, &v);
        let scale = expected.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        assert!(scale > 1e-3);
        for k in (0..5 * B).filter(|k| k % B != 3) {
            assert!((got[k] - expected[k]).abs() < 1e-6 * scale, "dof {k}: {} vs {}", got[k], expected[k]);
        }
    }
}
