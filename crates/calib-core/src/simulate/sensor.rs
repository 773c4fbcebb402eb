//! A simulated sensor's systematic error as a function of the true angle it measures, and its
//! inversion into a function of its own reading (the form every calib map takes).

use crate::angle::{ARCSEC_PER_RAD, wrap_2pi};
use crate::error_map::ErrorMap;
use std::f64::consts::TAU;

/// One term `amplitude·cos(order·θ + phase)`, radians, with the order kept as `f64` for the hot
/// loop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Term {
    pub(crate) order: f64,
    pub(crate) amplitude: f64,
    pub(crate) phase: f64,
}

/// A sum of terms evaluated by powers of `z = e^{iθ}`, for the generator's hot loop.
///
/// One `sin_cos` per call instead of one `cos` per term: `z^{2^k}` by repeated squaring, then
/// `z^h` as the product of the powers of `h`'s set bits, and `cos(hθ + φ) = Re(z^h·e^{iφ})`.
/// Each squaring at most doubles the relative rounding error, so for orders below 2^k the phase
/// error stays below ~2^k·1e-16 rad: 1e-13 rad (2e-8″ on a 200″ term) at order 1000, far below
/// any resolution; the test below checks it against direct `cos` sums.
#[derive(Debug, Clone, PartialEq, Default)]
pub(crate) struct FastSeries {
    /// Number of binary powers `z, z², z⁴, …` the orders need.
    powers: usize,
    /// `(order, A·cos φ, A·sin φ)` per term.
    terms: Vec<(u32, f64, f64)>,
}

impl FastSeries {
    pub(crate) fn new(terms: &[Term]) -> Self {
        // Orders come from the scenario's `u32` orders, so the conversion is exact.
        let terms: Vec<_> = terms
            .iter()
            .map(|t| {
                let (s, c) = t.phase.sin_cos();
                (t.order as u32, t.amplitude * c, t.amplitude * s)
            })
            .collect();
        let max = terms.iter().map(|t| t.0).max().unwrap_or(0);
        FastSeries {
            powers: (u32::BITS - max.leading_zeros()) as usize,
            terms,
        }
    }

    /// How many binary powers of `z` [`Self::eval_powers`] reads.
    pub(crate) fn powers_needed(&self) -> usize {
        self.powers
    }

    /// `Σ A·cos(h·θ + φ)` from the binary powers of `z = e^{iθ}` (at least
    /// [`Self::powers_needed`] of them).
    #[inline]
    pub(crate) fn eval_powers(&self, pw: &Powers) -> f64 {
        let mut sum = 0.0;
        for &(order, a, b) in &self.terms {
            let (mut x, mut y) = (1.0, 0.0);
            let mut rest = order;
            while rest != 0 {
                let (p, q) = pw.0[rest.trailing_zeros() as usize];
                (x, y) = (x * p - y * q, x * q + y * p);
                rest &= rest - 1;
            }
            sum += a * x - b * y;
        }
        sum
    }

    /// `Σ A·cos(h·θ + φ)` at `theta` (any revolution), using `buf` for the powers.
    pub(crate) fn eval(&self, theta: f64, buf: &mut Powers) -> f64 {
        if self.terms.is_empty() {
            return 0.0;
        }
        buf.set(theta.sin_cos(), self.powers);
        self.eval_powers(buf)
    }
}

/// The binary powers `z, z², z⁴, …` of a unit complex number `z = e^{iθ}`, as `(re, im)`:
/// computed once per sample and rotor, shared by every channel on that rotor.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Powers(Vec<(f64, f64)>);

impl Powers {
    /// Sets the first `n` powers of `z = (sin θ, cos θ)` given as `(s, c)`.
    #[inline]
    pub(crate) fn set(&mut self, (s, c): (f64, f64), n: usize) {
        self.0.resize(n.max(1), (1.0, 0.0));
        self.0[0] = (c, s);
        for k in 1..n {
            let (x, y) = self.0[k - 1];
            self.0[k] = (x * x - y * y, 2.0 * x * y);
        }
    }
}

/// `e(θ) = offset + Σ amplitude·cos(order·θ + phase)`, θ the true angle the sensor measures.
///
/// A head reading a shared scale at nominal angle `α` with angle error `δ` sees the scale at
/// `θ + α + δ` and reports `θ + α + δ + e_s(θ + α + δ) − α`: its error is `δ + e_s(θ + α + δ)`,
/// i.e. an offset `δ` and the scale's terms with phases advanced by `h·(α + δ)`.
#[derive(Debug, Clone, PartialEq, Default)]
pub(crate) struct ErrorModel {
    pub(crate) offset: f64,
    pub(crate) terms: Vec<Term>,
}

impl ErrorModel {
    /// The error at true angle `theta` (any revolution).
    #[inline]
    pub(crate) fn eval(&self, theta: f64) -> f64 {
        // Reduce first: `order·θ` of an accumulated angle would lose the phase's low bits.
        let th = wrap_2pi(theta);
        self.offset
            + self
                .terms
                .iter()
                .map(|t| t.amplitude * (t.order * th + t.phase).cos())
                .sum::<f64>()
    }

    /// The error and its derivative `de/dθ` at `theta`.
    fn eval_with_slope(&self, theta: f64) -> (f64, f64) {
        let th = wrap_2pi(theta);
        let (mut e, mut de) = (self.offset, 0.0);
        for t in &self.terms {
            let (s, c) = (t.order * th + t.phase).sin_cos();
            e += t.amplitude * c;
            de -= t.amplitude * t.order * s;
        }
        (e, de)
    }

    /// `Σ |order·amplitude|`, an upper bound of `|e′(θ)|`. Below 1, `θ ↦ θ + e(θ)` is strictly
    /// increasing, so every reading belongs to exactly one true angle.
    pub(crate) fn slope_bound(&self) -> f64 {
        self.terms
            .iter()
            .map(|t| (t.order * t.amplitude).abs())
            .sum()
    }

    /// The error at reading `r`: `r − θ` where `θ + e(θ) = r`.
    ///
    /// Safeguarded Newton: the root lies within `max |e|` of `r`, so that bracket is kept and a
    /// step leaving it is replaced by bisection. Requires [`Self::slope_bound`] `< 1` (checked by
    /// scenario validation), which makes the function strictly increasing.
    pub(crate) fn error_at_reading(&self, r: f64) -> f64 {
        let reach = self.offset.abs() + self.terms.iter().map(|t| t.amplitude.abs()).sum::<f64>();
        let g = |th: f64| {
            let (e, de) = self.eval_with_slope(th);
            (th + e - r, 1.0 + de)
        };
        let (mut lo, mut hi) = (r - reach - 1e-12, r + reach + 1e-12);
        let mut th = r - self.eval(r);
        for _ in 0..200 {
            let (val, slope) = g(th);
            if val == 0.0 {
                break;
            }
            if val < 0.0 {
                lo = th;
            } else {
                hi = th;
            }
            let newton = th - val / slope;
            let next = if newton > lo && newton < hi {
                newton
            } else {
                0.5 * (lo + hi)
            };
            // Converged when the step is at the rounding level of the angle (≪ 1e-6″).
            let done = (next - th).abs() <= 4.0 * f64::EPSILON * (1.0 + th.abs());
            th = next;
            if done {
                break;
            }
        }
        r - th
    }
}

/// The truth of one simulated channel: its error as a function of the true angle and of its own
/// reading.
///
/// Readings follow `reading = θ + e(θ)` exactly (before noise and quantization), θ the true angle
/// the channel measures (the driven shaft's for mount `b` and for heads, rotor A's for mount `a`).
#[derive(Debug, Clone, PartialEq)]
pub struct SensorTruth {
    pub(crate) name: String,
    pub(crate) model: ErrorModel,
    pub(crate) head_angle_error: Option<f64>,
}

impl SensorTruth {
    /// The channel's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The error `e(θ)` at true angle `theta` (radians in, radians out), including a head's
    /// constant offset.
    pub fn error_at_true(&self, theta: f64) -> f64 {
        self.model.eval(theta)
    }

    /// The error at the channel's own reading `r`: `r − θ` where `θ + e(θ) = r` (radians). Exact to
    /// rounding; this is what a calibration should recover.
    pub fn error_at_reading(&self, r: f64) -> f64 {
        self.model.error_at_reading(r)
    }

    /// The error map over one revolution of the channel's own reading on `points` grid points,
    /// mean removed (see [`ErrorMap`]). `points` is at least 1 (0 is treated as 1).
    pub fn map(&self, points: usize) -> ErrorMap {
        let n = points.max(1);
        ErrorMap::new(
            (0..n)
                .map(|i| self.error_at_reading(TAU * i as f64 / n as f64))
                .collect(),
        )
    }

    /// For a head on a shared scale: its actual angle minus its nominal angle `head_deg`
    /// (radians), which a multi-head method estimates; `None` for a sensor with its own error
    /// model.
    pub fn head_angle_error(&self) -> Option<f64> {
        self.head_angle_error
    }

    /// Largest `|e′(θ)|` bound, for diagnostics (`Σ order·|amplitude|`, dimensionless).
    pub fn slope_bound(&self) -> f64 {
        self.model.slope_bound()
    }

    /// Peak-to-peak of the error over the true angle, arcseconds, on a grid fine enough for its
    /// highest order (16 points per shortest period).
    pub fn peak_to_peak_arcsec(&self) -> f64 {
        let max_order = self.model.terms.iter().map(|t| t.order).fold(1.0, f64::max);
        let n = (16.0 * max_order) as usize;
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for i in 0..n {
            let e = self.model.eval(TAU * i as f64 / n as f64);
            lo = lo.min(e);
            hi = hi.max(e);
        }
        (hi - lo) * ARCSEC_PER_RAD
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::angle::ARCSEC_PER_RAD;

    fn model(terms: &[(f64, f64, f64)], offset_arcsec: f64) -> ErrorModel {
        ErrorModel {
            offset: offset_arcsec / ARCSEC_PER_RAD,
            terms: terms
                .iter()
                .map(|&(order, a, p)| Term {
                    order,
                    amplitude: a / ARCSEC_PER_RAD,
                    phase: p.to_radians(),
                })
                .collect(),
        }
    }

    #[test]
    fn fast_series_matches_direct_cos_sums() {
        let m = model(
            &[
                (84.0, 668.95, 10.0),
                (1000.0, 200.0, -170.0),
                (810.0, 11.71, 33.0),
                (1.0, 7.52, 100.0),
                (255.0, 5.0, 0.0),
            ],
            0.0,
        );
        let fast = FastSeries::new(&m.terms);
        let mut buf = Powers::default();
        assert_eq!(FastSeries::new(&[]).eval(1.0, &mut buf), 0.0);
        for k in 0..5000 {
            // Accumulated angles up to ~1000 revolutions, as long runs produce.
            let th = -10.0 + k as f64 * 1.2345;
            let d = (fast.eval(th, &mut buf) - m.eval(th)) * ARCSEC_PER_RAD;
            // `eval` reduces θ by k·TAU, and the f64 TAU is 2.4e-16 below 2π: at k = 1000
            // revolutions the order-1000 term's phase differs by 2.4e-10 rad, i.e. 5e-8″ on
            // 200″; both are far below any resolution.
            assert!(d.abs() < 1e-7, "{th}: {d}″");
        }
    }

    #[test]
    fn inversion_is_exact_even_for_large_errors() {
        // The 84-pole-pair sensor of the paper's Table IV (±680″): the largest errors calib meets.
        let m = model(
            &[
                (84.0, 668.95, 10.0),
                (168.0, 104.19, 70.0),
                (252.0, 35.56, -40.0),
                (2.0, 20.03, 5.0),
                (1.0, 7.52, 100.0),
                (336.0, 5.82, 0.0),
            ],
            3.0,
        );
        assert!(m.slope_bound() < 1.0);
        for k in 0..2000 {
            let th = -3.0 + k as f64 * 0.0123;
            let r = th + m.eval(th);
            let back = m.error_at_reading(r);
            // 1e-6″ = 5e-12 rad; the solver stops at rounding level (~1e-15 rad).
            assert!(((back - (r - th)) * ARCSEC_PER_RAD).abs() < 1e-6, "{th}");
        }
    }

    #[test]
    fn small_errors_map_to_first_order_the_same_function_of_the_reading() {
        // e(θ(r)) ≈ e(r) − e′(r)·e(r): for 1″ at order 3 the difference is ≤ 3·(1″)²/206265″ ≈ 1.5e-5″.
        let m = model(&[(3.0, 1.0, 30.0)], 0.0);
        for k in 0..100 {
            let r = k as f64 * 0.063;
            let d = (m.error_at_reading(r) - m.eval(r)) * ARCSEC_PER_RAD;
            assert!(d.abs() < 2e-5, "{d}");
        }
    }

    #[test]
    fn map_is_zero_mean_and_drops_a_head_offset() {
        let t = SensorTruth {
            name: "h".into(),
            model: model(&[(5.0, 2.0, 0.0)], 7.0),
            head_angle_error: Some(7.0 / ARCSEC_PER_RAD),
        };
        let map = t.map(360);
        let mean: f64 = map.values().iter().sum::<f64>() / 360.0;
        assert!(mean.abs() < 1e-18);
        assert!(
            (map.values()[0] * ARCSEC_PER_RAD - (t.error_at_reading(0.0) * ARCSEC_PER_RAD - 7.0))
                .abs()
                < 1e-4
        );
        assert!((t.peak_to_peak_arcsec() - 4.0).abs() < 1e-9);
    }
}
