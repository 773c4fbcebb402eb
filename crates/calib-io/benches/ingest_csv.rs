//! CSV ingest speed: `CsvReader` rows/s against reading the same bytes and doing nothing (`cat`).
//!
//! Two 1,000,000-row, 3-channel logs are generated in a temporary directory at run time:
//! - `decimals=6`: what a DAQ typically writes (`t` and readings with 6 decimals);
//! - `shortest`: what `CsvWriter` writes for arbitrary doubles (up to 17 significant digits), the
//!   slowest realistic case for float parsing.
//!
//! Run: `cargo bench -p calib-io --bench ingest_csv`. The target is ≥ 3 M rows/s on one core.
//!
//! Criterion measures wall time, which on a machine busy with other work (a shared build box)
//! understates what one core does. The `ingest_csv_cpu` group therefore measures the same passes
//! in the thread's own CPU time (Linux: `/proc/thread-self/schedstat`), which load barely moves.

use calib_core::{AngleUnit, Channel, Sample};
use calib_io::ReadOptions;
use calib_io::csv_log::{CsvReader, CsvWriter};
use criterion::measurement::{Measurement, ValueFormatter, WallTime};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use std::hint::black_box;
use std::io::Write;
use std::path::Path;
use std::time::Duration;

const ROWS: u64 = 1_000_000;

/// A reproducible stream of readings: three heads 120° apart turning at 1 rev/s, sampled at
/// 1 kHz, with a little pseudo-random noise so the digits vary.
fn samples() -> impl Iterator<Item = Sample> {
    let mut state: u64 = 7;
    (0..ROWS).map(move |i| {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let noise = ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 1e-5;
        let t = i as f64 * 1e-3;
        let base = t * std::f64::consts::TAU;
        Sample {
            t,
            values: (0..3)
                .map(|k| {
                    (base + noise + k as f64 * std::f64::consts::TAU / 3.0)
                        .rem_euclid(std::f64::consts::TAU)
                })
                .collect(),
            session: None,
        }
    })
}

fn write_decimals(path: &Path) {
    let mut out = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    writeln!(out, "t,a,b,c").unwrap();
    for s in samples() {
        let d: Vec<f64> = s.values.iter().map(|v| v.to_degrees()).collect();
        writeln!(out, "{:.6},{:.6},{:.6},{:.6}", s.t, d[0], d[1], d[2]).unwrap();
    }
    out.flush().unwrap();
}

fn write_shortest(path: &Path) {
    let channels: Vec<Channel> = ["a", "b", "c"]
        .iter()
        .map(|n| Channel {
            name: n.to_string(),
            unit: AngleUnit::Deg,
        })
        .collect();
    let mut w = CsvWriter::create(path, &channels, AngleUnit::Deg, false).unwrap();
    for s in samples() {
        w.write(&s).unwrap();
    }
    w.finish().unwrap();
}

/// CPU time this thread has run, nanoseconds (user and system: `cat`'s copying is in the kernel).
struct ThreadCpu {
    /// Only lends its formatter: the values are nanoseconds, as for wall time.
    wall: WallTime,
}

impl ThreadCpu {
    fn now() -> u64 {
        std::fs::read_to_string("/proc/thread-self/schedstat")
            .ok()
            .and_then(|s| s.split_whitespace().next()?.parse().ok())
            .expect("/proc/thread-self/schedstat (Linux) gives the thread's CPU time")
    }
}

impl Measurement for ThreadCpu {
    type Intermediate = u64;
    type Value = u64;
    fn start(&self) -> u64 {
        Self::now()
    }
    fn end(&self, start: u64) -> u64 {
        Self::now().saturating_sub(start)
    }
    fn add(&self, a: &u64, b: &u64) -> u64 {
        a + b
    }
    fn zero(&self) -> u64 {
        0
    }
    fn to_f64(&self, v: &u64) -> f64 {
        *v as f64
    }
    fn formatter(&self) -> &dyn ValueFormatter {
        self.wall.formatter()
    }
}

fn ingest_wall(c: &mut Criterion) {
    ingest(c, "ingest_csv");
}

fn ingest_cpu(c: &mut Criterion<ThreadCpu>) {
    ingest(c, "ingest_csv_cpu");
}

fn ingest<M: Measurement>(c: &mut Criterion<M>, group_name: &str) {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        ("decimals=6", write_decimals as fn(&Path)),
        ("shortest", write_shortest),
    ];
    let mut group = c.benchmark_group(group_name);
    // A whole pass over a million rows takes a few tenths of a second: ten samples are plenty
    // for a stable median and keep the bench short.
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(5));
    group.throughput(Throughput::Elements(ROWS));
    for (name, write) in cases {
        let path = dir.path().join(format!("{name}.csv"));
        write(&path);
        let bytes = std::fs::metadata(&path).unwrap().len();
        eprintln!(
            "{name}: {bytes} bytes, {:.1} bytes/row",
            bytes as f64 / ROWS as f64
        );

        group.bench_function(format!("rows=1e6/channels=3/{name}/cat"), |b| {
            b.iter(|| {
                let mut f = std::fs::File::open(&path).unwrap();
                black_box(std::io::copy(&mut f, &mut std::io::sink()).unwrap())
            })
        });
        group.bench_function(format!("rows=1e6/channels=3/{name}/csv_reader"), |b| {
            b.iter(|| {
                let reader = CsvReader::open(&path, &ReadOptions::default()).unwrap();
                let mut checksum = 0.0;
                let mut rows = 0u64;
                for s in reader {
                    let s = s.unwrap();
                    checksum += s.values[0];
                    rows += 1;
                }
                assert_eq!(rows, ROWS);
                black_box(checksum)
            })
        });
    }
    group.finish();
}

criterion_group!(wall, ingest_wall);
criterion_group! {
    name = cpu;
    config = Criterion::default().with_measurement(ThreadCpu { wall: WallTime });
    targets = ingest_cpu
}
criterion_main!(wall, cpu);
