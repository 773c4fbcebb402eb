//! `calib shift-angle`: load readings (and a budget) → calibrate → render tables, report, summary.

use anyhow::Context as _;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::shift_angle::{self, Method, ShiftAngleResult};
use calib_core::uncertainty::{self, BudgetResult};
use calib_core::{ChannelReport, ErrorMap, Report};
use std::fmt::Write as _;
use std::path::PathBuf;

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
/// The method cannot see harmonics of orders n, 2n, … of the encoder error (the closure of each
/// shift, eq. 2, removes them), like the traditional polygon calibration.
#[derive(Debug, clap::Args, PartialEq)]
#[command(verbatim_doc_comment)]
pub struct Args {
    /// The readings CSV (shift_deg,start_face,step,reading_arcsec).
    pub readings: PathBuf,
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
    /// Print report.json to standard output instead of the summary.
    #[arg(long)]
    pub json: bool,
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
    let readings = calib_io::readings::read_readings(&args.readings, args.faces)?;
    let budget = match &args.budget {
        Some(path) => {
            let b = calib_io::budget::read_budget(path)?;
            Some(uncertainty::evaluate(&b).with_context(|| format!("{}", path.display()))?)
        }
        None => None,
    };
    let method = match args.method {
        MethodArg::Joint => Method::Joint,
        MethodArg::Paper => Method::Paper,
    };
    let result = shift_angle::calibrate(&readings, method)
        .with_context(|| format!("{}", args.readings.display()))?;
    let report = build_report(args, &readings, &result, budget.as_ref())?;
    let report_json = serde_json::to_string_pretty(&report)? + "\n";

    check_values(&result).with_context(|| format!("{}", args.readings.display()))?;
    std::fs::create_dir_all(&args.output).with_context(|| {
        format!(
            "cannot create the output directory {}",
            args.output.display()
        )
    })?;
    let encoder_csv = render_encoder(&result, budget.as_ref());
    let polygon_csv = render_polygon(&result);
    // All three or none: a failed write leaves no table without its report.
    let mut outputs = calib_io::atomic::OutputSet::new();
    for (name, text) in [
        ("encoder.csv", &encoder_csv),
        ("polygon.csv", &polygon_csv),
        ("report.json", &report_json),
    ] {
        outputs.add(&args.output.join(name), text.as_bytes())?;
    }
    outputs.commit()?;
    if args.json {
        Ok(report_json)
    } else {
        Ok(render_summary(
            args,
            &readings,
            &result,
            budget.as_ref(),
            &report,
        ))
    }
}

fn opt(v: Option<f64>) -> String {
    v.map(|v| format!("{v:.6}")).unwrap_or_default()
}

/// Degrees with at most 9 decimals, trailing zeros trimmed (shifts are usually whole or tenths).
fn deg(v: f64) -> String {
    let s = format!("{v:.9}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.into() }
}

/// `encoder.csv`.
pub fn render_encoder(result: &ShiftAngleResult, budget: Option<&BudgetResult>) -> String {
    let mut s = String::from("angle_deg,error_arcsec,correction_arcsec,u_arcsec");
    s += if budget.is_some() {
        ",expanded_uncertainty_arcsec\n"
    } else {
        "\n"
    };
    for p in &result.points {
        let u = match budget {
            Some(b) => Some(b.combined_standard_uncertainty),
            None => p.u_arcsec,
        };
        let _ = write!(
            s,
            "{},{:.6},{:.6},{}",
            deg(p.angle_deg),
            p.error_arcsec,
            -p.error_arcsec,
            opt(u)
        );
        match budget {
            Some(b) => {
                let _ = writeln!(s, ",{:.6}", b.expanded_uncertainty);
            }
            None => s.push('\n'),
        }
    }
    s
}

/// Refuses a result with a value no table may hold (non-finite, or beyond
/// [`calib_io::table::MAX_TABLE_ARCSEC`]): extreme readings solve to numbers no encoder or
/// polygon has, and a wrong table is worse than none.
fn check_values(result: &ShiftAngleResult) -> anyhow::Result<()> {
    let limit = calib_io::table::MAX_TABLE_ARCSEC;
    let bad = |v: f64| !v.is_finite() || v.abs() > limit;
    for p in &result.points {
        if bad(p.error_arcsec) || p.u_arcsec.is_some_and(bad) {
            anyhow::bail!(
                "the encoder's error at {:.6}° solves to {}″ (u {:?}), not a finite value within \
                 ±{limit}″: check the readings' unit (arcseconds) and values; no table was written",
                p.angle_deg,
                p.error_arcsec,
                p.u_arcsec
            );
        }
    }
    for f in &result.polygon {
        if bad(f.pitch_deviation_arcsec) || f.u_arcsec.is_some_and(bad) {
            anyhow::bail!(
                "face {}'s pitch deviation solves to {}″ (u {:?}), not a finite value within \
                 ±{limit}″: check the readings' unit (arcseconds) and values; no table was written",
                f.face,
                f.pitch_deviation_arcsec,
                f.u_arcsec
            );
        }
    }
    Ok(())
}

/// `polygon.csv`.
pub fn render_polygon(result: &ShiftAngleResult) -> String {
    let mut s = String::from("face,pitch_deviation_arcsec,u_arcsec\n");
    for f in &result.polygon {
        let _ = writeln!(
            s,
            "{},{:.6},{}",
            f.face,
            f.pitch_deviation_arcsec,
            opt(f.u_arcsec)
        );
    }
    s
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
    let mut inputs = vec![args.readings.display().to_string()];
    if let Some(b) = &args.budget {
        inputs.push(b.display().to_string());
    }
    Ok(Report {
        calib_version: env!("CARGO_PKG_VERSION").to_string(),
        method: "shift-angle".into(),
        inputs,
        command_line: Some(std::env::args().collect::<Vec<_>>().join(" ")),
        channels: [("encoder".to_string(), channel)].into_iter().collect(),
        sessions: Vec::new(),
        warnings,
        details,
    })
}

fn render_summary(
    args: &Args,
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
    let _ = writeln!(
        s,
        "shift-angle ({estimator}): {n} faces, {} shift(s) {}°…{}°, {} readings",
        shifts.len(),
        deg(shifts[0].shift_deg),
        deg(shifts[shifts.len() - 1].shift_deg),
        readings.len()
    );
    if let Some(enc) = report.channels.get("encoder") {
        let _ = write!(
            s,
            "encoder: {} points, peak-to-peak {:.4}″, RMS {:.4}″",
            enc.points, enc.peak_to_peak_arcsec, enc.rms_arcsec
        );
        let top: Vec<String> = enc
            .harmonics
            .iter()
            .take(3)
            .map(|h| format!("order {} {:.4}″", h.order, h.amplitude_arcsec))
            .collect();
        if !top.is_empty() {
            let _ = write!(s, "; largest harmonics: {}", top.join(", "));
        }
        s.push('\n');
    }
    let (bmin, bmax) =
        result
            .polygon
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), f| {
                (
                    lo.min(f.pitch_deviation_arcsec),
                    hi.max(f.pitch_deviation_arcsec),
                )
            });
    let _ = writeln!(
        s,
        "polygon: pitch deviations {bmin:+.4}″ … {bmax:+.4}″ (Σβ = 0)"
    );
    let r = &result.residuals;
    let _ = write!(s, "residuals: RMS {:.4}″", r.rms_arcsec);
    if let Some(sigma) = r.sigma_arcsec {
        let _ = write!(s, ", σ̂ {sigma:.4}″ ({} dof)", r.dof);
    }
    let _ = writeln!(
        s,
        ", largest {:.4}″ at shift {}°, start face {}, step {}",
        r.max_abs_arcsec,
        deg(r.max_at_shift_deg),
        r.max_at_start_face,
        r.max_at_step
    );
    let us: Vec<f64> = result.points.iter().filter_map(|p| p.u_arcsec).collect();
    if !us.is_empty() {
        let lo = us.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = us.iter().copied().fold(0.0, f64::max);
        let _ = writeln!(s, "fit standard uncertainty of α: {lo:.4}″ … {hi:.4}″");
    }
    let sf = &result.sin_fit;
    let worst = sf
        .shifts
        .iter()
        .map(|x| x.difference_arcsec.abs())
        .fold(0.0, f64::max);
    let _ = writeln!(
        s,
        "sin-fit check (A, B from S = {}°): A = {:.4}″, B = {:.4} rad; max |U_fit − U| = {:.1e}″",
        deg(sf.reference_shift_deg),
        sf.amplitude_arcsec,
        sf.phase_rad,
        worst
    );
    if let Some(b) = budget {
        let _ = writeln!(
            s,
            "budget: u_c = {:.4}″, ν_eff = {}, k = {:.3}, U = {:.4}″ ({} %), attached to every point",
            b.combined_standard_uncertainty,
            b.effective_dof
                .map(|d| d.to_string())
                .unwrap_or_else(|| "∞".into()),
            b.coverage_factor,
            b.expanded_uncertainty,
            b.level * 100.0
        );
    }
    let _ = writeln!(
        s,
        "blind: harmonic orders {n}, {}, … of the encoder error are invisible to this method",
        2 * n
    );
    for w in &report.warnings {
        let _ = writeln!(s, "warning: {w}");
    }
    let _ = writeln!(
        s,
        "wrote {}, {}, {}",
        args.output.join("encoder.csv").display(),
        args.output.join("polygon.csv").display(),
        args.output.join("report.json").display()
    );
    s
}
