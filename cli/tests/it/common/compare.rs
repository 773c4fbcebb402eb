//! Maps compared with a known truth.
//!
//! Declared by the tests that compare: `#[path = "common/compare.rs"] mod compare;`.

/// Largest |table − expected| over the table's grid `(angle°, error″)`, both with their mean
/// removed (a map is known up to a constant), arcsec.
pub fn max_diff_zero_mean(got: &[(f64, f64)], expected: impl Fn(f64) -> f64) -> f64 {
    let t: Vec<f64> = got.iter().map(|(a, _)| expected(*a)).collect();
    let mean_g = got.iter().map(|r| r.1).sum::<f64>() / got.len() as f64;
    let mean_t = t.iter().sum::<f64>() / t.len() as f64;
    got.iter()
        .zip(&t)
        .map(|((_, g), t)| ((g - mean_g) - (t - mean_t)).abs())
        .fold(0.0, f64::max)
}
