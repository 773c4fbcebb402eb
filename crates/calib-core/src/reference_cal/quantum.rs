//! The DUT's quantum, found from its readings, and what it leaves in a map that averaging
//! cannot take out.
//!
//! # Why a term of its own
//! A quantized reading errs by `q(θ) = Q(θ) − θ`, a sawtooth of the true angle with the quantum
//! `Δ` as its period: within ±Δ/2, of standard deviation `Δ/√12` over the angle (GUM, JCGM
//! 100:2008 F.2.2.1). It is the same on every pass over the same angle — averaging passes
//! reduces it only where noise *before* the quantizer dithers the reading across codes. With
//! Gaussian noise `σ` in front of it, the mean of the quantized reading departs from the true
//! value by a periodic error whose fundamental has amplitude `(Δ/π)·exp(−2π²σ²/Δ²)` (Widrow &
//! Kollár, *Quantization Noise*, Cambridge 2008, ch. 4–5: the characteristic function of the
//! noise at the quantizer's first harmonic). So the part of the quantization that passes do not
//! average is taken as
//!
//! `u_q = (Δ/√12)·exp(−2π²σ²/Δ²)`
//!
//! at every point, added in quadrature to the point's standard error and not divided by its
//! passes: `Δ/√12` where nothing dithers (a slowly turning sensor without noise: a one-pass
//! firmware dump read at 19.8″ a code), 0.7 % of it at `σ = Δ/2`, and nothing once the noise
//! is larger (then the passes' scatter already holds the quantization, and averages it).
//!
//! `σ` is the noise in front of the quantizer, `σ² = s² − Δ²/12` from the pooled repeatability
//! `s` of points crossed more than once in one direction (which holds the quantization too);
//! a run that crosses no point twice in a direction cannot show its noise, and `σ` is taken as 0.
//!
//! # Finding the quantum
//! Every step between two readings of a quantized sensor is a whole number of codes, so the
//! quantum is the greatest common divisor of the steps ([`QuantumTracker`], Euclid's algorithm
//! on the steps with a remainder below [`RELATIVE_TOLERANCE`] of the divisor counted as none). Unquantized readings (noise in floating point) have no
//! such divisor: the running divisor falls below [`MIN_QUANTUM`] and the readings count as
//! unquantized. Readings printed with a few decimals are quantized by the printing, and that
//! quantum is what is found. Steps that are all the same multiple of the divisor (a noise-free
//! sweep at a constant step) do not show a quantum: one is taken only where the steps differ by
//! at least one of it.

use std::f64::consts::{PI, TAU};

/// A remainder smaller than this fraction of the divisor counts as none (the readings' unit
/// conversions and printed decimals leave ~10⁻⁹ of a code).
pub const RELATIVE_TOLERANCE: f64 = 1e-3;

/// Below this, radians (0.002″), readings count as unquantized: the term `Δ/√12` would be
/// below 0.001″.
pub const MIN_QUANTUM: f64 = 1e-8;

/// The running greatest common divisor of the steps between consecutive readings.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(super) struct QuantumTracker {
    /// The divisor so far, radians (`None` before the first nonzero step).
    divisor: Option<f64>,
    /// The divisor fell below [`MIN_QUANTUM`]: the readings are not quantized.
    unquantized: bool,
    /// The previous reading, radians.
    last: Option<f64>,
    /// The smallest and largest nonzero step, radians.
    steps: (f64, f64),
}

impl QuantumTracker {
    /// Adds a reading, radians; a non-finite one breaks the chain of steps.
    pub(super) fn add(&mut self, reading: f64) {
        if !reading.is_finite() {
            self.last = None;
            return;
        }
        let Some(last) = self.last.replace(reading) else {
            return;
        };
        if self.unquantized {
            return;
        }
        let step = crate::angle::wrap_pi(reading - last).abs();
        if step == 0.0 {
            return;
        }
        self.steps = if self.divisor.is_none() {
            (step, step)
        } else {
            (self.steps.0.min(step), self.steps.1.max(step))
        };
        let g = match self.divisor {
            None => step,
            Some(g) => {
                // The usual case: a whole number of the divisor, without Euclid.
                let k = (step / g).round();
                if k >= 1.0 && (step - k * g).abs() <= RELATIVE_TOLERANCE * g {
                    return;
                }
                gcd(g, step)
            }
        };
        if g < MIN_QUANTUM {
            self.unquantized = true;
            self.divisor = None;
        } else {
            self.divisor = Some(g);
        }
    }

    /// The quantum, radians, if the readings are quantized: the steps differ by at least one
    /// of it, and it is at most a quarter turn.
    pub(super) fn quantum(&self) -> Option<f64> {
        self.divisor.filter(|&g| {
            !self.unquantized && g <= TAU / 4.0 && self.steps.1 - self.steps.0 >= 0.5 * g
        })
    }
}

/// Euclid's algorithm on two positive reals, a remainder within [`RELATIVE_TOLERANCE`] of the
/// divisor (either side) counted as none; 0 when it falls below [`MIN_QUANTUM`].
fn gcd(a: f64, b: f64) -> f64 {
    let (mut a, mut b) = (a.max(b), a.min(b));
    while b >= MIN_QUANTUM {
        let r = a % b;
        let r = if r <= RELATIVE_TOLERANCE * b || b - r <= RELATIVE_TOLERANCE * b {
            0.0
        } else {
            r
        };
        if r == 0.0 {
            return b;
        }
        (a, b) = (b, r);
    }
    0.0
}

/// What the DUT's quantum leaves in every point of the map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quantization {
    /// The quantum `Δ` found from the readings, radians.
    pub quantum: f64,
    /// The noise `σ` in front of the quantizer, radians (`None`: no point crossed twice in a
    /// direction, taken as 0).
    pub noise: Option<f64>,
    /// The term `u_q = (Δ/√12)·exp(−2π²σ²/Δ²)` in every point's u, radians.
    pub u: f64,
}

impl Quantization {
    /// The term for quantum `quantum` and pooled repeatability `repeatability` (per pass, which
    /// holds the quantization too), radians (module docs).
    pub(super) fn new(quantum: f64, repeatability: Option<f64>) -> Quantization {
        let resolution2 = quantum * quantum / 12.0;
        let noise = repeatability.map(|s| (s * s - resolution2).max(0.0).sqrt());
        let sigma = noise.unwrap_or(0.0);
        let u = resolution2.sqrt() * (-2.0 * PI * PI * sigma * sigma / (quantum * quantum)).exp();
        Quantization { quantum, noise, u }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tracked(readings: impl Iterator<Item = f64>) -> Option<f64> {
        let mut t = QuantumTracker::default();
        readings.for_each(|r| t.add(r));
        t.quantum()
    }

    /// A 16-bit sensor read as radians (moteus' encoder: 19.8″), turning at 62 codes a sample
    /// with steps of 61–63 codes and wrapping: the quantum is found to 10⁻⁹ of itself.
    #[test]
    fn the_quantum_of_counts_is_their_unit() {
        let q = TAU / 65536.0;
        let found =
            tracked((0..5000).map(|k| ((62 * k + (k * k) % 3) % 65536) as f64 * q)).unwrap();
        assert!((found / q - 1.0).abs() < 1e-9, "{found}");
        // Degrees printed with four decimals: the printing's 0.0001°.
        let found = tracked((0..5000).map(|k| {
            let deg = (k as f64 * 0.0713_f64 + (k as f64).sin()).rem_euclid(360.0);
            ((deg * 1e4).round() / 1e4).to_radians()
        }))
        .unwrap();
        assert!((found / 1e-4f64.to_radians() - 1.0).abs() < 1e-6, "{found}");
    }

    /// A sweep sampled every 0.9° whose steps differ only by the DUT's smooth error (0.05″ from
    /// step to step), and a noise-free sweep of equal steps: neither is quantized.
    #[test]
    fn equal_or_nearly_equal_steps_are_no_quantum() {
        let deg = |k: f64| k * 0.9 + 50.0 / 3600.0 * (2.0 * (k * 0.9).to_radians()).sin();
        assert_eq!(tracked((0..800).map(|k| deg(k as f64).to_radians())), None);
        assert_eq!(
            tracked((0..800).map(|k| (k as f64 * 0.9).to_radians())),
            None
        );
    }

    #[test]
    fn readings_in_floating_point_have_no_quantum() {
        let mut state = 7u64;
        let found = tracked((0..5000).map(|k| {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            0.01 * k as f64 + (state >> 11) as f64 * 1e-21
        }));
        assert_eq!(found, None);
    }

    /// Without noise the term is the resolution's `Δ/√12`; noise of half a quantum in front of
    /// the quantizer leaves exp(−π²/2) = 0.72 % of it, and a quantum's worth nothing to speak of.
    #[test]
    fn dither_takes_the_term_away() {
        let q = 1.0;
        assert!((Quantization::new(q, None).u - 1.0 / 12f64.sqrt()).abs() < 1e-12);
        let s = |sigma: f64| (sigma * sigma + q * q / 12.0).sqrt();
        let half = Quantization::new(q, Some(s(0.5)));
        assert!((half.u * 12f64.sqrt() - (-PI * PI / 2.0).exp()).abs() < 1e-9);
        assert!(Quantization::new(q, Some(s(1.0))).u < 1e-8);
    }
}
