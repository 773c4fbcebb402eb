//! Streaming reduction of each CSRR session to fine bins of sensor A's reading.
//!
//! The joint equation (see [`super::joint`]) holds sample by sample. Samples that fall in one
//! narrow bin of A's reading `x` are replaced by their means `x̄`, `d̄` (d = x − y, unwrapped) and
//! count `n`, and `ȳ = x̄ − d̄`. Since `e_a(x) − e_b(x − d)` is smooth, the mean of the equation over
//! a bin equals the equation at the means up to a second-order term `½·e''·var(x)`; with bins of
//! 2π/65536 (≈ 19.8″) and orders up to 1000 that term is below 4·10⁻⁴ of a harmonic's amplitude at
//! order 1000, and below 10⁻⁵ at the pole-pair orders that carry large errors. The solve then costs
//! the same whatever the log's length: a session holds at most one entry per bin.

use super::SessionData;
use crate::segment::SessionSink;
use std::f64::consts::TAU;

/// One occupied bin of one session.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bin {
    /// Mean reading of sensor A, rad, in `[0, 2π)`.
    pub x: f64,
    /// Mean relative angle `x − y`, rad (continuous within the session).
    pub d: f64,
    /// Samples in the bin.
    pub n: f64,
    /// Sum of squared deviations of `d` from its mean within the bin, rad² (noise seen inside the
    /// bin, for the residual RMS).
    pub d_var_sum: f64,
}

/// A [`SessionSink`] that bins every session as it streams by.
#[derive(Debug)]
pub struct SessionBinner {
    bins_per_rev: usize,
    count: Vec<u32>,
    sum_x: Vec<f64>,
    sum_d: Vec<f64>,
    sum_d2: Vec<f64>,
    touched: Vec<u32>,
    active: Option<Active>,
    done: Vec<SessionData>,
}

#[derive(Debug)]
struct Active {
    id: usize,
    d_ref: f64,
    t_start: f64,
    t_end: f64,
    samples: u64,
    x_travel: f64,
    x_last: f64,
}

impl SessionBinner {
    /// A binner with `bins_per_rev` bins over A's revolution (65536 is a good default).
    pub fn new(bins_per_rev: usize) -> Self {
        let b = bins_per_rev.max(1);
        SessionBinner {
            bins_per_rev: b,
            count: vec![0; b],
            sum_x: vec![0.0; b],
            sum_d: vec![0.0; b],
            sum_d2: vec![0.0; b],
            touched: Vec::new(),
            active: None,
            done: Vec::new(),
        }
    }

    /// The sessions binned so far (accepted ones only), in log order.
    pub fn into_sessions(self) -> Vec<SessionData> {
        self.done
    }
}

impl SessionSink for SessionBinner {
    fn sample(&mut self, session: usize, t: f64, x: f64, _y: f64, d: f64, _extra: &[f64]) {
        if self.active.as_ref().is_none_or(|a| a.id != session) {
            self.active = Some(Active {
                id: session,
                d_ref: d,
                t_start: t,
                t_end: t,
                samples: 0,
                x_travel: 0.0,
                x_last: x,
            });
        }
        let a = self.active.as_mut().expect("set above");
        let width = TAU / self.bins_per_rev as f64;
        let i = ((x / width) as usize).min(self.bins_per_rev - 1);
        if self.count[i] == 0 {
            self.touched.push(i as u32);
        }
        self.count[i] += 1;
        self.sum_x[i] += x - i as f64 * width;
        let dd = d - a.d_ref;
        self.sum_d[i] += dd;
        self.sum_d2[i] += dd * dd;
        a.t_end = t;
        a.samples += 1;
        let step = crate::angle::wrap_pi(x - a.x_last);
        a.x_travel += step;
        a.x_last = x;
    }

    fn close(&mut self, session: usize, accepted: bool) {
        let active = self.active.take().filter(|a| a.id == session);
        let width = TAU / self.bins_per_rev as f64;
        let mut touched = std::mem::take(&mut self.touched);
        touched.sort_unstable();
        let mut bins = Vec::with_capacity(if accepted { touched.len() } else { 0 });
        for &i in &touched {
            let i = i as usize;
            let n = self.count[i] as f64;
            if accepted {
                let mean_d = self.sum_d[i] / n;
                bins.push(Bin {
                    x: i as f64 * width + self.sum_x[i] / n,
                    d: active.as_ref().map_or(0.0, |a| a.d_ref) + mean_d,
                    n,
                    d_var_sum: (self.sum_d2[i] - n * mean_d * mean_d).max(0.0),
                });
            }
            self.count[i] = 0;
            self.sum_x[i] = 0.0;
            self.sum_d[i] = 0.0;
            self.sum_d2[i] = 0.0;
        }
        touched.clear();
        self.touched = touched;
        if let (true, Some(a)) = (accepted, active) {
            self.done.push(SessionData {
                id: session,
                start_s: a.t_start,
                end_s: a.t_end,
                samples: a.samples,
                revolutions: a.x_travel.abs() / TAU,
                bins,
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bins_hold_means_and_counts() {
        let mut b = SessionBinner::new(4);
        // Two samples in bin 0, one in bin 2.
        b.sample(0, 0.0, 0.1, 0.0, 1.0, &[]);
        b.sample(0, 0.1, 0.3, 0.0, 1.2, &[]);
        b.sample(0, 0.2, 3.5, 0.0, 1.1, &[]);
        b.close(0, true);
        b.sample(1, 1.0, 0.1, 0.0, 5.0, &[]);
        b.close(1, false);
        let s = b.into_sessions();
        assert_eq!(s.len(), 1);
        let bins = &s[0].bins;
        assert_eq!(bins.len(), 2);
        assert!((bins[0].x - 0.2).abs() < 1e-12 && (bins[0].d - 1.1).abs() < 1e-12);
        assert_eq!(bins[0].n, 2.0);
        assert!((bins[0].d_var_sum - 0.02).abs() < 1e-12);
        assert!((bins[1].x - 3.5).abs() < 1e-12 && bins[1].n == 1.0);
        assert_eq!(s[0].samples, 3);
    }
}
