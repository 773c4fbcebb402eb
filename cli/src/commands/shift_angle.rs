//! `calib shift-angle`: load readings (and a budget) → calibrate → render tables, report, summary.

use crate::batch::{self, BatchArgs, Outcome};
use crate::method::{Results, finish};
use crate::summary::{TextTable, ending, key_values};
use anyhow::Context as _;
use calib_core::Report;
use calib_core::report::shift_angle::Spread;
use calib_core::shift_angle::{self, Method, ShiftAngleResult};
use calib_core::uncertainty::{self, BudgetResult};
use calib_io::shift_angle::deg;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Calibrate an encoder at every angle with a polygon and an autocollimator (shift-angle method).
///
/// The method of Hsieh, Watanabe & Hsu, Appl. Sci. 12 (2022) 5008.
///
/// READINGS is a CSV with header `shift_deg,start_face,step,reading_arcsec`, one row per
/// autocollimator reading ε_ij (arcsec) of eq. 3: the polygon's start face j (1..n) is set at
/// encoder angle S = shift_deg, the encoder is stepped by 360°/n, and step i (1..n) is read at
/// encoder angle (i−1)·360°/n + S. The number of faces n is the largest step. A shift may hold the
/// full n×n matrix (every start face) or only some start faces (e.g. face 1 only, as the paper does
/// for S > 0); every start face given needs all n steps. At least one shift needs two or more
/// start faces (the polygon is calibrated from them). Shifts lie in [0, 360°/n).
///
/// Writes into DIR (-o):
///
///   encoder.csv  angle_deg (encoder angle), error_arcsec (encoder error α: reading − true),
///                correction_arcsec (= −error), u_arcsec (standard uncertainty: the budget's
///                combined u_c with --budget, else the joint fit's own; empty for --method paper
///                without --budget), and with --budget expanded_uncertainty_arcsec (k·u_c).
///                One row per measured angle, sorted; zero-mean.
///
///   polygon.csv  face, pitch_deviation_arcsec (β: pitch angle − 360°/n; Σβ = 0),
///                u_arcsec (standard uncertainty from the fit; empty for --method paper).
///
///   report.json  channel `encoder` (peak-to-peak, RMS, harmonics where the angles are uniform)
///                and `details`: β, the setup error U of every start face and shift, the
///                residuals of the fit (a check of the measurement), the sin-fit check of
///                section 3.1, the budget.
///
///   report.html  the encoder map with its uncertainty band, the polygon's pitch deviations,
///                the fit residuals per reading, and the numbers as tables.
/// With several READINGS files, each one's files go to DIR/<file stem>/ and DIR/summary.json
/// holds every file's verdict.
///
/// The method cannot see harmonics of orders n, 2n, … of the encoder error (the closure of each
/// shift, eq. 2, removes them), like the traditional polygon calibration.
///
/// Exit status: 0 all calibrated and passed the gates, 1 bad or insufficient data, 2 bad usage,
/// 3 a gate failed (outputs written all the same).
#[derive(Debug, clap::Args, PartialEq)]
#[command(verbatim_doc_comment)]
pub struct Args {
    /// The readings CSVs (shift_deg,start_face,step,reading_arcsec), calibrated independently
    /// and in parallel.
    #[arg(required = true, value_name = "READINGS")]
    pub readings: Vec<PathBuf>,
    /// Output directory.
    #[arg(
        short = 'o',
        long = "output",
        value_name = "DIR",
        default_value = "calib-out"
    )]
    pub output: PathBuf,
    /// Estimator: `joint` (one least-squares fit of all α, β, U with the closures, residuals and
    /// uncertainties) or `paper` (the paper's Table 2 → eq. 7 → eq. 3 steps; needs a full n×n
    /// matrix at one shift).
    #[arg(long, value_enum, default_value_t = MethodArg::Joint)]
    pub method: MethodArg,
    /// The polygon's number of faces, checked against the readings (default: the largest step).
    #[arg(long, value_name = "N")]
    pub faces: Option<usize>,
    /// A GUM budget (TOML, see `calib uncertainty --help`) whose combined and expanded
    /// uncertainty are attached to every point of encoder.csv.
    #[arg(long, value_name = "FILE")]
    pub budget: Option<PathBuf>,
    /// Print report.json to standard output instead of the summary (summary.json with several
    /// files).
    #[arg(long)]
    pub json: bool,
    /// Pipelines and gates.
    #[command(flatten)]
    pub batch: BatchArgs,
}

/// The estimator, on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum MethodArg {
    /// One constrained least-squares fit of all unknowns.
    Joint,
    /// The paper's two-step estimate.
    Paper,
}

/// Runs `calib shift-angle`.
pub fn run(args: &Args) -> anyhow::Result<String> {
    let budget = match &args.budget {
        Some(path) => {
            let b = calib_io::budget::read_budget(path)?;
            Some(uncertainty::evaluate(&b).with_context(|| format!("{}", path.display()))?)
        }
        None => None,
    };
    batch::run(
        "shift-angle",
        &args.readings,
        &args.output,
        &args.batch,
        args.json,
        |path, out| calibrate(args, path, out, budget.as_ref()),
    )
}

/// Calibrates one readings file into the folder `out`.
fn calibrate(
    args: &Args,
    path: &Path,
    out: &Path,
    budget: Option<&BudgetResult>,
) -> anyhow::Result<Outcome> {
    let readings = calib_io::readings::read_readings(path, args.faces)?;
    let method = match args.method {
        MethodArg::Joint => Method::Joint,
        MethodArg::Paper => Method::Paper,
    };
    let result =
        shift_angle::calibrate(&readings, method).with_context(|| format!("{}", path.display()))?;
    calib_io::shift_angle::check_values(&result).with_context(|| format!("{}", path.display()))?;
    let mut inputs = vec![path.display().to_string()];
    inputs.extend(args.budget.iter().map(|b| b.display().to_string()));
    let section = result.report_section(&readings, budget);
    let results = Results {
        channels: section.channels.keys().cloned().collect(),
        section,
        tables: vec![
            (
                "encoder.csv".into(),
                calib_io::shift_angle::render_encoder(&result, budget).into_bytes(),
            ),
            (
                "polygon.csv".into(),
                calib_io::shift_angle::render_polygon(&result).into_bytes(),
            ),
        ],
        residual_rms_arcsec: Some(result.residuals.rms_arcsec),
        document: Box::new(|report| {
            crate::document::shift_angle::document(&readings, &result, budget, report)
        }),
        summary: Box::new(|report| render_summary(out, &readings, &result, budget, report)),
    };
    finish(out, args.json, inputs, Vec::new(), "", results)
}

/// The summary: what was measured and fitted, then the encoder's map and the polygon.
fn render_summary(
    out: &Path,
    readings: &shift_angle::Readings,
    result: &ShiftAngleResult,
    budget: Option<&BudgetResult>,
    report: &Report,
) -> String {
    let estimator = match result.method {
        Method::Joint => "joint least-squares fit",
        Method::Paper => "the paper's two steps",
    };
    let mut s = format!("shift-angle calibration ({estimator})\n\n");
    s += &key_values(&summary_facts(readings, result, budget));
    let table = summary_table(readings.faces(), result, report);
    let _ = writeln!(s, "\n{}", table.render().trim_end());
    s += &ending(
        &report.warnings,
        out,
        &[
            "encoder.csv".into(),
            "polygon.csv".into(),
            "report.json".into(),
        ],
        "encoder map with its uncertainty band, pitch deviations, fit residuals",
    );
    s
}

/// The facts above the summary's table: the readings, the fit, the blind orders, the sin-fit
/// check and the budget.
fn summary_facts(
    readings: &shift_angle::Readings,
    result: &ShiftAngleResult,
    budget: Option<&BudgetResult>,
) -> Vec<(&'static str, String)> {
    let n = readings.faces();
    let shifts = readings.shifts();
    let r = &result.residuals;
    let mut facts = vec![
        (
            "readings",
            format!(
                "{} of a {n}-face polygon, {} shift(s) {}°…{}°",
                readings.len(),
                shifts.len(),
                deg(shifts[0].shift_deg),
                deg(shifts[shifts.len() - 1].shift_deg),
            ),
        ),
        (
            "fit residual",
            format!(
                "RMS {:.4}″{}, largest {:.4}″ at shift {}°, start face {}, step {}",
                r.rms_arcsec,
                r.sigma_arcsec
                    .map(|sigma| format!(", σ̂ {sigma:.4}″ ({} dof)", r.dof))
                    .unwrap_or_default(),
                r.max_abs_arcsec,
                deg(r.max_at_shift_deg),
                r.max_at_start_face,
                r.max_at_step
            ),
        ),
        (
            "blind",
            format!(
                "harmonic orders {n}, {}, … of the encoder error are invisible to this method",
                2 * n
            ),
        ),
    ];
    let sf = &result.sin_fit;
    facts.push((
        "sin-fit check",
        format!(
            "A = {:.4}″, B = {:.4} rad from S = {}°; max |U_fit − U| = {:.1e}″",
            sf.amplitude_arcsec,
            sf.phase_rad,
            deg(sf.reference_shift_deg),
            result.sin_fit_worst_difference()
        ),
    ));
    if let Some(b) = budget {
        facts.push((
            "budget",
            format!(
                "u_c = {:.4}″, ν_eff = {}, k = {:.3}, U = {:.4}″ ({} %), attached to every point",
                b.combined_standard_uncertainty,
                b.effective_dof
                    .map(|d| d.to_string())
                    .unwrap_or_else(|| "∞".into()),
                b.coverage_factor,
                b.expanded_uncertainty,
                b.level * 100.0
            ),
        ));
    }
    facts
}

/// The range of standard uncertainties, or `—` for none.
fn u_range(spread: Option<Spread>) -> String {
    spread.map_or("—".to_string(), |u| format!("{:.4}…{:.4}″", u.min, u.max))
}

/// The summary's table: the encoder's map (from the report) and the polygon of `faces` faces.
fn summary_table(faces: usize, result: &ShiftAngleResult, report: &Report) -> TextTable {
    let mut t = TextTable::new(&["", "points", "p-p", "rms", "fit u", "largest"]);
    if let Some(enc) = report.channels.get("encoder") {
        let top: Vec<String> = enc
            .harmonics
            .iter()
            .take(3)
            .map(|h| format!("order {} {:.4}″", h.order, h.amplitude_arcsec))
            .collect();
        t.row(vec![
            "encoder".into(),
            format!("{} points", enc.points),
            format!("{:.4}″", enc.peak_to_peak_arcsec),
            format!("{:.4}″", enc.rms_arcsec),
            u_range(result.point_u_spread()),
            top.join(", "),
        ]);
    }
    if let Some(beta) = result.pitch_spread() {
        t.row(vec![
            "polygon β".into(),
            format!("{faces} faces"),
            format!("{:.4}″", beta.max - beta.min),
            format!("{:.4}″", beta.rms),
            u_range(result.face_u_spread()),
            format!("{:+.4}″ … {:+.4}″ (Σβ = 0)", beta.min, beta.max),
        ]);
    }
    t
}
