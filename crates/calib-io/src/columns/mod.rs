//! Logs whose channels are stored as whole columns of numbers — LabVIEW TDMS, MATLAB `.mat`,
//! HDF5 and Parquet. Each format is one type implementing [`ColumnFormat`], listed once in
//! [`FORMATS`]: it reads its file into a [`ColumnSet`], and [`reader::ColumnReader`] turns that
//! into samples the same way for every format (the time column or waveform, units, channel
//! selection, batches).

use std::path::Path;

use crate::csv_log::dialect::TimeUnit;
use crate::{Error, ReadOptions};

pub(crate) mod binary;
#[cfg(feature = "hdf5")]
pub(crate) mod hdf5;
pub(crate) mod mat;
#[cfg(feature = "parquet")]
pub(crate) mod parquet;
#[cfg(feature = "parquet")]
mod parquet_guards;
pub(crate) mod reader;
pub(crate) mod tdms;
#[cfg(feature = "parquet")]
mod thrift_walk;

/// A log format whose channels are whole columns. One type per format, listed in [`FORMATS`];
/// detection, `calib inspect` and the help texts take the formats from there.
pub(crate) trait ColumnFormat: Sync {
    /// The name messages and `calib inspect` give the format (`TDMS`, `MATLAB`, `HDF5`,
    /// `Parquet`).
    fn name(&self) -> &'static str;
    /// One line for the help texts: what the format is and who writes it.
    fn about(&self) -> &'static str;
    /// The file extensions of the format, lowercase, without the dot.
    fn extensions(&self) -> &'static [&'static str];
    /// Whether a file whose first bytes are `head` (up to [`SNIFF_BYTES`], fewer if the file is
    /// shorter) is of this format.
    fn sniff(&self, head: &[u8]) -> bool;
    /// Reads every numeric channel of the file at `path`. Sizes the file states are checked
    /// against its length before anything is allocated; errors name the file and the variable,
    /// group or column concerned.
    fn read(&self, path: &Path, opts: &ReadOptions) -> Result<ColumnSet, Error>;
}

/// How many first bytes [`ColumnFormat::sniff`] is shown.
pub(crate) const SNIFF_BYTES: usize = 128;

/// Every columnar format calib reads, in the order detection tries them.
pub(crate) static FORMATS: &[&dyn ColumnFormat] = &[
    &tdms::Tdms,
    // Before `mat::Mat`: a v7.3 file (HDF5 inside) is known by its header's text.
    #[cfg(feature = "hdf5")]
    &hdf5::MatV73,
    &mat::Mat,
    #[cfg(feature = "hdf5")]
    &hdf5::Hdf5,
    #[cfg(feature = "parquet")]
    &parquet::Parquet,
];

/// The format whose [`ColumnFormat::name`] is `name`.
pub(crate) fn by_name(name: &str) -> Option<&'static dyn ColumnFormat> {
    FORMATS.iter().copied().find(|f| f.name() == name)
}

/// The numeric channels of a columnar file, as its format's module read them.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct ColumnSet {
    /// Every numeric channel, in the file's order.
    pub columns: Vec<Column>,
    /// What the file holds, a line each, as `calib inspect` lists it: groups, variables,
    /// datasets or columns, with their shapes, types and what was not taken (strings, a matrix
    /// of three dimensions) and why.
    pub structure: Vec<String>,
}

/// One channel of a columnar file.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Column {
    /// The channel's name: a TDMS `group/channel`, a MATLAB variable (`var`, or `var[i]` for
    /// the i-th column or row of a matrix, 0-based, along its short side), an HDF5 dataset's
    /// path without the leading `/`, a Parquet column's path.
    pub name: String,
    /// The unit the file states (a TDMS `unit_string`, an HDF5 `unit`/`units` attribute), as
    /// written; `None` where it states none.
    pub unit: Option<String>,
    /// The values, one per sample.
    pub values: Values,
    /// What the file says of the column's time.
    pub time: ColumnTime,
}

/// A column's numbers, as stored: integers stay integers (stamps in ns since 1970 do not fit a
/// double to the nanosecond).
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Values {
    /// Floating-point values (and integers of 32 bits or fewer, widened).
    F64(Vec<f64>),
    /// 64-bit integers.
    I64(Vec<i64>),
}

impl Values {
    /// The number of values.
    pub(crate) fn len(&self) -> usize {
        match self {
            Values::F64(v) => v.len(),
            Values::I64(v) => v.len(),
        }
    }
}

/// What a file says of a column's time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum ColumnTime {
    /// Nothing: readings, or a time column known by its name (`t`, `time`, …) or
    /// `--time-column`.
    Unknown,
    /// The column holds time stamps since 1970 in this unit (a Parquet `TIMESTAMP`, a TDMS
    /// time-stamp channel).
    Stamps(TimeUnit),
    /// A waveform: the column's sample `i` was taken at `start_ns + i·increment_s` (TDMS
    /// `wf_start_time` and `wf_increment`; `start_ns` in ns since 1970, 0 where the file gives
    /// no start).
    Waveform {
        /// The first sample's stamp, ns since 1970 (or 0).
        start_ns: i64,
        /// Seconds between samples.
        increment_s: f64,
    },
}
