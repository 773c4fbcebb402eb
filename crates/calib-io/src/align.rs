//! Channels on different clocks brought onto one: the first channel's.
//!
//! A recording in which every sensor publishes on its own topic has no two readings at the same
//! instant; a method needs one reading of every channel per sample. The `Aligner` makes the
//! first selected channel the **clock**: every sample of it becomes a sample of the output, and
//! every other channel is interpolated at the clock's stamp from its own samples.
//!
//! # Interpolation
//! Quintic: the Lagrange polynomial through the channel's [`SIDE`] = 3 samples on either side of
//! the stamp, at their own (possibly jittered) stamps. Its error is `f⁽⁶⁾(ξ)/6! · Π(t − sₖ)`, at
//! most `0.0049·h⁶·max|f⁽⁶⁾|` mid-way between equally spaced samples `h` apart; four points
//! (cubic) give `0.0234·h⁴·max|f⁽⁴⁾|`, two (linear) `h²/8·max|f″|`. For a reading that carries an
//! error of order `n` and amplitude `A`, sampled `N` times per period of that order
//! (`ωh = 2π/N`), that is `A·(ωh)^k` times those constants. The CSRR paper's first experiment
//! (400 Hz at 10 r/min, `testdata/scenarios/csrr72.toml`) has order 72 at 24″ sampled 33 times
//! per period — linear 0.11″, as much as the whole calibration's residual, cubic 0.0007″ — but
//! also order 216 at 14″ sampled 11 times and order 432 at 1″ sampled 5.6 times per period:
//! cubic 0.034″ and 0.038″ there, quintic 0.002″ and 0.010″. Measured on that run with B on a
//! clock 3/8 of a period off (`cli/tests/it/recordings_cli.rs`): cubic 0.130″, quintic 0.074″
//! against 0.076″ synchronized. Near a gap or the ends of a channel fewer nodes are used.
//! The motion itself (constant speed, ramps) is a low-order polynomial over six samples.
//! Noise is not amplified: the mid-way weights `(3, −25, 150, 150, −25, 3)/256` have a sum of
//! squares of 0.71.
//!
//! Readings may be wrapped to one revolution: the nodes are unwrapped against `s₀`'s reading
//! before interpolating (a shaft turns less than half a revolution between two samples), and
//! where the nodes did wrap the result is wrapped the same way: to `[0, 2π)` if no node reading
//! is negative, else to `[−π, π)`.
//!
//! # What is never done
//! - **Interpolating across a gap**: no interpolation uses two consecutive samples further apart
//!   than the channel's *maximum gap*: [`AlignOptions::max_gap_s`] if given, else
//!   [`DEFAULT_GAP_INTERVALS`] of the channel's median interval (taken over its first
//!   [`GAP_WINDOW`] intervals). An outer node beyond a gap is left out (quadratic or linear
//!   interpolation within the samples on the stamp's side of it); a gap around the stamp
//!   itself drops the sample.
//! - **Extrapolating**: a clock stamp before a channel's first sample or after its last drops
//!   the sample.
//! - **Altering an exact stamp**: where the channel has a sample at exactly the clock's stamp
//!   (to the nanosecond), that reading is taken as it is.
//!
//! Every dropped sample is counted against the channel that could not be aligned
//! ([`ChannelAlignment::dropped`]), so a report says why a log lost samples.
//!
//! # Memory
//! Samples are decided in stamp order as soon as every channel has the samples the interpolation
//! needs. Clock samples wait at most [`ALIGN_QUEUE`] deep for a lagging channel (beyond it the
//! oldest is decided with what is there), and a channel keeps at most [`ALIGN_QUEUE`] samples
//! ahead of the clock, so memory is bounded whatever the log's length.

use std::collections::VecDeque;
use std::f64::consts::PI;

use calib_core::Sample;
use calib_core::angle::{wrap_2pi, wrap_pi};

/// A channel's default maximum gap, in its median sample intervals: one lost message (an
/// interval of two) is bridged, two lost messages are not.
pub const DEFAULT_GAP_INTERVALS: f64 = 2.5;

/// Intervals of a channel from which its median interval is taken.
pub const GAP_WINDOW: usize = 64;

/// Samples of a channel on each side of a clock stamp its reading there is interpolated from.
pub const SIDE: usize = 3;

/// Clock samples that may wait for a lagging channel, and samples a channel may hold ahead of
/// the clock: a minute at 1 kHz, more than any recorder buffers between topics.
pub const ALIGN_QUEUE: usize = 1 << 16;

/// Offsets to the clock kept for the median offset: the first this many aligned samples.
const OFFSET_WINDOW: usize = 1 << 16;

/// How channels on different clocks are aligned.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct AlignOptions {
    /// The longest interval between two samples of a channel that is interpolated across,
    /// seconds; `None`: `DEFAULT_GAP_INTERVALS` (2.5) of each channel's median interval.
    pub max_gap_s: Option<f64>,
}

pub use calib_core::report::{Alignment, ChannelAlignment};

struct ClockEntry {
    ns: i64,
    t: f64,
    value: f64,
    session: Option<u32>,
}

/// One non-clock channel's recent samples and counts.
struct Series {
    samples: VecDeque<(i64, f64)>,
    last: Option<i64>,
    intervals: Vec<i64>,
    max_gap: Option<i64>,
    offsets: Vec<i64>,
    exact: u64,
    interpolated: u64,
    dropped: u64,
    out_of_order: u64,
}

enum Decision {
    Wait,
    Drop,
    Exact(f64),
    Interpolated { value: f64, offset: i64 },
}

impl Series {
    fn new(max_gap: Option<i64>) -> Self {
        Series {
            samples: VecDeque::new(),
            last: None,
            intervals: Vec::new(),
            max_gap,
            offsets: Vec::new(),
            exact: 0,
            interpolated: 0,
            dropped: 0,
            out_of_order: 0,
        }
    }

    fn push(&mut self, ns: i64, value: f64) {
        if let Some(last) = self.last {
            if ns <= last {
                self.out_of_order += 1;
                return;
            }
            if self.max_gap.is_none() {
                self.intervals.push(ns - last);
                if self.intervals.len() >= GAP_WINDOW {
                    self.settle_gap();
                }
            }
        }
        self.last = Some(ns);
        if self.samples.len() >= ALIGN_QUEUE {
            self.samples.pop_front();
        }
        self.samples.push_back((ns, value));
    }

    /// Fixes the maximum gap from the intervals seen (none: only exact stamps align).
    fn settle_gap(&mut self) {
        if self.max_gap.is_some() {
            return;
        }
        let median = if self.intervals.is_empty() {
            0
        } else {
            let mid = self.intervals.len() / 2;
            *self.intervals.select_nth_unstable(mid).1
        };
        self.max_gap = Some((median as f64 * DEFAULT_GAP_INTERVALS).round() as i64);
        self.intervals = Vec::new();
    }

    /// The channel's reading at clock stamp `t`, if it can be had (`finished`: no more samples
    /// will come).
    fn decide(&self, t: i64, finished: bool) -> Decision {
        let s = &self.samples;
        let p = s.partition_point(|&(ns, _)| ns < t);
        if p < s.len() && s[p].0 == t {
            return Decision::Exact(s[p].1);
        }
        let Some(gap) = self.max_gap else {
            return Decision::Wait;
        };
        if p == s.len() {
            return if finished {
                Decision::Drop
            } else {
                Decision::Wait
            };
        }
        if p == 0 {
            return Decision::Drop;
        }
        let (i, j) = (p - 1, p);
        if s[j].0 - s[i].0 > gap {
            return Decision::Drop;
        }
        // Up to SIDE nodes each side, as far as no gap separates them from the stamp.
        let mut hi = j;
        while hi + 1 < s.len() && hi + 1 < j + SIDE && s[hi + 1].0 - s[hi].0 <= gap {
            hi += 1;
        }
        if hi + 1 == s.len() && hi + 1 < j + SIDE && !finished {
            return Decision::Wait;
        }
        let mut lo = i;
        while lo >= 1 && lo + SIDE > i + 1 && s[lo].0 - s[lo - 1].0 <= gap {
            lo -= 1;
        }
        let nodes: Vec<usize> = (lo..=hi).collect();
        let offset = if t - s[i].0 <= s[j].0 - t {
            s[i].0 - t
        } else {
            s[j].0 - t
        };
        Decision::Interpolated {
            value: lagrange(s, &nodes, i, t),
            offset,
        }
    }

    /// Forgets the samples no later clock stamp (≥ `t`) can need: all but the last [`SIDE`] at
    /// or before `t`.
    fn prune(&mut self, t: i64) {
        while self.samples.len() > SIDE && self.samples[SIDE].0 <= t {
            self.samples.pop_front();
        }
    }

    fn report(&self, channel: String) -> ChannelAlignment {
        let median_offset_s = (!self.offsets.is_empty()).then(|| {
            let mut o = self.offsets.clone();
            let mid = o.len() / 2;
            *o.select_nth_unstable(mid).1 as f64 * 1e-9
        });
        ChannelAlignment {
            channel,
            median_offset_s,
            max_gap_s: self.max_gap.unwrap_or(0) as f64 * 1e-9,
            exact: self.exact,
            interpolated: self.interpolated,
            dropped: self.dropped,
            out_of_order: self.out_of_order,
        }
    }
}

/// The Lagrange polynomial through `samples[nodes]` at `t`, readings unwrapped against
/// `samples[base]`'s (see the [module docs](self)). Stamps enter as differences to `t` in
/// nanoseconds: exact in `f64`, where absolute stamps in seconds since 1970 would lose 0.2 µs.
fn lagrange(samples: &VecDeque<(i64, f64)>, nodes: &[usize], base: usize, t: i64) -> f64 {
    let v0 = samples[base].1;
    let mut sum = 0.0;
    let mut wrapped = false;
    let mut lowest = v0;
    for &k in nodes {
        let (sk, vk) = samples[k];
        let d = vk - v0;
        wrapped |= d.abs() > PI;
        lowest = lowest.min(vk);
        let mut weight = 1.0;
        for &m in nodes {
            if m != k {
                let sm = samples[m].0;
                weight *= (t - sm) as f64 / (sk - sm) as f64;
            }
        }
        sum += weight * wrap_pi(d);
    }
    let value = v0 + sum;
    match (wrapped, lowest >= 0.0) {
        (false, _) => value,
        (true, true) => wrap_2pi(value),
        (true, false) => wrap_pi(value),
    }
}

/// Aligns the selected channels of a stream of readings on the first one's stamps (see the
/// [module docs](self)).
pub(crate) struct Aligner {
    /// Raw channel index of each output value; the first is the clock.
    selected: Vec<usize>,
    clock: VecDeque<ClockEntry>,
    /// One per selected channel after the clock.
    series: Vec<Series>,
    finished: bool,
    clock_samples: u64,
    emitted: u64,
    /// The decision for each series on the clock sample being popped, kept between samples so
    /// that popping allocates nothing but the sample's values.
    decisions: Vec<Decision>,
}

impl Aligner {
    /// An aligner of the raw channels `selected` (at least one; the first is the clock).
    pub(crate) fn new(selected: Vec<usize>, opts: AlignOptions) -> Self {
        let max_gap = opts.max_gap_s.map(|g| (g * 1e9).round() as i64);
        let series = (1..selected.len()).map(|_| Series::new(max_gap)).collect();
        Aligner {
            selected,
            clock: VecDeque::new(),
            series,
            finished: false,
            clock_samples: 0,
            emitted: 0,
            decisions: Vec::new(),
        }
    }

    /// Takes one record: `values` holds a reading per raw channel, NaN where the record does not
    /// carry that channel (readers refuse non-finite readings, so NaN means nothing else).
    pub(crate) fn push(&mut self, ns: i64, t: f64, values: &[f64], session: Option<u32>) {
        for (series, &raw) in self.series.iter_mut().zip(&self.selected[1..]) {
            let v = values[raw];
            if !v.is_nan() {
                series.push(ns, v);
            }
        }
        let value = values[self.selected[0]];
        if !value.is_nan() {
            self.clock_samples += 1;
            self.clock.push_back(ClockEntry {
                ns,
                t,
                value,
                session,
            });
        }
    }

    /// No more records will come: every waiting clock sample can now be decided.
    pub(crate) fn finish(&mut self) {
        self.finished = true;
        for series in &mut self.series {
            series.settle_gap();
        }
    }

    /// The next aligned sample, if one can be decided with the records pushed so far.
    pub(crate) fn pop(&mut self) -> Option<Sample> {
        loop {
            let front = self.clock.front()?;
            let force = self.finished || self.clock.len() > ALIGN_QUEUE;
            let decisions = &mut self.decisions;
            decisions.clear();
            for series in &self.series {
                match series.decide(front.ns, self.finished) {
                    Decision::Wait if !force => return None,
                    Decision::Wait => decisions.push(Decision::Drop),
                    d => decisions.push(d),
                }
            }
            let entry = self.clock.pop_front()?;
            let complete = !decisions.iter().any(|d| matches!(d, Decision::Drop));
            let mut values = Vec::with_capacity(self.selected.len());
            values.push(entry.value);
            for (series, decision) in self.series.iter_mut().zip(decisions.drain(..)) {
                match decision {
                    Decision::Drop => series.dropped += 1,
                    Decision::Exact(v) if complete => {
                        series.exact += 1;
                        if series.offsets.len() < OFFSET_WINDOW {
                            series.offsets.push(0);
                        }
                        values.push(v);
                    }
                    Decision::Interpolated { value, offset } if complete => {
                        series.interpolated += 1;
                        if series.offsets.len() < OFFSET_WINDOW {
                            series.offsets.push(offset);
                        }
                        values.push(value);
                    }
                    _ => {}
                }
                series.prune(entry.ns);
            }
            if complete {
                self.emitted += 1;
                return Some(Sample {
                    t: entry.t,
                    values,
                    session: entry.session,
                });
            }
        }
    }

    /// The raw channels that have had no reading so far (complete once the stream has ended):
    /// a column empty in every row, which leaves nothing to align the others with.
    pub(crate) fn without_readings(&self) -> Vec<usize> {
        let clock = (self.clock_samples == 0).then_some(self.selected[0]);
        let others = self
            .series
            .iter()
            .zip(&self.selected[1..])
            .filter(|(s, _)| s.last.is_none())
            .map(|(_, &raw)| raw);
        clock.into_iter().chain(others).collect()
    }

    /// How the channels were aligned so far (complete once the stream has ended), the channels
    /// named by `names` (indexed by raw channel).
    pub(crate) fn report(&self, names: &[String]) -> Alignment {
        Alignment {
            clock: names[self.selected[0]].clone(),
            clock_samples: self.clock_samples,
            samples: self.emitted,
            channels: self
                .series
                .iter()
                .zip(&self.selected[1..])
                .map(|(s, &raw)| s.report(names[raw].clone()))
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    const NAN: f64 = f64::NAN;

    fn run(aligner: &mut Aligner, records: &[(i64, [f64; 2])]) -> Vec<Sample> {
        let mut out = Vec::new();
        for &(ns, v) in records {
            aligner.push(ns, ns as f64 * 1e-9, &v, None);
            out.extend(std::iter::from_fn(|| aligner.pop()));
        }
        aligner.finish();
        out.extend(std::iter::from_fn(|| aligner.pop()));
        out
    }

    #[test]
    fn interpolation_is_exact_for_cubics_at_jittered_stamps() {
        // A cubic in time is reproduced exactly by Lagrange interpolation through four or more
        // nodes, whatever their spacing: the check of the weights.
        // Small steps between samples (< 0.2 rad), as of a turning shaft.
        let f = |t: f64| 0.3 + 0.02 * t - 1e-4 * t * t + 1e-6 * t * t * t;
        let mut records = Vec::new();
        // The other channel runs two samples longer, so every clock stamp has four nodes.
        for k in 0..202i64 {
            let clock = k * 1_000_000;
            let other = clock + 375_000 + (k % 3 - 1) * 125_000;
            if k < 200 {
                records.push((clock, [f(clock as f64 * 1e-6), NAN]));
            }
            records.push((other, [NAN, f(other as f64 * 1e-6)]));
        }
        let mut a = Aligner::new(vec![0, 1], AlignOptions::default());
        let out = run(&mut a, &records);
        // The first clock stamp precedes the other channel's first sample: not extrapolated.
        assert_eq!(out.len(), 199);
        for s in &out {
            let want = f(s.t * 1e3);
            // Rounding only: values below 10 summed over four nodes with weights below 2.
            assert!((s.values[1] - want).abs() < 1e-12, "{} {want}", s.values[1]);
        }
        let r = a.report(&["a".into(), "b".into()]);
        assert_eq!(r.channels[0].dropped, 1);
        assert_eq!(r.channels[0].interpolated, 199);
        // The nearest sample lies +0.25, +0.375 or +0.5 ms after each clock stamp, in turn.
        assert_eq!(r.channels[0].median_offset_s, Some(375e-6));
    }

    #[test]
    fn exact_stamps_stay_exact_and_gaps_are_not_bridged() {
        let mut records = Vec::new();
        for k in 0..100i64 {
            let ns = k * 10;
            // The other channel misses k = 40..=44 (a gap of 6 intervals).
            let other = if (40..=44).contains(&k) {
                NAN
            } else {
                k as f64
            };
            records.push((ns, [k as f64, other]));
        }
        let mut a = Aligner::new(vec![0, 1], AlignOptions::default());
        let out = run(&mut a, &records);
        assert_eq!(out.len(), 95);
        assert!(out.iter().all(|s| s.values[0] == s.values[1]));
        let r = a.report(&["a".into(), "b".into()]);
        assert_eq!((r.channels[0].exact, r.channels[0].dropped), (95, 5));
        assert_eq!(r.channels[0].interpolated, 0);
        // A user-given gap of 7 intervals bridges it.
        let mut a = Aligner::new(
            vec![0, 1],
            AlignOptions {
                max_gap_s: Some(70e-9),
            },
        );
        assert_eq!(run(&mut a, &records).len(), 100);
    }

    /// A channel without a single reading leaves no sample to align on, and is named: as the
    /// clock (nothing to emit) or as another channel (every clock sample dropped).
    #[test]
    fn channels_without_readings_are_named() {
        let records: Vec<(i64, [f64; 2])> = (0..50i64).map(|k| (k * 10, [k as f64, NAN])).collect();
        for (selected, empty) in [(vec![0, 1], vec![1]), (vec![1, 0], vec![1])] {
            let mut a = Aligner::new(selected, AlignOptions::default());
            assert!(run(&mut a, &records).is_empty());
            assert_eq!(a.without_readings(), empty);
        }
        let full: Vec<(i64, [f64; 2])> = (0..50i64).map(|k| (k * 10, [k as f64; 2])).collect();
        let mut a = Aligner::new(vec![0, 1], AlignOptions::default());
        assert_eq!(run(&mut a, &full).len(), 50);
        assert!(a.without_readings().is_empty());
    }

    #[test]
    fn wrapped_readings_interpolate_across_the_wrap() {
        // A shaft at 1 rad per unit time read wrapped to [0, 2π); the other channel samples
        // half-way.
        let wrap = |x: f64| x.rem_euclid(TAU);
        let mut records = Vec::new();
        for k in 0..40i64 {
            records.push((k * 1000, [wrap(k as f64 * 0.5), NAN]));
            records.push((k * 1000 + 500, [NAN, wrap(k as f64 * 0.5 + 0.25)]));
        }
        let mut a = Aligner::new(vec![0, 1], AlignOptions::default());
        let out = run(&mut a, &records);
        assert_eq!(out.len(), 39);
        for s in &out {
            // b reads the same shaft: equal to a, in [0, 2π).
            assert!((0.0..TAU).contains(&s.values[1]), "{}", s.values[1]);
            assert!(wrap_pi(s.values[1] - s.values[0]).abs() < 1e-12);
        }
    }
}
