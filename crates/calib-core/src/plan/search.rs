//! The maximin search shared by the planners: angles (relative rotations, head positions) that
//! maximize the worst, over orders `1..=N`, of a per-order measure of how well the order is seen.
//!
//! The measure of order `h` is a function of the sum `Σ_k e^{ihφ_k}` of the phasors of every
//! angle `φ_k` (the fixed ones first). Random candidates (seeded, so a plan is reproducible) are
//! screened, the best of them refined by a pattern search (each free angle moved by `±s`, `s`
//! halved from 2° down to 0.0001° or to the mechanism's step). With a step, every angle is a
//! multiple of it.
//!
//! # Cost
//! Linear in the angles `K` (and in the orders `N`): the screening draws `6000` candidates per
//! free angle but at most [`SCREEN_BUDGET`] angles in all (`6000·(K−1)` candidates of `K` angles
//! each grew as `K²`: 300 sessions took 47 s), and the pattern search tries a move of one angle
//! by updating the phasor sums of the others ([`Sums`]), `O(N)`, instead of summing all `K`
//! afresh. The planners refuse more than [`super::MAX_PLANNED_ANGLES`] angles.

use std::cell::Cell;
use std::f64::consts::TAU;

/// The angles the screening evaluates in all (candidates × angles each): `6000` candidates a
/// free angle up to 16 free angles (every plan of up to 17 sessions or heads screens as many
/// candidates as before the budget), fewer beyond.
pub const SCREEN_BUDGET: usize = CANDIDATES_PER_FREE * 16 * 17;

/// One search: the fixed angles, the orders, the grid and the measure.
pub(crate) struct Search<'a, F> {
    /// Angles held, rad (the first is the reference of the others).
    pub fixed: &'a [f64],
    /// The highest order, `N`.
    pub max_order: usize,
    /// Every angle a multiple of this, rad.
    pub step: Option<f64>,
    /// The measure of one order from the sums `(Σ_k cos hφ_k, Σ_k sin hφ_k)` over every angle.
    pub measure: F,
    /// Phasors `e^{ihφ}` evaluated so far (one angle at one order): the search's work, which
    /// the tests hold to grow linearly in the angles.
    pub work: Cell<u64>,
}

/// Random candidates drawn per free angle before refining.
const CANDIDATES_PER_FREE: usize = 6000;
/// Candidates refined by the pattern search.
const REFINED: usize = 16;

impl<'a, F: Fn(f64, f64) -> f64> Search<'a, F> {
    /// A search holding `fixed`, for orders `1..=max_order`, on `step`'s grid, by `measure`.
    pub fn new(fixed: &'a [f64], max_order: usize, step: Option<f64>, measure: F) -> Self {
        Search {
            fixed,
            max_order,
            step,
            measure,
            work: Cell::new(0),
        }
    }

    /// The worst measure over the orders of `fixed ∪ free`, or a value at most `cutoff` as soon
    /// as one order falls to `cutoff` or below.
    pub fn worst(&self, free: &[f64], cutoff: f64) -> f64 {
        let angles: Vec<f64> = self.fixed.iter().chain(free).copied().collect();
        let mut phasors = Phasors::new(&angles);
        let mut worst = f64::INFINITY;
        for h in 1..=self.max_order {
            let powers = phasors.next(h);
            let (c, s) = powers
                .iter()
                .fold((0.0, 0.0), |(c, s), p| (c + p.0, s + p.1));
            worst = worst.min((self.measure)(c, s));
            if worst <= cutoff {
                self.add_work(h * angles.len());
                return worst;
            }
        }
        self.add_work(self.max_order * angles.len());
        worst
    }

    fn add_work(&self, n: usize) {
        self.work.set(self.work.get() + n as u64);
    }

    /// The sums `Σ_k e^{ihφ_k}` over `fixed ∪ free` for every order.
    fn sums(&self, free: &[f64]) -> Sums {
        let angles: Vec<f64> = self.fixed.iter().chain(free).copied().collect();
        let mut phasors = Phasors::new(&angles);
        self.add_work(self.max_order * angles.len());
        Sums(
            (1..=self.max_order)
                .map(|h| {
                    phasors
                        .next(h)
                        .iter()
                        .fold((0.0, 0.0), |(c, s), p| (c + p.0, s + p.1))
                })
                .collect(),
        )
    }

    /// [`Self::worst`] of the angles of `sums` with one angle moved from `from` to `to`, at
    /// the cost of the orders looked at (not of the angles).
    fn worst_moved(&self, sums: &Sums, from: f64, to: f64, cutoff: f64) -> f64 {
        let angles = [from, to];
        let mut phasors = Phasors::new(&angles);
        let mut worst = f64::INFINITY;
        for (k, &(c, s)) in sums.0.iter().enumerate() {
            let h = k + 1;
            let p = phasors.next(h);
            worst = worst.min((self.measure)(c - p[0].0 + p[1].0, s - p[0].1 + p[1].1));
            if worst <= cutoff {
                self.add_work(2 * h);
                return worst;
            }
        }
        self.add_work(2 * self.max_order);
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
        let candidates = (CANDIDATES_PER_FREE * free)
            .min(SCREEN_BUDGET / (self.fixed.len() + free))
            .max(REFINED);
        for _ in 0..candidates {
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
    /// `s` halved when nothing does. The sums of the phasors are taken afresh at each sweep
    /// over the angles (no drift from many updates) and a move is tried on them.
    fn refine(&self, mut x: Vec<f64>, mut value: f64) -> (f64, Vec<f64>) {
        let start = 2.0_f64.to_radians();
        let (mut s, smallest) = match self.step {
            Some(step) => (step * (start / step).round().max(1.0), step),
            None => (start, 1e-4_f64.to_radians()),
        };
        loop {
            let mut moved = false;
            let mut sums = self.sums(&x);
            for i in 0..x.len() {
                for sign in [1.0, -1.0] {
                    let y = self.snap(x[i] + sign * s);
                    let v = self.worst_moved(&sums, x[i], y, value);
                    if v > value {
                        sums.moved(x[i], y);
                        self.add_work(2 * self.max_order);
                        x[i] = y;
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

/// The phasor sums `Σ_k e^{ihφ_k}` of a set of angles, order `h` at index `h − 1`.
struct Sums(Vec<(f64, f64)>);

impl Sums {
    /// One angle moved from `from` to `to`.
    fn moved(&mut self, from: f64, to: f64) {
        let angles = [from, to];
        let mut phasors = Phasors::new(&angles);
        for (k, sum) in self.0.iter_mut().enumerate() {
            let p = phasors.next(k + 1);
            *sum = (sum.0 - p[0].0 + p[1].0, sum.1 - p[0].1 + p[1].1);
        }
    }
}

/// The phasors `e^{ihφ_k}` of some angles for `h = 1, 2, …` in turn, by the recurrence
/// `e^{ihφ} = e^{i(h−1)φ}·e^{iφ}`, started afresh every 64 orders (it drifts by ~h·1e-16).
struct Phasors<'a> {
    angles: &'a [f64],
    unit: Vec<(f64, f64)>,
    powers: Vec<(f64, f64)>,
}

impl<'a> Phasors<'a> {
    fn new(angles: &'a [f64]) -> Self {
        let unit: Vec<(f64, f64)> = angles
            .iter()
            .map(|d| {
                let (s, c) = d.sin_cos();
                (c, s)
            })
            .collect();
        Phasors {
            angles,
            powers: unit.clone(),
            unit,
        }
    }

    /// The phasors of order `h`, called with `h = 1, 2, …` in turn.
    fn next(&mut self, h: usize) -> &[(f64, f64)] {
        if h > 1 {
            if h % 64 == 0 {
                for (p, d) in self.powers.iter_mut().zip(self.angles) {
                    let (s, c) = (h as f64 * d).sin_cos();
                    *p = (c, s);
                }
            } else {
                for (p, r) in self.powers.iter_mut().zip(&self.unit) {
                    *p = (p.0 * r.0 - p.1 * r.1, p.0 * r.1 + p.1 * r.0);
                }
            }
        }
        &self.powers
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The work of a proposal (phasors evaluated) for `angles` angles, the first fixed, to
    /// order 30, with CSRR's measure.
    fn work(angles: usize) -> u64 {
        let k = angles as f64;
        let fixed = [0.0];
        let search = Search::new(&fixed, 30, None, |c: f64, s: f64| {
            (1.0 - c.hypot(s) / k).min(1.2 * (1.0 - c / k) / 2.0)
        });
        assert_eq!(search.best(angles - 1).len(), angles - 1);
        search.work.get()
    }

    /// Four times the angles, at most about four times the work: the search is linear in them
    /// (the screening of 6000 candidates a free angle, each of all the angles, and the pattern
    /// search summing every angle for each move tried made it 16 times, quadratic). The bound
    /// is 8, halfway to 16 on a log scale: the pattern search's sweeps vary with the start.
    #[test]
    fn work_grows_linearly_with_the_angles() {
        let (small, large) = (work(50), work(200));
        let ratio = large as f64 / small as f64;
        assert!(ratio < 8.0, "{small} → {large}: ×{ratio:.1}");
    }

    /// A move tried on the sums gives the worst measure of the moved angles summed afresh
    /// (within rounding).
    #[test]
    fn a_move_on_the_sums_is_the_moved_set() {
        let fixed = [0.0, 0.3];
        let search = Search::new(&fixed, 200, None, |c: f64, s: f64| -(c * c + s * s));
        let free = [1.0, 2.5, 4.0];
        let sums = search.sums(&free);
        let moved = search.worst_moved(&sums, 2.5, 2.9, f64::NEG_INFINITY);
        let fresh = search.worst(&[1.0, 2.9, 4.0], f64::NEG_INFINITY);
        assert!(
            (moved - fresh).abs() < 1e-12 * fresh.abs(),
            "{moved} {fresh}"
        );
    }
}
