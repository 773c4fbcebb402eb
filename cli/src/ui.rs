//! What every command shares about presentation: the global option `--quiet` and progress bars
//! on standard error.
//!
//! The option is set once, from `main`, before the command runs; the bars read it, so no
//! command passes it around.

use calib_io::{ProgressUnit, ReadProgress};
use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::path::Path;
use std::sync::OnceLock;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

/// Options of every command (clap `global`: accepted before or after the subcommand).
#[derive(Debug, Clone, Default, PartialEq, clap::Args)]
pub struct Global {
    /// No progress bars on standard error (they are hidden anyway when it is not a terminal).
    #[arg(long, short = 'q', global = true, help_heading = "Every command")]
    pub quiet: bool,
}

static GLOBAL: OnceLock<Global> = OnceLock::new();

/// The command prints JSON (`--json`): no progress line either, as with `--quiet`.
static JSON: AtomicBool = AtomicBool::new(false);

/// Hides every progress line: the command's output is JSON for a program. Call it before the
/// first line is drawn.
pub fn json_output() {
    JSON.store(true, Ordering::Relaxed);
}

/// Sets the global options; the first call wins.
pub fn set(global: Global) {
    let _ = GLOBAL.set(global);
}

fn global() -> &'static Global {
    GLOBAL.get_or_init(Global::default)
}

/// A note for the user on standard error (`calib: note: …`), unless `--quiet`.
pub fn note(text: &str) {
    if !global().quiet {
        eprintln!("calib: note: {}", escape_controls(text));
    }
}

/// A path as a message shows it: control characters (a NUL, an escape sequence, a line end in a
/// file name) escaped, so that a message is one readable line that cannot drive the terminal.
pub fn shown(path: &Path) -> String {
    escape_controls(&path.display().to_string())
}

/// `text` with control characters escaped as Rust escapes them (`\0`, `\n`, `\u{1b}`), and
/// the Unicode bidirectional controls too (`\u{202e}`): a right-to-left override in a file or
/// channel name would otherwise reorder the rest of the line on the terminal.
pub fn escape_controls(text: &str) -> String {
    let hidden = |c: char| {
        c.is_control()
            || matches!(c, '\u{202A}'..='\u{202E}' | '\u{2066}'..='\u{2069}' | '\u{200E}' | '\u{200F}' | '\u{061C}')
    };
    if !text.chars().any(hidden) {
        return text.to_string();
    }
    text.chars()
        .map(|c| {
            if hidden(c) {
                c.escape_default().to_string()
            } else {
                c.to_string()
            }
        })
        .collect()
}

/// Where every bar draws: one stack on standard error, so the bars of logs read in parallel
/// sit one above the other.
fn bars() -> &'static MultiProgress {
    static BARS: OnceLock<MultiProgress> = OnceLock::new();
    BARS.get_or_init(|| {
        MultiProgress::with_draw_target(if global().quiet || JSON.load(Ordering::Relaxed) {
            ProgressDrawTarget::hidden()
        } else {
            // indicatif draws nothing when standard error is not a terminal (CI logs stay clean).
            ProgressDrawTarget::stderr()
        })
    })
}

/// The progress line of the log at `path` while it is read: the reader's `progress` — bytes of
/// the file, or a bag's messages — of its total, and the time left at the rate so far. Update it
/// with [`advance`] after each batch of samples (drawing on each sample would cost time), and
/// finish it with [`ProgressBar::finish_and_clear`].
pub fn reading(path: &Path, progress: &ReadProgress) -> ProgressBar {
    let name = path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    let template = match progress.unit() {
        ProgressUnit::Bytes => {
            "{spinner} reading {msg}: {bytes} of {total_bytes} ({percent} %), {eta} left"
        }
        ProgressUnit::Messages => {
            "{spinner} reading {msg}: {human_pos} of {human_len} messages ({percent} %), {eta} left"
        }
    };
    let bar = bars().add(ProgressBar::new(progress.total()));
    bar.set_style(
        ProgressStyle::with_template(template).unwrap_or_else(|_| ProgressStyle::default_spinner()),
    );
    bar.set_message(name);
    bar
}

/// Moves the reading line to where the reader is.
pub fn advance(bar: &ProgressBar, progress: &ReadProgress) {
    bar.set_position(progress.read());
}

/// A spinner with the elapsed time, for a step without a measure of progress (a solve).
pub fn working(what: &str) -> ProgressBar {
    let bar = bars().add(ProgressBar::new_spinner());
    bar.set_style(
        ProgressStyle::with_template("{spinner} {msg} ({elapsed})")
            .unwrap_or_else(|_| ProgressStyle::default_spinner()),
    );
    bar.set_message(what.to_string());
    bar.enable_steady_tick(Duration::from_millis(120));
    bar
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The reading line of a log read front to back counts its bytes against the file's size
    /// (issue 31: a total and an ETA, where it counted samples and overshot), and moves to where
    /// the reader is, never past the end.
    #[test]
    fn the_reading_line_counts_bytes_of_the_files_size() {
        let log = Path::new(env!("CARGO_MANIFEST_DIR")).join("../testdata/examples/quick.mcap");
        let mut reader =
            calib_io::LogReader::open(&log, &calib_io::ReadOptions::default()).unwrap();
        let progress = reader.progress();
        let bar = reading(&log, &progress);
        let size = std::fs::metadata(&log).unwrap().len();
        assert_eq!(bar.length(), Some(size));
        assert!(reader.by_ref().count() > 0);
        advance(&bar, &progress);
        assert!(
            bar.position() > 0 && bar.position() <= size,
            "{}",
            bar.position()
        );
    }

    /// A SQLite bag's rows are not read in the file's order: its line counts messages, of the
    /// number its `messages` tables hold for the topics read (issue 31: a total, where it counted
    /// samples and overshot), and ends at that number.
    #[test]
    fn a_bags_reading_line_counts_its_messages() {
        let bag = Path::new(env!("CARGO_MANIFEST_DIR")).join("../testdata/rosbag/small_bag");
        let mut reader =
            calib_io::LogReader::open(&bag, &calib_io::ReadOptions::default()).unwrap();
        let progress = reader.progress();
        let bar = reading(&bag, &progress);
        let samples = reader.by_ref().count() as u64;
        advance(&bar, &progress);
        assert!(samples > 0);
        assert_eq!(bar.length(), Some(progress.total()));
        assert_eq!(bar.position(), progress.total(), "{samples} samples");
    }
}
