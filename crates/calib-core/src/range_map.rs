//! Error maps over part of a revolution: the maps of joints that never turn a whole revolution.

use crate::angle::{ARCSEC_PER_RAD, wrap_2pi};
use std::f64::consts::TAU;

/// A sensor's error as a function of its own reading over a range shorter than a revolution, on
/// a uniform grid that includes both ends.
///
/// # Grid
/// A [`RangeMap`] holds `N ≥ 2` values `e(θ_i)` at `θ_i = start + i·step`, `i = 0..N−1`: both
/// ends of the range `[start, end]`, `end = start + (N−1)·step`, are grid points, and the range
/// is shorter than a revolution (`end − start < 2π`). `start` lies in `[0, 2π)`; `end` may pass
/// 2π when the range crosses the reading 0 (a joint swept from −30° to +30° has the range
/// 330°…390°). Values are radians.
///
/// # Mean
/// Like an [`ErrorMap`](crate::ErrorMap), a range map is zero-mean — but over its range, not over
/// the circle: [`RangeMap::new`] removes the mean of the grid values. Two range maps of the same
/// sensor over different ranges therefore differ by a constant; compare them over their common
/// range with that constant removed.
///
/// # Outside the range
/// A range map says nothing about readings outside its range: [`RangeMap::eval_linear`] returns
/// `None` there and never extrapolates.
#[derive(Debug, Clone, PartialEq)]
pub struct RangeMap {
    start: f64,
    step: f64,
    values: Vec<f64>,
}

/// Why a range map cannot be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RangeMapError {
    /// Fewer than two values.
    #[error("a range map needs at least 2 grid points, {0} given")]
    TooFewPoints(usize),
    /// The grid is not a finite, positive step over less than a revolution.
    #[error(
        "a range map's grid from {start_deg}° with step {step_deg}° over {points} points must be finite, \
         increasing and shorter than a revolution"
    )]
    BadGrid {
        /// First grid angle, degrees.
        start_deg: f64,
        /// Step, degrees.
        step_deg: f64,
        /// Grid points.
        points: usize,
    },
}

impl RangeMap {
    /// A map from its values at `start + i·step` (radians); `start` is brought into `[0, 2π)` and
    /// the mean of the values is removed.
    pub fn new(start: f64, step: f64, mut values: Vec<f64>) -> Result<Self, RangeMapError> {
        let n = values.len();
        if n < 2 {
            return Err(RangeMapError::TooFewPoints(n));
        }
        let span = step * (n - 1) as f64;
        if !(start.is_finite() && step.is_finite() && step > 0.0 && span < TAU) {
            return Err(RangeMapError::BadGrid {
                start_deg: start.to_degrees(),
                step_deg: step.to_degrees(),
                points: n,
            });
        }
        let mean = values.iter().sum::<f64>() / n as f64;
        values.iter_mut().for_each(|v| *v -= mean);
        Ok(RangeMap {
            start: wrap_2pi(start),
            step,
            values,
        })
    }

    /// First grid angle, radians, in `[0, 2π)`.
    pub fn start(&self) -> f64 {
        self.start
    }
    /// Last grid angle, radians (`start + (N−1)·step`; above 2π if the range crosses 0).
    pub fn end(&self) -> f64 {
        self.start + self.span()
    }
    /// The first and last grid angles in the sensor's own reading convention, degrees: as
    /// [`start`](Self::start)…[`end`](Self::end), except that a range crossing the reading 0 is
    /// signed (−40°…95°, not 320°…455°): never an angle above 360°.
    pub fn ends_deg(&self) -> (f64, f64) {
        let (lo, hi) = (self.start().to_degrees(), self.end().to_degrees());
        if hi > 360.0 {
            (lo - 360.0, hi - 360.0)
        } else {
            (lo, hi)
        }
    }
    /// `end − start`, radians (less than a revolution).
    pub fn span(&self) -> f64 {
        self.step * (self.values.len() - 1) as f64
    }
    /// Grid step, radians.
    pub fn step(&self) -> f64 {
        self.step
    }
    /// Number of grid points.
    pub fn len(&self) -> usize {
        self.values.len()
    }
    /// Always false: a range map has at least two points.
    pub fn is_empty(&self) -> bool {
        false
    }
    /// The values on the grid, radians.
    pub fn values(&self) -> &[f64] {
        &self.values
    }
    /// Grid angle of point `i`, radians (may exceed 2π, see [`RangeMap::end`]).
    pub fn grid_angle(&self, i: usize) -> f64 {
        self.start + self.step * i as f64
    }

    /// Where the reading `theta` (radians, any revolution) falls in the range, as an offset from
    /// `start` in `[0, span]`; `None` outside the range. Readings within a millionth of a step
    /// of an end count as on it (rounding of the table's angles).
    fn offset(&self, theta: f64) -> Option<f64> {
        let x = wrap_2pi(theta - self.start);
        let span = self.span();
        let slack = 1e-6 * self.step;
        if x <= span + slack {
            Some(x.min(span))
        } else if TAU - x <= slack {
            Some(0.0)
        } else {
            None
        }
    }

    /// Whether the reading `theta` (any revolution) lies in the range.
    pub fn contains(&self, theta: f64) -> bool {
        self.offset(theta).is_some()
    }

    /// Linear interpolation at the reading `theta` (radians, any revolution); `None` outside the
    /// range (never extrapolated).
    pub fn eval_linear(&self, theta: f64) -> Option<f64> {
        let x = self.offset(theta)?;
        let n = self.values.len();
        let u = x / self.step;
        let i = (u.floor() as usize).min(n - 2);
        let f = u - i as f64;
        Some(self.values[i] * (1.0 - f) + self.values[i + 1] * f)
    }

    /// This map on `points ≥ 2` grid points over the same range by linear interpolation, both
    /// ends kept and nothing wrapped (the two ends of a range are different readings); the mean
    /// of the new values is removed, as [`RangeMap::new`] does. `points < 2` is taken as 2.
    pub fn resample_linear(&self, points: usize) -> RangeMap {
        let n = points.max(2);
        if n == self.values.len() {
            return self.clone();
        }
        let v = &self.values;
        let last = v.len() - 1;
        let values = (0..n)
            .map(|i| {
                let x = i as f64 * last as f64 / (n - 1) as f64;
                let j = (x.floor() as usize).min(last - 1);
                let f = x - j as f64;
                v[j] + f * (v[j + 1] - v[j])
            })
            .collect();
        let mut map = RangeMap {
            start: self.start,
            step: self.span() / (n - 1) as f64,
            values,
        };
        let mean = map.values.iter().sum::<f64>() / n as f64;
        map.values.iter_mut().for_each(|v| *v -= mean);
        map
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

    /// Largest absolute value, arcseconds.
    pub fn max_abs_arcsec(&self) -> f64 {
        self.values.iter().fold(0.0f64, |m, v| m.max(v.abs())) * ARCSEC_PER_RAD
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolates_inside_and_refuses_outside() {
        let d = |deg: f64| deg.to_radians();
        // 330°…390° (crossing 0), 7 points 10° apart, values 0..6 before the mean (3) is removed.
        let m = RangeMap::new(d(-30.0), d(10.0), (0..7).map(f64::from).collect()).unwrap();
        assert!((m.start() - d(330.0)).abs() < 1e-12);
        assert!((m.end() - d(390.0)).abs() < 1e-12);
        assert!((m.eval_linear(d(335.0)).unwrap() + 2.5).abs() < 1e-9);
        assert!((m.eval_linear(d(5.0)).unwrap() - 0.5).abs() < 1e-9);
        assert!((m.eval_linear(d(30.0)).unwrap() - 3.0).abs() < 1e-9);
        assert!((m.eval_linear(d(-30.0)).unwrap() + 3.0).abs() < 1e-9);
        assert_eq!(m.eval_linear(d(31.0)), None);
        assert_eq!(m.eval_linear(d(329.0)), None);
        assert!(!m.contains(d(180.0)));
    }

    #[test]
    fn bad_grids_are_errors() {
        assert!(RangeMap::new(0.0, 0.1, vec![1.0]).is_err());
        assert!(RangeMap::new(0.0, -0.1, vec![1.0, 2.0]).is_err());
        assert!(RangeMap::new(0.0, 7.0, vec![1.0, 2.0]).is_err());
        assert!(RangeMap::new(f64::NAN, 0.1, vec![1.0, 2.0]).is_err());
    }
}
