//! Every limit calib enforces, in one place.
//!
//! - The range of values a reader accepts ([`MAX_READING_REV`], [`MAX_TIME_S`]): beyond it a
//!   value cannot be a real reading or time stamp, or an `f64` can no longer hold it to the
//!   precision calibration needs, so a reader reports it (naming file, line or message, and
//!   channel) instead of passing on a wrong number.
//! - The size of the work a command is asked for ([`MAX_TABLE_POINTS`], [`MAX_SIMULATED_SAMPLES`],
//!   [`MAX_CSV_LINE_BYTES`]): checked before any work starts, so that a mistyped option fails at
//!   once instead of running for minutes into gigabytes of memory or disk.

pub use crate::align::ALIGN_QUEUE;
use std::f64::consts::TAU;
use std::io::{self, Read};

/// The most points an output table may have (every command's `--points`): 3.6 million points are
/// 0.36″ steps, far finer than any map calib estimates (the interpolation error of a 0.01° grid is
/// already below 0.01″), and a table of them is about 100 MB of CSV.
pub const MAX_TABLE_POINTS: usize = 3_600_000;

/// The most samples `calib simulate` writes without `--force`: 50 million (14 hours at 1 kHz;
/// about 2.5 GB of CSV for two channels and as much time to write).
pub const MAX_SIMULATED_SAMPLES: u64 = 50_000_000;

/// The longest line a CSV reader accepts, bytes (1 MiB: a row of 40 000 channels in full
/// precision). Longer is not a log row (a binary file, `/dev/zero`, a file without line ends), and
/// reading it whole would take as much memory as it is long.
pub const MAX_CSV_LINE_BYTES: usize = 1 << 20;

/// The largest MCAP chunk decompressed on a worker thread, bytes, compressed or decompressed
/// (16 MiB, sixteen times the chunks the `mcap` and ROS 2 writers close by default). Larger chunks
/// are read by the streaming reader, which holds only part of a chunk at a time: a file claiming
/// huge chunks costs no memory for them, and reads the same either way.
pub const MAX_PARALLEL_CHUNK_BYTES: usize = 16 << 20;

/// The longest MCAP record calib reads where the file is shorter than it, bytes (64 MiB). A
/// record inside a compressed chunk can be longer than the whole file (one large, compressible
/// message), so the file's length alone would refuse a valid log; beyond this, a length is a
/// damaged one, and refusing it keeps a corrupt length from driving a large allocation.
pub const MAX_MCAP_RECORD_BYTES: usize = 64 << 20;

/// The record length limit of an MCAP file of `len` bytes: its length, or
/// [`MAX_MCAP_RECORD_BYTES`] if that is more.
pub(crate) fn mcap_record_limit(len: u64) -> usize {
    usize::try_from(len)
        .unwrap_or(usize::MAX)
        .max(MAX_MCAP_RECORD_BYTES)
}

/// The most a bag's split compressed whole (`compression_mode: FILE`) may grow when
/// decompressed, as a multiple of its compressed size (1000×, with at least 1 GiB allowed):
/// recorded data compresses 3–20×, and a SQLite file of empty pages a few hundred times. Checked
/// while decompressing, so a small damaged split is refused after writing at most this much.
pub const MAX_DECOMPRESSION_RATIO: u64 = 1000;

/// The decompressed size allowed a split of `compressed` bytes (see
/// [`MAX_DECOMPRESSION_RATIO`]).
pub(crate) fn decompressed_limit(compressed: u64) -> u64 {
    compressed
        .saturating_mul(MAX_DECOMPRESSION_RATIO)
        .max(1 << 30)
}

/// The largest message payload a bag's message-compressed rows (`compression_mode: MESSAGE`)
/// may decompress to, bytes (16 MiB: a JointState of [`MAX_JOINTS`] joints is under 1 MiB).
pub const MAX_PAYLOAD_BYTES: usize = 16 << 20;

/// The longest header of a ROS 1 bag record, and the longest data of a connection or chunk
/// info record, bytes (16 MiB: a connection's header holds its type's full message definition,
/// tens of kilobytes for the largest). Checked before the bytes are read.
pub const MAX_ROS1_HEADER_BYTES: usize = 16 << 20;

/// The largest ROS 1 bag chunk calib decompresses, bytes, compressed or not (256 MiB;
/// `rosbag record` closes chunks at 768 KiB by default). A chunk header's declared size is
/// checked against it before anything is allocated, and decompression stops at the declared
/// size.
pub const MAX_ROS1_CHUNK_BYTES: usize = 256 << 20;

/// The most decompressed chunk bytes a ROS 1 bag reader holds at once to hand on messages in
/// time order where chunks overlap in time (1 GiB). Chunks that follow one another in time
/// are held one at a time.
pub const MAX_ROS1_HELD_BYTES: usize = 1 << 30;

/// Bytes as a message shows them: printable ASCII as it is, anything else as `\xNN`.
pub(crate) fn shown_bytes(bytes: &[u8]) -> String {
    let text: String = bytes
        .iter()
        .flat_map(|&b| std::ascii::escape_default(b))
        .map(char::from)
        .collect();
    format!("`{text}`")
}

/// The most topics an MCAP file or a bag may have (10,000: a whole robot records a few hundred).
/// Checked from the summary or the bag's `topics` table before any message is read, and again as
/// the data section adds channels.
pub const MAX_TOPICS: usize = 10_000;

/// The most joints one JointState (or DynamicJointState) message may name (10,000: a robot has
/// tens). Checked before the names are read.
pub const MAX_JOINTS: usize = 10_000;

/// The most fields a JSON message may have (10,000).
pub const MAX_JSON_FIELDS: usize = 10_000;

/// The most message types a message definition may hold (1,000: a JointState's holds three, a
/// large driver message a few dozen).
pub const MAX_MESSAGE_TYPES: usize = 1_000;

/// The most columns a CSV log may have (10,000: a channel per column).
pub const MAX_CSV_COLUMNS: usize = 10_000;

/// Names listed in a message: at most this many, then how many more.
const LISTED: usize = 20;

/// `names` as a message lists them: comma-separated, the first [`LISTED`] and then how many more,
/// so that a file of 100,000 fields does not make a 789 KB error line.
pub(crate) fn listed(names: &[impl AsRef<str>]) -> String {
    let shown: Vec<&str> = names.iter().take(LISTED).map(AsRef::as_ref).collect();
    let mut text = shown.join(", ");
    if names.len() > LISTED {
        text.push_str(&format!(", … ({} more)", names.len() - LISTED));
    }
    text
}

/// A CSV line longer than [`MAX_CSV_LINE_BYTES`], found by [`LineLimit`].
#[derive(Debug)]
pub(crate) struct LineTooLong {
    /// The 1-based line.
    pub line: u64,
}

impl std::fmt::Display for LineTooLong {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "line {} is longer than {MAX_CSV_LINE_BYTES} bytes, more than any log row; this is \
             not a CSV log (a binary file, or one without line ends)",
            self.line
        )
    }
}

impl std::error::Error for LineTooLong {}

/// A reader that fails with [`LineTooLong`] as soon as a line exceeds [`MAX_CSV_LINE_BYTES`], so
/// a CSV parser never buffers more than that for one record.
#[derive(Debug)]
pub(crate) struct LineLimit<R> {
    inner: R,
    /// Line ends passed so far.
    newlines: u64,
    /// Bytes since the last line end.
    run: usize,
}

impl<R> LineLimit<R> {
    pub(crate) fn new(inner: R) -> Self {
        LineLimit {
            inner,
            newlines: 0,
            run: 0,
        }
    }
}

impl<R: Read> Read for LineLimit<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let n = self.inner.read(buf)?;
        let got = &buf[..n];
        match got.iter().rposition(|&b| b == b'\n' || b == b'\r') {
            Some(last) => {
                self.newlines += got.iter().filter(|&&b| b == b'\n').count() as u64;
                self.run = n - last - 1;
            }
            None => self.run += n,
        }
        if self.run > MAX_CSV_LINE_BYTES {
            return Err(io::Error::new(
                io::ErrorKind::InvalidData,
                LineTooLong {
                    line: self.newlines + 1,
                },
            ));
        }
        Ok(n)
    }
}

/// The [`LineTooLong`] inside an I/O error, if it is one.
pub(crate) fn line_too_long(e: &io::Error) -> Option<&LineTooLong> {
    e.get_ref()
        .and_then(|inner| inner.downcast_ref::<LineTooLong>())
}

/// The largest reading magnitude, in revolutions from zero (10 million: a shaft at 6000 rpm turns
/// that far in 28 hours). At this magnitude an `f64` in radians resolves 7·10⁻⁹ rad (0.0015″);
/// a billion revolutions would blur readings to 0.2″.
pub const MAX_READING_REV: f64 = 1e7;

/// The largest time stamp magnitude, seconds (10¹⁰ s: the year 2286 as a Unix time). Larger
/// stamps are in another unit (milliseconds, nanoseconds), and an `f64` of them no longer
/// resolves the microseconds between samples.
pub const MAX_TIME_S: f64 = 1e10;

/// Why a reading of `value` in the log's unit (written `shown` in the log), `rad` radians, cannot
/// be used, if it cannot.
pub(crate) fn reading_problem(
    shown: impl std::fmt::Display,
    value: f64,
    rad: f64,
) -> Option<String> {
    if !value.is_finite() {
        return Some(format!(
            "reading `{shown}` is not a finite number; remove the row or repair the recording \
             (calib cannot calibrate from missing readings)"
        ));
    }
    let rev = rad / TAU;
    if rev.abs() <= MAX_READING_REV {
        return None;
    }
    Some(format!(
        "reading {shown} is {rev:.3e} revolutions from zero, beyond the {MAX_READING_REV:e} an \
         angle can be held to 0.002″; check the channel's unit (the `unit` option), or subtract a whole \
         number of revolutions from the readings"
    ))
}

/// `x` as a message shows it: plain decimals between 10⁻⁴ and 10⁹ (at most 10 significant
/// digits), scientific notation beyond, so that 1e300 is not printed as 301 digits.
pub fn readable(x: f64) -> String {
    let a = x.abs();
    if !x.is_finite() || x == 0.0 {
        return format!("{x}");
    }
    if !(1e-4..1e9).contains(&a) {
        return format!("{x:.4e}");
    }
    // At most 10 significant digits, trailing zeros dropped.
    let decimals = (9 - a.log10().floor() as i32).clamp(0, 13) as usize;
    calib_core::report::trimmed(x, decimals)
}

/// [`readable`] as a [`std::fmt::Display`], formatted only when shown: readings are checked on the
/// hot path, and only a refused one is ever printed.
#[derive(Debug, Clone, Copy)]
pub struct Readable(pub f64);

impl std::fmt::Display for Readable {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&readable(self.0))
    }
}

/// What an array of samples handed in as numbers (calib-py's) holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Samples {
    /// Readings in radians.
    Readings,
    /// Time stamps in seconds.
    Stamps,
}

/// Why the array `name` of `values` cannot be used as `kind`, if it cannot: empty, or its first
/// value that a log's reader would refuse (NaN or infinite, a reading beyond
/// [`MAX_READING_REV`], a stamp beyond [`MAX_TIME_S`]), named as `name[index]`. The rule is the
/// readers' (`reading_problem`, `time_problem`), so that arrays and logs are held to one.
pub fn array_problem(name: &str, values: &[f64], kind: Samples) -> Option<String> {
    if values.is_empty() {
        return Some(format!(
            "`{name}` is empty: give one {} per sample",
            match kind {
                Samples::Readings => "reading (radians)",
                Samples::Stamps => "time stamp (seconds)",
            }
        ));
    }
    values.iter().enumerate().find_map(|(i, &v)| {
        let why = match kind {
            Samples::Readings => reading_problem(Readable(v), v, v),
            Samples::Stamps if !v.is_finite() => Some(format!(
                "time stamp `{v}` is not a finite number; remove the sample or repair the \
                 recording"
            )),
            Samples::Stamps => time_problem(v),
        };
        why.map(|why| format!("`{name}[{i}]` is {}: {why}", describe(v)))
    })
}

/// `v` named as a value of an array: `NaN`, `inf`, `-inf`, or the number.
fn describe(v: f64) -> String {
    if v.is_nan() {
        "NaN".to_string()
    } else {
        readable(v)
    }
}

/// Why a time stamp of `t` seconds cannot be used, if it cannot.
pub(crate) fn time_problem(t: f64) -> Option<String> {
    if t.abs() <= MAX_TIME_S {
        return None;
    }
    let t = readable(t);
    Some(format!(
        "time stamp {t} s is beyond ±{MAX_TIME_S:e} s (the year 2286): the column is not in \
         seconds; say its unit with `time_unit = ms`, `us` or `ns` (milliseconds, microseconds \
         or nanoseconds)"
    ))
}

/// The most datasets an HDF5 (or MATLAB v7.3) file may hold for calib to read it (10,000: a DAQ
/// export holds a dataset per channel, tens or hundreds). Checked from the file's index of
/// datasets before any is read.
pub const MAX_HDF5_DATASETS: usize = 10_000;

/// The most columns a Parquet file's schema may have for calib to read it (10,000, as for CSV).
/// Checked from the footer before any row group is read.
pub const MAX_PARQUET_COLUMNS: usize = 10_000;

/// The longest Parquet footer (the file's metadata) calib reads, bytes (64 MiB: a file of 10,000
/// columns and a thousand row groups has a few MiB). The footer states its own length; a larger
/// one is a damaged file.
pub const MAX_PARQUET_FOOTER_BYTES: u64 = 64 << 20;

#[cfg(test)]
mod tests {
    use super::*;

    /// Arrays are held to the readers' rule, named by argument and first bad index.
    #[test]
    fn arrays_are_named_at_their_first_bad_value() {
        let r = Samples::Readings;
        assert_eq!(array_problem("a", &[0.0, 1.0], r), None);
        assert!(
            array_problem("a", &[], r)
                .unwrap()
                .starts_with("`a` is empty")
        );
        let nan = array_problem("a", &[0.0, f64::NAN, f64::INFINITY], r).unwrap();
        assert!(nan.starts_with("`a[1]` is NaN: reading"), "{nan}");
        let far = array_problem("b", &[1e9], r).unwrap();
        assert!(
            far.starts_with("`b[0]` is 1.0000e9") && far.contains("revolutions"),
            "{far}"
        );
        let t = array_problem("t", &[0.0, f64::NEG_INFINITY], Samples::Stamps).unwrap();
        assert!(t.starts_with("`t[1]` is -inf"), "{t}");
        let ms = array_problem("t", &[0.0, 2e10], Samples::Stamps).unwrap();
        assert!(ms.contains("beyond"), "{ms}");
    }

    #[test]
    fn a_line_beyond_the_limit_fails_naming_it() {
        let mut text = b"t,a\n0,1\n".to_vec();
        text.extend(std::iter::repeat_n(b'9', MAX_CSV_LINE_BYTES + 1));
        let mut out = Vec::new();
        let err = LineLimit::new(text.as_slice())
            .read_to_end(&mut out)
            .unwrap_err();
        assert_eq!(line_too_long(&err).expect("LineTooLong").line, 3);
        let ok = vec![b'1'; MAX_CSV_LINE_BYTES];
        assert!(LineLimit::new(ok.as_slice()).read_to_end(&mut out).is_ok());
    }

    #[test]
    fn readings_up_to_ten_million_revolutions_pass() {
        assert_eq!(reading_problem(360.0, 360.0, TAU), None);
        assert_eq!(reading_problem(-3.6e9, -3.6e9, -1e7 * TAU), None);
        let far = reading_problem(1e12, 1e12, 1e12_f64.to_radians()).expect("1e12 degrees");
        assert!(far.contains("revolutions from zero"), "{far}");
        assert!(reading_problem("nan", f64::NAN, f64::NAN).is_some());
        // A finite reading whose conversion overflows (1e308 revolutions).
        assert!(reading_problem("1e308", 1e308, f64::INFINITY).is_some());
    }

    #[test]
    fn numbers_are_readable() {
        assert_eq!(readable(1e300), "1.0000e300");
        assert_eq!(readable(360.0), "360");
        assert_eq!(readable(-0.5), "-0.5");
        assert_eq!(readable(1.7e9), "1.7000e9");
        assert_eq!(readable(0.001234), "0.001234");
        assert_eq!(readable(1.0 / 3.0), "0.3333333333");
        assert_eq!(readable(f64::NAN), "NaN");
    }

    #[test]
    fn time_stamps_beyond_the_year_2286_fail() {
        assert_eq!(time_problem(1.7e9), None);
        assert_eq!(time_problem(-1.7e9), None);
        assert!(time_problem(1.7e18).expect("ns").contains("nanoseconds"));
        assert!(time_problem(f64::INFINITY).is_some());
    }
}
