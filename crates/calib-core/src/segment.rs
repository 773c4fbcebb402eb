//! Splitting a log of two coaxial sensors into stationary, co-rotating and turning segments.
//!
//! A CSRR log (Gou et al., the CSRR paper, section III-B, Fig. 4) alternates: the locked rotors turn
//! together for whole revolutions (a *session*), the shaft stops, rotor A alone is turned by Δ
//! against rotor B, and the next session starts. The [`Segmenter`] classifies short blocks of
//! samples (≈ [`SegmentOptions::block_s`]) and joins them:
//!
//! - **stationary**: neither sensor moves faster than [`SegmentOptions::min_speed`];
//! - **rotating**: both move, in the same direction, and the relative angle `d = x − y` is
//!   periodic in the shaft's angle — a CSRR session;
//! - **turning**: anything else (one sensor moves alone, or the relative angle drifts).
//!
//! # Sessions found from the motion
//! Within a session `d = Δ_k + e_a(θ) − e_b(θ − Δ_k)` (the CSRR paper's eq. 1 written for the
//! readings, see [`crate::csrr::joint`]): however large the sensors' errors, `d` returns to the
//! same value after one revolution of the shaft. A relative turn, or a slip, is a drift that does
//! not. So a rotating block continues the open session, in the same direction, while the mean of
//! `d(x) − d(x ∓ 2π)` over its samples — each sample against the session's own sample one
//! revolution earlier, linearly interpolated — stays within the session's tolerance. Until the
//! session has turned one revolution there is nothing to compare with, and the block continues
//! it. The tolerance is [`SegmentOptions::relative_tol`] when given; by default it is taken from
//! the session itself: [`AUTO_TOL_FACTOR`] times the RMS of the first [`AUTO_TOL_BLOCKS`] blocks'
//! departures (quantization and noise of the block means), at least [`MIN_AUTO_TOL`]; before
//! those blocks are in, [`PROVISIONAL_TOL`]. The largest tolerance applied is reported
//! ([`Segmentation::relative_tol`]). Sessions turning backwards, at any speed and of any length
//! are found alike; only those of at least one revolution are used.
//!
//! The block at each end of a rotating segment is not handed to the session sink, so that the
//! edges of a relative turn made while rotating never leak into a session.
//!
//! # A lag between the channels
//! Two interfaces rarely sample at the same instant. If B's sample stamped `t` was taken at
//! `t − τ`, then `d = x − y` carries `τ·ω(t)` (to first order, `ω` the shaft's speed): a constant
//! at a constant speed, which only shifts a session's relative rotation, but a change of
//! `τ·Δω` wherever the speed changes. The one-revolution departures see it free of the maps:
//! at the same reading of A the errors cancel, and what is left is `τ·(ω_now − ω_then)` plus
//! noise. Each block's mean departure is regressed on its speed change over the sessions
//! ([`LatencyEstimate`]); A lagging B gives a negative `τ`.
//!
//! The segmenter is streaming: it holds one block of samples and the list of segments.

use crate::angle::{Unwrapper, wrap_2pi};
use std::collections::VecDeque;
use std::f64::consts::TAU;

/// The default tolerance on a session's periodicity is this many times the RMS departure of its
/// first blocks from one revolution earlier: 10 standard deviations of their scatter.
pub const AUTO_TOL_FACTOR: f64 = 10.0;

/// Blocks whose departures set a session's default tolerance.
pub const AUTO_TOL_BLOCKS: usize = 8;

/// The default tolerance is never below this, rad (0.01° = 36″): a drift smaller than it within
/// one revolution is no relative turn anyone makes on purpose.
pub const MIN_AUTO_TOL: f64 = 0.01 * std::f64::consts::PI / 180.0;

/// The tolerance while a session's first [`AUTO_TOL_BLOCKS`] departures are gathered, rad (1°).
pub const PROVISIONAL_TOL: f64 = std::f64::consts::PI / 180.0;

/// Tuning of the [`Segmenter`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SegmentOptions {
    /// Speed below which a sensor counts as still, rad/s (default 1°/s).
    pub min_speed: f64,
    /// Largest departure of the relative angle from its value one revolution earlier within
    /// one session, rad (default `None`: from the session's own scatter, see the module docs).
    pub relative_tol: Option<f64>,
    /// Duration of one classification block, s (default 0.05 s; at least 3 samples).
    pub block_s: f64,
    /// Use the log's session marks instead of detecting sessions.
    pub use_marks: bool,
}

impl Default for SegmentOptions {
    fn default() -> Self {
        SegmentOptions {
            min_speed: 1f64.to_radians(),
            relative_tol: None,
            block_s: 0.05,
            use_marks: false,
        }
    }
}

/// What a segment of the log is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum SegmentKind {
    /// Neither sensor moves.
    Stationary,
    /// Both sensors turn together at a constant relative angle: a CSRR session candidate.
    Rotating,
    /// One sensor turns against the other (a relative turn), or motion too irregular to use.
    Turning,
}

/// A segment of the log.
#[derive(Debug, Clone, PartialEq, serde::Serialize, schemars::JsonSchema)]
pub struct Segment {
    /// Its kind.
    pub kind: SegmentKind,
    /// First sample's time, s.
    pub start_s: f64,
    /// Last sample's time, s.
    pub end_s: f64,
    /// Samples in it.
    pub samples: u64,
    /// Revolutions of the first sensor (signed by direction).
    pub revolutions: f64,
    /// Mean relative angle `x − y`, rad, wrapped to `[0, 2π)` (written to JSON as
    /// `relative_angle_deg` in `(−180, 180]`).
    #[serde(rename = "relative_angle_deg", serialize_with = "signed_degrees")]
    pub relative_angle: f64,
    /// For a rotating segment: the session index it became, or `None` when it was too short.
    pub session: Option<usize>,
}

fn signed_degrees<S: serde::Serializer>(rad: &f64, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_f64(crate::angle::wrap_pi(*rad).to_degrees())
}

/// Receives the samples of each session as the [`Segmenter`] finds them.
pub trait SessionSink {
    /// A sample of session `session`: time, both readings wrapped to `[0, 2π)`, and the relative
    /// angle `d = x − y` unwrapped continuously within the session (so `d` never jumps by 2π).
    /// `extra` carries the readings of any further channels fed to the segmenter.
    fn sample(&mut self, session: usize, t: f64, x: f64, y: f64, d: f64, extra: &[f64]);
    /// Session `session` is complete; `accepted` is false when it covered less than one
    /// revolution and must be discarded.
    fn close(&mut self, session: usize, accepted: bool);
}

/// A sink that discards samples (for `inspect`, which only wants the segments).
impl SessionSink for () {
    fn sample(&mut self, _: usize, _: f64, _: f64, _: f64, _: f64, _: &[f64]) {}
    fn close(&mut self, _: usize, _: bool) {}
}

#[derive(Debug, Clone)]
struct Buffered {
    t: f64,
    x: f64,
    y: f64,
    d: f64,
    xu: f64,
    yu: f64,
    mark: Option<u32>,
    extra: Vec<f64>,
}

#[derive(Debug, Clone, Copy)]
struct BlockStats {
    kind: SegmentKind,
    direction: f64,
}

/// Streaming splitter of a two-sensor log into segments and sessions. See the module docs.
#[derive(Debug)]
pub struct Segmenter {
    opts: SegmentOptions,
    ux: Unwrapper,
    uy: Unwrapper,
    block: Vec<Buffered>,
    /// A rotating block held back until the next block shows whether the session goes on.
    held: Vec<Buffered>,
    segments: Vec<Segment>,
    current: Option<Open>,
    sessions: usize,
    opposite_blocks: u64,
    moving_blocks: u64,
    /// Blocks in which the first / second sensor moved.
    moved: (u64, u64),
    /// The largest set tolerance (given, or from a session's own scatter) a rotating segment's
    /// periodicity was checked against, rad.
    tol_applied: Option<f64>,
    /// Whether a periodicity check used [`PROVISIONAL_TOL`].
    provisional_only: bool,
    /// The accepted sessions' squared departures from one revolution earlier, and their count.
    repeat: (f64, u64),
    /// The accepted sessions' departures against their speed changes.
    lag: LagSums,
}

/// Weighted sums of the blocks' departures `δ` against their speed changes `Δω` (weights: the
/// samples compared), for the least-squares lag `τ = Σnδ·Δω / ΣnΔω²`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct LagSums {
    n: f64,
    ww: f64,
    wd: f64,
    dd: f64,
    blocks: u64,
    max_speed: f64,
}

impl LagSums {
    fn add(&mut self, n: f64, speed_change: f64, departure: f64, speed: f64) {
        self.n += n;
        self.ww += n * speed_change * speed_change;
        self.wd += n * speed_change * departure;
        self.dd += n * departure * departure;
        self.blocks += 1;
        self.max_speed = self.max_speed.max(speed.abs());
    }

    fn merge(&mut self, other: &LagSums) {
        self.n += other.n;
        self.ww += other.ww;
        self.wd += other.wd;
        self.dd += other.dd;
        self.blocks += other.blocks;
        self.max_speed = self.max_speed.max(other.max_speed);
    }

    fn estimate(&self) -> Option<LatencyEstimate> {
        if self.blocks < 3 || self.ww.is_nan() || self.ww <= 0.0 {
            return None;
        }
        let tau = self.wd / self.ww;
        // Σn·r² of the block means is (blocks − 1)·σ² for a per-sample departure variance σ².
        let residual = (self.dd - tau * self.wd).max(0.0);
        let variance = residual / (self.blocks - 1) as f64;
        Some(LatencyEstimate {
            tau,
            u_tau: (variance / self.ww).sqrt(),
            noise: (variance / 2.0).sqrt(),
            speed_change_rms: (self.ww / self.n).sqrt(),
            max_speed: self.max_speed,
            blocks: self.blocks,
        })
    }
}

/// The lag between the two channels that the sessions' one-revolution departures show (see
/// [A lag between the channels](self#a-lag-between-the-channels)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LatencyEstimate {
    /// `τ`, seconds: how much older B's sample is than A's at the same stamp (negative: A's is
    /// older).
    pub tau: f64,
    /// Standard uncertainty of `τ`, seconds, from the scatter of the blocks about the fit.
    pub u_tau: f64,
    /// The noise of `d` per sample that scatter implies, rad (the departures less the lag, over
    /// √2: two samples' noise).
    pub noise: f64,
    /// RMS of the speed changes over one revolution the estimate rests on, rad/s (0 at a
    /// perfectly constant speed: no lag is visible then).
    pub speed_change_rms: f64,
    /// The largest block speed in the sessions, rad/s: `τ` moves `d` by up to `τ` times it.
    pub max_speed: f64,
    /// Blocks compared.
    pub blocks: u64,
}

#[derive(Debug)]
struct Open {
    kind: SegmentKind,
    start_s: f64,
    end_s: f64,
    samples: u64,
    x_start: f64,
    x_end: f64,
    d_sum: f64,
    direction: f64,
    mark: Option<u32>,
    /// The session id handed to the sink, for rotating segments.
    session: Option<usize>,
    /// A rotating segment's samples `(x unwrapped, d, t)` of (a little over) its last revolution.
    history: VecDeque<(f64, f64, f64)>,
    /// A rotating segment's departures from one revolution earlier, per block, while its
    /// tolerance is being set.
    departures: Vec<f64>,
    /// A rotating segment's tolerance once set.
    tol: Option<f64>,
    /// Sum of the squared per-sample departures from one revolution earlier, and their count.
    repeat: (f64, u64),
    /// The departures against the speed changes.
    lag: LagSums,
}

/// The mean departure of a block from one revolution earlier ([`Open::departure`]), with the
/// sum of the squared per-sample departures and their count, and the mean speed of the block
/// with its mean change from the speed at the same readings one revolution earlier (rad/s;
/// `None` under two samples).
struct Departure {
    mean: f64,
    sum_sq: f64,
    count: u64,
    speeds: Option<(f64, f64)>,
}

impl Open {
    /// The mean over `block` of `d(x) − d(x − 2π·direction)`, the session's own `d` one
    /// revolution earlier interpolated linearly in `x`; `None` when no sample of the block is a
    /// revolution past the segment's start.
    fn departure(&self, block: &[Buffered]) -> Option<Departure> {
        let dir = self.direction;
        let (mut sum, mut sum_sq, mut count) = (0.0, 0.0, 0u64);
        // The speed now and its change from one revolution earlier, between consecutive
        // samples compared (x, t now, t then): their sums and count.
        let mut previous: Option<(f64, f64, f64)> = None;
        let (mut speed, mut change, mut steps) = (0.0, 0.0, 0u32);
        let mut j = 0;
        for b in block {
            let target = b.xu - dir * TAU;
            if (target - self.x_start) * dir < 0.0 {
                continue;
            }
            j = self.first_not_before(target, j);
            let Some(&(x1, d1, t1)) = self.history.get(j) else {
                continue;
            };
            let (d_then, t_then) = match j.checked_sub(1).and_then(|i| self.history.get(i)) {
                Some(&(x0, d0, t0)) if x1 != x0 => {
                    let f = (target - x0) / (x1 - x0);
                    (
                        self.d_at(j, target).unwrap_or(d0 + (d1 - d0) * f),
                        t0 + (t1 - t0) * f,
                    )
                }
                _ => (d1, t1),
            };
            sum += b.d - d_then;
            sum_sq += (b.d - d_then).powi(2);
            count += 1;
            if let Some((x0, t0, t0_then)) = previous {
                let (dx, dt, dt_then) = (b.xu - x0, b.t - t0, t_then - t0_then);
                if dt > 0.0 && dt_then > 0.0 {
                    speed += dx / dt;
                    change += dx / dt - dx / dt_then;
                    steps += 1;
                }
            }
            previous = Some((b.xu, b.t, t_then));
        }
        if count == 0 {
            return None;
        }
        let speeds = (steps > 0).then(|| (speed / f64::from(steps), change / f64::from(steps)));
        Some(Departure {
            mean: sum / count as f64,
            sum_sq,
            count,
            speeds,
        })
    }

    /// `d` one revolution earlier at `target`, by the cubic in `x` through the history's two
    /// samples before it and two from `j` on (`None` without them): a straight line errs by
    /// `d''·h²/8` over a step `h` of `x`, and `h` grows with the speed, so a line's error would
    /// follow the speed and read as a lag between the channels.
    fn d_at(&self, j: usize, target: f64) -> Option<f64> {
        let nodes = [
            self.history.get(j.checked_sub(2)?)?,
            self.history.get(j - 1)?,
            self.history.get(j)?,
            self.history.get(j + 1)?,
        ];
        let mut sum = 0.0;
        for (i, &&(xi, di, _)) in nodes.iter().enumerate() {
            let mut w = 1.0;
            for (k, &&(xk, _, _)) in nodes.iter().enumerate() {
                if k != i {
                    if xi == xk {
                        return None;
                    }
                    w *= (target - xk) / (xi - xk);
                }
            }
            sum += di * w;
        }
        Some(sum)
    }

    /// The first sample of the history whose `x` is not before `target` along the direction of
    /// travel, searched from `hint` (the previous sample's): where `x` advances with the travel,
    /// as it does while the shaft turns, that is a step or two from it, and the result is what a
    /// binary search over the revolution (`partition_point`) gives, at a fraction of its cost.
    /// Further than [`WALK`] from `hint`, the binary search.
    fn first_not_before(&self, target: f64, hint: usize) -> usize {
        /// Steps walked from the hint before searching the whole history.
        const WALK: usize = 32;
        let before = |i: usize| (self.history[i].0 - target) * self.direction < 0.0;
        let n = self.history.len();
        let mut j = hint.min(n);
        for _ in 0..WALK {
            if j < n && before(j) {
                j += 1;
            } else if j > 0 && !before(j - 1) {
                j -= 1;
            } else {
                return j;
            }
        }
        self.history
            .partition_point(|&(x, _, _)| (x - target) * self.direction < 0.0)
    }

    /// Adds `block` to the history, keeping a little over one revolution.
    fn remember(&mut self, block: &[Buffered]) {
        self.history.extend(block.iter().map(|b| (b.xu, b.d, b.t)));
        let newest = block.last().map_or(self.x_end, |b| b.xu);
        while self
            .history
            .front()
            .is_some_and(|&(x, _, _)| (newest - x) * self.direction > 1.1 * TAU)
        {
            self.history.pop_front();
        }
    }

    /// The tolerance on the next block's departure: the option's, else the session's own (see
    /// the module docs).
    fn tolerance(&self, option: Option<f64>) -> f64 {
        option.or(self.tol).unwrap_or(PROVISIONAL_TOL)
    }

    /// Records a block's departure; the session's tolerance is set once enough are in.
    fn record(&mut self, departure: f64) {
        if self.tol.is_some() {
            return;
        }
        self.departures.push(departure);
        if self.departures.len() >= AUTO_TOL_BLOCKS {
            let rms = (self.departures.iter().map(|d| d * d).sum::<f64>()
                / self.departures.len() as f64)
                .sqrt();
            self.tol = Some((AUTO_TOL_FACTOR * rms).max(MIN_AUTO_TOL));
        }
    }
}

impl Segmenter {
    /// A segmenter with these options.
    pub fn new(opts: SegmentOptions) -> Self {
        Segmenter {
            opts,
            ux: Unwrapper::new(),
            uy: Unwrapper::new(),
            block: Vec::new(),
            held: Vec::new(),
            segments: Vec::new(),
            current: None,
            sessions: 0,
            opposite_blocks: 0,
            moving_blocks: 0,
            moved: (0, 0),
            tol_applied: None,
            provisional_only: false,
            repeat: (0.0, 0),
            lag: LagSums::default(),
        }
    }

    /// Feeds one sample: time (s), the two sensors' readings (rad, wrapped or not), the log's
    /// session mark if any, and further channels to pass through to the sink.
    pub fn push<S: SessionSink>(
        &mut self,
        t: f64,
        x: f64,
        y: f64,
        mark: Option<u32>,
        extra: &[f64],
        sink: &mut S,
    ) {
        let xu = self.ux.unwrap(x);
        let yu = self.uy.unwrap(y);
        let full = match self.block.first() {
            Some(first) => {
                let mark_changed = self.opts.use_marks && first.mark != mark;
                (t - first.t >= self.opts.block_s && self.block.len() >= 3) || mark_changed
            }
            None => false,
        };
        if full {
            self.flush_block(sink);
        }
        self.block.push(Buffered {
            t,
            x: wrap_2pi(x),
            y: wrap_2pi(y),
            d: xu - yu,
            xu,
            yu,
            mark,
            extra: extra.to_vec(),
        });
    }

    /// Ends the stream: closes the last segment and returns every segment found.
    pub fn finish<S: SessionSink>(mut self, sink: &mut S) -> Segmentation {
        if !self.block.is_empty() {
            self.flush_block(sink);
        }
        self.close_current(sink);
        Segmentation {
            segments: self.segments,
            sessions: self.sessions,
            opposite_direction: self.moving_blocks > 0
                && self.opposite_blocks * 2 > self.moving_blocks,
            moved: (self.moved.0 > 0, self.moved.1 > 0),
            relative_tol: self
                .tol_applied
                .or(self.provisional_only.then_some(PROVISIONAL_TOL)),
            repeatability: (self.repeat.1 > 0)
                .then(|| (self.repeat.0 / (2.0 * self.repeat.1 as f64)).sqrt()),
            latency: self.lag.estimate(),
        }
    }

    fn classify(&mut self, block: &[Buffered]) -> BlockStats {
        let (first, last) = (&block[0], &block[block.len() - 1]);
        let dt = (last.t - first.t).max(f64::MIN_POSITIVE);
        let vx = (last.xu - first.xu) / dt;
        let vy = (last.yu - first.yu) / dt;
        let min = self.opts.min_speed;
        let (mx, my) = (vx.abs() >= min, vy.abs() >= min);
        self.moved.0 += u64::from(mx);
        self.moved.1 += u64::from(my);
        if mx && my {
            self.moving_blocks += 1;
            if vx.signum() != vy.signum() {
                self.opposite_blocks += 1;
            }
        }
        let kind = if !mx && !my {
            SegmentKind::Stationary
        } else if mx && my && vx.signum() == vy.signum() {
            SegmentKind::Rotating
        } else {
            SegmentKind::Turning
        };
        BlockStats {
            kind,
            direction: vx.signum(),
        }
    }

    fn flush_block<S: SessionSink>(&mut self, sink: &mut S) {
        let block = std::mem::take(&mut self.block);
        let mut stats = self.classify(&block);
        let mark = block[0].mark;
        if self.opts.use_marks {
            // The log says which rows are sessions: marked rows are a session whatever the
            // motion, unmarked rows never are.
            if mark.is_some() {
                stats.kind = SegmentKind::Rotating;
            } else if stats.kind == SegmentKind::Rotating {
                stats.kind = SegmentKind::Turning;
            }
        }
        let departure = match &self.current {
            Some(open)
                if open.kind == SegmentKind::Rotating
                    && stats.kind == SegmentKind::Rotating
                    && stats.direction == open.direction =>
            {
                open.departure(&block)
            }
            _ => None,
        };
        let continues = match &mut self.current {
            Some(open) if open.kind == stats.kind => match stats.kind {
                SegmentKind::Rotating if self.opts.use_marks => open.mark == mark,
                SegmentKind::Rotating if stats.direction != open.direction => false,
                SegmentKind::Rotating => match &departure {
                    None => true,
                    Some(departure) => {
                        let tol = open.tolerance(self.opts.relative_tol);
                        if self.opts.relative_tol.is_some() || open.tol.is_some() {
                            self.tol_applied = Some(self.tol_applied.map_or(tol, |t| t.max(tol)));
                        } else {
                            self.provisional_only = true;
                        }
                        let periodic = departure.mean.abs() <= tol;
                        if periodic {
                            open.record(departure.mean);
                        }
                        periodic
                    }
                },
                _ => true,
            },
            _ => false,
        };
        if let (true, Some(dep), Some(open)) = (continues, &departure, &mut self.current) {
            open.repeat.0 += dep.sum_sq;
            open.repeat.1 += dep.count;
            if let Some((speed, change)) = dep.speeds {
                open.lag.add(dep.count as f64, change, dep.mean, speed);
            }
        }
        if !continues {
            self.close_current(sink);
            let first = &block[0];
            let session = (stats.kind == SegmentKind::Rotating).then(|| {
                self.sessions += 1;
                self.sessions - 1
            });
            self.current = Some(Open {
                kind: stats.kind,
                start_s: first.t,
                end_s: first.t,
                samples: 0,
                x_start: first.xu,
                x_end: first.xu,
                d_sum: 0.0,
                direction: stats.direction,
                mark,
                session,
                history: VecDeque::new(),
                departures: Vec::new(),
                tol: None,
                repeat: (0.0, 0),
                lag: LagSums::default(),
            });
        }
        let open = self.current.as_mut().expect("set above");
        if open.kind == SegmentKind::Rotating {
            open.remember(&block);
        }
        let last = &block[block.len() - 1];
        open.end_s = last.t;
        open.x_end = last.xu;
        open.samples += block.len() as u64;
        open.d_sum += block.iter().map(|b| b.d).sum::<f64>();
        let Some(session) = open.session else { return };
        if self.opts.use_marks {
            // Marked sessions are exactly what the log says: no edge trimming.
            for b in &block {
                sink.sample(session, b.t, b.x, b.y, b.d, &b.extra);
            }
        } else if continues {
            // Hand over the block held back last time and hold this one: the last block of a
            // session is dropped with `held` when the session ends.
            for b in self.held.drain(..) {
                sink.sample(session, b.t, b.x, b.y, b.d, &b.extra);
            }
            self.held = block;
        }
        // The first block of a detected session is neither handed over nor held: it is dropped.
    }

    fn close_current<S: SessionSink>(&mut self, sink: &mut S) {
        let Some(open) = self.current.take() else {
            return;
        };
        let revolutions = (open.x_end - open.x_start) / TAU;
        let mut session = open.session;
        if let Some(k) = open.session {
            let accepted = revolutions.abs() >= 1.0;
            sink.close(k, accepted);
            if accepted {
                self.repeat.0 += open.repeat.0;
                self.repeat.1 += open.repeat.1;
                self.lag.merge(&open.lag);
            } else {
                session = None;
            }
        }
        self.held.clear();
        self.segments.push(Segment {
            kind: open.kind,
            start_s: open.start_s,
            end_s: open.end_s,
            samples: open.samples,
            revolutions,
            relative_angle: wrap_2pi(open.d_sum / open.samples.max(1) as f64),
            session,
        });
    }
}

/// The segments of a log, and how many session ids were handed out.
#[derive(Debug, Clone, PartialEq)]
pub struct Segmentation {
    /// Every segment, in log order.
    pub segments: Vec<Segment>,
    /// Session ids handed to the sink (accepted or not) — ids run `0..sessions`.
    pub sessions: usize,
    /// Most moving blocks had the two sensors turning in opposite directions: one channel counts
    /// the other way round.
    pub opposite_direction: bool,
    /// Whether the first and the second sensor ever moved faster than the speed threshold.
    pub moved: (bool, bool),
    /// The largest tolerance a session's periodicity was checked against, rad: given, or set
    /// from a session's own scatter ([`PROVISIONAL_TOL`] where no session turned long enough to
    /// set one); `None` when no session turned a revolution or the log's marks were used.
    pub relative_tol: Option<f64>,
    /// The readings' noise as the sessions repeat it, rad per sample of `d = x − y`: the RMS
    /// departure of `d` from its value one revolution earlier over every accepted session,
    /// divided by √2 (two samples' noise). It is model-free and independent of the sensors'
    /// errors (slightly above the noise where `d` is curved between samples); `None` when no
    /// session turned more than one revolution.
    pub repeatability: Option<f64>,
    /// The lag between the channels the sessions show ([`LatencyEstimate`]); `None` where fewer
    /// than three blocks were compared or the speed never changed.
    pub latency: Option<LatencyEstimate>,
}

impl Segmentation {
    /// The rotating segments that became sessions.
    pub fn accepted_sessions(&self) -> impl Iterator<Item = &Segment> {
        self.segments.iter().filter(|s| s.session.is_some())
    }
    /// The rotating segments rejected for covering less than one revolution.
    pub fn short_segments(&self) -> impl Iterator<Item = &Segment> {
        self.segments
            .iter()
            .filter(|s| s.kind == SegmentKind::Rotating && s.session.is_none())
    }
}
