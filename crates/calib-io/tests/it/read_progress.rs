//! How far a reader has got through its log (`LogReader::progress`), what the progress line
//! with a total and an ETA shows (issue 31): the total is the file's size before the first
//! sample, the bytes read only grow, and at the end every byte has been read.

use calib_io::{LogReader, ReadOptions};
use std::path::{Path, PathBuf};

fn testdata(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../testdata")
        .join(path)
}

/// Reads the log to its end; the bytes read after each sample.
fn read_through(path: &Path) -> (u64, Vec<u64>) {
    let mut reader = LogReader::open(path, &ReadOptions::default()).unwrap();
    let progress = reader.progress();
    let size = std::fs::metadata(path).unwrap().len();
    assert_eq!(progress.total(), size, "{}", path.display());
    assert!(
        progress.read() < size,
        "nothing read yet of {}",
        path.display()
    );
    let mut seen = Vec::new();
    for sample in reader.by_ref() {
        sample.unwrap();
        seen.push(progress.read());
    }
    (size, seen)
}

#[test]
fn a_csv_log_is_read_to_its_last_byte_and_never_back() {
    let (size, seen) = read_through(&testdata("csv/small.csv"));
    assert!(seen.windows(2).all(|w| w[0] <= w[1]), "{seen:?}");
    assert_eq!(*seen.last().unwrap(), size);
}

#[test]
fn an_mcap_log_counts_the_bytes_of_its_data_section() {
    let path = testdata("examples/quick.mcap");
    let (size, seen) = read_through(&path);
    assert!(seen.windows(2).all(|w| w[0] <= w[1]), "{seen:?}");
    // The messages end with the data section; the summary and footer after it are not read
    // for samples, so the last message lies within them of the end.
    let last = *seen.last().unwrap();
    assert!(last > size / 2 && last <= size, "{last} of {size}");
}
