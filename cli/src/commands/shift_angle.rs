//! `calib shift-angle`: load readings (and a budget) → calibrate → render tables, report, summary.

use crate::batch::{self, BatchArgs, ChannelFigures, Outcome};
use crate::summary::{TextTable, ending, key_values};
use anyhow::Context as _;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::shift_angle::{self, Method, ShiftAngleResult};
use calib_core::uncertainty::{self, BudgetResult};
use calib_core::{ChannelReport, ErrorMap, Report};
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
    let report = build_report(args, path, &readings, &result, budget)?;
    let report_json = serde_json::to_string_pretty(&report)? + "\n";

    calib_io::shift_angle::check_values(&result).with_context(|| format!("{}", path.display()))?;
    let encoder_csv = calib_io::shift_angle::render_encoder(&result, budget);
    let polygon_csv = calib_io::shift_angle::render_polygon(&result);
    let doc = crate::document::shift_angle::document(&readings, &result, budget, &report);
    let files = crate::output::write_outputs(
        out,
        &[
            ("encoder.csv".into(), encoder_csv.into_bytes()),
            ("polygon.csv".into(), polygon_csv.into_bytes()),
            ("report.json".into(), report_json.clone().into_bytes()),
        ],
        &doc,
    )?;
    let text = if args.json {
        report_json
    } else {
        render_summary(out, &readings, &result, budget, &report)
    };
    Ok(Outcome {
        text,
        channels: report
            .channels
            .iter()
            .map(|(name, c)| ChannelFigures {
                channel: name.clone(),
                peak_to_peak_before_arcsec: c.peak_to_peak_arcsec,
                peak_to_peak_after_arcsec: None,
            })
            .collect(),
        residual_rms_arcsec: Some(result.residuals.rms_arcsec),
        warnings: report.warnings,
        files,
    })
}

/// Whether the points lie on the uniform grid `i·360/N` (then the map has harmonics).
fn uniform_map(result: &ShiftAngleResult) -> Option<ErrorMap> {
    let n = result.points.len();
    let step = 360.0 / n as f64;
    let uniform = result
        .points
        .iter()
        .enumerate()
        .all(|(i, p)| (p.angle_deg - i as f64 * step).abs() < 1e-6);
    uniform.then(|| {
        ErrorMap::new(
            result
                .points
                .iter()
                .map(|p| p.error_arcsec / ARCSEC_PER_RAD)
                .collect(),
        )
    })
}

fn build_report(
    args: &Args,
    path: &Path,
    readings: &shift_angle::Readings,
    result: &ShiftAngleResult,
    budget: Option<&BudgetResult>,
) -> anyhow::Result<Report> {
    let mut warnings = Vec::new();
    let channel = match uniform_map(result) {
        Some(map) => ChannelReport::of_map("encoder.csv", &map, 10),
        None => {
            warnings.push(
                "the measured angles are not a uniform grid over the circle (shifts not evenly spaced over one pitch): no harmonics in the report".to_string(),
            );
            let values: Vec<f64> = result.points.iter().map(|p| p.error_arcsec).collect();
            let max = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let min = values.iter().copied().fold(f64::INFINITY, f64::min);
            ChannelReport {
                table: "encoder.csv".into(),
                points: values.len(),
                peak_to_peak_arcsec: max - min,
                rms_arcsec: (values.iter().map(|v| v * v).sum::<f64>() / values.len() as f64)
                    .sqrt(),
                harmonics: Vec::new(),
            }
        }
    };
    let res = &result.residuals;
    if let Some(sigma) = res.sigma_arcsec
        && res.max_abs_arcsec > 5.0 * sigma
    {
        warnings.push(format!(
            "the reading at shift {}°, start face {}, step {} deviates from the fit by {:.4}″ ({:.1} σ̂): check it",
            deg(res.max_at_shift_deg),
            res.max_at_start_face,
            res.max_at_step,
            res.max_abs_arcsec,
            res.max_abs_arcsec / sigma
        ));
    }
    if res.dof == 0 {
        warnings.push(
            "the readings have no redundancy (0 residual degrees of freedom): no fit uncertainties and no check of the measurement".into(),
        );
    }
    let max_u_fit = result
        .points
        .iter()
        .filter_map(|p| p.u_arcsec)
        .fold(None, |m: Option<f64>, u| Some(m.map_or(u, |m| m.max(u))));
    match (budget, max_u_fit) {
        (None, None) => warnings.push(
            "encoder.csv has no uncertainties: the paper's method gives none per point; pass --budget FILE or use the joint method".into(),
        ),
        (Some(b), Some(u)) if u > b.combined_standard_uncertainty => warnings.push(format!(
            "the fit's standard uncertainty reaches {u:.4}″, more than the budget's u_c = {:.4}″: the budget may underestimate the measurement's noise",
            b.combined_standard_uncertainty
        )),
        _ => {}
    }
    let n = readings.faces();
    let mut details = std::collections::BTreeMap::new();
    let mut put = |k: &str, v: serde_json::Value| {
        details.insert(k.to_string(), v);
    };
    put("estimator", serde_json::to_value(result.method)?);
    put("faces", n.into());
    put("pitch_deg", (360.0 / n as f64).into());
    put("readings", readings.len().into());
    put(
        "shifts_deg",
        readings
            .shifts()
            .iter()
            .map(|s| s.shift_deg)
            .collect::<Vec<_>>()
            .into(),
    );
    put(
        "blind_harmonic_orders",
        format!(
            "multiples of {n} (orders {n}, {}, …): removed by the closure of each shift (eq. 2)",
            2 * n
        )
        .into(),
    );
    put("polygon", serde_json::to_value(&result.polygon)?);
    put("setup_errors", serde_json::to_value(&result.setup_errors)?);
    put("residuals", serde_json::to_value(result.residuals)?);
    put("sin_fit", serde_json::to_value(&result.sin_fit)?);
    if let Some(u) = max_u_fit {
        put("max_u_fit_arcsec", u.into());
    }
    if let Some(b) = budget {
        put("budget", serde_json::to_value(b)?);
    }
    let mut inputs = vec![path.display().to_string()];
    if let Some(b) = &args.budget {
        inputs.push(b.display().to_string());
    }
    Ok(Report {
        calib_version: env!("CARGO_PKG_VERSION").to_string(),
        method: "shift-angle".into(),
        inputs,
        command_line: Some(crate::input::command_line()),
        channels: [("encoder".to_string(), channel)].into_iter().collect(),
        sessions: Vec::new(),
        warnings,
        details,
    })
}

fn render_summary(
    out: &Path,
    readings: &shift_angle::Readings,
    result: &ShiftAngleResult,
    budget: Option<&BudgetResult>,
    report: &Report,
) -> String {
    let n = readings.faces();
    let shifts = readings.shifts();
    let mut s = String::new();
    let estimator = match result.method {
        Method::Joint => "joint least-squares fit",
        Method::Paper => "the paper's two steps",
    };
    let _ = writeln!(s, "shift-angle calibration ({estimator})\n");
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
    let worst = sf
        .shifts
        .iter()
        .map(|x| x.difference_arcsec.abs())
        .fold(0.0, f64::max);
    facts.push((
        "sin-fit check",
        format!(
            "A = {:.4}″, B = {:.4} rad from S = {}°; max |U_fit − U| = {worst:.1e}″",
            sf.amplitude_arcsec,
            sf.phase_rad,
            deg(sf.reference_shift_deg)
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
    s += &key_values(&facts);
    let us: Vec<f64> = result.points.iter().filter_map(|p| p.u_arcsec).collect();
    let u_range = |v: &[f64]| {
        if v.is_empty() {
            "—".to_string()
        } else {
            let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = v.iter().copied().fold(0.0, f64::max);
            format!("{lo:.4}…{hi:.4}″")
        }
    };
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
            u_range(&us),
            top.join(", "),
        ]);
    }
    let betas: Vec<f64> = result
        .polygon
        .iter()
        .map(|f| f.pitch_deviation_arcsec)
        .collect();
    let (bmin, bmax) = betas
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), b| {
            (lo.min(*b), hi.max(*b))
        });
    let beta_rms = (betas.iter().map(|b| b * b).sum::<f64>() / betas.len().max(1) as f64).sqrt();
    let bu: Vec<f64> = result.polygon.iter().filter_map(|f| f.u_arcsec).collect();
    t.row(vec![
        "polygon β".into(),
        format!("{n} faces"),
        format!("{:.4}″", bmax - bmin),
        format!("{beta_rms:.4}″"),
        u_range(&bu),
        format!("{bmin:+.4}″ … {bmax:+.4}″ (Σβ = 0)"),
    ]);
    let _ = writeln!(s, "\n{}", t.render().trim_end());
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
