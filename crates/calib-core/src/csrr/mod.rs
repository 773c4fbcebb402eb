//! CSRR self-calibration of two coaxial sensors (Gou et al., the CSRR paper, section II).
//!
//! Two sensors on one axis are read together while the axis turns whole revolutions; between
//! these sessions one rotor is turned by Δ_k against the other. From the log, [`Csrr`] finds the
//! sessions ([`crate::segment`]), reduces them as they stream by, and solves for both sensors'
//! error maps:
//!
//! - [`Method::Joint`] (default): every sample satisfies `e_a(x) − e_b(y) + Δ_k = x − y` exactly;
//!   both maps and all Δ_k are fitted at once by least squares ([`joint`]). Needs a handful of
//!   sessions, no time stamps, and is exact for large errors.
//! - [`Method::Paper`]: the published estimate (eqs. 4–7, [`paper`]), one map point per session.
//!
//! # What it cannot see
//! An absolute offset (maps are zero-mean), and order `h` when `h·(Δ_k − Δ_0) ≡ 0 (mod 360°)`
//! for every session ([`observability`]); those orders are left out and named, with the extra
//! relative rotation that would reveal them.
//!
//! # Example
//! The crate root's example feeds five simulated sessions to [`Csrr`] and reads both maps.

// `joint` and `paper` are public for their documentation and result types; the solvers'
// building blocks stay private, and the reference check's types are re-exported here.
mod bins;
pub mod joint;
pub mod latency;
mod observability;
pub mod paper;
mod reference;
#[doc(hidden)]
pub mod stages;

pub use crate::detection::{DETECTION_FLOOR, detection_floor};
pub use observability::{coefficient_variance, observability};
pub use reference::{EffectiveRange, EpsHarmonic, ReferenceCheck};

use crate::angle::{ARCSEC_PER_RAD, PartialTurn, Travel};
use crate::detection::{self, Verdict};
use crate::error_map::ErrorMap;
use crate::harmonics::FourierSeries;
use crate::segment::{SegmentOptions, Segmentation, Segmenter, SessionSink};
use crate::uncertainty::{Evaluation, MapComponent, MapUncertainty, interpolation_uncertainty};
use bins::{Bin, SessionBinner};
use joint::{ExcludedOrder, JointOptions, UnresolvedOrder};
use paper::{PaperAccumulator, PaperPoint};
use reference::ReferenceAccumulator;

/// One session, reduced to bins of A's reading.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct SessionData {
    /// Session id from the segmenter.
    pub id: usize,
    /// Start, s.
    pub start_s: f64,
    /// End, s.
    pub end_s: f64,
    /// Samples used.
    pub samples: u64,
    /// Revolutions covered.
    pub revolutions: f64,
    /// Occupied bins, ascending in `x`.
    pub bins: Vec<Bin>,
}

/// Why a CSRR calibration cannot be made from the data.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CsrrError {
    /// Fewer than two sessions.
    #[error(
        "found {found} session(s) of at least one revolution; CSRR needs at least 2, recorded at different relative rotations \
         (record whole revolutions with both rotors locked, turn one rotor against the other while stopped, and repeat; 5 sessions are a good start)"
    )]
    TooFewSessions {
        /// Sessions found.
        found: usize,
    },
    /// Every order is blind: all sessions share one relative rotation.
    #[error(
        "no harmonic order up to {max_order} is observable: the sessions' relative rotations are all (nearly) equal; \
         record sessions at different relative rotations (e.g. 0°, 76°, 87°, 141°, 179°)"
    )]
    NothingObservable {
        /// The highest order tried.
        max_order: usize,
    },
    /// The two sensors turn in opposite directions.
    #[error(
        "the two channels turn in opposite directions; one of them counts the other way round — negate its readings \
         (or check that the right channels were chosen)"
    )]
    OppositeDirections,
    /// A sensor moved but never turned a whole revolution: the likely reason the solve failed
    /// (`cause`).
    #[error("sensor {sensor} {turn}")]
    NoWholeTurn {
        /// `A` or `B`.
        sensor: char,
        /// Its travel.
        turn: PartialTurn,
        /// The error the solve gave.
        #[source]
        cause: Box<CsrrError>,
    },
    /// One sensor's readings never change faster than the speed threshold.
    #[error(
        "sensor {sensor} never moves: its readings stay (nearly) constant over the whole log, so no session can be found; \
         check that the right channel was chosen and that it records the shaft's angle"
    )]
    NeverMoves {
        /// `A` or `B`.
        sensor: char,
    },
    /// The requested order needs denser sampling.
    #[error(
        "order {requested} needs at least {needed} samples per revolution, but the densest session has {available:.0}; \
         lower the `max_order` option or record more slowly / at a higher sample rate"
    )]
    TooFewSamplesPerRevolution {
        /// The order asked for.
        requested: usize,
        /// Samples per revolution it needs.
        needed: usize,
        /// Samples per revolution of the densest session.
        available: f64,
    },
    /// The paper method needs more sessions.
    #[error(
        "the paper method gives one map point per session and needs at least 3 sessions with whole revolutions, found {found}; \
         record many sessions densely covering 0–360° of relative rotation, or use the joint method (the default)"
    )]
    PaperTooFewSessions {
        /// Usable sessions.
        found: usize,
    },
    /// The fit's residual is far above the readings' noise: the maps cannot explain the data.
    #[error(
        "the fit leaves {residual_arcsec:.4}″ RMS per sample where the sessions repeat to {noise_arcsec:.4}″ from one revolution \
         to the next (more than 10× the noise): the maps cannot explain the data. Most likely the error lies in orders these \
         sessions cannot see (every relative rotation a multiple of the same angle) or the relative angle drifts within \
         sessions; record sessions at relative rotations that are not all multiples of one angle"
    )]
    Unexplained {
        /// RMS of the fit's residual per sample, arcsec.
        residual_arcsec: f64,
        /// The sessions' repeatability from one revolution to the next, arcsec per sample.
        noise_arcsec: f64,
    },
    /// The fit's residual is beyond half a revolution: the solve diverged rather than fit.
    #[error(
        "the solve diverged: its residual grew beyond half a revolution RMS per sample, where the sessions repeat to \
         {noise_arcsec:.4}″; the data are not what CSRR models (two sensors on one shaft pair \
         sampled at the same instants): check the channels and their unit, and a lag between them (the `latency` option)"
    )]
    Diverged {
        /// RMS of the fit's residual per sample, degrees (any number; not a measure of anything).
        residual_deg: f64,
        /// The sessions' repeatability from one revolution to the next, arcsec per sample.
        noise_arcsec: f64,
    },
    /// The solve produced non-finite numbers (degenerate data).
    #[error(
        "the solve produced non-finite values: the data are degenerate (check that both channels carry real readings)"
    )]
    NotFinite,
    /// The solve failed with a lag between the channels left in the data ([`latency`]).
    #[error(
        "{older} samples are {lag_ms:.3} ms older than {newer} (u {u_ms:.3} ms), and the `latency` option \
         ({given_ms:.3} ms) leaves it in the data, where it moves `a − b` with every change of speed: \
         leave the `latency` option at auto to have it removed. The solve said: {cause}"
    )]
    Lag {
        /// `B's` or `A's`: whose samples are older.
        older: &'static str,
        /// The other one.
        newer: &'static str,
        /// The lag the sessions show, ms.
        lag_ms: f64,
        /// Its standard uncertainty, ms.
        u_ms: f64,
        /// The lag the option removed, ms.
        given_ms: f64,
        /// The solve's own error.
        cause: Box<CsrrError>,
    },
}

/// Which solver.
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Eq,
    Default,
    serde::Serialize,
    serde::Deserialize,
    schemars::JsonSchema,
)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// Joint least squares of both maps and all Δ_k ([`joint`]).
    #[default]
    Joint,
    /// The seed paper's published method ([`paper`]).
    Paper,
}

/// Options of a CSRR calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct CsrrOptions {
    /// The solver.
    pub method: Method,
    /// Highest order fitted (joint method); chosen from the sampling density when `None`
    /// ([`auto_max_order`] of the densest session's samples per revolution). Only the orders
    /// that stand above the noise are kept in the maps.
    pub max_order: Option<usize>,
    /// Session detection.
    pub segments: SegmentOptions,
    /// Bins per revolution of the streaming reduction (default 65536).
    pub bins_per_rev: usize,
    /// Orders with observability below this are left out (default 0.01).
    pub min_observability: f64,
    /// Points of the output maps; chosen so that linear interpolation of the table errs by less
    /// than 0.01″ when `None` (at least 3600).
    pub points: Option<usize>,
    /// Benchmark readings of A and B for the paper method, rad (default 0).
    pub benchmarks: (f64, f64),
    /// Whether samples carry a reference encoder's reading ([`Csrr::push_with_reference`]).
    pub reference: bool,
    /// B's lag behind A to remove, seconds (default 0): B's readings are moved to A's instants
    /// ([`latency`]). [`latency::calibrate`] finds it from the sessions.
    pub latency_s: f64,
}

impl Default for CsrrOptions {
    fn default() -> Self {
        CsrrOptions {
            method: Method::Joint,
            max_order: None,
            segments: SegmentOptions::default(),
            bins_per_rev: 65536,
            min_observability: 0.01,
            points: None,
            benchmarks: (0.0, 0.0),
            reference: false,
            latency_s: 0.0,
        }
    }
}

/// A session as the calibration used it.
#[derive(Debug, Clone, PartialEq)]
pub struct SessionSummary {
    /// Index among the used sessions, from 0.
    pub index: usize,
    /// The segmenter's id of the session (counts rejected segments too).
    pub id: usize,
    /// Start, s.
    pub start_s: f64,
    /// End, s.
    pub end_s: f64,
    /// Revolutions.
    pub revolutions: f64,
    /// Samples.
    pub samples: u64,
    /// Relative rotation against the first session, rad.
    pub relative_rotation: f64,
    /// The session's mean relative angle `Δ_k` as the method estimated it, rad.
    pub absolute_rotation: f64,
}

/// Advice for blind or ill-conditioned orders.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Advice {
    /// One more session at this relative rotation (against the first session), rad ...
    pub extra_rotation: f64,
    /// ... would raise the smallest observability over all fitted orders to this.
    pub min_observability: f64,
}

/// The result of a CSRR calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    /// The method used.
    pub method: Method,
    /// Sensor A's error map, as a function of A's reading.
    pub a: ErrorMap,
    /// Sensor B's error map, as a function of B's reading.
    pub b: ErrorMap,
    /// A's map as a Fourier series of A's reading (orders below half the map's points).
    pub a_series: FourierSeries,
    /// B's map as a Fourier series of B's reading.
    pub b_series: FourierSeries,
    /// The joint method's fitted errors as functions of the true angle, `(ε_a, ε_b)`.
    pub true_angle_series: Option<(FourierSeries, FourierSeries)>,
    /// The sessions used.
    pub sessions: Vec<SessionSummary>,
    /// How the log was segmented.
    pub segmentation: Segmentation,
    /// Highest order fitted.
    pub max_order: usize,
    /// The orders the maps hold (joint method): those up to `max_order` that stand above the
    /// noise by the significance rule (`docs/uncertainty.md`), ascending.
    pub orders: Vec<usize>,
    /// Orders left out of the maps because the relative rotations cannot see them.
    pub excluded: Vec<ExcludedOrder>,
    /// Orders above `max_order` where the fit's residual still holds periodic structure above
    /// the noise (joint method), ascending.
    pub unresolved: Vec<UnresolvedOrder>,
    /// What to record to reveal them.
    pub advice: Option<Advice>,
    /// RMS of the fit residual, rad (joint method).
    pub residual_rms: Option<f64>,
    /// The lag between the channels removed and what the sessions show after
    /// ([`latency::calibrate`]; `None` from [`Csrr::finish`] alone).
    pub latency: Option<latency::LatencyOutcome>,
    /// Solver iterations (joint method).
    pub iterations: usize,
    /// The paper method's points, one per session (paper method only).
    pub paper_points: Vec<PaperPoint>,
    /// Checks against the reference encoder, when one was given.
    pub reference: Option<ReferenceCheck>,
    /// The standard uncertainty of A's and B's maps at every table point, with their budgets
    /// (joint method: [`map_uncertainty`]; paper method: [`paper`]'s budget of the points' noise,
    /// the interpolation between them and ε_θ's bias). Given by both methods.
    pub uncertainty: Option<(MapUncertainty, MapUncertainty)>,
    /// Things the user should know.
    pub warnings: Vec<String>,
}

struct Sinks {
    binner: Option<SessionBinner>,
    paper: Option<PaperAccumulator>,
    reference: Option<ReferenceAccumulator>,
}

impl SessionSink for Sinks {
    fn sample(&mut self, session: usize, t: f64, x: f64, y: f64, d: f64, extra: &[f64]) {
        if let Some(b) = &mut self.binner {
            b.sample(session, t, x, y, d, extra);
        }
        if let Some(p) = &mut self.paper {
            p.sample(session, t, x, y, d, extra);
        }
        if let Some(r) = &mut self.reference {
            r.sample(session, t, x, y, d, extra);
        }
    }
    fn close(&mut self, session: usize, accepted: bool) {
        if let Some(b) = &mut self.binner {
            b.close(session, accepted);
        }
        if let Some(p) = &mut self.paper {
            p.close(session, accepted);
        }
        if let Some(r) = &mut self.reference {
            r.close(session, accepted);
        }
    }
}

/// A streaming CSRR calibration: [`Csrr::push`] every sample, then [`Csrr::finish`].
pub struct Csrr {
    opts: CsrrOptions,
    segmenter: Segmenter,
    sinks: Sinks,
    shift: Option<latency::TimeShift>,
    /// A's and B's travel, for [`CsrrError::NoWholeTurn`].
    travel: (Travel, Travel),
}

/// The error for a fit whose residual (`residual`, radians RMS) is far above the sessions'
/// repeatability (`repeat`): [`CsrrError::Unexplained`], or [`CsrrError::Diverged`] beyond half a
/// revolution, where the number is no residual of a fit any more.
fn unexplained(residual: f64, repeat: f64) -> CsrrError {
    if residual > std::f64::consts::PI {
        CsrrError::Diverged {
            residual_deg: residual.to_degrees(),
            noise_arcsec: repeat * ARCSEC_PER_RAD,
        }
    } else {
        CsrrError::Unexplained {
            residual_arcsec: residual * ARCSEC_PER_RAD,
            noise_arcsec: repeat * ARCSEC_PER_RAD,
        }
    }
}

/// Why CSRR needs whole turns, for [`CsrrError::NoWholeTurn`].
const NEEDS_WHOLE_TURNS: &str = "CSRR's self-calibration needs sessions of whole turns";

impl Csrr {
    /// A new calibration.
    pub fn new(opts: CsrrOptions) -> Self {
        let sinks = Sinks {
            binner: (opts.method == Method::Joint).then(|| SessionBinner::new(opts.bins_per_rev)),
            paper: (opts.method == Method::Paper)
                .then(|| PaperAccumulator::new(opts.benchmarks.0, opts.benchmarks.1)),
            reference: opts.reference.then(ReferenceAccumulator::new),
        };
        Csrr {
            segmenter: Segmenter::new(opts.segments),
            shift: (opts.latency_s != 0.0).then(|| latency::TimeShift::new(opts.latency_s)),
            opts,
            sinks,
            travel: Default::default(),
        }
    }

    /// Feeds one synchronized sample: time (s), A's and B's readings (rad), the log's session mark.
    pub fn push(&mut self, t: f64, x: f64, y: f64, mark: Option<u32>) {
        self.push_extra(t, x, y, mark, &[]);
    }

    /// Feeds one sample with a reference encoder's reading `r` (rad) on rotor B's shaft; the
    /// options must have [`CsrrOptions::reference`] set.
    pub fn push_with_reference(&mut self, t: f64, x: f64, y: f64, r: f64, mark: Option<u32>) {
        self.push_extra(t, x, y, mark, &[r]);
    }

    fn push_extra(&mut self, t: f64, x: f64, y: f64, mark: Option<u32>, extra: &[f64]) {
        self.travel.0.push(x);
        self.travel.1.push(y);
        let (segmenter, sinks) = (&mut self.segmenter, &mut self.sinks);
        match &mut self.shift {
            None => segmenter.push(t, x, y, mark, extra, sinks),
            Some(shift) => shift.push((t, x, y, mark, extra), |t, x, y, mark, extra| {
                segmenter.push(t, x, y, mark, extra, sinks);
            }),
        }
    }

    /// Solves, once every sample is in.
    pub fn finish(self) -> Result<Calibration, CsrrError> {
        self.segment().1.solve()
    }

    /// Ends the sessions: the lag between the channels they show (`Segmentation::latency`),
    /// and the solve still to run. A caller that reads the log again with the lag removed skips
    /// the solve; one that keeps this reading has the lag whether or not the solve succeeds (a
    /// lag can be what makes it fail).
    pub(crate) fn segment(mut self) -> (Option<crate::segment::LatencyEstimate>, Segmented) {
        let segmenter = std::mem::replace(&mut self.segmenter, Segmenter::new(self.opts.segments));
        let segmentation = segmenter.finish(&mut self.sinks);
        (
            segmentation.latency,
            Segmented {
                csrr: self,
                segmentation,
            },
        )
    }

    fn solve(mut self, segmentation: Segmentation) -> Result<Calibration, CsrrError> {
        let mut warnings = Vec::new();
        if let Some(shift) = &self.shift {
            let dropped = shift.dropped();
            let kept: u64 = segmentation.segments.iter().map(|s| s.samples).sum();
            if dropped * 100 > kept {
                warnings.push(format!(
                    "{dropped} samples left out: B's reading {:.3} ms later lies beyond the log or in a gap of it",
                    self.opts.latency_s * 1e3
                ));
            }
        }
        // Times from the log's start: a reader may count stamps from an origin of its own.
        let log_start = segmentation.segments.first().map_or(0.0, |s| s.start_s);
        for s in segmentation.short_segments() {
            warnings.push(format!(
                "the rotating segment {:.3}–{:.3} s after the log's start covers {:.2} revolutions, less than one: not used as a session",
                s.start_s - log_start,
                s.end_s - log_start,
                s.revolutions.abs()
            ));
        }
        if segmentation.accepted_sessions().count() == 0 {
            if segmentation.opposite_direction {
                return Err(CsrrError::OppositeDirections);
            }
            match segmentation.moved {
                (false, _) => return Err(CsrrError::NeverMoves { sensor: 'A' }),
                (_, false) => return Err(CsrrError::NeverMoves { sensor: 'B' }),
                _ => {}
            }
        }
        let mut cal = match self.opts.method {
            Method::Joint => {
                let binner = self.sinks.binner.take().expect("joint sink");
                finish_joint(&self.opts, binner.into_sessions(), segmentation, warnings)
            }
            Method::Paper => {
                let paper = self.sinks.paper.take().expect("paper sink");
                finish_paper(&self.opts, paper, segmentation, warnings)
            }
        }?;
        if let Some(r) = self.sinks.reference.take() {
            let deltas: Vec<(usize, f64)> = cal
                .sessions
                .iter()
                .map(|s| (s.id, s.absolute_rotation))
                .collect();
            cal.reference = Some(r.finish(&cal.a, &cal.b, &deltas));
        }
        Ok(cal)
    }
}

/// A calibration whose sessions are ended and whose solve is still to run ([`Csrr::segment`]).
pub(crate) struct Segmented {
    csrr: Csrr,
    segmentation: Segmentation,
}

impl Segmented {
    /// The joint solve ([`Csrr::finish`]); if it fails for a sensor that moved but never turned a
    /// whole revolution, the error is [`CsrrError::NoWholeTurn`].
    pub(crate) fn solve(self) -> Result<Calibration, CsrrError> {
        let Segmented {
            mut csrr,
            segmentation,
        } = self;
        let (a, b) = std::mem::take(&mut csrr.travel);
        csrr.solve(segmentation).map_err(|e| {
            let partial = |sensor, travel: &Travel| {
                travel
                    .partial_turn(NEEDS_WHOLE_TURNS)
                    .map(|turn| (sensor, turn))
            };
            match partial('A', &a).or_else(|| partial('B', &b)) {
                Some((sensor, turn)) => CsrrError::NoWholeTurn {
                    sensor,
                    turn,
                    cause: Box::new(e),
                },
                None => e,
            }
        })
    }
}

/// Fewest samples per revolution, for order `h`, that the joint solve accepts: 2.5 per period
/// (the Nyquist rate with margin for speed variation).
fn samples_needed(order: usize) -> usize {
    (order * 5).div_ceil(2)
}

/// The maximum order the sampling density supports: 40 % of the samples per revolution where
/// the data are densest (2.5 samples per period of the highest order), at most 2000. Orders that
/// hold nothing above the noise are dropped by the significance rule, so a high limit costs
/// computing time, not accuracy.
pub fn auto_max_order(samples_per_rev: f64) -> usize {
    ((0.4 * samples_per_rev).floor() as usize).clamp(1, 2000)
}

/// The largest error linear interpolation of a CSRR table may add between its points, arcsec.
pub const MAX_INTERPOLATION_ARCSEC: f64 = 0.01;

/// The joint method's tables are not made denser than needed for this interpolation error,
/// arcsec, however small the fit's noise (noise-free data would ask for the largest table).
pub const MIN_INTERPOLATION_ARCSEC: f64 = 0.001;

/// Grid points for a table of `series` such that periodic linear interpolation between them errs
/// by at most [`MAX_INTERPOLATION_ARCSEC`] (see [`table_points_within`]).
pub fn table_points(series: &FourierSeries) -> usize {
    table_points_within(series, MAX_INTERPOLATION_ARCSEC)
}

/// Grid points for a table of `series` such that periodic linear interpolation between them errs
/// by at most `tolerance_arcsec`: the error of linear interpolation of `A cos(hθ)` on a step `δ`
/// is at most `A·(hδ)²/8`. At least 3600 points (0.1°), a multiple of 3600 so 0.1° steps stay on
/// the grid, at most 1,843,200 (3600·2⁹, within the table limit of 3.6 million).
///
/// The joint method asks for the fit's noise `u_fit` (within 0.001–0.01″), so that reading
/// the table between its points adds no more than the fit's own uncertainty: with the orders
/// chosen by significance the maps are accurate to a few thousandths of an arcsecond, and a
/// 0.01″ interpolation error would dominate their `u`.
pub fn table_points_within(series: &FourierSeries, tolerance_arcsec: f64) -> usize {
    let curvature: f64 = series
        .harmonics()
        .iter()
        .map(|h| h.amplitude * (h.order as f64).powi(2))
        .sum::<f64>()
        * ARCSEC_PER_RAD;
    let mut points = 3600;
    while points < 1_843_200 {
        let step = std::f64::consts::TAU / points as f64;
        if curvature * step * step / 8.0 <= tolerance_arcsec {
            break;
        }
        points *= 2;
    }
    points
}

fn summaries(sessions: &[SessionData], deltas: &[f64]) -> Vec<SessionSummary> {
    sessions
        .iter()
        .zip(deltas)
        .enumerate()
        .map(|(i, (s, d))| SessionSummary {
            index: i,
            id: s.id,
            start_s: s.start_s,
            end_s: s.end_s,
            revolutions: s.revolutions,
            samples: s.samples,
            relative_rotation: crate::angle::wrap_pi(d - deltas[0]),
            absolute_rotation: *d,
        })
        .collect()
}

fn finish_joint(
    opts: &CsrrOptions,
    sessions: Vec<SessionData>,
    segmentation: Segmentation,
    mut warnings: Vec<String>,
) -> Result<Calibration, CsrrError> {
    if sessions.len() < 2 {
        return Err(CsrrError::TooFewSessions {
            found: sessions.len(),
        });
    }
    let densest = densest_samples_per_rev(&sessions);
    let max_order = match opts.max_order {
        Some(h) if samples_needed(h) as f64 > densest => {
            return Err(CsrrError::TooFewSamplesPerRevolution {
                requested: h,
                needed: samples_needed(h),
                available: densest,
            });
        }
        Some(h) => h.max(1),
        None => auto_max_order(densest),
    };
    let mut jopts = JointOptions::with_max_order(max_order);
    jopts.min_observability = opts.min_observability;
    jopts.check_up_to = residual_check_order(densest);
    let weights: Vec<f64> = sessions.iter().map(|s| s.samples as f64).collect();
    let (sol, screen) = fit_significant(&sessions, &jopts, &weights)?;
    if !sol.converged {
        warnings.push(format!(
            "the solver stopped after {} steps and {} iterations before reaching its tolerance; the maps may be inaccurate \
             (try a lower `max_order` option)",
            sol.steps, sol.iterations
        ));
    }
    let centred: Vec<f64> = sol.deltas.iter().map(|d| d - sol.deltas[0]).collect();
    let advice = (!sol.excluded.is_empty()).then(|| {
        let (extra_rotation, min_observability) =
            observability::best_extra_rotation(&centred, &weights, max_order);
        Advice {
            extra_rotation,
            min_observability,
        }
    });
    if let Some(adv) = advice {
        let orders: Vec<String> = sol
            .excluded
            .iter()
            .take(12)
            .map(|e| e.order.to_string())
            .collect();
        let more = sol.excluded.len().saturating_sub(12);
        warnings.push(format!(
            "{} order(s) cannot be separated with these relative rotations and are left out of both maps: {}{}; \
             one more session at a relative rotation of {:.1}° would reveal them",
            sol.excluded.len(),
            orders.join(", "),
            if more > 0 { format!(" and {more} more") } else { String::new() },
            adv.extra_rotation.to_degrees()
        ));
    }
    if let Some(w) = unresolved_warning(&sol.unresolved, max_order) {
        warnings.push(w);
    }
    let maps = joint_maps(&sol, &screen, opts.points);
    if screen.kept.is_empty() {
        let u = maps.uncertainty.0.max().max(maps.uncertainty.1.max());
        warnings.push(detection::empty_map_warning(
            u,
            &format!("1–{max_order}"),
            screen.detection_limit,
        ));
    }
    if let Some(repeat) = segmentation.repeatability {
        match detection::residual_verdict(sol.residual_rms, repeat, !screen.kept.is_empty()) {
            Verdict::Explained => {}
            Verdict::Above(ratio) => warnings.push(detection::residual_warning(
                sol.residual_rms,
                repeat,
                ratio,
                "the sessions repeat from one revolution to the next to",
                "the maps do",
                "errors in orders the sessions cannot see, a drift within sessions, or a lag between the channels",
            )),
            Verdict::Unexplained(_) => return Err(unexplained(sol.residual_rms, repeat)),
        }
    }
    Ok(Calibration {
        method: Method::Joint,
        a_series: maps.a_series,
        b_series: maps.b_series,
        true_angle_series: Some((sol.a, sol.b)),
        a: maps.a,
        b: maps.b,
        sessions: summaries(&sessions, &sol.deltas),
        segmentation,
        max_order,
        orders: screen.kept,
        excluded: sol.excluded,
        unresolved: sol.unresolved,
        advice,
        residual_rms: Some(sol.residual_rms),
        iterations: sol.iterations,
        paper_points: Vec::new(),
        reference: None,
        latency: None,
        uncertainty: Some(maps.uncertainty),
        warnings,
    })
}

/// The joint fit of the orders that stand above the noise: every observable order up to the
/// highest is fitted, screened by the significance rule ([`screen_orders`]), and the kept
/// orders fitted again alone, from the first fit's values. The solution's iterations and steps
/// count both fits.
fn fit_significant(
    sessions: &[SessionData],
    jopts: &JointOptions,
    weights: &[f64],
) -> Result<(joint::JointSolution, Screen), CsrrError> {
    let screening = joint::solve(sessions, jopts, None)?;
    let screen = screen_orders(&screening, weights);
    if screen.kept.len() == screen.tested {
        return Ok((screening, screen));
    }
    let mut sol = if screen.kept.is_empty() {
        // Nothing stands above the noise: both maps are zero.
        let mut sol = screening.clone();
        sol.a = FourierSeries::zeros(jopts.max_order);
        sol.b = FourierSeries::zeros(jopts.max_order);
        sol
    } else {
        joint::solve(sessions, jopts, Some((&screen.kept, &screening)))?
    };
    if !screen.kept.is_empty() {
        sol.iterations += screening.iterations;
        sol.steps += screening.steps;
        sol.converged &= screening.converged;
    }
    Ok((sol, screen))
}

/// Samples per revolution of the densest session.
fn densest_samples_per_rev(sessions: &[SessionData]) -> f64 {
    sessions
        .iter()
        .map(|s| s.samples as f64 / s.revolutions.max(1e-9))
        .fold(0.0, f64::max)
}

/// The highest order the residual is searched up to for structure above the fitted orders:
/// half the densest session's samples per revolution (its Nyquist limit), at most 4000.
fn residual_check_order(samples_per_rev: f64) -> usize {
    ((0.5 * samples_per_rev).floor() as usize).min(4000)
}

/// The warning for periodic structure left in the residual above the fitted orders, if any is
/// large enough to matter ([`crate::tdr::MATERIAL_ARCSEC`]).
fn unresolved_warning(unresolved: &[UnresolvedOrder], max_order: usize) -> Option<String> {
    let mut large: Vec<&UnresolvedOrder> = unresolved
        .iter()
        .filter(|u| u.a.max(u.b) * ARCSEC_PER_RAD >= crate::tdr::MATERIAL_ARCSEC)
        .collect();
    let highest = large.iter().map(|u| u.order).max()?;
    large.sort_by(|p, q| q.a.max(q.b).total_cmp(&p.a.max(p.b)));
    let listed: Vec<String> = large
        .iter()
        .take(8)
        .map(|u| {
            format!(
                "{} (A {:.3}″, B {:.3}″)",
                u.order,
                u.a * ARCSEC_PER_RAD,
                u.b * ARCSEC_PER_RAD
            )
        })
        .collect();
    let more = large.len().saturating_sub(8);
    Some(format!(
        "the fit's residual holds periodic structure above the noise at {} order(s) above the highest fitted ({max_order}), \
         missing from the maps: {}{}; fit them with the `max_order` option at {highest} or more",
        large.len(),
        listed.join(", "),
        if more > 0 {
            format!(" and {more} more")
        } else {
            String::new()
        },
    ))
}

/// The significance screening of a fit of every observable order.
struct Screen {
    /// Observable orders fitted.
    tested: usize,
    /// Orders kept, ascending: A's or B's pair of coefficients passes the significance rule.
    kept: Vec<usize>,
    /// The variance of each coefficient of each kept order, rad².
    kept_variance: Vec<f64>,
    /// RMS over the circle of what the dropped orders hold in A's and B's errors, rad.
    dropped: (f64, f64),
    /// The detection limit of the orders tested, rad: the smallest amplitude an order must have
    /// to be kept, `sqrt(threshold·v_h)` at the best-determined order.
    detection_limit: f64,
}

/// The significance rule for CSRR (`docs/uncertainty.md`): order `h`, fitted with all the
/// observable orders up to the highest, is kept when sensor A's or sensor B's coefficients
/// `x = (a_h, b_h)` stand above the noise, `|x|²/v_h > 2·ln(2M/α)` — the rule of
/// [`crate::tdr`] ([`crate::tdr::significance_threshold`], `α` =
/// [`crate::tdr::FALSE_ORDER_PROBABILITY`]) over the `2M` pairs of the `M` orders tested, with
/// `v_h = σ²·2W/(W² − |S_h|²)` the variance of each coefficient from the fit's per-order block
/// ([`observability::coefficient_variance`], `σ` the noise per sample from the bins' residuals,
/// or at an order where the sessions disagree significantly more than that, their scatter:
/// [`joint::JointSolution::order_noise`]). For noise alone the chance that any order is kept
/// is below `α`; structure that differs from session to session (the quantization of a slowly
/// turning sensor) is not taken for a harmonic, and where it is kept it carries its scatter in
/// `u`.
///
/// What the dropped orders hold together is estimated per sensor from `P = Σ_dropped (|x|² −
/// 2v_h)`, the unbiased estimate of their power, and `s_P` its standard deviation
/// (`var |x|² = 4v² + 4v·|μ|²` per order): when `P > 2·s_P` they hold more than their noise
/// and the RMS over the circle `sqrt(½·P)` enters the budget; otherwise nothing. Unlike
/// [`crate::tdr`]'s `sqrt(½·(P + s_P))`, no margin is added when `P` is noise: over the ~1000
/// orders a CSRR fit tests, `s_P` alone is several times the kept orders' noise, and `u` would
/// no longer be a standard uncertainty (it would cover > 99.99 % of the points within `2u`).
fn screen_orders(fit: &joint::JointSolution, weights: &[f64]) -> Screen {
    let centred: Vec<f64> = fit.deltas.iter().map(|d| d - fit.deltas[0]).collect();
    let fitted: Vec<usize> = (1..=fit.a.max_order())
        .filter(|h| fit.excluded.iter().all(|e| e.order != *h))
        .collect();
    let threshold = crate::tdr::significance_threshold(2 * fitted.len());
    let mut kept = Vec::new();
    let mut kept_variance = Vec::new();
    let mut power = [(0.0, 0.0); 2];
    let mut v_min = f64::INFINITY;
    for &h in &fitted {
        let v = observability::coefficient_variance(h, &centred, weights, fit.order_noise[h - 1]);
        if v.is_finite() && v >= 0.0 {
            v_min = v_min.min(v);
        }
        let xa = fit.a.cos[h - 1].powi(2) + fit.a.sin[h - 1].powi(2);
        let xb = fit.b.cos[h - 1].powi(2) + fit.b.sin[h - 1].powi(2);
        // σ = 0 (noise-free data): every order stands above the noise.
        if v.is_nan() || v <= 0.0 || xa.max(xb) > threshold * v {
            kept.push(h);
            kept_variance.push(v.max(0.0));
        } else {
            for (p, x) in power.iter_mut().zip([xa, xb]) {
                let excess = x - 2.0 * v;
                p.0 += excess;
                // var |x|² = 4v² + 4v|μ|² for a pair of variance v each and mean μ.
                p.1 += 4.0 * v * v + 4.0 * v * excess.max(0.0);
            }
        }
    }
    // Only power the dropped orders hold together beyond their noise (P > 2·s_P) is counted.
    let rms = |(p, var): (f64, f64)| {
        if p > 2.0 * f64::sqrt(var) {
            (p / 2.0).sqrt()
        } else {
            0.0
        }
    };
    Screen {
        tested: fitted.len(),
        kept,
        kept_variance,
        dropped: (rms(power[0]), rms(power[1])),
        detection_limit: detection::detection_limit(threshold, v_min),
    }
}

/// The tables of a joint solution and their uncertainties.
struct JointMaps {
    a: ErrorMap,
    b: ErrorMap,
    a_series: FourierSeries,
    b_series: FourierSeries,
    uncertainty: (MapUncertainty, MapUncertainty),
}

/// Both sensors' tables on `points` points (chosen by [`table_points`] when `None`) from the
/// joint solution, with their uncertainties.
fn joint_maps(sol: &joint::JointSolution, screen: &Screen, points: Option<usize>) -> JointMaps {
    let u_fit = screen.kept_variance.iter().sum::<f64>().sqrt();
    let points = points.unwrap_or_else(|| {
        let tolerance =
            (u_fit * ARCSEC_PER_RAD).clamp(MIN_INTERPOLATION_ARCSEC, MAX_INTERPOLATION_ARCSEC);
        table_points_within(&sol.a, tolerance).max(table_points_within(&sol.b, tolerance))
    });
    let a = joint::reading_map(&sol.a, points);
    let b = joint::reading_map(&sol.b, points);
    let a_series = a.series();
    let b_series = b.series();
    let missing = |amplitude: fn(&UnresolvedOrder) -> f64| {
        sol.unresolved
            .iter()
            .map(|u| amplitude(u).powi(2) / 2.0)
            .sum::<f64>()
            .sqrt()
    };
    let uncertainty = (
        map_uncertainty(
            [u_fit, screen.dropped.0, missing(|u| u.a)],
            detection_floor(screen.detection_limit),
            &a_series,
            points,
        ),
        map_uncertainty(
            [u_fit, screen.dropped.1, missing(|u| u.b)],
            detection_floor(screen.detection_limit),
            &b_series,
            points,
        ),
    );
    JointMaps {
        a,
        b,
        a_series,
        b_series,
        uncertainty,
    }
}

/// The budget of one CSRR map of `points` points from its components
/// `[u_fit, u_dropped, u_missing]`, rad, each the same at every angle (the last two left out
/// when zero):
///
/// - the fit's noise `u_fit`: the kept orders' coefficients have the variance `v_h`
///   ([`observability::coefficient_variance`]; cosine and sine uncorrelated within a sensor),
///   so `u_fit² = Σ_kept v_h` (Type A). Poorly observable orders (small `1 − |S_h|/W`) weigh
///   more; excluded (blind) orders are not in the maps and not in the sum — they are warnings,
///   not uncertainty;
/// - what the orders below the significance threshold hold (Type A, see `screen_orders`);
/// - periodic structure the residual holds above the fitted orders, of amplitude `A` at each
///   such order: RMS `A/√2` (Type A);
/// - the linear interpolation of the table between its points ([`interpolation_uncertainty`],
///   Type B).
///
/// `u` is never below `floor`, what the test could have missed ([`detection_floor`]): it is
/// listed in the budget by name and applied as a lower bound, not added in quadrature (where
/// the kept orders' noise already exceeds it, it is inside `u`).
///
/// See `docs/uncertainty.md`.
pub fn map_uncertainty(
    u: [f64; 3],
    floor: f64,
    series: &FourierSeries,
    points: usize,
) -> MapUncertainty {
    let names = [
        "noise of the readings propagated through the joint fit",
        "orders below the significance threshold, left out of the map",
        "periodic structure in the residual above the orders fitted",
    ];
    let mut components: Vec<MapComponent> = names
        .iter()
        .zip(u)
        .enumerate()
        .filter(|&(i, (_, u))| i == 0 || u > 0.0)
        .map(|(_, (name, u))| MapComponent {
            name: (*name).into(),
            evaluation: Evaluation::TypeA,
            u: vec![u],
        })
        .collect();
    components.push(MapComponent {
        name: "linear interpolation between table points".into(),
        evaluation: Evaluation::TypeB,
        u: vec![interpolation_uncertainty(&series.harmonics(), points)],
    });
    detection::apply_floor(MapUncertainty::combine(points, components), floor)
}

fn finish_paper(
    opts: &CsrrOptions,
    paper: PaperAccumulator,
    segmentation: Segmentation,
    mut warnings: Vec<String>,
) -> Result<Calibration, CsrrError> {
    let (points, stats, no_crossing) = paper.into_points();
    if !no_crossing.is_empty() {
        warnings.push(format!(
            "{} session(s) never passed a benchmark reading over a whole revolution and give no map point",
            no_crossing.len()
        ));
    }
    let n = opts.points.unwrap_or(3600);
    let a = paper::map_from_points(
        &points
            .iter()
            .map(|p| (p.a_angle, p.a_error))
            .collect::<Vec<_>>(),
        n,
    )?;
    let b = paper::map_from_points(
        &points
            .iter()
            .map(|p| (p.b_angle, p.b_error))
            .collect::<Vec<_>>(),
        n,
    )?;
    let budget = paper::uncertainty(&points, &stats, n);
    let resolvable = points.len() / 2;
    warnings.push(format!(
        "the paper method resolves orders below {resolvable} only (half the {} sessions); use the joint method for higher orders",
        points.len()
    ));
    let deltas: Vec<f64> = points.iter().map(|p| p.delta).collect();
    // The points hold only noise where no order the session grid resolves stands above it.
    let (a, b) = if budget.resolved {
        (a, b)
    } else {
        (ErrorMap::new(vec![0.0; n]), ErrorMap::new(vec![0.0; n]))
    };
    if !budget.resolved {
        warnings.push(detection::empty_map_warning(
            budget.a.max().max(budget.b.max()),
            &format!("1–{}", budget.orders),
            budget.detection_limit,
        ));
    }
    if let Some(repeat) = segmentation.repeatability {
        let misfit = paper::profile_misfit(&stats, &deltas, &a.series(), &b.series());
        match detection::residual_verdict(misfit, repeat, budget.resolved) {
            Verdict::Explained => {}
            Verdict::Above(ratio) => warnings.push(detection::residual_warning(
                misfit,
                repeat,
                ratio,
                "the sessions repeat from one revolution to the next to",
                "the maps (the sessions' points interpolated) do",
                "orders above half the number of sessions, orders every relative rotation sees alike, or a drift within \
                 sessions; the RMS is of the sessions' mean profiles",
            )),
            Verdict::Unexplained(_) => return Err(unexplained(misfit, repeat)),
        }
    }
    let uncertainty = (budget.a, budget.b);
    let sessions: Vec<SessionSummary> = points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let seg = segmentation
                .segments
                .iter()
                .find(|s| s.session == Some(p.session));
            SessionSummary {
                index: i,
                id: p.session,
                start_s: seg.map_or(0.0, |s| s.start_s),
                end_s: seg.map_or(0.0, |s| s.end_s),
                revolutions: seg.map_or(0.0, |s| s.revolutions.abs()),
                samples: seg.map_or(0, |s| s.samples),
                relative_rotation: crate::angle::wrap_pi(p.delta - deltas[0]),
                absolute_rotation: p.delta,
            }
        })
        .collect();
    Ok(Calibration {
        method: Method::Paper,
        a_series: a.series(),
        b_series: b.series(),
        true_angle_series: None,
        a,
        b,
        sessions,
        segmentation,
        max_order: resolvable,
        orders: Vec::new(),
        excluded: Vec::new(),
        unresolved: Vec::new(),
        advice: None,
        residual_rms: None,
        iterations: 0,
        paper_points: points,
        reference: None,
        latency: None,
        uncertainty: Some(uncertainty),
        warnings,
    })
}
