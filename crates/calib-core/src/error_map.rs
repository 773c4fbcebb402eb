//! Error maps over one revolution of a sensor's own reading.

use crate::angle::{ARCSEC_PER_RAD, wrap_2pi};
use crate::harmonics::FourierSeries;
use realfft::RealFftPlanner;
use std::f64::consts::TAU;

/// A sensor's error as a periodic function of its own reading, on a uniform grid.
///
/// # Grid
/// An [`ErrorMap`] holds `N` values `e(θ_i)` at `θ_i = i·2π/N`, `i = 0..N−1`: the origin is the
/// sensor's reading 0, the grid is uniform and periodic (θ_N ≡ θ_0). Values are radians.
///
/// # Sign
/// `e = reading − true angle`; the correction is `−e`, applied as `reading + correction(reading)`.
///
/// # Mean
/// Maps are zero-mean: [`ErrorMap::new`] removes the mean, because no self-calibration observes an
/// absolute offset.
///
/// # FFT normalization
/// [`ErrorMap::series`] returns coefficients normalized so that a map sampled from
/// `a cos hθ + b sin hθ` gives back `a` and `b` (i.e. `2/N` times the forward real FFT, for
/// `0 < h < N/2`).
#[derive(Debug, Clone, PartialEq)]
pub struct ErrorMap {
    values: Vec<f64>,
}

impl ErrorMap {
    /// A map from its values on the uniform grid (radians); the mean is removed.
    ///
    /// # Panics
    /// If `values` is empty; callers validate user-supplied grids first.
    pub fn new(mut values: Vec<f64>) -> Self {
        assert!(!values.is_empty(), "an error map needs at least one point");
        let mean = values.iter().sum::<f64>() / values.len() as f64;
        values.iter_mut().for_each(|v| *v -= mean);
        ErrorMap { values }
    }

    /// The map of a Fourier series sampled on `points` grid points (by inverse real FFT).
    pub fn from_series(series: &FourierSeries, points: usize) -> Self {
        let n = points.max(1);
        let mut planner = RealFftPlanner::<f64>::new();
        let c2r = planner.plan_fft_inverse(n);
        let mut spectrum = c2r.make_input_vec();
        let mut out = c2r.make_output_vec();
        // Orders at or above the Nyquist order alias on this grid: fold them in by direct
        // summation so the map is exact at its points whatever the series.
        let bins = spectrum.len();
        let mut aliased = FourierSeries::zeros(series.max_order());
        for h in 1..=series.max_order() {
            let (a, b) = (series.cos[h - 1], series.sin[h - 1]);
            if h < bins && 2 * h != n {
                // x[k] = Σ Re(X_h e^{i2πhk/N}) ·2/N … with X_h = (a − i b)·N/2 for the
                // unnormalized inverse.
                spectrum[h] = realfft::num_complex::Complex::new(a * 0.5, -b * 0.5);
            } else {
                aliased.cos[h - 1] = a;
                aliased.sin[h - 1] = b;
            }
        }
        c2r.process(&mut spectrum, &mut out)
            .expect("sizes come from the plan");
        // The unnormalized inverse of X_h = (a − ib)/2 at h and its conjugate at N−h gives
        // a cos + b sin exactly; no further scaling.
        if aliased.cos.iter().chain(&aliased.sin).any(|&v| v != 0.0) {
            for (i, v) in out.iter_mut().enumerate() {
                *v += aliased.eval(TAU * i as f64 / n as f64);
            }
        }
        ErrorMap::new(out)
    }

    /// Number of grid points.
    pub fn len(&self) -> usize {
        self.values.len()
    }
    /// Always false: a map has at least one point.
    pub fn is_empty(&self) -> bool {
        false
    }
    /// The values on the grid, radians.
    pub fn values(&self) -> &[f64] {
        &self.values
    }
    /// Grid angle of point `i`, radians.
    pub fn grid_angle(&self, i: usize) -> f64 {
        TAU * i as f64 / self.values.len() as f64
    }

    /// Periodic linear interpolation at `theta` (radians, any revolution).
    pub fn eval_linear(&self, theta: f64) -> f64 {
        interpolate_periodic(&self.values, theta)
    }

    /// Band-limited (trigonometric) interpolation at `theta`: the unique Fourier series of order
    /// below N/2 through the grid values, evaluated at `theta`.
    pub fn eval_bandlimited(&self, theta: f64) -> f64 {
        self.series().eval(theta)
    }

    /// The map's Fourier series, orders `1..⌈N/2⌉−1` (the Nyquist term of an even grid, which has
    /// no phase, is dropped).
    pub fn series(&self) -> FourierSeries {
        let n = self.values.len();
        let mut planner = RealFftPlanner::<f64>::new();
        let r2c = planner.plan_fft_forward(n);
        let mut input = self.values.clone();
        let mut spectrum = r2c.make_output_vec();
        r2c.process(&mut input, &mut spectrum)
            .expect("sizes come from the plan");
        let max_order = (n - 1) / 2;
        let mut s = FourierSeries::zeros(max_order);
        let scale = 2.0 / n as f64;
        for h in 1..=max_order {
            s.cos[h - 1] = spectrum[h].re * scale;
            s.sin[h - 1] = -spectrum[h].im * scale;
        }
        s
    }

    /// Peak-to-peak value, radians.
    pub fn peak_to_peak(&self) -> f64 {
        let max = self
            .values
            .iter()
            .copied()
            .fold(f64::NEG_INFINITY, f64::max);
        let min = self.values.iter().copied().fold(f64::INFINITY, f64::min);
        max - min
    }
    /// Root mean square, radians.
    pub fn rms(&self) -> f64 {
        (self.values.iter().map(|v| v * v).sum::<f64>() / self.values.len() as f64).sqrt()
    }

    /// This map resampled on `points` grid points by periodic linear interpolation.
    pub fn resample_linear(&self, points: usize) -> ErrorMap {
        let n = points.max(1);
        ErrorMap::new(
            (0..n)
                .map(|i| self.eval_linear(TAU * i as f64 / n as f64))
                .collect(),
        )
    }

    /// The difference `self − other`, both evaluated on `self`'s grid (other interpolated
    /// linearly), mean removed.
    pub fn minus(&self, other: &ErrorMap) -> ErrorMap {
        ErrorMap::new(
            (0..self.len())
                .map(|i| self.values[i] - other.eval_linear(self.grid_angle(i)))
                .collect(),
        )
    }

    /// Largest absolute value, arcseconds (handy for accuracy checks against a truth).
    pub fn max_abs_arcsec(&self) -> f64 {
        self.values.iter().fold(0.0f64, |m, v| m.max(v.abs())) * ARCSEC_PER_RAD
    }
}

/// Periodic linear interpolation at `theta` (radians, any revolution) of `values` on the uniform
/// grid `i·2π/N` — [`ErrorMap::eval_linear`] for values that are not a zero-mean map, such as
/// standard uncertainties or a table decoded from a controller's format.
///
/// # Panics
/// If `values` is empty.
pub fn interpolate_periodic(values: &[f64], theta: f64) -> f64 {
    let n = values.len();
    let u = wrap_2pi(theta) / TAU * n as f64;
    let i = (u.floor() as usize).min(n - 1);
    let f = u - i as f64;
    let j = (i + 1) % n;
    values[i] * (1.0 - f) + values[j] * f
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::harmonics::Harmonic;

    fn naive_dft_coefficient(values: &[f64], h: usize) -> (f64, f64) {
        let n = values.len() as f64;
        let (mut a, mut b) = (0.0, 0.0);
        for (i, v) in values.iter().enumerate() {
            let th = TAU * i as f64 / n;
            a += v * (h as f64 * th).cos();
            b += v * (h as f64 * th).sin();
        }
        (2.0 * a / n, 2.0 * b / n)
    }

    #[test]
    fn analysis_matches_a_naive_dft_and_synthesis_inverts_it() {
        let truth = [
            Harmonic::from_arcsec_deg(1, 2.34, 10.0),
            Harmonic::from_arcsec_deg(72, 23.87, -45.0),
            Harmonic::from_arcsec_deg(216, 14.03, 170.0),
        ];
        let series = FourierSeries::from_harmonics(&truth, 300);
        let map = ErrorMap::from_series(&series, 1000);
        for i in (0..1000).step_by(37) {
            let th = map.grid_angle(i);
            let direct: f64 = truth.iter().map(|h| h.eval(th)).sum();
            assert!((map.values()[i] - direct).abs() < 1e-15);
        }
        let back = map.series();
        for h in [1usize, 2, 72, 100, 216] {
            let (a, b) = naive_dft_coefficient(map.values(), h);
            assert!((back.cos[h - 1] - a).abs() < 1e-15 && (back.sin[h - 1] - b).abs() < 1e-15);
        }
        let amp72 = back.harmonics()[71].to_report();
        assert!((amp72.amplitude_arcsec - 23.87).abs() < 1e-9);
        assert!((amp72.phase_deg + 45.0).abs() < 1e-9);
    }

    #[test]
    fn orders_above_nyquist_are_folded_exactly() {
        let series = FourierSeries::from_harmonics(&[Harmonic::from_arcsec_deg(9, 1.0, 0.0)], 9);
        let map = ErrorMap::from_series(&series, 8);
        for i in 0..8 {
            assert!((map.values()[i] - series.eval(map.grid_angle(i))).abs() < 1e-15);
        }
    }

    #[test]
    fn interpolation_is_periodic_and_bandlimited_is_exact_for_low_orders() {
        let series = FourierSeries::from_harmonics(&[Harmonic::from_arcsec_deg(3, 5.0, 20.0)], 3);
        let map = ErrorMap::from_series(&series, 64);
        for th in [0.0, 0.01, 1.0, 6.2, -0.3, 100.0] {
            assert!((map.eval_bandlimited(th) - series.eval(th)).abs() < 1e-15);
            let lin_err = (map.eval_linear(th) - series.eval(th)).abs() * ARCSEC_PER_RAD;
            // Linear interpolation error ≤ h²·Δθ²/8·A = 9·(2π/64)²/8·5″ ≈ 0.054″.
            assert!(lin_err < 0.055, "{lin_err}");
        }
        assert!((map.eval_linear(TAU - 1e-12) - map.values()[0]).abs() < 1e-9);
    }

    #[test]
    fn maps_are_zero_mean() {
        let m = ErrorMap::new(vec![1.0, 2.0, 3.0]);
        assert_eq!(m.values(), &[-1.0, 0.0, 1.0]);
        assert_eq!(m.peak_to_peak(), 2.0);
    }
}
