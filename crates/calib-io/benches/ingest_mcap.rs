//! Reading a large JointState log: how much calib's reading (CDR decode into samples) costs over
//! the bare `mcap::MessageStream` iteration that any reader has to do.
//!
//! - `message_stream`: the mcap crate's iteration over the memory-mapped file, nothing decoded;
//! - `mcap_reader`: `McapReader` as an iterator, one owned `Sample` per message;
//! - `log_reader_batches`: `LogReader::fill` into one reused `SampleBatch` of 4096 samples, as
//!   the commands read on one thread (`--jobs 1`): no allocation per sample;
//! - `prefetch_batches`: the same batches filled ahead on a second thread (`Prefetch`), as the
//!   commands read by default.
//!
//! The log (1e6 messages, joints `a`, `b`, `c`, zstd) is written at run time by `McapWriter`
//! into a temporary directory; the time that takes is printed once.
//!
//! ```text
//! cargo bench -p calib-io --bench ingest_mcap
//! ```

use std::hint::black_box;
use std::path::Path;
use std::time::Instant;

use calib_core::{AngleUnit, Channel, Sample, SampleBatch};
use calib_io::Prefetch;
use calib_io::mcap_log::{DEFAULT_TOPIC, McapReader, McapWriter};
use calib_io::{LogReader, ReadOptions};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};

const MESSAGES: usize = 1_000_000;

fn write_log(path: &Path) {
    let channels: Vec<Channel> = ["a", "b", "c"]
        .iter()
        .map(|n| Channel {
            name: n.to_string(),
            unit: AngleUnit::Rad,
        })
        .collect();
    let start = Instant::now();
    let mut writer = McapWriter::create(path, &channels, DEFAULT_TOPIC).expect("create");
    let mut sample = Sample {
        t: 0.0,
        values: vec![0.0; 3],
        session: None,
    };
    for i in 0..MESSAGES {
        let x = i as f64 * 1e-3;
        sample.t = 1.0 + x;
        sample.values.copy_from_slice(&[x, x.sin(), -x]);
        writer.write(&sample).expect("write");
    }
    writer.finish().expect("finish");
    let secs = start.elapsed().as_secs_f64();
    eprintln!(
        "wrote {MESSAGES} messages ({} bytes) in {secs:.2} s: {:.2} M samples/s",
        std::fs::metadata(path).expect("metadata").len(),
        MESSAGES as f64 / secs / 1e6
    );
}

fn ingest(c: &mut Criterion) {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("bench.mcap");
    write_log(&path);

    let mut group = c.benchmark_group("ingest_mcap/messages=1e6/joints=3");
    group.sample_size(10);
    group.throughput(Throughput::Elements(MESSAGES as u64));
    group.bench_function("message_stream", |b| {
        b.iter(|| {
            let file = std::fs::File::open(&path).expect("open");
            // SAFETY: the file is private to this benchmark and not modified while mapped.
            let map = unsafe { memmap2::Mmap::map(&file) }.expect("map");
            let mut n = 0usize;
            for message in mcap::MessageStream::new(&map).expect("stream") {
                n += black_box(message.expect("message").data.len());
            }
            n
        })
    });
    group.bench_function("mcap_reader", |b| {
        b.iter(|| {
            let reader = McapReader::open(&path, &ReadOptions::default()).expect("open");
            let mut sum = 0.0;
            for sample in reader {
                sum += black_box(sample.expect("sample").values[0]);
            }
            sum
        })
    });
    group.bench_function("log_reader_batches", |b| {
        b.iter(|| {
            let mut reader = LogReader::open(&path, &ReadOptions::default()).expect("open");
            let mut batch =
                SampleBatch::with_capacity(reader.channels().len(), Prefetch::<LogReader>::BATCH);
            let mut sum = 0.0;
            loop {
                batch.clear();
                reader
                    .fill(&mut batch, Prefetch::<LogReader>::BATCH)
                    .expect("batch");
                if batch.is_empty() {
                    break;
                }
                sum += batch.iter().map(|s| black_box(s.values[0])).sum::<f64>();
            }
            sum
        })
    });
    group.bench_function("prefetch_batches", |b| {
        b.iter(|| {
            let reader = LogReader::open(&path, &ReadOptions::default()).expect("open");
            let mut ahead = Prefetch::new(reader);
            let mut sum = 0.0;
            while let Some(batch) = ahead.next_batch() {
                let batch = batch.expect("batch");
                sum += batch.iter().map(|s| black_box(s.values[0])).sum::<f64>();
            }
            sum
        })
    });
    group.finish();
}

criterion_group!(benches, ingest);
criterion_main!(benches);
