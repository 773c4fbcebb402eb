//! The run simulator: realistic recorded runs with a known truth, for tests, benches, and for
//! planning experiments.
//!
//! A [`Scenario`] (read by the CLI from a TOML file) describes a rig — sensors with their
//! systematic errors, resolution and noise, the driven shaft's speed non-uniformity — and the
//! CSRR procedure of Gou et al. (the CSRR paper, section III-B). [`Scenario::samples`] streams
//! the log it would record, one [`Sample`] at a time (10⁸ samples never sit in memory), and
//! [`Scenario::truth`] gives every channel's true [`ErrorMap`] to compare a calibration with.
//!
//! # Model
//! - **Shaft** (rotor B, driven): nominal angle `φ(t)` from the procedure's timeline (pauses,
//!   raised-cosine ramps, constant speed); true angle `θ_B = φ + ε_θ(φ)` with the sampling
//!   non-uniformity of eq. (9), `ε_θ(φ) = Σ m_Ω cos(Ω·φ + ψ_Ω)`, periodic per revolution
//!   ([`Speed`]).
//! - **Rotor A** is locked to the shaft at the session's relative rotation `Δ_k`:
//!   `θ_A = θ_B + Δ_k`, so the CSRR equation `e_a(x) − e_b(y) + Δ_k = wrap(x − y)` holds for
//!   readings `x` of a sensor on A and `y` of one on B (eq. 2 with `Δ_ab = −Δ_k`, the paper's
//!   sign being the other way round). Between sessions, with the shaft at rest, A turns from
//!   `Δ_{k−1}` to `Δ_k` in `turn_s`.
//! - **Sensor** on rotor `m` with error `e(θ)` (eq. 1, `f(θ) = θ + ε(θ)`): reading
//!   `= Q(θ_m + e(θ_m) + n)`, `n` Gaussian noise, `Q` rounding to the resolution, then wrapped
//!   to `[0, 2π)` if [`Scenario::wrap`]. Readings reach the core in radians
//!   ([`crate::AngleUnit::Rad`]).
//! - **Spin-down** (`[spin_down]`, replacing `[procedure]`, for `calib tdr`): the shaft
//!   coasts freely from `speed_rpm`, `dω/dt = −(c₀ + c₁ω + c₂ω²) − Σ a_h cos(hθ + φ_h)`, the
//!   last sum an angle-dependent drag (rolling bearings, cogging), integrated by RK4 on a fine
//!   grid ([`SpinDown`]). For example:
//!   ```toml
//!   [spin_down]
//!   speed_rpm = 600.0         # speed at t = 0, the drive just released
//!   duration_s = 20.0         # recorded coast (at rest once the speed reaches 0)
//!   friction = { coulomb = 0.0, viscous = 0.02, quadratic = 1e-4 }  # rad/s², 1/s, 1/rad
//!   drag_harmonics = [{ order = 2, amplitude = 0.05, phase_deg = 30.0 }]  # rad/s²
//!   ```
//!   With `drive` (a motor at constant voltage, [`Drive`]) the acceleration gains
//!   `(ω_v − ω)/τ`: a driven run at steady speed, for `calib tdr` on a driven motor
//!   (`testdata/scenarios/driven.toml`).
//! - **Sweep** (`[sweep]`, replacing `[procedure]`, for a joint that never turns a whole
//!   revolution): strokes `from_deg → to_deg → from_deg …` at a list of speeds with
//!   raised-cosine ramps and pauses ([`Sweep`]); [`Scenario::range_truth`] gives each channel's
//!   truth over the readings it swept.
//! - **Heads on a shared scale**: a head at nominal `α` with angle error `δ` reads
//!   `s + e_s(s) − α` at scale position `s = θ + α + δ` ([`Sensor`]).
//!
//! # Truth
//! The interface's maps are functions of the sensor's *own reading*. The reading follows
//! `r = θ + e(θ)` exactly, so the truth at reading `r` is `r − θ` with `θ` solving
//! `θ + e(θ) = r` (safeguarded Newton, exact to rounding). Validation requires
//! `Σ order·|amplitude| < 1`, which bounds `|e′| < 1` and makes `θ ↦ θ + e(θ)` strictly
//! increasing, so the inverse exists. For errors of hundreds of arcseconds at high orders (the
//! paper's 84-pole-pair sensor) the reading-domain map holds many more orders than `e` itself;
//! that is the truth a calibration must match, not `e` evaluated at the reading.
//!
//! # Determinism
//! Noise and jitter come from a hand-written xoshiro256++ with one stream per channel: a seed
//! fixes the random draws on every platform and calib version, and adding a sensor leaves the
//! others' noise unchanged. Samples are then bit-identical for a seed on one platform; across
//! platforms they may differ in the last bits, where the system's `cos`/`ln` round differently.
//!
//! # Scenario files
//! Every table rejects unknown keys. A complete example, each key annotated (values are the
//! defaults where a key is optional):
//!
//! ```
//! use calib_core::simulate::Scenario;
//!
//! let scenario: Scenario = toml::from_str(r#"
//! seed = 1                  # noise and jitter seed
//! rate_hz = 400.0           # sample rate, Hz
//! speed_rpm = 10.0          # nominal shaft speed while turning
//! wrap = true               # readings in [0, 360°) (false: accumulated)
//! time_jitter_s = 0.0       # σ of the true sampling instant around n/rate_hz
//! mark_sessions = false     # true: samples of session k's constant-speed turns get session = k
//!
//! [speed]                   # driven shaft non-uniformity, eq. (9): θ = φ + Σ m cos(Ωφ + ψ)
//! variation_percent = 1.0   # ±1 % speed ripple once per revolution (order 1, m = 0.01 rad)
//! [[speed.harmonic]]        # more position-modulation terms, e.g. Table III
//! order = 45
//! amplitude_arcsec = 17.06
//! phase_deg = 0.0
//!
//! [[sensor]]                # sensor under test on rotor A
//! name = "a"                # channel name
//! mount = "a"               # rotor A; "b" (default) is the driven shaft
//! harmonics = [             # e(θ) = Σ amplitude·cos(order·θ + phase), θ its true angle
//!   { order = 72, amplitude_arcsec = 23.87, phase_deg = 30.0 },
//!   { order = 1, amplitude_arcsec = 2.34, phase_deg = -60.0 },
//! ]
//! quantization_arcsec = 0.09  # resolution (0: none)
//! noise_arcsec = 0.05       # σ of Gaussian reading noise
//!
//! [[sensor]]
//! name = "b"
//! mount = "b"
//! harmonics = [{ order = 72, amplitude_arcsec = 22.0, phase_deg = 100.0 }]
//! quantization_arcsec = 0.09
//! noise_arcsec = 0.05
//!
//! [[scale]]                 # a graduated disc shared by heads
//! name = "disc"
//! mount = "b"
//! harmonics = [{ order = 2, amplitude_arcsec = 1.0, phase_deg = 0.0 }]
//!
//! [[sensor]]                # a head reading the disc: error δ + e_s(θ + α + δ)
//! name = "head90"
//! scale = "disc"
//! head_deg = 90.0           # nominal head angle α
//! head_error_arcsec = 3.0   # actual − nominal head angle δ
//! quantization_arcsec = 0.01
//!
//! [procedure]               # CSRR, section III-B
//! relative_deg = [0.0, 7.3, 23.9, 61.7, 151.1]  # Δ_k = θ_A − θ_B per session
//! revolutions = 3.0         # constant-speed revolutions per session
//! ramp_s = 1.0              # raised-cosine speed ramp at each start and stop
//! pause_s = 1.0             # at rest before/after each session and after each turn
//! turn_s = 2.0              # relative turn of rotor A, shaft at rest
//! ## or per session: [[procedure.sessions]] with relative_deg and optional revolutions,
//! ## speed_rpm and backward = true (the shaft turns the other way)
//! "#)?;
//! scenario.validate()?;
//! assert_eq!(scenario.channels().len(), 3);
//! let samples = scenario.samples()?;
//! let n = samples.len();
//! assert_eq!(samples.count(), n);
//! let truth = scenario.truth(3600)?;
//! assert_eq!(truth[0].0, "a");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # Not simulated
//! Relative-rotation (eccentricity) errors of eq. (8), drifts, and speed variation that is not
//! locked to the shaft's position.

mod motion;
pub(crate) mod rng;
mod scenario;
mod sensor;
mod spindown;
mod sweep;

pub use scenario::{
    DragHarmonic, Drive, DriveStep, Friction, HarmonicSpec, Mount, Procedure, Scale, Scenario,
    ScenarioError, Sensor, SessionSpec, Speed, SpinDown, Sweep,
};
pub use sensor::SensorTruth;

use crate::angle::{ARCSEC_PER_RAD, AngleUnit, DEG_PER_RAD, wrap_2pi};
use crate::error_map::ErrorMap;
use crate::range_map::RangeMap;
use crate::sample::{Channel, Sample};
use motion::{SessionPlan, State, Timeline, Timing};
use rng::Rng;
use sensor::{ErrorModel, FastSeries, Powers, Term};
use spindown::{Coast, ConstantVoltage};
use std::f64::consts::TAU;
use sweep::SweepTimeline;

fn terms(harmonics: &[HarmonicSpec]) -> Vec<Term> {
    harmonics
        .iter()
        .map(|h| Term {
            order: f64::from(h.order),
            amplitude: h.amplitude_arcsec / ARCSEC_PER_RAD,
            phase: h.phase_deg / DEG_PER_RAD,
        })
        .collect()
}

/// The RNG stream of the sampling-time jitter; channel `i` uses stream `i + 1`.
const JITTER_STREAM: u64 = 0;
/// The RNG stream of a random sweep's strokes.
const MOTION_STREAM: u64 = u64::MAX;

impl Scenario {
    /// The log's channels, one per `[[sensor]]` in file order, readings in radians.
    pub fn channels(&self) -> Vec<Channel> {
        self.sensors
            .iter()
            .map(|s| Channel {
                name: s.name.clone(),
                unit: AngleUnit::Rad,
            })
            .collect()
    }

    /// Every channel's truth (error model and its inversion), in channel order.
    pub fn sensor_truths(&self) -> Result<Vec<SensorTruth>, ScenarioError> {
        self.validate()?;
        Ok(self.sensors.iter().map(|s| self.truth_of(s)).collect())
    }

    /// Every channel's true error map as a function of its own reading, on `points` grid points
    /// (`angle = i·360°/points`), mean removed: `(channel name, map)` in channel order.
    pub fn truth(&self, points: usize) -> Result<Vec<(String, ErrorMap)>, ScenarioError> {
        if points == 0 {
            return Err(ScenarioError::InvalidValue {
                field: "points".into(),
                value: 0.0,
                expected: "≥ 1",
            });
        }
        Ok(self
            .sensor_truths()?
            .into_iter()
            .map(|t| {
                let map = t.map(points);
                (t.name, map)
            })
            .collect())
    }

    /// The recorded run, streamed: one [`Sample`] per `1/rate_hz` from `t = 0` until the
    /// procedure ends (at rest). Nothing is buffered; the iterator knows its exact length.
    pub fn samples(&self) -> Result<Samples, ScenarioError> {
        self.validate()?;
        let (motion, windows) = match (&self.sweep, &self.spin_down) {
            (Some(sw), _) => (Motion::Sweep(self.sweep_timeline(sw)), Vec::new()),
            (None, Some(sd)) => (Motion::Coast(self.coast(sd)), Vec::new()),
            (None, None) => {
                let timeline = self.timeline();
                // Sessions are marked by sample index: sample n belongs to a window [t0, t1)
                // when t0 ≤ n/rate < t1. A boundary within 1e-6 of a sample period of a sample
                // instant counts as at it, so that rounding in t0 and t1 neither drops nor adds
                // the boundary samples of a whole number of sample periods.
                let index = |t: f64| (t * self.rate_hz - 1e-6).ceil().max(0.0) as u64;
                let windows = timeline
                    .session_windows()
                    .into_iter()
                    .map(|(t0, t1)| (index(t0), index(t1)))
                    .collect();
                (Motion::Procedure(timeline), windows)
            }
        };
        // Samples at n/rate for every n with n/rate ≤ duration (float-to-int saturates).
        let count = (motion.duration() * self.rate_hz).floor() as u64 + 1;
        let channels: Vec<ChannelSim> = self
            .sensors
            .iter()
            .zip(1u64..)
            .map(|(s, stream)| {
                let model = self.truth_of(s).model;
                ChannelSim {
                    mount: self.mount_of(s),
                    offset: model.offset,
                    series: FastSeries::new(&model.terms),
                    quantum: s.quantization_arcsec / ARCSEC_PER_RAD,
                    noise: s.noise_arcsec / ARCSEC_PER_RAD,
                    rng: Rng::new(self.seed, stream),
                    delay: s.delay_s,
                    half_play: 0.5 * s.backlash_arcsec / ARCSEC_PER_RAD,
                    follower: None,
                    commanded: s.commanded,
                    ratio: s.ratio,
                }
            })
            .collect();
        let need = |mount| channel_powers_needed(&channels, mount);
        let (need_a, need_b) = (need(Mount::A), need(Mount::B));
        Ok(Samples {
            motion,
            need_a,
            need_b,
            powers_a: Powers::default(),
            powers_b: Powers::default(),
            powers_scratch: Powers::default(),
            rotation: None,
            windows,
            window: 0,
            channels,
            next: 0,
            count,
            rate_hz: self.rate_hz,
            jitter_s: self.time_jitter_s,
            jitter_rng: Rng::new(self.seed, JITTER_STREAM),
            wrap: self.wrap,
            mark_sessions: self.mark_sessions,
        })
    }

    /// The CSRR procedure's timeline.
    fn timeline(&self) -> Timeline {
        let speeds = self.procedure.session_speeds_rpm(self.speed_rpm);
        let sessions: Vec<SessionPlan> = self
            .procedure
            .resolved_sessions()
            .into_iter()
            .zip(speeds)
            .map(|((deg, revolutions), rpm)| SessionPlan {
                delta: deg / DEG_PER_RAD,
                revolutions,
                omega: Some(rpm * TAU / 60.0),
            })
            .collect();
        let modulation = self.modulation();
        let p = &self.procedure;
        let timing = Timing {
            omega: self.speed_rpm * TAU / 60.0,
            ramp_s: p.ramp_s,
            pause_s: p.pause_s,
            turn_s: p.turn_s,
        };
        Timeline::new(&sessions, timing, modulation)
    }

    /// The modulation of eq. (9): `[speed]`'s harmonics and its once-per-revolution ripple.
    fn modulation(&self) -> Vec<Term> {
        let mut modulation = terms(&self.speed.harmonics);
        if self.speed.variation_percent > 0.0 {
            modulation.push(Term {
                order: 1.0,
                amplitude: self.speed.variation_percent / 100.0,
                phase: 0.0,
            });
        }
        modulation
    }

    /// The sweep's timeline.
    fn sweep_timeline(&self, sw: &Sweep) -> SweepTimeline {
        let speeds: Vec<f64> = if sw.speeds_deg_s.is_empty() {
            vec![self.speed_rpm * TAU / 60.0]
        } else {
            sw.speeds_deg_s.iter().map(|v| v / DEG_PER_RAD).collect()
        };
        SweepTimeline::new(
            sw.from_deg / DEG_PER_RAD,
            sw.to_deg / DEG_PER_RAD,
            sw.cycles,
            &speeds,
            sw.ramp_s,
            sw.pause_s,
            &self.modulation(),
            sw.random.then(|| Rng::new(self.seed, MOTION_STREAM)),
        )
    }

    /// For a `[sweep]` shorter than a revolution: every channel's true error over the readings
    /// it swept, as a range map on a grid of step at most `2π/points` from its lowest to its
    /// highest reading (mean removed over the range), `(channel name, map)` in channel order.
    /// `None` for other procedures, and for a channel whose readings cover a whole revolution
    /// or that sits behind a gear (its truth is then [`Scenario::truth`]'s).
    ///
    /// The shaft's true angle `θ = φ + ε_θ(φ)` and every reading `θ + e(θ)` increase with the
    /// nominal angle `φ` (validation bounds both slopes), so the swept readings run from the
    /// reading at the stroke's lower end to the reading at its upper end.
    pub fn range_truth(&self, points: usize) -> Result<Option<Vec<RangeTruth>>, ScenarioError> {
        let truths = self.sensor_truths()?;
        let Some(sw) = &self.sweep else {
            return Ok(None);
        };
        let (lo, hi) = (
            sw.from_deg.min(sw.to_deg) / DEG_PER_RAD,
            sw.from_deg.max(sw.to_deg) / DEG_PER_RAD,
        );
        let modulation = FastSeries::new(&self.modulation());
        let mut buf = Powers::default();
        let true_angle = |phi: f64, buf: &mut Powers| phi + modulation.eval(phi, buf);
        let (t_lo, t_hi) = (true_angle(lo, &mut buf), true_angle(hi, &mut buf));
        if t_hi - t_lo >= TAU {
            return Ok(None);
        }
        let step = TAU / points.max(2) as f64;
        Ok(Some(
            truths
                .into_iter()
                .zip(&self.sensors)
                .map(|(t, s)| {
                    // A sensor behind a gear: its truth is a whole turn of its own angle.
                    if s.ratio != 1.0 {
                        return (t.name, None);
                    }
                    let r_lo = t_lo + t.error_at_true(t_lo);
                    let r_hi = t_hi + t.error_at_true(t_hi);
                    let span = r_hi - r_lo;
                    let map = (span < TAU - step).then(|| {
                        let m = ((span / step).ceil() as usize).max(1);
                        let values = (0..=m)
                            .map(|i| t.error_at_reading(r_lo + span * i as f64 / m as f64))
                            .collect();
                        RangeMap::new(r_lo, span / m as f64, values)
                            .expect("a span below a revolution on at least 2 points")
                    });
                    (t.name, map)
                })
                .collect(),
        ))
    }

    /// The coast-down's integrator.
    fn coast(&self, sd: &SpinDown) -> Coast {
        let drag: Vec<Term> = sd
            .drag_harmonics
            .iter()
            .map(|d| Term {
                order: f64::from(d.order),
                amplitude: d.amplitude,
                phase: d.phase_deg / DEG_PER_RAD,
            })
            .collect();
        let f = &sd.friction;
        let rpm = TAU / 60.0;
        let drive = sd.drive.as_ref().map(|d| ConstantVoltage {
            time_constant: d.time_constant_s,
            steps: d
                .steps
                .iter()
                .map(|s| (s.from_s, s.speed_rpm * rpm))
                .collect(),
        });
        Coast::new(
            sd.speed_rpm * rpm,
            sd.duration_s,
            [f.coulomb, f.viscous, f.quadratic],
            &drag,
            drive,
            self.rate_hz,
        )
    }

    fn mount_of(&self, s: &Sensor) -> Mount {
        match &s.scale {
            Some(name) => self
                .scales
                .iter()
                .find(|sc| &sc.name == name)
                .map_or(Mount::B, |sc| sc.mount),
            None => s.mount.unwrap_or_default(),
        }
    }

    /// The error model of a sensor of a validated scenario.
    fn truth_of(&self, s: &Sensor) -> SensorTruth {
        let scale = s
            .scale
            .as_ref()
            .and_then(|name| self.scales.iter().find(|sc| &sc.name == name));
        let (model, head_angle_error) = match scale {
            Some(sc) => {
                let delta = s.head_error_arcsec.unwrap_or(0.0) / ARCSEC_PER_RAD;
                let alpha = s.head_deg.unwrap_or(0.0) / DEG_PER_RAD + delta;
                // e(θ) = δ + e_s(θ + α + δ): the scale's terms with phases advanced by h·(α + δ).
                let terms = terms(&sc.harmonics)
                    .into_iter()
                    .map(|t| Term {
                        phase: (t.phase + t.order * alpha).rem_euclid(TAU),
                        ..t
                    })
                    .collect();
                (
                    ErrorModel {
                        offset: delta,
                        terms,
                    },
                    Some(delta),
                )
            }
            None => (
                ErrorModel {
                    offset: 0.0,
                    terms: terms(&s.harmonics),
                },
                None,
            ),
        };
        SensorTruth {
            name: s.name.clone(),
            model,
            head_angle_error,
        }
    }
}

/// One channel's truth over a sweep ([`Scenario::range_truth`]): its name and its range map
/// (`None` where its readings cover a whole revolution).
pub type RangeTruth = (String, Option<RangeMap>);

/// How many binary powers of `e^{iθ}` the channels on `mount` need.
fn channel_powers_needed(channels: &[ChannelSim], mount: Mount) -> usize {
    channels
        .iter()
        .filter(|c| c.mount == mount)
        .map(|c| c.series.powers_needed())
        .max()
        .unwrap_or(0)
}

/// `r` wrapped to `[0, 2π)` as [`wrap_2pi`] does, without its `fmod`, which is a slow software
/// routine: `r − k·2π` with `2π` split into a 32-bit head (so `k·HEAD` is exact for
/// `|k| < 2²¹`, and the subtraction is exact by Sterbenz's lemma) and a tail.
fn wrap_revolution(r: f64) -> f64 {
    const HEAD: f64 = f64::from_bits(TAU.to_bits() & !((1u64 << 21) - 1));
    const TAIL: f64 = TAU - HEAD;
    let k = (r / TAU).floor();
    if k.abs() >= (1u64 << 21) as f64 {
        return wrap_2pi(r);
    }
    let w = (r - k * HEAD) - k * TAIL;
    if w < 0.0 {
        w + TAU
    } else if w >= TAU {
        w - TAU
    } else {
        w
    }
}

#[derive(Debug, Clone)]
struct ChannelSim {
    mount: Mount,
    /// The error model `offset + series(θ)` (see `ErrorModel`), in its fast form.
    offset: f64,
    series: FastSeries,
    /// Resolution, radians (0: none).
    quantum: f64,
    /// Noise σ, radians.
    noise: f64,
    rng: Rng,
    /// How much older than its stamp the channel's sample is, seconds.
    delay: f64,
    /// Half the play of its coupling, radians (0: rigid).
    half_play: f64,
    /// Where the coupled side sits (with play).
    follower: Option<f64>,
    /// Reads the commanded angle `φ`, not the rotor.
    commanded: bool,
    /// Turns per turn of the rotor (a sensor behind a gear).
    ratio: f64,
}

/// What moves the rotors: the CSRR procedure or a free coast-down.
#[derive(Debug, Clone)]
enum Motion {
    Procedure(Timeline),
    Coast(Coast),
    Sweep(SweepTimeline),
}

impl Motion {
    fn duration(&self) -> f64 {
        match self {
            Motion::Procedure(tl) => tl.duration(),
            Motion::Coast(c) => c.duration(),
            Motion::Sweep(s) => s.duration(),
        }
    }

    fn state(&mut self, t: f64) -> State {
        match self {
            Motion::Procedure(tl) => tl.state(t),
            Motion::Coast(c) => {
                let theta = c.theta(t);
                State {
                    phi: theta,
                    theta_b: theta,
                    delta: 0.0,
                }
            }
            Motion::Sweep(s) => {
                let (phi, theta) = s.angles(t);
                State {
                    phi,
                    theta_b: theta,
                    delta: 0.0,
                }
            }
        }
    }
}

/// The stream of a simulated run's samples ([`Scenario::samples`]).
#[derive(Debug, Clone)]
pub struct Samples {
    motion: Motion,
    /// Sample index ranges `[first, end)` of each session's constant-speed revolutions.
    windows: Vec<(u64, u64)>,
    /// The window of the current or next session.
    window: usize,
    /// Binary powers of `e^{iθ_A}` and `e^{iθ_B}` needed by the channels on each rotor (0: none
    /// there), computed once per sample and shared by the channels.
    need_a: usize,
    need_b: usize,
    powers_a: Powers,
    powers_b: Powers,
    /// Powers for a channel that is not at its rotor's angle (delayed, with play, commanded,
    /// geared).
    powers_scratch: Powers,
    /// The last relative rotation Δ and its `(sin Δ, cos Δ)`: Δ changes only during turns.
    rotation: Option<(f64, (f64, f64))>,
    channels: Vec<ChannelSim>,
    next: u64,
    count: u64,
    rate_hz: f64,
    jitter_s: f64,
    jitter_rng: Rng,
    wrap: bool,
    mark_sessions: bool,
}

/// A sample together with the true angle each channel measured.
#[derive(Debug, Clone, PartialEq)]
pub struct SampleWithTruth {
    /// The sample as a log would hold it.
    pub sample: Sample,
    /// Per channel, the true angle of its rotor at the sampling instant, radians, accumulated
    /// (never wrapped): `θ_B` for mount `b` and heads on a `b` scale, `θ_B + Δ` for mount `a`;
    /// for a sensor behind a gear, its own angle (`ratio` times its rotor's).
    pub true_angles: Vec<f64>,
    /// The relative rotation `Δ = θ_A − θ_B` at the sampling instant, radians.
    pub relative: f64,
    /// The session whose constant-speed revolutions hold this sample, marked or not.
    pub session: Option<u32>,
}

impl Samples {
    /// The same stream, each sample with its truth (for tests and accuracy studies).
    pub fn with_truth(self) -> WithTruth {
        WithTruth(self)
    }

    /// Total duration of the run, seconds.
    pub fn duration_s(&self) -> f64 {
        self.motion.duration()
    }

    fn step(&mut self, mut truth: Option<&mut Vec<f64>>) -> Option<(Sample, f64, Option<u32>)> {
        if self.next >= self.count {
            return None;
        }
        let n = self.next;
        let t = n as f64 / self.rate_hz;
        self.next += 1;
        while self.window + 1 < self.windows.len() && n >= self.windows[self.window].1 {
            self.window += 1;
        }
        let in_session = self
            .windows
            .get(self.window)
            .is_some_and(|&(first, end)| n >= first && n < end)
            .then(|| u32::try_from(self.window).ok())
            .flatten();
        let instant = if self.jitter_s > 0.0 {
            t + self.jitter_s * self.jitter_rng.normal()
        } else {
            t
        };
        let state = self.motion.state(instant);
        if self.need_a > 0 || self.need_b > 0 {
            let (sb, cb) = state.theta_b.sin_cos();
            self.powers_b.set((sb, cb), self.need_b);
            if self.need_a > 0 {
                let (sd, cd) = match self.rotation {
                    Some((d, sc)) if d == state.delta => sc,
                    _ => {
                        let sc = state.delta.sin_cos();
                        self.rotation = Some((state.delta, sc));
                        sc
                    }
                };
                // e^{iθ_A} = e^{iθ_B}·e^{iΔ}.
                self.powers_a
                    .set((sb * cd + cb * sd, cb * cd - sb * sd), self.need_a);
            }
        }
        let mut values = Vec::with_capacity(self.channels.len());
        let motion = &mut self.motion;
        for ch in &mut self.channels {
            let special = ch.delay != 0.0 || ch.half_play > 0.0 || ch.commanded || ch.ratio != 1.0;
            let at = |s: &State| match ch.mount {
                _ if ch.commanded => s.phi,
                Mount::A => s.theta_b + s.delta,
                Mount::B => s.theta_b,
            };
            let mut theta = if ch.delay != 0.0 {
                at(&motion.state(instant - ch.delay))
            } else {
                at(&state)
            };
            if ch.half_play > 0.0 {
                // The coupled side stays put until the play is taken up, then is dragged along.
                let f = ch.follower.get_or_insert(theta);
                *f = f.clamp(theta - ch.half_play, theta + ch.half_play);
                theta = *f;
            }
            // Behind a gear the sensor turns `ratio` times the rotor.
            theta *= ch.ratio;
            if let Some(truth) = truth.as_deref_mut() {
                truth.push(theta);
            }
            let error = if special {
                ch.series.eval(theta, &mut self.powers_scratch)
            } else {
                ch.series.eval_powers(match ch.mount {
                    Mount::A => &self.powers_a,
                    Mount::B => &self.powers_b,
                })
            };
            let mut r = theta + ch.offset + error;
            if ch.noise > 0.0 {
                r += ch.noise * ch.rng.normal();
            }
            if ch.quantum > 0.0 {
                r = (r / ch.quantum).round() * ch.quantum;
            }
            values.push(if self.wrap { wrap_revolution(r) } else { r });
        }
        let session = if self.mark_sessions { in_session } else { None };
        Some((Sample { t, values, session }, state.delta, in_session))
    }

    fn remaining(&self) -> usize {
        usize::try_from(self.count - self.next).unwrap_or(usize::MAX)
    }
}

impl Iterator for Samples {
    type Item = Sample;

    fn next(&mut self) -> Option<Sample> {
        self.step(None).map(|(s, _, _)| s)
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        (self.remaining(), Some(self.remaining()))
    }
}

impl ExactSizeIterator for Samples {}

/// [`Samples`] with each sample's truth ([`Samples::with_truth`]).
#[derive(Debug, Clone)]
pub struct WithTruth(Samples);

impl Iterator for WithTruth {
    type Item = SampleWithTruth;

    fn next(&mut self) -> Option<SampleWithTruth> {
        let mut true_angles = Vec::with_capacity(self.0.channels.len());
        let (sample, relative, session) = self.0.step(Some(&mut true_angles))?;
        Some(SampleWithTruth {
            sample,
            true_angles,
            relative,
            session,
        })
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        self.0.size_hint()
    }
}

impl ExactSizeIterator for WithTruth {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_wrap_agrees_with_fmod() {
        for k in -20_000..20_000 {
            let r = k as f64 * 0.7345 + 1e-9 * k as f64;
            assert!(
                (wrap_revolution(r) - wrap_2pi(r)).abs() < 1e-15 * (1.0 + r.abs()),
                "{r}"
            );
            assert!((0.0..TAU).contains(&wrap_revolution(r)));
        }
        for r in [0.0, TAU, -TAU, 1e300, -1e-300, 3.0 * TAU - 1e-15] {
            assert!((0.0..TAU).contains(&wrap_revolution(r)), "{r}");
        }
    }
}
