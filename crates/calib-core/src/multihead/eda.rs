//! Equal-division averaging (eqs. 8–9, see the module doc): the head sets, given or inferred,
//! and eq. 9 per set.

use super::bins::Binned;
use super::joint::JointFit;
use super::{ExcludedOrder, Head, MultiheadError, SetEstimate};
use crate::angle::{DEG_PER_RAD, wrap_pi};
use crate::harmonics::FourierSeries;
use crate::nufft::GridTransform;
use realfft::num_complex::Complex;
use std::f64::consts::TAU;

/// The weights of the EDA estimate of order `h` (see [`eda`]): the mean over the `K` sets that
/// see `h` of eq. 9's `−(1/N) Σ_{j∈set} D_j(h)`, so head `j` weighs `−(1/K) Σ_{sets∋j} 1/N`.
pub(super) fn eda_weights(h: usize, sets: &[Vec<usize>], others: usize) -> Vec<Complex<f64>> {
    let seeing: Vec<&Vec<usize>> = sets.iter().filter(|s| h % s.len() != 0).collect();
    let k = seeing.len().max(1) as f64;
    let mut w = vec![Complex::new(0.0, 0.0); others];
    for set in seeing {
        let n = set.len() as f64;
        for &j in set.iter().filter(|&&j| j > 0) {
            w[j - 1] -= 1.0 / (k * n);
        }
    }
    w
}

/// Eq. 9 per set on the bin-centred differences, and the sets combined order by order.
pub(super) fn eda(
    data: &Binned,
    fit: &JointFit,
    sets: &[Vec<usize>],
    max_order: usize,
) -> (FourierSeries, Vec<SetEstimate>, Vec<ExcludedOrder>) {
    let b = data.n.len();
    let mut analysis = GridTransform::new(b);
    let orders: Vec<usize> = (1..=max_order).collect();
    let (mut cos, mut sin) = (vec![0.0; max_order], vec![0.0; max_order]);
    let mut estimates = Vec::with_capacity(sets.len());
    for set in sets {
        let n = set.len() as f64;
        // μ = −(1/N) Σ_j d_j at every bin centre (d_1 = 0).
        let mut mu = vec![0.0; b];
        for &j in set.iter().filter(|&&j| j > 0) {
            for (m, y) in mu.iter_mut().zip(&fit.centred[j - 1]) {
                *m -= y / n;
            }
        }
        analysis.analyze_transpose(&mut mu, &orders, &mut cos, &mut sin);
        let scale = 2.0 / b as f64;
        estimates.push(SetEstimate {
            heads: set.clone(),
            series: FourierSeries {
                cos: cos.iter().map(|v| v * scale).collect(),
                sin: sin.iter().map(|v| v * scale).collect(),
            },
        });
    }
    let mut combined = FourierSeries::zeros(max_order);
    let mut blind = Vec::new();
    for h in 1..=max_order {
        let seeing: Vec<&SetEstimate> = estimates
            .iter()
            .filter(|e| h % e.heads.len() != 0)
            .collect();
        if seeing.is_empty() {
            blind.push(ExcludedOrder {
                order: h,
                observability: 0.0,
            });
            continue;
        }
        let k = seeing.len() as f64;
        combined.cos[h - 1] = seeing.iter().map(|e| e.series.cos[h - 1]).sum::<f64>() / k;
        combined.sin[h - 1] = seeing.iter().map(|e| e.series.sin[h - 1]).sum::<f64>() / k;
    }
    (combined, estimates, blind)
}

/// Checks one EDA set: at least 2 heads, the first among them, no head twice, equally spaced.
pub(super) fn check_set(
    heads: &[Head],
    rel: &[f64],
    set: &[usize],
    tol: f64,
) -> Result<(), MultiheadError> {
    if let Some(&bad) = set.iter().find(|&&j| j >= heads.len()) {
        return Err(MultiheadError::Options(format!(
            "EDA set names head index {bad}, but there are {} heads",
            heads.len()
        )));
    }
    let names: Vec<String> = set.iter().map(|&j| heads[j].name.clone()).collect();
    for (i, &j) in set.iter().enumerate() {
        if set[..i].contains(&j) {
            return Err(MultiheadError::DuplicateHead {
                name: heads[j].name.clone(),
            });
        }
    }
    if set.len() < 2 {
        return Err(MultiheadError::SetTooSmall { set: names });
    }
    if !set.contains(&0) {
        return Err(MultiheadError::SetWithoutFirstHead {
            set: names,
            first: heads[0].name.clone(),
        });
    }
    let n = set.len();
    let step = TAU / n as f64;
    let mut taken = vec![false; n];
    for &j in set.iter().filter(|&&j| j > 0) {
        let k = (rel[j] / step).round() as usize % n;
        if k == 0 || taken[k] || wrap_pi(rel[j] - k as f64 * step).abs() > tol {
            return Err(MultiheadError::SetNotEquallySpaced {
                set: names,
                head: heads[j].name.clone(),
                angle_deg: rel[j] * DEG_PER_RAD,
                count: n,
                step_deg: step * DEG_PER_RAD,
            });
        }
        taken[k] = true;
    }
    Ok(())
}

/// The maximal sets of heads equally spaced with the first head (see the module doc), each
/// sorted by angle.
pub(super) fn infer_sets(rel: &[f64], tol: f64) -> Vec<Vec<usize>> {
    let mut found: Vec<Vec<usize>> = Vec::new();
    for n in 2..=rel.len() {
        let step = TAU / n as f64;
        let set: Option<Vec<usize>> =
            std::iter::once(Some(0))
                .chain((1..n).map(|k| {
                    (1..rel.len()).find(|&j| wrap_pi(rel[j] - k as f64 * step).abs() <= tol)
                }))
                .collect();
        if let Some(set) = set {
            found.push(set);
        }
    }
    let counts: Vec<usize> = found.iter().map(Vec::len).collect();
    found
        .into_iter()
        .filter(|s| !counts.iter().any(|&m| m != s.len() && m % s.len() == 0))
        .collect()
}
