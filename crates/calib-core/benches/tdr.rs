//! The spin-down (TDR) fit end to end in memory: [`Tdr::finish`] on a coast already pushed —
//! finding the coast, the spectra of its samples, the screening of 500 orders, drag, the final
//! fit and the residual's structure. No file is read: the samples come from
//! [`calib_core::simulate`] (`testdata/scenarios/spindown.toml` — an air-bearing coast from
//! 600 r/min — sampled at 100 kHz for 10 s, 10⁶ samples, the first tenth of the coast log of
//! `benches/end-to-end.sh`) and are pushed once, outside the timed loop; each iteration times a
//! clone of the pushed `Tdr` and its `finish`.
//!
//! ```text
//! cargo bench -p calib-core --bench tdr
//! ```

use std::hint::black_box;
use std::time::{Duration, Instant};

use calib_core::simulate::Scenario;
use calib_core::tdr::{Tdr, TdrOptions};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};

fn tdr(c: &mut Criterion) {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../testdata/scenarios/spindown.toml"
    ))
    .expect("the spin-down scenario");
    let text = text
        .replace("rate_hz = 2000.0", "rate_hz = 100000.0")
        .replace("duration_s = 30.0", "duration_s = 10.0");
    let scenario: Scenario = toml::from_str(&text).expect("a valid scenario");
    let mut pushed = Tdr::new(TdrOptions::default());
    let mut count = 0u64;
    for s in scenario.samples().expect("valid scenario") {
        pushed.push(s.t, s.values[0]);
        count += 1;
    }
    let start = Instant::now();
    let cal = pushed.clone().finish().expect("the bench coast calibrates");
    eprintln!(
        "{count} samples: {} used, orders 1–{} tested, {} kept, motion degree {}; one finish {:.2} s",
        cal.samples_used,
        cal.max_order,
        cal.orders.len(),
        cal.motion.degree,
        start.elapsed().as_secs_f64()
    );
    let mut group = c.benchmark_group("tdr");
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(5));
    group.throughput(Throughput::Elements(count));
    group.bench_function("finish/samples=1e6", |b| {
        b.iter(|| black_box(pushed.clone()).finish())
    });
    group.finish();
}

criterion_group!(benches, tdr);
criterion_main!(benches);
