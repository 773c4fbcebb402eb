//! Rewriting a log with one channel corrected: the I/O of `calib apply`.
//!
//! [`apply`] copies a log to a new file of the same format, replacing every reading of one
//! channel `r` with `r − e(r)` ([`calib_core::correction`]) and leaving everything else as it was:
//!
//! - **CSV**: the same header, columns and rows; only the channel's field of each row is
//!   rewritten (in the log's unit, shortest round-trip decimal form). Every other byte of the file
//!   — time stamps, sessions, other channels, quoting, line ends, blank lines — is copied as read.
//! - **MCAP**: every record is copied — header (profile,
//!   library), schemas and channels with their IDs, every message with its log time, publish
//!   time and sequence number, metadata, attachments and private records — and only the messages
//!   carrying the channel are changed: in a ROS 2 JointState message the 8 bytes of that joint's
//!   `position`, in a JSON message the text of that field's number. Chunks are re-formed (with the
//!   input's compression, where its summary names it) and the summary and indexes rewritten.
//!
//! With [`ApplyOptions::keep`] the channel is copied as it was and the corrected readings are
//! added beside it: a CSV column [`corrected_name`] right after the channel's (its header and
//! every row; the rest of each line as read), or, in an MCAP log, a copy of each message carrying
//! the channel, corrected as above, on a new channel of the same schema and encoding whose topic
//! is [`corrected_topic`] (the message right after the original, with its times and sequence).
//!
//! Both stream: memory stays bounded by a row or a few MCAP chunks, whatever the log's length.
//! An MCAP log of several chunks is read with its chunks decompressed on worker threads and
//! written on a thread of its own, its new chunks compressed on worker threads (see the `mcap`
//! module); [`ApplyOptions::one_thread`] does it all on the calling thread, with the same
//! output.
//!
//! # Wrapping
//! Unless told ([`ApplyOptions::wrapping`]), the channel's wrapping is detected by a first pass
//! over the log that finds the range of its readings ([`Wrapping::detect`]): a second read, but
//! the only way to know before the first corrected reading is written whether a reading of
//! 359.9999° may become 0.0001° or must become 360.0001°.
//!
//! # Atomicity
//! The output is written to a temporary file beside it and renamed into place only when
//! complete: an error leaves no partial output behind, and an existing file at the output path
//! stays as it was.

mod csv;
mod mcap;

use crate::log::LogFormat;
use crate::mcap_log::read::PARALLEL_CHUNKS;
use crate::{DamagedChunk, Error, Truncation};
use calib_core::correction::{Correction, Wrapping};
use calib_core::{AngleUnit, TableMap};
use std::path::Path;

/// What to correct and how.
#[derive(Debug, Clone, PartialEq)]
pub struct ApplyOptions {
    /// The channel: a CSV column, or a JointState joint or JSON field by its name (on whichever
    /// topic carries it) or as `TOPIC/NAME` (on that topic only).
    pub channel: String,
    /// The unit of CSV readings and JSON fields (degrees if `None`); JointState positions are
    /// radians by definition.
    pub unit: Option<AngleUnit>,
    /// How the channel's readings are wrapped; detected from their range if `None`.
    pub wrapping: Option<Wrapping>,
    /// MCAP: leave out chunks that do not match their CRC (listed in
    /// [`Applied::damaged_chunks`]) instead of failing on the first.
    pub skip_damaged: bool,
    /// Keep the channel as it was and add the corrected readings beside it (see
    /// [`Applied::beside`]), instead of replacing them: a CSV gets the column
    /// [`corrected_name`]`(channel)` right after the channel's, an MCAP log a copy of every
    /// message carrying the channel, corrected, on the topic [`corrected_topic`]`(topic)`.
    pub keep: bool,
    /// MCAP: read, correct and write on the calling thread only (no threads decompressing the
    /// log's chunks or compressing the output's, none writing). The output is the same either
    /// way.
    pub one_thread: bool,
}

/// The CSV column `--keep` adds beside channel `channel`: `a` → `a_corrected`.
pub fn corrected_name(channel: &str) -> String {
    format!("{channel}_corrected")
}

/// The MCAP topic `--keep` copies the corrected messages of `topic` to: `/joint_states` →
/// `/joint_states/corrected` (the joint keeps its name, so viewers plot the two side by side;
/// calib names it `/joint_states/corrected/a`).
pub fn corrected_topic(topic: &str) -> String {
    format!("{}/corrected", topic.trim_end_matches('/'))
}

/// What [`apply`] did.
#[derive(Debug, Clone, PartialEq)]
pub struct Applied {
    /// The log's format (the output has the same).
    pub format: LogFormat,
    /// Readings corrected.
    pub readings: u64,
    /// The unit of the readings corrected.
    pub unit: AngleUnit,
    /// The wrapping kept.
    pub wrapping: Wrapping,
    /// The smallest and largest reading before correction, in `unit`.
    pub range: (f64, f64),
    /// MCAP messages copied unchanged (other topics', and those without the channel); 0 for
    /// CSV, where every row holds the channel.
    pub copied: u64,
    /// Where an MCAP log ended early (a crashed recording): the output holds everything before
    /// the break, as a complete file.
    pub truncated: Option<Truncation>,
    /// MCAP chunks left out of the output because they were damaged (with
    /// [`ApplyOptions::skip_damaged`]).
    pub damaged_chunks: Vec<DamagedChunk>,
    /// Readings outside a range table's range, copied unchanged (0 for a whole-turn table).
    pub outside: u64,
    /// With [`ApplyOptions::keep`]: the CSV column, or the MCAP topics, that hold the corrected
    /// readings beside the unchanged channel; empty otherwise.
    pub beside: Vec<String>,
}

/// The readings of the channel a first pass over a log finds ([`scan`]): what decides their
/// wrapping, and what a caller checks their unit against before anything is written.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Readings {
    /// How many.
    pub count: u64,
    /// The smallest, in `unit`.
    pub min: f64,
    /// The largest, in `unit`.
    pub max: f64,
    /// Their unit: radians for JointState positions, else [`ApplyOptions::unit`] (degrees if
    /// `None`).
    pub unit: AngleUnit,
    /// Every one is a whole number in `unit` (encoder counts read as degrees look so).
    pub whole: bool,
}

impl Readings {
    fn new(unit: AngleUnit) -> Self {
        Readings {
            count: 0,
            min: f64::INFINITY,
            max: f64::NEG_INFINITY,
            unit,
            whole: true,
        }
    }
    fn add(&mut self, x: f64, unit: AngleUnit) {
        self.count += 1;
        self.min = self.min.min(x);
        self.max = self.max.max(x);
        self.whole &= x.fract() == 0.0;
        self.unit = unit;
    }
}

/// Writes `output`: the log at `input` with channel `opts.channel` corrected by `map` (see the
/// [module docs](self)): a whole-turn map corrects every reading; a range map the readings inside
/// its range, the others copied unchanged and counted in [`Applied::outside`].
///
/// `output` must have the input's format ([`output_extensions`]) and must not be `input` itself,
/// which the caller checks (the rename would replace the log being read). Errors name the file,
/// the line or message, and the channel: a channel the log does not have (listing those it has),
/// a reading that is not a finite number, a JointState message with fewer positions than names,
/// a damaged file.
pub fn apply(
    input: &Path,
    output: &Path,
    map: &TableMap,
    opts: &ApplyOptions,
) -> Result<Applied, Error> {
    formats(input, output)?;
    let range = scan(input, opts)?;
    apply_scanned(input, output, map, opts, &range)
}

/// The error of `apply` on a log calib reads but does not write (a bag, a columnar file).
fn not_rewritten(input: &Path, format: LogFormat) -> Error {
    Error::Data {
        path: input.to_path_buf(),
        message: format.not_rewritten().unwrap_or_default(),
    }
}

/// The format of `input`, which `output` must have too; a bag is refused.
fn formats(input: &Path, output: &Path) -> Result<LogFormat, Error> {
    let format = LogFormat::detect(input)?;
    if !format.rewritable() {
        return Err(not_rewritten(input, format));
    }
    if !fits_output(format, output) {
        return Err(Error::Write {
            path: output.to_path_buf(),
            message: format!(
                "the input {} is {}; write the corrected log in the same format (a {} file)",
                input.display(),
                format.name(),
                output_extensions(format)
                    .iter()
                    .map(|e| format!(".{e}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        });
    }
    Ok(format)
}

/// The extensions a corrected log of `format` may be written under: a CSV log under any of the
/// extensions calib reads CSV from (`.tsv`, `.txt` and `.dat` are the same text, in the input's
/// dialect), an MCAP log as `.mcap`.
pub fn output_extensions(format: LogFormat) -> &'static [&'static str] {
    match format {
        LogFormat::Csv => &["csv", "tsv", "txt", "dat"],
        LogFormat::Mcap => &["mcap"],
        LogFormat::Rosbag | LogFormat::Ros1Bag | LogFormat::Columns(_) => &[],
    }
}

/// Whether `output`'s extension is one of [`output_extensions`]`(format)` (case aside).
pub fn fits_output(format: LogFormat, output: &Path) -> bool {
    output
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| output_extensions(format).contains(&e.to_ascii_lowercase().as_str()))
}

/// The chunks an MCAP log needs for them to be read in parallel and the output written on
/// threads of its own: none with [`ApplyOptions::one_thread`].
fn parallel_chunks(opts: &ApplyOptions) -> usize {
    if opts.one_thread {
        usize::MAX
    } else {
        PARALLEL_CHUNKS
    }
}

/// The first pass of [`apply`] over `input`: the readings of `opts.channel`. An error if the
/// log is a bag, or holds no readings of the channel.
pub fn scan(input: &Path, opts: &ApplyOptions) -> Result<Readings, Error> {
    let format = LogFormat::detect(input)?;
    let unit = opts.unit.unwrap_or(AngleUnit::Deg);
    let range = match format {
        LogFormat::Csv => csv::scan(input, &opts.channel, unit)?,
        LogFormat::Mcap => mcap::scan(
            input,
            &opts.channel,
            unit,
            opts.skip_damaged,
            parallel_chunks(opts),
        )?,
        other => return Err(not_rewritten(input, other)),
    };
    if range.count == 0 {
        // `TOPIC.field.path` channels are read through their message definition, which `apply`
        // does not rewrite: say so rather than that the channel has no readings.
        let field_path = format == LogFormat::Mcap
            && opts
                .channel
                .split_once('.')
                .is_some_and(|(topic, path)| topic.starts_with('/') && !path.is_empty());
        let message = if field_path {
            format!(
                "`{}` names a field by path (TOPIC.field.path); calib reads such fields but \
                 apply rewrites only JointState joints and JSON fields: correct the readings \
                 where they are published, or apply the table to a CSV export of the channel",
                opts.channel
            )
        } else {
            format!(
                "the log holds no readings of channel `{}`; nothing to correct",
                opts.channel
            )
        };
        return Err(Error::Data {
            path: input.to_path_buf(),
            message,
        });
    }
    Ok(range)
}

/// The second pass of [`apply`]: writes `output` from `input` with the readings `range`
/// found by [`scan`] (checked by the caller in between).
pub fn apply_scanned(
    input: &Path,
    output: &Path,
    map: &TableMap,
    opts: &ApplyOptions,
    range: &Readings,
) -> Result<Applied, Error> {
    let format = formats(input, output)?;
    let unit = opts.unit.unwrap_or(AngleUnit::Deg);
    let wrapping = opts
        .wrapping
        .unwrap_or_else(|| Wrapping::detect(range.min, range.max, range.unit));
    let fix = |unit| Correction::new(map.clone(), unit, wrapping);
    let mut beside = Vec::new();
    let (readings, copied, truncated, outside, damaged_chunks) = match format {
        LogFormat::Csv => {
            let f = fix(unit);
            let keep = opts.keep.then(|| corrected_name(&opts.channel));
            let n = csv::rewrite(input, output, &opts.channel, &f, keep.as_deref())?;
            beside.extend(keep);
            (n, 0, None, f.outside(), Vec::new())
        }
        other @ (LogFormat::Rosbag | LogFormat::Ros1Bag | LogFormat::Columns(_)) => {
            return Err(not_rewritten(input, other));
        }
        LogFormat::Mcap => {
            let (joint, json) = (fix(AngleUnit::Rad), fix(unit));
            let done = mcap::rewrite(
                input,
                output,
                &opts.channel,
                (&joint, &json),
                opts.skip_damaged,
                opts.keep,
                parallel_chunks(opts),
            )?;
            beside.extend(done.beside);
            (
                done.readings,
                done.copied,
                done.truncated,
                joint.outside() + json.outside(),
                done.damaged,
            )
        }
    };
    Ok(Applied {
        format,
        readings,
        unit: range.unit,
        wrapping,
        range: (range.min, range.max),
        copied,
        truncated,
        damaged_chunks,
        outside,
        beside,
    })
}
