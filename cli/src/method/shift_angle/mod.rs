//! `calib shift-angle`: load readings (and a budget) → calibrate → render tables, report, summary.

mod document;
mod summary;

use crate::batch::{BatchArgs, Outcome};
use crate::method::{Results, finish};
use anyhow::Context as _;
use calib_core::shift_angle::{self, Method};
use calib_core::uncertainty::{self, BudgetResult};
use std::path::{Path, PathBuf};
use summary::render_summary;

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
    /// Output folder (created if missing).
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
impl super::Method for Args {
    const NAME: &'static str = "shift-angle";
    type Prepared = Option<BudgetResult>;

    fn runs(&self) -> super::Runs<'_> {
        super::Runs {
            inputs: &self.readings,
            output: &self.output,
            batch: &self.batch,
            json: self.json,
            unit: None,
        }
    }

    /// The budget, read and evaluated once.
    fn prepare(&self) -> anyhow::Result<Self::Prepared> {
        self.budget
            .as_deref()
            .map(|path| {
                let b = calib_io::budget::read_budget(path)?;
                uncertainty::evaluate(&b).with_context(|| format!("{}", path.display()))
            })
            .transpose()
    }

    fn calibrate(
        &self,
        budget: &Self::Prepared,
        path: &Path,
        out: &Path,
    ) -> anyhow::Result<Outcome> {
        calibrate(self, path, out, budget.as_ref())
    }
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
        document: Box::new(|report| document::document(&readings, &result, budget, report)),
        summary: Box::new(|report| render_summary(out, &readings, &result, budget, report)),
    };
    let shown = super::Presentation {
        json: args.json,
        plots: args.batch.plots.as_deref(),
    };
    finish(out, shown, inputs, Vec::new(), "", results)
}
