//! `calib uncertainty`: load a budget → combine (GUM) → render.

use crate::summary::TextTable;
use anyhow::Context as _;
use calib_core::uncertainty::{self, BudgetResult};
use std::fmt::Write as _;
use std::path::PathBuf;

/// Combine a GUM uncertainty budget: u_c, ν_eff, k and the expanded uncertainty U.
///
/// The combined standard uncertainty u_c = √Σ(c_i·u(x_i))², the Welch–Satterthwaite effective
/// degrees of freedom ν_eff (rounded down), the coverage factor k of the Student t distribution
/// at the budget's level (two-sided) and U = k·u_c (JCGM 100:2008).
///
/// BUDGET is TOML, values in arcsec, one [[component]] table per contribution:
///
///   level = 0.95                # coverage probability (default 0.95, two-sided Student t)
///
///   [[component]]
///   name = "Repeatability of angle error measurement"
///   u = 0.0531                  # the standard uncertainty, given directly, OR
///   # half_width = 0.0005       #   a half-width with its distribution:
///   # distribution = "rectangular"   # rectangular a/√3, triangular a/√6, u-shaped a/√2, OR
///   # value = 0.13              #   a value and the divisor that makes it standard
///   # divisor = 2.449           #   (√6 for a mean of 6 readings, k for a certificate's U)
///   sensitivity = 1             # c_i (default 1), OR
///   # estler_faces = 24         #   c_i = 1/n − 8/(9n²) for a polygon's pitch deviations (Estler)
///   dof = 5                     # degrees of freedom: a number or "inf" (default "inf"), OR
///   # relative_uncertainty = 0.10   # dof = 1/(2·0.10²) = 50 (GUM G.4.2)
///
/// Unknown keys are errors. The output lists each component's |c_i|·u(x_i) and its share of the
/// combined variance, then u_c, ν_eff (rounded down), k and U = k·u_c.
#[derive(Debug, clap::Args, PartialEq)]
#[command(verbatim_doc_comment)]
pub struct Args {
    /// The budget (TOML).
    pub budget: PathBuf,
    /// Coverage probability, overriding the budget's `level`.
    #[arg(long)]
    pub level: Option<f64>,
    /// Print the result as JSON instead of the table.
    #[arg(long)]
    pub json: bool,
}

/// Runs `calib uncertainty`.
pub fn run(args: &Args) -> anyhow::Result<String> {
    let mut budget = calib_io::budget::read_budget(&args.budget)?;
    if let Some(level) = args.level {
        if !(level > 0.0 && level < 1.0) {
            return Err(crate::exit::Usage(format!(
                "--level {level}: give the coverage probability as a fraction in (0, 1), e.g. 0.95"
            ))
            .into());
        }
        budget.level = level;
    }
    let result =
        uncertainty::evaluate(&budget).with_context(|| format!("{}", args.budget.display()))?;
    if args.json {
        Ok(serde_json::to_string_pretty(&result)? + "\n")
    } else {
        Ok(render(&result))
    }
}

/// The human table.
pub fn render(r: &BudgetResult) -> String {
    let mut table = TextTable::new(&["component", "u(x_i) ″", "c_i", "|c_i|u ″", "ν_i", "share"])
        .min_widths(&[0, 10, 8, 10, 6, 6])
        .flush_left();
    for c in &r.components {
        table.row(vec![
            c.name.clone(),
            format!("{:.4}", c.standard_uncertainty),
            format!("{:.4}", c.sensitivity),
            format!("{:.4}", c.contribution),
            c.dof
                .map(|d| format!("{d:.0}"))
                .unwrap_or_else(|| "∞".into()),
            format!("{:.1}%", c.variance_fraction * 100.0),
        ]);
    }
    let mut s = table.render();
    let _ = writeln!(
        s,
        "combined standard uncertainty  u_c   = {:.4}″",
        r.combined_standard_uncertainty
    );
    let _ = match (r.effective_dof, r.effective_dof_unrounded) {
        (Some(d), Some(raw)) => writeln!(
            s,
            "effective degrees of freedom   ν_eff = {d} (Welch–Satterthwaite {raw:.2}, rounded down)"
        ),
        _ => writeln!(s, "effective degrees of freedom   ν_eff = ∞"),
    };
    let _ = writeln!(
        s,
        "coverage factor                k     = {:.3} (Student t, {} % two-sided)",
        r.coverage_factor,
        r.level * 100.0
    );
    let _ = writeln!(
        s,
        "expanded uncertainty           U     = {:.4}″",
        r.expanded_uncertainty
    );
    s
}
