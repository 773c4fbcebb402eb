//! Round trips export → import for every format, and the forms controllers print.

use super::*;
use crate::export::{self, ExportOptions};
use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::{FourierSeries, Harmonic, TableMap};

/// 300″ at order 1, 40″ at 5, 3″ at 30 on `points` points: |error| ≤ 343″.
fn source(points: usize) -> ErrorMap {
    let hs = [
        Harmonic::from_arcsec_deg(1, 300.0, 20.0),
        Harmonic::from_arcsec_deg(5, 40.0, -60.0),
        Harmonic::from_arcsec_deg(30, 3.0, 0.0),
    ];
    ErrorMap::from_series(&FourierSeries::from_harmonics(&hs, 30), points)
}

fn read(text: &str, opts: &ImportOptions) -> Result<Imported, Error> {
    parse(text, Path::new("t.txt"), opts)
}

/// Half a code of each format's export of [`source`], radians; its header's scale where it has
/// one.
fn half_code(format: Format, header: &[String]) -> f64 {
    let scale = || {
        header
            .iter()
            .find_map(|l| l.strip_prefix("scale: "))
            .and_then(|l| l.rsplit(' ').next())
            .and_then(|s| s.parse::<f64>().ok())
            .expect("scale line")
    };
    match format {
        // Half a code of the scale in the header (arcseconds a code).
        Format::LutI16 | Format::LutU16 | Format::LutI8 => scale() / 2.0 / ARCSEC_PER_RAD,
        // compensation_scale is the largest |correction|, 127 codes.
        Format::Moteus | Format::MoteusConfig => {
            let largest = source(256).max_abs_arcsec();
            largest / 127.0 / 2.0 / ARCSEC_PER_RAD
        }
        Format::Simplefoc => export::simplefoc::QUANTUM_RAD / 2.0,
        // f32 of values up to 343″ (1.7·10⁻³ rad): 2⁻²⁴ relative.
        Format::LutF32Rad | Format::SimplefocFloat => 1e-10,
        // 6 decimals of an arcsecond, then the f32 a C compiler makes of up to 343″ (2·10⁻⁵″).
        Format::CArray => 2.1e-5 / ARCSEC_PER_RAD,
        // 6 decimals of an arcsecond.
        _ => 5.0e-7 / ARCSEC_PER_RAD,
    }
}

#[test]
fn every_format_round_trips_within_half_a_code() {
    // Every format calib exports and reads back: a new one is covered without a line here.
    for format in Format::ALL.into_iter().filter(|f| readable(*f)) {
        // A table of the size the export writes, so that it is written as it is.
        let points = format.required_points().unwrap_or(200);
        let map = source(points);
        let mut opts = ExportOptions::new(format, "t");
        opts.points = Some(points);
        let out = export::export(&TableMap::from(map.clone()), &opts).unwrap();
        // moteus's `conf set` lines carry no header; the others carry it.
        let got = read(&out.text, &ImportOptions::new(format)).unwrap();
        assert_eq!(got.values.len(), points, "{format:?}");
        let tol = half_code(format, &out.header);
        let worst = got
            .values
            .iter()
            .zip(map.values())
            .map(|(g, w)| (g - w).abs())
            .fold(0.0, f64::max);
        // The decoding's own f32 arithmetic adds 2⁻²⁴ of the value at most.
        let bound = tol * (1.0 + 1e-6) + 343.0 / ARCSEC_PER_RAD * 6e-8;
        assert!(
            worst <= bound,
            "{format:?}: {}″ > {}″",
            worst * ARCSEC_PER_RAD,
            bound * ARCSEC_PER_RAD
        );
        // The map is the same, zero mean.
        assert!(got.map.values().iter().sum::<f64>().abs() < 1e-9);
        assert!((got.map.values()[3] - (got.values[3] - got.mean)).abs() < 1e-15);
    }
}

/// What `printLUT()` prints (simplefoc/Arduino-FOC-drivers since PR #75), read as the driver
/// decodes it.
#[test]
fn print_lut_output_is_read_with_its_settings_as_notes() {
    let text = "\n// Calibrated Sensor LUT\nuint16_t calibrationLut[4] = {\n32777, 32767, 32757, \
                32767\n};\nfloat zero_electric_angle = 2.35;\nDirection sensor_direction = \
                Direction::CW;\n\n";
    let got = read(text, &ImportOptions::new(Format::Simplefoc)).unwrap();
    let code = 10.0 / f64::from(export::simplefoc::LUT_SCALE);
    let want = [code, 0.0, -code, 0.0];
    for (g, w) in got.values.iter().zip(want) {
        // decodeOffsetU16 in f32: 2⁻²⁴ of 10⁻³ rad.
        assert!((g - w).abs() < 1e-10, "{g} vs {w}");
    }
    assert!(
        got.notes
            .iter()
            .any(|n| n.contains("zero_electric_angle = 2.35"))
    );
    assert!(
        got.notes
            .iter()
            .any(|n| n.contains("sensor_direction = Direction::CW"))
    );
    // A float table is the earlier release's, and says so.
    let err = read(
        "float calib_lut[2] = { 1e-4f, -1e-4f };",
        &ImportOptions::new(Format::Simplefoc),
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("`format = simplefoc-float`"), "{err}");
    // A table cut short.
    let err = read(
        "uint16_t calibrationLut[5] = {1, 2, 3, 4};",
        &ImportOptions::new(Format::Simplefoc),
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("declared with 5 entries but holds 4"), "{err}");
    let err = read(
        "uint16_t calibrationLut[2] = {1, 70000};",
        &ImportOptions::new(Format::Simplefoc),
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("line 1") && err.contains("`70000`"), "{err}");
}

/// `conf get` answers, a configuration dump with other keys, and the source chosen.
#[test]
fn moteus_settings_are_read_in_every_form() {
    let mut dump = String::from("servo.pid_position.kp 4\nmotor_position.sources.0.cpr 16384\n");
    let mut transcript = String::new();
    for i in 0..256 {
        let code = if i % 2 == 0 { 127 } else { -127 };
        dump.push_str(&format!(
            "motor_position.sources.1.compensation_table.{i} {code}\n"
        ));
        transcript.push_str(&format!(
            "conf get motor_position.sources.1.compensation_table.{i}\n{code}\n"
        ));
    }
    dump.push_str("motor_position.sources.1.compensation_scale 0.001\n");
    transcript.push_str("conf get motor_position.sources.1.compensation_scale\n0.001\n");
    for text in [&dump, &transcript] {
        let got = read(text, &ImportOptions::new(Format::Moteus)).unwrap();
        // Entry 0 adds 127·0.001/127 rev: an error of −0.001 rev.
        let want = -0.001 * std::f64::consts::TAU;
        assert!((got.values[0] - want).abs() < 1e-9, "{}", got.values[0]);
        assert!((got.values[1] + want).abs() < 1e-9);
        assert!(got.notes[0].starts_with("moteus source 1"));
    }
    let mut opts = ImportOptions::new(Format::Moteus);
    opts.moteus_source = Some(0);
    let err = read(&dump, &opts).unwrap_err().to_string();
    assert!(err.contains("only of source 1"), "{err}");
    let cut = dump.replace("motor_position.sources.1.compensation_table.77 -127\n", "");
    let err = read(&cut, &ImportOptions::new(Format::Moteus))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("lacks 1 of its 256") && err.contains("compensation_table.77"),
        "{err}"
    );
    let bad = dump.replace("table.5 -127", "table.5 0.25");
    let err = read(&bad, &ImportOptions::new(Format::Moteus))
        .unwrap_err()
        .to_string();
    assert!(err.contains("int8"), "{err}");
}

#[test]
fn integer_tables_need_their_scale() {
    let err = read("1\n-1\n", &ImportOptions::new(Format::LutI16))
        .unwrap_err()
        .to_string();
    assert!(err.contains("the `scale_arcsec` option"), "{err}");
    let mut opts = ImportOptions::new(Format::LutI16);
    opts.scale_arcsec = Some(0.5);
    let got = read("2\n-2\n", &opts).unwrap();
    assert!((got.values[0] * ARCSEC_PER_RAD + 1.0).abs() < 1e-12);
    let err = read("# range: 10.000000 to 20.000000 deg\n1\n2\n", &opts)
        .unwrap_err()
        .to_string();
    assert!(err.contains("range table"), "{err}");
    let err = read("# scale: correction_arcsec = code * 1e0\n1\n2\n", &opts)
        .unwrap_err()
        .to_string();
    assert!(err.contains("the `scale_arcsec` option says 0.5"), "{err}");
}

/// A table beyond the point limit is refused as it is counted.
#[test]
fn tables_beyond_the_point_limit_are_refused() {
    let text = "1e-6\n".repeat(MAX_TABLE_POINTS + 1);
    let err = read(&text, &ImportOptions::new(Format::LutF32Rad))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains(&format!("line {}", MAX_TABLE_POINTS + 1)),
        "{err}"
    );
}

/// One rule for every importer: a file holding two tables is refused, naming the lines of both,
/// rather than one of them read silently (the first printLUT() table, the last value of each
/// moteus key); a moteus key repeated with its own value is read once.
#[test]
fn two_tables_in_one_file_are_refused_naming_their_lines() {
    let lut = |codes: &str| format!("uint16_t calibrationLut[2] = {{{codes}}};\n");
    let text = format!(
        "{}float zero_electric_angle = 2.35;\n{}",
        lut("1, 2"),
        lut("3, 4")
    );
    let err = read(&text, &ImportOptions::new(Format::Simplefoc))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("two tables") && err.contains("line 1") && err.contains("line 3"),
        "{err}"
    );
    // An array of another type beside the table is not a table.
    let text = format!("int pins[2] = {{3, 5}};\n{}", lut("32767, 32767"));
    let err = read(&text, &ImportOptions::new(Format::Simplefoc));
    assert!(err.is_err(), "the first array is still the table read");
    let text = format!("{}int pins[2] = {{3, 5}};\n", lut("32767, 32767"));
    assert!(read(&text, &ImportOptions::new(Format::Simplefoc)).is_ok());

    let mut dump = String::new();
    for i in 0..256 {
        dump.push_str(&format!(
            "motor_position.sources.0.compensation_table.{i} 5\n"
        ));
    }
    dump.push_str("motor_position.sources.0.compensation_scale 0.001\n");
    // The same values again (a `conf get` answer, a dump read twice): read once.
    let again = format!("{dump}{dump}");
    assert!(read(&again, &ImportOptions::new(Format::Moteus)).is_ok());
    let other = format!("{dump}{}", dump.replace("table.9 5", "table.9 -7"));
    let err = read(&other, &ImportOptions::new(Format::Moteus))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("compensation_table.9` is set twice")
            && err.contains("to 5 on line 10")
            && err.contains("to -7 on line 267"),
        "{err}"
    );
    let scaled = format!("{dump}motor_position.sources.0.compensation_scale 0.002\n");
    let err = read(&scaled, &ImportOptions::new(Format::Moteus))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("line 257") && err.contains("line 258"),
        "{err}"
    );

    // calib's own exports pasted together.
    for format in [Format::Csv, Format::LutI16, Format::LutF32Rad] {
        let out = export::export(
            &TableMap::from(source(64)),
            &ExportOptions::new(format, "t"),
        )
        .unwrap();
        let twice = format!("{}{}", out.text, out.text);
        let err = read(&twice, &ImportOptions::new(format))
            .unwrap_err()
            .to_string();
        assert!(err.contains("two tables"), "{format:?}: {err}");
        assert!(read(&out.text, &ImportOptions::new(format)).is_ok());
    }
}
