//! Multi-head self-calibration of one graduated scale: several read heads at known nominal
//! angles around one scale (the SelfA encoder of the shift-angle paper of Hsieh et al. 2022, section 2.3,
//! eqs. 8–9, and its section 3.2 with head sets of 3, 4 and 7).
//!
//! [`Multihead`] takes the heads' synchronized readings one sample at a time
//! ([`Multihead::push`]) and returns the scale's error map as the first head reads it, the heads'
//! actual angles, and which orders it cannot see ([`Multihead::finish`]):
//!
//! - [`Method::Joint`] (default): every head and every head set at once, by least squares; blind
//!   only to the orders no head pair sees.
//! - [`Method::Eda`]: the published equal-division average (eq. 9) per set of equally spaced
//!   heads, blind to the multiples of each set's head count.
//!
//! # Model
//! Heads `j = 1..J` read one scale at nominal angles `φ_j` with small unknown errors `δ_j`: head
//! `j` sits at `ψ_j = φ_j + δ_j`. Angles count from the first head (`φ_1 = δ_1 = 0`: the first
//! head is the origin, so the `δ_j` are head angle errors relative to it). Let `m(x)` be the
//! scale's error as the first head reads it, as a function of the first head's reading `x` (the
//! interface's map: `m(x) = x − θ`, `θ` the true angle). Head `j` reads the same scale at
//! `θ + ψ_j`; its reading plus `φ_j` is the reading the first head would give there, so
//! `r_j + φ_j − m(r_j + φ_j) = θ + ψ_j`. Subtracting `x − m(x) = θ` gives, for the difference
//! `d_j = r_j − r_1` of every synchronized sample, exactly and whatever the size of the errors,
//!
//! ```text
//! d_j(x) = δ_j + m(x + φ_j + d_j(x)) − m(x)                                        (1)
//! ```
//!
//! Only readings enter: no true angle, no time stamps, so neither the shaft's speed variation nor
//! its wobble in time matters, and the map comes out as a function of the reading directly.
//! Readings may be *relative to the head's nominal angle* (a head at 90° reads ≈ the first head's
//! value; calib's simulator writes these) or *raw scale readings* (a head at 90° reads ≈ 90° more);
//! each head's convention is recognized from its mean difference to the first head, which must lie
//! within [`MultiheadOptions::head_tol`] of 0 or of `φ_j`, and `φ_j` is removed from raw readings.
//! A wrong nominal angle among readings relative to it leaves the mean difference at 0 and shows
//! only as a misfit: per head, the bins' residual from the fit is compared with the scatter of the
//! differences within the bins (the readings' noise), and a head departing by more than 3× that
//! (and 0.01″) is named in a warning.
//!
//! # Joint least squares
//! Write `x + φ_j + d_j = x + ψ_j + g_j(x)` with `g_j = d_j − δ_j` (arcseconds). Then
//! (1) is `d_j(x) = δ_j + m(x + ψ_j) − m(x) + ρ_j(x)`, with `ρ_j = m(x + ψ_j + g_j) − m(x + ψ_j)
//! ≈ m′·g_j` second order in the error (for the SelfA scenario `|m′| ≤ Σ h·A_h = 5.5·10⁻⁵`,
//! `|g| ≤ 2.4″`: `|ρ| ≤ 1.3·10⁻⁴″`). With `m(x) = Σ_{h≠0} s_h e^{ihx}` (`s_{−h} = s̄_h`), the Fourier coefficients
//! of `d_j − ρ_j` are
//!
//! ```text
//! D_j(0) = δ_j,     D_j(h) = s_h · c_jh,     c_jh = e^{ihψ_j} − 1    (h ≠ 0)           (2)
//! ```
//!
//! By Parseval, the least-squares fit of all differences on a uniform grid of the first head's
//! reading is separable, one order at a time:
//!
//! ```text
//! s_h = Σ_j c̄_jh D_j(h) / Σ_j |c_jh|²,      δ_j = D_j(0)                            (3)
//! ```
//!
//! The **observability** `o_h = Σ_j |c_jh|² / (2J)` is 1 for `J` equally spaced heads and 0 when
//! `h·ψ_j ≡ 0 (mod 2π)` for every head: a component the heads all see at the same phase leaves no
//! trace in any difference. The noise on `s_h` is that of one difference's coefficient divided by
//! `√(2J·o_h)`. Orders with `o_h` below [`MultiheadOptions::min_observability`] are left out of
//! the map (set to 0) and reported: **blind** where every head's nominal angle is a multiple of
//! `360°/h` (to [`MultiheadOptions::angle_tol`]) — with the SelfA sets of 3, 4 and 7 heads, the
//! multiples of 84 = lcm(3, 4, 7) — else **ill-conditioned**.
//!
//! The head angles enter `c_jh` through `ψ_j`, so they are estimated, not assumed: order 0 is
//! apart from the others, so `δ̂_j = D_j(0)` is known before any `s_h` and every solve uses
//! `ψ_j = φ_j + δ̂_j`. Using `φ_j` instead would err at order `h` by `≈ h·|δ_j|` of `s_h`: 0.03″ on
//! a 1″ order-100 term with 1′ head errors; on the SelfA scenario (orders ≤ 100 of ≤ 0.1″ above
//! order 2) it changes the map by 10⁻⁴″ even with its head errors scaled to 1′. Then calib
//! iterates, with `ρ_j` and the sampling correction below computed from the current estimate,
//! until `s` and `δ` change by less than 10⁻⁶″ (about 5 solves). Measured on the SelfA scenario
//! without noise and quantization: 0.0039″ after the first solve, 0.0002″ iterated; with the
//! scale's errors scaled to 71″ peak to peak, 0.12″ and 0.005″.
//!
//! # Sampling
//! Samples stream into [`MultiheadOptions::bins_per_rev`] fine bins of the first head's reading
//! (count, mean reading and its spread, and per head the sum and sum of squares of `d_j`), so
//! memory does not grow with the log. At the end, fine bins are merged into the finest uniform
//! grid of `B` (a power of two) bins that *all* hold samples; each bin's mean difference is
//! brought from the bin's mean reading `x̄` to its centre `c` with the current model,
//! `d̄ − [F(x̄) + ½F″·var(x) − F(c)]` (`F` the right side of (1)), which makes the grid uniform
//! and the FFT of (3) exact for orders below `B/2`. Orders up to `B/4` are allowed, so that this
//! correction stays a contraction; by default [`MultiheadOptions::max_order`] is 40 % of the
//! samples per revolution (2.5 samples per period), at most `B/4` and 2000. Bins weigh equally
//! whatever their counts, so pauses and ramps (many samples in a few bins) do not tilt the fit.
//!
//! # Equal-division averaging (EDA, eqs. 8–9)
//! A set of `N` heads equally spaced by `360°/N`, the first head among them. Eq. 8's difference
//! `δ_{i,(1,j)} = a_i − a_{i+(j−1)NG/NH}` is the first head's error minus head `j`'s, `−d_j` in
//! calib's terms; eq. 9 averages it over the set:
//!
//! ```text
//! μ(x) = (1/N) Σ_j δ_{(1,j)} = −(1/N) Σ_j d_j(x) = m(x) − (1/N) Σ_j m(x + 2π(j−1)/N) − mean δ
//! ```
//!
//! At order `h` that is `s_h·(1 − (1/N) Σ_j e^{i2πh(j−1)/N})`: `s_h` for `N ∤ h`, 0 for `N | h`.
//! calib applies eq. 9 to the same bin-centred differences the joint method uses, per set; the
//! paper does not say how SelfA combines its three sets, so calib takes each order from the mean
//! of the sets that see it (`N ∤ h`) and leaves out the orders no set sees. Sets are given
//! ([`MultiheadOptions::sets`]) or inferred: for every `N`, the first head and heads at
//! `k·360°/N`, `k = 1..N−1` (to [`MultiheadOptions::angle_tol`]), keeping only sets not contained
//! in a larger one (the SelfA layout gives exactly its sets of 3, 4 and 7).
//!
//! # Uncertainty
//! [`MultiheadCalibration::uncertainty`] gives the standard uncertainty of the map at every table
//! point (both methods), GUM style: the noise of the differences propagated through the linear
//! estimate of each order, `s_h = Σ_j w_jh D_j(h)` (eq. 3's `w_jh = c̄_jh / Σ_k |c_kh|²`, or
//! eq. 9's averages), `u_fit² = Σ_h 2 Σ_jk Re(w_jh w̄_kh) Ĝ_jk` with `Ĝ` the covariance of the
//! coefficients' noise from the bins' residuals of the joint fit (Type A; it keeps the
//! correlation the first head's noise makes between the differences), and the linear
//! interpolation between table points (Type B). Blind and ill-conditioned orders are not in it:
//! they are named warnings.
//!
//! # What it cannot see
//! An absolute offset (the map is zero-mean); the orders every head sees in phase (blind, named);
//! orders above the fitted maximum. With EDA, the multiples of each set's `N` that no other set
//! sees. The head angle errors are relative to the first head.

use crate::angle::{DEG_PER_RAD, wrap_2pi, wrap_pi};
use crate::csrr::nufft::{GridTransform, Stencils};
use crate::error_map::ErrorMap;
use crate::harmonics::FourierSeries;
use crate::uncertainty::{Evaluation, MapComponent, MapUncertainty, interpolation_uncertainty};
use realfft::num_complex::Complex;
use std::f64::consts::{PI, TAU};

/// One read head: its channel name and nominal angle.
#[derive(Debug, Clone, PartialEq)]
pub struct Head {
    /// The channel's name (for messages and reports).
    pub name: String,
    /// Nominal angle around the scale, radians (only differences to the first head's matter).
    pub nominal: f64,
}

/// Which combination of the heads' differences.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// Joint least squares of all heads (eq. 3 of the module doc).
    #[default]
    Joint,
    /// The published equal-division average per set of equally spaced heads (eqs. 8–9).
    Eda,
}

/// Settings of a multi-head calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct MultiheadOptions {
    /// The method.
    pub method: Method,
    /// Highest order fitted; from the samples per revolution when `None` (see the module doc).
    pub max_order: Option<usize>,
    /// Fine bins per revolution of the streaming reduction: a power of two, at least 32
    /// (default 16384).
    pub bins_per_rev: usize,
    /// Orders whose observability is below this are left out of the map (default 0.01: noise on
    /// them would be amplified more than 10× against one equally spaced ring of the same heads).
    pub min_observability: f64,
    /// Points of the output map; enough for linear interpolation to 0.01″ when `None` (≥ 3600).
    pub points: Option<usize>,
    /// EDA head sets, as indices into the heads (each holding head 0); inferred from equal
    /// spacing when `None`. Only used by [`Method::Eda`].
    pub sets: Option<Vec<Vec<usize>>>,
    /// How far a nominal angle may be from a multiple of `360°/N` and still count as on it, for
    /// set membership and blind orders, radians (default 0.01°).
    pub angle_tol: f64,
    /// Largest head angle error, and largest change of a difference `r_j − r_1` over the log,
    /// radians (default 1°): beyond it the head is not where `--heads` says or does not read the
    /// same scale.
    pub head_tol: f64,
}

impl Default for MultiheadOptions {
    fn default() -> Self {
        MultiheadOptions {
            method: Method::Joint,
            max_order: None,
            bins_per_rev: 16384,
            min_observability: 0.01,
            points: None,
            sets: None,
            angle_tol: 0.01f64.to_radians(),
            head_tol: 1f64.to_radians(),
        }
    }
}

/// Why a multi-head calibration cannot be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MultiheadError {
    /// Fewer than two heads.
    #[error("{found} head(s) given; a multi-head calibration needs at least 2 heads on the scale")]
    TooFewHeads {
        /// Heads given.
        found: usize,
    },
    /// One head named twice.
    #[error("head `{name}` is named twice; name each head once")]
    DuplicateHead {
        /// The repeated name.
        name: String,
    },
    /// A nominal angle that is not a number.
    #[error("head `{head}` has no finite nominal angle")]
    NonFiniteAngle {
        /// The head.
        head: String,
    },
    /// Options that cannot work.
    #[error("invalid options: {0}")]
    Options(String),
    /// An EDA set of fewer than two heads.
    #[error("EDA set {{{}}} has fewer than 2 heads; a set is the first head and the heads equally spaced with it", set.join(", "))]
    SetTooSmall {
        /// The set's heads.
        set: Vec<String>,
    },
    /// An EDA set without the first head.
    #[error("EDA set {{{}}} does not hold the first head `{first}`: the map is the one the first head reads, so every set must include it", set.join(", "))]
    SetWithoutFirstHead {
        /// The set's heads.
        set: Vec<String>,
        /// The first head.
        first: String,
    },
    /// An EDA set whose heads are not equally spaced.
    #[error(
        "EDA set {{{}}}: head `{head}` sits at {angle_deg:.4}° from the first head, not at a multiple of 360°/{count} = {step_deg:.4}° \
         (or shares its place with another head of the set); EDA needs the set's heads equally spaced",
        set.join(", ")
    )]
    SetNotEquallySpaced {
        /// The set's heads.
        set: Vec<String>,
        /// The offending head.
        head: String,
        /// Its nominal angle from the first head, degrees.
        angle_deg: f64,
        /// Heads in the set.
        count: usize,
        /// The spacing they should have, degrees.
        step_deg: f64,
    },
    /// EDA without a set: no heads equally spaced with the first head.
    #[error(
        "no heads are equally spaced with the first head `{first}` (EDA needs e.g. one at 180°, or two at 120° and 240°); \
         check the angles in --heads, or use the joint method, which takes any spacing"
    )]
    NoEquallySpacedSet {
        /// The first head.
        first: String,
    },
    /// No sample with finite readings of every head.
    #[error("no sample has a finite reading of every head ({skipped} skipped); check the channels")]
    NoSamples {
        /// Samples skipped for non-finite readings.
        skipped: u64,
    },
    /// The first head's readings leave part of the circle without samples.
    #[error(
        "the readings of the first head `{first}` leave {gap_deg:.2}° around {at_deg:.2}° without samples; \
         record at least one whole revolution"
    )]
    NotCovered {
        /// The first head.
        first: String,
        /// The largest gap, degrees.
        gap_deg: f64,
        /// Its middle, degrees.
        at_deg: f64,
    },
    /// The requested order needs denser sampling.
    #[error(
        "order {requested} needs the first head's readings to fill {needed} equal bins per revolution, but they fill only \
         {available}; lower --max-order or record more samples per revolution"
    )]
    TooFewSamplesPerRevolution {
        /// The order asked for.
        requested: usize,
        /// Bins it needs (4 per period).
        needed: usize,
        /// Bins the log fills.
        available: usize,
    },
    /// A head's difference to the first head is far from its nominal angle.
    #[error(
        "head `{head}` reads {measured_deg:.4}° from the first head on average, neither 0 (readings relative to its nominal \
         angle) nor its nominal {nominal_deg:.4}° (raw scale readings), to within {tol_deg}°; check its angle in --heads"
    )]
    HeadAngleMismatch {
        /// The head.
        head: String,
        /// Its mean difference to the first head, degrees in `[−180, 180)`.
        measured_deg: f64,
        /// Its nominal angle from the first head, degrees.
        nominal_deg: f64,
        /// The tolerance, degrees.
        tol_deg: f64,
    },
    /// A head's difference to the first head changes too much: not the same scale.
    #[error(
        "the difference between head `{head}` and the first head `{first}` changes by {change_deg:.4}° over the log \
         (at most {tol_deg}° allowed): both must read the same scale, count the same way round and be in the same unit"
    )]
    NotFollowing {
        /// The head.
        head: String,
        /// The first head.
        first: String,
        /// Range of the difference, degrees.
        change_deg: f64,
        /// The tolerance, degrees.
        tol_deg: f64,
    },
    /// Every order is blind or ill-conditioned.
    #[error(
        "no order up to {max_order} is observable with these head angles (all heads at multiples of 360°/h for every h); \
         the heads must not all sit at one place"
    )]
    NothingObservable {
        /// The highest order tried.
        max_order: usize,
    },
}

/// How a head's readings relate to its place on the scale.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Readings {
    /// The head's reading minus its nominal angle (≈ the first head's reading).
    RelativeToNominal,
    /// The scale's reading under the head (≈ the first head's reading plus the nominal angle).
    Raw,
}

/// What the calibration found about one head.
#[derive(Debug, Clone, PartialEq)]
pub struct HeadEstimate {
    /// Its name.
    pub name: String,
    /// Nominal angle from the first head, radians in `[0, 2π)`.
    pub nominal: f64,
    /// Estimated actual minus nominal angle, radians, relative to the first head (0 for it).
    pub angle_error: f64,
    /// How its readings were taken (`None` for the first head).
    pub readings: Option<Readings>,
    /// RMS per sample of its difference's residual from the joint fit, radians (`None` for the
    /// first head).
    pub residual_rms: Option<f64>,
    /// RMS per sample of its difference's scatter within the bins (the readings' noise and
    /// quantization), radians; `None` for the first head or without two samples in any bin.
    pub noise_rms: Option<f64>,
}

/// An order left out of the map.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ExcludedOrder {
    /// The order.
    pub order: usize,
    /// Its observability `o_h` (0 for orders no EDA set sees).
    pub observability: f64,
}

/// One EDA set and its own estimate.
#[derive(Debug, Clone, PartialEq)]
pub struct SetEstimate {
    /// Its heads, as indices into the heads (the first head first).
    pub heads: Vec<usize>,
    /// The set's eq. 9 map as a Fourier series of the first head's reading (orders `1..=max_order`;
    /// multiples of the head count are what eq. 9 gives there, ≈ 0).
    pub series: FourierSeries,
}

/// The result of a multi-head calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct MultiheadCalibration {
    /// The method.
    pub method: Method,
    /// The scale's error as the first head reads it, as a function of its reading, zero mean.
    pub map: ErrorMap,
    /// The same as a Fourier series (orders `1..=max_order`, left-out orders 0).
    pub series: FourierSeries,
    /// Every head, in the order given, with its estimated angle error.
    pub heads: Vec<HeadEstimate>,
    /// Highest order fitted.
    pub max_order: usize,
    /// Uniform bins per revolution the fit used.
    pub bins: usize,
    /// Orders no head pair (joint) or no set (EDA) sees, left out.
    pub blind: Vec<ExcludedOrder>,
    /// Orders seen too weakly, left out (joint method).
    pub ill_conditioned: Vec<ExcludedOrder>,
    /// The EDA sets and their estimates (EDA only).
    pub sets: Vec<SetEstimate>,
    /// RMS per sample of the joint fit's residual over all differences, radians (joint only).
    pub residual_rms: Option<f64>,
    /// The standard uncertainty of the map at every table point, with its budget (see the
    /// module doc's section on uncertainty).
    pub uncertainty: MapUncertainty,
    /// Joint solves made (the EDA method makes them too, to bring the bins to their centres).
    pub iterations: usize,
    /// Samples used.
    pub samples: u64,
    /// Samples skipped (a non-finite reading).
    pub skipped: u64,
    /// Travel of the first head, revolutions.
    pub revolutions: f64,
    /// Things the user should know.
    pub warnings: Vec<String>,
}

/// A streaming multi-head calibration: [`Multihead::push`] every sample, then
/// [`Multihead::finish`].
#[derive(Debug, Clone)]
pub struct Multihead {
    heads: Vec<Head>,
    opts: MultiheadOptions,
    /// Nominal angle of each head from the first, `[0, 2π)`.
    rel: Vec<f64>,
    sets: Vec<Vec<usize>>,
    /// Per fine bin: samples, sum and sum of squares of the reading's offset from the bin's start.
    count: Vec<u32>,
    sum_x: Vec<f64>,
    sum_x2: Vec<f64>,
    /// Per fine bin and other head (`bin·(J−1) + j − 1`): sum and sum of squares of `d_j − d_ref`.
    sum_d: Vec<f64>,
    sum_d2: Vec<f64>,
    /// Per other head: the first sample's difference, and the range of `d_j − d_ref`.
    d_ref: Vec<f64>,
    d_min: Vec<f64>,
    d_max: Vec<f64>,
    last_x: Option<f64>,
    travel: f64,
    samples: u64,
    skipped: u64,
}

/// Solves at most this many times.
const MAX_ITERATIONS: usize = 50;
/// Convergence: largest change of a coefficient or head angle, radians (10⁻⁶″).
const TOLERANCE: f64 = 1e-6 / crate::angle::ARCSEC_PER_RAD;
/// Fewest uniform bins a fit accepts (4 orders).
const MIN_BINS: usize = 16;

impl Multihead {
    /// A calibration of these heads (the first is the reference whose map is returned).
    pub fn new(heads: Vec<Head>, opts: MultiheadOptions) -> Result<Self, MultiheadError> {
        if heads.len() < 2 {
            return Err(MultiheadError::TooFewHeads { found: heads.len() });
        }
        for (i, h) in heads.iter().enumerate() {
            if heads[..i].iter().any(|o| o.name == h.name) {
                return Err(MultiheadError::DuplicateHead {
                    name: h.name.clone(),
                });
            }
            if !h.nominal.is_finite() {
                return Err(MultiheadError::NonFiniteAngle {
                    head: h.name.clone(),
                });
            }
        }
        let f = opts.bins_per_rev;
        if !(f.is_power_of_two() && f >= 2 * MIN_BINS) {
            return Err(MultiheadError::Options(format!(
                "bins per revolution must be a power of two ≥ {}, got {f}",
                2 * MIN_BINS
            )));
        }
        if !(0.0..1.0).contains(&opts.min_observability) {
            return Err(MultiheadError::Options(
                "the minimum observability must be in [0, 1)".into(),
            ));
        }
        if !(opts.angle_tol >= 0.0 && opts.head_tol > 0.0 && opts.head_tol < 0.25 * TAU) {
            return Err(MultiheadError::Options(
                "the angle tolerance must be ≥ 0 and the head tolerance in (0, 90°)".into(),
            ));
        }
        if opts.max_order == Some(0) || opts.points.is_some_and(|p| p < 2) {
            return Err(MultiheadError::Options(
                "the maximum order must be ≥ 1 and the map's points ≥ 2".into(),
            ));
        }
        let rel: Vec<f64> = heads
            .iter()
            .map(|h| wrap_2pi(h.nominal - heads[0].nominal))
            .collect();
        let sets = match (&opts.method, &opts.sets) {
            (Method::Joint, _) => Vec::new(),
            (Method::Eda, Some(sets)) => {
                for set in sets {
                    check_set(&heads, &rel, set, opts.angle_tol)?;
                }
                sets.iter()
                    .map(|s| {
                        let mut s = s.clone();
                        s.sort_by(|&a, &b| rel[a].total_cmp(&rel[b]));
                        s
                    })
                    .collect()
            }
            (Method::Eda, None) => {
                let sets = infer_sets(&rel, opts.angle_tol);
                if sets.is_empty() {
                    return Err(MultiheadError::NoEquallySpacedSet {
                        first: heads[0].name.clone(),
                    });
                }
                sets
            }
        };
        let others = heads.len() - 1;
        Ok(Multihead {
            count: vec![0; f],
            sum_x: vec![0.0; f],
            sum_x2: vec![0.0; f],
            sum_d: vec![0.0; f * others],
            sum_d2: vec![0.0; f * others],
            d_ref: Vec::new(),
            d_min: vec![f64::INFINITY; others],
            d_max: vec![f64::NEG_INFINITY; others],
            last_x: None,
            travel: 0.0,
            samples: 0,
            skipped: 0,
            heads,
            opts,
            rel,
            sets,
        })
    }

    /// The EDA sets that will be used (given or inferred), as indices into the heads, each sorted
    /// by angle from the first head; empty for the joint method.
    pub fn sets(&self) -> &[Vec<usize>] {
        &self.sets
    }

    /// Adds one synchronized sample: every head's reading, radians, in the heads' order (wrapped
    /// or accumulated). Samples with a non-finite reading are skipped and counted.
    ///
    /// # Panics
    /// If `readings` does not hold one value per head.
    pub fn push(&mut self, readings: &[f64]) {
        assert_eq!(
            readings.len(),
            self.heads.len(),
            "one reading per head, in the heads' order"
        );
        if readings.iter().any(|r| !r.is_finite()) {
            self.skipped += 1;
            return;
        }
        let r1 = readings[0];
        if self.d_ref.is_empty() {
            self.d_ref = readings[1..].iter().map(|r| wrap_pi(r - r1)).collect();
        }
        if let Some(last) = self.last_x {
            self.travel += wrap_pi_near(r1 - last).abs();
        }
        self.last_x = Some(r1);
        let f = self.count.len();
        let width = TAU / f as f64;
        let x = if (0.0..TAU).contains(&r1) {
            r1
        } else {
            wrap_2pi(r1)
        };
        let i = ((x / width) as usize).min(f - 1);
        let off = x - i as f64 * width;
        self.count[i] += 1;
        self.sum_x[i] += off;
        self.sum_x2[i] += off * off;
        let others = self.heads.len() - 1;
        let base = i * others;
        for j in 0..others {
            let d = wrap_pi_near(readings[j + 1] - r1 - self.d_ref[j]);
            self.sum_d[base + j] += d;
            self.sum_d2[base + j] += d * d;
            self.d_min[j] = self.d_min[j].min(d);
            self.d_max[j] = self.d_max[j].max(d);
        }
        self.samples += 1;
    }

    /// Solves, once every sample is in.
    pub fn finish(self) -> Result<MultiheadCalibration, MultiheadError> {
        let first = self.heads[0].name.clone();
        if self.samples == 0 {
            return Err(MultiheadError::NoSamples {
                skipped: self.skipped,
            });
        }
        let others = self.heads.len() - 1;
        for j in 0..others {
            let change = self.d_max[j] - self.d_min[j];
            if change > self.opts.head_tol {
                return Err(MultiheadError::NotFollowing {
                    head: self.heads[j + 1].name.clone(),
                    first,
                    change_deg: change.to_degrees(),
                    tol_deg: self.opts.head_tol.to_degrees(),
                });
            }
        }
        // Each head's reading convention, from its mean difference to the first head.
        let n_all = self.samples as f64;
        let mut readings = Vec::with_capacity(others);
        let mut base = Vec::with_capacity(others);
        for j in 0..others {
            let total: f64 = (0..self.count.len())
                .map(|i| self.sum_d[i * others + j])
                .sum();
            let mean = wrap_pi(self.d_ref[j] + total / n_all);
            let nominal = self.rel[j + 1];
            let (relative, raw) = (mean.abs(), wrap_pi(mean - nominal).abs());
            let conv = if relative <= raw {
                Readings::RelativeToNominal
            } else {
                Readings::Raw
            };
            if relative.min(raw) > self.opts.head_tol {
                return Err(MultiheadError::HeadAngleMismatch {
                    head: self.heads[j + 1].name.clone(),
                    measured_deg: mean.to_degrees(),
                    nominal_deg: nominal.to_degrees(),
                    tol_deg: self.opts.head_tol.to_degrees(),
                });
            }
            let removed = if conv == Readings::Raw { nominal } else { 0.0 };
            base.push(wrap_pi(self.d_ref[j] - removed));
            readings.push(conv);
        }

        let bins = self.uniform_bins().ok_or_else(|| {
            let (gap, at) = largest_gap(&self.count);
            MultiheadError::NotCovered {
                first: first.clone(),
                gap_deg: gap.to_degrees(),
                at_deg: at.to_degrees(),
            }
        })?;
        let revolutions = self.travel / TAU;
        let max_order = match self.opts.max_order {
            Some(h) if 4 * h > bins => {
                return Err(MultiheadError::TooFewSamplesPerRevolution {
                    requested: h,
                    needed: 4 * h,
                    available: bins,
                });
            }
            Some(h) => h,
            None => {
                let per_rev = n_all / revolutions.max(1.0);
                ((0.4 * per_rev).floor() as usize).clamp(1, (bins / 4).min(2000))
            }
        };
        let data = self.merge(bins, &base);
        let rel_others: Vec<f64> = self.rel[1..].to_vec();
        let fit = joint(&data, &rel_others, max_order, &self.opts)?;

        let mut warnings = Vec::new();
        if self.skipped > 0 {
            warnings.push(format!(
                "{} sample(s) with a non-finite reading of some head were skipped",
                self.skipped
            ));
        }
        if !fit.converged {
            warnings.push(format!(
                "the solve stopped after {} iterations before reaching its tolerance; the map may be inaccurate \
                 (try a lower --max-order)",
                fit.iterations
            ));
        }
        if readings.contains(&Readings::Raw) && readings.contains(&Readings::RelativeToNominal) {
            warnings.push(
                "some heads read raw scale angles and others angles relative to their nominal place; check that this is \
                 what the log holds"
                    .into(),
            );
        }

        // Structural blindness: every head's nominal angle on a multiple of 360°/h.
        let structurally_blind = |h: usize| {
            self.rel
                .iter()
                .all(|&p| wrap_pi(h as f64 * p).abs() <= h as f64 * self.opts.angle_tol)
        };
        let psi: Vec<f64> = rel_others
            .iter()
            .zip(&fit.delta)
            .map(|(p, d)| p + d)
            .collect();
        let (series, blind, ill_conditioned, set_estimates, residual_rms) = match self.opts.method {
            Method::Joint => {
                let (blind, ill): (Vec<ExcludedOrder>, Vec<ExcludedOrder>) = fit
                    .excluded
                    .iter()
                    .partition(|e| structurally_blind(e.order));
                let series = series_of(&fit.s);
                let sum: f64 = fit.residuals.iter().map(|r| r.between + r.within).sum();
                let rms = (sum / (n_all * others as f64)).sqrt();
                (series, blind, ill, Vec::new(), Some(rms))
            }
            Method::Eda => {
                let (series, sets, blind) = eda(&data, &fit, &self.sets, max_order);
                (series, blind, Vec::new(), sets, None)
            }
        };
        let points = self
            .opts
            .points
            .unwrap_or_else(|| crate::csrr::table_points(&series));
        let map = ErrorMap::from_series(&series, points);
        let excluded: Vec<usize> = blind
            .iter()
            .chain(&ill_conditioned)
            .map(|e| e.order)
            .collect();
        let fitted: Vec<usize> = (1..=max_order).filter(|h| !excluded.contains(h)).collect();
        let weights = |h: usize| match self.opts.method {
            Method::Joint => joint_weights(h, &psi),
            Method::Eda => eda_weights(h, &self.sets, others),
        };
        let unknowns = 2 * fitted.len() + others;
        let u_fit = fit_noise(&fit.bin_residuals, unknowns, &fitted, weights);
        let uncertainty = map_uncertainty(self.opts.method, u_fit, &series, points);
        let heads: Vec<HeadEstimate> = self
            .heads
            .iter()
            .enumerate()
            .map(|(j, h)| HeadEstimate {
                name: h.name.clone(),
                nominal: self.rel[j],
                angle_error: if j == 0 { 0.0 } else { fit.delta[j - 1] },
                readings: (j > 0).then(|| readings[j - 1]),
                residual_rms: (j > 0).then(|| {
                    let r = fit.residuals[j - 1];
                    ((r.between + r.within) / n_all).sqrt()
                }),
                noise_rms: (j > 0)
                    .then(|| fit.residuals[j - 1])
                    .filter(|r| r.dof > 0.0)
                    .map(|r| (r.within / r.dof).sqrt()),
            })
            .collect();
        warnings.extend(misfits(&heads, &fit.residuals, bins));
        Ok(MultiheadCalibration {
            method: self.opts.method,
            map,
            series,
            heads,
            max_order,
            bins,
            blind,
            ill_conditioned,
            sets: set_estimates,
            residual_rms,
            uncertainty,
            iterations: fit.iterations,
            samples: self.samples,
            skipped: self.skipped,
            revolutions,
            warnings,
        })
    }

    /// The finest uniform grid of `B ≤ F/2` bins (a power of two, ≥ [`MIN_BINS`]) whose bins,
    /// centred on `b·2π/B`, all hold samples.
    fn uniform_bins(&self) -> Option<usize> {
        let f = self.count.len();
        let mut b = f / 2;
        while b >= MIN_BINS {
            let k = f / b;
            let covered =
                (0..b).all(|c| (0..k).any(|m| self.count[(c * k + f - k / 2 + m) % f] > 0));
            if covered {
                return Some(b);
            }
            b /= 2;
        }
        None
    }

    /// The fine bins merged into `b` bins centred on `c·2π/b`; `base[j]` is added to head `j`'s
    /// mean difference (its first difference, less the nominal angle for raw readings).
    fn merge(&self, b: usize, base: &[f64]) -> Binned {
        let f = self.count.len();
        let k = f / b;
        let fine = TAU / f as f64;
        let width = TAU / b as f64;
        let others = base.len();
        let mut out = Binned {
            width,
            n: vec![0.0; b],
            x: vec![0.0; b],
            var: vec![0.0; b],
            y: vec![vec![0.0; b]; others],
            scatter: vec![vec![0.0; b]; others],
        };
        let mut sd = vec![0.0; others];
        let mut sd2 = vec![0.0; others];
        for c in 0..b {
            let (mut n, mut sx, mut sx2) = (0.0, 0.0, 0.0);
            sd.iter_mut().for_each(|v| *v = 0.0);
            sd2.iter_mut().for_each(|v| *v = 0.0);
            for m in 0..k {
                let i = (c * k + f - k / 2 + m) % f;
                let cnt = f64::from(self.count[i]);
                if cnt == 0.0 {
                    continue;
                }
                // Offset of fine bin i's start from the centre c·width, in [−width/2, width/2).
                let shift = (m as f64 - (k / 2) as f64) * fine;
                n += cnt;
                sx += self.sum_x[i] + cnt * shift;
                sx2 += self.sum_x2[i] + 2.0 * shift * self.sum_x[i] + cnt * shift * shift;
                for j in 0..others {
                    sd[j] += self.sum_d[i * others + j];
                    sd2[j] += self.sum_d2[i * others + j];
                }
            }
            let mean_off = sx / n;
            out.n[c] = n;
            out.x[c] = c as f64 * width + mean_off;
            out.var[c] = (sx2 / n - mean_off * mean_off).max(0.0);
            for j in 0..others {
                let mean = sd[j] / n;
                out.y[j][c] = base[j] + mean;
                out.scatter[j][c] = (sd2[j] - n * mean * mean).max(0.0);
            }
        }
        out
    }
}

/// The samples reduced to a uniform grid of bins centred on `c·width`.
#[derive(Debug, Clone)]
struct Binned {
    width: f64,
    /// Samples per bin.
    n: Vec<f64>,
    /// Mean reading of the first head, rad.
    x: Vec<f64>,
    /// Variance of the first head's reading within the bin, rad².
    var: Vec<f64>,
    /// Per other head: mean difference to the first head, rad (nominal removed from raw readings).
    y: Vec<Vec<f64>>,
    /// Per other head: sum of squared deviations of the difference from its bin mean, rad².
    scatter: Vec<Vec<f64>>,
}

/// The joint solution.
struct JointFit {
    /// `s_h` at index `h − 1` (0 for left-out orders).
    s: Vec<Complex<f64>>,
    /// Head angle errors of the other heads, rad.
    delta: Vec<f64>,
    /// The differences brought to the bin centres (sampling correction only), per other head.
    centred: Vec<Vec<f64>>,
    excluded: Vec<ExcludedOrder>,
    /// Per other head: residual sums (see [`Corrections`]).
    residuals: Vec<Residual>,
    /// Per other head: each bin mean's residual from the linear model at the bin centres, rad.
    bin_residuals: Vec<Vec<f64>>,
    iterations: usize,
    converged: bool,
}

/// The model's value and bin corrections of one head, evaluated with the current estimate.
struct Corrections {
    /// Data at the centres, sampling-corrected: for EDA.
    centred: Vec<f64>,
    /// Data at the centres with the nonlinear remainder removed: for the linear solve.
    linear: Vec<f64>,
    residual: Residual,
    /// Each bin mean's residual, `linear − model`.
    bin_residual: Vec<f64>,
}

/// One head's residual sums over the bins.
#[derive(Debug, Clone, Copy, Default)]
struct Residual {
    /// `Σ n·r²`, `r` the bin mean's residual.
    between: f64,
    /// Within-bin scatter net of the model's slope, and its degrees of freedom `Σ (n − 1)`.
    within: f64,
    dof: f64,
}

/// The three grids of `m`, `m′`, `m″` and their values at the bins' means and centres.
struct Model {
    grid: usize,
    m: Vec<f64>,
    m1: Vec<f64>,
    m2: Vec<f64>,
}

impl Model {
    fn new(transform: &mut GridTransform, grid: usize, s: &[Complex<f64>]) -> Self {
        let orders: Vec<usize> = (1..=s.len()).collect();
        let a: Vec<f64> = s.iter().map(|c| 2.0 * c.re).collect();
        let b: Vec<f64> = s.iter().map(|c| -2.0 * c.im).collect();
        let h = |i: usize| (i + 1) as f64;
        // m′: h·(b cos − a sin); m″: −h²·(a cos + b sin).
        let a1: Vec<f64> = (0..s.len()).map(|i| h(i) * b[i]).collect();
        let b1: Vec<f64> = (0..s.len()).map(|i| -h(i) * a[i]).collect();
        let a2: Vec<f64> = (0..s.len()).map(|i| -h(i) * h(i) * a[i]).collect();
        let b2: Vec<f64> = (0..s.len()).map(|i| -h(i) * h(i) * b[i]).collect();
        let mut m = vec![0.0; grid];
        let mut m1 = vec![0.0; grid];
        let mut m2 = vec![0.0; grid];
        transform.synthesize(&orders, &a, &b, &mut m);
        transform.synthesize(&orders, &a1, &b1, &mut m1);
        transform.synthesize(&orders, &a2, &b2, &mut m2);
        Model { grid, m, m1, m2 }
    }

    fn at(&self, grid: &[f64], points: impl Iterator<Item = f64>, out: &mut [f64]) {
        Stencils::new(points, self.grid).gather(grid, out);
    }

    /// `F(x) = δ + m(x + φ + F(x)) − m(x)` at `xs` (the right side of eq. 1), by fixed-point
    /// iteration from the linear model `δ + m(x + ψ) − m(x)` (given as `linear`); `m_x` is `m(xs)`.
    fn exact(&self, xs: &[f64], phi: f64, delta: f64, linear: &[f64], m_x: &[f64]) -> Vec<f64> {
        let mut f = linear.to_vec();
        let mut shifted = vec![0.0; xs.len()];
        for _ in 0..20 {
            self.at(
                &self.m,
                xs.iter().zip(&f).map(|(x, f)| x + phi + f),
                &mut shifted,
            );
            let mut change = 0.0f64;
            for ((fv, s), mx) in f.iter_mut().zip(&shifted).zip(m_x) {
                let next = delta + s - mx;
                change = change.max((next - *fv).abs());
                *fv = next;
            }
            if change <= 1e-16 {
                break;
            }
        }
        f
    }
}

/// The joint least-squares solve of eq. 3 with the sampling and nonlinear corrections iterated.
fn joint(
    data: &Binned,
    rel: &[f64],
    max_order: usize,
    opts: &MultiheadOptions,
) -> Result<JointFit, MultiheadError> {
    let b = data.n.len();
    let others = rel.len();
    let heads = others + 1;
    let grid = (32 * max_order).max(1024).next_power_of_two();
    let mut synth = GridTransform::new(grid);
    let mut analysis = GridTransform::new(b);
    let orders: Vec<usize> = (1..=max_order).collect();
    let centres: Vec<f64> = (0..b).map(|c| c as f64 * data.width).collect();

    let mut s = vec![Complex::new(0.0, 0.0); max_order];
    let mut delta = vec![0.0; others];
    let mut fitted: Option<Vec<bool>> = None;
    let mut excluded = Vec::new();
    let mut iterations = 0;
    let mut converged = false;
    let mut scratch = vec![0.0; b];
    let (mut cos, mut sin) = (vec![0.0; max_order], vec![0.0; max_order]);
    loop {
        let model = Model::new(&mut synth, grid, &s);
        let mut m_x = vec![0.0; b];
        let mut m1_x = vec![0.0; b];
        let mut m2_x = vec![0.0; b];
        let mut m_c = vec![0.0; b];
        model.at(&model.m, data.x.iter().copied(), &mut m_x);
        model.at(&model.m1, data.x.iter().copied(), &mut m1_x);
        model.at(&model.m2, data.x.iter().copied(), &mut m2_x);
        model.at(&model.m, centres.iter().copied(), &mut m_c);
        let corrections: Vec<Corrections> = (0..others)
            .map(|j| {
                let psi = rel[j] + delta[j];
                let shifted = Stencils::new(data.x.iter().map(|x| x + psi), grid);
                let (mut mp, mut m1p, mut m2p) = (vec![0.0; b], vec![0.0; b], vec![0.0; b]);
                shifted.gather(&model.m, &mut mp);
                shifted.gather(&model.m1, &mut m1p);
                shifted.gather(&model.m2, &mut m2p);
                let mut mcp = vec![0.0; b];
                model.at(&model.m, centres.iter().map(|c| c + psi), &mut mcp);
                let lin_x: Vec<f64> = (0..b).map(|i| delta[j] + mp[i] - m_x[i]).collect();
                let lin_c: Vec<f64> = (0..b).map(|i| delta[j] + mcp[i] - m_c[i]).collect();
                let f_x = model.exact(&data.x, rel[j], delta[j], &lin_x, &m_x);
                let f_c = model.exact(&centres, rel[j], delta[j], &lin_c, &m_c);
                let mut centred = vec![0.0; b];
                let mut linear = vec![0.0; b];
                let mut residual = Residual::default();
                let mut bin_residual = vec![0.0; b];
                for i in 0..b {
                    let curvature = m2p[i] - m2_x[i];
                    let slope = m1p[i] - m1_x[i];
                    let sampling = f_x[i] + 0.5 * curvature * data.var[i] - f_c[i];
                    centred[i] = data.y[j][i] - sampling;
                    linear[i] = centred[i] - (f_c[i] - lin_c[i]);
                    let r = linear[i] - lin_c[i];
                    bin_residual[i] = r;
                    let within =
                        (data.scatter[j][i] - data.n[i] * slope * slope * data.var[i]).max(0.0);
                    residual.between += data.n[i] * r * r;
                    residual.within += within;
                    residual.dof += data.n[i] - 1.0;
                }
                Corrections {
                    centred,
                    linear,
                    residual,
                    bin_residual,
                }
            })
            .collect();
        if converged || iterations == MAX_ITERATIONS {
            return Ok(JointFit {
                s,
                delta,
                residuals: corrections.iter().map(|c| c.residual).collect(),
                bin_residuals: corrections.iter().map(|c| c.bin_residual.clone()).collect(),
                centred: corrections.into_iter().map(|c| c.centred).collect(),
                excluded,
                iterations,
                converged,
            });
        }

        // The solve: per-head coefficients D_j(h), then eq. 3 order by order.
        let mut coefficients = Vec::with_capacity(others);
        let mut new_delta = vec![0.0; others];
        for (j, c) in corrections.iter().enumerate() {
            scratch.copy_from_slice(&c.linear);
            new_delta[j] = scratch.iter().sum::<f64>() / b as f64;
            analysis.analyze_transpose(&mut scratch, &orders, &mut cos, &mut sin);
            let d: Vec<Complex<f64>> = (0..max_order)
                .map(|i| Complex::new(cos[i], -sin[i]) / b as f64)
                .collect();
            coefficients.push(d);
        }
        let fit = fitted.get_or_insert_with(|| {
            let mut fit = vec![true; max_order];
            for h in 1..=max_order {
                let q: f64 = (0..others)
                    .map(|j| (unit(h, rel[j] + new_delta[j]) - 1.0).norm_sqr())
                    .sum();
                let o = q / (2.0 * heads as f64);
                if o < opts.min_observability {
                    fit[h - 1] = false;
                    excluded.push(ExcludedOrder {
                        order: h,
                        observability: o,
                    });
                }
            }
            fit
        });
        if !fit.contains(&true) {
            return Err(MultiheadError::NothingObservable { max_order });
        }
        let mut change = 0.0f64;
        for h in 1..=max_order {
            let next = if fit[h - 1] {
                let (mut num, mut den) = (Complex::new(0.0, 0.0), 0.0);
                for j in 0..others {
                    let c = unit(h, rel[j] + new_delta[j]) - 1.0;
                    num += c.conj() * coefficients[j][h - 1];
                    den += c.norm_sqr();
                }
                num / den
            } else {
                Complex::new(0.0, 0.0)
            };
            change = change.max(2.0 * (next - s[h - 1]).norm());
            s[h - 1] = next;
        }
        for j in 0..others {
            change = change.max((new_delta[j] - delta[j]).abs());
        }
        delta = new_delta;
        iterations += 1;
        if !change.is_finite() {
            return Err(MultiheadError::NothingObservable { max_order });
        }
        converged = change <= TOLERANCE;
    }
}

/// The weights `w_j` of the joint solution's order `h` on the other heads' coefficients,
/// `s_h = Σ_j w_j D_j(h)`: eq. 3's `w_j = c̄_jh / Σ_k |c_kh|²`, `c_jh = e^{ihψ_j} − 1`.
fn joint_weights(h: usize, psi: &[f64]) -> Vec<Complex<f64>> {
    let c: Vec<Complex<f64>> = psi.iter().map(|&p| unit(h, p) - 1.0).collect();
    let q: f64 = c.iter().map(|c| c.norm_sqr()).sum();
    c.iter().map(|c| c.conj() / q).collect()
}

/// The weights of the EDA estimate of order `h` (see [`eda`]): the mean over the `K` sets that
/// see `h` of eq. 9's `−(1/N) Σ_{j∈set} D_j(h)`, so head `j` weighs `−(1/K) Σ_{sets∋j} 1/N`.
fn eda_weights(h: usize, sets: &[Vec<usize>], others: usize) -> Vec<Complex<f64>> {
    let seeing: Vec<&Vec<usize>> = sets.iter().filter(|s| h % s.len() != 0).collect();
    let k = seeing.len().max(1) as f64;
    let mut w = vec![Complex::new(0.0, 0.0); others];
    for set in seeing {
        let n = set.len() as f64;
        for &j in set.iter().filter(|&&j| j > 0) {
            w[j - 1] -= 1.0 / (k * n);
        }
    }
    w
}

/// The standard uncertainty, at any angle, that the noise of the differences leaves in the map.
///
/// Every order's estimate is linear in the heads' Fourier coefficients, `s_h = Σ_j w_j D_j(h)`
/// with `D_j(h) = (1/B) Σ_c y_jc e^{−ihx_c}` over the `B` bins ([`joint_weights`] for eq. 3,
/// [`eda_weights`] for eq. 9). With the bins' mean errors independent from bin to bin, the
/// coefficients' noise has the covariance `G_jk = E[δD_j δD̄_k] = (1/B²) Σ_c cov(y_jc, y_kc)` at
/// every order, estimated from the bins' residuals `r_jc` of the joint fit,
///
/// `Ĝ_jk = Σ_c r_jc r_kc / (B·(B − P/(J−1)))`  (`P` unknowns over the `(J−1)·B` bin means),
///
/// which keeps the correlation between the differences: every `d_j = r_j − r_1` holds the first
/// head's noise, so with `J` equally spaced heads of equal noise the first head's share of
/// `var s_h` is `(J/2)`-fold the others' together. Cosine and sine of `δs_h` have the same
/// variance and no correlation, so `m = Σ_h 2 Re(s_h e^{ihx})` has, at every angle,
///
/// `u_fit² = Σ_h 2 Σ_jk Re(w_j w̄_k) Ĝ_jk`
///
/// over the fitted orders: left-out (blind) orders are warnings, not uncertainty.
fn fit_noise(
    residuals: &[Vec<f64>],
    unknowns: usize,
    orders: &[usize],
    weights: impl Fn(usize) -> Vec<Complex<f64>>,
) -> f64 {
    let others = residuals.len();
    let b = residuals.first().map_or(0, Vec::len);
    let data = (others * b) as f64;
    let dof = data - unknowns as f64;
    if b == 0 || dof <= 0.0 {
        return 0.0;
    }
    let scale = data / dof / (b as f64 * b as f64);
    let g: Vec<Vec<f64>> = residuals
        .iter()
        .map(|rj| {
            residuals
                .iter()
                .map(|rk| scale * rj.iter().zip(rk).map(|(a, c)| a * c).sum::<f64>())
                .collect()
        })
        .collect();
    let var: f64 = orders
        .iter()
        .map(|&h| {
            let w = weights(h);
            let mut v = 0.0;
            for j in 0..others {
                for k in 0..others {
                    v += (w[j] * w[k].conj()).re * g[j][k];
                }
            }
            2.0 * v
        })
        .sum();
    var.max(0.0).sqrt()
}

/// The budget of the map of `points` points: the fit's noise `u_fit` ([`fit_noise`], Type A)
/// and the linear interpolation of the table between its points
/// ([`interpolation_uncertainty`], Type B).
fn map_uncertainty(
    method: Method,
    u_fit: f64,
    series: &FourierSeries,
    points: usize,
) -> MapUncertainty {
    let fit = match method {
        Method::Joint => "the joint fit",
        Method::Eda => "the equal-division average",
    };
    MapUncertainty::combine(
        points,
        vec![
            MapComponent {
                name: format!("noise of the readings propagated through {fit}"),
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

/// Warnings for heads whose bin means depart from the joint fit by far more than their noise
/// explains (a wrong nominal angle among readings relative to it shows only this way).
///
/// A bin mean of `n` samples has variance `σ²/n`, so `Σ n·r²` over `B` bins is `≈ B·σ²` when the
/// model holds. A head is flagged when its bin residual RMS exceeds 3σ and 0.01″ (the floor keeps
/// noise-free data quiet).
fn misfits(heads: &[HeadEstimate], residuals: &[Residual], bins: usize) -> Vec<String> {
    let floor = 0.01 / crate::angle::ARCSEC_PER_RAD;
    heads[1..]
        .iter()
        .zip(residuals)
        .filter_map(|(h, r)| {
            let misfit = (r.between / bins as f64).sqrt();
            let noise = h.noise_rms.unwrap_or(0.0);
            (misfit > 3.0 * noise && misfit > floor).then(|| {
                format!(
                    "head `{}` disagrees with the others: its differences depart from the fit by {:.4}″ RMS where its noise is \
                     {:.4}″; check its angle in --heads (and --max-order, if the scale has higher orders)",
                    h.name,
                    misfit * crate::angle::ARCSEC_PER_RAD,
                    noise * crate::angle::ARCSEC_PER_RAD
                )
            })
        })
        .collect()
}

/// [`wrap_pi`] without its `fmod` (a slow software routine) for values already in range, the
/// usual case for the small differences and steps of [`Multihead::push`].
#[inline]
fn wrap_pi_near(x: f64) -> f64 {
    if (-PI..PI).contains(&x) {
        x
    } else {
        wrap_pi(x)
    }
}

/// `e^{ihψ}`.
fn unit(h: usize, psi: f64) -> Complex<f64> {
    let (s, c) = (wrap_2pi(psi) * h as f64).sin_cos();
    Complex::new(c, s)
}

/// The map's Fourier series from the `s_h`: `a_h = 2 Re s_h`, `b_h = −2 Im s_h`.
fn series_of(s: &[Complex<f64>]) -> FourierSeries {
    FourierSeries {
        cos: s.iter().map(|c| 2.0 * c.re).collect(),
        sin: s.iter().map(|c| -2.0 * c.im).collect(),
    }
}

/// Eq. 9 per set on the bin-centred differences, and the sets combined order by order.
fn eda(
    data: &Binned,
    fit: &JointFit,
    sets: &[Vec<usize>],
    max_order: usize,
) -> (FourierSeries, Vec<SetEstimate>, Vec<ExcludedOrder>) {
    let b = data.n.len();
    let mut analysis = GridTransform::new(b);
    let orders: Vec<usize> = (1..=max_order).collect();
    let (mut cos, mut sin) = (vec![0.0; max_order], vec![0.0; max_order]);
    let mut estimates = Vec::with_capacity(sets.len());
    for set in sets {
        let n = set.len() as f64;
        // μ = −(1/N) Σ_j d_j at every bin centre (d_1 = 0).
        let mut mu = vec![0.0; b];
        for &j in set.iter().filter(|&&j| j > 0) {
            for (m, y) in mu.iter_mut().zip(&fit.centred[j - 1]) {
                *m -= y / n;
            }
        }
        analysis.analyze_transpose(&mut mu, &orders, &mut cos, &mut sin);
        let scale = 2.0 / b as f64;
        estimates.push(SetEstimate {
            heads: set.clone(),
            series: FourierSeries {
                cos: cos.iter().map(|v| v * scale).collect(),
                sin: sin.iter().map(|v| v * scale).collect(),
            },
        });
    }
    let mut combined = FourierSeries::zeros(max_order);
    let mut blind = Vec::new();
    for h in 1..=max_order {
        let seeing: Vec<&SetEstimate> = estimates
            .iter()
            .filter(|e| h % e.heads.len() != 0)
            .collect();
        if seeing.is_empty() {
            blind.push(ExcludedOrder {
                order: h,
                observability: 0.0,
            });
            continue;
        }
        let k = seeing.len() as f64;
        combined.cos[h - 1] = seeing.iter().map(|e| e.series.cos[h - 1]).sum::<f64>() / k;
        combined.sin[h - 1] = seeing.iter().map(|e| e.series.sin[h - 1]).sum::<f64>() / k;
    }
    (combined, estimates, blind)
}

/// Checks one EDA set: at least 2 heads, the first among them, no head twice, equally spaced.
fn check_set(heads: &[Head], rel: &[f64], set: &[usize], tol: f64) -> Result<(), MultiheadError> {
    if let Some(&bad) = set.iter().find(|&&j| j >= heads.len()) {
        return Err(MultiheadError::Options(format!(
            "EDA set names head index {bad}, but there are {} heads",
            heads.len()
        )));
    }
    let names: Vec<String> = set.iter().map(|&j| heads[j].name.clone()).collect();
    for (i, &j) in set.iter().enumerate() {
        if set[..i].contains(&j) {
            return Err(MultiheadError::DuplicateHead {
                name: heads[j].name.clone(),
            });
        }
    }
    if set.len() < 2 {
        return Err(MultiheadError::SetTooSmall { set: names });
    }
    if !set.contains(&0) {
        return Err(MultiheadError::SetWithoutFirstHead {
            set: names,
            first: heads[0].name.clone(),
        });
    }
    let n = set.len();
    let step = TAU / n as f64;
    let mut taken = vec![false; n];
    for &j in set.iter().filter(|&&j| j > 0) {
        let k = (rel[j] / step).round() as usize % n;
        if k == 0 || taken[k] || wrap_pi(rel[j] - k as f64 * step).abs() > tol {
            return Err(MultiheadError::SetNotEquallySpaced {
                set: names,
                head: heads[j].name.clone(),
                angle_deg: rel[j] * DEG_PER_RAD,
                count: n,
                step_deg: step * DEG_PER_RAD,
            });
        }
        taken[k] = true;
    }
    Ok(())
}

/// The maximal sets of heads equally spaced with the first head (see the module doc), each
/// sorted by angle.
fn infer_sets(rel: &[f64], tol: f64) -> Vec<Vec<usize>> {
    let mut found: Vec<Vec<usize>> = Vec::new();
    for n in 2..=rel.len() {
        let step = TAU / n as f64;
        let set: Option<Vec<usize>> =
            std::iter::once(Some(0))
                .chain((1..n).map(|k| {
                    (1..rel.len()).find(|&j| wrap_pi(rel[j] - k as f64 * step).abs() <= tol)
                }))
                .collect();
        if let Some(set) = set {
            found.push(set);
        }
    }
    let counts: Vec<usize> = found.iter().map(Vec::len).collect();
    found
        .into_iter()
        .filter(|s| !counts.iter().any(|&m| m != s.len() && m % s.len() == 0))
        .collect()
}

/// The largest circular run of empty fine bins: (width, middle), radians.
fn largest_gap(count: &[u32]) -> (f64, f64) {
    let f = count.len();
    let width = TAU / f as f64;
    let Some(start) = count.iter().position(|&c| c > 0) else {
        return (TAU, std::f64::consts::PI);
    };
    let (mut best, mut best_end, mut run) = (0usize, 0usize, 0usize);
    for step in 1..=f {
        let i = (start + step) % f;
        if count[i] == 0 {
            run += 1;
            if run > best {
                best = run;
                best_end = i;
            }
        } else {
            run = 0;
        }
    }
    let middle = (best_end as f64 + 1.0 - best as f64 / 2.0) * width;
    (best as f64 * width, wrap_2pi(middle))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::angle::ARCSEC_PER_RAD;
    use crate::harmonics::Harmonic;

    const ARCSEC: f64 = 1.0 / ARCSEC_PER_RAD;

    /// Heads at 0°, 90°, 180°, 270° (a set of 4) and 120°, 240° (with the first, a set of 3),
    /// and their angle errors, arcsec.
    const DEG: [f64; 6] = [0.0, 90.0, 180.0, 270.0, 120.0, 240.0];
    const ERR: [f64; 6] = [0.0, 2.0, -1.5, 3.0, -2.5, 1.0];

    /// The scale's error as a function of the true angle: orders 3, 4, 5, 8 and 12.
    fn scale() -> FourierSeries {
        let terms = [
            (3, 1.0, 10.0),
            (4, 0.5, -30.0),
            (5, 0.4, 60.0),
            (8, 0.3, 100.0),
            (12, 0.2, 0.0),
        ];
        let h: Vec<Harmonic> = terms
            .iter()
            .map(|&(h, a, p)| Harmonic::from_arcsec_deg(h, a, p))
            .collect();
        FourierSeries::from_harmonics(&h, 12)
    }

    fn heads(deg: &[f64]) -> Vec<Head> {
        deg.iter()
            .enumerate()
            .map(|(j, d)| Head {
                name: format!("h{}", j + 1),
                nominal: d.to_radians(),
            })
            .collect()
    }

    /// `per_rev·revs` noise-free samples of heads at `deg` with angle errors `err` (arcsec), each
    /// reading `s + e(s)` at its scale position `s`, less its nominal angle unless `raw`.
    fn feed(mh: &mut Multihead, deg: &[f64], err: &[f64], raw: bool, per_rev: usize, revs: f64) {
        let e = scale();
        let mut r = vec![0.0; deg.len()];
        for k in 0..(per_rev as f64 * revs) as usize {
            let theta = TAU * k as f64 / per_rev as f64 + 0.1234;
            for j in 0..deg.len() {
                let alpha = deg[j].to_radians();
                let s = theta + alpha + err[j] * ARCSEC;
                r[j] = s + e.eval(s) - if raw { 0.0 } else { alpha };
            }
            mh.push(&r);
        }
    }

    fn calibrate(opts: MultiheadOptions, raw: bool) -> MultiheadCalibration {
        let mut mh = Multihead::new(heads(&DEG), opts).unwrap();
        feed(&mut mh, &DEG, &ERR, raw, 2400, 2.0);
        mh.finish().unwrap()
    }

    /// The first head's map: `x − θ` with `θ + e(θ) = x`, on `points` readings `x`.
    fn truth(points: usize) -> ErrorMap {
        let e = scale();
        ErrorMap::new(
            (0..points)
                .map(|i| {
                    let x = TAU * i as f64 / points as f64;
                    let mut th = x;
                    for _ in 0..5 {
                        let de: f64 = (1..=12)
                            .map(|h| {
                                let hf = h as f64;
                                hf * (e.sin[h - 1] * (hf * th).cos()
                                    - e.cos[h - 1] * (hf * th).sin())
                            })
                            .sum();
                        th -= (th + e.eval(th) - x) / (1.0 + de);
                    }
                    x - th
                })
                .collect(),
        )
    }

    /// Amplitude of order `h` in a series, arcsec.
    fn amplitude(s: &FourierSeries, h: usize) -> f64 {
        s.cos[h - 1].hypot(s.sin[h - 1]) * ARCSEC_PER_RAD
    }

    fn opts(method: Method) -> MultiheadOptions {
        MultiheadOptions {
            method,
            max_order: Some(16),
            ..MultiheadOptions::default()
        }
    }

    #[test]
    fn joint_recovers_the_map_and_the_head_angles() {
        let cal = calibrate(opts(Method::Joint), false);
        // Every head is at a multiple of 30°: order 12 is blind, and named.
        let blind: Vec<usize> = cal.blind.iter().map(|e| e.order).collect();
        assert_eq!(blind, [12]);
        assert!(cal.ill_conditioned.is_empty());
        // The truth without its (unobservable) order 12; noise-free, so only the method's own
        // error remains: 10⁻⁴″ is far above rounding and far below any harmonic.
        let mut expected = truth(3600).series();
        expected.cos[11] = 0.0;
        expected.sin[11] = 0.0;
        let got = ErrorMap::from_series(&cal.series, 3600);
        let err = ErrorMap::from_series(&expected, 3600)
            .minus(&got)
            .max_abs_arcsec();
        assert!(err < 1e-4, "{err}″");
        for (h, want) in cal.heads.iter().zip(ERR) {
            let got = h.angle_error * ARCSEC_PER_RAD;
            assert!((got - want).abs() < 1e-4, "{}: {got}″ vs {want}″", h.name);
        }
        assert_eq!(cal.heads[1].readings, Some(Readings::RelativeToNominal));
        assert!(cal.residual_rms.unwrap() * ARCSEC_PER_RAD < 1e-4);
        assert!(cal.warnings.is_empty(), "{:?}", cal.warnings);
    }

    #[test]
    fn eda_is_blind_to_multiples_of_its_head_count_and_the_joint_method_is_not() {
        let set4 = MultiheadOptions {
            sets: Some(vec![vec![0, 1, 2, 3]]),
            ..opts(Method::Eda)
        };
        let eda4 = calibrate(set4, false);
        let joint = calibrate(opts(Method::Joint), false);
        let blind: Vec<usize> = eda4.blind.iter().map(|e| e.order).collect();
        assert_eq!(blind, [4, 8, 12, 16]);
        for (h, truth) in [(3, 1.0), (4, 0.5), (5, 0.4), (8, 0.3)] {
            // The joint method sees every order but 12 ...
            assert!(
                (amplitude(&joint.series, h) - truth).abs() < 1e-4,
                "joint {h}"
            );
            // ... EDA with 4 heads only the orders 4 does not divide.
            let eda = amplitude(&eda4.series, h);
            let want = if h % 4 == 0 { 0.0 } else { truth };
            assert!((eda - want).abs() < 1e-3, "EDA order {h}: {eda}″");
        }
        // Eq. 9 itself gives (nearly) nothing at the multiples of 4: 1 − (1/N)Σe^{ihψ_j} ≈ h·δ.
        assert!(amplitude(&eda4.sets[0].series, 4) < 1e-3);
        assert!(amplitude(&eda4.sets[0].series, 8) < 1e-3);

        // With both sets inferred, each order one set misses comes from the other; only the
        // multiples of lcm(3, 4) = 12 stay blind.
        let both = calibrate(opts(Method::Eda), false);
        let sets: Vec<Vec<usize>> = both.sets.iter().map(|s| s.heads.clone()).collect();
        assert_eq!(sets, [vec![0, 4, 5], vec![0, 1, 2, 3]]);
        let blind: Vec<usize> = both.blind.iter().map(|e| e.order).collect();
        assert_eq!(blind, [12]);
        for (h, truth) in [(3, 1.0), (4, 0.5), (5, 0.4), (8, 0.3)] {
            assert!((amplitude(&both.series, h) - truth).abs() < 1e-3, "{h}");
        }
    }

    #[test]
    fn raw_scale_readings_give_the_same_result() {
        let relative = calibrate(opts(Method::Joint), false);
        let raw = calibrate(opts(Method::Joint), true);
        assert_eq!(raw.heads[3].readings, Some(Readings::Raw));
        let d = relative.map.minus(&raw.map).max_abs_arcsec();
        assert!(d < 1e-6, "{d}″");
        for (a, b) in relative.heads.iter().zip(&raw.heads) {
            assert!((a.angle_error - b.angle_error).abs() * ARCSEC_PER_RAD < 1e-6);
        }
    }

    #[test]
    fn selfa_sets_are_inferred_from_equal_spacing() {
        let step = 360.0 / 7.0;
        // Heads numbered as in the paper: 1, 5, 9 at 120° steps; 1, 3, 7, 11 at 90°; 1, 2, 4, …
        // 12 at 360°/7 (angles as a user types them, to 6 decimals).
        let mut deg = [0.0; 12];
        for (k, j) in [0, 4, 8].into_iter().enumerate() {
            deg[j] = 120.0 * k as f64;
        }
        for (k, j) in [0, 2, 6, 10].into_iter().enumerate() {
            deg[j] = 90.0 * k as f64;
        }
        for (k, j) in [0, 1, 3, 5, 7, 9, 11].into_iter().enumerate() {
            deg[j] = (step * k as f64 * 1e6).round() / 1e6;
        }
        let rel: Vec<f64> = deg.iter().map(|d| d.to_radians()).collect();
        let sets = infer_sets(&rel, 0.01f64.to_radians());
        assert_eq!(
            sets,
            [vec![0, 4, 8], vec![0, 2, 6, 10], vec![0, 1, 3, 5, 7, 9, 11]]
        );
    }

    #[test]
    fn bad_heads_and_sets_are_errors() {
        let new = |deg: &[f64], opts: MultiheadOptions| Multihead::new(heads(deg), opts).err();
        let eda = |sets: Vec<Vec<usize>>| MultiheadOptions {
            method: Method::Eda,
            sets: Some(sets),
            ..MultiheadOptions::default()
        };
        assert!(matches!(
            new(&[0.0], MultiheadOptions::default()),
            Some(MultiheadError::TooFewHeads { found: 1 })
        ));
        let mut twice = heads(&[0.0, 90.0, 180.0]);
        twice[2].name = "h2".into();
        assert!(matches!(
            Multihead::new(twice, MultiheadOptions::default()).err(),
            Some(MultiheadError::DuplicateHead { name }) if name == "h2"
        ));
        assert!(matches!(
            new(&[0.0, f64::NAN], MultiheadOptions::default()),
            Some(MultiheadError::NonFiniteAngle { .. })
        ));
        assert!(matches!(
            new(&[0.0, 100.0], opts(Method::Eda)),
            Some(MultiheadError::NoEquallySpacedSet { .. })
        ));
        assert!(matches!(
            new(&DEG, eda(vec![vec![0, 1, 4]])),
            Some(MultiheadError::SetNotEquallySpaced { head, count: 3, .. }) if head == "h2"
        ));
        assert!(matches!(
            new(&DEG, eda(vec![vec![1, 3]])),
            Some(MultiheadError::SetWithoutFirstHead { .. })
        ));
        assert!(matches!(
            new(&DEG, eda(vec![vec![0]])),
            Some(MultiheadError::SetTooSmall { .. })
        ));
        assert!(matches!(
            new(&DEG, eda(vec![vec![0, 2, 2]])),
            Some(MultiheadError::DuplicateHead { .. })
        ));
        assert!(matches!(
            new(&DEG, eda(vec![vec![0, 9]])),
            Some(MultiheadError::Options(_))
        ));
        let bins = MultiheadOptions {
            bins_per_rev: 1000,
            ..MultiheadOptions::default()
        };
        assert!(matches!(new(&DEG, bins), Some(MultiheadError::Options(_))));
    }

    #[test]
    fn bad_data_are_errors_not_panics() {
        let run = |deg_declared: &[f64], deg_true: &[f64], per_rev: usize, revs: f64, opts| {
            let mut mh = Multihead::new(heads(deg_declared), opts).unwrap();
            feed(&mut mh, deg_true, &ERR, false, per_rev, revs);
            mh.finish().err()
        };
        let deg = &DEG[..3];
        assert!(matches!(
            Multihead::new(heads(deg), MultiheadOptions::default())
                .unwrap()
                .finish()
                .err(),
            Some(MultiheadError::NoSamples { skipped: 0 })
        ));
        let half = run(deg, deg, 2400, 0.5, MultiheadOptions::default());
        match half {
            Some(MultiheadError::NotCovered { gap_deg, .. }) => {
                assert!((gap_deg - 180.0).abs() < 0.5, "{gap_deg}")
            }
            other => panic!("{other:?}"),
        }
        let too_high = MultiheadOptions {
            max_order: Some(200),
            ..MultiheadOptions::default()
        };
        assert!(matches!(
            run(deg, deg, 400, 2.0, too_high),
            Some(MultiheadError::TooFewSamplesPerRevolution {
                requested: 200,
                needed: 800,
                available: 256
            })
        ));
        // A head declared at 60° that sits at 120°, reading raw scale angles: its mean difference
        // is neither 0 nor 60°.
        let mut mh =
            Multihead::new(heads(&[0.0, 60.0, 180.0]), MultiheadOptions::default()).unwrap();
        feed(&mut mh, &[0.0, 120.0, 180.0], &ERR, true, 2400, 1.5);
        assert!(matches!(
            mh.finish().err(),
            Some(MultiheadError::HeadAngleMismatch { head, .. }) if head == "h2"
        ));
        // Reading relative to its nominal angle, the same head shows only in the fit's residual.
        let mut mh = Multihead::new(heads(&[0.0, 60.0, 180.0]), opts(Method::Joint)).unwrap();
        feed(&mut mh, &[0.0, 120.0, 180.0], &ERR, false, 2400, 1.5);
        let cal = mh.finish().unwrap();
        assert!(
            cal.warnings
                .iter()
                .any(|w| w.contains("head `h2` disagrees")),
            "{:?}",
            cal.warnings
        );
        // A head counting the other way round.
        let mut mh = Multihead::new(heads(deg), MultiheadOptions::default()).unwrap();
        for k in 0..3000 {
            let th = TAU * k as f64 / 2000.0;
            mh.push(&[th, -th, th]);
        }
        assert!(matches!(
            mh.finish().err(),
            Some(MultiheadError::NotFollowing { head, .. }) if head == "h2"
        ));
        // Non-finite readings are skipped and counted.
        let mut mh = Multihead::new(heads(deg), opts(Method::Joint)).unwrap();
        mh.push(&[f64::NAN, 0.0, 0.0]);
        feed(&mut mh, deg, &ERR, false, 2400, 1.5);
        let cal = mh.finish().unwrap();
        assert_eq!(cal.skipped, 1);
        assert!(cal.warnings[0].contains("skipped"), "{:?}", cal.warnings);
    }

    #[test]
    fn the_largest_gap_is_found_across_zero() {
        let mut count = vec![1u32; 360];
        for i in (350..360).chain(0..5) {
            count[i] = 0;
        }
        let (gap, at) = largest_gap(&count);
        assert!((gap.to_degrees() - 15.0).abs() < 1e-9);
        assert!(
            (at.to_degrees() - 357.5).abs() < 1e-9,
            "{}",
            at.to_degrees()
        );
    }
}
