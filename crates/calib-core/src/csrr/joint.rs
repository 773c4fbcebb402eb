//! The joint CSRR solve: both sensors' maps and every session's relative rotation at once.
//!
//! # Equation
//! Sensor A reads `x = θ + ε_a(θ)`, sensor B reads `y = θ − Δ_k + ε_b(θ − Δ_k)` in session `k`
//! (seed paper `000_…`, eq. 1). Written in terms of each sensor's error *as a function of its own
//! reading*, `e_a(x) = x − θ` and `e_b(y) = y − (θ − Δ_k)`, so that subtracting gives, for every
//! synchronized sample, exactly and whatever the size of the errors,
//!
//! ```text
//! e_a(x_n) − e_b(y_n) + Δ_k = x_n − y_n        (mod 2π)
//! ```
//!
//! With `e_a, e_b` zero-mean Fourier series up to order `H` and one `Δ_k` per session this is a
//! *linear* least-squares problem in `4H + K` unknowns: the readings are known, so no
//! small-error linearization and no time stamps enter (speed variation cannot bias it, unlike the
//! paper's DC estimate of eqs. 4–5 whose error is analysed in eqs. 9–17).
//!
//! # Solution
//! Samples are first reduced to fine bins of `x` per session ([`super::bins`]). The normal
//! equations `AᵀNA·u = AᵀN·d` (`N` = bin counts) are solved by conjugate gradient without forming
//! `A`: `A·u` synthesizes both series on a uniform grid by inverse FFT and interpolates them at
//! the bins' `x̄` and `ȳ` ([`super::nufft`]); `Aᵀ` spreads and takes a forward FFT. One iteration
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

use super::nufft::{GridTransform, Stencils};
use super::observability::observability;
use super::{CsrrError, SessionData};
use crate::harmonics::FourierSeries;

/// Options of the joint solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointOptions {
    /// Highest order fitted in each map.
    pub max_order: usize,
    /// Orders whose observability ([`super::observability::observability`]) is below this are
    /// left out of the maps (default 0.01: noise on them would be amplified more than 10×).
    pub min_observability: f64,
    /// Stop when the preconditioned residual norm has fallen by this factor (default 1e-10).
    pub tolerance: f64,
    /// Give up after this many iterations (default 2000).
    pub max_iterations: usize,
}

impl JointOptions {
    /// Defaults for a given maximum order.
    pub fn with_max_order(max_order: usize) -> Self {
        JointOptions {
            max_order,
            min_observability: 0.01,
            tolerance: 1e-10,
            max_iterations: 2000,
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

/// The joint solve's result.
#[derive(Debug, Clone, PartialEq)]
pub struct JointSolution {
    /// Sensor A's map (orders `1..=max_order`, zero at excluded orders).
    pub a: FourierSeries,
    /// Sensor B's map.
    pub b: FourierSeries,
    /// Each session's relative rotation `Δ_k`, rad (absolute: the mean of `x − y`).
    pub deltas: Vec<f64>,
    /// Orders left out, ascending.
    pub excluded: Vec<ExcludedOrder>,
    /// RMS of the per-sample residual of the joint equation, rad.
    pub residual_rms: f64,
    /// Conjugate-gradient iterations taken.
    pub iterations: usize,
    /// Whether the tolerance was reached.
    pub converged: bool,
}

/// The flattened equations and the operator `AᵀNA`.
struct Problem {
    orders: Vec<usize>,
    sessions: usize,
    session_of: Vec<u32>,
    n: Vec<f64>,
    d: Vec<f64>,
    at_x: Stencils,
    at_y: Stencils,
    fft: GridTransform,
    grid_buf: Vec<f64>,
    ea: Vec<f64>,
    eb: Vec<f64>,
}

impl Problem {
    fn len(&self) -> usize {
        4 * self.orders.len() + self.sessions
    }

    /// `r = A·u` (per bin, unweighted).
    fn apply(&mut self, u: &[f64], r: &mut [f64]) {
        let l = self.orders.len();
        self.fft
            .synthesize(&self.orders, &u[..l], &u[l..2 * l], &mut self.grid_buf);
        self.at_x.gather(&self.grid_buf, &mut self.ea);
        self.fft.synthesize(
            &self.orders,
            &u[2 * l..3 * l],
            &u[3 * l..4 * l],
            &mut self.grid_buf,
        );
        self.at_y.gather(&self.grid_buf, &mut self.eb);
        let deltas = &u[4 * l..];
        for (j, rj) in r.iter_mut().enumerate() {
            *rj = self.ea[j] - self.eb[j] + deltas[self.session_of[j] as usize];
        }
    }

    /// `g = Aᵀ·(N∘r)`.
    fn transpose_weighted(&mut self, r: &[f64], g: &mut [f64]) {
        let l = self.orders.len();
        for (j, w) in self.ea.iter_mut().enumerate() {
            *w = self.n[j] * r[j];
        }
        let (ga, rest) = g.split_at_mut(2 * l);
        let (gb, gd) = rest.split_at_mut(2 * l);
        self.grid_buf.iter_mut().for_each(|v| *v = 0.0);
        self.at_x.scatter(&self.ea, &mut self.grid_buf);
        let (gac, gas) = ga.split_at_mut(l);
        self.fft
            .analyze_transpose(&mut self.grid_buf, &self.orders, gac, gas);
        self.grid_buf.iter_mut().for_each(|v| *v = 0.0);
        self.at_y.scatter(&self.ea, &mut self.grid_buf);
        let (gbc, gbs) = gb.split_at_mut(l);
        self.fft
            .analyze_transpose(&mut self.grid_buf, &self.orders, gbc, gbs);
        gb.iter_mut().for_each(|v| *v = -*v);
        gd.iter_mut().for_each(|v| *v = 0.0);
        for (j, w) in self.ea.iter().enumerate() {
            gd[self.session_of[j] as usize] += w;
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

/// Solves the joint CSRR equation for the binned sessions. See the module docs.
pub fn solve(sessions: &[SessionData], opts: &JointOptions) -> Result<JointSolution, CsrrError> {
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
    let init_deltas: Vec<f64> = sessions
        .iter()
        .zip(&weights)
        .map(|(s, w)| s.bins.iter().map(|b| b.n * b.d).sum::<f64>() / w)
        .collect();
    let centred: Vec<f64> = init_deltas.iter().map(|d| d - init_deltas[0]).collect();
    let mut orders = Vec::new();
    let mut excluded = Vec::new();
    for h in 1..=opts.max_order {
        let q = observability(h, &centred, &weights);
        if q < opts.min_observability {
            excluded.push(ExcludedOrder {
                order: h,
                observability: q,
            });
        } else {
            orders.push(h);
        }
    }
    if orders.is_empty() {
        return Err(CsrrError::NothingObservable {
            max_order: opts.max_order,
        });
    }

    let grid = (16 * opts.max_order).max(64).next_power_of_two();
    let bins = sessions.iter().flat_map(|s| s.bins.iter());
    let m: usize = sessions.iter().map(|s| s.bins.len()).sum();
    let mut session_of = Vec::with_capacity(m);
    for (k, s) in sessions.iter().enumerate() {
        session_of.extend(std::iter::repeat_n(k as u32, s.bins.len()));
    }
    let mut problem = Problem {
        sessions: k_count,
        session_of,
        n: bins.clone().map(|b| b.n).collect(),
        d: bins.clone().map(|b| b.d).collect(),
        at_x: Stencils::new(bins.clone().map(|b| b.x), grid),
        at_y: Stencils::new(bins.clone().map(|b| b.x - b.d), grid),
        fft: GridTransform::new(grid),
        grid_buf: vec![0.0; grid],
        ea: vec![0.0; m],
        eb: vec![0.0; m],
        orders,
    };
    debug_assert_eq!(problem.fft.grid(), grid);
    let precond = Preconditioner::new(&problem.orders, &centred, &weights);
    let nu = problem.len();
    let l = problem.orders.len();

    // Start from zero maps and the sessions' mean relative angles.
    let mut u = vec![0.0; nu];
    u[4 * l..].copy_from_slice(&init_deltas);
    let mut au = vec![0.0; m];
    let mut resid = vec![0.0; m];
    problem.apply(&u, &mut au);
    for j in 0..m {
        resid[j] = problem.d[j] - au[j];
    }
    let mut r = vec![0.0; nu];
    problem.transpose_weighted(&resid, &mut r);
    let mut z = vec![0.0; nu];
    precond.apply(&r, &mut z);
    let mut p = z.clone();
    let mut rz = dot(&r, &z);
    let rz0 = rz;
    let mut ap = vec![0.0; nu];
    let mut iterations = 0;
    let mut converged = rz0 == 0.0;
    while !converged && iterations < opts.max_iterations {
        problem.apply(&p, &mut au);
        problem.transpose_weighted(&au, &mut ap);
        let pap = dot(&p, &ap);
        if pap <= 0.0 || !pap.is_finite() {
            break;
        }
        let alpha = rz / pap;
        for i in 0..nu {
            u[i] += alpha * p[i];
            r[i] -= alpha * ap[i];
        }
        precond.apply(&r, &mut z);
        let rz_new = dot(&r, &z);
        iterations += 1;
        if rz_new.sqrt() <= opts.tolerance * rz0.sqrt() {
            converged = true;
            break;
        }
        let beta = rz_new / rz;
        rz = rz_new;
        for i in 0..nu {
            p[i] = z[i] + beta * p[i];
        }
    }

    problem.apply(&u, &mut au);
    let total: f64 = problem.n.iter().sum();
    let within: f64 = sessions
        .iter()
        .flat_map(|s| &s.bins)
        .map(|b| b.d_var_sum)
        .sum();
    let between: f64 = (0..m)
        .map(|j| problem.n[j] * (au[j] - problem.d[j]).powi(2))
        .sum();
    let residual_rms = ((between + within) / total).sqrt();
    if !residual_rms.is_finite() || u.iter().any(|v| !v.is_finite()) {
        return Err(CsrrError::NotFinite);
    }

    let mut a = FourierSeries::zeros(opts.max_order);
    let mut b = FourierSeries::zeros(opts.max_order);
    for (i, &h) in problem.orders.iter().enumerate() {
        a.cos[h - 1] = u[i];
        a.sin[h - 1] = u[l + i];
        b.cos[h - 1] = u[2 * l + i];
        b.sin[h - 1] = u[3 * l + i];
    }
    Ok(JointSolution {
        a,
        b,
        deltas: u[4 * l..].to_vec(),
        excluded,
        residual_rms,
        iterations,
        converged,
    })
}
