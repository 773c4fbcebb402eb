//! The free coast-down of the shaft ([`super::SpinDown`]): the friction ODE integrated by
//! classical Runge–Kutta (RK4) on a fine fixed grid.
//!
//! State `(θ, ω)`, `θ' = ω`, `ω' = −(c₀ + c₁ω + c₂ω²) − Σ a_h cos(hθ + φ_h)` while `ω > 0`,
//! plus `(ω_v − ω)/τ` while a motor drives it at constant voltage ([`super::Drive`]). The
//! drive's `ω_v` is taken at the start of each grid step: a voltage step acts from the first
//! grid point at or after its time, and RK4 never integrates across its jump.
//! The grid step is `min(1/rate, 0.005/(ω_max·h_max))`, `h_max` the highest drag order (1
//! without drag) and `ω_max` the larger of `ω₀` and the drive's no-load speeds: a step turns
//! the fastest drag term by at most 0.005 rad. RK4's local error is then
//! ~`δ·(0.005)⁵` for a drag response of amplitude δ (≤ 1e-4 rad), about 1e-15 rad per step, and
//! the global error over 10⁶ steps stays below 1e-9 rad (2e-4″); the tests check the result
//! against closed forms and against a quarter-step integration. A sample between grid points
//! takes one partial RK4 step from the grid point before it (after it, with a negative step,
//! when time jitter moves an instant backwards).

use super::sensor::{FastSeries, Powers, Term};

/// One integration state. The angle is `theta + theta_lo` and the speed `omega + omega_lo`:
/// the step's increments are added
/// with compensated (two-sum) summation, since the plain sum's rounding (half an ulp of an
/// angle of hundreds of radians, 3e-14 rad) is correlated from step to step while the
/// increments change slowly, and would grow linearly over 10⁵–10⁷ steps.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Point {
    t: f64,
    theta: f64,
    theta_lo: f64,
    omega: f64,
    omega_lo: f64,
}

/// `(s, e)` with `s + e = a + b` exactly (Knuth's two-sum).
fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    (s, (a - (s - bb)) + (b - bb))
}

/// A motor at constant voltage: `τ` (s) and the steps `(from, ω_v)` (s, rad/s) in time order.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ConstantVoltage {
    pub time_constant: f64,
    pub steps: Vec<(f64, f64)>,
}

impl ConstantVoltage {
    /// `ω_v` at `t`, `None` before the first step.
    fn no_load_speed(&self, t: f64) -> Option<f64> {
        self.steps
            .iter()
            .take_while(|(from, _)| *from <= t)
            .last()
            .map(|&(_, w)| w)
    }
}

/// The coasting (or driven) shaft: the ODE's parameters and the integration's current grid
/// point.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Coast {
    /// `c₀, c₁, c₂`.
    friction: [f64; 3],
    drive: Option<ConstantVoltage>,
    drag: FastSeries,
    powers: Powers,
    step: f64,
    duration: f64,
    /// The last grid point reached while moving, and its index `k` (at `t = k·step`).
    at: Point,
    k: u64,
    /// Where and when the shaft came to rest, once it has.
    stop: Option<Point>,
}

impl Coast {
    /// A coast from `θ = 0` at speed `omega0` (rad/s) for `duration` seconds, sampled at
    /// `rate_hz`.
    pub(crate) fn new(
        omega0: f64,
        duration: f64,
        friction: [f64; 3],
        drag: &[Term],
        drive: Option<ConstantVoltage>,
        rate_hz: f64,
    ) -> Self {
        let h_max = drag.iter().map(|t| t.order).fold(1.0, f64::max);
        let fastest = drive
            .iter()
            .flat_map(|d| d.steps.iter().map(|s| s.1))
            .fold(omega0, f64::max);
        Coast {
            friction,
            drive,
            drag: FastSeries::new(drag),
            powers: Powers::default(),
            step: (1.0 / rate_hz).min(0.005 / (fastest * h_max)),
            duration,
            at: Point {
                t: 0.0,
                theta: 0.0,
                theta_lo: 0.0,
                omega: omega0,
                omega_lo: 0.0,
            },
            k: 0,
            stop: None,
        }
    }

    /// Length of the coast, seconds.
    pub(crate) fn duration(&self) -> f64 {
        self.duration
    }

    /// `dω/dt` at `(θ, ω)` under a drive of no-load speed `driven` (`None`: coasting).
    fn accel(&mut self, theta: f64, omega: f64, driven: Option<f64>) -> f64 {
        let [c0, c1, c2] = self.friction;
        let drive = match (driven, &self.drive) {
            (Some(wv), Some(d)) => (wv - omega) / d.time_constant,
            _ => 0.0,
        };
        drive - (c0 + c1 * omega + c2 * omega * omega) - self.drag.eval(theta, &mut self.powers)
    }

    /// One RK4 step of size `dt` (may be negative) from `p`, the drive's speed taken at `p.t`.
    fn rk4(&mut self, p: Point, dt: f64) -> Point {
        let driven = self.drive.as_ref().and_then(|d| d.no_load_speed(p.t));
        let k1 = (p.omega, self.accel(p.theta, p.omega, driven));
        let k2 = {
            let (th, om) = (p.theta + 0.5 * dt * k1.0, p.omega + 0.5 * dt * k1.1);
            (om, self.accel(th, om, driven))
        };
        let k3 = {
            let (th, om) = (p.theta + 0.5 * dt * k2.0, p.omega + 0.5 * dt * k2.1);
            (om, self.accel(th, om, driven))
        };
        let k4 = {
            let (th, om) = (p.theta + dt * k3.0, p.omega + dt * k3.1);
            (om, self.accel(th, om, driven))
        };
        let (theta, lo) = two_sum(
            p.theta,
            dt / 6.0 * (k1.0 + 2.0 * k2.0 + 2.0 * k3.0 + k4.0) + p.theta_lo,
        );
        let (omega, omega_lo) = two_sum(
            p.omega,
            dt / 6.0 * (k1.1 + 2.0 * k2.1 + 2.0 * k3.1 + k4.1) + p.omega_lo,
        );
        Point {
            t: p.t + dt,
            theta,
            theta_lo: lo,
            omega,
            omega_lo,
        }
    }

    /// One grid step from the current point; detects the stop. The stop instant is where the
    /// step's speed, interpolated linearly, crosses 0, and the rest angle is reached by a partial
    /// step to it (speed then set to 0).
    ///
    /// Grid times are computed as `k·step`, and each step integrates over exactly the difference
    /// of two such times: summing `t += step` would let the clock drift from the integrated time
    /// by a rounding per step, an error in θ of ω·1e-15 s per step that adds up over 10⁶ steps.
    fn advance(&mut self) {
        let t_next = (self.k + 1) as f64 * self.step;
        let mut next = self.rk4(self.at, t_next - self.at.t);
        next.t = t_next;
        if next.omega > 0.0 {
            self.at = next;
            self.k += 1;
            return;
        }
        let frac = self.at.omega / (self.at.omega - next.omega);
        let rest = self.rk4(self.at, frac * (t_next - self.at.t));
        self.stop = Some(Point { omega: 0.0, ..rest });
    }

    /// The shaft's true angle at time `t` (radians, accumulated; clamped to `[0, duration]`).
    pub(crate) fn theta(&mut self, t: f64) -> f64 {
        let t = t.clamp(0.0, self.duration);
        while self.stop.is_none() && t >= (self.k + 1) as f64 * self.step {
            self.advance();
        }
        match self.stop {
            Some(stop) if t >= stop.t => return stop.theta + stop.theta_lo,
            _ => {}
        }
        let p = if t == self.at.t {
            self.at
        } else {
            self.rk4(self.at, t - self.at.t)
        };
        p.theta + p.theta_lo
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::angle::ARCSEC_PER_RAD;

    #[test]
    fn viscous_coast_matches_the_closed_form() {
        // θ' = ω, ω' = −c₁ω: θ(t) = ω₀/c₁·(1 − e^{−c₁t}).
        let (w0, c1) = (62.8, 0.03);
        let mut c = Coast::new(w0, 30.0, [0.0, c1, 0.0], &[], None, 1000.0);
        for k in 0..300 {
            let t = 0.1 * k as f64 + 0.0003;
            let exact = w0 / c1 * (1.0 - (-c1 * t).exp());
            // RK4's error for ω' = −c₁ω is (c₁·step)⁵/120 per step, nil here; what remains is
            // the rounding of ~2000 rad, 1e-13 rad ≈ 2e-8″ (compensated summation).
            assert!(((c.theta(t) - exact) * ARCSEC_PER_RAD).abs() < 1e-6, "{t}");
        }
    }

    #[test]
    fn coulomb_coast_stops_where_the_speed_reaches_zero() {
        // ω' = −c₀: stops at t = ω₀/c₀ after θ = ω₀²/(2c₀), then rests.
        let (w0, c0) = (10.0, 2.0);
        let mut c = Coast::new(w0, 8.0, [c0, 0.0, 0.0], &[], None, 100.0);
        let exact = |t: f64| w0 * t - 0.5 * c0 * t * t;
        // RK4 is exact for this quadratic; what remains is rounding (≪ 1e-12 rad).
        assert!((c.theta(3.0) - exact(3.0)).abs() < 1e-12);
        // The linear speed profile makes the interpolated stop instant exact.
        assert!((c.theta(6.0) - 25.0).abs() < 1e-12);
        assert!((c.theta(8.0) - 25.0).abs() < 1e-12);
    }

    #[test]
    fn a_drive_at_constant_voltage_settles_as_the_closed_form() {
        // ω' = (ω_v − ω)/τ − c₁ω from ω₀: ω → ω∞ = ω_v/(1 + c₁τ) with rate k = 1/τ + c₁,
        // θ(t) = ω∞·t + (ω₀ − ω∞)(1 − e^{−kt})/k, the voltage on from t = 0.
        let (w0, wv, tau, c1) = (20.0, 31.4, 0.8, 0.05);
        let drive = ConstantVoltage {
            time_constant: tau,
            steps: vec![(0.0, wv)],
        };
        let mut c = Coast::new(w0, 10.0, [0.0, c1, 0.0], &[], Some(drive), 2000.0);
        let (k, w_inf) = (1.0 / tau + c1, wv / (1.0 + c1 * tau));
        for i in 0..100 {
            let t = 0.1 * i as f64 + 0.00021;
            let exact = w_inf * t + (w0 - w_inf) * (1.0 - (-k * t).exp()) / k;
            // RK4's error (k·step)⁵/120 per step is nil; rounding of ~300 rad remains.
            assert!(((c.theta(t) - exact) * ARCSEC_PER_RAD).abs() < 1e-5, "{t}");
        }
    }

    #[test]
    fn drag_harmonics_integrate_to_well_below_a_milliarcsecond() {
        // Compare with the same coast integrated at a quarter of the step: RK4's global error
        // scales as step⁴, so the difference bounds the coarse integration's error.
        let drag = [Term {
            order: 8.0,
            amplitude: 0.5,
            phase: 0.3,
        }];
        let f = [0.05, 0.02, 1e-4];
        let mut coarse = Coast::new(62.8, 5.0, f, &drag, None, 1000.0);
        let mut fine = coarse.clone();
        fine.step /= 4.0;
        for k in 0..50 {
            let t = 0.1 * k as f64 + 0.00037;
            let d = (coarse.theta(t) - fine.theta(t)) * ARCSEC_PER_RAD;
            assert!(d.abs() < 1e-4, "{t}: {d}″");
        }
        // Jitter: an instant slightly before the last grid point gives the same angle.
        let a = coarse.theta(4.0);
        let _ = coarse.theta(4.001);
        assert!(((coarse.theta(4.0) - a) * ARCSEC_PER_RAD).abs() < 1e-6);
    }
}
