//! `calib-io`: reading recorded runs into [`calib_core::Sample`]s, and writing calib's tables and
//! reports.
//!
//! - [`csv_log`]: CSV logs (`t`, one column per channel, optional `session`).
//! - [`mcap_log`]: MCAP logs with ROS 2 `sensor_msgs/msg/JointState` or `std_msgs` scalars (CDR),
//!   or JSON messages.
//! - [`rosbag`]: rosbag2 bags (a bag directory or a `.db3` file) with the same ROS 2 messages.
//! - [`ros1bag`]: ROS 1 bags (`.bag`, format 2.0) with `sensor_msgs/JointState` or scalars.
//! - [`naming`]: channels addressed by joint name or `TOPIC/JOINT`.
//! - [`align`]: channels on different clocks interpolated onto the first one's stamps.
//! - [`table`]: correction tables (`angle_deg,error_arcsec,correction_arcsec[,u_arcsec]`).
//! - [`export`]: correction tables in the forms controllers load (look-up tables, moteus
//!   `conf set` lines, SimpleFOC `CalibratedSensor` tables, harmonics).
//! - [`import`]: the same forms read back into calib tables (a table already on a controller).
//! - [`atomic`]: output files that appear only when complete.
//! - [`folder_lock`]: one run at a time into an output folder.
//! - [`apply`]: a log rewritten with one channel corrected by an error map.
//! - [`log`]: [`LogReader`] and [`LogWriter`] choose the format from the file.
//! - [`Prefetch`]: a reader on a second thread, filling batches of samples ahead of the caller;
//!   [`ReadProgress`]: how far it has got, for a progress line.
//! - [`report`]: `report.json` and other JSON outputs.
//! - [`readings`]: shift-angle readings (`shift_deg,start_face,step,reading_arcsec`).
//! - [`shift_angle`]: the shift-angle method's `encoder.csv` and `polygon.csv`.
//! - [`compare`]: `compare.csv`, two error maps point by point.
//! - [`budget`]: GUM uncertainty budgets (TOML).
//! - [`scenario`]: simulation scenarios (TOML).
//! - [`points`]: tolerant reader of error tables on any grid, for comparisons.
//! - [`limits`]: the range of readings and time stamps readers accept.
//! - [`source`]: where a log's bytes come from: a file, memory, or (feature `remote`) a URL of
//!   object storage (`s3://`, `gs://`, `az://`, `http(s)://`), read by byte range.
//!
//! Every reader streams: memory stays bounded whatever the log's length. Every error names the
//! file and the line or message it concerns ([`Error`]).
//!
//! # Example
//! ```no_run
//! use calib_io::{LogReader, ReadOptions};
//!
//! let mut log = LogReader::open("run.mcap".as_ref(), &ReadOptions::default())?;
//! let names: Vec<String> = log.channels().iter().map(|c| c.name.clone()).collect();
//! let mut count = 0;
//! for sample in log.by_ref() {
//!     let sample = sample?; // errors name the file and the message or line
//!     count += sample.values.len();
//! }
//! println!("{count} readings of {names:?}");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![deny(missing_docs)]

pub mod align;
pub mod apply;
pub mod atomic;
mod bookkeeping;
pub mod budget;
mod columns;
pub mod compare;
pub mod csv_log;
mod error;
pub mod export;
pub mod folder_lock;
pub mod import;
pub mod limits;
pub mod log;
pub mod mcap_log;
pub mod moteus_dump;
pub mod naming;
pub mod points;
mod prefetch;
mod progress;
pub mod readings;
pub mod report;
pub mod ros1bag;
mod ros2;
pub mod rosbag;
pub mod scenario;
pub mod shift_angle;
pub mod source;
mod stamps;
pub mod table;

pub use align::AlignOptions;
pub use bookkeeping::is_bookkeeping;
pub use error::Error;
pub use log::{LogFormat, LogReader, LogWriter};
pub use naming::{ChannelLookup, ChannelName};
pub use prefetch::{BatchSource, Prefetch};
pub use progress::{ProgressUnit, ReadProgress};

use calib_core::AngleUnit;

/// How to read a log.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ReadOptions {
    /// The unit of readings in formats that do not fix it (CSV, JSON messages); degrees if `None`.
    /// JointState positions are radians by definition and ignore it.
    pub unit: Option<AngleUnit>,
    /// Pass messages (CSV rows) whose time stamp repeats with other readings or goes back
    /// instead of failing on them (for `calib inspect`, which reports them). Methods need
    /// increasing stamps and leave it off. Exact copies of the message before are dropped
    /// either way.
    pub allow_unordered_time: bool,
    /// Read a CSV file without a time column as a list of stationary points, in row order,
    /// timed by the row index (0, 1, 2, … s; see [`LogReader::is_point_list`]), instead of
    /// refusing it. For the commands that calibrate from points (`reference`) or describe a
    /// file (`inspect`).
    pub allow_point_list: bool,
    /// MCAP: leave out chunks that do not match their CRC (or cannot be decoded), listing them in
    /// [`ReadDiagnostics::damaged_chunks`], instead of failing on the first.
    pub skip_damaged: bool,
    /// Which time stamps MCAP messages are read at.
    pub time: TimeSource,
    /// The time column of a CSV log (default: `t`, `time` or `timestamp`, with or without a
    /// unit suffix).
    pub time_column: Option<String>,
    /// The unit of a CSV log's time column (default: its name's suffix, else seconds).
    pub time_unit: Option<csv_log::dialect::TimeUnit>,
    /// MCAP: channel names to read as `TOPIC.field.path` — a numeric field of a topic calib does
    /// not otherwise read, found through the `ros2msg` message definition the file carries, in
    /// the unit of [`unit`](Self::unit). Names of other forms are ignored here (pass every
    /// channel name the command was given).
    pub fields: Vec<String>,
    /// Read on the calling thread only: MCAP chunks are not decompressed on worker threads (for
    /// a caller limited to one thread, `calib --jobs 1`).
    pub one_thread: bool,
    /// Options of the object store a log named by a URL is read from (`aws_endpoint`,
    /// `aws_access_key_id`, `aws_region`, `aws_allow_http`, …, as `object_store` names them),
    /// over those the environment gives; see [`source`].
    pub storage_options: source::StorageOptions,
    /// The largest remote log of a format read from a file (rosbag2, ROS 1 bags, the columnar
    /// formats) copied to a temporary local file, bytes; `None`:
    /// [`source::DEFAULT_MAX_COPY_BYTES`].
    pub max_copy_bytes: Option<u64>,
}

/// The time of a message: the stamp its publisher wrote, or when the recorder logged it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum TimeSource {
    /// `header.stamp` (the log time where a message has no header or a zero stamp).
    #[default]
    Header,
    /// The log time the recorder wrote beside every message.
    Log,
}

/// What a reader noticed while reading, for `inspect` and for warnings.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct ReadDiagnostics {
    /// Where the log ended early (a crashed recording): the byte offset of the break and the
    /// number of messages read before it.
    pub truncated: Option<Truncation>,
    /// MCAP chunks left out because they were damaged (only with
    /// [`ReadOptions::skip_damaged`]; otherwise the first is an error).
    pub damaged_chunks: Vec<DamagedChunk>,
    /// Messages (CSV rows) dropped because they repeat the one before exactly, stamp and
    /// readings: a message recorded twice (see `stamps`, the rule every reader shares).
    pub duplicates_dropped: u64,
    /// How the unit of a CSV time column that names none was chosen from its stamps'
    /// magnitude (stamps since 1970 in ms, µs or ns); `None` where nothing was chosen.
    pub time_unit: Option<calib_core::report::TimeUnitChoice>,
}

/// An MCAP chunk whose records do not match the CRC its header records, or cannot be decoded.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct DamagedChunk {
    /// Byte offset of the chunk record in the file.
    pub byte_offset: u64,
    /// The log times its header gives for its first and last message, ns (`None` if the header
    /// could not be read).
    pub log_time_ns: Option<(u64, u64)>,
    /// What is wrong with it.
    pub reason: String,
}

impl DamagedChunk {
    /// The chunk `span` (or, if its header was never read, the chunk at `position`) damaged by
    /// `error`.
    pub(crate) fn new(
        span: Option<mcap::sans_io::ChunkSpan>,
        position: u64,
        error: &mcap::McapError,
    ) -> Self {
        let reason = match error {
            mcap::McapError::BadChunkCrc { saved, calculated } => format!(
                "its records do not match its CRC (recorded {saved:#010x}, computed \
                 {calculated:#010x})"
            ),
            e => format!("its records cannot be decoded ({e})"),
        };
        Self::because(span, position, reason)
    }

    /// The chunk `span` (or the chunk at `position`) damaged as `reason` says.
    pub(crate) fn because(
        span: Option<mcap::sans_io::ChunkSpan>,
        position: u64,
        reason: String,
    ) -> Self {
        DamagedChunk {
            byte_offset: span.map_or(position, |s| s.offset),
            log_time_ns: span
                .filter(|s| s.message_start_time != 0 || s.message_end_time != 0)
                .map(|s| (s.message_start_time, s.message_end_time)),
            reason,
        }
    }
}

impl std::fmt::Display for DamagedChunk {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let seconds = |ns: u64| format!("{}.{:06}", ns / 1_000_000_000, ns % 1_000_000_000 / 1000);
        write!(f, "the chunk at byte {}", self.byte_offset)?;
        if let Some((a, b)) = self.log_time_ns {
            write!(f, " (messages logged {} s to {} s)", seconds(a), seconds(b))?;
        }
        write!(f, " is damaged: {}", self.reason)
    }
}

/// A log that ends before its end marker.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Truncation {
    /// Byte offset at which reading stopped.
    pub byte_offset: u64,
    /// Messages read before it.
    pub messages_read: u64,
}
