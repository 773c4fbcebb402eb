//! What a log holds, for a user to check before calibrating (`calib inspect`).
//!
//! [`Inspector`] streams over the samples once and gathers, per channel, the range and the
//! revolutions travelled; for the log, the exact sample count, duration, mean sample interval
//! and its jitter, gaps and non-monotonic stamps; for a chosen pair of channels, the segments
//! (stationary, co-rotating with their relative angle — the CSRR sessions —, turning); and the
//! speed variation over a revolution as a spectrum in cycles per revolution.
//!
//! The speed spectrum comes from `Σdθ/Σdt` in 1024 bins of each channel's own reading, over the
//! samples where the channel moves within ±19 % of the speed it mostly turns at. It shows the sampling non-uniformity ε_θ of the seed paper
//! (Gou et al., eq. 9) in the form a user can act on: a speed ripple of `p` % at order `h` is a
//! position modulation of amplitude `p/100/h` rad. Computed from a sensor's own readings, it also
//! contains that sensor's error slope `e'(θ)`: read it from a reference encoder where there is one.

use crate::angle::{ARCSEC_PER_RAD, Unwrapper, wrap_2pi};
use crate::sample::Channel;
use crate::segment::{Segment, SegmentOptions, Segmenter};
use realfft::RealFftPlanner;
use std::f64::consts::TAU;

/// Bins of the speed-over-angle profile.
const SPEED_BINS: usize = 1024;
/// Samples from which the nominal interval is taken (median), before gaps are judged.
const NOMINAL_WINDOW: usize = 257;
/// Events (gaps, backward stamps) listed individually; the rest are only counted.
const LISTED: usize = 20;

/// Per-channel findings.
#[derive(Debug, Clone, PartialEq, serde::Serialize, schemars::JsonSchema)]
pub struct ChannelStats {
    /// Name.
    pub name: String,
    /// Unit of the log's readings.
    pub unit: String,
    /// Smallest reading, in the log's unit.
    pub min: f64,
    /// Largest reading, in the log's unit.
    pub max: f64,
    /// Net revolutions travelled (signed), readings unwrapped.
    pub revolutions: f64,
    /// Total revolutions travelled in either direction.
    pub travel_revolutions: f64,
    /// Whether the readings wrap (jump by about a revolution somewhere).
    pub wrapped: bool,
    /// Largest orders of the speed variation over a revolution, largest first.
    pub speed_spectrum: Vec<SpeedHarmonic>,
}

/// One order of the speed variation over a revolution.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, schemars::JsonSchema)]
pub struct SpeedHarmonic {
    /// Cycles per revolution.
    pub order: usize,
    /// Speed ripple, percent of the mean speed.
    pub speed_percent: f64,
    /// The same as a position modulation `m_h` (paper eq. 9), arcsec.
    pub position_arcsec: f64,
}

/// A time-stamp event: a gap or a step backwards.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, schemars::JsonSchema)]
pub struct StampEvent {
    /// 0-based index of the sample after the event.
    pub index: u64,
    /// Its time stamp, s.
    pub t: f64,
    /// The step from the previous stamp, s.
    pub step_s: f64,
}

impl Inspection {
    /// The inspection with its times on the log's own clock: the times the inspector was given
    /// plus `origin_s`, the stamp they were counted from (readers count stamps since 1970 from
    /// the first one's second, to keep their nanoseconds in a double).
    pub fn with_time_origin(mut self, origin_s: f64) -> Self {
        self.start_s += origin_s;
        self.end_s += origin_s;
        for e in self.gap_list.iter_mut().chain(&mut self.non_monotonic_list) {
            e.t += origin_s;
        }
        for s in &mut self.segments {
            s.start_s += origin_s;
            s.end_s += origin_s;
        }
        self
    }
}

/// Everything `inspect` found.
#[derive(Debug, Clone, PartialEq, serde::Serialize, schemars::JsonSchema)]
pub struct Inspection {
    /// Samples.
    pub samples: u64,
    /// First stamp, s.
    pub start_s: f64,
    /// Last stamp, s.
    pub end_s: f64,
    /// Mean sample rate, Hz.
    pub rate_hz: f64,
    /// Standard deviation of the sample interval, s.
    pub interval_jitter_s: f64,
    /// Intervals longer than twice the nominal one.
    pub gaps: u64,
    /// The first gaps.
    pub gap_list: Vec<StampEvent>,
    /// Stamps equal to or before the previous one.
    pub non_monotonic: u64,
    /// The first of those.
    pub non_monotonic_list: Vec<StampEvent>,
    /// Per channel.
    pub channels: Vec<ChannelStats>,
    /// The pair of channels segmented, if any.
    pub pair: Option<(String, String)>,
    /// Segments of the pair.
    pub segments: Vec<Segment>,
}

#[derive(Debug, Clone)]
struct ChannelAcc {
    min: f64,
    max: f64,
    unwrap: Unwrapper,
    first: Option<f64>,
    last_unwrapped: f64,
    last_raw: f64,
    travel: f64,
    wrapped: bool,
    /// Speed profiles per speed class (see [`SpeedProfiles`]).
    profiles: SpeedProfiles,
}

/// Angle-binned `Σdθ` and `Σdt`, kept separately for speed classes 9 % wide (2^(1/8)), so that
/// the profile can be taken at the speed the log mostly turns at: ramps and other speeds fall in
/// other classes and do not masquerade as speed variation over the revolution.
#[derive(Debug, Clone, Default)]
struct SpeedProfiles {
    /// Each class met, and where its profile is in `profiles`.
    classes: std::collections::BTreeMap<i32, usize>,
    /// Per class met, angle-binned `(Σdθ, Σdt)`.
    profiles: Vec<(Vec<f64>, Vec<f64>)>,
    /// The last class met (its profile's index) and the least and greatest speeds seen in it:
    /// a speed between two of one class is in that class (the logarithm is monotonic), so most
    /// samples need neither the logarithm nor the lookup.
    last: Option<(usize, f64, f64)>,
}

impl SpeedProfiles {
    fn add(&mut self, bin: usize, dtheta: f64, dt: f64) {
        let speed = dtheta / dt;
        let k = match self.last {
            Some((k, lo, hi)) if lo <= speed && speed <= hi => k,
            last => {
                let class = (speed.log2() * 8.0).floor() as i32;
                let next = self.profiles.len();
                let k = *self.classes.entry(class).or_insert(next);
                if k == next {
                    self.profiles
                        .push((vec![0.0; SPEED_BINS], vec![0.0; SPEED_BINS]));
                }
                self.last = Some(match last {
                    Some((l, lo, hi)) if l == k => (k, lo.min(speed), hi.max(speed)),
                    _ => (k, speed, speed),
                });
                k
            }
        };
        let (a, t) = &mut self.profiles[k];
        a[bin] += dtheta;
        t[bin] += dt;
    }
    /// The classes within ±2 (±19 %) of the one that holds the most time.
    fn cruise(&self) -> Option<(Vec<f64>, Vec<f64>)> {
        let time = |k: &usize| self.profiles[*k].1.iter().sum::<f64>();
        let busiest = *self
            .classes
            .iter()
            .max_by(|x, y| time(x.1).total_cmp(&time(y.1)))?
            .0;
        let mut a = vec![0.0; SPEED_BINS];
        let mut t = vec![0.0; SPEED_BINS];
        for (_, k) in self.classes.range(busiest - 2..=busiest + 2) {
            let (ca, ct) = &self.profiles[*k];
            a.iter_mut().zip(ca).for_each(|(x, y)| *x += y);
            t.iter_mut().zip(ct).for_each(|(x, y)| *x += y);
        }
        Some((a, t))
    }
}

/// Streaming inspection of a log: [`Inspector::push`] every sample, then [`Inspector::finish`].
#[derive(Debug)]
pub struct Inspector {
    channels: Vec<Channel>,
    acc: Vec<ChannelAcc>,
    pair: Option<(usize, usize)>,
    segmenter: Option<Segmenter>,
    min_speed: f64,
    samples: u64,
    start: f64,
    last_t: f64,
    nominal: Option<f64>,
    first_steps: Vec<f64>,
    step_sum: f64,
    step_sq: f64,
    steps: u64,
    gaps: u64,
    gap_list: Vec<StampEvent>,
    backward: u64,
    backward_list: Vec<StampEvent>,
}

impl Inspector {
    /// An inspector of a log with these channels; `pair` (indices) is segmented into
    /// stationary, rotating and turning segments.
    pub fn new(
        channels: &[Channel],
        pair: Option<(usize, usize)>,
        segments: SegmentOptions,
    ) -> Self {
        let acc = ChannelAcc {
            min: f64::INFINITY,
            max: f64::NEG_INFINITY,
            unwrap: Unwrapper::new(),
            first: None,
            last_unwrapped: 0.0,
            last_raw: 0.0,
            travel: 0.0,
            wrapped: false,
            profiles: SpeedProfiles::default(),
        };
        Inspector {
            acc: vec![acc; channels.len()],
            channels: channels.to_vec(),
            pair,
            segmenter: pair.map(|_| Segmenter::new(segments)),
            min_speed: segments.min_speed,
            samples: 0,
            start: 0.0,
            last_t: 0.0,
            nominal: None,
            first_steps: Vec::new(),
            step_sum: 0.0,
            step_sq: 0.0,
            steps: 0,
            gaps: 0,
            gap_list: Vec::new(),
            backward: 0,
            backward_list: Vec::new(),
        }
    }

    /// Feeds one sample (readings in radians, in the channel order given to [`Inspector::new`]).
    pub fn push(&mut self, t: f64, values: &[f64], mark: Option<u32>) {
        let index = self.samples;
        let dt = t - self.last_t;
        if self.samples == 0 {
            self.start = t;
        } else {
            if dt <= 0.0 {
                self.backward += 1;
                if self.backward_list.len() < LISTED {
                    self.backward_list.push(StampEvent {
                        index,
                        t,
                        step_s: dt,
                    });
                }
            } else {
                self.step_sum += dt;
                self.step_sq += dt * dt;
                self.steps += 1;
                match self.nominal {
                    None => {
                        self.first_steps.push(dt);
                        if self.first_steps.len() == NOMINAL_WINDOW {
                            self.first_steps.sort_by(f64::total_cmp);
                            self.nominal = Some(self.first_steps[NOMINAL_WINDOW / 2]);
                        }
                    }
                    Some(nominal) if dt > 2.0 * nominal => {
                        self.gaps += 1;
                        if self.gap_list.len() < LISTED {
                            self.gap_list.push(StampEvent {
                                index,
                                t,
                                step_s: dt,
                            });
                        }
                    }
                    Some(_) => {}
                }
            }
        }
        // A gap's interval says nothing about the speed at one angle: leave it out of the profile.
        let steady = dt > 0.0 && self.nominal.is_none_or(|nominal| dt <= 2.0 * nominal);
        for (acc, &v) in self.acc.iter_mut().zip(values) {
            acc.min = acc.min.min(v);
            acc.max = acc.max.max(v);
            let u = acc.unwrap.unwrap(v);
            if let Some(_first) = acc.first {
                let step = u - acc.last_unwrapped;
                acc.travel += step.abs();
                if (v - acc.last_raw).abs() > std::f64::consts::PI {
                    acc.wrapped = true;
                }
                if steady && (step / dt).abs() >= self.min_speed {
                    let bin = ((wrap_2pi(acc.last_raw + 0.5 * step) / TAU * SPEED_BINS as f64)
                        as usize)
                        .min(SPEED_BINS - 1);
                    acc.profiles.add(bin, step.abs(), dt);
                }
            } else {
                acc.first = Some(u);
            }
            acc.last_unwrapped = u;
            acc.last_raw = v;
        }
        if let (Some(seg), Some((a, b))) = (&mut self.segmenter, self.pair) {
            seg.push(t, values[a], values[b], mark, &[], &mut ());
        }
        self.samples += 1;
        self.last_t = t;
    }

    /// The findings.
    pub fn finish(mut self) -> Inspection {
        if self.nominal.is_none() && !self.first_steps.is_empty() {
            // Short log: judge gaps against the median of what there is.
            let mut steps = self.first_steps.clone();
            steps.sort_by(f64::total_cmp);
            let nominal = steps[steps.len() / 2];
            let first = self.start;
            let mut t = first;
            for (i, &dt) in self.first_steps.iter().enumerate() {
                t += dt;
                if dt > 2.0 * nominal {
                    self.gaps += 1;
                    self.gap_list.push(StampEvent {
                        index: i as u64 + 1,
                        t,
                        step_s: dt,
                    });
                }
            }
        }
        let mean_step = if self.steps > 0 {
            self.step_sum / self.steps as f64
        } else {
            0.0
        };
        let var = if self.steps > 1 {
            (self.step_sq / self.steps as f64 - mean_step * mean_step).max(0.0)
        } else {
            0.0
        };
        let segments = self
            .segmenter
            .take()
            .map(|s| s.finish(&mut ()).segments)
            .unwrap_or_default();
        let channels = self
            .channels
            .iter()
            .zip(&self.acc)
            .map(|(c, a)| ChannelStats {
                name: c.name.clone(),
                unit: c.unit.to_string(),
                min: if a.first.is_some() {
                    c.unit.from_rad(a.min)
                } else {
                    0.0
                },
                max: if a.first.is_some() {
                    c.unit.from_rad(a.max)
                } else {
                    0.0
                },
                revolutions: a.first.map_or(0.0, |f| (a.last_unwrapped - f) / TAU),
                travel_revolutions: a.travel / TAU,
                wrapped: a.wrapped,
                speed_spectrum: a
                    .profiles
                    .cruise()
                    .map(|(angle, time)| speed_spectrum(&angle, &time))
                    .unwrap_or_default(),
            })
            .collect();
        Inspection {
            samples: self.samples,
            start_s: self.start,
            end_s: self.last_t,
            rate_hz: if mean_step > 0.0 {
                1.0 / mean_step
            } else {
                0.0
            },
            interval_jitter_s: var.sqrt(),
            gaps: self.gaps,
            gap_list: self.gap_list,
            non_monotonic: self.backward,
            non_monotonic_list: self.backward_list,
            pair: self
                .pair
                .map(|(a, b)| (self.channels[a].name.clone(), self.channels[b].name.clone())),
            segments,
            channels,
        }
    }
}

/// The 8 largest orders of the relative speed profile `v(θ)/v̄ − 1`. Neighbouring bins are
/// merged (1024 → 512 → … → 16) until every bin was visited, so sparse logs still get the
/// low orders.
fn speed_spectrum(angle_sum: &[f64], time_sum: &[f64]) -> Vec<SpeedHarmonic> {
    let (mut angle_sum, mut time_sum) = (angle_sum.to_vec(), time_sum.to_vec());
    while time_sum.iter().any(|&t| t <= 0.0) {
        if angle_sum.len() <= 16 {
            return Vec::new();
        }
        let pairs = |v: &[f64]| v.chunks(2).map(|c| c.iter().sum()).collect::<Vec<f64>>();
        angle_sum = pairs(&angle_sum);
        time_sum = pairs(&time_sum);
    }
    let speed: Vec<f64> = angle_sum.iter().zip(time_sum).map(|(a, t)| a / t).collect();
    let mean = speed.iter().sum::<f64>() / speed.len() as f64;
    let mut rel: Vec<f64> = speed.iter().map(|v| v / mean - 1.0).collect();
    let n = rel.len();
    let fft = RealFftPlanner::<f64>::new().plan_fft_forward(n);
    let mut spec = fft.make_output_vec();
    if fft.process(&mut rel, &mut spec).is_err() {
        return Vec::new();
    }
    let mut out: Vec<SpeedHarmonic> = (1..n / 2)
        .map(|h| {
            let amp = 2.0 * spec[h].norm() / n as f64;
            SpeedHarmonic {
                order: h,
                speed_percent: 100.0 * amp,
                position_arcsec: amp / h as f64 * ARCSEC_PER_RAD,
            }
        })
        .collect();
    out.sort_by(|a, b| b.speed_percent.total_cmp(&a.speed_percent));
    out.truncate(8);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::angle::AngleUnit;
    use crate::segment::SegmentKind;

    #[test]
    fn finds_rate_gaps_segments_and_speed_ripple() {
        let ch = |n: &str| Channel {
            name: n.into(),
            unit: AngleUnit::Deg,
        };
        let mut ins = Inspector::new(&[ch("a"), ch("b")], Some((0, 1)), SegmentOptions::default());
        let rate = 1000.0;
        let omega = TAU; // 1 r/s
        let ripple = 0.02; // 2 % speed ripple at order 3
        let mut t = 0.0;
        let mut n = 0u64;
        // 4 s rotating with a relative angle of 10°, 1 s still, 3 s rotating at 50°.
        let mut theta = 0.0;
        for (dur, rel, moving) in [(4.0, 10f64, true), (1.0, 10.0, false), (3.0, 50.0, true)] {
            let steps = (dur * rate) as usize;
            for _ in 0..steps {
                if n == 2500 {
                    t += 0.01; // a gap of ten intervals
                }
                ins.push(
                    t,
                    &[wrap_2pi(theta), wrap_2pi(theta - rel.to_radians())],
                    None,
                );
                if moving {
                    // dθ/dt = ω(1 + r cos 3θ)
                    theta += omega * (1.0 + ripple * (3.0 * theta).cos()) / rate;
                }
                t += 1.0 / rate;
                n += 1;
            }
        }
        let r = ins.finish();
        assert_eq!(r.samples, 8000);
        assert_eq!(r.gaps, 1);
        assert!((r.rate_hz - 1000.0).abs() < 2.0, "{}", r.rate_hz);
        let rotating: Vec<_> = r
            .segments
            .iter()
            .filter(|s| s.kind == SegmentKind::Rotating)
            .collect();
        assert_eq!(rotating.len(), 2, "{:?}", r.segments);
        assert!((rotating[1].relative_angle.to_degrees() - 50.0).abs() < 1e-6);
        let top = r.channels[0].speed_spectrum[0];
        assert_eq!(top.order, 3);
        // The profile is sampled in 1024 bins: the ripple is recovered to well under 1 %.
        assert!((top.speed_percent - 2.0).abs() < 0.02, "{top:?}");
        assert!(r.channels[0].wrapped);
        assert!((r.channels[0].revolutions - 7.0).abs() < 0.1);
    }
}
