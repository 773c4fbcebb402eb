//! Fourier series of periodic errors and their harmonics.

use crate::angle::{ARCSEC_PER_RAD, DEG_PER_RAD};

/// One harmonic `amplitude·cos(order·θ + phase)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Harmonic {
    /// Cycles per revolution, ≥ 1.
    pub order: usize,
    /// Amplitude, radians.
    pub amplitude: f64,
    /// Phase, radians.
    pub phase: f64,
}

impl Harmonic {
    /// A harmonic given at the edges' units: amplitude in arcsec, phase in degrees.
    pub fn from_arcsec_deg(order: usize, amplitude_arcsec: f64, phase_deg: f64) -> Self {
        Harmonic {
            order,
            amplitude: amplitude_arcsec / ARCSEC_PER_RAD,
            phase: phase_deg / DEG_PER_RAD,
        }
    }
    /// Its value at `theta` (radians).
    pub fn eval(&self, theta: f64) -> f64 {
        self.amplitude * (self.order as f64 * theta + self.phase).cos()
    }
    /// The `(a, b)` coefficients of `a·cos hθ + b·sin hθ`.
    pub fn coefficients(&self) -> (f64, f64) {
        (
            self.amplitude * self.phase.cos(),
            -self.amplitude * self.phase.sin(),
        )
    }
    /// From `(a, b)` coefficients.
    pub fn from_coefficients(order: usize, a: f64, b: f64) -> Self {
        Harmonic {
            order,
            amplitude: a.hypot(b),
            phase: (-b).atan2(a),
        }
    }
    /// The report's view of it: amplitude in arcsec, phase in degrees in `(−180, 180]`.
    pub fn to_report(&self) -> HarmonicReport {
        HarmonicReport {
            order: self.order,
            amplitude_arcsec: self.amplitude * ARCSEC_PER_RAD,
            phase_deg: self.phase * DEG_PER_RAD,
        }
    }
}

/// A harmonic as `report.json` writes it.
#[derive(
    Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema,
)]
pub struct HarmonicReport {
    /// Cycles per revolution.
    pub order: usize,
    /// Amplitude, arcseconds.
    pub amplitude_arcsec: f64,
    /// Phase, degrees.
    pub phase_deg: f64,
}

/// A zero-mean Fourier series `e(θ) = Σ_{h=1..H} a_h cos hθ + b_h sin hθ` (radians).
///
/// # Convention
/// A harmonic of order `h` (cycles per revolution) is the component `A·cos(h·θ + φ)` of a map,
/// θ the sensor's own reading. In coefficient form `A·cos(hθ + φ) = a·cos hθ + b·sin hθ` with
/// `a = A cos φ`, `b = −A sin φ`. Amplitudes are radians inside, arcseconds at the edges; phases
/// are radians inside, degrees at the edges. Order 0 (a constant) is never part of a map: errors
/// are zero-mean over the circle.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FourierSeries {
    /// `a_h` at index `h − 1`.
    pub cos: Vec<f64>,
    /// `b_h` at index `h − 1`.
    pub sin: Vec<f64>,
}

impl FourierSeries {
    /// All-zero series up to order `max_order`.
    pub fn zeros(max_order: usize) -> Self {
        FourierSeries {
            cos: vec![0.0; max_order],
            sin: vec![0.0; max_order],
        }
    }
    /// The series holding these harmonics (orders above `max_order` are dropped).
    pub fn from_harmonics(harmonics: &[Harmonic], max_order: usize) -> Self {
        let mut s = Self::zeros(max_order);
        for h in harmonics
            .iter()
            .filter(|h| (1..=max_order).contains(&h.order))
        {
            let (a, b) = h.coefficients();
            s.cos[h.order - 1] += a;
            s.sin[h.order - 1] += b;
        }
        s
    }
    /// The series with only `orders` kept and every other coefficient zero; orders of 0 or above
    /// [`max_order`](Self::max_order) hold nothing and are ignored.
    pub fn only(&self, orders: &[usize]) -> FourierSeries {
        let mut s = Self::zeros(self.max_order());
        for &h in orders
            .iter()
            .filter(|&&h| (1..=self.max_order()).contains(&h))
        {
            s.cos[h - 1] = self.cos[h - 1];
            s.sin[h - 1] = self.sin[h - 1];
        }
        s
    }
    /// The `n` orders of largest amplitude, largest first (equal amplitudes: the lower order
    /// first), at most [`max_order`](Self::max_order) of them.
    pub fn largest_orders(&self, n: usize) -> Vec<usize> {
        let mut orders: Vec<usize> = (1..=self.max_order()).collect();
        let amplitude = |h: usize| self.cos[h - 1].hypot(self.sin[h - 1]);
        // A stable sort keeps equal amplitudes in order of increasing order.
        orders.sort_by(|&a, &b| amplitude(b).total_cmp(&amplitude(a)));
        orders.truncate(n);
        orders
    }
    /// Highest order held.
    pub fn max_order(&self) -> usize {
        self.cos.len()
    }
    /// The harmonics, in order.
    pub fn harmonics(&self) -> Vec<Harmonic> {
        (0..self.max_order())
            .map(|i| Harmonic::from_coefficients(i + 1, self.cos[i], self.sin[i]))
            .collect()
    }
    /// The value at `theta`, by direct summation (O(H); use an [`crate::ErrorMap`] for many
    /// points).
    pub fn eval(&self, theta: f64) -> f64 {
        // Chebyshev-style recurrence for cos hθ and sin hθ: one sin/cos per call.
        let (s1, c1) = theta.sin_cos();
        let (mut s, mut c) = (0.0, 1.0);
        let mut sum = 0.0;
        for (a, b) in self.cos.iter().zip(&self.sin) {
            (s, c) = (s * c1 + c * s1, c * c1 - s * s1);
            sum += a * c + b * s;
        }
        sum
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn coefficients_follow_the_phase_convention() {
        let h = Harmonic::from_arcsec_deg(3, 10.0, 30.0);
        let s = FourierSeries::from_harmonics(&[h], 5);
        for k in 0..50 {
            let th = k as f64 * 0.13;
            assert!((s.eval(th) - h.eval(th)).abs() < 1e-15);
        }
        let back = s.harmonics()[2].to_report();
        assert!((back.amplitude_arcsec - 10.0).abs() < 1e-9);
        assert!((back.phase_deg - 30.0).abs() < 1e-9);
    }

    #[test]
    fn selection_keeps_the_named_or_largest_orders() {
        let s = FourierSeries::from_harmonics(
            &[
                Harmonic::from_arcsec_deg(1, 2.0, 0.0),
                Harmonic::from_arcsec_deg(3, 10.0, 30.0),
                Harmonic::from_arcsec_deg(5, 2.0, 90.0),
            ],
            6,
        );
        assert_eq!(s.largest_orders(2), vec![3, 1]);
        assert_eq!(s.largest_orders(10), vec![3, 1, 5, 2, 4, 6]);
        let kept = s.only(&[3, 5, 0, 9]);
        let three = Harmonic::from_arcsec_deg(3, 10.0, 30.0);
        let five = Harmonic::from_arcsec_deg(5, 2.0, 90.0);
        for k in 0..20 {
            let th = k as f64 * 0.31;
            assert!((kept.eval(th) - three.eval(th) - five.eval(th)).abs() < 1e-15);
        }
    }
}
