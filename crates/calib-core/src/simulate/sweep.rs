//! The motion of a joint swept back and forth over part of a revolution ([`super::Sweep`]).
//!
//! The shaft's nominal angle `φ(t)` rests at `from` for `pause_s`, then makes `2·cycles` strokes
//! `from → to → from → …`, each followed by a pause. Stroke `k` runs at the `k`-th speed of the
//! list (repeated cyclically) with raised-cosine ramps of `ramp_s` at both ends: speed
//! `v(1 − cos πu)/2` up and `v(1 + cos πu)/2` down, each ramp covering `v·ramp/2` of angle. A
//! stroke too short for two full ramps gets shorter ramps (`ramp = |to − from|/v`, no cruise).
//! The true angle adds the speed modulation of eq. (9), `θ = φ + ε_θ(φ)`, as for the CSRR
//! procedure.
//!
//! A random sweep (a joint moved by hand) makes its strokes alternately toward `to` and toward
//! `from`, each ending at a point drawn uniformly in the far half of the range (so that every
//! stroke crosses the middle and the reversals scatter), at a speed drawn uniformly between the
//! smallest and largest of the list, each followed by a pause drawn uniformly up to `pause_s`.

use super::rng::Rng;
use super::sensor::{FastSeries, Powers, Term};
use std::f64::consts::PI;

/// One stroke: from `phi0` by `distance` (signed), with ramps of `ramp` s and a cruise of
/// `cruise` s at `speed` rad/s, starting at `t0`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Stroke {
    t0: f64,
    phi0: f64,
    sign: f64,
    speed: f64,
    ramp: f64,
    cruise: f64,
}

impl Stroke {
    fn duration(&self) -> f64 {
        2.0 * self.ramp + self.cruise
    }

    /// Distance travelled `s` seconds into the stroke (unsigned).
    fn travelled(&self, s: f64) -> f64 {
        let (v, r) = (self.speed, self.ramp);
        if s <= 0.0 {
            0.0
        } else if s < r {
            let u = s / r;
            v * r * (0.5 * u - (PI * u).sin() / (2.0 * PI))
        } else if s < r + self.cruise {
            0.5 * v * r + v * (s - r)
        } else {
            let u = ((s - r - self.cruise) / r).min(1.0);
            0.5 * v * r + v * self.cruise + v * r * (0.5 * u + (PI * u).sin() / (2.0 * PI))
        }
    }
}

/// The whole sweep: strokes separated by pauses, plus the shaft's position modulation.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct SweepTimeline {
    strokes: Vec<Stroke>,
    start: f64,
    duration: f64,
    modulation: FastSeries,
    powers: Powers,
    cursor: usize,
}

impl SweepTimeline {
    /// `from`, `to` in radians; `speeds` in rad/s (non-empty, positive); `cycles` there-and-back
    /// strokes pairs; `ramp_s`, `pause_s` seconds.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn new(
        from: f64,
        to: f64,
        cycles: u32,
        speeds: &[f64],
        ramp_s: f64,
        pause_s: f64,
        modulation: &[Term],
        mut random: Option<Rng>,
    ) -> Self {
        let mut strokes = Vec::new();
        let mut t = pause_s;
        let (slowest, fastest) = speeds
            .iter()
            .fold((f64::INFINITY, 0.0f64), |a, &v| (a.0.min(v), a.1.max(v)));
        let middle = 0.5 * (from + to);
        let mut at = from;
        for k in 0..2 * cycles as usize {
            let end = if k % 2 == 0 { to } else { from };
            let (target, speed) = match random.as_mut() {
                Some(rng) => (
                    middle + rng.uniform() * (end - middle),
                    slowest + rng.uniform() * (fastest - slowest),
                ),
                None => (end, speeds[k % speeds.len()]),
            };
            let distance = (target - at).abs();
            let ramp = ramp_s.min(distance / speed);
            let cruise = (distance - speed * ramp) / speed;
            let (phi0, sign) = (at, (target - at).signum());
            at = target;
            let pause = match random.as_mut() {
                Some(rng) => rng.uniform() * pause_s,
                None => pause_s,
            };
            let stroke = Stroke {
                t0: t,
                phi0,
                sign,
                speed,
                ramp,
                cruise: cruise.max(0.0),
            };
            t += stroke.duration() + pause;
            strokes.push(stroke);
        }
        SweepTimeline {
            strokes,
            start: from,
            duration: t,
            modulation: FastSeries::new(modulation),
            powers: Powers::default(),
            cursor: 0,
        }
    }

    /// Total duration, seconds.
    pub(crate) fn duration(&self) -> f64 {
        self.duration
    }

    /// The shaft's nominal and true angles `(φ, θ)` at `t` (clamped to the run).
    pub(crate) fn angles(&mut self, t: f64) -> (f64, f64) {
        let phi = match self.strokes.len() {
            0 => self.start,
            n => {
                while self.cursor + 1 < n && t >= self.strokes[self.cursor + 1].t0 {
                    self.cursor += 1;
                }
                while self.cursor > 0 && t < self.strokes[self.cursor].t0 {
                    self.cursor -= 1;
                }
                let s = self.strokes[self.cursor];
                if t < s.t0 {
                    self.start
                } else {
                    s.phi0 + s.sign * s.travelled((t - s.t0).min(s.duration()))
                }
            }
        };
        (phi, phi + self.modulation.eval(phi, &mut self.powers))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    impl SweepTimeline {
        fn theta(&mut self, t: f64) -> f64 {
            self.angles(t).1
        }
    }

    #[test]
    fn strokes_reach_their_ends_and_return() {
        let d = |x: f64| x.to_radians();
        let mut s = SweepTimeline::new(
            d(15.0),
            d(135.0),
            2,
            &[d(20.0), d(40.0)],
            0.5,
            1.0,
            &[],
            None,
        );
        // Stroke 1 at 20°/s: 0.5 s ramps cover 10°, cruise 110° in 5.5 s → 6.5 s. Stroke 2 at
        // 40°/s: ramps 20°, cruise 100° in 2.5 s → 3.5 s. Total 1 + 2·(6.5 + 1) + 2·(3.5 + 1).
        assert!((s.duration() - 25.0).abs() < 1e-12);
        assert!((s.theta(0.5) - d(15.0)).abs() < 1e-12);
        assert!((s.theta(1.5) - d(20.0)).abs() < 1e-12);
        assert!((s.theta(7.5) - d(135.0)).abs() < 1e-12);
        assert!((s.theta(8.0) - d(135.0)).abs() < 1e-12);
        // Halfway through stroke 2 (starts at 8.5 s, lasts 3.5 s): the middle of the range.
        assert!((s.theta(10.25) - d(75.0)).abs() < 1e-9);
        assert!((s.theta(12.0) - d(15.0)).abs() < 1e-12);
        assert!((s.theta(100.0) - d(15.0)).abs() < 1e-12);
        // The cursor also walks backwards.
        assert!((s.theta(1.5) - d(20.0)).abs() < 1e-12);
    }

    #[test]
    fn short_strokes_shorten_their_ramps() {
        let mut s = SweepTimeline::new(0.0, 0.1, 1, &[1.0], 1.0, 0.0, &[], None);
        // Ramp 0.1 s each, no cruise: 0.1 rad covered in 0.2 s.
        assert!((s.duration() - 0.4).abs() < 1e-12);
        assert!((s.theta(0.2) - 0.1).abs() < 1e-12);
        assert!((s.theta(0.1) - 0.05).abs() < 1e-12);
    }

    #[test]
    fn random_strokes_reverse_in_the_far_halves_at_speeds_within_the_list() {
        let d = |x: f64| x.to_radians();
        let sweep = || {
            SweepTimeline::new(
                0.0,
                d(540.0),
                6,
                &[d(60.0), d(500.0)],
                0.4,
                0.3,
                &[],
                Some(Rng::new(73, u64::MAX)),
            )
        };
        let s = sweep();
        assert_eq!(s.strokes.len(), 12);
        let mut at = 0.0;
        for (k, stroke) in s.strokes.iter().enumerate() {
            assert!(
                (stroke.phi0 - at).abs() < 1e-12,
                "stroke {k} starts where the last ended"
            );
            let end = stroke.phi0 + stroke.sign * stroke.travelled(stroke.duration());
            let far_half = if k % 2 == 0 {
                (d(270.0)..=d(540.0)).contains(&end)
            } else {
                (0.0..=d(270.0)).contains(&end)
            };
            assert!(far_half, "stroke {k} ends at {}°", end.to_degrees());
            assert!((d(60.0)..=d(500.0)).contains(&stroke.speed), "{stroke:?}");
            at = end;
        }
        assert_eq!(
            s.strokes,
            sweep().strokes,
            "the same seed, the same strokes"
        );
    }
}
