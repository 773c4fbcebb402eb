//! Driven runs (the module docs' "Driven runs"): the passes at steady speed, the motor's
//! orders, and their separation by the `1/ω²` dependence of the shake over passes at two or
//! more speeds.

use super::{Coast, MAX_DRAG_VARIANCE_INFLATION, Tdr, TdrCalibration, TdrError, check_log, union};
use crate::angle::ARCSEC_PER_RAD;
use crate::detection;
use crate::error_map::ErrorMap;
use crate::harmonics::{FourierSeries, Harmonic};
use crate::uncertainty::{Evaluation, MapComponent, MapUncertainty};
use std::f64::consts::TAU;

/// What a log holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RunKind {
    /// A coast where the log has one, else a driven run.
    #[default]
    Auto,
    /// A coast-down only: a log whose speed is held is refused.
    Coast,
    /// A driven run: passes at steady speed, each a smooth motion in time.
    Driven,
}

/// The orders at which a motor's torque is periodic in its angle: cogging and torque ripple.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum MotorOrders {
    /// None named.
    #[default]
    None,
    /// `k·6·p` for `k = 1, 2, …`, `p` the motor's pole pairs: a three-phase motor's torque
    /// ripple repeats six times per electrical turn (and its cogging mostly at these orders).
    PolePairs(usize),
    /// These orders.
    Orders(Vec<usize>),
}

impl MotorOrders {
    /// The orders up to `h`, ascending.
    pub fn up_to(&self, h: usize) -> Vec<usize> {
        match self {
            MotorOrders::None => Vec::new(),
            MotorOrders::PolePairs(0) => Vec::new(),
            MotorOrders::PolePairs(p) => (1..).map(|k| 6 * k * p).take_while(|&k| k <= h).collect(),
            MotorOrders::Orders(list) => union(&[], list)
                .into_iter()
                .filter(|&k| (1..=h).contains(&k))
                .collect(),
        }
    }
}

/// A revolution's mean speed may differ from the next one's by at most this fraction inside a
/// pass. Over a whole revolution the encoder's error and the shake of the motor's orders, both
/// periodic in angle, cancel: what is left is the drive's change of speed. A spin-up's tail at
/// constant voltage, whose speed approaches its end exponentially, joins the pass once it
/// changes slowly; a voltage step or a release, which change the acceleration at once, cut it.
/// (A kink whose speed change per revolution stays below this would be inside a pass; the fit's
/// residual then shows it.)
pub const STEADY_CHANGE: f64 = 0.005;

/// One pass of a driven run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DrivenPass {
    /// Start of the pass used, seconds.
    pub t_start: f64,
    /// End of the pass used, seconds.
    pub t_end: f64,
    /// `⟨ω⁻²⟩` over its samples, s².
    pub mean_inverse_square_speed: f64,
    /// Revolutions of the pass.
    pub revolutions: f64,
    /// Samples of the pass.
    pub samples: usize,
    /// RMS of its fit's residual, radians.
    pub residual_rms: f64,
}

impl DrivenPass {
    /// The speed of the pass, `1/√⟨ω⁻²⟩`, rad/s.
    pub fn speed(&self) -> f64 {
        self.mean_inverse_square_speed.sqrt().recip()
    }
}

/// What one pass measured at a motor order: the encoder's error and the shake together.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PassMeasurement {
    /// The pass (index in [`DrivenRun::passes`]).
    pub pass: usize,
    /// The fitted harmonic, radians.
    pub harmonic: Harmonic,
    /// Standard uncertainty of each of its coefficients, radians.
    pub u: f64,
}

/// A motor order separated over passes at different speeds: `c_s = e + D·g_s`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Separated {
    /// The encoder's error at this order (radians), in the map.
    pub encoder: Harmonic,
    /// Standard uncertainty of each of its coefficients, radians.
    pub u_encoder: f64,
    /// The angle-dependent deceleration `a·cos(kθ + φ)` that shakes the shaft, rad/s².
    pub deceleration: Harmonic,
    /// Standard uncertainty of its amplitude, rad/s².
    pub u_deceleration: f64,
    /// Factor by which the separation multiplies the noise, `√VIF` (module docs).
    pub noise_gain: f64,
}

/// One of the motor's orders in a driven run.
#[derive(Debug, Clone, PartialEq)]
pub struct MotorOrder {
    /// The order.
    pub order: usize,
    /// What each pass that tested it measured there.
    pub measured: Vec<PassMeasurement>,
    /// The separation by speed, where the passes' speeds allowed it (then the map holds the
    /// encoder's part); `None`: left out of the map.
    pub separated: Option<Separated>,
}

/// A driven run: its passes and the motor's orders.
#[derive(Debug, Clone, PartialEq)]
pub struct DrivenRun {
    /// The passes, in time order.
    pub passes: Vec<DrivenPass>,
    /// The pass whose fit gives the map outside the motor's orders (the one with the most
    /// samples), its motion and its residual.
    pub main_pass: usize,
    /// The motor's orders tested (up to the main pass's highest order).
    pub motor_orders: Vec<MotorOrder>,
}

/// What a pass's fit measured at a motor order: the coefficients of `cos kr` and `sin kr` and
/// each one's variance, radians.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct MotorMeasure {
    pub order: usize,
    pub cos: f64,
    pub sin: f64,
    pub variance: f64,
}

/// The budget component of the motor's orders left out of the map.
pub(super) const MOTOR_LEFT_OUT: &str = "the motor's orders, left out of the map (encoder error and shake together, measured at one speed)";

/// The budget component of the motor's orders separated by speed.
pub(super) const MOTOR_SEPARATED: &str =
    "the motor's orders, the encoder's part separated by the 1/ω² dependence of the shake";

/// The component for the motor's orders `left` out of the map: RMS over the circle of what
/// the map may miss there, `√Σ(A_k²/2 + σ_k²)` (`A_k` the amplitude measured, `σ_k²` each
/// coefficient's variance); `None` without any.
pub(super) fn left_out(left: &[MotorMeasure]) -> Option<MapComponent> {
    (!left.is_empty()).then(|| MapComponent {
        name: MOTOR_LEFT_OUT.into(),
        evaluation: Evaluation::TypeB,
        u: vec![
            left.iter()
                .map(|m| 0.5 * (m.cos * m.cos + m.sin * m.sin) + m.variance)
                .sum::<f64>()
                .sqrt(),
        ],
    })
}

/// The passes of a driven run: the longest stretches of whole revolutions whose mean speeds
/// change by at most [`STEADY_CHANGE`] from each to the next, less one revolution at each end
/// (where a kink may sit), each of at least [`super::TdrOptions::min_revolutions`].
///
/// A revolution ends where the reading first reaches the next level `r₀ ± 2π·m` (`r₀` the
/// first reading; it ends going back only at the level below): the same reading each time, so
/// the same error, and the time between two such instants (each interpolated linearly between
/// its samples) is exactly one revolution's.
pub(super) fn find_passes(
    t: &[f64],
    r: &[f64],
    extent: (f64, f64),
    opts: &super::TdrOptions,
) -> Result<Vec<Coast>, TdrError> {
    check_log(t.len(), extent)?;
    // (sample index, time, level) of each level reached.
    let mut marks: Vec<(usize, f64, f64)> = vec![(0, t[0], r[0])];
    let mut level = r[0];
    for n in 1..t.len() {
        let to = if r[n] >= level + TAU {
            level + TAU
        } else if r[n] <= level - TAU {
            level - TAU
        } else {
            continue;
        };
        let f = (to - r[n - 1]) / (r[n] - r[n - 1]);
        marks.push((n, t[n - 1] + f * (t[n] - t[n - 1]), to));
        level = to;
    }
    // The mean speed of revolution j (between marks j and j + 1), signed.
    let speeds: Vec<f64> = marks
        .windows(2)
        .map(|w| (w[1].2 - w[0].2) / (w[1].1 - w[0].1))
        .collect();
    let revs = speeds.len();
    let close = |a: f64, b: f64| a * b > 0.0 && (a - b).abs() <= STEADY_CHANGE * a.abs();
    let steady: Vec<bool> = (0..revs)
        .map(|j| {
            j > 0
                && j + 1 < revs
                && close(speeds[j], speeds[j - 1])
                && close(speeds[j], speeds[j + 1])
        })
        .collect();
    let (mut passes, mut longest) = (Vec::new(), 0usize);
    let mut j = 0;
    while j < revs {
        if !steady[j] {
            j += 1;
            continue;
        }
        let a = j;
        while j < revs && steady[j] {
            j += 1;
        }
        // Revolutions a..j are steady; the pass is a+1..j−1, from mark a+1 to mark j−1.
        let count = j.saturating_sub(a + 2);
        longest = longest.max(count);
        if count == 0 || (count as f64) < opts.min_revolutions {
            continue;
        }
        let inner = &speeds[a + 1..j - 1];
        let fastest = inner.iter().map(|v| v.abs()).fold(0.0, f64::max);
        passes.push(Coast {
            first: marks[a + 1].0,
            end: marks[j - 1].0,
            peak_speed: fastest,
            slowest_speed: inner.iter().map(|v| v.abs()).fold(fastest, f64::min),
            direction: inner[0].signum(),
            revolutions: count as f64,
            plateau_s: 0.0,
        });
    }
    if passes.is_empty() {
        return Err(TdrError::NoSteadyRun {
            revolutions: longest as f64,
            needed: opts.min_revolutions,
        });
    }
    Ok(passes)
}

/// The separation of a motor order of `order` over the passes' measurements `(g, measure)`,
/// `g = ⟨ω⁻²⟩` (module docs): `None` with fewer than two passes, or where the noise would grow
/// by more than `√`[`MAX_DRAG_VARIANCE_INFLATION`].
fn separate(order: usize, measured: &[(f64, MotorMeasure)]) -> Option<Separated> {
    if measured.len() < 2 {
        return None;
    }
    // Weighted sums: W = Σw, Σwg, Σwg², Σw·c, Σw·g·c for c the cos and the sin coefficients.
    let (mut w, mut wg, mut wgg) = (0.0, 0.0, 0.0);
    let (mut wc, mut ws, mut wgc, mut wgs) = (0.0, 0.0, 0.0, 0.0);
    for &(g, m) in measured {
        let x = 1.0 / m.variance;
        w += x;
        wg += x * g;
        wgg += x * g * g;
        wc += x * m.cos;
        ws += x * m.sin;
        wgc += x * g * m.cos;
        wgs += x * g * m.sin;
    }
    let det = w * wgg - wg * wg;
    let vif = w * wgg / det;
    if !(det > 0.0 && vif <= MAX_DRAG_VARIANCE_INFLATION) {
        return None;
    }
    let encoder = Harmonic::from_coefficients(
        order,
        (wgg * wc - wg * wgc) / det,
        (wgg * ws - wg * wgs) / det,
    );
    let shake =
        Harmonic::from_coefficients(order, (w * wgc - wg * wc) / det, (w * wgs - wg * ws) / det);
    let k2 = (order * order) as f64;
    Some(Separated {
        encoder,
        u_encoder: (wgg / det).sqrt(),
        deceleration: Harmonic {
            amplitude: shake.amplitude * k2,
            ..shake
        },
        u_deceleration: (w / det).sqrt() * k2,
        noise_gain: vif.sqrt(),
    })
}

/// The shake's sidebands in the reading. The shake `δ` is periodic in the true angle
/// `θ = r − E(r)`, so as a function of the reading it is `δ(r) − E(r)·δ′(r)` to first order:
/// the fit put the second term into the map's orders `k ± m` (`m` the map's own orders; with
/// 600″ at order 1 and 18″ of shake at order 42, ~1″ at 41 and 43). Returns, for each of
/// `orders`, the coefficients of `E·δ′` there: what the map's coefficients gain back. `shakes`
/// holds each motor order's shake `(k, p, q)`, `δ = p·cos kθ + q·sin kθ` (radians), `series`
/// the map `E`. The product is taken on a grid of more than twice its highest order.
fn sidebands(
    series: &FourierSeries,
    shakes: &[(usize, f64, f64)],
    orders: &[usize],
) -> Vec<(usize, f64, f64)> {
    let top = series.max_order() + shakes.iter().map(|s| s.0).max().unwrap_or(0);
    let n = 4 * top.max(1);
    let e = ErrorMap::from_series(series, n);
    let x = |i: usize| TAU * i as f64 / n as f64;
    let product: Vec<f64> = (0..n)
        .map(|i| {
            let slope: f64 = shakes
                .iter()
                .map(|&(k, p, q)| {
                    let (sn, cs) = (k as f64 * x(i)).sin_cos();
                    k as f64 * (q * cs - p * sn)
                })
                .sum();
            e.values()[i] * slope
        })
        .collect();
    orders
        .iter()
        .map(|&j| {
            let (a, b) = product
                .iter()
                .enumerate()
                .fold((0.0, 0.0), |(a, b), (i, v)| {
                    let (sn, cs) = (j as f64 * x(i)).sin_cos();
                    (a + 2.0 * v * cs / n as f64, b + 2.0 * v * sn / n as f64)
                });
            (j, a, b)
        })
        .collect()
}

impl Tdr {
    /// The driven run's calibration: each pass fitted, the map the main pass's, the motor's
    /// orders separated by speed where the passes allow it, else left out (module docs).
    pub(super) fn fit_driven(&self, passes: Vec<Coast>) -> Result<TdrCalibration, TdrError> {
        let mut fits = passes
            .iter()
            .map(|p| self.fit_run(p, true))
            .collect::<Result<Vec<_>, _>>()?;
        let main = (0..fits.len())
            .max_by_key(|&i| fits[i].0.samples_used)
            .unwrap_or(0);
        let summaries: Vec<DrivenPass> = fits
            .iter()
            .map(|(c, _)| DrivenPass {
                t_start: c.motion.t_start,
                t_end: c.motion.t_end,
                mean_inverse_square_speed: c.drag_gain,
                revolutions: c.revolutions,
                samples: c.samples_used,
                residual_rms: c.residual_rms,
            })
            .collect();
        let measures: Vec<Vec<MotorMeasure>> =
            fits.iter_mut().map(|f| std::mem::take(&mut f.1)).collect();
        let others: Vec<String> = fits
            .iter()
            .enumerate()
            .filter(|&(i, _)| i != main)
            .flat_map(|(i, (c, _))| {
                c.warnings
                    .iter()
                    .map(move |w| format!("pass {}: {w}", i + 1))
            })
            .collect();
        let mut cal = fits.swap_remove(main).0;

        let mut motor_orders = Vec::new();
        let mut left = Vec::new();
        let mut separated_u2 = 0.0;
        for m in &measures[main] {
            let of_order: Vec<(usize, MotorMeasure)> = measures
                .iter()
                .enumerate()
                .filter_map(|(i, ms)| ms.iter().find(|x| x.order == m.order).map(|&x| (i, x)))
                .collect();
            let with_gain: Vec<(f64, MotorMeasure)> = of_order
                .iter()
                .map(|&(i, x)| (summaries[i].mean_inverse_square_speed, x))
                .collect();
            let separated = separate(m.order, &with_gain);
            match &separated {
                Some(s) => {
                    let (c, sn) = s.encoder.coefficients();
                    cal.series.cos[m.order - 1] = c;
                    cal.series.sin[m.order - 1] = sn;
                    separated_u2 += s.u_encoder * s.u_encoder;
                    cal.orders = union(&cal.orders, &[m.order]);
                }
                None => left.push(*m),
            }
            motor_orders.push(MotorOrder {
                order: m.order,
                measured: of_order
                    .iter()
                    .map(|&(pass, x)| PassMeasurement {
                        pass,
                        harmonic: Harmonic::from_coefficients(x.order, x.cos, x.sin),
                        u: x.variance.sqrt(),
                    })
                    .collect(),
                separated,
            });
        }
        if separated_u2 > 0.0 {
            let g = summaries[main].mean_inverse_square_speed;
            let shakes: Vec<(usize, f64, f64)> = motor_orders
                .iter()
                .filter_map(|m| {
                    let s = m.separated.as_ref()?;
                    let (p, q) = s.deceleration.coefficients();
                    let k2 = (m.order * m.order) as f64;
                    Some((m.order, p * g / k2, q * g / k2))
                })
                .collect();
            let motor: Vec<usize> = motor_orders.iter().map(|m| m.order).collect();
            let corrected: Vec<usize> = cal
                .orders
                .iter()
                .copied()
                .filter(|k| !motor.contains(k))
                .collect();
            for (k, a, b) in sidebands(&cal.series, &shakes, &corrected) {
                cal.series.cos[k - 1] += a;
                cal.series.sin[k - 1] += b;
            }
            let points = cal.map.len();
            cal.map = ErrorMap::from_series(&cal.series, points);
            let mut components: Vec<MapComponent> = std::mem::take(&mut cal.uncertainty.components)
                .into_iter()
                .filter(|c| c.name != MOTOR_LEFT_OUT && c.name != detection::DETECTION_FLOOR)
                .collect();
            components.extend(left_out(&left));
            components.push(MapComponent {
                name: MOTOR_SEPARATED.into(),
                evaluation: Evaluation::TypeA,
                u: vec![separated_u2.sqrt()],
            });
            cal.uncertainty = detection::apply_floor(
                MapUncertainty::combine(points, components),
                detection::detection_floor(cal.detection_limit),
            );
        }
        cal.warnings.extend(others);
        cal.warnings
            .extend(self.motor_warnings(&motor_orders, cal.max_order));
        cal.driven = Some(DrivenRun {
            passes: summaries,
            main_pass: main,
            motor_orders,
        });
        Ok(cal)
    }

    /// Warnings about the motor's orders: none named, some above the orders tested, some left
    /// out of the map.
    fn motor_warnings(&self, orders: &[MotorOrder], h: usize) -> Vec<String> {
        let mut warnings = Vec::new();
        match &self.opts.motor {
            MotorOrders::None => warnings.push(
                "a driven run: the motor's cogging and torque ripple shake the shaft at its orders (k·6·pole pairs) as an encoder error would, and stay in the map; name them with the `pole_pairs` or `cogging_orders` option".to_string(),
            ),
            MotorOrders::Orders(list) => {
                let above: Vec<String> = list
                    .iter()
                    .filter(|&&k| k > h)
                    .map(|k| k.to_string())
                    .collect();
                if !above.is_empty() {
                    warnings.push(format!(
                        "the motor's orders {} are above the highest order tested ({h}): not fitted (the residual check names any that is there)",
                        above.join(", ")
                    ));
                }
            }
            MotorOrders::PolePairs(_) => {}
        }
        let left: Vec<String> = orders
            .iter()
            .filter(|o| o.separated.is_none())
            .map(|o| {
                let m = o
                    .measured
                    .iter()
                    .map(|p| p.harmonic.amplitude)
                    .fold(0.0, f64::max);
                format!("{} ({:.2}″)", o.order, m * ARCSEC_PER_RAD)
            })
            .collect();
        if !left.is_empty() {
            warnings.push(format!(
                "measured at one steady speed only, the motor's orders {} (cogging, torque ripple) cannot be told from the encoder's error: they are left out of the map, and its u covers what was measured there; add a pass at another speed (e.g. twice the voltage) that resolves them to separate them by the 1/ω² dependence of the shake",
                left.join(", ")
            ));
        }
        warnings
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pole_pairs_give_six_times_their_multiples() {
        assert_eq!(MotorOrders::PolePairs(7).up_to(100), vec![42, 84]);
        assert_eq!(MotorOrders::PolePairs(7).up_to(41), Vec::<usize>::new());
        assert_eq!(
            MotorOrders::Orders(vec![84, 0, 42, 42, 300]).up_to(100),
            vec![42, 84]
        );
    }

    #[test]
    fn the_sidebands_are_the_shake_seen_through_the_map() {
        // E = A·cos r and δ = S·cos kθ: −E·δ′ = A·S·k·cos r·sin kr = A·S·k/2·(sin(k+1)r +
        // sin(k−1)r), so E·δ′ has −A·S·k/2 in the sines of k ± 1.
        let (a, s, k) = (3e-3, 9e-5, 42);
        let mut series = FourierSeries::zeros(50);
        series.cos[0] = a;
        let got = sidebands(&series, &[(k, s, 0.0)], &[41, 43, 2]);
        let want = -a * s * k as f64 / 2.0;
        for (j, c, sn) in got {
            let expect = if j == 2 { 0.0 } else { want };
            assert!(
                c.abs() < 1e-15 && (sn - expect).abs() < 1e-15,
                "{j}: {c} {sn}"
            );
        }
    }

    #[test]
    fn two_speeds_give_back_the_encoder_and_the_deceleration() {
        // c_s = e + D·g_s exactly, at g = 1e-3 and 2.5e-4 s² (300 and 600 r/min).
        let (e, d) = ((2e-5, -1e-5), (0.03, 0.04));
        let at = |g: f64| MotorMeasure {
            order: 42,
            cos: e.0 + d.0 * g,
            sin: e.1 + d.1 * g,
            variance: 1e-14,
        };
        let s = separate(42, &[(1e-3, at(1e-3)), (2.5e-4, at(2.5e-4))]).unwrap();
        let want = Harmonic::from_coefficients(42, e.0, e.1);
        assert!((s.encoder.amplitude - want.amplitude).abs() < 1e-15);
        assert!((s.encoder.phase - want.phase).abs() < 1e-9);
        assert!((s.deceleration.amplitude - 0.05 * 42.0 * 42.0).abs() < 1e-9);
        // Equal variances at g and g/4: VIF = 2·(17/16)/(9/16) = 34/9.
        assert!((s.noise_gain - (34.0f64 / 9.0).sqrt()).abs() < 1e-9);
        // One speed twice: nothing to separate.
        assert!(separate(42, &[(1e-3, at(1e-3)), (1e-3, at(1e-3))]).is_none());
    }
}
