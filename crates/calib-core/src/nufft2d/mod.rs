//! Type-1 non-uniform FFT in two periodic dimensions, with real weights, several weight sets at
//! once.
//!
//! For samples `n = 0, …, len − 1` at angles `(a_n, b_n)` with real weights `w_{s,n}`,
//! `s = 0, …, K − 1`, [`type1`] returns
//!
//! ```text
//! F_s(j, m) = Σ_n w_{s,n} · e^{i(j·a_n + m·b_n)},   |j| ≤ j_max,  |m| ≤ m_max,
//! ```
//!
//! in `O(len·W² + N_a·N_b·log(N_a·N_b))` operations instead of `O(len·j_max·m_max)`.
//!
//! # Method
//! Barnett, Magland & af Klinteberg, *A parallel non-uniform fast Fourier transform library
//! based on an "exponential of semicircle" kernel*, SIAM J. Sci. Comput. 41(5), C479–C504
//! (2019), with their "exponential of semicircle" (ES) kernel
//!
//! ```text
//! φ(x) = exp(β(√(1 − z²) − 1)),  z = 2x/W,  |z| < 1  (0 elsewhere),  x in grid steps:
//! ```
//!
//! 1. *Spread*: each sample adds `w_{s,n}·φ(l_a − u_a)·φ(l_b − u_b)` to the `W × W` grid points
//!    `l` nearest its position `u = (a_n·N_a/2π, b_n·N_b/2π)` on a periodic real grid of
//!    `N_a × N_b` points, oversampled `σ = 2` times: `N ≥ 2·(2·max_order + 1)`.
//! 2. *FFT* the grid: `G(j, m) = Σ_l g(l)·e^{2πi(j·l_a/N_a + m·l_b/N_b)}` (a real FFT along `b`
//!    for `m ≥ 0`, then a complex FFT along `a`).
//! 3. *Correct*: by the Poisson summation formula `Σ_l φ(l − u)·e^{iξl} = e^{iξu}·φ̂(ξ)` plus
//!    aliased terms that the kernel makes negligible, with `φ̂(ξ) = ∫ φ(x)·cos(ξx) dx`:
//!    `F(j, m) = G(j, m) / (φ̂(2πj/N_a)·φ̂(2πm/N_b))`. The grid's point `l = 0` sits at angle 0,
//!    so the shift phase `e^{iξ·0}` is 1. `φ̂` has no closed form; it is integrated by
//!    Gauss–Legendre quadrature, as the paper does.
//!
//! `W = 16` and `β = 2.30·W` are the paper's (and FINUFFT's) parameters for σ = 2 at the highest
//! accuracy (FINUFFT's width rule `W = ⌈log₁₀(10/ε)⌉`, i.e. ε ≈ 10⁻¹⁵). The kernel's values are
//! piecewise polynomials in the fractional grid position (degree 13 on each of the `W` unit
//! intervals, fitted once per call at Chebyshev points, evaluated by Horner's rule as FINUFFT
//! does): a sample costs `2·W·13` multiply-adds for its two kernels and `K·W²` for the
//! spreading, no `exp`. Samples in time order, whose position along `a` moves slowly, are
//! spread by runs instead (the `spread` module): the kernel along `a`, a polynomial of degree 4
//! on each 1/128 of a grid step, is shared by a run's samples, so each adds `K·W·5` values to
//! five rows along `b`, and the run's `W` rows of the grid are written once.
//!
//! With `j_max = 0` the `a` dimension is dropped: a 1-D transform along `b` only.
//!
//! # Speed
//! On x86-64 CPUs with AVX2 and FMA (detected at run time) the spreading uses those
//! instructions, and places four samples on the grid at a time (the same bits as one at a
//! time). Two consecutive samples that share their first row (and, by runs, their
//! sub-interval) and start at most 4 columns apart along `b` — nearly all of them when the
//! samples are in time order — are added in one pass. Two consecutive samples' kernels along
//! `b` are evaluated together along one dimension (`j_max = 0`) and by runs (the two chains of
//! Horner's rule that a sample spread alone uses for `a` and `b`), each as it would be alone.
//! Measured on a 2-core machine shared with other jobs, 10⁷ samples of `calib tdr`'s
//! spin-down, `K = 2`, `j_max = 127`, `m_max = 1016` (`tests/nufft2d.rs`, 3 alternating
//! rounds): 0.41–0.61 s wall on two threads, 0.71–0.96 s on one (70–95 ns per sample); sample by
//! sample, as before runs, 0.60–0.79 and 1.09–1.49 s. Loading a pair's row once for a run's five
//! rows: 0.58–0.64 s on one thread where the same hour gave 0.63–0.65 s before.
//! `benches/nufft2d.rs` (10⁶ samples): 125 ms against 181 ms.
//!
//! # Accuracy
//! `|F_s(j, m) − exact| ≤ 10⁻¹³·Σ_n |w_{s,n}|` at every returned `(j, m)`: the tests measure
//! 1.4–5.2·10⁻¹⁵ over thousands of samples and 3.4·10⁻¹⁴ over five (whose rounding errors do
//! not average out) against direct summation. The angles are placed on the grid in
//! double-double arithmetic, so an angle of any size is reduced modulo 2π exactly: the result
//! is the spectrum of the angles as given, not of `a.rem_euclid(TAU)` (which differs from the
//! exact reduction by `k·(2π − TAU)` after `k` turns).
//!
//! # Determinism
//! The samples are split by index into pieces fixed by their count alone (one below 131,072
//! samples, at most eight), each spread in order into its own grid on the rayon pool, and the
//! grids are summed cell by cell, in the pieces' order, as their rows are transformed; the FFTs
//! of rows and columns are independent of each other. So the bits do not depend on the number
//! of threads. They may differ between CPUs with and without
//! AVX2/FMA (a fused multiply-add rounds once).
//!
//! # Memory
//! A grid per piece of `N_a × (N_b + 19)` cells of `K` values, of which the system allocates
//! only the rows the piece's samples reach (each written with zeros before it is added to, so
//! that its pages are allocated by one fault each, the module `spread`'s `FirstRows`), the peak:
//! samples in time order along `a`, as `calib tdr`'s, reach each piece's own rows, and the
//! grids together hold little more than one full grid — for `j_max = 127`, `m_max = 1016`,
//! `K = 2` (`N_a = 512`, `N_b = 4096`) 33.7 MB. Samples in random order reach every row from
//! every piece: up to eight full grids. The grids are summed a row at a time as the rows are
//! transformed, and freed after; then the row
//! spectra (`N_a·K·(m_max + 1)` complex values, 16.7 MB) and the columns' results (8.3 MB)
//! are held, and the returned spectra hold `(2·j_max + 1)·(m_max + 1)` complex values each
//! (4.2 MB). Below 131,072 samples, one grid. A piece spread by runs also holds the run's five
//! rows (`5·(N_b + 19)·K` values, 330 kB for the sizes above).

use rayon::prelude::*;
use realfft::RealFftPlanner;
use rustfft::FftPlanner;
pub use rustfft::num_complex::Complex64;
use std::f64::consts::TAU;
use std::ops::Range;

mod spread;

use spread::{PAIR_WIDTH, RunKernel};

/// Kernel width `W` in grid points per dimension (W = 16 for ε ≈ 10⁻¹⁵ at σ = 2).
const WIDTH: usize = 16;
/// Kernel shape parameter `β = 2.30·W`, the paper's choice for σ = 2.
const BETA: f64 = 2.30 * WIDTH as f64;
/// Degree of the polynomial that approximates the kernel on each of its `W` unit intervals: the
/// lowest whose error stays at the rounding of Horner's rule, 2·10⁻¹⁵ of the kernel's peak
/// (measured: degree 12 errs by 5·10⁻¹⁵, 11 by 4·10⁻¹⁴; test
/// `kernel_polynomials_match_the_kernel`).
const DEGREE: usize = 13;
/// Gauss–Legendre nodes on `[0, W/2]` for the kernel's Fourier transform: the integrand is
/// smooth apart from the kernel's `e^{−β}` step at the edge, and 3·W nodes integrate it to
/// rounding (FINUFFT uses 1.5·W + 2).
const QUADRATURE_NODES: usize = 3 * WIDTH;
/// Samples per piece at least: below twice this many, one grid (a second would cost more to clear
/// and add than the spreading it parallelizes).
const MIN_SPLIT: usize = 1 << 16;
/// Pieces at most. Each has its own grid and the cores take them one by one, so a core that runs
/// slower (a virtual machine's cores often do) waits for at most one piece of the other's, not
/// for half the work: measured on `calib tdr`'s 10⁷-sample coast on 2 cores, fixed halves
/// finished 0.35 s apart in one run of two.
const MAX_PIECES: usize = 8;
/// Samples [`type1_blocks`] asks for at a time; the pieces split at a multiple of it.
pub const BLOCK: usize = 256;
/// `1/(2π)` as a double-double: the nearest double plus the remainder.
const INV_TAU: (f64, f64) = (0.159_154_943_091_895_35, -9.839_338_337_591_243e-18);

/// One weight set's spectrum `F(j, m)` for `|j| ≤ j_max`, `|m| ≤ m_max`.
#[derive(Debug, Clone)]
pub struct Spectrum2 {
    j_max: usize,
    m_max: usize,
    /// `F(j, m)` for `m ≥ 0` at `(j + j_max)·(m_max + 1) + m`.
    values: Vec<Complex64>,
}

impl Spectrum2 {
    /// The largest `|j|` held.
    pub fn j_max(&self) -> usize {
        self.j_max
    }

    /// The largest `|m|` held.
    pub fn m_max(&self) -> usize {
        self.m_max
    }

    /// `F(j, m)` for `|j| ≤ j_max` and `|m| ≤ m_max`; for `m < 0` from
    /// `F(j, m) = conj F(−j, −m)` (the weights are real).
    ///
    /// # Panics
    /// If `|j| > j_max` or `|m| > m_max`.
    pub fn at(&self, j: i64, m: i64) -> Complex64 {
        assert!(
            j.unsigned_abs() <= self.j_max as u64 && m.unsigned_abs() <= self.m_max as u64,
            "F({j}, {m}) is outside |j| ≤ {}, |m| ≤ {}",
            self.j_max,
            self.m_max
        );
        if m < 0 {
            return self.at(-j, -m).conj();
        }
        let row = (j + self.j_max as i64) as usize;
        self.values[row * (self.m_max + 1) + m as usize]
    }
}

/// The spectra `F_s(j, m) = Σ_n w_{s,n}·e^{i(j·a_n + m·b_n)}` of `K` weight sets, for
/// `|j| ≤ j_max`, `0 ≤ m ≤ m_max` (and `m < 0` by symmetry, see [`Spectrum2::at`]).
///
/// `sample(n)` gives sample `n`'s two angles `(a_n, b_n)` in radians — any finite values, reduced
/// modulo 2π exactly inside (up to ~10¹³ turns, where a double's resolution becomes coarser than
/// the grid) — and its `K` real weights. It is called once per sample, from the rayon pool's
/// threads (each piece of `0..len` in order on one of them). With `j_max = 0`, `a_n` is not
/// used (a 1-D transform along `b`).
///
/// `len = 0` gives all-zero spectra. A non-finite angle or weight makes the spectra NaN (no panic).
/// Limits: a grid takes `N_a·(N_b + 19)·K·8` bytes (the module's memory section says how many
/// are held) with `N ≈ 4·max_order + 2` rounded up to a product of 2, 3 and 5 (at least 32),
/// `N_a = 1` when `j_max = 0`; sizes whose grids do not fit in memory abort on allocation.
pub fn type1<const K: usize>(
    len: usize,
    j_max: usize,
    m_max: usize,
    sample: impl Fn(usize) -> (f64, f64, [f64; K]) + Sync,
) -> [Spectrum2; K] {
    type1_blocks(len, j_max, m_max, |range, points| {
        points.extend(range.map(&sample));
    })
}

/// [`type1`] with the samples given a block at a time: `fill(range, points)` appends the points
/// of the samples `range` — at most [`BLOCK`] of them, starting at a multiple of `BLOCK`, each
/// block once, from the rayon pool's threads. A caller whose per-sample work vectorizes across
/// samples (a series evaluated side by side) does it here, and may keep a sum per block: the
/// blocks are the same whatever the threads.
pub fn type1_blocks<const K: usize>(
    len: usize,
    j_max: usize,
    m_max: usize,
    fill: impl Fn(Range<usize>, &mut Vec<(f64, f64, [f64; K])>) + Sync,
) -> [Spectrum2; K] {
    let plan = Plan::new(j_max, m_max);
    // The pieces go to the rayon pool one by one (a core that finishes early takes the next,
    // never two at once); `collect` keeps them in order.
    let pieces: Vec<Piece<K>> = pieces(len)
        .into_par_iter()
        .with_max_len(1)
        .map(|range| plan.spread(&fill, range))
        .collect();
    if plan.two_d {
        transform_2d(pieces, &plan.a, &plan.b, j_max, m_max)
    } else {
        transform_1d(&pieces, &plan.b, m_max)
    }
}

/// The pieces [`type1_blocks`] spreads each into its own grid: `0..len` cut at multiples of
/// [`BLOCK`] into `len / MIN_SPLIT` (at least 1, at most [`MAX_PIECES`]) runs of nearly equal
/// length. They depend on `len` alone, so the grids' sum has the same bits on any number of
/// threads.
fn pieces(len: usize) -> Vec<Range<usize>> {
    let count = (len / MIN_SPLIT).clamp(1, MAX_PIECES);
    let size = len / count / BLOCK * BLOCK;
    (0..count)
        .map(|k| k * size..if k + 1 == count { len } else { (k + 1) * size })
        .collect()
}

/// The grid one piece of the samples was spread into, and which of its rows they reached: the
/// others were never written, so the system never allocated their pages, and the sum of the
/// pieces' grids ([`Piece::row_sum`]) skips them.
struct Piece<const K: usize> {
    /// `N_a` rows of [`Plan::row_len`] cells, or one row; empty for no samples.
    grid: Vec<[f64; K]>,
    /// Per row: whether a sample's kernel reached it.
    reached: Vec<bool>,
}

impl<const K: usize> Piece<K> {
    /// Row `r` (of `row_len` cells) of the pieces' grids summed in the pieces' order: the one
    /// piece's row itself when only it reached the row, else the sum written into `sum`; `None`
    /// when no piece reached it (the row is zero).
    fn row_sum<'a>(
        pieces: &'a [Piece<K>],
        r: usize,
        row_len: usize,
        sum: &'a mut Vec<[f64; K]>,
    ) -> Option<&'a [[f64; K]]> {
        let mut reached = pieces.iter().filter(|p| p.reached[r]);
        let row = |p: &'a Piece<K>| &p.grid[r * row_len..(r + 1) * row_len];
        let first = row(reached.next()?);
        let Some(second) = reached.next() else {
            return Some(first);
        };
        sum.clear();
        sum.extend_from_slice(first);
        for piece in std::iter::once(second).chain(reached) {
            for (c, v) in sum.iter_mut().zip(row(piece)) {
                for s in 0..K {
                    c[s] += v[s];
                }
            }
        }
        Some(sum)
    }
}

/// The grid and kernel of one transform.
struct Plan {
    /// The `a` dimension (unused when `!two_d`).
    a: Axis,
    b: Axis,
    /// Whether `j_max > 0`; otherwise the grid is one row along `b`.
    two_d: bool,
    kernel: Kernel,
    /// The kernel along `a` as runs of samples use it.
    runs: RunKernel,
}

impl Plan {
    fn new(j_max: usize, m_max: usize) -> Self {
        Plan {
            a: Axis::new(j_max),
            b: Axis::new(m_max),
            two_d: j_max > 0,
            kernel: Kernel::fit(),
            runs: RunKernel::fit(),
        }
    }

    /// Cells of a grid's row: `N_b`, then `PAIR_WIDTH − 1` cells of padding (folded back by
    /// [`folded_row`]), so that every kernel row, of one sample or a pair, is one contiguous run.
    fn row_len(&self) -> usize {
        self.b.n + PAIR_WIDTH - 1
    }

    /// Rows of a grid: `N_a` or one.
    fn rows(&self) -> usize {
        if self.two_d { self.a.n } else { 1 }
    }
}

/// One periodic dimension of the oversampled grid.
struct Axis {
    /// Grid points over 2π.
    n: usize,
    /// `n/(2π)` as a double-double.
    scale: (f64, f64),
}

impl Axis {
    /// The grid for orders `|k| ≤ max_order`: σ = 2 (`n ≥ 2·(2·max_order + 1)`), at least two
    /// kernel widths, even, and a product of 2, 3 and 5 for a fast FFT.
    fn new(max_order: usize) -> Self {
        let min = (4 * max_order + 2).max(2 * WIDTH);
        let n = (min..)
            .find(|&n| {
                let mut r = n;
                for p in [2, 3, 5] {
                    while r % p == 0 {
                        r /= p;
                    }
                }
                r == 1 && n % 2 == 0
            })
            .expect("the products of 2, 3 and 5 are unbounded");
        let nf = n as f64;
        let hi = nf * INV_TAU.0;
        let scale = (hi, two_product_error(nf, INV_TAU.0, hi) + nf * INV_TAU.1);
        Axis { n, scale }
    }

    /// The first grid index of the kernel's `W` points around `x` (radians) and the fractional
    /// part `f ∈ [0, 1]` of `x·n/2π`: the points are `first + i` (mod `n`) at offsets
    /// `i + 1 − W/2 − f` from `x`, `i = 0, …, W − 1`.
    ///
    /// `x·n/2π` is formed in double-double arithmetic and wrapped by its integer part, so the
    /// fraction is exact to ~10⁻¹⁶ grid steps up to 2^52 grid steps (~10¹³ turns) of `x`.
    #[inline(always)]
    fn locate(&self, x: f64) -> (usize, f64) {
        let p = x * self.scale.0;
        let e = two_product_error(x, self.scale.0, p) + x * self.scale.1;
        let whole = p.floor();
        // `p − whole` is exact; adding the tiny `e` may leave the fraction a rounding outside
        // [0, 1], and beyond 2^52 grid steps (10¹³ turns) `e` is no longer tiny: clamped, so
        // that the kernel's polynomials stay finite (a NaN stays NaN).
        let frac = ((p - whole) + e).clamp(0.0, 1.0);
        let n = self.n as i64;
        // Saturated for huge or infinite angles (whose spectra are meaningless or NaN): wrap.
        let first = (whole as i64).wrapping_sub((WIDTH / 2 - 1) as i64);
        let first = if (0..n).contains(&first) {
            first
        } else {
            first.rem_euclid(n)
        };
        (first as usize, frac)
    }
}

/// The rounding error of `p = a·b`: `a·b − p` exactly (Dekker's product, without FMA so that
/// every CPU gives the same bits).
#[inline(always)]
fn two_product_error(a: f64, b: f64, p: f64) -> f64 {
    let (ah, al) = split(a);
    let (bh, bl) = split(b);
    ((ah * bh - p) + ah * bl + al * bh) + al * bl
}

/// Veltkamp's split of `a` into two halves of 26 bits each, `a = hi + lo`.
#[inline(always)]
fn split(a: f64) -> (f64, f64) {
    let c = 134_217_729.0 * a; // 2^27 + 1
    let hi = c - (c - a);
    (hi, a - hi)
}

/// The ES kernel `φ(x) = exp(β(√(1 − z²) − 1))`, `z = 2x/W`, zero outside `|z| < 1`.
///
/// The exponent is formed as `−β·z²/(1 + √(1 − z²))`: `√(1 − z²) − 1` would cancel near the
/// centre and err by `β·ε ≈ 4·10⁻¹⁵` there.
fn es_kernel(x: f64) -> f64 {
    let z = 2.0 * x / WIDTH as f64;
    if z.abs() < 1.0 {
        (-BETA * z * z / (1.0 + (1.0 - z * z).sqrt())).exp()
    } else {
        0.0
    }
}

/// The kernel's `W` values at the offsets `i + 1 − W/2 − f`, as polynomials in `t = 2f − 1`.
struct Kernel {
    /// `coeffs[d][i]`: the coefficient of `t^d` for offset `i`, laid out so that Horner's rule
    /// runs over the `W` offsets at once (vectorized).
    coeffs: [[f64; WIDTH]; DEGREE + 1],
}

impl Kernel {
    /// Interpolates `φ(i + 1 − W/2 − (t + 1)/2)` on `t ∈ [−1, 1]` at the `DEGREE + 1` Chebyshev
    /// points of each interval and converts the Chebyshev series to powers of `t` (the
    /// Chebyshev coefficients decay faster than the conversion's growth, so nothing is lost).
    fn fit() -> Self {
        Kernel {
            coeffs: fit_kernel(0.0, 1.0),
        }
    }
}

/// The kernel's `W` values at the offsets `i + 1 − W/2 − f` for `f ∈ [lo, hi]`, as polynomials
/// of degree `N − 1` in `t = 2(f − lo)/(hi − lo) − 1`: `[d][i]` the coefficient of `t^d` for
/// offset `i`. Interpolated at the `N` Chebyshev points of `[lo, hi]`, then the Chebyshev series
/// converted to powers of `t`.
fn fit_kernel<const N: usize>(lo: f64, hi: f64) -> [[f64; WIDTH]; N] {
    let mut coeffs = [[0.0; WIDTH]; N];
    // Monomial coefficients of T_0, …, T_{N−1}, from T_{k+1} = 2t·T_k − T_{k−1}.
    let mut cheb = [[0.0; N]; N];
    cheb[0][0] = 1.0;
    if N > 1 {
        cheb[1][1] = 1.0;
    }
    for k in 1..N - 1 {
        for d in 0..N {
            let up = if d > 0 { 2.0 * cheb[k][d - 1] } else { 0.0 };
            cheb[k + 1][d] = up - cheb[k - 1][d];
        }
    }
    let angle = |q: usize| std::f64::consts::PI * (q as f64 + 0.5) / N as f64;
    for i in 0..WIDTH {
        let values: [f64; N] = std::array::from_fn(|q| {
            let t = angle(q).cos();
            es_kernel(i as f64 + 1.0 - (WIDTH / 2) as f64 - (lo + (hi - lo) * (t + 1.0) / 2.0))
        });
        for k in 0..N {
            let scale = if k == 0 { 1.0 } else { 2.0 } / N as f64;
            let c: f64 = (0..N)
                .map(|q| values[q] * (k as f64 * angle(q)).cos())
                .sum::<f64>()
                * scale;
            for d in 0..N {
                coeffs[d][i] += c * cheb[k][d];
            }
        }
    }
    coeffs
}

/// `1/φ̂(2πk/n)` for `k = 0, …, max_order`, with `φ̂(ξ) = 2∫_0^{W/2} φ(x)·cos(ξx) dx` by
/// Gauss–Legendre quadrature, as in the paper.
fn inverse_kernel_transform(max_order: usize, n: usize) -> Vec<f64> {
    let half = WIDTH as f64 / 2.0;
    let (nodes, weights) = gauss_legendre(QUADRATURE_NODES);
    let (xs, ws): (Vec<f64>, Vec<f64>) = nodes
        .iter()
        .zip(&weights)
        .map(|(s, w)| {
            let x = half * (1.0 + s) / 2.0;
            (x, w * half * es_kernel(x)) // 2 · (W/4) · w · φ(x)
        })
        .unzip();
    (0..=max_order)
        .map(|k| {
            let xi = TAU * k as f64 / n as f64;
            let ft: f64 = xs.iter().zip(&ws).map(|(x, w)| w * (xi * x).cos()).sum();
            1.0 / ft
        })
        .collect()
}

/// Nodes and weights of the `q`-point Gauss–Legendre rule on `[−1, 1]`: Newton's iteration on
/// the Legendre polynomial `P_q` from the Chebyshev-like first guesses.
fn gauss_legendre(q: usize) -> (Vec<f64>, Vec<f64>) {
    let mut nodes = Vec::with_capacity(q);
    let mut weights = Vec::with_capacity(q);
    for i in 0..q {
        let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (q as f64 + 0.5)).cos();
        let mut derivative = 1.0;
        for _ in 0..100 {
            // P_q(x) and P_{q−1}(x) by the three-term recurrence.
            let (mut p, mut prev) = (1.0, 0.0);
            for k in 1..=q {
                let kf = k as f64;
                (p, prev) = (((2.0 * kf - 1.0) * x * p - (kf - 1.0) * prev) / kf, p);
            }
            derivative = q as f64 * (x * p - prev) / (x * x - 1.0);
            let step = p / derivative;
            x -= step;
            if step.abs() < 1e-16 {
                break;
            }
        }
        nodes.push(x);
        weights.push(2.0 / ((1.0 - x * x) * derivative * derivative));
    }
    (nodes, weights)
}

/// Row `s` of a grid with its padding (cells `N_b, N_b + 1, …`, which stand for `0, 1, …`)
/// folded back, into `line` (`N_b` values).
fn folded_row<const K: usize>(grid: &[[f64; K]], s: usize, line: &mut [f64]) {
    let n = line.len();
    for (l, g) in line.iter_mut().zip(grid) {
        *l = g[s];
    }
    for (l, g) in line.iter_mut().zip(&grid[n..]) {
        *l += g[s];
    }
}

/// Steps 2 and 3 for the 2-D grid: real FFTs of the rows, complex FFTs of the columns
/// `m ≤ m_max`, and the division by the kernel's transform. Rows, then columns, are transformed
/// in parallel; each is independent, so the bits do not depend on the threads. Each row is the
/// pieces' rows summed in their order; the pieces' grids are freed once the rows are
/// transformed.
fn transform_2d<const K: usize>(
    pieces: Vec<Piece<K>>,
    a_axis: &Axis,
    b_axis: &Axis,
    j_max: usize,
    m_max: usize,
) -> [Spectrum2; K] {
    let (na, nb) = (a_axis.n, b_axis.n);
    let row_len = nb + PAIR_WIDTH - 1;
    let width = m_max + 1;
    let rfft = RealFftPlanner::<f64>::new().plan_fft_forward(nb);
    // The row transforms, `m ≤ m_max`, of row r and set s at `(r·K + s)·width`.
    let mut rows = zeros(na * K * width);
    rows.par_chunks_exact_mut(K * width)
        .enumerate()
        .for_each_init(
            || {
                let line = rfft.make_input_vec();
                let sum = Vec::with_capacity(row_len);
                (line, rfft.make_output_vec(), rfft.make_scratch_vec(), sum)
            },
            |(line, out, scratch, sum), (r, spectra)| {
                // A row no sample reached transforms to zeros, as `rows` holds.
                let Some(row) = Piece::row_sum(&pieces, r, row_len, sum) else {
                    return;
                };
                for (s, spectrum) in spectra.chunks_exact_mut(width).enumerate() {
                    folded_row(row, s, line);
                    rfft.process_with_scratch(line, out, scratch)
                        .expect("buffer sizes come from the plan");
                    spectrum.copy_from_slice(&out[..width]);
                }
            },
        );
    drop(pieces);
    let inv_a = inverse_kernel_transform(j_max, na);
    let inv_b = inverse_kernel_transform(m_max, nb);
    let cfft = FftPlanner::<f64>::new().plan_fft_forward(na);
    let orders = 2 * j_max + 1;
    // F_s(j, m) at `(s·width + m)·orders + j + j_max`.
    let mut columns = zeros(K * width * orders);
    columns
        .par_chunks_exact_mut(orders)
        .enumerate()
        .for_each_init(
            || {
                let scratch = vec![Complex64::default(); cfft.get_inplace_scratch_len()];
                (vec![Complex64::default(); na], scratch)
            },
            |(column, scratch), (sm, out)| {
                let (s, m) = (sm / width, sm % width);
                for (r, c) in column.iter_mut().enumerate() {
                    *c = rows[(r * K + s) * width + m];
                }
                cfft.process_with_scratch(column, scratch);
                // The forward FFTs give Σ g·e^{−i(…)} = conj G for the real grid g.
                for (o, j) in out.iter_mut().zip(-(j_max as i64)..) {
                    let c = column[j.rem_euclid(na as i64) as usize];
                    *o = c.conj() * (inv_a[j.unsigned_abs() as usize] * inv_b[m]);
                }
            },
        );
    std::array::from_fn(|s| Spectrum2 {
        j_max,
        m_max,
        values: (0..orders * width)
            .into_par_iter()
            .map(|i| columns[(s * width + i % width) * orders + i / width])
            .collect(),
    })
}

/// `len` zeros, written on the rayon pool: `vec![Complex64::default(); len]` writes them on the
/// caller's thread (a struct gets no zeroed allocation), and the first write to each page is a
/// page fault — for the 2-D transform's 25 MB, 0.03 s with the other core idle.
fn zeros(len: usize) -> Vec<Complex64> {
    (0..len)
        .into_par_iter()
        .map(|_| Complex64::default())
        .collect()
}

/// Steps 2 and 3 for the 1-D grid (`j_max = 0`).
fn transform_1d<const K: usize>(
    pieces: &[Piece<K>],
    b_axis: &Axis,
    m_max: usize,
) -> [Spectrum2; K] {
    let nb = b_axis.n;
    let mut sum = Vec::new();
    let zeros = vec![[0.0; K]; nb + PAIR_WIDTH - 1];
    let grid = Piece::row_sum(pieces, 0, zeros.len(), &mut sum).unwrap_or(&zeros);
    let inv_b = inverse_kernel_transform(m_max, nb);
    let rfft = RealFftPlanner::<f64>::new().plan_fft_forward(nb);
    let mut line = rfft.make_input_vec();
    let mut out = rfft.make_output_vec();
    let mut scratch = rfft.make_scratch_vec();
    std::array::from_fn(|s| {
        folded_row(grid, s, &mut line);
        rfft.process_with_scratch(&mut line, &mut out, &mut scratch)
            .expect("buffer sizes come from the plan");
        Spectrum2 {
            j_max: 0,
            m_max,
            values: (0..=m_max).map(|m| out[m].conj() * inv_b[m]).collect(),
        }
    })
}

#[cfg(test)]
mod tests {
    use super::spread::{Lanes, Located};
    use super::*;

    /// SplitMix64: reproducible uniform numbers in [0, 1) without a dependency.
    struct Rng(u64);

    impl Rng {
        fn uniform(&mut self) -> f64 {
            self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// `e^{ikx}` to within a rounding of the result: `k·x` in double-double, reduced by a
    /// double-double 2π, so that the reference does not carry the `ulp(k·x)` phase error of a
    /// plain `(k·x).sin_cos()` (10⁻¹² at `k·x ≈ 6000`).
    fn cis(k: i64, x: f64) -> Complex64 {
        const TAU_LO: f64 = 2.449_293_598_294_706_4e-16;
        let kf = k as f64;
        let p = kf * x;
        let e = kf.mul_add(x, -p);
        let q = (p / TAU).round();
        let qh = q * TAU;
        let qe = q.mul_add(TAU, -qh);
        let r = ((p - qh) - qe + e) - q * TAU_LO;
        let (s, c) = r.sin_cos();
        Complex64::new(c, s)
    }

    /// Random samples: `a` from `acos` of a uniform number plus a few turns, `b` over up to
    /// 400 turns; weight set 0 all ones, 1 uniform in [0, 1), 2 of mixed signs in [−1, 1).
    fn samples(len: usize, seed: u64) -> Vec<(f64, f64, [f64; 3])> {
        let mut rng = Rng(seed);
        (0..len)
            .map(|_| {
                let turns = (rng.uniform() * 5.0).floor() - 2.0;
                let a = (2.0 * rng.uniform() - 1.0).acos() + TAU * turns;
                let b = TAU * 400.0 * rng.uniform();
                (a, b, [1.0, rng.uniform(), 2.0 * rng.uniform() - 1.0])
            })
            .collect()
    }

    /// Samples in time order, as `calib tdr` has them: `a = acos τ` with `τ` the normalized time,
    /// `b` a decelerating phase over `turns` turns with a µrad jitter; weight sets `[1, τ, ±1]`.
    fn time_ordered(len: usize, turns: f64, seed: u64) -> Vec<(f64, f64, [f64; 3])> {
        let mut rng = Rng(seed);
        (0..len)
            .map(|n| {
                let u = (n as f64 + 0.5) / len as f64;
                let tau = 2.0 * u - 1.0;
                let b = TAU * turns * (1.0 - (1.0 - u) * (1.0 - u)) + 1e-6 * rng.uniform();
                (tau.acos(), b, [1.0, tau, 2.0 * rng.uniform() - 1.0])
            })
            .collect()
    }

    /// max over the given `(j, m)` and weight sets of `|F_s(j, m) − direct| / Σ_n |w_{s,n}|`.
    fn max_relative_error(
        pts: &[(f64, f64, [f64; 3])],
        spectra: &[Spectrum2; 3],
        pairs: &[(i64, i64)],
    ) -> f64 {
        // e^{ija_n} and e^{imb_n} once per sample and order, for every order in `pairs`.
        let table = |order: fn(&(i64, i64)) -> i64, angle: fn(&(f64, f64, [f64; 3])) -> f64| {
            let mut orders: Vec<i64> = pairs.iter().map(order).collect();
            orders.sort_unstable();
            orders.dedup();
            let values: Vec<Vec<Complex64>> = orders
                .iter()
                .map(|&k| pts.iter().map(|p| cis(k, angle(p))).collect())
                .collect();
            (orders, values)
        };
        let (ja, ea) = table(|p| p.0, |p| p.0);
        let (mb, eb) = table(|p| p.1, |p| p.1);
        let mut worst: f64 = 0.0;
        for s in 0..3 {
            let l1: f64 = pts.iter().map(|p| p.2[s].abs()).sum();
            for &(j, m) in pairs {
                let x = &ea[ja.binary_search(&j).expect("tabulated")];
                let y = &eb[mb.binary_search(&m).expect("tabulated")];
                let direct: Complex64 = (x.iter().zip(y).zip(pts))
                    .map(|((x, y), p)| p.2[s] * x * y)
                    .sum();
                worst = worst.max((spectra[s].at(j, m) - direct).norm() / l1);
            }
        }
        worst
    }

    #[test]
    fn kernel_polynomials_match_the_kernel() {
        let kernel = Kernel::fit();
        let mut worst: f64 = 0.0;
        for q in 0..=1000 {
            let f = q as f64 / 1000.0;
            let mut values = spread::Portable.kernels(&kernel, f, f).to_vec();
            #[cfg(target_arch = "x86_64")]
            values.extend(
                spread::avx2::Avx2::detect().map_or(vec![], |l| l.kernels(&kernel, f, f).to_vec()),
            );
            for v in values {
                for (i, v) in v.iter().enumerate() {
                    let x = i as f64 + 1.0 - (WIDTH / 2) as f64 - f;
                    worst = worst.max((v - es_kernel(x)).abs());
                }
            }
        }
        // Horner's rounding, at most 2·DEGREE·ε·Σ_d |c_d| (measured 2.1e-15, at the centre), plus
        // the kernel's step e^{−β} = 1.0e-16 at |z| = 1, which the polynomials smooth over.
        let horner = (0..WIDTH)
            .map(|i| (0..=DEGREE).map(|d| kernel.coeffs[d][i].abs()).sum::<f64>())
            .fold(0.0, f64::max);
        let bound = 2.0 * DEGREE as f64 * f64::EPSILON * horner + (-BETA).exp();
        assert!(worst < bound, "{worst:e} ≥ {bound:e}");
    }

    // The bound 1e-13·Σ|w| of every accuracy test: the paper's W = 16 kernel at σ = 2 truncates
    // and aliases at ~1e-15, and the rounding of the kernel's values (~2e-15) and of the
    // FFTs is amplified at the highest orders by the division by φ̂, which falls there to a few
    // percent of φ̂(0) per dimension. Many samples average their rounding errors; a few do not.

    /// The orders checked at the use case's sizes (`j_max = 127`, `m_max = 1016`): all `j` at a
    /// few `m`, every third `m` at a few `j`.
    fn use_case_orders() -> Vec<(i64, i64)> {
        let mut pairs: Vec<(i64, i64)> = [-127, -64, -1, 0, 1, 37, 126, 127]
            .iter()
            .flat_map(|&j| (0..=1016).step_by(3).map(move |m| (j, m)))
            .collect();
        pairs.extend((-127..=127).flat_map(|j| [0, 1, 508, 1015, 1016].map(|m| (j, m))));
        pairs
    }

    #[test]
    fn two_dimensional_spectra_match_direct_sums() {
        // Small orders: every (j, m) checked.
        let pts = samples(3000, 1);
        let spectra = type1(pts.len(), 20, 100, |n| pts[n]);
        let pairs: Vec<(i64, i64)> = (-20..=20)
            .flat_map(|j| (-100..=100).map(move |m| (j, m)))
            .collect();
        let err = max_relative_error(&pts, &spectra, &pairs);
        assert!(err < 1e-13, "{err:e}"); // measured 2.9e-15

        // The use case's orders: all j at a few m, all m at a few j, N_a × N_b = 512 × 4096.
        let pts = samples(2000, 2);
        let spectra = type1(pts.len(), 127, 1016, |n| pts[n]);
        let err = max_relative_error(&pts, &spectra, &use_case_orders());
        assert!(err < 1e-13, "{err:e}"); // measured 2.7e-15
    }

    #[test]
    fn time_ordered_samples_match_direct_sums() {
        // Samples in time order, as `calib tdr` has them: `a = acos τ` with τ the normalized time
        // and `b` a decelerating phase over 2 turns. Consecutive samples share their row and
        // lie 0–6 columns apart, so both the paired and the single spreading run.
        let pts = time_ordered(3000, 2.0, 7);
        let spectra = type1(pts.len(), 127, 1016, |n| pts[n]);
        let err = max_relative_error(&pts, &spectra, &use_case_orders());
        assert!(err < 1e-13, "{err:e}"); // measured 5.2e-15
    }

    #[test]
    fn run_kernels_match_the_kernel() {
        let runs = RunKernel::fit();
        let mut worst: f64 = 0.0;
        for q in 0..=10_000 {
            let f = q as f64 / 10_000.0;
            for (i, v) in runs.values(f).iter().enumerate() {
                let x = i as f64 + 1.0 - (WIDTH / 2) as f64 - f;
                worst = worst.max((v - es_kernel(x)).abs());
            }
        }
        // The expansion's truncation and Horner's rounding, as the kernel's own polynomials.
        assert!(worst < 4e-15, "{worst:e}"); // measured 1.1e-15
    }

    #[test]
    fn long_runs_match_direct_sums() {
        // Time-ordered samples over few rows (`j_max = 4`: `a ∈ [0, π]` covers 16 rows) and
        // three turns: ~100 consecutive samples share a row and a sub-interval of its step, so
        // the blocks are spread by runs — all but the first and last few, where `a = acos τ`
        // crosses the sub-intervals faster than one per few samples.
        let pts = time_ordered(200_000, 3.0, 13);
        let plan = Plan::new(4, 40);
        let by_runs = |block: &[(f64, f64, [f64; 3])]| {
            let located: Vec<_> = block.iter().map(|&p| Located::new(&plan, p)).collect();
            spread::runs_pay(&plan, &located)
        };
        let blocks: Vec<bool> = pts.chunks(BLOCK).map(by_runs).collect();
        let runs = blocks.iter().filter(|&&r| r).count();
        assert!(runs > blocks.len() * 9 / 10, "{runs} of {}", blocks.len());
        assert!(!blocks[0], "the first block crosses many sub-intervals");
        // Samples out of order travel across the grid: sample by sample.
        assert!(!by_runs(&samples(BLOCK, 14)));
        let spectra = type1(pts.len(), 4, 40, |n| pts[n]);
        let orders: Vec<(i64, i64)> = (-4..=4)
            .flat_map(|j| [(j, 0), (j, 5), (j, -17), (j, 40), (j, -40)])
            .chain((-40..=40).map(|m| (3, m)))
            .collect();
        let err = max_relative_error(&pts, &spectra, &orders);
        // Measured 1.2e-14 (777 of 782 blocks by runs): the direct sums' own rounding over
        // 200,000 samples shows.
        assert!(err < 1e-13, "{err:e}");
    }

    #[test]
    fn pieces_summed_match_direct_sums() {
        // Enough time-ordered samples for four pieces, each reaching its own rows and the rows
        // either side of its borders shared with the next; and random samples in the last piece,
        // reaching every row.
        let mut pts = time_ordered(4 * MIN_SPLIT + 1000, 40.0, 11);
        pts.extend(samples(5000, 12));
        assert_eq!(pieces(pts.len()).len(), 4);
        let orders: Vec<(i64, i64)> = (-8..=8)
            .flat_map(|j| [(j, 0), (j, 17), (j, -40)])
            .chain((-40..=40).flat_map(|m| [(0, m), (5, m), (-8, m)]))
            .collect();
        let spectra = type1(pts.len(), 8, 40, |n| pts[n]);
        let err = max_relative_error(&pts, &spectra, &orders);
        // Measured 1.9e-14: the direct sums' own rounding over 267,000 samples shows.
        assert!(err < 1e-13, "{err:e}");
        let spectra = type1(pts.len(), 0, 40, |n| pts[n]);
        let line: Vec<(i64, i64)> = (-40..=40).map(|m| (0, m)).collect();
        let err = max_relative_error(&pts, &spectra, &line);
        assert!(err < 1e-13, "{err:e}"); // measured 1.9e-15
    }

    #[test]
    fn a_few_samples_match_direct_sums() {
        // No averaging of the per-sample errors over many samples: the hardest case for the bound.
        let pts = samples(5, 6);
        let spectra = type1(pts.len(), 127, 1016, |n| pts[n]);
        let pairs: Vec<(i64, i64)> = (-127..=127)
            .flat_map(|j| (0..=1016).map(move |m| (j, m)))
            .collect();
        let err = max_relative_error(&pts, &spectra, &pairs);
        assert!(err < 1e-13, "{err:e}"); // measured 3.4e-14
    }

    #[test]
    fn one_dimensional_spectra_match_direct_sums() {
        let pts = samples(3000, 3);
        let spectra = type1(pts.len(), 0, 1016, |n| pts[n]);
        let pairs: Vec<(i64, i64)> = (-1016..=1016).map(|m| (0, m)).collect();
        let err = max_relative_error(&pts, &spectra, &pairs);
        assert!(err < 1e-13, "{err:e}"); // measured 1.4e-15
    }

    #[test]
    fn no_samples_give_zero_spectra() {
        for j_max in [0, 3] {
            let [s] = type1(0, j_max, 5, |_| unreachable!("no samples"));
            assert!(s.values.iter().all(|v| *v == Complex64::default()));
            assert_eq!((s.j_max(), s.m_max()), (j_max, 5));
        }
    }

    #[test]
    fn bits_do_not_depend_on_the_threads() {
        // Time-ordered samples (mostly spread in pairs) then random ones (singly).
        let mut pts = time_ordered(2 * MIN_SPLIT + 7, 100.0, 4);
        pts.extend(samples(MIN_SPLIT, 8));
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("a thread pool");
            pool.install(|| {
                [
                    type1(pts.len(), 8, 40, |n| pts[n]),
                    type1(pts.len(), 0, 40, |n| pts[n]),
                ]
            })
        };
        let bits = |r: [[Spectrum2; 3]; 2]| -> Vec<u64> {
            r.iter()
                .flatten()
                .flat_map(|s| {
                    s.values
                        .iter()
                        .flat_map(|v| [v.re.to_bits(), v.im.to_bits()])
                })
                .collect()
        };
        assert_eq!(bits(run(1)), bits(run(2)));
    }

    #[test]
    fn non_finite_and_huge_inputs_give_nan_not_a_panic() {
        for x in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, -1e300, 1e300] {
            for j_max in [0, 3] {
                // Sample 0 has the value as both angles, sample 1 as its weight.
                let [s] = type1(2, j_max, 5, |n| {
                    if n == 0 {
                        (x, x, [1.0])
                    } else {
                        (0.1, 0.2, [x])
                    }
                });
                let nan = s.values.iter().any(|v| v.re.is_nan() || v.im.is_nan());
                assert_eq!(nan, !x.is_finite(), "{x}, j_max = {j_max}");
            }
        }
    }

    #[test]
    fn negative_orders_are_conjugates() {
        let pts = samples(50, 5);
        let [s, ..] = type1(pts.len(), 4, 6, |n| pts[n]);
        assert_eq!(s.at(-3, -5), s.at(3, 5).conj());
        assert_eq!(s.at(0, 0).im, 0.0);
    }

    #[test]
    #[should_panic(expected = "outside")]
    fn out_of_range_orders_panic() {
        let [s] = type1(1, 4, 6, |_| (0.0, 0.0, [1.0]));
        s.at(5, 0);
    }
}
