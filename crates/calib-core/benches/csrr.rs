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
//! Last, the solve's growth (`csrr-solve/threads=T/samples=N/orders=H`, issue 51): the joint
//! solve alone (`stages::solve`, as above) at orders `H` = 100, 500, 1000, 2000 and 5000 on logs of
//! ~10⁵, 10⁶, 10⁷ and 10⁸ samples (the same sensors at 12,500 samples per revolution, enough for
//! order 5000; short ramps, pauses and turns; each log binned as it is simulated, never held), on
//! one and on two threads (a rayon pool of each size). Binning is linear in the samples and
//! measured above; the solve sees only the bins (at most 65,536 per session), so its cost stops
//! growing with the samples once they fill them, and grows with the orders as the FFT grid does.
//! `CSRR_GROWTH=1e5,1e6` picks the logs (default 1e5, 1e6, 1e7; 1e8 takes a minute to simulate).
//!
//! ```text
//! cargo bench -p calib-core --bench csrr
//! cargo bench -p calib-core --bench csrr -- 'samples=1e5'    # the small log only
//! cargo bench -p calib-core --bench csrr -- 'csrr-stages'    # the stages only
//! CSRR_GROWTH=1e5,1e6,1e7,1e8 cargo bench -p calib-core --bench csrr -- 'csrr-solve'
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
    scenario_with(rate_hz, speed_rpm, revolutions, [1.0, 1.0, 2.0])
}

/// [`scenario`] with its ramps, pauses and turns of `[ramp_s, pause_s, turn_s]`.
fn scenario_with(rate_hz: f64, speed_rpm: f64, revolutions: f64, times: [f64; 3]) -> Scenario {
    let [ramp, pause, turn] = times;
    let text = format!(
        "seed = 72\nrate_hz = {rate_hz}\nspeed_rpm = {speed_rpm}\nwrap = true\n{SENSORS}\n\
         [procedure]\nrelative_deg = [0.0, 7.3, 23.9, 61.7, 151.1]\nrevolutions = {revolutions}\n\
         ramp_s = {ramp}\npause_s = {pause}\nturn_s = {turn}\n"
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
    let binned = stages::bin(readings.iter().copied());
    eprintln!("{label}: {} bins", binned.bins());
    let mut group = c.benchmark_group(format!("csrr-stages/samples={label}"));
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(1));
    group.measurement_time(Duration::from_secs(5));
    group.bench_function("binning", |b| {
        b.iter(|| stages::bin(black_box(readings).iter().copied()))
    });
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

/// The logs of the solve's growth: a label, revolutions per session at 12,500 samples per
/// revolution (60 r/min at 12.5 kHz), ramps of 0.05 s, pauses of 0.05 s, turns of 0.1 s.
const GROWTH_LOGS: [(&str, f64); 4] =
    [("1e5", 1.3), ("1e6", 15.7), ("1e7", 159.7), ("1e8", 1599.7)];

/// The orders of the solve's growth.
const GROWTH_ORDERS: [usize; 5] = [100, 500, 1000, 2000, 5000];

/// The solve alone at each of [`GROWTH_ORDERS`] on each log of [`GROWTH_LOGS`] that
/// `CSRR_GROWTH` names, on one and on two threads (see the module docs).
fn solve_growth(c: &mut Criterion) {
    let chosen = std::env::var("CSRR_GROWTH").unwrap_or_else(|_| "1e5,1e6,1e7".into());
    for (label, revolutions) in GROWTH_LOGS {
        if !chosen.split(',').any(|l| l.trim() == label) {
            continue;
        }
        let start = Instant::now();
        let scenario = scenario_with(12_500.0, 60.0, revolutions, [0.05, 0.05, 0.1]);
        let mut samples = 0u64;
        let binned = stages::bin(scenario.samples().expect("valid scenario").map(|s| {
            samples += 1;
            (s.t, s.values[0], s.values[1])
        }));
        eprintln!(
            "growth {label}: {samples} samples, {} bins, simulated and binned in {:.1} s",
            binned.bins(),
            start.elapsed().as_secs_f64()
        );
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("a thread pool");
            let mut group =
                c.benchmark_group(format!("csrr-solve/threads={threads}/samples={label}"));
            group.sample_size(10);
            group.warm_up_time(Duration::from_millis(500));
            group.measurement_time(Duration::from_secs(3));
            for orders in GROWTH_ORDERS {
                group.bench_function(format!("orders={orders}"), |b| {
                    b.iter(|| pool.install(|| stages::solve(black_box(&binned), orders)))
                });
            }
            group.finish();
        }
    }
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

criterion_group!(benches, csrr, solve_growth);
criterion_main!(benches);
