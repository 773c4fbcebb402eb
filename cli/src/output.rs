//! Writing a method's outputs: correction tables, `report.json` and `report.html` (and the
//! `--plots` files), together or not at all.

use crate::exit::Usage;
use anyhow::Context;
use calib_core::ErrorMap;
use calib_report::Document;
use std::path::Path;

/// Checks, before any reading, that `dir` can be an output folder (an existing folder, or one
/// that can be created where an existing folder is writable), and removes the temporary files
/// and folders that killed calib runs left in it and beside it, telling the user how many.
pub fn prepare_folder(dir: &Path) -> anyhow::Result<()> {
    if dir.exists() && !dir.is_dir() {
        return Err(Usage(format!(
            "-o {}: this is a file, not a folder; name a folder for the outputs (created if \
             missing)",
            dir.display()
        ))
        .into());
    }
    check_writable(dir, "-o")?;
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
/// writable, and it is not a folder), and removes stale temporary files beside it.
pub fn prepare_file(path: &Path, option: &str) -> anyhow::Result<()> {
    if path.is_dir() {
        return Err(Usage(format!(
            "{option} {}: this is a folder; name a file to write",
            path.display()
        ))
        .into());
    }
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if !parent.is_dir() {
        return Err(Usage(format!(
            "{option} {}: the folder {} does not exist; create it first or choose another path",
            path.display(),
            parent.display()
        ))
        .into());
    }
    check_writable(parent, option)?;
    report_stale(parent);
    Ok(())
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

/// Removes stale temporary files of calib's from `dir`, noting how many on standard error.
fn report_stale(dir: &Path) {
    let n = calib_io::atomic::remove_stale(dir);
    if n > 0 {
        eprintln!(
            "calib: note: removed {n} temporary file(s) left in {} by a calib run that was killed",
            dir.display()
        );
    }
}

pub use calib_core::report::table_name;

/// Writes one table per `(channel, map, standard uncertainty)`, `report.json` and the document
/// as `report.html` into `dir`; returns the names of the files written. See [`write_outputs`].
pub fn write_tables_and_report(
    dir: &Path,
    tables: &[(&str, &ErrorMap, Option<&[f64]>)],
    report_json: &str,
    document: &Document,
) -> anyhow::Result<Vec<String>> {
    let mut files = tables
        .iter()
        .map(|(name, map, u)| {
            let text = calib_io::table::render_table(map, *u)
                .with_context(|| format!("the table of channel `{name}`"))?;
            Ok((table_name(name), text.into_bytes()))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    files.push(("report.json".to_string(), report_json.as_bytes().to_vec()));
    write_outputs(dir, &files, document)
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
) -> anyhow::Result<Vec<String>> {
    let html = document.to_html()?;
    let plots = match crate::ui::plots_dir() {
        Some(p) => Some((p, document.plot_files()?)),
        None => None,
    };
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
