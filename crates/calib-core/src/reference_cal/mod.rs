//! Cross-calibration of an encoder (the DUT, device under test) against a better reference
//! encoder on the same shaft, with the ISO 230-2 figures of the result.
//!
//! # Method
//! Both encoders are sampled at the same instants while the shaft turns. At each sample the
//! difference `d = (DUT − DUT₀) − (ref − ref₀)` of the two continuous (unwrapped) readings is the
//! DUT's error minus the reference's error, plus a constant. Whenever the DUT's reading crosses a
//! grid point `θ_i = i·360°/N` between two consecutive moving samples, `d` is interpolated at
//! that crossing by the cubic through these two samples and their outer neighbours (at the end of
//! a run, before a reversal or a stop, the cubic through them and the two samples before; a
//! parabola or a straight line where the run has fewer samples): one value `x_ij` per grid point `i` per pass `j` (a pass is one
//! crossing, so a revolution is one pass at every point), kept per direction (↑ increasing, ↓
//! decreasing DUT readings). Speed variations do not matter: both readings are taken at the same
//! instant. Crossings within the first [`ReferenceOptions::approach`] (1°) of travel after each
//! reversal of direction are not used: there the backlash of the coupling is being taken up.
//!
//! # Whole turns, gaps and ranges
//! The map covers the grid points crossed ([`TableMap`]):
//! - all of them: a whole-turn [`ErrorMap`];
//! - all but one run of points whose gap (from the last measured point before it to the first
//!   after it) is at most [`ReferenceOptions::max_gap`] (5°): a whole-turn map with the gap
//!   bridged by the straight line between its measured ends, across the 360° wrap, after any
//!   fitted model is taken out of the measured points, its `u` holding what a gap that wide can
//!   hide ([`Gap`], module `gaps`; with a warning naming its size and place);
//! - else the range from the first to the last point crossed, the far side of the largest run
//!   of points never crossed: a [`RangeMap`] (both directions where the motion had both; at the
//!   range's ends one direction only, within the approach after each reversal). Nothing outside
//!   the data is extrapolated; points never crossed inside the range are an error.
//!
//! A point counts as crossed where a pass measured it: a step between two samples much wider
//! than its neighbours (samples lost) is a pass gap whose crossings are not used ([`PassGap`],
//! module `gaps`, with a warning naming it).
//!
//! A range that crosses the reading 0 is held from `start` in `[0, 2π)` to `end` above 2π;
//! tables and reports write it in the signed form (−40° to 95°), never above 360°.
//!
//! # Latency
//! A constant lag `τ` of the DUT's samples behind the reference's (two interfaces sampling at
//! different instants) adds `−τ·ω(t)` to the difference, which looks like a reversal at one speed
//! and like noise at several. With [`Latency::Auto`] (the default) `τ` is fitted jointly with the
//! map and a constant reversal from the differences between passes over the same point
//! ([`LatencyFit`]; module `latency`), and removed — the reference re-read at `t − τ` — where the
//! run tells it from backlash (passes at different speeds in one direction) and it differs from
//! 0 by more than 3 standard uncertainties. At one speed per direction a warning names both
//! readings of the reversal (a lag in ms, or a backlash in ″) and how to record a run that
//! separates them. An estimated `τ` adds `u(τ)·|ω̄_i|` to the point's `u`, `ω̄_i` the mean
//! signed speed of its crossings (zero where both directions went at the same speed).
//!
//! # One direction at the ends
//! Where a point was crossed in one direction only (the ends of a swept range, within the
//! approach after each reversal), its value is that direction's mean corrected by half the
//! reversal measured at the nearest points crossed both ways, with the correction's
//! uncertainty in `u` ([`EndCorrection`]; module `ends`), so that the map is the bidirectional
//! mean everywhere.
//!
//! # Commanded reference
//! With [`ReferenceKind::Commanded`] the reference is an open-loop commanded angle; the motor's
//! ripple, periodic in the electrical angle, is fitted and taken out of the map
//! ([`Ripple`]; module `ripple`).
//!
//! # Does the reference follow the DUT?
//! A DUT's error, however large (a resolver's ±15°), is a function of the angle: the difference
//! `d` at a grid point is the same on every pass. A reference on another shaft, slipping, counting
//! the other way round or in another unit gives a `d` that differs from pass to pass. So the check
//! is the largest spread `max_j x_ij − min_j x_ij` over all passes (both directions) at one grid
//! point, against [`ReferenceOptions::follow_tol`] (5°); only a run that crosses no point twice
//! falls back to the change of `d` over the whole run.
//!
//! # Terms (ISO 230-2:2014, for a rotary axis, at the target positions of [`Targets`])
//! With `n` passes at point `i` in one direction:
//! - mean unidirectional deviation `x̄_i↑ = (1/n) Σ_j x_ij↑` (likewise ↓);
//! - standard deviation `s_i↑ = sqrt(Σ_j (x_ij↑ − x̄_i↑)² / (n − 1))` (needs `n ≥ 2`);
//! - mean bidirectional deviation `x̄_i = (x̄_i↑ + x̄_i↓)/2` where both directions have data,
//!   else the one that has — **this is the error map** written to the table, mean removed over the
//!   circle (the same constant is removed from the directional means);
//! - reversal value `B_i = x̄_i↑ − x̄_i↓`; of the axis `B = max_i |B_i|`; mean `B̄ = mean_i B_i`;
//! - unidirectional repeatability `R_i↑ = 4 s_i↑` (±2s), `R↑ = max_i R_i↑`; bidirectional
//!   `R_i = max(2 s_i↑ + 2 s_i↓ + |B_i|, R_i↑, R_i↓)`, `R = max_i R_i`;
//! - systematic deviation `E↑ = max_i x̄_i↑ − min_i x̄_i↑`; bidirectional
//!   `E = max(x̄_i↑, x̄_i↓) − min(x̄_i↑, x̄_i↓)` over all `i`;
//! - mean bidirectional positional deviation `M = max_i x̄_i − min_i x̄_i`;
//! - accuracy `A↑ = max_i(x̄_i↑ + 2 s_i↑) − min_i(x̄_i↑ − 2 s_i↑)`; bidirectional
//!   `A = max(x̄_i↑ + 2 s_i↑, x̄_i↓ + 2 s_i↓) − min(x̄_i↑ − 2 s_i↑, x̄_i↓ − 2 s_i↓)`.
//!
//! Here `i` runs over the target positions (default 20, one in the middle of each twentieth of
//! the map's range, each on its nearest grid point); the map itself holds every grid point. Terms
//! that need `s` use only the targets with `n ≥ 2` passes in that direction; ISO 230-2 asks for 5
//! passes per direction (a warning says when there are fewer, at any grid point).
//!
//! # Sign
//! The values `x` here are calib's errors `e = DUT reading − reference reading` (interface
//! convention). ISO 230-2's positional deviation is `actual − target = reference − DUT = −e`; the
//! ranges `E`, `M`, `R`, `A` and `B` are the same in both conventions, but the signed mean
//! reversal `B̄` flips: [`Iso230_2::mean_reversal`] is reported in **calib's sign**
//! (`ē↑ − ē↓`).
//!
//! # Uncertainty
//! `u_i = sqrt(u_mean,i² + u_q² + u_ref²)`: the standard error of the point's mean (for the
//! bidirectional mean `sqrt(s↑²/n↑ + s↓²/n↓)/2`; a direction with `n < 2` uses the pooled `s` of
//! its direction), the part of the DUT's quantization that passes do not average ([`Quantization`],
//! module `quantum`: `(Δ/√12)·exp(−2π²σ²/Δ²)`, the whole `Δ/√12` of a quantum `Δ` no noise
//! dithers), and the reference's stated standard uncertainty.
//!
//! # What it cannot see
//! The reference's own error: the map is `e_DUT − e_ref` (why the reference must be much better
//! than the DUT). Error components with periods shorter than about four sample spacings are
//! attenuated by the interpolation between samples: the centred cubic's error is at most
//! `(9/384)·(h·Δθ)⁴` of an order-`h` amplitude for sample spacing `Δθ`, the one-sided cubic's at
//! the end of a run about `(1/24)·(h·Δθ)⁴` (a lone step's straight line `(h·Δθ)²/8`). The
//! interpolation is in the DUT's reading, so a steep error (degrees per degree) only changes the
//! spacing of the nodes. No absolute offset (maps are zero-mean, over their range).

mod ends;
mod gaps;
mod gear;
mod latency;
mod quantum;
mod ripple;

pub use ends::EndCorrection;
pub use gaps::{GAP_RATIO, PassGap};
pub use gear::{
    Coincidence, DEFAULT_REFERENCE_ORDERS, Gear, GearResult, GearedCal, MAX_FIT_SAMPLES,
    MIN_RANGE_REFERENCE_TURNS, MIN_REFERENCE_TURNS, Ratio, RatioSource, ReferenceMap, ReferenceRun,
    ReferenceTerm,
};
pub use latency::{LatencyFit, MIN_SPEED_SPREAD};
pub use quantum::Quantization;
pub use ripple::{Ripple, RippleTerm};

use crate::angle::{ARCSEC_PER_RAD, Unwrapper, wrap_2pi};
use crate::error_map::ErrorMap;
use crate::range_map::RangeMap;
use crate::table_map::TableMap;
use latency::Crossing;
use quantum::QuantumTracker;
use std::f64::consts::{PI, TAU};

/// Settings of a reference calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceOptions {
    /// Grid points of the map, ≥ 2 (default 3600).
    pub points: usize,
    /// Speed of the DUT below which it counts as stopped, rad/s (default 1°/s).
    pub min_speed: f64,
    /// The reference's stated standard uncertainty, radians (default 0).
    pub reference_u: f64,
    /// Largest change of the difference between the two readings while moving, radians (default
    /// 5°): beyond it the reference is not following the DUT's shaft.
    pub follow_tol: f64,
    /// Travel of the DUT after each reversal of direction (and at the first motion) whose
    /// crossings are not used, radians (default 1°): the approach of ISO 230-2, which lets
    /// backlash and wind-up settle before positions are measured.
    pub approach: f64,
    /// Largest gap of never-crossed readings, radians (default 5°), that a run otherwise
    /// covering a whole turn may have and still give a whole-turn map, the gap bridged by
    /// interpolation across it; a larger gap makes the map a range map.
    pub max_gap: f64,
    /// Where ISO 230-2's target positions lie (default: 20, see [`Targets`]).
    pub targets: Targets,
    /// The time offset between the channels (default [`Latency::Auto`]).
    pub latency: Latency,
    /// What the reference is (default [`ReferenceKind::Encoder`]).
    pub reference_kind: ReferenceKind,
}

/// The DUT's lag behind the reference (see [Latency](self#latency)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Latency {
    /// Estimated from the run; removed where the run separates it from backlash and it differs
    /// from 0 by more than 3 standard uncertainties, else reported and left at 0.
    Auto,
    /// This lag, seconds (positive: the DUT's sample is older than its stamp says), removed.
    Fixed(f64),
}

/// What the reference channel measures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ReferenceKind {
    /// An encoder on the DUT's shaft.
    Encoder,
    /// The commanded angle of a motor driven open loop with `pole_pairs` pole pairs: the ripple
    /// periodic in the electrical angle is taken out of the map and reported (see [`Ripple`]).
    Commanded {
        /// Pole pairs of the motor (≥ 1).
        pole_pairs: u32,
    },
}

/// The target positions of ISO 230-2, at which its figures are evaluated.
#[derive(Debug, Clone, PartialEq)]
pub enum Targets {
    /// `k` targets, one in the middle of each of `k` equal parts of the map's range (for a whole
    /// turn: `(j + ½)·360°/k`), each moved to its nearest grid point.
    Count(usize),
    /// These readings, radians, each moved to its nearest grid point; every one must lie in the
    /// map's range.
    Angles(Vec<f64>),
}

impl Default for ReferenceOptions {
    fn default() -> Self {
        ReferenceOptions {
            points: 3600,
            min_speed: 1f64.to_radians(),
            reference_u: 0.0,
            follow_tol: 5f64.to_radians(),
            approach: 1f64.to_radians(),
            max_gap: 5f64.to_radians(),
            targets: Targets::Count(20),
            latency: Latency::Auto,
            reference_kind: ReferenceKind::Encoder,
        }
    }
}

/// Why a reference calibration cannot be made from the data.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReferenceError {
    /// The DUT crossed fewer than two grid points while moving.
    #[error(
        "the DUT turned {revolutions:.4} revolution(s) while moving and crossed {crossed} grid point(s); a reference \
         calibration needs at least 2 (record the shaft turning over the range to calibrate, better 5 times in each direction)"
    )]
    TooLittleMotion {
        /// Revolutions of DUT travel while moving.
        revolutions: f64,
        /// Grid points crossed.
        crossed: usize,
    },
    /// Grid points inside the covered range were never crossed.
    #[error(
        "{missing} of {points} grid points inside the range the DUT covered were never crossed while moving (the first at \
         {first_deg:.3}°); the range must be swept without stopping in the middle: record the shaft turning through \
         every angle of the range"
    )]
    NotCovered {
        /// Grid points without data inside the range.
        missing: usize,
        /// Grid points.
        points: usize,
        /// The first of them, degrees.
        first_deg: f64,
    },
    /// The difference of the two readings at one DUT reading differs from pass to pass.
    #[error(
        "the reference does not follow the DUT: at the DUT's reading {at_deg:.3}° the difference of their readings \
         differs by {spread_deg:.3}° between passes (at most {tol_deg}° allowed). A DUT's error repeats from pass to pass, \
         however large; a reference on another shaft, slipping on its shaft, counting the other way round or in another \
         unit does not: check that both are on the same shaft, count the same way round (negate one otherwise) and are \
         in the same unit"
    )]
    NotRepeating {
        /// The largest spread of the difference at one grid point, degrees.
        spread_deg: f64,
        /// Where, degrees of the DUT's reading.
        at_deg: f64,
        /// The tolerance, degrees.
        tol_deg: f64,
    },
    /// The reference stays still while the DUT turns.
    #[error(
        "the reference does not move while the DUT turns ({reference_deg:.3}° of reference travel against {dut_deg:.1}° of the DUT): \
         check that the right channel was chosen and that the reference is on the DUT's shaft"
    )]
    ReferenceStill {
        /// Reference travel while the DUT moved, degrees.
        reference_deg: f64,
        /// DUT travel while moving, degrees.
        dut_deg: f64,
    },
    /// The two encoders' motions differ by more than the tolerance, in a run that crosses no
    /// reading twice (so nothing tells a drifting reference from a large DUT error).
    #[error(
        "the reference does not follow the DUT: the difference of their readings changed by {change_deg:.3}° over \
         {revolutions:.2} revolution(s) (at most {tol_deg}° allowed), and the run crosses no reading twice, so a large \
         DUT error cannot be told from a reference that drifts; check that both are on the same shaft, count the same \
         way round (negate one otherwise) and are in the same unit, or record the motion back and forth"
    )]
    NotFollowing {
        /// Range of the reading difference while moving, degrees.
        change_deg: f64,
        /// Revolutions of DUT travel.
        revolutions: f64,
        /// The tolerance, degrees.
        tol_deg: f64,
    },
    /// A commanded reference's range is too short to separate the motor's ripple.
    #[error(
        "the range holds {periods:.2} electrical period(s) of the motor ({pole_pairs} pole pairs); the ripple of a commanded \
         reference is separated over at least 2: sweep a wider range, or check the `pole_pairs` option"
    )]
    CommandedTooShort {
        /// Electrical periods in the map's range.
        periods: f64,
        /// Pole pairs given.
        pole_pairs: u32,
    },
    /// The reference turns at another ratio than the one given.
    #[error(
        "the reference turned {measured:.4} times per turn of the DUT, but the `ref_ratio` option says {given}: check the \
         gear's ratio and its sign (negative where the reference turns the other way), or let calib estimate it with \
         `ref_ratio = auto`"
    )]
    RatioMismatch {
        /// The ratio given.
        given: f64,
        /// The ratio the run shows (least-squares slope of the reference's reading on the DUT's).
        measured: f64,
    },
    /// The options cannot work.
    #[error("invalid options: {0}")]
    Options(String),
}

/// Running statistics of one grid point in one direction (Welford).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Welford {
    n: u32,
    mean: f64,
    m2: f64,
}

impl Welford {
    fn add(&mut self, x: f64) {
        self.n += 1;
        let d = x - self.mean;
        self.mean += d / f64::from(self.n);
        self.m2 += d * (x - self.mean);
    }
}

/// The statistics of one grid point in one direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointStats {
    /// Passes (crossings of the point in this direction).
    pub n: u32,
    /// Mean deviation `x̄_i`, radians, with the map's constant removed (meaningless if `n = 0`).
    pub mean: f64,
    /// Standard deviation `s_i` of the passes, radians (`None` if `n < 2`).
    pub s: Option<f64>,
}

/// The ISO 230-2 figures of a calibration, radians (`None` where the data cannot give them).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Iso230_2 {
    /// Unidirectional systematic deviation `E↑` (increasing readings).
    pub systematic_up: Option<f64>,
    /// Unidirectional systematic deviation `E↓` (decreasing readings).
    pub systematic_down: Option<f64>,
    /// Bidirectional systematic deviation `E`.
    pub systematic: Option<f64>,
    /// Mean bidirectional positional deviation `M` (range of the map before mean removal).
    pub mean_bidirectional: Option<f64>,
    /// Reversal value `B = max |B_i|` (needs both directions).
    pub reversal: Option<f64>,
    /// Mean reversal value `B̄ = mean B_i`, calib's sign (`ē↑ − ē↓`).
    pub mean_reversal: Option<f64>,
    /// Unidirectional repeatability `R↑ = max 4 s_i↑`.
    pub repeatability_up: Option<f64>,
    /// Unidirectional repeatability `R↓ = max 4 s_i↓`.
    pub repeatability_down: Option<f64>,
    /// Bidirectional repeatability `R`.
    pub repeatability: Option<f64>,
    /// Unidirectional accuracy `A↑`.
    pub accuracy_up: Option<f64>,
    /// Unidirectional accuracy `A↓`.
    pub accuracy_down: Option<f64>,
    /// Bidirectional accuracy `A`.
    pub accuracy: Option<f64>,
}

impl Iso230_2 {
    /// The figures as `(name, arcsec)` pairs, `None` for those not available.
    pub fn arcsec(&self) -> Vec<(&'static str, Option<f64>)> {
        let a = |v: Option<f64>| v.map(|x| x * ARCSEC_PER_RAD);
        vec![
            ("systematic_up", a(self.systematic_up)),
            ("systematic_down", a(self.systematic_down)),
            ("systematic", a(self.systematic)),
            ("mean_bidirectional", a(self.mean_bidirectional)),
            ("reversal", a(self.reversal)),
            ("mean_reversal", a(self.mean_reversal)),
            ("repeatability_up", a(self.repeatability_up)),
            ("repeatability_down", a(self.repeatability_down)),
            ("repeatability", a(self.repeatability)),
            ("accuracy_up", a(self.accuracy_up)),
            ("accuracy_down", a(self.accuracy_down)),
            ("accuracy", a(self.accuracy)),
        ]
    }
}

/// Readings a run never reached, bridged in a whole-turn map by linear interpolation across
/// them (periodic: from the last measured point before the gap to the first after it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gap {
    /// The last measured grid angle before the gap, radians in `[0, 2π)`.
    pub from: f64,
    /// The first measured grid angle after it, radians (`from + size`, possibly above 2π).
    pub to: f64,
    /// `to − from`, radians.
    pub size: f64,
    /// Grid points inside the gap, whose values are interpolated, not measured.
    pub points: usize,
    /// The most the error can depart from the straight line across the gap, radians: the
    /// largest departure of the measured map from the chord of any window as wide (module
    /// `gaps`), in the bridged points' `u`.
    pub bound: f64,
}

/// ISO 230-2's statistics at one target position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TargetStats {
    /// The target: the grid angle nearest the asked position, radians.
    pub angle: f64,
    /// Increasing readings.
    pub up: PointStats,
    /// Decreasing readings.
    pub down: PointStats,
}

/// The result of a reference calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceCalibration {
    /// The DUT's error map (bidirectional mean where both directions were measured), relative
    /// to the reference, zero mean over its grid.
    pub map: TableMap,
    /// Standard uncertainty of each map point, radians.
    pub u: Vec<f64>,
    /// Statistics per map point for increasing readings (`n = 0` at bridged points).
    pub up: Vec<PointStats>,
    /// Statistics per map point for decreasing readings.
    pub down: Vec<PointStats>,
    /// The ISO 230-2 figures, over the target positions.
    pub iso: Iso230_2,
    /// The ISO 230-2 target positions and their statistics.
    pub targets: Vec<TargetStats>,
    /// DUT travel while moving, revolutions (both directions).
    pub revolutions: f64,
    /// Fewest passes at a grid point crossed in each direction (`up`, `down`); 0 for a
    /// direction without data.
    pub min_passes: (u32, u32),
    /// The gap bridged in a whole-turn map, if the run left one.
    pub gap: Option<Gap>,
    /// Where a pass went through readings without a sample (module `gaps`): not measured there.
    pub pass_gaps: Vec<PassGap>,
    /// The largest spread of the reading difference at one grid point between passes (any
    /// direction), radians: how well the reference followed; `None` if no point was crossed
    /// twice.
    pub repeat_spread: Option<f64>,
    /// The time offset between the channels: what was estimated and what was removed.
    pub latency: Option<LatencyResult>,
    /// The correction of points measured in one direction only, where there were any next to
    /// points measured both ways.
    pub ends: Option<EndCorrection>,
    /// The motor's ripple taken out of the map (a commanded reference).
    pub ripple: Option<Ripple>,
    /// The DUT's quantum and the part of it no averaging takes out, in every point's u
    /// (`None`: the readings are not quantized).
    pub quantization: Option<Quantization>,
    /// What the user should know about the result.
    pub warnings: Vec<String>,
    /// A reference through a gear: the ratio and the reference's own map (module `gear`).
    pub gear: Option<GearResult>,
}

/// The time offset between the channels in a calibration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LatencyResult {
    /// The lag removed from the map, seconds (0: none).
    pub applied: f64,
    /// Where it comes from.
    pub source: LatencySource,
    /// The fit of the run (`None` with a given lag, or where the run cannot give one).
    pub fit: Option<LatencyFit>,
}

/// Where the lag removed comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LatencySource {
    /// Given by the user.
    Given,
    /// Estimated and removed.
    Estimated,
    /// Estimated, not different from 0 by 3 standard uncertainties: not removed.
    Insignificant,
    /// The run has one speed per direction: latency and backlash read the same; not removed.
    Ambiguous,
    /// The run cannot estimate it (too few points crossed twice, time stamps out of order).
    Unavailable,
}

/// A reference calibration fed one synchronized sample at a time.
#[derive(Debug, Clone)]
pub struct ReferenceCal {
    opts: ReferenceOptions,
    dut: Unwrapper,
    reference: Unwrapper,
    /// `(t, unwrapped DUT, difference)` of the previous sample.
    last: Option<(f64, f64, f64)>,
    first: Option<(f64, f64)>,
    up: Vec<Welford>,
    down: Vec<Welford>,
    /// Smallest and largest difference at each grid point, both directions.
    low: Vec<f64>,
    high: Vec<f64>,
    travel: f64,
    reference_travel: f64,
    d_min: f64,
    d_max: f64,
    /// Direction of the current run (`true`: increasing) and the DUT's travel since it began.
    run: Option<(bool, f64)>,
    /// The last moving step, whose crossings wait for the next sample (the cubic's outer node).
    pending: Option<Step>,
    /// The moving step before `pending`, whose crossings wait for the step after `pending`
    /// (whether `pending` is a pass gap, whose far node is not to be used).
    held: Option<Step>,
    /// The pass gaps met (module `gaps`).
    pass_gaps: Vec<PassGap>,
    /// `(t, unwrapped DUT, unwrapped reference)` of every sample, kept while a lag may have to
    /// be removed (the reference is then re-read at `t − τ`).
    samples: Vec<(f64, f64, f64)>,
    keep_samples: bool,
    /// Whether the kept samples' times increase.
    sorted: bool,
    /// Every crossing, kept to estimate the lag.
    crossings: Option<Vec<Crossing>>,
    /// Moving sample steps.
    steps: usize,
    /// Sum of the reference's speed over each grid point's crossings, rad/s.
    speed_sum: Vec<f64>,
    /// The DUT's quantum, from the steps between its readings.
    quantum: QuantumTracker,
}

/// A step between two consecutive moving samples: DUT readings `u` (unwrapped) and differences
/// `d` at both ends, the run's travel before it, and the sample before it if the run goes on.
#[derive(Debug, Clone, Copy)]
struct Step {
    /// Time at the step's start and end.
    t0: f64,
    t1: f64,
    u0: f64,
    d0: f64,
    u1: f64,
    d1: f64,
    travelled: f64,
    before: Option<(f64, f64)>,
    /// The sample before `before`, if the run goes on that far back.
    before2: Option<(f64, f64)>,
    /// A pass gap (module `gaps`), with its travel over its larger neighbour's: its crossings
    /// are not measurements.
    gap: Option<f64>,
}

impl Step {
    /// The travel of the DUT and of the reference over the step.
    fn travel(&self) -> (f64, f64) {
        let du = self.u1 - self.u0;
        (du.abs(), (du - (self.d1 - self.d0)).abs())
    }

    /// If this step is a pass gap (module `gaps`), its DUT travel over the larger of its
    /// neighbours': more than [`GAP_RATIO`] times theirs for both the DUT and the reference.
    /// `next` is the travel of the step after it in the same run.
    fn gap_ratio(&self, next: Option<(f64, f64)>) -> Option<f64> {
        let before = self.before.map(|(u, d)| {
            let du = self.u0 - u;
            (du.abs(), (du - (self.d0 - d)).abs())
        });
        let (du, dr) = before
            .into_iter()
            .chain(next)
            .reduce(|a, b| (a.0.max(b.0), a.1.max(b.1)))?;
        let (tu, tr) = self.travel();
        (tu > GAP_RATIO * du && tr > GAP_RATIO * dr).then(|| tu / du)
    }

    /// Whether `next` continues this step's run the same way.
    fn same_way(&self, next: &Step) -> bool {
        (self.u1 > self.u0) == (next.u1 > next.u0)
    }
}

/// The polynomial through points with distinct `x` (two to four of them), evaluated at `at`
/// (Lagrange form).
pub(crate) fn lagrange(nodes: &[(f64, f64)], at: f64) -> f64 {
    nodes
        .iter()
        .enumerate()
        .map(|(k, &(xk, yk))| {
            nodes
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != k)
                .fold(yk, |acc, (_, &(xj, _))| acc * (at - xj) / (xk - xj))
        })
        .sum()
}

impl ReferenceCal {
    /// A calibration with these options.
    pub fn new(opts: ReferenceOptions) -> Self {
        let n = opts.points;
        let keep = opts.latency != Latency::Fixed(0.0);
        ReferenceCal {
            samples: Vec::new(),
            keep_samples: keep,
            sorted: true,
            crossings: (opts.latency == Latency::Auto).then(Vec::new),
            steps: 0,
            speed_sum: vec![0.0; n],
            quantum: QuantumTracker::default(),
            opts,
            dut: Unwrapper::new(),
            reference: Unwrapper::new(),
            last: None,
            first: None,
            up: vec![Welford::default(); n],
            down: vec![Welford::default(); n],
            low: vec![f64::INFINITY; n],
            high: vec![f64::NEG_INFINITY; n],
            travel: 0.0,
            reference_travel: 0.0,
            d_min: f64::INFINITY,
            d_max: f64::NEG_INFINITY,
            run: None,
            pending: None,
            held: None,
            pass_gaps: Vec::new(),
        }
    }

    /// Adds a sample: time (s), the DUT's and the reference's readings (radians). Samples with a
    /// non-finite value are skipped (and break the interpolation between neighbours).
    pub fn push(&mut self, t: f64, dut: f64, reference: f64) {
        let finite = t.is_finite() && dut.is_finite() && reference.is_finite();
        self.quantum.add(if finite { dut } else { f64::NAN });
        if !finite {
            if self.keep_samples && t.is_finite() {
                self.keep(t, f64::NAN, f64::NAN);
            }
            self.flush();
            self.last = None;
            return;
        }
        let u = self.dut.unwrap(dut);
        let r = self.reference.unwrap(reference);
        if self.keep_samples {
            self.keep(t, u, r);
        }
        let (u0, r0) = *self.first.get_or_insert((u, r));
        let d = (u - u0) - (r - r0);
        let previous = self.last.replace((t, u, d));
        let Some((t_prev, u_prev, d_prev)) = previous else {
            return;
        };
        let (dt, du) = (t - t_prev, u - u_prev);
        // Out-of-order time stamps and jumps of half a revolution cannot be interpolated across.
        if dt <= 0.0 || du.abs() >= PI || du.abs() < self.opts.min_speed * dt {
            self.flush();
            return;
        }
        self.steps += 1;
        self.travel += du.abs();
        self.reference_travel += (d_prev - d + du).abs();
        self.d_min = self.d_min.min(d).min(d_prev);
        self.d_max = self.d_max.max(d).max(d_prev);
        let increasing = du > 0.0;
        let travelled = match self.run {
            Some((dir, travel)) if dir == increasing => travel,
            _ => 0.0,
        };
        self.run = Some((increasing, travelled + du.abs()));
        let mut step = Step {
            t0: t_prev,
            t1: t,
            u0: u_prev,
            d0: d_prev,
            u1: u,
            d1: d,
            travelled,
            before: None,
            before2: None,
            gap: None,
        };
        // Every push either leaves its step pending or flushes, so a pending step ends at this
        // step's start: contiguous, and usable as the other's outer node if it goes the same way.
        if let Some(mut p) = self.pending.take() {
            let same_way = p.same_way(&step);
            p.gap = p.gap_ratio(same_way.then(|| step.travel()));
            // The node at a pass gap's start lies across it: not used after it.
            if same_way && p.gap.is_none() {
                step.before = Some((p.u0, p.d0));
                step.before2 = p.before;
            }
            self.cross_held(&p);
            self.held = Some(p);
        }
        self.pending = Some(step);
    }

    /// Crosses the held step, `next` the step after it (now judged a pass gap or not).
    fn cross_held(&mut self, next: &Step) {
        if let Some(h) = self.held.take() {
            let after = (h.same_way(next) && next.gap.is_none()).then_some((next.u1, next.d1));
            self.cross(&h, after);
        }
    }

    fn keep(&mut self, t: f64, u: f64, r: f64) {
        if self.samples.last().is_some_and(|&(t0, _, _)| t <= t0) {
            self.sorted = false;
        }
        self.samples.push((t, u, r));
    }

    /// Crossings of the held and the pending step (the latter without an outer node after it).
    fn flush(&mut self) {
        match self.pending.take() {
            Some(mut p) => {
                p.gap = p.gap_ratio(None);
                self.cross_held(&p);
                self.cross(&p, None);
            }
            None => {
                if let Some(h) = self.held.take() {
                    self.cross(&h, None);
                }
            }
        }
    }

    /// Adds the grid crossings of a step to the statistics: the cubic through the samples either
    /// side where the run goes on both ways (`before` and `after`); at the end of a run the cubic
    /// through the step and the two samples before it; else the parabola or, for a lone step,
    /// the straight line.
    fn cross(&mut self, s: &Step, after: Option<(f64, f64)>) {
        let n = self.up.len();
        if n == 0 {
            return;
        }
        let grid = TAU / n as f64;
        let du = s.u1 - s.u0;
        // The reference's speed over the step: its reading is `u − d` plus a constant.
        let speed = (du - (s.d1 - s.d0)) / (s.t1 - s.t0);
        let (lo, hi) = if du > 0.0 { (s.u0, s.u1) } else { (s.u1, s.u0) };
        // Readings so large that grid indices lose precision cannot be placed on the grid.
        if lo.abs().max(hi.abs()) / grid > 1e15 {
            return;
        }
        // Grid points in (lo, hi] going up, [lo, hi) going down: each crossing counted once.
        let (first, last) = if du > 0.0 {
            ((lo / grid).floor() as i64 + 1, (hi / grid).floor() as i64)
        } else {
            ((lo / grid).ceil() as i64, (hi / grid).ceil() as i64 - 1)
        };
        let past_approach =
            |k: i64| s.travelled + (k as f64 * grid - s.u0).abs() >= self.opts.approach;
        if let Some(ratio) = s.gap {
            // Not measured: only where it was, for the map and the warning.
            let used: Vec<i64> = (first..=last).filter(|&k| past_approach(k)).collect();
            if let (Some(&a), Some(&b)) = (used.iter().min(), used.iter().max()) {
                self.pass_gaps.push(PassGap {
                    increasing: du > 0.0,
                    from: wrap_2pi(s.u0),
                    to: wrap_2pi(s.u1),
                    t: (s.t0, s.t1),
                    ratio,
                    grid: (a, b),
                });
            }
            return;
        }
        for k in first..=last {
            let theta = k as f64 * grid;
            if !past_approach(k) {
                continue;
            }
            let (p0, p1) = ((s.u0, s.d0), (s.u1, s.d1));
            let x = match (s.before2, s.before, after) {
                (_, Some(b), Some(a)) => lagrange(&[b, p0, p1, a], theta),
                (Some(b2), Some(b), None) => lagrange(&[b2, b, p0, p1], theta),
                (None, Some(b), None) => lagrange(&[b, p0, p1], theta),
                (_, None, Some(a)) => lagrange(&[p0, p1, a], theta),
                _ => lagrange(&[p0, p1], theta),
            };
            let i = k.rem_euclid(n as i64) as usize;
            if du > 0.0 {
                self.up[i].add(x);
            } else {
                self.down[i].add(x);
            }
            self.low[i] = self.low[i].min(x);
            self.high[i] = self.high[i].max(x);
            self.speed_sum[i] += speed;
            if let Some(c) = self.crossings.as_mut() {
                c.push(Crossing {
                    bin: i as u32,
                    up: du > 0.0,
                    x,
                    w: speed,
                });
            }
        }
    }

    /// The calibration from the samples pushed.
    ///
    /// With [`Latency::Auto`] the lag is first fitted on the crossings ([`LatencyFit`]); where
    /// it is removed, the map is computed again from the kept samples with the reference read at
    /// `t − τ` (a cubic in time), the fit is repeated on that map for what is left of `τ`, and
    /// the map computed once more with the sum. A given lag ([`Latency::Fixed`]) is removed the
    /// same way.
    pub fn finish(mut self) -> Result<ReferenceCalibration, ReferenceError> {
        self.flush();
        let samples = std::mem::take(&mut self.samples);
        let sorted = self.sorted;
        match self.opts.latency {
            Latency::Fixed(0.0) => self.finish_map(None),
            Latency::Fixed(tau) => {
                if !sorted {
                    return Err(ReferenceError::Options(
                        "a latency can only be removed from a log whose time stamps increase"
                            .to_string(),
                    ));
                }
                let result = LatencyResult {
                    applied: tau,
                    source: LatencySource::Given,
                    fit: None,
                };
                self.again(&samples, tau, false).finish_map(Some(result))
            }
            Latency::Auto => {
                let first = self
                    .crossings
                    .as_deref()
                    .and_then(|c| latency::fit(c, self.opts.points, self.steps));
                let source = match first {
                    None => LatencySource::Unavailable,
                    Some(_) if !sorted => LatencySource::Unavailable,
                    Some(f) if !f.separable() => LatencySource::Ambiguous,
                    Some(f) if !f.significant() => LatencySource::Insignificant,
                    Some(_) => LatencySource::Estimated,
                };
                let (Some(f), LatencySource::Estimated) = (first, source) else {
                    let result = LatencyResult {
                        applied: 0.0,
                        source,
                        fit: first,
                    };
                    return self.finish_map(Some(result));
                };
                let second = self.again(&samples, f.tau, true);
                let rest = second
                    .crossings
                    .as_deref()
                    .and_then(|c| latency::fit(c, second.opts.points, second.steps));
                let (tau, u_tau) = rest.map_or((f.tau, f.u_tau), |r| (f.tau + r.tau, r.u_tau));
                let result = LatencyResult {
                    applied: tau,
                    source,
                    fit: Some(LatencyFit { tau, u_tau, ..f }),
                };
                if tau == f.tau {
                    second.finish_map(Some(result))
                } else {
                    self.again(&samples, tau, false).finish_map(Some(result))
                }
            }
        }
    }

    /// A calibration of the kept samples with the reference read at `t − τ`, its crossings
    /// recorded if `record`.
    fn again(&self, samples: &[(f64, f64, f64)], tau: f64, record: bool) -> ReferenceCal {
        let mut cal = ReferenceCal::new(ReferenceOptions {
            latency: Latency::Fixed(0.0),
            ..self.opts.clone()
        });
        if record {
            cal.crossings = Some(Vec::new());
        }
        let reference: Vec<(f64, f64)> = samples.iter().map(|&(t, _, r)| (t, r)).collect();
        for &(t, u, _) in samples {
            let r = latency::interpolate(&reference, t - tau).unwrap_or(f64::NAN);
            cal.push(t, u, r);
        }
        cal.flush();
        cal
    }

    /// The calibration from the crossings gathered, `latency` saying what lag they were
    /// gathered with.
    fn finish_map(
        mut self,
        latency: Option<LatencyResult>,
    ) -> Result<ReferenceCalibration, ReferenceError> {
        self.flush();
        let n = self.opts.points;
        if n < 2 {
            return Err(ReferenceError::Options(format!(
                "the map needs at least 2 points, {n} asked for"
            )));
        }
        let step = TAU / n as f64;
        let revolutions = self.travel / TAU;
        let covered: Vec<bool> = (0..n)
            .map(|i| self.up[i].n > 0 || self.down[i].n > 0)
            .collect();
        let crossed = covered.iter().filter(|&&c| c).count();
        if crossed < 2 {
            return Err(ReferenceError::TooLittleMotion {
                revolutions,
                crossed,
            });
        }
        if self.reference_travel < 0.1 * self.travel {
            return Err(ReferenceError::ReferenceStill {
                reference_deg: self.reference_travel.to_degrees(),
                dut_deg: self.travel.to_degrees(),
            });
        }
        let tol = self.opts.follow_tol;
        let repeat = (0..n)
            .filter(|&i| self.up[i].n + self.down[i].n >= 2)
            .map(|i| (self.high[i] - self.low[i], i))
            .max_by(|a, b| a.0.total_cmp(&b.0));
        match repeat {
            Some((spread, i)) if spread > tol => {
                return Err(ReferenceError::NotRepeating {
                    spread_deg: spread.to_degrees(),
                    at_deg: (i as f64 * step).to_degrees(),
                    tol_deg: tol.to_degrees(),
                });
            }
            None if self.d_max - self.d_min > tol => {
                return Err(ReferenceError::NotFollowing {
                    change_deg: (self.d_max - self.d_min).to_degrees(),
                    revolutions,
                    tol_deg: tol.to_degrees(),
                });
            }
            _ => {}
        }
        let layout = layout(&covered, step, self.opts.max_gap)?;
        // The bins of the map's points, in grid order.
        let bins: Vec<usize> = match layout {
            Layout::Turn { .. } => (0..n).collect(),
            Layout::Range { first, len } => (0..len).map(|j| (first + j) % n).collect(),
        };
        let measured = |i: usize| match (self.up[i].n, self.down[i].n) {
            (0, 0) => None,
            (0, _) => Some(self.down[i].mean),
            (_, 0) => Some(self.up[i].mean),
            _ => Some(0.5 * (self.up[i].mean + self.down[i].mean)),
        };
        let mut raw: Vec<f64> = bins.iter().map(|&i| measured(i).unwrap_or(0.0)).collect();
        let (pool_up, pool_down) = (pooled(&self.up), pooled(&self.down));
        let quantization = self
            .quantum
            .quantum()
            .map(|q| Quantization::new(q, pooled(self.up.iter().chain(&self.down))));
        // A direction never crossed twice at a point has no repeatability: a pass's noise is
        // then taken from the scatter of the reversal between neighbouring points.
        // Neighbouring points between the same two samples share their noise, which the
        // scatter between neighbours does not see: scaled by the grid points per sample step.
        let per_step = bins
            .iter()
            .map(|&i| f64::from(self.up[i].n + self.down[i].n))
            .sum::<f64>()
            / self.steps.max(1) as f64;
        let scatter =
            reversal_scatter(&self.up, &self.down, &bins).map(|s| s * per_step.max(1.0).sqrt());
        let from_scatter = scatter.is_some() && (pool_up.is_none() || pool_down.is_none());
        let (pool_up, pool_down) = (pool_up.or(scatter), pool_down.or(scatter));
        let sem2_of = |w: &Welford, pool: Option<f64>| -> f64 {
            let s = if w.n >= 2 {
                Some((w.m2.max(0.0) / f64::from(w.n - 1)).sqrt())
            } else {
                pool
            };
            s.map_or(0.0, |s| s * s / f64::from(w.n))
        };
        // Points measured one way only: corrected by half the reversal next to them.
        let directions: Vec<ends::Directions> = bins
            .iter()
            .map(|&i| {
                let (a, b) = (&self.up[i], &self.down[i]);
                ends::Directions {
                    up: (a.n > 0).then(|| (a.mean, sem2_of(a, pool_up))),
                    down: (b.n > 0).then(|| (b.mean, sem2_of(b, pool_down))),
                }
            })
            .collect();
        let turn = matches!(layout, Layout::Turn { .. });
        let mut extra_u2 = vec![0.0; bins.len()];
        let mut end_correction: Option<EndCorrection> = None;
        for (j, c) in ends::corrections(&directions, turn).into_iter().enumerate() {
            if let Some((add, u)) = c {
                raw[j] += add;
                extra_u2[j] += u * u;
                let e = end_correction.get_or_insert(EndCorrection {
                    points: 0,
                    max_correction: 0.0,
                    max_u: 0.0,
                });
                e.points += 1;
                e.max_correction = e.max_correction.max(add.abs());
                e.max_u = e.max_u.max(u);
            }
        }
        // The map's points some pass measured; the others are a bridged gap's.
        let measured_at: Vec<bool> = bins.iter().map(|&i| covered[i]).collect();
        let crossings: f64 = bins
            .iter()
            .map(|&i| f64::from(self.up[i].n + self.down[i].n))
            .sum();
        // The ripple taken out at each point (zero without one), out of each direction's mean
        // as out of the map: it is the reference's error, not the DUT's.
        let mut ripple_at = vec![0.0; raw.len()];
        let ripple = match self.opts.reference_kind {
            ReferenceKind::Encoder => None,
            ReferenceKind::Commanded { pole_pairs } => {
                let (u0, r0) = self.first.unwrap_or((0.0, 0.0));
                // The reference's own reading at each point: the DUT's reading minus the
                // difference (`d = (u − u₀) − (r − r₀)`).
                let reference: Vec<f64> = bins
                    .iter()
                    .zip(&raw)
                    .map(|(&i, &x)| i as f64 * step - x - u0 + r0)
                    .collect();
                let per_sample = crossings / self.steps.max(1) as f64;
                let (fit, value, u_fit) = ripple::fit(
                    &raw,
                    &measured_at,
                    &reference,
                    n,
                    pole_pairs,
                    turn,
                    per_sample,
                )
                .map_err(|ripple::RippleProblem::TooShort { periods }| {
                    ReferenceError::CommandedTooShort {
                        periods,
                        pole_pairs,
                    }
                })?;
                // Taken out where measured only: a bridged point never held it.
                for j in (0..raw.len()).filter(|&j| measured_at[j]) {
                    raw[j] -= value[j];
                    extra_u2[j] += u_fit[j] * u_fit[j];
                    ripple_at[j] = value[j];
                }
                Some(fit)
            }
        };
        if let Some(LatencyResult {
            source: LatencySource::Estimated,
            fit: Some(f),
            ..
        }) = latency
        {
            // The lag's uncertainty moves a point by u(τ)·ω̄, ω̄ the mean signed speed of its
            // crossings (nothing where both directions went at the same speed).
            for (j, &i) in bins.iter().enumerate() {
                let count = f64::from(self.up[i].n + self.down[i].n);
                if count > 0.0 {
                    extra_u2[j] += (f.u_tau * self.speed_sum[i] / count).powi(2);
                }
            }
        }
        let gap = match layout {
            Layout::Turn {
                gap: Some((before, points)),
            } => {
                // What a gap of this width can hide (module `gaps`), from the measured map
                // with any model taken out; else the measured map's peak to peak.
                let bound = gaps::bridge_bound(&raw, &measured_at, points + 1, true)
                    .or_else(|| {
                        range(
                            raw.iter()
                                .zip(&measured_at)
                                .filter(|p| *p.1)
                                .map(|p| (*p.0, *p.0)),
                        )
                    })
                    .unwrap_or(0.0);
                // Linear across the gap, from the measured point before it to the one after.
                let after = (before + points + 1) % n;
                let (y0, y1) = (raw[before], raw[after]);
                for j in 1..=points {
                    let f = j as f64 / (points + 1) as f64;
                    raw[(before + j) % n] = y0 + f * (y1 - y0);
                }
                let from = before as f64 * step;
                let size = (points + 1) as f64 * step;
                Some(Gap {
                    from,
                    to: from + size,
                    size,
                    points,
                    bound,
                })
            }
            _ => None,
        };
        let offset = raw.iter().sum::<f64>() / raw.len() as f64;
        let stats = |w: &Welford, ripple: f64| PointStats {
            n: w.n,
            mean: w.mean - offset - ripple,
            s: (w.n >= 2).then(|| (w.m2.max(0.0) / f64::from(w.n - 1)).sqrt()),
        };
        let up: Vec<PointStats> = bins
            .iter()
            .zip(&ripple_at)
            .map(|(&i, &r)| stats(&self.up[i], r))
            .collect();
        let down: Vec<PointStats> = bins
            .iter()
            .zip(&ripple_at)
            .map(|(&i, &r)| stats(&self.down[i], r))
            .collect();
        let sem2 = |p: &PointStats, pool: Option<f64>| -> Option<f64> {
            let s = p.s.or(pool)?;
            Some(s * s / f64::from(p.n))
        };
        let mut no_repeatability = false;
        let mut u: Vec<Option<f64>> = up
            .iter()
            .zip(&down)
            .zip(&extra_u2)
            .map(|((a, b), extra)| {
                let var = match (a.n, b.n) {
                    (0, 0) => return None,
                    (0, _) => sem2(b, pool_down),
                    (_, 0) => sem2(a, pool_up),
                    _ => sem2(a, pool_up)
                        .zip(sem2(b, pool_down))
                        .map(|(x, y)| mean_variance(Some(x), Some(y))),
                };
                let var = var.unwrap_or_else(|| {
                    no_repeatability = true;
                    0.0
                });
                let u_q = quantization.map_or(0.0, |q| q.u);
                Some(point_uncertainty(
                    var,
                    *extra + u_q * u_q,
                    self.opts.reference_u,
                ))
            })
            .collect();
        if let Some(g) = gap {
            // A bridged point carries the larger uncertainty of the two it is interpolated from
            // and the most a gap of its width can hide (module `gaps`).
            let before = (g.from / step).round() as usize % n;
            let after = (before + g.points + 1) % n;
            let edge = u[before].unwrap_or(0.0).max(u[after].unwrap_or(0.0));
            for j in 1..=g.points {
                u[(before + j) % n] = Some(edge.hypot(g.bound));
            }
        }
        let u: Vec<f64> = u.into_iter().map(|u| u.unwrap_or(0.0)).collect();

        let map = match layout {
            Layout::Turn { .. } => TableMap::Turn(ErrorMap::new(raw)),
            Layout::Range { first, .. } => TableMap::Range(
                RangeMap::new(first as f64 * step, step, raw)
                    .map_err(|e| ReferenceError::Options(e.to_string()))?,
            ),
        };
        let targets = target_points(&self.opts.targets, &map, step)?
            .into_iter()
            .map(|j| TargetStats {
                angle: map.grid_angle(j),
                up: up[j],
                down: down[j],
            })
            .collect::<Vec<_>>();
        let (t_up, t_down): (Vec<PointStats>, Vec<PointStats>) =
            targets.iter().map(|t| (t.up, t.down)).unzip();
        let iso = iso_230_2(&t_up, &t_down);

        let min_passes =
            |p: &[PointStats]| p.iter().map(|p| p.n).filter(|&n| n > 0).min().unwrap_or(0);
        let min_passes = (min_passes(&up), min_passes(&down));
        let mut warnings = Vec::new();
        if no_repeatability {
            warnings.push(
                "some points were crossed only once in every direction: their u_arcsec holds only the reference's \
                 uncertainty; record several passes to estimate the repeatability"
                    .to_string(),
            );
        } else if from_scatter {
            warnings.push(
                "no point was crossed twice in one direction: u_arcsec takes a pass's noise from the scatter of the \
                 reversal between neighbouring points (a lower bound: noise common to neighbours is not in it); record \
                 several passes to estimate the repeatability"
                    .to_string(),
            );
        }
        let (has_up, has_down) = (min_passes.0 > 0, min_passes.1 > 0);
        if has_up && has_down {
            // At a range's ends one direction is missing by design (the approach after each
            // reversal); elsewhere a point measured one way only mixes the two directions.
            let margin = self.opts.approach + 2.0 * step;
            let len = up.len();
            let inner = |j: usize| match map {
                TableMap::Turn(_) => true,
                TableMap::Range(_) => {
                    let x = j as f64 * step;
                    x > margin && (len - 1 - j) as f64 * step > margin
                }
            };
            if (0..len).any(|j| inner(j) && (up[j].n == 0) != (down[j].n == 0)) {
                warnings.push(
                    "some points inside the range were crossed in one direction only, others in both: their values are \
                     corrected by half the reversal measured next to them (an extrapolation, in their u); record the \
                     motion over the whole range in each direction"
                        .to_string(),
                );
            }
        }
        for (name, has, m) in [
            ("increasing", has_up, min_passes.0),
            ("decreasing", has_down, min_passes.1),
        ] {
            if has && m < 5 {
                warnings.push(format!(
                    "only {m} pass(es) at some points with {name} readings; ISO 230-2 asks for 5 per direction"
                ));
            }
        }
        if let Some(w) = latency.as_ref().and_then(latency_warning) {
            warnings.push(w);
        }
        if let Some(g) = gap {
            warnings.push(format!(
                "the DUT never reached the readings between {:.3}° and {:.3}° (a gap of {:.3}° in the turn, {} grid point(s)): \
                 the map bridges it by linear interpolation, not by measurement{}, its u there holding {:.3}″, the most \
                 the measured map departs from a straight line over that width; record the whole turn to measure it \
                 (a gap wider than the `bridge_gap` option, {}°, gives a range table instead)",
                g.from.to_degrees(),
                wrap_2pi(g.to).to_degrees(),
                g.size.to_degrees(),
                g.points,
                if ripple.is_some() {
                    " (the motor's ripple, fitted where measured, is not taken out there)"
                } else {
                    ""
                },
                g.bound * ARCSEC_PER_RAD,
                self.opts.max_gap.to_degrees()
            ));
        }
        let groups = gaps::groups(&self.pass_gaps, n);
        const SHOWN: usize = 5;
        for g in groups.iter().take(SHOWN) {
            warnings.push(gaps::group_warning(g, self.gap_cover(g, &bins, &up, &down)));
        }
        if groups.len() > SHOWN {
            warnings.push(format!(
                "passes have no sample over {} more stretches of readings, left out of the map likewise",
                groups.len() - SHOWN
            ));
        }
        Ok(ReferenceCalibration {
            map,
            u,
            up,
            down,
            iso,
            targets,
            revolutions,
            min_passes,
            gap,
            pass_gaps: self.pass_gaps,
            repeat_spread: repeat.map(|r| r.0),
            latency,
            ends: end_correction,
            ripple,
            quantization,
            warnings,
            gear: None,
        })
    }
}

impl ReferenceCal {
    /// What the map holds at the grid points of a group of pass gaps, `bins` the map's bins in
    /// its order and `up`, `down` its statistics.
    fn gap_cover(
        &self,
        group: &[&PassGap],
        bins: &[usize],
        up: &[PointStats],
        down: &[PointStats],
    ) -> gaps::GapCover {
        let n = self.opts.points as i64;
        let mut crossed: Vec<usize> = group
            .iter()
            .flat_map(|g| (g.grid.0..=g.grid.1).map(|k| k.rem_euclid(n) as usize))
            .collect();
        crossed.sort_unstable();
        crossed.dedup();
        let mut cover = gaps::GapCover::default();
        for i in crossed {
            // The map's bins are consecutive (circularly) from the first.
            let j = (i + self.opts.points - bins[0]) % self.opts.points;
            match bins.get(j).map(|_| (up[j].n > 0, down[j].n > 0)) {
                None => cover.outside += 1,
                Some((true, true)) => cover.both += 1,
                Some((false, false)) => cover.bridged += 1,
                Some(_) => cover.one += 1,
            }
        }
        cover
    }
}

/// The warning of a run whose reversal may be latency or backlash: one speed per direction,
/// and a reversal larger than 3 of its standard uncertainties.
fn latency_warning(l: &LatencyResult) -> Option<String> {
    let f = l.fit?;
    if l.source != LatencySource::Ambiguous
        || f.reversal_if_no_latency.abs() <= 3.0 * f.u_reversal_if_no_latency
    {
        return None;
    }
    let speed = f.mean_speed.to_degrees();
    // Speeds to three significant figures at most, whatever their size.
    let decimals = |v: f64| (2.0 - v.abs().max(1e-9).log10().floor()).clamp(0.0, 6.0) as usize;
    let (fast, slow) = (speed, speed / 3.0);
    Some(format!(
        "the increasing and decreasing passes differ by {:.1}″ at one speed per direction (about {fast:.a$}°/s): this is \
         either a latency of {:.1} ms between the channels (the DUT's samples older if positive) or a backlash or \
         hysteresis of {:.1}″; at one speed the two read the same, so neither was removed (the map, the mean of both \
         directions, holds neither where both went at the same speed). To separate them record passes at two speeds \
         in each direction (e.g. {fast:.a$}°/s and {slow:.b$}°/s), or give the `latency` option (seconds) if the \
         interfaces' delay is known",
        f.reversal_if_no_latency * ARCSEC_PER_RAD,
        f.tau_if_no_backlash * 1e3,
        f.reversal_if_no_latency * ARCSEC_PER_RAD,
        a = decimals(fast),
        b = decimals(slow),
    ))
}

/// Which grid points a map holds.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Layout {
    /// Every point; `gap` = (the measured bin before a bridged gap, the gap's bins).
    Turn { gap: Option<(usize, usize)> },
    /// `len` bins from `first` on (circularly).
    Range { first: usize, len: usize },
}

/// The map's layout from the bins crossed: the whole turn if all were, or all but a gap of at
/// most `max_gap` (bridged); else the range between the largest run of uncrossed bins' ends,
/// which must hold every other uncrossed bin.
fn layout(covered: &[bool], step: f64, max_gap: f64) -> Result<Layout, ReferenceError> {
    let n = covered.len();
    let Some(start) = covered.iter().position(|&c| c) else {
        return Err(ReferenceError::TooLittleMotion {
            revolutions: 0.0,
            crossed: 0,
        });
    };
    // Runs of uncrossed bins, walking once round the circle from a crossed one.
    let (mut best, mut run, mut missing) = ((0, 0), None::<(usize, usize)>, 0);
    for k in 1..=n {
        let i = (start + k) % n;
        if covered[i] {
            if let Some(r) = run.take() {
                best = if r.1 > best.1 { r } else { best };
            }
        } else {
            missing += 1;
            let r = run.get_or_insert((i, 0));
            r.1 += 1;
        }
    }
    let (gap_start, gap_len) = best;
    if gap_len == 0 {
        return Ok(Layout::Turn { gap: None });
    }
    if missing > gap_len {
        let first = (0..n)
            .map(|k| (gap_start + gap_len + k) % n)
            .find(|&i| !covered[i])
            .unwrap_or(gap_start);
        return Err(ReferenceError::NotCovered {
            missing: missing - gap_len,
            points: n,
            first_deg: (first as f64 * step).to_degrees(),
        });
    }
    if (gap_len + 1) as f64 * step <= max_gap {
        return Ok(Layout::Turn {
            gap: Some(((gap_start + n - 1) % n, gap_len)),
        });
    }
    Ok(Layout::Range {
        first: (gap_start + gap_len) % n,
        len: n - gap_len,
    })
}

/// The variance of a point's mean deviation from its directions' squared standard errors
/// `s²/n` (module docs, "Uncertainty"): `(s↑²/n↑ + s↓²/n↓)/4` for the bidirectional mean where
/// both directions have passes, else the one direction's.
pub fn mean_variance(up: Option<f64>, down: Option<f64>) -> f64 {
    match (up, down) {
        (Some(x), Some(y)) => (x + y) / 4.0,
        (Some(x), None) | (None, Some(x)) => x,
        (None, None) => 0.0,
    }
}

/// A point's `u = √(u_mean² + extra + u_ref²)`: the variance of its mean ([`mean_variance`]),
/// any further variance (`extra`: the lag's and the DUT's undithered quantum's) and the
/// reference's standard uncertainty `u_ref`.
pub fn point_uncertainty(mean_variance: f64, extra: f64, reference_u: f64) -> f64 {
    (mean_variance + extra + reference_u.powi(2)).sqrt()
}

/// The map indices of the ISO 230-2 targets, in increasing order without repeats.
fn target_points(
    targets: &Targets,
    map: &TableMap,
    step: f64,
) -> Result<Vec<usize>, ReferenceError> {
    let len = map.len();
    let (start, span) = match map {
        TableMap::Turn(_) => (0.0, TAU),
        TableMap::Range(m) => (m.start(), m.span()),
    };
    let index = |x: f64| -> usize {
        let j = (x / step).round() as usize;
        if matches!(map, TableMap::Turn(_)) {
            j % len
        } else {
            j.min(len - 1)
        }
    };
    let mut points: Vec<usize> = match targets {
        Targets::Count(0) => {
            return Err(ReferenceError::Options(
                "at least one ISO 230-2 target is needed".to_string(),
            ));
        }
        // The middle of part j, (j + ½)·span/k, in grid steps, rounded in integers (exact:
        // k = the number of steps gives every grid point once).
        Targets::Count(k) => {
            let steps = match map {
                TableMap::Turn(_) => len,
                TableMap::Range(_) => len - 1,
            };
            (0..*k)
                .map(|j| ((2 * j + 1) * steps + k) / (2 * k))
                .map(|i| if steps == len { i % len } else { i.min(len - 1) })
                .collect()
        }
        Targets::Angles(angles) => angles
            .iter()
            .map(|&a| {
                let x = wrap_2pi(a - start);
                if matches!(map, TableMap::Range(_)) && x > span + 0.5 * step {
                    return Err(ReferenceError::Options(format!(
                        "the target {:.4}° lies outside the map's range {:.4}°…{:.4}°; choose targets inside it",
                        a.to_degrees(),
                        start.to_degrees(),
                        (start + span).to_degrees()
                    )));
                }
                Ok(index(x))
            })
            .collect::<Result<_, _>>()?,
    };
    points.sort_unstable();
    points.dedup();
    Ok(points)
}

/// A pass's standard deviation from the reversals `B_i = x̄_i↑ − x̄_i↓` of the points crossed
/// both ways, in grid order: each minus the mean of its 20 neighbours, `r`, has variance
/// `var(B)·(1 + 1/20)` for noise independent between points, and `var(B) = 2σ²` for one pass
/// each way. `None` with fewer than 21 such points.
fn reversal_scatter(up: &[Welford], down: &[Welford], bins: &[usize]) -> Option<f64> {
    const HALF: usize = 10;
    let b: Vec<f64> = bins
        .iter()
        .filter(|&&i| up[i].n > 0 && down[i].n > 0)
        .map(|&i| up[i].mean - down[i].mean)
        .collect();
    if b.len() < 2 * HALF + 1 {
        return None;
    }
    let residuals: Vec<f64> = (HALF..b.len() - HALF)
        .map(|j| {
            let local = (b[j - HALF..=j + HALF].iter().sum::<f64>() - b[j]) / (2 * HALF) as f64;
            b[j] - local
        })
        .collect();
    let var = residuals.iter().map(|r| r * r).sum::<f64>() / residuals.len() as f64;
    Some((var / (1.0 + 1.0 / (2 * HALF) as f64) / 2.0).sqrt())
}

/// The pooled standard deviation of a direction's points with `n ≥ 2`.
fn pooled<'a>(w: impl IntoIterator<Item = &'a Welford>) -> Option<f64> {
    let (m2, dof) = w
        .into_iter()
        .filter(|w| w.n >= 2)
        .fold((0.0, 0.0), |(m2, dof), w| {
            (m2 + w.m2.max(0.0), dof + f64::from(w.n - 1))
        });
    (dof > 0.0).then(|| (m2 / dof).sqrt())
}

/// Largest minus smallest of the values, `None` if there are none.
fn range(values: impl Iterator<Item = (f64, f64)>) -> Option<f64> {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), (a, b)| {
        (lo.min(a), hi.max(b))
    });
    (hi >= lo).then_some(hi - lo)
}

fn max(values: impl Iterator<Item = f64>) -> Option<f64> {
    values.fold(None, |m: Option<f64>, v| Some(m.map_or(v, |m| m.max(v))))
}

/// The ISO 230-2 figures from the per-point statistics (see the module doc).
pub(crate) fn iso_230_2(up: &[PointStats], down: &[PointStats]) -> Iso230_2 {
    let with_data =
        |p: &[PointStats]| -> Vec<PointStats> { p.iter().copied().filter(|p| p.n > 0).collect() };
    let (u, d) = (with_data(up), with_data(down));
    let means = |p: &[PointStats]| p.iter().map(|p| (p.mean, p.mean)).collect::<Vec<_>>();
    let bands = |p: &[PointStats]| {
        p.iter()
            .filter_map(|p| p.s.map(|s| (p.mean - 2.0 * s, p.mean + 2.0 * s)))
            .collect::<Vec<_>>()
    };
    let both: Vec<(&PointStats, &PointStats)> = up
        .iter()
        .zip(down)
        .filter(|(a, b)| a.n > 0 && b.n > 0)
        .collect();
    let reversals: Vec<f64> = both.iter().map(|(a, b)| a.mean - b.mean).collect();
    let bidirectional: Vec<f64> = up
        .iter()
        .zip(down)
        .filter_map(|(a, b)| match (a.n, b.n) {
            (0, 0) => None,
            (0, _) => Some(b.mean),
            (_, 0) => Some(a.mean),
            _ => Some(0.5 * (a.mean + b.mean)),
        })
        .collect();
    let r_bi = max(both.iter().filter_map(|(a, b)| {
        let (sa, sb) = (a.s?, b.s?);
        Some(
            (2.0 * sa + 2.0 * sb + (a.mean - b.mean).abs())
                .max(4.0 * sa)
                .max(4.0 * sb),
        )
    }));
    let r_up = max(u.iter().filter_map(|p| p.s.map(|s| 4.0 * s)));
    let r_down = max(d.iter().filter_map(|p| p.s.map(|s| 4.0 * s)));
    Iso230_2 {
        systematic_up: range(means(&u).into_iter()),
        systematic_down: range(means(&d).into_iter()),
        systematic: range(means(&u).into_iter().chain(means(&d))),
        mean_bidirectional: range(bidirectional.iter().map(|&v| (v, v))),
        reversal: max(reversals.iter().map(|b| b.abs())),
        mean_reversal: (!reversals.is_empty())
            .then(|| reversals.iter().sum::<f64>() / reversals.len() as f64),
        repeatability_up: r_up,
        repeatability_down: r_down,
        // With one direction only, the bidirectional figure is the unidirectional one.
        repeatability: r_bi
            .or(if d.is_empty() { r_up } else { None })
            .or(if u.is_empty() { r_down } else { None }),
        accuracy_up: range(bands(&u).into_iter()),
        accuracy_down: range(bands(&d).into_iter()),
        accuracy: range(bands(&u).into_iter().chain(bands(&d))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn welford_matches_the_two_pass_formula() {
        let xs = [1.0, 2.0, 4.0, 7.0];
        let mut w = Welford::default();
        xs.iter().for_each(|&x| w.add(x));
        let mean = 3.5;
        let var = xs.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / 3.0;
        assert!((w.mean - mean).abs() < 1e-15);
        assert!((w.m2 / 3.0 - var).abs() < 1e-12);
    }

    #[test]
    fn iso_figures_of_two_points() {
        let p = |mean: f64, s: f64| PointStats {
            n: 5,
            mean,
            s: Some(s),
        };
        let up = [p(1.0, 0.1), p(3.0, 0.2)];
        let down = [p(0.0, 0.1), p(2.0, 0.1)];
        let iso = iso_230_2(&up, &down);
        assert_eq!(iso.systematic_up, Some(2.0));
        assert_eq!(iso.systematic, Some(3.0));
        assert_eq!(iso.reversal, Some(1.0));
        assert_eq!(iso.mean_reversal, Some(1.0));
        assert!((iso.repeatability_up.unwrap() - 0.8).abs() < 1e-12);
        // Point 1: 2·0.2 + 2·0.1 + 1 = 1.6.
        assert!((iso.repeatability.unwrap() - 1.6).abs() < 1e-12);
        // max(3 + 0.4) − min(0 − 0.2) = 3.6.
        assert!((iso.accuracy.unwrap() - 3.6).abs() < 1e-12);
        assert!((iso.mean_bidirectional.unwrap() - 2.0).abs() < 1e-12);
    }

    #[test]
    fn too_few_points_is_an_error_not_a_panic() {
        let mut cal = ReferenceCal::new(ReferenceOptions {
            points: 0,
            ..ReferenceOptions::default()
        });
        cal.push(0.0, 0.0, 0.0);
        cal.push(0.1, 0.1, 0.1);
        assert!(matches!(cal.finish(), Err(ReferenceError::Options(_))));
    }

    #[test]
    fn layouts_of_coverage() {
        let step = TAU / 10.0;
        let cov = |s: &str| s.chars().map(|c| c == '#').collect::<Vec<bool>>();
        assert_eq!(
            layout(&cov("##########"), step, 0.1).unwrap(),
            Layout::Turn { gap: None }
        );
        // One bin missing: a gap of 2 steps (72°) between the measured neighbours.
        assert_eq!(
            layout(&cov("####.#####"), step, 2.0 * step).unwrap(),
            Layout::Turn { gap: Some((3, 1)) }
        );
        assert_eq!(
            layout(&cov("####.#####"), step, 1.5 * step).unwrap(),
            Layout::Range { first: 5, len: 9 }
        );
        // A range across bin 0.
        assert_eq!(
            layout(&cov("##.....###"), step, 0.0).unwrap(),
            Layout::Range { first: 7, len: 5 }
        );
        // A hole inside the range.
        assert!(matches!(
            layout(&cov("##.#.....#"), step, 0.0),
            Err(ReferenceError::NotCovered { missing: 1, .. })
        ));
    }

    /// A DUT with a steep, large error (15° at order 1 and 1° at order 8: slopes up to 0.4°
    /// per degree) against an exact reference, noise-free, swept 10° → 200° and back twice at
    /// 0.36° per sample: the map is the error within the cubic's bound, (9/384)·(hΔθ)⁴ of an
    /// order-h amplitude, here ≈ 6e-7 of 3600″ at order 8 — 0.01″ leaves room for the
    /// reading-versus-true-angle shift of the grid (exact: the map is a function of the reading).
    /// Measured: 0.0013″.
    #[test]
    fn steep_large_errors_are_interpolated_accurately() {
        let e =
            |th: f64| 15f64.to_radians() * (th + 0.3).cos() + 1f64.to_radians() * (8.0 * th).cos();
        let mut cal = ReferenceCal::new(ReferenceOptions::default());
        let (mut t, dth) = (0.0, 0.36f64.to_radians());
        let mut push = |cal: &mut ReferenceCal, th: f64| {
            cal.push(t, th + e(th), th);
            t += 0.01;
        };
        let (lo, hi) = (10f64.to_radians(), 200f64.to_radians());
        let steps = ((hi - lo) / dth) as usize;
        for _ in 0..2 {
            for k in 0..=steps {
                push(&mut cal, lo + k as f64 * dth);
            }
            for k in 0..=steps {
                push(&mut cal, lo + (steps - k) as f64 * dth);
            }
        }
        let cal = cal.finish().unwrap();
        let TableMap::Range(map) = &cal.map else {
            panic!("a range was swept")
        };
        // The truth at reading r: r − θ with θ + e(θ) = r (fixed point; |e′| ≤ 0.4).
        let truth = |r: f64| {
            let mut th = r;
            for _ in 0..200 {
                th = r - e(th);
            }
            r - th
        };
        let want: Vec<f64> = (0..map.len()).map(|i| truth(map.grid_angle(i))).collect();
        let mean = want.iter().sum::<f64>() / want.len() as f64;
        let worst = map
            .values()
            .iter()
            .zip(&want)
            .map(|(g, w)| (g - (w - mean)).abs())
            .fold(0.0, f64::max)
            * ARCSEC_PER_RAD;
        assert!(worst < 0.01, "{worst}″");
        assert!(
            cal.warnings
                .iter()
                .all(|w| !w.contains("one direction only")),
            "{:?}",
            cal.warnings
        );
    }
}
