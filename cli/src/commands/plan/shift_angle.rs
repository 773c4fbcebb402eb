//! `calib plan shift-angle`: the shifts and readings, the blind orders, the fit's u and the
//! Table 3 budget.

use super::{list, non_negative, write_procedure};
use crate::exit::Usage;
use calib_core::plan::shift_angle::{ShiftAnglePlan, Table3};
use calib_core::uncertainty::Budget;
use serde_json::json;
use std::fmt::Write;
use std::path::PathBuf;

/// `calib plan shift-angle`.
#[derive(Debug, clap::Args, PartialEq)]
pub struct ShiftAngleArgs {
    /// Faces of the polygon.
    #[arg(long, value_name = "F")]
    pub faces: usize,
    /// A point of the encoder every DEG degrees: shifts 0, DEG, 2·DEG, … below the pitch
    /// 360°/F (DEG must divide the pitch).
    #[arg(long, default_value_t = 1.0, value_name = "DEG")]
    pub spacing: f64,
    /// Repeats averaged into each reading.
    #[arg(long, default_value_t = 6, value_name = "R")]
    pub repeats: usize,
    /// Standard deviation of one autocollimator reading, arcsec (the paper: 0.13).
    #[arg(long, default_value_t = 0.13, value_name = "ARCSEC")]
    pub noise: f64,
    /// Standard deviation of one determination of a pitch deviation, arcsec (the paper: 0.12).
    #[arg(long, default_value_t = 0.12, value_name = "ARCSEC")]
    pub pitch_noise: f64,
    /// The encoder's resolution, arcsec (the paper: 0.04).
    #[arg(long, default_value_t = 0.04, value_name = "ARCSEC")]
    pub resolution: f64,
    /// The autocollimator's angle error, half-width of a rectangular distribution, arcsec
    /// (the paper: 0.07).
    #[arg(long, default_value_t = 0.07, value_name = "ARCSEC")]
    pub autocollimator_error: f64,
    /// Write the procedure (the shifts and the readings in order) to FILE, with beside it the
    /// readings sheet to fill in (FILE.csv, the file calib shift-angle reads) and the budget
    /// (FILE.budget.toml, for --budget). Shift-angle readings are not simulated: there is no
    /// scenario.
    #[arg(long, value_name = "FILE")]
    pub procedure: Option<PathBuf>,
    /// Print the plan as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Runs `calib plan shift-angle`.
pub fn run(args: &ShiftAngleArgs) -> anyhow::Result<String> {
    for (name, v) in [
        ("--noise", args.noise),
        ("--pitch-noise", args.pitch_noise),
        ("--resolution", args.resolution),
        ("--autocollimator-error", args.autocollimator_error),
    ] {
        non_negative(name, v, "arcsec")?;
    }
    let table3 = Table3 {
        repeatability: args.noise,
        repeats: args.repeats,
        pitch_repeatability: args.pitch_noise,
        encoder_resolution: args.resolution,
        autocollimator_error: args.autocollimator_error,
        ..Table3::default()
    };
    let plan =
        calib_core::plan::shift_angle::plan(args.faces, args.spacing, table3).map_err(|e| {
            anyhow::Error::new(Usage(format!("{e} (check --faces, --spacing, --repeats)")))
        })?;
    let mut written = Vec::new();
    if let Some(path) = &args.procedure {
        written = write_procedure(
            path,
            &render_procedure(&plan),
            &[
                ("csv", "readings sheet", readings_sheet(&plan)),
                (
                    "budget.toml",
                    "budget",
                    budget_toml(&plan.table3.budget(plan.faces)),
                ),
            ],
        )?;
    }
    if args.json {
        return Ok(serde_json::to_string_pretty(&to_json(&plan))? + "\n");
    }
    let mut out = render(&plan);
    for path in written {
        let _ = writeln!(out, "wrote {}", path.display());
    }
    Ok(out)
}

fn shifts_text(plan: &ShiftAnglePlan) -> String {
    let s: Vec<String> = plan
        .shifts_deg
        .iter()
        .map(|s| format!("{}°", super::num(*s)))
        .collect();
    if s.len() > 8 {
        format!("{}, {}, …, {}", s[0], s[1], s[s.len() - 1])
    } else {
        s.join(", ")
    }
}

fn to_json(plan: &ShiftAnglePlan) -> serde_json::Value {
    json!({
        "method": "shift-angle",
        "faces": plan.faces,
        "pitch_deg": 360.0 / plan.faces as f64,
        "shifts_deg": plan.shifts_deg,
        "readings": plan.readings(),
        "points": plan.points(),
        "max_order": plan.max_order,
        "blind_orders": plan.blind_orders,
        "reading_noise_arcsec": plan.reading_noise,
        "u_fit_arcsec": plan.rms_u_fit(),
        "max_u_fit_arcsec": plan.max_u_fit(),
        "budget": plan.budget,
    })
}

fn render(plan: &ShiftAnglePlan) -> String {
    let mut out = String::new();
    let n = plan.faces;
    let pitch = 360.0 / n as f64;
    let spacing = pitch / plan.shifts_deg.len() as f64;
    let _ = writeln!(
        out,
        "shift-angle plan: {n}-face polygon (pitch {}°), a point every {}° ({} points)",
        super::num(pitch),
        super::num(spacing),
        plan.points()
    );
    let _ = writeln!(
        out,
        "  shifts S: {} ({} shifts)",
        shifts_text(plan),
        plan.shifts_deg.len()
    );
    let _ = writeln!(
        out,
        "  readings: {} — the full {n} × {n} matrix at S = 0 (start faces 1–{n}), start face 1 at \
         the {} other shifts; each the mean of {} repeats",
        plan.readings(),
        plan.shifts_deg.len() - 1,
        plan.table3.repeats
    );
    let _ = writeln!(
        out,
        "  blind orders (eq. 2 removes them, whatever the shifts): {}; the points resolve orders \
         up to {}",
        if plan.blind_orders.is_empty() {
            "none".to_string()
        } else {
            list(&plan.blind_orders)
        },
        plan.max_order
    );
    let _ = writeln!(
        out,
        "  u of each point from the joint fit: {:.4}″ RMS, {:.4}″ at most ({:.4}″ per reading)",
        plan.rms_u_fit(),
        plan.max_u_fit(),
        plan.reading_noise
    );
    let b = &plan.budget;
    let _ = writeln!(
        out,
        "  Table 3 budget: u_c {:.4}″, ν_eff {}, k {:.3}, U({:.0} %) {:.3}″",
        b.combined_standard_uncertainty,
        b.effective_dof.map_or("∞".to_string(), |d| d.to_string()),
        b.coverage_factor,
        100.0 * b.level,
        b.expanded_uncertainty
    );
    let _ = writeln!(
        out,
        "    {:<44} {:>9} {:>8} {:>9}",
        "component", "u (″)", "c", "c·u (″)"
    );
    for c in &b.components {
        let _ = writeln!(
            out,
            "    {:<44} {:>9.4} {:>8.4} {:>9.4}",
            c.name, c.standard_uncertainty, c.sensitivity, c.contribution
        );
    }
    let _ = writeln!(
        out,
        "  then: calib shift-angle READINGS.csv --budget BUDGET.toml -o out/"
    );
    out
}

fn render_procedure(plan: &ShiftAnglePlan) -> String {
    let n = plan.faces;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "# Shift-angle procedure: {n}-face polygon, a point every {}°\n",
        super::num(360.0 / n as f64 / plan.shifts_deg.len() as f64)
    );
    let _ = writeln!(
        out,
        "At every shift S, set face j of the polygon at encoder angle S, then step the encoder \
         by the pitch {}° {n} times, reading the autocollimator at each step (each reading the \
         mean of {} repeats). Write each reading into the readings sheet (the .csv beside this \
         file) and run `calib shift-angle SHEET.csv --budget BUDGET.toml -o out/`.\n",
        super::num(360.0 / n as f64),
        plan.table3.repeats
    );
    let _ = writeln!(out, "| shift S | start faces | readings |");
    let _ = writeln!(out, "|---|---|---|");
    for s in plan.layout.shifts() {
        let faces: Vec<usize> = s.rows.iter().map(|r| r.start_face).collect();
        let _ = writeln!(
            out,
            "| {}° | {} | {} |",
            super::num(s.shift_deg),
            if faces.len() == n {
                format!("1–{n}")
            } else {
                list(&faces)
            },
            faces.len() * n
        );
    }
    let _ = writeln!(
        out,
        "\nBlind orders: {} (the polygon's closure). Expected u of each point from the fit: \
         {:.4}″; Table 3 budget U({:.0} %) = {:.3}″.",
        list(&plan.blind_orders),
        plan.rms_u_fit(),
        100.0 * plan.budget.level,
        plan.budget.expanded_uncertainty
    );
    out
}

/// The readings sheet in the layout `calib shift-angle` reads, the readings left empty.
fn readings_sheet(plan: &ShiftAnglePlan) -> String {
    let mut out = String::from("shift_deg,start_face,step,reading_arcsec\n");
    for s in plan.layout.shifts() {
        for row in &s.rows {
            for step in 1..=plan.faces {
                let _ = writeln!(
                    out,
                    "{},{},{step},",
                    super::num(s.shift_deg),
                    row.start_face
                );
            }
        }
    }
    out
}

/// The budget as a budget file (`calib shift-angle --budget`).
fn budget_toml(budget: &Budget) -> String {
    let mut out = format!(
        "# Table 3's budget as `calib plan shift-angle` planned it: edit the components to your\n\
         # instruments.\nlevel = {}\n",
        budget.level
    );
    for c in &budget.components {
        let dof = if c.dof.is_finite() {
            format!("{}", c.dof)
        } else {
            "\"inf\"".to_string()
        };
        let _ = write!(
            out,
            "\n[[component]]\nname = \"{}\"\nu = {}\nsensitivity = {}\ndof = {dof}\n",
            c.name, c.standard_uncertainty, c.sensitivity
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(extra: &[&str]) -> ShiftAngleArgs {
        let words: Vec<&str> = ["shift-angle"].iter().chain(extra).copied().collect();
        match super::super::parse(&words) {
            super::super::Method::ShiftAngle(a) => a,
            _ => unreachable!("parsed shift-angle"),
        }
    }

    /// The paper's 24 faces: the shifts, blind orders and budget in JSON; the written budget
    /// file, read back by calib-io's budget reader, evaluates to the plan's budget, and to the
    /// budget of testdata/shift-angle/derived.toml (the paper's section 3.3).
    #[test]
    fn the_papers_24_faces_and_the_written_budget() {
        let v: serde_json::Value =
            serde_json::from_str(&run(&args(&["--faces", "24", "--json"])).unwrap()).unwrap();
        assert_eq!(v["readings"], json!(912));
        assert_eq!(v["shifts_deg"].as_array().unwrap().len(), 15);
        assert_eq!(v["blind_orders"][0], json!(24));
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("run.md");
        let a = ShiftAngleArgs {
            procedure: Some(path.clone()),
            json: false,
            ..args(&["--faces", "24"])
        };
        let text = run(&a).unwrap();
        assert!(text.contains("U(95 %) 0.149″"), "{text}");
        let written = calib_io::budget::read_budget(&dir.path().join("run.budget.toml")).unwrap();
        let planned = calib_core::uncertainty::evaluate(&written).unwrap();
        let derived = calib_io::budget::read_budget(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../testdata/shift-angle/derived.toml"),
        )
        .unwrap();
        let paper = calib_core::uncertainty::evaluate(&derived).unwrap();
        assert!(
            (planned.expanded_uncertainty - paper.expanded_uncertainty).abs() < 1e-12,
            "{planned:?} vs {paper:?}"
        );
        assert_eq!(planned.effective_dof, paper.effective_dof);
        let sheet = std::fs::read_to_string(dir.path().join("run.csv")).unwrap();
        assert_eq!(sheet.lines().count(), 913);
        let clash = ShiftAngleArgs {
            procedure: Some(dir.path().join("run.csv")),
            ..args(&["--faces", "24"])
        };
        let e = run(&clash).unwrap_err();
        assert!(e.downcast_ref::<Usage>().is_some(), "{e}");
    }

    #[test]
    fn bad_values_are_usage_errors() {
        for extra in [
            &["--faces", "24", "--spacing", "0.7"][..],
            &["--faces", "2"],
            &["--faces", "24", "--repeats", "1"],
            &["--faces", "24", "--noise=-1"],
        ] {
            let e = run(&args(extra)).unwrap_err();
            assert!(e.downcast_ref::<Usage>().is_some(), "{extra:?}: {e}");
        }
    }
}
