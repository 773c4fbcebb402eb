//! Points measured in one direction only (the ends of a swept range, where the approach after
//! each reversal leaves one direction), corrected to the bidirectional mean.
//!
//! # Method
//! The map is the mean bidirectional deviation `x̄_i = (x̄_i↑ + x̄_i↓)/2 = x̄_i↑ − B_i/2 =
//! x̄_i↓ + B_i/2` (ISO 230-2, `B_i = x̄_i↑ − x̄_i↓` the reversal). Where only `x̄_i↑` (or `x̄_i↓`)
//! exists, `B_i` is taken from the [`NEIGHBOURS`] nearest points where both directions were
//! measured: their mean `B̄`, so the point becomes `x̄_i↑ − B̄/2` (or `x̄_i↓ + B̄/2`). The
//! correction's standard uncertainty is half of `sqrt(s_B²·(1 + 1/K) + ū_B²)`: `s_B` the spread
//! of those `K` reversals (how much the reversal changes along the axis, the extrapolation's
//! risk), `ū_B` their mean standard error.
//!
//! # What it cannot see
//! A reversal that changes abruptly within the last few points measured one way.

/// How many of the nearest bidirectional points give the reversal at a unidirectional one.
pub const NEIGHBOURS: usize = 20;

/// What was done at the points measured in one direction only.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EndCorrection {
    /// Points corrected.
    pub points: usize,
    /// The largest |half reversal| applied, radians.
    pub max_correction: f64,
    /// The largest standard uncertainty of the correction, radians.
    pub max_u: f64,
}

/// One map point: mean and squared standard error per direction (`None` where the direction
/// has no pass).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Directions {
    pub(super) up: Option<(f64, f64)>,
    pub(super) down: Option<(f64, f64)>,
}

/// The correction `(value to add to the one-direction mean, its standard uncertainty)` of each
/// point measured in one direction only, `None` at the others and everywhere if no point has
/// both directions. `circular`: the points are a whole turn (distances wrap).
pub(super) fn corrections(points: &[Directions], circular: bool) -> Vec<Option<(f64, f64)>> {
    let n = points.len();
    let both: Vec<(usize, f64, f64)> = points
        .iter()
        .enumerate()
        .filter_map(|(i, p)| match (p.up, p.down) {
            (Some((a, ua)), Some((b, ub))) => Some((i, a - b, ua + ub)),
            _ => None,
        })
        .collect();
    if both.is_empty() {
        return vec![None; n];
    }
    let distance = |i: usize, j: usize| {
        let d = i.abs_diff(j);
        if circular { d.min(n - d) } else { d }
    };
    points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let sign = match (p.up, p.down) {
                (Some(_), None) => -1.0,
                (None, Some(_)) => 1.0,
                _ => return None,
            };
            let mut near: Vec<&(usize, f64, f64)> = both.iter().collect();
            near.sort_by_key(|b| distance(i, b.0));
            near.truncate(NEIGHBOURS);
            let k = near.len() as f64;
            let mean = near.iter().map(|b| b.1).sum::<f64>() / k;
            let spread2 = if near.len() >= 2 {
                near.iter().map(|b| (b.1 - mean).powi(2)).sum::<f64>() / (k - 1.0)
            } else {
                mean * mean
            };
            let sem2 = near.iter().map(|b| b.2).sum::<f64>() / k;
            let u = 0.5 * (spread2 * (1.0 + 1.0 / k) + sem2).sqrt();
            Some((sign * 0.5 * mean, u))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_direction_points_get_half_the_reversal_next_to_them() {
        // A reversal of 2 (up − down), the ends measured one way.
        let p = |up: bool, down: bool| Directions {
            up: up.then_some((1.0, 0.0)),
            down: down.then_some((-1.0, 0.0)),
        };
        let points = [p(false, true), p(true, true), p(true, true), p(true, false)];
        let c = corrections(&points, false);
        assert_eq!(c[0], Some((1.0, 0.0)));
        assert_eq!(c[1], None);
        assert_eq!(c[3], Some((-1.0, 0.0)));
        // Nothing bidirectional: nothing to correct with.
        assert!(
            corrections(&[p(true, false), p(true, false)], false)
                .iter()
                .all(Option::is_none)
        );
    }
}
