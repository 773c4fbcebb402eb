//! Writing a method's outputs: correction tables, `report.json` and `report.html` (and the
//! `--plots` files), together or not at all.

use crate::exit::Usage;
use anyhow::Context;
use calib_core::ErrorMap;
use calib_report::Document;
use std::path::{Path, PathBuf};

/// Checks, before any reading, that `dir` can be an output folder (an existing folder, or one
/// that can be created where an existing folder is writable), and removes the temporary files
/// and folders that killed calib runs left in it and beside it, telling the user how many.
/// `option` (`-o`, `--plots`) is the option that named it, for messages.
pub fn prepare_folder(dir: &Path, option: &str) -> anyhow::Result<()> {
    if dir.exists() && !dir.is_dir() {
        return Err(Usage(format!(
            "{option} {}: this is a file, not a folder; name a folder for the {} (created if \
             missing)",
            dir.display(),
            if option == "--plots" {
                "plot files"
            } else {
                "outputs"
            }
        ))
        .into());
    }
    check_writable(dir, option)?;
    report_stale(dir);
    if let Some(parent) = std::fs::canonicalize(dir)
        .ok()
        .and_then(|d| d.parent().map(Path::to_path_buf))
    {
        report_stale(&parent);
    }
    Ok(())
}

/// Checks, before any reading, that a file can be written at `path` (its folder exists and is
/// writable, it is not a folder, and it is not a file calib did not write, unless `--force`:
/// [`check_file_replaceable`]), locks its folder for the run ([`lock_folder`]: the check, the
/// write and the folder's manifest are then this run's alone), and removes stale temporary files
/// beside it. The lock is held until the returned value is dropped.
pub fn prepare_file(
    path: &Path,
    option: &str,
) -> anyhow::Result<calib_io::folder_lock::FolderLock> {
    if path.is_dir() {
        return Err(Usage(format!(
            "{option} {}: this is a folder; name a file to write",
            path.display()
        ))
        .into());
    }
    let parent = parent_of(path);
    if !parent.is_dir() {
        return Err(Usage(format!(
            "{option} {}: the folder {} does not exist; create it first or choose another path",
            path.display(),
            parent.display()
        ))
        .into());
    }
    check_writable(parent, option)?;
    let lock = lock(parent, path, option)?;
    check_file_replaceable(path, option)?;
    report_stale(parent);
    Ok(lock)
}

/// Whether a file can be created in `dir` or, if it does not exist, in its nearest existing
/// ancestor (where `create_dir_all` will make it): found by creating and removing one.
fn check_writable(dir: &Path, option: &str) -> anyhow::Result<()> {
    let mut at = dir;
    while !at.exists() {
        match at.parent() {
            Some(p) if !p.as_os_str().is_empty() => at = p,
            _ => {
                at = Path::new(".");
                break;
            }
        }
    }
    if !at.is_dir() {
        return Err(Usage(format!(
            "{option} {}: {} is a file, so no folder can be made there; choose another path",
            dir.display(),
            at.display()
        ))
        .into());
    }
    tempfile::Builder::new()
        .prefix(".calib-probe")
        .tempfile_in(at)
        .map(drop)
        .map_err(|e| {
            Usage(format!(
                "{option} {}: cannot write into {} ({}); choose a folder you can write to",
                dir.display(),
                at.display(),
                crate::exit::os_reason(&e)
            ))
            .into()
        })
}

/// Removes stale temporary files of calib's from `dir`, noting how many on standard error, and
/// names those that may be stale but that calib cannot prove its own (so leaves alone).
fn report_stale(dir: &Path) {
    let stale = calib_io::atomic::remove_stale(dir);
    if stale.removed > 0 {
        eprintln!(
            "calib: note: removed {} temporary file(s) left in {} by a calib run that was killed",
            stale.removed,
            dir.display()
        );
    }
    for (path, why) in &stale.kept {
        eprintln!(
            "calib: note: left {} in place, although no process of this host has its pid: \
             {why}; remove it yourself if no calib run uses it",
            crate::ui::shown(path)
        );
    }
}

/// `--force`: replace files that calib did not write. Set once, from the command's arguments.
static FORCE: std::sync::OnceLock<bool> = std::sync::OnceLock::new();

/// Records the running command's `--force`; the first call wins.
pub fn allow_replacing(force: bool) {
    let _ = FORCE.set(force);
}

/// Checks that writing `names` into `folder` (for the option `via`, e.g. `-o out`) replaces no
/// file that calib did not write: each of them that exists must be listed in the folder's
/// manifest ([`calib_io::atomic::Manifest`]: an earlier output of calib's), unless `--force`.
/// The error names every such file and the option; an input of the run among them is named as
/// such instead ([`crate::overwrite`], which refuses inputs `--force` or not, wherever a command
/// writes). A folder in the way is not checked here:
/// nothing can replace it, and writing fails naming it before any file is put in place.
pub fn check_replaces_only_calibs<'a>(
    folder: &Path,
    names: impl IntoIterator<Item = &'a str>,
    via: &str,
) -> Result<(), Usage> {
    if FORCE.get().copied().unwrap_or(false) {
        return Ok(());
    }
    let manifest = calib_io::atomic::Manifest::read(folder);
    let mut foreign: Vec<&str> = names
        .into_iter()
        .filter(|n| {
            folder
                .join(n)
                .symlink_metadata()
                .is_ok_and(|m| !m.is_dir() && !manifest.lists(n))
        })
        .collect();
    foreign.dedup();
    if foreign.is_empty() {
        return Ok(());
    }
    for name in &foreign {
        crate::overwrite::check(&folder.join(name), via)?;
    }
    let (them, are, it) = if foreign.len() == 1 {
        ("it", "is", "it")
    } else {
        ("them", "are", "them")
    };
    Err(Usage(format!(
        "{via}: {} {are} already there and calib did not write {them} (no calib manifest in {} \
         lists {it}); calib replaces only its own earlier outputs: move {them} away, choose \
         another output path, or add --force to replace {them}",
        foreign
            .iter()
            .map(|n| crate::ui::shown(&folder.join(n)))
            .collect::<Vec<_>>()
            .join(", "),
        crate::ui::shown(folder)
    )))
}

/// [`check_replaces_only_calibs`] for one file, `path`.
pub fn check_file_replaceable(path: &Path, option: &str) -> Result<(), Usage> {
    let Some(name) = path.file_name() else {
        return Ok(());
    };
    let name = name.to_string_lossy();
    check_replaces_only_calibs(
        parent_of(path),
        [name.as_ref()],
        &format!("{option} {}", crate::ui::shown(path)),
    )
}

/// Lists `paths`, files just written one at a time, in their folders' manifests, so that
/// calib may replace them later without `--force`. A manifest that cannot be written is noted
/// on standard error: the outputs themselves are complete.
pub fn record_written<P: AsRef<Path>>(paths: impl IntoIterator<Item = P>) {
    for path in paths {
        if let Err(e) = calib_io::atomic::record_written(path.as_ref()) {
            eprintln!(
                "calib: note: {}: not listed as calib's output ({e}); replacing it later needs \
                 --force",
                crate::ui::shown(path.as_ref())
            );
        }
    }
}

/// Locks `dir` for this run ([`calib_io::folder_lock`]): a second run into the same folder
/// fails at once with a usage error naming the folder and the run that holds it.
pub fn lock_folder(dir: &Path, option: &str) -> anyhow::Result<calib_io::folder_lock::FolderLock> {
    lock(dir, dir, option)
}

/// Locks `dir` for a run writing `named` (the folder itself, or a file in it), as
/// [`lock_folder`] does.
fn lock(
    dir: &Path,
    named: &Path,
    option: &str,
) -> anyhow::Result<calib_io::folder_lock::FolderLock> {
    use calib_io::folder_lock::{FolderLock, LockError};
    FolderLock::acquire(dir).map_err(|e| match e {
        LockError::Held { holder, lock, .. } => Usage(format!(
            "{option} {}: another calib run is writing into {} ({holder}; lock file {}); calib \
             does not wait: run again once it has finished, or choose another {}",
            crate::ui::shown(named),
            if named == dir {
                "this folder".to_string()
            } else {
                format!("its folder {}", crate::ui::shown(dir))
            },
            crate::ui::shown(&lock),
            if named == dir { "folder" } else { "path" },
        ))
        .into(),
        LockError::Io(e) => anyhow::Error::new(e).context(format!(
            "cannot lock the folder {} for this run",
            dir.display()
        )),
    })
}

/// The directory holding `path` (`.` for a bare name).
fn parent_of(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

pub use calib_core::report::table_name;

/// Checks, before any reading, that writing the results of `method` on `logs` into `dir`
/// replaces no other run's results: a folder holding those of another command, or of the same
/// command on other logs, is a usage error naming that run and its files (`--force` skips this
/// check). Rerunning a command on the same logs replaces its results. The previous run is
/// known from the folder's `report.json` (its method and first input, the log) where the
/// folder holds one run's outputs (its manifest), or from its `summary.json` (several logs).
pub fn check_replacing(dir: &Path, method: &str, logs: &[PathBuf]) -> anyhow::Result<()> {
    let Some(previous) = previous_run(dir) else {
        return Ok(());
    };
    let same_logs = previous.logs.len() == logs.len()
        && logs
            .iter()
            .all(|log| previous.logs.iter().any(|p| same_path(Path::new(p), log)));
    if previous.method == method && same_logs {
        return Ok(());
    }
    let mut files = previous.files.join(", ");
    if files.len() > 200 {
        files = format!("{} files", previous.files.len());
    }
    Err(Usage(format!(
        "-o {}: the folder holds the results of `{}` ({files}); this run ({method} of {}) would \
         replace them: choose another folder with -o, or add --force to replace them",
        crate::ui::shown(dir),
        crate::ui::escape_controls(&previous.command),
        logs.iter()
            .map(|l| crate::ui::shown(l))
            .collect::<Vec<_>>()
            .join(", ")
    ))
    .into())
}

/// The run whose results an output folder holds.
#[derive(Debug)]
struct PreviousRun {
    /// Its method.
    method: String,
    /// Its logs, as it was given them.
    logs: Vec<String>,
    /// Its command line, or a reconstruction of it.
    command: String,
    /// The files and folders of it that a new run replaces.
    files: Vec<String>,
}

/// The run whose results `dir` holds, if calib wrote them: one log's outputs (a manifest
/// beside `report.json`) or several logs' (`summary.json`).
fn previous_run(dir: &Path) -> Option<PreviousRun> {
    let read = |name: &str| -> Option<serde_json::Value> {
        serde_json::from_str(&std::fs::read_to_string(dir.join(name)).ok()?).ok()
    };
    let text = |v: &serde_json::Value| v.as_str().map(str::to_string);
    let files = calib_io::atomic::read_manifest(dir);
    if !files.is_empty()
        && let Some(report) = read("report.json")
    {
        let method = text(&report["method"])?;
        let log = text(report["inputs"].get(0)?)?;
        let command =
            text(&report["command_line"]).unwrap_or_else(|| format!("calib {method} {log}"));
        return Some(PreviousRun {
            method,
            logs: vec![log],
            command,
            files,
        });
    }
    let summary = read("summary.json")?;
    let method = text(&summary["method"])?;
    let entries = summary["logs"].as_array()?;
    let logs: Vec<String> = entries.iter().filter_map(|l| text(&l["log"])).collect();
    let mut files = vec!["summary.json".to_string()];
    files.extend(
        entries
            .iter()
            .filter_map(|l| text(&l["output"]))
            .map(|o| o + "/"),
    );
    Some(PreviousRun {
        command: format!("calib {method} {}", logs.join(" ")),
        method,
        logs,
        files,
    })
}

/// Whether two paths name the same file: by their canonical paths where both exist, else as
/// written.
pub(crate) fn same_path(a: &Path, b: &Path) -> bool {
    match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
        (Ok(a), Ok(b)) => a == b,
        _ => a == b,
    }
}

/// A whole-turn table of channel `name` (its map and standard uncertainty) as the file it is
/// written to: `(<name>.csv, contents)`.
pub fn turn_table(
    name: &str,
    map: &ErrorMap,
    u: Option<&[f64]>,
) -> anyhow::Result<(String, Vec<u8>)> {
    let text = calib_io::table::render_table(&map.clone().into(), u)
        .with_context(|| format!("the table of channel `{name}`"))?;
    Ok((table_name(name), text.into_bytes()))
}

/// Writes `files` (name, contents) and the document as `report.html` into `dir`, and with
/// `--plots DIR` every plot as SVG and PNG there (folders created if missing); returns the names
/// of the files written into `dir`. Every file goes to a temporary name first and all are renamed
/// into place only when all were written, so a failed run leaves none of them behind. The reports
/// are renamed last: a run killed between two renames leaves complete tables, and a report only
/// beside all of its tables.
pub fn write_outputs(
    dir: &Path,
    files: &[(String, Vec<u8>)],
    document: &Document,
    plots: Option<&Path>,
) -> anyhow::Result<Vec<String>> {
    let html = document.to_html()?;
    let plots = match plots {
        Some(p) => Some((p, document.plot_files()?)),
        None => None,
    };
    // Nothing written may be an input: neither a file of this run nor one of the previous run's
    // files that replacing the folder removes.
    let folders = std::iter::once((
        dir,
        "-o",
        files
            .iter()
            .map(|f| f.0.as_str())
            .chain(["report.html"])
            .collect::<Vec<_>>(),
    ))
    .chain(plots.as_ref().map(|(folder, plot_files)| {
        (
            *folder,
            "--plots",
            plot_files.iter().map(|f| f.0.as_str()).collect(),
        )
    }));
    for (folder, option, names) in folders {
        let via = format!("{option} {}", crate::ui::shown(folder));
        let previous = calib_io::atomic::read_manifest(folder);
        for name in names
            .iter()
            .copied()
            .chain(previous.iter().map(String::as_str))
        {
            crate::overwrite::check(&folder.join(name), &via)?;
        }
        check_replaces_only_calibs(folder, names, &via)?;
    }
    let mut outputs = calib_io::atomic::OutputSet::new();
    for (folder, what) in
        std::iter::once((dir, "output")).chain(plots.as_ref().map(|p| (p.0, "plots")))
    {
        std::fs::create_dir_all(folder)
            .with_context(|| format!("cannot create the {what} folder {}", folder.display()))?;
    }
    for (file, bytes) in files {
        outputs.add(&dir.join(file), bytes)?;
    }
    outputs.add(&dir.join("report.html"), html.as_bytes())?;
    if let Some((folder, plot_files)) = &plots {
        for (file, bytes) in plot_files {
            outputs.add(&folder.join(file), bytes)?;
        }
    }
    outputs.commit()?;
    let mut written: Vec<String> = files.iter().map(|(file, _)| file.clone()).collect();
    written.push("report.html".into());
    Ok(written)
}
