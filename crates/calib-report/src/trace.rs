//! A decimated trace of a log's channels over time, in bounded memory for any log length.
//!
//! Time is cut into a fixed number of buckets, each keeping the minimum and maximum of every
//! channel; when a sample falls beyond the last bucket, neighbouring buckets are merged pairwise
//! and the bucket width doubles. Plotting each bucket's minimum and maximum keeps every peak
//! (a stop, a relative turn) visible however long the log is.

/// Min/max buckets of several channels over time.
#[derive(Debug, Clone, PartialEq)]
pub struct Trace {
    names: Vec<String>,
    buckets: usize,
    /// Time of the first sample, s.
    t0: Option<f64>,
    /// Bucket width, s.
    width: f64,
    /// Per bucket and channel: `(min, max)`; `None` while the bucket is empty.
    cells: Vec<Option<Vec<(f64, f64)>>>,
}

impl Trace {
    /// A trace of the named channels with `buckets` buckets (at least 2), starting 1 ms wide.
    pub fn new(names: &[&str], buckets: usize) -> Self {
        let buckets = buckets.max(2);
        Trace {
            names: names.iter().map(|n| n.to_string()).collect(),
            buckets,
            t0: None,
            width: 1e-3,
            cells: vec![None; buckets],
        }
    }

    /// Adds one sample: time (s) and a value per channel, in the order of the names. Samples with
    /// a non-finite time are skipped, non-finite values leave their channel's bucket unchanged.
    pub fn push(&mut self, t: f64, values: &[f64]) {
        if !t.is_finite() {
            return;
        }
        let t0 = *self.t0.get_or_insert(t);
        let mut i = ((t - t0) / self.width).max(0.0) as usize;
        while i >= self.buckets {
            self.merge();
            i = ((t - t0) / self.width) as usize;
        }
        let n = self.names.len();
        let cell = self.cells[i].get_or_insert_with(|| vec![(f64::INFINITY, f64::NEG_INFINITY); n]);
        for (c, v) in cell.iter_mut().zip(values) {
            if v.is_finite() {
                *c = (c.0.min(*v), c.1.max(*v));
            }
        }
    }

    fn merge(&mut self) {
        let half = self.buckets / 2;
        for k in 0..self.buckets {
            let merged = if k < half {
                match (
                    self.cells[2 * k].take(),
                    self.cells.get_mut(2 * k + 1).and_then(Option::take),
                ) {
                    (Some(a), Some(b)) => Some(
                        a.iter()
                            .zip(&b)
                            .map(|(x, y)| (x.0.min(y.0), x.1.max(y.1)))
                            .collect(),
                    ),
                    (a, b) => a.or(b),
                }
            } else if k == half && self.buckets % 2 == 1 {
                self.cells[2 * k].take()
            } else {
                None
            };
            self.cells[k] = merged;
        }
        self.width *= 2.0;
    }

    /// The channel names.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// Whether no sample was pushed.
    pub fn is_empty(&self) -> bool {
        self.cells.iter().all(Option::is_none)
    }

    /// Time stamp of the first sample (s, on the log's own clock), if any.
    pub fn start(&self) -> Option<f64> {
        self.t0
    }

    /// Channel `k` as points `(t, value)` with `t` in seconds since the first sample (a ROS log's
    /// stamps are seconds since 1970: absolute values would label every tick "2e9"). Each occupied
    /// bucket gives its minimum then its maximum at its centre time (at most twice the bucket
    /// count).
    pub fn series(&self, k: usize) -> Vec<(f64, f64)> {
        if self.t0.is_none() {
            return Vec::new();
        }
        self.cells
            .iter()
            .enumerate()
            .filter_map(|(i, c)| c.as_ref().map(|c| (i, c[k])))
            .filter(|(_, (lo, hi))| lo <= hi)
            .flat_map(|(i, (lo, hi))| {
                let t = (i as f64 + 0.5) * self.width;
                [(t, lo), (t, hi)]
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn memory_stays_bounded_and_extremes_survive() {
        let mut tr = Trace::new(&["x"], 64);
        for i in 0..1_000_000 {
            let t = i as f64 * 1e-3;
            let v = if i == 777_777 { 50.0 } else { (t * 0.01).sin() };
            tr.push(t, &[v]);
        }
        let s = tr.series(0);
        assert!(s.len() <= 128, "{} points", s.len());
        assert!(s.iter().any(|p| p.1 == 50.0), "the spike was lost");
        let (first, last) = (s[0].0, s[s.len() - 1].0);
        assert!(
            first < 10.0 && last > 990.0,
            "{first}…{last} does not span the log"
        );
        assert!(s.windows(2).all(|w| w[0].0 <= w[1].0));
    }

    #[test]
    fn times_count_from_the_first_sample() {
        let t0 = 1.7e9;
        let mut tr = Trace::new(&["x"], 16);
        for i in 0..1000 {
            tr.push(t0 + i as f64 * 0.01, &[i as f64]);
        }
        assert_eq!(tr.start(), Some(t0));
        let s = tr.series(0);
        assert!(s[0].0 >= 0.0 && s[0].0 < 1.0, "first point at {} s", s[0].0);
        assert!(
            s[s.len() - 1].0 < 11.0,
            "last point at {} s",
            s[s.len() - 1].0
        );
    }

    #[test]
    fn non_finite_input_is_ignored() {
        let mut tr = Trace::new(&["x", "y"], 8);
        tr.push(f64::NAN, &[1.0, 1.0]);
        assert!(tr.is_empty());
        tr.push(0.0, &[f64::NAN, 2.0]);
        tr.push(0.0001, &[3.0, f64::INFINITY]);
        assert_eq!(tr.series(0), vec![(0.0005, 3.0), (0.0005, 3.0)]);
        assert_eq!(tr.series(1), vec![(0.0005, 2.0), (0.0005, 2.0)]);
    }
}
