//! Writing a method's outputs: correction tables, `report.json` and `report.html` (and the
//! `--plots` files), together or not at all.

use crate::input::file_stem;
use anyhow::Context;
use calib_core::ErrorMap;
use calib_report::Document;
use std::path::Path;

/// The table file name of a channel: `<channel>.csv`, made safe as a file name.
pub fn table_name(channel: &str) -> String {
    format!("{}.csv", file_stem(channel))
}

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
