//! Correcting readings with an error map: what `calib apply` does to every reading of a channel.
//!
//! # Sign
//! A reading `r` is corrected as `r + correction(r) = r − e(r)`, `e` the map (error = reading −
//! true angle), evaluated at the reading itself: the map is a function of the sensor's own
//! reading, which is all a controller has at run time.
//!
//! # Interpolation
//! Between grid points the map is interpolated **linearly and periodically**
//! ([`ErrorMap::eval_linear`](crate::ErrorMap::eval_linear)), as a controller loading `calib export`'s look-up table does, so
//! corrected logs match what the corrected machine will read. The table's own resolution decides
//! the accuracy: for a harmonic of order `h` and amplitude `A` on a grid of step `Δ = 2π/N`,
//! linear interpolation errs by at most `A·(hΔ)²/8` between points (0.05″ for 24″ at order 72 on
//! 3600 points; 5·10⁻⁶″ for 20″ at order 8 on 36000 points). A finer table, not another
//! interpolation, is the cure for a coarse one: `calib csrr --points N`.
//!
//! # Range maps
//! A [`RangeMap`](crate::RangeMap) (a joint that never turns a whole revolution) corrects only the readings inside
//! its range, interpolated linearly there; a reading outside it is returned unchanged, bit for
//! bit, and counted ([`Correction::outside`]) so the caller can say how many were left alone.
//! Nothing is extrapolated.
//!
//! # Units and wrapping
//! [`Correction::apply`] takes and returns readings in the log's own unit, and subtracts the
//! error converted to that unit rather than converting the reading to radians and back, so a
//! reading with zero error comes back bit for bit. A channel wrapped to one revolution stays
//! wrapped the same way ([`Wrapping`]): near the wrap point a correction can carry a reading
//! across it (359.9999° + 0.5″ → 0.0001°), and the corrected value is wrapped back into the
//! channel's range; accumulated readings are never wrapped.

use crate::TableMap;
use crate::angle::AngleUnit;
use std::cell::Cell;

/// How a channel's readings are wrapped, in revolutions of its unit (360 for degrees, 2π for
/// radians, N for `counts:N`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Wrapping {
    /// Readings in `[0, 1 rev)`, e.g. `[0, 360)` degrees.
    Positive,
    /// Readings in `[−½ rev, ½ rev)`, e.g. `[−180, 180)` degrees.
    Signed,
    /// Readings accumulate over revolutions; nothing is wrapped.
    Unwrapped,
}

impl Wrapping {
    /// The wrapping of a channel whose readings span `[min, max]` (in `unit`): [`Positive`] if
    /// they all lie in `[0, 1 rev)`, else [`Signed`] if they all lie in `[−½, ½) rev`, else
    /// [`Unwrapped`]. A log that covers less than a revolution is ambiguous (an accumulating
    /// sensor that never passed zero looks wrapped); callers let the user decide then.
    ///
    /// [`Positive`]: Wrapping::Positive
    /// [`Signed`]: Wrapping::Signed
    /// [`Unwrapped`]: Wrapping::Unwrapped
    pub fn detect(min: f64, max: f64, unit: AngleUnit) -> Wrapping {
        let rev = revolution(unit);
        if min >= 0.0 && max < rev {
            Wrapping::Positive
        } else if min >= -rev / 2.0 && max < rev / 2.0 {
            Wrapping::Signed
        } else {
            Wrapping::Unwrapped
        }
    }

    /// `x` (in a unit of `rev` per revolution) brought into this range.
    fn wrap(self, x: f64, rev: f64) -> f64 {
        let into = |x: f64| {
            let r = x.rem_euclid(rev);
            // rem_euclid returns `rev` itself for tiny negative inputs.
            if r >= rev { 0.0 } else { r }
        };
        match self {
            Wrapping::Positive => into(x),
            Wrapping::Signed => into(x + rev / 2.0) - rev / 2.0,
            Wrapping::Unwrapped => x,
        }
    }
}

/// One revolution in `unit`.
fn revolution(unit: AngleUnit) -> f64 {
    unit.from_rad(std::f64::consts::TAU)
}

/// An error map ready to correct readings of one channel in its log's unit.
///
/// ```
/// use calib_core::correction::{Correction, Wrapping};
/// use calib_core::{AngleUnit, ErrorMap, angle::ARCSEC_PER_RAD};
///
/// // A sensor that reads 10″ high at 0° and 10″ low at 180° (two grid points, linear between).
/// let map = ErrorMap::new(vec![10.0 / ARCSEC_PER_RAD, -10.0 / ARCSEC_PER_RAD]);
/// let fix = Correction::new(map, AngleUnit::Deg, Wrapping::Positive);
/// let arcsec = |deg: f64| deg * 3600.0;
/// assert!((arcsec(fix.apply(90.0) - 90.0)).abs() < 1e-9); // e(90°) = 0
/// assert!((arcsec(fix.apply(180.0) - 180.0) - 10.0).abs() < 1e-9); // 10″ low: +10″
/// // 0° reads 10″ high: corrected to −10″, wrapped back into [0, 360).
/// assert!((arcsec(fix.apply(0.0) - 360.0) + 10.0).abs() < 1e-9);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Correction {
    map: TableMap,
    /// Readings outside a range map's range, left unchanged.
    outside: Cell<u64>,
    unit: AngleUnit,
    /// One revolution in `unit`.
    rev: f64,
    wrapping: Wrapping,
}

impl Correction {
    /// The unit of the readings corrected.
    pub fn unit(&self) -> AngleUnit {
        self.unit
    }

    /// Corrects readings in `unit`, wrapped as `wrapping` says, with `map` (an [`ErrorMap`] or a
    /// [`RangeMap`], or a [`TableMap`] of either): every reading for a whole-turn map, the
    /// readings inside its range for a range map (see [Range maps](self#range-maps)).
    ///
    /// [`ErrorMap`]: crate::ErrorMap
    /// [`RangeMap`]: crate::RangeMap
    pub fn new(map: impl Into<TableMap>, unit: AngleUnit, wrapping: Wrapping) -> Self {
        Correction {
            map: map.into(),
            outside: Cell::new(0),
            unit,
            rev: revolution(unit),
            wrapping,
        }
    }

    /// The corrected reading `x − e(x)` (see the [module docs](self)), in the reading's unit,
    /// wrapped as the channel is; a reading outside a range map's range comes back unchanged.
    pub fn apply(&self, x: f64) -> f64 {
        let theta = self.unit.to_rad(x);
        let Some(e) = self.map.eval_linear(theta) else {
            self.outside.set(self.outside.get() + 1);
            return x;
        };
        self.wrapping.wrap(x - self.unit.from_rad(e), self.rev)
    }

    /// How many readings [`Correction::apply`] left unchanged because they lay outside a range
    /// map's range (always 0 for a whole-turn map).
    pub fn outside(&self) -> u64 {
        self.outside.get()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::angle::ARCSEC_PER_RAD;
    use crate::{ErrorMap, FourierSeries, Harmonic, RangeMap};
    use std::f64::consts::{PI, TAU};

    #[test]
    fn detection_picks_the_narrowest_range() {
        let deg = AngleUnit::Deg;
        assert_eq!(Wrapping::detect(0.0, 359.99, deg), Wrapping::Positive);
        assert_eq!(Wrapping::detect(-180.0, 179.9, deg), Wrapping::Signed);
        assert_eq!(Wrapping::detect(-0.1, 359.0, deg), Wrapping::Unwrapped);
        assert_eq!(Wrapping::detect(0.0, 360.0, deg), Wrapping::Unwrapped);
        assert_eq!(
            Wrapping::detect(0.0, 4095.0, AngleUnit::Counts(4096)),
            Wrapping::Positive
        );
        assert_eq!(Wrapping::detect(-PI, 3.0, AngleUnit::Rad), Wrapping::Signed);
    }

    #[test]
    fn corrected_readings_stay_in_their_range() {
        let map = ErrorMap::new(vec![30.0 / ARCSEC_PER_RAD, -30.0 / ARCSEC_PER_RAD]);
        let tiny = 1.0 / 3600.0; // 1″ in degrees, well inside the 30″ error near 0°
        for w in [Wrapping::Positive, Wrapping::Signed] {
            let fix = Correction::new(map.clone(), AngleUnit::Deg, w);
            let (lo, hi) = if w == Wrapping::Positive {
                (0.0, 360.0)
            } else {
                (-180.0, 180.0)
            };
            for x in [
                lo,
                lo + tiny,
                hi - tiny,
                0.0,
                tiny,
                360.0 - tiny,
                180.0 - tiny,
            ] {
                if !(lo..hi).contains(&x) {
                    continue;
                }
                let c = fix.apply(x);
                assert!((lo..hi).contains(&c), "{w:?}: {x} → {c}");
                // The correction is 30″ at most, modulo a revolution.
                let d = (c - x + 540.0).rem_euclid(360.0) - 180.0;
                assert!(d.abs() * 3600.0 <= 30.0 + 1e-6, "{w:?}: {x} → {c}");
            }
        }
        // Accumulated readings are never wrapped: below zero and above a revolution alike.
        let fix = Correction::new(map, AngleUnit::Deg, Wrapping::Unwrapped);
        assert!(fix.apply(0.0) < 0.0);
        assert!(fix.apply(720.0) < 720.0 && fix.apply(720.0) > 719.0);
    }

    #[test]
    fn correction_inverts_the_error_within_the_interpolation_bound() {
        // e(θ) = 20″ cos(8θ + 30°), tabulated on 3600 points; readings r = θ + e(θ).
        let series = FourierSeries::from_harmonics(&[Harmonic::from_arcsec_deg(8, 20.0, 30.0)], 8);
        let n = 3600;
        // The map is a function of the reading: e(θ(r)); tabulate by inverting r = θ + e(θ)
        // with a fixed-point iteration (|e′| = 8·20″ ≪ 1, so it converges fast).
        let theta_of = |r: f64| {
            let mut th = r;
            for _ in 0..20 {
                th = r - series.eval(th);
            }
            th
        };
        let map = ErrorMap::new(
            (0..n)
                .map(|i| {
                    let r = TAU * i as f64 / n as f64;
                    r - theta_of(r)
                })
                .collect(),
        );
        let fix = Correction::new(map, AngleUnit::Rad, Wrapping::Unwrapped);
        // Linear interpolation bound A·(hΔ)²/8 = 20″·(8·2π/3600)²/8 ≈ 4.9·10⁻⁴″.
        let bound = 20.0 * (8.0 * TAU / n as f64).powi(2) / 8.0;
        let mut worst = 0.0f64;
        for k in 0..10_000 {
            let th = -3.0 + 13.0 * k as f64 / 10_000.0;
            let r = th + series.eval(th);
            worst = worst.max((fix.apply(r) - th).abs() * ARCSEC_PER_RAD);
        }
        assert!(worst <= bound * 1.01, "{worst}″ > {bound}″");
        assert!(
            worst > bound * 0.5,
            "the test should probe the bound: {worst}″"
        );
    }

    #[test]
    fn a_range_map_corrects_inside_and_counts_the_rest() {
        // 10″ over 90°…180°, linear from +10″ to −10″.
        let map = RangeMap::new(
            PI / 2.0,
            PI / 2.0,
            vec![10.0 / ARCSEC_PER_RAD, -10.0 / ARCSEC_PER_RAD],
        )
        .unwrap();
        let fix = Correction::new(map, AngleUnit::Deg, Wrapping::Positive);
        assert!(((fix.apply(90.0) - 90.0) * 3600.0 + 10.0).abs() < 1e-9);
        assert!(((fix.apply(135.0) - 135.0) * 3600.0).abs() < 1e-9);
        assert_eq!(fix.outside(), 0);
        for x in [0.0, 89.99, 180.01, 359.0] {
            assert_eq!(fix.apply(x), x);
        }
        assert_eq!(fix.outside(), 4);
    }

    #[test]
    fn a_zero_error_leaves_readings_bit_for_bit() {
        let fix = Correction::new(
            ErrorMap::new(vec![0.0; 8]),
            AngleUnit::Counts(1 << 20),
            Wrapping::Positive,
        );
        for x in [0.0, 1.0, 12345.0, 1048575.0] {
            assert_eq!(fix.apply(x), x);
        }
    }
}
