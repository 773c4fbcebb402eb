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
    points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let sign = match (p.up, p.down) {
                (Some(_), None) => -1.0,
                (None, Some(_)) => 1.0,
                _ => return None,
            };
            let near = nearest(&both, i, n, circular);
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

/// The [`NEIGHBOURS`] points of `both` (in index order) nearest to point `i` of `n`, nearest
/// first, ties in index order. Only the [`NEIGHBOURS`] on either side of `i` can be among them
/// (any other has that many nearer on its side), so each point costs `O(log m + NEIGHBOURS)`
/// of the `m` in `both`: sorting all of them for every point made a table of a million points
/// from a dump take a minute.
fn nearest(
    both: &[(usize, f64, f64)],
    i: usize,
    n: usize,
    circular: bool,
) -> Vec<&(usize, f64, f64)> {
    let distance = |j: usize| {
        let d = i.abs_diff(j);
        if circular { d.min(n - d) } else { d }
    };
    let mut near = candidates(both, i, circular);
    near.sort_by_key(|b| (distance(b.0), b.0));
    near.truncate(NEIGHBOURS);
    near
}

/// The points of `both` that can be among the [`NEIGHBOURS`] nearest to point `i`: all of
/// them if there are at most twice as many, else that many on either side (round the turn if
/// `circular`).
fn candidates(both: &[(usize, f64, f64)], i: usize, circular: bool) -> Vec<&(usize, f64, f64)> {
    let m = both.len();
    let after = both.partition_point(|b| b.0 < i);
    if m <= 2 * NEIGHBOURS {
        both.iter().collect()
    } else if circular {
        // The NEIGHBOURS before `i` and as many from it on, round the turn; distinct as m > 2K.
        (0..2 * NEIGHBOURS)
            .map(|k| &both[(after + m + k - NEIGHBOURS) % m])
            .collect()
    } else {
        both[after.saturating_sub(NEIGHBOURS)..(after + NEIGHBOURS).min(m)]
            .iter()
            .collect()
    }
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

    /// Every point's neighbours are those of a sort of all the bidirectional points by distance
    /// (ties in index order, as the stable sort this replaced), on a turn and on a range, and
    /// no more than 2·NEIGHBOURS of them are looked at for any point.
    #[test]
    fn nearest_matches_a_full_sort_and_looks_at_few() {
        let n = 500;
        // Bidirectional at a scattered third of the points.
        let both: Vec<(usize, f64, f64)> = (0..n)
            .filter(|i| (i * 7919) % 3 == 0 && !(100..180).contains(i))
            .map(|i| (i, i as f64, 0.0))
            .collect();
        for circular in [true, false] {
            for i in (0..n).filter(|i| !both.iter().any(|b| b.0 == *i)) {
                let distance = |j: usize| {
                    let d = i.abs_diff(j);
                    if circular { d.min(n - d) } else { d }
                };
                let mut all: Vec<&(usize, f64, f64)> = both.iter().collect();
                all.sort_by_key(|b| distance(b.0));
                all.truncate(NEIGHBOURS);
                assert_eq!(nearest(&both, i, n, circular), all, "point {i}");
            }
        }
        // Few bidirectional points: all of them, nearest first.
        let few = [(3, 0.0, 0.0), (9, 0.0, 0.0)];
        let got: Vec<usize> = nearest(&few, 8, 10, true).iter().map(|b| b.0).collect();
        assert_eq!(got, [9, 3]);
        // Many: never more than 2·NEIGHBOURS looked at, wherever the point.
        let many: Vec<(usize, f64, f64)> = (0..100_000).step_by(2).map(|i| (i, 0.0, 0.0)).collect();
        for i in [1, 50_001, 99_999] {
            for circular in [true, false] {
                assert!(candidates(&many, i, circular).len() <= 2 * NEIGHBOURS);
            }
        }
    }
}
