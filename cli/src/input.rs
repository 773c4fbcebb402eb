//! Opening logs and finding channels, with errors that say what to do.

use crate::exit::Usage;
use anyhow::Context;
use calib_core::AngleUnit;
use calib_core::sample::channel_index;
use calib_io::{LogReader, ReadOptions};
use std::path::Path;

/// clap value parser for `--unit`.
pub fn parse_unit(s: &str) -> Result<AngleUnit, String> {
    s.parse::<AngleUnit>().map_err(|e| e.to_string())
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
pub fn open_log_with(path: &Path, opts: ReadOptions) -> anyhow::Result<LogReader> {
    if !path.exists() {
        return Err(Usage(format!("{}: no such file; check the path", path.display())).into());
    }
    LogReader::open(path, &opts).with_context(|| format!("cannot read {}", path.display()))
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

/// The travel of a channel's continuous (unwrapped) reading, to say when a method that needs
/// whole turns was given a joint that never turned one.
#[derive(Debug, Clone)]
pub struct Travel {
    unwrapper: calib_core::Unwrapper,
    lo: f64,
    hi: f64,
}

impl Default for Travel {
    fn default() -> Self {
        Travel {
            unwrapper: calib_core::Unwrapper::new(),
            lo: f64::INFINITY,
            hi: f64::NEG_INFINITY,
        }
    }
}

impl Travel {
    /// Adds a reading (radians); non-finite ones are skipped.
    pub fn push(&mut self, reading: f64) {
        if reading.is_finite() {
            let u = self.unwrapper.unwrap(reading);
            self.lo = self.lo.min(u);
            self.hi = self.hi.max(u);
        }
    }

    /// Largest minus smallest continuous reading, degrees (0 without readings).
    pub fn span_deg(&self) -> f64 {
        if self.hi >= self.lo {
            (self.hi - self.lo).to_degrees()
        } else {
            0.0
        }
    }

    /// If the channel moved (more than 1°) but never turned a whole revolution, what to say
    /// before the method's own error: that `method` needs whole turns, and what to do for a joint
    /// instead. `None` if it turned one, or stood still (the method's own error says that).
    pub fn no_whole_turn(&self, log: &Path, channel: &str, method: &str) -> Option<String> {
        let span = self.span_deg();
        (span > 1.0 && span < 360.0).then(|| {
            format!(
                "{}: channel `{channel}` never turned a whole revolution (its readings span {span:.3}°): {method}; \
                 to map a joint that never turns a whole revolution, calibrate it against a reference encoder on its \
                 shaft with `calib reference`, which writes a range table",
                log.display()
            )
        })
    }
}
