//! Time integration of the momentum equation: backward Euler or the generalized-alpha
//! method for first-order systems (Jansen, Whiting & Hulbert 2000), as svMultiPhysics.
//!
//! Generalized-alpha with unknowns u_{n+1}, its time derivative a_{n+1} and p_{n+1}:
//!
//!   u_{n+1} = u_n + dt a_n + gamma dt (a_{n+1} - a_n)
//!   a_{n+am} = a_n + am (a_{n+1} - a_n),   u_{n+af} = u_n + af (u_{n+1} - u_n)
//!   rho a_{n+am} + N(u_{n+af}) + grad p_{n+1} = 0,   div u_{n+af} = 0
//!
//! with am = (3 - rho_inf) / (2 (1 + rho_inf)), af = 1 / (1 + rho_inf) and
//! gamma = 1/2 + am - af (second order). Solving for the stage velocity y = u_{n+af}
//! instead of u_{n+1}, the momentum equation becomes backward Euler's with another
//! time coefficient and another "old" velocity:
//!
//!   rho a_{n+am} = rho c (y - u*),  c = am / (gamma af dt),
//!   u* = u_n - (gamma - am) af dt / am  a_n,
//!
//! so the element matrices of [`crate::assembly`] serve both schemes unchanged
//! (1/dt -> c, u_old -> u*). Backward Euler is am = af = gamma = 1: c = 1/dt, u* = u_n,
//! u_{n+1} = y, and every formula below then reduces to it exactly (bit for bit).
//!
//! The pressure is the constraint's multiplier: the one solved for balances the momentum
//! at the stage time t_n + af dt, and it enters no later step (only as an initial guess).
//! Reported at t_{n+1} as it is, it would lag by (1 - af) dt, a first-order error in the
//! pressure (on the Womersley test: the same error as backward Euler's). So the reported
//! p_{n+1} is the stage pressure extrapolated linearly from the last two stage pressures,
//! p_s + (1 - af) dt (p_s - p_s,prev) / dt, second order; the pressure slot of the
//! "acceleration" vector keeps (p_s - p_s,prev) / dt for it.

use crate::sparse::B;

/// The time integration scheme of a transient run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TimeIntegration {
    /// First order, strongly damping (spectral radius 0 at infinite time step).
    BackwardEuler,
    /// Second order; `rho_inf` in [0, 1] is the spectral radius at infinite time step
    /// (svMultiPhysics' `Spectral_radius_of_infinite_time_step`): 1 keeps every
    /// frequency (no damping), 0 annihilates the highest in one step.
    GeneralizedAlpha { rho_inf: f64 },
}

/// svMultiPhysics' default spectral radius of infinite time step.
pub const DEFAULT_RHO_INF: f64 = 0.5;

impl TimeIntegration {
    pub fn coefficients(&self) -> Alpha {
        match *self {
            TimeIntegration::BackwardEuler => Alpha { alpha_m: 1.0, alpha_f: 1.0, gamma: 1.0 },
            TimeIntegration::GeneralizedAlpha { rho_inf } => Alpha::from_spectral_radius(rho_inf),
        }
    }

    /// The scheme's name as in case files and on the command line.
    pub fn name(&self) -> &'static str {
        match self {
            TimeIntegration::BackwardEuler => "backward-euler",
            TimeIntegration::GeneralizedAlpha { .. } => "generalized-alpha",
        }
    }
}

/// Generalized-alpha parameters (backward Euler: all 1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Alpha {
    pub alpha_m: f64,
    pub alpha_f: f64,
    pub gamma: f64,
}

impl Alpha {
    pub fn from_spectral_radius(rho_inf: f64) -> Alpha {
        let alpha_m = (3.0 - rho_inf) / (2.0 * (1.0 + rho_inf));
        let alpha_f = 1.0 / (1.0 + rho_inf);
        Alpha { alpha_m, alpha_f, gamma: 0.5 + alpha_m - alpha_f }
    }

    /// c: the time derivative at n+am is c (y - u*) for the stage velocity y = u_{n+af}.
    pub fn stage_inv_dt(&self, dt_s: f64) -> f64 {
        self.alpha_m / (self.gamma * self.alpha_f * dt_s)
    }

    /// u* = u_n - (gamma - am) af dt / am a_n.
    pub fn stage_base(&self, u_n: f64, a_n: f64, dt_s: f64) -> f64 {
        u_n - (self.gamma - self.alpha_m) * self.alpha_f * dt_s / self.alpha_m * a_n
    }

    /// u_{n+af} = (1 - af) u_n + af u_{n+1}: the stage value of a prescribed velocity.
    pub fn stage(&self, u_n: f64, u_next: f64) -> f64 {
        (1.0 - self.alpha_f) * u_n + self.alpha_f * u_next
    }

    /// (u_{n+1}, a_{n+1}) from the stage velocity y and (u_n, a_n).
    pub fn finish(&self, u_n: f64, a_n: f64, y: f64, dt_s: f64) -> (f64, f64) {
        let u_next = (y - (1.0 - self.alpha_f) * u_n) / self.alpha_f;
        let a_next = (u_next - u_n - dt_s * (1.0 - self.gamma) * a_n) / (self.gamma * dt_s);
        (u_next, a_next)
    }

    /// (p_{n+1}, its rate) from the stage pressure p_s and (p_n, its rate), p_n being
    /// the previous stage pressure extrapolated the same way (see the module notes).
    pub fn finish_pressure(&self, p_n: f64, rate_n: f64, p_stage: f64, dt_s: f64) -> (f64, f64) {
        let lag = (1.0 - self.alpha_f) * dt_s;
        let rate = (p_stage - (p_n - lag * rate_n)) / dt_s;
        (p_stage + lag * rate, rate)
    }
}

/// [`Alpha::stage_base`] on the velocity components of a solver vector (4 values a node;
/// the pressure slot is copied, the assembly does not read it).
pub fn stage_base(alpha: &Alpha, x_n: &[f64], a_n: &[f64], dt_s: f64) -> Vec<f64> {
    x_n.iter().zip(a_n).enumerate().map(|(k, (&u, &a))| if k % B == 3 { u } else { alpha.stage_base(u, a, dt_s) }).collect()
}

/// [`Alpha::finish`] on a solver vector: `x` holds the stage solution (y, p_s) on entry
/// and (u_{n+1}, p_{n+1}) on return; `a` goes from a_n to a_{n+1} (and from the
/// pressure's rate at n to that at n+1 in its slot).
pub fn finish(alpha: &Alpha, x_n: &[f64], x: &mut [f64], a: &mut [f64], dt_s: f64) {
    for (k, ((xk, ak), &un)) in x.iter_mut().zip(a.iter_mut()).zip(x_n).enumerate() {
        (*xk, *ak) = if k % B == 3 { alpha.finish_pressure(un, *ak, *xk, dt_s) } else { alpha.finish(un, *ak, *xk, dt_s) };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One step of u' = -k u + g(t) with the scheme: the stage equation
    /// c (y - u*) = -k y + g(t_n + af dt) solved exactly.
    fn step(alpha: &Alpha, k: f64, g: &dyn Fn(f64) -> f64, t: f64, dt: f64, u: f64, a: f64) -> (f64, f64) {
        let c = alpha.stage_inv_dt(dt);
        let y = (c * alpha.stage_base(u, a, dt) + g(t + alpha.alpha_f * dt)) / (c + k);
        alpha.finish(u, a, y, dt)
    }

    /// Error at t = 1 of u' = -u + cos t, u(0) = 0 (exact: (cos t + sin t - e^-t) / 2),
    /// started with the consistent a_0 = g(0) - k u_0.
    fn error_at_one(scheme: TimeIntegration, steps: usize) -> f64 {
        let alpha = scheme.coefficients();
        let dt = 1.0 / steps as f64;
        let (mut u, mut a) = (0.0, 1.0);
        for n in 0..steps {
            (u, a) = step(&alpha, 1.0, &|t: f64| t.cos(), n as f64 * dt, dt, u, a);
        }
        let exact = (1f64.cos() + 1f64.sin() - (-1f64).exp()) / 2.0;
        (u - exact).abs()
    }

    #[test]
    fn generalized_alpha_is_second_order_and_backward_euler_first() {
        for (scheme, order) in [(TimeIntegration::BackwardEuler, 1.0), (TimeIntegration::GeneralizedAlpha { rho_inf: 0.5 }, 2.0)] {
            let errors: Vec<f64> = [20, 40, 80].map(|n| error_at_one(scheme, n)).to_vec();
            for w in errors.windows(2) {
                let ratio = w[0] / w[1];
                assert!((ratio.log2() - order).abs() < 0.1, "{scheme:?}: errors {errors:?}, ratio {ratio}");
            }
        }
        for rho_inf in [0.0, 0.2, 1.0] {
            let ratio = error_at_one(TimeIntegration::GeneralizedAlpha { rho_inf }, 40) / error_at_one(TimeIntegration::GeneralizedAlpha { rho_inf }, 80);
            assert!((ratio.log2() - 2.0).abs() < 0.1, "rho_inf {rho_inf}: ratio {ratio}");
        }
    }

    /// Spectral radius of the step's amplification matrix on (u, a) for u' = -k u.
    fn spectral_radius(alpha: &Alpha, k_dt: f64) -> f64 {
        let columns = [(1.0, 0.0), (0.0, 1.0)].map(|(u, a)| step(alpha, k_dt, &|_| 0.0, 0.0, 1.0, u, a));
        let (m11, m21, m12, m22) = (columns[0].0, columns[0].1, columns[1].0, columns[1].1);
        let (tr, det) = (m11 + m22, m11 * m22 - m12 * m21);
        let disc = tr * tr / 4.0 - det;
        if disc >= 0.0 {
            (tr / 2.0).abs() + disc.sqrt()
        } else {
            det.sqrt()
        }
    }

    #[test]
    fn spectral_radius_at_infinite_step_is_rho_inf() {
        // rho_inf = 1 keeps the highest frequencies, 0 annihilates them, 0.5 (the
        // default) halves them every step; a resolved mode is stable and barely damped.
        for rho_inf in [0.0, 0.5, 1.0] {
            let alpha = Alpha::from_spectral_radius(rho_inf);
            assert!((alpha.gamma - (0.5 + alpha.alpha_m - alpha.alpha_f)).abs() < 1e-15);
            let r = spectral_radius(&alpha, 1e9);
            assert!((r - rho_inf).abs() < 1e-4, "rho_inf {rho_inf}: spectral radius {r}");
            let resolved = spectral_radius(&alpha, 1e-2);
            // (rho_inf = 1 also keeps the spurious root at modulus 1: stable, not damped.)
            assert!(resolved <= 1.0 + 1e-12 && resolved > 0.98, "rho_inf {rho_inf}: {resolved}");
        }
        assert!(spectral_radius(&TimeIntegration::BackwardEuler.coefficients(), 1e9) < 1e-6);
    }

    #[test]
    fn reported_pressure_is_second_order_at_the_step_time() {
        // Stage pressures sampled exactly at t_n + af dt from p(t) = sin 3t: the reported
        // p at t = 1 is second order (error 4x smaller a halving), not lagging by (1 - af) dt.
        let alpha = Alpha::from_spectral_radius(0.5);
        let error = |steps: usize| {
            let dt = 1.0 / steps as f64;
            let (mut p, mut rate) = (0.0, 3.0);
            for n in 0..steps {
                (p, rate) = alpha.finish_pressure(p, rate, (3.0 * (n as f64 + alpha.alpha_f) * dt).sin(), dt);
            }
            (p - 3f64.sin()).abs()
        };
        let ratio = error(40) / error(80);
        assert!((ratio.log2() - 2.0).abs() < 0.3, "ratio {ratio}");
    }

    #[test]
    fn backward_euler_coefficients_reduce_exactly() {
        let be = TimeIntegration::BackwardEuler.coefficients();
        let (u, a, y, dt) = (0.37, -12.5, 0.41, 1e-3);
        assert_eq!(be.stage_inv_dt(dt), 1.0 / dt);
        assert_eq!(be.stage_base(u, a, dt), u);
        assert_eq!(be.stage(u, y), y);
        assert_eq!(be.finish(u, a, y, dt).0, y);
        assert_eq!(be.finish_pressure(u, a, y, dt).0, y);
    }
}
