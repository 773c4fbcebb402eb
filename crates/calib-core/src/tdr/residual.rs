//! What the final fit leaves: the residual's periodic structure above the orders fitted, and the
//! check of the map against a reference encoder.

use super::chebyshev::chebyshev_lanes;
use super::moments::{Moments, Samples};
use super::{Basis, CoastBin, Fit, ReferenceCheck, significance_threshold};
use crate::angle::ARCSEC_PER_RAD;
use crate::error_map::ErrorMap;
use crate::harmonics::{FourierSeries, Harmonic};
use crate::nufft;
use crate::nufft2d::BLOCK;
use rayon::prelude::*;
use std::f64::consts::TAU;
use std::ops::Range;
use std::sync::OnceLock;

/// Samples whose motion is evaluated side by side.
const LANES: usize = 16;

/// Samples per piece of [`projections`]: a multiple of [`BLOCK`], small enough that two cores
/// finish their last pieces close together (~0.01 s each), large enough that each piece's grid
/// (`8·G` bytes, 1 MB at order 2000) is cleared and added only 20 times per 10⁷ samples.
const PROJECTION_PIECE: usize = 1 << 19;

/// Bytes of the pieces' grids [`projections`] holds at once (at least two grids).
const GRIDS_HELD: usize = 32 << 20;

/// Points per revolution of the tables the residual's periodic parts are interpolated from:
/// cubic interpolation of an order `k` errs by about `0.023·(2πk/TABLE)⁴` of its amplitude,
/// 10⁻⁷ at order 500 — far below the noise for the residual's projection.
const TABLE: usize = 1 << 16;

/// Intervals of the tables of the drag's weights over the coast's normalized time.
const WEIGHT_TABLE: usize = 4096;

/// What the final fit leaves, from one evaluation of its residuals over the samples:
///
/// - the residual's periodic structure at `orders`: each order's residual projected on
///   `e^{ikr}` over the samples, `z_k = Σ e_n e^{ikr_n}` (one non-uniform FFT), amplitude
///   `2|z_k|/N`; under white noise `2|z_k|²/(Nσ²)` is a chi-square of 2 degrees of freedom, and
///   the orders that pass the significance rule are returned, largest first;
/// - the coast in `bins` intervals of equal samples (fewer on a short coast): each interval's
///   mean speed and the residuals over it, for a report to draw against time.
///
/// The residuals are summed a block of samples at a time, each block in order by itself, and
/// the blocks in order: the same bits on any number of threads.
pub(super) fn residual_and_trace(
    s: Samples,
    basis: &Basis,
    fit: &Fit,
    orders: std::ops::RangeInclusive<usize>,
    bins: usize,
) -> (Vec<Harmonic>, Vec<CoastBin>) {
    let (lo, hi) = (*orders.start(), *orders.end());
    let model = Model::new(basis, fit);
    let trace = Trace::new(s.len(), bins);
    let residuals = |range: Range<usize>, points: &mut Vec<(f64, f64, [f64; 1])>| {
        let from = points.len();
        model.points(s, range.clone(), points);
        trace.record(range, points[from..].iter().map(|p| p.2[0]));
    };
    if hi < lo || fit.sigma <= 0.0 {
        (0..s.len().div_ceil(BLOCK))
            .into_par_iter()
            .for_each_init(Vec::new, |points, b| {
                points.clear();
                residuals(b * BLOCK..((b + 1) * BLOCK).min(s.len()), points);
            });
        return (Vec::new(), trace.bins(s));
    }
    let orders: Vec<usize> = (lo..=hi).collect();
    let (re, im) = projections(s.len(), &orders, residuals);
    let n = s.len() as f64;
    let sigma2 = fit.rss / n;
    let threshold = significance_threshold(hi - lo + 1);
    let mut found: Vec<Harmonic> = orders
        .iter()
        .zip(re.iter().zip(&im))
        .filter(|&(_, (&re, &im))| 2.0 * (re * re + im * im) / (n * sigma2) > threshold)
        .map(|(&k, (&re, &im))| Harmonic::from_coefficients(k, 2.0 * re / n, 2.0 * im / n))
        .collect();
    found.sort_by(|a, b| b.amplitude.total_cmp(&a.amplitude));
    (found, trace.bins(s))
}

/// `z_k = Σ_n e_n·e^{ikr_n}` of the residuals `e_n` at the readings `r_n` for `orders` (real and
/// imaginary parts), the points `(0, r_n, [e_n])` given a [`BLOCK`] at a time by `fill`.
///
/// Each residual is spread onto a uniform grid of `G ≥ 64·k_max` points over a revolution with
/// the 6-point Lagrange weights of the CSRR solver's transform ([`crate::nufft`]), and one real
/// FFT of the grid gives `z_k`: the transpose of interpolating `e^{ikr}` from the grid, which
/// errs by at most `(2πk/G)⁶·0.0098 ≤ 9·10⁻⁹` of each sample's term, so
/// `|z_k − exact| ≤ 9·10⁻⁹·Σ|e_n|` — for `N` residuals of RMS `σ` about `10⁻⁸·N·σ`, far below
/// the `√N·σ` the significance test compares with (5·10⁻⁵ of it at `N = 10⁷`, still 10⁻³ at
/// 10¹⁰). The 2-D transform's kernel (`2·16·13` multiply-adds a sample for 10⁻¹³) spent twice
/// the time here for digits the test cannot use.
///
/// The samples are cut into pieces of [`PROJECTION_PIECE`], each spread in order into its own
/// grid on the rayon pool (at most [`GRIDS_HELD`] bytes of them at once), the grids added in the
/// pieces' order: the same bits on any number of threads.
fn projections(
    len: usize,
    orders: &[usize],
    fill: impl Fn(Range<usize>, &mut Vec<(f64, f64, [f64; 1])>) + Sync,
) -> (Vec<f64>, Vec<f64>) {
    let top = orders.iter().copied().max().unwrap_or(1);
    let grid = (64 * top).next_power_of_two();
    let per_radian = grid as f64 / TAU;
    // The pieces' grids in waves of at most `GRIDS_HELD` bytes, each added in the pieces' order.
    let pieces = len.div_ceil(PROJECTION_PIECE);
    let wave = (GRIDS_HELD / (8 * grid)).max(2);
    let mut q = vec![0.0; grid];
    for first in (0..pieces).step_by(wave) {
        let grids: Vec<Vec<f64>> = (first..(first + wave).min(pieces))
            .into_par_iter()
            .with_max_len(1)
            .map(|piece| {
                let mut q = vec![0.0; grid];
                let mut points = Vec::with_capacity(BLOCK);
                let end = ((piece + 1) * PROJECTION_PIECE).min(len);
                for start in (piece * PROJECTION_PIECE..end).step_by(BLOCK) {
                    points.clear();
                    fill(start..(start + BLOCK).min(end), &mut points);
                    scatter(&mut q, &points, per_radian);
                }
                q
            })
            .collect();
        for g in &grids {
            for (q, g) in q.iter_mut().zip(g) {
                *q += g;
            }
        }
    }
    let (mut re, mut im) = (vec![0.0; orders.len()], vec![0.0; orders.len()]);
    nufft::GridTransform::new(grid).analyze_transpose(&mut q, orders, &mut re, &mut im);
    (re, im)
}

/// Adds each point's residual times its stencil's weights to the grid `q`. On x86-64 CPUs with
/// AVX (detected at run time) compiled for it: the stencil's `floor` becomes one instruction
/// instead of a call (SSE2 has none), the same bits.
fn scatter(q: &mut [f64], points: &[(f64, f64, [f64; 1])], per_radian: f64) {
    #[inline(always)]
    fn each(q: &mut [f64], points: &[(f64, f64, [f64; 1])], per_radian: f64) {
        let grid = q.len();
        for &(_, r, [e]) in points {
            let (first, w) = nufft::stencil(r, per_radian, grid);
            nufft::scatter_one(q, first, &w, e);
        }
    }
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx") {
        #[target_feature(enable = "avx")]
        unsafe fn avx(q: &mut [f64], points: &[(f64, f64, [f64; 1])], per_radian: f64) {
            each(q, points, per_radian);
        }
        // SAFETY: the CPU has AVX.
        return unsafe { avx(q, points, per_radian) };
    }
    each(q, points, per_radian);
}

/// The residuals' sum, least and greatest over the part of an interval in one block of samples.
#[derive(Debug, Clone, Copy)]
struct Part {
    bin: usize,
    sum: f64,
    min: f64,
    max: f64,
}

/// The coast's intervals `k·n/bins .. (k + 1)·n/bins`, gathered a block of [`BLOCK`] samples at a
/// time from any thread.
struct Trace {
    n: usize,
    bins: usize,
    /// Per block, its parts of the intervals it overlaps, in order.
    blocks: Vec<OnceLock<Vec<Part>>>,
}

impl Trace {
    fn new(n: usize, bins: usize) -> Trace {
        Trace {
            n,
            bins: bins.min(n / 2).max(1),
            blocks: (0..n.div_ceil(BLOCK)).map(|_| OnceLock::new()).collect(),
        }
    }

    /// The first sample of interval `k` (or `n` for `k = bins`).
    fn start(&self, k: usize) -> usize {
        k * self.n / self.bins
    }

    /// The residuals of the samples `range`, one block.
    fn record(&self, range: Range<usize>, residuals: impl Iterator<Item = f64>) {
        // Interval k holds sample i when start(k) ≤ i < start(k + 1), i.e. k·n < (i + 1)·bins.
        let mut bin = ((range.start + 1) * self.bins - 1) / self.n;
        let mut parts = Vec::with_capacity(2);
        let (mut first, mut residuals) = (range.start, residuals);
        while first < range.end {
            let end = self.start(bin + 1).min(range.end);
            let (sum, min, max) = summary(residuals.by_ref().take(end - first));
            parts.push(Part { bin, sum, min, max });
            (first, bin) = (end, bin + 1);
        }
        // Each block is recorded once; a second recording would hold the same values.
        let _ = self.blocks[range.start / BLOCK].set(parts);
    }

    /// The intervals, from the parts of every block (blocks never recorded count for nothing).
    fn bins(self, s: Samples) -> Vec<CoastBin> {
        let mut acc = vec![(0.0, f64::INFINITY, f64::NEG_INFINITY); self.bins];
        for part in self.blocks.iter().filter_map(OnceLock::get).flatten() {
            let a = &mut acc[part.bin];
            a.0 += part.sum;
            a.1 = a.1.min(part.min);
            a.2 = a.2.max(part.max);
        }
        acc.into_iter()
            .enumerate()
            .filter_map(|(k, (sum, min, max))| {
                let (first, end) = (self.start(k), self.start(k + 1));
                let last = end.checked_sub(1)?;
                let dt = s.t[last] - s.t[first];
                if last <= first || dt <= 0.0 {
                    return None;
                }
                Some(CoastBin {
                    t: 0.5 * (s.t[first] + s.t[last]),
                    speed: ((s.r[last] - s.r[first]) / dt).abs(),
                    residual_mean: sum / (end - first) as f64,
                    residual_min: min,
                    residual_max: max,
                })
            })
            .collect()
    }
}

/// The sum, the least and the greatest of `residuals`, in their order. Out of line, so that
/// the three stay in registers: inlined into the residuals' pass they went through memory at
/// every sample, and the intervals took 1.6 times as long.
#[inline(never)]
fn summary(residuals: impl Iterator<Item = f64>) -> (f64, f64, f64) {
    residuals.fold(
        (0.0, f64::INFINITY, f64::NEG_INFINITY),
        |(sum, min, max), e| (sum + e, min.min(e), max.max(e)),
    )
}

/// The final fit as a function of a sample: the motion's series, the map, and the drag
/// `w(τ)·A(r) + v(τ)·B(r)` with `A = Σ p_h cos hr + q_h sin hr`, `B = Σ (p_h sin hr − q_h cos hr)/h`
/// (eq. 3 regrouped), the periodic parts and the weights tabulated.
struct Model {
    motion: Vec<f64>,
    map: Periodic,
    drag: Option<DragModel>,
}

struct DragModel {
    a: Periodic,
    b: Periodic,
    w: Vec<f64>,
    v: Vec<f64>,
}

impl Model {
    fn new(basis: &Basis, fit: &Fit) -> Model {
        let f = basis.degree + 1;
        let top = basis.top().max(1);
        let mut map = FourierSeries::zeros(top);
        for (i, &k) in basis.orders.iter().enumerate() {
            map.cos[k - 1] = fit.beta[f + 2 * i];
            map.sin[k - 1] = fit.beta[f + 2 * i + 1];
        }
        let drag = basis.drag.as_ref().map(|d| {
            let (mut a, mut b) = (FourierSeries::zeros(top), FourierSeries::zeros(top));
            for (i, &h) in d.orders.iter().enumerate() {
                let (p, q) = (
                    fit.beta[basis.drag_column(i)],
                    fit.beta[basis.drag_column(i) + 1],
                );
                (a.cos[h - 1], a.sin[h - 1]) = (p, q);
                (b.cos[h - 1], b.sin[h - 1]) = (-q / h as f64, p / h as f64);
            }
            let weights: Vec<(f64, f64)> = (0..=WEIGHT_TABLE)
                .map(|i| {
                    let tau = -1.0 + 2.0 * i as f64 / WEIGHT_TABLE as f64;
                    let t = 0.5 * (basis.t0 + basis.t1) + 0.5 * tau * (basis.t1 - basis.t0);
                    let (_, w1, w2) = d.motion.eval(t);
                    (1.0 / (w1 * w1 * d.gain), 3.0 * w2 / (w1.powi(4) * d.gain))
                })
                .collect();
            DragModel {
                a: Periodic::of(&a),
                b: Periodic::of(&b),
                w: weights.iter().map(|p| p.0).collect(),
                v: weights.iter().map(|p| p.1).collect(),
            }
        });
        Model {
            motion: fit.beta[..f].to_vec(),
            map: Periodic::of(&map),
            drag,
        }
    }

    /// The residuals `y − Aβ` of the samples `range` as points of a 1-D spectrum,
    /// `(0, r, [e])`; the motion's series evaluated [`LANES`] samples side by side. On x86-64
    /// CPUs with AVX (detected at run time) compiled for it: the tables' `floor`s become one
    /// instruction instead of a call (SSE2 has none), the same bits.
    fn points(&self, s: Samples, range: Range<usize>, out: &mut Vec<(f64, f64, [f64; 1])>) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx") {
            #[target_feature(enable = "avx")]
            unsafe fn avx(
                model: &Model,
                s: Samples,
                range: Range<usize>,
                out: &mut Vec<(f64, f64, [f64; 1])>,
            ) {
                model.residuals(s, range, out);
            }
            // SAFETY: the CPU has AVX.
            return unsafe { avx(self, s, range, out) };
        }
        self.residuals(s, range, out);
    }

    /// [`points`](Self::points) as the compiler builds it for the CPU it targets.
    #[inline(always)]
    fn residuals(&self, s: Samples, range: Range<usize>, out: &mut Vec<(f64, f64, [f64; 1])>) {
        for first in range.clone().step_by(LANES) {
            let lanes = LANES.min(range.end - first);
            let tau: [f64; LANES] = s.taus(first, range.end);
            let motion = chebyshev_lanes(&self.motion, &tau);
            for l in 0..lanes {
                let r = s.r[first + l];
                // One place in the revolution for the map's table and the drag's two.
                let place = TablePlace::of(r);
                let mut e = r - s.origin - motion[l] - self.map.at(place);
                if let Some(d) = &self.drag {
                    let u = (tau[l] + 1.0) * 0.5 * WEIGHT_TABLE as f64;
                    e -= cubic(&d.w, u) * d.a.at(place) + cubic(&d.v, u) * d.b.at(place);
                }
                out.push((0.0, r, [e]));
            }
        }
    }
}

/// A periodic function tabulated at `TABLE` points over a revolution, padded by one point before
/// and two after so that cubic interpolation reads four neighbours without wrapping.
struct Periodic(Vec<f64>);

impl Periodic {
    fn of(series: &FourierSeries) -> Periodic {
        let map = ErrorMap::from_series(series, TABLE);
        let v = map.values();
        let mut padded = Vec::with_capacity(TABLE + 3);
        padded.push(v[TABLE - 1]);
        padded.extend_from_slice(v);
        padded.extend_from_slice(&v[..2]);
        Periodic(padded)
    }

    /// Cubic (4-point Lagrange) interpolation at `place`.
    #[inline(always)]
    fn at(&self, place: TablePlace) -> f64 {
        let p = &self.0[place.i..place.i + 4];
        lagrange([p[0], p[1], p[2], p[3]], place.f)
    }
}

/// Where an angle falls among a [`Periodic`] table's points: the point before it and the
/// fraction of the step past it.
#[derive(Debug, Clone, Copy)]
struct TablePlace {
    i: usize,
    f: f64,
}

impl TablePlace {
    /// The place of `x` radians (any revolution).
    #[inline(always)]
    fn of(x: f64) -> TablePlace {
        // x − 2π·⌊x/2π⌋ rather than `rem_euclid` (a libm call): a rounding of the turn count
        // moves the point by an ulp of x, nothing to an interpolation.
        let turns = x / TAU;
        let u = (turns - turns.floor()) * TABLE as f64;
        let i = (u.floor() as usize).min(TABLE - 1);
        TablePlace { i, f: u - i as f64 }
    }
}

/// Cubic interpolation of a table at fractional index `u`, its ends extrapolated from the
/// nearest four points.
#[inline(always)]
fn cubic(values: &[f64], u: f64) -> f64 {
    let last = values.len() - 1;
    let i = (u.floor().max(1.0) as usize).min(last - 2);
    lagrange(
        [values[i - 1], values[i], values[i + 1], values[i + 2]],
        u - i as f64,
    )
}

/// The cubic through `p` at `−1, 0, 1, 2`, at `f`.
#[inline(always)]
fn lagrange(p: [f64; 4], f: f64) -> f64 {
    let (a, b, c) = (f + 1.0, f - 1.0, f - 2.0);
    -p[0] * f * b * c / 6.0 + p[1] * a * b * c / 2.0 - p[2] * a * f * c / 2.0
        + p[3] * a * f * b / 6.0
}

/// Fits `d = c + Σ a_k cos kr + b_k sin kr` (DUT − reference against the DUT's reading `r`) at
/// `orders` — the map's and those the residual showed beyond it — and compares the map with the
/// TDR map.
pub(super) fn reference_check(
    r: &[f64],
    reference: &[f64],
    orders: &[usize],
    tdr: &ErrorMap,
) -> ReferenceCheck {
    let d0 = r[0] - reference[0];
    let top = orders.last().copied().unwrap_or(1);
    let moments = Moments::of_given(r, |i| r[i] - reference[i] - d0, top);
    let basis = Basis {
        t0: 0.0,
        t1: 1.0,
        degree: 0,
        orders: orders.to_vec(),
        drag: None,
    };
    let mut series = FourierSeries::zeros(top);
    if let Some(fit) = Fit::new(&moments, &basis) {
        for (i, &k) in orders.iter().enumerate() {
            series.cos[k - 1] = fit.beta[1 + 2 * i];
            series.sin[k - 1] = fit.beta[2 + 2 * i];
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_trace_gathered_by_blocks_is_the_trace_of_the_samples() {
        // Coasts with intervals longer than a block and shorter (several in one block), and a
        // last block that is not full; the blocks recorded out of order, as threads do.
        for n in [5, 300, 1000, 3 * BLOCK + 17, 250_000] {
            let t: Vec<f64> = (0..n).map(|i| 0.01 * i as f64).collect();
            let r: Vec<f64> = (0..n)
                .map(|i| 0.3 * i as f64 + 0.001 * (i * i) as f64)
                .collect();
            let e: Vec<f64> = (0..n).map(|i| (1.7 * i as f64).sin() * 1e-5).collect();
            let s = Samples {
                t: &t,
                r: &r,
                origin: 0.0,
                span: (t[0], t[n - 1]),
            };
            let trace = Trace::new(n, 400);
            let blocks = n.div_ceil(BLOCK);
            for b in (0..blocks).rev() {
                let range = b * BLOCK..((b + 1) * BLOCK).min(n);
                trace.record(range.clone(), e[range].iter().copied());
            }
            let bins = trace.bins(s);
            let count = 400.min(n / 2).max(1);
            assert_eq!(bins.len(), count, "n = {n}");
            for (k, bin) in bins.iter().enumerate() {
                let range = k * n / count..(k + 1) * n / count;
                let (first, last) = (range.start, range.end - 1);
                let part = &e[range.clone()];
                let mean = part.iter().sum::<f64>() / part.len() as f64;
                assert!(
                    (bin.residual_mean - mean).abs() < 1e-19,
                    "n = {n}, interval {k}"
                );
                assert_eq!(
                    bin.residual_min,
                    part.iter().copied().fold(f64::INFINITY, f64::min)
                );
                assert_eq!(
                    bin.residual_max,
                    part.iter().copied().fold(f64::NEG_INFINITY, f64::max)
                );
                assert_eq!(bin.t, 0.5 * (t[first] + t[last]));
                assert_eq!(bin.speed, (r[last] - r[first]) / (t[last] - t[first]));
            }
        }
    }

    #[test]
    fn projections_match_direct_sums_within_their_bound_on_any_threads() {
        // A coast's readings over ~300 turns; residuals of both signs holding order 37; three
        // pieces, the last partial.
        let n = 2 * PROJECTION_PIECE + 3 * BLOCK + 17;
        let r: Vec<f64> = (0..n)
            .map(|i| {
                let t = i as f64 / n as f64;
                2600.0 * t - 900.0 * t * t
            })
            .collect();
        let e: Vec<f64> = (0..n)
            .map(|i| 1e-6 * ((37.0 * r[i]).cos() + ((i * 7919) % 1000) as f64 / 500.0 - 1.0))
            .collect();
        let orders = [1, 2, 37, 100, 499, 500];
        let fill = |range: Range<usize>, out: &mut Vec<(f64, f64, [f64; 1])>| {
            out.extend(range.map(|i| (0.0, r[i], [e[i]])));
        };
        let on = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| projections(n, &orders, fill))
        };
        let (re, im) = on(1);
        let other = on(3);
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!((bits(&re), bits(&im)), (bits(&other.0), bits(&other.1)));
        let l1: f64 = e.iter().map(|x| x.abs()).sum();
        for (j, &k) in orders.iter().enumerate() {
            let (mut c, mut s) = (0.0, 0.0);
            for (r, e) in r.iter().zip(&e) {
                let (sin, cos) = (k as f64 * r).sin_cos();
                c += e * cos;
                s += e * sin;
            }
            // The bound in `projections`' docs: 9·10⁻⁹ of Σ|e|.
            let err = (re[j] - c).abs().max((im[j] - s).abs());
            assert!(err <= 9e-9 * l1, "order {k}: off by {err}");
        }
        // Order 37 holds half the residuals' amplitude per sample.
        assert!((re[2] / (0.5e-6 * n as f64) - 1.0).abs() < 0.01);
    }

    #[test]
    fn cubic_tables_interpolate_smooth_functions_closely() {
        let mut series = FourierSeries::zeros(500);
        series.sin[499] = 1.0;
        let table = Periodic::of(&series);
        for x in [0.0, 0.1, 1.234_567, 3.0, 6.2, 2000.5] {
            // 0.023·(2π·500/2¹⁶)⁴ ≈ 1.2·10⁻⁷ of the amplitude at order 500.
            let at = table.at(TablePlace::of(x));
            assert!((at - (500.0 * x).sin()).abs() < 2e-7, "at {x}");
        }
        let smooth: Vec<f64> = (0..=WEIGHT_TABLE)
            .map(|i| (-1.0 + 2.0 * i as f64 / WEIGHT_TABLE as f64).exp())
            .collect();
        for tau in [-1.0, -0.5, 0.1, 0.999, 1.0] {
            let u = (tau + 1.0) * 0.5 * WEIGHT_TABLE as f64;
            assert!((cubic(&smooth, u) - f64::exp(tau)).abs() < 1e-12);
        }
    }
}
