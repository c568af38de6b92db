//! Verification of the solver on tube meshes built by the tests themselves.

use std::f64::consts::PI;

use crate::settings::{CaseSettings, Outlet, RunMode};
use crate::solver::{simulate, Summary};
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
