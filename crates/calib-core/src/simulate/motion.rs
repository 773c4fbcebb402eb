//! The motion of the driven shaft (rotor B) and of rotor A during a CSRR procedure.
//!
//! The shaft's *nominal* angle `φ(t)` follows the procedure: stationary pauses, raised-cosine
//! speed ramps, constant speed `ω` over whole revolutions, and stationary relative turns of rotor
//! A. Its *true* angle adds the sampling non-uniformity of the paper's eq. (9),
//! `θ = φ + ε_θ(φ)`, where `ε_θ` is periodic in the shaft's position:
//! `ε_θ(φ) = Σ m_Ω cos(Ω·φ + ψ_Ω)`. Rotor A is locked to the shaft at the session's relative
//! rotation: `θ_A = θ_B + Δ(t)`, with `Δ` changing only during turns.

use super::sensor::{FastSeries, Powers, Term};
use std::f64::consts::PI;

/// What the shaft and rotor A do during one segment.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    /// Both rotors stationary.
    Still,
    /// Speed rising from 0 to ω as `ω(1 − cos πu)/2`, `u = (t − t0)/duration`.
    RampUp,
    /// Constant nominal speed ω.
    Cruise,
    /// Speed falling from ω to 0 as `ω(1 + cos πu)/2`.
    RampDown,
    /// Shaft stationary, rotor A turning from `delta0` to `delta1` with a raised-cosine profile.
    Turn,
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct Segment {
    kind: Kind,
    t0: f64,
    duration: f64,
    /// Nominal shaft angle at `t0`.
    phi0: f64,
    /// Relative rotation Δ = θ_A − θ_B at `t0` and at the end.
    delta0: f64,
    delta1: f64,
    /// The session whose constant-speed revolutions this segment holds.
    session: Option<u32>,
    /// The session's cruise speed, rad/s, signed: negative when the shaft turns backwards.
    omega: f64,
}

impl Segment {
    fn end(&self) -> f64 {
        self.t0 + self.duration
    }
}

/// One session as the timeline needs it: relative rotation (rad), revolutions, and its cruise
/// speed (rad/s, signed: negative turns the shaft backwards; `None`: the timing's).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct SessionPlan {
    pub(crate) delta: f64,
    pub(crate) revolutions: f64,
    pub(crate) omega: Option<f64>,
}

/// The procedure's timing, all in seconds; `omega` in rad/s.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Timing {
    pub(crate) omega: f64,
    pub(crate) ramp_s: f64,
    pub(crate) pause_s: f64,
    pub(crate) turn_s: f64,
}

/// The state of both rotors at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct State {
    /// Nominal (commanded) angle of the driven shaft, radians, accumulated: `θ_B` without the
    /// modulation of eq. (9).
    pub(crate) phi: f64,
    /// True angle of the driven shaft (rotor B), radians, accumulated.
    pub(crate) theta_b: f64,
    /// Relative rotation `θ_A − θ_B`, radians.
    pub(crate) delta: f64,
}

/// The whole procedure as a list of segments, plus the shaft's position modulation.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Timeline {
    segments: Vec<Segment>,
    modulation: FastSeries,
    powers: Powers,
    /// Index of the segment of the last lookup: time mostly moves forward by one sample.
    cursor: usize,
}

impl Timeline {
    /// The layout: pause, then per session `k` — (for `k > 0`: turn from `Δ_{k−1}` to `Δ_k`,
    /// pause) — ramp up, `revolutions` at constant speed, ramp down, pause. Runs start and end at
    /// rest. Segments of zero duration are left out.
    pub(crate) fn new(sessions: &[SessionPlan], timing: Timing, modulation: Vec<Term>) -> Self {
        let mut segments = Vec::new();
        let (mut t, mut phi) = (0.0, 0.0);
        let mut delta = sessions.first().map_or(0.0, |s| s.delta);
        let mut push = |kind, duration: f64, delta1: f64, session, omega: f64| {
            if duration > 0.0 {
                segments.push(Segment {
                    kind,
                    t0: t,
                    duration,
                    phi0: phi,
                    delta0: delta,
                    delta1,
                    session,
                    omega,
                });
            }
            t += duration;
            // A ramp covers half the distance constant speed would (mean of the raised cosine).
            phi += match kind {
                Kind::RampUp | Kind::RampDown => 0.5 * omega * duration,
                Kind::Cruise => omega * duration,
                Kind::Still | Kind::Turn => 0.0,
            };
            delta = delta1;
        };
        let first = sessions.first().map_or(0.0, |s| s.delta);
        push(Kind::Still, timing.pause_s, first, None, 0.0);
        for (k, s) in sessions.iter().enumerate() {
            if k > 0 {
                push(Kind::Turn, timing.turn_s, s.delta, None, 0.0);
                push(Kind::Still, timing.pause_s, s.delta, None, 0.0);
            }
            let omega = s.omega.unwrap_or(timing.omega);
            let cruise = s.revolutions * std::f64::consts::TAU / omega.abs();
            let session = u32::try_from(k).ok();
            push(Kind::RampUp, timing.ramp_s, s.delta, None, omega);
            push(Kind::Cruise, cruise, s.delta, session, omega);
            push(Kind::RampDown, timing.ramp_s, s.delta, None, omega);
            push(Kind::Still, timing.pause_s, s.delta, None, 0.0);
        }
        Timeline {
            segments,
            modulation: FastSeries::new(&modulation),
            powers: Powers::default(),
            cursor: 0,
        }
    }

    /// The constant-speed window `[start, end)` of each session, seconds, in session order.
    pub(crate) fn session_windows(&self) -> Vec<(f64, f64)> {
        let mut windows: Vec<_> = self
            .segments
            .iter()
            .filter_map(|s| s.session.map(|k| (k, (s.t0, s.end()))))
            .collect();
        windows.sort_by_key(|w| w.0);
        windows.into_iter().map(|w| w.1).collect()
    }

    /// Total duration, seconds.
    pub(crate) fn duration(&self) -> f64 {
        self.segments.last().map_or(0.0, Segment::end)
    }

    /// The state at time `t` (clamped to the run: before 0 the first state, after the end the
    /// last).
    pub(crate) fn state(&mut self, t: f64) -> State {
        let Some(last) = self.segments.len().checked_sub(1) else {
            return State {
                phi: 0.0,
                theta_b: 0.0,
                delta: 0.0,
            };
        };
        while self.cursor < last && t >= self.segments[self.cursor].end() {
            self.cursor += 1;
        }
        while self.cursor > 0 && t < self.segments[self.cursor].t0 {
            self.cursor -= 1;
        }
        let seg = self.segments[self.cursor];
        let u = ((t - seg.t0) / seg.duration).clamp(0.0, 1.0);
        let run = seg.omega * seg.duration;
        let (phi, delta) = match seg.kind {
            Kind::Still => (seg.phi0, seg.delta0),
            Kind::RampUp => (
                seg.phi0 + run * (0.5 * u - (PI * u).sin() / (2.0 * PI)),
                seg.delta0,
            ),
            Kind::Cruise => (seg.phi0 + run * u, seg.delta0),
            Kind::RampDown => (
                seg.phi0 + run * (0.5 * u + (PI * u).sin() / (2.0 * PI)),
                seg.delta0,
            ),
            Kind::Turn => {
                let s = 0.5 * (1.0 - (PI * u).cos());
                (seg.phi0, seg.delta0 + (seg.delta1 - seg.delta0) * s)
            }
        };
        State {
            phi,
            // ε_θ(φ) of eq. (9).
            theta_b: phi + self.modulation.eval(phi, &mut self.powers),
            delta,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    fn timeline(modulation: Vec<Term>) -> Timeline {
        Timeline::new(
            &[
                SessionPlan {
                    delta: 0.0,
                    revolutions: 2.0,
                    omega: None,
                },
                SessionPlan {
                    delta: 1.0,
                    revolutions: 1.0,
                    omega: None,
                },
            ],
            Timing {
                omega: TAU,
                ramp_s: 0.5,
                pause_s: 0.25,
                turn_s: 1.0,
            },
            modulation,
        )
    }

    #[test]
    fn layout_positions_and_sessions() {
        let mut tl = timeline(Vec::new());
        // pause .25, ramp .5, cruise 2, ramp .5, pause .25, turn 1, pause .25, ramp .5, cruise 1,
        // ramp .5, pause .25.
        assert!((tl.duration() - 7.0).abs() < 1e-12);
        assert_eq!(tl.session_windows(), [(0.75, 2.75), (5.25, 6.25)]);
        let s = tl.state(0.75);
        assert!((s.theta_b - 0.25 * TAU).abs() < 1e-12);
        let s = tl.state(2.75);
        assert!((s.theta_b - 2.25 * TAU).abs() < 1e-12);
        let s = tl.state(4.0);
        assert!((s.theta_b - 2.5 * TAU).abs() < 1e-12 && (s.delta - 0.5).abs() < 1e-12);
        let s = tl.state(5.25);
        assert!((s.theta_b - 2.75 * TAU).abs() < 1e-12 && (s.delta - 1.0).abs() < 1e-12);
        // Clamped outside the run, and the cursor also walks backwards.
        assert_eq!(tl.state(100.0).theta_b, tl.state(7.0).theta_b);
        assert_eq!(tl.state(-1.0).theta_b, 0.0);
    }

    #[test]
    fn a_backward_session_at_its_own_speed() {
        let mut tl = Timeline::new(
            &[SessionPlan {
                delta: 0.0,
                revolutions: 1.0,
                omega: Some(-0.5 * TAU),
            }],
            Timing {
                omega: TAU,
                ramp_s: 0.5,
                pause_s: 0.25,
                turn_s: 1.0,
            },
            Vec::new(),
        );
        // pause .25, ramp .5 (−⅛ turn), cruise 2 s (−1 turn), ramp .5, pause .25.
        assert_eq!(tl.session_windows(), [(0.75, 2.75)]);
        assert!((tl.state(0.75).theta_b + 0.125 * TAU).abs() < 1e-12);
        assert!((tl.state(2.75).theta_b + 1.125 * TAU).abs() < 1e-12);
        assert!((tl.state(10.0).theta_b + 1.25 * TAU).abs() < 1e-12);
    }

    #[test]
    fn modulation_is_added_to_the_true_angle() {
        let m = Term {
            order: 3.0,
            amplitude: 1e-4,
            phase: 0.2,
        };
        let mut tl = timeline(vec![m]);
        let plain = timeline(Vec::new()).state(1.1).theta_b;
        let got = tl.state(1.1).theta_b;
        assert!((got - plain - 1e-4 * (3.0 * plain + 0.2).cos()).abs() < 1e-12);
    }
}
