//! The streaming reduction's end: the fine bins merged into the finest uniform grid that every
//! bin covers (see the module doc's section on sampling).

use super::{MIN_BINS, Multihead};
use crate::angle::wrap_2pi;
use std::f64::consts::TAU;

impl Multihead {
    /// The finest uniform grid of `B ≤ F/2` bins (a power of two, ≥ [`MIN_BINS`]) whose bins,
    /// centred on `b·2π/B`, all hold samples.
    pub(super) fn uniform_bins(&self) -> Option<usize> {
        let f = self.count.len();
        let mut b = f / 2;
        while b >= MIN_BINS {
            let k = f / b;
            let covered =
                (0..b).all(|c| (0..k).any(|m| self.count[(c * k + f - k / 2 + m) % f] > 0));
            if covered {
                return Some(b);
            }
            b /= 2;
        }
        None
    }

    /// The fine bins merged into `b` bins centred on `c·2π/b`; `base[j]` is added to head `j`'s
    /// mean difference (its first difference, less the nominal angle for raw readings).
    pub(super) fn merge(&self, b: usize, base: &[f64]) -> Binned {
        let f = self.count.len();
        let k = f / b;
        let fine = TAU / f as f64;
        let width = TAU / b as f64;
        let others = base.len();
        let mut out = Binned {
            width,
            n: vec![0.0; b],
            x: vec![0.0; b],
            var: vec![0.0; b],
            y: vec![vec![0.0; b]; others],
            scatter: vec![vec![0.0; b]; others],
        };
        let mut sd = vec![0.0; others];
        let mut sd2 = vec![0.0; others];
        for c in 0..b {
            let (mut n, mut sx, mut sx2) = (0.0, 0.0, 0.0);
            sd.iter_mut().for_each(|v| *v = 0.0);
            sd2.iter_mut().for_each(|v| *v = 0.0);
            for m in 0..k {
                let i = (c * k + f - k / 2 + m) % f;
                let cnt = f64::from(self.count[i]);
                if cnt == 0.0 {
                    continue;
                }
                // Offset of fine bin i's start from the centre c·width, in [−width/2, width/2).
                let shift = (m as f64 - (k / 2) as f64) * fine;
                n += cnt;
                sx += self.sum_x[i] + cnt * shift;
                sx2 += self.sum_x2[i] + 2.0 * shift * self.sum_x[i] + cnt * shift * shift;
                for j in 0..others {
                    sd[j] += self.sum_d[i * others + j];
                    sd2[j] += self.sum_d2[i * others + j];
                }
            }
            let mean_off = sx / n;
            out.n[c] = n;
            out.x[c] = c as f64 * width + mean_off;
            out.var[c] = (sx2 / n - mean_off * mean_off).max(0.0);
            for j in 0..others {
                let mean = sd[j] / n;
                out.y[j][c] = base[j] + mean;
                out.scatter[j][c] = (sd2[j] - n * mean * mean).max(0.0);
            }
        }
        out
    }
}

/// The samples reduced to a uniform grid of bins centred on `c·width`.
#[derive(Debug, Clone)]
pub(super) struct Binned {
    pub(super) width: f64,
    /// Samples per bin.
    pub(super) n: Vec<f64>,
    /// Mean reading of the first head, rad.
    pub(super) x: Vec<f64>,
    /// Variance of the first head's reading within the bin, rad².
    pub(super) var: Vec<f64>,
    /// Per other head: mean difference to the first head, rad (nominal removed from raw readings).
    pub(super) y: Vec<Vec<f64>>,
    /// Per other head: sum of squared deviations of the difference from its bin mean, rad².
    pub(super) scatter: Vec<Vec<f64>>,
}

/// The largest circular run of empty fine bins: (width, middle), radians.
pub(super) fn largest_gap(count: &[u32]) -> (f64, f64) {
    let f = count.len();
    let width = TAU / f as f64;
    let Some(start) = count.iter().position(|&c| c > 0) else {
        return (TAU, std::f64::consts::PI);
    };
    let (mut best, mut best_end, mut run) = (0usize, 0usize, 0usize);
    for step in 1..=f {
        let i = (start + step) % f;
        if count[i] == 0 {
            run += 1;
            if run > best {
                best = run;
                best_end = i;
            }
        } else {
            run = 0;
        }
    }
    let middle = (best_end as f64 + 1.0 - best as f64 / 2.0) * width;
    (best as f64 * width, wrap_2pi(middle))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_largest_gap_is_found_across_zero() {
        let mut count = vec![1u32; 360];
        for i in (350..360).chain(0..5) {
            count[i] = 0;
        }
        let (gap, at) = largest_gap(&count);
        assert!((gap.to_degrees() - 15.0).abs() < 1e-9);
        assert!(
            (at.to_degrees() - 357.5).abs() < 1e-9,
            "{}",
            at.to_degrees()
        );
    }
}
