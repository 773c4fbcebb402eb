//! One table that corrects in one step what a table already in use and a residual correct in
//! turn: what `calib compose` computes.
//!
//! # Equation
//! A controller applying the map `e₁` turns a reading `r` into `r₁ = r − e₁(r)`. A residual map
//! `e_R`, calibrated from readings corrected that way, is a function of `r₁`, not of `r`:
//! correcting again gives `r₂ = r₁ − F·e_R(r₁)` (`F = 1` for the whole residual, `0 < F < 1` for
//! a partial update, as moteus users refine a table). The one map that does both is
//!
//! ```text
//! e₂(r) = r − r₂ = e₁(r) + F·e_R(r − e₁(r)),
//! ```
//!
//! evaluated at every grid point `rᵢ = i·2π/N` with `e₁` and `e_R` interpolated linearly and
//! periodically, as `calib apply` and the controllers do. Adding the two maps instead evaluates
//! `e_R` at `r` rather than at `r₁` and errs by about `e_R′·e₁` — with `e₁` of hundreds of
//! arcseconds and a residual of a few at a high order, tenths of an arcsecond.
//!
//! # What the grid can hold
//! At its grid points `e₂` is exact. Between them the sequence `e₁` then `e_R` is piecewise
//! linear with kinks where `r − e₁(r)` crosses a grid point of `e_R`, which is not where `e₂`'s
//! grid points are; `e₂` interpolated linearly departs from the sequence there by at most a
//! quarter of the residual's slope change times the step (`A·h²·Δ²/4` for a harmonic of order
//! `h` and amplitude `A` on a step `Δ`, the size of the residual's own interpolation error). A
//! finer grid reduces it; [`Composition::deviation`] is what was found.
//!
//! # Mean
//! Maps are zero-mean ([`ErrorMap::new`]); `e₂`'s values have a small mean of their own (of the
//! order of `e_R·e₁′`), which is removed like any map's. Corrected with `e₂` a reading comes out
//! [`Composition::offset`] higher than corrected by `e₁` then `e_R`: a constant that no
//! self-calibration observes.
//!
//! # Uncertainty
//! Where both tables carry standard uncertainties, `u₂(r) = √(u₁(r)² + (F·u_R(r − e₁(r)))²)`:
//! the two calibrations come from different logs and are taken as independent
//! ([`compose_uncertainty`]).

use crate::ErrorMap;
use crate::error_map::interpolate_periodic;
use std::f64::consts::TAU;

/// Points per grid step at which [`compose`] compares the composed map with the sequence.
pub const CHECK_POINTS_PER_STEP: usize = 16;

/// The composed map and how it relates to applying the two maps in sequence.
#[derive(Debug, Clone, PartialEq)]
pub struct Composition {
    /// `e₂` on the output grid (radians, zero mean).
    pub map: ErrorMap,
    /// The mean removed from `e₂` (radians): a reading corrected with [`map`](Self::map) comes
    /// out this much higher than corrected by the two maps in sequence.
    pub offset: f64,
    /// The largest difference (radians) between correcting with `map` (plus `offset`) and
    /// correcting by the two maps in sequence, found at [`CHECK_POINTS_PER_STEP`] points per
    /// grid step over the whole revolution.
    pub deviation: f64,
}

/// `e₂(rᵢ) = e₁(rᵢ) + factor·e_R(rᵢ − e₁(rᵢ))` on `points` grid points (see the [module
/// docs](self)); `first` is the map already in use (`e₁`), `residual` the map calibrated from
/// readings it corrected (`e_R`).
///
/// ```
/// use calib_core::compose::compose;
/// use calib_core::{ErrorMap, FourierSeries, Harmonic, angle::ARCSEC_PER_RAD};
///
/// let first = ErrorMap::from_series(
///     &FourierSeries::from_harmonics(&[Harmonic::from_arcsec_deg(1, 300.0, 0.0)], 1),
///     3600,
/// );
/// let residual = ErrorMap::from_series(
///     &FourierSeries::from_harmonics(&[Harmonic::from_arcsec_deg(72, 5.0, 0.0)], 72),
///     3600,
/// );
/// let both = compose(&first, &residual, 1.0, 3600);
/// // At r = 0, e₁ = 300″ and the residual is read at r₁ = −300″, not at 0.
/// let r1 = -300.0 / ARCSEC_PER_RAD;
/// let want = first.values()[0] + residual.eval_linear(r1);
/// assert!(((both.map.values()[0] + both.offset - want) * ARCSEC_PER_RAD).abs() < 1e-9);
/// // Between grid points: at most the residual's interpolation error, A·h²·Δ²/4 = 0.0198″.
/// assert!(both.deviation * ARCSEC_PER_RAD < 0.0198);
/// ```
///
/// # Panics
/// If `points` is 0.
pub fn compose(first: &ErrorMap, residual: &ErrorMap, factor: f64, points: usize) -> Composition {
    assert!(points > 0, "a composed map needs at least one point");
    let sequence = |r: f64| {
        let e1 = first.eval_linear(r);
        e1 + factor * residual.eval_linear(r - e1)
    };
    let values: Vec<f64> = (0..points)
        .map(|i| sequence(TAU * i as f64 / points as f64))
        .collect();
    let offset = values.iter().sum::<f64>() / points as f64;
    let map = ErrorMap::new(values);
    let steps = points * CHECK_POINTS_PER_STEP;
    let deviation = (0..steps)
        .map(|k| {
            let r = TAU * k as f64 / steps as f64;
            (map.eval_linear(r) + offset - sequence(r)).abs()
        })
        .fold(0.0, f64::max);
    Composition {
        map,
        offset,
        deviation,
    }
}

/// The standard uncertainty of [`compose`]'s map at its `points` grid points (radians):
/// `√(u₁(rᵢ)² + (factor·u_R(rᵢ − e₁(rᵢ)))²)`, each uncertainty on its own table's uniform grid and
/// interpolated linearly and periodically.
///
/// # Panics
/// If either uncertainty slice is empty or `points` is 0.
pub fn compose_uncertainty(
    first: &ErrorMap,
    u_first: &[f64],
    u_residual: &[f64],
    factor: f64,
    points: usize,
) -> Vec<f64> {
    (0..points)
        .map(|i| {
            let r = TAU * i as f64 / points as f64;
            let u1 = interpolate_periodic(u_first, r);
            let ur = factor * interpolate_periodic(u_residual, r - first.eval_linear(r));
            u1.hypot(ur)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::angle::{ARCSEC_PER_RAD, AngleUnit};
    use crate::correction::{Correction, Wrapping};
    use crate::{FourierSeries, Harmonic};

    fn map(harmonics: &[(usize, f64, f64)], points: usize) -> ErrorMap {
        let hs: Vec<Harmonic> = harmonics
            .iter()
            .map(|&(h, a, p)| Harmonic::from_arcsec_deg(h, a, p))
            .collect();
        ErrorMap::from_series(&FourierSeries::from_harmonics(&hs, 200), points)
    }

    #[test]
    fn composition_corrects_as_the_two_tables_in_sequence() {
        // Hundreds of arcseconds in the first table, a residual of a few at low and high orders.
        let first = map(
            &[(1, 400.0, 20.0), (2, 150.0, -70.0), (72, 30.0, 10.0)],
            3600,
        );
        let residual = map(&[(3, 4.0, 50.0), (72, 2.0, -30.0), (144, 0.5, 0.0)], 3600);
        let both = compose(&first, &residual, 1.0, 3600);
        let by = |m: &ErrorMap| Correction::new(m.clone(), AngleUnit::Rad, Wrapping::Unwrapped);
        let (c1, cr, c2) = (by(&first), by(&residual), by(&both.map));
        let mut worst = 0.0f64;
        for k in 0..100_000 {
            let r = -1.0 + 8.0 * k as f64 / 100_000.0;
            let sequence = cr.apply(c1.apply(r));
            worst = worst.max((c2.apply(r) - both.offset - sequence).abs());
        }
        // The residual's own interpolation error bounds the kinks' effect: A·h²·Δ²/4 for 2″ at
        // order 72 and 0.5″ at order 144 on 0.1° steps is 0.0079″ + 0.0079″.
        let bound = (2.0 * 72f64.powi(2) + 0.5 * 144f64.powi(2)) * (TAU / 3600.0).powi(2) / 4.0;
        assert!(
            worst * ARCSEC_PER_RAD <= bound,
            "{}″",
            worst * ARCSEC_PER_RAD
        );
        assert!(both.deviation * ARCSEC_PER_RAD <= bound);
        // The check's 16 points per step see what 100,000 points over 8 rad see.
        assert!(
            worst <= both.deviation * 1.05,
            "{worst} vs {}",
            both.deviation
        );
        // Adding the maps instead would be wrong by tenths of an arcsecond.
        let sum = ErrorMap::new(
            (0..3600)
                .map(|i| first.values()[i] + residual.values()[i])
                .collect(),
        );
        assert!(sum.minus(&both.map).max_abs_arcsec() > 0.2);
    }

    #[test]
    fn a_factor_takes_part_of_the_residual_and_zero_keeps_the_first() {
        let first = map(&[(1, 200.0, 0.0)], 720);
        let residual = map(&[(5, 10.0, 0.0)], 720);
        let none = compose(&first, &residual, 0.0, 720);
        assert!(none.map.minus(&first).max_abs_arcsec() < 1e-9);
        assert!(none.offset.abs() < 1e-15);
        let half = compose(&first, &residual, 0.5, 720);
        let full = compose(&first, &residual, 1.0, 720);
        for i in 0..720 {
            let mid = 0.5 * (none.map.values()[i] + full.map.values()[i]);
            assert!((half.map.values()[i] - mid).abs() * ARCSEC_PER_RAD < 1e-9);
        }
    }

    #[test]
    fn uncertainties_add_in_quadrature_where_the_residual_is_read() {
        let first = map(&[(1, 300.0, 0.0)], 360);
        let u1 = vec![0.3 / ARCSEC_PER_RAD; 360];
        let ur: Vec<f64> = (0..360).map(|i| i as f64 * 1e-8).collect();
        let u = compose_uncertainty(&first, &u1, &ur, 2.0, 360);
        let r = TAU * 10.0 / 360.0;
        let at = r - first.eval_linear(r);
        let want = u1[10].hypot(2.0 * interpolate_periodic(&ur, at));
        assert!((u[10] - want).abs() < 1e-18);
    }
}
