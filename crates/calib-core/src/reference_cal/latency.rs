//! A constant time offset between the two channels, fitted jointly with the map.
//!
//! # Model
//! Two interfaces rarely sample at the same instant. If the DUT's sample stamped `t` was taken
//! at `t − τ` (the DUT lags the reference by `τ`, positive when its sample is older), the
//! difference of the readings at a crossing of grid point `i` is, to first order in `τ`,
//!
//! `x = e_i + β·σ − τ·ω + noise`,
//!
//! `e_i` the map at the point, `σ = ±1` the direction of motion, `β` half a constant reversal
//! (a coupling's backlash or the DUT's hysteresis, `B = 2β`) and `ω` the reference's speed at
//! the crossing. The map is a free value per grid point, so `τ` and `β` are estimated from the
//! differences between passes over the same point (the within-point, "fixed effects" least
//! squares: `x`, `σ` and `ω` have their mean over the point's crossings removed, then `x` is
//! regressed on `σ` and `ω`). Latency is told from backlash only where the speed differs between
//! passes in the same direction: at one speed `τ·ω = τ·|ω|·σ` and the two are the same column.
//! Their squared correlation `ρ²` says how close to that the run is; the joint fit's `u(τ)`
//! grows as `1/√(1 − ρ²)`, and below `1 − ρ²` = [`MIN_SPEED_SPREAD`] the lag is not
//! separated at all (see there why).
//!
//! The first-order model is used to estimate `τ`; the map is then computed exactly, with the
//! reference interpolated at `t − τ` (a cubic in time), and the fit repeated on that map for
//! what is left of `τ` (see [`super::ReferenceCal::finish`]).
//!
//! # Uncertainty
//! `u(τ)² = s²·(S⁻¹)_ωω·g`: `s²` the residual variance, `S` the 2×2 normal matrix of the
//! demeaned `σ` and `ω`, and `g ≥ 1` the number of grid crossings per moving sample step
//! (neighbouring crossings between the same two samples share their noise).
//!
//! # What it cannot see
//! A latency that changes during the run, and one at a single speed per direction (then only
//! `τ·|ω| + β` is known: [`LatencyFit::separable`] is false and a warning names both readings).

/// The least `1 − ρ²` that separates latency from backlash: the speeds of a direction's passes
/// must differ by about a tenth of the speed. A run at one speed per direction still has its
/// ramps, where the speed differs; but there the mechanics' own lag under acceleration (an
/// open-loop stepper's, a coupling's wind-up) reads as latency too, so calib does not separate
/// the two from the ramps alone (runs at one cruise speed give `1 − ρ²` of 0.001–0.002).
pub const MIN_SPEED_SPREAD: f64 = 0.01;

/// One crossing of a grid point: the point, the direction, the reading difference there and the
/// reference's speed (rad/s, signed).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Crossing {
    pub(super) bin: u32,
    pub(super) up: bool,
    pub(super) x: f64,
    pub(super) w: f64,
}

/// The fitted time offset between the channels, and what the data say of it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LatencyFit {
    /// `τ`, seconds: the DUT's lag behind the reference (positive: the DUT's sample is older),
    /// fitted jointly with a constant reversal.
    pub tau: f64,
    /// Standard uncertainty of `τ`, seconds.
    pub u_tau: f64,
    /// The constant reversal `B = 2β` of the same fit, radians (calib's sign, `ē↑ − ē↓`).
    pub reversal: f64,
    /// `ρ²`: squared within-point correlation of direction and speed (1: one speed each way,
    /// latency and backlash indistinguishable).
    pub speed_direction_correlation: f64,
    /// `τ` if the whole reversal were latency (the fit without `β`), seconds.
    pub tau_if_no_backlash: f64,
    /// `B` if the whole reversal were backlash (the fit without `τ`), radians.
    pub reversal_if_no_latency: f64,
    /// Its standard uncertainty, radians.
    pub u_reversal_if_no_latency: f64,
    /// Mean absolute speed of the reference at the crossings, rad/s.
    pub mean_speed: f64,
    /// Crossings used (of points crossed at least twice).
    pub crossings: usize,
}

impl LatencyFit {
    /// Whether the run separates latency from backlash: the speed differs between passes in
    /// the same direction (`1 − ρ² ≥` [`MIN_SPEED_SPREAD`]) and `τ` is known to better than a
    /// third of the value the whole reversal would give it (or to a lag too small to matter).
    pub fn separable(&self) -> bool {
        1.0 - self.speed_direction_correlation >= MIN_SPEED_SPREAD
            && (self.u_tau < self.tau_if_no_backlash.abs() / 3.0
                || self.u_tau * self.mean_speed < 1e-7)
    }

    /// Whether `τ` differs from 0 by more than 3 standard uncertainties.
    pub fn significant(&self) -> bool {
        self.tau.abs() > 3.0 * self.u_tau
    }
}

/// The within-point least-squares fit of `x = e_i + β·σ − τ·ω` over `crossings` of `bins`
/// grid points; `steps` is the number of moving sample steps they came from. `None` when fewer
/// than 3 degrees of freedom remain or the speed does not vary within points.
pub(super) fn fit(crossings: &[Crossing], bins: usize, steps: usize) -> Option<LatencyFit> {
    #[derive(Clone, Copy, Default)]
    struct Sums {
        n: f64,
        s: f64,
        w: f64,
        x: f64,
    }
    let mut per = vec![Sums::default(); bins];
    for c in crossings {
        let p = &mut per[c.bin as usize];
        p.n += 1.0;
        p.s += if c.up { 1.0 } else { -1.0 };
        p.w += c.w;
        p.x += c.x;
    }
    let (mut sss, mut ssw, mut sww, mut ssx, mut swx, mut sxx) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    let (mut used, mut groups, mut speed) = (0usize, 0usize, 0.0);
    for c in crossings {
        let p = per[c.bin as usize];
        if p.n < 2.0 {
            continue;
        }
        let s = if c.up { 1.0 } else { -1.0 } - p.s / p.n;
        let w = c.w - p.w / p.n;
        let x = c.x - p.x / p.n;
        sss += s * s;
        ssw += s * w;
        sww += w * w;
        ssx += s * x;
        swx += w * x;
        sxx += x * x;
        used += 1;
        speed += c.w.abs();
    }
    groups += per.iter().filter(|p| p.n >= 2.0).count();
    let dof = used.checked_sub(groups + 2).filter(|&d| d >= 3)? as f64;
    if sww <= 0.0 {
        return None;
    }
    let inflate = (crossings.len() as f64 / steps.max(1) as f64).max(1.0);
    // The fit without β (all latency) and without τ (all backlash).
    let c_only = swx / sww;
    let rss_tau = (sxx - c_only * swx).max(0.0);
    let (b_only, u_b_only) = if sss > 0.0 {
        let b = ssx / sss;
        let rss = (sxx - b * ssx).max(0.0);
        (b, (rss / (dof + 1.0) / sss * inflate).sqrt())
    } else {
        (0.0, f64::INFINITY)
    };
    let det = sss * sww - ssw * ssw;
    // One direction only: nothing to confound the lag with.
    let rho2 = if sss > 0.0 {
        (ssw * ssw / (sss * sww)).min(1.0)
    } else {
        0.0
    };
    let (beta, c, u_c) = if sss > 0.0 && det > 1e-12 * sss * sww {
        let beta = (sww * ssx - ssw * swx) / det;
        let c = (sss * swx - ssw * ssx) / det;
        let rss = (sxx - beta * ssx - c * swx).max(0.0);
        (beta, c, (rss / dof * sss / det * inflate).sqrt())
    } else if sss > 0.0 {
        // One speed per direction: τ is not identified at all.
        (b_only, 0.0, f64::INFINITY)
    } else {
        // One direction only: no backlash term.
        (0.0, c_only, (rss_tau / (dof + 1.0) / sww * inflate).sqrt())
    };
    Some(LatencyFit {
        tau: -c,
        u_tau: u_c,
        reversal: 2.0 * beta,
        speed_direction_correlation: rho2,
        tau_if_no_backlash: -c_only,
        reversal_if_no_latency: 2.0 * b_only,
        u_reversal_if_no_latency: 2.0 * u_b_only,
        mean_speed: speed / used as f64,
        crossings: used,
    })
}

/// The value at `at` of a series `(t, v)` increasing in `t`: the cubic through the two samples
/// either side (a straight line next to an end or a non-finite neighbour); `None` outside the
/// series or next to a non-finite value.
pub(super) fn interpolate(series: &[(f64, f64)], at: f64) -> Option<f64> {
    let j = series.partition_point(|&(t, _)| t <= at);
    if j == 0 || j >= series.len() {
        return (j == series.len() && series.last().is_some_and(|&(t, _)| t == at))
            .then(|| series[j - 1].1)
            .filter(|v| v.is_finite());
    }
    let (a, b) = (series[j - 1], series[j]);
    if !(a.1.is_finite() && b.1.is_finite()) {
        return None;
    }
    let outer = j >= 2 && j + 1 < series.len() && {
        let (p, q) = (series[j - 2], series[j + 1]);
        p.1.is_finite() && q.1.is_finite()
    };
    Some(if outer {
        super::lagrange(&[series[j - 2], a, b, series[j + 1]], at)
    } else {
        super::lagrange(&[a, b], at)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Exact data `x = e_i + β·σ − τ·ω` at two speeds per direction: the fit returns τ and B
    /// to rounding.
    #[test]
    fn recovers_latency_and_backlash_from_two_speeds() {
        let (tau, beta) = (0.02, 1e-4);
        let mut crossings = Vec::new();
        for bin in 0..50u32 {
            let e = (bin as f64 * 0.3).sin() * 1e-3;
            for (up, w) in [(true, 0.2), (true, 0.7), (false, -0.3), (false, -0.9)] {
                let s = if up { 1.0 } else { -1.0 };
                crossings.push(Crossing {
                    bin,
                    up,
                    x: e + beta * s - tau * w,
                    w,
                });
            }
        }
        let f = fit(&crossings, 50, 200).unwrap();
        assert!((f.tau - tau).abs() < 1e-12, "{}", f.tau);
        assert!((f.reversal - 2.0 * beta).abs() < 1e-12);
        assert!(f.separable() && f.significant());
    }

    /// One speed each way: τ and B are the same column; the fit says so.
    #[test]
    fn one_speed_is_ambiguous() {
        let mut crossings = Vec::new();
        for bin in 0..50u32 {
            for (k, (up, w)) in [(true, 0.5), (false, -0.5)].into_iter().enumerate() {
                crossings.push(Crossing {
                    bin,
                    up,
                    x: 1e-4 * if up { 1.0 } else { -1.0 } + 1e-7 * (bin as f64 + k as f64).sin(),
                    w,
                });
            }
        }
        let f = fit(&crossings, 50, 100).unwrap();
        assert!(!f.separable());
        assert!((f.reversal_if_no_latency - 2e-4).abs() < 1e-6);
        assert!((f.tau_if_no_backlash + 2e-4).abs() < 1e-5);
    }

    #[test]
    fn interpolates_a_cubic_exactly() {
        let series: Vec<(f64, f64)> = (0..10)
            .map(|k| {
                let t = k as f64 * 0.1;
                (t, t * t * t - t)
            })
            .collect();
        let v = interpolate(&series, 0.43).unwrap();
        assert!((v - (0.43f64.powi(3) - 0.43)).abs() < 1e-12);
        assert!(interpolate(&series, -0.1).is_none());
        assert!(interpolate(&series, 0.95).is_none());
    }
}
