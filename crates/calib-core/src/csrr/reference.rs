//! Checks of a CSRR calibration against a reference encoder (`calib csrr --ref NAME`).
//!
//! With a reference encoder on rotor B's shaft (the seed paper's RON886, section III), the log
//! itself tells:
//!
//! - each sensor's map against the reference: `x − r` binned by `x` (and `y − r` by `y`), the
//!   session's offset removed, compared with the calibrated map (the reference's own error, ±1″
//!   for the paper's encoder, is part of the difference);
//! - the sampling non-uniformity `ε_θ` (eq. 9): over the steady revolutions of each session the
//!   reference reading is fitted as `r(t) = a + ω·t + p(r)`, a straight line in time plus a
//!   profile `p` periodic in the angle (one value per bin). Eliminating `p` leaves
//!   `ω = Σ_i Σ_{n∈i}(r − r̄_i)(t − t̄_i) / Σ_i Σ_{n∈i}(t − t̄_i)²` over the bins `i`, and
//!   `p_i = r̄_i − ω·t̄_i` up to a constant: a line fitted alone would absorb part of the order-1
//!   term over a few revolutions and leak a sawtooth into every order. `ε_θ` is reported as the
//!   spectrum `m_Ω` of `p` in cycles per revolution;
//! - the effective-range indicator `|Y_Ω| = 0.5·π·Ω·m_Ω` (eqs. 18–20) with `Ω = 2π·h` per
//!   revolution, i.e. `|Y_h| = π²·h·m_h` (m in rad) — the form that reproduces the paper's
//!   Table V (h = 810, m = 11.71″ → 0.454) — and the paper method's predicted residual
//!   `|Y_h|·A_h` for each sensor's harmonic `A_h`. The paper method is reliable where
//!   `|Y_h| < 1 %` or `A_h` is small (Fig. 2); the joint method does not use time stamps and is
//!   not affected.
//! - the first-order residual of the same mechanism, `½·h·m_h·A_h = |Y_h|·A_h / (2π²)`. Eq. 14
//!   gives the DC shift of `A cos(hθ + φ)` sampled at `θ(n) = nθ₀ + m sin(hnθ₀)` as
//!   `π·Ω·m·A·cos φ` in the units of its Fourier transform, where a constant `c` is `2π·c·δ(ω)`:
//!   an angle of `½·Ω·m·A·cos φ`, with `Ω` the order per radian (the Bessel argument of eq. 11
//!   is `h·m`). Table V's `|Y|` takes `Ω = 2π·h` and compares the transform-domain `F_JΩ`
//!   with an angle (eq. 20), which together make `|Y|·A` 2π² times the first-order shift. The
//!   simulator reproduces the first-order figure (`tests/it/csrr_accuracy.rs`); both are reported,
//!   `|Y|` as published.

use crate::angle::{ARCSEC_PER_RAD, Unwrapper, wrap_2pi, wrap_pi};
use crate::error_map::ErrorMap;
use crate::harmonics::FourierSeries;
use crate::segment::SessionSink;
use realfft::RealFftPlanner;
use std::f64::consts::{PI, TAU};

/// Bins of the reference comparison over one revolution: 40″ wide, so that comparing a bin's
/// mean with the map at the bin's mean angle errs by `e″·w²/24` ≈ 0.05″ for ±700″ at order 84.
const MAP_BINS: usize = 32768;
/// Bins of the ε_θ profile over one revolution (orders up to 1023).
const EPS_BINS: usize = 2048;
/// A revolution is steady when its speed in the first and last quarter differ by less than this.
const STEADY: f64 = 0.10;

#[derive(Debug, Clone)]
struct MapBins {
    sum: Vec<f64>,
    sum_angle: Vec<f64>,
    n: Vec<f64>,
}

impl MapBins {
    fn new() -> Self {
        MapBins {
            sum: vec![0.0; MAP_BINS],
            sum_angle: vec![0.0; MAP_BINS],
            n: vec![0.0; MAP_BINS],
        }
    }
    fn add(&mut self, angle: f64, value: f64) {
        let i = ((angle / TAU * MAP_BINS as f64) as usize).min(MAP_BINS - 1);
        self.sum[i] += value;
        self.sum_angle[i] += angle;
        self.n[i] += 1.0;
    }
    /// The occupied bins `(index, sum, angle sum, count)`, and resets them.
    fn take_compact(&mut self) -> Vec<(u32, f64, f64, f64)> {
        let out = (0..MAP_BINS)
            .filter(|&i| self.n[i] > 0.0)
            .map(|i| (i as u32, self.sum[i], self.sum_angle[i], self.n[i]))
            .collect();
        *self = MapBins::new();
        out
    }
    /// Adds a session's compact bins with `offset` subtracted from every value.
    fn add_compact(&mut self, bins: &[(u32, f64, f64, f64)], offset: f64) {
        for &(i, sum, angle, n) in bins {
            let i = i as usize;
            self.sum[i] += sum - n * offset;
            self.sum_angle[i] += angle;
            self.n[i] += n;
        }
    }
    fn points(&self) -> Vec<(f64, f64)> {
        (0..MAP_BINS)
            .filter(|&i| self.n[i] > 0.0)
            .map(|i| (self.sum_angle[i] / self.n[i], self.sum[i] / self.n[i]))
            .collect()
    }
}

/// Per-bin sums of one session's steady samples for the ε_θ fit.
#[derive(Debug, Clone)]
struct EpsBins {
    n: Vec<f64>,
    t: Vec<f64>,
    r: Vec<f64>,
    tt: Vec<f64>,
    tr: Vec<f64>,
}

impl EpsBins {
    fn new() -> Self {
        let z = vec![0.0; EPS_BINS];
        EpsBins {
            n: z.clone(),
            t: z.clone(),
            r: z.clone(),
            tt: z.clone(),
            tr: z,
        }
    }
    fn add(&mut self, angle: f64, t: f64, r: f64) {
        let i = ((angle / TAU * EPS_BINS as f64) as usize).min(EPS_BINS - 1);
        self.n[i] += 1.0;
        self.t[i] += t;
        self.r[i] += r;
        self.tt[i] += t * t;
        self.tr[i] += t * r;
    }
    /// The session's profile `p_i` (see the module docs), added into `sum` weighted by counts.
    fn merge_into(&self, sum: &mut [f64], count: &mut [f64]) {
        let (mut num, mut den) = (0.0, 0.0);
        for i in 0..EPS_BINS {
            if self.n[i] > 1.0 {
                num += self.tr[i] - self.t[i] * self.r[i] / self.n[i];
                den += self.tt[i] - self.t[i] * self.t[i] / self.n[i];
            }
        }
        if den <= 0.0 {
            return;
        }
        let omega = num / den;
        let profile: Vec<Option<f64>> = (0..EPS_BINS)
            .map(|i| (self.n[i] > 0.0).then(|| (self.r[i] - omega * self.t[i]) / self.n[i]))
            .collect();
        let known: Vec<f64> = profile.iter().flatten().copied().collect();
        let mean = known.iter().sum::<f64>() / known.len().max(1) as f64;
        for (i, p) in profile.iter().enumerate() {
            if let Some(p) = p {
                sum[i] += self.n[i] * (p - mean);
                count[i] += self.n[i];
            }
        }
    }
}

/// One session's bins against the reference.
#[derive(Debug, Clone)]
struct SessionBins {
    id: usize,
    a: Vec<(u32, f64, f64, f64)>,
    b: Vec<(u32, f64, f64, f64)>,
    offsets: (f64, f64),
}

/// A [`SessionSink`] that expects the reference reading as the first extra channel.
#[derive(Debug)]
pub struct ReferenceAccumulator {
    session: Option<usize>,
    origin: (f64, f64),
    unwrap: Unwrapper,
    off_a: f64,
    off_b: f64,
    a: MapBins,
    b: MapBins,
    /// Per accepted session: its compact bins of A and B against the reference, and the offsets
    /// `(x − r, y − r)` of its first sample that were taken off them.
    done: Vec<SessionBins>,
    rev: Vec<(f64, f64, f64)>,
    rev_index: Option<i64>,
    eps: EpsBins,
    eps_sum: Vec<f64>,
    eps_count: Vec<f64>,
}

impl Default for ReferenceAccumulator {
    fn default() -> Self {
        ReferenceAccumulator {
            session: None,
            origin: (0.0, 0.0),
            unwrap: Unwrapper::new(),
            off_a: 0.0,
            off_b: 0.0,
            a: MapBins::new(),
            b: MapBins::new(),
            done: Vec::new(),
            rev: Vec::new(),
            rev_index: None,
            eps: EpsBins::new(),
            eps_sum: vec![0.0; EPS_BINS],
            eps_count: vec![0.0; EPS_BINS],
        }
    }
}

impl ReferenceAccumulator {
    /// A new accumulator.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds a whole revolution to the session's line fit and ε_θ bins if its speed was steady.
    fn flush_revolution(&mut self) {
        let rev = std::mem::take(&mut self.rev);
        if rev.len() < 8 {
            return;
        }
        let q = rev.len() / 4;
        let speed =
            |s: &[(f64, f64, f64)]| (s[s.len() - 1].1 - s[0].1) / (s[s.len() - 1].0 - s[0].0);
        let (v0, v1) = (speed(&rev[..q.max(2)]), speed(&rev[rev.len() - q.max(2)..]));
        if !(v0.is_finite() && v1.is_finite()) || (v0 - v1).abs() > STEADY * v0.abs().max(v1.abs())
        {
            return;
        }
        for &(t, r, raw) in &rev {
            self.eps.add(raw, t, r);
        }
    }

    fn close_session(&mut self) {
        self.done.push(SessionBins {
            id: self.session.unwrap_or_default(),
            a: self.a.take_compact(),
            b: self.b.take_compact(),
            offsets: (self.off_a, self.off_b),
        });
        self.eps.merge_into(&mut self.eps_sum, &mut self.eps_count);
        self.eps = EpsBins::new();
        self.rev.clear();
        self.rev_index = None;
        self.session = None;
    }

    /// The checks, given the calibrated maps.
    ///
    /// `deltas` are the sessions' ids and relative rotations `Δ_k` (rad): A reads
    /// `x − r = e_a − e_ref + Δ_k`, so they are what separates A's map from the session offsets.
    /// Sessions without a `Δ_k` are left out.
    pub fn finish(self, a: &ErrorMap, b: &ErrorMap, deltas: &[(usize, f64)]) -> ReferenceCheck {
        let (mut a_all, mut b_all) = (MapBins::new(), MapBins::new());
        let first_b = self.done.first().map_or(0.0, |s| s.offsets.1);
        for s in &self.done {
            if let Some(&(_, delta)) = deltas.iter().find(|(id, _)| *id == s.id) {
                a_all.add_compact(&s.a, wrap_pi(delta - s.offsets.0));
                b_all.add_compact(&s.b, wrap_pi(first_b - s.offsets.1));
            }
        }
        let diff = |bins: &MapBins, map: &ErrorMap| -> f64 {
            let pts = bins.points();
            if pts.is_empty() {
                return f64::NAN;
            }
            let d: Vec<f64> = pts
                .iter()
                .map(|&(ang, v)| map.eval_linear(ang) - v)
                .collect();
            let mean = d.iter().sum::<f64>() / d.len() as f64;
            d.iter().fold(0.0f64, |m, v| m.max((v - mean).abs())) * ARCSEC_PER_RAD
        };
        let eps_theta = eps_spectrum(&self.eps_sum, &self.eps_count);
        let (sa, sb) = (a.series(), b.series());
        let amplitude = |s: &FourierSeries, h: usize| {
            if h <= s.max_order() {
                s.cos[h - 1].hypot(s.sin[h - 1])
            } else {
                0.0
            }
        };
        let indicators = eps_theta
            .iter()
            .map(|e| {
                let y = PI * PI * e.order as f64 * e.amplitude_arcsec / ARCSEC_PER_RAD;
                let (pa, pb) = (
                    y * amplitude(&sa, e.order) * ARCSEC_PER_RAD,
                    y * amplitude(&sb, e.order) * ARCSEC_PER_RAD,
                );
                let first_order = 1.0 / (2.0 * PI * PI);
                EffectiveRange {
                    order: e.order,
                    y,
                    predicted_a_arcsec: pa,
                    predicted_b_arcsec: pb,
                    first_order_a_arcsec: pa * first_order,
                    first_order_b_arcsec: pb * first_order,
                }
            })
            .collect();
        ReferenceCheck {
            a_max_diff_arcsec: diff(&a_all, a),
            b_max_diff_arcsec: diff(&b_all, b),
            a_vs_reference: a_all.points(),
            b_vs_reference: b_all.points(),
            eps_theta,
            effective_range: indicators,
        }
    }
}

impl SessionSink for ReferenceAccumulator {
    fn sample(&mut self, session: usize, t: f64, x: f64, y: f64, _d: f64, extra: &[f64]) {
        let Some(&r_raw) = extra.first() else { return };
        if self.session != Some(session) {
            if self.session.is_some() {
                self.close_session();
            }
            self.session = Some(session);
            self.unwrap = Unwrapper::new();
            self.origin = (t, self.unwrap.unwrap(r_raw));
            self.off_a = wrap_pi(x - r_raw);
            self.off_b = wrap_pi(y - r_raw);
        }
        self.a.add(x, wrap_pi(x - r_raw - self.off_a));
        self.b.add(y, wrap_pi(y - r_raw - self.off_b));
        let ru = self.unwrap.unwrap(r_raw) - self.origin.1;
        let tt = t - self.origin.0;
        let index = (ru / TAU).floor() as i64;
        if self.rev_index != Some(index) {
            // A revolution boundary: the buffered samples form a whole revolution unless this is
            // the first boundary of the session.
            if self.rev_index.is_some() && (index - self.rev_index.unwrap_or(index)).abs() == 1 {
                self.flush_revolution();
            }
            self.rev.clear();
            self.rev_index = Some(index);
        }
        self.rev.push((tt, ru, wrap_2pi(r_raw)));
    }

    fn close(&mut self, session: usize, accepted: bool) {
        if self.session == Some(session) {
            if accepted {
                self.close_session();
            } else {
                self.a = MapBins::new();
                self.b = MapBins::new();
                self.eps = EpsBins::new();
                self.rev.clear();
                self.rev_index = None;
                self.session = None;
            }
        }
    }
}

/// One order of the sampling non-uniformity.
#[derive(
    Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema,
)]
pub struct EpsHarmonic {
    /// Cycles per revolution.
    pub order: usize,
    /// Amplitude `m_h` of ε_θ, arcsec.
    pub amplitude_arcsec: f64,
}

/// The paper's effective-range indicator at one order.
#[derive(
    Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema,
)]
pub struct EffectiveRange {
    /// Cycles per revolution.
    pub order: usize,
    /// `|Y_h| = π²·h·m_h` (dimensionless).
    pub y: f64,
    /// `|Y_h|·A_h` for sensor A: the paper method's predicted residual at this order as
    /// published (eqs. 18–20, Table V), arcsec.
    pub predicted_a_arcsec: f64,
    /// The same for sensor B, arcsec.
    pub predicted_b_arcsec: f64,
    /// `½·h·m_h·A_h = |Y_h|·A_h / (2π²)` for sensor A: the first-order residual of position
    /// modulation (eq. 14 in angle units), arcsec.
    pub first_order_a_arcsec: f64,
    /// The same for sensor B, arcsec.
    pub first_order_b_arcsec: f64,
}

/// What the reference encoder says about a calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceCheck {
    /// Largest |A's calibrated map − A against the reference|, mean removed, arcsec.
    pub a_max_diff_arcsec: f64,
    /// The same for B.
    pub b_max_diff_arcsec: f64,
    /// A's error against the reference: `(A's reading, error)` per bin, rad.
    pub a_vs_reference: Vec<(f64, f64)>,
    /// B's error against the reference.
    pub b_vs_reference: Vec<(f64, f64)>,
    /// The 10 largest orders of ε_θ.
    pub eps_theta: Vec<EpsHarmonic>,
    /// `|Y_h|` and predicted residuals at those orders.
    pub effective_range: Vec<EffectiveRange>,
}

fn eps_spectrum(sum: &[f64], count: &[f64]) -> Vec<EpsHarmonic> {
    if count.iter().any(|&c| c <= 0.0) {
        return Vec::new();
    }
    let mut profile: Vec<f64> = sum.iter().zip(count).map(|(s, c)| s / c).collect();
    let n = profile.len();
    let fft = RealFftPlanner::<f64>::new().plan_fft_forward(n);
    let mut spec = fft.make_output_vec();
    if fft.process(&mut profile, &mut spec).is_err() {
        return Vec::new();
    }
    let mut out: Vec<EpsHarmonic> = (1..n / 2)
        .map(|h| EpsHarmonic {
            order: h,
            amplitude_arcsec: 2.0 * spec[h].norm() / n as f64 * ARCSEC_PER_RAD,
        })
        .collect();
    out.sort_by(|a, b| b.amplitude_arcsec.total_cmp(&a.amplitude_arcsec));
    out.truncate(10);
    out
}
