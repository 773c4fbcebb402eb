//! Chebyshev series `f(τ) = Σ_j c_j T_j(τ)` on `[−1, 1]`: the motion's model and the smooth
//! weights of the fit's columns.

use std::f64::consts::PI;

/// `f(τ)` at `L` points side by side by Clenshaw's recurrence
/// `b_j = c_j + 2τ·b_{j+1} − b_{j+2}`, `f = c_0 + τ·b_1 − b_2`: the lanes' independent chains keep
/// the core busy where one chain would wait on each step. On x86-64 CPUs with AVX (detected at
/// run time) the same operations run four lanes to an instruction, and the same bits: 16 lanes
/// of a degree-30 series took half the time of SSE2's two to an instruction (each step waits on
/// the last, so the wider vectors keep twice as many chains going).
pub(super) fn chebyshev_lanes<const L: usize>(c: &[f64], tau: &[f64; L]) -> [f64; L] {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx") {
        #[target_feature(enable = "avx")]
        unsafe fn avx<const L: usize>(c: &[f64], tau: &[f64; L]) -> [f64; L] {
            clenshaw(c, tau)
        }
        // SAFETY: the CPU has AVX.
        return unsafe { avx(c, tau) };
    }
    clenshaw(c, tau)
}

#[inline(always)]
fn clenshaw<const L: usize>(c: &[f64], tau: &[f64; L]) -> [f64; L] {
    let (mut b1, mut b2) = ([0.0; L], [0.0; L]);
    for &cj in c.iter().skip(1).rev() {
        for l in 0..L {
            (b1[l], b2[l]) = (cj + 2.0 * tau[l] * b1[l] - b2[l], b1[l]);
        }
    }
    let c0 = c.first().copied().unwrap_or(0.0);
    // A loop, not `array::from_fn`: its closure is compiled apart, without the caller's AVX.
    let mut f = [0.0; L];
    for l in 0..L {
        f[l] = c0 + tau[l] * b1[l] - b2[l];
    }
    f
}

/// The `n` coefficients of the Chebyshev interpolant of `f` at the `n` Chebyshev points
/// `τ_k = cos(π(k + ½)/n)`: `c_l = (2/n)·Σ_k f(τ_k)·cos(πl(k + ½)/n)`, `c_0` halved. For an
/// analytic `f` they equal its Chebyshev series' to within the series' tail beyond `n`.
pub(super) fn chebyshev_coefficients(f: impl Fn(f64) -> f64, n: usize) -> Vec<f64> {
    let values: Vec<f64> = (0..n)
        .map(|k| f((PI * (k as f64 + 0.5) / n as f64).cos()))
        .collect();
    (0..n)
        .map(|l| {
            let s: f64 = values
                .iter()
                .enumerate()
                .map(|(k, v)| v * (PI * l as f64 * (k as f64 + 0.5) / n as f64).cos())
                .sum();
            let c = 2.0 * s / n as f64;
            if l == 0 { 0.5 * c } else { c }
        })
        .collect()
}

/// `(f, f′, f″)` of `f(τ) = Σ c_j T_j(τ)` by the recurrences `T_{j+1} = 2τT_j − T_{j−1}`,
/// `T′_{j+1} = 2T_j + 2τT′_j − T′_{j−1}`, `T″_{j+1} = 4T′_j + 2τT″_j − T″_{j−1}`.
pub(super) fn chebyshev_with_derivatives(c: &[f64], tau: f64) -> (f64, f64, f64) {
    let (mut t0, mut t1) = (1.0, tau);
    let (mut d0, mut d1) = (0.0, 1.0);
    let (mut s0, mut s1) = (0.0, 0.0);
    let mut out = (0.0, 0.0, 0.0);
    for (j, &cj) in c.iter().enumerate() {
        let (tj, dj, sj) = if j == 0 { (t0, d0, s0) } else { (t1, d1, s1) };
        out.0 += cj * tj;
        out.1 += cj * dj;
        out.2 += cj * sj;
        if j >= 1 {
            let t2 = 2.0 * tau * t1 - t0;
            let d2 = 2.0 * t1 + 2.0 * tau * d1 - d0;
            let s2 = 4.0 * d1 + 2.0 * tau * s1 - s0;
            (t0, t1, d0, d1, s0, s1) = (t1, t2, d1, d2, s1, s2);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn coefficients_of_a_polynomial_are_recovered_and_evaluated() {
        let c = [0.3, -1.2, 0.5, 0.25, -0.125];
        let got = chebyshev_coefficients(|tau| chebyshev_with_derivatives(&c, tau).0, 8);
        for (l, g) in got.iter().enumerate() {
            let want = c.get(l).copied().unwrap_or(0.0);
            // Exact for a polynomial of degree below n, to rounding.
            assert!((g - want).abs() < 1e-14, "c_{l}: {g} against {want}");
        }
        let taus = [-1.0, -0.3, 0.0, 0.7, 1.0];
        let lanes = chebyshev_lanes(&c, &taus);
        for (tau, lane) in taus.into_iter().zip(lanes) {
            let (f, _, _) = chebyshev_with_derivatives(&c, tau);
            assert!((lane - f).abs() < 1e-14);
        }
    }
}
