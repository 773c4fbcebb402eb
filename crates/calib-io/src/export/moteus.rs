//! mjbots moteus: the encoder compensation table of a `motor_position` source (`--format moteus`,
//! `--format moteus-config`).
//!
//! # What the firmware does with the table
//! From `fw/motor_position.h` of mjbots/moteus at commit
//! `06a3d52033719a3e45fa06b634b55609513f6c20`:
//! - `SourceConfig::compensation_table` is a `std::array<int8_t, 256>` (`kCompensationSize`) and
//!   `compensation_scale` a `float`; the configuration keys are
//!   `motor_position.sources.N.compensation_table.I` and `motor_position.sources.N.compensation_scale`,
//!   `N` in 0–2 (`kNumSources`). Compensation is on when the scale and at least one entry are
//!   non-zero (`cached_any_compensation_enabled`).
//! - At every update `compensated_value = WrapCpr(offset_value + lerp(compensation_table,
//!   compensation_scale / 127.0f, offset_value / cpr) · cpr)`: an entry times `scale/127` is a
//!   **fraction of a revolution added to the reading**, so the table holds the correction
//!   (`−error`), in revolutions.
//! - `lerp(array, scale, ratio)` takes `left = min(N − 1, (int)(ratio·N))`, `right = (left + 1) %
//!   N`, `fraction = (ratio − left/N)·N` and returns `array[left]·scale·(1 − fraction) +
//!   array[right]·scale·fraction`: entry `i` sits at `ratio = i/256` of a revolution, interpolated
//!   linearly and periodically — calib's grid `i·360/256` with entry 0 at reading 0. (The comment
//!   above the table in that file speaks of bin *centres*; the code places the entries at the bin
//!   starts, and calib follows the code.)
//! - `offset_value = (raw + offset)·sign mod cpr` (`ISR_UpdateAbsoluteSource`): the table's origin
//!   and direction are those of the source after its `offset` and `sign`. The table must come
//!   from a log of that reading — the raw reading when `offset` is 0 and `sign` 1.
//!
//! From `lib/python/moteus/moteus_tool.py` at commit `00021a0bc1a5a47f584b30da1dd8d2bc1ba6b405`:
//! the 256-entry int8 table with its scale exists since firmware ABI 0x0109 (`FirmwareUpgrade`
//! converts older firmware's 32 `float` entries, which had no scale); calib writes the 256-entry
//! form only. Loading: `--write-config FILE` sends every line as a command, comments included, so
//! [`Format::Moteus`] has none; `--restore-config FILE` drops what follows a
//! `#`, sends `conf set` and the line, and ends with `conf write`, which
//! [`Format::MoteusConfig`] is written for.
//!
//! # Scale, codes and order of the lines
//! `compensation_scale` is the largest |correction| in revolutions (or 127 codes of `--scale`),
//! so every code `round(127·c/scale)` lies in −127…127: nothing saturates, and at its points the
//! table is within half a code, `scale/254`, of what it encodes. The scale is written in plain
//! decimals (the firmware's parser is not documented to take exponents), and the codes are
//! checked against it as the firmware will read it (`f32`). The first line sets the scale to 0,
//! which turns compensation off while the entries change one by one; the last sets the real
//! scale. [`Format::Moteus`] ends with `conf write`, which keeps the table
//! across power cycles.
//!
//! Not established from the source: whether the firmware's configuration parser takes numbers
//! in exponent notation (hence plain decimals), and the behaviour of firmware newer than the
//! commit cited.

use super::{ExportError, ExportOptions, Format, Rendered, corrections, plain_decimal, quantize};
use calib_core::ErrorMap;
use std::f64::consts::TAU;
use std::fmt::Write as _;

/// Entries of a moteus compensation table (`MotorPosition::kCompensationSize`).
pub const TABLE_SIZE: usize = 256;

/// Where [`TABLE_SIZE`] comes from, for error messages.
pub(super) const SIZE_SOURCE: &str = "moteus firmware ≥ 0x0109 holds compensation_table as std::array<int8_t, 256> and \
     interpolates over all of it";

/// Sources of a moteus controller (`MotorPosition::kNumSources`).
pub const SOURCES: u8 = 3;

/// Arcseconds in a revolution.
const ARCSEC_PER_REV: f64 = 1_296_000.0;

/// Renders `target` (errors on the 256-point grid) as moteus settings.
pub(super) fn render(target: &ErrorMap, opts: &ExportOptions) -> Result<Rendered, ExportError> {
    if opts.moteus_source >= SOURCES {
        return Err(ExportError::MoteusSource {
            given: opts.moteus_source,
        });
    }
    let c = corrections(target);
    let (lsb_arcsec, codes) = quantize(&c, 127, opts.scale_arcsec)?;
    let largest = codes.iter().map(|k| k.abs()).max().unwrap_or(0);
    let scale = if largest == 0 {
        0.0
    } else {
        (127.0 * lsb_arcsec / ARCSEC_PER_REV) as f32
    };
    let written = plain_decimal(scale);
    // What the firmware reads: the written decimal as a float, divided by 127 in float.
    let per_code = written.parse::<f32>().unwrap_or(scale) / 127.0f32;
    let key = format!("motor_position.sources.{}.compensation", opts.moteus_source);
    let prefix = if opts.format == Format::Moteus {
        "conf set "
    } else {
        ""
    };
    let mut body = String::new();
    // Writing into a String cannot fail.
    let _ = writeln!(body, "{prefix}{key}_scale 0");
    for (i, k) in codes.iter().enumerate() {
        let _ = writeln!(body, "{prefix}{key}_table.{i} {k}");
    }
    let _ = writeln!(body, "{prefix}{key}_scale {written}");
    if opts.format == Format::Moteus {
        body.push_str("conf write\n");
    }
    let lines = vec![
        format!(
            "moteus: {key}_table.0..255 and {key}_scale, firmware ABI >= 0x0109 (mjbots/moteus \
             fw/motor_position.h, commit 06a3d52)"
        ),
        format!(
            "moteus: compensated = offset_value + (code*scale/127)*cpr, interpolated linearly \
             between entries i/256 of a revolution: the table holds the correction, in \
             revolutions; scale = {written} rev, one code = {:.6} arcsec",
            f64::from(per_code) * ARCSEC_PER_REV
        ),
        "moteus: the reading calibrated must be the source's offset_value/cpr ((raw + offset) * \
         sign); the first line turns compensation off while the entries change"
            .to_string(),
        match opts.format {
            Format::Moteus => "load: moteus_tool -t ID --write-config FILE (or paste into \
                               moteus_tool -t ID --console); the last line, conf write, keeps it \
                               across power cycles"
                .to_string(),
            _ => "load: moteus_tool -t ID --restore-config FILE, which adds conf set to each line \
                  and ends with conf write"
                .to_string(),
        },
    ];
    let decoded = codes
        .iter()
        .map(|&k| -f64::from(k as f32 * per_code) * TAU)
        .collect();
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
    use calib_core::angle::ARCSEC_PER_RAD;
    use calib_core::{FourierSeries, Harmonic};

    /// The firmware's `lerp` (fw/motor_position.h), in `f32` as the firmware computes it.
    fn lerp(array: &[i8], scale: f32, ratio: f32) -> f32 {
        let size = array.len();
        let left = (size as i64 - 1).min((ratio * size as f32) as i64) as usize;
        let right = (left + 1) % size;
        let fraction = (ratio - left as f32 / size as f32) * size as f32;
        let left_comp = f32::from(array[left]) * scale;
        let right_comp = f32::from(array[right]) * scale;
        left_comp * (1.0 - fraction) + right_comp * fraction
    }

    /// The table and scale of source `n` from `conf set` (or `key value`) lines.
    fn load(text: &str, n: u8) -> (Vec<i8>, f32) {
        let mut table = vec![0i8; TABLE_SIZE];
        let mut scale = f32::NAN;
        let prefix = format!("motor_position.sources.{n}.compensation_");
        for line in text.lines() {
            let line = line.split('#').next().unwrap().trim();
            let line = line.strip_prefix("conf set ").unwrap_or(line);
            let Some(rest) = line.strip_prefix(&prefix) else {
                assert!(line.is_empty() || line == "conf write", "{line}");
                continue;
            };
            let (key, value) = rest.split_once(' ').unwrap();
            if key == "scale" {
                scale = value.parse().unwrap();
            } else {
                let i: usize = key.strip_prefix("table.").unwrap().parse().unwrap();
                table[i] = value.parse().unwrap();
            }
        }
        (table, scale)
    }

    /// 300″ at order 1, 40″ at 5 and 3″ at 30: the correction reaches ~343″.
    fn source() -> ErrorMap {
        let hs = [
            Harmonic::from_arcsec_deg(1, 300.0, 20.0),
            Harmonic::from_arcsec_deg(5, 40.0, -60.0),
            Harmonic::from_arcsec_deg(30, 3.0, 0.0),
        ];
        ErrorMap::from_series(&FourierSeries::from_harmonics(&hs, 30), 1024)
    }

    #[test]
    fn the_firmware_reads_back_the_table_within_half_a_code() {
        let map = source();
        for format in [Format::Moteus, Format::MoteusConfig] {
            let mut opts = ExportOptions::new(format, "t");
            opts.moteus_source = 2;
            let out = export(&TableMap::from(map.clone()), &opts).unwrap();
            let (table, scale) = load(&out.text, 2);
            let largest = table.iter().map(|k| k.unsigned_abs()).max().unwrap();
            assert_eq!(largest, 127, "the scale uses the whole int8 range");
            let half_code = f64::from(scale) / 254.0 * ARCSEC_PER_REV;
            let resampled = map.resample_linear(TABLE_SIZE);
            // At and between the entries, for every count of a 14-bit encoder (AS5047, cpr
            // 16384) as the firmware computes ratio = offset_value · (1/cpr).
            let cpr = 16384u32;
            let inv_cpr = 1.0f32 / cpr as f32;
            let mut worst = 0.0f64;
            for count in 0..cpr {
                let ratio = count as f32 * inv_cpr;
                let got = f64::from(lerp(&table, scale / 127.0, ratio)) * ARCSEC_PER_REV;
                let want = -resampled.eval_linear(f64::from(ratio) * TAU) * ARCSEC_PER_RAD;
                worst = worst.max((got - want).abs());
            }
            // Half a code, plus f32 rounding of values up to 343″ (2⁻²⁴ relative, 2·10⁻⁵″).
            assert!(
                worst <= half_code + 1e-4,
                "{format:?}: {worst}″ > {half_code}″"
            );
            let fit = out.fit.unwrap();
            assert!(fit.max > 0.0 && out.header.iter().any(|l| l.starts_with("fit: ")));
        }
    }

    #[test]
    fn conf_set_lines_have_no_comments_and_end_with_conf_write() {
        let out = export(
            &TableMap::from(source()),
            &ExportOptions::new(Format::Moteus, "t"),
        )
        .unwrap();
        let lines: Vec<&str> = out.text.lines().collect();
        assert_eq!(lines.len(), 256 + 3);
        assert_eq!(
            lines[0],
            "conf set motor_position.sources.0.compensation_scale 0"
        );
        assert!(lines[1].starts_with("conf set motor_position.sources.0.compensation_table.0 "));
        assert!(
            lines[257].starts_with("conf set motor_position.sources.0.compensation_scale 0.00")
        );
        assert_eq!(lines[258], "conf write");
        for line in &lines[..258] {
            let value = line.rsplit(' ').next().unwrap();
            assert!(!line.contains('#') && !value.contains('e'), "{line}");
            assert!(value.parse::<f64>().is_ok(), "{line}");
        }
        // The header is returned for the caller to show, not written.
        assert!(out.header.iter().any(|l| l.contains("--write-config")));
        let config = export(
            &TableMap::from(source()),
            &ExportOptions::new(Format::MoteusConfig, "t"),
        )
        .unwrap();
        assert!(config.text.starts_with("# t\n"));
        let settings: Vec<&str> = config
            .text
            .lines()
            .filter(|l| !l.starts_with('#'))
            .collect();
        assert_eq!(settings.len(), 258);
        assert!(settings.iter().all(|l| !l.contains("conf ")));
    }

    #[test]
    fn sizes_scales_and_smoothing() {
        let map = source();
        let mut opts = ExportOptions::new(Format::Moteus, "t");
        opts.points = Some(512);
        assert!(matches!(
            export(&TableMap::from(map.clone()), &opts),
            Err(ExportError::Points {
                required: 256,
                given: 512,
                ..
            })
        ));
        // A scale too small for 343″ in 127 codes is refused; one that holds it is used.
        opts.points = None;
        opts.scale_arcsec = Some(1.0);
        assert!(matches!(
            export(&TableMap::from(map.clone()), &opts),
            Err(ExportError::Saturated { max_code: 127, .. })
        ));
        opts.scale_arcsec = Some(3.0);
        let (table, scale) = load(
            &export(&TableMap::from(map.clone()), &opts).unwrap().text,
            0,
        );
        assert!((f64::from(scale) * ARCSEC_PER_REV - 381.0).abs() < 1e-3);
        assert!(table.iter().all(|&k| k.abs() < 127));
        // Keeping orders 1 and 5 leaves out the 3″ of order 30: the fit reports it.
        opts.scale_arcsec = None;
        opts.keep = Keep::Orders(vec![1, 5]);
        let out = export(&TableMap::from(map.clone()), &opts).unwrap();
        let fit = out.fit.unwrap().max * ARCSEC_PER_RAD;
        // Within half a code (343″/127/2 = 1.35″) and the interpolation of orders 1 and 5 on 256
        // points (0.1″) of the 3″ left out.
        assert!((3.0 - 1.5..3.0 + 1.5).contains(&fit), "{fit}");
        opts.keep = Keep::All;
        opts.moteus_source = 3;
        assert_eq!(
            export(&TableMap::from(map.clone()), &opts).unwrap_err(),
            ExportError::MoteusSource { given: 3 }
        );
    }
}
