//! `calib tdr`: self-calibration of one encoder from a free spin-down (coast-down) log, or from
//! a run driven at steady speed.

mod document;
mod summary;

use crate::batch::Outcome;
use crate::exit::Usage;
use crate::method::{MethodArgs, Results, finish_log, for_each_sample, in_log};
use crate::output::turn_table;
use anyhow::Context;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::tdr::{MotorOrders, RunKind, Tdr, TdrError, TdrOptions};
use std::path::Path;
use summary::render_summary;

/// Largest `--max-order` accepted: the fit is dense in the orders (cost ∝ samples·orders²).
const MAX_ORDER: usize = 1000;
/// Largest `--max-drag-order` accepted: a drag's imprint falls as 1/h², and each order costs
/// two columns of the dense fit.
const MAX_DRAG_ORDER: usize = 100;
/// Largest `--motion-degree` accepted (Chebyshev series of higher degree can follow the error).
const MAX_DEGREE: usize = 60;
/// Largest `--pole-pairs` accepted (its first motor order, 6 × it, is then at `MAX_ORDER`).
const MAX_POLE_PAIRS: usize = MAX_ORDER / 6;

/// What the log holds (`--run`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Run {
    /// A coast where the log has one, else a driven run.
    Auto,
    /// A free coast-down only.
    Coast,
    /// Passes at steady speed, a motor driving the shaft.
    Driven,
}

/// Self-calibrate one encoder from a spin-down or a driven run: the shaft coasting freely, or
/// driven at a steady speed (TDR, Lu & Trumper).
///
/// Spin the shaft up, release the drive (or cut the motor current) and log the encoder while the
/// shaft coasts down: 10 revolutions at the least, a few hundred is better, with the speed
/// falling noticeably (≥ 2 %). A free shaft's angle is a smooth function of time, so the part of
/// the reading that is periodic in angle is the encoder's error: the motion (a Chebyshev series
/// in time) and the map (a Fourier series of the reading) are fitted together by least squares.
/// A driven plateau before the release and the slow end of the coast are left out.
///
/// The orders come from the data: every order the coast resolves is tested (by default up to
/// 0.4 × the samples per revolution at its slowest end) and those standing above the noise are
/// kept; periodic structure left in the residual above the highest order is warned about.
///
/// An angle-dependent drag (rolling bearings, motor cogging, unbalance) shakes the shaft by
/// a_h/(h·ω)² at order h. Its imprint grows as 1/ω² while the encoder's error does not change
/// with speed, so over a coast whose speed falls enough (1/ω² varying by ≥ 10 % RMS) the drag is
/// fitted jointly and separated from the map, and reported. Over a narrower coast it cannot be,
/// and the warnings say how far the shaft must coast down. With --ref, the map is also checked
/// against a reference encoder on the same shaft.
///
/// A driven run works too (--run driven, or auto where the log holds no coast): a motor at
/// constant voltage, its inertia keeping the speed smooth (moteus' "inertial" calibration: ~300
/// r/min for ~20 s). Each stretch at steady speed is a pass, fitted as a coast is. At one speed the
/// motor's cogging and torque ripple (orders k × 6 × --pole-pairs, or --cogging-orders) cannot be
/// told from the encoder's error: those orders are named, left out of the map, and their measured
/// amplitude enters the map's u. With passes at two or more speeds (e.g. the voltage doubled
/// halfway) each is separated as e + D/ω²: the encoder's part goes into the map, the cogging is
/// reported (report.json details.driven).
///
/// Writes DIR/<channel>.csv (angle_deg, error_arcsec, correction_arcsec; error = reading − true
/// angle, correction = −error, a function of the encoder's own reading, zero mean) and
/// DIR/report.json and DIR/report.html, and prints a summary. With several logs, each log's files
/// go to DIR/<log stem>/ and DIR/summary.json holds every log's verdict.
///
/// Channels on separate topics are aligned on the stamps of --channel (see --time, --max-gap).
///
/// Exit status: 0 all logs calibrated and passed the gates, 1 a log could not be calibrated
/// (bad or insufficient data), 2 bad usage, 3 a gate failed (outputs written all the same).
#[derive(Debug, clap::Args, PartialEq)]
#[command(after_long_help = crate::input::channel_names())]
pub struct Args {
    /// Channel of the encoder to calibrate.
    #[arg(long)]
    pub channel: String,
    /// Channel of a reference encoder on the same shaft, to check the map against.
    #[arg(long = "ref")]
    pub reference: Option<String>,
    /// Highest harmonic order tested. Default: 0.4 × the samples per revolution where the coast
    /// is slowest (at most 500). Only orders that stand above the noise are kept in the map.
    #[arg(long)]
    pub max_order: Option<usize>,
    /// Highest order of angle-dependent drag fitted and separated from the map (0: none).
    #[arg(long, default_value_t = 16)]
    pub max_drag_order: usize,
    /// Degree of the motion's polynomial (Chebyshev series in time); default: chosen by the
    /// Bayesian information criterion, at most 30 and at most half the revolutions.
    #[arg(long)]
    pub motion_degree: Option<usize>,
    /// Fewest revolutions of coast (or of each driven pass) accepted.
    #[arg(long, default_value_t = 10.0)]
    pub min_revolutions: f64,
    /// What the log holds: a free coast-down, passes driven at steady speed, or auto (a coast
    /// where there is one, else a driven run).
    #[arg(long, value_enum, default_value_t = Run::Auto)]
    pub run: Run,
    /// Pole pairs of the motor of a driven run: its cogging and torque ripple are at orders
    /// k × 6 × pole pairs (42, 84, … for 7).
    #[arg(long, conflicts_with = "cogging_orders")]
    pub pole_pairs: Option<usize>,
    /// The motor's orders of a driven run as a list (e.g. 42,84), instead of --pole-pairs.
    #[arg(long, value_name = "LIST", value_delimiter = ',')]
    pub cogging_orders: Vec<usize>,
    /// Points of the output table (default: enough for linear interpolation to 0.01″, ≥ 3600,
    /// as csrr and multihead choose them: the map is a sum of the harmonics kept).
    #[arg(long)]
    pub points: Option<usize>,
    /// Logs, output, unit, output form, gates, timing.
    #[command(flatten)]
    pub common: MethodArgs,
}

/// Runs `calib tdr`.
impl super::Method for Args {
    const NAME: &'static str = "tdr";
    type Prepared = ();

    fn runs(&self) -> super::Runs<'_> {
        self.common.runs()
    }

    fn prepare(&self) -> anyhow::Result<()> {
        prepare(self)
    }

    fn calibrate(&self, (): &(), log: &Path, out: &Path) -> anyhow::Result<Outcome> {
        calibrate(self, log, out)
    }
}

/// Checks the arguments before any log is read.
fn prepare(args: &Args) -> anyhow::Result<()> {
    if args.reference.as_ref() == Some(&args.channel) {
        return Err(Usage(format!(
            "--channel and --ref both name `{}`: name the encoder to calibrate and a different reference",
            args.channel
        ))
        .into());
    }
    crate::input::check_points(args.points)?;
    if let Some(h) = args.max_order {
        crate::input::check_count("--max-order", h, 1, Some(MAX_ORDER))?;
    }
    crate::input::check_count(
        "--max-drag-order",
        args.max_drag_order,
        0,
        Some(MAX_DRAG_ORDER),
    )?;
    if let Some(p) = args.motion_degree {
        crate::input::check_count("--motion-degree", p, 1, Some(MAX_DEGREE))?;
    }
    if let Some(p) = args.pole_pairs {
        crate::input::check_count("--pole-pairs", p, 1, Some(MAX_POLE_PAIRS))?;
    }
    for &k in &args.cogging_orders {
        crate::input::check_count("--cogging-orders", k, 1, Some(MAX_ORDER))?;
    }
    if !(args.min_revolutions.is_finite() && args.min_revolutions >= 1.0) {
        return Err(Usage(format!(
            "--min-revolutions {} is outside its range: a finite number of at least 1",
            calib_io::limits::readable(args.min_revolutions)
        ))
        .into());
    }
    Ok(())
}

/// Calibrates one log into the folder `out`.
fn calibrate(args: &Args, log: &Path, out: &Path) -> anyhow::Result<Outcome> {
    let mut names = vec![args.channel.as_str()];
    names.extend(args.reference.as_deref());
    let reader = args.common.open(log, &names)?;
    let mut tdr = Tdr::new(TdrOptions {
        max_order: args.max_order,
        max_drag_order: args.max_drag_order,
        motion_degree: args.motion_degree,
        points: args.points,
        min_revolutions: args.min_revolutions,
        run: match args.run {
            Run::Auto => RunKind::Auto,
            Run::Coast => RunKind::Coast,
            Run::Driven => RunKind::Driven,
        },
        motor: match (args.pole_pairs, args.cogging_orders.is_empty()) {
            (Some(p), _) => MotorOrders::PolePairs(p),
            (None, false) => MotorOrders::Orders(args.cogging_orders.clone()),
            (None, true) => MotorOrders::None,
        },
        ..TdrOptions::default()
    });
    // The sample's values are the channels in the order opened: the encoder, then the reference.
    let reader = for_each_sample(log, reader, |s| match s.values.get(1) {
        Some(&r) => tdr.push_with_reference(s.t, s.values[0], r),
        None => tdr.push(s.t, s.values[0]),
    })?;
    let cal = tdr.finish().map_err(|e| match e {
        TdrError::NoWholeTurn { turn, cause } => {
            // The context below names the log and the channel.
            crate::input::no_whole_turn(*cause, "", &turn)
        }
        e => anyhow::Error::new(e),
    });
    let cal = cal
        .with_context(|| format!("{}: channel `{}`", log.display(), args.channel))
        .map_err(|e| in_log(e, &reader, log))?;
    let results = Results {
        section: cal.report_section(
            &args.channel,
            args.reference.as_deref(),
            args.max_drag_order,
        ),
        tables: vec![turn_table(
            &args.channel,
            &cal.map,
            Some(&cal.uncertainty.u),
        )?],
        channels: vec![args.channel.clone()],
        residual_rms_arcsec: Some(cal.residual_rms * ARCSEC_PER_RAD),
        document: Box::new(|report| {
            document::document(&args.channel, args.reference.as_deref(), &cal, report)
        }),
        summary: Box::new(|report| render_summary(args, out, &cal, report)),
    };
    finish_log(&reader, log, out, args.common.presentation(), results)
}
