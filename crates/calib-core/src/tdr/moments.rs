//! The sums the fit's normal equations need, from two spectra of the coast's samples.
//!
//! Every column of the fit (module docs, eqs. 1 and 3) is `Re[g(τ)·e^{ikr}]` with `g` a smooth
//! function of the normalized time: `T_j(τ)` for the motion (`k = 0`), `1` and `−i` for the
//! map's `cos kr` and `sin kr`, and `w − iv/h` and `−i(w − iv/h)` for the drag's pair at order
//! `h`. An entry of `AᵀA` is therefore
//!
//! `Σ_n Re[g_a e^{ik_a r_n}]·Re[g_b e^{ik_b r_n}] = ½Re Σ_n [g_a g_b e^{i(k_a+k_b)r_n} + g_a ḡ_b e^{i(k_a−k_b)r_n}]`,
//!
//! and with `g = Σ_l α_l T_l(τ)`, `T_l(τ) = cos lφ` for `φ = arccos τ`, every such sum is a
//! combination of one spectrum of the samples,
//!
//! `F(j, m) = Σ_n e^{i(jφ_n + m r_n)}`,   `Σ_n g(τ_n) e^{imr_n} = Σ_l α_l·½[F(l, m) + F(−l, m)]`.
//!
//! `Aᵀy` comes the same way from `F_y`, the spectrum weighted by the target `y_n`. One
//! non-uniform FFT of the samples ([`crate::nufft2d`]) gives both in `O(N·W²)` (`W` the
//! kernel's width); every fit after it costs `O(n²)` for its `n` columns, not `O(N·n²)`.
//!
//! # Precision
//! The readings grow by thousands of radians over a coast while the map is 10⁻⁴ rad, and the
//! spectra are exact only to about 10⁻¹³ of `Σ|weight|`. The target is therefore the readings
//! less a preliminary motion `P(τ)`, a Chebyshev fit of the motion's highest degree to a
//! subsample: `y′ = y − P` is as small as the encoder's error. A fit whose motion has a lower
//! degree `p` holds `P`'s coefficients above `p` fixed (`y − Aβ = y′ − A·b`, `b` the fitted
//! coefficients less `P`'s, `P`'s higher ones negated), so every fit solves for small numbers,
//! and `‖y′ − Ab‖² = y′ᵀy′ − 2bᵀAᵀy′ + bᵀAᵀAb` keeps its digits: `y′ᵀy′` is summed directly.

use super::Basis;
use super::chebyshev::{chebyshev_coefficients, chebyshev_lanes};
use crate::nufft2d::{BLOCK, Complex64, Spectrum2, type1, type1_blocks};
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};

/// Samples whose preliminary motion is evaluated side by side.
const LANES: usize = 16;

/// Highest Chebyshev degree kept of the drag's weights `w`, `v` and their products. They are
/// analytic on the coast (the speed stays above [`super::TdrOptions::min_speed_fraction`] of its
/// peak), so their coefficients fall geometrically: with the speed falling to a tenth the
/// nearest pole of `1/ω²` lies at `τ ≈ 1.2`, and degree 96 leaves less than 10⁻¹⁴.
const DRAG_WEIGHT_DEGREE: usize = 96;

/// Samples of the subsample the preliminary motion is fitted to.
const PRELIMINARY_SAMPLES: usize = 100_000;

/// Samples of the preliminary fit whose rows are summed side by side.
const PRELIMINARY_BATCH: usize = 8;

/// Samples per chunk of the direct sums (fixed, so the sums are the same bits on any number of
/// threads).
const CHUNK: usize = 1 << 14;

/// The coast's samples and their time normalization `τ = (2t − t₀ − t₁)/(t₁ − t₀)`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Samples<'a> {
    pub t: &'a [f64],
    pub r: &'a [f64],
    /// The reading the target is measured from, `y = r − origin`.
    pub origin: f64,
    pub span: (f64, f64),
}

impl Samples<'_> {
    pub fn tau(&self, i: usize) -> f64 {
        self.normalized(self.t[i])
    }

    #[inline(always)]
    fn normalized(&self, t: f64) -> f64 {
        (2.0 * t - self.span.0 - self.span.1) / (self.span.1 - self.span.0)
    }

    /// `τ` of the `N` samples from `first`, the one before `end` repeated past it. A whole
    /// group is one loop over a slice, which the compiler turns into vector divisions where
    /// the caller's target features allow (`array::from_fn`'s closure, compiled apart, divided
    /// one at a time).
    #[inline(always)]
    pub fn taus<const N: usize>(&self, first: usize, end: usize) -> [f64; N] {
        let mut tau = [0.0; N];
        match self.t.get(first..first + N).filter(|_| first + N <= end) {
            Some(t) => {
                for (tau, &t) in tau.iter_mut().zip(t) {
                    *tau = self.normalized(t);
                }
            }
            None => {
                for (l, tau) in tau.iter_mut().enumerate() {
                    *tau = self.tau((first + l).min(end - 1));
                }
            }
        }
        tau
    }

    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// The points of the spectra of the samples `range`: `(arccos τ, r, [1, y′])` with
    /// `y′ = r − origin − P(τ)` for the preliminary motion `P` (its series evaluated [`LANES`]
    /// samples side by side), and `Σ y′²` over them (in their order).
    fn points(&self, p: &[f64], range: Range<usize>, out: &mut Vec<(f64, f64, [f64; 2])>) -> f64 {
        let mut squares = 0.0;
        for first in range.clone().step_by(LANES) {
            let lanes = LANES.min(range.end - first);
            let tau: [f64; LANES] = self.taus(first, range.end);
            let motion = chebyshev_lanes(p, &tau);
            for l in 0..lanes {
                let r = self.r[first + l];
                let y = r - self.origin - motion[l];
                squares += y * y;
                out.push((tau[l].clamp(-1.0, 1.0).acos(), r, [1.0, y]));
            }
        }
        squares
    }
}

/// The spectra of a coast: `F` (unit weights) and `F_y` (the target `y′`), with `y′ᵀy′` and the
/// preliminary motion subtracted from the target.
#[derive(Debug, Clone)]
pub(super) struct Moments {
    one: Spectrum2,
    data: Spectrum2,
    /// `y′ᵀy′`.
    pub yy: f64,
    /// The preliminary motion's Chebyshev coefficients (degree [`Moments::degree`]); empty when
    /// the target was given small.
    pub preliminary: Vec<f64>,
    /// Samples summed.
    pub samples: usize,
}

impl Moments {
    /// The spectra of the coast for fits with the motion up to `degree`, the map's orders up to
    /// `h` and drag orders up to `drag`.
    pub fn of_coast(s: Samples, degree: usize, h: usize, drag: usize) -> Moments {
        Moments::with_preliminary(s, preliminary_motion(s, degree), h, drag)
    }

    /// [`of_coast`](Self::of_coast) with the preliminary motion given: [`preliminary_motion`]
    /// of the samples, its degree the motion's highest.
    pub fn with_preliminary(s: Samples, preliminary: Vec<f64>, h: usize, drag: usize) -> Moments {
        let degree = preliminary.len() - 1;
        let j_max = (degree + DRAG_WEIGHT_DEGREE).max(2 * degree);
        let m_max = (2 * h).max(h + drag).max(2 * drag).max(1);
        // Σy′² of each block, summed in order afterwards: the same bits on any threads.
        let squares: Vec<AtomicU64> = (0..s.len().div_ceil(BLOCK))
            .map(|_| AtomicU64::new(0))
            .collect();
        let [one, data] = type1_blocks::<2>(s.len(), j_max, m_max, |range, points| {
            let block = range.start / BLOCK;
            let sum = s.points(&preliminary, range, points);
            squares[block].store(sum.to_bits(), Ordering::Relaxed);
        });
        let yy = squares
            .iter()
            .map(|b| f64::from_bits(b.load(Ordering::Relaxed)))
            .sum();
        Moments {
            one,
            data,
            yy,
            preliminary,
            samples: s.len(),
        }
    }

    /// The spectra of a target `y` given at the samples of readings `r` (small: no preliminary
    /// motion), for fits of a constant and the map's orders up to `h`.
    pub fn of_given(r: &[f64], y: impl Fn(usize) -> f64 + Sync, h: usize) -> Moments {
        let [one, data] = type1::<2>(r.len(), 0, (2 * h).max(1), |i| (0.0, r[i], [1.0, y(i)]));
        let chunks: Vec<f64> = (0..r.len().div_ceil(CHUNK))
            .into_par_iter()
            .map(|c| {
                (c * CHUNK..((c + 1) * CHUNK).min(r.len()))
                    .map(|i| y(i).powi(2))
                    .sum()
            })
            .collect();
        Moments {
            one,
            data,
            yy: chunks.iter().sum(),
            preliminary: Vec::new(),
            samples: r.len(),
        }
    }

    /// The motion's highest degree the spectra serve.
    pub fn degree(&self) -> usize {
        self.preliminary.len().saturating_sub(1)
    }

    /// `Σ_n T_j(τ_n) e^{imr_n}` (weights 1 or `y′`).
    fn cheb(spectrum: &Spectrum2, j: usize, m: i64) -> Complex64 {
        let j = j as i64;
        if j == 0 {
            spectrum.at(0, m)
        } else {
            0.5 * (spectrum.at(j, m) + spectrum.at(-j, m))
        }
    }

    /// `Σ_n a(τ_n) e^{imr_n}` for `a = Σ_l α_l T_l`.
    fn smooth(spectrum: &Spectrum2, alpha: &[f64], m: i64) -> Complex64 {
        alpha
            .iter()
            .enumerate()
            .map(|(l, &a)| a * Self::cheb(spectrum, l, m))
            .sum()
    }

    /// `Σ_n a(τ_n)` for a smooth `a` given as a function of `τ` (its Chebyshev series to the
    /// degree the spectra hold).
    pub fn sum_of(&self, a: impl Fn(f64) -> f64) -> f64 {
        let alpha = chebyshev_coefficients(a, self.one.j_max() + 1);
        Self::smooth(&self.one, &alpha, 0).re
    }
}

/// `P`: the motion's Chebyshev series of `degree` fitted by least squares to about
/// [`PRELIMINARY_SAMPLES`] samples evenly spread over the coast.
pub(super) fn preliminary_motion(s: Samples, degree: usize) -> Vec<f64> {
    let stride = (s.len() / PRELIMINARY_SAMPLES).max(1);
    let n = degree + 1;
    // `GᵀG` in rows of whole vectors of 4 (its lower triangle used, and beside it as many
    // entries as fill a row's last vector), `Gᵀy`, each entry summed over the samples in their
    // order. The samples come [`PRELIMINARY_BATCH`] at a time, their rows side by side, so that
    // an entry's sums over them stay in a register (loading and storing each entry per sample
    // took 1.7 times as long).
    let width = n.next_multiple_of(4);
    let mut gram = vec![0.0; n * width];
    let mut b = vec![0.0; n];
    let mut rows = vec![0.0; PRELIMINARY_BATCH * width];
    let mut ys = [0.0; PRELIMINARY_BATCH];
    let batch_step = PRELIMINARY_BATCH * stride;
    for first in (0..s.len()).step_by(batch_step) {
        let batch = (first..s.len().min(first + batch_step)).step_by(stride);
        let count = batch.len();
        for ((i, row), y) in batch.zip(rows.chunks_exact_mut(width)).zip(&mut ys) {
            chebyshev_row(s.tau(i), &mut row[..n]);
            *y = s.r[i] - s.origin;
        }
        let rows = &rows[..count * width];
        for (a, (line, b)) in gram.chunks_exact_mut(width).zip(&mut b).enumerate() {
            for (q, cells) in line[..(a + 1).next_multiple_of(4)]
                .chunks_exact_mut(4)
                .enumerate()
            {
                let mut sums: [f64; 4] = cells.try_into().expect("chunks of 4");
                for row in rows.chunks_exact(width) {
                    for (sum, &rc) in sums.iter_mut().zip(&row[4 * q..4 * q + 4]) {
                        *sum += row[a] * rc;
                    }
                }
                cells.copy_from_slice(&sums);
            }
            for (row, &y) in rows.chunks_exact(width).zip(&ys) {
                *b += row[a] * y;
            }
        }
    }
    let g = DMatrix::<f64>::from_fn(n, n, |a, c| gram[a.max(c) * width + a.min(c)]);
    g.cholesky()
        .map(|ch| ch.solve(&DVector::from_vec(b)).iter().copied().collect())
        .unwrap_or_else(|| vec![0.0; n])
}

/// `T_0..T_p(τ)` into `out`.
pub(super) fn chebyshev_row(tau: f64, out: &mut [f64]) {
    out[0] = 1.0;
    if out.len() > 1 {
        out[1] = tau;
    }
    for j in 2..out.len() {
        out[j] = 2.0 * tau * out[j - 1] - out[j - 2];
    }
}

/// A smooth factor of a column: 1, `T_j(τ)`, or the drag's `w` or `v`.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Factor {
    One,
    Cheb(usize),
    W,
    V,
}

/// One term `c·factor(τ)·e^{ikr}` of a column `Re[Σ terms]`.
#[derive(Debug, Clone, Copy)]
struct Term {
    c: Complex64,
    factor: Factor,
    k: i64,
}

/// The columns of `basis` as terms, in its column order.
fn columns(basis: &Basis) -> Vec<Vec<Term>> {
    let one = Complex64::new(1.0, 0.0);
    let minus_i = Complex64::new(0.0, -1.0);
    let term = |c, factor, k: usize| Term {
        c,
        factor,
        k: k as i64,
    };
    let mut cols: Vec<Vec<Term>> = (0..=basis.degree)
        .map(|j| vec![term(one, Factor::Cheb(j), 0)])
        .collect();
    for &k in &basis.orders {
        cols.push(vec![term(one, Factor::One, k)]);
        cols.push(vec![term(minus_i, Factor::One, k)]);
    }
    if let Some(d) = &basis.drag {
        for &h in &d.orders {
            let hf = h as f64;
            // w·cos hr + (v/h)·sin hr = Re[(w − iv/h)e^{ihr}]
            cols.push(vec![
                term(one, Factor::W, h),
                term(Complex64::new(0.0, -1.0 / hf), Factor::V, h),
            ]);
            // w·sin hr − (v/h)·cos hr = Re[(−iw − v/h)e^{ihr}]
            cols.push(vec![
                term(minus_i, Factor::W, h),
                term(Complex64::new(-1.0 / hf, 0.0), Factor::V, h),
            ]);
        }
    }
    cols
}

/// The drag's weights `w = ω⁻²/⟨ω⁻²⟩` and `v = 3ω̇/(ω⁴⟨ω⁻²⟩)` (module docs, eq. 3) as Chebyshev
/// series, and the sums of them (and their products with each other and with `T_j`) the normal
/// equations take.
struct DragSums {
    /// `Σ w e^{imr}`, `Σ v e^{imr}` for `0 ≤ m ≤` the map's top order + the drag's.
    w: Vec<Complex64>,
    v: Vec<Complex64>,
    /// `Σ w² e^{imr}`, `Σ wv e^{imr}`, `Σ v² e^{imr}` for `m ≤ 2·` drag's top order.
    ww: Vec<Complex64>,
    wv: Vec<Complex64>,
    vv: Vec<Complex64>,
    /// `Σ w T_j e^{imr}`, `Σ v T_j e^{imr}`, `[j][m]` for `m ≤` the drag's top order.
    w_cheb: Vec<Vec<Complex64>>,
    v_cheb: Vec<Vec<Complex64>>,
    /// `Σ w y′ e^{imr}`, `Σ v y′ e^{imr}` for `m ≤` the drag's top order.
    w_data: Vec<Complex64>,
    v_data: Vec<Complex64>,
}

impl DragSums {
    fn new(moments: &Moments, basis: &Basis) -> Option<DragSums> {
        let d = basis.drag.as_ref()?;
        let top_drag = d.orders.last().copied().unwrap_or(0);
        let top = basis.top();
        let span = (basis.t0, basis.t1);
        let at = |tau: f64| {
            let t = 0.5 * (span.0 + span.1) + 0.5 * tau * (span.1 - span.0);
            let (_, w1, w2) = d.motion.eval(t);
            (1.0 / (w1 * w1 * d.gain), 3.0 * w2 / (w1.powi(4) * d.gain))
        };
        let terms = DRAG_WEIGHT_DEGREE + 1;
        let w = chebyshev_coefficients(|tau| at(tau).0, terms);
        let v = chebyshev_coefficients(|tau| at(tau).1, terms);
        let ww = chebyshev_coefficients(|tau| at(tau).0.powi(2), terms);
        let wv = chebyshev_coefficients(|tau| at(tau).0 * at(tau).1, terms);
        let vv = chebyshev_coefficients(|tau| at(tau).1.powi(2), terms);
        let table = |spectrum: &Spectrum2, alpha: &[f64], to: usize| -> Vec<Complex64> {
            (0..=to as i64)
                .map(|m| Moments::smooth(spectrum, alpha, m))
                .collect()
        };
        // w·T_j = ½Σ_l w_l (T_{l+j} + T_{|l−j|}).
        let times_cheb = |alpha: &[f64]| -> Vec<Vec<Complex64>> {
            (0..=moments.degree())
                .map(|j| {
                    (0..=top_drag as i64)
                        .map(|m| {
                            alpha
                                .iter()
                                .enumerate()
                                .map(|(l, &a)| {
                                    0.5 * a
                                        * (Moments::cheb(&moments.one, l + j, m)
                                            + Moments::cheb(&moments.one, l.abs_diff(j), m))
                                })
                                .sum()
                        })
                        .collect()
                })
                .collect()
        };
        Some(DragSums {
            w: table(&moments.one, &w, top + top_drag),
            v: table(&moments.one, &v, top + top_drag),
            ww: table(&moments.one, &ww, 2 * top_drag),
            wv: table(&moments.one, &wv, 2 * top_drag),
            vv: table(&moments.one, &vv, 2 * top_drag),
            w_cheb: times_cheb(&w),
            v_cheb: times_cheb(&v),
            w_data: table(&moments.data, &w, top_drag),
            v_data: table(&moments.data, &v, top_drag),
        })
    }
}

/// `table[|m|]`, conjugated for `m < 0` (the weights are real).
fn signed(table: &[Complex64], m: i64) -> Complex64 {
    let v = table[m.unsigned_abs() as usize];
    if m < 0 { v.conj() } else { v }
}

/// Normal equations of the largest column set of a basis — its motion at the spectra's highest
/// degree — for the target `y′`; fits take sub-blocks of them.
#[derive(Debug, Clone)]
pub(super) struct Normal {
    pub g: DMatrix<f64>,
    /// `Aᵀy′`.
    pub rhs: DVector<f64>,
    /// `y′ᵀy′`.
    pub yy: f64,
    /// The preliminary motion, in the motion's columns.
    pub preliminary: Vec<f64>,
    /// Samples summed.
    pub samples: usize,
}

impl Normal {
    /// `AᵀA` and `Aᵀy′` of `basis` (its motion taken to the spectra's degree), from the spectra.
    pub fn new(moments: &Moments, basis: &Basis) -> Normal {
        let basis = Basis {
            degree: moments.degree(),
            ..basis.clone()
        };
        let cols = columns(&basis);
        let drag = DragSums::new(moments, &basis);
        let sum = |a: Factor, b: Factor, m: i64| -> Complex64 {
            use Factor::*;
            let drag = || drag.as_ref().expect("drag columns have their sums");
            let cheb = |j: usize| Moments::cheb(&moments.one, j, m);
            match (a, b) {
                (One, One) => moments.one.at(0, m),
                (One, Cheb(j)) | (Cheb(j), One) => cheb(j),
                (Cheb(i), Cheb(j)) => 0.5 * (cheb(i + j) + cheb(i.abs_diff(j))),
                (One, W) | (W, One) => signed(&drag().w, m),
                (One, V) | (V, One) => signed(&drag().v, m),
                (Cheb(j), W) | (W, Cheb(j)) => signed(&drag().w_cheb[j], m),
                (Cheb(j), V) | (V, Cheb(j)) => signed(&drag().v_cheb[j], m),
                (W, W) => signed(&drag().ww, m),
                (W, V) | (V, W) => signed(&drag().wv, m),
                (V, V) => signed(&drag().vv, m),
            }
        };
        let data = |a: Factor, m: i64| -> Complex64 {
            match a {
                Factor::One => moments.data.at(0, m),
                Factor::Cheb(j) => Moments::cheb(&moments.data, j, m),
                Factor::W => signed(&drag.as_ref().expect("drag sums").w_data, m),
                Factor::V => signed(&drag.as_ref().expect("drag sums").v_data, m),
            }
        };
        let n = cols.len();
        let upper: Vec<Vec<f64>> = (0..n)
            .into_par_iter()
            .map(|a| {
                (a..n)
                    .map(|b| {
                        let mut s = Complex64::new(0.0, 0.0);
                        for ta in &cols[a] {
                            for tb in &cols[b] {
                                s += ta.c * tb.c * sum(ta.factor, tb.factor, ta.k + tb.k)
                                    + ta.c * tb.c.conj() * sum(ta.factor, tb.factor, ta.k - tb.k);
                            }
                        }
                        0.5 * s.re
                    })
                    .collect()
            })
            .collect();
        let g = DMatrix::from_fn(n, n, |a, b| {
            let (a, b) = (a.min(b), a.max(b));
            upper[a][b - a]
        });
        let rhs = DVector::from_fn(n, |a, _| {
            cols[a].iter().map(|t| (t.c * data(t.factor, t.k)).re).sum()
        });
        Normal {
            g,
            rhs,
            yy: moments.yy,
            preliminary: moments.preliminary.clone(),
            samples: moments.samples,
        }
    }

    /// The motion's highest degree in these equations.
    pub fn degree(&self) -> usize {
        self.preliminary.len().saturating_sub(1)
    }

    /// The columns of a fit whose motion has degree `p`: `T_0..T_p` and all others.
    pub fn columns(&self, p: usize) -> Vec<usize> {
        let top = self.degree();
        (0..=p.min(top)).chain(top + 1..self.g.nrows()).collect()
    }

    /// The least-squares fit of `cols` (from [`Normal::columns`]): `b`, the coefficients less the
    /// preliminary motion's over all columns (the motion's columns left out hold `−P`'s), and
    /// the Cholesky factor of `AᵀA` restricted to `cols`. `None` if singular.
    pub fn solve(
        &self,
        cols: &[usize],
    ) -> Option<(DVector<f64>, nalgebra::Cholesky<f64, nalgebra::Dyn>)> {
        let n = self.g.nrows();
        let mut b = DVector::<f64>::zeros(n);
        for (j, &p) in self.preliminary.iter().enumerate() {
            if !cols.contains(&j) {
                b[j] = -p;
            }
        }
        let fixed = &self.g * &b;
        let sub = DMatrix::from_fn(cols.len(), cols.len(), |a, c| self.g[(cols[a], cols[c])]);
        let chol = super::cholesky::factor(sub)?;
        let x = chol.solve(&DVector::from_fn(cols.len(), |a, _| {
            self.rhs[cols[a]] - fixed[cols[a]]
        }));
        if !x.iter().all(|v| v.is_finite()) {
            return None;
        }
        for (a, &c) in cols.iter().enumerate() {
            b[c] = x[a];
        }
        Some((b, chol))
    }

    /// `‖y′ − Ab‖²`.
    pub fn rss(&self, b: &DVector<f64>) -> f64 {
        (self.yy - 2.0 * b.dot(&self.rhs) + (b.transpose() * &self.g * b)[0]).max(0.0)
    }

    /// The coefficients of `cols` in the fit's own terms: `b` with the preliminary motion added
    /// back to the motion's columns.
    pub fn coefficients(&self, b: &DVector<f64>, cols: &[usize]) -> Vec<f64> {
        cols.iter()
            .map(|&c| b[c] + self.preliminary.get(c).copied().unwrap_or(0.0))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::super::{DragWeights, TdrMotion};
    use super::*;

    /// A coast of `n` samples: speed falling from 60 to 20 rad/s, a reading with a few orders of
    /// error and a little jitter.
    fn coast(n: usize) -> (Vec<f64>, Vec<f64>, TdrMotion) {
        let duration = 20.0;
        let motion = TdrMotion {
            degree: 2,
            t_start: 0.0,
            t_end: duration,
            angle_origin: 0.0,
            // θ(τ) = 400 + 400τ − 100τ²... in τ over [0, 20] s: ω = (400 − 200τ)/10 rad/s.
            coefficients: vec![350.0, 400.0, -50.0],
        };
        let t: Vec<f64> = (0..n)
            .map(|i| duration * i as f64 / (n - 1) as f64)
            .collect();
        let r = t
            .iter()
            .enumerate()
            .map(|(i, &ti)| {
                let theta = motion.eval(ti).0;
                theta
                    + 1e-4 * (2.0 * theta + 0.3).sin()
                    + 3e-5 * (7.0 * theta).cos()
                    + 1e-7 * ((i * 7919 % 1000) as f64 / 1000.0 - 0.5)
            })
            .collect();
        (t, r, motion)
    }

    #[test]
    fn the_preliminary_motion_sums_each_entry_over_the_samples_in_order() {
        // Each entry of `GᵀG` and `Gᵀy` summed over the samples one at a time, as the
        // equations read: the batched sums must give the same bits.
        let one_at_a_time = |s: Samples, degree: usize| {
            let stride = (s.len() / PRELIMINARY_SAMPLES).max(1);
            let n = degree + 1;
            let (mut g, mut b) = (DMatrix::<f64>::zeros(n, n), DVector::<f64>::zeros(n));
            let mut row = vec![0.0; n];
            for i in (0..s.len()).step_by(stride) {
                chebyshev_row(s.tau(i), &mut row);
                let y = s.r[i] - s.origin;
                for a in 0..n {
                    b[a] += row[a] * y;
                    for c in 0..=a {
                        g[(a, c)] += row[a] * row[c];
                    }
                }
            }
            let g = DMatrix::from_fn(n, n, |a, c| g[(a.max(c), a.min(c))]);
            g.cholesky()
                .map(|ch| ch.solve(&b).iter().copied().collect::<Vec<f64>>())
                .unwrap_or_else(|| vec![0.0; n])
        };
        for (n, degree) in [
            (5, 2),
            (13, 1),
            (20_003, 2),
            (20_003, 17),
            (250_001, 30),
            (9, 45),
        ] {
            let (t, r, _) = coast(n);
            let s = Samples {
                t: &t,
                r: &r,
                origin: r[0],
                span: (t[0], t[n - 1]),
            };
            let bits = |v: Vec<f64>| v.iter().map(|x| x.to_bits()).collect::<Vec<u64>>();
            assert_eq!(
                bits(preliminary_motion(s, degree)),
                bits(one_at_a_time(s, degree)),
                "{n} samples, degree {degree}"
            );
        }
    }

    #[test]
    fn normal_equations_from_the_spectra_are_the_direct_sums() {
        let (t, r, motion) = coast(20_000);
        let samples = Samples {
            t: &t,
            r: &r,
            origin: r[0],
            span: (t[0], t[t.len() - 1]),
        };
        let degree = 6;
        let moments = Moments::of_coast(samples, degree, 9, 3);
        let gain = 1.0 / 900.0;
        let basis = Basis {
            t0: samples.span.0,
            t1: samples.span.1,
            degree,
            orders: vec![1, 2, 5, 7, 9],
            drag: Some(DragWeights {
                orders: vec![1, 3],
                motion: motion.clone(),
                gain,
            }),
        };
        let normal = Normal::new(&moments, &basis);

        // The same sums, row by row.
        let n = basis.len();
        let mut g = DMatrix::<f64>::zeros(n, n);
        let mut rhs = DVector::<f64>::zeros(n);
        let mut yy = 0.0;
        let mut row = vec![0.0; n];
        for i in 0..t.len() {
            let tau = samples.tau(i);
            chebyshev_row(tau, &mut row[..=degree]);
            let mut c = degree + 1;
            for &k in &basis.orders {
                let (s, co) = (k as f64 * r[i]).sin_cos();
                (row[c], row[c + 1]) = (co, s);
                c += 2;
            }
            let (_, w1, w2) = motion.eval(t[i]);
            let (w, v) = (1.0 / (w1 * w1 * gain), 3.0 * w2 / (w1.powi(4) * gain));
            for &h in &[1usize, 3] {
                let (s, co) = (h as f64 * r[i]).sin_cos();
                let vh = v / h as f64;
                (row[c], row[c + 1]) = (w * co + vh * s, w * s - vh * co);
                c += 2;
            }
            let y = r[i]
                - r[0]
                - super::super::chebyshev::chebyshev_with_derivatives(&moments.preliminary, tau).0;
            yy += y * y;
            for a in 0..n {
                rhs[a] += row[a] * y;
                for b in 0..n {
                    g[(a, b)] += row[a] * row[b];
                }
            }
        }
        // The spectra are exact to ~10⁻¹³ of Σ|weight| (nufft2d) and the drag's weights' series
        // to ~10⁻¹⁴: entries of AᵀA (of size N·w², w up to 9 here) to 10⁻⁹ of N.
        let scale = t.len() as f64;
        for a in 0..n {
            for b in 0..n {
                let d = (normal.g[(a, b)] - g[(a, b)]).abs();
                assert!(
                    d < 1e-9 * scale * 81.0,
                    "G[{a},{b}]: {} against {}",
                    normal.g[(a, b)],
                    g[(a, b)]
                );
            }
            // y′ is ~10⁻⁴ rad: Aᵀy′ to 10⁻¹² of N.
            assert!(
                (normal.rhs[a] - rhs[a]).abs() < 1e-12 * scale * 9.0,
                "rhs[{a}]"
            );
        }
        // The two sums evaluate P differently (Clenshaw against the three-term recurrence): on
        // readings of ~10³ rad that differs by ~10⁻¹³ rad a sample, 10⁻⁹ of y′ ~ 10⁻⁴ rad.
        assert!(
            (normal.yy - yy).abs() < 1e-8 * yy,
            "y′ᵀy′ {} against {yy}",
            normal.yy
        );
    }
}
