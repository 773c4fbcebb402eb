//! [`ColumnReader`]: a [`ColumnSet`] turned into samples, the same way for every columnar format.
//!
//! The time of each sample comes from, in this order: the column `--time-column` names; a column
//! the file marks as stamps (a Parquet `TIMESTAMP`, a TDMS time-stamp channel); a column named as
//! a CSV time column is (`t`, `time`, `timestamp`, with a unit suffix); the channels' waveform
//! (TDMS `wf_increment`); else, where the caller reads point lists, the sample's index. Every
//! other numeric column of the time's length is a channel, in the unit its file states, else
//! `--unit`, else degrees; columns of another length are left out and listed. Stamps follow
//! the rule every reader does ([`crate::stamps`]): exact copies of a sample are dropped and
//! counted, a repeat with other readings or a step back is refused.

use std::path::Path;

use calib_core::{AngleUnit, Channel, SampleBatch};

use super::{Column, ColumnFormat, ColumnSet, ColumnTime, Values};
use crate::csv_log::dialect::{self, TimeUnit};
use crate::stamps::{ORIGIN_FROM_S, StampOrder, Step};
use crate::{Error, ReadDiagnostics, ReadOptions};

const NS_PER_S: i64 = 1_000_000_000;

/// Samples from a columnar file read whole into memory.
pub(crate) struct ColumnReader {
    format: &'static str,
    structure: Vec<String>,
    /// Every channel, in the file's order.
    all: Vec<Channel>,
    /// Each channel's readings, radians.
    readings: Vec<Vec<f64>>,
    /// Each sample's time, seconds from [`time_origin_s`](Self::time_origin_s).
    times: Vec<f64>,
    origin_s: f64,
    /// Where the time comes from, for `calib inspect`.
    time_from: String,
    /// Whether the samples are timed by their index (a point list).
    point_list: bool,
    /// The selected channels (indices into `all`), in the order of a sample's values.
    selection: Vec<usize>,
    selected: Vec<Channel>,
    next: usize,
    diagnostics: ReadDiagnostics,
    progress: crate::progress::ReadProgress,
    scratch: Vec<f64>,
}

impl ColumnReader {
    /// Reads the file at `path` with `format` and lays out its channels, every one selected.
    pub(crate) fn open(
        path: &Path,
        format: &'static dyn ColumnFormat,
        opts: &ReadOptions,
    ) -> Result<Self, Error> {
        let set = format.read(path, opts)?;
        Self::from_set(path, format.name(), set, opts)
    }

    /// Lays out the channels of `set`, read from `path` in the format named `format`.
    pub(crate) fn from_set(
        path: &Path,
        format: &'static str,
        set: ColumnSet,
        opts: &ReadOptions,
    ) -> Result<Self, Error> {
        let ColumnSet {
            columns,
            mut structure,
        } = set;
        let err = |message: String| Error::Data {
            path: path.to_path_buf(),
            message,
        };
        if columns.is_empty() {
            return Err(err(format!(
                "this {format} file holds no numeric channel{}",
                listing(&structure)
            )));
        }
        let axis = TimeAxis::find(&columns, opts).map_err(err)?;
        let len = axis.len(&columns);
        let mut diagnostics = ReadDiagnostics::default();
        let timing = axis.times(path, &columns, len, &mut diagnostics)?;
        let mut all = Vec::new();
        let mut readings = Vec::new();
        for (k, column) in columns.iter().enumerate() {
            if axis.column() == Some(k) {
                continue;
            }
            if column.values.len() != len {
                structure.push(format!(
                    "`{}`: left out, {} samples where the time has {len}",
                    column.name,
                    column.values.len()
                ));
                continue;
            }
            let unit = column
                .unit
                .as_deref()
                .and_then(dialect::angle_unit)
                .or(opts.unit)
                .unwrap_or(AngleUnit::Deg);
            // A channel with a reading no method could use (NaN, a fill value, a counter beyond
            // the range an angle is held to) is left out and listed, not the whole file refused:
            // files carry such columns beside the encoders.
            match to_radians(column, unit) {
                Ok(rad) => readings.push(rad),
                Err(problem) => {
                    structure.push(format!("`{}`: left out, {problem}", column.name));
                    continue;
                }
            }
            all.push(Channel {
                name: column.name.clone(),
                unit,
            });
        }
        if all.is_empty() {
            return Err(err(format!(
                "this {format} file holds no channel besides its time, {}{}",
                timing.what,
                listing(&structure)
            )));
        }
        let times = in_order(
            path,
            timing.stamps_ns,
            timing.origin_ns,
            &mut readings,
            &timing.what,
            opts,
            &mut diagnostics,
            &all,
        )?;
        let selection: Vec<usize> = (0..all.len()).collect();
        let size = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
        let progress = crate::progress::ReadProgress::new(size);
        Ok(ColumnReader {
            format,
            structure,
            selected: all.clone(),
            all,
            readings,
            times,
            origin_s: seconds(timing.origin_ns),
            time_from: timing.what,
            point_list: timing.point_list,
            selection,
            next: 0,
            diagnostics,
            progress,
            scratch: Vec::new(),
        })
    }

    /// The name of the file's format.
    pub(crate) fn format(&self) -> &'static str {
        self.format
    }

    /// What the file holds, a line each (groups, variables, datasets or columns), and where the
    /// time was taken from.
    pub(crate) fn structure(&self) -> Vec<String> {
        let mut lines = self.structure.clone();
        lines.push(format!("time: {}", self.time_from));
        lines
    }

    /// Every channel, in the file's order.
    pub(crate) fn all_channels(&self) -> &[Channel] {
        &self.all
    }

    /// The selected channels.
    pub(crate) fn channels(&self) -> &[Channel] {
        &self.selected
    }

    /// Reads only `channels` (indices into [`all_channels`](Self::all_channels)), in this order.
    /// Every channel has a reading at every stamp: nothing to align.
    pub(crate) fn select(&mut self, channels: &[usize]) {
        self.selection = channels.to_vec();
        self.selected = channels.iter().map(|&i| self.all[i].clone()).collect();
    }

    /// Whether the samples are timed by their index (no time in the file, read as a point list).
    pub(crate) fn is_point_list(&self) -> bool {
        self.point_list
    }

    /// The stamp, seconds, from which the samples' times are counted.
    pub(crate) fn time_origin_s(&self) -> f64 {
        self.origin_s
    }

    /// What was noticed (nothing: the file was read whole when it was opened).
    pub(crate) fn diagnostics(&self) -> &ReadDiagnostics {
        &self.diagnostics
    }

    /// How far the samples have been handed on, of the file's size.
    pub(crate) fn progress(&self) -> crate::progress::ReadProgress {
        self.progress.clone()
    }

    /// Appends samples to `out` until it holds `max` or the samples end.
    pub(crate) fn fill(&mut self, out: &mut SampleBatch, max: usize) {
        let total = self.times.len();
        self.scratch.resize(self.selection.len(), 0.0);
        while out.len() < max && self.next < total {
            let i = self.next;
            for (slot, &c) in self.scratch.iter_mut().zip(&self.selection) {
                *slot = self.readings[c][i];
            }
            out.push(self.times[i], &self.scratch, None);
            self.next += 1;
        }
        if total > 0 {
            let size = self.progress.total();
            self.progress
                .set((size as u128 * self.next as u128 / total as u128) as u64);
        }
    }
}

/// A column's readings in radians, each checked as a CSV reading is; what is wrong with the
/// first that is not a reading otherwise.
fn to_radians(column: &Column, unit: AngleUnit) -> Result<Vec<f64>, String> {
    let per_unit = unit.radians_per_unit();
    let values: Vec<f64> = match &column.values {
        Values::F64(v) => v.clone(),
        Values::I64(v) => v.iter().map(|&x| x as f64).collect(),
    };
    let mut rad = Vec::with_capacity(values.len());
    for (i, &v) in values.iter().enumerate() {
        let r = v * per_unit;
        if let Some(problem) = crate::limits::reading_problem(v, v, r) {
            return Err(format!("sample {i}: {problem}"));
        }
        rad.push(r);
    }
    Ok(rad)
}

/// Where a columnar file's time comes from.
enum TimeAxis {
    /// The column at this index, in this unit (`None`: stated nowhere, seconds unless its
    /// magnitude says a date in another unit), found as `why` says.
    Column {
        index: usize,
        unit: Option<TimeUnit>,
        why: &'static str,
    },
    /// Every channel's waveform: sample `i` at `start_ns + i·increment_s`.
    Waveform { start_ns: i64, increment_s: f64 },
    /// No time: samples timed by their index, 1 s apart.
    Index,
}

impl TimeAxis {
    /// The time axis of `columns`, or what to do when there is none.
    fn find(columns: &[Column], opts: &ReadOptions) -> Result<TimeAxis, String> {
        let names: Vec<String> = columns.iter().map(|c| c.name.clone()).collect();
        if let Some(wanted) = &opts.time_column {
            let Some(index) = names.iter().position(|n| n == wanted) else {
                return Err(format!(
                    "no channel is named `{wanted}` (the `time_column` option); the channels are {}",
                    quoted(&names)
                ));
            };
            let unit =
                opts.time_unit
                    .or(dialect::time_unit_of(wanted))
                    .or(match columns[index].time {
                        ColumnTime::Stamps(u) => Some(u),
                        _ => None,
                    });
            return Ok(TimeAxis::Column {
                index,
                unit,
                why: "named by the `time_column` option",
            });
        }
        if let Some(index) = columns
            .iter()
            .position(|c| matches!(c.time, ColumnTime::Stamps(_)))
        {
            let ColumnTime::Stamps(unit) = columns[index].time else {
                unreachable!("the position's column holds stamps")
            };
            return Ok(TimeAxis::Column {
                index,
                unit: Some(opts.time_unit.unwrap_or(unit)),
                why: "stamps since 1970, as the file types them",
            });
        }
        if let Some((index, _)) = dialect::time_column(&names, None, opts.time_unit) {
            return Ok(TimeAxis::Column {
                index,
                unit: opts.time_unit.or(dialect::time_unit_of(&names[index])),
                why: "by its name",
            });
        }
        if let Some(c) = columns
            .iter()
            .find(|c| matches!(c.time, ColumnTime::Waveform { .. }))
        {
            let ColumnTime::Waveform {
                start_ns,
                increment_s,
            } = c.time
            else {
                unreachable!("the found column is a waveform")
            };
            if !(increment_s.is_finite() && increment_s > 0.0) {
                return Err(format!(
                    "channel `{}` is a waveform with a sample interval of {increment_s} s; it \
                     must be a positive number of seconds (`wf_increment`)",
                    c.name
                ));
            }
            return Ok(TimeAxis::Waveform {
                start_ns,
                increment_s,
            });
        }
        if opts.allow_point_list {
            return Ok(TimeAxis::Index);
        }
        let hint = steady_hint(columns).map_or_else(
            || "; name the time channel with the `time_column` option".to_string(),
            |h| format!("; {h}"),
        );
        Err(format!(
            "no time channel among {} (none is named t, time or timestamp, nor typed as time \
             stamps or a waveform){hint}",
            quoted(&names)
        ))
    }

    /// The column that is the time, if one is.
    fn column(&self) -> Option<usize> {
        match self {
            TimeAxis::Column { index, .. } => Some(*index),
            _ => None,
        }
    }

    /// How many samples there are: the time column's length, or the longest channel's.
    fn len(&self, columns: &[Column]) -> usize {
        match self {
            TimeAxis::Column { index, .. } => columns[*index].values.len(),
            TimeAxis::Waveform { .. } | TimeAxis::Index => {
                columns.iter().map(|c| c.values.len()).max().unwrap_or(0)
            }
        }
    }

    /// Every sample's stamp, the origin the samples are timed from, and what the time is (for
    /// `inspect`); a time column whose unit nothing states is read in the unit its magnitude
    /// implies when its first stamp is a date since 1970 (noted in `diagnostics`).
    fn times(
        &self,
        path: &Path,
        columns: &[Column],
        len: usize,
        diagnostics: &mut ReadDiagnostics,
    ) -> Result<Timing, Error> {
        let (stamps_ns, what, point_list) = match self {
            TimeAxis::Index => {
                let what = match steady_hint(columns) {
                    Some(hint) => format!("none: read as a point list, samples in order; {hint}"),
                    None => "none: read as a point list, samples in order".into(),
                };
                let stamps = (0..len as i64).map(|i| i * NS_PER_S).collect();
                (stamps, what, true)
            }
            TimeAxis::Waveform {
                start_ns,
                increment_s,
            } => {
                let stamps = (0..len)
                    .map(|i| start_ns.saturating_add((i as f64 * increment_s * 1e9).round() as i64))
                    .collect::<Vec<i64>>();
                let what = format!("the channels' waveform, every {increment_s} s");
                (stamps, what, false)
            }
            TimeAxis::Column { index, unit, why } => {
                let column = &columns[*index];
                let unit = unit.unwrap_or_else(|| {
                    let first = match &column.values {
                        Values::F64(v) => v.first().copied(),
                        Values::I64(v) => v.first().map(|&x| x as f64),
                    };
                    match first.and_then(dialect::epoch_unit) {
                        Some((unit, year)) if unit != TimeUnit::S => {
                            diagnostics.time_unit = Some(calib_core::report::TimeUnitChoice {
                                column: column.name.clone(),
                                unit: unit.suffix().to_string(),
                                reason: format!(
                                    "the channel names no unit and its first stamp, {}, is a \
                                     date in {year} counted in {} since 1970 (in seconds it \
                                     would be beyond the year 2100); say `time_unit = s` to \
                                     read it in seconds",
                                    first.unwrap_or_default(),
                                    unit.name()
                                ),
                            });
                            unit
                        }
                        _ => TimeUnit::S,
                    }
                });
                let stamps = stamps_ns(column, unit).map_err(|m| Error::Data {
                    path: path.to_path_buf(),
                    message: format!("time channel `{}`: {m}", column.name),
                })?;
                let what = format!("`{}` ({why}), in {}", column.name, unit.name());
                (stamps, what, false)
            }
        };
        let origin_ns = match stamps_ns.first() {
            Some(&first) if first.div_euclid(NS_PER_S).abs() >= ORIGIN_FROM_S => {
                first.div_euclid(NS_PER_S) * NS_PER_S
            }
            _ => 0,
        };
        Ok(Timing {
            stamps_ns,
            origin_ns,
            what,
            point_list,
        })
    }
}

/// Where the samples' time comes from, as [`TimeAxis::times`] found it.
struct Timing {
    /// Every sample's stamp, ns.
    stamps_ns: Vec<i64>,
    /// The stamp the samples are timed from: the first one's whole second where it is beyond
    /// [`ORIGIN_FROM_S`], else 0.
    origin_ns: i64,
    /// What the time is, for `calib inspect`.
    what: String,
    /// Whether the samples are a point list, timed by their index.
    point_list: bool,
}

/// The samples' times, seconds from `origin_ns`, after the rule every reader follows
/// ([`crate::stamps`]): an exact copy of the sample before (the same stamp and readings) is
/// dropped from `readings` and counted in `diagnostics`; a repeat with other readings or a
/// stamp that goes back is refused (passed on where `allow_unordered_time`, for `inspect`).
#[allow(clippy::too_many_arguments)]
fn in_order(
    path: &Path,
    stamps_ns: Vec<i64>,
    origin_ns: i64,
    readings: &mut [Vec<f64>],
    what: &str,
    opts: &ReadOptions,
    diagnostics: &mut ReadDiagnostics,
    channels: &[Channel],
) -> Result<Vec<f64>, Error> {
    let err = |message: String| Error::Data {
        path: path.to_path_buf(),
        message,
    };
    let mut order = StampOrder::default();
    let mut keep = Vec::with_capacity(stamps_ns.len());
    let mut row = vec![0.0; readings.len()];
    for (i, &ns) in stamps_ns.iter().enumerate() {
        for (v, channel) in row.iter_mut().zip(readings.iter()) {
            *v = channel[i];
        }
        match order.check(ns, i as i64, &row) {
            Ok(Step::New) => keep.push(i),
            Ok(Step::Duplicate) => {}
            Err(_) if opts.allow_unordered_time => keep.push(i),
            Err(back) => {
                let how = match &back.conflict {
                    Some(_) => format!(
                        "repeats that of sample {} with other readings ({}); a time's readings \
                         must be one sample",
                        back.previous_message,
                        back.differences(|c| channels[c].name.clone(), |v| format!("{:.6} rad", v))
                    ),
                    None => format!(
                        "goes back before the previous sample's {} s (sample {}); the samples \
                         must be in increasing time order",
                        seconds(back.previous),
                        back.previous_message
                    ),
                };
                return Err(err(format!(
                    "the time ({what}) at sample {i}, {} s, {how}",
                    seconds(ns)
                )));
            }
        }
    }
    diagnostics.duplicates_dropped = order.duplicates();
    if keep.len() < stamps_ns.len() {
        for channel in readings.iter_mut() {
            *channel = keep.iter().map(|&i| channel[i]).collect();
        }
    }
    let times: Vec<f64> = keep
        .iter()
        .map(|&i| seconds(stamps_ns[i] - origin_ns))
        .collect();
    if let Some(problem) = times.last().and_then(|&t| crate::limits::time_problem(t)) {
        return Err(err(format!("the time ({what}): {problem}")));
    }
    Ok(times)
}

/// A time column's values as ns stamps, in `unit`.
fn stamps_ns(column: &Column, unit: TimeUnit) -> Result<Vec<i64>, String> {
    let ns_per_unit = match unit {
        TimeUnit::S => NS_PER_S,
        TimeUnit::Ms => 1_000_000,
        TimeUnit::Us => 1_000,
        TimeUnit::Ns => 1,
        TimeUnit::Ticks => 100,
    };
    match &column.values {
        Values::I64(v) => v
            .iter()
            .enumerate()
            .map(|(i, &x)| {
                x.checked_mul(ns_per_unit).ok_or_else(|| {
                    format!(
                        "sample {i}: {x} {} is beyond what 64-bit nanoseconds hold; check the \
                         unit (the `time_unit` option)",
                        unit.name()
                    )
                })
            })
            .collect(),
        Values::F64(v) => v
            .iter()
            .enumerate()
            .map(|(i, &x)| {
                let ns = x * ns_per_unit as f64;
                if ns.is_finite() && ns.abs() < 9.2e18 {
                    Ok(ns.round() as i64)
                } else {
                    Err(format!(
                        "sample {i}: `{x}` is not a time stamp calib can hold (finite, within \
                         ±292 years in ns); check the unit (the `time_unit` option)"
                    ))
                }
            })
            .collect(),
    }
}

/// Nanoseconds as seconds.
fn seconds(ns: i64) -> f64 {
    crate::ros2::decode::seconds(ns)
}

/// What to say of the first channel that increases steadily, the likely time of a file that
/// names none.
fn steady_hint(columns: &[Column]) -> Option<String> {
    columns
        .iter()
        .find(|c| steadily_increasing(&c.values))
        .map(|c| {
            // Quoted where a shell would expand it (`data_1[0]` is a glob).
            let value = if c
                .name
                .chars()
                .all(|ch| ch.is_alphanumeric() || matches!(ch, '_' | '-' | '.' | '/'))
            {
                c.name.clone()
            } else {
                format!("'{}'", c.name)
            };
            format!(
                "`{}` increases steadily: if it is the time, give `time_column = {value}` (and \
                 the `time_unit` option if it is not in seconds)",
                c.name
            )
        })
}

/// Whether `values` increase at every step, by steps within 1 % of their median: a clock.
fn steadily_increasing(values: &Values) -> bool {
    let v: Vec<f64> = match values {
        Values::F64(v) => v.iter().take(10_000).copied().collect(),
        Values::I64(v) => v.iter().take(10_000).map(|&x| x as f64).collect(),
    };
    if v.len() < 3 {
        return false;
    }
    let mut steps: Vec<f64> = v.windows(2).map(|w| w[1] - w[0]).collect();
    if !steps.iter().all(|s| *s > 0.0) {
        return false;
    }
    steps.sort_by(f64::total_cmp);
    let median = steps[steps.len() / 2];
    steps[0] > 0.99 * median && steps[steps.len() - 1] < 1.01 * median
}

/// Names as a message lists them: `a`, `b`, … (the first 12).
fn quoted(names: &[String]) -> String {
    let mut shown: Vec<String> = names.iter().take(12).map(|n| format!("`{n}`")).collect();
    if names.len() > 12 {
        shown.push(format!("and {} more", names.len() - 12));
    }
    shown.join(", ")
}

/// The structure lines as the tail of a message: what the file holds.
fn listing(structure: &[String]) -> String {
    if structure.is_empty() {
        String::new()
    } else {
        format!(" (it holds: {})", structure.join("; "))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn column(name: &str, values: Vec<f64>) -> Column {
        Column {
            name: name.into(),
            unit: None,
            values: Values::F64(values),
            time: ColumnTime::Unknown,
        }
    }

    fn read(set: ColumnSet, opts: &ReadOptions) -> Result<(ColumnReader, SampleBatch), Error> {
        let mut r = ColumnReader::from_set(Path::new("x.bin"), "TEST", set, opts)?;
        let mut batch = SampleBatch::new(r.channels().len());
        r.fill(&mut batch, usize::MAX);
        Ok((r, batch))
    }

    #[test]
    fn a_time_column_by_name_times_the_other_channels() {
        let set = ColumnSet {
            columns: vec![
                column("enc/a", vec![0.0, 1.0, 2.0]),
                column("Time [ms]", vec![0.0, 10.0, 20.0]),
                Column {
                    unit: Some("rad".into()),
                    ..column("enc/b", vec![0.0, 0.5, 1.0])
                },
            ],
            structure: vec![],
        };
        let (r, batch) = read(set, &ReadOptions::default()).unwrap();
        let names: Vec<&str> = r.channels().iter().map(|c| c.name.as_str()).collect();
        assert_eq!(names, ["enc/a", "enc/b"]);
        assert_eq!(r.channels()[1].unit, AngleUnit::Rad);
        let s = batch.get(2).to_sample();
        assert!((s.t - 0.02).abs() < 1e-15);
        // 2° and 1 rad, in radians.
        assert!((s.values[0] - 2f64.to_radians()).abs() < 1e-15);
        assert!((s.values[1] - 1.0).abs() < 1e-15);
    }

    #[test]
    fn epoch_stamps_are_counted_from_their_whole_second() {
        let t0 = 1_765_000_000_123_456_789i64;
        let set = ColumnSet {
            columns: vec![
                Column {
                    time: ColumnTime::Stamps(TimeUnit::Ns),
                    values: Values::I64(vec![t0, t0 + 1, t0 + 1_000_000]),
                    ..column("stamp", vec![])
                },
                column("a", vec![1.0, 2.0, 3.0]),
            ],
            structure: vec![],
        };
        let (r, batch) = read(set, &ReadOptions::default()).unwrap();
        assert_eq!(r.time_origin_s(), 1_765_000_000.0);
        let t: Vec<f64> = (0..3).map(|i| batch.get(i).to_sample().t).collect();
        // Every nanosecond kept: the first two stamps 1 ns apart (doubles near 0.12 s are
        // 1.4e-17 s apart; near 1.7e9 s they would be 2.4e-7 s apart).
        assert!((t[0] - 0.123456789).abs() < 1e-16);
        assert!((t[1] - t[0] - 1e-9).abs() < 1e-16);
        assert!((t[2] - 0.124456789).abs() < 1e-15);
    }

    #[test]
    fn a_waveform_times_its_samples_by_the_increment() {
        let set = ColumnSet {
            columns: vec![Column {
                time: ColumnTime::Waveform {
                    start_ns: 0,
                    increment_s: 0.001,
                },
                ..column("g/a", vec![1.0, 2.0, 3.0, 4.0])
            }],
            structure: vec!["group `g`: 1 channel".into()],
        };
        let (r, batch) = read(set, &ReadOptions::default()).unwrap();
        assert_eq!(batch.len(), 4);
        assert!((batch.get(3).to_sample().t - 0.003).abs() < 1e-15);
        assert!(r.structure().last().unwrap().contains("waveform"));
    }

    #[test]
    fn without_a_time_the_error_names_the_steady_column_and_the_option() {
        let set = ColumnSet {
            columns: vec![
                column("data_1[0]", vec![50.0, 50.001, 50.002, 50.003]),
                column("data_1[1]", vec![0.1, 0.3, 0.2, 0.4]),
            ],
            structure: vec![],
        };
        let err = read(set.clone(), &ReadOptions::default())
            .err()
            .unwrap()
            .to_string();
        assert!(err.contains("`time_column = 'data_1[0]'`"), "{err}");
        let opts = ReadOptions {
            time_column: Some("data_1[0]".into()),
            ..ReadOptions::default()
        };
        let (r, batch) = read(set, &opts).unwrap();
        assert_eq!(r.channels().len(), 1);
        assert!((batch.get(1).to_sample().t - 50.001).abs() < 1e-12);
    }

    #[test]
    fn stamps_that_go_back_are_refused_naming_the_sample() {
        let set = ColumnSet {
            columns: vec![column("t", vec![0.0, 1.0, 0.5]), column("a", vec![0.0; 3])],
            structure: vec![],
        };
        let err = read(set, &ReadOptions::default())
            .err()
            .unwrap()
            .to_string();
        assert!(
            err.contains("sample 2") && err.contains("goes back"),
            "{err}"
        );
    }

    #[test]
    fn exact_copies_are_dropped_and_counted_and_conflicts_refused() {
        let set = ColumnSet {
            columns: vec![
                column("t", vec![0.0, 1.0, 1.0, 2.0]),
                column("a", vec![0.0, 1.0, 1.0, 2.0]),
            ],
            structure: vec![],
        };
        let (r, batch) = read(set, &ReadOptions::default()).unwrap();
        assert_eq!(batch.len(), 3);
        assert_eq!(r.diagnostics().duplicates_dropped, 1);
        let set = ColumnSet {
            columns: vec![
                column("t", vec![0.0, 1.0, 1.0, 2.0]),
                column("a", vec![0.0, 1.0, 1.5, 2.0]),
            ],
            structure: vec![],
        };
        let err = read(set, &ReadOptions::default())
            .err()
            .unwrap()
            .to_string();
        assert!(
            err.contains("sample 2") && err.contains("other readings"),
            "{err}"
        );
    }

    #[test]
    fn a_time_column_without_a_unit_is_read_in_the_unit_its_magnitude_implies() {
        let t0 = 1_765_000_000_000_000_000i64;
        let set = ColumnSet {
            columns: vec![
                Column {
                    values: Values::I64(vec![t0, t0 + 5_000_000]),
                    ..column("timestamp", vec![])
                },
                column("a", vec![0.0, 1.0]),
            ],
            structure: vec![],
        };
        let (r, batch) = read(set, &ReadOptions::default()).unwrap();
        assert!((batch.get(1).to_sample().t - 0.005).abs() < 1e-15);
        let choice = r.diagnostics().time_unit.as_ref().unwrap();
        assert_eq!(choice.unit, "ns");
        assert!(r.structure().last().unwrap().contains("nanoseconds"));
    }

    #[test]
    fn a_column_of_another_length_is_left_out_and_listed() {
        let set = ColumnSet {
            columns: vec![
                column("t", vec![0.0, 1.0, 2.0]),
                column("a", vec![0.0; 3]),
                column("b", vec![0.0; 2]),
            ],
            structure: vec![],
        };
        let (r, _) = read(set, &ReadOptions::default()).unwrap();
        assert_eq!(r.all_channels().len(), 1);
        assert!(r.structure().iter().any(|l| l.contains("`b`: left out")));
    }

    #[test]
    fn a_channel_with_a_missing_reading_is_left_out_and_listed() {
        let set = ColumnSet {
            columns: vec![
                column("t", vec![0.0, 1.0, 2.0]),
                column("a", vec![0.0, 1.0, 2.0]),
                column("fill", vec![0.0, f64::NAN, 2.0]),
            ],
            structure: vec![],
        };
        let (r, _) = read(set, &ReadOptions::default()).unwrap();
        assert_eq!(r.all_channels().len(), 1);
        assert!(
            r.structure()
                .iter()
                .any(|l| l.contains("`fill`: left out, sample 1"))
        );
    }

    #[test]
    fn a_file_without_time_is_a_point_list_where_one_is_allowed() {
        let set = ColumnSet {
            columns: vec![
                column("ref", vec![0.0, 10.0]),
                column("dut", vec![0.1, 10.2]),
            ],
            structure: vec![],
        };
        let opts = ReadOptions {
            allow_point_list: true,
            ..ReadOptions::default()
        };
        let (r, batch) = read(set, &opts).unwrap();
        assert!(r.is_point_list());
        assert_eq!(batch.get(1).to_sample().t, 1.0);
    }
}
