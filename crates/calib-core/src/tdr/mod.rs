//! Self-calibration of one encoder from a free spin-down (coast-down), in the manner of the
//! time-measurement dynamic reversal (TDR) method of Lu & Trumper, "Self-calibration of on-axis
//! rotary encoders" (CIRP Annals 56(1), 2007 — the CSRR paper's reference list dates it 2009;
//! US patent 7,840,372), the method the CSRR paper (Gou et al., reference \[24\], Tables II and
//! IV) compares against.
//!
//! # Principle
//! The shaft is spun up, released, and coasts: nothing but its own friction acts on it, so its
//! true angle `θ(t)` is a smooth function of time. The encoder reads `r = θ + e(θ)`, i.e.
//! `θ = r − E(r)` with `E` the error as a function of the reading (the interface's map). Hence
//!
//! `r_n = θ(t_n) + E(r_n) + noise`,    `E(r) = Σ_{k=1..H} a_k cos kr + b_k sin kr`     (1)
//!
//! is **linear** in the unknowns — the motion's parameters and the `2H` Fourier coefficients —
//! and is solved by one linear least-squares fit (normal equations and Cholesky; no
//! Gauss–Newton is needed). Circular closure fixes the gauge: `E` is
//! periodic and has no constant term (the constant goes into the motion), so it is the zero-mean
//! map of the interface.
//!
//! # Motion model and separability
//! `θ(t)` is a Chebyshev series `Σ_{j=0..p} c_j T_j(τ)` in the normalized time
//! `τ = (2t − t₀ − t₁)/(t₁ − t₀) ∈ [−1, 1]` over the coast `[t₀, t₁]`. Why a polynomial and not
//! the friction ODE's closed form: the friction law is not known in advance (Coulomb, viscous,
//! aerodynamic, or mixtures), and any such solution is analytic in `t`, so its Chebyshev
//! coefficients fall geometrically — degree 10–25 reaches the 1e-9 rad level for coasts that lose
//! up to about two thirds of their speed, and keeps the fit linear. The degree is chosen by the
//! Bayesian information criterion `N ln(RSS/N) + n_params ln N` from 2 up to
//! `min(30, revolutions/2)` (or set by [`TdrOptions::motion_degree`]).
//!
//! Motion and error separate because the error is periodic in **angle** while the motion is
//! smooth in **time**: at falling speed `ω(t)` an order-`k` error is the chirp
//! `cos(kθ(t))`, with `k·(revolutions)` oscillations whose frequency sweeps as the speed falls,
//! and a degree-`p` polynomial (at most `p − 1` extrema) cannot follow it while
//! `p ≪ k·revolutions`. Hence the floor of 10 revolutions and the degree cap of
//! `revolutions/2` (order 1 then makes ≥ 2 oscillations per polynomial degree).
//!
//! # Which orders: chosen from the data
//! The highest order tested defaults to [`ORDERS_PER_SAMPLE`] of the samples per revolution
//! where the coast is slowest (its densest sampling): the slow end resolves orders far above the
//! fast start's, and since the speed sweeps, the sample positions do not repeat from revolution
//! to revolution, so an order above one speed's Nyquist limit is still determined by the whole
//! coast. Every order up to it is fitted (with the motion at its highest degree), and an order
//! is kept when its coefficients `x = (a_k, b_k)` stand above the noise by the **significance
//! rule** `xᵀC⁻¹x > 2·ln(M/α)`, `C = σ²·[(AᵀA)⁻¹]_kk` their covariance from the fit, `M` the
//! orders tested and `α` = [`FALSE_ORDER_PROBABILITY`]: for noise alone the chance that any
//! order passes is below `α`. The map holds only the kept orders, so asking for many orders
//! costs computing time (a dense factor of `2H` columns), not accuracy. After the final fit, the residual is projected on
//! the orders above the highest tested (to half the densest samples per revolution, at least
//! `2H`): orders there that pass the same rule are reported in
//! [`TdrCalibration::unresolved`] and warned about with their amplitude.
//!
//! # Angle-dependent drag, and its separation
//! If a torque that depends on the angle acts on the coasting shaft — rolling-element bearings,
//! motor cogging, an unbalanced rotor — its motion is no longer smooth in time. With the
//! deceleration `ω̇ = −F(ω) − Σ a_h cos(hθ + φ_h)` and `θ = θ₀ + δ`, `θ₀` the smooth coast,
//! `δ̈ ≈ −a_h cos(hθ₀ + φ_h)`; for `hω ≫ F′(ω)` and a slowly varying `ω` this gives
//!
//! `δ(t) ≈ a_h/(h·ω(t))² · cos(hθ₀ + φ_h)`                                                (2)
//!
//! — periodic in angle like an encoder error, added to it in (1). A least-squares fit with
//! constant coefficients takes its mean over the samples (uniform in time): the map's order `h`
//! would be off by `a_h/h² · ⟨ω⁻²⟩` ([`TdrCalibration::drag_gain`] `= ⟨ω⁻²⟩`). This is why the
//! CSRR paper finds TDR inaccurate on rolling bearings (its Table IV: > 56″ off).
//!
//! What separates them is speed: the encoder's error is the same at every speed, the drag's
//! imprint scales as `ω⁻²`, and a coast sweeps `ω`. Writing `δ = Re[f(t)·e^{i(hθ₀+φ_h)}]` in
//! `δ̈ = −a_h cos(hθ₀ + φ_h)` and expanding `f` in `ω̇/(hω²)` gives the next term of (2):
//!
//! `δ = Re[D_h·(w − i·v/h)·e^{ihθ}]`,  `w = ω⁻²/⟨ω⁻²⟩`,  `v = 3ω̇/(ω⁴⟨ω⁻²⟩)`,
//! `D_h = a_h e^{iφ_h}/h² · ⟨ω⁻²⟩`                                                          (3)
//!
//! (`ω`, `ω̇` signed, from the screening fit's motion). With `D_h = p − iq` this is linear in
//! `(p, q)`: two more columns per drag order, `w·cos hr + (v/h)·sin hr` and
//! `w·sin hr − (v/h)·cos hr` (`r` for `θ`: the difference is `h·e·δ`, below 1e-3 of `δ`). Drag
//! orders `1..=`[`TdrOptions::max_drag_order`] are fitted jointly with the map's kept orders,
//! the significant ones (same rule, and an imprint `|D_h|` ≥ [`MATERIAL_ARCSEC`]) kept in the
//! final fit and reported in [`TdrCalibration::drag`] with `a_h = |D_h|·h²/⟨ω⁻²⟩`. What (3)
//! neglects is `O(F′(ω)/(hω))` of the imprint (0.2 % at 120 r/min for air shear) and
//! `O((ω̇/(hω²))²)`.
//!
//! The separation costs noise: at a drag order the map's coefficients are uncertain by
//! `√(1 + 1/cv²)` times more, `cv` the relative RMS variation of `1/ω²` over the coast
//! ([`DragSeparation`]). Above a factor 10 ([`MAX_DRAG_VARIANCE_INFLATION`]) the coast is
//! taken as inseparable: the map keeps the drag (eq. 2), a warning says how far the shaft must
//! coast down, and the drag fit serves as a diagnostic: orders with a significant imprint are
//! reported in [`TdrCalibration::speed_dependence`] and warned about. Real bearing drag is not
//! strictly periodic in shaft angle (balls and cage turn at non-integer orders): what (3) cannot
//! fit stays in the residual, whose periodic structure is checked as above.
//!
//! # Driven runs
//! Nothing in (1) needs the shaft to coast: a motor driving it at constant voltage, its inertia
//! keeping the speed smooth (mjbots moteus' "inertial" encoder calibration: ~300 r/min for
//! ~20 s), moves it just as smoothly in time, and the fit is the same. What changes is the
//! torque that is periodic in angle: the motor's cogging and torque ripple, at its orders
//! `k·6·p` for `p` pole pairs ([`MotorOrders`]), shake the shaft by eq. (2) at every speed, and
//! at one steady speed `ω⁻²` does not vary, so eq. (3) cannot separate them (nor any other
//! angle-dependent drag; the drag fit is not tried). A driven run is found as **passes**:
//! stretches of whole revolutions whose mean speeds change by at most [`STEADY_CHANGE`] from
//! one to the next (a spin-up's tail included, a voltage step or a release excluded), each of
//! at least [`TdrOptions::min_revolutions`]. Each pass is fitted on its own (its own motion, the motor's
//! orders always in the fit), and
//!
//! - **at one speed** the motor's orders are named and **left out of the map**: their fitted
//!   coefficients (encoder error and shake together) are reported
//!   ([`DrivenRun::motor_orders`]), and the map's `u` gains their RMS `√Σ(A_k²/2 + σ_k²)` — what
//!   the map may miss there, assuming the encoder's error and the shake do not cancel;
//! - **at two or more speeds** each motor order's coefficient `c_s` in pass `s` is
//!   `e_k + D_k·g_s`, `g_s = ⟨ω⁻²⟩` over the pass and `D_k = a_k e^{iφ_k}/k²` (eq. 2): a
//!   weighted straight line in `g` (weights the inverse variances) gives the encoder's `e_k`,
//!   put **into the map** with its `u`, and the deceleration `a_k`. As for a coast (eq. 3),
//!   separating costs noise, by `√VIF` with `VIF = W·Σw g²/(W·Σw g² − (Σw g)²)`; above
//!   [`MAX_DRAG_VARIANCE_INFLATION`] (passes at too close speeds) the order is treated as at one
//!   speed. The rest of the map is the longest pass's, less the shake's sidebands: the shake
//!   is periodic in the true angle `r − E(r)`, so in the reading it also holds `−E·δ′` at the
//!   orders `k ± m` of the map's own orders `m`, which the fit took for encoder error there and
//!   the separated shake gives back (to first order in `E`).
//!
//! With [`RunKind::Auto`] (the default) a log is a coast when it holds one (as before driven
//! runs were accepted: a plateau before the release is skipped), else a driven run.
//!
//! # Other limits
//! No absolute offset (the gauge); orders above [`TdrCalibration::max_order`] are not modelled
//! (the residual check names them). A log with neither a coast nor a steady pass of enough
//! revolutions is refused ([`TdrError`]).
//!
//! # Streaming, and the cost of the fit
//! [`Tdr::push`] keeps of each sample only its time and unwrapped reading (16 bytes; 24 with a
//! reference channel; 160 MB for 10 million samples): the log itself is not kept. The fits do
//! not pass over the samples: every entry of their normal equations is a combination of two
//! spectra of the samples, `Σ_n e^{i(jφ_n + mr_n)}` and the same weighted by the readings,
//! `φ = arccos τ` (the `moments` module has the algebra), which one two-dimensional
//! non-uniform FFT gives ([`crate::nufft2d`]). Ten million samples cost one such pass and one
//! more for the residual's structure (above: the residuals spread onto a uniform grid with the
//! 6-point weights of CSRR's solver, exact to ~10⁻⁸ of `Σ|e|`, what a significance test against
//! the noise can use); each fit then costs `O(n²)` for its `n` columns and a Cholesky factor
//! (`nalgebra`'s arithmetic in panels of columns on the rayon pool, the `cholesky` module).
//! Both passes use two threads where rayon has them and sum in a fixed order, so the results
//! are the same bits on any number of threads; the readings' noise is measured beside the
//! screening's factorization, and the coast's trace (its intervals each in order) beside the
//! residual's pass.

use crate::angle::{ARCSEC_PER_RAD, PartialTurn, Unwrapper};
use crate::detection::{self, Verdict};
use crate::error_map::ErrorMap;
use crate::harmonics::{FourierSeries, Harmonic};
use crate::uncertainty::{Evaluation, MapComponent, MapUncertainty, interpolation_uncertainty};
use chebyshev::chebyshev_with_derivatives;
use moments::{Moments, Normal, Samples, preliminary_motion};
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use residual::{reference_check, residual_and_trace};
use std::f64::consts::TAU;

mod chebyshev;
mod cholesky;
mod driven;
mod moments;
mod residual;

pub use driven::{
    DrivenPass, DrivenRun, MotorOrder, MotorOrders, PassMeasurement, RunKind, STEADY_CHANGE,
    Separated,
};
use driven::{MotorMeasure, find_passes};

/// The statement of what a spin-down calibration cannot separate, for reports.
pub const DRAG_AMBIGUITY: &str = "An angle-dependent drag torque (rolling-element bearings, motor cogging, unbalance) decelerating the shaft by a_h·cos(hθ+φ) shakes it by a_h/(h·ω)² at order h, periodic in angle like the encoder's error. TDR separates the two by their speed dependence (the drag's imprint grows as 1/ω², the encoder's error does not) when the coast sweeps the speed widely enough (1/ω² varying by ≥ 10 % RMS); otherwise the map's order h absorbs a_h/h²·⟨ω⁻²⟩. Drag not periodic in shaft angle (ball and cage orders) is not separated: check the map against a reference (the `ref` option) on rolling bearings.";

/// The statement of what a driven run cannot separate, for reports.
pub const DRIVEN_AMBIGUITY: &str = "At a steady speed a torque periodic in angle (the motor's cogging and torque ripple at its orders k·6·pole pairs, rolling bearings, unbalance) shakes the shaft by a_h/(h·ω)² at order h, periodic in angle like the encoder's error and, at one speed, not to be told from it. The motor's named orders are left out of the map (listed with what was measured there, and covered by the map's u) unless passes at two or more speeds separate them by the 1/ω² dependence of the shake; at other orders any such shake stays in the map.";

/// Settings of a spin-down calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct TdrOptions {
    /// Highest order of the error map tested; `None` (default): what the coast resolves,
    /// [`ORDERS_PER_SAMPLE`] of the samples per revolution at its slowest (densest) end, at most
    /// [`MAX_DEFAULT_ORDER`]. Only the orders that pass the significance rule (module docs) are
    /// kept, so a high limit costs computing time, not accuracy.
    pub max_order: Option<usize>,
    /// Highest order of angle-dependent drag tested for (default 16; 0 turns the separation
    /// off). The drag's imprint falls as `1/h²`, so high orders rarely matter.
    pub max_drag_order: usize,
    /// Degree of the motion's Chebyshev series; `None` (default) chooses it by BIC.
    pub motion_degree: Option<usize>,
    /// Grid points of the map; `None` (default): enough for linear interpolation between them to
    /// err by at most 0.01″ ([`crate::csrr::table_points`], at least 3600), as CSRR's and
    /// multi-head's maps, which are sums of harmonics too.
    pub points: Option<usize>,
    /// Fewest revolutions of coast accepted (default 10).
    pub min_revolutions: f64,
    /// The coast ends where the speed falls below this fraction of its peak (default 0.1): at
    /// low speed drag effects (2) grow as ω⁻², and a shaft coming to rest stops abruptly.
    pub min_speed_fraction: f64,
    /// What the log holds: a coast, a driven run, or whichever is there (default
    /// [`RunKind::Auto`]; module docs, "Driven runs").
    pub run: RunKind,
    /// The motor's orders (cogging, torque ripple) of a driven run, named in the result and
    /// left out of the map or separated by speed (default none).
    pub motor: MotorOrders,
}

impl Default for TdrOptions {
    fn default() -> Self {
        TdrOptions {
            max_order: None,
            max_drag_order: 16,
            motion_degree: None,
            points: None,
            min_revolutions: 10.0,
            min_speed_fraction: 0.1,
            run: RunKind::Auto,
            motor: MotorOrders::None,
        }
    }
}

/// The default highest order is this fraction of the samples per revolution where the coast is
/// slowest: below the 1/2 of uniform sampling, since the fit needs some room to tell an order
/// from the motion and from its neighbours (the same fraction as CSRR's).
pub const ORDERS_PER_SAMPLE: f64 = 0.4;

/// Cap of the default highest order: the screening fit's cost grows as the orders cubed (a
/// dense Cholesky factor and its inverse), 500 orders take some 0.05 s on two cores.
pub const MAX_DEFAULT_ORDER: usize = 500;

/// The significance rule's family-wise false-alarm probability: an order (or drag order, or a
/// residual order) is kept when its two coefficients' chi-square `xᵀC⁻¹x` (`C` their covariance
/// from the fit) exceeds `2·ln(M/α)`, `M` the number of orders tested and `α` this value. For
/// pure noise the chi-square of one order has the tail `exp(−χ²/2)`, so the chance that any of
/// the `M` orders passes is at most `α` (Bonferroni).
pub const FALSE_ORDER_PROBABILITY: f64 = 0.01;

/// Separating drag from encoder error costs noise: the map's orders where drag is fitted get
/// their noise multiplied by `√VIF`, the variance inflation `VIF = 1 + 1/cv²` (`cv` the relative
/// RMS variation of `1/ω²` over the coast). Above this `VIF` (10× the noise) the coast is taken
/// as inseparable: a `cv` of at least 0.1 is needed, a coast that slows by ≈ 17 %.
pub const MAX_DRAG_VARIANCE_INFLATION: f64 = 100.0;

/// Drag imprints and residual structure smaller than this (arcseconds) are not warned about
/// however significant: they are below what a table of this kind is used for.
pub const MATERIAL_ARCSEC: f64 = 0.01;

/// The chi-square threshold of the significance rule for `tested` orders.
pub fn significance_threshold(tested: usize) -> f64 {
    2.0 * (tested.max(1) as f64 / FALSE_ORDER_PROBABILITY).ln()
}

/// Why a log gives no spin-down calibration. Each says what to record instead.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TdrError {
    /// The encoder moved but never turned a whole revolution: the likely reason the fit failed
    /// (`cause`).
    #[error("the encoder {turn}")]
    NoWholeTurn {
        /// Its travel.
        turn: PartialTurn,
        /// The error the fit gave.
        #[source]
        cause: Box<TdrError>,
    },
    /// Too few usable samples to look for a coast.
    #[error(
        "no spin-down: only {count} usable samples (at least 128 needed); record the shaft coasting freely: spin it up, release the drive, and log many revolutions while the speed falls"
    )]
    TooFewSamples {
        /// Usable (finite, time-ordered) samples.
        count: usize,
    },
    /// The reading hardly moves.
    #[error(
        "no spin-down: the reading moves by only {travel_deg:.3}° in the whole log — the shaft stands still; spin it up, release the drive, and log it coasting for many revolutions"
    )]
    Stationary {
        /// Largest minus smallest continuous reading, degrees.
        travel_deg: f64,
    },
    /// The speed does not fall: the shaft is driven.
    #[error(
        "no spin-down: the speed stays at {speed_rpm:.2} r/min (it falls by only {drop_percent:.2} % after its peak) — the shaft is driven, not coasting; release the drive (or cut the motor current) at speed and log the coast-down"
    )]
    NotFalling {
        /// Peak speed, revolutions per minute.
        speed_rpm: f64,
        /// Fall of the speed from its peak to the end of the coast, percent.
        drop_percent: f64,
    },
    /// No stretch of steady speed long enough for a driven run.
    #[error(
        "no spin-down and no driven run long enough: the longest stretch at steady speed (its speed over each revolution within 0.5 % of the next one's) covers {revolutions:.0} whole revolutions, at least {needed} needed; drive the shaft at a constant voltage for longer, or release it at speed and log the coast-down"
    )]
    NoSteadyRun {
        /// Revolutions of the longest steady stretch found.
        revolutions: f64,
        /// [`TdrOptions::min_revolutions`].
        needed: f64,
    },
    /// The coast is too short.
    #[error(
        "no spin-down long enough: the coast covers {revolutions:.1} revolutions, at least {needed} needed to tell the encoder's error (periodic in angle) from the motion (smooth in time); spin up faster or log the coast for longer"
    )]
    TooFewRevolutions {
        /// Revolutions of the coast found.
        revolutions: f64,
        /// [`TdrOptions::min_revolutions`].
        needed: f64,
    },
    /// The fit's residual is far above the readings' noise and no order stands above it: the
    /// map (zero) explains none of the data.
    #[error(
        "the fit leaves {residual_arcsec:.4}″ RMS per sample where the readings' noise (from their third differences in \
         time) is {noise_arcsec:.4}″ (more than 10× the noise), and no order of the encoder's error stands above the noise: \
         the map cannot explain the data. Most likely the shaft is not coasting freely (a drive or a load acting on it, a \
         speed that jumps) or the readings jump; record a free coast-down of the shaft alone"
    )]
    Unexplained {
        /// RMS of the fit's residual per sample, arcsec.
        residual_arcsec: f64,
        /// The readings' noise per sample, arcsec.
        noise_arcsec: f64,
    },
    /// The least-squares problem is singular.
    #[error(
        "the fit is underdetermined ({unknowns} unknowns from {samples} samples of the coast): lower the `max_order` option or the `motion_degree` option"
    )]
    Underdetermined {
        /// Unknowns of the fit.
        unknowns: usize,
        /// Samples of the coast.
        samples: usize,
    },
}

/// The fitted motion `θ(t) = θ_start + Σ c_j T_j(τ)` of the coast.
#[derive(Debug, Clone, PartialEq)]
pub struct TdrMotion {
    /// Degree `p` of the Chebyshev series.
    pub degree: usize,
    /// Start and end of the coast used, seconds.
    pub t_start: f64,
    /// End of the coast used, seconds.
    pub t_end: f64,
    /// Continuous reading at the coast's first sample (radians), the series' origin.
    pub angle_origin: f64,
    /// Chebyshev coefficients `c_0..c_p`, radians.
    pub coefficients: Vec<f64>,
}

impl TdrMotion {
    /// `(θ, dθ/dt, d²θ/dt²)` at time `t` (radians, rad/s, rad/s²).
    pub fn eval(&self, t: f64) -> (f64, f64, f64) {
        let half = 0.5 * (self.t_end - self.t_start);
        let tau = (t - 0.5 * (self.t_start + self.t_end)) / half;
        let (f, d1, d2) = chebyshev_with_derivatives(&self.coefficients, tau);
        (self.angle_origin + f, d1 / half, d2 / (half * half))
    }
}

/// The DUT's map against a reference channel recorded with it, as a check of the TDR map.
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceCheck {
    /// DUT reading − reference reading as a function of the DUT's reading, zero mean (the
    /// reference's own error included), Fourier series to the same order as the TDR map.
    pub map: ErrorMap,
    /// Largest `|TDR map − reference map|` on the grid, arcseconds.
    pub max_abs_diff_arcsec: f64,
    /// RMS of `TDR map − reference map`, arcseconds.
    pub rms_diff_arcsec: f64,
}

/// A speed-dependent part of one order (see the module docs): the amplitude whose shape over the
/// coast follows `ω⁻²/⟨ω⁻²⟩ − 1`, the signature of an angle-dependent drag.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpeedDependence {
    /// The order and its amplitude/phase (radians).
    pub harmonic: Harmonic,
    /// Standard uncertainty of the amplitude, radians.
    pub u: f64,
}

/// An angle-dependent drag separated from the encoder's error (module docs, eq. 3).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DragTerm {
    /// The deceleration `a_h·cos(hθ + φ_h)`: order, amplitude `a_h` (rad/s²) and phase (rad).
    pub deceleration: Harmonic,
    /// Its imprint at the coast's mean `⟨ω⁻²⟩`, `a_h/h²·⟨ω⁻²⟩` (radians): what a fit that ignored
    /// the drag would have put into the map's order `h`.
    pub imprint: f64,
    /// Standard uncertainty of `imprint`, radians.
    pub u_imprint: f64,
}

/// How well the coast's speed range separates drag from encoder error.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DragSeparation {
    /// Relative RMS variation of `1/ω²` over the samples used (std/mean).
    pub variation: f64,
    /// Factor by which separating drag multiplies the noise of the map's orders it is fitted
    /// at, `√(1 + 1/variation²)`.
    pub noise_gain: f64,
    /// Whether drag was fitted jointly with the map (`noise_gain² ≤`
    /// [`MAX_DRAG_VARIANCE_INFLATION`] and drag order ≥ 1 asked for).
    pub separated: bool,
}

/// One interval of the coast used, for reports: the speed measured over it and what the final
/// fit left of its samples. A coast of millions of samples is drawn from a few hundred of these.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CoastBin {
    /// Middle of the interval, seconds (the log's own time stamps).
    pub t: f64,
    /// Mean speed over the interval from its first and last readings, rad/s (a magnitude).
    pub speed: f64,
    /// Mean of the fit's residuals in the interval, radians.
    pub residual_mean: f64,
    /// Smallest residual in the interval, radians.
    pub residual_min: f64,
    /// Largest residual in the interval, radians.
    pub residual_max: f64,
}

/// Intervals of [`TdrCalibration::coast`].
pub const COAST_BINS: usize = 400;

/// A spin-down calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct TdrCalibration {
    /// The encoder's error map (function of its reading, zero mean), radians.
    pub map: ErrorMap,
    /// The map as a Fourier series.
    pub series: FourierSeries,
    /// Highest order tested ([`TdrOptions::max_order`] or the default from the data).
    pub max_order: usize,
    /// The orders kept by the significance rule (ascending): the map holds these only.
    pub orders: Vec<usize>,
    /// Periodic structure left in the fit's residual above [`TdrCalibration::max_order`]
    /// (orders that pass the significance rule), largest first.
    pub unresolved: Vec<Harmonic>,
    /// The fitted motion.
    pub motion: TdrMotion,
    /// The coast used in [`COAST_BINS`] intervals of equal samples: measured speed and the
    /// final fit's residual over time, what the report draws against the fitted motion.
    pub coast: Vec<CoastBin>,
    /// RMS of the fit's residuals, radians (noise and resolution; more means an unmodelled
    /// effect).
    pub residual_rms: f64,
    /// The readings' noise per sample measured without the model, from their second
    /// differences in time ([`readings_noise`]), radians: what `residual_rms` is judged against.
    pub noise_rms: f64,
    /// The detection limit of the orders tested, an amplitude in radians: an order below it
    /// cannot pass the significance rule ([`crate::detection`]).
    pub detection_limit: f64,
    /// Samples of the coast used.
    pub samples_used: usize,
    /// Revolutions of the coast used.
    pub revolutions: f64,
    /// Speed at the start of the coast used, rad/s (a magnitude; see `direction`).
    pub speed_start: f64,
    /// Speed at the end of the coast used, rad/s.
    pub speed_end: f64,
    /// Samples per revolution where the coast is slowest (densest).
    pub samples_per_revolution_densest: f64,
    /// `+1` for increasing readings, `−1` for decreasing.
    pub direction: f64,
    /// `⟨ω⁻²⟩` over the samples used, s²: a drag deceleration `a_h` (rad/s²) at order `h` shifts
    /// the map's order `h` by `a_h·drag_gain/h²` radians unless separated (module docs, eq. 2).
    pub drag_gain: f64,
    /// Whether the coast's speed range separates drag from encoder error.
    pub drag_separation: DragSeparation,
    /// The drag found and separated from the map (significant orders only).
    pub drag: Vec<DragTerm>,
    /// Where drag could not be separated: orders whose amplitude changes with speed as
    /// angle-dependent drag would make it (significant and > 0.01″), left in the map.
    pub speed_dependence: Vec<SpeedDependence>,
    /// The check against a reference channel, when one was pushed.
    pub reference: Option<ReferenceCheck>,
    /// The standard uncertainty of the map at every table point, with its budget (module docs,
    /// "Uncertainty").
    pub uncertainty: MapUncertainty,
    /// What the user should know.
    pub warnings: Vec<String>,
    /// What the method cannot separate ([`DRAG_AMBIGUITY`], or [`DRIVEN_AMBIGUITY`] for a
    /// driven run), for reports.
    pub ambiguity: &'static str,
    /// A driven run's passes and the motor's orders; `None` for a coast.
    pub driven: Option<DrivenRun>,
}

/// A spin-down calibration being fed samples.
#[derive(Debug, Clone)]
pub struct Tdr {
    opts: TdrOptions,
    t: Vec<f64>,
    r: Vec<f64>,
    reference: Vec<f64>,
    unwrap: Unwrapper,
    unwrap_ref: Unwrapper,
    skipped: usize,
}

impl Tdr {
    /// A calibration with these settings.
    pub fn new(opts: TdrOptions) -> Self {
        Tdr {
            opts,
            t: Vec::new(),
            r: Vec::new(),
            reference: Vec::new(),
            unwrap: Unwrapper::new(),
            unwrap_ref: Unwrapper::new(),
            skipped: 0,
        }
    }

    /// One sample: time (s) and reading (rad). Non-finite values and times that do not increase
    /// are skipped (and counted in a warning).
    pub fn push(&mut self, t: f64, reading: f64) {
        if self.accept(t, reading, 0.0) {
            self.t.push(t);
            self.r.push(self.unwrap.unwrap(reading));
        }
    }

    /// One sample with the reading of a reference encoder on the same shaft (rad), for
    /// [`TdrCalibration::reference`]. Use either this or [`Tdr::push`] for a whole log.
    pub fn push_with_reference(&mut self, t: f64, reading: f64, reference: f64) {
        if self.accept(t, reading, reference) {
            self.t.push(t);
            self.r.push(self.unwrap.unwrap(reading));
            self.reference.push(self.unwrap_ref.unwrap(reference));
        }
    }

    fn accept(&mut self, t: f64, reading: f64, reference: f64) -> bool {
        let ok = t.is_finite()
            && reading.is_finite()
            && reference.is_finite()
            && self.t.last().is_none_or(|&last| t > last);
        if !ok {
            self.skipped += 1;
        }
        ok
    }

    /// Finds the coast, chooses the orders, separates drag where the speed range allows, fits
    /// motion and map, and checks them. If that fails for a reading that moved but never turned
    /// a whole revolution, the error is [`TdrError::NoWholeTurn`].
    pub fn finish(self) -> Result<TdrCalibration, TdrError> {
        // The readings are unwrapped as they come: their extent is the travel.
        let (lo, hi) = extent(&self.r);
        let turn = PartialTurn::of(
            (hi - lo).to_degrees(),
            "TDR needs a free coast of at least one whole turn (better many) to tell the encoder's \
             error, periodic in angle, from the motion; a coast over part of a turn cannot separate \
             them",
        );
        self.fit((lo, hi)).map_err(|e| match turn {
            Some(turn) => TdrError::NoWholeTurn {
                turn,
                cause: Box::new(e),
            },
            None => e,
        })
    }

    /// The fit of the readings, which span `extent` (their least and greatest): of the coast,
    /// or of the driven run's passes (module docs, "Driven runs").
    fn fit(self, extent: (f64, f64)) -> Result<TdrCalibration, TdrError> {
        let coast = || find_coast(&self.t, &self.r, extent, &self.opts);
        let driven = || find_passes(&self.t, &self.r, extent, &self.opts);
        let of_coast = |c: Coast| self.fit_run(&c, false).map(|(cal, _)| cal);
        match self.opts.run {
            RunKind::Coast => of_coast(coast()?),
            RunKind::Driven => self.fit_driven(driven()?),
            RunKind::Auto => match coast() {
                Ok(c) => of_coast(c),
                Err(e) => match driven() {
                    Ok(passes) => self.fit_driven(passes),
                    // A held speed is a driven run: what it lacks is said by the driven error.
                    Err(d) if matches!(e, TdrError::NotFalling { .. }) => Err(d),
                    Err(_) => Err(e),
                },
            },
        }
    }

    /// The fit of one coast, or of one pass of a driven run (`driven`: no drag fit, the
    /// motor's orders in the fit and out of the map, returned as measured).
    fn fit_run(
        &self,
        coast: &Coast,
        driven: bool,
    ) -> Result<(TdrCalibration, Vec<MotorMeasure>), TdrError> {
        let (i0, i1) = (coast.first, coast.end);
        let t = &self.t[i0..i1];
        let r = &self.r[i0..i1];
        let mut warnings = self.coast_warnings(coast);
        let max_degree = self.max_degree(coast, &mut warnings);
        let y0 = r[0];
        let span = (t[0], t[t.len() - 1]);
        let samples = Samples {
            t,
            r,
            origin: y0,
            span,
        };
        // The two passes before the spectra, each on one core, side by side.
        let (step, preliminary) = rayon::join(
            || median_step(t),
            || preliminary_motion(samples, max_degree),
        );
        let densest = TAU / (coast.slowest_speed * step);
        let h = self.max_order(t.len(), densest, max_degree, &mut warnings)?;
        let underdetermined = TdrError::Underdetermined {
            unknowns: max_degree + 1 + 2 * h,
            samples: t.len(),
        };
        // At a steady speed ω⁻² does not vary: drag cannot be separated, and is not tried.
        let hd = if driven {
            0
        } else {
            self.opts.max_drag_order.min(h)
        };
        let motor_orders = if driven {
            self.opts.motor.up_to(h)
        } else {
            Vec::new()
        };
        let moments = Moments::with_preliminary(samples, preliminary, h, hd);

        // 1. Which orders the data hold: every order to h, the motion at its highest degree.
        // The readings' own noise, for the verdict at the end, is measured beside it (the
        // screening's factorization runs on one core).
        let (screen, noise_rms) = rayon::join(
            || screen_orders(&moments, span, max_degree, h, None),
            || readings_noise(t, r),
        );
        let mut screen = screen.ok_or(underdetermined)?;
        let screen_motion = TdrMotion {
            degree: max_degree,
            t_start: span.0,
            t_end: span.1,
            angle_origin: y0,
            coefficients: screen.motion.clone(),
        };
        let speeds = SpeedSpread::of(&screen_motion, &moments);

        // 2. Drag: the orders to max_drag_order fitted jointly with the map (eq. 3).
        let coasting = Coasting {
            moments: &moments,
            span,
            max_degree,
            h,
            hd,
        };
        let drag = self.drag_step(
            &coasting,
            coast,
            &mut screen,
            screen_motion,
            &speeds,
            &mut warnings,
        );
        let (drag_orders, speed_dependence, separable) =
            (drag.orders, drag.speed_dependence, drag.separable);
        let weights = |orders: Vec<usize>| DragWeights {
            orders,
            motion: drag.motion.clone(),
            gain: speeds.drag_gain,
        };

        // 3. The final fit: the kept orders (and the drag's, and the motor's), the motion's
        // degree by BIC.
        let orders = union(&union(&screen.kept, &drag_orders), &motor_orders);
        let mut basis = Basis {
            t0: span.0,
            t1: span.1,
            degree: max_degree,
            orders: orders.clone(),
            drag: (!drag_orders.is_empty()).then(|| weights(drag_orders.clone())),
        };
        let normal = Normal::new(&moments, &basis);
        let degree = match self.opts.motion_degree {
            Some(p) => p,
            None => motion_degree_by_bic(&normal, t.len()),
        };
        basis.degree = degree;
        let fit = Fit::from_normal(&normal, degree).ok_or(TdrError::Underdetermined {
            unknowns: basis.len(),
            samples: t.len(),
        })?;
        let residual_rms = (fit.rss / t.len() as f64).sqrt();

        let (mut series, motion) = series_and_motion(&basis, &fit, h, y0);
        // Points enough for the map with the motor's orders or without.
        let points = self
            .opts
            .points
            .unwrap_or_else(|| crate::csrr::table_points(&series));
        let motor = motor_measures(&basis, &fit, &motor_orders);
        for m in &motor {
            series.cos[m.order - 1] = 0.0;
            series.sin[m.order - 1] = 0.0;
        }
        let map_orders: Vec<usize> = orders
            .iter()
            .copied()
            .filter(|k| !motor_orders.contains(k))
            .collect();
        let map = ErrorMap::from_series(&series, points);
        let drag = drag_terms(&basis, &fit, speeds.drag_gain);

        // 4. What the model leaves: periodic structure in the residual above the orders fitted.
        let top = ((0.5 * densest) as usize).max(2 * h).min(4 * h.max(8));
        let (unresolved, coast_bins) =
            residual_and_trace(samples, &basis, &fit, h + 1..=top, COAST_BINS);
        warnings.extend(unresolved_warning(&unresolved, h));

        let floor = detection::detection_floor(screen.detection_limit);
        let mut components =
            map_components(&basis, &fit, &series, &unresolved, screen.dropped, points);
        components.extend(driven::left_out(&motor));
        let uncertainty =
            detection::apply_floor(MapUncertainty::combine(points, components), floor);
        if map_orders.is_empty() {
            warnings.push(detection::empty_map_warning(
                uncertainty.max(),
                &format!("1–{h}"),
                screen.detection_limit,
            ));
        }
        match detection::residual_verdict(residual_rms, noise_rms, !orders.is_empty()) {
            Verdict::Explained => {}
            Verdict::Above(ratio) => warnings.push(detection::residual_warning(
                residual_rms,
                noise_rms,
                ratio,
                "the readings' noise (from their third differences in time) is",
                "the map and the motion do",
                "something acts on the coasting shaft that is not periodic in its angle, the readings jump, or the error \
                 holds orders that are not whole",
            )),
            Verdict::Unexplained(_) => {
                return Err(TdrError::Unexplained {
                    residual_arcsec: residual_rms * ARCSEC_PER_RAD,
                    noise_arcsec: noise_rms * ARCSEC_PER_RAD,
                });
            }
        }
        let seen = union(
            &orders,
            &unresolved.iter().map(|u| u.order).collect::<Vec<_>>(),
        );
        let reference = self.reference_check(i0..i1, &seen, &map, &mut warnings);

        let cal = TdrCalibration {
            map,
            series,
            max_order: h,
            orders: map_orders,
            unresolved,
            speed_start: motion.eval(span.0).1.abs(),
            speed_end: motion.eval(span.1).1.abs(),
            motion,
            coast: coast_bins,
            residual_rms,
            noise_rms,
            detection_limit: screen.detection_limit,
            samples_used: t.len(),
            revolutions: coast.revolutions,
            samples_per_revolution_densest: densest,
            direction: coast.direction,
            drag_gain: speeds.drag_gain,
            drag_separation: DragSeparation {
                variation: speeds.variation,
                noise_gain: speeds.noise_gain,
                separated: separable,
            },
            drag,
            speed_dependence,
            reference,
            uncertainty,
            warnings,
            ambiguity: if driven {
                DRIVEN_AMBIGUITY
            } else {
                DRAG_AMBIGUITY
            },
            driven: None,
        };
        Ok((cal, motor))
    }

    /// Step 2 of [`finish`](Self::finish): the drag orders up to `max_drag_order` fitted jointly
    /// with the map (eq. 3) where the coast's speeds can separate them, the warnings about it,
    /// and the orders screened again with the drag found (unseparated drag inflates the
    /// screening's noise estimate and hides small orders).
    fn drag_step(
        &self,
        c: &Coasting,
        coast: &Coast,
        screen: &mut Screen,
        screen_motion: TdrMotion,
        speeds: &SpeedSpread,
        warnings: &mut Vec<String>,
    ) -> DragStep {
        let hd = c.hd;
        let separable =
            speeds.noise_gain * speeds.noise_gain <= MAX_DRAG_VARIANCE_INFLATION && hd >= 1;
        let weights = |orders: Vec<usize>| DragWeights {
            orders,
            motion: screen_motion.clone(),
            gain: speeds.drag_gain,
        };
        let (orders, speed_dependence) = if hd >= 1 {
            let tested: Vec<usize> = (1..=hd).collect();
            let basis = Basis {
                t0: c.span.0,
                t1: c.span.1,
                degree: c.max_degree,
                orders: union(&screen.kept, &tested),
                drag: Some(weights(tested)),
            };
            significant_drag(c.moments, &basis, separable)
        } else {
            (Vec::new(), Vec::new())
        };
        let too_narrow = !separable && hd >= 1;
        warnings.extend(drag_warnings(coast, speeds, too_narrow, &speed_dependence));
        if !orders.is_empty() {
            let drag = Some(weights(orders.clone()));
            if let Some(again) = screen_orders(c.moments, c.span, c.max_degree, c.h, drag) {
                *screen = Screen {
                    motion: std::mem::take(&mut screen.motion),
                    ..again
                };
            }
        }
        DragStep {
            orders,
            speed_dependence,
            separable,
            motion: screen_motion,
        }
    }

    /// Warnings about the samples and the coast found: skipped samples, a driven plateau.
    fn coast_warnings(&self, coast: &Coast) -> Vec<String> {
        let mut warnings = Vec::new();
        if self.skipped > 0 {
            warnings.push(format!(
                "{} samples skipped (non-finite values or times that do not increase)",
                self.skipped
            ));
        }
        if coast.plateau_s > 0.0 {
            warnings.push(format!(
                "the first {:.2} s after the peak speed hold the speed (a driven plateau?) and were not used; to calibrate from the driven run instead, set the `run` option to driven",
                coast.plateau_s
            ));
        }
        warnings
    }

    /// The motion's highest degree, given or from the coast's revolutions, with a warning where
    /// a given one is beyond what the coast supports.
    fn max_degree(&self, coast: &Coast, warnings: &mut Vec<String>) -> usize {
        match self.opts.motion_degree {
            Some(p) => {
                if p as f64 > coast.revolutions / 2.0 {
                    warnings.push(format!(
                        "motion degree {p} is above half the {:.1} revolutions: the polynomial can follow the low orders of the error, which then leak into the motion; lower it or log a longer coast",
                        coast.revolutions
                    ));
                }
                p
            }
            None => ((coast.revolutions / 2.0).floor() as usize).clamp(2, 30),
        }
    }

    /// The highest order tested, given or from the coast (`densest`: its samples per revolution
    /// at the slow end), with a warning where a given one is beyond what the coast supports; an
    /// error where the unknowns, with the motion to `max_degree`, exceed a quarter of the
    /// `samples`.
    fn max_order(
        &self,
        samples: usize,
        densest: f64,
        max_degree: usize,
        warnings: &mut Vec<String>,
    ) -> Result<usize, TdrError> {
        // At most a quarter as many unknowns as samples.
        let room = (samples / 4).saturating_sub(max_degree + 1) / 2;
        let h = match self.opts.max_order {
            Some(h) => {
                if (h as f64) > 0.5 * densest {
                    warnings.push(format!(
                        "the `max_order` option {h} is above half the {densest:.0} samples per revolution where the coast is slowest: the highest orders are poorly determined; sample faster or lower the `max_order` option"
                    ));
                }
                h
            }
            None => ((ORDERS_PER_SAMPLE * densest) as usize)
                .clamp(1, MAX_DEFAULT_ORDER.min(room.max(1))),
        };
        let unknowns = max_degree + 1 + 2 * h;
        if 4 * unknowns > samples {
            return Err(TdrError::Underdetermined { unknowns, samples });
        }
        Ok(h)
    }

    /// The reference check over the coast's samples `range` at the orders `seen`, or `None`
    /// without reference readings (or with some missing, which is warned about).
    fn reference_check(
        &self,
        range: std::ops::Range<usize>,
        seen: &[usize],
        map: &ErrorMap,
        warnings: &mut Vec<String>,
    ) -> Option<ReferenceCheck> {
        let mixed = !self.reference.is_empty() && self.reference.len() != self.r.len();
        if mixed {
            warnings.push(
                "a reference reading came with only some samples (push and push_with_reference mixed): the reference check is skipped".to_string(),
            );
        }
        (!self.reference.is_empty() && !mixed)
            .then(|| reference_check(&self.r[range.clone()], &self.reference[range], seen, map))
    }
}

/// The coast as the fits take it: its spectra, its time span, the motion's highest degree, the
/// highest order tested and the highest drag order.
struct Coasting<'a> {
    moments: &'a Moments,
    span: (f64, f64),
    max_degree: usize,
    h: usize,
    hd: usize,
}

/// What [`Tdr::drag_step`] found.
struct DragStep {
    /// The drag orders that stand above the noise.
    orders: Vec<usize>,
    /// The speed-dependent parts of the orders, the signature of an angle-dependent drag.
    speed_dependence: Vec<SpeedDependence>,
    /// Whether the coast's speeds can separate drag from the encoder's error.
    separable: bool,
    /// The screening fit's motion, which the drag's weights follow.
    motion: TdrMotion,
}

/// How widely the coast sweeps `1/ω²`, from the screening's motion: the drag's gain `⟨ω⁻²⟩`,
/// the relative RMS variation `cv` of `ω⁻²` and the noise gain `√(1 + 1/cv²)` of separating
/// drag from the map (see [`MAX_DRAG_VARIANCE_INFLATION`]).
struct SpeedSpread {
    drag_gain: f64,
    variation: f64,
    noise_gain: f64,
}

impl SpeedSpread {
    /// From the motion, its means over the samples taken from the spectra (`ω⁻²` is smooth).
    fn of(motion: &TdrMotion, moments: &Moments) -> Self {
        let (mid, half) = (
            0.5 * (motion.t_start + motion.t_end),
            0.5 * (motion.t_end - motion.t_start),
        );
        let speed = |tau: f64| motion.eval(mid + tau * half).1.abs();
        let n = moments.samples as f64;
        let drag_gain = moments.sum_of(|tau| speed(tau).powi(-2)) / n;
        let mean_w2 = moments.sum_of(|tau| speed(tau).powi(-4)) / n;
        let (variation, noise_gain) = speed_variation(drag_gain, mean_w2);
        SpeedSpread {
            drag_gain,
            variation,
            noise_gain,
        }
    }
}

/// How widely a coast sweeps `1/ω²`, from the means over its samples `⟨ω⁻²⟩` and `⟨ω⁻⁴⟩`:
/// the relative RMS variation `cv = √(⟨ω⁻⁴⟩/⟨ω⁻²⟩² − 1)` and the noise gain `√(1 + 1/cv²)` of
/// separating drag from the map ([`DragSeparation`]; the coast is separable when the gain
/// squared is at most [`MAX_DRAG_VARIANCE_INFLATION`]).
pub fn speed_variation(mean_inv_speed2: f64, mean_inv_speed4: f64) -> (f64, f64) {
    let variation = (mean_inv_speed4 / (mean_inv_speed2 * mean_inv_speed2) - 1.0)
        .max(0.0)
        .sqrt();
    let noise_gain = (1.0 + 1.0 / (variation * variation).max(1e-300)).sqrt();
    (variation, noise_gain)
}

/// The "noise of the readings propagated through the fit" component of the map's `u` that
/// [`Tdr::finish`] reports, for a coast read at times `t` (s) with continuous readings `r`
/// (rad; a planned coast's angles will do), the map's `orders` (ascending), the motion's
/// Chebyshev `degree` and noise `sigma` (rad) per sample: `u_fit(x) = σ·‖L⁻¹c(x)‖` at `points`
/// grid points (the same function the method's budget uses, with its `σ̂` replaced by `sigma`).
/// For planning a coast before it is recorded; `None` where the fit is underdetermined.
pub fn fit_noise(
    t: &[f64],
    r: &[f64],
    orders: &[usize],
    degree: usize,
    sigma: f64,
    points: usize,
) -> Option<Vec<f64>> {
    let (&first, &last) = (t.first()?, t.last()?);
    let h = orders.last().copied().unwrap_or(1);
    let samples = Samples {
        t,
        r,
        origin: r[0],
        span: (first, last),
    };
    let moments = Moments::of_coast(samples, degree, h, 0);
    let basis = Basis {
        t0: first,
        t1: last,
        degree,
        orders: orders.to_vec(),
        drag: None,
    };
    if 4 * basis.len() > t.len() {
        return None;
    }
    let fit = Fit::new(&moments, &basis)?;
    Some(noise_through_fit(&basis, &fit.l_inv, sigma, points))
}

/// The drag orders of `basis` (fitted jointly with the map) that pass the significance rule
/// and are material: where the coast separates drag (`separable`) the orders to fit as drag,
/// else the speed dependence found, to be warned about.
fn significant_drag(
    moments: &Moments,
    basis: &Basis,
    separable: bool,
) -> (Vec<usize>, Vec<SpeedDependence>) {
    let (mut drag_orders, mut speed_dependence) = (Vec::new(), Vec::new());
    let (Some(fit), Some(weights)) = (Fit::new(moments, basis), &basis.drag) else {
        return (drag_orders, speed_dependence);
    };
    let threshold = significance_threshold(weights.orders.len());
    let first = basis.drag_column(0);
    for (i, &k) in weights.orders.iter().enumerate() {
        let (c, s) = (first + 2 * i, first + 2 * i + 1);
        let (p, q) = (fit.beta[c], fit.beta[s]);
        let chi2 = fit.chi_square(c, s);
        let imprint = Harmonic::from_coefficients(k, p, q);
        if chi2 < threshold || imprint.amplitude * ARCSEC_PER_RAD < MATERIAL_ARCSEC {
            continue;
        }
        let u = fit.sigma * (0.5 * (fit.covariance(c, c) + fit.covariance(s, s))).sqrt();
        if separable {
            drag_orders.push(k);
        } else {
            speed_dependence.push(SpeedDependence {
                harmonic: imprint,
                u,
            });
        }
    }
    (drag_orders, speed_dependence)
}

/// Warnings about drag: a coast `too_narrow` in speed to separate it, and the map's orders that
/// change with speed as drag would make them.
fn drag_warnings(
    coast: &Coast,
    speeds: &SpeedSpread,
    too_narrow: bool,
    speed_dependence: &[SpeedDependence],
) -> Vec<String> {
    let mut warnings = Vec::new();
    if too_narrow {
        let start = 60.0 / TAU * coast.peak_speed;
        warnings.push(format!(
            "the coast's speed range is too narrow to separate angle-dependent drag from encoder error: 1/ω² varies by {:.1} % (RMS) over it, at least 10 % is needed (the separation would multiply the noise by {:.0}); let the shaft coast down to about {:.0} r/min or below (17 % under its {start:.0} r/min start), or trust the map only on an air bearing",
            100.0 * speeds.variation,
            speeds.noise_gain,
            0.83 * start
        ));
    }
    if !speed_dependence.is_empty() {
        let list: Vec<String> = speed_dependence
            .iter()
            .map(|s| {
                format!(
                    "order {} {:.3}″ ± {:.3}″",
                    s.harmonic.order,
                    s.harmonic.amplitude * ARCSEC_PER_RAD,
                    s.u * ARCSEC_PER_RAD
                )
            })
            .collect();
        warnings.push(format!(
            "the map changes with speed as angle-dependent drag would make it ({}): part of these orders is likely the shaft's motion, not the encoder (see the ambiguity note)",
            list.join(", ")
        ));
    }
    warnings
}

/// The motion's degree, 2 to the normal equations' highest, with the least BIC
/// `N ln(RSS/N) + n_params ln N` over the `samples`: nested fits, each from the normal equations
/// alone.
fn motion_degree_by_bic(normal: &Normal, samples: usize) -> usize {
    let max_degree = normal.degree();
    let n = samples as f64;
    let mut best: Option<(f64, usize)> = None;
    for p in 2..=max_degree {
        let cols = normal.columns(p);
        let Some((b, _)) = normal.solve(&cols) else {
            continue;
        };
        let rss = normal.rss(&b);
        let bic = n * (rss / n).max(1e-300).ln() + cols.len() as f64 * n.ln();
        if best.is_none_or(|(least, _)| bic < least) {
            best = Some((bic, p));
        }
    }
    best.map_or(max_degree, |(_, p)| p)
}

/// The map's series (orders `1..=h`, those not in `basis` zero) and the motion (`y0` its angle
/// origin) of the final fit.
fn series_and_motion(basis: &Basis, fit: &Fit, h: usize, y0: f64) -> (FourierSeries, TdrMotion) {
    let degree = basis.degree;
    let mut series = FourierSeries::zeros(h);
    for (i, &k) in basis.orders.iter().enumerate() {
        series.cos[k - 1] = fit.beta[degree + 1 + 2 * i];
        series.sin[k - 1] = fit.beta[degree + 2 + 2 * i];
    }
    let motion = TdrMotion {
        degree,
        t_start: basis.t0,
        t_end: basis.t1,
        angle_origin: y0,
        coefficients: fit.beta[..=degree].to_vec(),
    };
    (series, motion)
}

/// The drag terms of the final fit: each order's imprint, and the deceleration
/// `h²·imprint/⟨ω⁻²⟩` that makes it (eq. 2).
fn drag_terms(basis: &Basis, fit: &Fit, drag_gain: f64) -> Vec<DragTerm> {
    let Some(weights) = &basis.drag else {
        return Vec::new();
    };
    let first = basis.drag_column(0);
    weights
        .orders
        .iter()
        .enumerate()
        .map(|(i, &k)| {
            let (c, s) = (first + 2 * i, first + 2 * i + 1);
            let imprint = Harmonic::from_coefficients(k, fit.beta[c], fit.beta[s]);
            let hh = (k * k) as f64;
            DragTerm {
                deceleration: Harmonic {
                    amplitude: imprint.amplitude * hh / drag_gain,
                    ..imprint
                },
                imprint: imprint.amplitude,
                u_imprint: fit.sigma * (0.5 * (fit.covariance(c, c) + fit.covariance(s, s))).sqrt(),
            }
        })
        .collect()
}

/// The warning about material periodic structure left in the residual above order `h`.
fn unresolved_warning(unresolved: &[Harmonic], h: usize) -> Option<String> {
    let material: Vec<&Harmonic> = unresolved
        .iter()
        .filter(|u| u.amplitude * ARCSEC_PER_RAD >= MATERIAL_ARCSEC)
        .collect();
    if material.is_empty() {
        return None;
    }
    let list: Vec<String> = material
        .iter()
        .take(6)
        .map(|u| format!("order {} {:.3}″", u.order, u.amplitude * ARCSEC_PER_RAD))
        .collect();
    Some(format!(
        "the fit's residual still holds periodic structure above the highest order fitted ({h}): {}{} — the map leaves these out; raise the `max_order` option to at least {}",
        list.join(", "),
        if material.len() > 6 { ", …" } else { "" },
        material.iter().map(|u| u.order).max().unwrap_or(h)
    ))
}

/// The coast found in a log: sample range `[first, end)` and its figures.
#[derive(Debug, Clone, PartialEq)]
struct Coast {
    first: usize,
    end: usize,
    peak_speed: f64,
    /// The lowest window speed of the coast, rad/s.
    slowest_speed: f64,
    direction: f64,
    revolutions: f64,
    plateau_s: f64,
}

/// Finds the coast: the log is cut into windows (at most 256, at least 8 samples each) whose mean
/// speeds are compared. From the fastest window, a plateau within 0.1 % of the peak speed (a
/// drive still on) is skipped, and the window where it ends; the coast then runs until the speed falls below
/// [`TdrOptions::min_speed_fraction`] of the peak, rises again by more than 1 % of the peak above
/// its lowest value so far (the drive back on), or the log ends.
fn find_coast(
    t: &[f64],
    r: &[f64],
    (lo, hi): (f64, f64),
    opts: &TdrOptions,
) -> Result<Coast, TdrError> {
    let n = t.len();
    check_log(n, (lo, hi))?;
    let windows = (n / 8).min(256);
    let bound = |k: usize| k * (n - 1) / windows;
    let speeds: Vec<f64> = (0..windows)
        .map(|k| {
            let (a, b) = (bound(k), bound(k + 1));
            (r[b] - r[a]) / (t[b] - t[a])
        })
        .collect();
    let k0 = (0..windows)
        .max_by(|&a, &b| speeds[a].abs().total_cmp(&speeds[b].abs()))
        .unwrap_or(0);
    let direction = speeds[k0].signum();
    let s: Vec<f64> = speeds.iter().map(|v| v * direction).collect();
    let peak = s[k0];
    let mut start = k0;
    while start + 2 < windows && s[start + 1] >= 0.999 * peak {
        start += 1;
    }
    let rpm = |w: f64| w * 60.0 / TAU;
    if start + 2 > windows {
        // The peak is at the end of the log.
        return Err(TdrError::NotFalling {
            speed_rpm: rpm(peak),
            drop_percent: 0.0,
        });
    }
    let mut end = start + 2;
    let mut lowest = s[start + 1];
    while end < windows {
        let v = s[end];
        if v < opts.min_speed_fraction * peak || v > lowest + 0.01 * peak {
            break;
        }
        lowest = lowest.min(v);
        end += 1;
    }
    // The coast starts after the last window at the peak speed: the drive may be released
    // anywhere inside it, and the kink there is no smooth motion.
    let (first, last) = (bound(start + 1), bound(end));
    let drop = 1.0 - s[end - 1] / peak;
    if drop < 0.02 {
        return Err(TdrError::NotFalling {
            speed_rpm: rpm(peak),
            drop_percent: 100.0 * drop,
        });
    }
    let revolutions = (r[last] - r[first]).abs() / TAU;
    if revolutions < opts.min_revolutions {
        return Err(TdrError::TooFewRevolutions {
            revolutions,
            needed: opts.min_revolutions,
        });
    }
    Ok(Coast {
        first,
        end: last + 1,
        peak_speed: peak,
        slowest_speed: lowest,
        direction,
        revolutions,
        plateau_s: if start > k0 {
            t[bound(start)] - t[bound(k0)]
        } else {
            0.0
        },
    })
}

/// The refusals of a log before any motion is looked for: too few samples (`n`), or a travel
/// (`extent`, the least and greatest readings) of less than a turn.
fn check_log(n: usize, (lo, hi): (f64, f64)) -> Result<(), TdrError> {
    if n < 128 {
        return Err(TdrError::TooFewSamples { count: n });
    }
    if hi - lo < TAU {
        return Err(TdrError::Stationary {
            travel_deg: (hi - lo).to_degrees(),
        });
    }
    Ok(())
}

/// The least and the greatest of `values`, on both cores (NaNs left out; the same whatever the
/// order).
fn extent(values: &[f64]) -> (f64, f64) {
    let least_greatest = |(lo, hi): (f64, f64), v: f64| (lo.min(v), hi.max(v));
    let none = || (f64::INFINITY, f64::NEG_INFINITY);
    values
        .par_chunks(1 << 16)
        .map(|c| c.iter().copied().fold(none(), least_greatest))
        .reduce(none, |a, b| least_greatest(least_greatest(a, b.0), b.1))
}

/// The median time step, seconds: the step of rank `⌊(N−1)/2⌋` among the `N − 1` steps.
///
/// Positive doubles order as their bits do, so the steps are compared as bits. Two values of a
/// regular subsample of the steps bracket the median ([`bracketed_step`]), and one pass over
/// the times finds it; where the bracket misses (a subsample unlike the whole) a radix
/// selection finds it in four ([`radix_step`]). Neither sorts a copy of all the steps: ten
/// million samples would need 80 MB more.
fn median_step(t: &[f64]) -> f64 {
    let rank = (t.len() - 1) / 2;
    bracketed_step(t, rank).unwrap_or_else(|| radix_step(t, rank))
}

/// Steps between two of the subsample [`bracketed_step`] takes (a prime, so that a pattern of
/// steps repeating with a short period is not sampled at one phase only).
const STEP_SAMPLE: usize = 251;

/// The step of `rank` among the steps of `t` when it lies between the subsample's values `lo ≤
/// hi` of ranks `m/2 ∓ 3√m` among its `m`: one pass counts the steps below `lo`, at `lo` and
/// at `hi`, and keeps those between, and the step of `rank` is `lo`, `hi` or the kept one of
/// its rank. `None` when it is outside, or more than a quarter of the steps fall between. (For
/// the median to fall outside, the count of the subsample's steps below it must stray from
/// `m/2` by `3√m`: six standard deviations were they drawn at random. Ten million samples give
/// `m ≈ 40,000` and a bracket of 3 % of the steps; below some 300,000 samples a quarter or
/// more fall between, and the radix selection answers.)
///
/// The pass counts pieces of [`STEP_PIECE`] steps on the threads rayon has and adds their
/// counts and kept steps: the same answer in any order.
fn bracketed_step(t: &[f64], rank: usize) -> Option<f64> {
    let steps = t.len() - 1;
    let step = |i: usize| (t[i + 1] - t[i]).to_bits();
    let mut sample: Vec<u64> = (0..steps).step_by(STEP_SAMPLE).map(step).collect();
    let (m, spread) = (sample.len(), 3 * sample.len().isqrt());
    if m <= 2 * spread + 1 {
        return None;
    }
    sample.sort_unstable();
    let (lo, hi) = (sample[m / 2 - spread], sample[m / 2 + spread]);
    let cap = steps / 4;
    #[derive(Default)]
    struct Tally {
        below: usize,
        at_lo: usize,
        at_hi: usize,
        between: Vec<u64>,
    }
    let tally = |piece: usize| {
        let mut tally = Tally::default();
        let end = ((piece + 1) * STEP_PIECE).min(steps);
        for w in t[piece * STEP_PIECE..=end].windows(2) {
            let s = (w[1] - w[0]).to_bits();
            tally.below += usize::from(s < lo);
            tally.at_lo += usize::from(s == lo);
            tally.at_hi += usize::from(s == hi && hi != lo);
            if lo < s && s < hi && tally.between.len() <= cap {
                tally.between.push(s);
            }
        }
        tally
    };
    let mut tally = (0..steps.div_ceil(STEP_PIECE))
        .into_par_iter()
        .map(tally)
        .reduce(Tally::default, |mut a, mut b| {
            a.below += b.below;
            a.at_lo += b.at_lo;
            a.at_hi += b.at_hi;
            a.between.append(&mut b.between);
            a
        });
    if tally.between.len() > cap {
        return None;
    }
    let mut rank = rank.checked_sub(tally.below)?;
    if rank < tally.at_lo {
        return Some(f64::from_bits(lo));
    }
    rank -= tally.at_lo;
    if rank < tally.between.len() {
        return Some(f64::from_bits(*tally.between.select_nth_unstable(rank).1));
    }
    rank -= tally.between.len();
    (rank < tally.at_hi).then_some(f64::from_bits(hi))
}

/// The step of `rank` among the steps of `t` by a radix selection on their bits, 16 bits a
/// pass over the times. Each pass counts pieces of [`STEP_PIECE`] steps on the threads rayon
/// has, and adds their counts: whole numbers, the same in any order.
fn radix_step(t: &[f64], rank: usize) -> f64 {
    let steps = t.len() - 1;
    let mut rank = rank;
    let mut prefix = 0u64;
    for pass in 0..4 {
        let shift = 48 - 16 * pass;
        let mask = if pass == 0 {
            0
        } else {
            u64::MAX << (shift + 16)
        };
        let count = |piece: usize| {
            let mut counts = vec![0usize; 1 << 16];
            let end = ((piece + 1) * STEP_PIECE).min(steps);
            for w in t[piece * STEP_PIECE..=end].windows(2) {
                let s = (w[1] - w[0]).to_bits();
                if s & mask == prefix {
                    counts[((s >> shift) & 0xffff) as usize] += 1;
                }
            }
            counts
        };
        let counts = (0..steps.div_ceil(STEP_PIECE))
            .into_par_iter()
            .map(count)
            .reduce_with(|mut a, b| {
                for (a, b) in a.iter_mut().zip(b) {
                    *a += b;
                }
                a
            })
            .unwrap_or_default();
        let mut digit = 0;
        while rank >= counts[digit] {
            rank -= counts[digit];
            digit += 1;
        }
        prefix |= (digit as u64) << shift;
    }
    f64::from_bits(prefix)
}

/// Steps [`median_step`] counts in one piece.
const STEP_PIECE: usize = 1 << 20;

/// The columns of the fit (1): `T_0..T_p(τ)`, then `cos kr, sin kr` for the map's orders `k`,
/// then for each drag order `h` the pair of eq. (3),
/// `w·cos hr + (v/h)·sin hr` and `w·sin hr − (v/h)·cos hr`, with `w = ω⁻²/⟨ω⁻²⟩` and
/// `v = 3ω̇/(ω⁴⟨ω⁻²⟩)` from a previously fitted motion.
#[derive(Debug, Clone)]
struct Basis {
    t0: f64,
    t1: f64,
    degree: usize,
    /// The map's orders, ascending.
    orders: Vec<usize>,
    drag: Option<DragWeights>,
}

/// The drag orders and what defines their columns' weights.
#[derive(Debug, Clone)]
struct DragWeights {
    orders: Vec<usize>,
    motion: TdrMotion,
    /// `⟨ω⁻²⟩`.
    gain: f64,
}

impl Basis {
    fn len(&self) -> usize {
        self.degree
            + 1
            + 2 * self.orders.len()
            + self.drag.as_ref().map_or(0, |d| 2 * d.orders.len())
    }

    /// Index of the first column of drag order number `i`.
    fn drag_column(&self, i: usize) -> usize {
        self.degree + 1 + 2 * self.orders.len() + 2 * i
    }

    /// The highest harmonic order any column needs.
    fn top(&self) -> usize {
        self.orders.last().copied().unwrap_or(0).max(
            self.drag
                .as_ref()
                .and_then(|d| d.orders.last().copied())
                .unwrap_or(0),
        )
    }
}

/// A least-squares fit with the columns of its basis: coefficients (the motion's from the coast's
/// first reading), residual sum of squares, the noise `σ` per sample estimated from it, and the
/// inverse `L⁻¹` of the Cholesky factor of `AᵀA = LLᵀ`, from which `(AᵀA)⁻¹ = L⁻ᵀL⁻¹` (the
/// coefficients' covariance over `σ²`) is read entry by entry.
#[derive(Debug, Clone)]
struct Fit {
    beta: Vec<f64>,
    rss: f64,
    sigma: f64,
    l_inv: DMatrix<f64>,
}

impl Fit {
    fn new(moments: &Moments, basis: &Basis) -> Option<Fit> {
        Fit::from_normal(&Normal::new(moments, basis), basis.degree)
    }

    /// The fit of the normal equations' columns with the motion to degree `p`.
    fn from_normal(normal: &Normal, p: usize) -> Option<Fit> {
        let cols = normal.columns(p);
        let (b, chol) = normal.solve(&cols)?;
        let rss = normal.rss(&b);
        let dof = normal.samples.saturating_sub(cols.len()).max(1) as f64;
        Some(Fit {
            beta: normal.coefficients(&b, &cols),
            rss,
            sigma: (rss / dof).sqrt(),
            l_inv: lower_triangular_inverse(&chol.l()),
        })
    }

    /// `(AᵀA)⁻¹` at `(a, b)`: the dot product of columns `a` and `b` of `L⁻¹`.
    fn covariance(&self, a: usize, b: usize) -> f64 {
        let from = a.max(b);
        let (ca, cb) = (self.l_inv.column(a), self.l_inv.column(b));
        (from..ca.len()).map(|k| ca[k] * cb[k]).sum()
    }

    /// `xᵀC⁻¹x` of the coefficient pair in columns `(c, s)`, `C = σ²·(AᵀA)⁻¹` restricted to it.
    fn chi_square(&self, c: usize, s: usize) -> f64 {
        let (a, b) = (self.beta[c], self.beta[s]);
        let (p, q, o) = (
            self.covariance(c, c),
            self.covariance(s, s),
            self.covariance(c, s),
        );
        let det = p * q - o * o;
        if det <= 0.0 || self.sigma <= 0.0 {
            return f64::INFINITY;
        }
        (a * a * q - 2.0 * a * b * o + b * b * p) / det / (self.sigma * self.sigma)
    }
}

/// `L⁻¹` of a lower-triangular `L`, column by column (`n³/6` multiply-adds, on contiguous
/// columns of `L`).
fn lower_triangular_inverse(l: &DMatrix<f64>) -> DMatrix<f64> {
    let n = l.nrows();
    // Each column of L⁻¹ on its own (on the threads rayon has), each as it would be alone.
    let columns: Vec<Vec<f64>> = (0..n)
        .into_par_iter()
        .map(|j| inverse_column(l.as_slice(), n, j))
        .collect();
    DMatrix::from_fn(n, n, |i, j| columns[j][i])
}

/// Column `j` of `L⁻¹` for the column-major `n × n` lower-triangular `l`, by forward
/// substitution. On x86-64 CPUs with AVX (detected at run time) the updates run four to an
/// instruction instead of SSE2's two: the same multiplications and subtractions (no fused
/// multiply-add), so the same bits.
fn inverse_column(l: &[f64], n: usize, j: usize) -> Vec<f64> {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx") {
        #[target_feature(enable = "avx")]
        unsafe fn avx(l: &[f64], n: usize, j: usize) -> Vec<f64> {
            substitute(l, n, j)
        }
        // SAFETY: the CPU has AVX.
        return unsafe { avx(l, n, j) };
    }
    substitute(l, n, j)
}

/// [`inverse_column`] as the compiler builds it for the CPU it targets.
#[inline(always)]
fn substitute(l: &[f64], n: usize, j: usize) -> Vec<f64> {
    let mut col = vec![0.0; n];
    col[j] = 1.0;
    for k in j..n {
        let lk = &l[k * n..(k + 1) * n];
        let v = col[k] / lk[k];
        col[k] = v;
        if v != 0.0 {
            for (c, x) in col[k + 1..].iter_mut().zip(&lk[k + 1..]) {
                *c -= v * x;
            }
        }
    }
    col
}

/// The components of the map's budget. The fit's noise: the map at `x` is `c(x)ᵀβ_E`, `c(x)`
/// the `cos kx, sin kx` of the orders fitted, so `u_fit(x)² = σ²·c(x)ᵀ[(AᵀA)⁻¹]_EE·c(x) =
/// σ²·‖L⁻¹·c(x)‖²` (with the motion's and the drag's columns in the fit: their correlation
/// with the map is included; a driven pass's motor orders count whether the map keeps them or
/// not).
/// Periodic structure the residual still holds above the fitted orders is missing from the map:
/// each such order of amplitude `A` errs by `A·cos(kx + φ)`, RMS `A/√2`, taken as a uniform
/// component. The orders the significance rule dropped hold, on average over the circle, what
/// their coefficients hold beyond their noise ([`Screen::dropped`]). And the table's linear
/// interpolation.
fn map_components(
    basis: &Basis,
    fit: &Fit,
    series: &FourierSeries,
    unresolved: &[Harmonic],
    dropped: f64,
    points: usize,
) -> Vec<MapComponent> {
    let u_fit = noise_through_fit(basis, &fit.l_inv, fit.sigma, points);
    let missing = (unresolved
        .iter()
        .map(|h| h.amplitude.powi(2) / 2.0)
        .sum::<f64>())
    .sqrt();
    let mut components = vec![MapComponent {
        name: "noise of the readings propagated through the fit".into(),
        evaluation: Evaluation::TypeA,
        u: u_fit,
    }];
    if dropped > 0.0 {
        components.push(MapComponent {
            name: "orders below the significance threshold, left out of the map".into(),
            evaluation: Evaluation::TypeA,
            u: vec![dropped],
        });
    }
    if missing > 0.0 {
        components.push(MapComponent {
            name: "periodic structure in the residual above the orders fitted".into(),
            evaluation: Evaluation::TypeA,
            u: vec![missing],
        });
    }
    components.push(MapComponent {
        name: "linear interpolation between table points".into(),
        evaluation: Evaluation::TypeB,
        u: vec![interpolation_uncertainty(&series.harmonics(), points)],
    });
    components
}

/// What the final fit measured at the motor's `orders` (each in `basis`): the coefficients
/// and their variance, each coefficient's `σ²·[(AᵀA)⁻¹]` averaged over the pair.
fn motor_measures(basis: &Basis, fit: &Fit, orders: &[usize]) -> Vec<MotorMeasure> {
    let f = basis.degree + 1;
    basis
        .orders
        .iter()
        .enumerate()
        .filter(|(_, k)| orders.contains(k))
        .map(|(i, &order)| {
            let (c, s) = (f + 2 * i, f + 2 * i + 1);
            MotorMeasure {
                order,
                cos: fit.beta[c],
                sin: fit.beta[s],
                variance: fit.sigma.powi(2) * 0.5 * (fit.covariance(c, c) + fit.covariance(s, s)),
            }
        })
        .collect()
}

/// `u_fit(x) = σ·‖L⁻¹c(x)‖` at `points` grid points, `c(x)` the `cos kx, sin kx` of the map's
/// orders in `basis` and `L⁻¹` the inverse of the fit's Cholesky factor ([`map_components`]).
fn noise_through_fit(basis: &Basis, l_inv: &DMatrix<f64>, sigma: f64, points: usize) -> Vec<f64> {
    let f = basis.degree + 1;
    let n = basis.len();
    let cols: Vec<usize> = (f..f + 2 * basis.orders.len()).collect();
    // B = L⁻¹ restricted to the map's columns.
    let b = DMatrix::from_fn(n, cols.len(), |i, j| l_inv[(i, cols[j])]);
    let mut c = DVector::<f64>::zeros(cols.len());
    (0..points)
        .map(|i| {
            let x = TAU * i as f64 / points as f64;
            for (j, &k) in basis.orders.iter().enumerate() {
                let (sn, cs) = (k as f64 * x).sin_cos();
                c[2 * j] = cs;
                c[2 * j + 1] = sn;
            }
            sigma * (&b * &c).norm()
        })
        .collect()
}

/// The readings' noise per sample without any model: the third divided difference of four
/// consecutive readings, `e_n = Σ_i w_i·r_i`, `w_i = 1/Π_{j≠i}(t_i − t_j)` (`i, j` over
/// `n … n+3`), is zero for any quadratic in time — a coast's steady deceleration leaves nothing
/// in it — and of white noise `σ` has the variance `σ²·Σ w_i²`. So `σ̂² = mean_n e_n²/Σ w_i²`,
/// a little above the noise where the motion's jerk or the encoder's error curves within a few
/// samples (a high order at the fast start of a coast): a residual judged against it is never
/// taken for structure too early.
///
/// The terms are computed eight samples side by side (with AVX where the CPU has it: four
/// divisions to an instruction) and summed in order: the same bits as one at a time.
pub fn readings_noise(t: &[f64], r: &[f64]) -> f64 {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx") {
        #[target_feature(enable = "avx")]
        unsafe fn avx(t: &[f64], r: &[f64]) -> f64 {
            third_differences(t, r)
        }
        // SAFETY: the CPU has AVX.
        return unsafe { avx(t, r) };
    }
    third_differences(t, r)
}

/// Samples whose third differences [`readings_noise`] computes side by side.
const NOISE_LANES: usize = 8;

#[inline(always)]
fn third_differences(t: &[f64], r: &[f64]) -> f64 {
    const L: usize = NOISE_LANES;
    let n = t.len().min(r.len()).saturating_sub(3);
    let (mut sum, mut count) = (0.0, 0usize);
    // The sum stays in a register: nothing in this loop calls a function (copying a block of
    // a length not fixed, as the last one is, called `memmove`, and the sum was stored and
    // loaded around it every sample).
    let whole = n / L * L;
    for first in (0..whole).step_by(L) {
        let tb = t[first..first + L + 3].try_into().expect("a block's times");
        let rb = r[first..first + L + 3]
            .try_into()
            .expect("a block's readings");
        let (term, ascending) = noise_terms(tb, rb);
        for l in 0..L {
            if ascending[l] {
                sum += term[l];
                count += 1;
            }
        }
    }
    if whole < n {
        // The last block padded with zeros, whose lanes are computed and left out.
        let (mut tb, mut rb) = ([0.0; L + 3], [0.0; L + 3]);
        let lanes = n - whole;
        tb[..lanes + 3].copy_from_slice(&t[whole..n + 3]);
        rb[..lanes + 3].copy_from_slice(&r[whole..n + 3]);
        let (term, ascending) = noise_terms(&tb, &rb);
        for l in 0..lanes {
            if ascending[l] {
                sum += term[l];
                count += 1;
            }
        }
    }
    if count == 0 {
        0.0
    } else {
        (sum / count as f64).sqrt()
    }
}

/// The terms `e_n²/Σ w_i²` of [`readings_noise`] for the samples `n = 0..NOISE_LANES` of a block
/// of times and readings, and whether each one's four times ascend (a term whose times do not
/// is left out).
#[inline(always)]
fn noise_terms(
    tb: &[f64; NOISE_LANES + 3],
    rb: &[f64; NOISE_LANES + 3],
) -> ([f64; NOISE_LANES], [bool; NOISE_LANES]) {
    const L: usize = NOISE_LANES;
    let (mut e, mut w2) = ([0.0; L], [0.0; L]);
    for i in 0..4 {
        let mut p = [1.0; L];
        for j in (0..4).filter(|&j| j != i) {
            for l in 0..L {
                p[l] *= tb[l + i] - tb[l + j];
            }
        }
        for l in 0..L {
            let w = 1.0 / p[l];
            // The weights sum to zero: readings relative to the first keep the precision.
            e[l] += w * (rb[l + i] - rb[l]);
            w2[l] += w * w;
        }
    }
    let (mut term, mut ascending) = ([0.0; L], [false; L]);
    for l in 0..L {
        term[l] = e[l] * e[l] / w2[l];
        ascending[l] = !(0..3).any(|i| tb[l + i + 1] <= tb[l + i]);
    }
    (term, ascending)
}

/// The ascending union of two ascending order lists.
fn union(a: &[usize], b: &[usize]) -> Vec<usize> {
    let mut u: Vec<usize> = a.iter().chain(b).copied().collect();
    u.sort_unstable();
    u.dedup();
    u
}

/// The screening fit: motion of degree `degree` and every order `1..=h`, then the significance
/// rule on each order's pair of coefficients.
#[derive(Debug, Clone)]
struct Screen {
    /// Orders kept.
    kept: Vec<usize>,
    /// The motion's Chebyshev coefficients.
    motion: Vec<f64>,
    /// The RMS over the circle of what the dropped orders hold: `sqrt(½·(P + s_P))` with
    /// `P = Σ_dropped (a_k² + b_k² − var a_k − var b_k)` the unbiased estimate of their power and
    /// `s_P` its standard deviation (`var |x|² = 4v² + 4v|μ|²` per order), rad. The estimate
    /// alone is as noisy as it is large when many orders hold little; one standard deviation
    /// above it makes it a one-sided 84 % bound that does not vanish with the noise.
    dropped: f64,
    /// The detection limit of the orders tested, rad: `sqrt(T·v_min)`, `v_min` the variance of
    /// each coefficient at the best-determined order ([`detection::detection_limit`]).
    detection_limit: f64,
}

fn screen_orders(
    moments: &Moments,
    span: (f64, f64),
    degree: usize,
    h: usize,
    drag: Option<DragWeights>,
) -> Option<Screen> {
    let basis = Basis {
        t0: span.0,
        t1: span.1,
        degree,
        orders: (1..=h).collect(),
        drag,
    };
    let fit = Fit::new(moments, &basis)?;
    let threshold = significance_threshold(h);
    let f = degree + 1;
    let mut kept = Vec::new();
    let (mut power, mut power_var) = (0.0, 0.0);
    let mut v_min = f64::INFINITY;
    for k in 1..=h {
        let (c, s) = (f + 2 * (k - 1), f + 2 * k - 1);
        v_min = v_min.min(0.5 * fit.sigma.powi(2) * (fit.covariance(c, c) + fit.covariance(s, s)));
        if fit.chi_square(c, s) > threshold {
            kept.push(k);
        } else {
            let noise = fit.sigma.powi(2) * (fit.covariance(c, c) + fit.covariance(s, s));
            let excess = fit.beta[c].powi(2) + fit.beta[s].powi(2) - noise;
            power += excess;
            // var |x|² = 4v² + 4v|μ|² for a pair of variance v each and mean μ.
            let v = 0.5 * noise;
            power_var += 4.0 * v * v + 4.0 * v * excess.max(0.0);
        }
    }
    Some(Screen {
        kept,
        motion: fit.beta[..=degree].to_vec(),
        dropped: ((power + power_var.sqrt()).max(0.0) / 2.0).sqrt(),
        detection_limit: detection::detection_limit(threshold, v_min),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_median_step_is_the_sorted_steps_middle_one() {
        // Steps with many repeats (a regular clock), jitter and a few gaps.
        // More than two pieces of steps, counted on any threads.
        let mut t = vec![0.0];
        let mut state = 12_345u64;
        for i in 0..2 * STEP_PIECE + 10_001 {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            let step = match state >> 61 {
                0 => 1e-3 + (state >> 20) as f64 * 1e-25,
                1 if i % 97 == 0 => 0.5,
                _ => 1e-3,
            };
            t.push(t[i] + step);
        }
        let median = |t: &[f64]| {
            let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
            d.sort_by(f64::total_cmp);
            d[(t.len() - 1) / 2]
        };
        for len in [3, 4, 1000, 10_000, STEP_PIECE + 1, STEP_PIECE + 2, t.len()] {
            assert_eq!(
                median_step(&t[..len]).to_bits(),
                median(&t[..len]).to_bits()
            );
            assert_eq!(
                radix_step(&t[..len], (len - 1) / 2).to_bits(),
                median(&t[..len]).to_bits()
            );
        }
        // The bracket found it on the long runs; a clock whose every 251st step is long shows
        // the subsample only long steps: the bracket misses, and the radix selection answers.
        assert!(bracketed_step(&t, (t.len() - 1) / 2).is_some());
        let mut t = vec![0.0];
        for i in 0..100_000 {
            let step = if i % STEP_SAMPLE == 0 { 0.25 } else { 1e-3 };
            t.push(t[i] + step);
        }
        assert!(bracketed_step(&t, (t.len() - 1) / 2).is_none());
        assert_eq!(median_step(&t).to_bits(), median(&t).to_bits());
        // Jittered steps all distinct: the median among the kept ones.
        let mut state = 99u64;
        let mut t = vec![0.0];
        for i in 0..1_000_000 {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            t.push(t[i] + 1e-3 * (1.0 + (state >> 11) as f64 / (1u64 << 53) as f64));
        }
        assert!(bracketed_step(&t, (t.len() - 1) / 2).is_some());
        for len in [400 * STEP_SAMPLE, 400 * STEP_SAMPLE + 1, t.len()] {
            assert_eq!(
                median_step(&t[..len]).to_bits(),
                median(&t[..len]).to_bits()
            );
        }
    }

    #[test]
    fn the_noise_side_by_side_is_the_noise_one_at_a_time() {
        // Each sample's term as the equation reads, summed in order.
        let one_at_a_time = |t: &[f64], r: &[f64]| {
            let (mut sum, mut count) = (0.0, 0usize);
            for n in 0..t.len().saturating_sub(3) {
                let (ts, rs) = (&t[n..n + 4], &r[n..n + 4]);
                if ts.windows(2).any(|w| w[1] <= w[0]) {
                    continue;
                }
                let (mut e, mut w2) = (0.0, 0.0);
                for i in 0..4 {
                    let w = 1.0
                        / (0..4)
                            .filter(|&j| j != i)
                            .map(|j| ts[i] - ts[j])
                            .product::<f64>();
                    e += w * (rs[i] - rs[0]);
                    w2 += w * w;
                }
                sum += e * e / w2;
                count += 1;
            }
            if count == 0 {
                0.0
            } else {
                (sum / count as f64).sqrt()
            }
        };
        // A jittered clock with a repeated time (skipped) and noisy readings of a coast.
        let mut state = 7u64;
        let mut next = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut t: Vec<f64> = (0..1003)
            .map(|i| 1e-4 * (i as f64 + 0.3 * next()))
            .collect();
        t[500] = t[499];
        let r: Vec<f64> = t
            .iter()
            .map(|&t| 60.0 * t - 2.0 * t * t + 1e-6 * next())
            .collect();
        for len in [0, 3, 4, 11, 12, 13, 1003] {
            let (t, r) = (&t[..len], &r[..len]);
            let got = readings_noise(t, r);
            assert_eq!(
                got.to_bits(),
                one_at_a_time(t, r).to_bits(),
                "{len} samples"
            );
            assert!(len < 12 || got > 0.0);
        }
    }

    #[test]
    fn the_inverse_is_the_substitution_as_built_and_inverts() {
        // Well-conditioned lower-triangular matrices with zeros below the diagonal, of sizes
        // around the vectors' width.
        for n in [1, 2, 3, 5, 8, 37] {
            let l = DMatrix::from_fn(n, n, |i, j| match (i, j) {
                (i, j) if i < j => 0.0,
                (i, j) if i == j => 2.0 + (i as f64 * 0.37).sin(),
                (i, j) if (i + j) % 5 == 0 => 0.0,
                (i, j) => ((i * 7 + j * 3) as f64).cos() / n as f64,
            });
            let inv = lower_triangular_inverse(&l);
            for j in 0..n {
                let portable = substitute(l.as_slice(), n, j);
                for i in 0..n {
                    assert_eq!(inv[(i, j)].to_bits(), portable[i].to_bits(), "n = {n}");
                }
            }
            let identity = &l * &inv;
            for i in 0..n {
                for j in 0..n {
                    let want = if i == j { 1.0 } else { 0.0 };
                    assert!((identity[(i, j)] - want).abs() < 1e-14, "n = {n}");
                }
            }
        }
    }
}
