//! Reference calibration from stationary points: a list of (DUT reading, reference reading)
//! pairs, one per stop of the shaft, in the order they were measured — a protractor or
//! autocollimator table, a rotary table stepped through ISO 230-2 targets, the MagAlpha tool's
//! input. No time: what a timed run gives by crossing grid points ([`crate::reference_cal`]),
//! a point list gives at its stops.
//!
//! # Method
//! At point `k` the error is `e_k = DUT_k − ref_k`, taken within ±180° of the first point's
//! difference (the constant between the two scales is removed with the map's mean). Points are
//! grouped into **targets**: points whose DUT readings lie within the target tolerance `τ` of
//! each other (chained, around the circle) are one target measured several times — ISO 230-2's
//! cycles. `τ` is [`PointOptions::target_tol`], by default a tenth of the median step between
//! consecutive points (a step smaller than that is a repeat, not a move).
//!
//! The **direction of approach** of a point is the sign of the step that brought the DUT there
//! (steps within `τ` do not count); a point reached without a step (the first point, or a
//! target measured again at a reversal — ISO 230-2's sequence `1…5, 5…1`) takes the direction
//! of the next step. Where the list states a point's direction ([`Approach`], a `direction`
//! column), that direction is taken instead: a stop reached by overshooting the target and coming
//! back to it was approached against the step from the previous stop, which the order of the
//! points cannot show. Per target and direction: `n` points, the mean `x̄↑`, `x̄↓` and standard
//! deviation `s`, as in [`crate::reference_cal`] (ISO 230-2:2014 §3, the same formulas and sign;
//! here the target positions are the points themselves, not chosen on a grid).
//!
//! # Map
//! The map is the mean bidirectional deviation `x̄_i` of each target, joined by straight lines
//! between neighbouring targets (nothing else is known between two stops) and sampled on the
//! table's grid, mean removed. It covers the whole turn when the targets go round it evenly:
//! no gap between neighbouring targets wider than twice their median spacing (with two targets,
//! twice the other gap's; or than the bridge gap, 5°); else the range from the first to the
//! last target, across the widest gap's far side. Nothing outside the targets is extrapolated.
//!
//! # Uncertainty
//! At a target, `u_i² = sem_i² + u_ref²` with the standard error of its mean as in
//! [`crate::reference_cal`] (a direction measured once uses its direction's pooled `s`). Where
//! no target was measured twice, `s` is estimated from the targets' scatter about the straight
//! line through their neighbours: `s = rms(x̄_i − lerp(x̄_{i−1}, x̄_{i+1}))/√1.5` (for
//! independent noise of deviation `s` on every target the residual's variance is at least
//! `1.5 s²`; the error's curvature only adds to it, so the estimate errs high). Between targets a
//! grid point carries the larger `u` of the two targets it is interpolated from.
//!
//! # What it cannot see
//! The error between two targets: the straight line between them misses every component of
//! period shorter than about twice their spacing (MagAlpha's 200 points see orders up to ~50),
//! and the reference's own error, as with any reference calibration.

use crate::TableMap;
use crate::angle::{wrap_2pi, wrap_pi};
use crate::error_map::ErrorMap;
use crate::range_map::RangeMap;
use crate::reference_cal::{
    PointStats, ReferenceCalibration, ReferenceError, TargetStats, iso_230_2,
};
use std::f64::consts::TAU;

/// Settings of a calibration from stationary points.
#[derive(Debug, Clone, PartialEq)]
pub struct PointOptions {
    /// Grid points of the map over a whole turn, ≥ 2 (a range map has as many per radian).
    pub points: usize,
    /// The reference's stated standard uncertainty, radians.
    pub reference_u: f64,
    /// Largest spread of one target's errors (all its points, both directions), radians; beyond
    /// it the reference is taken not to be on the DUT's shaft.
    pub follow_tol: f64,
    /// Gap between neighbouring targets, radians, that a whole turn may have whatever their
    /// spacing (see the module docs).
    pub max_gap: f64,
    /// Points whose DUT readings lie within this of each other are one target, radians;
    /// `None`: a tenth of the median step between consecutive points.
    pub target_tol: Option<f64>,
}

/// The direction a point was approached from, as a list states it: with increasing or with
/// decreasing DUT readings (ISO 230-2's ↑ and ↓).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Approach {
    /// The DUT's reading increased into the point.
    Increasing,
    /// The DUT's reading decreased into the point.
    Decreasing,
}

/// Why a calibration from points cannot be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PointError {
    /// As for a timed run.
    #[error(transparent)]
    Reference(#[from] ReferenceError),
    /// The difference of the readings changes between consecutive points by about as much as
    /// the DUT moves.
    #[error(
        "the reference does not follow the DUT: between consecutive points the difference of their \
         readings changes by {ratio:.2} times the DUT's step (the median of {steps} steps; an \
         encoder's error changes much less than its reading, at most {MAX_SLOPE} times it is \
         allowed). The reference counts the other way round (give the `ref_reversed` option), is in another \
         unit, or its rows are not paired with the DUT's"
    )]
    NotFollowing {
        /// The median of |Δ(DUT − ref)| / |ΔDUT| over the steps.
        ratio: f64,
        /// Steps it is the median of.
        steps: usize,
    },
}

/// The largest median change of the error per unit of the DUT's step between consecutive
/// points: an encoder whose error changed by more than half its reading's change would barely
/// count forward; a reference counting the other way round gives 2, one in radians against
/// degrees 0.98.
pub const MAX_SLOPE: f64 = 0.5;

impl Default for PointOptions {
    fn default() -> Self {
        PointOptions {
            points: 3600,
            reference_u: 0.0,
            follow_tol: 5f64.to_radians(),
            max_gap: 5f64.to_radians(),
            target_tol: None,
        }
    }
}

/// One target: where it is, and its points' errors per direction.
#[derive(Debug, Clone, Default)]
struct Target {
    /// DUT reading, radians: the anchor (first point's reading in `[0, 2π)`) plus the mean of
    /// the points' offsets from it.
    position: f64,
    up: Vec<f64>,
    down: Vec<f64>,
}

impl Target {
    fn bidirectional(&self) -> f64 {
        match (mean(&self.up), mean(&self.down)) {
            (Some(a), Some(b)) => 0.5 * (a + b),
            (a, b) => a.or(b).unwrap_or(0.0),
        }
    }
}

fn mean(x: &[f64]) -> Option<f64> {
    (!x.is_empty()).then(|| x.iter().sum::<f64>() / x.len() as f64)
}

/// ISO 230-2's statistics of one direction's errors, `offset` removed from the mean.
fn stats(x: &[f64], offset: f64) -> PointStats {
    let n = x.len();
    let m = mean(x).unwrap_or(0.0);
    PointStats {
        n: n as u32,
        mean: m - offset,
        s: (n >= 2)
            .then(|| (x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt()),
    }
}

/// The calibration of the DUT from `points` = `(DUT reading, reference reading)`, radians, in
/// the order they were measured (see the [module docs](self)), each point's direction of
/// approach taken from the order of the points.
pub fn calibrate_points(
    points: &[(f64, f64)],
    opts: &PointOptions,
) -> Result<ReferenceCalibration, PointError> {
    calibrate_points_with_directions(points, &[], opts)
}

/// As [`calibrate_points`], with the direction of approach of each point the list states:
/// `directions` is empty or holds one entry per point, `None` where the point's direction is to
/// be taken from the order of the points.
pub fn calibrate_points_with_directions(
    points: &[(f64, f64)],
    directions: &[Option<Approach>],
    opts: &PointOptions,
) -> Result<ReferenceCalibration, PointError> {
    if !directions.is_empty() && directions.len() != points.len() {
        return Err(ReferenceError::Options(format!(
            "{} directions of approach given for {} points; give one per point",
            directions.len(),
            points.len()
        ))
        .into());
    }
    if opts.points < 2 {
        return Err(ReferenceError::Options(format!(
            "the map needs at least 2 points, {} asked for",
            opts.points
        ))
        .into());
    }
    let too_few = |crossed| ReferenceError::TooLittleMotion {
        revolutions: 0.0,
        crossed,
    };
    let Some(&(dut0, ref0)) = points.first() else {
        return Err(too_few(0).into());
    };
    let c0 = dut0 - ref0;
    let errors: Vec<f64> = points.iter().map(|&(d, r)| wrap_pi(d - r - c0)).collect();
    let steps: Vec<f64> = points
        .windows(2)
        .map(|w| wrap_pi(w[1].0 - w[0].0))
        .collect();
    let travel: f64 = steps.iter().map(|s| s.abs()).sum();
    let reference_travel: f64 = points
        .windows(2)
        .map(|w| wrap_pi(w[1].1 - w[0].1).abs())
        .sum();
    let mut moves: Vec<f64> = steps.iter().map(|s| s.abs()).filter(|&s| s > 0.0).collect();
    if moves.is_empty() {
        return Err(too_few(1).into());
    }
    moves.sort_by(f64::total_cmp);
    let tol = opts.target_tol.unwrap_or(0.1 * moves[moves.len() / 2]);
    if reference_travel < 0.1 * travel {
        return Err(ReferenceError::ReferenceStill {
            reference_deg: reference_travel.to_degrees(),
            dut_deg: travel.to_degrees(),
        }
        .into());
    }

    // Direction of approach: the step into the point, else the next step that moves.
    let moving: Vec<Option<bool>> = steps
        .iter()
        .map(|&s| (s.abs() > tol).then_some(s > 0.0))
        .collect();
    let mut up = vec![true; points.len()];
    let mut next = None;
    for k in (0..points.len()).rev() {
        let into = if k > 0 { moving[k - 1] } else { None };
        up[k] = into.or(next).unwrap_or(true);
        if let Some(d) = into {
            next = Some(d);
        }
    }
    // A stated direction rules: the steps cannot show an approach from beyond the target.
    for (up, given) in up.iter_mut().zip(directions) {
        if let Some(given) = given {
            *up = *given == Approach::Increasing;
        }
    }

    let targets = group(points, &errors, &up, tol);
    if targets.len() < 2 {
        return Err(too_few(targets.len()).into());
    }
    for t in &targets {
        let (lo, hi) =
            t.up.iter()
                .chain(&t.down)
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &e| {
                    (lo.min(e), hi.max(e))
                });
        if hi - lo > opts.follow_tol {
            return Err(ReferenceError::NotRepeating {
                spread_deg: (hi - lo).to_degrees(),
                at_deg: t.position.to_degrees(),
                tol_deg: opts.follow_tol.to_degrees(),
            }
            .into());
        }
    }
    // Points met once each cannot repeat: the error's change from point to point must then be
    // small against the DUT's step.
    let mut slopes: Vec<f64> = steps
        .iter()
        .zip(errors.windows(2))
        .filter(|(s, _)| s.abs() > tol)
        .map(|(s, e)| wrap_pi(e[1] - e[0]).abs() / s.abs())
        .collect();
    slopes.sort_by(f64::total_cmp);
    if let Some(&ratio) = slopes.get(slopes.len() / 2)
        && ratio > MAX_SLOPE
    {
        return Err(PointError::NotFollowing {
            ratio,
            steps: slopes.len(),
        });
    }
    let repeat_spread = targets
        .iter()
        .filter(|t| t.up.len() + t.down.len() >= 2)
        .map(|t| {
            let all: Vec<f64> = t.up.iter().chain(&t.down).copied().collect();
            let (lo, hi) = all
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &e| {
                    (lo.min(e), hi.max(e))
                });
            hi - lo
        })
        .max_by(f64::total_cmp);

    // The targets in map order, positions unwrapped from the map's start; whole turn or range.
    let m = targets.len();
    let gaps: Vec<f64> = (0..m)
        .map(|i| {
            let next = if i + 1 < m {
                targets[i + 1].position
            } else {
                targets[0].position + TAU
            };
            next - targets[i].position
        })
        .collect();
    let (widest, &widest_gap) = gaps
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .unwrap_or((0, &0.0));
    let mut sorted_gaps = gaps.clone();
    sorted_gaps.sort_by(f64::total_cmp);
    // The spacing the widest gap is judged against: the median of all the gaps (the upper one
    // of an even count), but with two targets that is the widest gap itself, which would pass
    // any pair as a whole turn: there it is the other gap.
    let spacing = if m == 2 {
        sorted_gaps[0]
    } else {
        sorted_gaps[m / 2]
    };
    let whole_turn = widest_gap <= opts.max_gap.max(2.0 * spacing);
    let first = if whole_turn { 0 } else { (widest + 1) % m };
    let order: Vec<&Target> = (0..m).map(|j| &targets[(first + j) % m]).collect();
    let start = order[0].position;
    let x: Vec<f64> = order
        .iter()
        .map(|t| start + wrap_2pi(t.position - start))
        .collect();
    let means: Vec<f64> = order.iter().map(|t| t.bidirectional()).collect();

    // The grid.
    let (grid, step): (Vec<f64>, f64) = if whole_turn {
        let step = TAU / opts.points as f64;
        ((0..opts.points).map(|g| g as f64 * step).collect(), step)
    } else {
        let span = x[m - 1] - start;
        let len = ((span / (TAU / opts.points as f64)).round() as usize + 1).max(2);
        let step = span / (len - 1) as f64;
        ((0..len).map(|g| start + g as f64 * step).collect(), step)
    };
    let nodes: Vec<(f64, f64)> = x.iter().copied().zip(means.iter().copied()).collect();
    let raw: Vec<f64> = grid
        .iter()
        .map(|&a| lerp(&nodes, a, whole_turn).map_or(0.0, |(v, _, _)| v))
        .collect();
    let offset = raw.iter().sum::<f64>() / raw.len() as f64;

    // Uncertainty per target, then per grid point.
    let up_stats: Vec<PointStats> = order.iter().map(|t| stats(&t.up, offset)).collect();
    let down_stats: Vec<PointStats> = order.iter().map(|t| stats(&t.down, offset)).collect();
    let pooled = |p: &[PointStats]| {
        let (ss, dof) = p
            .iter()
            .filter_map(|p| p.s.map(|s| (p.n, s)))
            .fold((0.0, 0.0), |(ss, dof), (n, s)| {
                (ss + s * s * f64::from(n - 1), dof + f64::from(n - 1))
            });
        (dof > 0.0).then(|| (ss / dof).sqrt())
    };
    let scatter = scatter(&nodes, whole_turn);
    let (pool_up, pool_down) = (pooled(&up_stats), pooled(&down_stats));
    let no_repeatability = pool_up.is_none() && pool_down.is_none();
    let fallback = |pool: Option<f64>| pool.or(pool_up).or(pool_down).or(scatter);
    let sem2 = |p: &PointStats, pool: Option<f64>| {
        p.s.or(fallback(pool))
            .map_or(0.0, |s| s * s / f64::from(p.n))
    };
    let target_u: Vec<f64> = up_stats
        .iter()
        .zip(&down_stats)
        .map(|(a, b)| {
            let var = match (a.n, b.n) {
                (0, _) => sem2(b, pool_down),
                (_, 0) => sem2(a, pool_up),
                _ => (sem2(a, pool_up) + sem2(b, pool_down)) / 4.0,
            };
            (var + opts.reference_u.powi(2)).sqrt()
        })
        .collect();
    let u_nodes: Vec<(f64, f64)> = x.iter().copied().zip(target_u.iter().copied()).collect();
    let u: Vec<f64> = grid
        .iter()
        .map(|&a| {
            lerp(&u_nodes, a, whole_turn)
                .map_or(0.0, |(_, lo, hi)| u_nodes[lo].1.max(u_nodes[hi].1))
        })
        .collect();

    // Each direction's means on the grid, where that direction has targets on both sides.
    let side = |stats: &[PointStats]| -> Vec<PointStats> {
        let nodes: Vec<(f64, f64)> = x
            .iter()
            .zip(stats)
            .filter(|(_, p)| p.n > 0)
            .map(|(&x, p)| (x, p.mean))
            .collect();
        let counts: Vec<u32> = stats.iter().map(|p| p.n).filter(|&n| n > 0).collect();
        grid.iter()
            .map(|&a| match lerp(&nodes, a, whole_turn) {
                Some((v, lo, hi)) => PointStats {
                    n: counts[lo].min(counts[hi]),
                    mean: v,
                    s: None,
                },
                None => PointStats {
                    n: 0,
                    mean: 0.0,
                    s: None,
                },
            })
            .collect()
    };
    let (up_grid, down_grid) = (side(&up_stats), side(&down_stats));

    let map = if whole_turn {
        TableMap::Turn(ErrorMap::new(raw))
    } else {
        TableMap::Range(
            RangeMap::new(start, step, raw)
                .map_err(|e| PointError::from(ReferenceError::Options(e.to_string())))?,
        )
    };
    let target_stats: Vec<TargetStats> = order
        .iter()
        .zip(up_stats.iter().zip(&down_stats))
        .map(|(t, (&up, &down))| TargetStats {
            angle: wrap_2pi(t.position),
            up,
            down,
        })
        .collect();
    let iso = iso_230_2(&up_stats, &down_stats);
    let min_passes = |p: &[PointStats]| p.iter().map(|p| p.n).filter(|&n| n > 0).min().unwrap_or(0);
    let min_passes = (min_passes(&up_stats), min_passes(&down_stats));

    let mut warnings = Vec::new();
    if no_repeatability {
        warnings.push(format!(
            "no target was measured twice in one direction: u_arcsec holds the targets' scatter \
             about the straight line through their neighbours ({:.3}″, an estimate of one \
             reading's noise) instead of a repeatability; measure each target several times \
             (ISO 230-2: 5 cycles each way)",
            scatter.unwrap_or(0.0) * crate::angle::ARCSEC_PER_RAD
        ));
    }
    let (has_up, has_down) = (min_passes.0 > 0, min_passes.1 > 0);
    if has_up && has_down {
        let one_way = up_stats
            .iter()
            .zip(&down_stats)
            .filter(|(a, b)| (a.n == 0) != (b.n == 0))
            .count();
        if one_way == m {
            warnings.push(
                "every target was reached in one direction only, some increasing, some \
                 decreasing: the map joins deviations of both directions, so a reversal error \
                 shows as a zigzag between neighbouring targets; measure each target from both \
                 sides (or set the `target_tol` option if points meant as one target were kept apart)"
                    .to_string(),
            );
        } else if one_way > 0 {
            warnings.push(format!(
                "{one_way} of {m} targets were reached in one direction only, the others in both: \
                 the map mixes unidirectional and bidirectional means; measure every target in \
                 each direction (or set the `target_tol` option if points meant as one target were kept \
                 apart)"
            ));
        }
    }
    for (name, has, n) in [
        ("increasing", has_up, min_passes.0),
        ("decreasing", has_down, min_passes.1),
    ] {
        if has && n < 5 {
            warnings.push(format!(
                "only {n} measurement(s) at some targets with {name} readings; ISO 230-2 asks \
                 for 5 per direction"
            ));
        }
    }
    Ok(ReferenceCalibration {
        map,
        u,
        up: up_grid,
        down: down_grid,
        iso,
        targets: target_stats,
        revolutions: travel / TAU,
        min_passes,
        gap: None,
        pass_gaps: Vec::new(),
        repeat_spread,
        // Stationary points have no time: no lag between the channels to estimate.
        latency: None,
        ends: None,
        ripple: None,
        quantization: None,
        warnings,
        gear: None,
    })
}

/// The points grouped into targets: sorted round the circle, neighbours within `tol` chained
/// into one (across 0° too); sorted by position in `[0, 2π)`.
fn group(points: &[(f64, f64)], errors: &[f64], up: &[bool], tol: f64) -> Vec<Target> {
    let mut idx: Vec<usize> = (0..points.len()).collect();
    let pos = |k: usize| wrap_2pi(points[k].0);
    idx.sort_by(|&a, &b| pos(a).total_cmp(&pos(b)));
    let mut clusters: Vec<Vec<usize>> = Vec::new();
    for &k in &idx {
        match clusters.last_mut() {
            Some(c) if pos(k) - pos(c[c.len() - 1]) <= tol => c.push(k),
            _ => clusters.push(vec![k]),
        }
    }
    if clusters.len() > 1 {
        let (first, last) = (
            clusters[0][0],
            *clusters[clusters.len() - 1].last().unwrap_or(&0),
        );
        if pos(first) + TAU - pos(last) <= tol {
            let tail = clusters.pop().unwrap_or_default();
            clusters[0].extend(tail);
        }
    }
    let mut targets: Vec<Target> = clusters
        .into_iter()
        .map(|c| {
            let anchor = pos(c[0]);
            let offset = c.iter().map(|&k| wrap_pi(pos(k) - anchor)).sum::<f64>() / c.len() as f64;
            let mut t = Target {
                position: wrap_2pi(anchor + offset),
                ..Target::default()
            };
            // In measurement order within a direction.
            let mut members = c;
            members.sort_unstable();
            for k in members {
                if up[k] {
                    t.up.push(errors[k]);
                } else {
                    t.down.push(errors[k]);
                }
            }
            t
        })
        .collect();
    targets.sort_by(|a, b| a.position.total_cmp(&b.position));
    targets
}

/// The straight line through `nodes` (increasing `x`) at `a`, with the indices of the two
/// nodes it lies between; `periodic`: `a` and the nodes on the circle (the segment from the
/// last node to the first + 2π included). `None` outside the nodes of a non-periodic list.
fn lerp(nodes: &[(f64, f64)], a: f64, periodic: bool) -> Option<(f64, usize, usize)> {
    let n = nodes.len();
    if n == 0 {
        return None;
    }
    if n == 1 {
        return Some((nodes[0].1, 0, 0));
    }
    let a = if periodic {
        nodes[0].0 + wrap_2pi(a - nodes[0].0)
    } else {
        a
    };
    let eps = 1e-12;
    if !periodic && (a < nodes[0].0 - eps || a > nodes[n - 1].0 + eps) {
        return None;
    }
    let j = nodes.partition_point(|&(x, _)| x <= a);
    let (lo, hi) = match j {
        0 => (0, 0),
        j if j == n => {
            if periodic {
                (n - 1, 0)
            } else {
                (n - 1, n - 1)
            }
        }
        j => (j - 1, j),
    };
    let (x0, y0) = nodes[lo];
    let (mut x1, y1) = nodes[hi];
    if periodic && hi < lo {
        x1 += TAU;
    }
    if x1 <= x0 {
        return Some((y0, lo, hi));
    }
    let f = ((a - x0) / (x1 - x0)).clamp(0.0, 1.0);
    Some((y0 + f * (y1 - y0), lo, hi))
}

/// The noise of one target's mean estimated from the scatter about the straight line through
/// its neighbours (see the module docs); `None` with fewer than three targets.
fn scatter(nodes: &[(f64, f64)], periodic: bool) -> Option<f64> {
    let n = nodes.len();
    if n < 3 {
        return None;
    }
    let inner: Vec<usize> = if periodic {
        (0..n).collect()
    } else {
        (1..n - 1).collect()
    };
    let ss: f64 = inner
        .iter()
        .map(|&j| {
            let (p, q) = ((j + n - 1) % n, (j + 1) % n);
            let (xp, yp) = nodes[p];
            let (mut xq, yq) = nodes[q];
            let mut x = nodes[j].0;
            if periodic {
                let base = xp;
                x = base + wrap_2pi(x - base);
                xq = base + wrap_2pi(xq - base);
            }
            let f = if xq > xp { (x - xp) / (xq - xp) } else { 0.5 };
            (nodes[j].1 - (yp + f * (yq - yp))).powi(2)
        })
        .sum();
    Some((ss / inner.len() as f64 / 1.5).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    const ARCSEC: f64 = 1.0 / crate::angle::ARCSEC_PER_RAD;

    /// An ISO 230-2 sequence: `cycles` times up through `targets` then down, each point's
    /// reference reading = DUT − error(DUT) − (±backlash/2).
    fn iso_run(
        targets: &[f64],
        cycles: usize,
        error: impl Fn(f64, usize, bool) -> f64,
    ) -> Vec<(f64, f64)> {
        let mut p = Vec::new();
        for c in 0..cycles {
            for &t in targets {
                p.push((t, t - error(t, c, true)));
            }
            for &t in targets.iter().rev() {
                p.push((t, t - error(t, c, false)));
            }
        }
        p
    }

    #[test]
    fn iso_figures_of_a_hand_worked_set() {
        // Three targets 10°, 20°, 30°, two cycles each way; errors e (arcsec), by hand:
        //   target   ↑ cycle 1, 2   ↓ cycle 1, 2
        //   10°         2, 4          0, 0
        //   20°         6, 6          2, 4
        //   30°         1, 3          5, 5
        // x̄↑ = 3, 6, 2; x̄↓ = 0, 3, 5; s↑ = √2, 0, √2; s↓ = 0, √2, 0.
        // B_i = 3, 3, −3 → B = 3. x̄_i = 1.5, 4.5, 3.5 → M = 3.
        // E↑ = 6 − 2 = 4, E↓ = 5 − 0 = 5, E = 6 − 0 = 6.
        // R↑ = 4√2, R↓ = 4√2; R_i = max(2s↑ + 2s↓ + |B_i|, 4s↑, 4s↓) = 2√2 + 3 at every target.
        // A↑ = max(3+2√2, 6, 2+2√2) − min(3−2√2, 6, 2−2√2) = 6 − 2 + 2√2 = 4 + 2√2;
        // A↓ = max(0, 3+2√2, 5) − min(0, 3−2√2, 5) = 3 + 2√2; A = largest upper band end
        //   (6, at 20° ↑) − smallest lower one (2 − 2√2, at 30° ↑) = 4 + 2√2.
        let e = [
            [2.0, 4.0, 0.0, 0.0],
            [6.0, 6.0, 2.0, 4.0],
            [1.0, 3.0, 5.0, 5.0],
        ];
        let t = [10f64.to_radians(), 20f64.to_radians(), 30f64.to_radians()];
        let p = iso_run(&t, 2, |x, c, up| {
            let i = t.iter().position(|&y| y == x).unwrap();
            e[i][if up { c } else { 2 + c }] * ARCSEC
        });
        let cal = calibrate_points(&p, &PointOptions::default()).unwrap();
        let r2 = 2f64.sqrt();
        let iso: std::collections::BTreeMap<_, _> = cal.iso.arcsec().into_iter().collect();
        let want = [
            ("reversal", 3.0),
            ("mean_bidirectional", 3.0),
            ("systematic_up", 4.0),
            ("systematic_down", 5.0),
            ("systematic", 6.0),
            ("repeatability_up", 4.0 * r2),
            ("repeatability_down", 4.0 * r2),
            ("repeatability", 2.0 * r2 + 3.0),
            ("accuracy_up", 4.0 + 2.0 * r2),
            ("accuracy_down", 3.0 + 2.0 * r2),
            ("accuracy", 4.0 + 2.0 * r2),
        ];
        for (k, v) in want {
            // Sums of a few arcsec-sized values: exact to rounding (1e-9″).
            let got = iso[k].unwrap();
            assert!((got - v).abs() < 1e-9, "{k}: {got} vs {v}");
        }
        assert_eq!(cal.targets.len(), 3);
        assert_eq!(cal.min_passes, (2, 2));
        // A range over the three targets; the map is the bidirectional means, mean removed.
        let (lo, hi) = cal.map.range().unwrap();
        assert!((lo.to_degrees() - 10.0).abs() < 1e-9 && (hi.to_degrees() - 30.0).abs() < 1e-9);
        assert!((cal.map.peak_to_peak() / ARCSEC - 3.0).abs() < 1e-9);
    }

    #[test]
    fn stated_directions_rule_where_the_steps_mislead() {
        // The hand-worked set measured target by target, each from below and then from above
        // (overshoot, come back): ↑ then ↓ at 10°, the same at 20° and 30°, two cycles. The
        // step into each ↓ point is zero, so the order of the points calls it ↑ (the next step
        // goes up): both of a target's points land in one direction and the reversal vanishes.
        // Stated, the directions give the hand-worked figures exactly.
        let e = [
            [2.0, 4.0, 0.0, 0.0],
            [6.0, 6.0, 2.0, 4.0],
            [1.0, 3.0, 5.0, 5.0],
        ];
        let t = [10f64.to_radians(), 20f64.to_radians(), 30f64.to_radians()];
        let mut p = Vec::new();
        let mut given = Vec::new();
        for c in 0..2 {
            for (i, &x) in t.iter().enumerate() {
                p.push((x, x - e[i][c] * ARCSEC));
                given.push(Some(Approach::Increasing));
                p.push((x, x - e[i][2 + c] * ARCSEC));
                given.push(Some(Approach::Decreasing));
            }
        }
        let iso = |cal: &ReferenceCalibration| -> std::collections::BTreeMap<_, _> {
            cal.iso.arcsec().into_iter().collect()
        };
        let by_order = calibrate_points(&p, &PointOptions::default()).unwrap();
        let at_20 = &by_order.targets[1];
        assert_eq!((at_20.up.n, at_20.down.n), (4, 0), "the order alone");
        assert!(
            by_order
                .warnings
                .iter()
                .any(|w| w.contains("one direction"))
        );

        let cal = calibrate_points_with_directions(&p, &given, &PointOptions::default()).unwrap();
        let got = iso(&cal);
        let r2 = 2f64.sqrt();
        for (k, v) in [
            ("reversal", 3.0),
            ("mean_bidirectional", 3.0),
            ("systematic", 6.0),
            ("repeatability", 2.0 * r2 + 3.0),
            ("accuracy", 4.0 + 2.0 * r2),
        ] {
            // The same sums as the hand-worked set: exact to rounding.
            let g = got[k].unwrap();
            assert!((g - v).abs() < 1e-9, "{k}: {g} vs {v}");
        }
        assert_eq!(cal.min_passes, (2, 2));
        assert!(cal.warnings.iter().all(|w| !w.contains("one direction")));

        // Only the misleading points stated (each ↓ point, and the 10° ↑ point reached from
        // 30° at a cycle's start), the rest from the order: the same figures.
        let partial: Vec<Option<Approach>> = given
            .iter()
            .enumerate()
            .map(|(k, &d)| d.filter(|&d| d == Approach::Decreasing || k % 6 == 0))
            .collect();
        let cal = calibrate_points_with_directions(&p, &partial, &PointOptions::default()).unwrap();
        assert_eq!(iso(&cal), got);

        assert!(matches!(
            calibrate_points_with_directions(&p, &given[1..], &PointOptions::default()),
            Err(PointError::Reference(ReferenceError::Options(_)))
        ));
    }

    /// Two targets 10° apart measured 3 times each way: the table is the range between them
    /// (the straight line joining their means), not a whole turn whose 350° were never
    /// measured. Two targets half a turn apart go round it evenly: a whole turn.
    #[test]
    fn two_targets_give_a_range() {
        let t = [10f64.to_radians(), 20f64.to_radians()];
        let e = |x: f64| 20.0 * ARCSEC * (x * 3.0).sin();
        let p = iso_run(&t, 3, |x, _, _| e(x));
        let cal = calibrate_points(&p, &PointOptions::default()).unwrap();
        let TableMap::Range(m) = &cal.map else {
            panic!("two targets 10° apart gave a whole turn")
        };
        assert!(
            (m.start() - t[0]).abs() < 1e-12,
            "{}",
            m.start().to_degrees()
        );
        assert!((m.end() - t[1]).abs() < 1e-9, "{}", m.end().to_degrees());
        // 10° at the default 0.1° grid: 101 points, from one target's mean to the other's.
        assert_eq!(m.len(), 101);
        let half = [0.0, 180f64.to_radians()];
        let cal = calibrate_points(&iso_run(&half, 3, |x, _, _| e(x)), &PointOptions::default());
        assert!(matches!(cal.unwrap().map, TableMap::Turn(_)));
    }

    #[test]
    fn a_whole_turn_list_recovers_its_harmonics() {
        // 200 points round a turn, one pass, error 3.5° cos 2θ: the straight lines between points
        // 1.8° apart miss (2·1.8°)²/8 = 0.002 of the amplitude at order 2 (the chord's sag).
        let n = 200;
        let p: Vec<(f64, f64)> = (0..n)
            .map(|k| {
                let dut = (k as f64 + 0.3) * TAU / n as f64;
                let e = 3.5f64.to_radians() * (2.0 * dut).cos();
                (dut, wrap_2pi(dut - e + 1.0))
            })
            .collect();
        let cal = calibrate_points(&p, &PointOptions::default()).unwrap();
        assert!(matches!(cal.map, TableMap::Turn(_)));
        let pp = cal.map.peak_to_peak().to_degrees();
        assert!((pp - 7.0).abs() < 0.02, "p-p {pp}°");
        assert!(cal.warnings.iter().any(|w| w.contains("measured twice")));
    }

    #[test]
    fn a_reference_on_another_shaft_is_refused() {
        let t: Vec<f64> = (0..5).map(|i| (10.0 * i as f64).to_radians()).collect();
        let p = iso_run(
            &t,
            3,
            |x, c, _| if c == 1 { 10f64.to_radians() + x } else { 0.0 },
        );
        assert!(matches!(
            calibrate_points(&p, &PointOptions::default()),
            Err(PointError::Reference(ReferenceError::NotRepeating { .. }))
        ));
        // Met once each, a reference counting the other way round changes the difference by
        // twice the DUT's step.
        let p: Vec<(f64, f64)> = (0..20)
            .map(|k| {
                let a = (5.0 * k as f64).to_radians();
                (a, -a)
            })
            .collect();
        match calibrate_points(&p, &PointOptions::default()) {
            Err(PointError::NotFollowing { ratio, steps }) => {
                assert!((ratio - 2.0).abs() < 1e-9 && steps == 19, "{ratio} {steps}");
            }
            other => panic!("{other:?}"),
        }
    }
}
