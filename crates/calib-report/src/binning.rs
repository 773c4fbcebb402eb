//! Points reduced to their mean and spread per bin of x: a reference read at every sample gives
//! hundreds of thousands of residuals whose noise, drawn point by point, hides the systematic
//! part under a solid band.

/// One bin of points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bin {
    /// The bin's centre.
    pub x: f64,
    /// Mean of its points' y.
    pub mean: f64,
    /// Standard deviation of its points' y (0 for a single point).
    pub s: f64,
    /// Points in it.
    pub n: usize,
}

/// `points` in `bins` equal bins of x over `[0, period)` (x taken modulo the period), empty
/// bins left out, in x order.
pub fn bin(points: &[(f64, f64)], bins: usize, period: f64) -> Vec<Bin> {
    let bins = bins.max(1);
    let width = period / bins as f64;
    let mut sums = vec![(0usize, 0.0f64, 0.0f64); bins];
    for &(x, y) in points {
        if !(x.is_finite() && y.is_finite()) {
            continue;
        }
        let k = ((x.rem_euclid(period) / width) as usize).min(bins - 1);
        let (n, mean, m2) = &mut sums[k];
        // Welford: residuals of a fraction of an arcsecond on large offsets lose nothing.
        *n += 1;
        let d = y - *mean;
        *mean += d / *n as f64;
        *m2 += d * (y - *mean);
    }
    sums.iter()
        .enumerate()
        .filter(|(_, s)| s.0 > 0)
        .map(|(k, &(n, mean, m2))| Bin {
            x: (k as f64 + 0.5) * width,
            mean,
            s: if n > 1 {
                (m2 / (n - 1) as f64).sqrt()
            } else {
                0.0
            },
            n,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bins_hold_mean_and_spread() {
        let points: Vec<(f64, f64)> = (0..36_000)
            .map(|i| {
                let x = (i as f64 + 0.5) * 0.01;
                (x, if i % 2 == 0 { 1.0 } else { -1.0 } + x / 100.0)
            })
            .collect();
        let b = bin(&points, 360, 360.0);
        assert_eq!(b.len(), 360);
        assert!(b.iter().all(|b| b.n == 100 && (b.s - 1.0).abs() < 0.01));
        assert!((b[100].mean - 1.005).abs() < 1e-9 && (b[100].x - 100.5).abs() < 1e-9);
    }

    #[test]
    fn empty_bins_are_left_out_and_angles_wrap() {
        let b = bin(&[(361.0, 2.0), (-1.0, 4.0)], 360, 360.0);
        assert_eq!(
            b.iter().map(|b| (b.x, b.mean)).collect::<Vec<_>>(),
            [(1.5, 2.0), (359.5, 4.0)]
        );
    }
}
