//! Reading a log on a second thread while the caller computes on the first.

use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::thread::JoinHandle;

use calib_core::SampleBatch;

use crate::{Error, LogReader};

/// Samples per batch: large enough that the hand-over costs nothing per sample, small enough that
/// the first batch of a small log arrives at once.
pub const BATCH: usize = 4096;
/// Batches filled ahead of the caller: 131,072 samples, some 13 ms of a 10⁷-message log's
/// reading, so that neither side waits for the other when the system hands a core to a third
/// thread for a scheduler tick (4 ms). Four batches left both cores idle some 15 % of the
/// reading; 32 shortened `calib csrr` on the 10⁷-message log by 0.1–0.2 s (16 and 128: no
/// better), for 4 MB more.
pub const DEPTH: usize = 32;

/// What fills batches of samples: a [`LogReader`], or a test's stand-in.
pub trait BatchSource: Send + 'static {
    /// Why reading stopped early.
    type Error: Send + 'static;
    /// Readings per sample.
    fn width(&self) -> usize;
    /// Appends samples to `batch` until it holds `max` (fewer only at the end of the log); those
    /// read before an error stay in `batch`, and the error ends the log.
    fn fill(&mut self, batch: &mut SampleBatch, max: usize) -> Result<(), Self::Error>;
}

impl BatchSource for LogReader {
    type Error = Error;

    fn width(&self) -> usize {
        self.channels().len()
    }

    fn fill(&mut self, batch: &mut SampleBatch, max: usize) -> Result<(), Error> {
        LogReader::fill(self, batch, max)
    }
}

/// Batches of a reader's samples, filled ahead on a worker thread.
///
/// ```
/// use calib_core::SampleBatch;
/// use calib_io::{BatchSource, Prefetch};
///
/// /// The numbers below `end`, one reading per sample.
/// struct Count { next: u32, end: u32 }
/// impl BatchSource for Count {
///     type Error = String;
///     fn width(&self) -> usize { 1 }
///     fn fill(&mut self, batch: &mut SampleBatch, max: usize) -> Result<(), String> {
///         while batch.len() < max && self.next < self.end {
///             batch.push(f64::from(self.next), &[f64::from(self.next)], None);
///             self.next += 1;
///         }
///         Ok(())
///     }
/// }
///
/// let mut ahead = Prefetch::new(Count { next: 0, end: 10_000 });
/// let mut sum = 0.0;
/// while let Some(batch) = ahead.next_batch() {
///     sum += batch.unwrap().iter().map(|s| s.values[0]).sum::<f64>();
/// }
/// assert_eq!(sum, 49_995_000.0);
/// assert_eq!(ahead.finish().next, 10_000);
/// ```
///
/// Every method streams a log once: decompressing and decoding a sample costs about as much as
/// segmenting and binning it, and on one thread the two add up. [`Prefetch`] moves the reader to
/// a worker thread that fills [`SampleBatch`]es ahead of the caller, handed over through a
/// bounded channel and handed back empty to be filled again: wall time approaches the slower of
/// the two threads instead of their sum, and nothing is allocated per sample once the first
/// batches exist. Memory stays bounded: at most 32 batches (`DEPTH`) of 4096 samples
/// (`BATCH`) wait at any time.
///
/// The reader comes back with [`Prefetch::finish`], its diagnostics (truncation, alignment)
/// complete. The samples and the first error are exactly the reader's: the worker stops after
/// the first error, as every caller does. Where no thread can be started (or one is asked for,
/// [`Prefetch::inline`]) the reader runs on the caller's thread, unchanged.
pub struct Prefetch<R: BatchSource> {
    inner: Inner<R>,
    /// The batch last handed to the caller.
    current: SampleBatch,
    /// The error that ended the log, once the samples before it are handed on.
    error: Option<R::Error>,
    /// The log has ended (or failed).
    ended: bool,
}

/// A batch filled on the worker, and the error that ended the log after its samples.
type Filled<E> = (SampleBatch, Option<E>);

enum Inner<R: BatchSource> {
    Ahead {
        full: Receiver<Filled<R::Error>>,
        /// Batches handed back to be filled again.
        empty: SyncSender<SampleBatch>,
        worker: JoinHandle<Option<R>>,
    },
    /// No thread could be started, or none was wanted.
    Inline(R),
}

impl<R: BatchSource> Prefetch<R> {
    /// Samples per batch: large enough that the hand-over costs nothing per sample, small
    /// enough that the first batch of a small log arrives at once.
    pub const BATCH: usize = BATCH;

    /// Starts reading `reader` on a worker thread.
    pub fn new(reader: R) -> Self {
        let width = reader.width();
        let (full_tx, full) = sync_channel::<Filled<R::Error>>(DEPTH);
        let (empty, empty_rx) = sync_channel::<SampleBatch>(DEPTH + 2);
        // The reader is handed over only once the thread runs, so that a thread that cannot be
        // started leaves it here.
        let (reader_tx, reader_rx) = sync_channel::<R>(1);
        let spawned = std::thread::Builder::new()
            .name("calib-reader".into())
            .spawn(move || {
                let mut reader = reader_rx.recv().ok()?;
                loop {
                    let mut batch = empty_rx
                        .try_recv()
                        .unwrap_or_else(|_| SampleBatch::with_capacity(width, BATCH));
                    batch.clear();
                    let error = reader.fill(&mut batch, BATCH).err();
                    let ended = error.is_some() || batch.len() < BATCH;
                    // Stop at the end, after an error, or when the caller has gone.
                    let wanted = !batch.is_empty() || error.is_some();
                    if (wanted && full_tx.send((batch, error)).is_err()) || ended {
                        return Some(reader);
                    }
                }
            });
        let inner = match spawned {
            Ok(worker) => match reader_tx.send(reader) {
                Ok(()) => Inner::Ahead {
                    full,
                    empty,
                    worker,
                },
                Err(returned) => Inner::Inline(returned.0),
            },
            Err(_) => Inner::Inline(reader),
        };
        Prefetch::with(inner, width)
    }

    /// Reads `reader` on the caller's thread, batch by batch, as [`new`](Self::new) would on a
    /// worker (one thread in all).
    pub fn inline(reader: R) -> Self {
        let width = reader.width();
        Prefetch::with(Inner::Inline(reader), width)
    }

    fn with(inner: Inner<R>, width: usize) -> Self {
        Prefetch {
            inner,
            current: SampleBatch::with_capacity(width, BATCH),
            error: None,
            ended: false,
        }
    }

    /// The next batch of samples (never empty), or `None` at the end of the log. An error comes
    /// after the samples read before it, and ends the log.
    pub fn next_batch(&mut self) -> Option<Result<&SampleBatch, R::Error>> {
        if let Some(e) = self.error.take() {
            return Some(Err(e));
        }
        if self.ended {
            return None;
        }
        match &mut self.inner {
            Inner::Inline(reader) => {
                self.current.clear();
                self.error = reader.fill(&mut self.current, BATCH).err();
                self.ended = self.error.is_some() || self.current.len() < BATCH;
            }
            Inner::Ahead { full, empty, .. } => match full.recv() {
                Ok((batch, error)) => {
                    // The batch handed on last goes back to be filled again (or is dropped if
                    // the worker has enough).
                    let _ = empty.try_send(std::mem::replace(&mut self.current, batch));
                    self.error = error;
                    self.ended = self.error.is_some();
                }
                Err(_) => {
                    self.ended = true;
                    return None;
                }
            },
        }
        if self.current.is_empty() {
            return self.error.take().map(Err);
        }
        Some(Ok(&self.current))
    }

    /// Stops reading ahead and returns the reader: its diagnostics are complete once
    /// [`next_batch`](Self::next_batch) has returned `None`.
    pub fn finish(self) -> R {
        match self.inner {
            Inner::Inline(reader) => reader,
            Inner::Ahead {
                full,
                empty,
                worker,
                ..
            } => {
                // Closing the channels stops a worker that is still reading ahead.
                drop(full);
                drop(empty);
                match worker.join() {
                    Ok(reader) => reader.expect("a running worker has received the reader"),
                    Err(panic) => std::panic::resume_unwind(panic),
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A reader of the numbers below `end` that counts how far it was read and fails at
    /// `fail_at`.
    struct Counting {
        next: usize,
        end: usize,
        fail_at: Option<usize>,
    }

    impl BatchSource for Counting {
        type Error = String;

        fn width(&self) -> usize {
            2
        }

        fn fill(&mut self, batch: &mut SampleBatch, max: usize) -> Result<(), String> {
            while batch.len() < max && self.next < self.end {
                let i = self.next;
                self.next += 1;
                if Some(i) == self.fail_at {
                    return Err(format!("bad item {i}"));
                }
                batch.push(i as f64, &[i as f64, -(i as f64)], None);
            }
            Ok(())
        }
    }

    fn counting(end: usize, fail_at: Option<usize>) -> Counting {
        Counting {
            next: 0,
            end,
            fail_at,
        }
    }

    /// Every sample's number, then the error if one ended the log.
    fn drain(ahead: &mut Prefetch<Counting>) -> (Vec<usize>, Option<String>) {
        let mut got = Vec::new();
        while let Some(batch) = ahead.next_batch() {
            match batch {
                Ok(batch) => {
                    assert!(!batch.is_empty(), "no empty batch is handed on");
                    for s in batch.iter() {
                        assert_eq!(s.values, [s.t, -s.t]);
                        got.push(s.t as usize);
                    }
                }
                Err(e) => {
                    assert!(ahead.next_batch().is_none(), "an error ends the log");
                    return (got, Some(e));
                }
            }
        }
        (got, None)
    }

    #[test]
    fn samples_come_in_order_and_the_reader_comes_back_exhausted() {
        for end in [0, 1, BATCH - 1, BATCH, BATCH + 1, 5 * BATCH + 17] {
            for mut ahead in [
                Prefetch::new(counting(end, None)),
                Prefetch::inline(counting(end, None)),
            ] {
                let (got, error) = drain(&mut ahead);
                assert_eq!(got, (0..end).collect::<Vec<_>>());
                assert_eq!(error, None);
                assert!(ahead.next_batch().is_none(), "stays exhausted");
                assert_eq!(ahead.finish().next, end);
            }
        }
    }

    #[test]
    fn the_first_error_ends_the_log_after_the_samples_before_it() {
        for mut ahead in [
            Prefetch::new(counting(3 * BATCH, Some(BATCH + 5))),
            Prefetch::inline(counting(3 * BATCH, Some(BATCH + 5))),
        ] {
            let (got, error) = drain(&mut ahead);
            assert_eq!(got, (0..BATCH + 5).collect::<Vec<_>>());
            assert_eq!(error, Some(format!("bad item {}", BATCH + 5)));
            // Nothing was read past the error.
            assert_eq!(ahead.finish().next, BATCH + 6);
        }
    }

    #[test]
    fn a_caller_that_stops_early_gets_the_reader_back_without_reading_it_all() {
        let end = 1_000 * BATCH;
        let mut ahead = Prefetch::new(counting(end, None));
        let first = ahead.next_batch().expect("a batch").expect("no error");
        assert_eq!(first.get(0).t, 0.0);
        let reader = ahead.finish();
        // At most the batches that fit in the channel, the one being handed over and the one
        // being filled were read.
        assert!(reader.next <= (DEPTH + 3) * BATCH, "read {}", reader.next);
    }
}
