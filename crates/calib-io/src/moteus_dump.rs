//! moteus' raw encoder calibration dump: what `moteus_tool --calibrate --cal-write-raw FILE`
//! saves.
//!
//! # Format
//! From `lib/python/moteus/calibrate_encoder.py` of mjbots/moteus (`parse_file`, `calibrate`;
//! read at commit `0765532c062333008f1617ea7da14d056b87722d`): a first line starting `CAL
//! start`, a last line starting `CAL done`, and between them one line per sample, `direction
//! phase encoder` separated by single spaces, optionally followed by `i1=…`, `i2=…`, `i3=…`
//! (phase currents, mA; ignored here). `direction` is 1 while the commanded phase rises, 2 while
//! it falls; `phase` is the commanded electrical phase, 65536 per electrical turn; `encoder` the
//! raw encoder reading, 65536 per revolution. Both are `uint16` and wrap.
//!
//! # What calib makes of it
//! The encoder (the DUT) against the commanded angle (the reference): `phase` unwrapped, over
//! 65536, over the pole pairs, in radians of the shaft. The pole pairs are the ratio of the
//! phase travelled to the encoder travelled over the rising part, rounded (moteus' own rule; an
//! error if the ratio is more than 0.1 from a whole number). As moteus does, the first 4 rising
//! samples are dropped (the rotor is still settling onto the first commanded phase). An encoder
//! that counts against the phase is read as is and the commanded angle negated, so that both
//! count the same way round: the table is then of the raw reading.
//!
//! The dump has no time stamps: sample `k` is given the time `k·`[`SAMPLE_PERIOD_S`] (a
//! nominal period; only the order of the samples matters to the calibration without latency).

use crate::Error;
use std::f64::consts::TAU;
use std::path::Path;

/// Nominal time between two samples of a dump, seconds.
pub const SAMPLE_PERIOD_S: f64 = 0.01;

/// Rising samples dropped at the start (as `calibrate_encoder.py` does).
pub const SETTLING_SAMPLES: usize = 4;

/// A dump read: the samples in file order and what they say of the motor.
#[derive(Debug, Clone, PartialEq)]
pub struct CalDump {
    /// `(t, encoder, commanded)`: time (s, nominal), the encoder's reading and the commanded
    /// shaft angle (radians; the commanded angle accumulated over the dump).
    pub samples: Vec<(f64, f64, f64)>,
    /// Pole pairs: given, or the rounded ratio of phase to encoder travel.
    pub pole_pairs: u32,
    /// The ratio of phase to encoder travel over the rising part, unrounded.
    pub ratio: f64,
    /// Whether the encoder counts against the phase (the commanded angle was negated).
    pub encoder_reversed: bool,
    /// Rising and falling samples kept.
    pub rising: usize,
    /// Falling samples.
    pub falling: usize,
}

fn error(path: &Path, line: u64, message: String) -> Error {
    Error::Csv {
        path: path.to_path_buf(),
        line,
        channel: None,
        message,
    }
}

/// The signed step from `a` to `b` of a `uint16` that wraps.
fn step(a: u16, b: u16) -> f64 {
    f64::from(b.wrapping_sub(a) as i16)
}

/// Reads a dump; `pole_pairs` overrides the pole pairs found from the data.
pub fn read_cal_dump(path: &Path, pole_pairs: Option<u32>) -> Result<CalDump, Error> {
    let bytes = std::fs::read(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let text = String::from_utf8_lossy(&bytes);
    // A byte order mark (a dump saved by a Windows editor) is not part of `CAL start`.
    let lines: Vec<(u64, &str)> = text
        .trim_start_matches('\u{feff}')
        .lines()
        .enumerate()
        .map(|(k, l)| (k as u64 + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty())
        .collect();
    let hint = "a moteus calibration dump (moteus_tool --calibrate --cal-write-raw FILE) starts with `CAL start`, \
                ends with `CAL done`, and holds `direction phase encoder` lines between";
    let Some(&(first_no, first)) = lines.first() else {
        return Err(error(path, 1, format!("the file is empty: {hint}")));
    };
    if !first.starts_with("CAL start") {
        return Err(error(
            path,
            first_no,
            format!("`{first}` is not `CAL start`: {hint}"),
        ));
    }
    let (last_no, last) = lines[lines.len() - 1];
    if lines.len() < 2 || !last.starts_with("CAL done") {
        return Err(error(
            path,
            last_no,
            format!("the dump does not end with `CAL done` (cut short?): {hint}"),
        ));
    }
    let mut rows: Vec<(u8, u16, u16)> = Vec::new();
    for &(n, line) in &lines[1..lines.len() - 1] {
        let fields: Vec<&str> = line.split_whitespace().collect();
        let parse = |k: usize, what: &str| -> Result<u16, Error> {
            fields
                .get(k)
                .and_then(|f| f.parse::<u16>().ok())
                .ok_or_else(|| {
                    error(
                        path,
                        n,
                        format!(
                            "`{line}`: field {} ({what}) is not an integer 0–65535; {hint}",
                            k + 1
                        ),
                    )
                })
        };
        let direction = parse(0, "direction, 1 or 2")?;
        if !(direction == 1 || direction == 2) {
            return Err(error(
                path,
                n,
                format!(
                    "`{line}`: direction {direction} is neither 1 (phase rising) nor 2 (falling)"
                ),
            ));
        }
        rows.push((direction as u8, parse(1, "phase")?, parse(2, "encoder")?));
    }
    let rising: Vec<(u8, u16, u16)> = rows
        .iter()
        .copied()
        .filter(|r| r.0 == 1)
        .skip(SETTLING_SAMPLES)
        .collect();
    let falling = rows.iter().filter(|r| r.0 == 2).count();
    if rising.len() < 2 || falling < 2 {
        return Err(error(
            path,
            1,
            format!(
                "the dump holds {} rising and {falling} falling samples (after dropping the first {SETTLING_SAMPLES} \
                 rising ones); a calibration needs both directions",
                rising.len()
            ),
        ));
    }
    let phase: f64 = rising.windows(2).map(|w| step(w[0].1, w[1].1)).sum();
    let encoder: f64 = rising.windows(2).map(|w| step(w[0].2, w[1].2)).sum();
    if encoder == 0.0 {
        return Err(error(
            path,
            1,
            "the encoder did not move while the phase rose: is it on the motor's shaft?"
                .to_string(),
        ));
    }
    let ratio = phase / encoder;
    let reversed = ratio < 0.0;
    let pole_pairs = match pole_pairs {
        Some(p) => p,
        None => {
            let p = ratio.abs().round();
            if (ratio.abs() - p).abs() > 0.1 || p < 1.0 {
                return Err(error(
                    path,
                    1,
                    format!(
                        "the phase travelled {:.3} times the encoder's travel, not a whole number of pole pairs: give \
                         the `pole_pairs` option (a 42-pole motor has 21)",
                        ratio.abs()
                    ),
                ));
            }
            p as u32
        }
    };
    let sign = if reversed { -1.0 } else { 1.0 };
    let scale = TAU / 65536.0;
    let kept: Vec<(u8, u16, u16)> = rows
        .iter()
        .copied()
        .filter(|r| r.0 == 1)
        .skip(SETTLING_SAMPLES)
        .chain(rows.iter().copied().filter(|r| r.0 == 2))
        .collect();
    let mut commanded = 0.0;
    let samples = kept
        .iter()
        .enumerate()
        .map(|(k, &(_, p, e))| {
            if k > 0 {
                commanded += step(kept[k - 1].1, p);
            }
            let reference = f64::from(kept[0].1) + commanded;
            (
                k as f64 * SAMPLE_PERIOD_S,
                f64::from(e) * scale,
                sign * reference * scale / f64::from(pole_pairs),
            )
        })
        .collect();
    Ok(CalDump {
        samples,
        pole_pairs,
        ratio: ratio.abs(),
        encoder_reversed: reversed,
        rising: rising.len(),
        falling,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_a_dump_and_finds_the_pole_pairs() {
        let dir = std::env::temp_dir().join(format!("calib-moteus-dump-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("dump.txt");
        let mut text = String::from("CAL start\n");
        // 7 pole pairs, the encoder counting against the phase, 200 samples each way.
        for k in 0..200u32 {
            let phase = (k * 7 * 65536 / 200) as u16;
            let encoder = (40000u32.wrapping_sub(k * 65536 / 200) % 65536) as u16;
            text += &format!("1 {phase} {encoder}\n");
        }
        for k in (0..200u32).rev() {
            let phase = (k * 7 * 65536 / 200) as u16;
            let encoder = (40000u32.wrapping_sub(k * 65536 / 200) % 65536) as u16;
            text += &format!("2 {phase} {encoder} i1=1 i2=2\n");
        }
        text += "CAL done\n";
        std::fs::write(&path, &text).unwrap();
        let d = read_cal_dump(&path, None).unwrap();
        assert_eq!(d.pole_pairs, 7);
        assert!(d.encoder_reversed);
        assert_eq!((d.rising, d.falling), (196, 200));
        // The commanded angle follows the encoder (both decreasing while the phase rises).
        let (a, b) = (d.samples[0], d.samples[10]);
        assert!((b.2 - a.2) < 0.0 && (b.1 - a.1) < 0.0);
        std::fs::write(&path, "CAL start\n1 2 x\nCAL done\n").unwrap();
        let e = read_cal_dump(&path, None).unwrap_err().to_string();
        assert!(e.contains("line 2") && e.contains("encoder"), "{e}");
        // A byte order mark before `CAL start` is read past (a dump saved by a Windows editor).
        let with_bom = format!("\u{feff}{text}");
        std::fs::write(&path, with_bom).unwrap();
        assert_eq!(read_cal_dump(&path, None).unwrap(), d);
        std::fs::write(&path, "CAL start\n1 2 3\n").unwrap();
        assert!(
            read_cal_dump(&path, None)
                .unwrap_err()
                .to_string()
                .contains("CAL done")
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
