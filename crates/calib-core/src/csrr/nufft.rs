//! Fast evaluation of Fourier series at arbitrary points, and its exact adjoint.
//!
//! The joint solver needs `e(x_j) = Σ_h a_h cos hx_j + b_h sin hx_j` at ~10⁵–10⁶ points for
//! ~1000 orders, and the transpose of that map, dozens of times. Direct summation costs O(M·H).
//! Instead (a non-uniform FFT of the simplest kind): synthesize the series on a uniform grid of
//! `G ≥ 16·H` points with one inverse real FFT, then interpolate each point from its 6 nearest grid
//! values with Lagrange weights. The transpose spreads values onto the grid with the same weights
//! and takes one forward real FFT, so forward and transpose are exact adjoints of each other and
//! conjugate gradient sees a symmetric operator.
//!
//! Accuracy: 6-point Lagrange interpolation of `cos(hx)` errs by at most
//! `(hδ)⁶/720 · max|Π(f − o_m)| ≈ (hδ)⁶ · 0.0098` with `δ = 2π/G`; at `hδ ≤ 2π/16` (the highest
//! order) that is 3.5·10⁻⁵ of the harmonic's amplitude, and 2·10⁻⁸ at a quarter of the top order.
//! No crate offers a real-valued NUFFT with an exact adjoint on these terms, hence this module.

use realfft::num_complex::Complex;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use std::f64::consts::TAU;
use std::sync::Arc;

/// Points per interpolation stencil.
const P: usize = 6;
/// Offset of the stencil's first node from `floor(u)`.
const FIRST: isize = -2;

/// Interpolation weights of a set of points on a periodic grid.
#[derive(Debug, Clone)]
pub(crate) struct Stencils {
    grid: usize,
    start: Vec<u32>,
    weights: Vec<[f64; P]>,
}

impl Stencils {
    /// Stencils for `points` (radians, any value) on a grid of `grid` points over 2π.
    pub(crate) fn new(points: impl Iterator<Item = f64>, grid: usize) -> Self {
        let g = grid as f64;
        let mut start = Vec::new();
        let mut weights = Vec::new();
        for x in points {
            let u = crate::angle::wrap_2pi(x) / TAU * g;
            let fl = u.floor();
            let f = u - fl;
            let s = (fl as isize + FIRST).rem_euclid(grid as isize);
            start.push(s as u32);
            let mut w = [0.0; P];
            for (k, wk) in w.iter_mut().enumerate() {
                let ok = (k as isize + FIRST) as f64;
                let mut num = 1.0;
                let mut den = 1.0;
                for m in 0..P {
                    if m != k {
                        let om = (m as isize + FIRST) as f64;
                        num *= f - om;
                        den *= ok - om;
                    }
                }
                *wk = num / den;
            }
            weights.push(w);
        }
        Stencils {
            grid,
            start,
            weights,
        }
    }

    /// `out[j] = Σ_k w_jk · grid[s_j + k]`.
    pub(crate) fn gather(&self, grid: &[f64], out: &mut [f64]) {
        let g = self.grid;
        for ((o, &s), w) in out.iter_mut().zip(&self.start).zip(&self.weights) {
            let s = s as usize;
            *o = if s + P <= g {
                let v = &grid[s..s + P];
                w[0] * v[0] + w[1] * v[1] + w[2] * v[2] + w[3] * v[3] + w[4] * v[4] + w[5] * v[5]
            } else {
                (0..P).map(|k| w[k] * grid[(s + k) % g]).sum()
            };
        }
    }

    /// `grid[s_j + k] += w_jk · values[j]` (the transpose of [`Stencils::gather`]).
    pub(crate) fn scatter(&self, values: &[f64], grid: &mut [f64]) {
        let g = self.grid;
        for ((&v, &s), w) in values.iter().zip(&self.start).zip(&self.weights) {
            let s = s as usize;
            if s + P <= g {
                for k in 0..P {
                    grid[s + k] += w[k] * v;
                }
            } else {
                for k in 0..P {
                    grid[(s + k) % g] += w[k] * v;
                }
            }
        }
    }
}

/// Synthesis of a Fourier series on the uniform grid, and its transpose.
pub(crate) struct GridTransform {
    inverse: Arc<dyn ComplexToReal<f64>>,
    forward: Arc<dyn RealToComplex<f64>>,
    spectrum: Vec<Complex<f64>>,
    scratch_in: Vec<Complex<f64>>,
    scratch_fwd: Vec<Complex<f64>>,
}

impl GridTransform {
    /// Plans the transforms for a grid of `grid` points (a power of two is fastest).
    pub(crate) fn new(grid: usize) -> Self {
        let mut planner = RealFftPlanner::<f64>::new();
        let inverse = planner.plan_fft_inverse(grid);
        let forward = planner.plan_fft_forward(grid);
        GridTransform {
            spectrum: inverse.make_input_vec(),
            scratch_in: inverse.make_scratch_vec(),
            scratch_fwd: forward.make_scratch_vec(),
            inverse,
            forward,
        }
    }

    /// `grid[m] = Σ_i cos_i·cos(h_i θ_m) + sin_i·sin(h_i θ_m)`, `θ_m = 2πm/G`, for the orders
    /// `orders` (all below G/2).
    pub(crate) fn synthesize(
        &mut self,
        orders: &[usize],
        cos: &[f64],
        sin: &[f64],
        grid: &mut [f64],
    ) {
        self.spectrum
            .iter_mut()
            .for_each(|c| *c = Complex::new(0.0, 0.0));
        for ((&h, &a), &b) in orders.iter().zip(cos).zip(sin) {
            // The unnormalized inverse of X_h = (a − ib)/2 and its mirror gives a cos + b sin.
            self.spectrum[h] = Complex::new(0.5 * a, -0.5 * b);
        }
        self.inverse
            .process_with_scratch(&mut self.spectrum, grid, &mut self.scratch_in)
            .expect("buffer sizes come from the plan");
    }

    /// The transpose of [`GridTransform::synthesize`]: `cos_i = Σ_m q_m cos(h_i θ_m)`,
    /// `sin_i = Σ_m q_m sin(h_i θ_m)`. Overwrites `q`.
    pub(crate) fn analyze_transpose(
        &mut self,
        q: &mut [f64],
        orders: &[usize],
        cos: &mut [f64],
        sin: &mut [f64],
    ) {
        self.forward
            .process_with_scratch(q, &mut self.spectrum, &mut self.scratch_fwd)
            .expect("buffer sizes come from the plan");
        for ((&h, a), b) in orders.iter().zip(cos.iter_mut()).zip(sin.iter_mut()) {
            *a = self.spectrum[h].re;
            *b = -self.spectrum[h].im;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolated_synthesis_matches_direct_sums() {
        let orders: Vec<usize> = (1..=200).collect();
        let cos: Vec<f64> = orders.iter().map(|&h| 1.0 / h as f64).collect();
        let sin: Vec<f64> = orders.iter().map(|&h| 0.5 / (h as f64).sqrt()).collect();
        let grid = 4096; // ≥ 16·200
        let mut t = GridTransform::new(grid);
        let mut g = vec![0.0; grid];
        t.synthesize(&orders, &cos, &sin, &mut g);
        let pts: Vec<f64> = (0..500).map(|j| j as f64 * 0.01234567 - 0.5).collect();
        let st = Stencils::new(pts.iter().copied(), grid);
        let mut out = vec![0.0; pts.len()];
        st.gather(&g, &mut out);
        let amp: f64 = cos.iter().zip(&sin).map(|(a, b)| a.hypot(*b)).sum();
        for (x, o) in pts.iter().zip(&out) {
            let direct: f64 = orders
                .iter()
                .map(|&h| cos[h - 1] * (h as f64 * x).cos() + sin[h - 1] * (h as f64 * x).sin())
                .sum();
            assert!((direct - o).abs() < 3.5e-5 * amp, "{direct} vs {o}");
        }
    }

    #[test]
    fn scatter_and_analyze_are_the_exact_transpose() {
        let orders = [1usize, 5, 17, 60];
        let grid = 1024;
        let mut t = GridTransform::new(grid);
        let pts: Vec<f64> = (0..37).map(|j| j as f64 * 0.7).collect();
        let st = Stencils::new(pts.iter().copied(), grid);
        let (c, s) = ([0.3, -1.0, 0.25, 2.0], [1.0, 0.5, -0.75, 0.1]);
        let r: Vec<f64> = (0..37).map(|j| ((j * 7) % 11) as f64 - 5.0).collect();
        // <A u, r>
        let mut g = vec![0.0; grid];
        t.synthesize(&orders, &c, &s, &mut g);
        let mut au = vec![0.0; pts.len()];
        st.gather(&g, &mut au);
        let lhs: f64 = au.iter().zip(&r).map(|(a, b)| a * b).sum();
        // <u, Aᵀ r>
        let mut q = vec![0.0; grid];
        st.scatter(&r, &mut q);
        let (mut ca, mut sa) = ([0.0; 4], [0.0; 4]);
        t.analyze_transpose(&mut q, &orders, &mut ca, &mut sa);
        let rhs: f64 = (0..4).map(|i| c[i] * ca[i] + s[i] * sa[i]).sum();
        assert!((lhs - rhs).abs() < 1e-9 * lhs.abs().max(1.0), "{lhs} {rhs}");
    }
}
