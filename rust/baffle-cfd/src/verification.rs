//! Verification of the solver on tube meshes built by the tests themselves.

use std::f64::consts::PI;

use crate::settings::{CaseSettings, NonlinearIterations, Outlet, RunMode};
use crate::solver::{simulate, Summary};
use crate::time_integration::TimeIntegration;
use crate::test_meshes::{tube, INLET, OUTLET, PLANE};
use crate::waveform::Waveform;

const RADIUS_CM: f64 = 0.25;
const LENGTH_CM: f64 = 3.0;
const MU: f64 = 0.04;

fn hagen_poiseuille_dp_dyn_cm2(q_ml_s: f64, length_cm: f64) -> f64 {
    8.0 * MU * length_cm * q_ml_s / (PI * RADIUS_CM.powi(4))
}

fn steady_settings(q_ml_s: f64, resistance: f64) -> CaseSettings {
    let mut s = CaseSettings::new(INLET, Waveform::Constant { q_ml_s }, vec![Outlet { face_id: OUTLET, resistance_dyn_s_cm5: resistance }]);
    s.mode = RunMode::Steady;
    s.steady_pseudo_dt_s = f64::INFINITY;
    s.linear_tolerance = 1e-8;
    s.steady_tolerance = 1e-8;
    s.steady_max_iterations = 20;
    s
}

fn run(rings: usize, layers: usize, settings: &CaseSettings) -> (Summary, [i32; 2]) {
    let (lo, hi) = (layers / 3, 5 * layers / 6);
    let mesh = tube(RADIUS_CM, LENGTH_CM, rings, layers, &[lo, hi]);
    let summary = simulate(&mesh, settings, &mut |_, _| true).unwrap();
    (summary, [PLANE + lo as i32, PLANE + hi as i32])
}

#[test]
fn poiseuille_pressure_drop_converges_to_hagen_poiseuille() {
    // Re = rho U D / mu = 13.5: the plug inflow develops within ~0.3 cm, well
    // before the first measurement plane at z = 1 cm.
    let q_ml_s = 0.2;
    let mut errors = Vec::new();
    for (rings, layers) in [(3, 12), (5, 18), (8, 30)] {
        let start = std::time::Instant::now();
        let (summary, [lo, hi]) = run(rings, layers, &steady_settings(q_ml_s, 0.0));
        assert!(summary.converged);
        let step = &summary.steps[0];
        let dp = step.face(lo).unwrap().mean_pressure_dyn_cm2 - step.face(hi).unwrap().mean_pressure_dyn_cm2;
        let length = LENGTH_CM * (5.0 / 6.0 - 1.0 / 3.0);
        let exact = hagen_poiseuille_dp_dyn_cm2(q_ml_s, length);
        let error = (dp - exact).abs() / exact;
        println!("rings {rings} layers {layers}: dp {dp:.4} exact {exact:.4} error {:.2}% ({:?}, {} picard)", 100.0 * error, start.elapsed(), step.nonlinear_iterations);
        errors.push(error);
    }
    assert!(errors.windows(2).all(|w| w[1] < w[0]), "error decreases with refinement: {errors:?}");
    assert!(errors[2] < 0.03, "finest error {errors:?}");
}

#[test]
fn resistance_outlet_pressure_is_r_times_q() {
    // R in the patients' range (3800-5500 dyn s/cm5), coupled implicitly.
    let q_ml_s = 0.2;
    for resistance in [3800.0, 5500.0] {
        let (summary, _) = run(4, 12, &steady_settings(q_ml_s, resistance));
        let step = &summary.steps[0];
        let outlet = step.face(OUTLET).unwrap();
        let expected = resistance * outlet.flow_ml_s;
        let error = (outlet.mean_pressure_dyn_cm2 - expected).abs() / expected;
        println!("R {resistance}: outlet p {:.3} R Q {expected:.3} error {:.4}%", outlet.mean_pressure_dyn_cm2, 100.0 * error);
        assert!(error < 0.01, "R {resistance}: {error}");
        assert!((outlet.flow_ml_s - q_ml_s).abs() < 1e-3 * q_ml_s);
    }
}

#[test]
fn transient_run_conserves_mass_and_follows_the_waveform() {
    // A pulse of the built-in ejection shape, compressed to 0.05 s, on a resistance
    // outlet: inflow = outflow within 0.5% at every step with flow.
    let mesh = tube(RADIUS_CM, LENGTH_CM, 3, 12, &[6]);
    let inflow = Waveform::Ejection { period_s: 0.05, q_mean_ml_s: 0.5 };
    let mut s = CaseSettings::new(INLET, inflow.clone(), vec![Outlet { face_id: OUTLET, resistance_dyn_s_cm5: 4000.0 }]);
    s.cycles = 1;
    s.dt_s = 1e-3;
    let mut calls = 0;
    let summary = simulate(&mesh, &s, &mut |_, _| {
        calls += 1;
        true
    })
    .unwrap();
    assert_eq!(summary.steps.len(), 50);
    assert_eq!(calls, 50);
    let peak = inflow.peak().0;
    for step in &summary.steps {
        assert!((step.inflow_ml_s - step.prescribed_inflow_ml_s).abs() < 1e-9 * peak, "{step:?}");
        if step.inflow_ml_s > 0.05 * peak {
            let imbalance = (step.inflow_ml_s - step.outflow_ml_s).abs() / step.inflow_ml_s;
            assert!(imbalance < 0.005, "step {}: in {} out {}", step.step, step.inflow_ml_s, step.outflow_ml_s);
        }
    }
    let worst = summary
        .steps
        .iter()
        .filter(|s| s.inflow_ml_s > 0.05 * peak)
        .map(|s| (s.inflow_ml_s - s.outflow_ml_s).abs() / s.inflow_ml_s)
        .fold(0.0, f64::max);
    println!("worst mass imbalance {:.3e}", worst);
}

#[test]
fn cancel_and_bad_settings_are_reported() {
    let mesh = tube(RADIUS_CM, 1.0, 2, 4, &[]);
    let mut s = CaseSettings::new(INLET, Waveform::Ejection { period_s: 0.01, q_mean_ml_s: 0.5 }, vec![Outlet { face_id: OUTLET, resistance_dyn_s_cm5: 0.0 }]);
    s.cycles = 1;
    let err = simulate(&mesh, &s, &mut |fraction, _| fraction < 0.5).unwrap_err();
    assert!(matches!(err, crate::CfdError::Cancelled { .. }), "{err}");
    s.outlets[0].face_id = 7;
    assert!(simulate(&mesh, &s, &mut |_, _| true).unwrap_err().to_string().contains("outlet face 7"));
    s.outlets[0].face_id = INLET;
    assert!(simulate(&mesh, &s, &mut |_, _| true).unwrap_err().to_string().contains("both inlet and outlet"));
}

#[test]
fn stopped_run_resumes_to_the_same_result() {
    for scheme in [TimeIntegration::BackwardEuler, TimeIntegration::GeneralizedAlpha { rho_inf: 0.5 }] {
        stopped_run_resumes_to_the_same_result_with(scheme);
    }
}

fn stopped_run_resumes_to_the_same_result_with(scheme: TimeIntegration) {
    let mesh = tube(RADIUS_CM, 1.0, 2, 4, &[]);
    let mut s = CaseSettings::new(INLET, Waveform::Ejection { period_s: 0.01, q_mean_ml_s: 0.5 }, vec![Outlet { face_id: OUTLET, resistance_dyn_s_cm5: 500.0 }]);
    s.cycles = 1;
    s.dt_s = 1e-3;
    s.time_integration = scheme;
    // New factors every step: a resumed run starts with new factors where the straight
    // run may still reuse old ones, which changes the solves within the linear tolerance.
    s.preconditioner_max_age = 1;
    let straight = crate::simulate_from(&mesh, &s, None, &mut |_| true).unwrap();
    assert_eq!(straight.summary.steps.len(), 10);
    assert!(straight.cancelled_at_s.is_none());
    // Stop after step 4 (results so far kept), continue from the state the observer saw.
    let mut seen = None;
    let first = crate::simulate_from(&mesh, &s, None, &mut |view| {
        seen = view.state();
        view.step < 4
    })
    .unwrap();
    assert_eq!(first.summary.steps.len(), 4);
    assert!((first.cancelled_at_s.unwrap() - 4e-3).abs() < 1e-12);
    let state = first.state.unwrap();
    assert_eq!(Some(&state), seen.as_ref());
    assert_eq!(state.step, 4);
    let rest = crate::simulate_from(&mesh, &s, Some(&state), &mut |_| true).unwrap();
    assert_eq!(rest.summary.steps.first().map(|r| r.step), Some(5));
    let joined: Vec<_> = first.summary.steps.iter().chain(&rest.summary.steps).collect();
    assert_eq!(joined.len(), straight.summary.steps.len());
    for (a, b) in joined.iter().zip(&straight.summary.steps) {
        assert_eq!(a.step, b.step);
        let scale = b.faces[0].mean_pressure_dyn_cm2.abs().max(1.0);
        assert!((a.faces[0].mean_pressure_dyn_cm2 - b.faces[0].mean_pressure_dyn_cm2).abs() < 1e-9 * scale, "step {}", a.step);
        assert!((a.max_velocity_cm_s - b.max_velocity_cm_s).abs() < 1e-9 * b.max_velocity_cm_s.max(1.0));
    }
    // A state of another mesh is refused; steady runs do not take one.
    let mut bad = state.clone();
    bad.pressure_dyn_cm2.pop();
    assert!(crate::simulate_from(&mesh, &s, Some(&bad), &mut |_| true).unwrap_err().to_string().contains("mesh nodes"));
    // Generalized-alpha needs the acceleration, which a backward-Euler state lacks.
    assert_eq!(state.acceleration_cm_s2.is_empty(), scheme == TimeIntegration::BackwardEuler);
    if scheme == TimeIntegration::BackwardEuler {
        let mut other = s.clone();
        other.time_integration = TimeIntegration::GeneralizedAlpha { rho_inf: 0.5 };
        assert!(crate::simulate_from(&mesh, &other, Some(&state), &mut |_| true).unwrap_err().to_string().contains("no acceleration"));
    }
    s.mode = RunMode::Steady;
    assert!(crate::simulate_from(&mesh, &s, Some(&state), &mut |_| true).is_err());
}

#[test]
fn pulsatile_run_becomes_periodic_over_cycles() {
    // Four cycles of the ejection waveform from rest: the start-up transient (the
    // velocity profile developing from rest) decays, so each cycle repeats the one
    // before more closely; measured on the inlet-outlet pressure difference as the
    // CLI's periodicity_nrmsd.
    let mesh = tube(RADIUS_CM, 1.5, 3, 8, &[]);
    let period_steps = 40;
    let inflow = Waveform::Ejection { period_s: period_steps as f64 * 1e-3, q_mean_ml_s: 0.5 };
    let mut s = CaseSettings::new(INLET, inflow, vec![Outlet { face_id: OUTLET, resistance_dyn_s_cm5: 4000.0 }]);
    s.cycles = 4;
    s.nonlinear_iterations = Some(NonlinearIterations::Fixed(1));
    let summary = simulate(&mesh, &s, &mut |_, _| true).unwrap();
    assert_eq!(summary.steps.len(), 4 * period_steps);
    let dp: Vec<f64> = summary
        .steps
        .iter()
        .map(|r| r.face(INLET).unwrap().mean_pressure_dyn_cm2 - r.face(OUTLET).unwrap().mean_pressure_dyn_cm2)
        .collect();
    let by_cycles: Vec<f64> = (2..=4).map(|c| crate::periodicity_nrmsd(&dp[..c * period_steps], period_steps).unwrap()).collect();
    println!("periodicity NRMSD cycles 1-2, 2-3, 3-4: {by_cycles:?}");
    assert!(by_cycles.windows(2).all(|w| w[1] <= w[0]), "{by_cycles:?}");
    assert!(by_cycles[2] < 0.01, "cycle 4 vs 3: {by_cycles:?}");
}

#[test]
fn stopped_steady_solve_resumes_on_the_same_path() {
    // Stop after 3 iterations, continue from the observer's state: the same iterations
    // (count, pseudo steps, Newton switch) and the same converged solution.
    let mesh = tube(RADIUS_CM, 1.5, 3, 8, &[]);
    let mut s = CaseSettings::new(INLET, Waveform::Constant { q_ml_s: 2.0 }, vec![Outlet { face_id: OUTLET, resistance_dyn_s_cm5: 4000.0 }]);
    s.mode = RunMode::Steady;
    let straight = crate::simulate_from(&mesh, &s, None, &mut |_| true).unwrap();
    assert!(straight.summary.converged);
    let total = straight.state.as_ref().unwrap().step;
    assert!(total > 4, "{total} iterations");
    let first = crate::simulate_from(&mesh, &s, None, &mut |view| view.step < 3).unwrap();
    let state = first.state.unwrap();
    assert_eq!((state.step, first.cancelled_at_s.is_some()), (3, true));
    assert!(state.steady.is_some());
    let rest = crate::simulate_from(&mesh, &s, Some(&state), &mut |_| true).unwrap();
    assert!(rest.summary.converged);
    assert_eq!(rest.state.as_ref().unwrap().step, total);
    let (a, b) = (&rest.summary.steps[0], &straight.summary.steps[0]);
    let p = |r: &crate::StepResult| r.face(INLET).unwrap().mean_pressure_dyn_cm2;
    assert!((p(a) - p(b)).abs() < 1e-9 * p(b).abs(), "{} vs {}", p(a), p(b));
    // A steady state does not start a transient run.
    s.mode = RunMode::Transient;
    s.inflow = Waveform::Ejection { period_s: 0.01, q_mean_ml_s: 0.5 };
    assert!(crate::simulate_from(&mesh, &s, Some(&state), &mut |_| true).unwrap_err().to_string().contains("steady solve"));
}

#[test]
fn blow_up_is_reported_with_step_and_time() {
    // A grossly excessive flow through a coarse tube with dt far too large for the
    // iteration count: the Picard iterates leave any physical range.
    let mesh = tube(RADIUS_CM, 1.0, 2, 4, &[]);
    let mut s = CaseSettings::new(INLET, Waveform::Constant { q_ml_s: 1e6 }, vec![Outlet { face_id: OUTLET, resistance_dyn_s_cm5: 0.0 }]);
    s.mode = RunMode::Steady;
    let err = simulate(&mesh, &s, &mut |_, _| true).unwrap_err();
    let msg = err.to_string();
    assert!(msg.contains("step") && msg.contains("t = ") && msg.contains("residual"), "{msg}");
}

/// Minimal complex arithmetic for the Womersley solution.
#[derive(Clone, Copy, Debug)]
struct C(f64, f64);

impl C {
    fn add(self, o: C) -> C {
        C(self.0 + o.0, self.1 + o.1)
    }
    fn mul(self, o: C) -> C {
        C(self.0 * o.0 - self.1 * o.1, self.0 * o.1 + self.1 * o.0)
    }
    fn div(self, o: C) -> C {
        let d = o.0 * o.0 + o.1 * o.1;
        C((self.0 * o.0 + self.1 * o.1) / d, (self.1 * o.0 - self.0 * o.1) / d)
    }
    fn scale(self, s: f64) -> C {
        C(self.0 * s, self.1 * s)
    }
    fn abs(self) -> f64 {
        self.0.hypot(self.1)
    }
    fn arg(self) -> f64 {
        self.1.atan2(self.0)
    }
}

/// Bessel function J_n(z), n = 0 or 1, by its power series (|z| <= ~10).
fn bessel_j(n: i32, z: C) -> C {
    let half = z.scale(0.5);
    let q = half.mul(half).scale(-1.0);
    let mut term = if n == 0 { C(1.0, 0.0) } else { half };
    let mut sum = term;
    for k in 1..60 {
        term = term.mul(q).scale(1.0 / (k as f64 * (k + n) as f64));
        sum = sum.add(term);
    }
    sum
}

/// Complex amplitude G of the Womersley pressure gradient -dp/dz = Im(G e^{i w t}) for
/// the flux Q(t) = Q0 sin(w t) in a tube of radius R:
/// G = i w rho Q0 / (pi R^2 (1 - 2 J1(L) / (L J0(L)))), L = i^{3/2} alpha.
fn womersley_gradient(q0: f64, omega: f64, rho: f64, mu: f64, radius: f64) -> C {
    let alpha = radius * (omega * rho / mu).sqrt();
    let l = C((0.75 * PI).cos(), (0.75 * PI).sin()).scale(alpha);
    let ratio = bessel_j(1, l).scale(2.0).div(l.mul(bessel_j(0, l)));
    let denominator = C(1.0, 0.0).add(ratio.scale(-1.0)).scale(PI * radius * radius);
    C(0.0, omega * rho * q0).div(denominator)
}

#[test]
fn womersley_solution_is_poiseuille_at_low_frequency() {
    let (q0, rho) = (0.2, 1.06);
    let g = womersley_gradient(q0, 1e-4, rho, MU, RADIUS_CM);
    let poiseuille = 8.0 * MU * q0 / (PI * RADIUS_CM.powi(4));
    assert!((g.abs() - poiseuille).abs() < 1e-6 * poiseuille && g.arg().abs() < 1e-4, "{g:?} vs {poiseuille}");
}

/// The Womersley case of alpha = 4 (the gradient leads the flux by about 50 degrees):
/// sinusoidal flux through a plug inlet, zero outlet pressure, `per_period` steps a
/// period; the pressure gradient between interior planes at z = 1 and 2.5 cm fitted
/// over the second period (the first is discarded: zero-flux transients decay at
/// ~16/s). Returns the fitted and the exact complex gradient amplitude.
fn womersley_fit(per_period: usize, rings: usize, layers: usize, scheme: TimeIntegration, tau_includes_dt: bool) -> (C, C) {
    womersley_fit_with(per_period, rings, layers, scheme, tau_includes_dt, NonlinearIterations::Fixed(1)).0
}

/// [`womersley_fit`] with the given Picard iterations; also returns the run's summary.
fn womersley_fit_with(per_period: usize, rings: usize, layers: usize, scheme: TimeIntegration, tau_includes_dt: bool, nonlinear: NonlinearIterations) -> ((C, C), Summary) {
    let (rho, alpha, q0) = (1.06, 4.0, 0.2);
    let omega = alpha * alpha * MU / (rho * RADIUS_CM * RADIUS_CM);
    let period = 2.0 * PI / omega;
    let dt = period / per_period as f64;
    // A finer table than any step, so the inflow's linear interpolation adds no error.
    let table = 1280;
    let times_s: Vec<f64> = (0..table).map(|i| i as f64 * period / table as f64).collect();
    let flows_ml_s = times_s.iter().map(|t| q0 * (omega * t).sin()).collect();
    let inflow = Waveform::Table { times_s, flows_ml_s, period_s: period };
    let (lo, hi) = (layers / 3, 5 * layers / 6);
    let mesh = tube(RADIUS_CM, LENGTH_CM, rings, layers, &[lo, hi]);
    let mut s = CaseSettings::new(INLET, inflow, vec![Outlet { face_id: OUTLET, resistance_dyn_s_cm5: 0.0 }]);
    s.density_g_cm3 = rho;
    s.dt_s = dt;
    s.cycles = 2;
    s.linear_tolerance = 1e-8;
    s.time_integration = scheme;
    s.tau_includes_dt = tau_includes_dt;
    s.nonlinear_iterations = Some(nonlinear);
    let start = std::time::Instant::now();
    let summary = simulate(&mesh, &s, &mut |_, _| true).unwrap();
    let length = LENGTH_CM * (hi - lo) as f64 / layers as f64;
    let (mut a, mut b) = (0.0, 0.0);
    for step in &summary.steps[per_period..] {
        let g = (step.face(PLANE + lo as i32).unwrap().mean_pressure_dyn_cm2 - step.face(PLANE + hi as i32).unwrap().mean_pressure_dyn_cm2) / length;
        a += 2.0 / per_period as f64 * g * (omega * step.time_s).sin();
        b += 2.0 / per_period as f64 * g * (omega * step.time_s).cos();
    }
    let (computed, exact) = (C(a, b), womersley_gradient(q0, omega, rho, MU, RADIUS_CM));
    println!(
        "Womersley alpha {alpha}, {scheme:?}, {per_period} steps a period: |G| {:.5} exact {:.5}, phase {:.3} deg exact {:.3} deg, {} steps in {:?}",
        computed.abs(),
        exact.abs(),
        computed.arg().to_degrees(),
        exact.arg().to_degrees(),
        summary.steps.len(),
        start.elapsed()
    );
    ((computed, exact), summary)
}

#[test]
fn womersley_pressure_gradient_amplitude_and_phase() {
    for scheme in [TimeIntegration::BackwardEuler, TimeIntegration::GeneralizedAlpha { rho_inf: 0.5 }] {
        let (computed, exact) = womersley_fit(160, 4, 12, scheme, true);
        let amplitude_error = (computed.abs() - exact.abs()) / exact.abs();
        let phase_error = (computed.arg() - exact.arg()) / exact.arg();
        assert!(amplitude_error.abs() < 0.05, "{scheme:?}: amplitude error {amplitude_error}");
        assert!(phase_error.abs() < 0.05, "{scheme:?}: phase error {phase_error}");
    }
}

/// |G(dt) - G(dt/2)| for dt = T/20, T/40, T/80 (self-convergence on one mesh: the
/// spatial error cancels in the differences).
fn womersley_differences(scheme: TimeIntegration, tau_includes_dt: bool) -> Vec<f64> {
    womersley_differences_with(&[20, 40, 80, 160], scheme, tau_includes_dt, NonlinearIterations::Fixed(1))
}

fn womersley_differences_with(per_period: &[usize], scheme: TimeIntegration, tau_includes_dt: bool, nonlinear: NonlinearIterations) -> Vec<f64> {
    let g: Vec<C> = per_period.iter().map(|&n| womersley_fit_with(n, 2, 6, scheme, tau_includes_dt, nonlinear).0 .0).collect();
    let d: Vec<f64> = g.windows(2).map(|w| w[0].add(w[1].scale(-1.0)).abs()).collect();
    println!("{scheme:?}, {nonlinear:?}, tau with dt {tau_includes_dt}: differences {d:?}, ratios {:?}", d.windows(2).map(|w| w[0] / w[1]).collect::<Vec<_>>());
    d
}

#[test]
fn generalized_alpha_converges_in_time_at_second_order_on_womersley() {
    // Without dt in tau the discrete operator is the same at every dt, and the
    // differences shrink 4x a halving for generalized-alpha (any rho_inf), 2x for
    // backward Euler.
    let order = |d: &[f64]| d.windows(2).map(|w| (w[0] / w[1]).log2()).collect::<Vec<f64>>();
    for rho_inf in [0.0, 0.5, 1.0] {
        let d = womersley_differences(TimeIntegration::GeneralizedAlpha { rho_inf }, false);
        assert!(order(&d).iter().all(|p| (p - 2.0).abs() < 0.15), "rho_inf {rho_inf}: differences {d:?}");
    }
    let d = womersley_differences(TimeIntegration::BackwardEuler, false);
    assert!(order(&d).iter().all(|p| (p - 1.0).abs() < 0.15), "backward Euler: differences {d:?}");
    // With dt in tau (the default) the operator's own first-order change remains, but
    // generalized-alpha's dt-error is still a fraction of backward Euler's.
    let (be, ga) = (womersley_differences(TimeIntegration::BackwardEuler, true), womersley_differences(TimeIntegration::GeneralizedAlpha { rho_inf: 0.5 }, true));
    assert!(be.iter().zip(&ga).all(|(b, g)| g < &(0.6 * b)), "backward Euler {be:?}, generalized-alpha {ga:?}");
}

/// A short pulsatile tube run: 10 steps of 1 ms over one ejection.
fn retry_case(max_linear_iterations: usize) -> CaseSettings {
    let inflow = Waveform::Ejection { period_s: 0.01, q_mean_ml_s: 2.0 };
    let mut s = CaseSettings::new(INLET, inflow, vec![Outlet { face_id: OUTLET, resistance_dyn_s_cm5: 500.0 }]);
    s.cycles = 1;
    // Tight, so that a solve accepted at 100x the tolerance is still accurate to ~1e-4.
    s.linear_tolerance = 1e-6;
    s.max_linear_iterations = max_linear_iterations;
    s
}

#[test]
fn a_stalled_linear_solve_is_retried_and_the_run_goes_on() {
    // A GMRES budget too small for the configured solve forces every step onto the
    // retry ladder; the retried steps must give the unhindered run's answer.
    let mesh = tube(RADIUS_CM, 1.0, 3, 8, &[]);
    let free = simulate(&mesh, &retry_case(600), &mut |_, _| true).unwrap();
    let fewest = free.steps.iter().map(|s| s.linear_iterations).min().unwrap();
    assert!(free.steps.iter().all(|s| s.retries == 0));
    let capped = simulate(&mesh, &retry_case(fewest / 2), &mut |_, _| true).unwrap();
    assert!(capped.steps.iter().any(|s| s.retries > 0), "fewest GMRES iterations a step {fewest}; {:?}", capped.steps.iter().map(|s| s.retries).collect::<Vec<_>>());
    // Both solved each step to the linear tolerance (or accepted at 100x it).
    assert_same_inlet_pressures(&capped, &free, 1e-3);
}

/// `run`'s inlet pressure at every step within `tolerance` of the largest of `reference`'s.
fn assert_same_inlet_pressures(run: &Summary, reference: &Summary, tolerance: f64) {
    let p = |s: &crate::StepResult| s.face(INLET).unwrap().mean_pressure_dyn_cm2;
    let scale = reference.steps.iter().map(|s| p(s).abs()).fold(0.0, f64::max);
    for (a, b) in run.steps.iter().zip(&reference.steps) {
        assert!((p(a) - p(b)).abs() <= tolerance * scale, "step {}: {} vs {} (largest {scale})", a.step, p(a), p(b));
    }
}

#[test]
fn reused_preconditioners_give_the_fresh_answer_with_fewer_factorizations() {
    // Keeping the factors (the default) changes only how GMRES gets to the linear
    // tolerance, not the solution it reaches; new factors every step as the reference.
    let mesh = tube(RADIUS_CM, 1.0, 3, 8, &[]);
    let mut s = retry_case(600);
    s.preconditioner_max_age = 1;
    let fresh = simulate(&mesh, &s, &mut |_, _| true).unwrap();
    let reused = simulate(&mesh, &retry_case(600), &mut |_, _| true).unwrap();
    let n = fresh.steps.len();
    assert_eq!(fresh.timings.factorizations, n);
    assert!(reused.timings.factorizations < n, "{} factorizations in {n} steps", reused.timings.factorizations);
    s.preconditioner_max_age = 3;
    let capped = simulate(&mesh, &s, &mut |_, _| true).unwrap();
    assert!(capped.timings.factorizations >= n.div_ceil(3), "at most 3 solves a factorization: {} in {n} steps", capped.timings.factorizations);
    assert!(reused.steps.iter().all(|s| s.retries == 0));
    assert_same_inlet_pressures(&reused, &fresh, 1e-4);
}

#[test]
fn a_step_that_fails_every_retry_says_what_was_tried_and_what_to_try() {
    let mesh = tube(RADIUS_CM, 1.0, 3, 8, &[]);
    let mut s = retry_case(1);
    s.linear_tolerance = 1e-12;
    let msg = simulate(&mesh, &s, &mut |_, _| true).unwrap_err().to_string();
    assert!(msg.starts_with("time step 1 (t = 0.0010 s) failed on every retry"), "{msg}");
    assert!(msg.contains("the configured solve: linear solver failed") && msg.contains("on 4 sub-steps of dt/4"), "{msg}");
    assert!(msg.contains("Try a smaller time step"), "{msg}");
}

#[test]
fn generalized_alpha_with_its_auto_loop_stays_second_order_on_womersley() {
    // The scheme's default (the convergence-controlled Picard loop) against backward
    // Euler's (one solve a step): G(T/20) - G(T/40) and G(T/40) - G(T/80) shrink 4x and 2x.
    let ga = TimeIntegration::GeneralizedAlpha { rho_inf: 0.5 };
    let auto = NonlinearIterations::Auto { cap: crate::AUTO_NONLINEAR_CAP };
    let d_ga = womersley_differences_with(&[20, 40, 80], ga, false, auto);
    let d_be = womersley_differences_with(&[20, 40, 80], TimeIntegration::BackwardEuler, false, NonlinearIterations::Fixed(1));
    let order = |d: &[f64]| (d[0] / d[1]).log2();
    assert!((order(&d_ga) - 2.0).abs() < 0.15, "generalized-alpha auto: differences {d_ga:?}");
    assert!((order(&d_be) - 1.0).abs() < 0.15, "backward Euler: differences {d_be:?}");
    assert!(d_ga[1] < 0.2 * d_be[1], "generalized-alpha {d_ga:?} vs backward Euler {d_be:?}");
    let ((_, _), summary) = womersley_fit_with(40, 2, 6, ga, false, auto);
    assert!(summary.steps.iter().all(|r| r.nonlinear_converged), "every step converged");
}

/// Generalized-alpha (its default: the auto loop) over one ejection of `q_mean_ml_s`
/// through a short tube, 1 ms steps.
fn auto_loop_run(q_mean_ml_s: f64, nonlinear: Option<NonlinearIterations>, tolerance: f64) -> Summary {
    let mesh = tube(RADIUS_CM, 1.0, 3, 8, &[]);
    let inflow = Waveform::Ejection { period_s: 0.01, q_mean_ml_s };
    let mut s = CaseSettings::new(INLET, inflow, vec![Outlet { face_id: OUTLET, resistance_dyn_s_cm5: 500.0 }]);
    s.cycles = 1;
    s.time_integration = TimeIntegration::GeneralizedAlpha { rho_inf: 0.5 };
    s.nonlinear_iterations = nonlinear;
    s.nonlinear_tolerance = tolerance;
    simulate(&mesh, &s, &mut |_, _| true).unwrap()
}

#[test]
fn auto_loop_stops_early_where_convection_is_negligible_and_iterates_where_it_is_not() {
    // Stokes-like (Re ~0.1 in a 5 mm tube): the first solve is converged, the second
    // only confirms it (its update is the first's linear-solve error), and the loop stops
    // there, far below its cap (a third where the flow stops and the pressure is small).
    let stokes = auto_loop_run(0.01, None, 1e-3);
    let solves: Vec<usize> = stokes.steps.iter().map(|r| r.nonlinear_iterations).collect();
    assert!(solves.iter().all(|&n| n <= 3) && solves.iter().filter(|&&n| n == 2).count() * 2 > solves.len(), "solves a step {solves:?}");
    assert!(stokes.steps.iter().all(|r| r.nonlinear_converged));
    // Re ~1,000 at the peak: the convection velocity moves, the loop iterates (below its cap)
    // and lands where a fixed 6 iterations do.
    let fast = auto_loop_run(20.0, None, 1e-3);
    let solves: Vec<usize> = fast.steps.iter().map(|r| r.nonlinear_iterations).collect();
    assert!(solves.iter().any(|&n| n >= 2) && solves.iter().all(|&n| n < crate::AUTO_NONLINEAR_CAP), "solves a step {solves:?}");
    assert!(fast.steps.iter().all(|r| r.nonlinear_converged));
    let iterated = auto_loop_run(20.0, Some(NonlinearIterations::Fixed(6)), 1e-9);
    let p = |r: &crate::StepResult| r.face(INLET).unwrap().mean_pressure_dyn_cm2;
    let scale = iterated.steps.iter().map(|r| p(r).abs()).fold(0.0, f64::max);
    for (a, b) in fast.steps.iter().zip(&iterated.steps) {
        assert!((p(a) - p(b)).abs() <= 5e-3 * scale, "step {}: {} vs {} (largest {scale})", a.step, p(a), p(b));
    }
}

#[test]
fn a_step_at_the_auto_loops_cap_is_reported_unconverged() {
    // A tolerance no update reaches: every step stops at the cap of 2 solves, flagged;
    // a fixed iteration count (the user's explicit choice) is never flagged.
    let capped = auto_loop_run(20.0, Some(NonlinearIterations::Auto { cap: 2 }), 1e-14);
    assert!(capped.steps.iter().all(|r| !r.nonlinear_converged && r.nonlinear_iterations == 2), "{:?}", capped.steps.iter().map(|r| (r.nonlinear_iterations, r.nonlinear_converged)).collect::<Vec<_>>());
    let fixed = auto_loop_run(20.0, Some(NonlinearIterations::Fixed(2)), 1e-14);
    assert!(fixed.steps.iter().all(|r| r.nonlinear_converged));
    // The default for generalized-alpha is the auto loop, for backward Euler one solve.
    let mut s = CaseSettings::new(INLET, Waveform::Ejection { period_s: 0.01, q_mean_ml_s: 1.0 }, vec![Outlet { face_id: OUTLET, resistance_dyn_s_cm5: 0.0 }]);
    assert_eq!(s.nonlinear(), NonlinearIterations::Fixed(1));
    s.time_integration = TimeIntegration::GeneralizedAlpha { rho_inf: 0.5 };
    assert_eq!(s.nonlinear(), NonlinearIterations::Auto { cap: crate::AUTO_NONLINEAR_CAP });
    s.nonlinear_iterations = Some(NonlinearIterations::Auto { cap: 0 });
    assert!(s.validate().unwrap_err().to_string().contains("iteration limits"));
}
