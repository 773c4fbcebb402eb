//! Uncertainty budgets in the terms of the GUM (JCGM 100:2008), as in section 3.3 and Table 3 of
//! the shift-angle paper (Hsieh, Watanabe, Hsu 2022, eqs. 10–12).
//!
//! - Each [`Component`] has a standard uncertainty `u(x_i)`, a sensitivity coefficient `c_i` and
//!   degrees of freedom `ν_i` (`∞` for a value known exactly, e.g. from a certificate with no
//!   stated reliability). [`Distribution`] turns a half-width into a standard uncertainty;
//!   [`dof_from_relative_uncertainty`] gives `ν = ½ (Δu/u)⁻²` (GUM G.4.2).
//! - [`evaluate`]: combined standard uncertainty `u_c = sqrt(Σ (c_i u_i)²)` (GUM 5.1.2, the
//!   paper's eq. 10), Welch–Satterthwaite effective degrees of freedom
//!   `ν_eff = u_c⁴ / Σ (c_i u_i)⁴/ν_i` rounded down (GUM G.4.1), the coverage factor
//!   `k = t_{(1+p)/2}(ν_eff)` of the Student t distribution (two-sided, level `p`; the normal
//!   quantile for `ν_eff = ∞`) and the expanded uncertainty `U = k·u_c`.
//! - [`estler_sensitivity`]: the sensitivity of an encoder error to a polygon's pitch deviations
//!   in a closure calibration, `1/n − 8/(9n²)` (Estler 1998, the paper's eq. 11).
//!
//! # The paper's Table 3
//! Its components as printed (`u` rounded to 0.1 mas) give `u_c = 0.0692″`,
//! `ν_eff = 13.95 → 13`, `k = t_{0.975}(13) = 2.160` and `U = 0.150″`: the table's `k = 2.16` is
//! right and the text's `k = 2.31` is a misprint (2.31 is `t_{0.975}(8)`). This module's tests
//! hold that vector. Derived again from section 3.3's unrounded inputs (`0.13″/√6`, `0.07″/√3`, …)
//! the same budget gives `u_c = 0.0694″`, `ν_eff = 14.16 → 14`, `k = 2.145`, `U = 0.149″`: `ν_eff`
//! sits near an integer, so rounding the inputs moves it by one; `U` is 0.15″ either way.

use statrs::distribution::{ContinuousCDF, Normal, StudentsT};

/// The distribution of a quantity known by a half-width `a`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Distribution {
    /// Uniform over `±a`: `u = a/√3`.
    Rectangular,
    /// Triangular over `±a`: `u = a/√6`.
    Triangular,
    /// Arcsine (U-shaped) over `±a`: `u = a/√2`.
    UShaped,
}

impl Distribution {
    /// All distributions with their budget names, for error messages.
    pub const NAMES: [&str; 3] = ["rectangular", "triangular", "u-shaped"];

    /// The distribution named `name` (`rectangular`, `triangular`, `u-shaped`).
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "rectangular" => Some(Self::Rectangular),
            "triangular" => Some(Self::Triangular),
            "u-shaped" => Some(Self::UShaped),
            _ => None,
        }
    }
    /// The divisor that turns a half-width into a standard uncertainty.
    pub fn divisor(self) -> f64 {
        match self {
            Self::Rectangular => 3f64.sqrt(),
            Self::Triangular => 6f64.sqrt(),
            Self::UShaped => 2f64.sqrt(),
        }
    }
}

/// Degrees of freedom of an uncertainty whose relative uncertainty is `rel` (GUM G.4.2):
/// `ν = ½ rel⁻²`; `rel = 0` gives `∞`.
pub fn dof_from_relative_uncertainty(rel: f64) -> f64 {
    if rel == 0.0 {
        f64::INFINITY
    } else {
        0.5 / (rel * rel)
    }
}

/// The sensitivity of the encoder's error to a pitch deviation of an `n`-face polygon in a
/// closure cross-calibration, `1/n − 8/(9n²)` (Estler, J. Res. NIST 103 (1998) 141; the paper's
/// eq. 11): `0.0401` for `n = 24`.
pub fn estler_sensitivity(faces: usize) -> f64 {
    let n = faces as f64;
    1.0 / n - 8.0 / (9.0 * n * n)
}

/// One contribution to a budget.
#[derive(Debug, Clone, PartialEq)]
pub struct Component {
    /// Its name, as the budget gives it.
    pub name: String,
    /// Standard uncertainty `u(x_i)`, in the budget's unit (arcsec for calib).
    pub standard_uncertainty: f64,
    /// Sensitivity coefficient `c_i`.
    pub sensitivity: f64,
    /// Degrees of freedom `ν_i`, possibly `f64::INFINITY`.
    pub dof: f64,
}

/// A budget: components and the coverage probability of the expanded uncertainty.
#[derive(Debug, Clone, PartialEq)]
pub struct Budget {
    /// Coverage probability, in `(0, 1)` (GUM's level of confidence), e.g. 0.95.
    pub level: f64,
    /// The components.
    pub components: Vec<Component>,
}

/// One component's share of the result.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
pub struct Contribution {
    /// The component's name.
    pub name: String,
    /// `u(x_i)`.
    pub standard_uncertainty: f64,
    /// `c_i`.
    pub sensitivity: f64,
    /// `|c_i| u(x_i)`.
    pub contribution: f64,
    /// `(c_i u_i)² / u_c²`: its share of the combined variance.
    pub variance_fraction: f64,
    /// `ν_i`; `None` for infinity (JSON has no infinity).
    pub dof: Option<f64>,
}

/// The result of [`evaluate`].
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
pub struct BudgetResult {
    /// Coverage probability.
    pub level: f64,
    /// `u_c`.
    pub combined_standard_uncertainty: f64,
    /// Welch–Satterthwaite `ν_eff`, rounded down; `None` for infinity.
    pub effective_dof: Option<u64>,
    /// `ν_eff` before rounding; `None` for infinity.
    pub effective_dof_unrounded: Option<f64>,
    /// `k`.
    pub coverage_factor: f64,
    /// `U = k u_c`.
    pub expanded_uncertainty: f64,
    /// One row per component, in the budget's order.
    pub components: Vec<Contribution>,
}

/// Why a budget cannot be evaluated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum UncertaintyError {
    /// The budget has no components.
    #[error("the budget has no components: add at least one [[component]] table")]
    Empty,
    /// The level is outside (0, 1).
    #[error(
        "level = {level}: the coverage probability must lie strictly between 0 and 1, e.g. 0.95"
    )]
    BadLevel {
        /// The level given.
        level: f64,
    },
    /// A component's numbers are unusable.
    #[error("component `{name}`: {message}")]
    BadComponent {
        /// The component.
        name: String,
        /// What is wrong and what to write instead.
        message: String,
    },
    /// All contributions are zero.
    #[error("every component contributes zero: the combined uncertainty is 0")]
    AllZero,
}

/// The two-sided coverage factor at level `p` for `dof` degrees of freedom (normal for `∞`).
pub fn coverage_factor(dof: f64, level: f64) -> Result<f64, UncertaintyError> {
    if !(level > 0.0 && level < 1.0) {
        return Err(UncertaintyError::BadLevel { level });
    }
    let q = 0.5 + level / 2.0;
    // Past 1e7 degrees of freedom t and normal quantiles agree to 1e-7; statrs's t quantile
    // loses accuracy there.
    if dof.is_infinite() || dof > 1e7 {
        let normal = Normal::new(0.0, 1.0).map_err(|_| UncertaintyError::BadLevel { level })?;
        return Ok(normal.inverse_cdf(q));
    }
    let t = StudentsT::new(0.0, 1.0, dof).map_err(|_| UncertaintyError::BadComponent {
        name: "(effective degrees of freedom)".into(),
        message: format!("{dof} degrees of freedom: must be at least 1"),
    })?;
    Ok(t.inverse_cdf(q))
}

/// Combines a budget (see the module docs).
pub fn evaluate(budget: &Budget) -> Result<BudgetResult, UncertaintyError> {
    if budget.components.is_empty() {
        return Err(UncertaintyError::Empty);
    }
    if !(budget.level > 0.0 && budget.level < 1.0) {
        return Err(UncertaintyError::BadLevel {
            level: budget.level,
        });
    }
    for c in &budget.components {
        let bad = |message: &str| UncertaintyError::BadComponent {
            name: c.name.clone(),
            message: message.into(),
        };
        if !(c.standard_uncertainty.is_finite() && c.standard_uncertainty >= 0.0) {
            return Err(bad("the standard uncertainty must be a finite number ≥ 0"));
        }
        if !c.sensitivity.is_finite() {
            return Err(bad("the sensitivity coefficient must be a finite number"));
        }
        if c.dof.is_nan() || c.dof < 1.0 {
            return Err(bad("degrees of freedom must be at least 1, or \"inf\""));
        }
    }
    let var: f64 = budget
        .components
        .iter()
        .map(|c| (c.sensitivity * c.standard_uncertainty).powi(2))
        .sum();
    if var == 0.0 {
        return Err(UncertaintyError::AllZero);
    }
    let uc = var.sqrt();
    let denom: f64 = budget
        .components
        .iter()
        .filter(|c| c.dof.is_finite())
        .map(|c| (c.sensitivity * c.standard_uncertainty).powi(4) / c.dof)
        .sum();
    let nu = if denom > 0.0 {
        var * var / denom
    } else {
        f64::INFINITY
    };
    // GUM G.4.1: round ν_eff down to the next lower integer (conservative k).
    let nu_used = if nu.is_finite() {
        nu.floor().max(1.0)
    } else {
        nu
    };
    let k = coverage_factor(nu_used, budget.level)?;
    Ok(BudgetResult {
        level: budget.level,
        combined_standard_uncertainty: uc,
        effective_dof: nu_used.is_finite().then_some(nu_used as u64),
        effective_dof_unrounded: nu.is_finite().then_some(nu),
        coverage_factor: k,
        expanded_uncertainty: k * uc,
        components: budget
            .components
            .iter()
            .map(|c| {
                let contribution = (c.sensitivity * c.standard_uncertainty).abs();
                Contribution {
                    name: c.name.clone(),
                    standard_uncertainty: c.standard_uncertainty,
                    sensitivity: c.sensitivity,
                    contribution,
                    variance_fraction: contribution * contribution / var,
                    dof: c.dof.is_finite().then_some(c.dof),
                }
            })
            .collect(),
    })
}

/// How a component of a map's uncertainty was evaluated (GUM 4.2 and 4.3).
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize, schemars::JsonSchema,
)]
pub enum Evaluation {
    /// Type A: from the statistics of the data (the fit's residual).
    #[serde(rename = "A")]
    TypeA,
    /// Type B: from a model of what the data cannot show directly.
    #[serde(rename = "B")]
    TypeB,
}

/// One component of a map's uncertainty budget: a standard uncertainty at every table point
/// (one value when it is the same everywhere), radians.
#[derive(Debug, Clone, PartialEq)]
pub struct MapComponent {
    /// What it is, in the GUM's words.
    pub name: String,
    /// Type A or B.
    pub evaluation: Evaluation,
    /// Standard uncertainty per table point, or one value for all, radians.
    pub u: Vec<f64>,
}

impl MapComponent {
    /// The component at table point `i`.
    pub fn at(&self, i: usize) -> f64 {
        if self.u.len() == 1 {
            self.u[0]
        } else {
            self.u[i]
        }
    }

    /// RMS over the table's points, radians.
    pub fn rms(&self) -> f64 {
        (self.u.iter().map(|v| v * v).sum::<f64>() / self.u.len().max(1) as f64).sqrt()
    }
}

/// The standard uncertainty of an error map at each of its table points, with its budget: the
/// components are independent and combine in quadrature (GUM 5.1.2 with unit sensitivities),
/// `u(θ_i) = sqrt(Σ_j u_j(θ_i)²)`.
#[derive(Debug, Clone, PartialEq)]
pub struct MapUncertainty {
    /// Combined standard uncertainty per table point, radians.
    pub u: Vec<f64>,
    /// The components.
    pub components: Vec<MapComponent>,
}

impl MapUncertainty {
    /// Combines `components` over a table of `points` points.
    pub fn combine(points: usize, components: Vec<MapComponent>) -> Self {
        let u = (0..points)
            .map(|i| {
                components
                    .iter()
                    .map(|c| c.at(i).powi(2))
                    .sum::<f64>()
                    .sqrt()
            })
            .collect();
        MapUncertainty { u, components }
    }

    /// Largest `u`, radians.
    pub fn max(&self) -> f64 {
        self.u.iter().copied().fold(0.0, f64::max)
    }

    /// RMS of `u` over the points, radians.
    pub fn rms(&self) -> f64 {
        (self.u.iter().map(|v| v * v).sum::<f64>() / self.u.len().max(1) as f64).sqrt()
    }

    /// Median of `u`, radians.
    pub fn median(&self) -> f64 {
        let mut v = self.u.clone();
        if v.is_empty() {
            return 0.0;
        }
        let mid = v.len() / 2;
        v.select_nth_unstable_by(mid, f64::total_cmp);
        v[mid]
    }
}

/// The standard uncertainty that linear interpolation between the table's points adds, for a
/// map with these harmonics (radians) on `points` points: `A·(hδ)²/8` bounds the error of
/// interpolating `A·cos hθ` over a step `δ = 2π/points`; summed over the orders as a half-width
/// with a rectangular distribution (`/√3`). Zero at the table points themselves.
pub fn interpolation_uncertainty(harmonics: &[crate::Harmonic], points: usize) -> f64 {
    let step = std::f64::consts::TAU / points.max(1) as f64;
    let bound: f64 = harmonics
        .iter()
        .map(|h| h.amplitude * (h.order as f64 * step).powi(2) / 8.0)
        .sum();
    bound / 3f64.sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn comp(name: &str, u: f64, c: f64, dof: f64) -> Component {
        Component {
            name: name.into(),
            standard_uncertainty: u,
            sensitivity: c,
            dof,
        }
    }

    /// The paper's Table 3 as printed.
    fn table3() -> Budget {
        Budget {
            level: 0.95,
            components: vec![
                comp("repeatability", 0.0531, 1.0, 5.0),
                comp("autocollimator resolution", 0.0003, 1.0, 50.0),
                comp("autocollimator traceability", 0.0050, 1.0, 50.0),
                comp("autocollimator error", 0.0404, 1.0, 50.0),
                comp("encoder resolution", 0.0101, 1.0, 50.0),
                comp("residual setup error", 0.0001, 1.0, 50.0),
                comp("pitch repeatability", 0.0490, 0.0401, 5.0),
                comp("setup error", 0.0144, 1.0, 50.0),
            ],
        }
    }

    /// The same budget derived from section 3.3's unrounded inputs.
    fn table3_derived() -> Budget {
        let rect = Distribution::Rectangular.divisor();
        let nu10 = dof_from_relative_uncertainty(0.10);
        Budget {
            level: 0.95,
            components: vec![
                comp("repeatability", 0.13 / 6f64.sqrt(), 1.0, 5.0),
                comp("autocollimator resolution", 0.0005 / rect, 1.0, nu10),
                comp("autocollimator traceability", 0.01 / 2.0, 1.0, nu10),
                comp("autocollimator error", 0.07 / rect, 1.0, nu10),
                comp("encoder resolution", 0.02 / rect, 1.0, nu10),
                comp("residual setup error", 0.00005 / rect, 1.0, nu10),
                comp(
                    "pitch repeatability",
                    0.12 / 6f64.sqrt(),
                    estler_sensitivity(24),
                    5.0,
                ),
                comp("setup error", 0.025 / rect, 1.0, nu10),
            ],
        }
    }

    #[test]
    fn the_papers_table_3() {
        let r = evaluate(&table3()).unwrap();
        // Table 3: u_c 0.07″ (0.0692 unrounded), ν_eff 13, k 2.16, U 0.15″.
        assert!(
            (r.combined_standard_uncertainty - 0.0692).abs() < 5e-4,
            "{r:?}"
        );
        assert_eq!(r.effective_dof, Some(13));
        assert!(
            (r.coverage_factor - 2.1604).abs() < 1e-4,
            "{}",
            r.coverage_factor
        );
        assert!((r.expanded_uncertainty - 0.15).abs() < 1e-3);
        assert!((estler_sensitivity(24) - 0.0401).abs() < 5e-5);
        assert_eq!(dof_from_relative_uncertainty(0.1).round(), 50.0);
        let d = evaluate(&table3_derived()).unwrap();
        assert!((d.combined_standard_uncertainty - 0.0694).abs() < 5e-4);
        assert_eq!(d.effective_dof, Some(14));
        assert!(
            (d.coverage_factor - 2.1448).abs() < 1e-4,
            "{}",
            d.coverage_factor
        );
        assert!((d.expanded_uncertainty - 0.149).abs() < 1e-3);
    }

    #[test]
    fn coverage_factors_match_tables() {
        // Reference values: GUM Table G.2 and statrs's documented t(10) quantile.
        assert!((coverage_factor(10.0, 0.95).unwrap() - 2.228138852).abs() < 1e-8);
        assert!((coverage_factor(8.0, 0.95).unwrap() - 2.306).abs() < 1e-3);
        assert!((coverage_factor(f64::INFINITY, 0.95).unwrap() - 1.959964).abs() < 1e-6);
        assert!((coverage_factor(f64::INFINITY, 0.9973).unwrap() - 3.0).abs() < 1e-3);
        assert!(coverage_factor(5.0, 1.0).is_err());
    }

    #[test]
    fn infinite_dof_and_bad_components() {
        let r = evaluate(&Budget {
            level: 0.95,
            components: vec![
                comp("a", 0.3, 1.0, f64::INFINITY),
                comp("b", 0.4, -1.0, f64::INFINITY),
            ],
        })
        .unwrap();
        assert!((r.combined_standard_uncertainty - 0.5).abs() < 1e-12);
        assert_eq!(r.effective_dof, None);
        assert!((r.components[1].variance_fraction - 0.64).abs() < 1e-12);
        let err = evaluate(&Budget {
            level: 0.95,
            components: vec![comp("noisy", -1.0, 1.0, 3.0)],
        })
        .unwrap_err();
        assert!(err.to_string().contains("`noisy`"));
    }
}
