//! The Cholesky factor of the normal equations, in panels of columns on the rayon pool, with
//! `nalgebra`'s arithmetic.
//!
//! `nalgebra`'s `cholesky()` is left-looking: column `j` of `L` (`G = LLᵀ`) is
//!
//! ```text
//! L[i][j] = (G[i][j] − Σ_{k<j} L[j][k]·L[i][k]) / L[j][j],   L[j][j] = √(G[j][j] − Σ_{k<j} L[j][k]²),
//! ```
//!
//! each product added to `G[i][j]` as `−L[j][k]` times `L[i][k]`, in increasing `k`, on one
//! thread. For a fit of a thousand columns (the screening of every order to 500) it streams the
//! `n³/6` products' columns through the cache once per column of `L`: 0.08 s, one core. Here
//! the same sums are formed in the same order — so the factor has the same bits — but a panel of
//! [`PANEL`] columns takes the products of all the columns left of it together, a tile of
//! [`ROWS`] rows at a time held in registers, the tiles on the threads rayon has; then the panel's
//! own columns are factored as `nalgebra` does. Any order of the work that keeps each element's
//! sum in increasing `k` gives the same numbers: no fused multiply-add is used.

use nalgebra::{Cholesky, DMatrix, Dyn};
use rayon::prelude::*;

/// Columns factored together: their products with the columns before them share each load.
const PANEL: usize = 32;
/// Rows of a panel's tile: with [`GROUP`] columns, 32 sums in eight of AVX's sixteen registers.
const ROWS: usize = 8;
/// Columns of a tile whose sums are held in registers together.
const GROUP: usize = 4;
/// Tiles a task takes at least (smaller tasks cost more to hand out than they save).
const MIN_TILES: usize = 16;

/// `G = LLᵀ` of the symmetric `g` (only its lower triangle read), `None` where `G` is not
/// positive definite: the same bits and the same `None`s as `g.cholesky()`.
pub(super) fn factor(g: DMatrix<f64>) -> Option<Cholesky<f64, Dyn>> {
    let n = g.nrows();
    assert_eq!(n, g.ncols(), "a Cholesky factor needs a square matrix");
    let mut a = g;
    let s = a.as_mut_slice();
    for j0 in (0..n).step_by(PANEL) {
        let width = PANEL.min(n - j0);
        if j0 > 0 {
            update_panel(s, n, j0, width);
        }
        factor_panel(s, n, j0, width)?;
    }
    Some(Cholesky::pack_dirty(a))
}

/// The columns left of a panel, as its tiles read them.
struct Left<'a> {
    /// The matrix being factored, column-major; its columns `0..k_end` are `L`'s.
    s: &'a [f64],
    n: usize,
    /// `−L[j][k]` for the panel's rows `j = j0 + jj`, at `k·width + jj`.
    neg: Vec<f64>,
    width: usize,
    /// The panel's first column: the columns before it are `L`'s.
    k_end: usize,
}

/// Adds to the panel of columns `j0..j0 + width`, at rows `i ≥ j` (column `j`'s), the products
/// `−L[j][k]·L[i][k]` of every column `k < j0`, in increasing `k`.
fn update_panel(s: &mut [f64], n: usize, j0: usize, width: usize) {
    // The panel's rows j0..n, copied tile by tile (tile t, column jj, row r at
    // t·ROWS·width + jj·ROWS + r) so that the tasks own disjoint tiles.
    let mut panel = vec![0.0; (n - j0).div_ceil(ROWS) * ROWS * width];
    {
        let mut neg = vec![0.0; j0 * width];
        for k in 0..j0 {
            for jj in 0..width {
                neg[k * width + jj] = -s[k * n + j0 + jj];
            }
        }
        let left = Left {
            s,
            n,
            neg,
            width,
            k_end: j0,
        };
        panel
            .par_chunks_mut(ROWS * width)
            .with_min_len(MIN_TILES)
            .enumerate()
            .for_each(|(t, tile)| {
                let row0 = j0 + t * ROWS;
                let count = ROWS.min(n - row0);
                for jj in 0..width {
                    let column = &left.s[(j0 + jj) * n + row0..][..count];
                    tile[jj * ROWS..][..count].copy_from_slice(column);
                }
                if count == ROWS {
                    left.products(tile, row0);
                } else {
                    left.products_partial(tile, row0, count);
                }
            });
    }
    // Back at the rows on or below each column's diagonal (the rest is the input's, as
    // nalgebra leaves it).
    for jj in 0..width {
        let j = j0 + jj;
        for i in j..n {
            let (t, r) = ((i - j0) / ROWS, (i - j0) % ROWS);
            s[j * n + i] = panel[t * ROWS * width + jj * ROWS + r];
        }
    }
}

impl Left<'_> {
    /// A whole tile's products (its rows from `row0`), with AVX where the CPU has it.
    fn products(&self, tile: &mut [f64], row0: usize) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx") {
            // SAFETY: the CPU has AVX.
            let done = unsafe { self.products_avx(tile, row0) };
            return self.products_from(tile, row0, done);
        }
        self.products_from(tile, row0, 0);
    }

    /// The sums of the tile's columns from `jj` on, [`ROWS`] rows of [`GROUP`] columns held
    /// together while `k` runs.
    fn products_from(&self, tile: &mut [f64], row0: usize, mut jj: usize) {
        let (s, n, width) = (self.s, self.n, self.width);
        while jj < width {
            let group = GROUP.min(width - jj);
            let mut sums = [[0.0; ROWS]; GROUP];
            for (q, sum) in sums.iter_mut().enumerate().take(group) {
                sum.copy_from_slice(&tile[(jj + q) * ROWS..][..ROWS]);
            }
            for k in 0..self.k_end {
                let x = &s[k * n + row0..][..ROWS];
                let f = &self.neg[k * width + jj..][..group];
                for (sum, &f) in sums.iter_mut().zip(f) {
                    for (sum, &x) in sum.iter_mut().zip(x) {
                        *sum += f * x;
                    }
                }
            }
            for (q, sum) in sums.iter().enumerate().take(group) {
                tile[(jj + q) * ROWS..][..ROWS].copy_from_slice(sum);
            }
            jj += group;
        }
    }

    /// [`products_from`](Self::products_from) for the tile's whole groups of [`GROUP`]
    /// columns, their 4 × 8 sums in eight 256-bit registers: a multiplication and an addition
    /// per four products (no fused multiply-add: the same bits). Returns the columns done.
    ///
    /// # Safety
    /// The CPU must have AVX.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    unsafe fn products_avx(&self, tile: &mut [f64], row0: usize) -> usize {
        use std::arch::x86_64::{
            __m256d, _mm256_add_pd, _mm256_loadu_pd, _mm256_mul_pd, _mm256_set1_pd,
            _mm256_setzero_pd, _mm256_storeu_pd,
        };
        const HALF: usize = ROWS / 2;
        let (s, n, width) = (self.s, self.n, self.width);
        let mut jj = 0;
        while jj + GROUP <= width {
            let block = &mut tile[jj * ROWS..(jj + GROUP) * ROWS];
            // SAFETY (all loads and stores): each reads or writes four values inside a slice
            // whose length was checked by indexing.
            let mut sums: [__m256d; 2 * GROUP] = [_mm256_setzero_pd(); 2 * GROUP];
            for (v, sum) in sums.iter_mut().enumerate() {
                *sum = unsafe { _mm256_loadu_pd(block[v * HALF..][..HALF].as_ptr()) };
            }
            for k in 0..self.k_end {
                let x = &s[k * n + row0..][..ROWS];
                let (x0, x1) = unsafe {
                    (
                        _mm256_loadu_pd(x.as_ptr()),
                        _mm256_loadu_pd(x[HALF..].as_ptr()),
                    )
                };
                let f = &self.neg[k * width + jj..][..GROUP];
                for q in 0..GROUP {
                    let fq = _mm256_set1_pd(f[q]);
                    sums[2 * q] = _mm256_add_pd(sums[2 * q], _mm256_mul_pd(fq, x0));
                    sums[2 * q + 1] = _mm256_add_pd(sums[2 * q + 1], _mm256_mul_pd(fq, x1));
                }
            }
            for (v, sum) in sums.iter().enumerate() {
                unsafe { _mm256_storeu_pd(block[v * HALF..][..HALF].as_mut_ptr(), *sum) };
            }
            jj += GROUP;
        }
        jj
    }

    /// The last tile's products, its `count < ROWS` rows from `row0` one at a time.
    fn products_partial(&self, tile: &mut [f64], row0: usize, count: usize) {
        let (s, n, width) = (self.s, self.n, self.width);
        for jj in 0..width {
            for r in 0..count {
                let mut sum = tile[jj * ROWS + r];
                for k in 0..self.k_end {
                    sum += self.neg[k * width + jj] * s[k * n + row0 + r];
                }
                tile[jj * ROWS + r] = sum;
            }
        }
    }
}

/// The panel's own columns as `nalgebra` factors a column: the products of the panel's columns
/// before it (those left of the panel are in already), the square root of the diagonal, the
/// division below it. `None` at a diagonal that is not positive.
fn factor_panel(s: &mut [f64], n: usize, j0: usize, width: usize) -> Option<()> {
    for j in j0..j0 + width {
        let (left, right) = s.split_at_mut(j * n);
        let column = &mut right[j..n];
        for k in j0..j {
            let f = -left[k * n + j];
            for (c, x) in column.iter_mut().zip(&left[k * n + j..k * n + n]) {
                *c += f * x;
            }
        }
        // nalgebra's `sqrt_denom`: no factor where the diagonal is zero or `try_sqrt` fails
        // (negative or NaN).
        let diagonal = column[0];
        if diagonal.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
        let root = diagonal.sqrt();
        column[0] = root;
        for c in &mut column[1..] {
            *c /= root;
        }
    }
    Some(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A symmetric positive definite matrix of size `n`, far from diagonal (the normal
    /// equations' Gram matrices are dense), with a condition number around `10⁶`.
    fn gram(n: usize, seed: u64) -> DMatrix<f64> {
        let mut state = seed;
        let mut next = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let m = n + 3;
        let a = DMatrix::from_fn(m, n, |i, j| next() + if i == j { 1e-3 } else { 0.0 });
        a.transpose() * a
    }

    #[test]
    fn the_factor_is_nalgebras_to_the_bit_on_any_threads() {
        // Sizes around the panel, the tile and the group, and a screening-sized one.
        let sizes = [1, 2, 5, 8, 9, 31, 32, 33, 40, 64, 71, 150, 301];
        for threads in [1, 3] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("a pool");
            for (s, &n) in sizes.iter().enumerate() {
                let g = gram(n, s as u64 + 1);
                let ours = pool
                    .install(|| factor(g.clone()))
                    .expect("positive definite");
                let theirs = g.clone().cholesky().expect("positive definite");
                let same = ours
                    .l_dirty()
                    .iter()
                    .zip(theirs.l_dirty().iter())
                    .all(|(a, b)| a.to_bits() == b.to_bits());
                assert!(same, "n = {n} on {threads} threads");
            }
        }
    }

    #[test]
    fn a_tile_without_avx_is_the_tile_with_it() {
        // The portable loop (CPUs without AVX) against the dispatched one, to the bit, on a
        // panel of a whole group and a part of one.
        let (n, j0) = (48, 32);
        let g = gram(n, 5);
        for width in [4, 7] {
            let neg = (0..j0 * width)
                .map(|i| -g.as_slice()[i * 7 % (n * n)])
                .collect();
            let left = Left {
                s: g.as_slice(),
                n,
                neg,
                width,
                k_end: j0,
            };
            let start: Vec<f64> = (0..ROWS * width).map(|i| i as f64 * 0.37).collect();
            let (mut dispatched, mut portable) = (start.clone(), start);
            left.products(&mut dispatched, j0 + ROWS);
            left.products_from(&mut portable, j0 + ROWS, 0);
            let same = dispatched
                .iter()
                .zip(&portable)
                .all(|(a, b)| a.to_bits() == b.to_bits());
            assert!(same, "width {width}");
        }
    }

    #[test]
    fn a_matrix_that_is_not_positive_definite_has_no_factor_as_with_nalgebra() {
        for n in [3, 40, 100] {
            let mut g = gram(n, 9);
            // A negative pivot at the last column, past the first panel where n > 32.
            g[(n - 1, n - 1)] = -1.0;
            assert!(factor(g.clone()).is_none());
            assert!(g.cholesky().is_none());
            let mut g = gram(n, 10);
            g[(n / 2, n / 2)] = f64::NAN;
            assert!(factor(g.clone()).is_none());
            assert!(g.cholesky().is_none());
        }
    }
}
