//! SimpleFOC: the look-up table of `CalibratedSensor` as C++ (`--format simplefoc`, `--format
//! simplefoc-u16`).
//!
//! # What the driver does with the table
//! From `src/encoders/calibrated/CalibratedSensor.{h,cpp}` of simplefoc/Arduino-FOC-drivers at
//! commit `011c6123f4ea6dff5ae04808580be40e8724a649`:
//! - `CalibratedSensor(Sensor& wrapped, int n_lut = 200, float* lut = nullptr)`: a table given at
//!   construction is used as it is (compiled in, it is kept across boots); `calibrate()` would
//!   measure a new one over it.
//! - `getSensorAngle()`: `raw = fmodf(wrapped.getMechanicalAngle(), _2PI)` (plus `_2PI` if
//!   negative), `res = _2PI / n_lut`, `i = (int)(raw / res)`, `d = (raw − i·res) / res`, and it
//!   returns `raw − ((1 − d)·lut[i] + d·lut[(i + 1) % n_lut])`: entry `i` sits at raw angle
//!   `i·2π/n_lut`, interpolated linearly and periodically, and is **subtracted** — the table holds
//!   the error (`reading − true angle`, calib's `error_arcsec`), in radians. `calibrate()` fills
//!   it with that meaning: the measured error minus its mean, indexed by raw angle.
//! - The origin is the wrapped sensor's own mechanical angle 0, in its own direction: the table
//!   must come from a log of that reading.
//!
//! An earlier version (commit `b6c0c7ddd1ec49057c9f5eafd9e0269f612946c2`) had a fixed 128-entry
//! table that could not be given from outside and *added* it to the raw angle; calib writes for
//! the current API only.
//!
//! # uint16
//! No `uint16_t` table was found in the driver's source: the constructor takes `float*`.
//! `simplefoc-u16` stores offset-binary codes in a `const uint16_t` array (2 bytes an entry, in
//! flash) with a scale, and a function that fills the `float` table from them at start-up:
//! `error_rad = (code − 32768) × CALIB_LUT_SCALE_RAD`, the scale the smallest that holds the
//! table (or `--scale`), never one that saturates.

use super::{ExportError, ExportOptions, Format, Rendered, quantize};
use calib_core::ErrorMap;
use calib_core::angle::ARCSEC_PER_RAD;
use std::fmt::Write as _;

/// Renders `target` (errors on the output grid) as a C++ table for `CalibratedSensor`.
pub(super) fn render(target: &ErrorMap, opts: &ExportOptions) -> Result<Rendered, ExportError> {
    let n = target.len();
    let mut lines = vec![
        "simplefoc: CalibratedSensor (simplefoc/Arduino-FOC-drivers \
         src/encoders/calibrated/CalibratedSensor.cpp, commit 011c612) returns raw - lut(raw), \
         lut interpolated linearly between entries at raw angle i*2*PI/CALIB_LUT_SIZE: the table \
         holds the ERROR (= -correction), in radians"
            .to_string(),
        "simplefoc: raw is the wrapped sensor's getMechanicalAngle() in [0, 2*PI), so calibrate \
         that reading; CalibratedSensor sensor_calibrated = CalibratedSensor(sensor, \
         CALIB_LUT_SIZE, calib_lut) uses this table as it is: do not call calibrate(), which \
         measures a new one over it"
            .to_string(),
    ];
    let mut body = String::new();
    // Writing into a String cannot fail: the results of writeln! are ignored.
    let _ = writeln!(body, "#define CALIB_LUT_SIZE {n}");
    let decoded: Vec<f64> = if opts.format == Format::Simplefoc {
        lines.push(format!(
            "memory: {} bytes of RAM (the constructor takes a non-const float*)",
            4 * n
        ));
        let values: Vec<f32> = target.values().iter().map(|&e| e as f32).collect();
        let _ = writeln!(body, "float calib_lut[CALIB_LUT_SIZE] = {{");
        for chunk in values.chunks(6) {
            let row: Vec<String> = chunk.iter().map(|v| format!("{v:e}f")).collect();
            let _ = writeln!(body, "    {},", row.join(", "));
        }
        let _ = writeln!(body, "}};");
        values.iter().map(|&v| f64::from(v)).collect()
    } else {
        let errors: Vec<f64> = target.values().iter().map(|e| e * ARCSEC_PER_RAD).collect();
        let (lsb_arcsec, codes) = quantize(&errors, i64::from(i16::MAX), opts.scale_arcsec)?;
        let scale = (lsb_arcsec / ARCSEC_PER_RAD) as f32;
        lines.push(format!(
            "memory: {} bytes of const codes (flash) and {} bytes of RAM for the float table \
             calib_lut_load() fills; error_rad = (code - 32768) * CALIB_LUT_SCALE_RAD, one code \
             = {:.9} arcsec (uint16 is calib's storage: the driver takes float)",
            2 * n,
            4 * n,
            f64::from(scale) * ARCSEC_PER_RAD
        ));
        let _ = writeln!(body, "#define CALIB_LUT_SCALE_RAD {scale:e}f");
        let _ = writeln!(
            body,
            "static const uint16_t calib_lut_u16[CALIB_LUT_SIZE] = {{"
        );
        for chunk in codes.chunks(12) {
            let row: Vec<String> = chunk.iter().map(|k| (k + 32768).to_string()).collect();
            let _ = writeln!(body, "    {},", row.join(", "));
        }
        let _ = writeln!(body, "}};");
        let _ = writeln!(body, "float calib_lut[CALIB_LUT_SIZE];");
        let _ = writeln!(
            body,
            "// Fills calib_lut from the codes; call it in setup() before sensor_calibrated.init()."
        );
        let _ = writeln!(body, "static void calib_lut_load() {{");
        let _ = writeln!(body, "    for (int i = 0; i < CALIB_LUT_SIZE; i++) {{");
        let _ = writeln!(
            body,
            "        calib_lut[i] = (float)((int32_t)calib_lut_u16[i] - 32768) * \
             CALIB_LUT_SCALE_RAD;"
        );
        let _ = writeln!(body, "    }}");
        let _ = writeln!(body, "}}");
        codes.iter().map(|&k| f64::from(k as f32 * scale)).collect()
    };
    let _ = writeln!(
        body,
        "// CalibratedSensor sensor_calibrated = CalibratedSensor(sensor, CALIB_LUT_SIZE, \
         calib_lut);"
    );
    Ok(Rendered {
        lines,
        body,
        decoded,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::export::export;
    use calib_core::{FourierSeries, Harmonic};
    use std::f64::consts::TAU;

    /// `_2PI` of Arduino-FOC's `src/common/foc_utils.h`, 6.28318530718, as the float the driver
    /// computes with: the same `f32` as τ.
    const TWO_PI: f32 = std::f32::consts::TAU;

    /// `CalibratedSensor::getSensorAngle()` in `f32`, for a raw mechanical angle.
    fn sensor_angle(lut: &[f32], mechanical: f32) -> f32 {
        let n_lut = lut.len();
        let mut raw = mechanical % TWO_PI;
        if raw < 0.0 {
            raw += TWO_PI;
        }
        let resolution = TWO_PI / n_lut as f32;
        let index = (raw / resolution) as usize;
        let y0 = lut[index];
        let y1 = lut[(index + 1) % n_lut];
        let distance = (raw - index as f32 * resolution) / resolution;
        let offset = (1.0 - distance) * y0 + distance * y1;
        raw - offset
    }

    /// The `float` table a snippet gives the driver: the array's numbers, or the codes decoded
    /// as `calib_lut_load()` does.
    fn load(text: &str) -> Vec<f32> {
        let define = |name: &str| {
            text.lines()
                .find_map(|l| l.strip_prefix(&format!("#define {name} ")))
                .map(|v| v.trim_end_matches('f').to_string())
        };
        let size: usize = define("CALIB_LUT_SIZE").unwrap().parse().unwrap();
        let open = text.find("] = {").unwrap();
        let close = open + text[open..].find("};").unwrap();
        let numbers: Vec<&str> = text[open + 5..close]
            .split([',', '\n', ' '])
            .filter(|t| !t.is_empty())
            .collect();
        assert_eq!(numbers.len(), size);
        match define("CALIB_LUT_SCALE_RAD") {
            None => numbers
                .iter()
                .map(|t| t.trim_end_matches('f').parse().unwrap())
                .collect(),
            Some(scale) => {
                let scale: f32 = scale.parse().unwrap();
                numbers
                    .iter()
                    .map(|t| (t.parse::<i32>().unwrap() - 32768) as f32 * scale)
                    .collect()
            }
        }
    }

    #[test]
    fn the_driver_reads_back_the_table_within_its_quantization() {
        let hs = [
            Harmonic::from_arcsec_deg(1, 300.0, 20.0),
            Harmonic::from_arcsec_deg(7, 20.0, -60.0),
        ];
        let map = ErrorMap::from_series(&FourierSeries::from_harmonics(&hs, 7), 720);
        for format in [Format::Simplefoc, Format::SimplefocU16] {
            let mut opts = ExportOptions::new(format, "t");
            opts.points = Some(200);
            let out = export(&map, &opts).unwrap();
            assert!(out.text.starts_with("// t\n"));
            let lut = load(&out.text);
            let resampled = map.resample_linear(200);
            // Half a code of the u16 table: |error| ≤ 320″ on 32767 codes.
            let quantum = match format {
                Format::Simplefoc => 0.0,
                _ => 320.0 / 32767.0 / 2.0,
            };
            let mut worst = 0.0f64;
            for k in 0..20_000 {
                let mechanical = (TAU * k as f64 / 20_000.0) as f32;
                // What the driver subtracts from the raw angle, against calib's error there.
                let applied = f64::from(mechanical - sensor_angle(&lut, mechanical));
                let want = resampled.eval_linear(f64::from(mechanical));
                worst = worst.max((applied - want).abs() * ARCSEC_PER_RAD);
            }
            // raw − offset is rounded to the f32 spacing of angles in [4, 8) rad, 4.8·10⁻⁷ rad
            // (0.098″), of which half is the most rounding can cost; the interpolation's own
            // float arithmetic costs below 10⁻⁸ rad here. Bound: the quantum and one spacing.
            let bound = quantum + 4.0 * f64::from(f32::EPSILON) * ARCSEC_PER_RAD;
            assert!(worst <= bound, "{format:?}: {worst}″ > {bound}″");
            assert!(out.fit.is_some());
        }
    }

    #[test]
    fn the_u16_scale_refuses_to_saturate() {
        let map = ErrorMap::new(vec![0.0, 1e-3, -1e-3, 0.0]);
        let mut opts = ExportOptions::new(Format::SimplefocU16, "t");
        opts.scale_arcsec = Some(0.001);
        assert!(matches!(
            export(&map, &opts),
            Err(ExportError::Saturated {
                max_code: 32767,
                ..
            })
        ));
    }
}
