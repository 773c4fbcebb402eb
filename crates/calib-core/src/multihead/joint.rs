//! The joint least-squares solve of eq. 3 (see the module doc), with the sampling and
//! nonlinear corrections iterated.

use super::bins::Binned;
use super::{ExcludedOrder, MAX_ITERATIONS, MultiheadError, MultiheadOptions, TOLERANCE};
use crate::angle::wrap_2pi;
use crate::harmonics::FourierSeries;
use crate::nufft::{GridTransform, Stencils};
use realfft::num_complex::Complex;

/// The joint solution.
pub(super) struct JointFit {
    /// `s_h` at index `h − 1` (0 for left-out orders).
    pub(super) s: Vec<Complex<f64>>,
    /// Head angle errors of the other heads, rad.
    pub(super) delta: Vec<f64>,
    /// The differences brought to the bin centres (sampling correction only), per other head.
    pub(super) centred: Vec<Vec<f64>>,
    pub(super) excluded: Vec<ExcludedOrder>,
    /// Per other head: residual sums (see [`Corrections`]).
    pub(super) residuals: Vec<Residual>,
    /// Per other head: each bin mean's residual from the linear model at the bin centres, rad.
    pub(super) bin_residuals: Vec<Vec<f64>>,
    pub(super) iterations: usize,
    pub(super) converged: bool,
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
pub(super) struct Residual {
    /// `Σ n·r²`, `r` the bin mean's residual.
    pub(super) between: f64,
    /// Within-bin scatter net of the model's slope, and its degrees of freedom `Σ (n − 1)`.
    pub(super) within: f64,
    pub(super) dof: f64,
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
pub(super) fn joint(
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
pub fn joint_weights(h: usize, psi: &[f64]) -> Vec<Complex<f64>> {
    let c: Vec<Complex<f64>> = psi.iter().map(|&p| unit(h, p) - 1.0).collect();
    let q: f64 = c.iter().map(|c| c.norm_sqr()).sum();
    c.iter().map(|c| c.conj() / q).collect()
}

/// `e^{ihψ}`.
fn unit(h: usize, psi: f64) -> Complex<f64> {
    let (s, c) = (wrap_2pi(psi) * h as f64).sin_cos();
    Complex::new(c, s)
}

/// The map's Fourier series from the `s_h`: `a_h = 2 Re s_h`, `b_h = −2 Im s_h`.
pub(super) fn series_of(s: &[Complex<f64>]) -> FourierSeries {
    FourierSeries {
        cos: s.iter().map(|c| 2.0 * c.re).collect(),
        sin: s.iter().map(|c| -2.0 * c.im).collect(),
    }
}
