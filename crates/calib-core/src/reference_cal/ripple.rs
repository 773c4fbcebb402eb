//! An open-loop (commanded) reference: the motor's ripple, periodic in the electrical angle,
//! separated from the DUT's map.
//!
//! # Model
//! Firmware calibrations (moteus, SimpleFOC, ODrive) drive the motor open loop and compare the
//! encoder with the *commanded* angle `c`. The rotor does not sit exactly at `c`: its cogging and
//! torque ripple pull it by `ρ(φ)`, a function of the electrical angle `φ = p·c` (`p` pole
//! pairs; six cycles per electrical turn is typical). The difference at a DUT reading is then
//! `x = e(r) + ρ(p·c) + const`. Every firmware tool averages `x` over an electrical period
//! (moteus' `calibrate_encoder.py`, `_window_average`), which removes `ρ` but also attenuates
//! the DUT's own orders `h` by `sin(πh/p)/(πh/p)` (0.4 % of order 1 at `p = 21`).
//!
//! Here `ρ` is fitted instead, as `ρ(φ) = Σ_{k=1..K} a_k·cos(kφ) + b_k·sin(kφ)` by least squares
//! on the map's high-passed part `x − x̄_p` (`x̄_p` the moving mean over one electrical period,
//! in grid points `N/p`, with fractional end weights), and subtracted from the map: the DUT's
//! orders are kept unattenuated, the ripple's orders `k·p` are taken out, and the fitted terms
//! are reported as the motor's ripple. `φ` at each grid point is `p` times the reference's own
//! reading there (the DUT's reading minus the measured difference), so the ripple is fitted in
//! the motor's angle even where the DUT errs by degrees. On a range, only points whose whole
//! window lies inside the range enter the fit; likewise only points whose window holds no point
//! left unmeasured (a gap no pass measured, bridged after the ripple is taken out: module
//! `gaps`). The fitted ripple is removed at every measured point.
//!
//! # Uncertainty
//! Each point's `u` gains the fit's standard error there, `sqrt(φ_iᵀ·C·φ_i)`, `C = s²(ΦᵀΦ)⁻¹·g`,
//! `s²` the residual variance and `g ≥ 1` the grid points per sample step.
//!
//! # What it cannot see
//! The DUT's own error at orders `k·p` (multiples of the pole pairs): it is taken for ripple.

use nalgebra::{DMatrix, DVector};
use std::f64::consts::TAU;

/// Highest harmonic of the electrical angle fitted.
pub const MAX_HARMONIC: usize = 12;

/// One fitted term of the ripple: `amplitude·cos(k·φ + phase)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RippleTerm {
    /// Cycles per electrical turn `k`.
    pub harmonic: usize,
    /// Cycles per mechanical revolution, `k·p`.
    pub order: usize,
    /// Amplitude, radians of the mechanical angle.
    pub amplitude: f64,
    /// Phase, radians (`cos` convention, against the electrical angle of the reference).
    pub phase: f64,
    /// Standard uncertainty of the amplitude, radians.
    pub u_amplitude: f64,
}

/// The motor's ripple taken out of the map of a commanded reference.
#[derive(Debug, Clone, PartialEq)]
pub struct Ripple {
    /// Pole pairs `p`.
    pub pole_pairs: u32,
    /// The fitted terms, `k = 1..K`.
    pub terms: Vec<RippleTerm>,
    /// Peak-to-peak of the ripple removed over the map, radians.
    pub peak_to_peak: f64,
    /// Grid points that entered the fit.
    pub fitted_points: usize,
}

/// Why the ripple cannot be separated.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum RippleProblem {
    /// The map's range holds fewer than two electrical periods.
    TooShort { periods: f64 },
}

/// Fits the ripple on the map `values` (a whole turn if `circular`), measured where `measured`
/// says, the reference's reading `reference` at each point (radians), `points_per_turn` grid
/// points per revolution; returns the ripple and its value and standard uncertainty at each
/// point (the peak-to-peak over the measured ones).
pub(super) fn fit(
    values: &[f64],
    measured: &[bool],
    reference: &[f64],
    points_per_turn: usize,
    pole_pairs: u32,
    circular: bool,
    grid_per_sample: f64,
) -> Result<(Ripple, Vec<f64>, Vec<f64>), RippleProblem> {
    let n = values.len();
    let p = f64::from(pole_pairs);
    let window = points_per_turn as f64 / p;
    let periods = (n - 1) as f64 / window;
    if !circular && periods < 2.0 {
        return Err(RippleProblem::TooShort { periods });
    }
    let mut means = moving_mean(values, window, circular);
    // The moving mean's reach (as in `moving_mean`) about each unmeasured point.
    let reach = (window / 2.0).ceil() as usize + 1;
    for g in (0..n).filter(|&g| !measured[g]) {
        for k in 0..=2 * reach {
            let i = (g + k) as i64 - reach as i64;
            if circular {
                means[i.rem_euclid(n as i64) as usize] = None;
            } else if (0..n as i64).contains(&i) {
                means[i as usize] = None;
            }
        }
    }
    let k_max = (points_per_turn / (4 * pole_pairs as usize)).clamp(1, MAX_HARMONIC);
    let rows: Vec<usize> = (0..n).filter(|&i| means[i].is_some()).collect();
    let basis = |i: usize| -> Vec<f64> {
        let phi = p * reference[i];
        (1..=k_max)
            .flat_map(|k| {
                let (s, c) = (k as f64 * phi).sin_cos();
                [c, s]
            })
            .collect()
    };
    let cols = 2 * k_max;
    let a = DMatrix::from_fn(rows.len(), cols, |r, c| basis(rows[r])[c]);
    let y = DVector::from_iterator(
        rows.len(),
        rows.iter().map(|&i| values[i] - means[i].unwrap_or(0.0)),
    );
    let normal = a.transpose() * &a;
    let Some(inverse) = normal.clone().try_inverse() else {
        return Err(RippleProblem::TooShort { periods });
    };
    let coef = &inverse * (a.transpose() * &y);
    let residual = &y - &a * &coef;
    let dof = rows.len().saturating_sub(cols).max(1) as f64;
    let s2 = residual.norm_squared() / dof * grid_per_sample.max(1.0);
    let cov = inverse * s2;
    let terms = (0..k_max)
        .map(|k| {
            let (ac, bs) = (coef[2 * k], coef[2 * k + 1]);
            let amplitude = ac.hypot(bs);
            // a·cos + b·sin = A·cos(kφ + ψ), ψ = atan2(−b, a).
            let var = if amplitude > 0.0 {
                (ac * ac * cov[(2 * k, 2 * k)]
                    + bs * bs * cov[(2 * k + 1, 2 * k + 1)]
                    + 2.0 * ac * bs * cov[(2 * k, 2 * k + 1)])
                    / (amplitude * amplitude)
            } else {
                0.5 * (cov[(2 * k, 2 * k)] + cov[(2 * k + 1, 2 * k + 1)])
            };
            RippleTerm {
                harmonic: k + 1,
                order: (k + 1) * pole_pairs as usize,
                amplitude,
                phase: (-bs).atan2(ac).rem_euclid(TAU),
                u_amplitude: var.max(0.0).sqrt(),
            }
        })
        .collect();
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    let (mut value, mut u) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for i in 0..n {
        let b = DVector::from_vec(basis(i));
        let v = b.dot(&coef);
        if measured[i] {
            lo = lo.min(v);
            hi = hi.max(v);
        }
        value.push(v);
        u.push((&cov * &b).dot(&b).max(0.0).sqrt());
    }
    Ok((
        Ripple {
            pole_pairs,
            terms,
            peak_to_peak: hi - lo,
            fitted_points: rows.len(),
        },
        value,
        u,
    ))
}

/// The mean of the linear interpolant of `values` over `[i − w/2, i + w/2]` at each point `i`;
/// `None` where the window leaves a range (`circular` false).
fn moving_mean(values: &[f64], w: f64, circular: bool) -> Vec<Option<f64>> {
    let n = values.len();
    let reach = (w / 2.0).ceil() as usize + 1;
    // The values extended by `reach` on both sides (circularly), and the integral of their
    // linear interpolant from the first.
    let ext: Vec<f64> = if circular {
        (0..n + 2 * reach)
            .map(|j| values[(j + n * (reach / n + 1) - reach) % n])
            .collect()
    } else {
        values.to_vec()
    };
    let shift = if circular { reach as f64 } else { 0.0 };
    let mut cum = vec![0.0; ext.len()];
    for j in 1..ext.len() {
        cum[j] = cum[j - 1] + 0.5 * (ext[j - 1] + ext[j]);
    }
    let integral = |x: f64| -> Option<f64> {
        if x < 0.0 || x > (ext.len() - 1) as f64 {
            return None;
        }
        let k = (x.floor() as usize).min(ext.len() - 2);
        let f = x - k as f64;
        Some(cum[k] + f * ext[k] + 0.5 * f * f * (ext[k + 1] - ext[k]))
    };
    (0..n)
        .map(|i| {
            let c = i as f64 + shift;
            let hi = integral(c + w / 2.0)?;
            let lo = integral(c - w / 2.0)?;
            Some((hi - lo) / w)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_moving_mean_of_a_period_is_zero() {
        let n = 3600;
        let w = n as f64 / 21.0;
        let v: Vec<f64> = (0..n)
            .map(|i| (TAU * 21.0 * 6.0 * i as f64 / n as f64).cos())
            .collect();
        for m in moving_mean(&v, w, true).into_iter().map(Option::unwrap) {
            assert!(m.abs() < 2e-4, "{m}");
        }
        let r = moving_mean(&v[..1000], w, false);
        assert!(r[0].is_none() && r[500].is_some() && r[999].is_none());
    }

    /// A DUT's orders 1 and 2 plus a 6-per-electrical-turn ripple at 7 pole pairs, over a whole
    /// turn: the fit finds the ripple's amplitude (to the leak of the linear interpolant's mean,
    /// ~1e-3 of it) and leaves the DUT's orders.
    #[test]
    fn separates_ripple_from_low_orders() {
        let n = 3600;
        let step = TAU / n as f64;
        let e = |th: f64| 1e-3 * (th + 0.4).cos() + 5e-4 * (2.0 * th).cos();
        let rho = |phi: f64| 3e-4 * (6.0 * phi + 1.0).cos();
        let reference: Vec<f64> = (0..n).map(|i| i as f64 * step).collect();
        let values: Vec<f64> = reference.iter().map(|&c| e(c) + rho(7.0 * c)).collect();
        let (ripple, value, _) = fit(&values, &vec![true; n], &reference, n, 7, true, 1.0).unwrap();
        let six = ripple.terms.iter().find(|t| t.harmonic == 6).unwrap();
        assert_eq!(six.order, 42);
        assert!((six.amplitude - 3e-4).abs() < 1e-6, "{}", six.amplitude);
        let worst = (0..n)
            .map(|i| (values[i] - value[i] - e(reference[i])).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-6, "{worst}");
    }
}
