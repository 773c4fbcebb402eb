//! Any log calib reads, behind one interface: [`LogReader`] and [`LogWriter`].

use crate::align::{AlignOptions, Aligner, Alignment};
use crate::columns::{self, ColumnFormat, reader::ColumnReader};
use crate::csv_log::{CsvReader, CsvWriter};
use crate::mcap_log::{DEFAULT_TOPIC, McapReader, McapWriter, TopicInfo};
use crate::naming::{self, ChannelLookup, ChannelName};
use crate::ros1bag::{self, Ros1BagReader};
use crate::ros2::samples::{OneByOne, Ros2Reader};
use crate::rosbag::{self, BagReader, PreparedStorage, SQLITE_MAGIC};
use crate::source::{self, ByteSource, Fetched};
use crate::{Error, ReadDiagnostics, ReadOptions};
use calib_core::{AngleUnit, Channel, Sample, SampleBatch};
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The formats calib reads and writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LogFormat {
    /// CSV with a header row.
    Csv,
    /// MCAP.
    Mcap,
    /// A rosbag2 bag: a bag directory (`metadata.yaml`, `.db3` or `.mcap` splits) or a `.db3`
    /// file. Read only.
    Rosbag,
    /// A file whose channels are whole columns (TDMS, MATLAB, HDF5, Parquet), by the name of its
    /// `ColumnFormat`. Read only.
    Columns(&'static str),
    /// A ROS 1 bag (`.bag`, format 2.0). Read only.
    Ros1Bag,
}

const MCAP_MAGIC: &[u8] = b"\x89MCAP0\r\n";

/// A path that names no log calib can open, found before anything is read: the mistakes of
/// naming a path (the command line calls them usage errors), said with what to do.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum NotALog {
    /// Nothing is there.
    #[error("no such file; check the path")]
    Missing,
    /// A folder that is not a rosbag2 bag directory.
    #[error(
        "this is a folder, not a log nor a rosbag2 bag directory (which holds metadata.yaml or \
         .db3 files); name the .csv or .mcap file inside it, or the bag directory"
    )]
    Folder,
}

impl NotALog {
    /// Why `path` cannot be a log, if it cannot: missing, or a folder other than a rosbag2 bag
    /// directory. Other files are for [`LogFormat::detect`] to judge by their content.
    /// A URL ([`crate::source::url_of`]) is not looked at here: what is there is found when it
    /// is opened.
    pub fn check(path: &Path) -> Option<NotALog> {
        if crate::source::url_of(path).is_some() {
            return None;
        }
        match std::fs::metadata(path) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Some(NotALog::Missing),
            Ok(meta) if meta.is_dir() && !rosbag::is_bag_dir(path) => Some(NotALog::Folder),
            _ => None,
        }
    }
}

impl LogFormat {
    /// The format's usual file extension: `csv` or `mcap`.
    pub fn name(self) -> &'static str {
        match self {
            LogFormat::Csv => "csv",
            LogFormat::Mcap => "mcap",
            LogFormat::Rosbag => "db3",
            LogFormat::Ros1Bag => "bag",
            LogFormat::Columns(name) => {
                columns::by_name(name).map_or("bin", |f| f.extensions().first().unwrap_or(&"bin"))
            }
        }
    }

    /// Whether `calib apply` writes a corrected log of this format (CSV and MCAP).
    pub fn rewritable(self) -> bool {
        matches!(self, LogFormat::Csv | LogFormat::Mcap)
    }

    /// Why `calib apply` does not rewrite a log of this format, and what to do instead; `None`
    /// for the formats it rewrites.
    pub fn not_rewritten(self) -> Option<String> {
        match self {
            LogFormat::Csv | LogFormat::Mcap => None,
            LogFormat::Rosbag => Some(
                "calib corrects CSV and MCAP logs, not rosbag2 bags; convert the bag to MCAP \
                 (`ros2 bag convert`) and correct that"
                    .into(),
            ),
            LogFormat::Ros1Bag => Some(
                "calib corrects CSV and MCAP logs, not ROS 1 bags; convert the bag to MCAP \
                 (`mcap convert run.bag run.mcap`) and correct that"
                    .into(),
            ),
            LogFormat::Columns(name) => Some(format!(
                "calib corrects CSV and MCAP logs, not {name} files; save the run as CSV and \
                 correct that (or correct readings from Python with `calib.apply_table`)"
            )),
        }
    }

    /// The format of a file to write, from its extension.
    pub fn for_output(path: &Path) -> Result<Self, Error> {
        match extension(path).as_deref() {
            Some("csv") => Ok(LogFormat::Csv),
            Some("mcap") => Ok(LogFormat::Mcap),
            _ => Err(Error::UnknownFormat {
                path: path.to_path_buf(),
            }),
        }
    }

    /// The format of an existing log. A directory is a rosbag2 bag if [`rosbag::is_bag_dir`]
    /// says so (it holds `metadata.yaml` or `.db3` files), else an error. A file is known by its
    /// first bytes whatever its extension: MCAP's magic number, SQLite's (a rosbag2 `.db3`
    /// file), a ROS 1 bag's (`#ROSBAG V`, of any version, for the ROS 1 reader to refuse any but
    /// 2.0 with its reason), or another known kind of file (compressed, an archive, UTF-16 or
    /// binary data), which is an error saying what the file is and what to do. Other content is
    /// a bag if the extension is `.db3` or `.bag` (for the bag readers to refuse with their
    /// reason), CSV if the extension says so (or is unknown and the text looks like CSV).
    /// Devices and sockets are refused: a log is a file (a named pipe, which can be read only
    /// once, is taken by its extension).
    pub fn detect(path: &Path) -> Result<Self, Error> {
        let io = |source| Error::Io {
            path: path.to_path_buf(),
            source,
        };
        if crate::source::url_of(path).is_some() {
            let source = crate::source::open(path, &Vec::new())?;
            return Self::detect_source(path, &source);
        }
        let meta = std::fs::metadata(path).map_err(io)?;
        if meta.is_dir() && rosbag::is_bag_dir(path) {
            return Ok(LogFormat::Rosbag);
        }
        if let Some(not) = NotALog::check(path).filter(|not| *not != NotALog::Missing) {
            return Err(Error::Data {
                path: path.to_path_buf(),
                message: not.to_string(),
            });
        }
        if !meta.is_file() && !is_fifo(&meta) {
            return Err(Error::Data {
                path: path.to_path_buf(),
                message: "this is a device or socket, not a log file; name a .csv or .mcap file"
                    .into(),
            });
        }
        if is_fifo(&meta) {
            // A pipe can be read once: its first bytes cannot be looked at before the reader
            // reads them. Its extension decides.
            return Self::for_output(path);
        }
        let mut head = [0u8; columns::SNIFF_BYTES];
        let mut file = std::fs::File::open(path).map_err(io)?;
        let n = read_head(&mut file, &mut head).map_err(io)?;
        Self::detect_head(path, &head[..n])
    }

    /// The format of the log in `source`, named `name` (a URL): by its first bytes, else its
    /// name's extension, as [`detect`](Self::detect) judges a file.
    pub fn detect_source(name: &Path, source: &Arc<dyn ByteSource>) -> Result<Self, Error> {
        // Exactly the head: a front-to-back read of an object would fetch a block ahead.
        let mut head = [0u8; columns::SNIFF_BYTES];
        let n = head
            .len()
            .min(usize::try_from(source.len()).unwrap_or(usize::MAX));
        source
            .read_exact_at(0, &mut head[..n])
            .map_err(|source| Error::Io {
                path: name.to_path_buf(),
                source,
            })?;
        Self::detect_head(name, &head[..n])
    }

    /// The format of a log named `path` whose first bytes are `head`.
    fn detect_head(path: &Path, head: &[u8]) -> Result<Self, Error> {
        if head.starts_with(MCAP_MAGIC) {
            return Ok(LogFormat::Mcap);
        }
        if head.starts_with(SQLITE_MAGIC) {
            return Ok(LogFormat::Rosbag);
        }
        if head.starts_with(ros1bag::records::MAGIC_PREFIX) {
            return Ok(LogFormat::Ros1Bag);
        }
        if let Some(format) = columns::FORMATS.iter().find(|f| f.sniff(head)) {
            return Ok(LogFormat::Columns(format.name()));
        }
        if let Some((kind, todo)) = foreign_kind(head) {
            return Err(Error::Data {
                path: path.to_path_buf(),
                message: format!(
                    "this is {kind}, not a log calib reads ({}); {todo}",
                    formats_read()
                ),
            });
        }
        match extension(path).as_deref() {
            Some("mcap") => Ok(LogFormat::Mcap),
            // Text exports: TwinCAT, MATLAB and numpy write `.txt` and `.dat` as often as `.csv`.
            Some("csv" | "txt" | "dat" | "tsv") => Ok(LogFormat::Csv),
            Some("db3") => Ok(LogFormat::Rosbag),
            Some("bag") => Ok(LogFormat::Ros1Bag),
            Some(ext) => columns::FORMATS
                .iter()
                .find(|f| f.extensions().contains(&ext))
                .map(|f| LogFormat::Columns(f.name()))
                .ok_or_else(|| Error::UnknownFormat {
                    path: path.to_path_buf(),
                }),
            None => Err(Error::UnknownFormat {
                path: path.to_path_buf(),
            }),
        }
    }
}

/// Reads the first `head.len()` bytes of `file` into `head` (fewer only at its end): their
/// number.
fn read_head(file: &mut impl Read, head: &mut [u8]) -> std::io::Result<usize> {
    let mut n = 0;
    while n < head.len() {
        match file.read(&mut head[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(n)
}

#[cfg(unix)]
fn is_fifo(meta: &std::fs::Metadata) -> bool {
    use std::os::unix::fs::FileTypeExt;
    meta.file_type().is_fifo()
}

#[cfg(not(unix))]
fn is_fifo(_meta: &std::fs::Metadata) -> bool {
    false
}

/// What a file starting with `head` is, and what to do, if it is a known kind that is not a log.
fn foreign_kind(head: &[u8]) -> Option<(&'static str, &'static str)> {
    const KINDS: &[(&[u8], &str, &str)] = &[
        (
            b"\x1f\x8b",
            "a gzip-compressed file",
            "decompress it first (gunzip)",
        ),
        (
            b"\x28\xb5\x2f\xfd",
            "a zstd-compressed file",
            "decompress it first (zstd -d)",
        ),
        (
            b"BZh",
            "a bzip2-compressed file",
            "decompress it first (bunzip2)",
        ),
        (
            b"\xfd7zXZ\x00",
            "an xz-compressed file",
            "decompress it first (unxz)",
        ),
        (
            b"PK\x03\x04",
            "a ZIP archive (or a spreadsheet)",
            "extract the log, or export the sheet as CSV",
        ),
        (b"\x89PNG", "a PNG image", "name the log file"),
        (b"%PDF", "a PDF document", "name the log file"),
        (b"\xff\xfe", "UTF-16 text", "save it as UTF-8"),
        (b"\xfe\xff", "UTF-16 text", "save it as UTF-8"),
    ];
    if let Some((_, kind, todo)) = KINDS.iter().find(|(magic, _, _)| head.starts_with(magic)) {
        return Some((kind, todo));
    }
    // Text has no NUL bytes (UTF-16 aside, caught above). Only the first 16 bytes judge: a text
    // log with a stray NUL further on is refused by its reader, naming the line.
    head[..head.len().min(16)]
        .contains(&0)
        .then_some(("binary data", "name the log file"))
}

/// The formats calib reads, as help texts and errors list them: CSV, MCAP, rosbag2 and the
/// columnar formats calib-io lists (TDMS, MATLAB, HDF5, Parquet).
pub fn formats_read() -> String {
    let mut names: Vec<String> = [
        "CSV (.csv)",
        "MCAP (.mcap)",
        "rosbag2 bags (a bag directory or .db3)",
        "ROS 1 bags (.bag)",
    ]
    .map(String::from)
    .to_vec();
    names.extend(
        columns::FORMATS
            .iter()
            .map(|f| format!("{} (.{})", f.name(), f.extensions().join(", ."))),
    );
    names.join(", ")
}

/// One line per columnar format calib reads (TDMS, MATLAB, …): what it is, who writes it and
/// how its channels are named, from calib-io's list of them, for the help texts.
pub fn column_formats_help() -> Vec<String> {
    columns::FORMATS
        .iter()
        .map(|f| {
            format!(
                "{} (.{}): {}",
                f.name(),
                f.extensions().join(", ."),
                f.about()
            )
        })
        .collect()
}

fn extension(path: &Path) -> Option<String> {
    path.extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
}

/// A streaming reader of any supported log.
///
/// It opens with every channel of the log selected; [`select`](Self::select) narrows the samples
/// to the channels a method needs, in its order, aligned on the first one's clock (see
/// [`crate::align`]). Channels are found by name with [`resolve`](Self::resolve) (see
/// [`crate::naming`]).
pub struct LogReader {
    inner: Inner,
    names: Vec<ChannelName>,
    /// CSV: the selected columns and their channels (MCAP selects itself).
    selection: Option<(Vec<usize>, Vec<Channel>)>,
    /// A sparse CSV's selected channels aligned on the first one's stamps, as MCAP topics are;
    /// `true` once the file is read to its end.
    csv_aligner: Option<(Aligner, bool)>,
    /// How a CSV's selected channels are aligned, should the file turn out sparse after its
    /// first rows ([`CsvReader::sparse_from_line`]).
    csv_align: AlignOptions,
    /// A bag's warnings about how it was found (a missing `metadata.yaml`).
    bag_warnings: Vec<String>,
    /// The samples read but not yet handed on by [`Iterator::next`].
    one: OneByOne,
    /// A bag's temporary files and the splits (or bag) errors name instead.
    renames: Vec<(PathBuf, PathBuf)>,
    /// A bag's decompressed or merged files, removed when the reader is dropped (after it:
    /// fields drop in order).
    _temp: Option<crate::atomic::TempFolder>,
    /// A log read from a URL: where its bytes come from, and whether they were copied to a
    /// temporary file first (the copy, removed when the reader is dropped).
    remote: Option<Remote>,
}

/// A log read from a URL.
struct Remote {
    name: PathBuf,
    source: Arc<dyn ByteSource>,
    /// The temporary local copy it was read from, if its format needs a file.
    copy: Option<source::LocalCopy>,
}

/// How a log named by a URL was read: for a note, and for `calib inspect`.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct RemoteRead {
    /// The object's length, bytes.
    pub len: u64,
    /// Bytes fetched, and the requests that fetched them.
    pub fetched: Fetched,
    /// Whether the log was copied to a temporary local file first (the formats read from a
    /// file: rosbag2, ROS 1 bags, the columnar formats).
    pub copied: bool,
}

/// Both boxed: the readers are large, and of different sizes.
enum Inner {
    Csv(Box<CsvReader>),
    /// An MCAP file or a bag: either reader, through the ROS 2 layer they share.
    Ros2(Box<dyn Ros2Reader>),
    /// A columnar file (TDMS, MATLAB, HDF5, Parquet), read whole.
    Columns(Box<ColumnReader>),
}

impl LogReader {
    /// Opens a log, choosing the reader by [`LogFormat::detect`]. A path that is a URL
    /// ([`source::url_of`]) is read from object storage (the `remote` feature; see
    /// [`crate::source`]), with [`ReadOptions::storage_options`].
    pub fn open(path: &Path, opts: &ReadOptions) -> Result<Self, Error> {
        if source::url_of(path).is_some() {
            let source = source::open(path, &opts.storage_options)?;
            return Self::open_source(path, source, opts);
        }
        Self::open_file(path, opts)
    }

    /// Opens the log whose bytes `source` holds, named `name` in messages and reports (its
    /// extension decides where its first bytes do not). MCAP is read at the ranges it needs and
    /// CSV streamed; the other formats need a file and are copied to a temporary one first, at
    /// most [`ReadOptions::max_copy_bytes`] (see [`crate::source`]).
    pub fn open_source(
        name: &Path,
        source: Arc<dyn ByteSource>,
        opts: &ReadOptions,
    ) -> Result<Self, Error> {
        let inner = match LogFormat::detect_source(name, &source)? {
            LogFormat::Csv => Inner::Csv(Box::new(CsvReader::open_source(
                name,
                Arc::clone(&source),
                opts,
            )?)),
            LogFormat::Mcap => Inner::Ros2(Box::new(McapReader::open_source(
                name,
                Arc::clone(&source),
                opts,
            )?)),
            _ => {
                let max = opts
                    .max_copy_bytes
                    .unwrap_or(source::DEFAULT_MAX_COPY_BYTES);
                let copy = source::local_copy(name, &source, max)?;
                let mut reader = Self::open_file(&copy.path, opts)
                    .map_err(|e| e.renamed(&[(copy.path.clone(), name.to_path_buf())]))?;
                reader.renames.push((copy.path.clone(), name.to_path_buf()));
                reader.remote = Some(Remote {
                    name: name.to_path_buf(),
                    source,
                    copy: Some(copy),
                });
                return Ok(reader);
            }
        };
        let mut reader = Self::with(inner, Vec::new(), Vec::new(), None);
        reader.remote = Some(Remote {
            name: name.to_path_buf(),
            source,
            copy: None,
        });
        Ok(reader)
    }

    /// How a log named by a URL was read so far: its length, the bytes fetched and whether it
    /// was copied; `None` for a local file.
    pub fn remote_read(&self) -> Option<RemoteRead> {
        self.remote.as_ref().map(|r| RemoteRead {
            len: r.source.len(),
            fetched: r.source.fetched(),
            copied: r.copy.is_some(),
        })
    }

    /// What was fetched of a log named by a URL, as a line for the user: the bytes of its
    /// length and the requests, and whether it was copied to a temporary file first; `None` for a
    /// local file.
    pub fn remote_note(&self) -> Option<String> {
        let r = self.remote.as_ref()?;
        let read = self.remote_read()?;
        Some(format!(
            "{}: fetched {} of its {} bytes in {} request(s){}",
            r.name.display(),
            read.fetched.bytes,
            read.len,
            read.fetched.requests,
            if read.copied {
                ", into a temporary local copy (calib reads this format from a file)"
            } else {
                ""
            }
        ))
    }

    /// Opens a local log.
    fn open_file(path: &Path, opts: &ReadOptions) -> Result<Self, Error> {
        let mut bag_warnings = Vec::new();
        let mut temp = None;
        let mut renames = Vec::new();
        let inner = match LogFormat::detect(path)? {
            LogFormat::Csv => Inner::Csv(Box::new(CsvReader::open(path, opts)?)),
            LogFormat::Mcap => Inner::Ros2(Box::new(McapReader::open(path, opts)?)),
            LogFormat::Rosbag => {
                let bag = rosbag::prepare_with(path, opts.skip_damaged)?;
                temp = bag.temp;
                renames = bag.renames;
                bag_warnings = bag.warnings;
                let rename = |e: Error| e.renamed(&renames);
                Inner::Ros2(match bag.storage {
                    PreparedStorage::Sqlite3(files) => Box::new(
                        BagReader::open(
                            path,
                            files,
                            bag.compressed_messages,
                            bag_warnings.clone(),
                            opts,
                        )
                        .map_err(rename)?,
                    ),
                    PreparedStorage::Mcap(file) => {
                        Box::new(McapReader::open(&file, opts).map_err(rename)?)
                    }
                })
            }
            LogFormat::Ros1Bag => {
                let bag = Ros1BagReader::open(path, opts)?;
                bag_warnings = bag.warnings().to_vec();
                Inner::Ros2(Box::new(bag))
            }
            LogFormat::Columns(name) => {
                let format: &dyn ColumnFormat =
                    columns::by_name(name).expect("detect names a listed format");
                Inner::Columns(Box::new(ColumnReader::open(path, format, opts)?))
            }
        };
        Ok(Self::with(inner, bag_warnings, renames, temp))
    }

    fn with(
        inner: Inner,
        bag_warnings: Vec<String>,
        renames: Vec<(PathBuf, PathBuf)>,
        temp: Option<crate::atomic::TempFolder>,
    ) -> Self {
        let names = match &inner {
            Inner::Csv(r) => r
                .channels()
                .iter()
                .map(|c| ChannelName::plain(&c.name))
                .collect(),
            Inner::Ros2(r) => r.samples().names().to_vec(),
            Inner::Columns(r) => r
                .all_channels()
                .iter()
                .map(|c| ChannelName::plain(&c.name))
                .collect(),
        };
        LogReader {
            inner,
            names,
            selection: None,
            csv_aligner: None,
            csv_align: AlignOptions::default(),
            bag_warnings,
            one: OneByOne::default(),
            renames,
            _temp: temp,
            remote: None,
        }
    }

    /// The names of every channel of the log, selected or not: the indices
    /// [`select`](Self::select) takes.
    pub fn names(&self) -> &[ChannelName] {
        &self.names
    }

    /// The index of the channel `name` names (a qualified name, or a short one no other channel
    /// shares).
    pub fn resolve(&self, name: &str) -> Result<usize, ChannelLookup> {
        naming::resolve(&self.names, name)
    }

    /// Reads only `channels` (indices into [`names`](Self::names)), in this order, aligned on the
    /// first one's stamps. Call it before reading any sample.
    pub fn select(&mut self, channels: &[usize], opts: AlignOptions) {
        match &mut self.inner {
            Inner::Csv(r) => {
                let all = r.channels();
                let chosen = channels.iter().map(|&i| all[i].clone()).collect();
                if r.is_sparse() && !channels.is_empty() {
                    self.csv_aligner = Some((Aligner::new(channels.to_vec(), opts), false));
                }
                r.set_needed(channels);
                self.csv_align = opts;
                self.selection = Some((channels.to_vec(), chosen));
            }
            Inner::Ros2(r) => r.samples_mut().select(channels, opts),
            Inner::Columns(r) => r.select(channels),
        }
    }

    /// The channels of each sample, in the order of its values.
    pub fn channels(&self) -> &[Channel] {
        match (&self.inner, &self.selection) {
            (_, Some((_, chosen))) => chosen,
            (Inner::Csv(r), None) => r.channels(),
            (Inner::Ros2(r), None) => r.samples().channels(),
            (Inner::Columns(r), None) => r.channels(),
        }
    }

    /// Whether the log is a list of stationary points without time (a CSV file without a time
    /// column, read with [`ReadOptions::allow_point_list`]): its samples are its rows in order,
    /// timed by their index.
    pub fn is_point_list(&self) -> bool {
        match &self.inner {
            Inner::Csv(r) => r.is_point_list(),
            Inner::Columns(r) => r.is_point_list(),
            Inner::Ros2(_) => false,
        }
    }

    /// The direction of approach each point of a point list states (`None` where its cell is
    /// empty), by row (a sample's time is its row), read so far; `None` for a log without a
    /// `direction` column ([`crate::csv_log::direction`]).
    pub fn point_directions(&self) -> Option<&[Option<calib_core::reference_points::Approach>]> {
        match &self.inner {
            Inner::Csv(r) => r.directions(),
            Inner::Ros2(_) | Inner::Columns(_) => None,
        }
    }

    /// Points of a point list whose `direction` column states their direction of approach (a
    /// non-empty cell), read so far; `None` without the column.
    pub fn stated_directions(&self) -> Option<u64> {
        self.point_directions()
            .map(|d| d.iter().filter(|d| d.is_some()).count() as u64)
    }

    /// The layout of a CSV log; `None` for the other formats.
    pub fn csv_dialect(&self) -> Option<&crate::csv_log::dialect::Dialect> {
        match &self.inner {
            Inner::Csv(r) => Some(r.dialect()),
            Inner::Ros2(_) | Inner::Columns(_) => None,
        }
    }

    /// What to say when the log seems not to move (or to turn impossibly fast) and a CSV time
    /// column's step fits another unit better than the one it was read in (see
    /// [`crate::csv_log::time_step`]), from the rows read so far; `None` otherwise.
    pub fn time_unit_hint(&self) -> Option<String> {
        match &self.inner {
            Inner::Csv(r) => r.time_step().and_then(|s| s.unit_hint()),
            Inner::Ros2(_) | Inner::Columns(_) => None,
        }
    }

    /// What to say when a method found the log too slow to count as moving (under `min_speed`,
    /// rad/s): [`time_unit_hint`](Self::time_unit_hint), else the smaller unit of a CSV time
    /// column in which the readings, which do move, would turn fast enough (see
    /// [`crate::csv_log::time_step`]).
    pub fn time_unit_hint_when_still(&self, min_speed: f64) -> Option<String> {
        match &self.inner {
            Inner::Csv(r) => r
                .time_step()
                .and_then(|s| s.unit_hint_when_still(min_speed)),
            Inner::Ros2(_) | Inner::Columns(_) => None,
        }
    }

    /// How far the reader has got through the log's file, of its size (a SQLite bag, whose rows
    /// are not read in the file's order: its messages, of those of the topics read): a handle to
    /// read from another thread while it reads.
    pub fn progress(&self) -> crate::progress::ReadProgress {
        match &self.inner {
            Inner::Csv(r) => r.progress(),
            Inner::Ros2(r) => r.progress(),
            Inner::Columns(r) => r.progress(),
        }
    }

    /// Whether the log marks CSRR sessions (a CSV `session` column).
    pub fn has_session_marks(&self) -> bool {
        matches!(&self.inner, Inner::Csv(r) if r.has_session_column())
    }

    /// The stamp, seconds on the log's own clock, from which the samples' times are counted:
    /// a sample's time plus this is its stamp. Stamps since 1970 as doubles are 2.4·10⁻⁷ s
    /// apart, too coarse for a fast coast, so the readers count stamps beyond 2²¹ s (24 days) from
    /// the whole second of the first (an MCAP file's, a bag's, a CSV time column's); 0 for a log
    /// timed from its start and for integer CSV stamps beyond 2⁵³, which are counted from the
    /// first row's (see `docs/recordings.md`). Known once the first sample is read; reports add
    /// it back.
    pub fn time_origin_s(&self) -> f64 {
        match &self.inner {
            Inner::Csv(r) => r.time_origin_s(),
            Inner::Ros2(r) => r.samples().time_origin_s(),
            Inner::Columns(r) => r.time_origin_s(),
        }
    }

    /// What the reader noticed so far (complete once the iterator is exhausted).
    pub fn diagnostics(&self) -> &ReadDiagnostics {
        match &self.inner {
            Inner::Csv(r) => r.diagnostics(),
            Inner::Ros2(r) => &r.samples().diagnostics,
            Inner::Columns(r) => r.diagnostics(),
        }
    }

    /// How the log was read where the reader decided something the user did not say, for
    /// `details.reading` in `report.json` (complete once the iterator is exhausted): messages
    /// dropped as exact copies of the one before (the `stamps` module), the unit a CSV time
    /// column was read in by its stamps' magnitude. `None` where it decided nothing.
    pub fn reading(&self) -> Option<calib_core::report::Reading> {
        let d = self.diagnostics();
        (d.duplicates_dropped > 0 || d.time_unit.is_some()).then(|| calib_core::report::Reading {
            duplicates_dropped: d.duplicates_dropped,
            time_unit: d.time_unit.clone(),
        })
    }

    /// The selected channels (indices into [`names`](Self::names)) of a sparse CSV log that had
    /// no reading in any row (complete once the iterator is exhausted): an entirely empty
    /// column. Aligned on, such a channel leaves no sample; [`select`](Self::select) the
    /// others to read them. Empty for other logs, whose readers leave out a channel without
    /// readings when they open the file.
    pub fn channels_without_readings(&self) -> Vec<usize> {
        self.csv_aligner
            .as_ref()
            .map_or_else(Vec::new, |(a, _)| a.without_readings())
    }

    /// How the channels were aligned on the first one's clock (complete once the iterator is
    /// exhausted); `None` for a CSV log whose rows hold every channel at one stamp.
    pub fn alignment(&self) -> Option<Alignment> {
        match &self.inner {
            Inner::Csv(r) => self.csv_aligner.as_ref().map(|(a, _)| {
                let names: Vec<String> = r.channels().iter().map(|c| c.name.clone()).collect();
                a.report(&names)
            }),
            Inner::Ros2(r) => Some(r.samples().alignment()),
            Inner::Columns(_) => None,
        }
    }

    /// The log's topics with their type, encoding, message count, rate and channels (those
    /// skipped too); empty for a CSV log.
    pub fn topics(&self) -> Vec<TopicInfo> {
        match &self.inner {
            Inner::Csv(_) | Inner::Columns(_) => Vec::new(),
            Inner::Ros2(r) => r.samples().topics(),
        }
    }

    /// What a columnar file holds (its format, then groups, variables, datasets or columns, a
    /// line each, and where the time was taken from), as `calib inspect` lists it; empty for the
    /// other formats, whose [`topics`](Self::topics) say it.
    pub fn structure(&self) -> Vec<String> {
        match &self.inner {
            Inner::Columns(r) => {
                let mut lines = vec![format!("{} file", r.format())];
                lines.extend(r.structure());
                lines
            }
            Inner::Csv(_) | Inner::Ros2(_) => Vec::new(),
        }
    }

    /// Notes for the user about parts of the log that were not read (topics of other schemas),
    /// but for the ROS 2 bookkeeping topics every recording carries
    /// ([`is_bookkeeping`](crate::is_bookkeeping): `/rosout`, `/tf`, …), which are expected.
    /// A log named by a URL adds its [`remote_note`](Self::remote_note).
    pub fn notes(&self) -> Vec<String> {
        let mut notes: Vec<String> = self.remote_note().into_iter().collect();
        let Inner::Ros2(r) = &self.inner else {
            return notes;
        };
        notes.extend(
            r.samples()
                .ignored_topics()
                .iter()
                .filter(|t| !crate::bookkeeping::is_bookkeeping(&t.topic))
                .map(|t| {
                    format!(
                        "topic `{}` ({}, {}) is not JointState, a std_msgs scalar or JSON and was \
                     skipped",
                        t.topic, t.schema, t.message_encoding
                    )
                }),
        );
        notes
    }

    /// What a description of the log (`calib inspect`, calib-py's `inspect`) warns of once it
    /// has been read: [`warnings`](Self::warnings), [`notes`](Self::notes) and the
    /// [`time_unit_hint`](Self::time_unit_hint), each naming `path`.
    pub fn inspect_warnings(&self, path: &Path) -> Vec<String> {
        let mut w = self.warnings(path);
        w.extend(self.notes());
        w.extend(
            self.time_unit_hint()
                .map(|hint| format!("{}: {hint}", path.display())),
        );
        w
    }

    /// Warnings the user must see once the log has been read: truncation, damaged chunks skipped,
    /// and samples dropped because a channel could not be aligned on the clock.
    pub fn warnings(&self, path: &Path) -> Vec<String> {
        let d = self.diagnostics();
        let mut w = self.bag_warnings.clone();
        if d.duplicates_dropped > 0 {
            let what = match &self.inner {
                Inner::Csv(_) => "row(s)",
                Inner::Ros2(_) => "message(s)",
                Inner::Columns(_) => "sample(s)",
            };
            w.push(format!(
                "{}: {} duplicated {what} dropped: each repeated the one before it exactly, \
                 stamp and readings (recorded twice: a recorder or bridge subscribed twice, a \
                 replayed segment)",
                path.display(),
                d.duplicates_dropped
            ));
        }
        if let Inner::Csv(r) = &self.inner
            && let Some(line) = r.sparse_from_line()
        {
            w.push(format!(
                "{}: rows leave a channel's cell empty from line {line} on: read from there as \
                 sparse rows, each channel a series of its own aligned on the first one's stamps",
                path.display()
            ));
        }
        if let Some(t) = &d.truncated {
            w.push(format!(
                "{}: the log ends early at byte {} (a crashed recording?): the {} messages before the break were used",
                path.display(),
                t.byte_offset,
                t.messages_read
            ));
        }
        if !d.damaged_chunks.is_empty() {
            let list: Vec<String> = d.damaged_chunks.iter().map(|c| c.to_string()).collect();
            w.push(format!(
                "{}: skipped {} damaged chunk(s) and their messages (the `skip_damaged` option): {}",
                path.display(),
                d.damaged_chunks.len(),
                list.join("; ")
            ));
        }
        if let Some(a) = self.alignment() {
            for c in &a.channels {
                if c.dropped > 0 {
                    w.push(format!(
                        "{}: {} of {} sample(s) of the clock `{}` were dropped because channel `{}` could not be aligned there (no sample of it within `max_gap = {:.6}` s on both sides, or before its first or after its last sample)",
                        path.display(),
                        c.dropped,
                        a.clock_samples,
                        a.clock,
                        c.channel,
                        c.max_gap_s
                    ));
                }
                if c.out_of_order > 0 {
                    w.push(format!(
                        "{}: {} sample(s) of channel `{}` were not used because their stamp did not increase",
                        path.display(),
                        c.out_of_order,
                        c.channel
                    ));
                }
            }
        }
        w
    }
}

impl LogReader {
    /// Appends samples to `batch` until it holds `max` or the log ends (a few more where channels
    /// are aligned and several complete at once). The samples read before an error stay in
    /// `batch`; the error ends the log. `batch` holds one reading per selected channel
    /// ([`channels`](Self::channels)).
    pub fn fill(&mut self, batch: &mut SampleBatch, max: usize) -> Result<(), Error> {
        match &mut self.inner {
            Inner::Ros2(r) => return r.fill(batch, max).map_err(|e| e.renamed(&self.renames)),
            Inner::Columns(r) => {
                r.fill(batch, max);
                return Ok(());
            }
            Inner::Csv(_) => {}
        }
        while batch.len() < max {
            match self.next_csv() {
                Some(Ok(s)) => batch.push(s.t, &s.values, s.session),
                Some(Err(e)) => return Err(e),
                None => break,
            }
        }
        Ok(())
    }

    /// The next sample of a CSV log, its selected columns aligned where the file is sparse.
    fn next_csv(&mut self) -> Option<Result<Sample, Error>> {
        let Inner::Csv(r) = &mut self.inner else {
            return None;
        };
        if self.csv_aligner.is_none() {
            let sample = r.next()?;
            let Some((columns, _)) = &self.selection else {
                return Some(sample);
            };
            match sample {
                Ok(s) if r.sparse_from_line().is_some() && !columns.is_empty() => {
                    // Sparse from this row on: it and the rows after it through the aligner.
                    let mut aligner = Aligner::new(columns.clone(), self.csv_align);
                    aligner.push((s.t * 1e9).round() as i64, s.t, &s.values, s.session);
                    self.csv_aligner = Some((aligner, false));
                }
                Ok(mut s) => {
                    s.values = columns.iter().map(|&i| s.values[i]).collect();
                    return Some(Ok(s));
                }
                Err(e) => return Some(Err(e)),
            }
        }
        let (aligner, ended) = self.csv_aligner.as_mut()?;
        loop {
            if let Some(s) = aligner.pop() {
                return Some(Ok(s));
            }
            if *ended {
                return None;
            }
            match r.next() {
                Some(Ok(s)) => aligner.push((s.t * 1e9).round() as i64, s.t, &s.values, s.session),
                Some(Err(e)) => {
                    *ended = true;
                    return Some(Err(e));
                }
                None => {
                    *ended = true;
                    aligner.finish();
                }
            }
        }
    }
}

impl Iterator for LogReader {
    type Item = Result<Sample, Error>;
    fn next(&mut self) -> Option<Self::Item> {
        if matches!(self.inner, Inner::Csv(_)) {
            return self.next_csv();
        }
        let mut one = std::mem::take(&mut self.one);
        let next = one.next(self.channels().len(), |batch| self.fill(batch, 1));
        self.one = one;
        next
    }
}

/// A writer of any supported log format; the output appears only on [`LogWriter::finish`].
pub enum LogWriter {
    /// CSV, readings in degrees.
    Csv(CsvWriter),
    /// MCAP, JointState on one topic, readings in radians (boxed: the MCAP writer is large).
    Mcap(Box<McapWriter>),
}

impl LogWriter {
    /// Creates a log at `path`, the format from its extension (`.csv` or `.mcap`).
    pub fn create(path: &Path, channels: &[Channel], with_session: bool) -> Result<Self, Error> {
        Ok(match LogFormat::for_output(path)? {
            LogFormat::Csv => LogWriter::Csv(CsvWriter::create(
                path,
                channels,
                AngleUnit::Deg,
                with_session,
            )?),
            LogFormat::Mcap => {
                LogWriter::Mcap(Box::new(McapWriter::create(path, channels, DEFAULT_TOPIC)?))
            }
            // `for_output` names no format calib cannot write.
            LogFormat::Rosbag | LogFormat::Ros1Bag | LogFormat::Columns(_) => {
                return Err(Error::UnknownFormat {
                    path: path.to_path_buf(),
                });
            }
        })
    }
    /// Writes one sample.
    pub fn write(&mut self, sample: &Sample) -> Result<(), Error> {
        match self {
            LogWriter::Csv(w) => w.write(sample),
            LogWriter::Mcap(w) => w.write(sample),
        }
    }
    /// Completes the file and moves it into place.
    pub fn finish(self) -> Result<(), Error> {
        match self {
            LogWriter::Csv(w) => w.finish(),
            LogWriter::Mcap(w) => w.finish(),
        }
    }
}
