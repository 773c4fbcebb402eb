//! All-or-nothing output files.
//!
//! The interface promises that "a failed run leaves no half-written table behind". An
//! [`AtomicFile`] writes into a temporary file in the target's own directory (so the final rename
//! never crosses a file system) and only [`AtomicFile::commit`] puts it in place: flush, `fsync`,
//! rename. Dropping it uncommitted — an error, a panic elsewhere, an early return — removes the
//! temporary file and leaves whatever was at the target untouched.

use crate::Error;
use std::fs::File;
use std::io::{self, BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use tempfile::NamedTempFile;

/// A buffered file that appears at its path only when committed.
///
/// It is [`Write`] + [`Seek`], so any encoder can write through it (the CSV and table writers
/// here; the MCAP writer, which seeks back to patch its summary offsets).
///
/// ```
/// use calib_io::atomic::AtomicFile;
/// use std::io::Write;
/// let dir = tempfile::tempdir()?;
/// let path = dir.path().join("out.csv");
/// let mut f = AtomicFile::create(&path)?;
/// writeln!(f, "hello")?;
/// assert!(!path.exists()); // nothing at the target until the commit
/// f.commit()?;
/// assert_eq!(std::fs::read_to_string(&path)?, "hello\n");
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct AtomicFile {
    target: PathBuf,
    inner: BufWriter<NamedTempFile>,
}

impl AtomicFile {
    /// Starts writing `target`: creates a hidden temporary file beside it.
    ///
    /// Fails (naming `target`) when its directory does not exist or is not writable.
    pub fn create(target: &Path) -> Result<Self, Error> {
        let io_err = |source| Error::Io {
            path: target.to_path_buf(),
            source,
        };
        let temp = temp_file_beside(target).map_err(io_err)?;
        Ok(AtomicFile {
            target: target.to_path_buf(),
            // Large enough that writing a million-row log is not dominated by system calls.
            inner: BufWriter::with_capacity(1 << 16, temp),
        })
    }

    /// The path the file will have once committed.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Flushes, syncs to disk and renames the file into place, replacing any file there.
    pub fn commit(self) -> Result<(), Error> {
        let target = self.target;
        let io_err = |source| Error::Io {
            path: target.clone(),
            source,
        };
        let temp = self
            .inner
            .into_inner()
            .map_err(|e| io_err(e.into_error()))?;
        // Sync before the rename: otherwise a crash can leave the new name pointing at an empty
        // or partial file on file systems that reorder metadata and data writes.
        temp.as_file().sync_all().map_err(io_err)?;
        temp.persist(&target).map_err(|e| io_err(e.error))?;
        sync_parent_dir(&target);
        Ok(())
    }
}

/// Makes the rename itself durable. Best effort: some file systems refuse to sync a directory,
/// and the output is complete and in place either way, so a failure here is not an error.
#[cfg(unix)]
fn sync_parent_dir(target: &Path) {
    let dir = match target.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
}

/// Directories cannot be opened as files on this platform; the rename is all there is.
#[cfg(not(unix))]
fn sync_parent_dir(_target: &Path) {}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.inner.write(buf)
    }
    fn write_all(&mut self, buf: &[u8]) -> io::Result<()> {
        self.inner.write_all(buf)
    }
    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }
}

impl Seek for AtomicFile {
    fn seek(&mut self, pos: SeekFrom) -> io::Result<u64> {
        self.inner.seek(pos)
    }
}

/// A hidden temporary file in `target`'s directory (`.name.XXXX.tmp`), readable as an ordinary
/// output once renamed: a `NamedTempFile` is private (0600) by default, so ask for 0666 and let
/// the user's umask decide, as for any other file they create.
pub(crate) fn temp_file_beside(target: &Path) -> io::Result<NamedTempFile> {
    let dir = match target.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let name = target
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let prefix = format!(".{name}.");
    let mut builder = tempfile::Builder::new();
    builder.prefix(&prefix).suffix(".tmp");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    builder.tempfile_in(dir)
}

/// Several outputs that appear together or not at all: each is written in full to a temporary
/// file first, and only when all are written are they renamed into place. A run that fails
/// while writing (a full disk, a folder in the way) leaves none of them behind.
#[derive(Debug, Default)]
pub struct OutputSet {
    files: Vec<AtomicFile>,
}

impl OutputSet {
    /// An empty set.
    pub fn new() -> Self {
        Self::default()
    }
    /// Writes `bytes` for `path` to a temporary file.
    pub fn add(&mut self, path: &Path, bytes: &[u8]) -> Result<(), Error> {
        let mut file = AtomicFile::create(path)?;
        file.write_all(bytes).map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })?;
        self.files.push(file);
        Ok(())
    }
    /// Renames every file into place. A target that is a folder fails the whole set before any
    /// rename; should a rename still fail, the files already renamed are removed again.
    pub fn commit(self) -> Result<(), Error> {
        if let Some(f) = self.files.iter().find(|f| f.target().is_dir()) {
            return Err(Error::Write {
                path: f.target().to_path_buf(),
                message:
                    "a folder of that name is in the way; remove it or choose another output folder"
                        .into(),
            });
        }
        let mut done: Vec<PathBuf> = Vec::new();
        for file in self.files {
            let target = file.target().to_path_buf();
            if let Err(e) = file.commit() {
                for path in &done {
                    let _ = std::fs::remove_file(path);
                }
                return Err(e);
            }
            done.push(target);
        }
        Ok(())
    }
}

/// Writes `bytes` to `path` atomically: the file appears only when complete.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), Error> {
    let mut file = AtomicFile::create(path)?;
    file.write_all(bytes).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })?;
    file.commit()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entries(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn dropping_uncommitted_leaves_the_old_file_and_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.csv");
        std::fs::write(&path, "old").unwrap();
        {
            let mut f = AtomicFile::create(&path).unwrap();
            f.write_all(b"new, half-written").unwrap();
            f.flush().unwrap();
            assert_eq!(entries(dir.path()).len(), 2);
        }
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "old");
        assert_eq!(entries(dir.path()), ["t.csv"]);
    }

    #[test]
    fn commit_replaces_and_seek_works() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.bin");
        std::fs::write(&path, "old").unwrap();
        let mut f = AtomicFile::create(&path).unwrap();
        f.write_all(b"abcdef").unwrap();
        f.seek(SeekFrom::Start(1)).unwrap();
        f.write_all(b"X").unwrap();
        assert_eq!(f.target(), path);
        f.commit().unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "aXcdef");
        assert_eq!(entries(dir.path()), ["t.bin"]);
    }

    #[test]
    fn a_missing_directory_is_an_error_naming_the_target() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("no/such/dir/t.csv");
        let err = AtomicFile::create(&path).unwrap_err();
        assert!(err.to_string().contains("no/such/dir/t.csv"), "{err}");
    }
}
