//! Which harmonic orders a set of relative rotations can see.
//!
//! For order `h`, the joint equation restricted to that order reads, per session `k`,
//! `α_h − β_h·e^{−ihΔ_k} = (data)`, with `α_h, β_h` the complex amplitudes of `e_a, e_b`. With
//! session weights `W_k` (samples) the 2×2 normal matrix is `½[[W, −S̄], [−S, W]]`,
//! `S = Σ_k W_k e^{ihΔ_k}`, `W = Σ_k W_k`, whose eigenvalues are `½(W ± |S|)`. The
//! **observability** `q_h = 1 − |S|/W ∈ [0, 1]` is the smallest one relative to the ideal `½W`:
//! noise on the worst-determined combination of the two maps is amplified by `1/√q_h`.
//! `q_h = 0` exactly when `h·(Δ_k − Δ_0) ≡ 0 (mod 2π)` for every `k` (a blind order: a common
//! harmonic of both sensors leaves no trace in `x − y`).

use std::f64::consts::TAU;

/// The observability `q_h = 1 − |Σ_k W_k e^{ihΔ_k}| / Σ_k W_k` of order `h`.
pub fn observability(order: usize, deltas: &[f64], weights: &[f64]) -> f64 {
    let w: f64 = weights.iter().sum();
    if w <= 0.0 {
        return 0.0;
    }
    let (mut c, mut s) = (0.0, 0.0);
    for (&d, &wk) in deltas.iter().zip(weights) {
        let (sn, cs) = (order as f64 * d).sin_cos();
        c += wk * cs;
        s += wk * sn;
    }
    (1.0 - c.hypot(s) / w).max(0.0)
}

/// The variance of each of the four coefficients (cosine and sine of A and of B) of order `h`
/// in the joint fit, `σ²·2W/(W² − |S_h|²)` with `σ` the noise per sample (rad): the diagonal of
/// the inverse of the 2×2 (complex) block `½[[W, −S̄], [−S, W]]` above, scaled by `σ²`. Within
/// a sensor the cosine and the sine are uncorrelated. It is the variance for readings spread
/// uniformly over the circle, which the joint solver's preconditioner also assumes.
pub fn coefficient_variance(order: usize, deltas: &[f64], weights: &[f64], sigma: f64) -> f64 {
    let w: f64 = weights.iter().sum();
    let (mut c, mut s) = (0.0, 0.0);
    for (&d, &wk) in deltas.iter().zip(weights) {
        let (sn, cs) = (order as f64 * d).sin_cos();
        c += wk * cs;
        s += wk * sn;
    }
    sigma * sigma * 2.0 * w / (w * w - c * c - s * s)
}

/// The extra relative rotation (rad, in `[0, 2π)`, on a 0.1° grid) that, recorded as one more
/// session of average weight, maximizes the smallest observability over orders `1..=max_order`.
/// Returns the rotation and the smallest observability it would give.
pub fn best_extra_rotation(deltas: &[f64], weights: &[f64], max_order: usize) -> (f64, f64) {
    let w_new = weights.iter().sum::<f64>() / weights.len().max(1) as f64;
    // Per-order phasor sums of the sessions recorded so far.
    let sums: Vec<(f64, f64)> = (1..=max_order)
        .map(|h| {
            deltas
                .iter()
                .zip(weights)
                .fold((0.0, 0.0), |(c, s), (&d, &wk)| {
                    let (sn, cs) = (h as f64 * d).sin_cos();
                    (c + wk * cs, s + wk * sn)
                })
        })
        .collect();
    let total = weights.iter().sum::<f64>() + w_new;
    let mut best = (0.0, -1.0);
    for step in 0..3600 {
        let delta = step as f64 * TAU / 3600.0;
        let mut worst = f64::INFINITY;
        for (i, &(c, s)) in sums.iter().enumerate() {
            let (sn, cs) = ((i + 1) as f64 * delta).sin_cos();
            let q = 1.0 - (c + w_new * cs).hypot(s + w_new * sn) / total;
            worst = worst.min(q);
            if worst <= best.1 {
                break;
            }
        }
        if worst > best.1 {
            best = (delta, worst);
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blind_orders_are_the_multiples_of_the_turn_fraction() {
        // Sessions at 0°, 90°, 180°, 270°: orders that are multiples of 4 are blind.
        let d: Vec<f64> = [0.0f64, 90.0, 180.0, 270.0]
            .iter()
            .map(|x| x.to_radians())
            .collect();
        let w = [1.0; 4];
        for h in 1..=20 {
            let q = observability(h, &d, &w);
            if h % 4 == 0 {
                assert!(q < 1e-12, "order {h}: {q}");
            } else {
                assert!(q > 0.5, "order {h}: {q}");
            }
        }
        let (extra, q) = best_extra_rotation(&d, &w, 20);
        assert!(q > 0.05, "advice {} gives {q}", extra.to_degrees());
        let mut d2 = d.clone();
        d2.push(extra);
        assert!((1..=20).all(|h| observability(h, &d2, &[1.0; 5]) >= q - 1e-12));
    }
}
