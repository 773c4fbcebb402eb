//! Opening logs and finding channels, with errors that say what to do.

use crate::exit::Usage;
use anyhow::Context;
use calib_core::AngleUnit;
use calib_core::sample::channel_index;
use calib_io::limits::MAX_TABLE_POINTS;
use calib_io::{LogReader, ReadOptions};
use std::path::Path;

/// clap value parser for `--unit`.
pub fn parse_unit(s: &str) -> Result<AngleUnit, String> {
    s.parse::<AngleUnit>().map_err(|e| e.to_string())
}

/// Checks a `--points` value against [`MAX_TABLE_POINTS`], before any work.
pub fn check_points(points: Option<usize>) -> Result<(), Usage> {
    match points {
        Some(p) if !(2..=MAX_TABLE_POINTS).contains(&p) => Err(Usage(format!(
            "--points {p} is outside its range, 2 to {MAX_TABLE_POINTS} (0.36″ steps, finer than \
             any map calib estimates; see Limits in `calib --help`)"
        ))),
        _ => Ok(()),
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

/// Checks that `path` can be a log before it is opened: it exists (exit 2 if not, naming it)
/// and is not a folder (exit 2). The one place that decides what a log path may be, so that
/// folder formats (a rosbag2 bag directory) are accepted here.
pub fn check_log_path(path: &Path) -> Result<(), Usage> {
    let shown = crate::ui::shown(path);
    match std::fs::metadata(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            Err(Usage(format!("{shown}: no such file; check the path")))
        }
        Ok(meta) if meta.is_dir() => Err(Usage(format!(
            "{shown}: this is a folder, not a log; name the .csv or .mcap file inside it"
        ))),
        _ => Ok(()),
    }
}

/// Opens a log for reading.
pub fn open_log(path: &Path, unit: Option<AngleUnit>) -> anyhow::Result<LogReader> {
    open_log_with(
        path,
        ReadOptions {
            unit,
            ..ReadOptions::default()
        },
    )
}

/// Opens a log for reading with these options.
pub fn open_log_with(path: &Path, mut opts: ReadOptions) -> anyhow::Result<LogReader> {
    opts.skip_damaged |= crate::ui::skip_damaged();
    check_log_path(path)?;
    LogReader::open(path, &opts).with_context(|| format!("cannot read {}", crate::ui::shown(path)))
}

/// The index of channel `name` of the log at `path`.
pub fn channel(reader: &LogReader, path: &Path, name: &str) -> anyhow::Result<usize> {
    channel_index(reader.channels(), name).with_context(|| format!("{}", path.display()))
}

/// A channel name as a file name: characters other than letters, digits, `-`, `_` and `.`
/// become `_` (JointState names such as `arm/joint1` stay usable).
pub fn file_stem(channel: &str) -> String {
    let s: String = channel
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.') {
                c
            } else {
                '_'
            }
        })
        .collect();
    if s.is_empty() || s.starts_with('.') {
        format!("_{s}")
    } else {
        s
    }
}

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
