//! The CSRR joint solver end to end in memory: segmentation, binning and the solve, from
//! synchronized `(t, x, y)` readings to both error maps ([`Csrr::push`] every sample, then
//! [`Csrr::finish`]). No file is read: the readings come from [`calib_core::simulate`] and are
//! generated once, outside the timed loop, into a `Vec<(t, x, y)>` (10⁷ × 24 B = 240 MB).
//!
//! Two sizes of log:
//! - `samples=1e5`: the CSRR paper's first experiment (`testdata/scenarios/csrr72.toml`: two
//!   72-pole-pair sensors, 400 Hz, 10 r/min) with 7 revolutions per session instead of 3.
//! - `samples=1e7`: the same sensors, 5 sessions of ~190 revolutions at 60 r/min sampled at
//!   10 kHz — a long, densely sampled log; the automatic maximum order hits its cap of 2000.
//!
//! `orders=` in a case name is the maximum order the solve fitted (chosen automatically from the
//! sampling density, as `calib csrr` does without `--max-order`); each case is also run at a low
//! fixed order, to separate the cost of streaming the samples through the segmenter and binner
//! (linear in the samples) from the cost of the solve (independent of them once binned).
//! Before timing, each case runs once and prints what it solved (sessions, bins, iterations).
//!
//! Then the stages one by one (`csrr-stages/samples=…/…`, through the hidden
//! `calib_core::csrr::stages`): `binning` (segmentation and binning of every sample), `stencils`
//! (one build of the NUFFT interpolation stencils of every bin's two readings), `solve` (the
//! joint Gauss–Newton solve of the binned sessions) and `uncertainty` (the tables from the solved
//! series and their uncertainty), at the order the end-to-end case fitted.
//!
//! ```text
//! cargo bench -p calib-core --bench csrr
//! cargo bench -p calib-core --bench csrr -- 'samples=1e5'    # the small log only
//! cargo bench -p calib-core --bench csrr -- 'csrr-stages'    # the stages only
//! ```

use std::hint::black_box;
use std::time::{Duration, Instant};

use calib_core::csrr::{Calibration, Csrr, CsrrOptions, stages};
use calib_core::simulate::Scenario;
use criterion::{Criterion, Throughput, criterion_group, criterion_main};

/// The two sensors of `testdata/scenarios/csrr72.toml` (the reference encoder left out, since the
/// solve does not read it), with the rate, speed and procedure left to [`scenario`].
const SENSORS: &str = r#"
[speed]
variation_percent = 1.0

[[sensor]]
name = "a"
mount = "a"
harmonics = [
  { order = 72, amplitude_arcsec = 23.87, phase_deg = 41.0 },
  { order = 216, amplitude_arcsec = 14.03, phase_deg = -112.0 },
  { order = 144, amplitude_arcsec = 5.27, phase_deg = 167.0 },
  { order = 1, amplitude_arcsec = 2.34, phase_deg = 12.0 },
  { order = 2, amplitude_arcsec = 1.68, phase_deg = -75.0 },
  { order = 432, amplitude_arcsec = 0.96, phase_deg = 58.0 },
]
quantization_arcsec = 0.09
noise_arcsec = 0.05

[[sensor]]
name = "b"
mount = "b"
harmonics = [
  { order = 72, amplitude_arcsec = 21.40, phase_deg = -133.0 },
  { order = 216, amplitude_arcsec = 15.60, phase_deg = 24.0 },
  { order = 144, amplitude_arcsec = 4.35, phase_deg = -61.0 },
  { order = 1, amplitude_arcsec = 2.90, phase_deg = 140.0 },
  { order = 2, amplitude_arcsec = 1.31, phase_deg = 95.0 },
  { order = 432, amplitude_arcsec = 1.12, phase_deg = -170.0 },
]
quantization_arcsec = 0.09
noise_arcsec = 0.05
"#;

/// A 5-session CSRR run of the two sensors at `rate_hz` and `speed_rpm`, `revolutions` per session.
fn scenario(rate_hz: f64, speed_rpm: f64, revolutions: f64) -> Scenario {
    let text = format!(
        "seed = 72\nrate_hz = {rate_hz}\nspeed_rpm = {speed_rpm}\nwrap = true\n{SENSORS}\n\
         [procedure]\nrelative_deg = [0.0, 7.3, 23.9, 61.7, 151.1]\nrevolutions = {revolutions}\n\
         ramp_s = 1.0\npause_s = 1.0\nturn_s = 2.0\n"
    );
    toml::from_str(&text).expect("bench scenario")
}

/// The run's readings of `a` and `b`, as `(t, x, y)`.
fn readings(scenario: &Scenario) -> Vec<(f64, f64, f64)> {
    let start = Instant::now();
    let samples = scenario.samples().expect("valid scenario");
    let mut out = Vec::with_capacity(samples.len());
    out.extend(samples.map(|s| (s.t, s.values[0], s.values[1])));
    eprintln!(
        "simulated {} samples in {:.2} s",
        out.len(),
        start.elapsed().as_secs_f64()
    );
    out
}

/// Segmentation, binning and the joint solve over all of `readings`.
fn calibrate(readings: &[(f64, f64, f64)], max_order: Option<usize>) -> Calibration {
    let mut csrr = Csrr::new(CsrrOptions {
        max_order,
        ..CsrrOptions::default()
    });
    for &(t, x, y) in readings {
        csrr.push(t, x, y, None);
    }
    csrr.finish().expect("the bench scenario calibrates")
}

/// Benches one log's stages at `max_order`.
fn bench_stages(c: &mut Criterion, label: &str, readings: &[(f64, f64, f64)], max_order: usize) {
    let binned = stages::bin(readings);
    eprintln!("{label}: {} bins", binned.bins());
    let mut group = c.benchmark_group(format!("csrr-stages/samples={label}"));
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(5));
    group.bench_function("binning", |b| b.iter(|| stages::bin(black_box(readings))));
    group.bench_function(format!("stencils/orders={max_order}"), |b| {
        b.iter(|| stages::stencils(black_box(&binned), max_order))
    });
    group.bench_function(format!("solve/orders={max_order}"), |b| {
        b.iter(|| stages::solve(black_box(&binned), max_order))
    });
    let solved = stages::solve(&binned, max_order).expect("the bench scenario solves");
    group.bench_function(format!("uncertainty/orders={max_order}"), |b| {
        b.iter(|| stages::uncertainty(black_box(&solved)))
    });
    group.finish();
}

/// Benches one log at its automatic maximum order and at `low_order`, end to end, then its
/// stages at the automatic order.
fn bench_log(c: &mut Criterion, label: &str, readings: &[(f64, f64, f64)], low_order: usize) {
    let mut auto_order = low_order;
    for max_order in [None, Some(low_order)] {
        // One untimed run: names the case by the order actually fitted, and shows what it did.
        let start = Instant::now();
        let cal = calibrate(readings, max_order);
        let in_sessions: u64 = cal
            .segmentation
            .accepted_sessions()
            .map(|s| s.samples)
            .sum();
        eprintln!(
            "{label}: {} sessions ({in_sessions} samples in sessions), max order {}, {} CG iterations, \
             residual {:.3}″, {} excluded orders; one run {:.2} s",
            cal.sessions.len(),
            cal.max_order,
            cal.iterations,
            cal.residual_rms.unwrap_or(f64::NAN) * calib_core::angle::ARCSEC_PER_RAD,
            cal.excluded.len(),
            start.elapsed().as_secs_f64(),
        );
        let mut group = c.benchmark_group(format!("csrr/samples={label}"));
        // Seconds per run at 10⁷ samples: 10 runs, no long warm-up, so the whole bench stays
        // within a few minutes on 2 cores.
        group.sample_size(10);
        group.warm_up_time(Duration::from_secs(1));
        group.measurement_time(Duration::from_secs(5));
        group.throughput(Throughput::Elements(readings.len() as u64));
        group.bench_function(format!("orders={}", cal.max_order), |b| {
            b.iter(|| calibrate(black_box(readings), max_order))
        });
        group.finish();
        if max_order.is_none() {
            auto_order = cal.max_order;
        }
    }
    bench_stages(c, label, readings, auto_order);
}

fn csrr(c: &mut Criterion) {
    // 5 × (7 rev × 2400 samples/rev + ramps, pauses, turns) ≈ 1e5 samples.
    let small = readings(&scenario(400.0, 10.0, 7.0));
    bench_log(c, "1e5", &small, 100);
    drop(small);

    // 5 × (195 rev × 10000 samples/rev + ramps, pauses, turns) ≈ 1e7 samples.
    let large = readings(&scenario(10_000.0, 60.0, 195.0));
    bench_log(c, "1e7", &large, 100);
}

criterion_group!(benches, csrr);
criterion_main!(benches);
