//! SimpleFOC: the look-up table of `CalibratedSensor` as C++ (`--format simplefoc` for current
//! releases, `--format simplefoc-float` for releases before PR #75).
//!
//! # What the driver does with the table
//! From `src/encoders/calibrated/CalibratedSensor.{h,cpp}` of simplefoc/Arduino-FOC-drivers as
//! changed by PR #75 ("Bug calibrated sensor + uint16 lut", merged 2025-12):
//! - `CalibratedSensor(Sensor& wrapped, int n_lut = 200, uint16_t* lut = nullptr)`: a table given
//!   at construction is used as it is (compiled in, it is kept across boots). From PR #75 until
//!   PR #83 ("Allow calibration with provided lut", merged 2026-04) `calibrate()` returns at once
//!   when a table was given; since PR #83 it measures a new table into the given array, as the
//!   float releases before PR #75 did. Read at commit `89b8e95` of Schnilz/Arduino-FOC-drivers
//!   (the fork PR #83 was merged from) and, for PR #75 alone, an upstream copy without a commit id.
//! - Entries are `uint16_t` codes of an offset in radians: `encodeOffsetU16(offset) =
//!   (uint16_t)(offset·LUT_SCALE + LUT_OFFSET)`, `decodeOffsetU16(code) = (code − LUT_OFFSET) /
//!   LUT_SCALE`, with `LUT_SCALE = 10430.2191955f` (65535/2π) and `LUT_OFFSET = 32767.0f`: one
//!   code is 2π/65535 rad ([`QUANTUM_RAD`], 19.78″), the range about ±π.
//! - `getSensorAngle()`: `raw = getMechanicalAngle()` wrapped to `[0, 2π)`, `i = (int)(raw ·
//!   n_lut/2π)`, `d = (raw − i·2π/n_lut)·n_lut/2π`, and it returns `raw − ((1 − d)·lut(i) +
//!   d·lut((i + 1) mod n_lut))` (decoded entries): entry `i` sits at raw angle `i·2π/n_lut`,
//!   interpolated linearly and periodically, and is **subtracted** — the table holds the error
//!   (`reading − true angle`, calib's `error_arcsec`). `calibrate()` fills it with that meaning:
//!   the measured error minus its mean, indexed by raw angle.
//! - `printLUT()` prints `uint16_t calibrationLut[N] = {…};`, `float zero_electric_angle = …;` and
//!   `Direction sensor_direction = …;` for pasting into a sketch; calib writes the same array.
//! - The origin is the wrapped sensor's own mechanical angle 0, in its own direction: the table
//!   must come from a log of that reading.
//!
//! # Rounding
//! calib rounds each entry to the nearest code, so the decoded table is within half a code
//! (9.89″) of what it encodes. The driver's own encoder truncates (the `(uint16_t)` cast of a
//! positive number), which puts its own tables up to one code below the offset, half a code on
//! average; a header line says so.
//!
//! # Releases before PR #75 (`simplefoc-float`)
//! At commit `011c6123f4ea6dff5ae04808580be40e8724a649` the constructor was
//! `CalibratedSensor(Sensor& wrapped, int n_lut = 200, float* lut = nullptr)`, the table `float`
//! radians of the error with the same grid, interpolation and sign. `simplefoc-float` writes that
//! form (`float calib_lut[N]`), which current releases no longer compile.
//!
//! # Size
//! Without `--points`, [`default_points`]: the driver's default 200 entries, or more where the
//! table has orders a 200-entry table cannot hold to the quantum.

use super::{ExportError, ExportOptions, Format, Rendered};
use calib_core::ErrorMap;
use calib_core::angle::ARCSEC_PER_RAD;
use std::f64::consts::PI;
use std::fmt::Write as _;

/// `LUT_SCALE` of `CalibratedSensor.h`, codes per radian, as the `f32` the firmware holds.
pub const LUT_SCALE: f32 = 10430.219;

/// `LUT_OFFSET` of `CalibratedSensor.h`: the code of a zero offset.
pub const LUT_OFFSET: f32 = 32767.0;

/// One code of the `uint16_t` table, radians (`1/LUT_SCALE` = 2π/65535, 19.78″).
pub const QUANTUM_RAD: f64 = 1.0 / LUT_SCALE as f64;

/// `n_lut`'s default in the driver's constructor.
pub const DEFAULT_ENTRIES: usize = 200;

/// Why `simplefoc` takes no `--scale`.
const FIXED_SCALE: &str = "the driver decodes every entry as (code - 32767)/10430.2191955 rad \
                           (LUT_SCALE and LUT_OFFSET of CalibratedSensor.h), one code = 19.78″";

/// The most entries [`default_points`] gives: 4096, 8 KB of RAM on the microcontroller. A table
/// that needs more gets these and the export's fit line (and warning) says what is left.
pub const MAX_DEFAULT_ENTRIES: usize = 4096;

/// The number of entries a SimpleFOC table of `map` gets without `--points`: the driver's
/// default [`DEFAULT_ENTRIES`], or more where `map` needs them to be held to the code
/// ([`QUANTUM_RAD`] `= q`). The smallest orders whose amplitudes add up to at most `q/4` may be
/// left out (together they err by at most a quarter of a code); every other order `h` must be
/// below `N/2`, and their linear interpolation must err by at most `q/4`: interpolating
/// `A·cos(hθ)` between points `Δ = 2π/N` apart errs by at most `A(hΔ)²/8`, so
/// `Σ A_h·π²h²/(2N²) ≤ q/4`, i.e. `N ≥ π·√(2·Σ A_h·h² / q)`. With rounding to half a code, the
/// table as the driver uses it is then within one code of `map`. At most
/// [`MAX_DEFAULT_ENTRIES`].
pub fn default_points(map: &ErrorMap) -> usize {
    let mut orders: Vec<(usize, f64)> = map
        .series()
        .harmonics()
        .iter()
        .map(|h| (h.order, h.amplitude))
        .collect();
    orders.sort_by(|a, b| a.1.total_cmp(&b.1));
    let mut left_out = 0.0;
    let held = orders
        .iter()
        .skip_while(|&&(_, a)| {
            left_out += a;
            left_out <= QUANTUM_RAD / 4.0
        })
        .copied();
    let (mut highest, mut curvature) = (0, 0.0);
    for (h, a) in held {
        highest = highest.max(h);
        curvature += a * (h * h) as f64;
    }
    let interpolation = (PI * (2.0 * curvature / QUANTUM_RAD).sqrt()).ceil() as usize;
    DEFAULT_ENTRIES
        .max(2 * highest + 1)
        .max(interpolation)
        .min(MAX_DEFAULT_ENTRIES)
        .min(map.len().max(DEFAULT_ENTRIES))
}

/// The code `calib` writes for an error of `e` radians: the nearest, `round(e·LUT_SCALE +
/// LUT_OFFSET)`, or `None` beyond the 0…65535 a `uint16_t` holds.
pub fn encode(e: f64) -> Option<u16> {
    let code = (e * f64::from(LUT_SCALE) + f64::from(LUT_OFFSET)).round();
    (0.0..=f64::from(u16::MAX))
        .contains(&code)
        .then_some(code as u16)
}

/// `decodeOffsetU16`: the error a code stands for, radians, in the firmware's `f32`.
pub fn decode(code: u16) -> f32 {
    (f32::from(code) - LUT_OFFSET) / LUT_SCALE
}

/// Renders `target` (errors on the output grid) as a C++ table for `CalibratedSensor`.
pub(super) fn render(target: &ErrorMap, opts: &ExportOptions) -> Result<Rendered, ExportError> {
    let n = target.len();
    let mut body = String::new();
    // Writing into a String cannot fail: the results of writeln! are ignored.
    let (lines, decoded) = if opts.format == Format::Simplefoc {
        if opts.scale_arcsec.is_some() {
            return Err(ExportError::FixedScale {
                format: opts.format.name(),
                why: FIXED_SCALE,
            });
        }
        let mut codes = Vec::with_capacity(n);
        for (i, &e) in target.values().iter().enumerate() {
            codes.push(encode(e).ok_or(ExportError::OutOfRange {
                format: opts.format.name(),
                angle_deg: 360.0 * i as f64 / n as f64,
                arcsec: e * ARCSEC_PER_RAD,
                limit_arcsec: 32767.0 * QUANTUM_RAD * ARCSEC_PER_RAD,
                why: "uint16_t codes 0 to 65535 around LUT_OFFSET 32767",
            })?);
        }
        let quantum = QUANTUM_RAD * ARCSEC_PER_RAD;
        let lines = vec![
            "simplefoc: CalibratedSensor (simplefoc/Arduino-FOC-drivers \
             src/encoders/calibrated/CalibratedSensor.cpp, releases since PR #75) returns raw - \
             lut(raw), lut interpolated linearly between entries at raw angle i*2*PI/N, each \
             decoded as (code - LUT_OFFSET)/LUT_SCALE = (code - 32767)/10430.2191955 rad: the \
             table holds the ERROR (= -correction)"
                .to_string(),
            format!(
                "simplefoc: one code = 2*PI/65535 rad = {quantum:.4} arcsec; calib rounds each \
                 entry to the nearest code (within {:.4} arcsec); the driver's own calibrate() \
                 truncates (encodeOffsetU16 casts to uint16_t), which puts its tables up to one \
                 code below the error, {:.4} arcsec on average",
                quantum / 2.0,
                quantum / 2.0
            ),
            "simplefoc: raw is the wrapped sensor's getMechanicalAngle() in [0, 2*PI), so \
             calibrate that reading; pass the table as CalibratedSensor(sensor, N, \
             calibrationLut), and do not call calibrate() with it (since PR #83 it measures a new \
             table into this array); zero_electric_angle and sensor_direction, which \
             printLUT() also prints, come from your usual initialisation"
                .to_string(),
            format!(
                "memory: {} bytes of RAM (the constructor takes a non-const uint16_t*); releases \
                 before PR #75 take a float table: --format simplefoc-float",
                2 * n
            ),
        ];
        let _ = writeln!(body, "uint16_t calibrationLut[{n}] = {{");
        for chunk in codes.chunks(12) {
            let row: Vec<String> = chunk.iter().map(u16::to_string).collect();
            let _ = writeln!(body, "    {},", row.join(", "));
        }
        let _ = writeln!(body, "}};");
        let _ = writeln!(
            body,
            "// CalibratedSensor sensor_calibrated = CalibratedSensor(sensor, {n}, calibrationLut);"
        );
        let decoded = codes.iter().map(|&k| f64::from(decode(k))).collect();
        (lines, decoded)
    } else {
        let lines = vec![
            "simplefoc-float: for simplefoc/Arduino-FOC-drivers releases before PR #75 (commit \
             011c612: CalibratedSensor(Sensor&, int n_lut, float* lut)); current releases take a \
             uint16_t table: --format simplefoc"
                .to_string(),
            "simplefoc: CalibratedSensor returns raw - lut(raw), lut interpolated linearly \
             between entries at raw angle i*2*PI/CALIB_LUT_SIZE: the table holds the ERROR (= \
             -correction), in radians"
                .to_string(),
            "simplefoc: raw is the wrapped sensor's getMechanicalAngle() in [0, 2*PI), so \
             calibrate that reading; CalibratedSensor sensor_calibrated = \
             CalibratedSensor(sensor, CALIB_LUT_SIZE, calib_lut) uses this table as it is: do \
             not call calibrate(), which measures a new one over it"
                .to_string(),
            format!(
                "memory: {} bytes of RAM (the constructor takes a non-const float*)",
                4 * n
            ),
        ];
        let values: Vec<f32> = target.values().iter().map(|&e| e as f32).collect();
        let _ = writeln!(body, "#define CALIB_LUT_SIZE {n}");
        let _ = writeln!(body, "float calib_lut[CALIB_LUT_SIZE] = {{");
        for chunk in values.chunks(6) {
            let row: Vec<String> = chunk.iter().map(|v| format!("{v:e}f")).collect();
            let _ = writeln!(body, "    {},", row.join(", "));
        }
        let _ = writeln!(body, "}};");
        let _ = writeln!(
            body,
            "// CalibratedSensor sensor_calibrated = CalibratedSensor(sensor, CALIB_LUT_SIZE, \
             calib_lut);"
        );
        (lines, values.iter().map(|&v| f64::from(v)).collect())
    };
    Ok(Rendered {
        lines,
        body,
        decoded,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::export::{Keep, export};
    use calib_core::TableMap;
    use calib_core::{FourierSeries, Harmonic};
    use std::f64::consts::TAU;

    /// `_2PI` of Arduino-FOC's `src/common/foc_utils.h`, 6.28318530718, as the float the driver
    /// computes with: the same `f32` as τ.
    const TWO_PI: f32 = std::f32::consts::TAU;

    /// `CalibratedSensor::getSensorAngle()` in `f32` for a raw mechanical angle in `[0, 2π)`,
    /// with the entries as the driver decodes them: since PR #75 `decodeOffsetU16` of the codes,
    /// before it the floats themselves. `lut_resolution = _2PI/n_lut` and its inverse are
    /// computed once, as the constructor does.
    fn sensor_angle(lut: &[f32], raw: f32) -> f32 {
        let n_lut = lut.len();
        let resolution = TWO_PI / n_lut as f32;
        let resolution_inv = 1.0 / resolution;
        let index = (raw * resolution_inv) as usize;
        let lower = lut[index];
        let higher = lut[if index >= n_lut - 1 { 0 } else { index + 1 }];
        let distance = (raw - index as f32 * resolution) * resolution_inv;
        raw - ((1.0 - distance) * lower + distance * higher)
    }

    /// The entries a snippet gives the driver, decoded as the driver decodes them.
    fn load(text: &str) -> Vec<f32> {
        let open = text.find("] = {").unwrap();
        let close = open + text[open..].find("};").unwrap();
        let numbers = text[open + 5..close]
            .split([',', '\n', ' '])
            .filter(|t| !t.is_empty());
        if text.contains("uint16_t calibrationLut[") {
            numbers.map(|t| decode(t.parse().unwrap())).collect()
        } else {
            numbers
                .map(|t| t.trim_end_matches('f').parse().unwrap())
                .collect()
        }
    }

    #[test]
    fn the_firmware_constants_are_the_drivers() {
        assert_eq!(LUT_SCALE, "10430.2191955".parse::<f32>().unwrap());
        // One code is 2π/65535 rad, to the f32 rounding of LUT_SCALE (2⁻²⁴ relative).
        assert!((QUANTUM_RAD / (TAU / 65535.0) - 1.0).abs() < 1e-7);
        assert_eq!(encode(0.0), Some(32767));
        assert_eq!(encode(-4.0), None);
        assert_eq!(decode(32767), 0.0);
    }

    #[test]
    fn the_driver_reads_back_the_table_within_half_a_code() {
        let hs = [
            Harmonic::from_arcsec_deg(1, 300.0, 20.0),
            Harmonic::from_arcsec_deg(7, 20.0, -60.0),
        ];
        let map = ErrorMap::from_series(&FourierSeries::from_harmonics(&hs, 7), 720);
        for (format, points) in [
            (Format::Simplefoc, 200),
            (Format::Simplefoc, 333),
            (Format::SimplefocFloat, 200),
        ] {
            let mut opts = ExportOptions::new(format, "t");
            opts.points = Some(points);
            let out = export(&TableMap::from(map.clone()), &opts).unwrap();
            assert!(out.text.starts_with("// t\n"));
            let lut = load(&out.text);
            assert_eq!(lut.len(), points);
            // Orders 1 and 7 are held exactly at the 200 or 333 entries.
            let entries = ErrorMap::from_series(&map.series(), points);
            let quantum = match format {
                Format::Simplefoc => QUANTUM_RAD / 2.0,
                _ => 0.0,
            };
            let (mut worst_entry, mut worst) = (0.0f64, 0.0f64);
            for k in 0..20_000 {
                let raw = (TAU * k as f64 / 20_000.0) as f32;
                // What the driver subtracts from the raw angle, against calib's error there.
                let applied = f64::from(raw - sensor_angle(&lut, raw));
                let want = entries.eval_linear(f64::from(raw));
                worst = worst.max((applied - want).abs());
                if k % (20_000 / points.min(100)) == 0 {
                    let i = (f64::from(raw) / TAU * points as f64).round() as usize % points;
                    worst_entry = worst_entry.max((f64::from(lut[i]) - entries.values()[i]).abs());
                }
            }
            // Each entry within half a code (f32 decoding adds 2⁻²⁴ of 300″).
            assert!(worst_entry <= quantum + 1e-9, "{format:?}: {worst_entry}");
            // raw − offset is rounded to the f32 spacing of angles in [4, 8) rad, 4.8·10⁻⁷ rad
            // (0.098″), of which half is the most rounding can cost; the interpolation's own
            // float arithmetic costs below 10⁻⁸ rad here. Bound: half a code and one spacing.
            let bound = quantum + 4.0 * f64::from(f32::EPSILON);
            assert!(worst <= bound, "{format:?}: {worst} > {bound}");
            assert!(out.fit.is_some());
        }
    }

    #[test]
    fn the_current_form_is_what_print_lut_prints() {
        let map = ErrorMap::new(vec![1e-3, 0.0, -1e-3, 0.0]);
        let mut opts = ExportOptions::new(Format::Simplefoc, "t");
        opts.points = Some(4);
        let out = export(&TableMap::from(map.clone()), &opts).unwrap();
        let body: Vec<&str> = out.text.lines().filter(|l| !l.starts_with("//")).collect();
        // 1e-3 rad is 10.43 codes: 32777 and 32757.
        assert_eq!(
            body,
            vec![
                "uint16_t calibrationLut[4] = {",
                "    32777, 32767, 32757, 32767,",
                "};"
            ]
        );
        opts.scale_arcsec = Some(1.0);
        assert!(matches!(
            export(&TableMap::from(map.clone()), &opts),
            Err(ExportError::FixedScale { .. })
        ));
    }

    /// Orders 1, 72, 144 and 216 (a 72-pole-pair sensor's) need more than the driver's 200
    /// entries; a table without high orders gets 200.
    #[test]
    fn the_default_size_holds_the_orders_to_the_quantum() {
        let smooth = ErrorMap::from_series(
            &FourierSeries::from_harmonics(&[Harmonic::from_arcsec_deg(1, 300.0, 0.0)], 1),
            3600,
        );
        assert_eq!(default_points(&smooth), DEFAULT_ENTRIES);
        let poles = ErrorMap::from_series(
            &FourierSeries::from_harmonics(
                &[
                    Harmonic::from_arcsec_deg(72, 30.0, 0.0),
                    Harmonic::from_arcsec_deg(144, 20.0, 0.0),
                    Harmonic::from_arcsec_deg(216, 5.0, 0.0),
                ],
                216,
            ),
            57_600,
        );
        let n = default_points(&poles);
        // 216 is held (N > 432; its 5″ are above a quarter code, 4.94″), and the interpolation
        // bound: π·√(2·(30·72² + 20·144² + 5·216²)″ / 19.7757″) = 895.6.
        assert_eq!(n, 896);
        let mut opts = ExportOptions::new(Format::Simplefoc, "t");
        opts.keep = Keep::All;
        let out = export(&TableMap::from(poles.clone()), &opts).unwrap();
        assert!(out.text.contains(&format!("calibrationLut[{n}]")), "{n}");
        let fit = out.fit.unwrap();
        // Interpolation held to a quarter code, plus the rounding of each entry to half a code
        // (nothing left out: every amplitude is above a quarter code).
        assert!(
            fit.max <= QUANTUM_RAD * 0.75,
            "{}",
            fit.max * ARCSEC_PER_RAD
        );
        assert!(out.warnings.is_empty());
    }
}
