//! How far a reader has got through its log, for a progress line with a total and an ETA.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

/// What a [`ReadProgress`] counts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ProgressUnit {
    /// Bytes of the log's file.
    Bytes,
    /// Messages (a bag's rows).
    Messages,
}

/// Bytes (or messages) of a log read so far, of its size.
///
/// A reader counts the bytes of its file it has read into a [`ReadProgress`]; a clone of it
/// reads the count from another thread (the reader runs on its own, [`Prefetch`](crate::Prefetch)). The
/// total is the file's size, known before the first sample: a CSV log's rows, an MCAP log's
/// records and chunks all lie between its first and last byte. A rosbag2 SQLite bag, whose rows
/// are not read in the file's order, counts its messages instead, of the number its `messages`
/// table holds for the topics read.
#[derive(Debug, Clone)]
pub struct ReadProgress {
    read: Arc<AtomicU64>,
    total: u64,
    unit: ProgressUnit,
}

impl ReadProgress {
    /// No byte read yet of a file of `total` bytes.
    pub(crate) fn new(total: u64) -> Self {
        ReadProgress {
            read: Arc::new(AtomicU64::new(0)),
            total,
            unit: ProgressUnit::Bytes,
        }
    }

    /// No message read yet of `total`.
    pub(crate) fn messages(total: u64) -> Self {
        ReadProgress {
            unit: ProgressUnit::Messages,
            ..ReadProgress::new(total)
        }
    }

    /// What it counts.
    pub fn unit(&self) -> ProgressUnit {
        self.unit
    }

    /// Records that the reader has got to byte `at`.
    pub(crate) fn set(&self, at: u64) {
        self.read.store(at, Ordering::Relaxed);
    }

    /// Bytes (messages) read so far (at most [`total`](Self::total)).
    pub fn read(&self) -> u64 {
        self.read.load(Ordering::Relaxed).min(self.total)
    }

    /// The file's size in bytes (the messages to read).
    pub fn total(&self) -> u64 {
        self.total
    }
}
