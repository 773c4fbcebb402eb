//! How many threads calib computes on: `--jobs N`, else the `CALIB_JOBS` environment variable,
//! else the number of cores.
//!
//! With one thread everything runs on the main thread: the log is read, decompressed and decoded
//! there, then the solve. With more, one log is read ahead on a second thread (MCAP chunks
//! decompressed on up to two more) while the main thread computes, and the solvers split their
//! products between the threads; several logs are calibrated `N` at a time, each read on its
//! own thread. Results are the same whatever the number of threads.

use calib_io::LogReader;
use calib_io::Prefetch;
use std::sync::OnceLock;

use crate::exit::Usage;

/// The environment variable that sets the number of threads when `--jobs` is not given.
pub const ENV: &str = "CALIB_JOBS";

static JOBS: OnceLock<usize> = OnceLock::new();

/// Fixes the number of threads for this run: `jobs` (the command's `--jobs`), else [`ENV`], else
/// the number of cores; starts rayon's threads to match.
pub fn declare(jobs: Option<u16>) -> anyhow::Result<()> {
    let jobs = match jobs {
        Some(n) => usize::from(n),
        None => from_env()?.unwrap_or_else(cores),
    };
    if JOBS.set(jobs).is_ok() {
        // A pool already built (by a test harness calling twice) keeps its threads.
        let _ = rayon::ThreadPoolBuilder::new()
            .num_threads(jobs)
            .thread_name(|i| format!("calib-{i}"))
            .build_global();
    }
    Ok(())
}

/// The number of threads calib computes on.
pub fn jobs() -> usize {
    JOBS.get().copied().unwrap_or_else(cores)
}

/// Whether a log is read on the thread that computes (one thread in all).
pub fn read_inline() -> bool {
    jobs() == 1
}

/// The samples of `reader`, read ahead on a second thread unless calib runs on one.
pub fn prefetch(reader: LogReader) -> Prefetch<LogReader> {
    if read_inline() {
        Prefetch::inline(reader)
    } else {
        Prefetch::new(reader)
    }
}

fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// [`ENV`] if set: a whole number from 1.
fn from_env() -> anyhow::Result<Option<usize>> {
    let Some(value) = std::env::var_os(ENV) else {
        return Ok(None);
    };
    let text = value.to_string_lossy();
    match text.trim().parse::<usize>() {
        Ok(n) if n >= 1 => Ok(Some(n)),
        _ => Err(Usage(format!(
            "the environment variable {ENV}={text} is not a number of threads: set it to a \
             whole number from 1 (or unset it to use every core)"
        ))
        .into()),
    }
}
