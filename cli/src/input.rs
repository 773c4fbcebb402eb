//! Opening logs and finding channels, with errors that say what to do.

use crate::exit::Usage;
use anyhow::Context;
use calib_core::AngleUnit;
use calib_core::report::Alignment;
use calib_io::AlignOptions;
use calib_io::csv_log::dialect::TimeUnit;
use calib_io::limits::MAX_TABLE_POINTS;
use calib_io::{LogReader, ReadOptions, TimeSource};
use std::fmt::Write;
use std::path::Path;

/// How channels are named, for the `--help` of every command that reads a log (written once):
/// CSV, MCAP and bags, then a line per columnar format from calib-io's list of them.
pub fn channel_names() -> String {
    let mut text =
        "Channels are named by their CSV column (`1`, `2`, … in a file without a header \
row); in MCAP and ROS bags by the joint name (JointState, DynamicJointState) or field (JSON) where \
no other topic carries that name, by the topic for std_msgs scalars, as TOPIC.field.path for a \
numeric field of another message whose MCAP file carries its definition (/motor/state.position), \
and always accepted as TOPIC/NAME (/sensor_a/joint_states/encoder; `calib inspect LOG` lists \
them). A qualified channel's table is named without the leading `/` and with `/` as `_`. Files of \
whole columns are read whole, their time from --time-column, a time-stamp column, a column named \
t/time/timestamp, or a waveform:"
            .to_string();
    for line in calib_io::log::column_formats_help() {
        text.push_str("\n  ");
        text.push_str(&line);
    }
    text
}

/// Which stamps a message is read at.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum TimeArg {
    /// The stamp the publisher wrote (`header.stamp`); the log time where it is zero.
    Header,
    /// The time the recorder logged the message.
    Log,
}

/// How a log is timed: the CSV time column, the MCAP stamps, and how channels on different
/// clocks are aligned (the command's first channel sets the clock, every other channel is
/// interpolated, quintic, at its stamps from its own samples).
#[derive(Debug, Clone, PartialEq, clap::Args)]
#[command(next_help_heading = "Reading the log")]
pub struct LogArgs {
    /// Time of an MCAP message: its `header.stamp` or its log time.
    #[arg(long, value_enum, default_value_t = TimeArg::Header)]
    pub time: TimeArg,
    /// Longest interval between two samples of a channel that is interpolated across, seconds
    /// (default: 2.5 of that channel's median intervals). A clock sample inside a longer gap is
    /// dropped and counted, never invented.
    #[arg(long, value_name = "SECONDS")]
    pub max_gap: Option<f64>,
    /// The time column of a CSV log (default: `t`, `time` or `timestamp`, any case, with a unit
    /// suffix such as ` [s]`, `_ms` or ` (us)` honoured).
    #[arg(long, value_name = "NAME")]
    pub time_column: Option<String>,
    /// Unit of a CSV log's time column: s, ms, us, ns or 100ns (FILETIME ticks) (default: its
    /// name's suffix, else the units row's entry, else s). A run that "never moves" whose
    /// column steps by more than 0.5 s, or less than 2 µs, in that unit names the unit that fits;
    /// so does one whose readings turn faster than 30,000 r/min in it, or (where a method finds
    /// the run too slow) one whose readings move but under --min-speed.
    #[arg(long, value_name = "UNIT", value_parser = parse_time_unit)]
    pub time_unit: Option<TimeUnit>,
    /// Leave out MCAP chunks whose checksum (CRC) does not match, warning and listing each in
    /// the report. Without it a damaged chunk is an error (exit 1): its readings may be wrong.
    #[arg(long)]
    pub skip_damaged: bool,
    /// Largest log named by a URL that is copied to a temporary local file to be read, MB
    /// (10⁶ bytes; default 2000): rosbag2, ROS 1 bags and the columnar formats are read from a
    /// file (MCAP is read in place, CSV streamed).
    #[arg(long, value_name = "MB")]
    pub max_copy: Option<f64>,
}

/// clap value parser for `--time-unit`.
fn parse_time_unit(s: &str) -> Result<TimeUnit, String> {
    s.parse()
}

impl LogArgs {
    /// The options of reading (with readings in `unit`) and aligning.
    pub fn options(&self, unit: Option<AngleUnit>) -> anyhow::Result<(ReadOptions, AlignOptions)> {
        if self.max_gap.is_some_and(|g| !(g > 0.0 && g.is_finite())) {
            return Err(Usage("--max-gap must be a positive number of seconds".into()).into());
        }
        if self.max_copy.is_some_and(|m| !(m >= 0.0 && m.is_finite())) {
            return Err(Usage("--max-copy must be a number of megabytes, 0 or more".into()).into());
        }
        let time = match self.time {
            TimeArg::Header => TimeSource::Header,
            TimeArg::Log => TimeSource::Log,
        };
        let read = ReadOptions {
            unit,
            time,
            time_column: self.time_column.clone(),
            time_unit: self.time_unit,
            skip_damaged: self.skip_damaged,
            one_thread: crate::threads::read_inline(),
            max_copy_bytes: self.max_copy.map(|mb| (mb * 1e6) as u64),
            ..ReadOptions::default()
        };
        Ok((
            read,
            AlignOptions {
                max_gap_s: self.max_gap,
            },
        ))
    }
}

/// Opens the log at `path` reading the channels `names` only, in this order, the first setting
/// the clock: sample value `k` is channel `names[k]`.
pub fn open_selected(
    path: &Path,
    unit: Option<AngleUnit>,
    log: &LogArgs,
    names: &[&str],
) -> anyhow::Result<LogReader> {
    let (mut read, align) = log.options(unit)?;
    read.fields = names.iter().map(|n| n.to_string()).collect();
    let mut reader = open_log_with(path, read)?;
    let indices = names
        .iter()
        .map(|n| channel(&reader, path, n))
        .collect::<anyhow::Result<Vec<_>>>()?;
    reader.select(&indices, align);
    Ok(reader)
}

/// The alignment of a log read, for report.json's `details.alignment`; `None` where every
/// channel was read at the clock's own stamps with nothing dropped.
pub fn alignment_detail(reader: &LogReader) -> Option<Alignment> {
    reader.alignment().filter(|a| !a.is_exact())
}

/// Summary lines on how the channels were aligned on the clock; empty where nothing was
/// interpolated or dropped.
pub fn alignment_text(alignment: Option<&Alignment>) -> String {
    let mut o = String::new();
    let Some(a) = alignment.filter(|a| !a.is_exact()) else {
        return o;
    };
    let _ = writeln!(
        o,
        "aligned on the clock of `{}`: {} of its {} samples kept",
        a.clock, a.samples, a.clock_samples
    );
    for c in &a.channels {
        let offset = c
            .median_offset_s
            .map_or_else(|| "—".to_string(), |o| format!("{:+.3} ms", o * 1e3));
        let _ = writeln!(
            o,
            "  {}: median offset {offset}, {} interpolated, {} exact, {} dropped",
            c.channel, c.interpolated, c.exact, c.dropped
        );
    }
    o
}

/// clap value parser for `--unit`.
pub fn parse_unit(s: &str) -> Result<AngleUnit, String> {
    s.parse::<AngleUnit>().map_err(|e| e.to_string())
}

/// Checks a `--points` value against [`MAX_TABLE_POINTS`], before any work.
pub fn check_points(points: Option<usize>) -> Result<(), Usage> {
    match points {
        Some(p) => check_count("--points", p, 2, Some(MAX_TABLE_POINTS)).map_err(|Usage(m)| {
            Usage(format!(
                "{m} (0.36″ steps, finer than any map calib estimates; see Limits in `calib \
                 --help`)"
            ))
        }),
        None => Ok(()),
    }
}

/// Checks that `value` of `option` lies in (`low`, `high`], naming the option and its range.
pub fn check_range(option: &str, value: f64, low: f64, high: f64, unit: &str) -> Result<(), Usage> {
    if value > low && value <= high {
        return Ok(());
    }
    let r = calib_io::limits::readable;
    Err(Usage(format!(
        "{option} {} is outside its range: above {} and at most {} {unit}",
        r(value),
        r(low),
        r(high)
    )))
}

/// Checks that the count or order `value` of `option` is at least `low` and, where it has a bound,
/// at most `high`, naming the option (the ranges' one phrasing, as [`check_range`]'s).
pub fn check_count(
    option: &str,
    value: usize,
    low: usize,
    high: Option<usize>,
) -> Result<(), Usage> {
    if value >= low && high.is_none_or(|h| value <= h) {
        return Ok(());
    }
    Err(Usage(format!(
        "{option} {value} is outside its range: at least {low}{}",
        high.map_or(String::new(), |h| format!(" and at most {h}"))
    )))
}

/// Checks that `value` of `option` is a fraction: at least 0 and below 1, naming the option.
pub fn check_fraction(option: &str, value: f64) -> Result<(), Usage> {
    if (0.0..1.0).contains(&value) {
        return Ok(());
    }
    Err(Usage(format!(
        "{option} {} is outside its range: at least 0 and below 1",
        calib_io::limits::readable(value)
    )))
}

/// Checks that `value` of `option` is a finite number of at least 0, naming the option.
pub fn check_non_negative(option: &str, value: f64, unit: &str) -> Result<(), Usage> {
    if value.is_finite() && value >= 0.0 {
        return Ok(());
    }
    Err(Usage(format!(
        "{option} {} is outside its range: a finite number of at least 0 {unit}",
        calib_io::limits::readable(value)
    )))
}

/// Checks that `path` can be a log before it is opened ([`calib_io::log::NotALog::check`]:
/// missing, or a folder that is no rosbag2 bag directory), each a usage error (exit 2)
/// naming the path; what the file holds is for the reader to judge.
pub fn check_log_path(path: &Path) -> Result<(), Usage> {
    let shown = crate::ui::shown(path);
    match calib_io::log::NotALog::check(path) {
        Some(not) => Err(Usage(format!("{shown}: {not}"))),
        None => Ok(()),
    }
}

/// Opens a log for reading, a damaged MCAP chunk an error unless `skip_damaged`.
pub fn open_log(
    path: &Path,
    unit: Option<AngleUnit>,
    skip_damaged: bool,
) -> anyhow::Result<LogReader> {
    open_log_with(
        path,
        ReadOptions {
            unit,
            skip_damaged,
            ..ReadOptions::default()
        },
    )
}

/// Opens a log for reading with these options.
pub fn open_log_with(path: &Path, opts: ReadOptions) -> anyhow::Result<LogReader> {
    check_log_path(path)?;
    LogReader::open(path, &opts).with_context(|| format!("cannot read {}", crate::ui::shown(path)))
}

/// The index of channel `name` of the log at `path` among all its channels (an unknown or
/// ambiguous name is a usage error).
pub fn channel(reader: &LogReader, path: &Path, name: &str) -> anyhow::Result<usize> {
    reader
        .resolve(name)
        .with_context(|| format!("{}", path.display()))
}

pub use calib_core::report::file_stem;

/// The command line that is running, arguments quoted where the shell would need it, for
/// reports: what produced a table should be reproducible from the report alone. The program is
/// written `calib` whatever path started it, so equal runs give equal reports on any machine.
pub fn command_line() -> String {
    std::iter::once("calib".to_string())
        .chain(std::env::args().skip(1))
        .map(|a| {
            if !a.is_empty()
                && a.chars()
                    .all(|c| c.is_ascii_alphanumeric() || "-_./:=@,+".contains(c))
            {
                a
            } else {
                format!("'{}'", a.replace('\'', "'\\''"))
            }
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// A method's error `cause` under what it says first (`turn`): that `who` (a channel, named as
/// the surrounding message does not already name it; empty if it does) never turned the whole
/// revolution the method needs.
pub fn no_whole_turn<E>(cause: E, who: &str, turn: &calib_core::PartialTurn) -> anyhow::Error
where
    E: std::error::Error + Send + Sync + 'static,
{
    let said = if who.is_empty() {
        turn.to_string()
    } else {
        format!("{who} {turn}")
    };
    anyhow::Error::new(cause).context(said)
}

/// `--latency`: `auto` or a lag in seconds (`0.02`, `-0.005`), within ±10 s.
pub fn parse_latency(text: &str) -> Result<calib_core::reference_cal::Latency, String> {
    use calib_core::reference_cal::Latency;
    let text = text.trim();
    if text.eq_ignore_ascii_case("auto") {
        return Ok(Latency::Auto);
    }
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() && v.abs() <= 10.0 => Ok(Latency::Fixed(v)),
        _ => Err(format!(
            "`{text}`: give `auto` or the lag in seconds, within ±10 (e.g. 0.02 for 20 ms; 0 for none)"
        )),
    }
}
