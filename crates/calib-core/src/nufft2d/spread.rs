//! Step 1 of the transform: the samples spread onto a piece's grid, a [`BLOCK`] at a time.
//!
//! Each sample adds `w_s·φ(l_a − u_a)·φ(l_b − u_b)` to the `W × W` cells around it. A block is
//! spread one of two ways, whichever takes fewer multiply-adds ([`runs_pay`]):
//!
//! - *sample by sample*: each sample's `W` values along `b` times its weights, added to `W` rows,
//!   each scaled by the kernel along `a`. Two consecutive samples that share their first row and
//!   start at most [`PAIR_SHIFT`] columns apart are added in one pass over [`PAIR_WIDTH`] cells
//!   per row: one load and one store of the grid for both (the stores bound the speed of this
//!   loop: the store buffer fills; pairs make 40 % fewer).
//! - *by runs*: samples in time order move slowly along `a` — `calib tdr`'s coast has
//!   thousands of consecutive samples per grid row — so consecutive samples share their first
//!   row `r` and one of the [`SUBDIV`] sub-intervals `s` of the grid step. On it the kernel
//!   along `a` is a polynomial in the sample's place `u ∈ [−1, 1]` within the sub-interval,
//!   `φ(i + 1 − W/2 − f_a) = Σ_{d<RANK} c_{s,d,i}·u^d` (to 4·10⁻¹⁵ of the peak, test
//!   `run_kernels_match_the_kernel`), so the run adds to row `r + i` the combination
//!   `Σ_d c_{s,d,i}·H_d` of `RANK` rows `H_d = Σ_n u_n^d·φ(l_b − u_{b,n})·w_n` summed along `b`
//!   alone: [`RANK`] rows per sample instead of `W`, and the `W` grid rows written once per run
//!   for the columns it reached. Two samples' kernels along `b` come from one evaluation.
//!
//! Either way the grid gets the same sums to rounding; which way a block goes depends on its
//! samples alone, so the bits do not depend on the threads.

use super::{BLOCK, DEGREE, Kernel, Piece, Plan, WIDTH, fit_kernel};
use std::ops::Range;

/// Columns by which the second sample of a pair may start after the first; the rows carry as
/// many extra cells of padding.
pub(super) const PAIR_SHIFT: usize = 4;
/// Cells of a pair's rows.
pub(super) const PAIR_WIDTH: usize = WIDTH + PAIR_SHIFT;
/// Sub-intervals of a grid step along `a` on which a run's kernel is a polynomial.
const SUBDIV: usize = 128;
/// Terms of the run's kernel on a sub-interval: degree 4 on 1/128 of a step errs by 1.1·10⁻¹⁵
/// of the kernel's peak (test `run_kernels_match_the_kernel`), as the kernel's own polynomials;
/// degree 3 errs by 10⁻¹², and degree 4 on 1/64 of a step by 2·10⁻¹⁴.
const RANK: usize = 5;
/// Columns of a run's rows written to the grid together.
const TILE: usize = 16;

impl Plan {
    /// The grid of the samples `range` (empty for an empty range), `fill`ed a block at a time.
    pub(super) fn spread<const K: usize, F>(&self, fill: &F, range: Range<usize>) -> Piece<K>
    where
        F: Fn(Range<usize>, &mut Vec<(f64, f64, [f64; K])>),
    {
        let rows = self.rows();
        if range.is_empty() {
            return Piece {
                grid: Vec::new(),
                reached: vec![false; rows],
            };
        }
        let mut spreading = Spreading {
            grid: vec![[0.0; K]; rows * self.row_len()],
            first_rows: FirstRows::new(rows, self.two_d),
            located: Vec::with_capacity(BLOCK),
            run: Run::new(self),
        };
        let mut points = Vec::with_capacity(BLOCK);
        #[cfg(target_arch = "x86_64")]
        let avx2 = avx2::Avx2::detect();
        for start in range.clone().step_by(BLOCK) {
            let block = start..(start + BLOCK).min(range.end);
            let last = block.end == range.end;
            refill(fill, block, &mut points);
            #[cfg(target_arch = "x86_64")]
            match avx2 {
                Some(avx2) => avx2.spread_block(self, &points, last, &mut spreading),
                None => spread_block(Portable, self, &points, last, &mut spreading),
            }
            #[cfg(not(target_arch = "x86_64"))]
            spread_block(Portable, self, &points, last, &mut spreading);
        }
        let first_rows = spreading.first_rows.first;
        let reached = (0..rows)
            .map(|r| (0..WIDTH.min(rows)).any(|i| first_rows[(r + rows - i) % rows]))
            .collect();
        Piece {
            grid: spreading.grid,
            reached,
        }
    }
}

/// The points of the samples `range`, by `fill`, in place of `points`' old ones: out of line,
/// once per [`BLOCK`], so that the spreading loop stays small. With a caller's `fill` inlined
/// into it (a residual model evaluated there), the 1-D loop waited on each point through
/// memory; out of line, `calib tdr`'s residual pass (then a 1-D transform) took a quarter less
/// time.
#[inline(never)]
fn refill<const K: usize, F>(fill: &F, range: Range<usize>, points: &mut Vec<(f64, f64, [f64; K])>)
where
    F: Fn(Range<usize>, &mut Vec<(f64, f64, [f64; K])>),
{
    points.clear();
    fill(range, points);
}

/// A piece's grid while its samples are spread, and what is carried from block to block.
struct Spreading<const K: usize> {
    /// `N_a` rows of [`Plan::row_len`] cells, or one.
    grid: Vec<[f64; K]>,
    /// Which rows are the first of a sample's kernel.
    first_rows: FirstRows,
    /// The block's samples on the grid.
    located: Vec<Located<K>>,
    /// The open run (two dimensions).
    run: Run<K>,
}

/// A sample on the grid: the first row and column of its kernel, the fractional parts of its
/// position along `a` and `b`, its sub-interval of the step along `a` and its place `u` there.
#[derive(Clone, Copy)]
pub(super) struct Located<const K: usize> {
    row: usize,
    fa: f64,
    sub: usize,
    u: f64,
    first: usize,
    fb: f64,
    w: [f64; K],
}

impl<const K: usize> Located<K> {
    #[inline(always)]
    pub(super) fn new(plan: &Plan, (a, b, w): (f64, f64, [f64; K])) -> Self {
        let (row, fa) = plan.a.locate(a);
        let (first, fb) = plan.b.locate(b);
        let x = fa * SUBDIV as f64;
        let sub = (x as usize).min(SUBDIV - 1);
        let u = 2.0 * (x - sub as f64) - 1.0;
        Located {
            row,
            fa,
            sub,
            u,
            first,
            fb,
            w,
        }
    }

    /// The run it belongs to.
    fn key(&self) -> (usize, usize) {
        (self.row, self.sub)
    }
}

/// Per row of a piece's grid: whether it is the first row of a sample's kernel (all, in one
/// dimension), and whether its cells have been written.
///
/// The grid is allocated zeroed and untouched, so the system gives it pages as they are first
/// touched. Adding to a cell reads it first: a page first read is mapped to the system's shared
/// page of zeros, and the write after it replaces that mapping, which makes the system flush
/// it from every core running the process (an interrupt to the other core). So the `W` rows of
/// a kernel are written with zeros before anything is added to them, once each: one page fault
/// per page, no flush. (On `calib tdr`'s 10⁷-sample coast the flushes took ~2 % of its CPU.)
struct FirstRows {
    first: Vec<bool>,
    written: Vec<bool>,
}

impl FirstRows {
    fn new(rows: usize, two_d: bool) -> Self {
        FirstRows {
            first: vec![!two_d; rows],
            written: vec![!two_d; rows],
        }
    }

    /// Marks `row` as the first of a kernel, its `W` rows (wrapped) written with zeros where
    /// nothing was written yet, before any is added to.
    #[inline(always)]
    fn mark<const K: usize>(&mut self, grid: &mut [[f64; K]], row_len: usize, row: usize) {
        if self.first[row] {
            return;
        }
        self.first[row] = true;
        let rows = self.first.len();
        for i in 0..WIDTH.min(rows) {
            let r = (row + i) % rows;
            if !self.written[r] {
                self.written[r] = true;
                grid[r * row_len..(r + 1) * row_len].fill([0.0; K]);
            }
        }
    }
}

/// Spreads one block of samples; the last of the piece closes the open run.
#[inline(always)]
fn spread_block<const K: usize, L: Lanes>(
    lanes: L,
    plan: &Plan,
    points: &[(f64, f64, [f64; K])],
    last: bool,
    spreading: &mut Spreading<K>,
) {
    let Spreading {
        grid,
        first_rows,
        located,
        run,
    } = spreading;
    if !plan.two_d {
        spread_row(lanes, plan, points, grid);
        return;
    }
    located.clear();
    lanes.locate(plan, points, located);
    if runs_pay(plan, located) {
        spread_runs(lanes, plan, located, run, grid, first_rows);
    } else {
        spread_samples(lanes, plan, located, grid, first_rows);
    }
    if last {
        run.close(lanes, plan, grid, first_rows);
    }
}

/// Whether a block is spread with fewer multiply-adds by runs than sample by sample, counted
/// in rows of `W` cells: `W` per sample against `RANK` per sample plus, for the grid's rows
/// written, `RANK·TILE` per tile of columns — one per `TILE` columns the samples travel, and
/// two more per run (where it starts and ends). (The runs' shared evaluation of the kernel
/// along `b` is not counted: the choice errs towards sample by sample.)
pub(super) fn runs_pay<const K: usize>(plan: &Plan, located: &[Located<K>]) -> bool {
    let n = plan.b.n;
    let (mut runs, mut travel) = (1, 0);
    for pair in located.windows(2) {
        let (p, q) = (&pair[0], &pair[1]);
        runs += usize::from(p.key() != q.key());
        let d = p.first.abs_diff(q.first);
        travel += d.min(n - d);
    }
    let samples = located.len();
    RANK * (samples + travel + 2 * TILE * runs) < WIDTH * samples
}

/// The kernel along `a` on each of the [`SUBDIV`] sub-intervals of a grid step, as polynomials
/// of degree `RANK − 1` in the place `u ∈ [−1, 1]` within it: `[s][d][i]` for offset `i`.
pub(super) struct RunKernel {
    coeffs: Vec<[[f64; WIDTH]; RANK]>,
}

impl RunKernel {
    pub(super) fn fit() -> Self {
        let coeffs = (0..SUBDIV)
            .map(|s| fit_kernel(s as f64 / SUBDIV as f64, (s + 1) as f64 / SUBDIV as f64))
            .collect();
        RunKernel { coeffs }
    }

    /// The kernel's `W` values for fraction `f` along `a`, as a run computes them.
    #[cfg(test)]
    pub(super) fn values(&self, f: f64) -> [f64; WIDTH] {
        let x = f * SUBDIV as f64;
        let sub = (x as usize).min(SUBDIV - 1);
        let u = 2.0 * (x - sub as f64) - 1.0;
        let c = &self.coeffs[sub];
        std::array::from_fn(|i| (0..RANK).rev().fold(0.0, |v, d| v * u + c[d][i]))
    }
}

/// The open run: its first row and sub-interval, and its `RANK` rows `H_d` along `b`.
struct Run<const K: usize> {
    key: Option<(usize, usize)>,
    /// `H_d` at `d·len`: [`Plan::row_len`] cells rounded up to whole tiles (none in one
    /// dimension).
    sums: Vec<[f64; K]>,
    len: usize,
    /// Per tile: whether the run reached it; and the tiles reached, in order.
    touched: Vec<bool>,
    tiles: Vec<usize>,
}

impl<const K: usize> Run<K> {
    fn new(plan: &Plan) -> Self {
        let len = if plan.two_d {
            plan.row_len().next_multiple_of(TILE)
        } else {
            0
        };
        Run {
            key: None,
            sums: vec![[0.0; K]; RANK * len],
            len,
            touched: vec![false; len / TILE],
            tiles: Vec::new(),
        }
    }

    /// Makes `key`'s run the open one, closing another.
    #[inline(always)]
    fn open(
        &mut self,
        lanes: impl Lanes,
        plan: &Plan,
        key: (usize, usize),
        grid: &mut [[f64; K]],
        first_rows: &mut FirstRows,
    ) {
        if self.key != Some(key) {
            self.close(lanes, plan, grid, first_rows);
            self.key = Some(key);
        }
    }

    /// Adds two samples' rows `scaled` (of one length, from column `first`), each times its
    /// powers `u^d`, to every `H_d`; a lone sample comes with a row of zeros.
    #[inline(always)]
    fn add(
        &mut self,
        lanes: impl Lanes,
        first: usize,
        pows: [[f64; RANK]; 2],
        scaled: [&[f64]; 2],
    ) {
        let cells = scaled[0].len() / K;
        for t in first / TILE..=(first + cells - 1) / TILE {
            if !self.touched[t] {
                self.touched[t] = true;
                self.tiles.push(t);
            }
        }
        let mut k = [[0.0; 2]; RANK];
        for (d, k) in k.iter_mut().enumerate() {
            *k = [pows[0][d], pows[1][d]];
        }
        let from = first * K;
        let rows = &mut self.sums.as_flattened_mut()[from..];
        lanes.add_rows_pair(rows, self.len * K, k, scaled);
    }

    /// Adds the open run to the grid's `W` rows from its first, `Σ_d c_{s,d,i}·H_d` to row
    /// `r + i`, for the tiles it reached, and empties it.
    #[inline(always)]
    fn close(
        &mut self,
        lanes: impl Lanes,
        plan: &Plan,
        grid: &mut [[f64; K]],
        first_rows: &mut FirstRows,
    ) {
        let Some((row, sub)) = self.key.take() else {
            return;
        };
        let row_len = plan.row_len();
        first_rows.mark(grid, row_len, row);
        let coeffs = &plan.runs.coeffs[sub];
        let unwrapped = (plan.a.n - row).min(WIDTH);
        for &t in &self.tiles {
            self.touched[t] = false;
            let (start, end) = (t * TILE, ((t + 1) * TILE).min(row_len));
            let sums: [&[f64]; RANK] = std::array::from_fn(|d| {
                self.sums[d * self.len + start..d * self.len + end].as_flattened()
            });
            for i in 0..WIDTH {
                let r = if i < unwrapped {
                    row + i
                } else {
                    i - unwrapped
                };
                let cells = grid[r * row_len + start..r * row_len + end].as_flattened_mut();
                lanes.add_combination(cells, std::array::from_fn(|d| coeffs[d][i]), sums);
            }
            for d in 0..RANK {
                self.sums[d * self.len + start..d * self.len + (t + 1) * TILE].fill([0.0; K]);
            }
        }
        self.tiles.clear();
    }
}

/// Spreads a block by runs (module docs): two consecutive samples of one run that start at
/// most [`PAIR_SHIFT`] columns apart are added to its rows together, others one by one.
#[inline(always)]
fn spread_runs<const K: usize, L: Lanes>(
    lanes: L,
    plan: &Plan,
    located: &[Located<K>],
    run: &mut Run<K>,
    grid: &mut [[f64; K]],
    first_rows: &mut FirstRows,
) {
    // Each sample's kernel along `b` times its weights, between `PAIR_SHIFT` zero cells on
    // either side, so that a pair's second sample reads its row shifted without a copy.
    let mut padded = [[[0.0; K]; WIDTH + 2 * PAIR_SHIFT]; 2];
    let zero = [[0.0; K]; WIDTH];
    for pair in located.chunks(2) {
        // A lone last sample is computed twice and added once.
        let [p, q] = [&pair[0], pair.get(1).unwrap_or(&pair[0])];
        let kb = lanes.kernels(&plan.kernel, p.fb, q.fb);
        let (u, w) = ([p.u, q.u], [p.w, q.w]);
        let mut pows = [[1.0; RANK]; 2];
        for i in 0..2 {
            for d in 1..RANK {
                pows[i][d] = pows[i][d - 1] * u[i];
            }
            for (c, k) in padded[i][PAIR_SHIFT..].iter_mut().zip(kb[i]) {
                for s in 0..K {
                    c[s] = k * w[i][s];
                }
            }
        }
        let shift = q.first.wrapping_sub(p.first);
        if pair.len() == 2 && p.key() == q.key() && shift <= PAIR_SHIFT {
            run.open(lanes, plan, p.key(), grid, first_rows);
            let s0 = padded[0][PAIR_SHIFT..PAIR_SHIFT + PAIR_WIDTH].as_flattened();
            let s1 = padded[1][PAIR_SHIFT - shift..PAIR_SHIFT - shift + PAIR_WIDTH].as_flattened();
            run.add(lanes, p.first, pows, [s0, s1]);
        } else {
            for (i, p) in pair.iter().enumerate() {
                run.open(lanes, plan, p.key(), grid, first_rows);
                let scaled = padded[i][PAIR_SHIFT..PAIR_SHIFT + WIDTH].as_flattened();
                run.add(lanes, p.first, [pows[i]; 2], [scaled, zero.as_flattened()]);
            }
        }
    }
}

/// How the spreading loop computes: [`Portable`] Rust, or AVX2 and FMA instructions
/// (`avx2::Avx2`, four fused multiply-adds per instruction where SSE2 does two multiplications
/// and two additions; the compiler's own vectorization of the same loops was half as fast). The
/// two differ in the last bits (a fused multiply-add rounds once): the results are
/// reproducible on one kind of CPU.
pub(super) trait Lanes: Copy {
    /// Each point [`Located::new`] on the grid, pushed to `located` in order.
    fn locate<const K: usize>(
        self,
        plan: &Plan,
        points: &[(f64, f64, [f64; K])],
        located: &mut Vec<Located<K>>,
    );

    /// The kernel's `W` values at the offsets `i + 1 − W/2 − f` for the two fractions
    /// `f = f_a, f_b`, by Horner's rule (eight independent chains of multiply-adds).
    fn kernels(self, kernel: &Kernel, fa: f64, fb: f64) -> [[f64; WIDTH]; 2];

    /// `cells[q] += k·scaled[q]` for the `W·K` values of one kernel row.
    fn add_row(self, cells: &mut [f64], k: f64, scaled: &[f64]);

    /// `cells[q] += k₀·scaled₀[q] + k₁·scaled₁[q]`: one kernel row of two samples, each
    /// `scaled` zero outside its sample's `W·K` values.
    fn add_row_pair(self, cells: &mut [f64], k: [f64; 2], scaled: [&[f64]; 2]);

    /// `rows[d·stride + q] += k_d₀·scaled₀[q] + k_d₁·scaled₁[q]` for `d < RANK`: the same two
    /// samples' row into each of a run's rows, as [`add_row_pair`](Lanes::add_row_pair) would
    /// add it to each, the two rows' values loaded once for all.
    fn add_rows_pair(
        self,
        rows: &mut [f64],
        stride: usize,
        k: [[f64; 2]; RANK],
        scaled: [&[f64]; 2],
    );

    /// `cells[q] += Σ_d k_d·rows_d[q]`: a run's rows into one of the grid's.
    fn add_combination(self, cells: &mut [f64], k: [f64; RANK], rows: [&[f64]; RANK]);
}

/// [`Lanes`] in portable Rust.
#[derive(Clone, Copy)]
pub(super) struct Portable;

impl Lanes for Portable {
    #[inline(always)]
    fn locate<const K: usize>(
        self,
        plan: &Plan,
        points: &[(f64, f64, [f64; K])],
        located: &mut Vec<Located<K>>,
    ) {
        // A loop, not `extend` with a closure: a closure is compiled apart, without the
        // caller's target features, and `locate`'s `floor` became a call into libm.
        for &p in points {
            located.push(Located::new(plan, p));
        }
    }

    #[inline(always)]
    fn kernels(self, kernel: &Kernel, fa: f64, fb: f64) -> [[f64; WIDTH]; 2] {
        let t = [2.0 * fa - 1.0, 2.0 * fb - 1.0];
        let mut v = [kernel.coeffs[DEGREE]; 2];
        for c in kernel.coeffs[..DEGREE].iter().rev() {
            for (v, t) in v.iter_mut().zip(t) {
                for (v, c) in v.iter_mut().zip(c) {
                    *v = *v * t + c;
                }
            }
        }
        v
    }

    #[inline(always)]
    fn add_row(self, cells: &mut [f64], k: f64, scaled: &[f64]) {
        for (c, v) in cells.iter_mut().zip(scaled) {
            *c += k * v;
        }
    }

    #[inline(always)]
    fn add_row_pair(self, cells: &mut [f64], k: [f64; 2], [s0, s1]: [&[f64]; 2]) {
        for ((c, v0), v1) in cells.iter_mut().zip(s0).zip(s1) {
            *c += k[0] * v0 + k[1] * v1;
        }
    }

    #[inline(always)]
    fn add_rows_pair(
        self,
        rows: &mut [f64],
        stride: usize,
        k: [[f64; 2]; RANK],
        [s0, s1]: [&[f64]; 2],
    ) {
        for (q, (v0, v1)) in s0.iter().zip(s1).enumerate() {
            for (d, k) in k.iter().enumerate() {
                let c = &mut rows[d * stride + q];
                *c += k[0] * v0 + k[1] * v1;
            }
        }
    }

    #[inline(always)]
    fn add_combination(self, cells: &mut [f64], k: [f64; RANK], rows: [&[f64]; RANK]) {
        for (q, c) in cells.iter_mut().enumerate() {
            for d in 0..RANK {
                *c += k[d] * rows[d][q];
            }
        }
    }
}

/// A sample placed on the grid for spreading sample by sample: its first row and column, its
/// kernel along `a`, and its kernel along `b` times its weights between [`PAIR_SHIFT`] zero
/// cells on either side, so that a pair's second sample reads its row shifted by up to
/// [`PAIR_SHIFT`] cells without a copy.
struct Placed<const K: usize> {
    row: usize,
    first: usize,
    ka: [f64; WIDTH],
    padded: [[f64; K]; WIDTH + 2 * PAIR_SHIFT],
}

impl<const K: usize> Placed<K> {
    fn zero() -> Self {
        Placed {
            row: 0,
            first: 0,
            ka: [0.0; WIDTH],
            padded: [[0.0; K]; WIDTH + 2 * PAIR_SHIFT],
        }
    }

    /// Places sample `p`, in place (no copies of the arrays, and the zeros stay).
    #[inline(always)]
    fn place(&mut self, lanes: impl Lanes, plan: &Plan, p: &Located<K>) {
        let [ka, kb] = lanes.kernels(&plan.kernel, p.fa, p.fb);
        for (c, k) in self.padded[PAIR_SHIFT..].iter_mut().zip(kb) {
            for s in 0..K {
                c[s] = k * p.w[s];
            }
        }
        (self.row, self.first, self.ka) = (p.row, p.first, ka);
    }

    /// The kernel along `b` times the weights, starting `shift` cells into `len` cells.
    #[inline(always)]
    fn scaled(&self, shift: usize, len: usize) -> &[f64] {
        self.padded[PAIR_SHIFT - shift..PAIR_SHIFT - shift + len].as_flattened()
    }

    /// The kernel's rows `row, …, row + W − 1` (wrapped past the last of `rows`) with the
    /// kernel's value along `a` in each.
    #[inline(always)]
    fn rows(&self, rows: usize) -> impl Iterator<Item = (usize, usize)> + '_ {
        let unwrapped = (rows - self.row).min(WIDTH);
        (0..WIDTH).map(move |i| {
            let r = if i < unwrapped {
                self.row + i
            } else {
                i - unwrapped
            };
            (i, r)
        })
    }
}

/// Spreads a block sample by sample (module docs), in order.
#[inline(always)]
fn spread_samples<const K: usize, L: Lanes>(
    lanes: L,
    plan: &Plan,
    located: &[Located<K>],
    grid: &mut [[f64; K]],
    first_rows: &mut FirstRows,
) {
    let row_len = plan.row_len();
    // `slots[0]` is the next sample to spread when `placed`, `slots[1]` the one after it.
    let mut slots = [Placed::zero(), Placed::zero()];
    let mut placed = false;
    let mut samples = located.iter();
    loop {
        if !placed {
            let Some(p) = samples.next() else {
                return;
            };
            slots[0].place(lanes, plan, p);
            first_rows.mark(grid, row_len, p.row);
        }
        placed = false;
        let Some(q) = samples.next() else {
            spread_one(lanes, plan, &slots[0], grid);
            return;
        };
        slots[1].place(lanes, plan, q);
        first_rows.mark(grid, row_len, q.row);
        let [p, q] = &slots;
        let shift = q.first.wrapping_sub(p.first);
        if q.row != p.row || shift > PAIR_SHIFT {
            spread_one(lanes, plan, p, grid);
            slots.swap(0, 1);
            placed = true;
            continue;
        }
        let scaled = [p.scaled(0, PAIR_WIDTH), q.scaled(shift, PAIR_WIDTH)];
        for (i, r) in p.rows(plan.a.n) {
            let start = r * row_len + p.first;
            let cells = grid[start..start + PAIR_WIDTH].as_flattened_mut();
            lanes.add_row_pair(cells, [p.ka[i], q.ka[i]], scaled);
        }
    }
}

/// Adds one placed sample to `grid` (two dimensions).
#[inline(always)]
fn spread_one<const K: usize>(
    lanes: impl Lanes,
    plan: &Plan,
    p: &Placed<K>,
    grid: &mut [[f64; K]],
) {
    let (first, scaled) = (p.first, p.scaled(0, WIDTH));
    for (i, r) in p.rows(plan.a.n) {
        let start = r * plan.row_len() + first;
        lanes.add_row(
            grid[start..start + WIDTH].as_flattened_mut(),
            p.ka[i],
            scaled,
        );
    }
}

/// Spreads a block along `b` alone (`j_max = 0`, one row): the kernels of two consecutive
/// samples from one call of [`Lanes::kernels`], whose two chains are computed alike (each gives
/// the bits it gives for one sample), then each sample's `W` values times its weights added to
/// the row, in order.
#[inline(always)]
fn spread_row<const K: usize, L: Lanes>(
    lanes: L,
    plan: &Plan,
    points: &[(f64, f64, [f64; K])],
    grid: &mut [[f64; K]],
) {
    let mut scaled = [[0.0; K]; WIDTH];
    for pair in points.chunks(2) {
        let second = pair.get(1).unwrap_or(&pair[0]);
        let located = [plan.b.locate(pair[0].1), plan.b.locate(second.1)];
        let kernels = lanes.kernels(&plan.kernel, located[0].1, located[1].1);
        for ((p, (first, _)), kernel) in pair.iter().zip(located).zip(kernels) {
            for (c, k) in scaled.iter_mut().zip(kernel) {
                for s in 0..K {
                    c[s] = k * p.2[s];
                }
            }
            lanes.add_row(
                grid[first..first + WIDTH].as_flattened_mut(),
                1.0,
                scaled.as_flattened(),
            );
        }
    }
}

#[cfg(target_arch = "x86_64")]
pub(super) mod avx2 {
    //! [`Lanes`] in AVX2 and FMA instructions.

    use super::{
        DEGREE, Kernel, Lanes, Located, PAIR_WIDTH, Plan, RANK, SUBDIV, Spreading, WIDTH,
        spread_block,
    };
    use crate::nufft2d::Axis;
    use std::arch::x86_64::{
        __m256d, _CMP_EQ_OQ, _CMP_GE_OQ, _CMP_LE_OQ, _mm_storeu_si128, _mm256_add_pd,
        _mm256_and_pd, _mm256_cmp_pd, _mm256_cvttpd_epi32, _mm256_div_pd, _mm256_floor_pd,
        _mm256_fmadd_pd, _mm256_fmsub_pd, _mm256_fnmadd_pd, _mm256_loadu_pd, _mm256_max_pd,
        _mm256_min_pd, _mm256_movemask_pd, _mm256_mul_pd, _mm256_or_pd, _mm256_set_pd,
        _mm256_set1_pd, _mm256_setzero_pd, _mm256_storeu_pd, _mm256_sub_pd,
    };

    /// Grid steps up to which four samples are placed together: their integer parts, `− W/2 + 1`
    /// and wrapped by `n`, are exact in doubles (below 2^52) as [`Axis::locate`]'s are in
    /// integers.
    const VECTOR_STEPS: f64 = (1u64 << 50) as f64;
    /// Angles below which (other than zero) four samples are placed one by one: the product's
    /// rounding error that [`Axis::locate`] forms by Dekker's method and these lanes by one
    /// fused multiply-subtract is the same exact number only while it is not subnormal.
    const VECTOR_TINY: f64 = 1e-150;

    /// [`Axis::locate`] of four angles: the first grid index (as a whole double) and the
    /// fraction of each, the same bits; `None` when one is beyond [`VECTOR_STEPS`], tiny
    /// ([`VECTOR_TINY`]) or not finite.
    ///
    /// # Safety
    /// The CPU has AVX2 and FMA.
    #[inline(always)]
    unsafe fn locate4(axis: &Axis, x: __m256d) -> Option<(__m256d, __m256d)> {
        // SAFETY: the caller's.
        unsafe {
            let p = _mm256_mul_pd(x, _mm256_set1_pd(axis.scale.0));
            let abs = |v| _mm256_and_pd(v, _mm256_set1_pd(f64::from_bits(!(1 << 63))));
            let (ax, ap) = (abs(x), abs(p));
            let in_range = _mm256_and_pd(
                _mm256_cmp_pd::<_CMP_LE_OQ>(ap, _mm256_set1_pd(VECTOR_STEPS)),
                _mm256_or_pd(
                    _mm256_cmp_pd::<_CMP_GE_OQ>(ax, _mm256_set1_pd(VECTOR_TINY)),
                    _mm256_cmp_pd::<_CMP_EQ_OQ>(ax, _mm256_setzero_pd()),
                ),
            );
            if _mm256_movemask_pd(in_range) != 0b1111 {
                return None;
            }
            // `a·b − p` exactly, as Dekker's product forms it.
            let error = _mm256_fmsub_pd(x, _mm256_set1_pd(axis.scale.0), p);
            let e = _mm256_add_pd(error, _mm256_mul_pd(x, _mm256_set1_pd(axis.scale.1)));
            let whole = _mm256_floor_pd(p);
            // `clamp(0, 1)`: `max` and `min` return their second operand, the fraction, unless
            // it is beyond the first (a −0 stays −0, as `clamp` leaves it).
            let frac = _mm256_min_pd(
                _mm256_set1_pd(1.0),
                _mm256_max_pd(
                    _mm256_setzero_pd(),
                    _mm256_add_pd(_mm256_sub_pd(p, whole), e),
                ),
            );
            let first = _mm256_sub_pd(whole, _mm256_set1_pd((WIDTH / 2 - 1) as f64));
            // `first.rem_euclid(n)`: the quotient's floor is exact below 2^52, and so is
            // `first − q·n`, a whole number in `0..n`.
            let n = _mm256_set1_pd(axis.n as f64);
            let q = _mm256_floor_pd(_mm256_div_pd(first, n));
            Some((_mm256_fnmadd_pd(q, n, first), frac))
        }
    }

    /// The lanes of a vector of whole numbers in `0..2^31` as indices.
    ///
    /// # Safety
    /// The CPU has AVX.
    #[inline(always)]
    unsafe fn indices(v: __m256d) -> [usize; 4] {
        let mut out = [0i32; 4];
        // SAFETY: the caller's; the store covers the 16 bytes of `out`.
        unsafe { _mm_storeu_si128(out.as_mut_ptr().cast(), _mm256_cvttpd_epi32(v)) };
        out.map(|i| i as usize)
    }

    /// The lanes of a vector.
    ///
    /// # Safety
    /// The CPU has AVX.
    #[inline(always)]
    unsafe fn lanes(v: __m256d) -> [f64; 4] {
        let mut out = [0.0; 4];
        // SAFETY: the caller's; the store covers the 32 bytes of `out`.
        unsafe { _mm256_storeu_pd(out.as_mut_ptr(), v) };
        out
    }

    /// Proof that the CPU has AVX2 and FMA: made only by [`Avx2::detect`].
    #[derive(Clone, Copy)]
    pub(in crate::nufft2d) struct Avx2(());

    const _: () = assert!(
        WIDTH % 4 == 0 && PAIR_WIDTH % 4 == 0,
        "rows are whole vectors of 4 lanes"
    );

    impl Avx2 {
        /// `Some` on a CPU with AVX2 and FMA.
        pub(in crate::nufft2d) fn detect() -> Option<Self> {
            (std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma"))
            .then_some(Avx2(()))
        }

        /// [`spread_block`] compiled with AVX2 and FMA enabled.
        pub(super) fn spread_block<const K: usize>(
            self,
            plan: &Plan,
            points: &[(f64, f64, [f64; K])],
            last: bool,
            spreading: &mut Spreading<K>,
        ) {
            #[target_feature(enable = "avx2,fma")]
            unsafe fn run<const K: usize>(
                lanes: Avx2,
                plan: &Plan,
                points: &[(f64, f64, [f64; K])],
                last: bool,
                spreading: &mut Spreading<K>,
            ) {
                spread_block(lanes, plan, points, last, spreading);
            }
            // SAFETY: `self` exists only on a CPU with AVX2 and FMA.
            unsafe { run(self, plan, points, last, spreading) }
        }
    }

    impl Lanes for Avx2 {
        /// Four samples at a time (the scalar form took a quarter of `calib tdr`'s spreading),
        /// the same bits; a group with an angle the vector form does not hold exactly, and the
        /// last few, one by one.
        #[inline(always)]
        fn locate<const K: usize>(
            self,
            plan: &Plan,
            points: &[(f64, f64, [f64; K])],
            located: &mut Vec<Located<K>>,
        ) {
            let mut groups = points.chunks_exact(4);
            for g in &mut groups {
                // SAFETY: `self` proves AVX2 and FMA.
                let placed = unsafe {
                    let a = _mm256_set_pd(g[3].0, g[2].0, g[1].0, g[0].0);
                    let b = _mm256_set_pd(g[3].1, g[2].1, g[1].1, g[0].1);
                    match (locate4(&plan.a, a), locate4(&plan.b, b)) {
                        (Some((row, fa)), Some((first, fb))) => {
                            // `Located::new`'s sub-interval and place in it, the same operations.
                            let x = _mm256_mul_pd(fa, _mm256_set1_pd(SUBDIV as f64));
                            let sub = _mm256_min_pd(
                                _mm256_floor_pd(x),
                                _mm256_set1_pd((SUBDIV - 1) as f64),
                            );
                            let u = _mm256_sub_pd(
                                _mm256_mul_pd(_mm256_set1_pd(2.0), _mm256_sub_pd(x, sub)),
                                _mm256_set1_pd(1.0),
                            );
                            Some((
                                indices(row),
                                lanes(fa),
                                indices(sub),
                                lanes(u),
                                indices(first),
                                lanes(fb),
                            ))
                        }
                        _ => None,
                    }
                };
                match placed {
                    Some((row, fa, sub, u, first, fb)) => {
                        for (l, p) in g.iter().enumerate() {
                            located.push(Located {
                                row: row[l],
                                fa: fa[l],
                                sub: sub[l],
                                u: u[l],
                                first: first[l],
                                fb: fb[l],
                                w: p.2,
                            });
                        }
                    }
                    None => super::Portable.locate(plan, g, located),
                }
            }
            super::Portable.locate(plan, groups.remainder(), located);
        }

        #[inline(always)]
        fn kernels(self, kernel: &Kernel, fa: f64, fb: f64) -> [[f64; WIDTH]; 2] {
            let mut out = [[0.0; WIDTH]; 2];
            // SAFETY: `self` proves AVX2 and FMA; every load and store covers 4 of an array's
            // `WIDTH` values at a multiple of 4 below `WIDTH`.
            unsafe {
                let t = [
                    _mm256_set1_pd(2.0 * fa - 1.0),
                    _mm256_set1_pd(2.0 * fb - 1.0),
                ];
                let top = kernel.coeffs[DEGREE].as_ptr();
                let v = [0, 1, 2, 3].map(|l| _mm256_loadu_pd(top.add(4 * l)));
                let mut v = [v, v];
                for c in kernel.coeffs[..DEGREE].iter().rev() {
                    for (v, t) in v.iter_mut().zip(t) {
                        for (l, v) in v.iter_mut().enumerate() {
                            *v = _mm256_fmadd_pd(*v, t, _mm256_loadu_pd(c.as_ptr().add(4 * l)));
                        }
                    }
                }
                for (o, v) in out.iter_mut().zip(v) {
                    for (l, v) in v.into_iter().enumerate() {
                        _mm256_storeu_pd(o.as_mut_ptr().add(4 * l), v);
                    }
                }
            }
            out
        }

        #[inline(always)]
        fn add_row(self, cells: &mut [f64], k: f64, scaled: &[f64]) {
            assert!(cells.len() == scaled.len() && cells.len() % 4 == 0);
            // SAFETY: `self` proves AVX2 and FMA; each load and store covers `q..q + 4` of
            // slices of the same length, a multiple of 4.
            unsafe {
                let k = _mm256_set1_pd(k);
                for q in (0..cells.len()).step_by(4) {
                    let p = cells.as_mut_ptr().add(q);
                    let v = _mm256_loadu_pd(scaled.as_ptr().add(q));
                    _mm256_storeu_pd(p, _mm256_fmadd_pd(k, v, _mm256_loadu_pd(p)));
                }
            }
        }

        #[inline(always)]
        fn add_row_pair(self, cells: &mut [f64], k: [f64; 2], [s0, s1]: [&[f64]; 2]) {
            assert!(cells.len() == s0.len() && cells.len() == s1.len() && cells.len() % 4 == 0);
            // SAFETY: as in `add_row`.
            unsafe {
                let (k0, k1) = (_mm256_set1_pd(k[0]), _mm256_set1_pd(k[1]));
                for q in (0..cells.len()).step_by(4) {
                    let p = cells.as_mut_ptr().add(q);
                    let v0 = _mm256_loadu_pd(s0.as_ptr().add(q));
                    let v1 = _mm256_loadu_pd(s1.as_ptr().add(q));
                    let c = _mm256_fmadd_pd(k0, v0, _mm256_loadu_pd(p));
                    _mm256_storeu_pd(p, _mm256_fmadd_pd(k1, v1, c));
                }
            }
        }

        #[inline(always)]
        fn add_rows_pair(
            self,
            rows: &mut [f64],
            stride: usize,
            k: [[f64; 2]; RANK],
            [s0, s1]: [&[f64]; 2],
        ) {
            let len = s0.len();
            assert!(s1.len() == len && len % 4 == 0 && rows.len() >= (RANK - 1) * stride + len);
            // SAFETY: `self` proves AVX2 and FMA; each load and store covers `q..q + 4` below
            // `len` of `s0`, `s1` and of `rows` from `d·stride`, all within the slices.
            unsafe {
                let mut k0 = [_mm256_setzero_pd(); RANK];
                let mut k1 = [_mm256_setzero_pd(); RANK];
                for d in 0..RANK {
                    k0[d] = _mm256_set1_pd(k[d][0]);
                    k1[d] = _mm256_set1_pd(k[d][1]);
                }
                for q in (0..len).step_by(4) {
                    let v0 = _mm256_loadu_pd(s0.as_ptr().add(q));
                    let v1 = _mm256_loadu_pd(s1.as_ptr().add(q));
                    for d in 0..RANK {
                        let p = rows.as_mut_ptr().add(d * stride + q);
                        let c = _mm256_fmadd_pd(k0[d], v0, _mm256_loadu_pd(p));
                        _mm256_storeu_pd(p, _mm256_fmadd_pd(k1[d], v1, c));
                    }
                }
            }
        }

        #[inline(always)]
        fn add_combination(self, cells: &mut [f64], k: [f64; RANK], rows: [&[f64]; RANK]) {
            let len = cells.len();
            assert!(rows.iter().all(|r| r.len() == len));
            let whole = len / 4 * 4;
            // SAFETY: `self` proves AVX2 and FMA; each load and store covers `q..q + 4` below
            // `whole ≤ len`, the length of every slice.
            unsafe {
                let mut kv = [_mm256_setzero_pd(); RANK];
                for d in 0..RANK {
                    kv[d] = _mm256_set1_pd(k[d]);
                }
                for q in (0..whole).step_by(4) {
                    let p = cells.as_mut_ptr().add(q);
                    let mut c = _mm256_loadu_pd(p);
                    for d in 0..RANK {
                        c = _mm256_fmadd_pd(kv[d], _mm256_loadu_pd(rows[d].as_ptr().add(q)), c);
                    }
                    _mm256_storeu_pd(p, c);
                }
            }
            for q in whole..len {
                for d in 0..RANK {
                    cells[q] += k[d] * rows[d][q];
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The grid of `points` spread a block at a time with `lanes`.
    fn grid<L: Lanes>(lanes: L, plan: &Plan, points: &[(f64, f64, [f64; 2])]) -> Vec<[f64; 2]> {
        let mut spreading = Spreading {
            grid: vec![[0.0; 2]; plan.rows() * plan.row_len()],
            first_rows: FirstRows::new(plan.rows(), true),
            located: Vec::new(),
            run: Run::new(plan),
        };
        let blocks = points.chunks(BLOCK).count();
        for (b, block) in points.chunks(BLOCK).enumerate() {
            spread_block(lanes, plan, block, b + 1 == blocks, &mut spreading);
        }
        spreading.grid
    }

    /// A located sample's fields as bits, to compare to the bit.
    fn bits<const K: usize>(l: &Located<K>) -> [u64; 6] {
        [
            l.row as u64,
            l.fa.to_bits(),
            l.sub as u64,
            l.u.to_bits(),
            l.first as u64,
            l.fb.to_bits(),
        ]
    }

    #[test]
    #[cfg(target_arch = "x86_64")]
    fn avx2_lanes_locate_as_the_scalar_form() {
        let Some(avx2) = avx2::Avx2::detect() else {
            return;
        };
        // Angles of every size and sign, exact grid points and their neighbours, thousands of
        // turns, tiny and subnormal ones, zeros of both signs, non-finite and huge ones (groups
        // with one of those go one by one), in groups of four and a remainder.
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut uniform = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut angles = vec![0.0, -0.0, 1e-300, -5e-324, 1e-160, 1e-140, f64::NAN];
        angles.extend([
            f64::INFINITY,
            -1e300,
            1e17,
            -1e15,
            3.0e14,
            1e-3,
            std::f64::consts::PI,
        ]);
        for k in -40..40 {
            let step = std::f64::consts::TAU / 4096.0;
            let x = k as f64 * step;
            angles.extend([x, x.next_up(), x.next_down()]);
        }
        for _ in 0..20_000 {
            let scale = 10f64.powf(-6.0 + 12.0 * uniform());
            angles.push((2.0 * uniform() - 1.0) * scale);
        }
        for (j_max, m_max) in [(4, 40), (127, 1016), (113, 1000), (1, 5000)] {
            let plan = Plan::new(j_max, m_max);
            for shift in 0..4 {
                let points: Vec<(f64, f64, [f64; 2])> = angles[shift..]
                    .iter()
                    .zip(angles.iter().rev())
                    .map(|(&a, &b)| (a.abs().min(3.2), b, [1.0, a]))
                    .collect();
                let (mut scalar, mut vector) = (Vec::new(), Vec::new());
                Portable.locate(&plan, &points, &mut scalar);
                avx2.locate(&plan, &points, &mut vector);
                assert_eq!(scalar.len(), vector.len());
                for (i, (s, v)) in scalar.iter().zip(&vector).enumerate() {
                    assert_eq!(bits(s), bits(v), "point {i}: {:?}", points[i]);
                }
            }
        }
    }

    #[test]
    #[cfg(target_arch = "x86_64")]
    fn portable_and_avx2_lanes_spread_alike() {
        let Some(avx2) = avx2::Avx2::detect() else {
            return;
        };
        // Time-ordered samples moving slowly along `a` (by runs: ~100 per sub-interval), then
        // the same shuffled (sample by sample): both ways on both kinds of lanes.
        let n = 4 * BLOCK;
        let mut points: Vec<(f64, f64, [f64; 2])> = (0..n)
            .map(|i| {
                let tau = 2.0 * (i as f64 + 0.5) / n as f64 - 1.0;
                (1.0 + 0.005 * tau, 0.3 + 0.001 * i as f64, [1.0, tau])
            })
            .collect();
        let shuffled: Vec<_> = (0..n).map(|i| points[(i * 389) % n]).collect();
        points.extend(shuffled);
        let plan = Plan::new(4, 40);
        let by_runs: Vec<bool> = points
            .chunks(BLOCK)
            .map(|block| {
                let located: Vec<_> = block.iter().map(|&p| Located::new(&plan, p)).collect();
                runs_pay(&plan, &located)
            })
            .collect();
        assert_eq!(
            by_runs,
            [true, true, true, true, false, false, false, false]
        );
        let (a, b) = (grid(Portable, &plan, &points), grid(avx2, &plan, &points));
        let peak = a.iter().flatten().fold(0.0_f64, |m, v| m.max(v.abs()));
        let worst = a
            .iter()
            .flatten()
            .zip(b.iter().flatten())
            .fold(0.0_f64, |m, (x, y)| m.max((x - y).abs()));
        // Only the roundings of separate and fused multiply-adds differ.
        assert!(peak > 1.0 && worst < 1e-14 * peak, "{worst:e} of {peak}"); // measured 3.4e-16
    }
}
