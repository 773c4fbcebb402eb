//! The CSRR method as published (Gou et al., the CSRR paper, section II-B).
//!
//! Per session `k`:
//! - the relative rotation is the DC component of `f_ab = x − y` over whole revolutions of sensor
//!   A (eqs. 4–5): the mean of the samples between the first and the last time A's reading passes
//!   its benchmark value `v_a`. It is a time average, so sampling non-uniformity biases it
//!   (eqs. 9–17) — kept as published, since users compare against the paper;
//! - sensor B's error is read where A crosses its benchmark (eq. 7): there the true angle is the
//!   same in every session, so `e_b(y_c) = Δ̂_k − d_c + const`, with `d_c` the relative angle
//!   interpolated at the crossing and `y_c = v_a − d_c` B's reading there; the crossings of all
//!   the session's revolutions are averaged;
//! - symmetrically, sensor A's error where B crosses its benchmark `v_b`:
//!   `e_a(x_c) = d_c − Δ̂_k + const`, `x_c = v_b + d_c`.
//!
//! Each session thus gives one point of each map; the maps are the periodic linear interpolation
//! of those points, mean removed. Orders above half the number of sessions cannot be resolved
//! (Nyquist over the Δ grid), which is why the method needs many sessions densely covering
//! 0…360°.
//!
//! The maps' standard uncertainty (`uncertainty`) is built from what the same pass collects:
//! the spread of each session's crossings (the points' noise), each session's relative-angle
//! profile projected on orders up to `PROFILE_ORDERS` (what lies between the points, and
//! above the session grid's Nyquist limit), and the bias of `Δ̂_k` against the profile's mean
//! over the angle (ε_θ). See `docs/uncertainty.md`.

use super::CsrrError;
use crate::angle::{wrap_2pi, wrap_pi};
use crate::error_map::ErrorMap;
use crate::segment::SessionSink;
use crate::uncertainty::{Evaluation, MapComponent, MapUncertainty};
use realfft::RealFftPlanner;
use realfft::num_complex::Complex;
use std::f64::consts::TAU;

/// One session's contribution: a point of each map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PaperPoint {
    /// Session id.
    pub session: usize,
    /// The DC relative rotation `Δ̂_k`, rad.
    pub delta: f64,
    /// B's reading where A crossed its benchmark, rad.
    pub b_angle: f64,
    /// B's error there (up to a constant), rad.
    pub b_error: f64,
    /// A's reading where B crossed its benchmark, rad.
    pub a_angle: f64,
    /// A's error there (up to a constant), rad.
    pub a_error: f64,
}

/// The highest order of a session's relative-angle profile `f_ab` that is projected (also at
/// most half the session's samples per revolution).
const PROFILE_ORDERS: usize = 512;

/// Bins of a profile over A's reading. A sample's phase `e^{−ihx}` is taken about its bin's
/// centre to second order, so the remainder is at most `(h·π/BINS)³/6` of its term: 1.3·10⁻³
/// at order 512.
const PROFILE_BINS: usize = 8192;

/// A session's relative-angle profile over A's reading, for its trapezoidal Fourier sums
/// (see [`Profile::finish`]). Projecting every sample on every order would cost 512 complex
/// multiply-adds per sample; instead each sample adds to the moments of its bin,
/// `S_j = Σ ω_n (d_n − d_ref)·δ_n^j` (`δ_n = x_n − x_c`, `j = 0, 1, 2`), and the sums are made
/// once, by FFT, from `e^{−ihx_n} = e^{−ihx_c}·(1 − ihδ_n − h²δ_n²/2 + …)`.
#[derive(Debug, Clone)]
struct Profile {
    /// `[S₀, S₁, S₂]` of each bin.
    bins: Vec<[f64; 3]>,
    /// The bins added to since the last [`commit`](Self::commit) (a bin may be listed twice).
    touched: Vec<u32>,
    /// `Σ ω_n (d_n − d_ref)` and `Σ ω_n`.
    dc: f64,
    span: f64,
}

impl Default for Profile {
    fn default() -> Self {
        Profile {
            bins: vec![[0.0; 3]; PROFILE_BINS],
            touched: Vec::new(),
            dc: 0.0,
            span: 0.0,
        }
    }
}

impl Profile {
    /// Adds a sample of weight `weight` at reading `x ∈ [0, 2π)`.
    fn add(&mut self, weight: f64, x: f64, d: f64) {
        let width = TAU / PROFILE_BINS as f64;
        let bin = ((x / width) as usize).min(PROFILE_BINS - 1);
        let delta = x - (bin as f64 + 0.5) * width;
        let wd = weight * d;
        let b = &mut self.bins[bin];
        if *b == [0.0; 3] {
            self.touched.push(bin as u32);
        }
        b[0] += wd;
        b[1] += wd * delta;
        b[2] += wd * delta * delta;
        self.dc += wd;
        self.span += weight;
    }

    /// Moves what was added since the last commit into `whole` (the profile over whole
    /// revolutions, as it stood at A's latest crossing): `O(samples added)`, not `O(bins)`.
    fn commit(&mut self, whole: &mut Profile) {
        for &bin in &self.touched {
            let (from, to) = (&mut self.bins[bin as usize], &mut whole.bins[bin as usize]);
            for (t, f) in to.iter_mut().zip(from.iter_mut()) {
                *t += *f;
                *f = 0.0;
            }
        }
        self.touched.clear();
        whole.dc += std::mem::take(&mut self.dc);
        whole.span += std::mem::take(&mut self.span);
    }

    /// The profile's mean over the circle (`d_ref` added back) and its complex amplitudes `c_h`
    /// at orders `1 … orders` (`f_ab ≈ c₀ + Re Σ c_h e^{ihx}`, `orders` ≤ `PROFILE_ORDERS`):
    /// the trapezoidal rule over the samples' own readings, `c_h = 2·Σ ω_n d_n e^{−ihx_n} / Σ ω_n`
    /// over whole revolutions.
    fn finish(&self, d_ref: f64, orders: usize) -> Option<(f64, Vec<Complex<f64>>)> {
        if self.span == 0.0 {
            return None;
        }
        let orders = orders.min(PROFILE_ORDERS);
        let fft = RealFftPlanner::<f64>::new().plan_fft_forward(PROFILE_BINS);
        let moments: Vec<Vec<Complex<f64>>> = (0..3)
            .map(|j| {
                let mut input: Vec<f64> = self.bins.iter().map(|b| b[j]).collect();
                let mut output = fft.make_output_vec();
                fft.process(&mut input, &mut output).ok()?;
                Some(output)
            })
            .collect::<Option<_>>()?;
        let scale = 2.0 / self.span;
        let half_bin = std::f64::consts::PI / PROFILE_BINS as f64;
        let amplitudes = (1..=orders)
            .map(|h| {
                let hf = h as f64;
                // Σ_b e^{−ihx_c}·(S₀ − ihS₁ − h²S₂/2), x_c = (b + ½)·2π/BINS.
                let taylor = moments[0][h]
                    - Complex::new(0.0, hf) * moments[1][h]
                    - moments[2][h] * (0.5 * hf * hf);
                taylor * Complex::from_polar(scale, -hf * half_bin)
            })
            .collect();
        Some((d_ref + self.dc / self.span, amplitudes))
    }
}

#[derive(Debug, Default, Clone)]
struct Open {
    id: usize,
    prev: Option<(f64, f64, f64)>,
    cum_d: f64,
    cum_n: f64,
    /// `(cum_d, cum_n)` at A's first and latest benchmark crossing.
    first_a: Option<(f64, f64)>,
    last_a: Option<(f64, f64)>,
    /// The relative angle at each of A's and of B's benchmark crossings.
    at_a: Vec<f64>,
    at_b: Vec<f64>,
    /// The sample before the previous one, `(x, d)`, for the trapezoidal weights.
    before: Option<(f64, f64)>,
    /// The relative angle at the session's first sample: the profile is summed about it.
    d_ref: f64,
    /// The profile since A's latest crossing, and over the whole revolutions before it.
    profile: Profile,
    profile_at_last: Profile,
}

/// What one session tells of its point's noise and of the content between the points, for the
/// paper method's uncertainty (`uncertainty`).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct SessionStats {
    /// `Σ (d − d̄)²` over A's benchmark crossings, and its degrees of freedom (crossings − 1).
    spread_a: (f64, f64),
    /// The same over B's crossings.
    spread_b: (f64, f64),
    /// Crossings of A and of B.
    crossings: (f64, f64),
    /// Samples in the whole revolutions that `Δ̂_k` averages.
    delta_samples: f64,
    /// Samples in the relative-angle profile.
    samples: f64,
    /// `Δ̂_k` minus the profile's mean over A's reading: the bias of the time average.
    eps_bias: f64,
    /// Complex amplitudes of the profile `f_ab(x)` at orders `1…`, rad.
    profile: Vec<Complex<f64>>,
}

/// A [`SessionSink`] collecting the paper method's per-session quantities as the log streams.
#[derive(Debug, Default)]
pub(crate) struct PaperAccumulator {
    bench_a: f64,
    bench_b: f64,
    open: Option<Open>,
    points: Vec<PaperPoint>,
    stats: Vec<SessionStats>,
    no_crossing: Vec<usize>,
}

/// The fraction `f ∈ [0, 1)` of the step `from → to` at which a wrapped reading passes `v`,
/// if it does (steps are taken as the short way round).
fn crossing(from: f64, to: f64, v: f64) -> Option<f64> {
    let step = wrap_pi(to - from);
    let before = wrap_pi(from - v);
    if step == 0.0 {
        return None;
    }
    let f = -before / step;
    (0.0..1.0).contains(&f).then_some(f)
}

impl PaperAccumulator {
    /// Benchmark values of A and B, rad.
    pub(crate) fn new(bench_a: f64, bench_b: f64) -> Self {
        PaperAccumulator {
            bench_a: wrap_2pi(bench_a),
            bench_b: wrap_2pi(bench_b),
            ..Default::default()
        }
    }

    /// Each session's point with its statistics, and the sessions in which a sensor never
    /// crossed its benchmark over a whole revolution.
    pub(crate) fn into_points(self) -> (Vec<PaperPoint>, Vec<SessionStats>, Vec<usize>) {
        (self.points, self.stats, self.no_crossing)
    }
}

impl SessionSink for PaperAccumulator {
    fn sample(&mut self, session: usize, _t: f64, x: f64, y: f64, d: f64, _extra: &[f64]) {
        if self.open.as_ref().is_none_or(|o| o.id != session) {
            self.open = Some(Open {
                id: session,
                d_ref: d,
                ..Default::default()
            });
        }
        let o = self.open.as_mut().expect("set above");
        // The previous sample's trapezoidal weight is known now that its successor is; it
        // counts from A's first crossing on (whole revolutions, as `Δ̂_k`).
        if let (Some((bx, _)), Some((px, _, pd))) = (o.before, o.prev)
            && o.first_a.is_some()
        {
            o.profile.add(0.5 * wrap_pi(x - bx), px, pd - o.d_ref);
        }
        if let Some((px, py, pd)) = o.prev {
            if let Some(f) = crossing(px, x, self.bench_a) {
                // Cumulative sums up to the crossing (the fraction of this sample's weight
                // before it is negligible against whole revolutions; count it whole).
                let mark = (o.cum_d, o.cum_n);
                o.first_a.get_or_insert(mark);
                o.last_a = Some(mark);
                o.profile.commit(&mut o.profile_at_last);
                o.at_a.push(pd + f * (d - pd));
            }
            if let Some(f) = crossing(py, y, self.bench_b) {
                o.at_b.push(pd + f * (d - pd));
            }
        }
        o.cum_d += d;
        o.cum_n += 1.0;
        o.before = o.prev.map(|(px, _, pd)| (px, pd));
        o.prev = Some((x, y, d));
    }

    fn close(&mut self, session: usize, accepted: bool) {
        let Some(o) = self.open.take().filter(|o| o.id == session) else {
            return;
        };
        if !accepted {
            return;
        }
        let (Some(first), Some(last)) = (o.first_a, o.last_a) else {
            self.no_crossing.push(session);
            return;
        };
        if last.1 <= first.1 || o.at_b.is_empty() {
            self.no_crossing.push(session);
            return;
        }
        let delta = (last.0 - first.0) / (last.1 - first.1);
        let (d_a, spread_a) = mean_and_spread(&o.at_a);
        let (d_b, spread_b) = mean_and_spread(&o.at_b);
        let per_rev = (last.1 - first.1) / (o.at_a.len() - 1).max(1) as f64;
        let orders = ((per_rev / 2.0) as usize).saturating_sub(1);
        let Some((dc, profile)) = o.profile_at_last.finish(o.d_ref, orders) else {
            self.no_crossing.push(session);
            return;
        };
        self.stats.push(SessionStats {
            spread_a,
            spread_b,
            crossings: (o.at_a.len() as f64, o.at_b.len() as f64),
            delta_samples: last.1 - first.1,
            samples: o.cum_n,
            eps_bias: delta - dc,
            profile,
        });
        self.points.push(PaperPoint {
            session,
            delta,
            b_angle: wrap_2pi(self.bench_a - d_a),
            b_error: delta - d_a,
            a_angle: wrap_2pi(self.bench_b + d_b),
            a_error: d_b - delta,
        });
    }
}

/// The mean of `v` and `(Σ (v − v̄)², len − 1)`.
fn mean_and_spread(v: &[f64]) -> (f64, (f64, f64)) {
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    let ss = v.iter().map(|x| (x - mean).powi(2)).sum();
    (mean, (ss, (v.len() - 1) as f64))
}

/// How each of `points` grid points `θ_i = 2πi/points` lies between the sorted `angles`
/// (periodically): the indices of the points before and after it, its fraction `w` of the way,
/// and the span between them, rad.
struct Segment {
    lo: usize,
    hi: usize,
    w: f64,
    span: f64,
}

fn segments(angles: &[f64], points: usize) -> Vec<Segment> {
    let n = points.max(1);
    (0..n)
        .map(|i| {
            let th = TAU * i as f64 / n as f64;
            let k = angles.partition_point(|&a| a <= th);
            let (lo, hi) = if k == 0 || k == angles.len() {
                (angles.len() - 1, 0)
            } else {
                (k - 1, k)
            };
            let span = wrap_2pi(angles[hi] - angles[lo]);
            let w = if span == 0.0 {
                0.0
            } else {
                wrap_2pi(th - angles[lo]) / span
            };
            Segment { lo, hi, w, span }
        })
        .collect()
}

/// The indices of `angles` in ascending order of the wrapped angle, with the wrapped angles.
fn by_angle(angles: impl Iterator<Item = f64>) -> (Vec<usize>, Vec<f64>) {
    let mut p: Vec<(usize, f64)> = angles.map(wrap_2pi).enumerate().collect();
    p.sort_by(|a, b| a.1.total_cmp(&b.1));
    p.into_iter().unzip()
}

/// The map through `(angle, error)` points by periodic linear interpolation on `points` grid
/// points, mean removed.
pub(crate) fn map_from_points(pts: &[(f64, f64)], points: usize) -> Result<ErrorMap, CsrrError> {
    if pts.len() < 3 {
        return Err(CsrrError::PaperTooFewSessions { found: pts.len() });
    }
    let (order, angles) = by_angle(pts.iter().map(|p| p.0));
    let error: Vec<f64> = order.iter().map(|&i| pts[i].1).collect();
    let values = segments(&angles, points)
        .iter()
        .map(|s| error[s.lo] + (error[s.hi] - error[s.lo]) * s.w)
        .collect();
    Ok(ErrorMap::new(values))
}

/// Which sensor's map.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Sensor {
    A,
    B,
}

/// The standard uncertainty of A's and B's maps of `points` points made from `pts` and
/// `stats` (one per session, in the same order), with their budgets (`docs/uncertainty.md`):
///
/// - **noise of each session's point** (Type A). A's point is `d̄_B − Δ̂_k`: the mean of the
///   relative angle at B's `c_k` benchmark crossings, where the true angle is the same on every
///   revolution (eq. 7), less the time average `Δ̂_k` of `N_k` samples (eqs. 4–5). The
///   crossings' spread, pooled over the sessions, gives `s_B²` (degrees of freedom `Σ(c_k − 1)`);
///   a crossing interpolates linearly between two samples, `var = ((1−f)² + f²)σ²`, whose mean
///   over the fraction `f` is `⅔σ²`, so a sample's noise is `σ² = 1.5·s²` (pooled over both
///   sensors' crossings). `u_k² = s_B²/c_k + σ²/N_k` (B's point: `s_A²`). The map at `θ` is
///   `Σ_k (w_k(θ) − c̄_k)·p_k`, `w_k` the linear interpolation's weights (two of them nonzero)
///   and `c̄_k` their mean over the grid (the mean removal), so
///   `u_A(θ)² = Σ_k (w_k(θ) − c̄_k)²·u_k²` — the sessions' points are independent;
/// - **linear interpolation between the sessions' points** (Type B), from the harmonic
///   content of the maps the sessions' profiles show ([`harmonic_content`]). For `A·cos(hθ + φ)`
///   the error of interpolating between points a span `δ` apart, at the fraction `w`, is a
///   sinusoid in `φ` of amplitude `A·|e^{ihwδ} − (1 − w) − w·e^{ihδ}|` (≈ `A·(hδ)²·w(1−w)/2`
///   for small `hδ`, the `A·(hδ)²/8` of [`interpolation_uncertainty`] at `w = ½`). An
///   encoder's harmonics are often locked in phase (a pole pair's overtones), so the orders'
///   amplitudes are added — the largest the error can be whatever the phases — and the sum is
///   the half-width of a rectangular distribution (`/√3`, GUM 4.3.7). Orders below half the
///   number of sessions (the Nyquist limit of the session grid) and those at or above it
///   (aliased: the points cannot hold them) are two components;
/// - **sampling non-uniformity ε_θ** (Type B): `Δ̂_k` is a time average, biased by ε_θ at the
///   orders the sensors share (eqs. 9–17; to first order `½·h·m_h·A_h`, the shift
///   [`super::EffectiveRange`] reports against a reference). The bias is measured in each session
///   as `β_k = Δ̂_k − f̄_ab`, `f̄_ab` the profile's mean over A's reading (unaffected by the
///   timing of the samples); it moves A's point by `−β_k` and B's by `+β_k`, and after the mean
///   removal by `β_k − Σ_j c̄_j β_j`. The method as published does not correct it: it enters as a
///   rectangular distribution of half-width `(1 − w)·|β'_lo| + w·|β'_hi|` at each table point
///   (`/√3`, GUM 4.3.7), so `2u` covers the bias itself.
///
/// [`interpolation_uncertainty`]: crate::uncertainty::interpolation_uncertainty
///
/// `u` is never below the detection limit of the orders the sessions' profiles test
/// ([`harmonic_content`]; [`crate::detection`]): the floor is in each budget by name.
pub(crate) fn uncertainty(
    pts: &[PaperPoint],
    stats: &[SessionStats],
    points: usize,
) -> PaperUncertainty {
    let pooled = |spread: fn(&SessionStats) -> (f64, f64)| {
        stats
            .iter()
            .map(spread)
            .fold((0.0, 0.0), |(a, b), (c, d)| (a + c, b + d))
    };
    let (ss_a, dof_a) = pooled(|s| s.spread_a);
    let (ss_b, dof_b) = pooled(|s| s.spread_b);
    // A's crossings always have at least one degree of freedom (a whole revolution lies
    // between the first and the last); B's may have none.
    let s2_a = ss_a / dof_a.max(1.0);
    let s2_b = if dof_b > 0.0 { ss_b / dof_b } else { s2_a };
    let sigma2 = 1.5 * (ss_a + ss_b) / (dof_a + dof_b).max(1.0);
    let deltas: Vec<f64> = pts.iter().map(|p| p.delta).collect();
    let content = harmonic_content(stats, &deltas);
    let (content_a, content_b) = (content.a, content.b);
    let nyquist = pts.len().div_ceil(2);
    let floor = crate::detection::detection_floor(content.detection_limit);
    let map = |sensor: Sensor| {
        let (angles, var, bias, content) = match sensor {
            Sensor::A => (
                pts.iter().map(|p| p.a_angle).collect::<Vec<_>>(),
                stats
                    .iter()
                    .map(|s| s2_b / s.crossings.1 + sigma2 / s.delta_samples)
                    .collect::<Vec<_>>(),
                -1.0,
                &content_a,
            ),
            Sensor::B => (
                pts.iter().map(|p| p.b_angle).collect(),
                stats
                    .iter()
                    .map(|s| s2_a / s.crossings.0 + sigma2 / s.delta_samples)
                    .collect(),
                1.0,
                &content_b,
            ),
        };
        let (order, sorted_angles) = by_angle(angles.into_iter());
        let var: Vec<f64> = order.iter().map(|&i| var[i]).collect();
        let beta: Vec<f64> = order.iter().map(|&i| bias * stats[i].eps_bias).collect();
        let segs = segments(&sorted_angles, points);
        let mut weight = vec![0.0; sorted_angles.len()];
        for s in &segs {
            weight[s.lo] += (1.0 - s.w) / segs.len() as f64;
            weight[s.hi] += s.w / segs.len() as f64;
        }
        let base: f64 = weight.iter().zip(&var).map(|(c, v)| c * c * v).sum();
        let beta_mean: f64 = weight.iter().zip(&beta).map(|(c, b)| c * b).sum();
        let noise = segs
            .iter()
            .map(|s| {
                let (lo, hi) = (s.lo, s.hi);
                let v = base - weight[lo].powi(2) * var[lo] - weight[hi].powi(2) * var[hi]
                    + (1.0 - s.w - weight[lo]).powi(2) * var[lo]
                    + (s.w - weight[hi]).powi(2) * var[hi];
                v.max(0.0).sqrt()
            })
            .collect();
        let interpolation = |keep: &dyn Fn(usize) -> bool| -> Vec<f64> {
            segs.iter()
                .map(|s| {
                    content
                        .iter()
                        .filter(|(h, _)| keep(*h))
                        .map(|&(h, amp)| {
                            let (p, q) = (h as f64 * s.w * s.span, h as f64 * s.span);
                            let re = p.cos() - (1.0 - s.w) - s.w * q.cos();
                            let im = p.sin() - s.w * q.sin();
                            amp * re.hypot(im)
                        })
                        .sum::<f64>()
                        / 3f64.sqrt()
                })
                .collect()
        };
        let eps = segs
            .iter()
            .map(|s| {
                ((1.0 - s.w) * (beta[s.lo] - beta_mean).abs()
                    + s.w * (beta[s.hi] - beta_mean).abs())
                    / 3f64.sqrt()
            })
            .collect();
        let components = vec![
            MapComponent {
                name: "noise of the sessions' points (crossings and relative rotation) through the interpolation".into(),
                evaluation: Evaluation::TypeA,
                u: noise,
            },
            MapComponent {
                name: "linear interpolation between the sessions' points".into(),
                evaluation: Evaluation::TypeB,
                u: interpolation(&|h| h < nyquist),
            },
            MapComponent {
                name: format!(
                    "orders at or above half the number of sessions ({nyquist}), aliased by the session grid"
                ),
                evaluation: Evaluation::TypeB,
                u: interpolation(&|h| h >= nyquist),
            },
            MapComponent {
                name: "sampling non-uniformity: bias of the time-averaged relative rotation".into(),
                evaluation: Evaluation::TypeB,
                u: eps,
            },
        ];
        // A Type B component that is zero at every point (no such content) is left out.
        let components = components
            .into_iter()
            .filter(|c| c.evaluation == Evaluation::TypeA || c.u.iter().any(|&u| u > 0.0))
            .collect();
        crate::detection::apply_floor(MapUncertainty::combine(segs.len(), components), floor)
    };
    let resolved = |c: &Content| c.iter().any(|&(h, _)| h < nyquist);
    PaperUncertainty {
        a: map(Sensor::A),
        b: map(Sensor::B),
        detection_limit: content.detection_limit,
        orders: content.orders,
        resolved: resolved(&content_a) || resolved(&content_b),
    }
}

/// The paper method's budgets and what its significance rule found.
pub(crate) struct PaperUncertainty {
    /// A's and B's budgets.
    pub a: MapUncertainty,
    pub b: MapUncertainty,
    /// The detection limit of the orders the profiles test, an amplitude, rad.
    pub detection_limit: f64,
    /// Orders the profiles test (`1..=orders`).
    pub orders: usize,
    /// Whether any order the session grid resolves (below half the sessions) stands above the
    /// noise in A's or B's content: the points hold more than noise.
    pub resolved: bool,
}

/// What the maps leave of the sessions' relative-angle profiles, RMS over the circle and the
/// sessions, rad: at order `h` session `k`'s profile is `G_k = a_h − b_h·e^{−ihΔ_k}`
/// ([`harmonic_content`]), `a_h`, `b_h` the maps' complex amplitudes (`cos − i·sin`
/// coefficients), and by Parseval the misfit's mean square over the circle is
/// `Σ_h |G_k − a_h + b_h e^{−ihΔ_k}|²/2`. What the maps cannot hold (orders above the session
/// grid's Nyquist limit, orders every `hΔ_k` sees alike) stays in it; noise adds only
/// `σ·sqrt(H/N_k)`, far below the per-sample noise it is judged against.
pub(crate) fn profile_misfit(
    stats: &[SessionStats],
    deltas: &[f64],
    a: &crate::harmonics::FourierSeries,
    b: &crate::harmonics::FourierSeries,
) -> f64 {
    let amplitude = |s: &crate::harmonics::FourierSeries, h: usize| {
        if h <= s.max_order() {
            Complex::new(s.cos[h - 1], -s.sin[h - 1])
        } else {
            Complex::new(0.0, 0.0)
        }
    };
    let per_session: Vec<f64> = stats
        .iter()
        .zip(deltas)
        .map(|(st, &d)| {
            st.profile
                .iter()
                .enumerate()
                .map(|(i, g)| {
                    let h = i + 1;
                    let z = Complex::from_polar(1.0, -(h as f64) * d);
                    (g - amplitude(a, h) + amplitude(b, h) * z).norm_sqr() / 2.0
                })
                .sum::<f64>()
        })
        .collect();
    if per_session.is_empty() {
        return 0.0;
    }
    (per_session.iter().sum::<f64>() / per_session.len() as f64).sqrt()
}

/// A sensor's harmonic content: `(order, amplitude)` pairs, amplitude in rad.
type Content = Vec<(usize, f64)>;

/// The amplitudes `(order, A_h)` of A's and of B's errors that stand above the noise, from the
/// sessions' relative-angle profiles: at order `h` session `k` shows `G_k = a_h − b_h·z_k`,
/// `z_k = e^{−ihΔ_k}` (`f_ab(x) = e_a(x) − e_b(x − Δ_k) + Δ_k`), so over the `K` sessions the
/// least-squares estimates are `b_h = (S̄·ΣG_k − K·Σ z̄_k G_k)/(K² − |S|²)` and
/// `a_h = (ΣG_k + S·b_h)/K`, `S = Σ z_k`, each of their cosine and sine with the variance
/// `v·K/(K² − |S|²)`, `v` that of one session's coefficient. `v` is estimated from the fit's
/// residuals `r_k = G_k − a_h + b_h z_k`: `v_h = Σ_k |r_k|²/(2(K − 2))` at each order, and `v`
/// their median over the orders (robust to the few orders that hold more than noise). An order
/// is kept when `|a_h|²` or `|b_h|²` exceeds its variance by the significance rule of the joint
/// method ([`crate::tdr::significance_threshold`] over the `2M` amplitudes of the `M` orders).
/// Where the sessions cannot separate the two sensors (`K² − |S|² < 1 %` of `K²`: every `hΔ_k`
/// nearly equal), only `a_h − b_h·z` is seen: its mean amplitude is given to both sensors when
/// it stands above its noise `v/K`.
fn harmonic_content(stats: &[SessionStats], deltas: &[f64]) -> HarmonicContent {
    let orders = stats.iter().map(|s| s.profile.len()).min().unwrap_or(0);
    let k = stats.len() as f64;
    struct Fit {
        h: usize,
        a: Complex<f64>,
        b: Complex<f64>,
        /// `K/(K² − |S|²)`, or `None` where the sensors cannot be separated.
        gain: Option<f64>,
    }
    let mut residual_var = Vec::with_capacity(orders);
    let fits: Vec<Fit> = (1..=orders)
        .map(|h| {
            let z: Vec<Complex<f64>> = deltas
                .iter()
                .map(|d| Complex::from_polar(1.0, -(h as f64) * d))
                .collect();
            let g: Vec<Complex<f64>> = stats.iter().map(|s| s.profile[h - 1]).collect();
            let s: Complex<f64> = z.iter().sum();
            let sum_g: Complex<f64> = g.iter().sum();
            let det = k * k - s.norm_sqr();
            if det < 0.01 * k * k {
                let mean = sum_g / k;
                return Fit {
                    h,
                    a: mean,
                    b: mean,
                    gain: None,
                };
            }
            let sum_zg: Complex<f64> = z.iter().zip(&g).map(|(z, g)| z.conj() * g).sum();
            let b = (s.conj() * sum_g - sum_zg * k) / det;
            let a = (sum_g + s * b) / k;
            let rss: f64 = z
                .iter()
                .zip(&g)
                .map(|(z, g)| (g - a + b * z).norm_sqr())
                .sum();
            residual_var.push(rss / (2.0 * (k - 2.0)).max(1.0));
            Fit {
                h,
                a,
                b,
                gain: Some(k / det),
            }
        })
        .collect();
    residual_var.sort_by(f64::total_cmp);
    let v = residual_var
        .get(residual_var.len() / 2)
        .copied()
        .unwrap_or(0.0);
    let threshold = crate::tdr::significance_threshold(2 * orders);
    let (mut a, mut b) = (Vec::new(), Vec::new());
    let mut v_min = f64::INFINITY;
    for f in fits {
        let var = f.gain.map_or(v / k, |g| v * g);
        v_min = v_min.min(var);
        if f.a.norm_sqr().max(f.b.norm_sqr()) > threshold * var {
            a.push((f.h, f.a.norm()));
            b.push((f.h, f.b.norm()));
        }
    }
    HarmonicContent {
        a,
        b,
        detection_limit: crate::detection::detection_limit(threshold, v_min),
        orders,
    }
}

/// A's and B's content ([`harmonic_content`]), with the detection limit of its rule (an
/// amplitude, rad) and the orders it tested.
struct HarmonicContent {
    a: Content,
    b: Content,
    detection_limit: f64,
    orders: usize,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crossings_are_found_across_the_wrap() {
        let v = 0.0;
        assert!(crossing(TAU - 0.1, 0.1, v).is_some_and(|f| (f - 0.5).abs() < 1e-12));
        assert!(crossing(0.1, 0.3, v).is_none());
        assert!(crossing(0.3, 0.1, 0.2).is_some_and(|f| (f - 0.5).abs() < 1e-9));
    }

    /// Two revolutions of unevenly spaced samples (jittered by ±30 % of a step) of
    /// `0.3 + 10⁻⁴·cos(3x + 0.5)`: the trapezoidal sums give the mean and the order-3 amplitude
    /// to 10⁻³ of the harmonic's size (the rule's error is `O((hδ)²)` times the jitter), and
    /// nothing at the other orders.
    #[test]
    fn the_profile_recovers_a_harmonic_from_unevenly_spaced_samples() {
        let n = 1400;
        let step = 2.0 * TAU / n as f64;
        let x = |k: i64| k as f64 * step + 0.3 * step * (1.7 * k.rem_euclid(n) as f64).sin();
        let f = |x: f64| 1e-4 * (3.0 * x + 0.5).cos();
        let mut p = Profile::default();
        for k in 0..n {
            p.add(0.5 * (x(k + 1) - x(k - 1)), wrap_2pi(x(k)), f(x(k)));
        }
        let (dc, c) = p.finish(0.3, 10).unwrap();
        assert!((dc - 0.3).abs() < 1e-7, "{dc}");
        let want = Complex::from_polar(1e-4, 0.5);
        assert!((c[2] - want).norm() < 1e-7, "{:?}", c[2]);
        for (h, c) in c.iter().enumerate().filter(|(h, _)| *h != 2) {
            assert!(c.norm() < 1e-7, "order {}: {c}", h + 1);
        }
    }

    #[test]
    fn points_interpolate_periodically() {
        let pts = [(0.0, 1.0), (TAU / 3.0, -1.0), (2.0 * TAU / 3.0, 0.0)];
        let m = map_from_points(&pts, 6).unwrap();
        // Grid at 0, 60°, 120°, 180°, 240°, 300°: 1, 0, −1, −0.5, 0, 0.5 before mean removal.
        let want = [1.0, 0.0, -1.0, -0.5, 0.0, 0.5];
        for (v, w) in m.values().iter().zip(want) {
            assert!((v - w).abs() < 1e-12, "{:?}", m.values());
        }
    }
}
