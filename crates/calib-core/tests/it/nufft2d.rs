//! The use case of `calib_core::nufft2d` at full size, run by hand (`#[ignore]`d: it takes
//! ~1 GB and seconds):
//!
//! ```text
//! cargo test --release -p calib-core --test it nufft2d:: -- --ignored --nocapture
//! ```
//!
//! 10⁷ time-ordered samples of a spin-down, K = 2 weight sets, `j_max = 127`, `m_max = 1016`
//! (then along `b` alone, `j_max = 0`, with one of the weight sets):
//! `a_n = acos(τ_n)` with `τ_n` the normalized time from −1 to 1 (so that `cos(j·a_n)` is the
//! Chebyshev polynomial `T_j(τ_n)`), `b_n` a decelerating phase over 400 turns.

use std::time::Instant;

use calib_core::nufft2d::type1;

use crate::support::spin_down;

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
    // Along `b` alone with one weight set (the 1-D path).
    let start = Instant::now();
    let [r] = type1(pts.len(), 0, 1016, |n| (0.0, pts[n].1, [pts[n].2[1]]));
    eprintln!(
        "type1 along b alone (K = 1) in {:.3} s",
        start.elapsed().as_secs_f64()
    );
    assert!((r.at(0, 0).re - sum_tau).abs() <= 1e-13 * l1);
}
