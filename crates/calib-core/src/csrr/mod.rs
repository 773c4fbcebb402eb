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
pub(crate) mod nufft;
mod observability;
pub mod paper;
mod reference;

pub use observability::observability;
pub use reference::{EffectiveRange, EpsHarmonic, ReferenceCheck};

use crate::angle::ARCSEC_PER_RAD;
use crate::error_map::ErrorMap;
use crate::harmonics::FourierSeries;
use crate::segment::{SegmentOptions, Segmentation, Segmenter, SessionSink};
use crate::uncertainty::{Evaluation, MapComponent, MapUncertainty, interpolation_uncertainty};
use bins::{Bin, SessionBinner};
use joint::{ExcludedOrder, JointOptions};
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
        "order {requested} needs at least {needed} samples per revolution, but the sparsest session has {available:.0}; \
         lower --max-order or record more slowly / at a higher sample rate"
    )]
    TooFewSamplesPerRevolution {
        /// The order asked for.
        requested: usize,
        /// Samples per revolution it needs.
        needed: usize,
        /// Samples per revolution of the sparsest session.
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
    /// The solve produced non-finite numbers (degenerate data).
    #[error(
        "the solve produced non-finite values: the data are degenerate (check that both channels carry real readings)"
    )]
    NotFinite,
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
    /// Highest order fitted (joint method); chosen from the sampling density when `None`.
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
    /// Orders left out of the maps.
    pub excluded: Vec<ExcludedOrder>,
    /// What to record to reveal them.
    pub advice: Option<Advice>,
    /// RMS of the fit residual, rad (joint method).
    pub residual_rms: Option<f64>,
    /// Solver iterations (joint method).
    pub iterations: usize,
    /// The paper method's points, one per session (paper method only).
    pub paper_points: Vec<PaperPoint>,
    /// Checks against the reference encoder, when one was given.
    pub reference: Option<ReferenceCheck>,
    /// The standard uncertainty of A's and B's maps at every table point, with their budgets
    /// (joint method; see [`map_uncertainty`]).
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
}

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
            opts,
            sinks,
        }
    }

    /// Feeds one synchronized sample: time (s), A's and B's readings (rad), the log's session mark.
    pub fn push(&mut self, t: f64, x: f64, y: f64, mark: Option<u32>) {
        self.segmenter.push(t, x, y, mark, &[], &mut self.sinks);
    }

    /// Feeds one sample with a reference encoder's reading `r` (rad) on rotor B's shaft; the
    /// options must have [`CsrrOptions::reference`] set.
    pub fn push_with_reference(&mut self, t: f64, x: f64, y: f64, r: f64, mark: Option<u32>) {
        self.segmenter.push(t, x, y, mark, &[r], &mut self.sinks);
    }

    /// Solves, once every sample is in.
    pub fn finish(mut self) -> Result<Calibration, CsrrError> {
        let segmentation = self.segmenter.finish(&mut self.sinks);
        let mut warnings = Vec::new();
        for s in segmentation.short_segments() {
            warnings.push(format!(
                "the rotating segment at {:.3}–{:.3} s covers {:.2} revolutions, less than one: not used as a session",
                s.start_s,
                s.end_s,
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

/// Fewest samples per revolution, for order `h`, that the joint solve accepts: 2.5 per period
/// (the Nyquist rate with margin for speed variation).
fn samples_needed(order: usize) -> usize {
    (order * 5).div_ceil(2)
}

/// The maximum order the sampling density supports: 40 % of the sparsest session's samples per
/// revolution (2.5 samples per period of the highest order), at most 2000.
pub fn auto_max_order(samples_per_rev: f64) -> usize {
    ((0.4 * samples_per_rev).floor() as usize).clamp(1, 2000)
}

/// Grid points for a table of `series` such that periodic linear interpolation between them errs
/// by at most 0.01″: the error of linear interpolation of `A cos(hθ)` on a step `δ` is at most
/// `A·(hδ)²/8`. At least 3600 points (0.1°), and a multiple of 3600 so 0.1° steps stay on the grid.
pub fn table_points(series: &FourierSeries) -> usize {
    let curvature: f64 = series
        .harmonics()
        .iter()
        .map(|h| h.amplitude * (h.order as f64).powi(2))
        .sum::<f64>()
        * ARCSEC_PER_RAD;
    let mut points = 3600;
    while points < 3_600_000 {
        let step = std::f64::consts::TAU / points as f64;
        if curvature * step * step / 8.0 <= 0.01 {
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
    let sparsest = sessions
        .iter()
        .map(|s| s.samples as f64 / s.revolutions.max(1e-9))
        .fold(f64::INFINITY, f64::min);
    let max_order = match opts.max_order {
        Some(h) if samples_needed(h) as f64 > sparsest => {
            return Err(CsrrError::TooFewSamplesPerRevolution {
                requested: h,
                needed: samples_needed(h),
                available: sparsest,
            });
        }
        Some(h) => h.max(1),
        None => auto_max_order(sparsest),
    };
    let mut jopts = JointOptions::with_max_order(max_order);
    jopts.min_observability = opts.min_observability;
    let sol = joint::solve(&sessions, &jopts)?;
    if !sol.converged {
        warnings.push(format!(
            "the solver stopped after {} steps and {} iterations before reaching its tolerance; the maps may be inaccurate \
             (try a lower --max-order)",
            sol.steps, sol.iterations
        ));
    }
    let weights: Vec<f64> = sessions.iter().map(|s| s.samples as f64).collect();
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
    let points = opts
        .points
        .unwrap_or_else(|| table_points(&sol.a).max(table_points(&sol.b)));
    let a = joint::reading_map(&sol.a, points);
    let b = joint::reading_map(&sol.b, points);
    let a_series = a.series();
    let b_series = b.series();
    let fitted: Vec<usize> = (1..=max_order)
        .filter(|h| sol.excluded.iter().all(|e| e.order != *h))
        .collect();
    let u_fit = fit_noise(&fitted, &centred, &weights, sol.noise_rms);
    let uncertainty = Some((
        map_uncertainty(u_fit, &a_series, points),
        map_uncertainty(u_fit, &b_series, points),
    ));
    Ok(Calibration {
        method: Method::Joint,
        a_series,
        b_series,
        true_angle_series: Some((sol.a, sol.b)),
        a,
        b,
        sessions: summaries(&sessions, &sol.deltas),
        segmentation,
        max_order,
        excluded: sol.excluded,
        advice,
        residual_rms: Some(sol.residual_rms),
        iterations: sol.iterations,
        paper_points: Vec::new(),
        reference: None,
        uncertainty,
        warnings,
    })
}

/// The standard uncertainty, at any angle, that the noise of the readings leaves in either
/// sensor's map, propagated through the joint fit by its per-order block structure (the
/// preconditioner of [`joint`]): for uniformly spread readings the normal matrix of order `h`'s
/// four coefficients is `½[[W·I, −R_h], [−R_hᵀ, W·I]]`, whose inverse has `2W/(W² − |Z_h|²)` on
/// its diagonal, `Z_h = Σ_k W_k e^{ihΔ_k}` and `W = Σ_k W_k` (samples per session). With `σ` the
/// residual per sample, each coefficient of order `h` has the variance `σ²·2W/(W² − |Z_h|²)`, the
/// cosine and sine are uncorrelated within a sensor, so the map's variance at any angle is
/// (`σ` from the bins' residuals, [`joint::JointSolution::noise_rms`])
///
/// `u_fit² = Σ_h 2σ²W/(W² − |Z_h|²)`,
///
/// the same at every angle. Poorly observable orders (small `1 − |Z_h|/W`) weigh more; excluded
/// (blind) orders are not in the maps and not in the sum — they are warnings, not uncertainty.
fn fit_noise(orders: &[usize], deltas: &[f64], weights: &[f64], sigma: f64) -> f64 {
    let w: f64 = weights.iter().sum();
    let var: f64 = orders
        .iter()
        .map(|&h| {
            let (mut c, mut s) = (0.0, 0.0);
            for (&d, &wk) in deltas.iter().zip(weights) {
                let (sn, cs) = (h as f64 * d).sin_cos();
                c += wk * cs;
                s += wk * sn;
            }
            2.0 * w / (w * w - c * c - s * s)
        })
        .sum();
    sigma * var.sqrt()
}

/// The budget of one CSRR map of `points` points: the fit's noise `u_fit` (Type A, propagated
/// through the joint fit's per-order blocks: see `docs/uncertainty.md`) and
/// the linear interpolation of the table between its points
/// ([`interpolation_uncertainty`], Type B).
pub fn map_uncertainty(u_fit: f64, series: &FourierSeries, points: usize) -> MapUncertainty {
    MapUncertainty::combine(
        points,
        vec![
            MapComponent {
                name: "noise of the readings propagated through the joint fit".into(),
                evaluation: Evaluation::TypeA,
                u: vec![u_fit],
            },
            MapComponent {
                name: "linear interpolation between table points".into(),
                evaluation: Evaluation::TypeB,
                u: vec![interpolation_uncertainty(&series.harmonics(), points)],
            },
        ],
    )
}

fn finish_paper(
    opts: &CsrrOptions,
    paper: PaperAccumulator,
    segmentation: Segmentation,
    mut warnings: Vec<String>,
) -> Result<Calibration, CsrrError> {
    let (points, no_crossing) = paper.into_points();
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
    let resolvable = points.len() / 2;
    warnings.push(format!(
        "the paper method resolves orders below {resolvable} only (half the {} sessions); use the joint method for higher orders",
        points.len()
    ));
    let deltas: Vec<f64> = points.iter().map(|p| p.delta).collect();
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
        excluded: Vec::new(),
        advice: None,
        residual_rms: None,
        iterations: 0,
        paper_points: points,
        reference: None,
        uncertainty: None,
        warnings,
    })
}
