//! A reference through a gear: the DUT (an actuator's output encoder) calibrated against an
//! encoder that turns `R` times per turn of the DUT (the motor's, before the gear), and the
//! reference's own map from the same run.
//!
//! # Model
//! With `θ` the DUT's true angle, the DUT reads `u = θ + f(θ)` and the reference
//! `r = R·θ + g(r) + c`: `f` is the DUT's error (a function of its angle), `g` the reference's
//! (a function of its own angle, periodic over one of its turns). The difference
//! `d = u − r/R = f − g/R + const` holds both. Over whole turns of the DUT with `R` not a whole
//! number, the two are different functions of time and a joint fit tells them apart; where they
//! coincide they cannot be (see below). Through a gear, `g/R` is the reference's error seen at
//! the output: 900″ of a motor encoder's once-per-turn error is 18″ at the output of a 50:1 gear.
//!
//! # Stage 1: the ratio and the reference's map
//! On the moving samples (at most [`MAX_FIT_SAMPLES`], evenly strided, none within the approach
//! after a reversal), least squares of
//! `d_i = c + β·(u_i − ū) + τ·ω_i + (b/2)·sign(ω_i) + f(u_i) + Σ_k (p_k cos k r_i + q_k sin k r_i)`
//! with `ω` the DUT's speed (`τ` a lag, `b` a lost motion between the encoders: nuisances),
//! `k = 1..K` the reference's orders ([`Gear::reference_orders`], of which those passing the
//! significance rule of the other methods make the map) and `f` the DUT's error in a
//! basis that cannot hold the reference's frequencies:
//! - over whole turns, the DUT's orders `1..24` and those within 2 of each `k·|R|`, except those
//!   that *coincide* with one: `|h − k·|R||·T < ½`, `T` the turns the DUT spans (fewer than
//!   half a beat over the run: no fit can split them);
//! - over a range `[a, b]`, the cosines `cos(mπ(u − a)/(b − a))`, `m = 1..M`, `M` the reference's
//!   turns over the range (below half the reference's lowest frequency): a range holds no whole
//!   turn of the DUT, so everything that repeats with the reference's turn is the reference's.
//!
//! `β` is the ratio's error: `R ← R·(1 − β)` and the fit repeated until `β` vanishes
//! ([`Ratio::Auto`]; with [`Ratio::Given`] there is no `β`). Over a range a straight line in `f`
//! (the DUT's scale error) and `β` are the same function: with `Auto` `f` holds no line
//! (its cosines are made orthogonal to one) and the line goes into the ratio; with `Given` the
//! line is the DUT's, measured. The reference's map is `g = −R·Σ_k (p_k cos k r + q_k sin k r)`.
//!
//! # Stage 2: the DUT's map
//! The reference's readings are corrected and brought to the DUT's angle, `(r − g(r))/R`, and
//! the run is calibrated as on one shaft ([`super::ReferenceCal`]): the DUT's map at every grid
//! point, the ISO 230-2 figures, latency, ends and gaps. With `Auto` over a range, the straight
//! line left in that map (the fit's weights are the samples', the map's the grid points') is
//! moved into the ratio and the map made again.
//!
//! # Uncertainty
//! The fit's covariance `s²·(XᵀX)⁺·(1 + ρ)/(1 − ρ)`, `ρ` the lag-1 autocorrelation of its
//! residuals in time (correlated residuals hold less information than their count says); an
//! estimated ratio's `u` is at least half the difference of the ratios the two halves of the
//! run give alone (what the motion's own structure can bias). The fit also holds probes at the reference's orders `k + ½`, where neither encoder errs: where
//! their mean square exceeds the variance the fit gives the reference's coefficients (residual
//! structure the noise model misses, such as the DUT's quantization, a function of its angle),
//! the reference's covariance is scaled up to it. The reference's map's `u` at each of its
//! points is `R·sqrt(xᵀCx)`; the ratio's `|R|·u(β)`; every
//! point of the DUT's map gains the largest `u` of the reference's map divided by `|R|` (its
//! correction went into every reading).
//!
//! # A commanded reference through a gear
//! With [`ReferenceKind::Commanded`] the reference is a motor's commanded angle before the gear:
//! its "error" is the motor's ripple, periodic in the motor's electrical angle, so its orders are
//! `k·p` (`k = 1…12`, `p` pole pairs) of the motor's turn instead of `1…K`, and the reference's
//! map is that ripple; the DUT's map is then made as against an encoder.
//!
//! # What cannot be separated
//! A DUT order `h` that coincides with the reference's order `k` (`h = k·R`, `R` a whole number
//! or a ratio of small ones, over whole turns): both are in the reference's map, and the DUT's
//! map holds nothing at `h` — named in [`GearResult::coincident`]. Over a range, the DUT's own
//! error at the reference's frequencies is likewise in the reference's map. A gear's
//! transmission error periodic in the motor's angle is in the reference's map; periodic in the
//! output's, in the DUT's: no run through the gear tells it from the encoder there.

use super::{ReferenceCal, ReferenceCalibration, ReferenceError, ReferenceKind, ReferenceOptions};
use crate::angle::Unwrapper;
use crate::error_map::ErrorMap;
use nalgebra::{DMatrix, DVector, SymmetricEigen};
use std::f64::consts::{PI, TAU};

/// Orders of the reference's error fitted by default, per turn of the reference.
pub const DEFAULT_REFERENCE_ORDERS: usize = 16;
/// Most samples the stage-1 fit uses (evenly strided): enough for a few hundred unknowns.
pub const MAX_FIT_SAMPLES: usize = 40_000;
/// The DUT's orders always in the stage-1 fit over whole turns.
const LOW_ORDERS: u32 = 24;
/// The DUT's orders either side of each reference frequency in the stage-1 fit.
const WINDOW: u32 = 2;
/// Most cosines of the DUT's error over a range in the stage-1 fit.
const MAX_RANGE_TERMS: usize = 60;
/// Fewest turns of the reference over the DUT's travel from which its map is separated, over
/// whole turns of the DUT.
pub const MIN_REFERENCE_TURNS: f64 = 2.0;
/// The same over a range: the DUT's error is modelled there by cosines slower than half the
/// reference's turn, so the reference's turns bound the DUT's detail the fit can hold apart
/// from the reference's error (10 turns: the DUT's error up to 5 cycles over the range; fewer,
/// and an encoder's own orders 4–8 over a range of 120° would be taken for the reference's).
pub const MIN_RANGE_REFERENCE_TURNS: f64 = 10.0;

/// How many times the reference turns per turn of the DUT.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Ratio {
    /// This ratio (a gear's tooth counts): any real number but 0, negative where the reference
    /// turns the other way.
    Given(f64),
    /// Estimated from the run, jointly with both maps.
    Auto,
}

impl std::str::FromStr for Ratio {
    type Err = String;

    /// `auto`, or the turns of the reference per turn of the DUT.
    fn from_str(text: &str) -> Result<Ratio, String> {
        let text = text.trim();
        if text.eq_ignore_ascii_case("auto") {
            return Ok(Ratio::Auto);
        }
        match text.parse::<f64>() {
            Ok(r) if r.is_finite() && r != 0.0 && r.abs() <= 1e4 => Ok(Ratio::Given(r)),
            _ => Err(format!(
                "`{text}`: give the turns of the reference per turn of the DUT (50 for a 50:1 gear, -7.3 where the \
                 reference turns the other way; at most 10⁴ in size), or `auto` to estimate it"
            )),
        }
    }
}

/// A reference calibration on the DUT's shaft or through a gear: one type for the callers that
/// take either.
#[derive(Debug, Clone)]
pub enum ReferenceRun {
    /// On the DUT's shaft.
    Shaft(Box<ReferenceCal>),
    /// Through a gear.
    Gear(GearedCal),
}

impl ReferenceRun {
    /// A calibration with these options, through `gear` if there is one.
    pub fn new(opts: ReferenceOptions, gear: Option<Gear>) -> Self {
        match gear {
            None => ReferenceRun::Shaft(Box::new(ReferenceCal::new(opts))),
            Some(g) => ReferenceRun::Gear(GearedCal::new(opts, g)),
        }
    }

    /// Adds a sample: time (s), the DUT's and the reference's readings (radians).
    pub fn push(&mut self, t: f64, dut: f64, reference: f64) {
        match self {
            ReferenceRun::Shaft(c) => c.push(t, dut, reference),
            ReferenceRun::Gear(c) => c.push(t, dut, reference),
        }
    }

    /// The calibration from the samples pushed.
    pub fn finish(self) -> Result<ReferenceCalibration, ReferenceError> {
        match self {
            ReferenceRun::Shaft(c) => c.finish(),
            ReferenceRun::Gear(c) => c.finish(),
        }
    }
}

/// A reference through a gear.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gear {
    /// The ratio.
    pub ratio: Ratio,
    /// Orders of the reference's own error fitted, per turn of the reference (≥ 1).
    pub reference_orders: usize,
}

impl Gear {
    /// The reference's orders fitted, `1..K` per turn of it; for a commanded reference with
    /// `p` pole pairs the motor's ripple, `k·p` for `k = 1…12` (as on one shaft, module
    /// `ripple`).
    fn orders(&self, kind: ReferenceKind) -> Vec<u32> {
        match kind {
            ReferenceKind::Encoder => (1..=self.reference_orders as u32).collect(),
            ReferenceKind::Commanded { pole_pairs } => (1..=super::ripple::MAX_HARMONIC as u32)
                .map(|k| k * pole_pairs)
                .collect(),
        }
    }
}

/// A DUT order and a reference order that are the same frequency over the run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Coincidence {
    /// Cycles per turn of the DUT.
    pub dut_order: u32,
    /// Cycles per turn of the reference.
    pub reference_order: u32,
}

/// One term of the reference's map, `amplitude·cos(k·r + phase)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReferenceTerm {
    /// Cycles per turn of the reference.
    pub order: u32,
    /// Amplitude, radians of the reference's angle.
    pub amplitude: f64,
    /// Its standard uncertainty, radians.
    pub u_amplitude: f64,
    /// Phase, radians.
    pub phase: f64,
    /// Whether it passed the significance rule and is in the map.
    pub kept: bool,
}

/// The reference's own map, a function of its reading over one of its turns.
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceMap {
    /// The error `g` at each grid point, radians of the reference's angle (mean zero).
    pub map: ErrorMap,
    /// Its standard uncertainty at each point, radians.
    pub u: Vec<f64>,
    /// The fitted terms, orders `1..K`; those that pass the significance rule of the other
    /// methods (chi-square over `2·ln(K/0.01)`) are in the map.
    pub terms: Vec<ReferenceTerm>,
}

/// Where the ratio came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RatioSource {
    /// Given (`--ref-ratio R`).
    Given,
    /// Estimated from the run.
    Estimated,
}

/// What the gear adds to a reference calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct GearResult {
    /// Turns of the reference per turn of the DUT.
    pub ratio: f64,
    /// Its standard uncertainty (`None` where given).
    pub ratio_u: Option<f64>,
    /// Given or estimated.
    pub source: RatioSource,
    /// The reference's turns over the DUT's travel.
    pub reference_turns: f64,
    /// The reference's own map (`None`: it turned fewer than [`MIN_REFERENCE_TURNS`] times over
    /// the DUT's span, [`MIN_RANGE_REFERENCE_TURNS`] over a range, so its error is in the DUT's
    /// map).
    pub reference_map: Option<ReferenceMap>,
    /// Orders of the two that are one frequency over the run: put in the reference's map.
    pub coincident: Vec<Coincidence>,
    /// A range: what repeats every turn of the reference is put in the reference's map.
    pub range: bool,
    /// A range with the ratio estimated: the DUT's straight-line part is in the ratio, the map
    /// has none.
    pub line_in_ratio: bool,
}

/// A reference calibration through a gear, fed one synchronized sample at a time.
#[derive(Debug, Clone)]
pub struct GearedCal {
    opts: ReferenceOptions,
    gear: Gear,
    dut: Unwrapper,
    reference: Unwrapper,
    /// `(t, unwrapped DUT, unwrapped reference)`; a row of NaN readings breaks the run.
    samples: Vec<(f64, f64, f64)>,
}

/// The reference's orders in the fit, and the number of its turns one of them spans at the
/// least (1 for an encoder, the pole pairs for a commanded reference's ripple).
struct Orders {
    list: Vec<u32>,
    lowest: u32,
}

impl GearedCal {
    /// A calibration with these options, the reference turning through `gear`.
    pub fn new(opts: ReferenceOptions, gear: Gear) -> Self {
        GearedCal {
            opts,
            gear,
            dut: Unwrapper::new(),
            reference: Unwrapper::new(),
            samples: Vec::new(),
        }
    }

    /// Adds a sample: time (s), the DUT's and the reference's readings (radians; either may be
    /// wrapped to a turn or accumulated over many). A non-finite value breaks the run there.
    pub fn push(&mut self, t: f64, dut: f64, reference: f64) {
        if !(t.is_finite() && dut.is_finite() && reference.is_finite()) {
            if t.is_finite() {
                self.samples.push((t, f64::NAN, f64::NAN));
            }
            return;
        }
        let u = self.dut.unwrap(dut);
        let r = self.reference.unwrap(reference);
        self.samples.push((t, u, r));
    }

    /// Both maps and the ratio from the samples pushed.
    pub fn finish(self) -> Result<ReferenceCalibration, ReferenceError> {
        let GearedCal {
            opts,
            gear,
            samples,
            ..
        } = self;
        // Through a gear a commanded reference's ripple is periodic in the motor's angle: it is
        // the reference's map, and the shaft calibration after it takes an encoder's.
        let list = gear.orders(opts.reference_kind);
        let orders = Orders {
            lowest: list.first().copied().unwrap_or(1),
            list,
        };
        let opts = ReferenceOptions {
            reference_kind: ReferenceKind::Encoder,
            ..opts
        };
        if gear.reference_orders == 0 {
            return Err(ReferenceError::Options(
                "the `ref_orders` option must be at least 1".to_string(),
            ));
        }
        if let Ratio::Given(r) = gear.ratio
            && !(r.is_finite() && r != 0.0)
        {
            return Err(ReferenceError::Options(format!(
                "the `ref_ratio` option must be a real number other than 0, not {r}"
            )));
        }
        let used = fit_samples(&samples, &opts);
        let measured = measured_ratio(&samples, &used).ok_or_else(|| {
            let travel: f64 = samples
                .windows(2)
                .map(|w| (w[1].1 - w[0].1).abs())
                .filter(|d| d.is_finite())
                .sum();
            ReferenceError::TooLittleMotion {
                revolutions: travel / TAU,
                crossed: 0,
            }
        })?;
        if measured.abs() < 1e-3 {
            let (du, dr) = travels(&samples);
            return Err(ReferenceError::ReferenceStill {
                reference_deg: dr.to_degrees(),
                dut_deg: du.to_degrees(),
            });
        }
        let mut ratio = match gear.ratio {
            Ratio::Given(r) => {
                if r.signum() != measured.signum() || (measured / r - 1.0).abs() > 0.05 {
                    return Err(ReferenceError::RatioMismatch { given: r, measured });
                }
                r
            }
            Ratio::Auto => measured,
        };
        let (lo, hi) = used
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |a, &i| {
                (a.0.min(samples[i].1), a.1.max(samples[i].1))
            });
        let span = hi - lo;
        let whole = span >= TAU - opts.max_gap;
        let reference_turns = ratio.abs() * span / TAU;
        let needed = if whole {
            MIN_REFERENCE_TURNS
        } else {
            MIN_RANGE_REFERENCE_TURNS
        };
        let separable = reference_turns >= needed && !orders.list.is_empty();
        let auto = gear.ratio == Ratio::Auto;
        let mut fit = None;
        let mut ratio_u = None;
        let mut coincident = Vec::new();
        // The stage-1 fit over `part` of the samples at `ratio`, and its coincident orders.
        let fit_at = |part: &[usize], ratio: f64| {
            let basis = Basis::new(
                &samples,
                part,
                ratio,
                whole,
                (lo, hi),
                &orders,
                separable,
                auto,
            );
            (basis.solve(&samples, part, ratio), basis.coincident)
        };
        if separable || auto {
            for _ in 0..4 {
                let (f, c) = fit_at(&used, ratio);
                let step = f.line.map_or(0.0, |(b, _)| b);
                coincident = c;
                if auto {
                    ratio_u = f.line.map(|(_, u)| ratio.abs() * u);
                    ratio *= 1.0 - step;
                }
                fit = Some(f);
                if step.abs() < 1e-12 {
                    break;
                }
            }
        }
        if auto && used.len() >= 64 {
            // The ratio from each half of the run: what they differ by is what the fit's noise
            // model may miss (the motion's own structure, a lag not quite constant).
            let half =
                |part: &[usize]| ratio * (1.0 - fit_at(part, ratio).0.line.map_or(0.0, |l| l.0));
            let (first, second) = used.split_at(used.len() / 2);
            let spread = 0.5 * (half(first) - half(second)).abs();
            ratio_u = ratio_u.map(|u| u.max(spread));
        }
        let reference_map = fit
            .as_ref()
            .filter(|_| separable)
            .map(|f| f.reference_map(ratio, opts.points));
        // `g` is the reference's, whatever the ratio later becomes.
        let fit_ratio = ratio;
        let g = |r: f64| {
            fit.as_ref()
                .filter(|_| separable)
                .map_or(0.0, |f| f.reference_error(fit_ratio, r))
        };
        let mut cal = stage_two(&opts, &samples, ratio, &g)?;
        let line_in_ratio = auto && !whole;
        if line_in_ratio && let Some(s) = straight_line(&cal) {
            // The map's own weighting of the line (grid points, not samples): into the ratio.
            ratio *= 1.0 - s;
            cal = stage_two(&opts, &samples, ratio, &g)?;
        }
        if let Some(m) = &reference_map {
            let u_g = m.u.iter().fold(0.0f64, |a, &u| a.max(u)) / ratio.abs();
            cal.u.iter_mut().for_each(|u| *u = u.hypot(u_g));
        } else {
            cal.warnings.push(format!(
                "the reference turned only {reference_turns:.2} time(s) over the DUT's {} (at least {needed} needed \
                 to tell its error, periodic in its turn, from the DUT's): its own error is in the DUT's map; record \
                 whole turns of the DUT, or a longer travel",
                if whole { "travel" } else { "range" }
            ));
        }
        if !coincident.is_empty() {
            let list: Vec<String> = coincident
                .iter()
                .map(|c| format!("{} (reference {})", c.dut_order, c.reference_order))
                .collect();
            cal.warnings.push(format!(
                "the DUT's orders {} are the reference's over this run (ratio {:.6}): they cannot be split between the \
                 two encoders and are put in the reference's map; the DUT's own error at these orders is not measured",
                list.join(", "),
                ratio
            ));
        }
        cal.gear = Some(GearResult {
            ratio,
            ratio_u,
            source: match gear.ratio {
                Ratio::Given(_) => RatioSource::Given,
                Ratio::Auto => RatioSource::Estimated,
            },
            reference_turns,
            reference_map,
            coincident,
            range: !whole,
            line_in_ratio,
        });
        Ok(cal)
    }
}

/// The DUT's travel and the reference's over the run, radians.
fn travels(samples: &[(f64, f64, f64)]) -> (f64, f64) {
    samples
        .windows(2)
        .map(|w| ((w[1].1 - w[0].1).abs(), (w[1].2 - w[0].2).abs()))
        .filter(|(a, b)| a.is_finite() && b.is_finite())
        .fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1))
}

/// Stage 2: the run calibrated on the DUT's shaft, the reference corrected by `g` and brought
/// to the DUT's angle.
fn stage_two(
    opts: &ReferenceOptions,
    samples: &[(f64, f64, f64)],
    ratio: f64,
    g: &dyn Fn(f64) -> f64,
) -> Result<ReferenceCalibration, ReferenceError> {
    let mut cal = ReferenceCal::new(opts.clone());
    for &(t, u, r) in samples {
        cal.push(t, u, (r - g(r)) / ratio);
    }
    cal.finish()
}

/// The slope of the least-squares line through a range map's values (none for a whole turn).
fn straight_line(cal: &ReferenceCalibration) -> Option<f64> {
    let (lo, hi) = cal.map.range()?;
    let v = cal.map.values();
    let n = v.len();
    if n < 2 {
        return None;
    }
    let step = (hi - lo) / (n - 1) as f64;
    let xm = 0.5 * (n - 1) as f64 * step;
    let ym = v.iter().sum::<f64>() / n as f64;
    let (sxy, sxx) = v.iter().enumerate().fold((0.0, 0.0), |a, (i, &y)| {
        let x = i as f64 * step - xm;
        (a.0 + x * (y - ym), a.1 + x * x)
    });
    Some(sxy / sxx).filter(|s| s.is_finite())
}

/// The samples of the stage-1 fit: moving (the DUT's speed over both neighbours at least
/// `min_speed`), past the approach after each reversal, at most [`MAX_FIT_SAMPLES`] of them
/// evenly strided, in time order.
fn fit_samples(samples: &[(f64, f64, f64)], opts: &ReferenceOptions) -> Vec<usize> {
    let mut moving = Vec::new();
    let mut run: Option<(bool, f64)> = None;
    for i in 1..samples.len().saturating_sub(1) {
        let ((t0, u0, _), (_, u, _), (t1, u1, _)) = (samples[i - 1], samples[i], samples[i + 1]);
        let (dt, du) = (t1 - t0, u1 - u0);
        if !(u.is_finite() && du.is_finite() && dt > 0.0) || du.abs() < opts.min_speed * dt {
            run = None;
            continue;
        }
        let up = du > 0.0;
        let travelled = match run {
            Some((dir, travel)) if dir == up => travel + 0.5 * du.abs(),
            _ => 0.0,
        };
        run = Some((up, travelled));
        if travelled >= opts.approach {
            moving.push(i);
        }
    }
    let stride = moving.len().div_ceil(MAX_FIT_SAMPLES).max(1);
    moving.into_iter().step_by(stride).collect()
}

/// The least-squares slope of the reference's reading on the DUT's over the fit's samples.
fn measured_ratio(samples: &[(f64, f64, f64)], used: &[usize]) -> Option<f64> {
    if used.len() < 2 {
        return None;
    }
    let n = used.len() as f64;
    let (um, rm) = used.iter().fold((0.0, 0.0), |a, &i| {
        (a.0 + samples[i].1 / n, a.1 + samples[i].2 / n)
    });
    let (sur, suu) = used.iter().fold((0.0, 0.0), |a, &i| {
        let (du, dr) = (samples[i].1 - um, samples[i].2 - rm);
        (a.0 + du * dr, a.1 + du * du)
    });
    (suu > 0.0).then(|| sur / suu).filter(|s| s.is_finite())
}

/// One column of the stage-1 fit.
#[derive(Debug, Clone, Copy)]
enum Column {
    Constant,
    /// `u − ū`, scaled: the ratio's error.
    Line,
    /// The DUT's speed, scaled: a lag.
    Lag,
    /// `sign(ω)/2`: lost motion.
    Play,
    DutCos(u32),
    DutSin(u32),
    /// The `m`-th cosine over the range, less its line where the line is the ratio's.
    RangeCos(u32, f64, f64),
    RefCos(u32),
    RefSin(u32),
    /// A probe at the reference's order `k + ½`, where neither encoder errs: what the residual
    /// puts at a frequency of the reference's.
    ProbeCos(u32, f64),
    ProbeSin(u32, f64),
}

/// The columns of the stage-1 fit for one ratio.
struct Basis {
    columns: Vec<Column>,
    coincident: Vec<Coincidence>,
    /// `ū` and the scale of the line column.
    u_mean: f64,
    u_scale: f64,
    /// The scale of the lag column.
    w_scale: f64,
    range: (f64, f64),
}

/// The stage-1 fit.
struct Fit {
    /// The line's coefficient `β` and its standard uncertainty, if fitted.
    line: Option<(f64, f64)>,
    /// `(order, p, q)` of the reference's terms in `d`, and their covariance (2K × 2K).
    reference: Vec<(u32, f64, f64)>,
    /// Which of them pass the significance rule: only these are in the map.
    kept: Vec<bool>,
    covariance: DMatrix<f64>,
}

impl Basis {
    #[allow(clippy::too_many_arguments)]
    fn new(
        samples: &[(f64, f64, f64)],
        used: &[usize],
        ratio: f64,
        whole: bool,
        (lo, hi): (f64, f64),
        orders: &Orders,
        separable: bool,
        auto: bool,
    ) -> Basis {
        let n = used.len() as f64;
        let u_mean = used.iter().map(|&i| samples[i].1).sum::<f64>() / n;
        let u_scale = (used
            .iter()
            .map(|&i| (samples[i].1 - u_mean).powi(2))
            .sum::<f64>()
            / n)
            .sqrt()
            .max(1e-12);
        let w_scale = (used.iter().map(|&i| speed(samples, i).powi(2)).sum::<f64>() / n)
            .sqrt()
            .max(1e-12);
        let mut columns = vec![Column::Constant, Column::Lag, Column::Play];
        if auto {
            columns.push(Column::Line);
        }
        let reference_orders: &[u32] = if separable { &orders.list } else { &[] };
        let r = ratio.abs();
        let turns = (hi - lo) / TAU;
        let mut coincident = Vec::new();
        if whole {
            let mut orders: Vec<u32> = (1..=LOW_ORDERS).collect();
            for &k in reference_orders {
                let c = (f64::from(k) * r).round() as i64;
                orders.extend(
                    (c - i64::from(WINDOW)..=c + i64::from(WINDOW))
                        .filter(|&h| h >= 1)
                        .map(|h| h as u32),
                );
            }
            orders.sort_unstable();
            orders.dedup();
            for h in orders {
                let with = reference_orders
                    .iter()
                    .copied()
                    .find(|&k| (f64::from(h) - f64::from(k) * r).abs() * turns < 0.5);
                match with {
                    Some(k) => coincident.push(Coincidence {
                        dut_order: h,
                        reference_order: k,
                    }),
                    None => columns.extend([Column::DutCos(h), Column::DutSin(h)]),
                }
            }
        } else {
            // Below half the reference's lowest frequency over the range.
            let lowest = f64::from(orders.lowest);
            let terms = ((lowest * r * turns).floor() as usize).clamp(1, MAX_RANGE_TERMS) as u32;
            for m in 1..=terms {
                let cos = |u: f64| (f64::from(m) * PI * (u - lo) / (hi - lo)).cos();
                // Its least-squares line over the samples, taken out where the line is the
                // ratio's.
                let (a, b) = if auto {
                    let (sc, scu, suu) = used.iter().fold((0.0, 0.0, 0.0), |acc, &i| {
                        let (c, x) = (cos(samples[i].1), samples[i].1 - u_mean);
                        (acc.0 + c, acc.1 + c * x, acc.2 + x * x)
                    });
                    (sc / n, if suu > 0.0 { scu / suu } else { 0.0 })
                } else {
                    (0.0, 0.0)
                };
                columns.push(Column::RangeCos(m, a, b));
            }
        }
        for &k in reference_orders {
            columns.extend([Column::RefCos(k), Column::RefSin(k)]);
        }
        // A probe at one of the DUT's orders in the fit would measure that order: left out.
        let dut_orders: Vec<u32> = columns
            .iter()
            .filter_map(|c| match c {
                Column::DutCos(h) => Some(*h),
                _ => None,
            })
            .collect();
        // Probes half a step above each order (`k + ½` for an encoder, `k·p + p/2` for ripple).
        let half = 0.5 * f64::from(orders.lowest);
        for &k in reference_orders {
            let f = (f64::from(k) + half) * r;
            if !dut_orders
                .iter()
                .any(|&h| (f64::from(h) - f).abs() * turns < 0.5)
            {
                columns.extend([Column::ProbeCos(k, half), Column::ProbeSin(k, half)]);
            }
        }
        Basis {
            columns,
            coincident,
            u_mean,
            u_scale,
            w_scale,
            range: (lo, hi),
        }
    }

    /// The row of sample `i`.
    fn row(&self, samples: &[(f64, f64, f64)], i: usize, out: &mut [f64]) {
        let (_, u, r) = samples[i];
        let w = speed(samples, i);
        let (lo, hi) = self.range;
        for (o, c) in out.iter_mut().zip(&self.columns) {
            *o = match *c {
                Column::Constant => 1.0,
                Column::Line => (u - self.u_mean) / self.u_scale,
                Column::Lag => w / self.w_scale,
                Column::Play => 0.5 * w.signum(),
                Column::DutCos(h) => (f64::from(h) * u).cos(),
                Column::DutSin(h) => (f64::from(h) * u).sin(),
                Column::RangeCos(m, a, b) => {
                    (f64::from(m) * PI * (u - lo) / (hi - lo)).cos() - a - b * (u - self.u_mean)
                }
                Column::RefCos(k) => (f64::from(k) * r).cos(),
                Column::RefSin(k) => (f64::from(k) * r).sin(),
                Column::ProbeCos(k, half) => ((f64::from(k) + half) * r).cos(),
                Column::ProbeSin(k, half) => ((f64::from(k) + half) * r).sin(),
            };
        }
    }

    /// Least squares of `d = (u − ū) − (r − r̄)/R` on the columns over the fit's samples.
    fn solve(&self, samples: &[(f64, f64, f64)], used: &[usize], ratio: f64) -> Fit {
        const BLOCK: usize = 512;
        let p = self.columns.len();
        let r_mean = used.iter().map(|&i| samples[i].2).sum::<f64>() / used.len() as f64;
        let d = |i: usize| (samples[i].1 - self.u_mean) - (samples[i].2 - r_mean) / ratio;
        let mut xtx = DMatrix::<f64>::zeros(p, p);
        let mut xtd = DVector::<f64>::zeros(p);
        let mut block = DMatrix::<f64>::zeros(BLOCK, p);
        let mut rhs = DVector::<f64>::zeros(BLOCK);
        let mut row = vec![0.0; p];
        for chunk in used.chunks(BLOCK) {
            block.fill(0.0);
            rhs.fill(0.0);
            for (j, &i) in chunk.iter().enumerate() {
                self.row(samples, i, &mut row);
                for (c, v) in row.iter().enumerate() {
                    block[(j, c)] = *v;
                }
                rhs[j] = d(i);
            }
            xtx += block.tr_mul(&block);
            xtd += block.tr_mul(&rhs);
        }
        // A pseudo-inverse: columns the run cannot tell apart (lag and lost motion at one speed
        // per direction) share their part rather than blow up.
        let eig = SymmetricEigen::new(xtx);
        let top = eig.eigenvalues.iter().fold(0.0f64, |a, &v| a.max(v));
        let inv = DVector::from_iterator(
            p,
            eig.eigenvalues
                .iter()
                .map(|&v| if v > 1e-11 * top { 1.0 / v } else { 0.0 }),
        );
        let pinv = &eig.eigenvectors * DMatrix::from_diagonal(&inv) * eig.eigenvectors.transpose();
        let beta = &pinv * xtd;
        // Residuals in time order: their variance and lag-1 correlation.
        let (mut rss, mut lag1, mut previous) = (0.0, 0.0, None);
        for &i in used {
            self.row(samples, i, &mut row);
            let e = d(i) - row.iter().zip(beta.iter()).map(|(a, b)| a * b).sum::<f64>();
            rss += e * e;
            if let Some(p) = previous {
                lag1 += p * e;
            }
            previous = Some(e);
        }
        let rho = if rss > 0.0 {
            (lag1 / rss).clamp(0.0, 0.98)
        } else {
            0.0
        };
        let dof = used.len().saturating_sub(p).max(1) as f64;
        let s2 = rss / dof * (1.0 + rho) / (1.0 - rho);
        let covariance = pinv * s2;
        let line = self
            .columns
            .iter()
            .position(|c| matches!(c, Column::Line))
            .map(|j| {
                (
                    beta[j] / self.u_scale,
                    covariance[(j, j)].sqrt() / self.u_scale,
                )
            });
        let refs: Vec<usize> = self
            .columns
            .iter()
            .enumerate()
            .filter(|(_, c)| matches!(c, Column::RefCos(_) | Column::RefSin(_)))
            .map(|(j, _)| j)
            .collect();
        let reference: Vec<(u32, f64, f64)> = refs
            .chunks(2)
            .map(|pair| match self.columns[pair[0]] {
                Column::RefCos(k) => (k, beta[pair[0]], beta[pair[1]]),
                _ => unreachable!("reference columns come in cosine, sine pairs"),
            })
            .collect();
        // The probes' mean square per coefficient, against the fit's own variance of the
        // reference's coefficients: residual structure the noise model misses (the DUT's
        // quantization, a function of its angle) raises the probes, and u with them.
        let (probe_ms, count) = self
            .columns
            .iter()
            .enumerate()
            .filter(|(_, c)| matches!(c, Column::ProbeCos(..) | Column::ProbeSin(..)))
            .fold((0.0, 0usize), |a, (j, _)| {
                (a.0 + beta[j] * beta[j], a.1 + 1)
            });
        let formal =
            refs.iter().map(|&j| covariance[(j, j)]).sum::<f64>() / refs.len().max(1) as f64;
        let inflation = if count > 0 && formal > 0.0 {
            (probe_ms / count as f64 / formal).max(1.0)
        } else {
            1.0
        };
        let covariance = DMatrix::from_fn(refs.len(), refs.len(), |a, b| {
            covariance[(refs[a], refs[b])] * inflation
        });
        // The significance rule of the other methods (`tdr::significance_threshold`): an order
        // is kept where its chi-square over the fitted orders' count passes.
        let threshold = crate::tdr::significance_threshold(reference.len().max(1));
        let kept = reference
            .iter()
            .enumerate()
            .map(|(j, &(_, p, q))| {
                let var = 0.5 * (covariance[(2 * j, 2 * j)] + covariance[(2 * j + 1, 2 * j + 1)]);
                var <= 0.0 || (p * p + q * q) / var >= threshold
            })
            .collect();
        Fit {
            line,
            reference,
            kept,
            covariance,
        }
    }
}

/// The DUT's speed at sample `i` (central difference), radians per second.
fn speed(samples: &[(f64, f64, f64)], i: usize) -> f64 {
    let (t0, u0, _) = samples[i - 1];
    let (t1, u1, _) = samples[i + 1];
    (u1 - u0) / (t1 - t0)
}

impl Fit {
    /// The reference's error at its reading `r`: `g = −R·Σ (p cos kr + q sin kr)`.
    fn reference_error(&self, ratio: f64, r: f64) -> f64 {
        -ratio
            * self
                .reference
                .iter()
                .zip(&self.kept)
                .filter(|(_, kept)| **kept)
                .map(|(&(k, p, q), _)| {
                    let (s, c) = (f64::from(k) * r).sin_cos();
                    p * c + q * s
                })
                .sum::<f64>()
    }

    /// The reference's map on `points` grid points of its turn, with its terms and `u`.
    fn reference_map(&self, ratio: f64, points: usize) -> ReferenceMap {
        let n = points.max(1);
        let values: Vec<f64> = (0..n)
            .map(|j| self.reference_error(ratio, j as f64 * TAU / n as f64))
            .collect();
        let cov = &self.covariance * (ratio * ratio);
        let u = (0..n)
            .map(|j| {
                let r = j as f64 * TAU / n as f64;
                // A term left out of the map may hold what its noise hides: its variance stays.
                let x = DVector::from_iterator(
                    cov.nrows(),
                    self.reference
                        .iter()
                        .zip(&self.kept)
                        .flat_map(|(&(k, _, _), &kept)| {
                            let (s, c) = (f64::from(k) * r).sin_cos();
                            if kept { [c, s] } else { [0.0, 0.0] }
                        }),
                );
                let dropped: f64 = (0..self.reference.len())
                    .filter(|&j| !self.kept[j])
                    .map(|j| 0.5 * (cov[(2 * j, 2 * j)] + cov[(2 * j + 1, 2 * j + 1)]))
                    .sum();
                (x.dot(&(&cov * &x)) + dropped).max(0.0).sqrt()
            })
            .collect();
        let terms = self
            .reference
            .iter()
            .enumerate()
            .map(|(j, &(k, p, q))| {
                // g's terms: −R·(p cos + q sin) = A cos(kr + φ), A = |R|·hypot(p, q).
                let (a, b) = (-ratio * p, -ratio * q);
                let amplitude = a.hypot(b);
                let var = (cov[(2 * j, 2 * j)] + cov[(2 * j + 1, 2 * j + 1)]) / 2.0;
                ReferenceTerm {
                    order: k,
                    amplitude,
                    u_amplitude: var.max(0.0).sqrt(),
                    phase: (-b).atan2(a),
                    kept: self.kept[j],
                }
            })
            .collect();
        ReferenceMap {
            map: ErrorMap::new(values),
            u,
            terms,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::angle::ARCSEC_PER_RAD;
    use crate::simulate::Scenario;

    /// A 4:1 gear over whole turns: every motor order `k` is the output's order `4k`. The
    /// motor's 600″ at its order 1 (150″ at the output, at the output's order 4) must go to the
    /// motor's map, the output's orders 4, 8, … be named, and the output's own orders 1 and 3
    /// stay in its map (within 1″: noise 1″ and no quantization over 3 turns each way at 1 kHz
    /// leave ~0.02″ per order).
    #[test]
    fn a_whole_number_ratio_puts_the_common_orders_in_the_reference() {
        let scenario: Scenario = toml::from_str(
            r#"
            seed = 4
            rate_hz = 1000.0
            wrap = true
            [[sensor]]
            name = "out"
            harmonics = [{ order = 1, amplitude_arcsec = 300.0, phase_deg = 10.0 },
                         { order = 3, amplitude_arcsec = 80.0, phase_deg = -20.0 }]
            noise_arcsec = 1.0
            [[sensor]]
            name = "motor"
            ratio = 4.0
            harmonics = [{ order = 1, amplitude_arcsec = 600.0, phase_deg = 40.0 }]
            noise_arcsec = 1.0
            [sweep]
            from_deg = 0.0
            to_deg = 1080.0
            cycles = 1
            speeds_deg_s = [90.0]
            ramp_s = 0.2
            pause_s = 0.2
            "#,
        )
        .unwrap();
        let mut cal = GearedCal::new(
            ReferenceOptions::default(),
            Gear {
                ratio: Ratio::Given(4.0),
                reference_orders: 4,
            },
        );
        for s in scenario.samples().unwrap() {
            cal.push(s.t, s.values[0], s.values[1]);
        }
        let result = cal.finish().unwrap();
        let gear = result.gear.as_ref().unwrap();
        let named: Vec<u32> = gear.coincident.iter().map(|c| c.dut_order).collect();
        assert_eq!(named, [4, 8, 12, 16]);
        let motor = gear.reference_map.as_ref().unwrap();
        let first = motor.terms[0];
        assert!(
            first.kept && (first.amplitude * ARCSEC_PER_RAD - 600.0).abs() < 1.0,
            "{first:?}"
        );
        let harmonics = result.map.turn().unwrap().series().harmonics();
        let amplitude = |h: usize| harmonics[h - 1].amplitude * ARCSEC_PER_RAD;
        assert!(
            (amplitude(1) - 300.0).abs() < 1.0,
            "order 1: {}",
            amplitude(1)
        );
        assert!(
            (amplitude(3) - 80.0).abs() < 1.0,
            "order 3: {}",
            amplitude(3)
        );
        assert!(
            amplitude(4) < 1.0,
            "order 4 left in the output's map: {}",
            amplitude(4)
        );
    }

    #[test]
    fn ratios_parse_as_numbers_or_auto() {
        assert_eq!("auto".parse::<Ratio>(), Ok(Ratio::Auto));
        assert_eq!(" -7.3 ".parse::<Ratio>(), Ok(Ratio::Given(-7.3)));
        for bad in ["0", "", "x", "NaN", "1e5"] {
            assert!(bad.parse::<Ratio>().is_err(), "{bad}");
        }
    }
}
