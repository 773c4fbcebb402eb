//! Planning a multi-head self-calibration: where to place `J` heads so that every order up to
//! `N` is seen, and the `u` the joint method will give.
//!
//! # The formulas (the method's own)
//! The joint multi-head method ([`crate::multihead`], after the SelfA set-up of Hsieh, Watanabe,
//! Hsu 2022, eqs. 8–9) sees order `h` of the scale's error through the differences to the first
//! head, `c_jh = e^{ihψ_j} − 1` at head angles `ψ_j`; its observability is
//! `o_h = Σ_j |c_jh|²/(2J)` (1 for `J` equally spaced heads, which are blind at every multiple of
//! `J`; the SelfA sets of 3, 4 and 7 heads together are blind at the multiples of 84). Its `u` is
//! `u_fit² = Σ_h 2 Σ_jk Re(w_jh w̄_kh) G_jk` over the fitted orders, with the weights `w_jh` of
//! its eq. 3 and `G_jk` the covariance of the differences' Fourier coefficients; for a planned
//! run of `M` samples spread evenly over the circle and equal noise `σ` per head and sample,
//! `G_jk = σ²(1 + δ_jk)/M` (every difference holds the first head's noise). The planner calls the
//! method's weight function, and its propagation in the closed form that `G` gives
//! ([`planned_variance`], linear in the heads).
//!
//! # The search
//! [`plan`] maximizes the worst `o_h` over `h ≤ N` by the search of `super::search` (the first
//! head at 0°, the others free or on a mechanism's step).
//!
//! # What a plan cannot see
//! EDA (eq. 9) is not planned: its sets are equally spaced by construction, so its blind orders are
//! the multiples of each set's size. Orders above `N` are not planned for.

use super::MAX_PLANNED_ANGLES;
use super::search::Search;
use crate::multihead::{MultiheadOptions, joint_weights};
use realfft::num_complex::Complex;

/// A placement of heads and what the joint method will see with it.
#[derive(Debug, Clone, PartialEq)]
pub struct MultiheadPlan {
    /// Head angles, rad, the first 0.
    pub positions: Vec<f64>,
    /// Orders `1..=N`.
    pub orders: Vec<HeadOrderPlan>,
    /// Orders the method leaves out (observability below its threshold).
    pub blind_orders: Vec<usize>,
    /// Samples of the run (at constant speed).
    pub samples: f64,
    /// Noise per head and sample, rad.
    pub sigma: f64,
}

/// One order of a placement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeadOrderPlan {
    /// The order `h`.
    pub order: usize,
    /// Its observability `o_h`.
    pub observability: f64,
    /// The `u` it adds to the map, rad (∞ for an order left out).
    pub u: f64,
}

impl MultiheadPlan {
    /// The plan of heads at `positions` (rad; only differences to the first matter) for orders
    /// `1..=max_order`, with `samples` samples and noise `sigma` (rad) per head.
    pub fn of(positions: &[f64], max_order: usize, samples: f64, sigma: f64) -> MultiheadPlan {
        let heads = positions.len();
        let psi: Vec<f64> = positions[1..].iter().map(|p| p - positions[0]).collect();
        let threshold = MultiheadOptions::default().min_observability;
        let orders: Vec<HeadOrderPlan> = (1..=max_order)
            .map(|h| {
                let o = observability(h, &psi, heads);
                let u = if o < threshold {
                    f64::INFINITY
                } else {
                    planned_variance(&joint_weights(h, &psi), sigma * sigma / samples).sqrt()
                };
                HeadOrderPlan {
                    order: h,
                    observability: o,
                    u,
                }
            })
            .collect();
        MultiheadPlan {
            positions: positions.to_vec(),
            blind_orders: orders
                .iter()
                .filter(|o| o.observability < threshold)
                .map(|o| o.order)
                .collect(),
            orders,
            samples,
            sigma,
        }
    }

    /// The order seen worst.
    pub fn worst(&self) -> Option<&HeadOrderPlan> {
        self.orders
            .iter()
            .min_by(|a, b| a.observability.total_cmp(&b.observability))
    }

    /// The map's `u` from the noise, `√(Σ u_h²)` over the orders the method fits (every order up
    /// to `N` it does not leave out, as its own `u` sums them).
    pub fn u_fit(&self) -> f64 {
        self.orders
            .iter()
            .filter(|o| o.u.is_finite())
            .map(|o| o.u * o.u)
            .sum::<f64>()
            .sqrt()
    }
}

/// The method's [`crate::multihead::order_variance`] of weights `w` for the planned covariance
/// `G_jk = g·(1 + δ_jk)` (every difference holds the first head's noise): `2 Σ_jk Re(w_j w̄_k)
/// G_jk = 2g·(Σ_j |w_j|² + |Σ_j w_j|²)`, in `O(J)` where `G` written out takes `O(J²)` (a plan of
/// 1000 heads held a million-entry `G` and summed it at every order).
pub fn planned_variance(w: &[Complex<f64>], g: f64) -> f64 {
    let total: Complex<f64> = w.iter().sum();
    2.0 * g * (w.iter().map(|w| w.norm_sqr()).sum::<f64>() + total.norm_sqr())
}

/// `o_h = Σ_j |e^{ihψ_j} − 1|²/(2J)` over the heads after the first (`ψ` relative to it).
pub fn observability(order: usize, psi: &[f64], heads: usize) -> f64 {
    psi.iter()
        .map(|p| 2.0 - 2.0 * (order as f64 * p).cos())
        .sum::<f64>()
        / (2.0 * heads as f64)
}

/// The placement of `heads` heads (the first at 0°; every angle a multiple of `step` if given)
/// that maximizes the worst observability over orders `1..=max_order`.
pub fn plan(
    heads: usize,
    max_order: usize,
    step: Option<f64>,
    samples: f64,
    sigma: f64,
) -> Result<MultiheadPlan, super::csrr::PlanError> {
    let invalid = |what, value: f64, expected| super::csrr::PlanError::Invalid {
        what,
        value,
        expected,
    };
    if !(2..=MAX_PLANNED_ANGLES).contains(&heads) {
        return Err(invalid("the number of heads", heads as f64, "in 2..=1000"));
    }
    if max_order == 0 || max_order > super::csrr::MAX_PLANNED_ORDER {
        return Err(invalid(
            "the highest order",
            max_order as f64,
            "in 1..=20000",
        ));
    }
    if let Some(s) = step
        && !(s.is_finite() && s > 0.0 && s <= std::f64::consts::PI)
    {
        return Err(invalid("the step", s.to_degrees(), "in (0°, 180°]"));
    }
    if !(samples.is_finite() && samples >= 1.0) {
        return Err(invalid("the samples", samples, "at least 1"));
    }
    if !(sigma.is_finite() && sigma >= 0.0) {
        return Err(invalid("the noise", sigma, "finite and ≥ 0"));
    }
    let fixed = [0.0];
    let j = heads as f64;
    let search = Search::new(&fixed, max_order, step, |c: f64, _| (j - c) / j);
    let positions: Vec<f64> = fixed
        .iter()
        .copied()
        .chain(search.best(heads - 1))
        .collect();
    Ok(MultiheadPlan::of(&positions, max_order, samples, sigma))
}

#[cfg(test)]
// The tests print the figures docs/plan.md quotes (run with --nocapture).
#[allow(clippy::print_stderr)]
mod tests {
    use super::*;
    use crate::angle::ARCSEC_PER_RAD;
    use crate::multihead::order_variance;

    fn rad(d: &[f64]) -> Vec<f64> {
        d.iter().map(|d| d.to_radians()).collect()
    }

    /// The SelfA layout (3, 4 and 7 equally spaced heads sharing the first) is blind at the
    /// multiples of 84 = lcm(3, 4, 7); a planned placement of the same 12 heads is not, and sees
    /// its worst order better than SelfA's worst observable one.
    #[test]
    fn selfa_heads_are_blind_at_84_and_a_plan_is_not() {
        let mut selfa: Vec<f64> = vec![0.0];
        for n in [3.0, 4.0, 7.0] {
            for k in 1..n as usize {
                selfa.push(360.0 / n * k as f64);
            }
        }
        assert_eq!(selfa.len(), 12);
        let p = MultiheadPlan::of(&rad(&selfa), 200, 1e4, 1e-7);
        assert_eq!(p.blind_orders, vec![84, 168]);
        let planned = plan(12, 200, None, 1e4, 1e-7).unwrap();
        assert!(planned.blind_orders.is_empty());
        let seen = p
            .orders
            .iter()
            .filter(|o| o.u.is_finite())
            .map(|o| o.observability)
            .fold(f64::INFINITY, f64::min);
        assert!(planned.worst().unwrap().observability > seen);
    }

    /// Four equally spaced heads are blind at multiples of 4, as eq. 9 says; a planned set of four
    /// on a 1° step sees every order up to 90.
    #[test]
    fn equal_spacing_is_blind_at_its_multiples() {
        let p = MultiheadPlan::of(&rad(&[0.0, 90.0, 180.0, 270.0]), 12, 1e4, 1e-7);
        assert_eq!(p.blind_orders, vec![4, 8, 12]);
        for o in p.orders.iter().filter(|o| o.order % 4 != 0) {
            assert!((o.observability - 1.0).abs() < 1e-12);
        }
        let planned = plan(4, 90, Some(1f64.to_radians()), 1e4, 1e-7).unwrap();
        assert!(
            planned.blind_orders.is_empty(),
            "{:?}",
            planned.blind_orders
        );
        for d in &planned.positions {
            let deg = d.to_degrees();
            assert!((deg - deg.round()).abs() < 1e-9, "{deg}");
        }
    }

    /// The planned `u` against the `u` the joint method reports on a simulation of the planned
    /// placement (and of the SelfA layout): within the factor 1.5.
    #[test]
    fn planned_u_matches_the_u_of_the_simulated_run() {
        use crate::multihead::{Head, Multihead};
        use crate::simulate::{HarmonicSpec, Mount, Procedure, Scale, Scenario, Sensor};
        let (rate, rpm, revolutions, noise, q) = (400.0, 10.0, 2.0, 0.01, 0.01);
        let samples = revolutions * rate * 60.0 / rpm;
        let sigma = (noise * noise + q * q / 12.0_f64).sqrt() / ARCSEC_PER_RAD;
        let max_order = 60;
        let mut selfa: Vec<f64> = vec![0.0];
        for n in [3.0, 4.0, 7.0] {
            for k in 1..n as usize {
                selfa.push(360.0 / n * k as f64);
            }
        }
        let planned = plan(5, max_order, None, samples, sigma).unwrap();
        for positions in [planned.positions.clone(), rad(&selfa)] {
            let p = MultiheadPlan::of(&positions, max_order, samples, sigma);
            let h = |order, amplitude_arcsec, phase_deg| HarmonicSpec {
                order,
                amplitude_arcsec,
                phase_deg,
            };
            let scenario = Scenario {
                seed: 3,
                rate_hz: rate,
                speed_rpm: rpm,
                scales: vec![Scale {
                    name: "disc".into(),
                    harmonics: vec![h(2, 1.0, 30.0), h(7, 0.2, 120.0), h(30, 0.05, 0.0)],
                    mount: Mount::B,
                }],
                sensors: positions
                    .iter()
                    .enumerate()
                    .map(|(i, d)| Sensor {
                        name: format!("h{}", i + 1),
                        mount: None,
                        harmonics: Vec::new(),
                        scale: Some("disc".into()),
                        head_deg: Some(d.to_degrees()),
                        head_error_arcsec: Some(if i == 0 { 0.0 } else { 1.5 }),
                        quantization_arcsec: q,
                        noise_arcsec: noise,
                        delay_s: 0.0,
                        backlash_arcsec: 0.0,
                        commanded: false,
                        ratio: 1.0,
                    })
                    .collect(),
                procedure: Procedure {
                    relative_deg: vec![0.0],
                    revolutions,
                    sessions: Vec::new(),
                    ramp_s: 1.0,
                    pause_s: 1.0,
                    turn_s: 0.0,
                },
                ..Scenario::default()
            };
            let heads: Vec<Head> = scenario
                .sensors
                .iter()
                .map(|s| Head {
                    name: s.name.clone(),
                    nominal: s.head_deg.unwrap_or(0.0).to_radians(),
                })
                .collect();
            let mut mh = Multihead::new(
                heads,
                MultiheadOptions {
                    max_order: Some(max_order),
                    ..MultiheadOptions::default()
                },
            )
            .unwrap();
            for s in scenario.samples().unwrap() {
                mh.push(&s.values);
            }
            let cal = mh.finish().unwrap();
            let blind: Vec<usize> = cal
                .blind
                .iter()
                .chain(&cal.ill_conditioned)
                .map(|e| e.order)
                .collect();
            assert_eq!(blind, p.blind_orders);
            let u_method = cal.uncertainty.components[0].u[0];
            let ratio = p.u_fit() / u_method;
            eprintln!(
                "{:?}: planned u {:.5}″, method {:.5}″",
                positions.iter().map(|d| d.to_degrees()).collect::<Vec<_>>(),
                p.u_fit() * ARCSEC_PER_RAD,
                u_method * ARCSEC_PER_RAD
            );
            // The method estimates the noise from the bins' residuals and its bins hold the
            // ramps' samples too: agreement to tens of percent, the bar is 1.5.
            assert!((1.0 / 1.5..1.5).contains(&ratio), "ratio {ratio}");
        }
    }

    /// The closed form of the planned variance is the method's propagation through the
    /// written-out `G_jk = g·(1 + δ_jk)` (to rounding).
    #[test]
    fn planned_variance_is_the_methods_propagation() {
        let psi = rad(&[17.0, 95.5, 143.0, 211.2, 300.9]);
        let g = 3e-14;
        let full: Vec<Vec<f64>> = (0..psi.len())
            .map(|j| {
                (0..psi.len())
                    .map(|k| g * if j == k { 2.0 } else { 1.0 })
                    .collect()
            })
            .collect();
        for h in [1, 2, 7, 84, 199] {
            let w = joint_weights(h, &psi);
            let (closed, method) = (planned_variance(&w, g), order_variance(&full, &w));
            assert!(
                (closed - method).abs() <= 1e-12 * method,
                "{h}: {closed} {method}"
            );
        }
    }
}
