//! Fast evaluation of Fourier series at arbitrary points, and its exact adjoint.
//!
//! Used by CSRR's and multi-head's joint solvers, and by TDR's check of its residual (the
//! adjoint alone, [`stencil`] and [`scatter_one`] a point at a time). The CSRR solver needs
//! `e(x_j) = Σ_h a_h cos hx_j + b_h sin hx_j` at ~10⁵–10⁶ points for ~1000 orders, and the
//! transpose of that map, dozens of times. Direct summation costs O(M·H).
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

/// `1/Π_{m≠k}(o_k − o_m)` for the stencil's nodes `o = −2, …, 3`: the denominators of the
/// Lagrange weights, which do not depend on the point.
const INV_DENOMINATORS: [f64; P] = [
    -1.0 / 120.0,
    1.0 / 24.0,
    -1.0 / 12.0,
    1.0 / 12.0,
    -1.0 / 24.0,
    1.0 / 120.0,
];

/// Interpolation weights of a set of points on a periodic grid.
///
/// They depend on the points only: a solver that evaluates many series at the same points builds
/// them once and gathers (or scatters) as often as it needs.
#[derive(Debug, Clone)]
pub(crate) struct Stencils {
    grid: usize,
    start: Vec<u32>,
    weights: Vec<[f64; P]>,
}

impl Stencils {
    /// Stencils for `points` (radians, any finite value) on a grid of `grid` points over 2π.
    ///
    /// The weight of node `k` at the fractional position `f` is the Lagrange weight
    /// `Π_{m≠k}(f − o_m) / Π_{m≠k}(o_k − o_m)`, its numerator formed from prefix and suffix
    /// products (10 multiplications instead of 30) and its denominator a constant.
    pub(crate) fn new(points: impl Iterator<Item = f64>, grid: usize) -> Self {
        let per_radian = grid as f64 / TAU;
        let (lower, _) = points.size_hint();
        let mut start = Vec::with_capacity(lower);
        let mut weights = Vec::with_capacity(lower);
        for x in points {
            let (s, w) = stencil(x, per_radian, grid);
            start.push(s as u32);
            weights.push(w);
        }
        Stencils {
            grid,
            start,
            weights,
        }
    }

    /// Points held.
    pub(crate) fn len(&self) -> usize {
        self.start.len()
    }

    /// Moves point `i` to `x` (radians): its stencil built again, as [`Stencils::new`] builds
    /// it.
    pub(crate) fn set(&mut self, i: usize, x: f64) {
        let (s, w) = stencil(x, self.grid as f64 / TAU, self.grid);
        self.start[i] = s as u32;
        self.weights[i] = w;
    }

    /// `Σ_k w_k · grid[s + k]` for one stencil starting at `s`. A stencil that does not wrap
    /// (all but the last few points of the grid) reads one bounds-checked array of `P` values.
    #[inline(always)]
    fn dot(grid: &[f64], s: usize, w: &[f64; P]) -> f64 {
        match grid.get(s..s + P) {
            Some(v) => {
                let v: &[f64; P] = v.try_into().expect("P values");
                w[0] * v[0] + w[1] * v[1] + w[2] * v[2] + w[3] * v[3] + w[4] * v[4] + w[5] * v[5]
            }
            None => (0..P).map(|k| w[k] * grid[(s + k) % grid.len()]).sum(),
        }
    }

    /// `out[j] = Σ_k w_jk · grid[s_j + k]`.
    pub(crate) fn gather(&self, grid: &[f64], out: &mut [f64]) {
        debug_assert_eq!(grid.len(), self.grid);
        for ((o, &s), w) in out.iter_mut().zip(&self.start).zip(&self.weights) {
            *o = Self::dot(grid, s as usize, w);
        }
    }

    /// [`Stencils::gather`] of two grids at once (the stencils read once for both).
    pub(crate) fn gather2(&self, grids: (&[f64], &[f64]), out: (&mut [f64], &mut [f64])) {
        debug_assert!(grids.0.len() == self.grid && grids.1.len() == self.grid);
        for (((o0, o1), &s), w) in out
            .0
            .iter_mut()
            .zip(out.1.iter_mut())
            .zip(&self.start)
            .zip(&self.weights)
        {
            *o0 = Self::dot(grids.0, s as usize, w);
            *o1 = Self::dot(grids.1, s as usize, w);
        }
    }

    /// [`Stencils::gather2`] at the points `which` only (indices), the other outputs left as
    /// they are.
    pub(crate) fn gather2_at(
        &self,
        which: &[usize],
        grids: (&[f64], &[f64]),
        out: (&mut [f64], &mut [f64]),
    ) {
        debug_assert!(grids.0.len() == self.grid && grids.1.len() == self.grid);
        for &j in which {
            let (s, w) = (self.start[j] as usize, &self.weights[j]);
            out.0[j] = Self::dot(grids.0, s, w);
            out.1[j] = Self::dot(grids.1, s, w);
        }
    }

    /// `grid[s_j + k] += w_jk · values[j]` (the transpose of [`Stencils::gather`]).
    pub(crate) fn scatter(&self, values: &[f64], grid: &mut [f64]) {
        debug_assert_eq!(grid.len(), self.grid);
        for ((&v, &s), w) in values.iter().zip(&self.start).zip(&self.weights) {
            scatter_one(grid, s as usize, w, v);
        }
    }
}

/// The stencil of the point `x` (radians, any finite value) on a grid of `grid` points,
/// `per_radian = grid/2π` of them per radian: its first node (wrapped) and its `P` weights, as
/// [`Stencils::new`] describes.
#[inline(always)]
pub(crate) fn stencil(x: f64, per_radian: f64, grid: usize) -> (usize, [f64; P]) {
    // The position on the grid, wrapped by the integer part only (no floating-point
    // remainder): the fraction keeps its precision for readings within a few turns of 0.
    let u = x * per_radian;
    let fl = u.floor();
    let f = u - fl;
    let s = (fl as i64).wrapping_add(FIRST as i64);
    // The remainder of a power of two (the usual grid) by its mask: a division costs ~40 cycles.
    let s = if grid.is_power_of_two() {
        s & (grid as i64 - 1)
    } else {
        s.rem_euclid(grid as i64)
    };
    let d: [f64; P] = std::array::from_fn(|m| f - (m as isize + FIRST) as f64);
    let mut left = [1.0; P];
    let mut right = [1.0; P];
    for m in 1..P {
        left[m] = left[m - 1] * d[m - 1];
        right[P - 1 - m] = right[P - m] * d[P - m];
    }
    (
        s as usize,
        std::array::from_fn(|k| left[k] * right[k] * INV_DENOMINATORS[k]),
    )
}

/// `grid[s + k] += w_k · v`, wrapped past the grid's end: one point of [`Stencils::scatter`].
#[inline(always)]
pub(crate) fn scatter_one(grid: &mut [f64], s: usize, w: &[f64; P], v: f64) {
    match grid.get_mut(s..s + P) {
        Some(cells) => {
            let cells: &mut [f64; P] = cells.try_into().expect("P values");
            for k in 0..P {
                cells[k] += w[k] * v;
            }
        }
        None => {
            let g = grid.len();
            for k in 0..P {
                grid[(s + k) % g] += w[k] * v;
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
    fn stencils_start_at_the_wrapped_node_on_any_grid() {
        // A power of two (the mask) and not (the remainder), points on either side of 0.
        for grid in [1000, 1024] {
            let per_radian = grid as f64 / TAU;
            for x in [-700.3, -7.3, -0.001, 0.0, 3.1, 6.2, 100.0, 2600.7] {
                let (s, w) = stencil(x, per_radian, grid);
                let node = (x * per_radian).floor() as i64 + FIRST as i64;
                assert_eq!(s as i64, node.rem_euclid(grid as i64), "{x} on {grid}");
                assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn moved_points_read_as_stencils_built_anew() {
        // Stencils moved point by point (`set`, `gather2_at`) are the stencils and values of a
        // fresh build at the new points, bit for bit: CSRR's inversion relies on it.
        let grid = 512;
        let mut pts: Vec<f64> = (0..400).map(|j| j as f64 * 0.0157 - 0.2).collect();
        let mut st = Stencils::new(pts.iter().copied(), grid);
        let (g0, g1): (Vec<f64>, Vec<f64>) = (0..grid)
            .map(|m| ((m as f64 * 0.1).sin(), (m as f64 * 0.37).cos()))
            .unzip();
        let (mut a0, mut a1) = (vec![0.0; pts.len()], vec![0.0; pts.len()]);
        st.gather2((&g0, &g1), (&mut a0, &mut a1));
        let moved: Vec<usize> = (0..pts.len()).filter(|j| j % 3 == 0).collect();
        for &j in &moved {
            pts[j] += 1e-3 * (j as f64 - 200.0);
            st.set(j, pts[j]);
        }
        st.gather2_at(&moved, (&g0, &g1), (&mut a0, &mut a1));
        let fresh = Stencils::new(pts.iter().copied(), grid);
        let (mut b0, mut b1) = (vec![0.0; pts.len()], vec![0.0; pts.len()]);
        fresh.gather2((&g0, &g1), (&mut b0, &mut b1));
        assert_eq!(st.start, fresh.start);
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let weights = |s: &Stencils| bits(&s.weights.concat());
        assert_eq!(weights(&st), weights(&fresh));
        assert_eq!((bits(&a0), bits(&a1)), (bits(&b0), bits(&b1)));
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
