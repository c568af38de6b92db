//! Element matrices of the stabilized P1-P1 formulation and their parallel assembly.
//!
//! Formulation (Tezduyar 1992; Bazilevs et al. 2007 VMS as in svMultiPhysics, reduced
//! to SUPG/PSPG/LSIC for linear elements), backward Euler in time (generalized-alpha
//! uses the same matrices with another time coefficient and old velocity, see
//! [`crate::time_integration`]), Picard (Oseen)
//! linearization with the advecting velocity a = the latest iterate:
//!
//!   momentum:  (rho (u - u_n)/dt + rho a.grad u, w) + (mu grad u, grad w) - (p, div w)
//!              + sum_e (tau a.grad w, r_M) + sum_e (nu_C rho div w, div u) + outlet terms
//!   continuity: (q, div u) + sum_e (tau/rho grad q, r_M)
//!   r_M = rho (u - u_n)/dt + rho a.grad u + grad p   (the viscous term vanishes on P1)
//!
//! tau = [ (2/dt)^2 + a.G.a + C_I nu^2 G:G ]^(-1/2), nu_C = 1 / (tau tr G). By default
//! G and C_I are svMultiPhysics' (fluid.cpp: G = J^-T J^-1 of the reference tet, ctC = 36),
//! G averaged over the node numberings ([`TauMetric::SvMultiPhysics`]); the alternative
//! [`TauMetric::Invariant`] (G = 2 sum_a grad N_a (x) grad N_a, C_I = 3) has an LSIC
//! coefficient nu_C 2.7 times smaller and made dp 9-12 % lower than svMultiPhysics early
//! in the p3 ramp and 8 % lower at p1's peak (docs/validation.md, issue 28). The solver's
//! default adds the rest of svMultiPhysics' VMS: the stabilization at the four Gauss points
//! ([`GaussState`]), the Galerkin convection integrated exactly, advection by a + u', and
//! the Reynolds-stress term tau_B (u'.grad w)(u'.grad u) ([`Formulation::vms_reynolds_stress`]);
//! without that term our dp at p3's first peak was 7.3 % below svMultiPhysics' on the same
//! mesh, with all four +0.1 %. The mass matrix is consistent.
//! The viscous term is the Laplacian form, whose natural condition at outlets is
//! mu du/dn - p n = -P n (traction-free up to the outlet pressure P).

use rayon::prelude::*;

use crate::sparse::{split_by, wide, BlockPattern, B, BB};

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
    let c23 = crate::flow_mesh::cross(e2, e3);
    let c31 = crate::flow_mesh::cross(e3, e1);
    let c12 = crate::flow_mesh::cross(e1, e2);
    let det = crate::flow_mesh::dot(e1, c23);
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
    /// How the element terms are formed ([`Formulation`]).
    pub formulation: Formulation,
}

/// How the element terms are formed: tau's element length and which of svMultiPhysics'
/// ingredients the assembly uses. One struct for the solver's settings and each
/// assembly's [`Physics`], so that a run's choice reaches the elements unchanged.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Formulation {
    /// The element length inside tau and its inverse-estimate constant (see [`TauMetric`]).
    pub tau_metric: TauMetric,
    /// Galerkin convection (rho a.grad u, w) integrated exactly for the P1 advecting
    /// velocity (true), or with a at the centroid (false).
    pub exact_convection: bool,
    /// Variational multiscale advection (svMultiPhysics' VMS): the Galerkin convection and
    /// the SUPG test advected by a + u', u' = -tau r_M(a) the fine-scale velocity of the
    /// current iterate (lagged, elementwise constant).
    pub vms_advection: bool,
    /// Viscous term in stress form (mu (grad u + grad u^T), grad w), as svMultiPhysics.
    pub stress_viscosity: bool,
    /// Stabilization (tau, nu_C, the SUPG, PSPG and LSIC terms) at the tetrahedron's four
    /// Gauss points with the P1 velocity there, as svMultiPhysics integrates it, instead of
    /// once at the centroid ([`GaussState`]). Its SUPG test is advected by a(x_g);
    /// `vms_advection` then adds u' to the Galerkin convection only.
    pub gauss_stabilization: bool,
    /// svMultiPhysics' VMS "Reynolds stress" term (fluid.cpp, tauB): the diffusion
    /// tau_B (u'.grad w)(u'.grad u), tau_B = rho / sqrt(u'.G.u'), along the fine-scale
    /// velocity u' = -tau r_M of the latest iterate (centroid, lagged), about rho |u'| h:
    /// it acts where the residual is large, in the jet's shear layers.
    pub vms_reynolds_stress: bool,
}

/// The metric tensor G of tau's element length and the inverse-estimate constant C_I.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TauMetric {
    /// G = 2 sum_a grad N_a (x) grad N_a, C_I = 3 (a.G.a = (2|a|/h)^2 on a regular tet).
    Invariant,
    /// svMultiPhysics' G = J^-T J^-1 of the reference tet (sum of grad N_a (x) grad N_a
    /// over three of the four nodes), averaged over the four node numberings:
    /// 3/4 sum_a grad N_a (x) grad N_a; C_I = 36 (its ctC).
    SvMultiPhysics,
}

impl TauMetric {
    /// (scale of sum_a grad N_a (x) grad N_a, C_I).
    fn constants(self) -> (f64, f64) {
        match self {
            TauMetric::Invariant => (2.0, 3.0),
            TauMetric::SvMultiPhysics => (0.75, 36.0),
        }
    }
}

/// Element matrix (4x4 node blocks of 4x4 (u,v,w,p) entries) and right-hand side.
pub struct ElementSystem {
    pub k: [[[f64; BB]; 4]; 4],
    pub f: [[f64; B]; 4],
}

#[inline(always)]
fn mean3(v: &[[f64; 3]; 4]) -> [f64; 3] {
    [0, 1, 2].map(|k| 0.25 * (v[0][k] + v[1][k] + v[2][k] + v[3][k]))
}

/// Stabilization parameters (tau in s, nu_C in cm^2/s) for advecting velocity `a` in an
/// element of metric `g` ([`metric`], made once per element: the centroid, the four Gauss
/// points and the Reynolds-stress term share it).
#[inline(always)]
pub fn stabilization(g: &[[f64; 3]; 3], a: [f64; 3], phys: &Physics) -> (f64, f64) {
    let c_inverse = phys.formulation.tau_metric.constants().1;
    let gg: f64 = g.iter().flatten().map(|x| x * x).sum();
    let nu = phys.viscosity_g_cm_s / phys.density_g_cm3;
    let transient = 2.0 * phys.inv_dt_tau_per_s;
    let tau = 1.0 / (transient * transient + quadratic_form(g, a) + c_inverse * nu * nu * gg).sqrt();
    let trace = g[0][0] + g[1][1] + g[2][2];
    (tau, 1.0 / (tau * trace))
}

/// v.G.v
#[inline(always)]
fn quadratic_form(g: &[[f64; 3]; 3], v: [f64; 3]) -> f64 {
    let mut vgv = 0.0;
    for i in 0..3 {
        for j in 0..3 {
            vgv += v[i] * g[i][j] * v[j];
        }
    }
    vgv
}

/// The element metric G = scale sum_a grad N_a (x) grad N_a of phys' [`TauMetric`].
#[inline(always)]
pub fn metric(geo: &ElementGeometry, phys: &Physics) -> [[f64; 3]; 3] {
    let scale = phys.formulation.tau_metric.constants().0;
    let mut g = [[0.0; 3]; 3];
    for grad in &geo.grads_per_cm {
        for i in 0..3 {
            for j in 0..3 {
                g[i][j] += scale * grad[i] * grad[j];
            }
        }
    }
    g
}

/// What the four rows of one element's system share: the centroid velocity of the
/// previous step, the stabilization parameters and s_a = a_bar . grad N_a.
#[derive(Clone, Copy, Debug, Default)]
pub struct ElementState {
    u_old_bar: [f64; 3],
    tau: f64,
    nu_c: f64,
    s: [f64; 4],
    /// The Reynolds-stress term's tau_B and u'.grad N_b (0 without it).
    tau_b: f64,
    fine_s: [f64; 4],
}

/// The [`ElementState`] for advecting velocity `a` and previous-step velocity `u_old` at the nodes.
pub fn element_state(geo: &ElementGeometry, a: &[[f64; 3]; 4], u_old: &[[f64; 3]; 4], p: &[f64; 4], phys: &Physics) -> ElementState {
    element_state_in(geo, &metric(geo, phys), a, u_old, p, phys)
}

/// [`element_state`] in an element of metric `g` (the assembly makes it once for this
/// and the [`GaussState`]).
#[inline(always)]
fn element_state_in(geo: &ElementGeometry, g: &[[f64; 3]; 3], a: &[[f64; 3]; 4], u_old: &[[f64; 3]; 4], p: &[f64; 4], phys: &Physics) -> ElementState {
    let a_bar = mean3(a);
    let u_old_bar = mean3(u_old);
    let (tau, nu_c) = stabilization(g, a_bar, phys);
    let fine = (phys.formulation.vms_advection || phys.formulation.vms_reynolds_stress).then(|| fine_scale_velocity(geo, a, a_bar, u_old_bar, p, tau, phys));
    let advecting = match fine {
        Some(u_fine) if phys.formulation.vms_advection => add3(a_bar, u_fine),
        _ => a_bar,
    };
    let (tau_b, fine_s) = match fine {
        Some(u_fine) if phys.formulation.vms_reynolds_stress => reynolds_stress(geo, g, u_fine, phys),
        _ => (0.0, [0.0; 4]),
    };
    ElementState { u_old_bar, tau, nu_c, s: geo.grads_per_cm.map(|ga| crate::flow_mesh::dot(advecting, ga)), tau_b, fine_s }
}

/// tau_B = rho / sqrt(u'.G.u') and u'.grad N_b of svMultiPhysics' Reynolds-stress term
/// (0 where u' vanishes).
#[inline(always)]
fn reynolds_stress(geo: &ElementGeometry, g: &[[f64; 3]; 3], u_fine: [f64; 3], phys: &Physics) -> (f64, [f64; 4]) {
    let ugu = quadratic_form(g, u_fine);
    if !(ugu > 0.0) {
        return (0.0, [0.0; 4]);
    }
    (phys.density_g_cm3 / ugu.sqrt(), geo.grads_per_cm.map(|gb| crate::flow_mesh::dot(u_fine, gb)))
}

/// The 4-point Gauss rule of a tetrahedron (degree 2; weight V/4 each): point g has
/// barycentric coordinate GAUSS_NEAR on node g and GAUSS_FAR on the other three.
const GAUSS_NEAR: f64 = 0.585_410_196_624_968_5;
const GAUSS_FAR: f64 = 0.138_196_601_125_010_5;

#[inline(always)]
fn gauss_weight(g: usize, b: usize) -> f64 {
    if g == b {
        GAUSS_NEAR
    } else {
        GAUSS_FAR
    }
}

#[inline(always)]
fn at_gauss_point(v: &[[f64; 3]; 4], g: usize) -> [f64; 3] {
    [0, 1, 2].map(|k| (0..4).map(|b| gauss_weight(g, b) * v[b][k]).sum())
}

/// Stabilization at the four Gauss points: tau and nu_C from the P1 advecting velocity
/// there, s_b = a(x_g) . grad N_b, and the previous step's velocity there. With one point
/// (the centroid) tau and the SUPG term see the element's mean velocity only; across a
/// jet's shear layer, a few elements wide, the velocity varies within an element, and the
/// SUPG term (a.grad w)(a.grad u), quadratic in a, is then larger on average than at
/// the mean (svMultiPhysics evaluates all of it at Gauss points; issue 28).
#[derive(Clone, Copy, Debug, Default)]
pub struct GaussState {
    /// The Gauss-point sums each block needs, summed once per element (w = V/4): SUPG
    /// sum tau w s_a s_b and sum tau w s_a N_b; sum tau w s_a; sum tau w N_b; sum tau w;
    /// sum nu_C w; the old velocity's sum tau w s_a u_old and sum tau w u_old.
    supg_convection: [[f64; 4]; 4],
    supg_time: [[f64; 4]; 4],
    tau_s: [f64; 4],
    tau_n: [f64; 4],
    tau: f64,
    nu_c: f64,
    supg_old: [[f64; 3]; 4],
    tau_old: [f64; 3],
}

pub fn gauss_state(geo: &ElementGeometry, a: &[[f64; 3]; 4], u_old: &[[f64; 3]; 4], phys: &Physics) -> GaussState {
    gauss_state_in(geo, &metric(geo, phys), a, u_old, phys)
}

/// [`gauss_state`] in an element of metric `g`.
#[inline(always)]
fn gauss_state_in(geo: &ElementGeometry, g: &[[f64; 3]; 3], a: &[[f64; 3]; 4], u_old: &[[f64; 3]; 4], phys: &Physics) -> GaussState {
    let mut st = GaussState::default();
    let w = 0.25 * geo.volume_cm3;
    for q in 0..4 {
        let a_q = at_gauss_point(a, q);
        let (tau, nu_c) = stabilization(g, a_q, phys);
        let s = geo.grads_per_cm.map(|gb| crate::flow_mesh::dot(a_q, gb));
        let u_old_q = at_gauss_point(u_old, q);
        let tw = tau * w;
        st.tau += tw;
        st.nu_c += nu_c * w;
        for a in 0..4 {
            st.tau_s[a] += tw * s[a];
            st.tau_n[a] += tw * gauss_weight(q, a);
            for b in 0..4 {
                st.supg_convection[a][b] += tw * s[a] * s[b];
                st.supg_time[a][b] += tw * s[a] * gauss_weight(q, b);
            }
            for i in 0..3 {
                st.supg_old[a][i] += tw * s[a] * u_old_q[i];
            }
        }
        for i in 0..3 {
            st.tau_old[i] += tw * u_old_q[i];
        }
    }
    st
}

/// The stabilization's share of block (ai, bi) and of row ai's right-hand side, per unit
/// of its factors (see [`element_row`]).
#[derive(Clone, Copy, Default)]
struct StabilizationTerms {
    /// SUPG on the velocity (identity coefficient).
    supg_u: f64,
    /// LSIC: nu_C rho V (times grad N_a (x) grad N_b).
    lsic: f64,
    /// SUPG on the pressure column: sum tau w s_a grad N_b.
    supg_p: [f64; 3],
    /// PSPG on the velocity columns: sum tau w grad N_a (dt-term + s_b).
    pspg_u: [f64; 3],
    /// PSPG pressure-pressure: sum tau / rho w grad N_a . grad N_b.
    pspg_p: f64,
}

/// The old velocity's SUPG and PSPG shares of row ai's right-hand side (velocity, pressure).
#[inline(always)]
fn stabilization_rhs(geo: &ElementGeometry, st: &ElementState, gauss: Option<&GaussState>, phys: &Physics, ai: usize) -> ([f64; 3], f64) {
    let (rho, idt, g) = (phys.density_g_cm3, phys.inv_dt_per_s, &geo.grads_per_cm);
    match gauss {
        Some(gs) => (gs.supg_old[ai].map(|x| rho * idt * x), idt * crate::flow_mesh::dot(g[ai], gs.tau_old)),
        None => {
            let (tau, v) = (st.tau, geo.volume_cm3);
            (st.u_old_bar.map(|x| tau * v * st.s[ai] * rho * idt * x), tau * v * idt * crate::flow_mesh::dot(g[ai], st.u_old_bar))
        }
    }
}

#[inline(always)]
fn centroid_terms(geo: &ElementGeometry, st: &ElementState, phys: &Physics, ai: usize, bi: usize) -> StabilizationTerms {
    let (rho, idt, v, g) = (phys.density_g_cm3, phys.inv_dt_per_s, geo.volume_cm3, &geo.grads_per_cm);
    let (tau, s) = (st.tau, &st.s);
    StabilizationTerms {
        supg_u: tau * v * s[ai] * rho * (0.25 * idt + s[bi]),
        lsic: st.nu_c * rho * v,
        supg_p: g[bi].map(|x| tau * v * s[ai] * x),
        pspg_u: g[ai].map(|x| tau * v * x * (0.25 * idt + s[bi])),
        pspg_p: tau / rho * v * crate::flow_mesh::dot(g[ai], g[bi]),
    }
}

#[inline(always)]
fn gauss_terms(geo: &ElementGeometry, gs: &GaussState, phys: &Physics, ai: usize, bi: usize) -> StabilizationTerms {
    let (rho, idt, g) = (phys.density_g_cm3, phys.inv_dt_per_s, &geo.grads_per_cm);
    StabilizationTerms {
        supg_u: rho * (idt * gs.supg_time[ai][bi] + gs.supg_convection[ai][bi]),
        lsic: gs.nu_c * rho,
        supg_p: g[bi].map(|x| gs.tau_s[ai] * x),
        pspg_u: g[ai].map(|x| x * (idt * gs.tau_n[bi] + gs.tau_s[bi])),
        pspg_p: gs.tau / rho * crate::flow_mesh::dot(g[ai], g[bi]),
    }
}

#[inline(always)]
fn add3(x: [f64; 3], y: [f64; 3]) -> [f64; 3] {
    [x[0] + y[0], x[1] + y[1], x[2] + y[2]]
}

/// u' = -tau (dt-term + a.grad a + grad p / rho) at the centroid (the viscous part of r_M
/// vanishes on P1).
#[inline(always)]
fn fine_scale_velocity(geo: &ElementGeometry, a: &[[f64; 3]; 4], a_bar: [f64; 3], u_old_bar: [f64; 3], p: &[f64; 4], tau: f64, phys: &Physics) -> [f64; 3] {
    let g = &geo.grads_per_cm;
    let mut r = [0.0; 3];
    for k in 0..3 {
        let mut convective = 0.0;
        let mut grad_p = 0.0;
        for n in 0..4 {
            convective += crate::flow_mesh::dot(a_bar, g[n]) * a[n][k];
            grad_p += g[n][k] * p[n];
        }
        r[k] = phys.inv_dt_per_s * (a_bar[k] - u_old_bar[k]) + convective + grad_p / phys.density_g_cm3;
    }
    r.map(|v| -tau * v)
}

/// Row `ai` of the element system: the blocks (ai, 0..4) and node ai's right-hand side,
/// `u_old_ai` being node ai's previous-step velocity (the consistent mass row only needs
/// it and the centroid's: sum_b M_ab u_b = V/5 u_bar + V/20 u_a, so the rows gather no
/// other node's old velocity).
///
/// `a_ai` is node ai's advecting velocity: the exact Galerkin convection of a P1 velocity
/// is V/20 (4 a_bar + a_ai) . grad N_b (the mass matrix's weights again), the one-point
/// rule's V/4 a_bar . grad N_b drops the second part, an O(h grad a / |a|) relative
/// error that is not small in the shear layers of a jet a few elements wide.
/// `gauss`: the stabilization at Gauss points ([`Formulation::gauss_stabilization`]), else
/// at the centroid from `st`.
pub fn element_row(geo: &ElementGeometry, st: &ElementState, gauss: Option<&GaussState>, u_old_ai: &[f64; 3], a_ai: &[f64; 3], phys: &Physics, ai: usize) -> ([[f64; BB]; 4], [f64; B]) {
    let mut k = [[0.0; BB]; 4];
    let f = element_row_into(geo, st, gauss, u_old_ai, a_ai, phys, ai, |bi, blk| k[bi] = *blk);
    (k, f)
}

/// [`element_row`] handing each block (ai, bi) to `sink` as it is made: returned as a
/// whole, the row's 512 bytes were zeroed and copied out per element and node, which
/// took a quarter of the assembly (memset and memmove in the profile of p3's run).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn element_row_into(
    geo: &ElementGeometry,
    st: &ElementState,
    gauss: Option<&GaussState>,
    u_old_ai: &[f64; 3],
    a_ai: &[f64; 3],
    phys: &Physics,
    ai: usize,
    mut sink: impl FnMut(usize, &[f64; BB]),
) -> [f64; B] {
    let rho = phys.density_g_cm3;
    let mu = phys.viscosity_g_cm_s;
    let idt = phys.inv_dt_per_s;
    let v = geo.volume_cm3;
    let g = &geo.grads_per_cm;
    let s = &st.s;
    let terms = |bi: usize| match gauss {
        Some(gs) => gauss_terms(geo, gs, phys, ai, bi),
        None => centroid_terms(geo, st, phys, ai, bi),
    };
    let mut f = [0.0; B];
    for bi in 0..4 {
        let t = terms(bi);
        let mass = if ai == bi { v / 10.0 } else { v / 20.0 };
        let convection = if phys.formulation.exact_convection { 0.2 * s[bi] + 0.05 * crate::flow_mesh::dot(*a_ai, g[bi]) } else { 0.25 * s[bi] };
        let reynolds = st.tau_b * v * st.fine_s[ai] * st.fine_s[bi];
        let diag = rho * idt * mass + rho * v * convection + mu * v * crate::flow_mesh::dot(g[ai], g[bi]) + t.supg_u + reynolds;
        let mut blk = [0.0; BB];
        for i in 0..3 {
            blk[i * B + i] += diag;
            for j in 0..3 {
                blk[i * B + j] += t.lsic * g[ai][i] * g[bi][j];
            }
            // Apart, so the default (Laplacian form) does not multiply by zero 9 times a block.
            if phys.formulation.stress_viscosity {
                for j in 0..3 {
                    blk[i * B + j] += mu * v * g[ai][j] * g[bi][i];
                }
            }
            // pressure column: -(p, div w) + SUPG grad p
            blk[i * B + 3] = -0.25 * v * g[ai][i] + t.supg_p[i];
            // continuity row: (q, div u) + PSPG
            blk[3 * B + i] = 0.25 * v * g[bi][i] + t.pspg_u[i];
        }
        blk[3 * B + 3] = t.pspg_p;
        sink(bi, &blk);
    }
    let (rhs_u, rhs_p) = stabilization_rhs(geo, st, gauss, phys, ai);
    for i in 0..3 {
        f[i] = rho * idt * (0.2 * v * st.u_old_bar[i] + 0.05 * v * u_old_ai[i]) + rhs_u[i];
    }
    f[3] = rhs_p;
    f
}

/// Element system for advecting velocity `a` and previous-step velocity `u_old` at the nodes.
pub fn element_system(geo: &ElementGeometry, a: &[[f64; 3]; 4], u_old: &[[f64; 3]; 4], phys: &Physics) -> ElementSystem {
    let st = element_state(geo, a, u_old, &[0.0; 4], phys);
    let gs = phys.formulation.gauss_stabilization.then(|| gauss_state(geo, a, u_old, phys));
    let rows = [0, 1, 2, 3].map(|ai| element_row(geo, &st, gs.as_ref(), &u_old[ai], &a[ai], phys, ai));
    ElementSystem { k: rows.map(|r| r.0), f: rows.map(|r| r.1) }
}

/// Mesh data for assembly: element geometry, block positions of each element's 16
/// node pairs, and for each node the elements around it.
///
/// The matrix is assembled row by row: each block row gathers the rows of its
/// elements' systems, so it is written once, in order, while it sits in L1, and rows
/// in different partitions are written by different threads without conflicts. Each
/// element's shared quantities ([`ElementState`]) are computed once per assembly in a
/// pass over the elements before the rows gather them (computed per row, four times
/// an element, they were about a quarter of the assembly's CPU time on p2). Scattering
/// whole element matrices instead (elements in the order of their lowest node) spent
/// about 100 of the 134 ms of an assembly on p2 adding blocks into rows that were no
/// longer in cache.
pub struct Assembler {
    /// The elements, in the order of their lowest node (see [`Assembler::new`]).
    pub tets: Vec<[u32; 4]>,
    pub geometry: Vec<ElementGeometry>,
    positions: Vec<[u32; 16]>,
    parts: Vec<std::ops::Range<usize>>,
    /// Node i's elements are `node_elements[node_element_ptr[i]..node_element_ptr[i + 1]]`,
    /// each as (element, local index of node i in it).
    node_element_ptr: Vec<usize>,
    node_elements: Vec<(u32, u32)>,
    /// Each element's [`ElementState`] of the assembly in progress (storage kept across steps).
    states: Vec<ElementState>,
    /// Each element's [`GaussState`] when the stabilization is at Gauss points (else empty).
    gauss_states: Vec<GaussState>,
}

impl Assembler {
    pub fn new(points_cm: &[[f64; 3]], mut tets: Vec<[u32; 4]>, pattern: &BlockPattern, parts: Vec<std::ops::Range<usize>>) -> Self {
        // Elements in the order of their lowest node: with the nodes in reverse
        // Cuthill-McKee order, the elements around consecutive rows then lie close
        // together in memory.
        tets.sort_by_key(|t| t.iter().min().copied());
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
        let mut node_element_ptr = vec![0usize; pattern.n_rows() + 1];
        for t in &tets {
            t.iter().for_each(|&n| node_element_ptr[n as usize + 1] += 1);
        }
        for i in 0..pattern.n_rows() {
            node_element_ptr[i + 1] += node_element_ptr[i];
        }
        let mut fill = node_element_ptr.clone();
        let mut node_elements = vec![(0u32, 0u32); node_element_ptr[pattern.n_rows()]];
        for (e, t) in tets.iter().enumerate() {
            for (local, &n) in t.iter().enumerate() {
                node_elements[fill[n as usize]] = (e as u32, local as u32);
                fill[n as usize] += 1;
            }
        }
        let states = vec![ElementState::default(); tets.len()];
        Assembler { tets, geometry, positions, parts, node_element_ptr, node_elements, states, gauss_states: Vec::new() }
    }

    /// Calls `visit(i, row_vals, first, rhs_i)` for every block row i, the partitions
    /// in parallel: `row_vals` are row i's block values (blocks `first..` of the
    /// pattern) and `rhs_i` its right-hand side (empty without `rhs`).
    fn for_each_row(&self, pattern: &BlockPattern, vals: &mut [f64], rhs: Option<&mut [f64]>, visit: impl Fn(usize, &mut [f64], usize, &mut [f64]) + Sync) {
        let val_parts = split_by(vals, self.parts.iter().map(|r| pattern.blocks_in(r) * BB));
        let rhs_parts = match rhs {
            Some(rhs) => split_by(rhs, self.parts.iter().map(|r| r.len() * B)),
            None => self.parts.iter().map(|_| &mut [][..]).collect(),
        };
        val_parts.into_par_iter().zip(rhs_parts).zip(&self.parts).for_each(|((vals_p, rhs_p), rows)| {
            let base = pattern.row_ptr[rows.start];
            wide(#[inline(always)] || {
                for i in rows.clone() {
                    let (first, end) = (pattern.row_ptr[i], pattern.row_ptr[i + 1]);
                    let rhs_i = if rhs_p.is_empty() { &mut [][..] } else { &mut rhs_p[(i - rows.start) * B..(i - rows.start + 1) * B] };
                    visit(i, &mut vals_p[(first - base) * BB..(end - base) * BB], first, rhs_i);
                }
            })
        });
    }

    /// The elements around node i, as (element, local index of node i).
    fn elements_of(&self, i: usize) -> &[(u32, u32)] {
        &self.node_elements[self.node_element_ptr[i]..self.node_element_ptr[i + 1]]
    }

    /// Add `block` to the block of row `row_vals` (which starts at pattern block `first`)
    /// that element `e`'s node pair (ai, bi) lands in.
    #[inline(always)]
    fn add_block(&self, row_vals: &mut [f64], first: usize, e: usize, ai: usize, bi: usize, block: &[f64; BB]) {
        let at = (self.positions[e][ai * 4 + bi] as usize - first) * BB;
        row_vals[at..at + BB].iter_mut().zip(block).for_each(|(d, s)| *d += s);
    }

    /// Add the Newton term of the Galerkin convection to the velocity blocks of `vals`:
    /// the derivative of (rho a.grad u, w) with respect to the advecting velocity a,
    /// evaluated at a = u = `x` with the Picard term's rule: block (a, b) gets rho M_ab
    /// grad u (grad u constant on P1), M_ab = V/20 (1 + delta_ab) for the exact
    /// convection, V/16 for the centroid rule. The derivatives of the SUPG/PSPG terms
    /// and of tau are not included (inexact Newton).
    pub fn add_convection_jacobian(&self, pattern: &BlockPattern, phys: &Physics, x: &[f64], vals: &mut [f64]) {
        self.for_each_row(pattern, vals, None, |i, row_vals, first, _| {
            for &(e, ai) in self.elements_of(i) {
                let (e, ai) = (e as usize, ai as usize);
                let geo = &self.geometry[e];
                let mut grad_u = [[0.0; 3]; 3];
                for (a, &n) in self.tets[e].iter().enumerate() {
                    for r in 0..3 {
                        for c in 0..3 {
                            grad_u[r][c] += x[n as usize * B + r] * geo.grads_per_cm[a][c];
                        }
                    }
                }
                for bi in 0..4 {
                    let weight = match (phys.formulation.exact_convection, ai == bi) {
                        (true, true) => 0.1,
                        (true, false) => 0.05,
                        (false, _) => 1.0 / 16.0,
                    };
                    let c = phys.density_g_cm3 * geo.volume_cm3 * weight;
                    let mut block = [0.0; BB];
                    for r in 0..3 {
                        for col in 0..3 {
                            block[r * B + col] = c * grad_u[r][col];
                        }
                    }
                    self.add_block(row_vals, first, e, ai, bi, &block);
                }
            }
        });
    }

    /// Each element's [`ElementState`] (and [`GaussState`]) for this assembly, in one pass
    /// that gathers the element's nodal values and makes its metric once for both.
    fn update_states(&mut self, phys: &Physics, a: &[f64], u_old: &[f64]) {
        let nodal = |t: &[u32; 4], field: &[f64]| t.map(|n| [0, 1, 2].map(|c| field[n as usize * B + c]));
        let (tets, geometry) = (&self.tets, &self.geometry);
        // Per element through `wide`: these sums are compute-bound.
        let fill = |st: &mut ElementState, gs: Option<&mut GaussState>, t: &[u32; 4], geo: &ElementGeometry| wide(#[inline(always)] || {
            let (g, a_e, u_old_e) = (metric(geo, phys), nodal(t, a), nodal(t, u_old));
            *st = element_state_in(geo, &g, &a_e, &u_old_e, &t.map(|n| a[n as usize * B + 3]), phys);
            if let Some(gs) = gs {
                *gs = gauss_state_in(geo, &g, &a_e, &u_old_e, phys);
            }
        });
        let elements = tets.par_iter().zip(geometry);
        if phys.formulation.gauss_stabilization {
            self.gauss_states.resize(tets.len(), GaussState::default());
            let states = self.states.par_iter_mut().zip(self.gauss_states.par_iter_mut());
            states.zip(elements).with_min_len(1024).for_each(|((st, gs), (t, geo))| fill(st, Some(gs), t, geo));
        } else {
            self.states.par_iter_mut().zip(elements).with_min_len(1024).for_each(|(st, (t, geo))| fill(st, None, t, geo));
        }
    }

    /// Assemble K and F into `vals` / `rhs` (overwritten). `a` and `u_old` are nodal
    /// velocities, 4 values per node (u, v, w, p).
    pub fn assemble(&mut self, pattern: &BlockPattern, phys: &Physics, a: &[f64], u_old: &[f64], vals: &mut [f64], rhs: &mut [f64]) {
        self.update_states(phys, a, u_old);
        let this = &*self;
        this.for_each_row(pattern, vals, Some(rhs), #[inline(always)] |i, row_vals, first, rhs_i| {
            row_vals.fill(0.0);
            rhs_i.fill(0.0);
            let u_old_i = [0, 1, 2].map(|c| u_old[i * B + c]);
            let a_i = [0, 1, 2].map(|c| a[i * B + c]);
            for &(e, ai) in this.elements_of(i) {
                let (e, ai) = (e as usize, ai as usize);
                let gauss = phys.formulation.gauss_stabilization.then(|| &this.gauss_states[e]);
                let f = element_row_into(&this.geometry[e], &this.states[e], gauss, &u_old_i, &a_i, phys, ai, |bi, blk| this.add_block(row_vals, first, e, ai, bi, blk));
                rhs_i.iter_mut().zip(f).for_each(|(d, s)| *d += s);
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The solver's default formulation (the other fields are set by each test).
    const TEST_PHYSICS: Physics = Physics {
        density_g_cm3: 1.0,
        viscosity_g_cm_s: 1.0,
        inv_dt_per_s: 0.0,
        inv_dt_tau_per_s: 0.0,
        formulation: Formulation {
            tau_metric: TauMetric::SvMultiPhysics,
            exact_convection: false,
            vms_advection: false,
            stress_viscosity: false,
            gauss_stabilization: false,
            vms_reynolds_stress: false,
        },
    };

    #[test]
    fn gauss_point_stabilization_is_the_centroids_for_a_uniform_flow_and_not_across_a_shear_layer() {
        let p = [[0.0, 0.0, 0.0], [0.12, 0.01, 0.0], [0.02, 0.09, 0.01], [0.01, 0.03, 0.11]];
        let geo = element_geometry(&p, &[0, 1, 2, 3]);
        let phys = Physics { density_g_cm3: 1.06, viscosity_g_cm_s: 0.04, inv_dt_per_s: 1000.0, inv_dt_tau_per_s: 1000.0, ..TEST_PHYSICS };
        let systems = |a: &[[f64; 3]; 4], gauss_stabilization: bool| element_system(&geo, a, &a.map(|x| x.map(|c| 0.9 * c)), &Physics { formulation: Formulation { gauss_stabilization, ..phys.formulation }, ..phys });
        let largest_difference = |a: &[[f64; 3]; 4]| {
            let (c, g) = (systems(a, false), systems(a, true));
            let scale = c.k.iter().flatten().flatten().fold(0.0f64, |m, x| m.max(x.abs()));
            let k = c.k.iter().flatten().flatten().zip(g.k.iter().flatten().flatten()).fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
            let f = c.f.iter().flatten().zip(g.f.iter().flatten()).fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
            (k / scale, f)
        };
        // A uniform velocity is the same at every Gauss point: the same element system.
        let (k, f) = largest_difference(&[[40.0, -10.0, 5.0]; 4]);
        assert!(k < 1e-12 && f < 1e-9, "uniform flow: {k:e}, {f:e}");
        // A jet's edge: 150 cm/s on two nodes, at rest on the others.
        let (k, _) = largest_difference(&[[150.0, 0.0, 0.0], [150.0, 0.0, 0.0], [0.0; 3], [0.0; 3]]);
        assert!(k > 1e-3, "shear layer: {k:e}");
    }

    #[test]
    fn the_stress_form_annihilates_a_rigid_rotation_and_the_laplacian_form_does_not() {
        // u = omega x x has grad u + grad u^T = 0: no viscous stress. With a = 0 and no
        // time term only the viscous, LSIC (div u = 0 here) and pressure blocks act.
        let p = [[0.0, 0.0, 0.0], [1.2, 0.1, 0.0], [0.2, 0.9, 0.1], [0.1, 0.3, 1.1]];
        let geo = element_geometry(&p, &[0, 1, 2, 3]);
        let omega = [0.3, -0.7, 1.1];
        let u: [[f64; 3]; 4] = p.map(|x| crate::flow_mesh::cross(omega, x));
        let force = |stress_viscosity: bool| {
            let phys = Physics { density_g_cm3: 1.06, viscosity_g_cm_s: 0.04, formulation: Formulation { stress_viscosity, ..TEST_PHYSICS.formulation }, ..TEST_PHYSICS };
            let es = element_system(&geo, &[[0.0; 3]; 4], &[[0.0; 3]; 4], &phys);
            let mut largest = 0.0f64;
            for a in 0..4 {
                for i in 0..3 {
                    let f: f64 = (0..4).map(|b| (0..3).map(|j| es.k[a][b][i * B + j] * u[b][j]).sum::<f64>()).sum();
                    largest = largest.max(f.abs());
                }
            }
            largest
        };
        let scale = 0.04 * geo.volume_cm3 * 1.1;
        assert!(force(true) < 1e-12 * scale, "stress form: {}", force(true));
        assert!(force(false) > 1e-3 * scale, "Laplacian form: {}", force(false));
    }

    #[test]
    fn vms_advection_adds_the_fine_scale_velocity_of_the_residual() {
        // Uniform a equal to the old velocity (no time or convective residual) under a
        // pressure gradient: r_M = grad p / rho, so u' = -tau grad p / rho.
        let p = [[0.0, 0.0, 0.0], [1.2, 0.1, 0.0], [0.2, 0.9, 0.1], [0.1, 0.3, 1.1]];
        let geo = element_geometry(&p, &[0, 1, 2, 3]);
        let a = [[10.0, -5.0, 3.0]; 4];
        let grad_p = [40.0, -20.0, 7.0];
        let pressure = p.map(|x| crate::flow_mesh::dot(grad_p, x));
        let phys = Physics { density_g_cm3: 1.06, viscosity_g_cm_s: 0.04, inv_dt_per_s: 1e3, inv_dt_tau_per_s: 1e3, ..TEST_PHYSICS };
        let plain = element_state(&geo, &a, &a, &pressure, &phys);
        let vms = element_state(&geo, &a, &a, &pressure, &Physics { formulation: Formulation { vms_advection: true, ..phys.formulation }, ..phys });
        assert_eq!(plain.tau, vms.tau);
        let fine = grad_p.map(|g| -plain.tau * g / phys.density_g_cm3);
        for b in 0..4 {
            let expected = crate::flow_mesh::dot(add3(a[0], fine), geo.grads_per_cm[b]);
            assert!((vms.s[b] - expected).abs() < 1e-12 * expected.abs().max(1.0), "node {b}: {} vs {expected}", vms.s[b]);
            assert!((plain.s[b] - crate::flow_mesh::dot(a[0], geo.grads_per_cm[b])).abs() < 1e-12);
        }
        // Without a pressure gradient the uniform flow has no residual: nothing is added.
        let still = element_state(&geo, &a, &a, &[5.0; 4], &Physics { formulation: Formulation { vms_advection: true, ..phys.formulation }, ..phys });
        for b in 0..4 {
            assert!((still.s[b] - plain.s[b]).abs() < 1e-9 * plain.s[b].abs().max(1.0), "node {b}: {} vs {}", still.s[b], plain.s[b]);
        }
    }

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
        let phys = Physics { density_g_cm3: 1.06, viscosity_g_cm_s: 0.04, inv_dt_per_s: 0.0, inv_dt_tau_per_s: 0.0, ..TEST_PHYSICS };
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
    fn time_rows_apply_the_consistent_mass_matrix_to_the_old_velocity() {
        // With no advection (no SUPG term) node a's right-hand side is rho/dt sum_b M_ab u_b,
        // M_ab = V/10 on the diagonal and V/20 off it.
        let p = [[0.0, 0.0, 0.0], [1.2, 0.1, 0.0], [0.2, 0.9, 0.1], [0.1, 0.3, 1.1]];
        let geo = element_geometry(&p, &[0, 1, 2, 3]);
        let phys = Physics { density_g_cm3: 1.06, viscosity_g_cm_s: 0.04, inv_dt_per_s: 1e3, inv_dt_tau_per_s: 1e3, ..TEST_PHYSICS };
        let u_old = [[1.0, -2.0, 0.5], [0.3, 0.7, -1.1], [2.2, 0.0, 0.4], [-0.6, 1.5, 0.9]];
        let es = element_system(&geo, &[[0.0; 3]; 4], &u_old, &phys);
        for a in 0..4 {
            for i in 0..3 {
                let mass: f64 = (0..4).map(|b| if a == b { 0.1 } else { 0.05 } * geo.volume_cm3 * u_old[b][i]).sum();
                let expected = phys.density_g_cm3 * phys.inv_dt_per_s * mass;
                assert!((es.f[a][i] - expected).abs() < 1e-12 * expected.abs().max(1.0), "node {a}, component {i}: {} vs {expected}", es.f[a][i]);
            }
        }
    }

    #[test]
    fn row_by_row_assembly_equals_scattering_the_element_systems() {
        // The textbook assembly (scatter each element's whole system) against the
        // row-gathering one, on a tube whose rows are split over three partitions.
        let mesh = crate::test_meshes::tube(0.5, 2.0, 3, 6, &[]);
        let n = mesh.points_cm.len();
        let pattern = BlockPattern::from_tets(n, &mesh.tets);
        let parts = crate::linear::partitions(&pattern, 3);
        let mut asm = Assembler::new(&mesh.points_cm, mesh.tets.clone(), &pattern, parts);
        let phys = Physics { density_g_cm3: 1.06, viscosity_g_cm_s: 0.04, inv_dt_per_s: 1000.0, inv_dt_tau_per_s: 1000.0, ..TEST_PHYSICS };
        let field = |s: f64| (0..n * B).map(|k| ((k as f64 + s) * 0.37).sin() * 30.0).collect::<Vec<f64>>();
        let (a, u_old) = (field(0.0), field(2.0));
        let (mut expected, mut expected_rhs) = (vec![0.0; pattern.cols.len() * BB], vec![0.0; n * B]);
        for t in &mesh.tets {
            let nodal = |f: &[f64]| t.map(|i| [0, 1, 2].map(|c| f[i as usize * B + c]));
            let es = element_system(&element_geometry(&mesh.points_cm, t), &nodal(&a), &nodal(&u_old), &phys);
            for ai in 0..4 {
                for bi in 0..4 {
                    let p = pattern.position(t[ai] as usize, t[bi]).unwrap();
                    expected[p * BB..(p + 1) * BB].iter_mut().zip(&es.k[ai][bi]).for_each(|(d, s)| *d += s);
                }
                expected_rhs[t[ai] as usize * B..(t[ai] as usize + 1) * B].iter_mut().zip(&es.f[ai]).for_each(|(d, s)| *d += s);
            }
        }
        let (mut vals, mut rhs) = (vec![f64::NAN; expected.len()], vec![f64::NAN; expected_rhs.len()]);
        asm.assemble(&pattern, &phys, &a, &u_old, &mut vals, &mut rhs);
        let scale = expected.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let worst = vals.iter().zip(&expected).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max);
        assert!(worst <= 1e-12 * scale, "matrix differs by {worst:e} (scale {scale:e})");
        let rhs_scale = expected_rhs.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let rhs_worst = rhs.iter().zip(&expected_rhs).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max);
        assert!(rhs_scale > 0.0 && rhs_worst <= 1e-12 * rhs_scale, "rhs differs by {rhs_worst:e}");
    }

    #[test]
    fn convection_jacobian_is_the_derivative_of_the_galerkin_convection() {
        // The Galerkin convection c(a, u) is bilinear, so its derivative in a at a = u,
        // applied to v, equals c(v, u) = [K(a = v) - K(a = 0)] u. A huge viscosity makes
        // the SUPG/PSPG terms (which the Jacobian omits) negligible: tau ~ h^2 / nu.
        let p = [[0.0, 0.0, 0.0], [1.0, 0.1, 0.0], [0.2, 1.0, 0.1], [0.1, 0.3, 1.2], [1.0, 1.0, 1.0]];
        let tets = vec![[0, 1, 2, 3], [1, 2, 3, 4]];
        let pattern = BlockPattern::from_tets(5, &tets);
        let mut asm = Assembler::new(&p, tets, &pattern, vec![0..5]);
        for exact_convection in [false, true] {
            let phys = Physics { density_g_cm3: 1.0, viscosity_g_cm_s: 1e6, inv_dt_per_s: 0.0, inv_dt_tau_per_s: 0.0, formulation: Formulation { exact_convection, ..TEST_PHYSICS.formulation }, ..TEST_PHYSICS };
            jacobian_matches_the_convection_difference(&mut asm, &pattern, &phys);
        }
    }

    #[test]
    fn exact_convection_equals_the_galerkin_integral_of_the_p1_velocity() {
        // rho int N_a (a_h . grad N_b) dV with the 4-point Gauss rule (exact for the
        // quadratic integrand) against K(a) - K(0) on the velocity diagonal; a huge
        // viscosity keeps tau (and so the stabilization's dependence on a) negligible.
        let p = [[0.0, 0.0, 0.0], [1.2, 0.1, 0.0], [0.2, 0.9, 0.1], [0.1, 0.3, 1.1]];
        let geo = element_geometry(&p, &[0, 1, 2, 3]);
        let a = [[1.0, -2.0, 0.5], [0.3, 0.7, -1.1], [2.2, 0.0, 0.4], [-0.6, 1.5, 0.9]];
        let phys = Physics { density_g_cm3: 1.06, viscosity_g_cm_s: 1e8, formulation: Formulation { exact_convection: true, ..TEST_PHYSICS.formulation }, ..TEST_PHYSICS };
        let (with_a, without) = (element_system(&geo, &a, &[[0.0; 3]; 4], &phys), element_system(&geo, &[[0.0; 3]; 4], &[[0.0; 3]; 4], &phys));
        let (alpha, beta) = (0.585_410_196_624_968_5, 0.138_196_601_125_010_5);
        for ai in 0..4 {
            for bi in 0..4 {
                let mut expected = 0.0;
                for q in 0..4 {
                    let n: [f64; 4] = std::array::from_fn(|c| if c == q { alpha } else { beta });
                    let a_q: [f64; 3] = std::array::from_fn(|k| (0..4).map(|c| n[c] * a[c][k]).sum());
                    expected += 0.25 * geo.volume_cm3 * n[ai] * crate::flow_mesh::dot(a_q, geo.grads_per_cm[bi]);
                }
                expected *= phys.density_g_cm3;
                let got = with_a.k[ai][bi][0] - without.k[ai][bi][0];
                assert!((got - expected).abs() < 1e-6 * geo.volume_cm3, "({ai}, {bi}): {got} vs {expected}");
            }
        }
    }

    fn jacobian_matches_the_convection_difference(asm: &mut Assembler, pattern: &BlockPattern, phys: &Physics) {
        let field = |s: f64| (0..5 * B).map(|k| if k % B == 3 { 0.0 } else { ((k as f64 + s) * 0.7).sin() }).collect::<Vec<f64>>();
        let (u, v) = (field(0.0), field(1.3));
        let n_vals = pattern.cols.len() * BB;
        let matvec = |vals: &[f64], x: &[f64]| {
            let mut y = vec![0.0; x.len()];
            crate::sparse::spmv(pattern, vals, x, &mut y);
            y
        };
        let (mut k1, mut k0, mut rhs) = (vec![0.0; n_vals], vec![0.0; n_vals], vec![0.0; 5 * B]);
        asm.assemble(pattern, phys, &v, &u, &mut k1, &mut rhs);
        asm.assemble(pattern, phys, &vec![0.0; 5 * B], &u, &mut k0, &mut rhs);
        let expected: Vec<f64> = matvec(&k1, &u).iter().zip(matvec(&k0, &u)).map(|(a, b)| a - b).collect();
        let mut jac = vec![0.0; n_vals];
        asm.add_convection_jacobian(pattern, phys, &u, &mut jac);
        let got = matvec(&jac, &v);
        let scale = expected.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        assert!(scale > 1e-3);
        for k in (0..5 * B).filter(|k| k % B != 3) {
            assert!((got[k] - expected[k]).abs() < 1e-6 * scale, "exact {}: dof {k}: {} vs {}", phys.formulation.exact_convection, got[k], expected[k]);
        }
    }
}
