//! The use case of `calib_core::nufft2d` at full size, run by hand (`#[ignore]`d: it takes
//! ~1 GB and seconds):
//!
//! ```text
//! cargo test --release -p calib-core --test nufft2d -- --ignored --nocapture
//! ```
//!
//! 10⁷ time-ordered samples of a spin-down, K = 2 weight sets, `j_max = 127`, `m_max = 1016`:
//! `a_n = acos(τ_n)` with `τ_n` the normalized time from −1 to 1 (so that `cos(j·a_n)` is the
//! Chebyshev polynomial `T_j(τ_n)`), `b_n` a decelerating phase over 400 turns.

use std::f64::consts::TAU;
use std::time::Instant;

use calib_core::nufft2d::type1;

/// The use case's samples `(a_n, b_n, [1, τ_n])`: `τ_n` the normalized time, evenly spaced over
/// [−1, 1], and a SplitMix64 jitter of ±0.5 µrad on `b_n`.
fn spin_down(len: usize) -> Vec<(f64, f64, [f64; 2])> {
    let mut state = 0x5eed_u64;
    let mut uniform = move || {
        state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..len)
        .map(|n| {
            let u = (n as f64 + 0.5) / len as f64;
            let tau = 2.0 * u - 1.0;
            let b = TAU * 400.0 * (1.0 - (1.0 - u) * (1.0 - u)) + 1e-6 * (uniform() - 0.5);
            (tau.acos(), b, [1.0, tau])
        })
        .collect()
}

#[test]
#[ignore = "full size (10⁷ samples): run by hand with --release"]
#[allow(clippy::print_stderr, reason = "the figures are the point of this run")]
fn ten_million_samples() {
    let start = Instant::now();
    let pts = spin_down(10_000_000);
    eprintln!(
        "samples generated in {:.3} s",
        start.elapsed().as_secs_f64()
    );
    let start = Instant::now();
    let [s0, s1] = type1(pts.len(), 127, 1016, |n| pts[n]);
    eprintln!("type1 in {:.3} s", start.elapsed().as_secs_f64());
    // F_0(0, 0) = Σ 1 = len; F_1(0, 0) = Σ τ_n, within the accuracy bound 1e-13·Σ|w|.
    assert!((s0.at(0, 0).re - 1e7).abs() <= 1e-13 * 1e7);
    let sum_tau: f64 = pts.iter().map(|p| p.2[1]).sum();
    let l1: f64 = pts.iter().map(|p| p.2[1].abs()).sum();
    assert!((s1.at(0, 0).re - sum_tau).abs() <= 1e-13 * l1);
}
