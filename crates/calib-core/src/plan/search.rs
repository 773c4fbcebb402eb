//! The maximin search shared by the planners: angles (relative rotations, head positions) that
//! maximize the worst, over orders `1..=N`, of a per-order measure of how well the order is seen.
//!
//! The measure of order `h` is a function of the phasors `e^{ihφ_k}` of every angle `φ_k` (the
//! fixed ones first). Random candidates (seeded, so a plan is reproducible) are screened, the
//! best of them refined by a pattern search (each free angle moved by `±s`, `s` halved from 2°
//! down to 0.0001° or to the mechanism's step). With a step, every angle is a multiple of it.

use std::f64::consts::TAU;

/// One search: the fixed angles, the orders, the grid and the measure.
pub(crate) struct Search<'a, F> {
    /// Angles held, rad (the first is the reference of the others).
    pub fixed: &'a [f64],
    /// The highest order, `N`.
    pub max_order: usize,
    /// Every angle a multiple of this, rad.
    pub step: Option<f64>,
    /// The measure of one order from the phasors `(cos hφ_k, sin hφ_k)`, fixed angles first.
    pub measure: F,
}

/// Random candidates drawn per free angle before refining.
const CANDIDATES_PER_FREE: usize = 6000;
/// Candidates refined by the pattern search.
const REFINED: usize = 16;

impl<F: Fn(&[(f64, f64)]) -> f64> Search<'_, F> {
    /// The worst measure over the orders of `fixed ∪ free`, or a value at most `cutoff` as soon
    /// as one order falls to `cutoff` or below.
    pub fn worst(&self, free: &[f64], cutoff: f64) -> f64 {
        let angles: Vec<f64> = self.fixed.iter().chain(free).copied().collect();
        let unit: Vec<(f64, f64)> = angles
            .iter()
            .map(|d| {
                let (s, c) = d.sin_cos();
                (c, s)
            })
            .collect();
        let mut powers = unit.clone();
        let mut worst = f64::INFINITY;
        for h in 1..=self.max_order {
            if h > 1 {
                if h % 64 == 0 {
                    // The recurrence drifts by ~h·1e-16: start it afresh now and then.
                    for (p, d) in powers.iter_mut().zip(&angles) {
                        let (s, c) = (h as f64 * d).sin_cos();
                        *p = (c, s);
                    }
                } else {
                    for (p, r) in powers.iter_mut().zip(&unit) {
                        *p = (p.0 * r.0 - p.1 * r.1, p.0 * r.1 + p.1 * r.0);
                    }
                }
            }
            worst = worst.min((self.measure)(&powers));
            if worst <= cutoff {
                break;
            }
        }
        worst
    }

    fn snap(&self, d: f64) -> f64 {
        let d = d.rem_euclid(TAU);
        match self.step {
            Some(step) => ((d / step).round() * step).rem_euclid(TAU),
            None => d,
        }
    }

    /// The best `free` angles found, ascending.
    pub fn best(&self, free: usize) -> Vec<f64> {
        if free == 0 {
            return Vec::new();
        }
        let mut rng = SplitMix(0x5eed_c5e7 ^ ((self.max_order as u64) << 8) ^ free as u64);
        // The best REFINED candidates, worst first.
        let mut top: Vec<(f64, Vec<f64>)> = Vec::with_capacity(REFINED + 1);
        for _ in 0..CANDIDATES_PER_FREE * free {
            let candidate: Vec<f64> = (0..free).map(|_| self.snap(rng.next() * TAU)).collect();
            let cutoff = if top.len() == REFINED {
                top[0].0
            } else {
                f64::NEG_INFINITY
            };
            let value = self.worst(&candidate, cutoff);
            if value > cutoff {
                top.push((value, candidate));
                top.sort_by(|a, b| a.0.total_cmp(&b.0));
                if top.len() > REFINED {
                    top.remove(0);
                }
            }
        }
        let mut best = top
            .into_iter()
            .map(|(value, candidate)| self.refine(candidate, value))
            .max_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(_, c)| c)
            .unwrap_or_default();
        best.sort_by(f64::total_cmp);
        best
    }

    /// Pattern search from `x`: each angle moved by `±s` while that raises the worst measure,
    /// `s` halved when nothing does.
    fn refine(&self, mut x: Vec<f64>, mut value: f64) -> (f64, Vec<f64>) {
        let start = 2.0_f64.to_radians();
        let (mut s, smallest) = match self.step {
            Some(step) => (step * (start / step).round().max(1.0), step),
            None => (start, 1e-4_f64.to_radians()),
        };
        loop {
            let mut moved = false;
            for i in 0..x.len() {
                for sign in [1.0, -1.0] {
                    let mut y = x.clone();
                    y[i] = self.snap(x[i] + sign * s);
                    let v = self.worst(&y, value);
                    if v > value {
                        x = y;
                        value = v;
                        moved = true;
                        break;
                    }
                }
            }
            if !moved {
                if s <= smallest * 1.5 {
                    break;
                }
                s = match self.step {
                    Some(step) => (step * (s / step / 2.0).round()).max(step),
                    None => s / 2.0,
                };
            }
        }
        (value, x)
    }
}

/// A small seeded generator (SplitMix64) of uniform numbers in `[0, 1)`.
struct SplitMix(u64);

impl SplitMix {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
}
