//! Case settings with the paper's defaults (Martinez et al., svMultiPhysics setup).

use crate::assembly::{Formulation, TauMetric};
use crate::time_integration::TimeIntegration;
use crate::waveform::Waveform;
use crate::CfdError;

/// Resistance outlet: p = R Q, coupled implicitly.
#[derive(Clone, Debug, PartialEq)]
pub struct Outlet {
    pub face_id: i32,
    pub resistance_dyn_s_cm5: f64,
}

/// Velocity profile imposed on the inlet cap.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InflowProfile {
    /// The same velocity at every node off the rim (rim nodes are no-slip).
    Plug,
    /// Fully developed laminar profile of the cap's shape (-lap phi = 1, phi = 0 on the rim).
    Poiseuille,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RunMode {
    /// Time-accurate run over `cycles` periods of the inflow waveform.
    Transient,
    /// Steady solution with the inflow fixed at the waveform's peak flow.
    Steady,
}

/// How many Picard iterations (linear solves, each with the convection velocity of the
/// last iterate) a transient time step makes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NonlinearIterations {
    /// At most this many. 1 is the semi-implicit step: one solve with the extrapolated
    /// convection velocity, no residual check; more stop once the residual has fallen by
    /// `nonlinear_tolerance`. The step is never reported unconverged.
    Fixed(usize),
    /// Until an update changes the velocity and the pressure by less than
    /// `nonlinear_tolerance` (relative 2-norms, each apart; see `solver::relative_change`),
    /// at most `cap` solves; a step still changing at the cap is reported unconverged
    /// (`StepResult::nonlinear_converged`).
    Auto { cap: usize },
}

/// The auto loop's cap: on p2's published mesh, from rest to the first peak, generalized-alpha
/// needs at most 3 solves a step at dt 1-2 ms (1.9 / 2.6 on average; docs/cfd.md).
pub const AUTO_NONLINEAR_CAP: usize = 6;

impl NonlinearIterations {
    /// The most linear solves a step may make.
    pub fn max_iterations(&self) -> usize {
        match *self {
            NonlinearIterations::Fixed(n) => n,
            NonlinearIterations::Auto { cap } => cap,
        }
    }
}

/// Aggregate size of the two-level preconditioner: on tubes of 9.7k-150k tets GMRES
/// then needs 31-45 iterations a step against ILU(0)'s 49-283 (docs/measurements.md).
pub const TWO_LEVEL_AGGREGATE_NODES: usize = 256;

#[derive(Clone, Debug, PartialEq)]
pub struct CaseSettings {
    pub density_g_cm3: f64,
    pub viscosity_g_cm_s: f64,
    pub dt_s: f64,
    pub cycles: usize,
    /// Relative residual reduction of each linear solve.
    pub linear_tolerance: f64,
    /// Backflow stabilization coefficient beta at outlets (Esmaily Moghadam et al. 2011).
    pub backflow_stabilization: f64,
    pub inlet_face_id: i32,
    pub inflow: Waveform,
    pub inflow_profile: InflowProfile,
    pub outlets: Vec<Outlet>,
    pub mode: RunMode,
    /// Transient runs: backward Euler (the default, as the published runs) or
    /// generalized-alpha (second order, as svMultiPhysics); steady solves ignore it.
    pub time_integration: TimeIntegration,
    /// Whether tau holds the time scale (2/dt)^2 (true, the default, as svMultiPhysics).
    /// With it the discrete operator changes with dt, by a first-order term at a fixed
    /// mesh (Womersley test: it then dominates generalized-alpha's temporal error);
    /// false keeps only the flow and mesh scales, so the time error is the scheme's own.
    pub tau_includes_dt: bool,
    /// How the element terms are formed: tau's metric and svMultiPhysics' VMS ingredients
    /// ([`Formulation`]).
    pub formulation: Formulation,
    /// Picard iterations per transient step (None: the scheme's default, see
    /// [`CaseSettings::nonlinear`]) and their relative target (residual or update).
    pub nonlinear_iterations: Option<NonlinearIterations>,
    pub nonlinear_tolerance: f64,
    pub gmres_restart: usize,
    pub max_linear_iterations: usize,
    /// Inner GMRES in f32 with f64 iterative refinement (`linear::solve_refined`)
    /// instead of GMRES in f64: same tolerance on the f64 residual, less memory traffic.
    pub mixed_precision: bool,
    /// Two-level preconditioner ([`crate::coarse`]): after ILU(0), a coarse-grid
    /// correction on aggregates of at least this many nodes (0: ILU(0) alone).
    pub coarse_aggregate_nodes: usize,
    /// Transient runs: how many consecutive solves one ILU(0) factorization and coarse
    /// correction may precondition (1: new factors at every solve). Old factors are
    /// renewed earlier when GMRES needs clearly more iterations with them.
    pub preconditioner_max_age: usize,
    /// Steady mode: pseudo time step (s) of the pseudo-transient continuation, or
    /// infinite for plain Picard iterations; iterations and residual reduction target.
    pub steady_pseudo_dt_s: f64,
    /// Cap of the growing pseudo time step (infinite: none).
    pub steady_pseudo_dt_max_s: f64,
    /// Steady mode: Newton (convection Jacobian) instead of Picard linearization once
    /// the relative steady residual is below this value (0: Picard only).
    pub steady_newton_below: f64,
    pub steady_max_iterations: usize,
    pub steady_tolerance: f64,
}

/// svMultiPhysics' method, the solver's default (issue 28): with tau's metric alone our dp
/// was 7.3 % below svMultiPhysics' at p3's first peak on the same mesh; the Reynolds-stress
/// term closes most of it (-2.2 %), Gauss-point stabilization and exact convection the rest
/// (+0.0 %), VMS advection keeps the jet's kinetic energy at the aortic plane (v_max -0.6
/// %); docs/validation.md. An export to svMultiPhysics runs this method and tau with dt.
pub const SVMULTIPHYSICS_FORMULATION: Formulation = Formulation {
    tau_metric: TauMetric::SvMultiPhysics,
    exact_convection: true,
    vms_advection: true,
    stress_viscosity: false,
    gauss_stabilization: true,
    vms_reynolds_stress: true,
};

impl CaseSettings {
    /// Paper defaults: rho 1.06, mu 0.04, dt 1 ms, 4 cycles, linear tolerance 1e-4,
    /// backflow stabilization 0.2.
    pub fn new(inlet_face_id: i32, inflow: Waveform, outlets: Vec<Outlet>) -> Self {
        CaseSettings {
            density_g_cm3: 1.06,
            viscosity_g_cm_s: 0.04,
            dt_s: 1e-3,
            cycles: 4,
            linear_tolerance: 1e-4,
            backflow_stabilization: 0.2,
            inlet_face_id,
            inflow,
            inflow_profile: InflowProfile::Plug,
            outlets,
            mode: RunMode::Transient,
            time_integration: TimeIntegration::BackwardEuler,
            tau_includes_dt: true,
            formulation: SVMULTIPHYSICS_FORMULATION,
            nonlinear_iterations: None,
            nonlinear_tolerance: 1e-3,
            // GMRES(30): on tubes of 9.7k-622k tets 4-10 % fewer iterations and 10-17 % less
            // CPU a step than GMRES(60) (shorter f32 rounds, each restarted from the f64
            // residual; docs/measurements.md).
            gmres_restart: 30,
            max_linear_iterations: 600,
            mixed_precision: true,
            // Two-level (ILU(0) + coarse correction): on p2's published mesh 15 GMRES
            // iterations a step instead of 40, 0.61 instead of 1.07 s a step.
            coarse_aggregate_nodes: TWO_LEVEL_AGGREGATE_NODES,
            // Factors kept while they cost fewer GMRES iterations than a renewal (solver.rs,
            // FactorsUse): on p2 from rest to the first peak (164 steps) 12 factorizations
            // instead of 164, 14.2 instead of 13.7 GMRES iterations a step, the same dp and
            // v_max to 4 digits, CPU 0.33 -> 0.27-0.33 s a step (docs/measurements.md).
            preconditioner_max_age: 50,
            steady_pseudo_dt_s: 0.01,
            steady_pseudo_dt_max_s: f64::INFINITY,
            steady_newton_below: 1e-2,
            steady_max_iterations: 60,
            steady_tolerance: 1e-4,
        }
    }

    /// The Picard iterations of a transient step. By default backward Euler makes one
    /// linear solve (semi-implicit, see solver.rs): on p2 it follows Picard iterated to
    /// 1e-3 within 0.3 % in dp, at a third of the time, its damping hiding the
    /// extrapolation's oscillation. Generalized-alpha iterates to convergence: semi-implicit
    /// it oscillates in p2's VSD jet at dt 1-2 ms (dp at the first peak -4.6 % at 1 ms,
    /// +10.9 % at 2 ms against the 0.25 ms run; iterated -1.3 % and -0.4 %, within the
    /// jet's own 0.1 mmHg fluctuation, as backward Euler; docs/cfd.md).
    pub fn nonlinear(&self) -> NonlinearIterations {
        self.nonlinear_iterations.unwrap_or(match self.time_integration {
            TimeIntegration::BackwardEuler => NonlinearIterations::Fixed(1),
            TimeIntegration::GeneralizedAlpha { .. } => NonlinearIterations::Auto { cap: AUTO_NONLINEAR_CAP },
        })
    }

    pub fn validate(&self) -> Result<(), CfdError> {
        let positive = [
            ("density", self.density_g_cm3),
            ("viscosity", self.viscosity_g_cm_s),
            ("dt", self.dt_s),
            ("linear tolerance", self.linear_tolerance),
            ("nonlinear tolerance", self.nonlinear_tolerance),
            ("steady tolerance", self.steady_tolerance),
            ("steady pseudo dt", self.steady_pseudo_dt_s),
            ("steady pseudo dt cap", self.steady_pseudo_dt_max_s),
        ];
        for (name, v) in positive {
            if !(v > 0.0) || v.is_nan() {
                return Err(CfdError::Settings(format!("{name} must be positive, got {v}")));
            }
        }
        if !(self.backflow_stabilization >= 0.0) {
            return Err(CfdError::Settings(format!("backflow stabilization must be >= 0, got {}", self.backflow_stabilization)));
        }
        if let TimeIntegration::GeneralizedAlpha { rho_inf } = self.time_integration {
            if !(0.0..=1.0).contains(&rho_inf) {
                return Err(CfdError::Settings(format!("generalized-alpha spectral radius rho_inf must be in [0, 1], got {rho_inf}")));
            }
        }
        if self.outlets.is_empty() {
            return Err(CfdError::Settings("at least one outlet is needed".into()));
        }
        for o in &self.outlets {
            if !(o.resistance_dyn_s_cm5 >= 0.0 && o.resistance_dyn_s_cm5.is_finite()) {
                return Err(CfdError::Settings(format!("outlet {} resistance {} is not >= 0", o.face_id, o.resistance_dyn_s_cm5)));
            }
            if o.face_id == self.inlet_face_id {
                return Err(CfdError::Settings(format!("face {} is both inlet and outlet", o.face_id)));
            }
        }
        if self.mode == RunMode::Transient && (self.cycles == 0 || !self.inflow.period_s().is_finite()) {
            return Err(CfdError::Settings("a transient run needs cycles >= 1 of a periodic waveform".into()));
        }
        if self.nonlinear().max_iterations() == 0 || self.gmres_restart == 0 || self.max_linear_iterations == 0 || self.preconditioner_max_age == 0 {
            return Err(CfdError::Settings("iteration limits must be >= 1".into()));
        }
        Ok(())
    }
}
