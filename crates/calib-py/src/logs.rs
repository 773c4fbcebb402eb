//! Reading logs: `calib.read`, and the opening and streaming the `*_log` methods share.

use crate::errors::{data, usage};
use calib_core::{AngleUnit, SampleRef};
use calib_io::AlignOptions;
use calib_io::Prefetch;
use calib_io::{LogReader, ReadOptions, TimeSource};
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use calib_io::source::{ByteSource, MemorySource};

/// A log as the `*_log` functions take it: a path or a URL (`str` or `os.PathLike`), or a file
/// object (anything with `.read()`, such as an `fsspec` file), read whole into memory.
pub enum LogInput {
    /// A path, or a URL ([`calib_io::source::url_of`]).
    Path(PathBuf),
    /// A file object's bytes, named by its `name` or `path` attribute (whose extension decides
    /// the format where its first bytes do not).
    Memory(PathBuf, Arc<dyn ByteSource>),
}

impl LogInput {
    /// The log `obj` gives: a file object is read here (with the GIL: it is Python code).
    pub fn from_py(obj: &Bound<'_, PyAny>) -> PyResult<Self> {
        if let Ok(path) = obj.extract::<PathBuf>() {
            return Ok(LogInput::Path(path));
        }
        if !obj.hasattr("read")? {
            return Err(usage(format!(
                "a log is a path, a URL or a file object (with .read()), not {}",
                obj.get_type().name()?
            )));
        }
        let name = ["name", "path", "full_name"]
            .iter()
            .find_map(|attr| obj.getattr(*attr).ok()?.extract::<String>().ok())
            .unwrap_or_else(|| "<file object>".to_string());
        let read = obj.call_method0("read")?;
        let bytes = read.extract::<&[u8]>().map_err(|_| {
            usage(format!(
                "{name}: its .read() gave no bytes; open it in binary mode (\"rb\")"
            ))
        })?;
        Ok(LogInput::Memory(
            PathBuf::from(name),
            Arc::new(MemorySource::new(bytes.to_vec())),
        ))
    }

    /// The log's name in messages and reports: its path, its URL, or the file object's name.
    pub fn name(&self) -> &Path {
        match self {
            LogInput::Path(path) | LogInput::Memory(path, _) => path,
        }
    }

    /// Opens it with `read`.
    fn open(&self, read: &ReadOptions) -> Result<LogReader, calib_io::Error> {
        match self {
            LogInput::Path(path) => LogReader::open(path, read),
            LogInput::Memory(name, source) => {
                LogReader::open_source(name, Arc::clone(source), read)
            }
        }
    }
}

/// How a log is read: the keyword arguments of the CLI's `--unit`, `--time`, `--max-gap`,
/// `--time-column` and `--time-unit`.
pub struct LogOptions {
    read: ReadOptions,
    align: AlignOptions,
}

impl LogOptions {
    /// The options from the keyword arguments, checked.
    pub fn new(
        unit: Option<&str>,
        time: &str,
        max_gap: Option<f64>,
        time_column: Option<String>,
        time_unit: Option<&str>,
        storage_options: Option<HashMap<String, String>>,
    ) -> PyResult<Self> {
        let unit = unit
            .map(|u| u.parse::<AngleUnit>())
            .transpose()
            .map_err(|e| usage(format!("unit: {e}")))?;
        let time = match time {
            "header" => TimeSource::Header,
            "log" => TimeSource::Log,
            other => {
                return Err(usage(format!(
                    "time=`{other}`: give \"header\" (the message's header.stamp) or \"log\" (the \
                     time the recorder logged it)"
                )));
            }
        };
        if max_gap.is_some_and(|g| !(g > 0.0 && g.is_finite())) {
            return Err(usage("max_gap must be a positive number of seconds"));
        }
        let time_unit = time_unit
            .map(|u| u.parse())
            .transpose()
            .map_err(|e: String| usage(format!("time_unit: {e}")))?;
        Ok(LogOptions {
            read: ReadOptions {
                unit,
                time,
                time_column,
                time_unit,
                storage_options: storage_options.into_iter().flatten().collect(),
                ..ReadOptions::default()
            },
            align: AlignOptions { max_gap_s: max_gap },
        })
    }
}

/// Checks that `path` can be a log, as the CLI does before opening it
/// ([`calib_io::log::NotALog::check`]): a `UsageError` naming the path if not.
fn check_log_path(input: &LogInput) -> PyResult<()> {
    let LogInput::Path(path) = input else {
        return Ok(());
    };
    let shown = path.display().to_string();
    match calib_io::log::NotALog::check(path) {
        Some(not) => Err(usage(format!("{shown}: {not}"))),
        None => Ok(()),
    }
}

/// Opens the log at `path` reading the channels `names` only (every channel if `None`), in
/// this order, the first setting the clock.
/// Called without the GIL: a URL's log is fetched here.
pub fn open(input: &LogInput, names: Option<&[String]>, opts: &LogOptions) -> PyResult<LogReader> {
    check_log_path(input)?;
    let path = input.name();
    let mut read = opts.read.clone();
    read.fields = names.map(<[String]>::to_vec).unwrap_or_default();
    let mut reader = input
        .open(&read)
        .map_err(|e| data(format!("cannot read {}: {e}", path.display())))?;
    if let Some(names) = names {
        let indices = names
            .iter()
            .map(|n| {
                reader
                    .resolve(n)
                    .map_err(|e| usage(format!("{}: {e}", path.display())))
            })
            .collect::<PyResult<Vec<_>>>()?;
        reader.select(&indices, opts.align);
    }
    Ok(reader)
}

/// [`open`] again for a later reading of the same log (a method that reads it twice), its
/// errors as messages: the log was opened once already, so they are data errors.
pub fn reopen(input: &LogInput, names: &[String], opts: &LogOptions) -> Result<LogReader, String> {
    let path = input.name();
    let mut read = opts.read.clone();
    read.fields = names.to_vec();
    let mut reader = input
        .open(&read)
        .map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    let indices = names
        .iter()
        .map(|n| {
            reader
                .resolve(n)
                .map_err(|e| format!("{}: {e}", path.display()))
        })
        .collect::<Result<Vec<_>, _>>()?;
    reader.select(&indices, opts.align);
    Ok(reader)
}

/// Calls `push` with every sample of `reader` (opened on `path`), decoding on a second thread
/// while this one pushes. Returns the reader, for its warnings and alignment, or the message
/// of the first sample that cannot be read.
pub fn for_each_sample(
    path: &Path,
    reader: LogReader,
    mut push: impl FnMut(SampleRef),
) -> Result<LogReader, String> {
    let mut samples = Prefetch::new(reader);
    while let Some(batch) = samples.next_batch() {
        let batch = batch.map_err(|e| format!("cannot read {}: {e}", path.display()))?;
        batch.iter().for_each(&mut push);
    }
    Ok(samples.finish())
}

/// The alignment of a log read as JSON (report.json's `details.alignment`), `None` where every
/// channel was read at the clock's own stamps with nothing dropped.
pub fn alignment(reader: &LogReader) -> Option<calib_core::report::Alignment> {
    reader.alignment().filter(|a| !a.is_exact())
}

/// What a result's report takes from how its log was read (the default for readings given as
/// arrays).
#[derive(Debug, Default)]
pub struct LogRead {
    /// How the channels were aligned on the clock ([`alignment`]).
    pub alignment: Option<calib_core::report::Alignment>,
    /// The stamp, s, from which the samples' times count ([`LogReader::time_origin_s`]).
    pub time_origin_s: f64,
    /// What the reader decided that the user did not say (report.json's `details.reading`,
    /// [`LogReader::reading`]): exact copies dropped, the unit of epoch stamps.
    pub reading: Option<calib_core::report::Reading>,
}

/// How `reader`'s log was read, once it is read.
pub fn log_read(reader: &LogReader) -> LogRead {
    LogRead {
        alignment: alignment(reader),
        time_origin_s: reader.time_origin_s(),
        reading: reader.reading(),
    }
}

/// Reads a whole log into numpy arrays (see `calib.read`).
#[pyfunction]
#[pyo3(signature = (path, channels=None, time="header", unit=None, max_gap=None, time_column=None, time_unit=None, storage_options=None))]
#[allow(clippy::too_many_arguments)]
pub fn read<'py>(
    py: Python<'py>,
    path: Bound<'py, PyAny>,
    channels: Option<Vec<String>>,
    time: &str,
    unit: Option<&str>,
    max_gap: Option<f64>,
    time_column: Option<String>,
    time_unit: Option<&str>,
    storage_options: Option<HashMap<String, String>>,
) -> PyResult<Bound<'py, PyDict>> {
    let opts = LogOptions::new(unit, time, max_gap, time_column, time_unit, storage_options)?;
    let input = LogInput::from_py(&path)?;
    let path = input.name().to_path_buf();
    let reader = py.detach(|| open(&input, channels.as_deref(), &opts))?;
    let names: Vec<String> = match &channels {
        Some(c) => c.clone(),
        None => reader.channels().iter().map(|c| c.name.clone()).collect(),
    };
    let marks = reader.has_session_marks();
    let (t, values, sessions, reader) = py
        .detach(|| {
            let mut t = Vec::new();
            let mut values = vec![Vec::new(); names.len()];
            let mut sessions = Vec::new();
            let reader = for_each_sample(&path, reader, |s| {
                t.push(s.t);
                for (column, v) in values.iter_mut().zip(s.values) {
                    column.push(*v);
                }
                if marks {
                    sessions.push(s.session.map_or(-1, i64::from));
                }
            })?;
            Ok::<_, String>((t, values, sessions, reader))
        })
        .map_err(data)?;
    // The stamps on the log's own clock (the reader counts them from an origin).
    let origin = reader.time_origin_s();
    let t: Vec<f64> = t.into_iter().map(|t| t + origin).collect();
    let out = PyDict::new(py);
    out.set_item("t", PyArray1::from_vec(py, t))?;
    let columns = PyDict::new(py);
    for (name, column) in names.iter().zip(values) {
        columns.set_item(name, PyArray1::from_vec(py, column))?;
    }
    out.set_item("channels", columns)?;
    out.set_item("session", marks.then(|| PyArray1::from_vec(py, sessions)))?;
    let alignment = alignment(&reader)
        .map(|a| serde_json::to_string(&a))
        .transpose()
        .map_err(|e| data(e.to_string()))?;
    out.set_item("alignment_json", alignment)?;
    out.set_item("warnings", reader.warnings(&path))?;
    out.set_item("notes", reader.notes())?;
    Ok(out)
}

/// What a log holds, as `calib inspect --json` prints it (see `calib.inspect`): the keys of
/// every object in alphabetical order.
#[pyfunction]
#[pyo3(signature = (path, a=None, b=None, time="header", unit=None, max_gap=None, time_column=None, time_unit=None, storage_options=None))]
#[allow(clippy::too_many_arguments)]
pub fn inspect(
    py: Python<'_>,
    path: Bound<'_, PyAny>,
    a: Option<String>,
    b: Option<String>,
    time: &str,
    unit: Option<&str>,
    max_gap: Option<f64>,
    time_column: Option<String>,
    time_unit: Option<&str>,
    storage_options: Option<HashMap<String, String>>,
) -> PyResult<String> {
    let opts = LogOptions::new(unit, time, max_gap, time_column, time_unit, storage_options)?;
    let input = LogInput::from_py(&path)?;
    let path = input.name().to_path_buf();
    check_log_path(&input)?;
    let read = ReadOptions {
        allow_unordered_time: true,
        allow_point_list: true,
        fields: [&a, &b].into_iter().flatten().cloned().collect(),
        ..opts.read
    };
    let mut reader = py
        .detach(|| input.open(&read))
        .map_err(|e| data(format!("cannot read {}: {e}", path.display())))?;
    let names: Vec<String> = reader.names().iter().map(|n| n.display.clone()).collect();
    let resolve = |name: &str| {
        reader
            .resolve(name)
            .map_err(|e| usage(format!("{}: {e}", path.display())))
    };
    let pick = |given: &Option<String>, default: &str, fallback: usize| match given {
        Some(name) => resolve(name).map(Some),
        None if names.iter().any(|n| n == default) => resolve(default).map(Some),
        None => Ok((fallback < names.len()).then_some(fallback)),
    };
    let point_list = reader.is_point_list();
    let pair = match (pick(&a, "a", 0)?, pick(&b, "b", 1)?) {
        // A point list has no motion to segment.
        (Some(a), Some(b)) if a != b && !point_list => Some((a, b)),
        _ => None,
    };
    // Every channel, the pair's first (or the log's first) leading: it sets the clock.
    let clock = pair.map_or(0, |(a, _)| a);
    let order: Vec<usize> = std::iter::once(clock)
        .chain((0..names.len()).filter(|&i| i != clock))
        .collect();
    reader.select(&order, opts.align);
    let at = |raw: usize| order.iter().position(|&i| i == raw).unwrap_or(0);
    let pair = pair.map(|(a, b)| (at(a), at(b)));
    let mut inspector = calib_core::inspect::Inspector::new(
        reader.channels(),
        pair,
        calib_core::segment::SegmentOptions {
            use_marks: reader.has_session_marks(),
            ..calib_core::segment::SegmentOptions::default()
        },
    );
    let (result, reader) = py
        .detach(|| {
            let reader =
                for_each_sample(&path, reader, |s| inspector.push(s.t, s.values, s.session))?;
            let result = inspector.finish().with_time_origin(reader.time_origin_s());
            Ok::<_, String>((result, reader))
        })
        .map_err(data)?;
    if result.samples == 0 {
        return Err(data(format!(
            "{}: the log holds no samples",
            path.display()
        )));
    }
    let warnings = reader.inspect_warnings(&path);
    let suggestions = calib_core::purpose::suggestions(&result);
    let json = serde_json::json!({
        "schema_version": calib_core::report::SCHEMA_VERSION,
        "log": path.display().to_string(),
        "point_list": point_list,
        "points": point_list.then_some(result.samples),
        "stated_directions": reader.stated_directions(),
        "topics": reader.topics(),
        "alignment": reader.alignment(),
        "inspection": result,
        "suggestions": suggestions,
        "warnings": warnings,
    });
    calib_io::report::render_json(&json).map_err(|e| data(e.to_string()))
}
