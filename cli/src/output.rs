//! Writing a method's outputs: correction tables and `report.json`, together or not at all.

use crate::input::file_stem;
use anyhow::Context;
use calib_core::ErrorMap;
use std::path::Path;

/// The table file name of a channel: `<channel>.csv`, made safe as a file name.
pub fn table_name(channel: &str) -> String {
    format!("{}.csv", file_stem(channel))
}

/// Writes one table per `(channel, map, standard uncertainty)` and `report.json` into `dir`
/// (created if missing). Every file goes to a temporary name first and all are renamed into
/// place only when all were written, so a failed run leaves none of them behind. The report is
/// renamed last: a run killed between two renames leaves complete tables, and a report only
/// beside all of its tables.
pub fn write_tables_and_report(
    dir: &Path,
    tables: &[(&str, &ErrorMap, Option<&[f64]>)],
    report_json: &str,
) -> anyhow::Result<()> {
    let rendered = tables
        .iter()
        .map(|(name, map, u)| {
            let text = calib_io::table::render_table(map, *u)
                .with_context(|| format!("the table of channel `{name}`"))?;
            Ok((table_name(name), text))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    std::fs::create_dir_all(dir)
        .with_context(|| format!("cannot create the output folder {}", dir.display()))?;
    let mut outputs = calib_io::atomic::OutputSet::new();
    for (file, text) in &rendered {
        outputs.add(&dir.join(file), text.as_bytes())?;
    }
    outputs.add(&dir.join("report.json"), report_json.as_bytes())?;
    outputs.commit()?;
    Ok(())
}
