//! The joint CSRR solve: both sensors' maps and every session's relative rotation at once.
//!
//! # Equation
//! Sensor A reads `x = θ + ε_a(θ)`, sensor B reads `y = θ − Δ_k + ε_b(θ − Δ_k)` in session `k`
//! (Gou et al., the CSRR paper, eq. 1). Written in terms of each sensor's error *as a function of its own
//! reading*, `e_a(x) = x − θ` and `e_b(y) = y − (θ − Δ_k)`, so that subtracting gives, for every
//! synchronized sample, exactly and whatever the size of the errors,
//!
//! ```text
//! e_a(x_n) − e_b(y_n) + Δ_k = x_n − y_n        (mod 2π)
//! ```
//!
//! No time stamps enter, so speed variation cannot bias it (unlike the paper's DC estimate of
//! eqs. 4–5, whose error is analysed in eqs. 9–17).
//!
//! # Unknowns: errors as functions of the true angle
//! A map as a function of the reading holds far more orders than the error as a function of the
//! true angle: `θ ↦ θ + ε(θ)` spreads a harmonic of order `h` and slope `h·A` into orders `2h`,
//! `3h`, … (for the seed paper's 84-pole-pair sensor, ±680″, still 0.3″ at order 1008 — beyond
//! the 1200 orders that 2400 samples per revolution can resolve). So the unknowns are the
//! Fourier series `ε_a, ε_b` of the true angle, up to order `H`, and `e(r) = ε(θ(r))` where
//! `θ(r)` solves `θ + ε(θ) = r`. Differentiating, `∂e(r)/∂c = φ_c(θ) / (1 + ε′(θ))` for a
//! coefficient `c` with basis function `φ_c`. Gauss–Newton: starting from `ε = 0` (where the
//! first step is the linear least-squares fit of the reading-domain series), each step solves
//! the linear problem
//!
//! ```text
//! δε_a(θ_a)/(1 + ε_a′(θ_a)) − δε_b(θ_b)/(1 + ε_b′(θ_b)) + δΔ_k = d_n − model_n
//! ```
//!
//! for all samples, with `θ_a = θ(x_n)`, `θ_b = θ(y_n)` from the current series. It converges in
//! a few steps (the correction is second order in the error's slope). The tables are then
//! `e(r_i) = r_i − θ(r_i)` on the output grid, exact whatever orders that takes.
//!
//! # Solution of each step
//! Samples are first reduced to fine bins of `x` per session (`csrr/bins.rs`). The normal
//! equations `AᵀNA·u = AᵀN·r` (`N` = bin counts) are solved by conjugate gradient without forming
//! `A`: `A·u` synthesizes both series on a uniform grid by inverse FFT and interpolates them at
//! the bins' `θ_a` and `θ_b` (the `nufft` module), scaled by `1/(1 + ε′)`; `Aᵀ` scales, spreads and
//! takes a forward FFT. One iteration
//! costs `O(M + G log G)` for `M` bins and a grid of `G ≈ 16H` points, so the cost of the solve
//! does not grow with the log once the bins are filled, and nothing of size `M·H` is ever formed.
//!
//! # Preconditioner
//! For uniformly spread readings the normal matrix is block-diagonal by order: the block of
//! `(a_h, b_h)` of A and B is `½[[W·I, −R_h], [−R_hᵀ, W·I]]` with `R_h = [[C, −S], [S, C]]`,
//! `C + iS = Σ_k W_k e^{ihΔ_k}`, `W = Σ_k W_k`, and the block of the `Δ_k` is `diag(W_k)`. Its
//! closed-form inverse `2/(W² − |C+iS|²)·[[W·I, R_h], [R_hᵀ, W·I]]` is the preconditioner; the
//! departures from uniform sampling (speed variation, partial revolutions, large errors) are what
//! the iterations resolve, typically in a few dozen.
//!
//! # What it cannot see
//! Order `h` is blind when `h·(Δ_k − Δ_0) ≡ 0 (mod 2π)` for all `k` and poorly determined near it
//! ([`super::observability`]); such orders are left out of both maps and reported.

use super::observability::{coefficient_variance, observability};
use super::{CsrrError, SessionData};
use crate::error_map::ErrorMap;
use crate::harmonics::FourierSeries;
use crate::nufft::{GridTransform, Stencils};

/// Options of the joint solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct JointOptions {
    /// Highest order fitted in each sensor's error (as a function of the true angle).
    pub max_order: usize,
    /// Orders whose observability ([`super::observability::observability`]) is below this are
    /// left out of the maps (default 0.01: noise on them would be amplified more than 10×).
    pub min_observability: f64,
    /// Stop each step's conjugate gradient when the preconditioned residual norm has fallen by
    /// this factor (default 1e-10).
    pub tolerance: f64,
    /// Give up a step's conjugate gradient after this many iterations (default 2000).
    pub max_iterations: usize,
    /// Gauss–Newton steps at most (default 12; degree-size errors with a coarse quantum take
    /// 7–9, see [`settled_below`]).
    pub max_steps: usize,
    /// After the fit, the residual is searched for periodic structure at the orders above
    /// `max_order` up to this one ([`JointSolution::unresolved`]; default 0: not searched).
    pub check_up_to: usize,
}

impl JointOptions {
    /// Defaults for a given maximum order.
    pub(crate) fn with_max_order(max_order: usize) -> Self {
        JointOptions {
            max_order,
            min_observability: 0.01,
            tolerance: 1e-10,
            max_iterations: 2000,
            max_steps: 12,
            check_up_to: 0,
        }
    }
}

/// An order left out of the maps.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ExcludedOrder {
    /// The order.
    pub order: usize,
    /// Its observability `q_h` (0: blind).
    pub observability: f64,
}

/// Periodic structure left in the residual at an order above the fitted ones.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct UnresolvedOrder {
    /// The order.
    pub order: usize,
    /// The amplitude that sensor A's error would have there, rad.
    pub a: f64,
    /// The amplitude that sensor B's error would have there, rad.
    pub b: f64,
}

/// The joint solve's result.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct JointSolution {
    /// Sensor A's error as a function of the true angle, `ε_a(θ)` (orders `1..=max_order`, zero
    /// at excluded orders). Its map as a function of A's reading is [`reading_map`].
    pub a: FourierSeries,
    /// Sensor B's error as a function of the true angle.
    pub b: FourierSeries,
    /// Each session's relative rotation `Δ_k`, rad (absolute: the mean of `x − y`).
    pub deltas: Vec<f64>,
    /// Orders left out, ascending.
    pub excluded: Vec<ExcludedOrder>,
    /// RMS of the per-sample residual of the joint equation, rad.
    pub residual_rms: f64,
    /// The noise per sample estimated from the bins' residuals alone,
    /// `σ² = Σ_j n_j·r_j² / (M − P)` (`r_j` the residual of bin `j`'s mean, which has the
    /// variance `σ²/n_j`; `M` bins, `P` unknowns), rad. Unlike [`JointSolution::residual_rms`] it
    /// leaves out the spread inside the bins, which for steep errors is mostly the errors'
    /// own change across a bin, not noise.
    pub noise_rms: f64,
    /// The noise per sample each order is judged by, rad, indexed by order − 1: `noise_rms`, or
    /// where the sessions disagree at that order significantly more, their scatter
    /// ([`order_noise`]).
    pub order_noise: Vec<f64>,
    /// Orders above `max_order` (up to [`JointOptions::check_up_to`]) where the residual holds
    /// periodic structure that passes the significance rule (see [`solve`]), ascending.
    pub unresolved: Vec<UnresolvedOrder>,
    /// Conjugate-gradient iterations taken, over all steps.
    pub iterations: usize,
    /// Gauss–Newton steps taken.
    pub steps: usize,
    /// Whether every step reached its tolerance and the steps converged.
    pub converged: bool,
}

/// Fast evaluation of a series and its derivative at many points, by grid synthesis and
/// interpolation (the `nufft` module).
struct SeriesEval {
    orders: Vec<usize>,
    fft: GridTransform,
    value: Vec<f64>,
    slope: Vec<f64>,
}

impl SeriesEval {
    fn new(orders: Vec<usize>, grid: usize) -> Self {
        SeriesEval {
            fft: GridTransform::new(grid),
            value: vec![0.0; grid],
            slope: vec![0.0; grid],
            orders,
        }
    }

    /// Loads `cos`/`sin` coefficients (one per order in `orders`).
    fn load(&mut self, cos: &[f64], sin: &[f64]) {
        self.fft.synthesize(&self.orders, cos, sin, &mut self.value);
        // d/dθ (a cos hθ + b sin hθ) = h·b cos hθ − h·a sin hθ
        let dcos: Vec<f64> = self
            .orders
            .iter()
            .zip(sin)
            .map(|(&h, b)| h as f64 * b)
            .collect();
        let dsin: Vec<f64> = self
            .orders
            .iter()
            .zip(cos)
            .map(|(&h, a)| -(h as f64) * a)
            .collect();
        self.fft
            .synthesize(&self.orders, &dcos, &dsin, &mut self.slope);
    }

    /// `θ` with `θ + ε(θ) = r` for every `r`, by Newton's method (`|ε′| < 1` for any sensor whose
    /// reading increases with the angle), from the guess in `theta` (overwritten). Returns the
    /// stencils at the final `θ` (which the step's operator reuses) and `1/(1 + ε′(θ))` there.
    ///
    /// Newton stops when no point moved by more than [`NEWTON_TOLERANCE`] (the next update would
    /// be of the order of its square), or after [`NEWTON_STEPS`] updates. From the previous
    /// Gauss–Newton step's `θ` that takes one update once the series settle.
    ///
    /// `at`: the stencils at `theta` as given, if the caller holds them (the last inversion's,
    /// `theta` unchanged since). After an update only the points whose `θ` changed (bit for bit)
    /// get a new stencil and a new `ε, ε′`: a stencil is a function of its point alone, so the
    /// others' are the same numbers. Near the end most updates are below half an ulp of `θ` and
    /// change nothing; building every stencil after every update (four builds per inversion on
    /// average) was as much of the solve as its conjugate-gradient iterations (callgrind,
    /// `calib csrr --jobs 1`, 10⁶ samples: 2.8 of 5.6·10⁹ instructions).
    fn invert(
        &self,
        readings: &[f64],
        theta: &mut [f64],
        at: Option<Stencils>,
    ) -> (Stencils, Vec<f64>) {
        let grid = self.value.len();
        let mut e = vec![0.0; theta.len()];
        let mut de = vec![0.0; theta.len()];
        let mut st = at.unwrap_or_else(|| Stencils::new(theta.iter().copied(), grid));
        debug_assert_eq!(st.len(), theta.len());
        st.gather2((&self.value, &self.slope), (&mut e, &mut de));
        let mut settled = false;
        let mut updates = 0;
        let mut moved = Vec::new();
        loop {
            if settled || updates == NEWTON_STEPS {
                let scale = de.iter().map(|d| 1.0 / (1.0 + d).max(0.05)).collect();
                return (st, scale);
            }
            let mut largest = 0.0f64;
            moved.clear();
            for (j, (((t, &r), &e), &de)) in
                theta.iter_mut().zip(readings).zip(&e).zip(&de).enumerate()
            {
                let update = (*t + e - r) / (1.0 + de).max(0.05);
                let before = t.to_bits();
                *t -= update;
                if t.to_bits() != before {
                    moved.push(j);
                }
                largest = largest.max(update.abs());
            }
            updates += 1;
            settled = largest <= NEWTON_TOLERANCE;
            for &j in &moved {
                st.set(j, theta[j]);
            }
            st.gather2_at(&moved, (&self.value, &self.slope), (&mut e, &mut de));
        }
    }
}

/// A sensor's stencils at its inverted angles and `1/(1 + ε′)` there ([`SeriesEval::invert`]).
type Inverted = (Stencils, Vec<f64>);

/// A series' `cos` and `sin` coefficients, one per order.
type Coefficients<'a> = (&'a [f64], &'a [f64]);

/// Both sensors' series loaded with their `(cos, sin)` coefficients and inverted at their
/// readings ([`SeriesEval::invert`], from the stencils `at` at `theta` where given), side by
/// side on rayon's threads: each exactly as alone.
fn invert_both(
    evals: (&mut SeriesEval, &mut SeriesEval),
    coefficients: (Coefficients, Coefficients),
    readings: (&[f64], &[f64]),
    theta: (&mut [f64], &mut [f64]),
    at: (Option<Stencils>, Option<Stencils>),
) -> (Inverted, Inverted) {
    let ((ca, sa), (cb, sb)) = coefficients;
    rayon::join(
        || {
            evals.0.load(ca, sa);
            evals.0.invert(readings.0, theta.0, at.0)
        },
        || {
            evals.1.load(cb, sb);
            evals.1.invert(readings.1, theta.1, at.1)
        },
    )
}

/// Newton's updates in [`SeriesEval::invert`] stop below this, rad (2·10⁻⁹″).
const NEWTON_TOLERANCE: f64 = 1e-14;

/// At most this many Newton updates per inversion: from the readings themselves (`θ = r`), the
/// first update leaves an error of about `ε″·ε²/2` and each further one squares it, so for
/// errors of ±680″ at order 84 (the steepest bundled case) three suffice.
const NEWTON_STEPS: usize = 8;

/// One Gauss–Newton step's linear operator `A` and its weighted transpose.
///
/// The two sensors' halves of each product are independent (each its own series, stencils and
/// grid) and run side by side on rayon's threads; each is computed exactly as it would be alone,
/// so the result does not depend on the number of threads.
struct Step<'a> {
    orders: &'a [usize],
    /// Bins `sessions[k]` belong to session `k` (bins are grouped by session).
    sessions: &'a [std::ops::Range<usize>],
    n: &'a [f64],
    /// Sensor `a`'s half, its weights `n·scale_a`.
    a: Side<'a>,
    /// Sensor `b`'s half, its weights `−n·scale_b`.
    b: Side<'a>,
}

/// One sensor's half of a [`Step`]: its series evaluated at the bins' angles, and the transpose.
struct Side<'a> {
    at: Stencils,
    scale: Vec<f64>,
    /// The weights of [`Side::transpose`]: `±n·scale`.
    weight: Vec<f64>,
    fft: &'a mut GridTransform,
    grid: Vec<f64>,
    /// The series at each bin (after [`Side::evaluate`]), or the weighted residual.
    e: Vec<f64>,
}

impl Side<'_> {
    /// `e = Σ_h c_h cos hθ + s_h sin hθ` at the bins' angles.
    fn evaluate(&mut self, orders: &[usize], cos: &[f64], sin: &[f64]) {
        self.fft.synthesize(orders, cos, sin, &mut self.grid);
        self.at.gather(&self.grid, &mut self.e);
    }

    /// `(gc, gs) = Σ_j weight_j r_j (cos hθ_j, sin hθ_j)`, the transpose of
    /// [`Side::evaluate`] applied to the weighted `r`.
    fn transpose(&mut self, orders: &[usize], r: &[f64], gc: &mut [f64], gs: &mut [f64]) {
        for ((e, &w), &r) in self.e.iter_mut().zip(&self.weight).zip(r) {
            *e = w * r;
        }
        self.grid.fill(0.0);
        self.at.scatter(&self.e, &mut self.grid);
        self.fft.analyze_transpose(&mut self.grid, orders, gc, gs);
    }
}

impl Step<'_> {
    fn len(&self) -> usize {
        4 * self.orders.len() + self.sessions.len()
    }

    /// `r = A·u` (per bin, unweighted).
    fn apply(&mut self, u: &[f64], r: &mut [f64]) {
        let l = self.orders.len();
        let orders = self.orders;
        let (a, b) = (&mut self.a, &mut self.b);
        rayon::join(
            || a.evaluate(orders, &u[..l], &u[l..2 * l]),
            || b.evaluate(orders, &u[2 * l..3 * l], &u[3 * l..4 * l]),
        );
        let deltas = &u[4 * l..];
        for (range, &delta) in self.sessions.iter().zip(deltas) {
            let r = &mut r[range.clone()];
            let (sa, ea) = (&self.a.scale[range.clone()], &self.a.e[range.clone()]);
            let (sb, eb) = (&self.b.scale[range.clone()], &self.b.e[range.clone()]);
            for ((((rj, &sa), &ea), &sb), &eb) in r.iter_mut().zip(sa).zip(ea).zip(sb).zip(eb) {
                *rj = sa * ea - sb * eb + delta;
            }
        }
    }

    /// `g = Aᵀ·(N∘r)`.
    fn transpose_weighted(&mut self, r: &[f64], g: &mut [f64]) {
        let l = self.orders.len();
        let orders = self.orders;
        let (ga, rest) = g.split_at_mut(2 * l);
        let (gb, gd) = rest.split_at_mut(2 * l);
        let (gac, gas) = ga.split_at_mut(l);
        let (gbc, gbs) = gb.split_at_mut(l);
        let (a, b) = (&mut self.a, &mut self.b);
        rayon::join(
            || a.transpose(orders, r, gac, gas),
            || b.transpose(orders, r, gbc, gbs),
        );
        for (range, gd) in self.sessions.iter().zip(gd) {
            *gd = self.n[range.clone()]
                .iter()
                .zip(&r[range.clone()])
                .map(|(n, r)| n * r)
                .sum();
        }
    }
}

/// Block-Jacobi preconditioner of the idealized normal matrix (see the module docs).
struct Preconditioner {
    /// Per included order: `(W, C, S)` scaled as `2/(W² − C² − S²)`.
    blocks: Vec<[f64; 3]>,
    session_weights: Vec<f64>,
}

impl Preconditioner {
    fn new(orders: &[usize], deltas: &[f64], weights: &[f64]) -> Self {
        let w: f64 = weights.iter().sum();
        let blocks = orders
            .iter()
            .map(|&h| {
                let (mut c, mut s) = (0.0, 0.0);
                for (&d, &wk) in deltas.iter().zip(weights) {
                    let (sn, cs) = (h as f64 * d).sin_cos();
                    c += wk * cs;
                    s += wk * sn;
                }
                let f = 2.0 / (w * w - c * c - s * s);
                [w * f, c * f, s * f]
            })
            .collect();
        Preconditioner {
            blocks,
            session_weights: weights.to_vec(),
        }
    }

    fn apply(&self, r: &[f64], z: &mut [f64]) {
        let l = self.blocks.len();
        for (i, &[w, c, s]) in self.blocks.iter().enumerate() {
            let (ac, as_, bc, bs) = (r[i], r[l + i], r[2 * l + i], r[3 * l + i]);
            z[i] = w * ac + c * bc - s * bs;
            z[l + i] = w * as_ + s * bc + c * bs;
            z[2 * l + i] = c * ac + s * as_ + w * bc;
            z[3 * l + i] = -s * ac + c * as_ + w * bs;
        }
        for (k, &wk) in self.session_weights.iter().enumerate() {
            z[4 * l + k] = r[4 * l + k] / wk;
        }
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Preconditioned conjugate gradient on `AᵀNA·u = AᵀN·rhs`, from `u = 0`. Returns the
/// iterations taken and whether the tolerance was reached.
fn conjugate_gradient(
    step: &mut Step<'_>,
    precond: &Preconditioner,
    rhs: &[f64],
    u: &mut [f64],
    opts: &JointOptions,
) -> (usize, bool) {
    let nu = step.len();
    let mut au = vec![0.0; rhs.len()];
    let mut r = vec![0.0; nu];
    step.transpose_weighted(rhs, &mut r);
    u.iter_mut().for_each(|v| *v = 0.0);
    let mut z = vec![0.0; nu];
    precond.apply(&r, &mut z);
    let mut p = z.clone();
    let mut rz = dot(&r, &z);
    let rz0 = rz;
    if rz0 == 0.0 {
        return (0, true);
    }
    let mut ap = vec![0.0; nu];
    for iteration in 1..=opts.max_iterations {
        step.apply(&p, &mut au);
        step.transpose_weighted(&au, &mut ap);
        let pap = dot(&p, &ap);
        if pap <= 0.0 || !pap.is_finite() {
            return (iteration, false);
        }
        let alpha = rz / pap;
        for i in 0..nu {
            u[i] += alpha * p[i];
            r[i] -= alpha * ap[i];
        }
        precond.apply(&r, &mut z);
        let rz_new = dot(&r, &z);
        if rz_new.sqrt() <= opts.tolerance * rz0.sqrt() {
            return (iteration, true);
        }
        let beta = rz_new / rz;
        rz = rz_new;
        for i in 0..nu {
            p[i] = z[i] + beta * p[i];
        }
    }
    (opts.max_iterations, false)
}

/// Gauss–Newton has converged when its last step moved no coefficient by more than this, rad:
/// [`SETTLED_FRACTION`] of the smallest standard deviation a coefficient can have,
/// `σ·√(2/W)` (`σ` the RMS residual per sample at the step, `W` the samples; an order seen
/// ideally, [`super::observability::coefficient_variance`]), and at least 10⁻⁶″ (noise-free
/// data). The steps contract by about `σ·h` (the residual times the curvature of the model in
/// the coefficients of order `h`), so with degree-size errors and a coarse quantum (σ ≈ 30″,
/// `σ·h ≈ 0.2` at order 1200) an absolute bound of 10⁻⁶″ takes more steps than any
/// statistically meaningful change; a step below 1 % of the coefficients' noise changes no
/// figure the calibration reports.
fn settled_below(sigma: f64, weights: &[f64]) -> f64 {
    let w: f64 = weights.iter().sum();
    let floor = 1e-6 / crate::angle::ARCSEC_PER_RAD;
    if w > 0.0 && sigma.is_finite() {
        (SETTLED_FRACTION * sigma * (2.0 / w).sqrt()).max(floor)
    } else {
        floor
    }
}

/// See [`settled_below`].
const SETTLED_FRACTION: f64 = 1e-2;

/// Points of the uniform grid for series up to `max_order`: at least 16 per period of the highest
/// order (the `nufft` module's accuracy), a power of two for the FFT.
pub(crate) fn grid_points(max_order: usize) -> usize {
    (16 * max_order).max(64).next_power_of_two()
}

/// Solves the joint CSRR equation for the binned sessions. See the module docs.
///
/// Every observable order up to [`JointOptions::max_order`] is fitted, or, with
/// `refit = (orders, previous)`, the observable ones among `orders`, starting from `previous`'s
/// coefficients and rotations (a fit of more orders to the same data: one or two Gauss–Newton
/// steps then suffice). Then, if [`JointOptions::check_up_to`] is above the highest
/// order, the residual `r_j` is projected per session on the orders above it,
/// `z_k(h) = (2/W_k)·Σ_{j∈k} n_j r_j e^{−ihθ_j}` (by scatter and FFT, as in the solve), and
/// `z_k = α − β·e^{−ihΔ_k}` is solved for the complex amplitudes `α, β` that sensor A's and B's
/// errors would have at order `h` — the same 2×2 block as the fit's, whose inverse gives each
/// amplitude the variance `2σ²W/(W² − |S_h|²)` per coefficient
/// ([`super::observability::coefficient_variance`]). An order whose `α` or `β` passes the
/// significance rule ([`crate::tdr::significance_threshold`] over the `2M` amplitudes of the `M`
/// orders searched) is reported.
///
/// A harmonic of either sensor's error leaves the same `α` and `β` in every session; structure
/// that differs from session to session is not one. So each order is judged by the noise
/// [`order_noise`] gives it: `σ`, or the sessions' own scatter about `α − β·e^{−ihΔ_k}` where that
/// is significantly larger. The same per-order noise is given for the fitted orders
/// ([`JointSolution::order_noise`]), for their significance and uncertainty.
pub(crate) fn solve(
    sessions: &[SessionData],
    opts: &JointOptions,
    refit: Option<(&[usize], &JointSolution)>,
) -> Result<JointSolution, CsrrError> {
    if sessions.len() < 2 {
        return Err(CsrrError::TooFewSessions {
            found: sessions.len(),
        });
    }
    let k_count = sessions.len();
    let weights: Vec<f64> = sessions
        .iter()
        .map(|s| s.bins.iter().map(|b| b.n).sum())
        .collect();
    let mut deltas: Vec<f64> = sessions
        .iter()
        .zip(&weights)
        .map(|(s, w)| s.bins.iter().map(|b| b.n * b.d).sum::<f64>() / w)
        .collect();
    let centred: Vec<f64> = deltas.iter().map(|d| d - deltas[0]).collect();
    let mut orders = Vec::new();
    let mut excluded = Vec::new();
    for h in 1..=opts.max_order {
        let q = observability(h, &centred, &weights);
        if q < opts.min_observability {
            excluded.push(ExcludedOrder {
                order: h,
                observability: q,
            });
        } else if refit.is_none_or(|(o, _)| o.contains(&h)) {
            orders.push(h);
        }
    }
    if orders.is_empty() {
        return Err(CsrrError::NothingObservable {
            max_order: opts.max_order,
        });
    }

    let grid = grid_points(*orders.last().expect("not empty"));
    let bins: Vec<_> = sessions.iter().flat_map(|s| s.bins.iter()).collect();
    let m = bins.len();
    let xs: Vec<f64> = bins.iter().map(|b| b.x).collect();
    let ys: Vec<f64> = bins.iter().map(|b| b.x - b.d).collect();
    let d: Vec<f64> = bins.iter().map(|b| b.d).collect();
    let n: Vec<f64> = bins.iter().map(|b| b.n).collect();
    let mut session_of: Vec<u32> = Vec::with_capacity(m);
    let mut ranges = Vec::with_capacity(k_count);
    for (k, s) in sessions.iter().enumerate() {
        ranges.push(session_of.len()..session_of.len() + s.bins.len());
        session_of.extend(std::iter::repeat_n(k as u32, s.bins.len()));
    }
    let precond = Preconditioner::new(&orders, &centred, &weights);
    let l = orders.len();
    let (mut ca, mut sa, mut cb, mut sb) = (vec![0.0; l], vec![0.0; l], vec![0.0; l], vec![0.0; l]);
    if let Some((_, previous)) = refit {
        for (i, &h) in orders.iter().enumerate() {
            ca[i] = previous.a.cos[h - 1];
            sa[i] = previous.a.sin[h - 1];
            cb[i] = previous.b.cos[h - 1];
            sb[i] = previous.b.sin[h - 1];
        }
        deltas.clone_from(&previous.deltas);
    }
    let mut eval_a = SeriesEval::new(orders.clone(), grid);
    let mut eval_b = SeriesEval::new(orders.clone(), grid);
    let mut iterations = 0;
    let mut converged = false;
    let mut steps = 0;
    let mut residual = vec![0.0; m];
    let mut du = vec![0.0; 4 * l + k_count];
    let (mut fft_a, mut fft_b) = (GridTransform::new(grid), GridTransform::new(grid));
    // Each step's inversion starts from the last step's angles, and their stencils.
    let mut theta_a = xs.clone();
    let mut theta_b = ys.clone();
    let mut at = (None, None);
    while steps < opts.max_steps {
        let ((at_a, scale_a), (at_b, scale_b)) = invert_both(
            (&mut eval_a, &mut eval_b),
            ((&ca, &sa), (&cb, &sb)),
            (&xs, &ys),
            (&mut theta_a, &mut theta_b),
            at,
        );
        for j in 0..m {
            let model =
                (xs[j] - theta_a[j]) - (ys[j] - theta_b[j]) + deltas[session_of[j] as usize];
            residual[j] = d[j] - model;
        }
        let mut step = Step {
            orders: &orders,
            sessions: &ranges,
            n: &n,
            a: Side {
                at: at_a,
                weight: n.iter().zip(&scale_a).map(|(n, s)| n * s).collect(),
                scale: scale_a,
                fft: &mut fft_a,
                grid: vec![0.0; grid],
                e: vec![0.0; m],
            },
            b: Side {
                at: at_b,
                weight: n.iter().zip(&scale_b).map(|(n, s)| -n * s).collect(),
                scale: scale_b,
                fft: &mut fft_b,
                grid: vec![0.0; grid],
                e: vec![0.0; m],
            },
        };
        let (its, ok) = conjugate_gradient(&mut step, &precond, &residual, &mut du, opts);
        at = (Some(step.a.at), Some(step.b.at));
        let step_noise = (n.iter().zip(&residual).map(|(n, r)| n * r * r).sum::<f64>()
            / n.iter().sum::<f64>())
        .sqrt();
        iterations += its;
        steps += 1;
        let mut largest = 0.0f64;
        for i in 0..l {
            ca[i] += du[i];
            sa[i] += du[l + i];
            cb[i] += du[2 * l + i];
            sb[i] += du[3 * l + i];
            largest = largest
                .max(du[i].hypot(du[l + i]))
                .max(du[2 * l + i].hypot(du[3 * l + i]));
        }
        for k in 0..k_count {
            deltas[k] += du[4 * l + k];
        }
        if !largest.is_finite() {
            return Err(CsrrError::NotFinite);
        }
        if largest < settled_below(step_noise, &weights) {
            converged = ok;
            break;
        }
    }

    // Residual of the final model, per sample: between-bin part plus the spread inside bins.
    invert_both(
        (&mut eval_a, &mut eval_b),
        ((&ca, &sa), (&cb, &sb)),
        (&xs, &ys),
        (&mut theta_a, &mut theta_b),
        at,
    );
    let total: f64 = n.iter().sum();
    let within: f64 = sessions
        .iter()
        .flat_map(|s| &s.bins)
        .map(|b| b.d_var_sum)
        .sum();
    for j in 0..m {
        let model = (xs[j] - theta_a[j]) - (ys[j] - theta_b[j]) + deltas[session_of[j] as usize];
        residual[j] = d[j] - model;
    }
    let between: f64 = n.iter().zip(&residual).map(|(n, r)| n * r * r).sum();
    let residual_rms = ((between + within) / total).sqrt();
    let noise_rms = (between / m.saturating_sub(4 * l + k_count).max(1) as f64).sqrt();
    if !residual_rms.is_finite() {
        return Err(CsrrError::NotFinite);
    }

    let unresolved = residual_structure(
        opts, &ranges, &theta_a, &n, &residual, &deltas, &weights, noise_rms,
    );
    let order_noise = fitted_order_noise(
        opts.max_order,
        &orders,
        &ranges,
        &theta_a,
        &n,
        &residual,
        &deltas,
        &weights,
        noise_rms,
    );

    let mut a = FourierSeries::zeros(opts.max_order);
    let mut b = FourierSeries::zeros(opts.max_order);
    for (i, &h) in orders.iter().enumerate() {
        a.cos[h - 1] = ca[i];
        a.sin[h - 1] = sa[i];
        b.cos[h - 1] = cb[i];
        b.sin[h - 1] = sb[i];
    }
    Ok(JointSolution {
        a,
        b,
        deltas,
        excluded,
        residual_rms,
        noise_rms,
        order_noise,
        unresolved,
        iterations,
        steps,
        converged,
    })
}

/// Each session's projection of the weighted residual on `orders`:
/// `z_k(h) = (2/W_k)·Σ_{j∈k} n_j r_j e^{−ihθ_j}` as `(re, im)`, `z[k][i]` for `orders[i]` (by
/// scatter onto a grid and FFT, as in the solve).
fn session_projections(
    ranges: &[std::ops::Range<usize>],
    theta: &[f64],
    n: &[f64],
    residual: &[f64],
    weights: &[f64],
    orders: &[usize],
) -> Vec<Vec<(f64, f64)>> {
    let grid = grid_points(orders.iter().copied().max().unwrap_or(1));
    let mut fft = GridTransform::new(grid);
    let mut q = vec![0.0; grid];
    ranges
        .iter()
        .zip(weights)
        .map(|(range, &w)| {
            let st = Stencils::new(theta[range.clone()].iter().copied(), grid);
            let values: Vec<f64> = n[range.clone()]
                .iter()
                .zip(&residual[range.clone()])
                .map(|(n, r)| n * r)
                .collect();
            q.fill(0.0);
            st.scatter(&values, &mut q);
            let (mut c, mut s) = (vec![0.0; orders.len()], vec![0.0; orders.len()]);
            fft.analyze_transpose(&mut q, orders, &mut c, &mut s);
            c.iter()
                .zip(&s)
                .map(|(c, s)| (2.0 * c / w, -2.0 * s / w))
                .collect()
        })
        .collect()
}

/// Order `h`'s weighted least squares of the sessions' projections `z_k = α − β·u_k`,
/// `u_k = e^{−ihΔ_k}` (`z` one projection per session, `centred` the rotations against the
/// first): the complex amplitudes `α, β` A's and B's errors would have there, and the misfit
/// `Σ_k W_k·|z_k − α + β·u_k|²` — what the sessions disagree on beyond any pair of harmonics.
fn fit_order(
    h: usize,
    z: impl Fn(usize) -> (f64, f64),
    centred: &[f64],
    weights: &[f64],
) -> ((f64, f64), (f64, f64), f64) {
    let w: f64 = weights.iter().sum();
    // [[W, −S], [−S̄, W]]·[α; β] = [Σ W_k z_k; −Σ W_k ū_k z_k], S = Σ W_k u_k.
    let (mut s, mut p, mut r) = ((0.0, 0.0), (0.0, 0.0), (0.0, 0.0));
    for (k, &wk) in weights.iter().enumerate() {
        let (sn, cs) = (h as f64 * centred[k]).sin_cos();
        let u = (cs, -sn);
        let zk = z(k);
        s = (s.0 + wk * u.0, s.1 + wk * u.1);
        p = (p.0 + wk * zk.0, p.1 + wk * zk.1);
        // −ū·z = −(u.0 − i u.1)(z.0 + i z.1)
        r = (
            r.0 - wk * (u.0 * zk.0 + u.1 * zk.1),
            r.1 - wk * (u.0 * zk.1 - u.1 * zk.0),
        );
    }
    let det = w * w - s.0 * s.0 - s.1 * s.1;
    // α = (W·P + S·R)/det, β = (S̄·P + W·R)/det
    let alpha = (
        (w * p.0 + s.0 * r.0 - s.1 * r.1) / det,
        (w * p.1 + s.0 * r.1 + s.1 * r.0) / det,
    );
    let beta = (
        (s.0 * p.0 + s.1 * p.1 + w * r.0) / det,
        (s.0 * p.1 - s.1 * p.0 + w * r.1) / det,
    );
    let mut misfit = 0.0;
    for (k, &wk) in weights.iter().enumerate() {
        let (sn, cs) = (h as f64 * centred[k]).sin_cos();
        let zk = z(k);
        // α − β·u with u = (cs, −sn)
        let fit = (
            alpha.0 - (beta.0 * cs + beta.1 * sn),
            alpha.1 - (beta.1 * cs - beta.0 * sn),
        );
        misfit += wk * ((zk.0 - fit.0).powi(2) + (zk.1 - fit.1).powi(2));
    }
    (alpha, beta, misfit)
}

/// The noise per sample to judge order `h` by: `σ`, or the sessions' own scatter at that order
/// where it is significantly larger. Under noise alone `misfit` ([`fit_order`]) is
/// `2σ²·χ²(ν)`, `ν = 2K − 4` for `K` sessions (each `z_k` has the variance `2σ²/W_k` per
/// component; four real unknowns fitted), so `σ_h² = misfit/(2ν)` estimates `σ²`. Structure that
/// differs from session to session — not a harmonic of either sensor, e.g. the quantization of a
/// slowly turning sensor, whose residual depends on where each session's relative rotation puts
/// B's quantum against A's — makes it larger. `σ_h` replaces `σ` when `σ_h²/σ²` exceeds the 99th
/// percentile of `χ²(ν)/ν` (Wilson–Hilferty); with fewer than three sessions (`ν = 0`) `σ` is
/// kept.
///
/// The noise need not be white: a coarse quantum makes the residual's spectrum uneven. So `σ`
/// is first raised to `local`, the sessions' scatter averaged over the neighbouring orders
/// ([`local_scatter`]) where that is larger: an order must stand out of the noise around it.
fn order_noise(sigma: f64, misfit: f64, local: f64, sessions: usize) -> f64 {
    let nu = (2 * sessions).saturating_sub(4);
    if nu == 0 {
        return sigma;
    }
    let sigma = sigma.max(local);
    let nu = nu as f64;
    let scatter = misfit / (2.0 * nu);
    // 99th percentile of χ²(ν)/ν: (1 − 2/(9ν) + z·√(2/(9ν)))³, z = 2.326.
    let c = 2.0 / (9.0 * nu);
    let quantile = (1.0 - c + 2.326 * c.sqrt()).powi(3);
    if scatter > quantile * sigma * sigma {
        scatter.sqrt()
    } else {
        sigma
    }
}

/// Half-width, in orders, of the window [`local_scatter`] averages over: 65 orders of `2K − 4`
/// degrees of freedom each (≥ 130), so that under white noise the local figure is within about
/// ±12 % of `σ` (two standard deviations) and raises it little.
const LOCAL_ORDERS: usize = 32;

/// For each of `misfits` (one per order of an ascending list), the scatter `misfit/(2ν)`
/// averaged over the [`LOCAL_ORDERS`] entries on either side, as an RMS per sample (0 with
/// fewer than three sessions).
fn local_scatter(misfits: &[f64], sessions: usize) -> Vec<f64> {
    let nu = (2 * sessions).saturating_sub(4);
    if nu == 0 {
        return vec![0.0; misfits.len()];
    }
    let mut prefix = vec![0.0; misfits.len() + 1];
    for (i, m) in misfits.iter().enumerate() {
        prefix[i + 1] = prefix[i] + m;
    }
    (0..misfits.len())
        .map(|i| {
            let lo = i.saturating_sub(LOCAL_ORDERS);
            let hi = (i + LOCAL_ORDERS + 1).min(misfits.len());
            ((prefix[hi] - prefix[lo]) / ((hi - lo) as f64 * 2.0 * nu as f64)).sqrt()
        })
        .collect()
}

/// The noise per sample to judge each fitted order by ([`order_noise`]), indexed by order − 1
/// up to `max_order` (`σ` at orders not fitted).
#[allow(clippy::too_many_arguments)]
fn fitted_order_noise(
    max_order: usize,
    orders: &[usize],
    ranges: &[std::ops::Range<usize>],
    theta: &[f64],
    n: &[f64],
    residual: &[f64],
    deltas: &[f64],
    weights: &[f64],
    sigma: f64,
) -> Vec<f64> {
    let mut noise = vec![sigma; max_order];
    if sigma <= 0.0 || orders.is_empty() {
        return noise;
    }
    let z = session_projections(ranges, theta, n, residual, weights, orders);
    let centred: Vec<f64> = deltas.iter().map(|d| d - deltas[0]).collect();
    let misfits: Vec<f64> = (0..orders.len())
        .map(|i| fit_order(orders[i], |k| z[k][i], &centred, weights).2)
        .collect();
    let local = local_scatter(&misfits, weights.len());
    for (i, &h) in orders.iter().enumerate() {
        noise[h - 1] = order_noise(sigma, misfits[i], local[i], weights.len());
    }
    noise
}

/// The orders above the fitted ones that the residual holds (see [`solve`]).
#[allow(clippy::too_many_arguments)]
fn residual_structure(
    opts: &JointOptions,
    ranges: &[std::ops::Range<usize>],
    theta: &[f64],
    n: &[f64],
    residual: &[f64],
    deltas: &[f64],
    weights: &[f64],
    sigma: f64,
) -> Vec<UnresolvedOrder> {
    let (lo, hi) = (opts.max_order + 1, opts.check_up_to);
    if hi < lo || sigma <= 0.0 {
        return Vec::new();
    }
    let tested: Vec<usize> = (lo..=hi).collect();
    let z = session_projections(ranges, theta, n, residual, weights, &tested);
    let centred: Vec<f64> = deltas.iter().map(|d| d - deltas[0]).collect();
    let threshold = crate::tdr::significance_threshold(2 * tested.len());
    let fits: Vec<_> = (0..tested.len())
        .map(|i| fit_order(tested[i], |k| z[k][i], &centred, weights))
        .collect();
    let misfits: Vec<f64> = fits.iter().map(|f| f.2).collect();
    let local = local_scatter(&misfits, weights.len());
    let mut found = Vec::new();
    for (i, &h) in tested.iter().enumerate() {
        if observability(h, &centred, weights) < opts.min_observability {
            continue;
        }
        let (alpha, beta, misfit) = fits[i];
        let sigma_h = order_noise(sigma, misfit, local[i], weights.len());
        let var = coefficient_variance(h, &centred, weights, sigma_h);
        let (a, b) = (alpha.0.hypot(alpha.1), beta.0.hypot(beta.1));
        if a * a / var > threshold || b * b / var > threshold {
            found.push(UnresolvedOrder { order: h, a, b });
        }
    }
    found
}

/// The map of an error given as a function of the true angle, `ε(θ)`, as a function of the
/// reading: `e(r_i) = r_i − θ(r_i)` with `θ + ε(θ) = r_i`, on `points` grid points. Exact
/// whatever orders the reading-domain map holds.
pub(crate) fn reading_map(series: &FourierSeries, points: usize) -> ErrorMap {
    let orders: Vec<usize> = (1..=series.max_order()).collect();
    let grid = grid_points(series.max_order());
    let mut eval = SeriesEval::new(orders, grid);
    eval.load(&series.cos, &series.sin);
    let n = points.max(1);
    let readings: Vec<f64> = (0..n)
        .map(|i| std::f64::consts::TAU * i as f64 / n as f64)
        .collect();
    let mut theta = readings.clone();
    eval.invert(&readings, &mut theta, None);
    ErrorMap::new(readings.iter().zip(&theta).map(|(r, t)| r - t).collect())
}
