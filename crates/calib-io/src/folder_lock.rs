//! One run at a time into an output folder.
//!
//! Two runs into one folder would each stage a complete set and swap it in, and both report
//! success while one's results are gone. A [`FolderLock`], held for the whole run, makes the
//! second refuse at once instead ([`LockError::Held`], naming the run that holds the folder):
//! waiting would leave a pipeline blocked for as long as the other calibration takes, with
//! nothing to say whose results the folder will hold.
//!
//! The lock is an advisory `flock` on a file beside the folder, `.<folder>.calib-lock` in its
//! parent (inside the folder, `.calib-lock`, where the parent cannot be written): beside, because
//! the folder itself is swapped whole at the end of a run. The file holds `<pid>@<host>` of the
//! run holding it, for the message; it is removed when the lock is released, and one left by a
//! killed run is harmless (the kernel released its lock with the process). The folders a run
//! made — the output folder and any of its parents that were missing (`-o a/b/c` where only `a`
//! exists makes `a/b`) — are removed when the lock is released if they are still empty, so a run
//! that fails leaves no folder behind; a folder that existed before the run, or that holds
//! anything, is never removed. On Linux, NFS carries
//! `flock` to the server as a whole-file lock, so runs on two hosts sharing the folder exclude
//! each other too. Elsewhere than Unix there is no lock.

use crate::Error;
use std::fs::File;
use std::io::{self, Read, Write};
use std::path::{Path, PathBuf};

/// The lock of one output folder, released when dropped.
#[derive(Debug)]
pub struct FolderLock {
    /// The lock file.
    path: PathBuf,
    /// The folders missing when the lock was taken (the output folder and the parents made for
    /// it), the deepest first: removed on release where still empty.
    made: Vec<PathBuf>,
    /// The open lock file: the lock lasts as long as it is open.
    _file: File,
}

/// Why a folder could not be locked.
#[derive(Debug, thiserror::Error)]
pub enum LockError {
    /// Another run holds it.
    #[error(
        "{}: another calib run is writing into this folder ({holder}, lock file {}); wait for it \
         to finish or choose another output folder",
        folder.display(),
        lock.display()
    )]
    Held {
        /// The folder.
        folder: PathBuf,
        /// The lock file.
        lock: PathBuf,
        /// Who holds it: `process <pid> on <host>`, as its lock file says.
        holder: String,
    },
    /// The lock file could not be made or locked.
    #[error(transparent)]
    Io(#[from] Error),
}

impl FolderLock {
    /// Locks `folder` (which need not exist yet; its parent is created if missing) for this
    /// run, or fails at once if another run holds it. The folders it made, and `folder` if it
    /// is made later, are removed on release if empty (see the [module docs](self)).
    pub fn acquire(folder: &Path) -> Result<Self, LockError> {
        let folder = absolute(folder).map_err(|source| {
            LockError::Io(Error::Io {
                path: folder.to_path_buf(),
                source,
            })
        })?;
        let made: Vec<PathBuf> = folder
            .ancestors()
            .take_while(|dir| !dir.exists())
            .map(Path::to_path_buf)
            .collect();
        Self::acquire_made(folder, made.clone()).inspect_err(|_| remove_empty(&made))
    }

    /// [`acquire`](Self::acquire) of the absolute `folder`, of which the folders `made` were
    /// missing.
    fn acquire_made(folder: PathBuf, made: Vec<PathBuf>) -> Result<Self, LockError> {
        let io_err = |path: &Path| {
            let path = path.to_path_buf();
            move |source| LockError::Io(Error::Io { path, source })
        };
        let beside = folder.parent().zip(folder.file_name());
        if let Some((parent, _)) = beside {
            std::fs::create_dir_all(parent).map_err(io_err(parent))?;
        }
        // Beside the folder where its parent can be written; inside it elsewhere (then the
        // folder is never swapped whole: its staging folder is inside it too).
        let path = match beside {
            Some((parent, name)) if writable(parent) => {
                parent.join(format!(".{}.calib-lock", name.to_string_lossy()))
            }
            _ => {
                std::fs::create_dir_all(&folder).map_err(io_err(&folder))?;
                folder.join(".calib-lock")
            }
        };
        // A failing run into a sibling folder removes the parent it made once empty: if that
        // happens between making the parent here and opening the lock file, make it again.
        let mut remake = 3;
        loop {
            let opened = std::fs::OpenOptions::new()
                .read(true)
                .write(true)
                .create(true)
                .truncate(false)
                .open(&path);
            let mut file = match opened {
                Err(e) if e.kind() == io::ErrorKind::NotFound && remake > 0 => {
                    remake -= 1;
                    if let Some(parent) = path.parent() {
                        std::fs::create_dir_all(parent).map_err(io_err(parent))?;
                    }
                    continue;
                }
                opened => opened.map_err(io_err(&path))?,
            };
            if !try_lock(&file).map_err(io_err(&path))? {
                // The holder writes who it is right after it locks: a run that lost the race by
                // microseconds gives it up to 100 ms to, so that the message names it.
                let mut holder = String::new();
                for _ in 0..20 {
                    holder.clear();
                    let _ = std::io::Seek::rewind(&mut file);
                    let _ = file.read_to_string(&mut holder);
                    if !holder.trim().is_empty() {
                        break;
                    }
                    std::thread::sleep(std::time::Duration::from_millis(5));
                }
                return Err(LockError::Held {
                    folder,
                    lock: path,
                    holder: describe(holder.trim()),
                });
            }
            // The run that held it may have removed the file between our open and our lock:
            // then this lock is on a file no other run can find; open the path again.
            if !same_file(&file, &path) {
                continue;
            }
            file.set_len(0).map_err(io_err(&path))?;
            file.write_all(format!("{}\n", crate::atomic::owner()).as_bytes())
                .map_err(io_err(&path))?;
            return Ok(FolderLock {
                path,
                made,
                _file: file,
            });
        }
    }

    /// The lock file.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for FolderLock {
    fn drop(&mut self) {
        // Removed while still locked, so a run that opened it meanwhile finds, once it has the
        // lock, that the path names another file (or none) and opens it again.
        let _ = std::fs::remove_file(&self.path);
        remove_empty(&self.made);
    }
}

/// Removes the folders of `made` (the deepest first) that exist and are empty, up to the first
/// that holds anything: a folder this run made and left empty, never one with contents.
fn remove_empty(made: &[PathBuf]) {
    for dir in made {
        match std::fs::remove_dir(dir) {
            Ok(()) => {}
            Err(e) if e.kind() == io::ErrorKind::NotFound => {}
            Err(_) => break,
        }
    }
}

/// `process <pid> on <host>` from a lock file's `<pid>@<host>`.
fn describe(owner: &str) -> String {
    match owner.split_once('@') {
        Some((pid, host)) => {
            let host = host.split_once('+').map_or(host, |h| h.0);
            format!("process {pid} on {host}")
        }
        None => "a run that has not yet said which".to_string(),
    }
}

/// `path` made absolute against the working directory, with `.` and `..` resolved where the
/// path exists (so that `-o .` and `-o ../lab` from inside `lab` name one lock).
fn absolute(path: &Path) -> io::Result<PathBuf> {
    if let Ok(p) = std::fs::canonicalize(path) {
        return Ok(p);
    }
    let path = std::path::absolute(path)?;
    // A folder not made yet: its nearest existing ancestor canonical, the rest as written.
    match (path.parent(), path.file_name()) {
        (Some(parent), Some(name)) => Ok(absolute(parent)?.join(name)),
        _ => Ok(path),
    }
}

/// Whether a file can be created in `dir`.
fn writable(dir: &Path) -> bool {
    tempfile::Builder::new()
        .prefix(".calib-probe")
        .tempfile_in(dir)
        .is_ok()
}

/// Takes an exclusive `flock` without waiting: `false` if another holds it.
#[cfg(unix)]
fn try_lock(file: &File) -> io::Result<bool> {
    use std::os::fd::AsRawFd;
    // SAFETY: the descriptor is the open file's.
    let r = unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) };
    if r == 0 {
        return Ok(true);
    }
    let err = io::Error::last_os_error();
    if err.raw_os_error() == Some(libc::EWOULDBLOCK) {
        Ok(false)
    } else {
        Err(err)
    }
}

/// No advisory lock here: every run gets it.
#[cfg(not(unix))]
fn try_lock(_file: &File) -> io::Result<bool> {
    Ok(true)
}

/// Whether `path` still names the open `file`.
#[cfg(unix)]
fn same_file(file: &File, path: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (file.metadata(), std::fs::metadata(path)) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}

#[cfg(not(unix))]
fn same_file(_file: &File, _path: &Path) -> bool {
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_lock_is_refused_naming_the_holder_and_free_once_released() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("new/out");
        let first = FolderLock::acquire(&out).unwrap();
        assert_eq!(first.path(), dir.path().join("new/.out.calib-lock"));
        assert!(!out.exists(), "the folder itself is not made by the lock");
        // Another open file description, as another process has: flock excludes it.
        let err = FolderLock::acquire(&out).unwrap_err();
        let text = err.to_string();
        let host = crate::atomic::owner();
        let pid = host.split_once('@').unwrap().0;
        assert!(text.contains(&format!("process {pid} on ")), "{text}");
        assert!(text.contains("another calib run is writing"), "{text}");
        drop(first);
        assert!(!dir.path().join("new/.out.calib-lock").exists());
        let again = FolderLock::acquire(&dir.path().join("new/./out")).unwrap();
        drop(again);
    }
}
