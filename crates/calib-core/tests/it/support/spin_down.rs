//! The samples of `calib tdr`'s use case of `calib_core::nufft2d`, shared by its bench and its
//! full-size test.

use std::f64::consts::TAU;

/// The use case's samples `(a_n, b_n, [1, τ_n])`: `τ_n` the normalized time, evenly spaced over
/// [−1, 1], and `b_n` a decelerating phase over 400 turns with a SplitMix64 jitter of ±0.5 µrad.
pub fn spin_down(len: usize) -> Vec<(f64, f64, [f64; 2])> {
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
