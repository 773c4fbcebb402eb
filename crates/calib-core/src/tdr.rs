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
//! and is solved by one linear least-squares fit (normal equations, Cholesky, one step of
//! iterative refinement; no Gauss–Newton is needed). Circular closure fixes the gauge: `E` is
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
//! # What it cannot separate: angle-dependent drag
//! If a torque that depends on the angle acts on the coasting shaft — rolling-element bearings,
//! motor cogging, an unbalanced rotor — its motion is no longer smooth in time. With the
//! deceleration `ω̇ = −F(ω) − Σ a_h cos(hθ + φ_h)` and `θ = θ₀ + δ`, `θ₀` the smooth coast,
//! `δ̈ ≈ −a_h cos(hθ₀ + φ_h)`; for `hω ≫ F′(ω)` and a slowly varying `ω` this gives
//!
//! `δ(t) ≈ a_h/(h·ω(t))² · cos(hθ₀ + φ_h)`                                                (2)
//!
//! — periodic in angle like an encoder error, added to it in (1). A least-squares fit with
//! constant coefficients takes its mean over the samples (uniform in time): the map's order `h`
//! is off by `a_h/h² · ⟨ω⁻²⟩` ([`TdrCalibration::drag_gain`] `= ⟨ω⁻²⟩`). This is why the CSRR
//! paper finds TDR inaccurate on rolling bearings (its Table IV: > 56″ off). As a diagnostic the
//! fit is repeated with each order also allowed an amplitude proportional to
//! `ω(t)⁻²/⟨ω⁻²⟩ − 1` (the signature of (2)); a significant amplitude there is reported per order
//! in [`TdrCalibration::speed_dependence`] and warned about. It is only a diagnostic: the map is
//! not corrected, since real bearing drag is not strictly periodic in shaft angle (balls and
//! cage turn at non-integer orders), so (2) does not hold term by term.
//!
//! # Other limits
//! No absolute offset (the gauge); orders above [`TdrOptions::max_order`] are not modelled and
//! orders near or above half the samples per revolution at the peak speed are poorly determined
//! (a warning says so). The motion must be free: a driven constant-speed plateau is skipped, and
//! a log without falling speed is refused ([`TdrError`]).
//!
//! # Streaming
//! [`Tdr::push`] keeps of each sample only its time and unwrapped reading (16 bytes; 24 with a
//! reference channel): the log itself is not kept, and the fit reads these pairs a few times
//! (normal equations for all candidate degrees in one pass, then one pass per candidate).

use crate::angle::{ARCSEC_PER_RAD, Unwrapper};
use crate::error_map::ErrorMap;
use crate::harmonics::{FourierSeries, Harmonic};
use nalgebra::{DMatrix, DVector};
use std::f64::consts::TAU;

/// The statement of what a spin-down calibration cannot separate, for reports.
pub const DRAG_AMBIGUITY: &str = "TDR cannot tell encoder error from an angle-dependent drag torque (rolling-element bearings, motor cogging, unbalance): a deceleration a_h·cos(hθ+φ) shakes the coasting shaft by a_h/(h·ω)² at order h, periodic in angle like the encoder's error, and the map's order h absorbs a_h/h²·⟨ω⁻²⟩. Trust the map only on an air or fluid bearing with no motor coupled, or check it against a reference (--ref).";

/// Settings of a spin-down calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct TdrOptions {
    /// Highest order of the error map (default 32).
    pub max_order: usize,
    /// Degree of the motion's Chebyshev series; `None` (default) chooses it by BIC.
    pub motion_degree: Option<usize>,
    /// Grid points of the map (default 3600).
    pub points: usize,
    /// Fewest revolutions of coast accepted (default 10).
    pub min_revolutions: f64,
    /// The coast ends where the speed falls below this fraction of its peak (default 0.1): at
    /// low speed drag effects (2) grow as ω⁻², and a shaft coming to rest stops abruptly.
    pub min_speed_fraction: f64,
}

impl Default for TdrOptions {
    fn default() -> Self {
        TdrOptions {
            max_order: 32,
            motion_degree: None,
            points: 3600,
            min_revolutions: 10.0,
            min_speed_fraction: 0.1,
        }
    }
}

/// Why a log gives no spin-down calibration. Each says what to record instead.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TdrError {
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
    /// The least-squares problem is singular.
    #[error(
        "the fit is underdetermined ({unknowns} unknowns from {samples} samples of the coast): lower --max-order or the motion degree"
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

/// A spin-down calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct TdrCalibration {
    /// The encoder's error map (function of its reading, zero mean), radians.
    pub map: ErrorMap,
    /// The map as a Fourier series.
    pub series: FourierSeries,
    /// The fitted motion.
    pub motion: TdrMotion,
    /// RMS of the fit's residuals, radians (noise and resolution; more means an unmodelled
    /// effect).
    pub residual_rms: f64,
    /// Samples of the coast used.
    pub samples_used: usize,
    /// Revolutions of the coast used.
    pub revolutions: f64,
    /// Speed at the start of the coast used, rad/s (a magnitude; see `direction`).
    pub speed_start: f64,
    /// Speed at the end of the coast used, rad/s.
    pub speed_end: f64,
    /// `+1` for increasing readings, `−1` for decreasing.
    pub direction: f64,
    /// `⟨ω⁻²⟩` over the samples used, s²: a drag deceleration `a_h` (rad/s²) at order `h` shifts
    /// the map's order `h` by `a_h·drag_gain/h²` radians (module docs, eq. 2).
    pub drag_gain: f64,
    /// Orders whose amplitude changes with speed as angle-dependent drag would make it, with
    /// uncertainty; only those significant (> 4 u and > 0.01″).
    pub speed_dependence: Vec<SpeedDependence>,
    /// The check against a reference channel, when one was pushed.
    pub reference: Option<ReferenceCheck>,
    /// What the user should know.
    pub warnings: Vec<String>,
    /// What the method cannot separate ([`DRAG_AMBIGUITY`]), for reports.
    pub ambiguity: &'static str,
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

    /// Finds the coast, fits motion and map, and checks them.
    pub fn finish(self) -> Result<TdrCalibration, TdrError> {
        let coast = find_coast(&self.t, &self.r, &self.opts)?;
        let (i0, i1) = (coast.first, coast.end);
        let t = &self.t[i0..i1];
        let r = &self.r[i0..i1];
        let h = self.opts.max_order;
        let mut warnings = Vec::new();
        if self.skipped > 0 {
            warnings.push(format!(
                "{} samples skipped (non-finite values or times that do not increase)",
                self.skipped
            ));
        }
        if coast.plateau_s > 0.0 {
            warnings.push(format!(
                "the first {:.2} s after the peak speed hold the speed (a driven plateau?) and were not used",
                coast.plateau_s
            ));
        }
        let per_rev_at_peak = TAU / (coast.peak_speed * median_step(t));
        if (h as f64) > 0.5 * per_rev_at_peak {
            warnings.push(format!(
                "--max-order {h} is above half the {per_rev_at_peak:.0} samples per revolution at the peak speed: the highest orders are poorly determined; sample faster or lower --max-order"
            ));
        }

        let max_degree = match self.opts.motion_degree {
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
        };
        let basis = Basis {
            t0: t[0],
            t1: t[t.len() - 1],
            degree: max_degree,
            max_order: h,
            weight: None,
        };
        let unknowns = max_degree + 1 + 2 * h;
        if 4 * unknowns > t.len() {
            return Err(TdrError::Underdetermined {
                unknowns,
                samples: t.len(),
            });
        }
        let y0 = r[0];
        let y: Vec<f64> = r.iter().map(|v| v - y0).collect();
        let normal = basis.normal_equations(t, r, &y);
        let fourier: Vec<usize> = (max_degree + 1..unknowns).collect();
        let columns = |p: usize| -> Vec<usize> { (0..=p).chain(fourier.iter().copied()).collect() };
        let degree = match self.opts.motion_degree {
            Some(p) => p,
            None => {
                let n = t.len() as f64;
                let mut best: Option<(f64, usize)> = None;
                for p in 2..=max_degree {
                    let cols = columns(p);
                    let Some(beta) = normal.solve(&cols, None) else {
                        continue;
                    };
                    let rss = basis.rss(t, r, &y, &cols, &beta);
                    let bic = n * (rss / n).max(1e-300).ln() + cols.len() as f64 * n.ln();
                    if best.is_none_or(|(b, _)| bic < b) {
                        best = Some((bic, p));
                    }
                }
                best.map_or(max_degree, |(_, p)| p)
            }
        };
        let cols = columns(degree);
        let beta = normal
            .solve(&cols, None)
            .map(|b| basis.refine(t, r, &y, &cols, &normal, b))
            .ok_or(TdrError::Underdetermined {
                unknowns: cols.len(),
                samples: t.len(),
            })?;
        let rss = basis.rss(t, r, &y, &cols, &beta);
        let residual_rms = (rss / t.len() as f64).sqrt();

        let mut series = FourierSeries::zeros(h);
        for k in 0..h {
            series.cos[k] = beta[degree + 1 + 2 * k];
            series.sin[k] = beta[degree + 2 + 2 * k];
        }
        let map = ErrorMap::from_series(&series, self.opts.points);
        let motion = TdrMotion {
            degree,
            t_start: basis.t0,
            t_end: basis.t1,
            angle_origin: y0,
            coefficients: beta[..=degree].to_vec(),
        };
        let speed = |t: f64| (motion.eval(t).1).abs();
        let drag_gain = t.iter().map(|&ti| speed(ti).powi(-2)).sum::<f64>() / t.len() as f64;
        let (speed_start, speed_end) = (speed(basis.t0), speed(basis.t1));

        let speed_dependence =
            speed_dependence(t, r, &y, &basis, degree, drag_gain, &motion, residual_rms);
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

        let mixed = !self.reference.is_empty() && self.reference.len() != self.r.len();
        if mixed {
            warnings.push(
                "a reference reading came with only some samples (push and push_with_reference mixed): the reference check is skipped".to_string(),
            );
        }
        let reference = (!self.reference.is_empty() && !mixed).then(|| {
            let d: Vec<f64> = (i0..i1).map(|i| self.r[i] - self.reference[i]).collect();
            reference_check(r, &d, h, &map)
        });

        Ok(TdrCalibration {
            map,
            series,
            motion,
            residual_rms,
            samples_used: t.len(),
            revolutions: coast.revolutions,
            speed_start,
            speed_end,
            direction: coast.direction,
            drag_gain,
            speed_dependence,
            reference,
            warnings,
            ambiguity: DRAG_AMBIGUITY,
        })
    }
}

/// The coast found in a log: sample range `[first, end)` and its figures.
#[derive(Debug, Clone, PartialEq)]
struct Coast {
    first: usize,
    end: usize,
    peak_speed: f64,
    direction: f64,
    revolutions: f64,
    plateau_s: f64,
}

/// Finds the coast: the log is cut into windows (at most 256, at least 8 samples each) whose mean
/// speeds are compared. From the fastest window, a plateau within 0.1 % of the peak speed (a
/// drive still on) is skipped, and the window where it ends; the coast then runs until the speed falls below
/// [`TdrOptions::min_speed_fraction`] of the peak, rises again by more than 1 % of the peak above
/// its lowest value so far (the drive back on), or the log ends.
fn find_coast(t: &[f64], r: &[f64], opts: &TdrOptions) -> Result<Coast, TdrError> {
    let n = t.len();
    if n < 128 {
        return Err(TdrError::TooFewSamples { count: n });
    }
    let (lo, hi) = r
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        });
    if hi - lo < TAU {
        return Err(TdrError::Stationary {
            travel_deg: (hi - lo).to_degrees(),
        });
    }
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
        direction,
        revolutions,
        plateau_s: if start > k0 {
            t[bound(start)] - t[bound(k0)]
        } else {
            0.0
        },
    })
}

/// The median time step, seconds.
fn median_step(t: &[f64]) -> f64 {
    let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    let mid = d.len() / 2;
    d.select_nth_unstable_by(mid, f64::total_cmp);
    d[mid]
}

/// `(f, f′, f″)` of `f(τ) = Σ c_j T_j(τ)` by the recurrences `T_{j+1} = 2τT_j − T_{j−1}`,
/// `T′_{j+1} = 2T_j + 2τT′_j − T′_{j−1}`, `T″_{j+1} = 4T′_j + 2τT″_j − T″_{j−1}`.
fn chebyshev_with_derivatives(c: &[f64], tau: f64) -> (f64, f64, f64) {
    let (mut t0, mut t1) = (1.0, tau);
    let (mut d0, mut d1) = (0.0, 1.0);
    let (mut s0, mut s1) = (0.0, 0.0);
    let mut out = (0.0, 0.0, 0.0);
    for (j, &cj) in c.iter().enumerate() {
        let (tj, dj, sj) = if j == 0 { (t0, d0, s0) } else { (t1, d1, s1) };
        out.0 += cj * tj;
        out.1 += cj * dj;
        out.2 += cj * sj;
        if j >= 1 {
            let t2 = 2.0 * tau * t1 - t0;
            let d2 = 2.0 * t1 + 2.0 * tau * d1 - d0;
            let s2 = 4.0 * d1 + 2.0 * tau * s1 - s0;
            (t0, t1, d0, d1, s0, s1) = (t1, t2, d1, d2, s1, s2);
        }
    }
    out
}

/// The columns of the fit (1): `T_0..T_p(τ)`, then `cos kr, sin kr` for `k = 1..H`, then (for
/// the speed-dependence diagnostic) `w(t)·cos kr, w(t)·sin kr` with `w = ω⁻²/⟨ω⁻²⟩ − 1`.
#[derive(Debug, Clone)]
struct Basis {
    t0: f64,
    t1: f64,
    degree: usize,
    max_order: usize,
    /// The motion and `⟨ω⁻²⟩` defining `w(t)`.
    weight: Option<(TdrMotion, f64)>,
}

impl Basis {
    fn len(&self) -> usize {
        self.degree + 1 + if self.weight.is_some() { 4 } else { 2 } * self.max_order
    }

    fn row(&self, t: f64, r: f64, out: &mut [f64]) {
        let tau = (2.0 * t - self.t0 - self.t1) / (self.t1 - self.t0);
        out[0] = 1.0;
        if self.degree >= 1 {
            out[1] = tau;
        }
        for j in 2..=self.degree {
            out[j] = 2.0 * tau * out[j - 1] - out[j - 2];
        }
        let f = self.degree + 1;
        let (s1, c1) = r.sin_cos();
        let (mut s, mut c) = (0.0, 1.0);
        for k in 0..self.max_order {
            (s, c) = (s * c1 + c * s1, c * c1 - s * s1);
            out[f + 2 * k] = c;
            out[f + 2 * k + 1] = s;
        }
        if let Some((motion, gain)) = &self.weight {
            let w = motion.eval(t).1.powi(-2) / gain - 1.0;
            let g = f + 2 * self.max_order;
            for k in 0..2 * self.max_order {
                out[g + k] = w * out[f + k];
            }
        }
    }

    /// `AᵀA` and `Aᵀy` over all samples, in one pass.
    fn normal_equations(&self, t: &[f64], r: &[f64], y: &[f64]) -> Normal {
        let n = self.len();
        let mut g = vec![0.0; n * n];
        let mut rhs = vec![0.0; n];
        let mut row = vec![0.0; n];
        for i in 0..t.len() {
            self.row(t[i], r[i], &mut row);
            for a in 0..n {
                let ra = row[a];
                rhs[a] += ra * y[i];
                let line = &mut g[a * n..(a + 1) * n];
                for b in a..n {
                    line[b] += ra * row[b];
                }
            }
        }
        let g = DMatrix::from_fn(
            n,
            n,
            |a, b| if a <= b { g[a * n + b] } else { g[b * n + a] },
        );
        Normal {
            g,
            rhs: DVector::from_vec(rhs),
        }
    }

    /// The residuals `y − Aβ` of the columns `cols`, passed to `each`.
    fn residuals(
        &self,
        t: &[f64],
        r: &[f64],
        y: &[f64],
        cols: &[usize],
        beta: &[f64],
        mut each: impl FnMut(&[f64], f64),
    ) {
        let mut row = vec![0.0; self.len()];
        for i in 0..t.len() {
            self.row(t[i], r[i], &mut row);
            let fit: f64 = cols.iter().zip(beta).map(|(&c, b)| row[c] * b).sum();
            each(&row, y[i] - fit);
        }
    }

    /// Residual sum of squares.
    fn rss(&self, t: &[f64], r: &[f64], y: &[f64], cols: &[usize], beta: &[f64]) -> f64 {
        let mut sum = 0.0;
        self.residuals(t, r, y, cols, beta, |_, e| sum += e * e);
        sum
    }

    /// One step of iterative refinement: solves for the correction from the exact residuals,
    /// which removes the rounding the normal equations add for readings of many revolutions.
    fn refine(
        &self,
        t: &[f64],
        r: &[f64],
        y: &[f64],
        cols: &[usize],
        normal: &Normal,
        beta: Vec<f64>,
    ) -> Vec<f64> {
        let mut rhs = vec![0.0; cols.len()];
        self.residuals(t, r, y, cols, &beta, |row, e| {
            for (k, &c) in cols.iter().enumerate() {
                rhs[k] += row[c] * e;
            }
        });
        match normal.solve(cols, Some(&rhs)) {
            Some(d) => beta.iter().zip(&d).map(|(b, d)| b + d).collect(),
            None => beta,
        }
    }
}

/// Normal equations of the largest column set; fits use sub-blocks of them.
#[derive(Debug, Clone)]
struct Normal {
    g: DMatrix<f64>,
    rhs: DVector<f64>,
}

impl Normal {
    fn sub(&self, cols: &[usize]) -> DMatrix<f64> {
        DMatrix::from_fn(cols.len(), cols.len(), |a, b| self.g[(cols[a], cols[b])])
    }

    /// The least-squares coefficients of columns `cols` (in that order), for the stored
    /// right-hand side or for `rhs` (already restricted to `cols`). `None` if singular.
    fn solve(&self, cols: &[usize], rhs: Option<&[f64]>) -> Option<Vec<f64>> {
        let chol = self.sub(cols).cholesky()?;
        let b = match rhs {
            Some(v) => DVector::from_column_slice(v),
            None => DVector::from_fn(cols.len(), |a, _| self.rhs[cols[a]]),
        };
        let x = chol.solve(&b);
        x.iter()
            .all(|v| v.is_finite())
            .then(|| x.iter().copied().collect())
    }
}

/// The speed-dependence diagnostic (module docs): refit with the columns `w(t)·{cos, sin} kr`
/// added and keep the orders whose amplitude there is significant.
#[allow(clippy::too_many_arguments)]
fn speed_dependence(
    t: &[f64],
    r: &[f64],
    y: &[f64],
    basis: &Basis,
    degree: usize,
    drag_gain: f64,
    motion: &TdrMotion,
    sigma: f64,
) -> Vec<SpeedDependence> {
    let ext = Basis {
        degree,
        weight: Some((motion.clone(), drag_gain)),
        ..basis.clone()
    };
    let n = ext.len();
    let normal = ext.normal_equations(t, r, y);
    let cols: Vec<usize> = (0..n).collect();
    let Some(beta) = normal.solve(&cols, None) else {
        return Vec::new();
    };
    let Some(inverse) = normal.g.clone().cholesky().map(|c| c.inverse()) else {
        return Vec::new();
    };
    let g = degree + 1 + 2 * basis.max_order;
    (0..basis.max_order)
        .filter_map(|k| {
            let (a, b) = (beta[g + 2 * k], beta[g + 2 * k + 1]);
            let var =
                0.5 * (inverse[(g + 2 * k, g + 2 * k)] + inverse[(g + 2 * k + 1, g + 2 * k + 1)]);
            let u = sigma * var.sqrt();
            let harmonic = Harmonic::from_coefficients(k + 1, a, b);
            (harmonic.amplitude > 4.0 * u && harmonic.amplitude * ARCSEC_PER_RAD > 0.01)
                .then_some(SpeedDependence { harmonic, u })
        })
        .collect()
}

/// Fits `d = c + Σ a_k cos kr + b_k sin kr` (DUT − reference against the DUT's reading) and
/// compares the map with the TDR map.
fn reference_check(r: &[f64], d: &[f64], max_order: usize, tdr: &ErrorMap) -> ReferenceCheck {
    let basis = Basis {
        t0: -1.0,
        t1: 1.0,
        degree: 0,
        max_order,
        weight: None,
    };
    let d0 = d[0];
    let y: Vec<f64> = d.iter().map(|v| v - d0).collect();
    let zeros = vec![0.0; r.len()];
    let normal = basis.normal_equations(&zeros, r, &y);
    let cols: Vec<usize> = (0..basis.len()).collect();
    let mut series = FourierSeries::zeros(max_order);
    if let Some(beta) = normal.solve(&cols, None) {
        for k in 0..max_order {
            series.cos[k] = beta[1 + 2 * k];
            series.sin[k] = beta[2 + 2 * k];
        }
    }
    let map = ErrorMap::from_series(&series, tdr.len());
    let diff = tdr.minus(&map);
    ReferenceCheck {
        max_abs_diff_arcsec: diff.max_abs_arcsec(),
        rms_diff_arcsec: diff.rms() * ARCSEC_PER_RAD,
        map,
    }
}
