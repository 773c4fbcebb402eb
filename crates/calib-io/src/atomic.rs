//! All-or-nothing output files and output folders.
//!
//! The interface promises that "a failed run leaves no half-written table behind". An
//! [`AtomicFile`] writes into a temporary file in the target's own directory (so the final rename
//! never crosses a file system) and only [`AtomicFile::commit`] puts it in place: flush, `fsync`,
//! rename. Dropping it uncommitted — an error, a panic elsewhere, an early return — removes the
//! temporary file and leaves whatever was at the target untouched.
//!
//! An [`OutputSet`] does the same for the files of a run that belong together (tables, reports,
//! plots): see its docs for the guarantee. Temporary files and folders are named
//! `.<name>.calib-<pid>@<host>.<random>.tmp` ([`owner`]): [`remove_stale`] removes those that
//! this host's runs left when they died, and [`remove_live_and_exit`] (called on SIGINT/SIGTERM)
//! those of this run. A folder's [`Manifest`] lists the files calib wrote there, the only ones a
//! run may replace without being told to.

use crate::Error;
use std::fs::File;
use std::io::{self, BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, OnceLock};
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
    /// The temporary file's path, registered in [`LIVE`] until committed or dropped.
    temp: PathBuf,
    /// `None` once committed.
    inner: Option<BufWriter<NamedTempFile>>,
    /// Bytes written since the disk was last asked to write the file out.
    unsynced: u64,
}

/// Bytes written after which the file's pages are handed to the disk while writing goes on (see
/// [`AtomicFile::start_write_out`]).
const WRITE_OUT: u64 = 16 << 20;

impl AtomicFile {
    /// Starts writing `target`: creates a hidden temporary file beside it.
    ///
    /// Fails (naming `target`) when its directory does not exist or is not writable.
    pub fn create(target: &Path) -> Result<Self, Error> {
        let io_err = |source| Error::Io {
            path: target.to_path_buf(),
            source,
        };
        let file =
            registered(|| temp_file_beside(target), |f| f.path().to_path_buf()).map_err(io_err)?;
        let temp = file.path().to_path_buf();
        Ok(AtomicFile {
            target: target.to_path_buf(),
            temp,
            // Large enough that writing a million-row log is not dominated by system calls.
            inner: Some(BufWriter::with_capacity(1 << 16, file)),
            unsynced: 0,
        })
    }

    /// Counts `n` bytes written; every [`WRITE_OUT`] bytes, starts writing what the file holds
    /// so far to disk without waiting for it, so that the `fsync` of [`commit`](Self::commit)
    /// waits only for the last part (a 450 MB MCAP copy waited about a second there for all of
    /// it). Linux only (`sync_file_range`); elsewhere the `fsync` writes everything.
    fn written(&mut self, n: usize) {
        self.unsynced += n as u64;
        if self.unsynced < WRITE_OUT {
            return;
        }
        self.unsynced = 0;
        #[cfg(target_os = "linux")]
        if let Some(w) = &self.inner {
            use std::os::fd::AsRawFd;
            let fd = w.get_ref().as_file().as_raw_fd();
            // SAFETY: `fd` is the open temporary file's; the call only starts the write-back of
            // its dirty pages (errors are the commit's `fsync`'s to report).
            unsafe { libc::sync_file_range(fd, 0, 0, libc::SYNC_FILE_RANGE_WRITE) };
        }
    }

    /// The path the file will have once committed.
    pub fn target(&self) -> &Path {
        &self.target
    }

    fn writer(&mut self) -> io::Result<&mut BufWriter<NamedTempFile>> {
        self.inner
            .as_mut()
            .ok_or_else(|| io::Error::other("the file was already committed"))
    }

    /// Flushes, syncs to disk and renames the file into place, replacing any file there.
    pub fn commit(mut self) -> Result<(), Error> {
        let target = self.target.clone();
        let io_err = |source| Error::Io {
            path: target.clone(),
            source,
        };
        let Some(inner) = self.inner.take() else {
            return Ok(());
        };
        let temp = inner.into_inner().map_err(|e| io_err(e.into_error()))?;
        // Sync before the rename: otherwise a crash can leave the new name pointing at an empty
        // or partial file on file systems that reorder metadata and data writes.
        temp.as_file().sync_all().map_err(io_err)?;
        fault_point();
        {
            // Under the lock: a signal's clean-up either runs before the rename (and removes the
            // temporary file) or after it (and finds it gone).
            let mut live = lock_live();
            temp.persist(&target).map_err(|e| io_err(e.error))?;
            live.retain(|p| *p != self.temp);
        }
        sync_parent_dir(&target);
        Ok(())
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if self.inner.take().is_some() {
            // The `NamedTempFile` just dropped removed the file.
            lock_live().retain(|p| *p != self.temp);
        }
    }
}

/// Makes a rename durable. Best effort: some file systems refuse to sync a directory, and the
/// output is complete and in place either way, so a failure here is not an error.
#[cfg(unix)]
fn sync_dir(dir: &Path) {
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
}

/// Directories cannot be opened as files on this platform; the rename is all there is.
#[cfg(not(unix))]
fn sync_dir(_dir: &Path) {}

fn sync_parent_dir(target: &Path) {
    sync_dir(parent_of(target));
}

/// The directory holding `path` (`.` for a bare name).
fn parent_of(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let n = self.writer()?.write(buf)?;
        self.written(n);
        Ok(n)
    }
    fn write_all(&mut self, buf: &[u8]) -> io::Result<()> {
        self.writer()?.write_all(buf)?;
        self.written(buf.len());
        Ok(())
    }
    fn flush(&mut self) -> io::Result<()> {
        self.writer()?.flush()
    }
}

impl Seek for AtomicFile {
    fn seek(&mut self, pos: SeekFrom) -> io::Result<u64> {
        self.writer()?.seek(pos)
    }
}

/// The infix of every temporary name calib makes: `.<name>.calib-<pid>@<host>.<random>.tmp`.
const TEMP_INFIX: &str = ".calib-";

/// The start of the temporary names for `name` made by this process.
fn temp_prefix(name: &str) -> String {
    format!(".{name}{TEMP_INFIX}{}.", owner())
}

/// Who makes this process's temporary names: `<pid>@<host>`, where `<host>` is the host's name
/// (letters, digits and `-`; anything else as `-`, at most 40 characters) and, on Linux, `+` and
/// the number of the PID namespace the pid belongs to. A temporary is removed as stale only by a
/// run whose `<host>` is the same — on this host, in this PID namespace, where "no process has
/// that pid" means its run is gone — never by a run on another host sharing the folder (NFS, a
/// CI cache), whose pids mean nothing here.
pub fn owner() -> &'static str {
    static OWNER: OnceLock<String> = OnceLock::new();
    OWNER.get_or_init(|| format!("{}@{}", std::process::id(), host_token()))
}

/// The `<host>` of [`owner`]: empty where the host's name is unknown (then no temporary is ever
/// taken for this host's).
fn host_token() -> String {
    let mut host: String = host_name()
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' {
                c
            } else {
                '-'
            }
        })
        .take(40)
        .collect();
    if host.is_empty() {
        return host;
    }
    if let Some(ns) = pid_namespace() {
        host.push('+');
        host.push_str(&ns.to_string());
    }
    host
}

/// The host's name (`gethostname`), empty if unknown.
#[cfg(unix)]
fn host_name() -> String {
    let mut buf = [0u8; 256];
    // SAFETY: the buffer is valid for its length; the name is NUL-terminated when it fits.
    let r = unsafe { libc::gethostname(buf.as_mut_ptr().cast(), buf.len()) };
    if r != 0 {
        return String::new();
    }
    let end = buf.iter().position(|&b| b == 0).unwrap_or(buf.len());
    String::from_utf8_lossy(&buf[..end]).into_owned()
}

/// The host's name, from the environment where the system gives none directly.
#[cfg(not(unix))]
fn host_name() -> String {
    std::env::var("COMPUTERNAME").unwrap_or_default()
}

/// The inode of this process's PID namespace (`/proc/self/ns/pid` → `pid:[4026531836]`).
fn pid_namespace() -> Option<u64> {
    let link = std::fs::read_link("/proc/self/ns/pid").ok()?;
    let link = link.to_str()?;
    link.strip_prefix("pid:[")?.strip_suffix(']')?.parse().ok()
}

/// A hidden temporary file in `target`'s directory (`.name.calib-<pid>@<host>.XXXXXX.tmp`),
/// readable as an ordinary output once renamed: a `NamedTempFile` is private (0600) by default,
/// so ask for 0666 and let the user's umask decide, as for any other file they create.
pub(crate) fn temp_file_beside(target: &Path) -> io::Result<NamedTempFile> {
    let name = target
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let prefix = temp_prefix(&name);
    let mut builder = tempfile::Builder::new();
    builder.prefix(&prefix).suffix(".tmp");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    builder.tempfile_in(parent_of(target))
}

/// A temporary folder of this run in the system's temporary directory (a bag's decompressed or
/// merged splits), named as calib's other temporaries (`.<name>.calib-<pid>@<host>.<random>.tmp`):
/// removed when dropped, by [`remove_live_and_exit`] on SIGINT/SIGTERM, and by [`remove_stale`]
/// of the temporary directory (which [`TempFolder::create`] runs first) once its run has died
/// without either.
#[derive(Debug)]
pub struct TempFolder {
    dir: tempfile::TempDir,
}

impl TempFolder {
    /// Creates one for `name`, after removing those of dead runs.
    pub fn create(name: &str) -> io::Result<Self> {
        let parent = std::env::temp_dir();
        remove_stale(&parent);
        let dir = registered(
            || {
                tempfile::Builder::new()
                    .prefix(&temp_prefix(name))
                    .suffix(".tmp")
                    .tempdir_in(&parent)
            },
            |d| d.path().to_path_buf(),
        )?;
        Ok(TempFolder { dir })
    }

    /// Its path.
    pub fn path(&self) -> &Path {
        self.dir.path()
    }
}

impl Drop for TempFolder {
    fn drop(&mut self) {
        // Removed under the lock, so that a signal's clean-up (which holds it while it removes
        // what is registered, then exits) finds the folder either registered or gone, never
        // half-removed and forgotten. The `TempDir` dropped after this finds nothing to remove.
        let mut live = lock_live();
        let _ = std::fs::remove_dir_all(self.dir.path());
        live.retain(|p| p != self.dir.path());
    }
}

/// The temporary files and folders of this run not yet renamed into place or removed.
static LIVE: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// A temporary made by `make`, its `path` registered in [`LIVE`] under the lock: a signal's
/// clean-up, which takes the lock, finds it registered or not yet made (made first and
/// registered after, a signal between the two left it behind).
fn registered<T>(
    make: impl FnOnce() -> io::Result<T>,
    path: impl FnOnce(&T) -> PathBuf,
) -> io::Result<T> {
    let mut live = lock_live();
    let made = make()?;
    live.push(path(&made));
    Ok(made)
}

fn lock_live() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    // A panic while holding the lock leaves the list itself intact.
    LIVE.lock().unwrap_or_else(|e| e.into_inner())
}

/// Removes this run's temporary files and folders and exits with `code`, holding the lock so
/// that no rename into place starts meanwhile: for a SIGINT/SIGTERM handler. A file being
/// renamed when the signal came is either in place (complete) or removed.
pub fn remove_live_and_exit(code: i32) -> ! {
    let live = lock_live();
    for path in live.iter() {
        if path.is_dir() {
            let _ = std::fs::remove_dir_all(path);
        } else {
            let _ = std::fs::remove_file(path);
        }
    }
    std::process::exit(code)
}

/// What [`remove_stale`] did in a folder.
#[derive(Debug, Default, PartialEq, Eq)]
pub struct Stale {
    /// Temporary files and staging folders removed: this host's, of runs that have died.
    pub removed: usize,
    /// Entries of calib's temporary naming that were kept although they may be stale, with why:
    /// a folder that does not hold what calib stages (only files), or a name without a host
    /// (made by an earlier calib, which cannot tell where it ran). The user decides.
    pub kept: Vec<(PathBuf, &'static str)>,
}

/// Removes, from `dir`, the temporary files and staging folders that runs of calib on this host
/// left when they died (killed before they could clean up), as far as it can prove them its own:
/// the name says which process on which host made it ([`owner`]), and it is removed only when
/// that host is this one and that process no longer exists. An entry of another host (a run
/// elsewhere sharing the folder) or of a live run (a concurrent run into the same folder) is
/// left alone; so is a folder that holds anything but plain files (calib stages only files
/// there: a folder holding a subfolder or a link is not calib's to remove), which is reported
/// in [`Stale::kept`] instead. Nothing is removed recursively.
pub fn remove_stale(dir: &Path) -> Stale {
    let mut stale = Stale::default();
    let Ok(entries) = std::fs::read_dir(dir) else {
        return stale;
    };
    let host = owner().split_once('@').map_or("", |o| o.1);
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let Some((pid, made_on)) = stale_owner(&name) else {
            continue;
        };
        let path = entry.path();
        let Some(made_on) = made_on else {
            if !alive(pid) {
                stale.kept.push((
                    path,
                    "made by an older calib, which did not record its host",
                ));
            }
            continue;
        };
        if host.is_empty() || made_on != host || pid == std::process::id() || alive(pid) {
            continue;
        }
        let removed = match entry.file_type() {
            Ok(t) if t.is_file() => std::fs::remove_file(&path).is_ok(),
            Ok(t) if t.is_dir() => match remove_staging_folder(&path) {
                Some(gone) => gone,
                None => {
                    stale
                        .kept
                        .push((path, "a folder holding more than calib's staged files"));
                    false
                }
            },
            _ => {
                stale.kept.push((path, "neither a file nor a folder"));
                false
            }
        };
        stale.removed += usize::from(removed);
    }
    stale
}

/// Removes `folder` if it has calib's staging layout — plain files only, no subfolder, no link —
/// file by file and then the empty folder: `Some(removed)`. `None` (and nothing removed) if it
/// holds anything else.
fn remove_staging_folder(folder: &Path) -> Option<bool> {
    let files: Vec<PathBuf> = std::fs::read_dir(folder)
        .ok()?
        .map(|e| {
            let e = e.ok()?;
            e.file_type().ok()?.is_file().then(|| e.path())
        })
        .collect::<Option<_>>()?;
    for file in &files {
        let _ = std::fs::remove_file(file);
    }
    Some(std::fs::remove_dir(folder).is_ok())
}

/// The process ID and host in a temporary name of calib's
/// (`.<name>.calib-<pid>@<host>.<random>.tmp`); the host is `None` in a name made by an earlier
/// calib (`.<name>.calib-<pid>.<random>.tmp`).
fn stale_owner(name: &str) -> Option<(u32, Option<&str>)> {
    if !name.starts_with('.') || !name.ends_with(".tmp") {
        return None;
    }
    let at = name.rfind(TEMP_INFIX)?;
    let rest = &name[at + TEMP_INFIX.len()..];
    let (owner, random) = rest.split_once('.')?;
    (random.len() > ".tmp".len()).then_some(())?;
    match owner.split_once('@') {
        Some((pid, host)) => Some((pid.parse().ok()?, Some(host))),
        None => Some((owner.parse().ok()?, None)),
    }
}

/// Whether process `pid` exists.
#[cfg(unix)]
fn alive(pid: u32) -> bool {
    let Ok(pid) = libc::pid_t::try_from(pid) else {
        return false;
    };
    // SAFETY: signal 0 only checks that the process exists and may be signalled.
    let r = unsafe { libc::kill(pid, 0) };
    r == 0 || io::Error::last_os_error().raw_os_error() == Some(libc::EPERM)
}

/// Without a way to ask, every owner is taken to be alive: nothing is removed.
#[cfg(not(unix))]
fn alive(_pid: u32) -> bool {
    true
}

/// The fault-injection hook of the tests: with `CALIB_TEST_KILL_AT=n` in the environment, the
/// process exits at once (no clean-up, as after SIGKILL) at the `n`-th step of writing outputs
/// (1-based), so that a test can stop a run at every step in turn instead of relying on timing.
fn fault_point() {
    static AT: OnceLock<Option<u64>> = OnceLock::new();
    static STEP: AtomicU64 = AtomicU64::new(0);
    let Some(at) = *AT.get_or_init(|| {
        std::env::var("CALIB_TEST_KILL_AT")
            .ok()
            .and_then(|v| v.parse().ok())
    }) else {
        return;
    };
    if STEP.fetch_add(1, Ordering::SeqCst) + 1 == at {
        std::process::exit(KILLED_EXIT);
    }
}

/// The exit status of a run stopped by the fault-injection hook.
pub const KILLED_EXIT: i32 = 86;

/// The file listing the files calib wrote into a folder, one name per line ([`Manifest`]).
pub const MANIFEST: &str = ".calib-manifest";

/// What a folder's [`MANIFEST`] lists: the files calib wrote there, and so the only files there
/// that a run replaces without `--force`.
///
/// One name per line. A plain name is a file of the set the last [`OutputSet`] into the folder
/// wrote (a method's tables and reports), which the next set replaces whole; a name after a `/`
/// (`/corrected.mcap`) is a file written alone ([`record_written`]: `calib apply -o`, `calib
/// export -o`, …), which a set leaves in place. No file name holds a `/`, so the two cannot be
/// confused, and readers that know only plain names skip the others.
#[derive(Debug, Default, Clone, PartialEq, Eq)]
pub struct Manifest {
    /// The files of the last set written into the folder.
    pub set: Vec<String>,
    /// The files written into the folder one at a time.
    pub alone: Vec<String>,
}

impl Manifest {
    /// `folder`'s manifest (empty if it has none or it cannot be read).
    pub fn read(folder: &Path) -> Self {
        let Ok(text) = std::fs::read_to_string(folder.join(MANIFEST)) else {
            return Self::default();
        };
        let name_ok = |l: &str| !l.is_empty() && !l.contains('/') && l != "." && l != "..";
        let mut manifest = Self::default();
        for line in text.lines() {
            match line.strip_prefix('/') {
                Some(alone) if name_ok(alone) => manifest.alone.push(alone.to_string()),
                Some(_) => {}
                None if name_ok(line) => manifest.set.push(line.to_string()),
                None => {}
            }
        }
        manifest
    }

    /// Whether it lists `name` (in the set or alone): a file calib wrote.
    pub fn lists(&self, name: &str) -> bool {
        self.set.iter().chain(&self.alone).any(|n| n == name)
    }

    /// Its text: the set's names, then the others after a `/`; a blank line when empty.
    fn render(&self) -> String {
        let mut text: String = self.set.iter().map(|f| format!("{f}\n")).collect();
        text.extend(self.alone.iter().map(|f| format!("/{f}\n")));
        if text.is_empty() {
            text.push('\n');
        }
        text
    }
}

/// Adds `path`, a file just written alone (not as part of an [`OutputSet`]), to its folder's
/// [`Manifest`], so that a later run may replace it as calib's own. The manifest is replaced
/// atomically; a name it already lists is left where it is. Two such writes into one folder at
/// the same instant may keep only one of the names: the other file then needs `--force` to be
/// replaced, never more.
pub fn record_written(path: &Path) -> Result<(), Error> {
    let Some(name) = path.file_name().map(|n| n.to_string_lossy().into_owned()) else {
        return Ok(());
    };
    let folder = parent_of(path);
    let mut manifest = Manifest::read(folder);
    if manifest.lists(&name) {
        return Ok(());
    }
    manifest.alone.push(name);
    write_atomic(&folder.join(MANIFEST), manifest.render().as_bytes())
}

/// Several outputs that appear together or not at all.
///
/// The files are grouped by folder. Each folder's files are written in full into a staging
/// folder beside it (`.<folder>.calib-<pid>.<random>.tmp`), with a [`MANIFEST`] listing them,
/// and synced; then the staging folder takes the folder's place in one step:
/// - a folder that does not exist yet is created by renaming the staging folder;
/// - a folder that holds only a previous run's outputs (every entry listed in its manifest) or
///   nothing is swapped with the staging folder by one `renameat2(RENAME_EXCHANGE)` on Linux,
///   and the previous run's files are removed after the swap. Elsewhere (or on a file system
///   without the exchange) the old folder is renamed aside and the new one renamed in: for an
///   instant there is no folder, never a mixed one.
///
/// So after a run, killed or not, the folder holds exactly one run's files. A folder holding
/// other files too (`-o .` beside the logs) cannot be swapped without moving them, nor can a
/// folder whose parent is not writable or is another file system (a mount point), nor the
/// working directory: there the files are staged inside it and renamed in one by one, then the previous run's files not written this time are
/// removed, and the manifest is renamed in last, naming the set that is complete. With several
/// folders (`--plots DIR`), they are replaced in the reverse order of their first file, so the
/// folder of the first file (the output folder) is replaced last.
#[derive(Debug, Default)]
pub struct OutputSet {
    folders: Vec<Staged>,
}

/// One folder's files, staged.
#[derive(Debug)]
struct Staged {
    target: PathBuf,
    staging: PathBuf,
    /// The staging folder is inside the target (its parent is not writable or is another file
    /// system), so the files can only be renamed in one by one.
    inside: bool,
    files: Vec<String>,
}

impl OutputSet {
    /// An empty set.
    pub fn new() -> Self {
        Self::default()
    }

    /// Writes `bytes` for `path` into its folder's staging folder. `path`'s folder must exist.
    pub fn add(&mut self, path: &Path, bytes: &[u8]) -> Result<(), Error> {
        let io_err = |source| Error::Io {
            path: path.to_path_buf(),
            source,
        };
        let name = path
            .file_name()
            .ok_or_else(|| Error::Write {
                path: path.to_path_buf(),
                message: "the path names no file".into(),
            })?
            .to_string_lossy()
            .into_owned();
        let folder = std::fs::canonicalize(parent_of(path)).map_err(io_err)?;
        let k = match self.folders.iter().position(|f| f.target == folder) {
            Some(k) => k,
            None => {
                let (staging, inside) = staging_for(&folder).map_err(io_err)?;
                self.folders.push(Staged {
                    target: folder,
                    staging,
                    inside,
                    files: Vec::new(),
                });
                self.folders.len() - 1
            }
        };
        let staged = &mut self.folders[k];
        let mut file = File::create(staged.staging.join(&name)).map_err(io_err)?;
        file.write_all(bytes).map_err(io_err)?;
        file.sync_all().map_err(io_err)?;
        staged.files.retain(|f| *f != name);
        staged.files.push(name);
        fault_point();
        Ok(())
    }

    /// Puts every folder's files in place (see the type's docs).
    pub fn commit(mut self) -> Result<(), Error> {
        while let Some(staged) = self.folders.pop() {
            staged.commit()?;
        }
        Ok(())
    }
}

impl Drop for OutputSet {
    fn drop(&mut self) {
        for staged in &self.folders {
            let _ = std::fs::remove_dir_all(&staged.staging);
            lock_live().retain(|p| *p != staged.staging);
        }
    }
}

/// A new, registered staging folder for `folder` (an absolute path): beside it where its parent
/// is writable and on the same file system (so that one rename can swap them), else inside it;
/// and whether it is inside.
fn staging_for(folder: &Path) -> io::Result<(PathBuf, bool)> {
    let name = folder
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let make = |dir: &Path| {
        tempfile::Builder::new()
            .prefix(&temp_prefix(&name))
            .suffix(".tmp")
            .tempdir_in(dir)
            .map(tempfile::TempDir::keep)
    };
    let parent = folder.parent().filter(|p| same_file_system(folder, p));
    registered(
        || match parent.map(make) {
            Some(Ok(staging)) => Ok((staging, false)),
            _ => Ok((make(folder)?, true)),
        },
        |(staging, _)| staging.clone(),
    )
}

#[cfg(unix)]
fn same_file_system(a: &Path, b: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        (Ok(a), Ok(b)) => a.dev() == b.dev(),
        _ => false,
    }
}

/// Without device numbers, assume one file system: a failed swap is an error, nothing is lost.
#[cfg(not(unix))]
fn same_file_system(_a: &Path, _b: &Path) -> bool {
    true
}

impl Staged {
    fn commit(self) -> Result<(), Error> {
        let io_err = |path: &Path| {
            let path = path.to_path_buf();
            move |source| Error::Io { path, source }
        };
        // The files written alone into the folder stay, and stay listed (they are still calib's),
        // where this set does not write them again.
        let previous = Manifest::read(&self.target);
        let listing = Manifest {
            set: self.files.clone(),
            alone: previous
                .alone
                .into_iter()
                .filter(|f| !self.files.contains(f) && self.target.join(f).is_file())
                .collect(),
        }
        .render();
        let manifest = self.staging.join(MANIFEST);
        let mut file = File::create(&manifest).map_err(io_err(&self.target.join(MANIFEST)))?;
        file.write_all(listing.as_bytes())
            .and_then(|()| file.sync_all())
            .map_err(io_err(&self.target.join(MANIFEST)))?;
        sync_dir(&self.staging);
        fault_point();
        let swap = !self.inside && replaceable(&self.target);
        if let Some(f) = self
            .files
            .iter()
            .find(|f| self.target.join(f).is_dir() && !swap)
        {
            return Err(Error::Write {
                path: self.target.join(f),
                message:
                    "a folder of that name is in the way; remove it or choose another output folder"
                        .into(),
            });
        }
        if swap {
            self.swap().map_err(io_err(&self.target))
        } else {
            self.file_by_file()
        }
    }

    /// Swaps the staging folder in for the target folder and removes the old contents.
    fn swap(&self) -> io::Result<()> {
        #[cfg(unix)]
        if let Ok(meta) = std::fs::metadata(&self.target) {
            // The new folder keeps the old one's permissions (a group-shared results folder).
            let _ = std::fs::set_permissions(&self.staging, meta.permissions());
        }
        {
            let live = lock_live();
            if !self.target.exists() {
                std::fs::rename(&self.staging, &self.target)?;
                drop(live);
                lock_live().retain(|p| *p != self.staging);
                sync_parent_dir(&self.target);
                return Ok(());
            }
            if exchange(&self.staging, &self.target).is_err() {
                // No atomic exchange here: move the old folder aside (under the staging name,
                // so its clean-up is the same), then the new one in.
                let aside = self.staging.with_extension("old.tmp");
                std::fs::rename(&self.target, &aside)?;
                fault_point();
                std::fs::rename(&self.staging, &self.target)?;
                std::fs::rename(&aside, &self.staging)?;
            }
            drop(live);
        }
        sync_parent_dir(&self.target);
        fault_point();
        // The staging name now holds the previous run's files.
        let removed = std::fs::remove_dir_all(&self.staging);
        lock_live().retain(|p| *p != self.staging);
        removed
    }

    /// Renames the files in one by one, removes the previous run's other files, and renames the
    /// manifest in last.
    fn file_by_file(&self) -> Result<(), Error> {
        let previous = read_manifest(&self.target);
        let live = lock_live();
        for f in &self.files {
            let to = self.target.join(f);
            std::fs::rename(self.staging.join(f), &to).map_err(|source| Error::Io {
                path: to.clone(),
                source,
            })?;
            fault_point();
        }
        for old in previous.iter().filter(|o| !self.files.contains(o)) {
            let _ = std::fs::remove_file(self.target.join(old));
        }
        let to = self.target.join(MANIFEST);
        std::fs::rename(self.staging.join(MANIFEST), &to)
            .map_err(|source| Error::Io { path: to, source })?;
        drop(live);
        sync_dir(&self.target);
        let _ = std::fs::remove_dir(&self.staging);
        lock_live().retain(|p| *p != self.staging);
        Ok(())
    }
}

/// The file names listed in `folder`'s manifest (empty if it has none): the files a previous
/// run wrote there, which the next [`OutputSet`] into `folder` removes where it does not write
/// them again.
pub fn read_manifest(folder: &Path) -> Vec<String> {
    Manifest::read(folder).set
}

/// Whether `folder` can be replaced as a whole: it does not exist, is empty, or holds only the
/// files its manifest lists. A temporary file of a live run (a concurrent run into the same
/// folder) is another run's business, so it keeps the folder from being replaced.
fn replaceable(folder: &Path) -> bool {
    // The working directory (or one holding it) is never swapped: the user's shell would be left
    // in a removed folder.
    if std::env::current_dir()
        .and_then(std::fs::canonicalize)
        .is_ok_and(|cwd| cwd.starts_with(folder))
    {
        return false;
    }
    let Ok(entries) = std::fs::read_dir(folder) else {
        return !folder.exists();
    };
    let listed = read_manifest(folder);
    entries.flatten().all(|e| {
        let name = e.file_name().to_string_lossy().into_owned();
        name == MANIFEST || (listed.contains(&name) && e.file_type().is_ok_and(|t| t.is_file()))
    })
}

/// Exchanges two paths atomically (`renameat2(RENAME_EXCHANGE)`, Linux 3.15).
#[cfg(target_os = "linux")]
fn exchange(a: &Path, b: &Path) -> io::Result<()> {
    use std::ffi::CString;
    use std::os::unix::ffi::OsStrExt;
    let a = CString::new(a.as_os_str().as_bytes())?;
    let b = CString::new(b.as_os_str().as_bytes())?;
    // SAFETY: both are NUL-terminated paths that outlive the call.
    let r = unsafe {
        libc::syscall(
            libc::SYS_renameat2,
            libc::AT_FDCWD,
            a.as_ptr(),
            libc::AT_FDCWD,
            b.as_ptr(),
            libc::RENAME_EXCHANGE,
        )
    };
    if r == 0 {
        Ok(())
    } else {
        Err(io::Error::last_os_error())
    }
}

#[cfg(not(target_os = "linux"))]
fn exchange(_a: &Path, _b: &Path) -> io::Result<()> {
    Err(io::Error::from(io::ErrorKind::Unsupported))
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
    fn temporary_names_carry_the_owner_and_host() {
        assert_eq!(
            stale_owner(".a.csv.calib-123@lab-pc+4026531836.AbC9x1.tmp"),
            Some((123, Some("lab-pc+4026531836")))
        );
        assert_eq!(
            stale_owner(".out.calib-77@ci.Xy12Zq.old.tmp"),
            Some((77, Some("ci")))
        );
        // An earlier calib's name: the pid, but no host.
        assert_eq!(
            stale_owner(".a.csv.calib-123.AbC9x1.tmp"),
            Some((123, None))
        );
        assert_eq!(stale_owner("a.csv"), None);
        assert_eq!(stale_owner(".a.csv.AbC9x1.tmp"), None);
        assert_eq!(stale_owner(".calib-manifest"), None);
        let dir = tempfile::tempdir().unwrap();
        let f = temp_file_beside(&dir.path().join("t.csv")).unwrap();
        let name = f.path().file_name().unwrap().to_string_lossy().into_owned();
        let (pid, host) = stale_owner(&name).unwrap();
        assert_eq!(pid, std::process::id(), "{name}");
        assert_eq!(Some(host.unwrap()), owner().split_once('@').map(|o| o.1));
        assert!(
            !host.unwrap().is_empty() && !host.unwrap().contains('.'),
            "{name}"
        );
    }

    #[test]
    fn an_output_set_replaces_its_folder_whole() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out");
        std::fs::create_dir(&out).unwrap();
        let mut set = OutputSet::new();
        set.add(&out.join("a.csv"), b"a1").unwrap();
        set.add(&out.join("b.csv"), b"b1").unwrap();
        set.commit().unwrap();
        assert_eq!(entries(&out), [MANIFEST, "a.csv", "b.csv"]);
        // A second set without b.csv: the folder holds exactly it.
        let mut set = OutputSet::new();
        set.add(&out.join("a.csv"), b"a2").unwrap();
        set.add(&out.join("c.csv"), b"c2").unwrap();
        set.commit().unwrap();
        assert_eq!(entries(&out), [MANIFEST, "a.csv", "c.csv"]);
        assert_eq!(std::fs::read(out.join("a.csv")).unwrap(), b"a2");
        assert_eq!(entries(dir.path()), ["out"]);
        // Dropped uncommitted: nothing changes and nothing is left.
        let mut set = OutputSet::new();
        set.add(&out.join("a.csv"), b"a3").unwrap();
        drop(set);
        assert_eq!(std::fs::read(out.join("a.csv")).unwrap(), b"a2");
        assert_eq!(entries(dir.path()), ["out"]);
        // Other tests run alongside: only this folder's entries must be gone from the list.
        assert!(!lock_live().iter().any(|p| p.starts_with(dir.path())));
    }

    #[test]
    fn a_shared_folder_keeps_its_other_files() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out");
        std::fs::create_dir(&out).unwrap();
        std::fs::write(out.join("run.csv"), "the user's log").unwrap();
        let mut set = OutputSet::new();
        set.add(&out.join("a.csv"), b"a1").unwrap();
        set.add(&out.join("b.csv"), b"b1").unwrap();
        set.commit().unwrap();
        let mut set = OutputSet::new();
        set.add(&out.join("a.csv"), b"a2").unwrap();
        set.commit().unwrap();
        assert_eq!(entries(&out), [MANIFEST, "a.csv", "run.csv"]);
        assert_eq!(
            std::fs::read_to_string(out.join(MANIFEST)).unwrap(),
            "a.csv\n"
        );
        assert_eq!(entries(dir.path()), ["out"]);
    }

    /// A pid no process has: that of a child that has ended.
    fn dead_pid() -> u32 {
        let mut child = std::process::Command::new("true").spawn().unwrap();
        child.wait().unwrap();
        child.id()
    }

    #[test]
    fn stale_temporaries_of_dead_runs_on_this_host_go_and_others_stay() {
        let dir = tempfile::tempdir().unwrap();
        let here = owner().split_once('@').unwrap().1.to_string();
        let dead = dead_pid();
        let name = |what: &str, owner: &str| format!(".{what}.calib-{owner}.AbCdEf.tmp");
        let file = name("a.csv", &format!("{dead}@{here}"));
        let mine = name("b.csv", owner());
        let staging = name("out", &format!("{dead}@{here}"));
        let elsewhere = name("out2", &format!("{dead}@other-host+1"));
        let earlier = name("out3", &dead.to_string());
        let not_staging = name("out4", &format!("{dead}@{here}"));
        std::fs::write(dir.path().join(&file), "x").unwrap();
        std::fs::write(dir.path().join(&mine), "x").unwrap();
        for folder in [&staging, &elsewhere, &earlier] {
            std::fs::create_dir(dir.path().join(folder)).unwrap();
            std::fs::write(dir.path().join(folder).join("a.csv"), "x").unwrap();
        }
        std::fs::create_dir_all(dir.path().join(&not_staging).join("keep")).unwrap();
        let stale = remove_stale(dir.path());
        assert_eq!(stale.removed, 2);
        let mut kept: Vec<String> = stale
            .kept
            .iter()
            .map(|(p, _)| p.file_name().unwrap().to_string_lossy().into_owned())
            .collect();
        kept.sort();
        assert_eq!(kept, [earlier.clone(), not_staging.clone()]);
        let mut left = vec![mine, elsewhere, earlier, not_staging.clone()];
        left.sort();
        assert_eq!(entries(dir.path()), left);
        assert_eq!(entries(&dir.path().join(&not_staging)), ["keep"]);
    }

    #[test]
    fn the_manifest_keeps_files_written_alone_apart_from_the_set() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out");
        std::fs::create_dir(&out).unwrap();
        write_atomic(&out.join("x.h"), b"an export").unwrap();
        record_written(&out.join("x.h")).unwrap();
        record_written(&out.join("x.h")).unwrap();
        assert_eq!(
            std::fs::read_to_string(out.join(MANIFEST)).unwrap(),
            "/x.h\n"
        );
        let mut set = OutputSet::new();
        set.add(&out.join("a.csv"), b"a1").unwrap();
        set.commit().unwrap();
        // The file written alone stays, listed after the set.
        assert_eq!(entries(&out), [MANIFEST, "a.csv", "x.h"]);
        let manifest = Manifest::read(&out);
        assert_eq!(manifest.set, ["a.csv"]);
        assert_eq!(manifest.alone, ["x.h"]);
        assert!(manifest.lists("x.h") && manifest.lists("a.csv") && !manifest.lists("b.csv"));
        assert_eq!(read_manifest(&out), ["a.csv"]);
    }

    #[test]
    fn a_temporary_folder_is_live_until_dropped_and_named_for_stale_removal() {
        let folder = TempFolder::create("bag").unwrap();
        let path = folder.path().to_path_buf();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        // Removed by a later run once this one has died (SIGKILL), as the other temporaries.
        assert_eq!(
            stale_owner(&name).map(|o| o.0),
            Some(std::process::id()),
            "{name}"
        );
        // Removed by the SIGINT/SIGTERM handler while alive.
        assert!(lock_live().contains(&path));
        std::fs::write(path.join("bag_0.db3"), "x").unwrap();
        drop(folder);
        assert!(!path.exists());
        assert!(!lock_live().contains(&path));
    }

    #[test]
    fn a_missing_directory_is_an_error_naming_the_target() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("no/such/dir/t.csv");
        let err = AtomicFile::create(&path).unwrap_err();
        assert!(err.to_string().contains("no/such/dir/t.csv"), "{err}");
    }
}
