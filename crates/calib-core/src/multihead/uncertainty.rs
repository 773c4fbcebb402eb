//! The map's uncertainty (see the module doc's section on uncertainty).

use super::Method;
use crate::harmonics::FourierSeries;
use crate::uncertainty::{Evaluation, MapComponent, MapUncertainty, interpolation_uncertainty};
use realfft::num_complex::Complex;

/// The standard uncertainty, at any angle, that the noise of the differences leaves in the map.
///
/// Every order's estimate is linear in the heads' Fourier coefficients, `s_h = Σ_j w_j D_j(h)`
/// with `D_j(h) = (1/B) Σ_c y_jc e^{−ihx_c}` over the `B` bins ([`joint_weights`](super::joint::joint_weights) for eq. 3,
/// [`eda_weights`](super::eda::eda_weights) for eq. 9). With the bins' mean errors independent from bin to bin, the
/// coefficients' noise has the covariance `G_jk = E[δD_j δD̄_k] = (1/B²) Σ_c cov(y_jc, y_kc)` at
/// every order, estimated from the bins' residuals `r_jc` of the joint fit,
///
/// `Ĝ_jk = Σ_c r_jc r_kc / (B·(B − P/(J−1)))`  (`P` unknowns over the `(J−1)·B` bin means),
///
/// which keeps the correlation between the differences: every `d_j = r_j − r_1` holds the first
/// head's noise, so with `J` equally spaced heads of equal noise the first head's share of
/// `var s_h` is `(J/2)`-fold the others' together. Cosine and sine of `δs_h` have the same
/// variance and no correlation, so `m = Σ_h 2 Re(s_h e^{ihx})` has, at every angle,
///
/// `u_fit² = Σ_h 2 Σ_jk Re(w_j w̄_k) Ĝ_jk`
///
/// over the fitted orders: left-out (blind) orders are warnings, not uncertainty. Returned is
/// each order's term `2 Σ_jk Re(w_j w̄_k) Ĝ_jk`, also the variance of each of the order's cosine
/// and sine coefficients (zeros where the bins leave no degrees of freedom).
pub(super) fn order_variances(
    residuals: &[Vec<f64>],
    unknowns: usize,
    orders: &[usize],
    weights: impl Fn(usize) -> Vec<Complex<f64>>,
) -> Vec<f64> {
    let others = residuals.len();
    let b = residuals.first().map_or(0, Vec::len);
    let data = (others * b) as f64;
    let dof = data - unknowns as f64;
    if b == 0 || dof <= 0.0 {
        return vec![0.0; orders.len()];
    }
    let scale = data / dof / (b as f64 * b as f64);
    let g: Vec<Vec<f64>> = residuals
        .iter()
        .map(|rj| {
            residuals
                .iter()
                .map(|rk| scale * rj.iter().zip(rk).map(|(a, c)| a * c).sum::<f64>())
                .collect()
        })
        .collect();
    orders
        .iter()
        .map(|&h| order_variance(&g, &weights(h)))
        .collect()
}

/// The variance one order adds to the map at every angle, `2 Σ_jk Re(w_j w̄_k) G_jk`, from the
/// order's weights `w` on the other heads' coefficients and their noise covariance `G` (see
/// `order_variances`; [`crate::plan::multihead`] calls it with a planned `G`).
pub fn order_variance(g: &[Vec<f64>], w: &[Complex<f64>]) -> f64 {
    let mut v = 0.0;
    for (j, gj) in g.iter().enumerate() {
        for (k, gjk) in gj.iter().enumerate() {
            v += (w[j] * w[k].conj()).re * gjk;
        }
    }
    2.0 * v
}

/// The budget of the map of `points` points: the fit's noise `u_fit = sqrt(Σ_h v_h)` ([`order_variances`], Type A),
/// the linear interpolation of the table between its points ([`interpolation_uncertainty`],
/// Type B), and `u` never below `floor`, the detection limit of the orders tested
/// ([`crate::detection`]).
pub(super) fn map_uncertainty(
    method: Method,
    u_fit: f64,
    floor: f64,
    series: &FourierSeries,
    points: usize,
) -> MapUncertainty {
    let fit = match method {
        Method::Joint => "the joint fit",
        Method::Eda => "the equal-division average",
    };
    let combined = MapUncertainty::combine(
        points,
        vec![
            MapComponent {
                name: format!("noise of the readings propagated through {fit}"),
                evaluation: Evaluation::TypeA,
                u: vec![u_fit],
            },
            MapComponent {
                name: "linear interpolation between table points".into(),
                evaluation: Evaluation::TypeB,
                u: vec![interpolation_uncertainty(&series.harmonics(), points)],
            },
        ],
    );
    crate::detection::apply_floor(combined, floor)
}
