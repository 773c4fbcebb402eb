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

mod bins;
mod eda;
mod error;
mod joint;
#[cfg(test)]
mod tests;
mod uncertainty;

pub use error::MultiheadError;
pub use joint::joint_weights;
pub use uncertainty::order_variance;

use crate::angle::{Travel, wrap_2pi, wrap_pi};
use crate::detection::{self, Verdict};
use crate::error_map::ErrorMap;
use crate::harmonics::FourierSeries;
use crate::uncertainty::MapUncertainty;
use bins::Binned;
use bins::largest_gap;
use eda::{check_set, eda, eda_weights, infer_sets};
use joint::{JointFit, Residual, joint, series_of};
use std::f64::consts::{PI, TAU};
use uncertainty::{map_uncertainty, order_variances};

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
    /// The first head's extent, for [`MultiheadError::NoWholeTurn`].
    first: Travel,
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
            first: Travel::new(),
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
        self.first.push(r1);
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

    /// Solves, once every sample is in: checks that the heads follow the first, recognizes each
    /// head's reading convention, chooses the grid and the orders, fits, and describes the
    /// result (each a step below). If that fails for a first head that moved but never turned
    /// a whole revolution, the error is [`MultiheadError::NoWholeTurn`].
    pub fn finish(self) -> Result<MultiheadCalibration, MultiheadError> {
        let turn = self.first.partial_turn(
            "multi-head self-calibration needs the scale to turn whole revolutions past the heads",
        );
        self.solve().map_err(|e| match turn {
            Some(turn) => MultiheadError::NoWholeTurn {
                turn,
                cause: Box::new(e),
            },
            None => e,
        })
    }

    fn solve(self) -> Result<MultiheadCalibration, MultiheadError> {
        self.check_following()?;
        let (readings, base) = self.conventions()?;
        let (bins, max_order) = self.grid()?;
        let data = self.merge(bins, &base);
        let fit = joint(&data, &self.rel[1..], max_order, &self.opts)?;

        let mut warnings = self.fit_warnings(&fit, &readings);
        let mut orders = self.orders(&data, &fit, max_order);
        let screen = self.screen(&fit, &orders, max_order);
        if screen.kept == 0 {
            // Nothing stands above the noise: the map is zero, within its floor.
            orders.series = FourierSeries::zeros(max_order);
        }
        let points = self
            .opts
            .points
            .unwrap_or_else(|| crate::csrr::table_points(&orders.series));
        let map = ErrorMap::from_series(&orders.series, points);
        let u_fit = screen.variances.iter().sum::<f64>().max(0.0).sqrt();
        let floor = detection::detection_floor(screen.detection_limit);
        let uncertainty = map_uncertainty(self.opts.method, u_fit, floor, &orders.series, points);
        if screen.kept == 0 {
            warnings.push(detection::empty_map_warning(
                uncertainty.max(),
                &format!("1–{max_order}"),
                screen.detection_limit,
            ));
        }
        let heads = self.head_estimates(&fit, &readings);
        warnings.extend(misfits(&heads, &fit.residuals, bins));
        let (residual, noise) = self.residual_and_noise(&fit);
        match detection::residual_verdict(residual, noise, screen.kept > 0) {
            Verdict::Explained => {}
            Verdict::Above(ratio) => warnings.push(detection::residual_warning(
                residual,
                noise,
                ratio,
                "the differences to the first head scatter within the bins by",
                "the map and the head angles do",
                "the scale's error above the highest order fitted, or a head not where the `heads` option says",
            )),
            Verdict::Unexplained(_) => {
                return Err(MultiheadError::Unexplained {
                    residual_arcsec: residual * crate::angle::ARCSEC_PER_RAD,
                    noise_arcsec: noise * crate::angle::ARCSEC_PER_RAD,
                });
            }
        }
        Ok(MultiheadCalibration {
            method: self.opts.method,
            map,
            series: orders.series,
            heads,
            max_order,
            bins,
            blind: orders.blind,
            ill_conditioned: orders.ill_conditioned,
            sets: orders.sets,
            residual_rms: orders.residual_rms,
            uncertainty,
            iterations: fit.iterations,
            samples: self.samples,
            skipped: self.skipped,
            revolutions: self.travel / TAU,
            warnings,
        })
    }

    /// Refuses a log without samples, and heads whose difference to the first head changes by
    /// more than [`MultiheadOptions::head_tol`] (not the same scale).
    fn check_following(&self) -> Result<(), MultiheadError> {
        if self.samples == 0 {
            return Err(MultiheadError::NoSamples {
                skipped: self.skipped,
            });
        }
        for j in 0..self.heads.len() - 1 {
            let change = self.d_max[j] - self.d_min[j];
            if change > self.opts.head_tol {
                return Err(MultiheadError::NotFollowing {
                    head: self.heads[j + 1].name.clone(),
                    first: self.heads[0].name.clone(),
                    change_deg: change.to_degrees(),
                    tol_deg: self.opts.head_tol.to_degrees(),
                });
            }
        }
        Ok(())
    }

    /// Each other head's reading convention, from its mean difference to the first head, and the
    /// base added to its bin means (its first difference, less the nominal angle for raw
    /// readings).
    fn conventions(&self) -> Result<(Vec<Readings>, Vec<f64>), MultiheadError> {
        let others = self.heads.len() - 1;
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
        Ok((readings, base))
    }

    /// The uniform bins every bin of which holds samples, and the highest order fitted (given,
    /// or from the samples per revolution; see the module doc's section on sampling).
    fn grid(&self) -> Result<(usize, usize), MultiheadError> {
        let bins = self.uniform_bins().ok_or_else(|| {
            let (gap, at) = largest_gap(&self.count);
            MultiheadError::NotCovered {
                first: self.heads[0].name.clone(),
                gap_deg: gap.to_degrees(),
                at_deg: at.to_degrees(),
            }
        })?;
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
                let per_rev = self.samples as f64 / (self.travel / TAU).max(1.0);
                ((0.4 * per_rev).floor() as usize).clamp(1, (bins / 4).min(2000))
            }
        };
        Ok((bins, max_order))
    }

    /// Warnings about the samples and the solve: skipped samples, a solve that did not
    /// converge, heads of both reading conventions.
    fn fit_warnings(&self, fit: &JointFit, readings: &[Readings]) -> Vec<String> {
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
                 (try a lower `max_order` option)",
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
        warnings
    }

    /// The map's series and the orders left out, by the chosen method: the joint fit's own, its
    /// excluded orders split into blind (every head's nominal angle on a multiple of `360°/h`)
    /// and ill-conditioned; or eq. 9 per set, combined.
    fn orders(&self, data: &Binned, fit: &JointFit, max_order: usize) -> Orders {
        match self.opts.method {
            Method::Joint => {
                let structurally_blind = |h: usize| {
                    self.rel
                        .iter()
                        .all(|&p| wrap_pi(h as f64 * p).abs() <= h as f64 * self.opts.angle_tol)
                };
                let (blind, ill_conditioned): (Vec<ExcludedOrder>, Vec<ExcludedOrder>) = fit
                    .excluded
                    .iter()
                    .partition(|e| structurally_blind(e.order));
                let sum: f64 = fit.residuals.iter().map(|r| r.between + r.within).sum();
                let others = self.heads.len() - 1;
                let rms = (sum / (self.samples as f64 * others as f64)).sqrt();
                Orders {
                    series: series_of(&fit.s),
                    blind,
                    ill_conditioned,
                    sets: Vec::new(),
                    residual_rms: Some(rms),
                }
            }
            Method::Eda => {
                let (series, sets, blind) = eda(data, fit, &self.sets, max_order);
                Orders {
                    series,
                    blind,
                    ill_conditioned: Vec::new(),
                    sets,
                    residual_rms: None,
                }
            }
        }
    }

    /// The significance screening of the map's orders: the variance each fitted order adds to
    /// the map (with the heads' estimated angles, [`order_variances`]), how many stand above
    /// the noise by the rule of [`crate::detection`] (`(a_h² + b_h²)/v_h > 2·ln(M/α)`, `M` the
    /// orders fitted, [`crate::tdr::significance_threshold`]), and the detection limit.
    fn screen(&self, fit: &JointFit, orders: &Orders, max_order: usize) -> Screen {
        let others = self.heads.len() - 1;
        let excluded: Vec<usize> = orders
            .blind
            .iter()
            .chain(&orders.ill_conditioned)
            .map(|e| e.order)
            .collect();
        let fitted: Vec<usize> = (1..=max_order).filter(|h| !excluded.contains(h)).collect();
        let psi: Vec<f64> = self.rel[1..]
            .iter()
            .zip(&fit.delta)
            .map(|(p, d)| p + d)
            .collect();
        let weights = |h: usize| match self.opts.method {
            Method::Joint => joint_weights(h, &psi),
            Method::Eda => eda_weights(h, &self.sets, others),
        };
        let unknowns = 2 * fitted.len() + others;
        let variances = order_variances(&fit.bin_residuals, unknowns, &fitted, weights);
        let threshold = crate::tdr::significance_threshold(fitted.len());
        let s = &orders.series;
        let kept = fitted
            .iter()
            .zip(&variances)
            .filter(|&(&h, &v)| {
                let x = s.cos[h - 1].powi(2) + s.sin[h - 1].powi(2);
                // v = 0 (noise-free data): every order stands above the noise.
                v <= 0.0 || x > threshold * v
            })
            .count();
        let v_min = variances
            .iter()
            .copied()
            .filter(|&v| v > 0.0)
            .fold(f64::INFINITY, f64::min);
        Screen {
            variances,
            kept,
            detection_limit: detection::detection_limit(threshold, v_min),
        }
    }

    /// The joint fit's residual RMS per sample over all differences, and the noise figure it
    /// is judged against: the differences' scatter within the bins (net of the model's slope,
    /// pooled over the heads), radians per sample.
    fn residual_and_noise(&self, fit: &JointFit) -> (f64, f64) {
        let others = self.heads.len() - 1;
        let sum: f64 = fit.residuals.iter().map(|r| r.between + r.within).sum();
        let residual = (sum / (self.samples as f64 * others as f64)).sqrt();
        let (within, dof) = fit
            .residuals
            .iter()
            .fold((0.0, 0.0), |(w, d), r| (w + r.within, d + r.dof));
        let noise = if dof > 0.0 {
            (within / dof).sqrt()
        } else {
            residual
        };
        (residual, noise)
    }

    /// Every head with its estimated angle error, reading convention, residual and noise.
    fn head_estimates(&self, fit: &JointFit, readings: &[Readings]) -> Vec<HeadEstimate> {
        let n_all = self.samples as f64;
        self.heads
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
            .collect()
    }
}

/// The significance screening of a fit's orders (see [`Multihead::screen`]).
struct Screen {
    /// The variance each fitted order adds to the map, rad².
    variances: Vec<f64>,
    /// Orders standing above the noise.
    kept: usize,
    /// The detection limit of the orders tested, an amplitude, rad.
    detection_limit: f64,
}

/// The map's series and what was left out of it, by method (see [`Multihead::finish`]).
struct Orders {
    series: FourierSeries,
    blind: Vec<ExcludedOrder>,
    ill_conditioned: Vec<ExcludedOrder>,
    sets: Vec<SetEstimate>,
    residual_rms: Option<f64>,
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
                     {:.4}″; check its angle in the `heads` option (and the `max_order` option, if the scale has higher orders)",
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
