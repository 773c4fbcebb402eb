//! moteus: a `motor_position` source's compensation table, read back (`--format moteus`, which
//! also reads `moteus-config` files).
//!
//! # Lines read
//! - `conf set KEY VALUE` (calib's `moteus` output, a `--write-config` file, a console
//!   transcript);
//! - `KEY VALUE` (calib's `moteus-config`, `moteus_tool --dump-config`, `conf enumerate`);
//! - `conf get KEY` followed by the line the controller answers with, the value alone (a console
//!   transcript).
//!
//! `#` starts a comment; `conf write`, blank lines and every other key are skipped, so a whole
//! configuration dump can be read. The keys are `motor_position.sources.N.compensation_table.I`
//! (`I` in 0–255, int8 codes) and `motor_position.sources.N.compensation_scale` (revolutions);
//! a key set twice to one value is read once; set twice to different values it is refused
//! (but for a `compensation_scale` of 0 first, which turns compensation off while the entries
//! change, as calib's `moteus` output starts),
//! naming both lines: a file holding two tables (two dumps pasted together, a table edited after
//! it was read) cannot say which one the controller holds ([`super`]'s rule for every importer).
//!
//! # Decoding
//! As the firmware's `lerp` (mjbots/moteus `fw/motor_position.h`, commit `06a3d52`): an entry is
//! `code · (compensation_scale / 127)` revolutions **added** to the reading, computed in `f32`;
//! calib's error is its negation, in radians.

use super::{at, data};
use crate::Error;
use crate::export::moteus::{SOURCES, TABLE_SIZE};
use std::f64::consts::TAU;
use std::path::Path;

/// One source's settings as read: the entries and the scale, each with its line.
#[derive(Debug, Clone)]
struct Source {
    entries: Vec<Option<(i8, usize)>>,
    scale: Option<(f32, usize)>,
}

impl Source {
    fn new() -> Self {
        Source {
            entries: vec![None; TABLE_SIZE],
            scale: None,
        }
    }

    fn is_empty(&self) -> bool {
        self.scale.is_none() && self.entries.iter().all(Option::is_none)
    }
}

/// The errors (radians, entry `i` at `i/256` of a turn) of source `wanted` (or the only one with
/// a table), and notes on what was read.
pub(super) fn parse(
    text: &str,
    path: &Path,
    wanted: Option<u8>,
) -> Result<(Vec<f64>, Vec<String>), Error> {
    let mut sources: Vec<Source> = (0..SOURCES).map(|_| Source::new()).collect();
    let mut pending: Option<(String, usize)> = None;
    for (k, raw) in text.lines().enumerate() {
        let line_no = k + 1;
        let line = raw.split('#').next().unwrap_or_default().trim();
        if line.is_empty() {
            continue;
        }
        if let Some((key, _)) = pending.take() {
            // The controller answers `conf get KEY` with the value alone.
            if !line.contains(' ') && !line.starts_with("conf ") {
                set(&mut sources, path, &key, line, line_no)?;
                continue;
            }
        }
        if line == "conf write" {
            continue;
        }
        if let Some(key) = line.strip_prefix("conf get ") {
            pending = Some((key.trim().to_string(), line_no));
            continue;
        }
        let setting = line.strip_prefix("conf set ").unwrap_or(line);
        let mut words = setting.split_whitespace();
        let (Some(key), Some(value)) = (words.next(), words.next()) else {
            continue;
        };
        if words.next().is_none() {
            set(&mut sources, path, key, value, line_no)?;
        } else if compensation_key(key).is_some() {
            return Err(at(
                path,
                line_no,
                format!("`{line}` has more than a key and a value; write `{key} VALUE`"),
            ));
        }
    }
    let present: Vec<u8> = (0..SOURCES)
        .filter(|&n| !sources[n as usize].is_empty())
        .collect();
    let n = match wanted {
        Some(n) if n >= SOURCES => {
            return Err(data(
                path,
                format!(
                    "moteus has sources 0 to {} (the `moteus_source` option); not {n}",
                    SOURCES - 1
                ),
            ));
        }
        Some(n) if present.contains(&n) => n,
        Some(n) if present.is_empty() => return Err(data(path, none_found(Some(n)))),
        Some(n) => {
            return Err(data(
                path,
                format!(
                    "the file holds no compensation settings of source {n}, only of source{} {}; \
                     choose one with the `moteus_source` option",
                    if present.len() == 1 { "" } else { "s" },
                    list(&present)
                ),
            ));
        }
        None => match present.as_slice() {
            [] => return Err(data(path, none_found(None))),
            [n] => *n,
            _ => {
                return Err(data(
                    path,
                    format!(
                        "the file holds compensation tables of sources {}; choose one with \
                         the `moteus_source` option",
                        list(&present)
                    ),
                ));
            }
        },
    };
    let source = &sources[n as usize];
    let missing: Vec<usize> = (0..TABLE_SIZE)
        .filter(|&i| source.entries[i].is_none())
        .collect();
    if let Some(&first) = missing.first() {
        return Err(data(
            path,
            format!(
                "source {n}'s compensation_table lacks {} of its {TABLE_SIZE} entries (the first \
                 missing is motor_position.sources.{n}.compensation_table.{first}); read every \
                 entry from the controller (conf get each, or moteus_tool --dump-config)",
                missing.len()
            ),
        ));
    }
    let Some((scale, _)) = source.scale else {
        return Err(data(
            path,
            format!(
                "the file has source {n}'s compensation_table but not \
                 motor_position.sources.{n}.compensation_scale, without which its entries mean \
                 nothing; add that line"
            ),
        ));
    };
    let codes: Vec<i8> = source.entries.iter().flatten().map(|&(c, _)| c).collect();
    // The firmware passes compensation_scale / 127.0f to lerp, which multiplies each entry by it.
    let per_code = scale / 127.0;
    let values = codes
        .iter()
        .map(|&c| -f64::from(f32::from(c) * per_code) * TAU)
        .collect();
    let mut notes = vec![format!(
        "moteus source {n}: {TABLE_SIZE} int8 entries, compensation_scale {scale} rev (one code = \
         {:.6} arcsec), the correction added to the reading",
        f64::from(per_code) * 1_296_000.0
    )];
    if scale == 0.0 || codes.iter().all(|&c| c == 0) {
        notes.push(
            "compensation is off on this source (its scale or every entry is 0): the table is zero"
                .into(),
        );
    }
    Ok((values, notes))
}

/// `(source, Some(entry))` for a compensation table key, `(source, None)` for the scale.
fn compensation_key(key: &str) -> Option<(&str, Option<&str>)> {
    let rest = key.strip_prefix("motor_position.sources.")?;
    let (source, setting) = rest.split_once('.')?;
    if setting == "compensation_scale" {
        Some((source, None))
    } else {
        setting
            .strip_prefix("compensation_table.")
            .map(|i| (source, Some(i)))
    }
}

/// Records `key = value` from line `line_no` if it is a compensation setting.
fn set(
    sources: &mut [Source],
    path: &Path,
    key: &str,
    value: &str,
    line_no: usize,
) -> Result<(), Error> {
    let Some((source, entry)) = compensation_key(key) else {
        return Ok(());
    };
    let source = match source.parse::<u8>() {
        Ok(n) if n < SOURCES => n,
        _ => {
            return Err(at(
                path,
                line_no,
                format!(
                    "`{key}`: moteus has sources 0 to {} (motor_position.sources.N)",
                    SOURCES - 1
                ),
            ));
        }
    };
    let settings = &mut sources[source as usize];
    match entry {
        None => {
            let scale = value.parse::<f32>().ok().filter(|s| s.is_finite());
            let Some(scale) = scale else {
                return Err(at(
                    path,
                    line_no,
                    format!(
                        "`{value}` is not a number; compensation_scale is a float (revolutions)"
                    ),
                ));
            };
            // A scale of 0 first turns compensation off while the entries change (calib's
            // `moteus` output starts so): the value set after it is the table's, not another's.
            if let Some((before, first)) = settings.scale
                && before != scale
                && before != 0.0
            {
                return Err(twice(path, key, (before, first), (scale, line_no)));
            }
            settings.scale = Some((scale, line_no));
        }
        Some(index) => {
            let index = match index.parse::<usize>() {
                Ok(i) if i < TABLE_SIZE => i,
                _ => {
                    return Err(at(
                        path,
                        line_no,
                        format!(
                            "`{key}`: the compensation table has entries 0 to {} (firmware ≥ \
                             0x0109; older firmware's 32-entry float table is not read)",
                            TABLE_SIZE - 1
                        ),
                    ));
                }
            };
            let Ok(code) = value.parse::<i8>() else {
                return Err(at(
                    path,
                    line_no,
                    format!(
                        "`{value}` is not an int8 code (−128 to 127); compensation_table entries \
                         are int8 since firmware 0x0109 (older firmware's floats are not read)"
                    ),
                ));
            };
            if let Some((before, first)) = settings.entries[index]
                && before != code
            {
                return Err(twice(path, key, (before, first), (code, line_no)));
            }
            settings.entries[index] = Some((code, line_no));
        }
    }
    Ok(())
}

/// Refuses `key` set to two different values, on lines `first.1` and `then.1`.
fn twice(
    path: &Path,
    key: &str,
    first: (impl std::fmt::Display, usize),
    then: (impl std::fmt::Display, usize),
) -> Error {
    at(
        path,
        then.1,
        format!(
            "`{key}` is set twice, to {} on line {} and to {} on line {}: the file holds two \
             tables (two dumps pasted together, or a table changed after it was read) and calib \
             cannot tell which one the controller holds; keep the lines of one table only",
            first.0, first.1, then.0, then.1
        ),
    )
}

fn none_found(wanted: Option<u8>) -> String {
    let which = wanted.map_or("N".to_string(), |n| n.to_string());
    format!(
        "no motor_position.sources.{which}.compensation_table lines found; \
         `format = moteus` reads `conf set KEY VALUE` lines, `KEY VALUE` lines (--dump-config, \
         --restore-config files) and `conf get KEY` answered by its value"
    )
}

fn list(sources: &[u8]) -> String {
    let names: Vec<String> = sources.iter().map(u8::to_string).collect();
    names.join(", ")
}
