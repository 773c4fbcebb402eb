//! A map over a whole turn or over a range: what a correction table holds, whatever the method

use crate::{ErrorMap, RangeMap};

/// A calibrated map: over a whole turn, or over the range of readings the run covered.
///
/// that made it.
///
/// Most calibrations give an [`ErrorMap`] over a whole revolution; a joint that never turns a
/// whole revolution gives a [`RangeMap`] over the readings it covered. [`TableMap`] is either,
/// and is the one type that tables, `calib apply`, `calib export`, `calib compose` and the
/// reports take, so each of them handles both kinds in one place.
///
/// # Degrees of the grid
/// Tables are written in degrees, and a table read back must give the same grid: a whole turn's
/// point `i` of `N` is at `i·360/N`, a range's at `LO + i·(HI − LO)/(N − 1)` with `LO…HI` its
/// ends in the sensor's reading convention ([`RangeMap::ends_deg`]). [`TableMap::grid_deg`]
/// computes them so, not by converting radians, so the same map always prints the same angles.
#[derive(Debug, Clone, PartialEq)]
pub enum TableMap {
    /// A whole revolution.
    Turn(ErrorMap),
    /// Part of a revolution: the sensor never covered a whole turn.
    Range(RangeMap),
}

impl From<ErrorMap> for TableMap {
    fn from(map: ErrorMap) -> Self {
        TableMap::Turn(map)
    }
}

impl From<RangeMap> for TableMap {
    fn from(map: RangeMap) -> Self {
        TableMap::Range(map)
    }
}

impl TableMap {
    /// The values on the grid, radians.
    pub fn values(&self) -> &[f64] {
        match self {
            TableMap::Turn(m) => m.values(),
            TableMap::Range(m) => m.values(),
        }
    }
    /// Number of grid points.
    pub fn len(&self) -> usize {
        self.values().len()
    }
    /// Always false: a map has at least one point.
    pub fn is_empty(&self) -> bool {
        false
    }
    /// Grid angle of point `i`, radians.
    pub fn grid_angle(&self, i: usize) -> f64 {
        match self {
            TableMap::Turn(m) => m.grid_angle(i),
            TableMap::Range(m) => m.grid_angle(i),
        }
    }
    /// Grid angle of point `i` of `n` spread over this map's turn or range, degrees (see
    /// [Degrees of the grid](TableMap#degrees-of-the-grid)); `n = len()` gives the map's own grid.
    pub fn grid_deg(&self, i: usize, n: usize) -> f64 {
        match self {
            TableMap::Turn(_) => 360.0 * i as f64 / n as f64,
            TableMap::Range(m) => {
                let (lo, hi) = m.ends_deg();
                lo + (hi - lo) * i as f64 / (n - 1).max(1) as f64
            }
        }
    }
    /// Spacing of `n` points over this map's turn or range, degrees: `360/n`, or
    /// `(HI − LO)/(n − 1)` for a range.
    pub fn step_deg(&self, n: usize) -> f64 {
        match self {
            TableMap::Turn(_) => 360.0 / n as f64,
            TableMap::Range(m) => {
                let (lo, hi) = m.ends_deg();
                (hi - lo) / (n - 1).max(1) as f64
            }
        }
    }
    /// The ends `(LO, HI)` of a range map in degrees of the reading (signed if it crosses 0,
    /// [`RangeMap::ends_deg`]); `None` for a whole turn.
    pub fn range_deg(&self) -> Option<(f64, f64)> {
        match self {
            TableMap::Turn(_) => None,
            TableMap::Range(m) => Some(m.ends_deg()),
        }
    }
    /// The range `(start, end)`, radians, of a range map; `None` for a whole turn.
    pub fn range(&self) -> Option<(f64, f64)> {
        match self {
            TableMap::Turn(_) => None,
            TableMap::Range(m) => Some((m.start(), m.end())),
        }
    }
    /// The whole-turn map, if this is one.
    pub fn turn(&self) -> Option<&ErrorMap> {
        match self {
            TableMap::Turn(m) => Some(m),
            TableMap::Range(_) => None,
        }
    }
    /// Linear interpolation at the reading `theta` (radians, any revolution): periodic over a
    /// whole turn; inside a range only, `None` outside it (never extrapolated).
    pub fn eval_linear(&self, theta: f64) -> Option<f64> {
        match self {
            TableMap::Turn(m) => Some(m.eval_linear(theta)),
            TableMap::Range(m) => m.eval_linear(theta),
        }
    }
    /// This map on `points` grid points by linear interpolation: periodic over a whole turn
    /// ([`ErrorMap::resample_linear`]), over a range with both ends kept
    /// ([`RangeMap::resample_linear`]).
    pub fn resample(&self, points: usize) -> TableMap {
        match self {
            TableMap::Turn(m) if points == m.len() => self.clone(),
            TableMap::Turn(m) => TableMap::Turn(m.resample_linear(points)),
            TableMap::Range(m) => TableMap::Range(m.resample_linear(points)),
        }
    }
    /// Peak-to-peak value, radians.
    pub fn peak_to_peak(&self) -> f64 {
        match self {
            TableMap::Turn(m) => m.peak_to_peak(),
            TableMap::Range(m) => m.peak_to_peak(),
        }
    }
    /// Root mean square, radians.
    pub fn rms(&self) -> f64 {
        match self {
            TableMap::Turn(m) => m.rms(),
            TableMap::Range(m) => m.rms(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_range_resampled_keeps_its_ends_and_its_line() {
        let d = |deg: f64| deg.to_radians();
        // −30°…30° in 7 points, a straight line: any resampling lies on the same line.
        let m = RangeMap::new(d(-30.0), d(10.0), (0..7).map(f64::from).collect()).unwrap();
        let map = TableMap::Range(m);
        let fine = map.resample(13);
        assert_eq!(fine.len(), 13);
        assert_eq!(fine.range_deg(), map.range_deg());
        assert!((fine.grid_deg(12, 13) - 30.0).abs() < 1e-9);
        for (i, v) in fine.values().iter().enumerate() {
            assert!((v - (i as f64 / 2.0 - 3.0)).abs() < 1e-12, "point {i}: {v}");
        }
        assert_eq!(map.resample(7), map);
    }

    #[test]
    fn a_whole_turn_interpolates_periodically_and_a_range_only_inside() {
        let turn = TableMap::from(ErrorMap::new(vec![1.0, -1.0]));
        assert_eq!(turn.eval_linear(-std::f64::consts::FRAC_PI_2), Some(0.0));
        assert_eq!(turn.grid_deg(1, 2), 180.0);
        assert_eq!(turn.range_deg(), None);
        let range = TableMap::from(RangeMap::new(0.0, 0.1, vec![1.0, -1.0]).unwrap());
        assert_eq!(range.eval_linear(0.05), Some(0.0));
        assert_eq!(range.eval_linear(1.0), None);
        assert!(range.turn().is_none());
    }
}
