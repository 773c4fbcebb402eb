//! Reading a log on a second thread while the caller computes on the first.
//!
//! Every method streams a log once: decompressing and decoding a sample costs about as much as
//! segmenting and binning it, and on one thread the two add up. [`Prefetch`] moves the reader to
//! a worker thread that decodes ahead into batches of samples handed over through a bounded
//! channel, so wall time approaches the slower of the two instead of their sum. Memory stays
//! bounded: at most [`DEPTH`] batches of [`BATCH`] samples wait at any time.
//!
//! The reader comes back with [`Prefetch::finish`], its diagnostics (truncation, alignment)
//! complete. The order of the items and the first error are exactly the reader's: the
//! worker stops after the first error, as every caller does. Where no thread can be started the
//! reader runs on the caller's thread, unchanged.

use std::sync::mpsc::{Receiver, sync_channel};
use std::thread::JoinHandle;

/// Items per batch: large enough that the hand-over costs nothing per sample, small enough that
/// the first batch of a small log arrives at once.
pub const BATCH: usize = 4096;
/// Batches decoded ahead of the caller.
pub const DEPTH: usize = 4;

/// An iterator over another iterator's items, computed ahead on a worker thread.
///
/// ```
/// use calib_io::prefetch::Prefetch;
/// let items = (0..10_000).map(Ok::<u32, String>);
/// let mut ahead = Prefetch::new(items);
/// let sum: u64 = ahead.by_ref().map(|x| u64::from(x.unwrap())).sum();
/// assert_eq!(sum, 49_995_000);
/// let _exhausted = ahead.finish();
/// ```
pub struct Prefetch<R: Iterator> {
    inner: Inner<R>,
}

enum Inner<R: Iterator> {
    Ahead {
        batches: Receiver<Vec<R::Item>>,
        current: std::vec::IntoIter<R::Item>,
        worker: JoinHandle<Option<R>>,
    },
    /// No thread could be started.
    Inline(R),
}

impl<T, E, R> Prefetch<R>
where
    R: Iterator<Item = Result<T, E>> + Send + 'static,
    T: Send + 'static,
    E: Send + 'static,
{
    /// Starts reading `reader` on a worker thread.
    pub fn new(reader: R) -> Self {
        let (batch_tx, batches) = sync_channel::<Vec<R::Item>>(DEPTH);
        // The reader is handed over only once the thread runs, so that a thread that cannot be
        // started leaves it here.
        let (reader_tx, reader_rx) = sync_channel::<R>(1);
        let spawned = std::thread::Builder::new()
            .name("calib-reader".into())
            .spawn(move || {
                let mut reader = reader_rx.recv().ok()?;
                loop {
                    let mut batch = Vec::with_capacity(BATCH);
                    let mut last = true;
                    for item in reader.by_ref() {
                        let failed = item.is_err();
                        batch.push(item);
                        if failed {
                            break;
                        }
                        if batch.len() == BATCH {
                            last = false;
                            break;
                        }
                    }
                    // Stop at the end, after an error, or when the caller has gone.
                    if batch.is_empty() || batch_tx.send(batch).is_err() || last {
                        return Some(reader);
                    }
                }
            });
        let inner = match spawned {
            Ok(worker) => match reader_tx.send(reader) {
                Ok(()) => Inner::Ahead {
                    batches,
                    current: Vec::new().into_iter(),
                    worker,
                },
                Err(returned) => Inner::Inline(returned.0),
            },
            Err(_) => Inner::Inline(reader),
        };
        Prefetch { inner }
    }

    /// Stops reading ahead and returns the reader: its diagnostics are complete once this
    /// iterator has been exhausted.
    pub fn finish(self) -> R {
        match self.inner {
            Inner::Inline(reader) => reader,
            Inner::Ahead {
                batches, worker, ..
            } => {
                // Closing the channel stops a worker that is still reading ahead.
                drop(batches);
                match worker.join() {
                    Ok(reader) => reader.expect("a running worker has received the reader"),
                    Err(panic) => std::panic::resume_unwind(panic),
                }
            }
        }
    }
}

impl<R: Iterator> Iterator for Prefetch<R> {
    type Item = R::Item;

    fn next(&mut self) -> Option<R::Item> {
        match &mut self.inner {
            Inner::Inline(reader) => reader.next(),
            Inner::Ahead {
                batches, current, ..
            } => loop {
                if let Some(item) = current.next() {
                    return Some(item);
                }
                *current = batches.recv().ok()?.into_iter();
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A reader that counts how far it was read and fails at `fail_at`.
    struct Counting {
        next: usize,
        end: usize,
        fail_at: Option<usize>,
    }

    impl Iterator for Counting {
        type Item = Result<usize, String>;
        fn next(&mut self) -> Option<Self::Item> {
            if self.next >= self.end {
                return None;
            }
            let i = self.next;
            self.next += 1;
            Some(if Some(i) == self.fail_at {
                Err(format!("bad item {i}"))
            } else {
                Ok(i)
            })
        }
    }

    fn counting(end: usize, fail_at: Option<usize>) -> Counting {
        Counting {
            next: 0,
            end,
            fail_at,
        }
    }

    #[test]
    fn items_come_in_order_and_the_reader_comes_back_exhausted() {
        for end in [0, 1, BATCH - 1, BATCH, BATCH + 1, 5 * BATCH + 17] {
            let mut ahead = Prefetch::new(counting(end, None));
            let got: Vec<usize> = ahead.by_ref().map(Result::unwrap).collect();
            assert_eq!(got, (0..end).collect::<Vec<_>>());
            assert_eq!(ahead.next(), None, "stays exhausted");
            assert_eq!(ahead.finish().next, end);
        }
    }

    #[test]
    fn the_first_error_ends_the_stream_as_the_reader_left_it() {
        let mut ahead = Prefetch::new(counting(3 * BATCH, Some(BATCH + 5)));
        let got: Vec<_> = ahead.by_ref().collect();
        assert_eq!(got.len(), BATCH + 6);
        assert_eq!(got[BATCH + 5], Err(format!("bad item {}", BATCH + 5)));
        assert!(got[..BATCH + 5].iter().all(Result::is_ok));
        // Nothing was read past the error.
        assert_eq!(ahead.finish().next, BATCH + 6);
    }

    #[test]
    fn a_caller_that_stops_early_gets_the_reader_back_without_reading_it_all() {
        let end = 1_000 * BATCH;
        let mut ahead = Prefetch::new(counting(end, None));
        assert_eq!(ahead.next(), Some(Ok(0)));
        let reader = ahead.finish();
        // At most the batches that fit in the channel, the one being handed over and the one
        // being filled were read.
        assert!(reader.next <= (DEPTH + 3) * BATCH, "read {}", reader.next);
    }
}
