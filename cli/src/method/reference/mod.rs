//! `calib reference`: cross-calibration of an encoder against a better reference encoder.

pub(crate) mod document;
pub(crate) mod summary;

use crate::batch::Outcome;
use crate::exit::Usage;
use crate::input::{channel, open_log_with};
use crate::method::{MethodArgs, Results, finish_log, for_each_sample, in_log, with_time_hint};
use crate::output::table_name;
use crate::reference_table::ReferenceTable;
use anyhow::Context;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::reference_cal::{
    DEFAULT_REFERENCE_ORDERS, Gear, Latency, Ratio, ReferenceError, ReferenceKind,
    ReferenceOptions, ReferenceRun, Targets,
};
use calib_core::reference_points::{Approach, PointOptions, calibrate_points_with_directions};
use calib_io::{LogReader, ReadOptions};
use std::path::{Path, PathBuf};
use summary::render_summary;

/// Calibrate an encoder (the DUT) against a better reference encoder on the same shaft.
///
/// Record both encoders turning together: whole revolutions, ideally 5 or more in each direction
/// (ISO 230-2), or for a joint that never turns a whole revolution, its travel swept back and
/// forth. The DUT's error map is DUT reading − reference reading (mean removed) as a function of
/// the DUT's reading, the mean of both directions; the report holds the ISO 230-2 figures
/// (systematic deviation E, reversal value B, repeatability R, accuracy A) at the target
/// positions (--targets). The reference's own error is part of the map: use a reference much
/// better than the DUT.
///
/// A run that does not cover a whole turn gives a range table over the readings it crossed
/// (a `# range_deg: LO to HI` first line, then the same columns); a whole turn but for a gap of at
/// most --bridge-gap degrees gives a whole-turn table with the gap bridged by interpolation, and a
/// warning naming it. Large DUT errors (degrees) are measured: the reference is refused only if
/// the difference of the readings at the same DUT reading differs from pass to pass by more than
/// --follow-tol.
///
/// Writes DIR/<dut>.csv (angle_deg, error_arcsec, correction_arcsec, u_arcsec; correction =
/// −error, applied as reading + correction(reading)), DIR/report.json and DIR/report.html (the
/// map with its uncertainty band, the ISO 230-2 figures), and prints a summary. With several
/// logs, each log's files go to DIR/<log stem>/ and DIR/summary.json holds every log's verdict.
///
/// A CSV file without a time column is a list of stationary points, one row per stop of the
/// shaft in the order measured (a protractor table, a rotary table stepped through ISO 230-2
/// targets, the MagAlpha tool's input): each row's DUT − reference is one measurement; rows whose
/// DUT readings lie within --target-tol are one target measured again (a cycle), approached in
/// the direction of the step that led there — or as a `direction` column (also `dir`) says:
/// `+`/`-` (1/-1, up/down, increasing/decreasing, forward/backward) for increasing or decreasing
/// DUT readings, an empty cell for the step's direction; give it where a target was reached by
/// overshooting it and coming back. The map joins the targets' means by straight lines;
/// the ISO 230-2 figures are taken at the targets (--targets and the options of motion do not
/// apply). A whole turn if the targets go round evenly, else a range table. When the reference
/// readings are in a file of their own, one per row in the same order, name it with --ref-file.
///
/// Channels on separate topics are aligned on the stamps of the DUT (see --time, --max-gap).
///
/// Exit status: 0 all logs calibrated and passed the gates, 1 a log could not be calibrated
/// (bad or insufficient data), 2 bad usage, 3 a gate failed (outputs written all the same).
#[derive(Debug, clap::Args, PartialEq)]
#[command(after_long_help = crate::input::channel_names())]
pub struct Args {
    /// Channel of the encoder to calibrate (device under test).
    #[arg(long)]
    pub dut: String,
    /// Channel of the reference encoder.
    #[arg(long = "ref")]
    pub reference: String,
    /// The reference's stated standard uncertainty, arcseconds, combined into every u_arcsec.
    /// Without it (or --ref-table) the reference's uncertainty is not known: u excludes the
    /// reference, which the summary, the report and a warning say (--fail-on-warning fails).
    #[arg(long, value_name = "ARCSEC", conflicts_with = "ref_table")]
    pub ref_u: Option<f64>,
    /// The reference's own calibrated table (angle_deg, error_arcsec, correction_arcsec,
    /// u_arcsec; a whole turn, e.g. from an earlier `calib reference` or `calib csrr` of it):
    /// its readings are corrected by it, and its largest u is combined into every u_arcsec.
    #[arg(long, value_name = "FILE")]
    pub ref_table: Option<PathBuf>,
    /// Points of the output table: the grid at which every pass is measured (where the DUT's
    /// reading crosses each point), 0.1° apart over a turn by default. A fixed default, unlike
    /// csrr's, multihead's and tdr's (from the harmonics they fit): this map is measured at its
    /// points, not summed from harmonics; a finer grid needs samples closer than its step.
    #[arg(long, default_value_t = 3600)]
    pub points: usize,
    /// Speed below which the DUT counts as stopped, degrees per second.
    #[arg(long, default_value_t = 1.0)]
    pub min_speed: f64,
    /// Largest spread, degrees, of the difference between the two readings at one DUT reading
    /// from pass to pass; beyond it the reference is taken not to be on the DUT's shaft (a run
    /// that crosses no reading twice: largest change of the difference over the run).
    #[arg(long, default_value_t = 5.0)]
    pub follow_tol: f64,
    /// Largest gap of never-reached readings, degrees, bridged by interpolation in a whole-turn
    /// table (with a warning); a wider gap gives a range table.
    #[arg(long, default_value_t = 5.0)]
    pub bridge_gap: f64,
    /// ISO 230-2 target positions: a count K (one in the middle of each of K equal parts of the
    /// map's range) or a list of readings in degrees (`--targets 20,40,60`); each moved to the
    /// nearest grid point.
    #[arg(long, default_value = "20", value_parser = parse_targets)]
    pub targets: Targets,
    /// Travel after each reversal of direction whose data are not used, degrees (the ISO 230-2
    /// approach: backlash settles).
    #[arg(long, default_value_t = 1.0)]
    pub approach: f64,
    /// The DUT's lag behind the reference, removed from the map: `auto` fits it jointly with the
    /// map (the difference then carries lag × speed) and removes it where the run tells it from
    /// backlash — passes at two or more speeds in the same direction — and it differs from 0 by
    /// more than 3 standard uncertainties; at one speed per direction a warning names both
    /// readings (a lag in ms or a backlash in ″). SECONDS removes this lag (positive: the DUT's
    /// sample is older than its stamp; a resolver terminal, SSI/BiSS or CAN encoder lags
    /// 1–50 ms); `0` assumes none. report.json: details.latency_s and details.latency.
    #[arg(long, default_value = "auto", value_parser = crate::input::parse_latency, value_name = "SECONDS|auto")]
    pub latency: Latency,
    /// What the reference is: `encoder`, a better encoder on the DUT's shaft; or `commanded`,
    /// the commanded angle of a motor driven open loop (a firmware calibration: moteus,
    /// SimpleFOC, ODrive), whose rotor follows with the motor's ripple. With `commanded` the
    /// components periodic in the electrical angle (orders k × --pole-pairs) are fitted, taken
    /// out of the map and reported as the motor's ripple (details.ripple); the DUT's own error
    /// at those orders cannot be told from it.
    #[arg(long, value_enum, default_value_t = RefKind::Encoder)]
    pub ref_kind: RefKind,
    /// Pole pairs of the motor of a commanded reference (needs --ref-kind commanded).
    #[arg(long)]
    pub pole_pairs: Option<u32>,
    /// The reference turns R times per turn of the DUT: an actuator's motor encoder before a
    /// gear of ratio R, the DUT its output encoder (any real number, negative where the motor
    /// turns the other way; 50 for a 50:1 harmonic drive). `auto` estimates R from the run, with
    /// its u (details.ratio, details.ratio_u). The reference may count turns or wrap at one.
    /// Both encoders' maps come from the one run: the reference's error, periodic in its own
    /// turn, is fitted (--ref-orders) and written as DIR/<ref>.csv over one of its turns (the
    /// table its controller wants), and the DUT's map is made against the corrected reference.
    /// What repeats with both turns cannot be split and is put in the reference's map: DUT
    /// orders that are multiples of a whole-number R, and over a range everything that repeats
    /// every turn of the reference (named in the summary and report). Over a range with `auto`,
    /// a scale error of the DUT is the ratio's: the map then has no straight-line part. With
    /// --ref-kind commanded (a motor driven open loop before the gear) the reference's map is
    /// the motor's ripple, its orders k × --pole-pairs of the motor's turn.
    #[arg(long, value_name = "R|auto", value_parser = str::parse::<Ratio>, allow_negative_numbers = true)]
    pub ref_ratio: Option<Ratio>,
    /// Orders of the reference's own error fitted through a gear (--ref-ratio), per turn of the
    /// reference.
    #[arg(long, value_name = "K", default_value_t = DEFAULT_REFERENCE_ORDERS, requires = "ref_ratio")]
    pub ref_orders: usize,
    /// Point lists: the reference's readings are in this file, one row per point in the same
    /// order as the log's rows (a protractor's readings noted beside the encoder's); --ref names
    /// its column (`1` in a file without a header row). The two must have as many points.
    #[arg(long, value_name = "FILE")]
    pub ref_file: Option<std::path::PathBuf>,
    /// The reference counts the other way round: its readings are negated (a protractor read as
    /// 180° − reading; the constant does not matter, maps are zero-mean).
    #[arg(long)]
    pub ref_reversed: bool,
    /// Point lists: points whose DUT readings lie within this many degrees of each other are one
    /// target measured again (default: a tenth of the median step between consecutive points).
    #[arg(long, value_name = "DEG")]
    pub target_tol: Option<f64>,
    /// Logs, output, unit, output form, gates, timing.
    #[command(flatten)]
    pub common: MethodArgs,
}

/// What `--ref` is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum RefKind {
    /// A better encoder on the DUT's shaft.
    Encoder,
    /// The commanded angle of a motor driven open loop.
    Commanded,
}

/// The reference kind of the options, checked against `--pole-pairs`.
fn reference_kind(args: &Args) -> Result<ReferenceKind, Usage> {
    match (args.ref_kind, args.pole_pairs) {
        (RefKind::Encoder, None) => Ok(ReferenceKind::Encoder),
        (RefKind::Encoder, Some(_)) => Err(Usage(
            "--pole-pairs is for a commanded reference: add --ref-kind commanded, or drop --pole-pairs".to_string(),
        )),
        (RefKind::Commanded, None) => Err(Usage(
            "--ref-kind commanded needs the motor's --pole-pairs (moteus: motor.poles / 2; a 42-pole motor has 21)"
                .to_string(),
        )),
        (RefKind::Commanded, Some(p)) if p == 0 || args.points < 8 * p as usize => Err(Usage(format!(
            "--pole-pairs {p} needs at least 1 and --points of at least 8 per pole pair ({}): the ripple is fitted \
             on the table's grid",
            8 * p.max(1)
        ))),
        (RefKind::Commanded, Some(p)) => Ok(ReferenceKind::Commanded { pole_pairs: p }),
    }
}

/// `--targets`: a count (`20`) or a comma-separated list of degrees (`15,30.5,45`).
fn parse_targets(text: &str) -> Result<Targets, String> {
    let text = text.trim();
    if !text.contains(',') {
        return match text.parse::<usize>() {
            Ok(k) if k >= 1 => Ok(Targets::Count(k)),
            _ => Err(format!(
                "`{text}`: give a count of targets (≥ 1) or a list of readings in degrees such as 15,30,45"
            )),
        };
    }
    text.split(',')
        .map(|a| match a.trim().parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v.to_radians()),
            _ => Err(format!(
                "`{}` is not an angle in degrees; give the targets as 15,30,45",
                a.trim()
            )),
        })
        .collect::<Result<Vec<_>, _>>()
        .map(Targets::Angles)
}

/// Runs `calib reference`.
impl super::Method for Args {
    const NAME: &'static str = "reference";
    type Prepared = Option<ReferenceTable>;

    fn runs(&self) -> super::Runs<'_> {
        self.common.runs()
    }

    fn prepare(&self) -> anyhow::Result<Self::Prepared> {
        prepare(self)
    }

    fn calibrate(
        &self,
        reference: &Self::Prepared,
        log: &Path,
        out: &Path,
    ) -> anyhow::Result<Outcome> {
        calibrate(self, reference.as_ref(), log, out)
    }
}

/// Checks the arguments before any log is read; the reference's table, read once.
fn prepare(args: &Args) -> anyhow::Result<Option<ReferenceTable>> {
    // With --ref-file the two name columns of different files.
    if args.dut == args.reference && args.ref_file.is_none() {
        return Err(Usage(format!(
            "--dut and --ref both name `{}`: name the encoder to calibrate and the reference",
            args.dut
        ))
        .into());
    }
    crate::input::check_points(Some(args.points))?;
    if let Some(u) = args.ref_u {
        crate::input::check_non_negative("--ref-u", u, "arcseconds")?;
    }
    let reference = args
        .ref_table
        .as_deref()
        .map(ReferenceTable::read)
        .transpose()?;
    if let (Some(path), Some(ReferenceTable { u_max: None, .. })) = (&args.ref_table, &reference) {
        return Err(Usage(format!(
            "--ref-table {}: the table has no u_arcsec column, so the reference's uncertainty is \
             still not known; give a table with u_arcsec, or the reference's stated uncertainty \
             with --ref-u",
            path.display()
        ))
        .into());
    }
    crate::input::check_non_negative("--approach", args.approach, "degrees")?;
    crate::input::check_range(
        "--min-speed",
        args.min_speed,
        0.0,
        360_000.0,
        "degrees per second",
    )?;
    crate::input::check_range("--follow-tol", args.follow_tol, 0.0, 180.0, "degrees")?;
    if let Some(tol) = args.target_tol {
        crate::input::check_range("--target-tol", tol, 0.0, 180.0, "degrees")?;
    }
    if !(args.bridge_gap.is_finite() && (0.0..360.0).contains(&args.bridge_gap)) {
        return Err(Usage(format!(
            "--bridge-gap {} is outside its range: at least 0 and below 360 degrees",
            calib_io::limits::readable(args.bridge_gap)
        ))
        .into());
    }
    reference_kind(args)?;
    if args.ref_ratio.is_some() {
        if args.ref_file.is_some() {
            return Err(Usage(
                "--ref-ratio needs a timed log with both encoders; --ref-file pairs point lists"
                    .to_string(),
            )
            .into());
        }
        crate::input::check_range("--ref-orders", args.ref_orders as f64, 0.0, 200.0, "orders")?;
    }
    Ok(reference)
}

/// Opens `log` (a timed log or a point list) reading the channels `names`, in this order.
fn open(args: &Args, log: &Path, names: &[&str]) -> anyhow::Result<LogReader> {
    let (read, align) = args.common.input.options(args.common.unit)?;
    let read = ReadOptions {
        fields: names.iter().map(|n| n.to_string()).collect(),
        allow_point_list: true,
        ..read
    };
    let mut reader = open_log_with(log, read)?;
    let indices = names
        .iter()
        .map(|n| channel(&reader, log, n))
        .collect::<anyhow::Result<Vec<_>>>()?;
    reader.select(&indices, align);
    Ok(reader)
}

/// Every sample's values of a point list.
fn read_points(log: &Path, reader: LogReader) -> anyhow::Result<(Vec<Vec<f64>>, LogReader)> {
    let (values, _, reader) = read_points_with_rows(log, reader)?;
    Ok((values, reader))
}

/// Every sample's values of a point list, and its row (a point's time is its row's index).
fn read_points_with_rows(
    log: &Path,
    reader: LogReader,
) -> anyhow::Result<(Vec<Vec<f64>>, Vec<usize>, LogReader)> {
    let mut values = Vec::new();
    let mut rows = Vec::new();
    let reader = for_each_sample(log, reader, |s| {
        values.push(s.values.to_vec());
        rows.push(s.t.round() as usize);
    })?;
    Ok((values, rows, reader))
}

/// The reference's readings of a point list from `--ref-file`, paired by row with `dut`'s
/// points.
fn reference_file(args: &Args, log: &Path, file: &Path, points: usize) -> anyhow::Result<Vec<f64>> {
    let reader = open(args, file, &[args.reference.as_str()])?;
    if !reader.is_point_list() {
        anyhow::bail!(
            "{}: --ref-file pairs the rows of two point lists, but this file has a time column; \
             give the reference as a channel of the log with --ref instead",
            file.display()
        );
    }
    let (values, _) = read_points(file, reader)?;
    if values.len() != points {
        anyhow::bail!(
            "{} holds {} point(s) and {} holds {}: --ref-file pairs the two lists row by row, so \
             they must hold as many points; remove the rows that have no partner in the other file",
            log.display(),
            points,
            file.display(),
            values.len()
        );
    }
    Ok(values.into_iter().map(|v| v[0]).collect())
}

/// Calibrates one log into the folder `out`, the reference's readings corrected by its table
/// where given.
fn calibrate(
    args: &Args,
    reference: Option<&ReferenceTable>,
    log: &Path,
    out: &Path,
) -> anyhow::Result<Outcome> {
    let reference_u = match reference {
        Some(r) => r.u_max,
        None => args.ref_u.map(|u| u / ARCSEC_PER_RAD),
    };
    // A calibrated reference reads r − error(r) (its table's correction applied), before a
    // reversed one is negated.
    let corrected = |r: f64| reference.map_or(r, |t| r - t.map.eval_linear(r));
    let names: &[&str] = match args.ref_file {
        Some(_) => &[args.dut.as_str()],
        None => &[args.dut.as_str(), args.reference.as_str()],
    };
    let reader = open(args, log, names)?;
    let sign = if args.ref_reversed { -1.0 } else { 1.0 };
    let context = || {
        format!(
            "{}: DUT `{}`, reference `{}`",
            log.display(),
            args.dut,
            args.reference
        )
    };
    let (cal, reader, points) = if reader.is_point_list() {
        let (values, rows, reader) = read_points_with_rows(log, reader)?;
        // The directions the list states, point by point (none without a `direction` column).
        let directions: Vec<Option<Approach>> =
            reader.point_directions().map_or_else(Vec::new, |d| {
                rows.iter().map(|&r| d.get(r).copied().flatten()).collect()
            });
        let reference: Vec<f64> = match &args.ref_file {
            Some(file) => reference_file(args, log, file, values.len())?,
            None => values.iter().map(|v| v[1]).collect(),
        };
        let points: Vec<(f64, f64)> = values
            .iter()
            .zip(&reference)
            .map(|(v, &r)| (v[0], sign * corrected(r)))
            .collect();
        let opts = PointOptions {
            points: args.points,
            reference_u: reference_u.unwrap_or(0.0),
            follow_tol: args.follow_tol.to_radians(),
            max_gap: args.bridge_gap.to_radians(),
            target_tol: args.target_tol.map(f64::to_radians),
        };
        let cal = calibrate_points_with_directions(&points, &directions, &opts)
            .with_context(context)
            .map_err(|e| in_log(e, &reader, log))?;
        (cal, reader, Some(points.len()))
    } else {
        if let Some(file) = &args.ref_file {
            return Err(Usage(format!(
                "--ref-file {} pairs the rows of two point lists, but {} has a time column; name \
                 the reference as a channel of the log with --ref",
                file.display(),
                log.display()
            ))
            .into());
        }
        let opts = ReferenceOptions {
            points: args.points,
            min_speed: args.min_speed.to_radians(),
            reference_u: reference_u.unwrap_or(0.0),
            follow_tol: args.follow_tol.to_radians(),
            approach: args.approach.to_radians(),
            max_gap: args.bridge_gap.to_radians(),
            targets: args.targets.clone(),
            latency: args.latency,
            reference_kind: reference_kind(args)?,
        };
        let gear = args.ref_ratio.map(|ratio| Gear {
            ratio,
            reference_orders: args.ref_orders,
        });
        let mut cal = ReferenceRun::new(opts, gear);
        // The sample's values are the DUT's reading, then the reference's.
        let reader = for_each_sample(log, reader, |s| {
            cal.push(s.t, s.values[0], sign * corrected(s.values[1]))
        })?;
        let cal = cal
            .finish()
            .map_err(|e| match e {
                ReferenceError::TooLittleMotion { .. } | ReferenceError::NotCovered { .. } => {
                    with_time_hint(e, &reader, Some(args.min_speed.to_radians()))
                }
                e => with_time_hint(e, &reader, None),
            })
            .with_context(context)
            .map_err(|e| in_log(e, &reader, log))?;
        (cal, reader, None)
    };
    let table = calib_io::table::render_table(&cal.map, Some(&cal.u))
        .with_context(|| format!("the table of channel `{}`", args.dut))?;
    let mut tables = vec![(table_name(&args.dut), table.into_bytes())];
    let mut channels = vec![args.dut.clone()];
    if let Some(m) = cal.gear.as_ref().and_then(|g| g.reference_map.as_ref()) {
        let map = calib_core::TableMap::Turn(m.map.clone());
        let table = calib_io::table::render_table(&map, Some(&m.u))
            .with_context(|| format!("the table of channel `{}`", args.reference))?;
        tables.push((table_name(&args.reference), table.into_bytes()));
        channels.push(args.reference.clone());
    }
    let results = Results {
        section: cal.report_section(
            &args.dut,
            &args.reference,
            reference_u.map(|u| u * ARCSEC_PER_RAD),
        ),
        tables,
        channels,
        residual_rms_arcsec: None,
        document: Box::new(|report| document::document(&args.dut, &args.reference, &cal, report)),
        summary: Box::new(|report| render_summary(args, out, &cal, report, points)),
    };
    finish_log(&reader, log, out, args.common.presentation(), results)
}
