//! rosbag2 bags: what `ros2 bag record` writes.
//!
//! A bag is a directory holding `metadata.yaml` and one or more storage files split by size or
//! duration (`my_bag_0.db3`, `my_bag_1.db3`, …), listed in order by the metadata's
//! `relative_file_paths`. ROS 2 Humble records to SQLite (`storage_identifier: sqlite3`, the
//! default until Iron); later releases to MCAP.
//!
//! # SQLite storage
//! Each `.db3` file holds the tables `topics(id, name, type, serialization_format,
//! offered_qos_profiles)` and `messages(id, topic_id, timestamp, data)`; `data` is the CDR
//! payload with its 4-byte encapsulation header, `timestamp` the receive time in nanoseconds.
//! Humble stores no message definitions, so a topic is recognised by its type name:
//! `sensor_msgs/msg/JointState`, `control_msgs/msg/DynamicJointState` and the `std_msgs` scalars (`Float64`, `Float32`, `Int64`,
//! `Int32`, `UInt32`, `UInt16`) are read as in an MCAP file (see [`crate::mcap_log`]): each row
//! becomes the MCAP message it stands for and goes to the ROS 2 layer the MCAP reader hands its
//! messages to (`calib_io::ros2`, private), which decodes it and names and aligns the channels
//! (the joint name where unique, else `TOPIC/JOINT`; channels on several topics aligned on the
//! first selected one's stamps). Topics of other types are listed by [`BagReader::topics`] and
//! skipped.
//!
//! Messages are read in `timestamp` order within a file, file after file in the metadata's order
//! (rosbag2 splits a recording in time, so this is the recording's order). A background thread
//! streams the rows through a bounded channel, so memory stays bounded whatever the bag's size.
//!
//! # MCAP storage
//! A bag directory of MCAP storage is read by the MCAP reader: one `.mcap` file as it is,
//! several splits merged in order into one temporary file first ([`prepare`]).
//!
//! # Compression
//! `ros2 bag record --compression-format zstd` compresses either each split whole
//! (`compression_mode: FILE`: `bag_0.db3.zstd`, `bag_0.mcap.zstd`), which [`prepare`]
//! decompresses into a temporary folder, or each message's payload (`MESSAGE`, SQLite storage),
//! which is decompressed as it is read.

use std::borrow::Cow;
use std::collections::HashMap;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};

use calib_core::{AngleUnit, Channel, SampleBatch};
use rusqlite::{Connection, OpenFlags};
use rustc_hash::FxHashMap;

use crate::align::{AlignOptions, Alignment};
use crate::mcap_log::JOINT_STATE_SCHEMA;
use crate::naming::ChannelName;
use crate::progress::ReadProgress;
use crate::ros2::PEEK_WINDOW;
use crate::ros2::encoding::Encoding;
use crate::ros2::registry::{IgnoredTopic, Registry, Resolved, TopicInfo, too_many_topics};
use crate::ros2::samples::{Failure, Ros2Reader, Samples};
use crate::ros2::topic::TopicStats;
use crate::{Error, ReadDiagnostics, ReadOptions};

/// The first 16 bytes of every SQLite 3 database file.
pub const SQLITE_MAGIC: &[u8; 16] = b"SQLite format 3\0";

/// The metadata file of a bag directory.
pub const METADATA: &str = "metadata.yaml";

/// Rows handed over at once from the thread reading the bag to the reader: enough that the
/// hand-over costs nothing per row.
const ROWS_PER_BLOCK: usize = 512;
/// Payload bytes after which a block is handed over with fewer rows, so that large messages
/// keep it small.
const BLOCK_BYTES: usize = 1 << 20;
/// Blocks in flight between the two threads: enough to keep both busy, few enough that memory
/// stays small.
const BLOCKS_IN_FLIGHT: usize = 4;

/// The storage files of a bag, in reading order.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Storage {
    /// SQLite `.db3` files.
    Sqlite3(Vec<PathBuf>),
    /// MCAP files.
    Mcap(Vec<PathBuf>),
}

/// How a bag is compressed (`compression_format` and `compression_mode` of its metadata).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Compression {
    /// Not compressed.
    #[default]
    None,
    /// `zstd`, `FILE`: each split file compressed whole (`bag_0.db3.zstd`).
    File,
    /// `zstd`, `MESSAGE`: each message's payload compressed on its own.
    Message,
}

/// A bag's storage and what the user should know about how it was found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BagFiles {
    /// The storage files, as the bag holds them (compressed, in file mode).
    pub storage: Storage,
    /// How the bag is compressed.
    pub compression: Compression,
    /// Warnings (a missing `metadata.yaml`).
    pub warnings: Vec<String>,
}

/// A bag ready to read: splits compressed whole are decompressed, and MCAP splits merged into
/// one file, in a temporary folder that lives as long as this.
#[derive(Debug)]
pub struct PreparedBag {
    /// `.db3` files to read in order, or the one MCAP file.
    pub storage: PreparedStorage,
    /// Each message's payload is zstd-compressed (`compression_mode: MESSAGE`).
    pub compressed_messages: bool,
    /// Warnings (a missing `metadata.yaml`).
    pub warnings: Vec<String>,
    /// The files of the temporary folder and what messages call them: the split each was
    /// decompressed or copied from, or the bag for the merged file (the temporary paths are gone
    /// once calib exits).
    pub renames: Vec<(PathBuf, PathBuf)>,
    /// The folder of decompressed or merged files, removed when dropped (and on SIGINT/SIGTERM,
    /// or by a later run if this one is killed).
    pub temp: Option<crate::atomic::TempFolder>,
}

/// What [`PreparedBag`] reads.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum PreparedStorage {
    /// SQLite `.db3` files, in order.
    Sqlite3(Vec<PathBuf>),
    /// One MCAP file (the bag's only split, or its splits merged in order).
    Mcap(PathBuf),
}

/// Whether `dir` is a bag directory: it holds `metadata.yaml` or `.db3` files.
pub fn is_bag_dir(dir: &Path) -> bool {
    dir.is_dir() && (dir.join(METADATA).is_file() || !files_with(dir, "db3").is_empty())
}

fn bag_error(
    path: &Path,
    table: Option<&str>,
    message_id: Option<i64>,
    topic: Option<&str>,
    message: String,
) -> Error {
    Error::Bag {
        path: path.to_path_buf(),
        table: table.map(str::to_string),
        message_id,
        topic: topic.map(str::to_string),
        message,
    }
}

/// The files of `dir` with this extension, ordered by their split index (the number after the
/// last `_`: `bag_10.db3` after `bag_9.db3`), then by name.
fn files_with(dir: &Path, ext: &str) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut files: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && p.extension().is_some_and(|e| e.eq_ignore_ascii_case(ext)))
        .collect();
    let split_index = |p: &PathBuf| {
        p.file_stem()
            .and_then(|s| s.to_str())
            .and_then(|s| s.rsplit('_').next())
            .and_then(|n| n.parse::<u64>().ok())
    };
    files.sort_by(|a, b| (split_index(a), a).cmp(&(split_index(b), b)));
    files
}

/// The storage files of the bag at `path`: a `.db3` file itself, or a bag directory's files in
/// the order its `metadata.yaml` lists them (without one, the `.db3` or `.mcap` files found, with
/// a warning).
pub fn bag_files(path: &Path) -> Result<BagFiles, Error> {
    if !path.is_dir() {
        return Ok(BagFiles {
            storage: Storage::Sqlite3(vec![path.to_path_buf()]),
            compression: Compression::None,
            warnings: Vec::new(),
        });
    }
    let metadata = path.join(METADATA);
    let mut compression = Compression::None;
    let (storage_id, files, warnings) = if metadata.is_file() {
        let text = std::fs::read_to_string(&metadata).map_err(|source| Error::Io {
            path: metadata.clone(),
            source,
        })?;
        let parsed =
            parse_metadata(&text).map_err(|m| bag_error(&metadata, None, None, None, m))?;
        compression = parsed.compression;
        let (storage_id, relative) = (parsed.storage, parsed.files);
        let mut files = Vec::with_capacity(relative.len());
        for (k, rel) in relative.iter().enumerate() {
            let outside = Path::new(rel).components().any(|c| {
                !matches!(
                    c,
                    std::path::Component::Normal(_) | std::path::Component::CurDir
                )
            });
            if outside {
                return Err(bag_error(
                    &metadata,
                    None,
                    None,
                    None,
                    format!(
                        "relative_file_paths entry {} names `{}`, a path outside the bag \
                         directory; rosbag2 lists its splits by their names inside it: fix the \
                         entry, or remove it from {METADATA} to read the other splits",
                        k + 1,
                        rel
                    ),
                ));
            }
            let file = locate_split(path, rel).ok_or_else(|| {
                bag_error(
                    &metadata,
                    None,
                    None,
                    None,
                    format!(
                        "relative_file_paths entry {} names the split `{}`, which is not in \
                         the bag directory {}; copy the whole bag directory, or remove the \
                         entry from {METADATA} to read the other splits",
                        k + 1,
                        rel,
                        path.display()
                    ),
                )
            })?;
            files.push(file);
        }
        (storage_id, files, Vec::new())
    } else {
        let db3 = files_with(path, "db3");
        let (storage_id, files) = if db3.is_empty() {
            ("mcap".to_string(), files_with(path, "mcap"))
        } else {
            ("sqlite3".to_string(), db3)
        };
        if files.is_empty() {
            return Err(bag_error(
                path,
                None,
                None,
                None,
                format!(
                    "the directory holds neither {METADATA} nor .db3 or .mcap files; give a \
                     rosbag2 bag directory, or the log file itself"
                ),
            ));
        }
        let names: Vec<String> = files
            .iter()
            .map(|f| {
                f.file_name()
                    .unwrap_or_default()
                    .to_string_lossy()
                    .into_owned()
            })
            .collect();
        let warning = format!(
            "{}: the bag has no {METADATA}; reading the {} {} file(s) found, in the order of \
             their split number: {}",
            path.display(),
            files.len(),
            if storage_id == "mcap" {
                ".mcap"
            } else {
                ".db3"
            },
            names.join(", ")
        );
        (storage_id, files, vec![warning])
    };
    let storage = match storage_id.as_str() {
        "sqlite3" => Storage::Sqlite3(files),
        "mcap" if compression == Compression::Message => {
            return Err(bag_error(
                &metadata,
                None,
                None,
                None,
                "the bag is MCAP storage with each message zstd-compressed (compression_mode: \
                 MESSAGE), which calib does not read; convert it with `ros2 bag convert` to \
                 an uncompressed or file-compressed bag"
                    .into(),
            ));
        }
        "mcap" => Storage::Mcap(files),
        other => {
            return Err(bag_error(
                &metadata,
                None,
                None,
                None,
                format!(
                    "storage_identifier `{other}` is not one calib reads (sqlite3, mcap); \
                     convert the bag with `ros2 bag convert`"
                ),
            ));
        }
    };
    Ok(BagFiles {
        storage,
        compression,
        warnings,
    })
}

/// The bag at `path` ready to read (see [`PreparedBag`]): its files found by [`bag_files`],
/// splits compressed whole (`.zstd`) decompressed and several MCAP splits merged, in order,
/// into one file, in a temporary folder. The whole recording is then on disk uncompressed:
/// SQLite reads a database from a file, and the MCAP reader reads one file.
pub fn prepare(path: &Path) -> Result<PreparedBag, Error> {
    prepare_with(path, false)
}

/// [`prepare`], leaving out the damaged chunks of MCAP splits where `skip_damaged` (as
/// [`ReadOptions::skip_damaged`] does for one file) and listing them in the warnings.
pub fn prepare_with(path: &Path, skip_damaged: bool) -> Result<PreparedBag, Error> {
    let found = bag_files(path)?;
    let mut warnings = found.warnings.clone();
    let renames = std::cell::RefCell::new(Vec::new());
    let mut temp = None;
    // The temporary folder, made when a file (`for_file`) first needs it (`why`).
    let mut folder = |for_file: &Path, why: &str| -> Result<PathBuf, Error> {
        if temp.is_none() {
            temp = Some(
                crate::atomic::TempFolder::create("bag")
                    .map_err(|e| no_temporary_folder(for_file, why, &e))?,
            );
        }
        Ok(temp
            .as_ref()
            .map_or_else(PathBuf::new, |t| t.path().to_path_buf()))
    };
    let mut unpack = |files: Vec<PathBuf>| -> Result<Vec<PathBuf>, Error> {
        if found.compression != Compression::File {
            return Ok(files);
        }
        files
            .iter()
            .map(|split| {
                let dir = folder(split, "to decompress the split (compression_mode: FILE)")?;
                let out = decompress(split, &dir)?;
                renames.borrow_mut().push((out.clone(), split.clone()));
                Ok(out)
            })
            .collect()
    };
    let storage = match found.storage {
        Storage::Sqlite3(files) => {
            let mut files = unpack(files)?;
            // A WAL-mode split whose log beside it holds data: read from a copy of both, so
            // that nothing is written beside the recording (SQLite would add its `-shm` file,
            // and cannot open it at all in a read-only folder).
            for file in &mut files {
                if is_wal(file) && has_wal_log(file) {
                    let why = format!(
                        "to read it with its write-ahead log ({}: transactions not yet in the \
                         file) from a copy of both, as SQLite cannot read them in place without \
                         writing beside them",
                        wal_log(file)
                            .file_name()
                            .unwrap_or_default()
                            .to_string_lossy()
                    );
                    let copy = copy_with_wal(file, &folder(file, &why)?, &why)?;
                    renames.borrow_mut().push((copy.clone(), file.clone()));
                    *file = copy;
                }
            }
            PreparedStorage::Sqlite3(files)
        }
        Storage::Mcap(originals) => {
            let files = unpack(originals.clone())?;
            match <[PathBuf; 1]>::try_from(files) {
                Ok([file]) => PreparedStorage::Mcap(file),
                Err(files) => {
                    let name = path.file_name().unwrap_or_default().to_string_lossy();
                    let merged = folder(path, "to merge its MCAP splits into one file")?
                        .join(format!("{name}.merged.mcap"));
                    let splits: Vec<(&Path, &Path)> = files
                        .iter()
                        .zip(&originals)
                        .map(|(f, o)| (f.as_path(), o.as_path()))
                        .collect();
                    warnings.extend(merge_mcap(&splits, &merged, skip_damaged)?);
                    renames
                        .borrow_mut()
                        .push((merged.clone(), path.to_path_buf()));
                    PreparedStorage::Mcap(merged)
                }
            }
        }
    };
    Ok(PreparedBag {
        storage,
        compressed_messages: found.compression == Compression::Message,
        warnings,
        renames: renames.into_inner(),
        temp,
    })
}

/// The error of a bag whose file `file` must be copied or decompressed (`why`) into a temporary
/// folder that cannot be made (`e`): calib writes nothing beside a recording, so the remedy is
/// another temporary folder, or a copy of the bag where it can be read in place.
fn no_temporary_folder(file: &Path, why: &str, e: &std::io::Error) -> Error {
    // The reason alone: the error's own text names the folder's random name, never made.
    let reason = e.raw_os_error().map_or_else(
        || e.kind().to_string(),
        |code| std::io::Error::from_raw_os_error(code).to_string(),
    );
    bag_error(
        file,
        None,
        None,
        None,
        format!(
            "cannot create a temporary folder in {} ({reason}), needed {why}; set TMPDIR to a folder \
             you can write with room for the bag, or copy the bag to such a folder and read it \
             there",
            std::env::temp_dir().display()
        ),
    )
}

/// Decompresses the zstd-compressed split `split` (`bag_0.db3.zstd`) into `dir` under its name
/// without `.zstd`; the new file's path.
fn decompress(split: &Path, dir: &Path) -> Result<PathBuf, Error> {
    let name = split.file_name().unwrap_or_default().to_string_lossy();
    let name = name.strip_suffix(".zstd").unwrap_or(&name);
    let out = dir.join(name);
    let io = |source| Error::Io {
        path: split.to_path_buf(),
        source,
    };
    let input = std::fs::File::open(split).map_err(io)?;
    let compressed = input.metadata().map_err(io)?.len();
    let fail = |message: String| bag_error(split, None, None, None, message);
    let undecodable = |e: std::io::Error| {
        fail(format!(
            "cannot decompress the split ({e}); the bag's metadata says its files are \
             zstd-compressed (compression_mode: FILE): the file is damaged or not zstd"
        ))
    };
    let mut decoder = zstd::stream::read::Decoder::new(input).map_err(undecodable)?;
    // What the split must start with once decompressed: checked before anything is written, so
    // that a small damaged or foreign file writes nothing.
    let magic: &[u8] = if name.ends_with(".mcap") {
        mcap::MAGIC
    } else {
        SQLITE_MAGIC
    };
    let mut head = vec![0u8; magic.len()];
    decoder.read_exact(&mut head).map_err(undecodable)?;
    if head != magic {
        return Err(fail(format!(
            "the split decompresses to something that is not {} (it starts with {}); the file \
             is damaged or not part of this bag",
            if magic == mcap::MAGIC {
                "MCAP"
            } else {
                "SQLite"
            },
            crate::limits::shown_bytes(&head)
        )));
    }
    let limit = crate::limits::decompressed_limit(compressed);
    let mut output =
        std::io::BufWriter::new(std::fs::File::create(&out).map_err(|source| Error::Io {
            path: out.clone(),
            source,
        })?);
    output.write_all(&head).map_err(|source| Error::Io {
        path: out.clone(),
        source,
    })?;
    // Bounded while decompressing: one byte past the limit is enough to refuse the split.
    let written = std::io::copy(&mut (&mut decoder).take(limit), &mut output).map_err(|e| {
        // Reading a zstd stream never fills a disk: that is the copy being written.
        if is_disk_full(&e) {
            let written = std::fs::metadata(&out).map_or(0, |m| m.len());
            copy_failed(
                split,
                dir,
                &format!("more than the {} written", bytes(written)),
                "to decompress the split (compression_mode: FILE)",
                &e,
            )
        } else {
            undecodable(e)
        }
    })? + head.len() as u64;
    if written >= limit {
        return Err(fail(format!(
            "the split decompresses to more than {limit} bytes, {}× its {compressed} bytes \
             (more than a recording compresses); the file is damaged",
            crate::limits::MAX_DECOMPRESSION_RATIO
        )));
    }
    output.flush().map_err(|source| Error::Io {
        path: out.clone(),
        source,
    })?;
    Ok(out)
}

/// Writes the messages of the MCAP splits `files`, split after split, each in its order, to
/// the MCAP file `out`: the bag as one recording. Channels of equal topic, message encoding and
/// schema share one channel.
///
/// Each split is `(file, name)`: the file read (a decompressed copy in the temporary folder, or
/// the split itself) and the split as the bag holds it, which errors and warnings name (a
/// temporary copy is gone once calib exits). The last split cut short (a crashed recording)
/// gives the messages before the cut, as one file alone does, with a warning; with
/// `skip_damaged`, damaged chunks are left out and listed in a warning. Returns the warnings.
fn merge_mcap(
    files: &[(&Path, &Path)],
    out: &Path,
    skip_damaged: bool,
) -> Result<Vec<String>, Error> {
    use crate::mcap_log::records;
    use mcap::sans_io::LinearReaderOptions;
    let write_error = |e: mcap::McapError| Error::Write {
        path: out.to_path_buf(),
        message: format!("cannot write the merged MCAP file: {e}"),
    };
    let file = std::fs::File::create(out).map_err(|source| Error::Io {
        path: out.to_path_buf(),
        source,
    })?;
    let mut writer = mcap::WriteOptions::new()
        .compression(None)
        .create(std::io::BufWriter::new(file))
        .map_err(write_error)?;
    let mut channels: HashMap<(String, String, String), u16> = HashMap::new();
    let mut warnings = Vec::new();
    for (k, &(split, name)) in files.iter().enumerate() {
        let io = |source| Error::Io {
            path: name.to_path_buf(),
            source,
        };
        let input = std::fs::File::open(split).map_err(io)?;
        let len = input.metadata().map_err(io)?.len();
        let options = LinearReaderOptions::default()
            .with_skip_end_magic(true)
            .with_record_length_limit(crate::limits::mcap_record_limit(len));
        let mut stream =
            records::Stream::new(std::io::BufReader::new(input), options, skip_damaged);
        let last = k + 1 == files.len();
        for (index, message) in stream.by_ref().enumerate() {
            let index = index as u64;
            let message = match message {
                Ok(message) => message,
                Err(records::StreamError::Mcap(mcap::McapError::UnexpectedEof)) if last => {
                    warnings.push(format!(
                        "{}: the last split ends early (a crashed recording?): the {index} \
                         messages before the break were used",
                        name.display()
                    ));
                    break;
                }
                Err(e) => {
                    return Err(Error::Mcap {
                        path: name.to_path_buf(),
                        message_index: Some(index),
                        channel: None,
                        message: format!(
                            "the split is damaged here ({e}); {}recover it with `mcap \
                             recover`, or remove it from {METADATA} to read the other splits",
                            if matches!(e, records::StreamError::Damaged(_)) {
                                "run with the `skip_damaged` option to leave the damaged chunk out, "
                            } else {
                                ""
                            }
                        ),
                    });
                }
            };
            let c = &message.channel;
            let schema = c.schema.as_ref();
            let key = (
                c.topic.clone(),
                c.message_encoding.clone(),
                schema.map_or_else(String::new, |s| s.name.clone()),
            );
            let id = match channels.get(&key) {
                Some(&id) => id,
                None => {
                    let schema_id = match schema {
                        Some(s) => writer
                            .add_schema(&s.name, &s.encoding, &s.data)
                            .map_err(write_error)?,
                        None => 0,
                    };
                    let id = writer
                        .add_channel(schema_id, &c.topic, &c.message_encoding, &c.metadata)
                        .map_err(write_error)?;
                    channels.insert(key, id);
                    id
                }
            };
            let header = mcap::records::MessageHeader {
                channel_id: id,
                sequence: message.sequence,
                log_time: message.log_time,
                publish_time: message.publish_time,
            };
            writer
                .write_to_known_channel(&header, &message.data)
                .map_err(write_error)?;
        }
        if !stream.damaged().is_empty() {
            let list: Vec<String> = stream.damaged().iter().map(|c| c.to_string()).collect();
            warnings.push(format!(
                "{}: skipped {} damaged chunk(s) and their messages (the `skip_damaged` option): {}",
                name.display(),
                list.len(),
                list.join("; ")
            ));
        }
    }
    writer.finish().map_err(write_error)?;
    Ok(warnings)
}

/// A split named by the metadata, relative to the bag directory. Bags from ROS 2 Foxy and
/// earlier list it with the bag directory's name in front, which no longer resolves once the
/// bag is moved: then the file name alone is tried.
fn locate_split(dir: &Path, relative: &str) -> Option<PathBuf> {
    let direct = dir.join(relative);
    if direct.is_file() {
        return Some(direct);
    }
    let bare = dir.join(Path::new(relative).file_name()?);
    bare.is_file().then_some(bare)
}

/// What calib needs from a bag's `metadata.yaml`.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Metadata {
    /// `storage_identifier` (default `sqlite3`).
    storage: String,
    /// `relative_file_paths`.
    files: Vec<String>,
    /// `compression_format` and `compression_mode`.
    compression: Compression,
}

/// `storage_identifier`, `relative_file_paths`, `compression_format` and `compression_mode`
/// of a bag's `metadata.yaml`.
///
/// Parsed by hand rather than with a YAML crate: calib needs two keys of a file rosbag2 writes
/// in one fixed layout (block style, one scalar per line, a `- ` list), and a YAML dependency
/// would be larger than this function. Flow-style lists (`[a, b]`) and quoted scalars are
/// accepted too, as hand edits produce them.
fn parse_metadata(text: &str) -> Result<Metadata, String> {
    let scalar = |v: &str| {
        let v = v.trim();
        let v = v
            .strip_prefix('"')
            .and_then(|v| v.strip_suffix('"'))
            .or_else(|| v.strip_prefix('\'').and_then(|v| v.strip_suffix('\'')))
            .unwrap_or(v);
        v.to_string()
    };
    if !text.contains("rosbag2_bagfile_information:") {
        return Err(format!(
            "not a rosbag2 {METADATA} (no `rosbag2_bagfile_information` key); give the bag \
             directory `ros2 bag record` wrote"
        ));
    }
    let mut storage = None;
    let mut files: Option<Vec<String>> = None;
    let (mut format, mut mode) = (String::new(), String::new());
    let mut lines = text.lines().peekable();
    while let Some(line) = lines.next() {
        let key_indent = line.len() - line.trim_start().len();
        let trimmed = line.trim();
        if storage.is_none()
            && let Some(v) = trimmed.strip_prefix("storage_identifier:")
        {
            storage = Some(scalar(v));
        } else if let Some(v) = trimmed.strip_prefix("compression_format:") {
            format = scalar(v);
        } else if let Some(v) = trimmed.strip_prefix("compression_mode:") {
            mode = scalar(v);
        } else if files.is_none()
            && let Some(v) = trimmed.strip_prefix("relative_file_paths:")
        {
            let v = v.trim();
            if let Some(flow) = v.strip_prefix('[').and_then(|v| v.strip_suffix(']')) {
                files = Some(
                    flow.split(',')
                        .map(scalar)
                        .filter(|s| !s.is_empty())
                        .collect(),
                );
                continue;
            }
            let mut list = Vec::new();
            while let Some(next) = lines.peek() {
                let indent = next.len() - next.trim_start().len();
                match next.trim().strip_prefix('-') {
                    Some(item) if indent >= key_indent => {
                        list.push(scalar(item));
                        lines.next();
                    }
                    _ => break,
                }
            }
            files = Some(list);
        }
    }
    let files = files.filter(|f| !f.is_empty()).ok_or_else(|| {
        format!("no `relative_file_paths` list of storage files; the {METADATA} is incomplete")
    })?;
    let compression = match (format.as_str(), mode.to_ascii_uppercase().as_str()) {
        (_, "" | "NONE") | ("", _) => Compression::None,
        ("zstd", "FILE") => Compression::File,
        ("zstd", "MESSAGE") => Compression::Message,
        (format, mode) => {
            return Err(format!(
                "the bag is compressed with `{format}` ({mode}); calib reads zstd (FILE or \
                 MESSAGE): decompress it with `ros2 bag convert`"
            ));
        }
    };
    Ok(Metadata {
        storage: storage.unwrap_or_else(|| "sqlite3".into()),
        files,
        compression,
    })
}

/// One row of a `messages` table, its topic resolved to the reader's.
struct Row<'a> {
    /// Index of the `.db3` file.
    file: usize,
    id: i64,
    /// Index into [`BagReader::topic_channels`].
    topic: usize,
    timestamp: i64,
    data: &'a [u8],
}

/// Rows read one after the other, handed from the thread reading the bag to the reader in one
/// piece and handed back to be filled again: their keys, and their payloads end to end.
#[derive(Default)]
struct RowBlock {
    /// Per row: file, id, topic and timestamp as in [`Row`], and where its payload ends.
    keys: Vec<(usize, i64, usize, i64, usize)>,
    data: Vec<u8>,
}

impl RowBlock {
    fn len(&self) -> usize {
        self.keys.len()
    }

    fn push(&mut self, row: &Row) {
        self.data.extend_from_slice(row.data);
        self.keys
            .push((row.file, row.id, row.topic, row.timestamp, self.data.len()));
    }

    /// Whether the block is ready to be handed over.
    fn is_full(&self) -> bool {
        self.keys.len() >= ROWS_PER_BLOCK || self.data.len() >= BLOCK_BYTES
    }

    fn clear(&mut self) {
        self.keys.clear();
        self.data.clear();
    }

    fn row(&self, i: usize) -> Row<'_> {
        let (file, id, topic, timestamp, end) = self.keys[i];
        let start = i.checked_sub(1).map_or(0, |p| self.keys[p].4);
        Row {
            file,
            id,
            topic,
            timestamp,
            data: &self.data[start..end],
        }
    }
}

/// The topics of each file to read: per file, the `topic_id`s and the reader's topic of each.
type Wanted = Vec<Vec<(i64, usize)>>;

/// Whether the SQLite file at `path` is in WAL mode (its header's read and write versions are
/// 2); a file that cannot be read is not.
fn is_wal(path: &Path) -> bool {
    let mut head = [0u8; 20];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok_and(|()| head.starts_with(SQLITE_MAGIC) && head[18] == 2 && head[19] == 2)
}

/// The write-ahead log beside a SQLite file (`bag_0.db3-wal`).
fn wal_log(path: &Path) -> PathBuf {
    let mut name = path.as_os_str().to_owned();
    name.push("-wal");
    PathBuf::from(name)
}

/// Whether the SQLite file at `path` has a non-empty write-ahead log beside it: transactions
/// not yet copied into the file (a recording that stopped without closing it).
fn has_wal_log(path: &Path) -> bool {
    std::fs::metadata(wal_log(path)).is_ok_and(|m| m.len() > 0)
}

/// Copies the WAL-mode split `split` and its write-ahead log into `dir` (`why`: what for); the
/// copy's path.
fn copy_with_wal(split: &Path, dir: &Path, why: &str) -> Result<PathBuf, Error> {
    let name = split.file_name().unwrap_or_default();
    let out = dir.join(name);
    let size = |p: &Path| std::fs::metadata(p).map_or(0, |m| m.len());
    let needed = size(split) + size(&wal_log(split));
    for (from, to) in [
        (split.to_path_buf(), out.clone()),
        (wal_log(split), wal_log(&out)),
    ] {
        std::fs::copy(&from, &to).map_err(|e| copy_failed(&from, dir, &bytes(needed), why, &e))?;
    }
    Ok(out)
}

/// Whether `e` says the disk (or the user's quota on it) is full.
fn is_disk_full(e: &std::io::Error) -> bool {
    matches!(
        e.kind(),
        std::io::ErrorKind::StorageFull | std::io::ErrorKind::QuotaExceeded
    )
}

/// `n` bytes, and in MB: "73400320 bytes (73.4 MB)".
fn bytes(n: u64) -> String {
    format!("{n} bytes ({:.1} MB)", n as f64 / 1e6)
}

/// The error of a copy of the bag's file `from` into the temporary folder `dir` (`needed`: how
/// much it takes, in words; `why`: what for) that failed with `e`. A full disk is named as such,
/// with the folder, the bytes and what to do: the generic I/O message named only `from`, which
/// is intact.
fn copy_failed(from: &Path, dir: &Path, needed: &str, why: &str, e: &std::io::Error) -> Error {
    let message = if is_disk_full(e) {
        format!(
            "cannot copy it into the temporary folder {}: the disk is full ({e}); the copy needs \
             {needed}, {why}. Set TMPDIR to a folder on a disk with that much room (e.g. \
             `TMPDIR=/mnt/big calib …`), or free space in {}; the partial copy was removed",
            dir.display(),
            std::env::temp_dir().display()
        )
    } else {
        format!(
            "cannot copy it into the temporary folder {} ({e}), {why}; set TMPDIR to a folder \
             you can write with room for {needed}",
            dir.display()
        )
    };
    bag_error(from, None, None, None, message)
}

/// A `file:` URI of `path` opening it immutable: SQLite then takes no lock and writes no `-shm`
/// or `-wal` file beside it, which a WAL-mode file otherwise needs even to be read.
fn immutable_uri(path: &Path) -> String {
    let mut uri = String::from("file:");
    for &b in path.as_os_str().as_encoded_bytes() {
        if b.is_ascii_alphanumeric() || b"/-_.~".contains(&b) {
            uri.push(char::from(b));
        } else {
            uri.push_str(&format!("%{b:02X}"));
        }
    }
    uri.push_str("?immutable=1");
    uri
}

/// Opens a `.db3` file read-only, writing nothing beside it: a WAL-mode file without a
/// write-ahead log to replay is opened immutable (one with one was copied by [`prepare`]).
fn open_db(path: &Path) -> Result<Connection, Error> {
    let flags = OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX;
    let opened = if is_wal(path) && !has_wal_log(path) {
        Connection::open_with_flags(immutable_uri(path), flags | OpenFlags::SQLITE_OPEN_URI)
    } else {
        Connection::open_with_flags(path, flags)
    };
    opened.map_err(|e| {
        bag_error(
            path,
            None,
            None,
            None,
            format!("cannot open as SQLite: {e}"),
        )
    })
}

/// Calls `f` on each message of the wanted topics, file after file, in `timestamp` order within
/// a file, until it returns `false`.
/// `compressed`: each payload is zstd-compressed (`compression_mode: MESSAGE`) and is
/// decompressed here.
fn scan(
    files: &[PathBuf],
    wanted: &Wanted,
    compressed: bool,
    mut f: impl FnMut(Row<'_>) -> bool,
) -> Result<(), Error> {
    for (k, (path, topics)) in files.iter().zip(wanted).enumerate() {
        if topics.is_empty() {
            continue;
        }
        // Looked up per row: FxHash, not SipHash (a twentieth of `calib inspect`'s CPU).
        let of_id: FxHashMap<i64, usize> = topics.iter().copied().collect();
        let ids: Vec<String> = topics.iter().map(|(id, _)| id.to_string()).collect();
        let fail = |e: rusqlite::Error| {
            bag_error(
                path,
                Some("messages"),
                None,
                None,
                format!("cannot read the messages: {e}; the file is damaged"),
            )
        };
        let db = open_db(path)?;
        let mut statement = db
            .prepare(&format!(
                "SELECT id, topic_id, timestamp, data FROM messages WHERE topic_id IN ({}) \
                 ORDER BY timestamp, id",
                ids.join(",")
            ))
            .map_err(fail)?;
        let mut rows = statement.query([]).map_err(fail)?;
        while let Some(row) = rows.next().map_err(fail)? {
            let id: i64 = row.get(0).map_err(fail)?;
            let topic_id: i64 = row.get(1).map_err(fail)?;
            let column = |e: rusqlite::Error| {
                bag_error(
                    path,
                    Some("messages"),
                    Some(id),
                    None,
                    format!("{e}; the row is damaged"),
                )
            };
            let timestamp: i64 = row.get(2).map_err(column)?;
            // The payload where SQLite holds it, copied only where it is not a blob (for
            // `get`'s error) or is decompressed.
            let owned: Vec<u8>;
            let mut data: &[u8] = match row.get_ref(3) {
                Ok(rusqlite::types::ValueRef::Blob(blob)) => blob,
                _ => {
                    owned = row.get(3).map_err(column)?;
                    &owned
                }
            };
            let decompressed: Vec<u8>;
            if compressed {
                decompressed = decompress_payload(data)
                    .map_err(|m| bag_error(path, Some("messages"), Some(id), None, m))?;
                data = &decompressed;
            }
            let Some(&topic) = of_id.get(&topic_id) else {
                continue;
            };
            if !f(Row {
                file: k,
                id,
                topic,
                timestamp,
                data,
            }) {
                return Ok(());
            }
        }
    }
    Ok(())
}

/// A zstd-compressed message payload (`compression_mode: MESSAGE`) decompressed, at most
/// [`MAX_PAYLOAD_BYTES`](crate::limits::MAX_PAYLOAD_BYTES): bounded while decompressing, so
/// that a small damaged payload cannot take gigabytes of memory.
fn decompress_payload(data: &[u8]) -> Result<Vec<u8>, String> {
    let limit = crate::limits::MAX_PAYLOAD_BYTES as u64;
    let mut out = Vec::new();
    zstd::stream::read::Decoder::new(data)
        .and_then(|decoder| decoder.take(limit + 1).read_to_end(&mut out))
        .map_err(|e| {
            format!(
                "the payload cannot be decompressed ({e}); the bag's metadata says each \
                 message is zstd-compressed (compression_mode: MESSAGE)"
            )
        })?;
    if out.len() as u64 > limit {
        return Err(format!(
            "the payload decompresses to more than {limit} bytes, more than any message calib \
             reads; the row is damaged"
        ));
    }
    Ok(out)
}

/// Reads a rosbag2 bag with SQLite storage as a stream of [`Sample`](calib_core::Sample)s (see the
/// [module docs](self)).
///
/// The iterator ends after the first error it yields.
pub struct BagReader {
    files: Vec<PathBuf>,
    wanted: Wanted,
    /// Each payload is zstd-compressed.
    compressed: bool,
    /// One MCAP channel per topic of the bag (by name), so that messages are decoded and
    /// registered exactly as the MCAP reader does.
    topic_channels: Vec<Arc<mcap::Channel<'static>>>,
    /// The channels, the selection and the samples in progress, shared with the MCAP reader.
    samples: Samples,
    rows: Option<Receiver<Result<RowBlock, Error>>>,
    /// Blocks decoded, handed back to the thread to be filled again.
    spent: Option<SyncSender<RowBlock>>,
    /// The block being decoded, and its next row.
    block: RowBlock,
    next_row: usize,
    /// Rows decoded so far, of those of the topics read.
    progress: ReadProgress,
    rows_done: u64,
    warnings: Vec<String>,
    done: bool,
    failed: bool,
}

/// The MCAP message a bag row stands for: log and publish time the row's `timestamp`.
fn message<'a>(channel: &Arc<mcap::Channel<'static>>, row: &Row<'a>) -> mcap::Message<'a> {
    let log_time = u64::try_from(row.timestamp).unwrap_or(0);
    mcap::Message {
        channel: Arc::clone(channel),
        sequence: 0,
        log_time,
        publish_time: log_time,
        data: Cow::Borrowed(row.data),
    }
}

impl BagReader {
    /// Opens a bag with SQLite storage: `files` are its `.db3` files in order (decompressed),
    /// `compressed` whether each payload is zstd-compressed, `warnings` what [`bag_files`]
    /// found to say.
    ///
    /// Errors if a file is not a rosbag2 SQLite file, no topic holds JointState or scalar
    /// messages, a topic has two types, or a topic's first message is bad.
    pub fn open(
        path: &Path,
        files: Vec<PathBuf>,
        compressed: bool,
        warnings: Vec<String>,
        opts: &ReadOptions,
    ) -> Result<Self, Error> {
        let mut topic_channels: Vec<Arc<mcap::Channel<'static>>> = Vec::new();
        let mut stats: Vec<TopicStats> = Vec::new();
        let mut wanted: Wanted = Vec::with_capacity(files.len());
        // The rows of the topics read, for the progress line.
        let mut rows_wanted = 0u64;
        // Each topic's index by name, and the file that listed it first.
        let mut by_name: HashMap<String, (usize, usize)> = HashMap::new();
        for (f, file) in files.iter().enumerate() {
            let db = open_db(file)?;
            check_tables(&db, file)?;
            let topics = read_topics(&db, file)?;
            let counts = read_counts(&db, file)?;
            let mut of_file = Vec::new();
            for (id, name, kind, format) in topics {
                let k = match by_name.get(&name).copied() {
                    Some((k, first_file)) => {
                        let c = &topic_channels[k];
                        let known = c.schema.as_ref().map_or("", |s| s.name.as_str());
                        if known != kind || c.message_encoding != format {
                            let where_else = if first_file == f {
                                "in another row of this file's `topics` table"
                            } else {
                                "in an earlier split"
                            };
                            return Err(bag_error(
                                file,
                                Some("topics"),
                                None,
                                Some(&name),
                                format!(
                                    "the topic is {kind} ({format}) here but {known} ({}) \
                                     {where_else}; calib cannot read one topic as two types",
                                    c.message_encoding
                                ),
                            ));
                        }
                        k
                    }
                    None => {
                        let id16 = u16::try_from(topic_channels.len()).map_err(|_| {
                            bag_error(
                                file,
                                Some("topics"),
                                None,
                                None,
                                "more than 65535 topics; calib reads bags of fewer".into(),
                            )
                        })?;
                        topic_channels.push(Arc::new(mcap::Channel {
                            id: id16,
                            topic: name.clone(),
                            schema: Some(Arc::new(mcap::Schema {
                                id: 1,
                                name: kind.clone(),
                                encoding: "ros2msg".into(),
                                data: Cow::Borrowed(&[]),
                            })),
                            message_encoding: format.clone(),
                            metadata: Default::default(),
                        }));
                        stats.push(TopicStats::default());
                        by_name.insert(name.clone(), (topic_channels.len() - 1, f));
                        topic_channels.len() - 1
                    }
                };
                if let Some(&(n, first, last)) = counts.get(&id) {
                    let s = &mut stats[k];
                    if s.messages == 0 {
                        s.first = first;
                    }
                    s.messages += n;
                    s.last = last;
                }
                if Encoding::from_names(&format, &kind).is_some() {
                    of_file.push((id, k));
                    rows_wanted += counts.get(&id).map_or(0, |c| c.0);
                }
            }
            wanted.push(of_file);
        }
        let mut registry = Registry::default();
        // Topics with messages calib does not read: listed with their counts, never streamed.
        for (channel, s) in topic_channels.iter().zip(&stats) {
            if s.messages > 0
                && let Ok(Resolved::Ignored(k)) = registry.resolve(channel)
            {
                registry.ignored_stats[k] = *s;
            }
        }
        let expected = topic_channels
            .iter()
            .zip(&stats)
            .filter(|(c, s)| s.messages > 0 && Encoding::of(c).is_some())
            .count();
        let scale = opts.unit.unwrap_or(AngleUnit::Deg).radians_per_unit();
        let mut failure = None;
        let mut after_all: Option<u64> = None;
        scan(&files, &wanted, compressed, |row| {
            let msg = message(&topic_channels[row.topic], &row);
            let fail = |m| {
                bag_error(
                    &files[row.file],
                    Some("messages"),
                    Some(row.id),
                    Some(&msg.channel.topic),
                    m,
                )
            };
            if let Err(m) = registry.learn(&msg, scale) {
                failure = Some(fail(m));
                return false;
            }
            if let Some(n) = &mut after_all {
                *n += 1;
            } else if registry.topics.len() == expected {
                after_all = Some(0);
            }
            // Go on until every topic has shown itself and PEEK_WINDOW messages more, or to
            // the end where a topic's messages carry different joint sets.
            after_all.is_none_or(|n| n < PEEK_WINDOW) || registry.topics.iter().any(|t| t.subset)
        })?;
        if let Some(e) = failure {
            return Err(e);
        }
        if registry.topics.is_empty() {
            let found: Vec<String> = registry
                .ignored
                .iter()
                .map(|t| format!("{} ({})", t.topic, t.schema))
                .collect();
            if found.is_empty() {
                return Err(Error::Empty {
                    path: path.to_path_buf(),
                });
            }
            return Err(bag_error(
                path,
                Some("topics"),
                None,
                None,
                format!(
                    "no topic holds {JOINT_STATE_SCHEMA} or std_msgs scalar messages (found: \
                     {}); record the encoders as JointState",
                    found.join(", ")
                ),
            ));
        }
        Ok(BagReader {
            files,
            wanted,
            compressed,
            topic_channels,
            samples: Samples::new(registry, opts, "message id"),
            rows: None,
            spent: None,
            block: RowBlock::default(),
            next_row: 0,
            progress: ReadProgress::messages(rows_wanted),
            rows_done: 0,
            warnings,
            done: false,
            failed: false,
        })
    }

    /// The selected channels, in the order of each sample's values.
    pub fn channels(&self) -> &[Channel] {
        self.samples.channels()
    }

    /// The names of every channel of the bag, in raw order: the indices
    /// [`select`](Self::select) takes.
    pub fn names(&self) -> &[ChannelName] {
        self.samples.names()
    }

    /// Reads only `channels` (indices into [`names`](Self::names)), in this order, aligned on
    /// the first one's stamps ([`crate::align`]). Call it before reading any sample.
    pub fn select(&mut self, channels: &[usize], opts: AlignOptions) {
        self.samples.select(channels, opts);
    }

    /// How the selected channels were aligned on the first one's clock (complete once
    /// iteration has ended).
    pub fn alignment(&self) -> Alignment {
        self.samples.alignment()
    }

    /// The stamp, s, from which the samples' times count: the whole second of the first
    /// message's stamp (see [`crate::LogReader::time_origin_s`]).
    pub fn time_origin_s(&self) -> f64 {
        self.samples.time_origin_s()
    }

    /// What the reader noticed so far.
    pub fn diagnostics(&self) -> &ReadDiagnostics {
        &self.samples.diagnostics
    }

    /// Warnings about how the bag was found (a missing `metadata.yaml`).
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// Topics skipped because calib does not read their type.
    pub fn ignored_topics(&self) -> &[IgnoredTopic] {
        self.samples.ignored_topics()
    }

    /// Every topic of the bag: those read with their channels, then those skipped. Counts and
    /// rates of the topics read are of the messages read so far; of those skipped, of the bag.
    pub fn topics(&self) -> Vec<TopicInfo> {
        self.samples.topics()
    }

    /// Starts the thread that streams the rows of the topics read, in blocks; the spent blocks
    /// go back to it through `spent`.
    fn start(&mut self) -> Receiver<Result<RowBlock, Error>> {
        let (tx, rx) = sync_channel(BLOCKS_IN_FLIGHT);
        let (spent, spent_rx) = sync_channel::<RowBlock>(BLOCKS_IN_FLIGHT + 2);
        self.spent = Some(spent);
        let (files, wanted, compressed) =
            (self.files.clone(), self.wanted.clone(), self.compressed);
        std::thread::spawn(move || {
            let mut block = RowBlock::default();
            let result = scan(&files, &wanted, compressed, |row| {
                block.push(&row);
                if !block.is_full() {
                    return true;
                }
                let mut next = spent_rx.try_recv().unwrap_or_default();
                next.clear();
                // A failed send means the reader was dropped: stop reading.
                tx.send(Ok(std::mem::replace(&mut block, next))).is_ok()
            });
            if block.len() > 0 {
                let _ = tx.send(Ok(block));
            }
            if let Err(e) = result {
                let _ = tx.send(Err(e));
            }
        });
        rx
    }

    /// Decodes one row, appending to `out` the samples it completes.
    fn step(&mut self, row: &Row, out: &mut SampleBatch) -> Result<(), Error> {
        let file = &self.files[row.file];
        let channel = &self.topic_channels[row.topic];
        let fail = |m: String| {
            bag_error(
                file,
                Some("messages"),
                Some(row.id),
                Some(&channel.topic),
                m,
            )
        };
        if row.timestamp < 0 {
            return Err(fail(format!(
                "the timestamp {} ns is before 1970; the recorder's clock is wrong",
                row.timestamp
            )));
        }
        self.samples
            .step(&message(channel, row), row.id, out)
            .map_err(|failure| {
                fail(match failure {
                    Failure::NewTopic => "this topic's first message was not met when the bag \
                                          was opened; the bag changed while it was read"
                        .into(),
                    Failure::Message {
                        joint: Some(joint),
                        message,
                    } => format!("joint `{joint}`: {message}"),
                    Failure::Message {
                        joint: None,
                        message,
                    } => message,
                })
            })
    }
}

impl Ros2Reader for BagReader {
    fn samples(&self) -> &Samples {
        &self.samples
    }

    fn samples_mut(&mut self) -> &mut Samples {
        &mut self.samples
    }

    fn progress(&self) -> ReadProgress {
        self.progress.clone()
    }

    fn fill(&mut self, out: &mut SampleBatch, max: usize) -> Result<(), Error> {
        while out.len() < max && !self.done && !self.failed {
            if self.next_row < self.block.len() {
                // The block is taken out while its rows are decoded (they borrow it).
                let block = std::mem::take(&mut self.block);
                let mut stepped = Ok(());
                let first = self.next_row;
                while self.next_row < block.len() && out.len() < max && stepped.is_ok() {
                    stepped = self.step(&block.row(self.next_row), out);
                    self.next_row += 1;
                }
                self.block = block;
                self.rows_done += (self.next_row - first) as u64;
                self.progress.set(self.rows_done);
                if let Err(e) = stepped {
                    self.failed = true;
                    return Err(e);
                }
                continue;
            }
            if self.rows.is_none() {
                self.rows = Some(self.start());
            }
            let received = self.rows.as_ref().map(Receiver::recv);
            match received {
                Some(Ok(Ok(block))) => {
                    let spent = std::mem::replace(&mut self.block, block);
                    if let Some(back) = &self.spent {
                        let _ = back.try_send(spent);
                    }
                    self.next_row = 0;
                }
                Some(Ok(Err(e))) => {
                    self.failed = true;
                    return Err(e);
                }
                // The thread has read every row.
                Some(Err(_)) | None => {
                    self.done = true;
                    self.samples.finish(out);
                }
            }
        }
        Ok(())
    }
}

/// Checks that the file is SQLite with rosbag2's `topics` and `messages` tables.
fn check_tables(db: &Connection, file: &Path) -> Result<(), Error> {
    let tables: Result<Vec<String>, rusqlite::Error> = db
        .prepare("SELECT name FROM sqlite_master WHERE type = 'table' ORDER BY name")
        .and_then(|mut s| s.query_map([], |r| r.get(0))?.collect());
    let tables = tables.map_err(|e| {
        bag_error(
            file,
            None,
            None,
            None,
            format!(
                "not a rosbag2 bag: SQLite cannot read it ({e}); give a bag directory or a \
                 .db3 file `ros2 bag record` wrote"
            ),
        )
    })?;
    for needed in ["topics", "messages"] {
        if !tables.iter().any(|t| t == needed) {
            return Err(bag_error(
                file,
                Some(needed),
                None,
                None,
                format!(
                    "not a rosbag2 bag: the SQLite file has no `{needed}` table (its tables: \
                     {}); give a .db3 file `ros2 bag record` wrote",
                    if tables.is_empty() {
                        "none".to_string()
                    } else {
                        tables.join(", ")
                    }
                ),
            ));
        }
    }
    Ok(())
}

/// `(id, name, type, serialization_format)` of each row of `topics`, by id.
fn read_topics(db: &Connection, file: &Path) -> Result<Vec<(i64, String, String, String)>, Error> {
    // One row past the limit is enough to refuse the file, before any message is read.
    let rows: Result<Vec<_>, rusqlite::Error> = db
        .prepare("SELECT id, name, type, serialization_format FROM topics ORDER BY id LIMIT ?1")
        .and_then(|mut s| {
            s.query_map([crate::limits::MAX_TOPICS as i64 + 1], |r| {
                Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?))
            })?
            .collect()
        });
    if rows
        .as_ref()
        .is_ok_and(|r: &Vec<_>| r.len() > crate::limits::MAX_TOPICS)
    {
        return Err(bag_error(
            file,
            Some("topics"),
            None,
            None,
            too_many_topics(),
        ));
    }
    rows.map_err(|e| {
        bag_error(
            file,
            Some("topics"),
            None,
            None,
            format!(
                "cannot read the topics ({e}); rosbag2's table has the columns id, name, \
                 type, serialization_format"
            ),
        )
    })
}

/// Messages, first and last timestamp of each `topic_id`: the table's rows in its own order,
/// counted here. (SQLite answers `GROUP BY topic_id` by sorting every row first, with no index
/// on the topic: 0.3 s of CPU on a 1 M-message bag, more than the ordered scan of the messages
/// that follows.)
fn read_counts(db: &Connection, file: &Path) -> Result<HashMap<i64, (u64, u64, u64)>, Error> {
    // Updated per row: FxHash, as in `scan`.
    let mut counts: FxHashMap<i64, (u64, i64, i64)> = FxHashMap::default();
    let rows = db
        .prepare("SELECT topic_id, timestamp FROM messages")
        .and_then(|mut s| {
            let mut rows = s.query([])?;
            while let Some(r) = rows.next()? {
                let (topic, t): (i64, i64) = (r.get(0)?, r.get(1)?);
                let (n, first, last) = counts.entry(topic).or_insert((0, t, t));
                *n += 1;
                *first = (*first).min(t);
                *last = (*last).max(t);
            }
            Ok(())
        });
    let ns = |v: i64| u64::try_from(v).unwrap_or(0);
    rows.map(|()| {
        counts
            .into_iter()
            .map(|(topic, (n, first, last))| (topic, (n, ns(first), ns(last))))
            .collect()
    })
    .map_err(|e| {
        bag_error(
            file,
            Some("messages"),
            None,
            None,
            format!(
                "cannot read the messages ({e}); rosbag2's table has the columns id, \
                 topic_id, timestamp, data"
            ),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn topic_counts_are_what_sqlite_groups() {
        // Rows out of time order, two topics, a negative stamp (read as 0, as before).
        let db = Connection::open_in_memory().unwrap();
        db.execute_batch(
            "CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL, \
             timestamp INTEGER NOT NULL, data BLOB NOT NULL);",
        )
        .unwrap();
        let rows = [(1, 50), (2, 7), (1, 20), (1, 90), (2, -3), (3, 4), (1, 60)];
        for (topic, t) in rows {
            db.execute(
                "INSERT INTO messages(topic_id, timestamp, data) VALUES (?1, ?2, x'00')",
                (topic, t),
            )
            .unwrap();
        }
        let counts = read_counts(&db, Path::new("bag_0.db3")).unwrap();
        let ns = |v: i64| u64::try_from(v).unwrap_or(0);
        let grouped: HashMap<i64, (u64, u64, u64)> = db
            .prepare(
                "SELECT topic_id, COUNT(*), MIN(timestamp), MAX(timestamp) FROM messages \
                 GROUP BY topic_id",
            )
            .unwrap()
            .query_map([], |r| {
                let (n, first, last): (i64, i64, i64) = (r.get(1)?, r.get(2)?, r.get(3)?);
                Ok((r.get(0)?, (ns(n), ns(first), ns(last))))
            })
            .unwrap()
            .collect::<Result<_, _>>()
            .unwrap();
        assert_eq!(counts, grouped);
        assert_eq!(counts[&1], (4, 20, 90));
        assert_eq!(counts[&2], (2, 0, 7));
    }

    #[test]
    fn a_full_disk_under_a_copy_is_named_with_the_folder_the_bytes_and_tmpdir() {
        // What std::fs::copy returns when the temporary folder's disk fills (ENOSPC, or EDQUOT
        // over a quota): no bounded folder is needed to check the message it becomes.
        let dir = tempfile::tempdir().unwrap();
        let split = dir.path().join("rec").join("rec_0.db3");
        let temp = dir.path().join("calib-bag-1234");
        for e in [
            std::io::Error::from(std::io::ErrorKind::StorageFull),
            std::io::Error::from(std::io::ErrorKind::QuotaExceeded),
        ] {
            let err = copy_failed(
                &split,
                &temp,
                &bytes(73_400_320),
                "to read it with its write-ahead log",
                &e,
            )
            .to_string();
            for part in [
                &split.display().to_string(),
                &format!(
                    "cannot copy it into the temporary folder {}",
                    temp.display()
                ),
                "the disk is full",
                "the copy needs 73400320 bytes (73.4 MB), to read it with its write-ahead log",
                "Set TMPDIR to a folder on a disk with that much room",
            ] {
                assert!(err.contains(part), "{part:?} not in {err}");
            }
        }
        // Another failure keeps its own reason, still naming the folder.
        let err = copy_failed(
            &split,
            &temp,
            &bytes(10),
            "to read it",
            &std::io::Error::from(std::io::ErrorKind::PermissionDenied),
        )
        .to_string();
        assert!(
            err.contains("permission denied") && err.contains("calib-bag-1234"),
            "{err}"
        );
        assert!(!err.contains("disk is full"), "{err}");
    }

    #[test]
    fn metadata_as_rosbag2_writes_it() {
        let text = "rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: sqlite3\n  \
                    duration:\n    nanoseconds: 100\n  relative_file_paths:\n    - run_0.db3\n    \
                    - run_1.db3\n  topics_with_message_count:\n    - topic_metadata:\n        \
                    name: /a\n";
        let m = parse_metadata(text).unwrap();
        assert_eq!(m.storage, "sqlite3");
        assert_eq!(m.files, ["run_0.db3", "run_1.db3"]);
        assert_eq!(m.compression, Compression::None);
        let text = "rosbag2_bagfile_information:\n  storage_identifier: 'mcap'\n  \
                    relative_file_paths: [\"a_0.mcap\", a_1.mcap]\n";
        let m = parse_metadata(text).unwrap();
        assert_eq!(m.storage, "mcap");
        assert_eq!(m.files, ["a_0.mcap", "a_1.mcap"]);
        let zstd = |mode: &str| {
            let text = format!(
                "rosbag2_bagfile_information:\n  relative_file_paths:\n  - x.db3.zstd\n  \
                 compression_format: zstd\n  compression_mode: {mode}\n"
            );
            parse_metadata(&text).map(|m| m.compression)
        };
        assert_eq!(zstd("FILE"), Ok(Compression::File));
        assert_eq!(zstd("MESSAGE"), Ok(Compression::Message));
        assert_eq!(zstd("\"\""), Ok(Compression::None));
        let text = "rosbag2_bagfile_information:\n  relative_file_paths: [a]\n  \
                    compression_format: lz4\n  compression_mode: FILE\n";
        assert!(parse_metadata(text).unwrap_err().contains("`lz4`"));
        // Lists at the key's own indentation are YAML too.
        let text = "rosbag2_bagfile_information:\n  relative_file_paths:\n  - x.db3\n  files:\n";
        assert_eq!(parse_metadata(text).unwrap().files, ["x.db3"]);
        assert!(parse_metadata("foo: 1\n").is_err());
        assert!(parse_metadata("rosbag2_bagfile_information:\n  version: 5\n").is_err());
    }
}
