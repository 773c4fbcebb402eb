//! Gaps under the map: readings a pass went through without a sample (lost samples, lines cut
//! from a log), and readings no pass measured.
//!
//! # A pass's gap
//! The map's value at a grid point is interpolated between the samples either side of its
//! crossing (module docs, "Method"). Where samples are missing the two samples either side are
//! far apart, and whatever the difference does between them (a commanded reference's ripple,
//! 2.9° a period at 21 pole pairs; the DUT's own fine orders) is lost: the cubic draws a smooth
//! curve across, and a model fitted elsewhere (the ripple) is then subtracted from a value that
//! never held it. So a step between two consecutive moving samples whose travel is more than
//! [`GAP_RATIO`] times the larger of its neighbours' in the same run (the sample spacing there),
//! for the DUT and for the reference alike, is a **pass gap** ([`PassGap`]): its crossings are
//! not measurements and are left out of the statistics, and the neighbouring steps are
//! interpolated without the node across it. Both must jump: a rotor that lurches between two
//! samples of a steady commanded angle (stick-slip at the motor's cogging: mjbots' own dump
//! has steps 2.6 times their neighbours' every 8 to 17 samples) is motion, measured by the
//! smooth reference, not samples lost; samples lost jump both readings by the same ratio. A grid
//! point inside it holds the other passes' measurements (the other direction's corrected by
//! half the reversal next to it, module `ends`, where only that direction measured it); where
//! no pass measured it, the point is bridged ([`BridgeBound`]) or the map ends there.
//!
//! A step is judged against its neighbours, not against a nominal rate (a dump's times are
//! nominal: its lost lines show in its readings only), so speed changes and ramps (each step
//! close to the next) are not gaps; sampling jitter would need instants off by a third of a
//! period to give a step 2.5 times both neighbours. With an encoder reference on the shaft a
//! lurch over 2.5 sample spacings does count: between those samples nothing was measured.
//!
//! # A bridged gap's uncertainty
//! A point no pass measured, between the measured points `a` and `b = a + W`, is the straight
//! line `L` between them (after any fitted model is taken out: the model is subtracted only
//! where it was measured with the data). The DUT's error `f` differs from it by
//! `f(x) − L(x) = f″(ξ)·(x − a)(x − b)/2`; for harmonics of amplitude `A_h` that is at most
//! `Σ A_h·(1 − cos(h·W/2))`, the sagitta of each over the gap's width. An error is a function
//! of the angle, the same in the gap as elsewhere, and each of its harmonics meets every phase
//! over a turn: so the largest departure `D` of the measured map from the chord of any window
//! of the same width `W` lying wholly in measured points ([`BridgeBound`]) bounds what the gap
//! can hide, to the variation of the harmonics' phases over one gap width (the noise of the
//! measured points only adds to `D`). A bridged point's `u` is `sqrt(max(u_a, u_b)² + D²)`:
//! the line's ends' and the bound taken whole as a standard uncertainty (not `D/√3`: the
//! departure peaks in the gap's middle, where the bound is met, not spread evenly within it).
//!
//! # What it cannot see
//! A single lost sample: its step is twice its neighbours' and is interpolated as measured
//! (the cubic's error there is about 7 times the centred one's, `(1/6)·(h·Δθ)⁴` of an order-`h`
//! amplitude). Two gaps one sample apart: each step is judged against the other, wide one.

use crate::angle::{wrap_2pi, wrap_pi};

/// A step more than this many times the larger of its neighbours' travel is a pass gap.
pub const GAP_RATIO: f64 = 2.5;

/// Readings one pass went through between two samples too far apart to interpolate between.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PassGap {
    /// Whether the pass's readings increased.
    pub increasing: bool,
    /// The DUT's readings at the gap's ends, radians in `[0, 2π)` (`from` the first sample's).
    pub from: f64,
    /// The reading of the sample after the gap, radians in `[0, 2π)`.
    pub to: f64,
    /// The times of the two samples, seconds.
    pub t: (f64, f64),
    /// The step's travel over the larger neighbouring step's.
    pub ratio: f64,
    /// The grid points the step crossed past the approach after a reversal, unwrapped grid
    /// indices (`first..=last`).
    pub(super) grid: (i64, i64),
}

/// What the map holds at a pass gap's grid points.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(super) struct GapCover {
    /// Measured in both directions by other passes.
    pub(super) both: usize,
    /// Measured in one direction only (corrected by half the reversal).
    pub(super) one: usize,
    /// Measured by no pass: bridged.
    pub(super) bridged: usize,
    /// Outside the map (it ends there).
    pub(super) outside: usize,
}

/// Pass gaps over the same readings, grouped: a gap joins the first group holding one of its
/// grid points (of `points` a turn), in the order met.
pub(super) fn groups(gaps: &[PassGap], points: usize) -> Vec<Vec<&PassGap>> {
    let mut label: Vec<Option<usize>> = vec![None; points];
    let mut groups: Vec<Vec<&PassGap>> = Vec::new();
    for g in gaps {
        let bins = || (g.grid.0..=g.grid.1).map(|k| k.rem_euclid(points as i64) as usize);
        let id = bins().find_map(|i| label[i]).unwrap_or_else(|| {
            groups.push(Vec::new());
            groups.len() - 1
        });
        groups[id].push(g);
        bins().for_each(|i| label[i] = Some(id));
    }
    groups
}

/// The warning of a group of pass gaps over the same readings: where, which passes, and what
/// the map holds there (`cover`, over the grid points any of them crossed).
pub(super) fn group_warning(group: &[&PassGap], cover: GapCover) -> String {
    let pass = |g: &PassGap| {
        format!(
            "the {} pass at t {:.3}–{:.3} s, {:.1} times the sample step next to it",
            if g.increasing {
                "increasing"
            } else {
                "decreasing"
            },
            g.t.0,
            g.t.1,
            g.ratio
        )
    };
    // The readings between the gaps' samples, unwrapped from the first gap's lower end.
    let first = group[0];
    let base = first.from.min(first.to);
    let unwrap = |a: f64| base + wrap_pi(a - base);
    let (lo, hi) = group
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), g| {
            let (a, b) = (unwrap(g.from), unwrap(g.to));
            (lo.min(a.min(b)), hi.max(a.max(b)))
        });
    const LISTED: usize = 3;
    let mut passes: Vec<String> = group.iter().take(LISTED).map(|g| pass(g)).collect();
    if group.len() > LISTED {
        passes.push(format!("{} more", group.len() - LISTED));
    }
    let mut done = Vec::new();
    if cover.both > 0 {
        done.push(format!(
            "{} hold the other passes' measurements in both directions",
            cover.both
        ));
    }
    if cover.one > 0 {
        done.push(format!(
            "{} hold one direction's measurements, corrected by half the reversal next to them",
            cover.one
        ));
    }
    if cover.bridged > 0 {
        done.push(format!(
            "{} were measured by no pass and are bridged by a straight line, u holding what the gap can hide",
            cover.bridged
        ));
    }
    if cover.outside > 0 {
        done.push(format!(
            "{} were measured by no pass and lie outside the map, which ends there",
            cover.outside
        ));
    }
    format!(
        "{} has no sample between the readings {:.3}° and {:.3}° ({}): its values there, interpolated across \
         the gap, are not used; of the {} grid point(s) there {}; record without losing samples to measure them",
        if group.len() == 1 {
            "one pass".to_string()
        } else {
            format!("each of {} passes", group.len())
        },
        wrap_2pi(lo).to_degrees(),
        wrap_2pi(hi).to_degrees(),
        passes.join("; "),
        cover.both + cover.one + cover.bridged + cover.outside,
        done.join(", ")
    )
}

/// The largest departure of the measured map from the chord over any window of `width` grid
/// steps lying wholly in measured points (module docs): what a bridged gap of that width can
/// hide. `None` where no such window exists.
pub(super) fn bridge_bound(
    values: &[f64],
    measured: &[bool],
    width: usize,
    circular: bool,
) -> Option<f64> {
    let n = values.len();
    if width < 2 || width >= n {
        return None;
    }
    let starts = if circular { n } else { n - width };
    let mut worst: Option<f64> = None;
    for a in 0..starts {
        let at = |j: usize| (a + j) % n;
        if !(0..=width).all(|j| measured[at(j)]) {
            continue;
        }
        let (ya, yb) = (values[a], values[at(width)]);
        let d = (1..width)
            .map(|j| (values[at(j)] - (ya + (yb - ya) * j as f64 / width as f64)).abs())
            .fold(0.0, f64::max);
        worst = Some(worst.map_or(d, |w: f64| w.max(d)));
    }
    worst
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    /// One harmonic over a turn: the bound is its sagitta over the width, `A·(1 − cos(hW/2))`,
    /// to the grid's phase resolution.
    #[test]
    fn the_bound_of_a_harmonic_is_its_sagitta() {
        let n = 3600;
        let values: Vec<f64> = (0..n)
            .map(|i| (3.0 * TAU * i as f64 / n as f64 + 0.3).cos())
            .collect();
        let mut measured = vec![true; n];
        measured[100..120].fill(false);
        let width = 60;
        let sagitta = 1.0 - (3.0 * TAU * width as f64 / n as f64 / 2.0).cos();
        let b = bridge_bound(&values, &measured, width, true).unwrap();
        assert!((b - sagitta).abs() < 1e-3 * sagitta, "{b} {sagitta}");
        assert!(bridge_bound(&values, &vec![false; n], width, true).is_none());
    }
}
