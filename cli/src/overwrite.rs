//! No command writes over one of its inputs.
//!
//! Every command's input paths — logs, tables, budgets, scenarios, truth folders — are
//! recorded once, before anything is read ([`protect`], from the command's arguments), and
//! every path a command writes is checked against them before anything is written
//! ([`check`]): a match is a usage error (exit 2) naming both.
//!
//! A path is compared by what it is, not by how it is spelled: an output that exists by its
//! device and inode (so a symlink, `./`, `..` or a hard link to an input is caught), one that
//! does not exist yet by its canonical folder and name. A folder given as an input (a rosbag2
//! bag directory, a `--truth` folder) is protected whole: nothing is written inside it.

use crate::exit::Usage;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// One input of the running command.
#[derive(Debug, Clone)]
struct Input {
    /// The path as given.
    given: PathBuf,
    /// What it is, for messages: `log`, `table`, `budget`, …
    what: &'static str,
    /// Its canonical path (it exists when recorded; an input that does not is left out: the
    /// command refuses it before writing anything).
    canonical: PathBuf,
    /// Its device and inode.
    id: Option<(u64, u64)>,
    /// A folder: everything inside it is protected.
    folder: bool,
}

/// The kinds of input that may be folders: a log (a rosbag2 bag directory), a `--truth`
/// folder, and a run's output folder (`calib compare --against`).
const FOLDER_INPUTS: [&str; 3] = ["log", "truth", "run"];

/// The inputs of the running command, set once by [`protect`].
static INPUTS: OnceLock<Inputs> = OnceLock::new();

/// A set of input paths that no output may be.
#[derive(Debug, Default, Clone)]
pub struct Inputs(Vec<Input>);

impl Inputs {
    /// The inputs `paths`, each with what it is (`log`, `table`, …). Paths that do not exist
    /// are left out, and so are folders given where a file is read (a table, a budget): the
    /// command refuses them as inputs, with its own message.
    pub fn new<'a>(paths: impl IntoIterator<Item = (&'a Path, &'static str)>) -> Self {
        Inputs(
            paths
                .into_iter()
                .filter_map(|(path, what)| {
                    let meta = std::fs::metadata(path).ok()?;
                    if meta.is_dir() && !FOLDER_INPUTS.contains(&what) {
                        return None;
                    }
                    Some(Input {
                        given: path.to_path_buf(),
                        what,
                        canonical: std::fs::canonicalize(path).ok()?,
                        id: identity(&meta),
                        folder: meta.is_dir(),
                    })
                })
                .collect(),
        )
    }

    /// Checks that writing `path` (for the option or output `via`, e.g. `-o out`) replaces,
    /// and lands inside, none of the inputs; the error names both and says what to do.
    pub fn check(&self, path: &Path, via: &str) -> Result<(), Usage> {
        let Some(hit) = self.hit(path) else {
            return Ok(());
        };
        let shown = crate::ui::shown;
        let what = if hit.folder && !same_place(path, &hit.canonical) {
            "write into"
        } else {
            "replace"
        };
        Err(Usage(format!(
            "{via}: writing {} would {what} the {} {}, an input of this run; calib never \
             writes over its inputs: choose another output path",
            shown(path),
            hit.what,
            shown(&hit.given)
        )))
    }

    /// The input that writing `path` would replace or write into.
    fn hit(&self, path: &Path) -> Option<&Input> {
        let id = std::fs::metadata(path).ok().and_then(|m| identity(&m));
        let place = location(path);
        self.0.iter().find(|input| {
            (id.is_some() && id == input.id && !input.folder)
                || place.as_ref().is_some_and(|p| {
                    *p == input.canonical || (input.folder && p.starts_with(&input.canonical))
                })
        })
    }
}

/// Whether `path` is (by its canonical location) `canonical`.
fn same_place(path: &Path, canonical: &Path) -> bool {
    location(path).is_some_and(|p| p == canonical)
}

/// Where `path` is: its canonical path if it exists, else its folder's canonical path joined
/// with its name (`None` if the folder does not exist either: nothing can be there yet).
fn location(path: &Path) -> Option<PathBuf> {
    if let Ok(p) = std::fs::canonicalize(path) {
        return Some(p);
    }
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let name = path.file_name()?;
    // A folder not yet made may be under an input folder: find its nearest existing ancestor.
    location(parent).map(|dir| dir.join(name))
}

#[cfg(unix)]
fn identity(meta: &std::fs::Metadata) -> Option<(u64, u64)> {
    use std::os::unix::fs::MetadataExt;
    Some((meta.dev(), meta.ino()))
}

/// Without device and inode numbers, files are compared by their canonical paths alone.
#[cfg(not(unix))]
fn identity(_meta: &std::fs::Metadata) -> Option<(u64, u64)> {
    None
}

/// Records the running command's inputs; the first call wins.
pub fn protect(inputs: Inputs) {
    let _ = INPUTS.set(inputs);
}

/// Checks `path`, about to be written for `via`, against the running command's inputs
/// ([`Inputs::check`]).
pub fn check(path: &Path, via: &str) -> Result<(), Usage> {
    match INPUTS.get() {
        Some(inputs) => inputs.check(path, via),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn inputs(dir: &Path) -> Inputs {
        Inputs::new([
            (dir.join("dut.csv").as_path(), "log"),
            (dir.join("bag").as_path(), "log"),
        ])
    }

    #[test]
    fn every_spelling_of_an_input_is_refused() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        std::fs::write(dir.join("dut.csv"), "t,dut,ref\n").unwrap();
        std::fs::create_dir(dir.join("bag")).unwrap();
        std::fs::create_dir(dir.join("sub")).unwrap();
        let guard = inputs(dir);
        let hard = dir.join("hard.csv");
        std::fs::hard_link(dir.join("dut.csv"), &hard).unwrap();
        #[cfg(unix)]
        std::os::unix::fs::symlink(dir.join("dut.csv"), dir.join("link.csv")).unwrap();
        for spelling in [
            dir.join("dut.csv"),
            dir.join(".").join("dut.csv"),
            dir.join("sub").join("..").join("dut.csv"),
            hard,
            #[cfg(unix)]
            dir.join("link.csv"),
        ] {
            let err = guard.check(&spelling, "-o x").unwrap_err().to_string();
            assert!(
                err.contains("would replace the log"),
                "{}: {err}",
                spelling.display()
            );
            assert!(err.contains("dut.csv"), "{err}");
        }
        let err = guard
            .check(&dir.join("bag").join("new").join("a.csv"), "-o y")
            .unwrap_err()
            .to_string();
        assert!(err.contains("would write into the log"), "{err}");
        // Other files beside the inputs, and the folder holding them, are not inputs.
        for free in [
            dir.join("a.csv"),
            dir.join("sub/dut.csv"),
            dir.join("new/x"),
        ] {
            assert!(guard.check(&free, "-o x").is_ok(), "{}", free.display());
        }
    }
}
