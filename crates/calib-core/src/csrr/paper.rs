//! The CSRR method as published (Gou et al., the CSRR paper, section II-B).
//!
//! Per session `k`:
//! - the relative rotation is the DC component of `f_ab = x − y` over whole revolutions of sensor
//!   A (eqs. 4–5): the mean of the samples between the first and the last time A's reading passes
//!   its benchmark value `v_a`. It is a time average, so sampling non-uniformity biases it
//!   (eqs. 9–17) — kept as published, since users compare against the paper;
//! - sensor B's error is read where A crosses its benchmark (eq. 7): there the true angle is the
//!   same in every session, so `e_b(y_c) = Δ̂_k − d_c + const`, with `d_c` the relative angle
//!   interpolated at the crossing and `y_c = v_a − d_c` B's reading there; the crossings of all
//!   the session's revolutions are averaged;
//! - symmetrically, sensor A's error where B crosses its benchmark `v_b`:
//!   `e_a(x_c) = d_c − Δ̂_k + const`, `x_c = v_b + d_c`.
//!
//! Each session thus gives one point of each map; the maps are the periodic linear interpolation
//! of those points, mean removed. Orders above half the number of sessions cannot be resolved
//! (Nyquist over the Δ grid), which is why the method needs many sessions densely covering
//! 0…360°.

use super::CsrrError;
use crate::angle::{wrap_2pi, wrap_pi};
use crate::error_map::ErrorMap;
use crate::segment::SessionSink;
use std::f64::consts::TAU;

/// One session's contribution: a point of each map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PaperPoint {
    /// Session id.
    pub session: usize,
    /// The DC relative rotation `Δ̂_k`, rad.
    pub delta: f64,
    /// B's reading where A crossed its benchmark, rad.
    pub b_angle: f64,
    /// B's error there (up to a constant), rad.
    pub b_error: f64,
    /// A's reading where B crossed its benchmark, rad.
    pub a_angle: f64,
    /// A's error there (up to a constant), rad.
    pub a_error: f64,
}

#[derive(Debug, Default, Clone)]
struct Open {
    id: usize,
    prev: Option<(f64, f64, f64)>,
    cum_d: f64,
    cum_n: f64,
    /// `(cum_d, cum_n)` at A's first and latest benchmark crossing.
    first_a: Option<(f64, f64)>,
    last_a: Option<(f64, f64)>,
    a_crossings: u32,
    d_at_a: f64,
    b_crossings: u32,
    d_at_b: f64,
}

/// A [`SessionSink`] collecting the paper method's per-session quantities as the log streams.
#[derive(Debug, Default)]
pub(crate) struct PaperAccumulator {
    bench_a: f64,
    bench_b: f64,
    open: Option<Open>,
    points: Vec<PaperPoint>,
    no_crossing: Vec<usize>,
}

/// The fraction `f ∈ [0, 1)` of the step `from → to` at which a wrapped reading passes `v`,
/// if it does (steps are taken as the short way round).
fn crossing(from: f64, to: f64, v: f64) -> Option<f64> {
    let step = wrap_pi(to - from);
    let before = wrap_pi(from - v);
    if step == 0.0 {
        return None;
    }
    let f = -before / step;
    (0.0..1.0).contains(&f).then_some(f)
}

impl PaperAccumulator {
    /// Benchmark values of A and B, rad.
    pub(crate) fn new(bench_a: f64, bench_b: f64) -> Self {
        PaperAccumulator {
            bench_a: wrap_2pi(bench_a),
            bench_b: wrap_2pi(bench_b),
            ..Default::default()
        }
    }

    /// Each session's point, and the sessions in which a sensor never crossed its benchmark
    /// over a whole revolution.
    pub(crate) fn into_points(self) -> (Vec<PaperPoint>, Vec<usize>) {
        (self.points, self.no_crossing)
    }
}

impl SessionSink for PaperAccumulator {
    fn sample(&mut self, session: usize, _t: f64, x: f64, y: f64, d: f64, _extra: &[f64]) {
        if self.open.as_ref().is_none_or(|o| o.id != session) {
            self.open = Some(Open {
                id: session,
                ..Default::default()
            });
        }
        let o = self.open.as_mut().expect("set above");
        if let Some((px, py, pd)) = o.prev {
            if let Some(f) = crossing(px, x, self.bench_a) {
                // Cumulative sums up to the crossing (the fraction of this sample's weight
                // before it is negligible against whole revolutions; count it whole).
                let mark = (o.cum_d, o.cum_n);
                o.first_a.get_or_insert(mark);
                o.last_a = Some(mark);
                o.a_crossings += 1;
                o.d_at_a += pd + f * (d - pd);
            }
            if let Some(f) = crossing(py, y, self.bench_b) {
                o.b_crossings += 1;
                o.d_at_b += pd + f * (d - pd);
            }
        }
        o.cum_d += d;
        o.cum_n += 1.0;
        o.prev = Some((x, y, d));
    }

    fn close(&mut self, session: usize, accepted: bool) {
        let Some(o) = self.open.take().filter(|o| o.id == session) else {
            return;
        };
        if !accepted {
            return;
        }
        let (Some(first), Some(last)) = (o.first_a, o.last_a) else {
            self.no_crossing.push(session);
            return;
        };
        if last.1 <= first.1 || o.b_crossings == 0 {
            self.no_crossing.push(session);
            return;
        }
        let delta = (last.0 - first.0) / (last.1 - first.1);
        let d_a = o.d_at_a / o.a_crossings as f64;
        let d_b = o.d_at_b / o.b_crossings as f64;
        self.points.push(PaperPoint {
            session,
            delta,
            b_angle: wrap_2pi(self.bench_a - d_a),
            b_error: delta - d_a,
            a_angle: wrap_2pi(self.bench_b + d_b),
            a_error: d_b - delta,
        });
    }
}

/// The map through `(angle, error)` points by periodic linear interpolation on `points` grid
/// points, mean removed.
pub(crate) fn map_from_points(pts: &[(f64, f64)], points: usize) -> Result<ErrorMap, CsrrError> {
    if pts.len() < 3 {
        return Err(CsrrError::PaperTooFewSessions { found: pts.len() });
    }
    let mut p: Vec<(f64, f64)> = pts.iter().map(|&(a, e)| (wrap_2pi(a), e)).collect();
    p.sort_by(|a, b| a.0.total_cmp(&b.0));
    let n = points.max(1);
    let values = (0..n)
        .map(|i| {
            let th = TAU * i as f64 / n as f64;
            let k = p.partition_point(|q| q.0 <= th);
            let (lo, hi) = if k == 0 || k == p.len() {
                (p[p.len() - 1], p[0])
            } else {
                (p[k - 1], p[k])
            };
            let span = wrap_2pi(hi.0 - lo.0);
            let off = wrap_2pi(th - lo.0);
            if span == 0.0 {
                lo.1
            } else {
                lo.1 + (hi.1 - lo.1) * off / span
            }
        })
        .collect();
    Ok(ErrorMap::new(values))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crossings_are_found_across_the_wrap() {
        let v = 0.0;
        assert!(crossing(TAU - 0.1, 0.1, v).is_some_and(|f| (f - 0.5).abs() < 1e-12));
        assert!(crossing(0.1, 0.3, v).is_none());
        assert!(crossing(0.3, 0.1, 0.2).is_some_and(|f| (f - 0.5).abs() < 1e-9));
    }

    #[test]
    fn points_interpolate_periodically() {
        let pts = [(0.0, 1.0), (TAU / 3.0, -1.0), (2.0 * TAU / 3.0, 0.0)];
        let m = map_from_points(&pts, 6).unwrap();
        // Grid at 0, 60°, 120°, 180°, 240°, 300°: 1, 0, −1, −0.5, 0, 0.5 before mean removal.
        let want = [1.0, 0.0, -1.0, -0.5, 0.0, 0.5];
        for (v, w) in m.values().iter().zip(want) {
            assert!((v - w).abs() < 1e-12, "{:?}", m.values());
        }
    }
}
