//! `calib inspect`: what a log holds.

use crate::input::{LogArgs, alignment_text, channel, open_log_with, parse_unit};
use crate::summary::TextTable;
use anyhow::Context;
use calib_core::AngleUnit;
use calib_core::inspect::{Inspection, Inspector};
use calib_core::segment::{SegmentKind, SegmentOptions};
use calib_io::ReadOptions;
use calib_io::mcap_log::TopicInfo;
use std::fmt::Write;
use std::path::PathBuf;

/// Show what a log holds before calibrating from it.
///
/// Lists the channels (unit, range, revolutions), the exact sample count, duration, sample rate
/// and its jitter, gaps and time stamps that go backwards, the segments of the log for a pair of
/// channels — stationary, rotating together (CSRR sessions, with the relative angle between the
/// two), turning — and the speed variation over a revolution in cycles per revolution. For an
/// MCAP log it lists every topic first: message type, encoding, message count, rate, and its
/// channels by the names the other commands accept.
///
/// Channels on separate topics are aligned on the stamps of the pair's first channel (or the log's
/// first channel), as the methods do.
#[derive(Debug, clap::Args, PartialEq)]
#[command(after_long_help = crate::input::channel_names())]
pub struct Args {
    /// The log (.csv, .mcap, a rosbag2 bag: its directory or a .db3 file, or a ROS 1 .bag), or
    /// its URL (s3://, gs://, az://, http(s)://; see docs/recordings.md).
    pub log: PathBuf,
    /// Unit of CSV, JSON and std_msgs readings: deg (the default), rad, arcsec, rev, counts:N.
    /// JointState positions are radians.
    #[arg(long, value_parser = parse_unit)]
    pub unit: Option<AngleUnit>,
    /// First channel of the pair to segment (default: `a`, else the log's first channel).
    #[arg(long)]
    pub a: Option<String>,
    /// Second channel of the pair (default: `b`, else the log's second channel).
    #[arg(long)]
    pub b: Option<String>,
    /// Print the findings as JSON instead of tables.
    #[arg(long)]
    pub json: bool,
    /// Threads to read on (default: the CALIB_JOBS environment variable, else the number of
    /// cores). 1: the log is read and inspected on one thread; more: it is read ahead on a
    /// second thread (MCAP chunks decompressed on up to two more).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    pub jobs: Option<u16>,
    /// How the log is timed (CSV time column, MCAP stamps) and its channels aligned.
    #[command(flatten)]
    pub input: LogArgs,
}

/// Runs `calib inspect`.
pub fn run(args: &Args) -> anyhow::Result<String> {
    let (opts, align) = args.input.options(args.unit)?;
    let opts = ReadOptions {
        allow_unordered_time: true,
        allow_point_list: true,
        fields: [&args.a, &args.b].into_iter().flatten().cloned().collect(),
        ..opts
    };
    let mut pass = read(args, opts.clone(), align, &[])?;
    // A column of a CSV file empty in every row (a sparse file's) leaves nothing to align the
    // other channels on: it is listed, and the log read again without it. Found only once the
    // file is read, so such a file is read twice.
    let empty = pass.without_readings.clone();
    if pass.result.samples == 0 && !empty.is_empty() && empty.len() < pass.names.len() {
        pass = read(args, opts, align, &empty)?;
    }
    let Pass {
        reader,
        result,
        names,
        point_list,
        structure,
        layout,
        ..
    } = pass;
    if result.samples == 0 {
        anyhow::bail!("{}: the log holds no samples", args.log.display());
    }
    let suggestions = calib_core::purpose::suggestions(&result);
    let warnings: Vec<String> = empty
        .iter()
        .map(|&i| {
            format!(
                "{}: column `{}` is empty (no reading in any row): left out, the other channels \
                 are inspected without it",
                crate::ui::shown(&args.log),
                names[i]
            )
        })
        .chain(
            reader
                .inspect_warnings(&args.log)
                .iter()
                .map(|w| crate::flags::in_cli_words(w)),
        )
        .collect();
    let topics = reader.topics();
    let alignment = reader.alignment();
    let reading = reader.reading();
    let stated = reader.stated_directions();
    if args.json {
        let json = InspectJson {
            schema_version: calib_core::report::SCHEMA_VERSION,
            log: args.log.display().to_string(),
            point_list,
            points: point_list.then_some(result.samples),
            stated_directions: stated,
            structure,
            topics,
            alignment,
            reading,
            inspection: result,
            suggestions,
            warnings,
        };
        return crate::json::render(&json);
    }
    if point_list {
        return Ok(render_points(
            &args.log,
            &result,
            layout.as_deref(),
            stated,
            &warnings,
        ));
    }
    let mut text = render(&args.log, &result, &render_topics(&topics), &warnings);
    // After the file's name: how it was read.
    let at = text.find('\n').map_or(text.len(), |i| i + 1);
    if let Some(choice) = reading.as_ref().and_then(|r| r.time_unit.as_ref()) {
        let line = format!(
            "  time: column `{}` read in {}: {}\n",
            choice.column,
            choice.unit,
            crate::flags::in_cli_words(&choice.reason)
        );
        text.insert_str(at, &line);
    }
    if let Some(layout) = layout {
        text.insert_str(at, &format!("  read as: {layout}\n"));
    }
    Ok(text + &alignment_text(alignment.as_ref()) + &render_next(&args.log, &suggestions))
}

/// One reading of the log for `calib inspect`.
struct Pass {
    /// The reader, read to its end.
    reader: calib_io::LogReader,
    result: Inspection,
    /// Every channel of the log, read or not.
    names: Vec<String>,
    point_list: bool,
    /// What a columnar file holds ([`InspectJson::structure`]).
    structure: Vec<String>,
    /// How the file was read, for the `read as:` line.
    layout: Option<String>,
    /// The channels read that had no reading at all (indices into `names`).
    without_readings: Vec<usize>,
}

/// Reads the log of `args` with every channel but those of `skip` (indices into the log's
/// channels), the pair's first (or the log's first) channel setting the clock.
fn read(
    args: &Args,
    opts: ReadOptions,
    align: calib_io::AlignOptions,
    skip: &[usize],
) -> anyhow::Result<Pass> {
    let mut reader = open_log_with(&args.log, opts)?;
    let names: Vec<String> = reader.names().iter().map(|n| n.display.clone()).collect();
    let read: Vec<usize> = (0..names.len()).filter(|i| !skip.contains(i)).collect();
    let pick =
        |given: &Option<String>, default: &str, fallback: usize| -> anyhow::Result<Option<usize>> {
            let found = match given {
                Some(name) => Some(channel(&reader, &args.log, name)?),
                None if names.iter().any(|n| n == default) => {
                    Some(channel(&reader, &args.log, default)?)
                }
                None => read.get(fallback).copied(),
            };
            match found {
                Some(i) if skip.contains(&i) => match given {
                    Some(name) => anyhow::bail!(
                        "{}: channel `{name}` is an empty column (no reading in any row); \
                         choose another channel",
                        crate::ui::shown(&args.log)
                    ),
                    // The default `a` or `b` is empty: the first channels with readings.
                    None => Ok(read.get(fallback).copied()),
                },
                found => Ok(found),
            }
        };
    let a = pick(&args.a, "a", 0)?;
    let b = pick(&args.b, "b", 1)?;
    let pair = match (a, b) {
        // A point list has no motion to segment.
        (Some(a), Some(b)) if a != b && !reader.is_point_list() => Some((a, b)),
        _ => None,
    };
    let point_list = reader.is_point_list();
    // How the file was read: a CSV dialect other than the plain one, or what a columnar file
    // holds and where its time came from.
    let structure: Vec<String> = reader
        .structure()
        .iter()
        .map(|l| crate::flags::in_cli_words(l))
        .collect();
    let layout = reader
        .csv_dialect()
        .filter(|d| !d.is_plain())
        .map(|d| d.describe())
        .or_else(|| (!structure.is_empty()).then(|| structure.join("\n    ")));
    // Every channel read, the pair's first (or the first read) leading: it sets the clock.
    let clock = pair.map_or_else(|| read.first().copied().unwrap_or(0), |(a, _)| a);
    let order: Vec<usize> = std::iter::once(clock)
        .chain(read.iter().copied().filter(|&i| i != clock))
        .collect();
    reader.select(&order, align);
    let at = |raw: usize| order.iter().position(|&i| i == raw).unwrap_or(0);
    let pair = pair.map(|(a, b)| (at(a), at(b)));
    let marks = reader.has_session_marks();
    let mut inspector = Inspector::new(
        reader.channels(),
        pair,
        SegmentOptions {
            use_marks: marks,
            ..SegmentOptions::default()
        },
    );
    // Decoding runs ahead on a second thread.
    let mut samples = crate::threads::prefetch(reader);
    while let Some(batch) = samples.next_batch() {
        let batch = batch.with_context(|| format!("cannot read {}", args.log.display()))?;
        for s in batch.iter() {
            inspector.push(s.t, s.values, s.session);
        }
    }
    let reader = samples.finish();
    let result = inspector.finish().with_time_origin(reader.time_origin_s());
    let without_readings = reader.channels_without_readings();
    Ok(Pass {
        reader,
        result,
        names,
        point_list,
        structure,
        layout,
        without_readings,
    })
}

/// Which command to run next: one line per method the log suits, with its channels.
fn render_next(log: &std::path::Path, suggestions: &[calib_core::purpose::Suggestion]) -> String {
    let mut o = String::new();
    if suggestions.is_empty() {
        return o;
    }
    let _ = writeln!(o, "\nnext:");
    for s in suggestions {
        let c = &s.channels;
        let options = match (s.method.as_str(), c.as_slice()) {
            ("csrr", [a, b]) => format!("--a {a} --b {b}"),
            ("reference", [dut, reference]) => format!("--dut {dut} --ref {reference}"),
            ("tdr", [channel]) => format!("--channel {channel}"),
            ("tdr", [channel, reference]) => format!("--channel {channel} --ref {reference}"),
            // Each head's nominal angle is the user's to give.
            ("multihead", heads) => format!(
                "--heads {}@0,{}",
                heads[0],
                heads[1..]
                    .iter()
                    .map(|h| format!("{h}@DEG"))
                    .collect::<Vec<_>>()
                    .join(",")
            ),
            _ => c.join(" "),
        };
        let extra: String = s.options.iter().map(|x| format!(" {x}")).collect();
        let _ = writeln!(
            o,
            "  calib {} {} {options}{extra}\n    ({})",
            s.method,
            log.display(),
            s.why
        );
    }
    o
}

/// `calib inspect --json`.
#[derive(Debug, serde::Serialize, schemars::JsonSchema)]
pub struct InspectJson {
    /// The version of this output's shape (as report.json's).
    pub schema_version: u32,
    /// The log, as given.
    pub log: String,
    /// The log is a list of stationary points without time (a CSV file without a time column):
    /// its samples are its rows, timed by their index (0, 1, 2, … s), and it has no motion to
    /// segment; `calib reference` calibrates from it.
    pub point_list: bool,
    /// The points of a point list; `null` for a timed log.
    pub points: Option<u64>,
    /// Points of a point list whose direction of approach its `direction` column states (a
    /// non-empty cell); `null` without such a column.
    pub stated_directions: Option<u64>,
    /// What a columnar file (TDMS, MATLAB, HDF5, Parquet) holds: its format, then its groups,
    /// variables, datasets or columns, a line each, and where the time was taken from; absent
    /// for the other formats.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub structure: Vec<String>,
    /// The log's topics (MCAP and rosbag2; none for CSV), read or not.
    pub topics: Vec<TopicInfo>,
    /// How the channels were aligned on one clock (`null` for one channel or CSV).
    pub alignment: Option<calib_core::report::Alignment>,
    /// How the log was read where the reader decided something the user did not say: messages
    /// dropped as exact copies, the unit a CSV time column was read in by its magnitude (as in
    /// report.json's `details.reading`); absent where it decided nothing.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reading: Option<calib_core::report::Reading>,
    /// What the log holds: timing, channels, segments.
    pub inspection: Inspection,
    /// The methods the log's motion suits, the likeliest first, with the channels to give them.
    pub suggestions: Vec<calib_core::purpose::Suggestion>,
    /// What the user should know about the log.
    pub warnings: Vec<String>,
}

/// Width the channel lists of the topic table are wrapped at.
const LINE_WIDTH: usize = 100;

/// The topic table: one line per topic (type, encoding, messages, rate), its channels wrapped
/// below it; empty for a log without topics (CSV).
fn render_topics(topics: &[TopicInfo]) -> String {
    let mut o = String::new();
    if topics.is_empty() {
        return o;
    }
    let read = topics.iter().filter(|t| !t.channels.is_empty()).count();
    let _ = writeln!(o, "topics: {read} read, {} not read", topics.len() - read);
    let width = topics.iter().map(|t| t.topic.len()).max().unwrap_or(0);
    let type_width = topics.iter().map(|t| t.schema.len()).max().unwrap_or(0);
    for t in topics {
        let rate = t
            .rate_hz
            .map_or_else(|| "—".to_string(), |r| format!("{r:.2} Hz"));
        let _ = writeln!(
            o,
            "  {:<width$}  {:<type_width$}  {:<5} {:>9} msg {:>12}{}",
            t.topic,
            t.schema,
            t.message_encoding,
            t.messages,
            rate,
            if !t.channels.is_empty() {
                ""
            } else if calib_io::is_bookkeeping(&t.topic) {
                "  (not read: ROS bookkeeping)"
            } else {
                "  (not read)"
            }
        );
        let mut line = String::from("     ");
        for (i, c) in t.channels.iter().enumerate() {
            let item = if i + 1 < t.channels.len() {
                format!(" {c},")
            } else {
                format!(" {c}")
            };
            if line.len() + item.len() > LINE_WIDTH && line.len() > 5 {
                let _ = writeln!(o, "{line}");
                line = String::from("     ");
            }
            line.push_str(&item);
        }
        if line.len() > 5 {
            let _ = writeln!(o, "{line}");
        }
    }
    let _ = writeln!(o);
    o
}

/// The human report of a point list: its points and channels, and how to calibrate from it.
fn render_points(
    path: &std::path::Path,
    r: &Inspection,
    layout: Option<&str>,
    stated: Option<u64>,
    warnings: &[String],
) -> String {
    let mut o = String::new();
    let _ = writeln!(o, "{}", path.display());
    if let Some(layout) = layout {
        let _ = writeln!(o, "  read as: {layout}");
    }
    let _ = writeln!(
        o,
        "  a list of {} stationary points (no time column): each row one measurement, in the \
         order measured",
        r.samples
    );
    match stated {
        Some(stated) if stated == r.samples => {
            let _ = writeln!(
                o,
                "  directions of approach: every point's stated by its direction column"
            );
        }
        Some(stated) => {
            let _ = writeln!(
                o,
                "  directions of approach: {stated} of {} stated by its direction column, the \
                 others taken from the order of the points",
                r.samples
            );
        }
        None => {}
    }
    let _ = writeln!(o, "\nchannels");
    let mut channels = TextTable::new(&["name", "unit", "min", "max", "revs"]);
    for c in &r.channels {
        channels.row(vec![
            c.name.clone(),
            c.unit.to_string(),
            format!("{:.6}", c.min),
            format!("{:.6}", c.max),
            format!("{:.3}", c.revolutions),
        ]);
    }
    o.push_str(&channels.render());
    let _ = writeln!(
        o,
        "\ncalibrate an encoder against a reference from it: calib reference {} --dut ENCODER \
         --ref REFERENCE, naming two of the channels above (the reference's readings may come \
         from a second list with the same rows: --ref-file FILE)",
        path.display(),
    );
    for w in warnings {
        let _ = writeln!(o, "\nwarning: {w}");
    }
    o
}

/// The human report.
fn render(path: &std::path::Path, r: &Inspection, topics: &str, warnings: &[String]) -> String {
    let mut o = String::new();
    let duration = r.end_s - r.start_s;
    let _ = writeln!(o, "{}", path.display());
    let _ = writeln!(
        o,
        "  {} samples over {:.3} s ({:.3} … {:.3} s), {:.2} Hz mean, interval jitter {:.3} ms",
        r.samples,
        duration,
        r.start_s,
        r.end_s,
        r.rate_hz,
        r.interval_jitter_s * 1e3
    );
    let _ = writeln!(
        o,
        "  gaps (> 2× nominal interval): {}   stamps not increasing: {}",
        r.gaps, r.non_monotonic
    );
    for g in &r.gap_list {
        let _ = writeln!(
            o,
            "    gap of {:.4} s before sample {} at {:.4} s",
            g.step_s, g.index, g.t
        );
    }
    for g in &r.non_monotonic_list {
        if g.step_s == 0.0 {
            let _ = writeln!(
                o,
                "    stamp repeats the previous one at sample {} ({:.6} s)",
                g.index, g.t
            );
        } else {
            let _ = writeln!(
                o,
                "    stamp steps back by {:.6} s at sample {} ({:.6} s)",
                -g.step_s, g.index, g.t
            );
        }
    }
    if !topics.is_empty() {
        let _ = write!(o, "\n{}", topics.trim_end_matches('\n'));
        let _ = writeln!(o);
    }
    let _ = writeln!(o, "\nchannels");
    let mut channels = TextTable::new(&["name", "unit", "min", "max", "revs", "wrapped"]);
    for c in &r.channels {
        channels.row(vec![
            c.name.clone(),
            c.unit.to_string(),
            format!("{:.6}", c.min),
            format!("{:.6}", c.max),
            format!("{:.3}", c.revolutions),
            if c.wrapped { "yes" } else { "no" }.to_string(),
        ]);
    }
    o.push_str(&channels.render());
    if let Some((a, b)) = &r.pair {
        let _ = writeln!(o, "\nsegments of {a} and {b}");
        let mut segments = TextTable::new(&[
            "kind",
            "start s",
            "end s",
            "samples",
            "revs",
            "a−b deg",
            "session",
        ]);
        for s in &r.segments {
            let kind = match s.kind {
                SegmentKind::Stationary => "stationary",
                SegmentKind::Rotating => "rotating",
                SegmentKind::Turning => "turning",
            };
            let rel = if s.kind == SegmentKind::Rotating {
                format!(
                    "{:.4}",
                    calib_core::angle::wrap_pi(s.relative_angle).to_degrees()
                )
            } else {
                String::new()
            };
            let session = match (s.kind, s.session) {
                (SegmentKind::Rotating, Some(k)) => format!("#{k}"),
                (SegmentKind::Rotating, None) => "too short (< 1 rev)".to_string(),
                _ => String::new(),
            };
            segments.row(vec![
                kind.to_string(),
                format!("{:.3}", s.start_s),
                format!("{:.3}", s.end_s),
                s.samples.to_string(),
                format!("{:.3}", s.revolutions),
                rel,
                session,
            ]);
        }
        o.push_str(&segments.render());
        let sessions = r
            .segments
            .iter()
            .filter(|s| s.session.is_some() && s.kind == SegmentKind::Rotating)
            .count();
        let _ = writeln!(o, "  {sessions} CSRR session(s) of at least one revolution");
    }
    let _ = writeln!(
        o,
        "\nspeed variation over a revolution (from each channel's own readings)"
    );
    for c in &r.channels {
        let top: Vec<String> = c
            .speed_spectrum
            .iter()
            .take(5)
            .map(|h| {
                format!(
                    "{}: {:.3} % ({:.2}″)",
                    h.order, h.speed_percent, h.position_arcsec
                )
            })
            .collect();
        let _ = writeln!(
            o,
            "  {:<16} {}",
            c.name,
            if top.is_empty() {
                "not every angle was passed while moving".to_string()
            } else {
                top.join(", ")
            }
        );
    }
    for w in warnings {
        let _ = writeln!(o, "\nwarning: {w}");
    }
    o
}
