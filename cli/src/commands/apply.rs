//! `calib apply`: a log rewritten with one channel corrected by a correction table.

use crate::exit::Usage;
use crate::input::{channel, open_log, parse_unit};
use crate::json::ApplyJson;
use crate::units::UnitCheck;
use anyhow::Context;
use calib_core::AngleUnit;
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::correction::Wrapping;
use calib_io::LogFormat;
use calib_io::apply::{Applied, ApplyOptions, apply_scanned, scan};
use calib_io::table::Table;
use std::fmt::Write;
use std::path::PathBuf;

/// How the channel's readings are wrapped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Wrap {
    /// Detect from the readings' range: [0, 1 rev) if they all lie there, else [−½, ½) rev if
    /// they all lie there, else unwrapped.
    Auto,
    /// Readings in [0, 1 rev), e.g. [0, 360) degrees.
    Positive,
    /// Readings in [−½, ½) rev, e.g. [−180, 180) degrees.
    Signed,
    /// Accumulated readings: never wrapped.
    None,
}

/// Write a log with one channel corrected by a correction table.
///
/// Every reading r of the channel becomes r + correction(r) = r − error(r), the table
/// interpolated linearly and periodically at r, as a controller loading `calib export`'s table
/// does. The output has the input's format and content: a CSV keeps its header, columns, time
/// stamps, sessions and other channels byte for byte, the channel written in the same unit; an
/// MCAP keeps every schema, channel, topic, message time and sequence number, metadata record
/// and attachment, and only the messages carrying the channel change (the joint's position in a
/// JointState message, the field's number in a JSON one). Wrapped readings stay wrapped the same
/// way (359.9999° corrected by +0.5″ becomes 0.0001°, not 360.0001°); accumulated ones stay
/// accumulated. The log is read twice (once to find the readings' range, skipped with --wrap)
/// and streamed: memory stays small whatever its size. OUT appears only when complete.
///
/// A range table (a joint that never turns a whole revolution, first line `# range_deg: LO to
/// HI`) corrects the readings inside its range; readings outside it are copied unchanged,
/// counted in the summary and warned about (never extrapolated).
///
/// With --keep the channel stays as it was and the corrected readings are added beside it (a
/// CSV column, an MCAP topic): see --keep.
///
/// Example: `calib apply calib-out/a.csv run.mcap -o run-corrected.mcap`
#[derive(Debug, clap::Args, PartialEq)]
pub struct Args {
    /// The correction table (`angle_deg,error_arcsec,correction_arcsec[,u_arcsec]`), e.g. from
    /// `calib csrr`.
    pub table: PathBuf,
    /// The log to correct (.csv or .mcap; a CSV log in any dialect the methods read, also as
    /// .tsv, .txt or .dat).
    pub log: PathBuf,
    /// The corrected log to write, in the same format as LOG (a CSV log as .csv, .tsv, .txt or
    /// .dat, in LOG's dialect; an MCAP log as .mcap) and not LOG itself.
    #[arg(short, long = "output", value_name = "FILE")]
    pub output: PathBuf,
    /// The channel to correct (default: the table's file name without extension, so
    /// `calib-out/a.csv` corrects channel `a`): a CSV column, a joint or JSON field by its name,
    /// or as TOPIC/NAME to correct it on that topic only.
    #[arg(long)]
    pub channel: Option<String>,
    /// Unit of CSV readings and JSON fields: deg (default), rad, arcsec, rev, counts:N.
    /// JointState positions are radians. Without it, readings that fit radians or counts and
    /// not degrees (a whole turn within [0, 2π), whole numbers beyond 1024) are refused before
    /// anything is written, naming the likely unit, as the methods refuse them.
    #[arg(long, value_parser = parse_unit)]
    pub unit: Option<AngleUnit>,
    /// How the channel's readings are wrapped (revolutions of their unit).
    #[arg(long, value_enum, default_value_t = Wrap::Auto)]
    pub wrap: Wrap,
    /// Leave out MCAP chunks whose checksum (CRC) does not match (their messages are not in the
    /// output), warning about each. Without it a damaged chunk is an error (exit 1) and nothing
    /// is written.
    #[arg(long)]
    pub skip_damaged: bool,
    /// Keep the channel as it was and add the corrected one beside it, for viewers (Foxglove,
    /// PlotJuggler) to plot the two together: a CSV gets a column `<channel>_corrected` right
    /// after the channel's; an MCAP log a copy of every message carrying the channel, corrected,
    /// on the topic `<topic>/corrected` (same schema; the joint or field keeps its name, so calib
    /// reads it back as `<topic>/corrected/<channel>`).
    #[arg(long)]
    pub keep: bool,
    /// Threads to work on (default: the CALIB_JOBS environment variable, else the number of
    /// cores). 1: the log is read, corrected and written on one thread; more: an MCAP log of
    /// several chunks has its chunks decompressed on up to two threads and its new chunks
    /// compressed on up to two more, written on a thread of its own. The output is the same,
    /// byte for byte, either way.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    pub jobs: Option<u16>,
    /// Print what was done as JSON (docs/apply.schema.json) instead of the summary.
    #[arg(long)]
    pub json: bool,
    /// Replace FILE even if calib did not write it (without it, a file there that no calib
    /// manifest of its folder lists is refused, exit 2, and left as it is).
    #[arg(long)]
    pub force: bool,
}

/// Runs `calib apply`: checks the arguments, corrects the log, says what was done.
pub fn run(args: &Args) -> anyhow::Result<String> {
    let (name, format) = validate(args)?;
    let table = calib_io::table::read_table(&args.table)
        .with_context(|| format!("cannot read the table {}", args.table.display()))?;
    let reader = open_log(&args.log, args.unit, args.skip_damaged)?;
    channel(&reader, &args.log, &name).with_context(|| {
        if args.channel.is_none() {
            format!(
                "the channel is named after the table {}; name it with --channel",
                args.table.display()
            )
        } else {
            "choose the channel with --channel".to_string()
        }
    })?;
    let notes: Vec<String> = reader
        .notes()
        .iter()
        .map(|n| crate::flags::in_cli_words(n))
        .collect();
    drop(reader);

    let opts = ApplyOptions {
        channel: name.clone(),
        unit: args.unit,
        wrapping: match args.wrap {
            Wrap::Auto => None,
            Wrap::Positive => Some(Wrapping::Positive),
            Wrap::Signed => Some(Wrapping::Signed),
            Wrap::None => Some(Wrapping::Unwrapped),
        },
        skip_damaged: args.skip_damaged,
        keep: args.keep,
        one_thread: crate::threads::read_inline(),
    };
    let cannot = || format!("cannot correct {}", args.log.display());
    let readings = scan(&args.log, &opts).with_context(cannot)?;
    // The unit checked against the readings as the methods check it, before anything is written.
    UnitCheck::of_range(
        &name,
        args.unit,
        readings.unit,
        (readings.min, readings.max),
        readings.whole,
    )
    .finish(&args.log)?;
    let done = apply_scanned(&args.log, &args.output, &table.map, &opts, &readings)
        .with_context(cannot)?;
    crate::output::record_written([&args.output]);
    if args.json {
        return render_json(args, &name, &table, &done, &notes);
    }
    Ok(render_summary(args, &name, format, &table, &done, &notes))
}

/// The channel to correct and the log's format, once the paths are checked: the table exists,
/// the log is a CSV or MCAP file, and the output is another file of the same format.
fn validate(args: &Args) -> anyhow::Result<(String, LogFormat)> {
    if !args.table.exists() {
        return Err(Usage(format!(
            "{}: no such table; check the path",
            args.table.display()
        ))
        .into());
    }
    let name = match &args.channel {
        Some(name) => name.clone(),
        None => args
            .table
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .ok_or_else(|| Usage("name the channel to correct with --channel".into()))?,
    };
    if calib_io::source::url_of(&args.log).is_some() {
        return Err(Usage(format!(
            "{}: calib apply rewrites a local log; download it first and name the copy",
            crate::ui::shown(&args.log)
        ))
        .into());
    }
    crate::input::check_log_path(&args.log)?;
    crate::overwrite::check(
        &args.output,
        &format!("-o {}", crate::ui::shown(&args.output)),
    )?;
    crate::output::prepare_file(&args.output, "-o")?;
    let format = LogFormat::detect(&args.log)?;
    if let Some(why) = format.not_rewritten() {
        return Err(Usage(format!("{}: {why}", args.log.display())).into());
    }
    if !calib_io::apply::fits_output(format, &args.output) {
        let extensions = calib_io::apply::output_extensions(format);
        let example = args
            .log
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .filter(|e| extensions.contains(&e.as_str()))
            .unwrap_or_else(|| extensions[0].to_string());
        let listed: Vec<String> = extensions.iter().map(|e| format!(".{e}")).collect();
        let listed = match listed.split_last() {
            Some((last, rest)) if !rest.is_empty() => format!("{} or {last}", rest.join(", ")),
            _ => listed.join(""),
        };
        return Err(Usage(format!(
            "{} is a .{} log; name the output {listed}, in the same format (e.g. -o \
             corrected.{example})",
            args.log.display(),
            format.name(),
        ))
        .into());
    }
    Ok((name, format))
}

/// What `calib apply` did: readings corrected, their range and wrapping, what was copied,
/// and the warnings.
fn render_summary(
    args: &Args,
    name: &str,
    format: LogFormat,
    table: &Table,
    done: &Applied,
    notes: &[String],
) -> String {
    let mut o = String::new();
    let (points, pp, span) = (table.map.len(), table.map.peak_to_peak(), range_deg(table));
    let _ = writeln!(
        o,
        "corrected {} readings of `{name}` in {} with {} ({points} points{}, error peak-to-peak \
         {:.3}″, interpolated linearly)",
        done.readings - done.outside,
        args.log.display(),
        args.table.display(),
        span.map_or(String::new(), |(lo, hi)| format!(
            ", range {}° to {}°",
            short(lo),
            short(hi)
        )),
        pp * ARCSEC_PER_RAD
    );
    let unit = done.unit;
    let rev = unit.from_rad(std::f64::consts::TAU);
    let range = match done.wrapping {
        Wrapping::Positive => format!("kept in [0, {}) {unit}", short(rev)),
        Wrapping::Signed => format!(
            "kept in [{}, {}) {unit}",
            short(-rev / 2.0),
            short(rev / 2.0)
        ),
        Wrapping::Unwrapped => "left unwrapped".to_string(),
    };
    let _ = writeln!(
        o,
        "  readings from {} to {} {unit}: {range}{}",
        short(done.range.0),
        short(done.range.1),
        if args.wrap == Wrap::Auto {
            " (detected; see --wrap)"
        } else {
            ""
        }
    );
    if args.keep {
        let what = if format == LogFormat::Csv {
            "column"
        } else {
            "topic"
        };
        let names: Vec<String> = done.beside.iter().map(|n| format!("`{n}`")).collect();
        let _ = writeln!(
            o,
            "  `{name}` kept as it was (--keep); the corrected readings are beside it, in {what} {}",
            names.join(", ")
        );
    }
    if format == LogFormat::Mcap {
        let _ = writeln!(
            o,
            "  {} other messages copied unchanged, with every schema, channel, metadata record \
             and attachment",
            done.copied
        );
    }
    let _ = writeln!(o, "wrote {}", args.output.display());
    for w in warnings(args, name, done, span) {
        let _ = writeln!(o, "\nwarning: {w}");
    }
    for w in notes {
        let _ = writeln!(o, "note: {w}; copied unchanged");
    }
    o
}

/// What the user should know about a correction: a log that ended early, damaged chunks left
/// out, readings outside a range table's range.
fn warnings(args: &Args, name: &str, done: &Applied, span: Option<(f64, f64)>) -> Vec<String> {
    let mut w = Vec::new();
    if let Some(t) = &done.truncated {
        w.push(format!(
            "{}: the log ends early at byte {} (a crashed recording?): the output holds the {} \
             messages before the break",
            args.log.display(),
            t.byte_offset,
            t.messages_read
        ));
    }
    if !done.damaged_chunks.is_empty() {
        let list: Vec<String> = done.damaged_chunks.iter().map(|c| c.to_string()).collect();
        w.push(format!(
            "{}: skipped {} damaged chunk(s) and their messages (--skip-damaged); the output \
             leaves them out: {}",
            args.log.display(),
            done.damaged_chunks.len(),
            list.join("; ")
        ));
    }
    if let Some((lo, hi)) = span.filter(|_| done.outside > 0) {
        w.push(format!(
            "{} of {} readings of `{name}` lie outside the table's range {}° to {}° and were \
             copied unchanged (a range table says nothing there); calibrate over the whole \
             travel to correct them",
            done.outside,
            done.readings,
            short(lo),
            short(hi)
        ));
    }
    w
}

/// `calib apply --json`.
fn render_json(
    args: &Args,
    name: &str,
    table: &Table,
    done: &Applied,
    notes: &[String],
) -> anyhow::Result<String> {
    let span = range_deg(table);
    crate::json::render(&ApplyJson {
        schema_version: calib_core::report::SCHEMA_VERSION,
        log: args.log.display().to_string(),
        table: args.table.display().to_string(),
        output: args.output.display().to_string(),
        channel: name.to_string(),
        unit: done.unit.to_string(),
        corrected: done.readings - done.outside,
        outside: done.outside,
        range: [done.range.0, done.range.1],
        beside: done.beside.clone(),
        wrapping: match done.wrapping {
            Wrapping::Positive => "positive",
            Wrapping::Signed => "signed",
            Wrapping::Unwrapped => "unwrapped",
        }
        .to_string(),
        copied: (done.format == LogFormat::Mcap).then_some(done.copied),
        warnings: warnings(args, name, done, span),
        notes: notes.to_vec(),
    })
}

/// `x` with at most 6 decimals, trailing zeros dropped (`360`, `6.283185`, `-0.5`).
fn short(x: f64) -> String {
    calib_core::report::trimmed(x, 6)
}

/// A range table's range in degrees, from its first grid angle (in `[0°, 360°)`) to its last
/// (above 360° across the reading 0); `None` for a whole turn.
fn range_deg(table: &Table) -> Option<(f64, f64)> {
    table
        .map
        .range()
        .map(|(start, end)| (start.to_degrees(), end.to_degrees()))
}
