//! Exports of a 72-pole-pair sensor's table (orders 72, 144, 216 beside order 1) loaded by each
//! controller's arithmetic, re-implemented here in `f32` as the firmware computes, against the
//! known truth: the table never makes the sensor worse, and no order the sensor never had
//! appears (issue 30: a 256-entry moteus table folded 144 and 216 onto 112 and 40).
//!
//! `cargo test -p calib-io --test it controller_firmware:: -- --nocapture` prints the figures.

use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::{ErrorMap, FourierSeries, Harmonic};
use calib_io::export::{ExportOptions, Format, export, moteus, simplefoc};
use std::f64::consts::TAU;

/// The truth: 20″ at order 1, 30″ at 72, 15″ at 144, 8″ at 216.
fn truth() -> FourierSeries {
    FourierSeries::from_harmonics(
        &[
            Harmonic::from_arcsec_deg(1, 20.0, 10.0),
            Harmonic::from_arcsec_deg(72, 30.0, 40.0),
            Harmonic::from_arcsec_deg(144, 15.0, -70.0),
            Harmonic::from_arcsec_deg(216, 8.0, 120.0),
        ],
        216,
    )
}

/// The source table: the truth on 57,600 points (0.00625° steps).
fn source() -> ErrorMap {
    ErrorMap::from_series(&truth(), 57_600)
}

/// The table and scale of source 0 from `conf set` lines.
fn moteus_table(text: &str) -> (Vec<i8>, f32) {
    let mut table = vec![0i8; moteus::TABLE_SIZE];
    let mut scale = f32::NAN;
    for line in text.lines() {
        let Some(rest) = line.strip_prefix("conf set motor_position.sources.0.compensation_")
        else {
            continue;
        };
        let (key, value) = rest.split_once(' ').unwrap();
        match key.strip_prefix("table.") {
            Some(i) => table[i.parse::<usize>().unwrap()] = value.parse().unwrap(),
            None => scale = value.parse().unwrap(),
        }
    }
    (table, scale)
}

/// moteus `lerp` (fw/motor_position.h) in `f32`: the correction added, revolutions.
fn lerp(array: &[i8], scale: f32, ratio: f32) -> f32 {
    let size = array.len();
    let left = (size as i64 - 1).min((ratio * size as f32) as i64) as usize;
    let right = (left + 1) % size;
    let fraction = (ratio - left as f32 / size as f32) * size as f32;
    f32::from(array[left]) * scale * (1.0 - fraction) + f32::from(array[right]) * scale * fraction
}

/// SimpleFOC `CalibratedSensor::getSensorAngle()` since PR #75, in `f32`: the codes decoded by
/// `decodeOffsetU16` and interpolated; returns what it subtracts from `raw`, radians.
fn simplefoc_offset(codes: &[u16], raw: f32) -> f32 {
    let n_lut = codes.len();
    let resolution = std::f32::consts::TAU / n_lut as f32;
    let resolution_inv = 1.0 / resolution;
    let index = (raw * resolution_inv) as usize;
    let lower = (f32::from(codes[index]) - 32767.0) / 10430.219;
    let next = if index >= n_lut - 1 { 0 } else { index + 1 };
    let higher = (f32::from(codes[next]) - 32767.0) / 10430.219;
    let distance = (raw - index as f32 * resolution) * resolution_inv;
    (1.0 - distance) * lower + distance * higher
}

/// The codes of `uint16_t calibrationLut[N] = {…};`.
fn simplefoc_codes(text: &str) -> Vec<u16> {
    let open = text.find("] = {").unwrap() + 5;
    let close = open + text[open..].find("};").unwrap();
    text[open..close]
        .split([',', '\n', ' '])
        .filter(|t| !t.is_empty())
        .map(|t| t.parse().unwrap())
        .collect()
}

/// What the sensor is left with, arcseconds, on `n` uniform readings: `truth − applied`.
fn residual(n: usize, applied: impl Fn(usize) -> f64) -> Vec<f64> {
    let truth = truth();
    (0..n)
        .map(|k| (truth.eval(TAU * k as f64 / n as f64) - applied(k)) * ARCSEC_PER_RAD)
        .collect()
}

fn pp(v: &[f64]) -> f64 {
    v.iter().copied().fold(f64::NEG_INFINITY, f64::max)
        - v.iter().copied().fold(f64::INFINITY, f64::min)
}

/// Amplitude of order `h` in `v` (uniform over a turn).
fn order(v: &[f64], h: usize) -> f64 {
    let n = v.len() as f64;
    let (mut c, mut s) = (0.0, 0.0);
    for (k, x) in v.iter().enumerate() {
        let a = TAU * (h * k) as f64 / n;
        c += x * a.cos();
        s += x * a.sin();
    }
    2.0 * (c * c + s * s).sqrt() / n
}

/// moteus through its `lerp`, at every count of a 14-bit encoder.
fn moteus_residual(text: &str) -> Vec<f64> {
    let (table, scale) = moteus_table(text);
    let cpr = 16384u32;
    let inv_cpr = 1.0 / cpr as f32;
    residual(cpr as usize, |k| {
        // The correction is added: the error it removes is its negation.
        -f64::from(lerp(&table, scale / 127.0, k as f32 * inv_cpr)) * TAU
    })
}

#[test]
fn moteus_keeps_what_256_entries_hold_and_folds_nothing() {
    let map = source();
    let uncorrected = residual(16384, |_| 0.0);
    // Before: the table resampled to 256 entries by interpolation, as calib did.
    let folded = export(
        &map.resample_linear(256).into(),
        &ExportOptions::new(Format::Moteus, "before"),
    )
    .unwrap();
    let before = moteus_residual(&folded.text);
    let out = export(
        &map.clone().into(),
        &ExportOptions::new(Format::Moteus, "after"),
    )
    .unwrap();
    let after = moteus_residual(&out.text);
    println!(
        "moteus 256: uncorrected {:.2}″ p-p; folded {:.2}″ p-p (order 40 {:.2}″); now {:.2}″ p-p \
         (order 40 {:.3}″)",
        pp(&uncorrected),
        pp(&before),
        order(&before, 40),
        pp(&after),
        order(&after, 40)
    );
    // Orders 144 and 216 cannot be held by 256 entries: they are left as they are (15″ and 8″,
    // 46″ p-p at most), order 72 is corrected but for its interpolation between entries
    // (30″·(72·2π/256)²/8 = 11.7″ at most) and half a code (58″/127/2 = 0.23″).
    assert!(
        pp(&after) < 2.0 * (15.0 + 8.0 + 11.7 + 0.3),
        "{}",
        pp(&after)
    );
    assert!(pp(&after) < pp(&uncorrected));
    // Nothing folded onto order 40 (216's image on 256 entries): below the interpolation's
    // images of order 72 there (at 256 − 72 = 184, not 40) and half a code.
    assert!(order(&after, 40) < 0.3, "{}", order(&after, 40));
    assert!(order(&before, 40) > 3.0, "{}", order(&before, 40));
    // The header names the dropped orders with their p-p, and warns: most of what is left is them.
    let dropped = out
        .header
        .iter()
        .find(|l| l.starts_with("harmonics: "))
        .unwrap();
    assert!(
        dropped.contains("order 144 30.0000") && dropped.contains("order 216 16.0000"),
        "{dropped}"
    );
    assert!(
        out.warnings.len() == 1 && out.warnings[0].contains("cannot hold"),
        "{:?}",
        out.warnings
    );
}

#[test]
fn simplefoc_gets_a_size_that_holds_the_orders_and_never_folds() {
    let map = source();
    let uncorrected = residual(100_000, |_| 0.0);
    let simplefoc_residual = |text: &str| {
        let codes = simplefoc_codes(text);
        residual(100_000, |k| {
            let raw = (TAU * k as f64 / 100_000.0) as f32;
            f64::from(simplefoc_offset(&codes, raw))
        })
    };
    let out = export(
        &map.clone().into(),
        &ExportOptions::new(Format::Simplefoc, "t"),
    )
    .unwrap();
    let n = simplefoc_codes(&out.text).len();
    let sized = simplefoc_residual(&out.text);
    let mut opts = ExportOptions::new(Format::Simplefoc, "t");
    opts.points = Some(200);
    let small = export(&map.clone().into(), &opts).unwrap();
    let at_200 = simplefoc_residual(&small.text);
    let folded = simplefoc_residual(
        &export(
            &map.resample_linear(200).into(),
            &ExportOptions::new(Format::Simplefoc, "t"),
        )
        .unwrap()
        .text,
    );
    println!(
        "simplefoc: uncorrected {:.2}″ p-p; default {n} entries {:.2}″ p-p; 200 entries {:.2}″ \
         p-p, folded {:.2}″ p-p (order 16 = 216 − 200: {:.2}″ folded, {:.3}″ now)",
        pp(&uncorrected),
        pp(&sized),
        pp(&at_200),
        pp(&folded),
        order(&folded, 16),
        order(&at_200, 16)
    );
    // The default holds 216 (N > 432) and interpolates to a quarter code (4.9″), π·√(2·(20 +
    // 30·72² + 15·144² + 8·216²)″ / 19.7757″) = 915.6 entries: with rounding to half a code,
    // every reading within three quarters of a code (14.8″) plus f32 rounding of raw (0.1″).
    assert_eq!(n, 916);
    let worst = sized.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let code = simplefoc::QUANTUM_RAD * ARCSEC_PER_RAD;
    assert!(worst <= 0.75 * code + 0.1, "{worst}″");
    // 200 entries hold order 72 but not 144 or 216: those stay, nothing is folded onto order 16.
    // What is there is the rounding to the 19.8″ code, spread over the table's 100 orders: about
    // (q/2)/√3·√(2/200) = 0.57″ an order.
    assert!(order(&at_200, 16) < 1.5, "{}", order(&at_200, 16));
    assert!(order(&folded, 16) > 3.0, "{}", order(&folded, 16));
}
