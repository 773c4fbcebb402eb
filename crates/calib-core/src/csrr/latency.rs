//! A constant lag between the two sensors' samples: found from the sessions and removed.
//!
//! # Model
//! If B's sample stamped `t` was taken at `t − τ` (an SSI/BiSS master, a CAN encoder, a
//! resolver terminal: 1–50 ms are common), the relative angle `d = x − y` carries `τ·ω(t)` to
//! first order. At a constant speed that is a constant and only moves a session's relative
//! rotation `Δ_k`, which the method solves for anyway; wherever the speed changes within a
//! session (its ramps, a speed ripple) `d` changes by `τ·Δω`, which no pair of maps can hold: 2 ms
//! at 60 r/min is 2592″ between rest and speed. The segmenter measures `τ` free of the maps, from
//! each block's departure from one revolution earlier against its change of speed
//! ([`crate::segment::LatencyEstimate`]).
//!
//! # Removal
//! B's readings are moved to A's instants: the sample stamped `t` takes B's reading interpolated
//! in time at `t + τ` by a cubic through the two readings on each side (`TimeShift`), which
//! holds the second-order terms the first-order model leaves (`½τ²·α` at an acceleration `α`).
//! A straight line between two readings would not do: it errs by `α·h²/8` for a step `h`, 16″
//! at 200 Hz in a ramp of 25 rad/s²; the cubic is exact for a constant acceleration. With the lag unknown
//! ([`Latency::Auto`]) the log is calibrated, the lag the sessions still show is added to the
//! shift and the log is read again, until what is left is not significant ([`significant`]), is
//! no smaller than what the reading before left (the shift no longer acts on it), or after
//! [`MAX_PASSES`] readings; the first-order estimate falls short of a large lag (a 20 ms
//! lag reads as 14 ms on the first pass, where it also cuts sessions at their ramps), and each
//! pass takes most of what is left.
//!
//! # What it cannot see
//! A lag that changes during the run; a lag at a perfectly constant speed (then it changes
//! nothing either). The reference channel (`push_with_reference`) is compared with B as
//! recorded, not shifted.

use super::{Calibration, Csrr, CsrrError, CsrrOptions};
use crate::angle::Unwrapper;
use crate::segment::LatencyEstimate;
use crate::uncertainty::{Evaluation, MapComponent, MapUncertainty};
use std::collections::VecDeque;

/// How the lag is handled, as in the reference method: [`Latency::Auto`] finds it from the
/// sessions and removes it where significant; [`Latency::Fixed`] removes B's lag behind A as
/// given (0: none, and only a warning where the sessions show one).
pub use crate::reference_cal::Latency;

/// Readings of the log at most: the first and up to four corrections (a 20 ms lag at 60 r/min
/// takes four: 14 ms, then 19.9, 20.0000, 20.00001).
pub const MAX_PASSES: usize = 5;

/// The name of the lag's term in the maps' uncertainty budget.
pub const LAG_TERM: &str = "lag between the channels, removed: u(τ) × RMS speed change";

/// What was done about the lag, and what the sessions show of it after.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LatencyOutcome {
    /// How the lag was set.
    pub mode: Latency,
    /// The lag removed (B's samples moved this much later), seconds.
    pub applied: f64,
    /// Its standard uncertainty, seconds: the last pass's `u(τ)` (what is left is known to
    /// that); `None` where nothing was estimated.
    pub u_applied: Option<f64>,
    /// What the sessions still show after the shift (the last pass's estimate).
    pub left: Option<LatencyEstimate>,
    /// Readings of the log.
    pub passes: usize,
}

impl LatencyOutcome {
    /// Whether a lag the sessions show is left in the result (given 0, or auto that ran out of
    /// passes) and matters ([`matters`]).
    pub fn left_significant(&self) -> bool {
        self.left
            .as_ref()
            .is_some_and(|e| significant(e) && matters(e))
    }
}

/// Whether the sessions show a lag: more than 3 u from 0. `auto` reads the log again while they
/// do: a lag moves the maps by about a third of `τ` times the top speed (1 µs at 60 r/min:
/// 0.4″), so even one the noise of a sample hides shows in the maps.
pub fn significant(e: &LatencyEstimate) -> bool {
    e.tau.abs() > 3.0 * e.u_tau
}

/// Whether a lag is worth a warning: it moves `d` by more than the noise of a sample between
/// rest and the run's top speed.
pub fn matters(e: &LatencyEstimate) -> bool {
    e.tau.abs() * e.max_speed > e.noise
}

/// Calibrates with the lag handled as `latency` says. `feed` pushes every sample of the log
/// into the calibration it is given, and is called once per reading of the log (at most
/// [`MAX_PASSES`]); its error ends the calibration.
pub fn calibrate<E>(
    opts: &CsrrOptions,
    latency: Latency,
    mut feed: impl FnMut(&mut Csrr) -> Result<(), E>,
) -> Result<Result<Calibration, CsrrError>, E> {
    let mut applied = match latency {
        Latency::Auto => 0.0,
        Latency::Fixed(tau) => tau,
    };
    let mut passes = 0;
    // |τ| left after the last reading: a reading that leaves no less will not converge.
    let mut last_left = f64::INFINITY;
    loop {
        passes += 1;
        let mut csrr = Csrr::new(CsrrOptions {
            latency_s: applied,
            ..opts.clone()
        });
        feed(&mut csrr)?;
        // A large lag can make the solve fail: the lag is read again with it removed first,
        // and a reading that is read again is not solved.
        let (left, segmented) = csrr.segment();
        let again = latency == Latency::Auto
            && passes < MAX_PASSES
            && left
                .as_ref()
                .is_some_and(|e| significant(e) && e.tau.abs() < last_left);
        if let (true, Some(left)) = (again, left) {
            applied += left.tau;
            last_left = left.tau.abs();
            continue;
        }
        let mut cal = match (
            segmented.solve(),
            left.filter(|e| significant(e) && matters(e)),
        ) {
            (Ok(cal), _) => cal,
            (Err(e), None) => return Ok(Err(e)),
            (Err(e), Some(lag)) => {
                let (older, newer) = if lag.tau > 0.0 {
                    ("B's", "A's")
                } else {
                    ("A's", "B's")
                };
                return Ok(Err(CsrrError::Lag {
                    older,
                    newer,
                    lag_ms: lag.tau.abs() * 1e3,
                    u_ms: lag.u_tau * 1e3,
                    given_ms: applied * 1e3,
                    cause: Box::new(e),
                }));
            }
        };
        let outcome = LatencyOutcome {
            mode: latency,
            applied,
            u_applied: left.map(|l| l.u_tau),
            left,
            passes,
        };
        if let Some(w) = warning(&outcome) {
            cal.warnings.push(w);
        }
        if let (true, Some(left)) = (applied != 0.0, left) {
            add_lag_term(&mut cal, left.u_tau * left.speed_change_rms);
        }
        cal.latency = Some(outcome);
        return Ok(Ok(cal));
    }
}

/// Adds the removed lag's uncertainty to both maps' budgets: what is left of `τ`, `u(τ)`,
/// moves `d` by `u(τ)·Δω` where the speed changes by `Δω`; over the run that is `u(τ)` times the
/// RMS speed change, radians, at every point (Type A: from the sessions' scatter).
fn add_lag_term(cal: &mut Calibration, u: f64) {
    if let Some((ua, ub)) = &mut cal.uncertainty {
        for map in [ua, ub] {
            let mut components = std::mem::take(&mut map.components);
            components.push(MapComponent {
                name: LAG_TERM.to_string(),
                evaluation: Evaluation::TypeA,
                u: vec![u],
            });
            *map = MapUncertainty::combine(map.u.len(), components);
        }
    }
}

/// The warning for a lag left in the result.
fn warning(o: &LatencyOutcome) -> Option<String> {
    let left = o.left.filter(|e| significant(e) && matters(e))?;
    let ms = |s: f64| s * 1e3;
    let effect = (left.tau * left.max_speed).abs() * crate::angle::ARCSEC_PER_RAD;
    let who = if left.tau > 0.0 {
        "B's samples are older than A's"
    } else {
        "A's samples are older than B's"
    };
    let done = match o.mode {
        Latency::Fixed(0.0) => {
            "not removed (the `latency` option is 0); leave it at auto to remove it".to_string()
        }
        Latency::Fixed(t) => format!(
            "left after removing the {:.3} ms given; leave the `latency` option at auto",
            ms(t)
        ),
        Latency::Auto => format!(
            "left after {} readings of the log that removed {:.3} ms",
            o.passes,
            ms(o.applied)
        ),
    };
    Some(format!(
        "{who} by {:.3} ms (u {:.3} ms), {done}: between rest and {:.1}°/s it moves `a − b` by \
         {effect:.1}″, which no pair of maps can hold where the speed changes within a session, \
         so the maps and their u may be off by as much",
        ms(left.tau.abs()),
        ms(left.u_tau),
        left.max_speed.to_degrees()
    ))
}

/// B's readings moved to A's instants: the sample stamped `t` gets B's reading at `t + τ`
/// (unwrapped), by the cubic through the two readings before it and the two after it (the
/// Lagrange form), or the straight line between the two around it where there are no more
/// (at the ends of the log, next to a gap). A sample whose `t + τ` lies before the log, beyond
/// its end, or in a gap (two samples further apart than [`GAP_FACTOR`] times the step before
/// them) is dropped and counted.
///
/// Time is counted from the first sample's inside: stamps since 1970 (a ROS 2 bag's) are
/// ~1.7·10⁹ s, whose doubles are 2.4·10⁻⁷ s apart, so `t + τ` could not move by a lag of a
/// few nanoseconds; their differences from the first stamp are exact.
#[derive(Debug)]
pub(super) struct TimeShift {
    tau: f64,
    /// The first sample's time.
    origin: Option<f64>,
    unwrap: Unwrapper,
    /// B's readings `(t − origin, y unwrapped)` from a little before the oldest pending
    /// `t − origin + τ`.
    b: VecDeque<(f64, f64)>,
    /// Samples waiting for B's reading at `t + τ`: `(t, x, mark, extra)`.
    pending: VecDeque<(f64, f64, Option<u32>, Vec<f64>)>,
    dropped: u64,
}

/// Two samples further apart than this many times the step before them are a gap, across which
/// B's reading is not interpolated.
pub(super) const GAP_FACTOR: f64 = 4.0;

impl TimeShift {
    pub(super) fn new(tau: f64) -> Self {
        TimeShift {
            tau,
            origin: None,
            unwrap: Unwrapper::new(),
            b: VecDeque::new(),
            pending: VecDeque::new(),
            dropped: 0,
        }
    }

    /// Takes one sample; hands `emit(t, x, y, mark, extra)` every sample whose shifted reading
    /// is now known.
    pub(super) fn push(
        &mut self,
        (t, x, y, mark, extra): (f64, f64, f64, Option<u32>, &[f64]),
        mut emit: impl FnMut(f64, f64, f64, Option<u32>, &[f64]),
    ) {
        let yu = self.unwrap.unwrap(y);
        let origin = *self.origin.get_or_insert(t);
        self.b.push_back((t - origin, yu));
        self.pending.push_back((t, x, mark, extra.to_vec()));
        while let Some(&(tp, _, _, _)) = self.pending.front() {
            let target = (tp - origin) + self.tau;
            // Two readings at or after the target: the cubic's right-hand pair.
            let after = self
                .b
                .iter()
                .rev()
                .take_while(|&&(tb, _)| tb >= target)
                .count();
            if after < 2 {
                break;
            }
            let (tp, xp, mp, ep) = self.pending.pop_front().expect("front exists");
            match self.at(target) {
                Some(yp) => emit(tp, xp, yp, mp, &ep),
                None => self.dropped += 1,
            }
        }
        // Keep one reading before the oldest target still to come.
        let oldest = self.pending.front().map_or(t, |&(tp, _, _, _)| tp).min(t) - origin + self.tau;
        while self.b.len() > 4 && self.b[3].0 <= oldest {
            self.b.pop_front();
        }
    }

    /// B's reading at `target` (from the origin), which is not after the newest reading.
    fn at(&self, target: f64) -> Option<f64> {
        let i = self.b.partition_point(|&(tb, _)| tb < target);
        let &(t1, y1) = self.b.get(i)?;
        if t1 == target {
            return Some(y1);
        }
        let &(t0, y0) = self.b.get(i.checked_sub(1)?)?;
        let outer = (
            i.checked_sub(2).and_then(|j| self.b.get(j)),
            self.b.get(i + 1),
        );
        let gap = |a: f64, b: f64, step: f64| b - a > GAP_FACTOR * step;
        if outer.0.is_some_and(|&(tm, _)| gap(t0, t1, t0 - tm)) {
            return None;
        }
        match outer {
            (Some(&(tm, ym)), Some(&(t2, y2)))
                if !gap(t1, t2, t1 - t0) && !gap(tm, t0, t1 - t0) =>
            {
                let nodes = [(tm, ym), (t0, y0), (t1, y1), (t2, y2)];
                Some(lagrange(&nodes, target))
            }
            _ => Some(y0 + (y1 - y0) * (target - t0) / (t1 - t0)),
        }
    }

    /// Samples dropped so far, and those still pending (dropped at the end of the log).
    pub(super) fn dropped(&self) -> u64 {
        self.dropped + self.pending.len() as u64
    }
}

/// The polynomial through `nodes` at `t` (Lagrange's form; four nodes: a cubic).
fn lagrange(nodes: &[(f64, f64)], t: f64) -> f64 {
    nodes
        .iter()
        .enumerate()
        .map(|(i, &(ti, yi))| {
            let w: f64 = nodes
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .map(|(_, &(tj, _))| (t - tj) / (ti - tj))
                .product();
            yi * w
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shifted(tau: f64, samples: &[(f64, f64)]) -> (Vec<(f64, f64)>, u64) {
        let mut s = TimeShift::new(tau);
        let mut out = Vec::new();
        for &(t, y) in samples {
            s.push((t, 0.0, y, None, &[]), |t, _, y, _, _| out.push((t, y)));
        }
        (out, s.dropped())
    }

    #[test]
    fn a_later_reading_is_interpolated_in_time() {
        // y = 2t at 10 ms steps; shifted by 15 ms every output is 2(t + 0.015).
        let samples: Vec<(f64, f64)> = (0..100)
            .map(|i| (i as f64 * 0.01, 0.02 * i as f64))
            .collect();
        let (out, dropped) = shifted(0.015, &samples);
        assert_eq!(out.len() as u64 + dropped, 100);
        assert_eq!(
            dropped, 3,
            "the last three samples lack two readings from 15 ms later on"
        );
        for (t, y) in out {
            assert!((y - 2.0 * (t + 0.015)).abs() < 1e-12, "{t} {y}");
        }
    }

    #[test]
    fn a_lag_of_nanoseconds_moves_stamps_since_1970() {
        // Stamps of 1.7·10⁹ s are 2.4·10⁻⁷ s apart as doubles: a 3 ns shift must still act.
        let t0 = 1_700_000_000.0;
        let samples: Vec<(f64, f64)> = (0..100)
            .map(|i| {
                let t = t0 + i as f64 * 1e-4;
                (t, 2.0 * (t - t0))
            })
            .collect();
        let (out, _) = shifted(3e-9, &samples);
        assert!(out.len() > 90);
        for (t, y) in out {
            assert!((y - 2.0 * (t - t0 + 3e-9)).abs() < 1e-13, "{t} {y}");
        }
    }

    #[test]
    fn a_constant_acceleration_is_followed_exactly() {
        // A ramp of 25 rad/s² sampled at 200 Hz, shifted by 2 ms (0.4 of a step): a straight
        // line between samples would err by up to α·h²/8 = 7.8·10⁻⁵ rad (16″).
        let y = |t: f64| 12.5 * t * t;
        let samples: Vec<(f64, f64)> = (0..60)
            .map(|i| (i as f64 * 0.005, y(i as f64 * 0.005)))
            .collect();
        let (out, _) = shifted(0.002, &samples);
        assert!(out.len() > 50);
        for (t, v) in out.iter().skip(1) {
            assert!(
                (v - y(t + 0.002)).abs() < 1e-12,
                "{t}: {v} against {}",
                y(t + 0.002)
            );
        }
    }

    #[test]
    fn an_earlier_reading_and_a_gap() {
        // y = 2t; shifted by −15 ms the first two samples have no reading before them.
        let mut samples: Vec<(f64, f64)> = (0..50)
            .map(|i| (i as f64 * 0.01, 0.02 * i as f64))
            .collect();
        // A 1 s gap: the samples whose t − 15 ms falls in it are dropped, not interpolated.
        samples.extend((0..50).map(|i| (1.5 + i as f64 * 0.01, 2.0 * (1.5 + i as f64 * 0.01))));
        let (out, dropped) = shifted(-0.015, &samples);
        assert_eq!(dropped, 2 + 2);
        for (t, y) in out {
            assert!((y - 2.0 * (t - 0.015)).abs() < 1e-9, "{t} {y}");
        }
    }

    #[test]
    fn wrapped_readings_are_unwrapped_first() {
        let tau = std::f64::consts::TAU;
        // Readings wrap from just below 2π to just above 0 between two samples.
        let samples = [
            (0.0, tau - 0.2),
            (0.01, tau - 0.1),
            (0.02, 0.0),
            (0.03, 0.1),
            (0.04, 0.2),
        ];
        let (out, _) = shifted(0.005, &samples);
        assert!((out[1].1 - (tau - 0.05)).abs() < 1e-12);
        assert!((out[2].1 - (tau + 0.05)).abs() < 1e-12);
    }
}
