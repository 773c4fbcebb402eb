//! Combine a GUM uncertainty budget: combined and expanded uncertainty, Welch–Satterthwaite
//! effective degrees of freedom, Student-t coverage factor.
//!
//! `cargo run -p calib-core --example uncertainty`

use calib_core::uncertainty::{Budget, Component, Distribution, evaluate};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let budget = Budget {
        level: 0.95,
        components: vec![
            Component {
                name: "repeatability (6 readings)".into(),
                standard_uncertainty: 0.0531,
                sensitivity: 1.0,
                dof: 5.0,
            },
            Component {
                name: "autocollimator resolution (±0.0005″, rectangular)".into(),
                standard_uncertainty: 0.0005 / Distribution::Rectangular.divisor(),
                sensitivity: 1.0,
                dof: f64::INFINITY,
            },
        ],
    };
    let result = evaluate(&budget)?;
    println!(
        "u_c = {:.4}″, ν_eff = {:?}, k = {:.3}, U = {:.4}″ ({} %)",
        result.combined_standard_uncertainty,
        result.effective_dof,
        result.coverage_factor,
        result.expanded_uncertainty,
        result.level * 100.0
    );
    for c in &result.components {
        println!(
            "  {:<52} {:.5}″  {:5.1} % of the variance",
            c.name,
            c.contribution,
            100.0 * c.variance_fraction
        );
    }
    // The repeatability dominates: ν_eff stays 5, and t(0.975, 5) = 2.571.
    assert_eq!(result.effective_dof, Some(5));
    assert!((result.coverage_factor - 2.5706).abs() < 1e-3);
    Ok(())
}
