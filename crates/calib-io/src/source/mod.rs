//! Where a log's bytes come from: a local file, a memory buffer or, with the `remote` feature,
//! an object store (`s3://`, `gs://`, `az://`, `http(s)://`), behind one [`ByteSource`]: a
//! length and reads of a byte range.
//!
//! The readers take their bytes from a source, not a path, so a log in a bucket is read as a
//! local one is, without a local copy where the format allows it:
//! - **MCAP** is read at the ranges it needs: the magic, the footer and summary, then (from an
//!   object store) only the chunks its chunk index lists for the topics calib reads, each in one
//!   request (see [`crate::mcap_log`]).
//! - **CSV** is streamed front to back.
//! - **The other formats** (rosbag2's SQLite, ROS 1 bags, the columnar files) need a file:
//!   a remote log of these is copied to a temporary file first, at most
//!   [`ReadOptions::max_copy_bytes`](crate::ReadOptions::max_copy_bytes) bytes
//!   ([`DEFAULT_MAX_COPY_BYTES`] by default), removed when the reader is dropped.
//!
//! # Names
//! A log is named by a path; a path whose text starts with a URL scheme calib reads
//! ([`url_of`]) is a URL, never a relative path (a local file literally named `s3:` is not a
//! concern). Errors name the URL as they name a path.

#[cfg(feature = "remote")]
mod remote;

use std::fmt;
use std::fs::File;
use std::io::{self, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use crate::Error;

/// A log's bytes: its length, and reads at any offset, from any thread.
pub trait ByteSource: Send + Sync + fmt::Debug {
    /// The length in bytes.
    fn len(&self) -> u64;

    /// Whether it holds no byte.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Fills `buf` with the bytes from `offset` on; an error of kind `UnexpectedEof` if fewer
    /// are left.
    fn read_exact_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()>;

    /// Reads from `offset` into `buf` for a reader going front to back (a [`SourceCursor`]):
    /// the bytes read, at least one unless the source ends at `offset`. An object store fetches
    /// a block ahead here, where a chunk's [`read_exact_at`](Self::read_exact_at) fetches
    /// exactly its range.
    fn read_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<usize> {
        let left = self.len().saturating_sub(offset);
        let n = buf.len().min(usize::try_from(left).unwrap_or(usize::MAX));
        self.read_exact_at(offset, &mut buf[..n])?;
        Ok(n)
    }

    /// The ranges (offset, length), in file order, that a reader is about to read with
    /// [`read_exact_at`](Self::read_exact_at): an object store may then fetch several that lie
    /// close together in one request. The default ignores it.
    fn plan(&self, ranges: &[(u64, u64)]) {
        let _ = ranges;
    }

    /// Whether reads are requests to another machine: readers then ask for few, large ranges
    /// (MCAP reads only its indexed chunks), where a local file is read front to back.
    fn is_remote(&self) -> bool {
        false
    }

    /// Bytes read from it so far, and the reads that fetched them.
    fn fetched(&self) -> Fetched;
}

/// Bytes a [`ByteSource`] has read so far, and in how many reads (requests, for an object
/// store).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct Fetched {
    /// Bytes read.
    pub bytes: u64,
    /// Reads (HTTP requests for an object store, `pread` calls for a file).
    pub requests: u64,
}

/// Counts a source's reads.
#[derive(Debug, Default)]
struct Counter {
    bytes: AtomicU64,
    requests: AtomicU64,
}

impl Counter {
    fn add(&self, bytes: usize) {
        self.bytes.fetch_add(bytes as u64, Ordering::Relaxed);
        self.requests.fetch_add(1, Ordering::Relaxed);
    }
    fn get(&self) -> Fetched {
        Fetched {
            bytes: self.bytes.load(Ordering::Relaxed),
            requests: self.requests.load(Ordering::Relaxed),
        }
    }
}

/// A local file.
#[derive(Debug)]
pub struct FileSource {
    file: File,
    len: u64,
    counter: Counter,
}

impl FileSource {
    /// Opens the file at `path`.
    pub fn open(path: &Path) -> io::Result<Self> {
        Self::new(File::open(path)?)
    }

    /// An open file (its length as it is now).
    pub fn new(file: File) -> io::Result<Self> {
        let len = file.metadata()?.len();
        Ok(FileSource {
            file,
            len,
            counter: Counter::default(),
        })
    }
}

impl ByteSource for FileSource {
    fn len(&self) -> u64 {
        self.len
    }

    #[cfg(unix)]
    fn read_exact_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
        use std::os::unix::fs::FileExt;
        self.counter.add(buf.len());
        self.file.read_exact_at(buf, offset)
    }

    #[cfg(windows)]
    fn read_exact_at(&self, mut offset: u64, mut buf: &mut [u8]) -> io::Result<()> {
        use std::os::windows::fs::FileExt;
        self.counter.add(buf.len());
        while !buf.is_empty() {
            match self.file.seek_read(buf, offset) {
                Ok(0) => return Err(io::ErrorKind::UnexpectedEof.into()),
                Ok(n) => {
                    buf = &mut buf[n..];
                    offset += n as u64;
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
        Ok(())
    }

    fn fetched(&self) -> Fetched {
        self.counter.get()
    }
}

/// Bytes in memory (a Python file object read whole, a test's log).
#[derive(Debug)]
pub struct MemorySource {
    bytes: Vec<u8>,
    counter: Counter,
}

impl MemorySource {
    /// The source of `bytes`.
    pub fn new(bytes: Vec<u8>) -> Self {
        MemorySource {
            bytes,
            counter: Counter::default(),
        }
    }
}

impl ByteSource for MemorySource {
    fn len(&self) -> u64 {
        self.bytes.len() as u64
    }

    fn read_exact_at(&self, offset: u64, buf: &mut [u8]) -> io::Result<()> {
        let from = usize::try_from(offset).unwrap_or(usize::MAX);
        let bytes = from
            .checked_add(buf.len())
            .and_then(|end| self.bytes.get(from..end))
            .ok_or(io::ErrorKind::UnexpectedEof)?;
        self.counter.add(buf.len());
        buf.copy_from_slice(bytes);
        Ok(())
    }

    fn fetched(&self) -> Fetched {
        self.counter.get()
    }
}

/// A [`ByteSource`] read as a file is: [`Read`] and [`Seek`] from a position of its own. Clones
/// share the source and keep their own position.
#[derive(Debug, Clone)]
pub struct SourceCursor {
    source: Arc<dyn ByteSource>,
    pos: u64,
}

impl SourceCursor {
    /// A cursor at the start of `source`.
    pub fn new(source: Arc<dyn ByteSource>) -> Self {
        SourceCursor { source, pos: 0 }
    }

    /// The source it reads.
    pub fn source(&self) -> &Arc<dyn ByteSource> {
        &self.source
    }
}

impl Read for SourceCursor {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if buf.is_empty() || self.pos >= self.source.len() {
            return Ok(0);
        }
        let n = self.source.read_at(self.pos, buf)?;
        self.pos += n as u64;
        Ok(n)
    }
}

impl Seek for SourceCursor {
    fn seek(&mut self, to: SeekFrom) -> io::Result<u64> {
        let pos = match to {
            SeekFrom::Start(p) => Some(p),
            SeekFrom::End(d) => self.source.len().checked_add_signed(d),
            SeekFrom::Current(d) => self.pos.checked_add_signed(d),
        };
        self.pos = pos
            .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "seek before the start"))?;
        Ok(self.pos)
    }
}

/// The URL schemes calib reads logs from (with the `remote` feature).
pub const URL_SCHEMES: &[&str] = &["s3", "s3a", "gs", "az", "abfs", "abfss", "http", "https"];

/// The URL `path` is, if its text starts with one of [`URL_SCHEMES`] and `://` (any case).
pub fn url_of(path: &Path) -> Option<&str> {
    let text = path.to_str()?;
    let (scheme, rest) = text.split_once("://")?;
    (URL_SCHEMES.iter().any(|s| s.eq_ignore_ascii_case(scheme)) && !rest.is_empty()).then_some(text)
}

/// Whether this build reads URLs (the `remote` feature).
pub const REMOTE: bool = cfg!(feature = "remote");

/// Options of an object store, as `object_store` names them (`aws_endpoint`,
/// `aws_access_key_id`, `aws_region`, `aws_allow_http`, `google_service_account`,
/// `azure_storage_account_name`, …), over what the environment gives.
pub type StorageOptions = Vec<(String, String)>;

/// The default of [`ReadOptions::max_copy_bytes`](crate::ReadOptions::max_copy_bytes): 2 GB.
pub const DEFAULT_MAX_COPY_BYTES: u64 = 2_000_000_000;

/// Opens the object at `url` (credentials from the environment as the clouds' own tools take
/// them, then `options`): its length is known once it is open, so a missing object, a bucket
/// that does not exist or refused credentials are errors here, naming the URL and what to do.
pub fn open_url(url: &str, options: &StorageOptions) -> Result<Arc<dyn ByteSource>, Error> {
    #[cfg(feature = "remote")]
    {
        remote::ObjectSource::open(url, options).map(|s| Arc::new(s) as Arc<dyn ByteSource>)
    }
    #[cfg(not(feature = "remote"))]
    {
        let _ = options;
        Err(Error::Data {
            path: PathBuf::from(url),
            message: "this calib was built without reading URLs (the `remote` feature of \
                      calib-io); install it with the README's install command, or download \
                      the log and name the local file"
                .into(),
        })
    }
}

/// A log's bytes and its name: a local file, or an object at a URL.
pub(crate) fn open(path: &Path, options: &StorageOptions) -> Result<Arc<dyn ByteSource>, Error> {
    match url_of(path) {
        Some(url) => open_url(url, options),
        None => FileSource::open(path)
            .map(|s| Arc::new(s) as Arc<dyn ByteSource>)
            .map_err(|source| Error::Io {
                path: path.to_path_buf(),
                source,
            }),
    }
}

/// A temporary local copy of a source, for the formats that need a file (rosbag2's SQLite,
/// ROS 1 bags, the columnar formats); removed when dropped.
pub(crate) struct LocalCopy {
    /// Holds the copy; removed with it.
    _dir: tempfile::TempDir,
    /// The copy, named as the log is (its extension decides the format as the original's would).
    pub(crate) path: PathBuf,
}

/// Copies `source` (named `name`, a URL) to a temporary file, if it is at most `max` bytes;
/// else an error saying the size and the option that raises it.
pub(crate) fn local_copy(
    name: &Path,
    source: &Arc<dyn ByteSource>,
    max: u64,
) -> Result<LocalCopy, Error> {
    let len = source.len();
    if len > max {
        return Err(Error::Data {
            path: name.to_path_buf(),
            message: format!(
                "this log is {len} bytes; calib reads this format from a local file, and copies \
                 a remote one first only up to {max} bytes (raise it with the `max_copy_bytes` \
                 option), or download it and name the local file"
            ),
        });
    }
    let io = |source| Error::Io {
        path: name.to_path_buf(),
        source,
    };
    let dir = tempfile::Builder::new()
        .prefix("calib-remote-")
        .tempdir()
        .map_err(io)?;
    let file_name = name
        .to_str()
        .and_then(|t| t.rsplit('/').next())
        .filter(|n| !n.is_empty())
        .unwrap_or("log");
    let path = dir.path().join(file_name);
    let mut out = File::create(&path).map_err(io)?;
    // Large reads: one request per 8 MiB.
    let mut cursor = SourceCursor::new(Arc::clone(source));
    let mut buf = vec![0u8; 8 << 20];
    loop {
        let n = cursor.read(&mut buf).map_err(io)?;
        if n == 0 {
            break;
        }
        io::Write::write_all(&mut out, &buf[..n]).map_err(io)?;
    }
    Ok(LocalCopy { _dir: dir, path })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn urls_are_told_from_paths() {
        for url in [
            "s3://fleet/r1/run.mcap",
            "gs://b/run.csv",
            "az://c/run.mcap",
            "HTTPS://example.org/run.mcap",
            "http://127.0.0.1:9000/b/run.mcap",
        ] {
            assert_eq!(url_of(Path::new(url)), Some(url), "{url}");
        }
        for path in [
            "run.mcap",
            "s3:/run.mcap",
            "./s3/run.mcap",
            "ftp://x/run.mcap",
            "s3://",
        ] {
            assert_eq!(url_of(Path::new(path)), None, "{path}");
        }
    }

    #[test]
    fn a_cursor_reads_and_seeks_as_a_file_does() {
        let source: Arc<dyn ByteSource> = Arc::new(MemorySource::new((0u8..100).collect()));
        let mut cursor = SourceCursor::new(Arc::clone(&source));
        let mut buf = [0u8; 8];
        assert_eq!(cursor.read(&mut buf).unwrap(), 8);
        assert_eq!(buf, [0, 1, 2, 3, 4, 5, 6, 7]);
        cursor.seek(SeekFrom::End(-3)).unwrap();
        assert_eq!(cursor.read(&mut buf).unwrap(), 3);
        assert_eq!(&buf[..3], &[97, 98, 99]);
        assert_eq!(cursor.read(&mut buf).unwrap(), 0);
        assert!(cursor.seek(SeekFrom::Current(-200)).is_err());
        assert_eq!(
            source.fetched(),
            Fetched {
                bytes: 11,
                requests: 2
            }
        );
        let err = source.read_exact_at(95, &mut buf).unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::UnexpectedEof);
    }
}
