//! Cross-calibrate an encoder (the DUT) against a better reference encoder on the same shaft,
//! with the ISO 230-2 figures.
//!
//! `cargo run -p calib-core --example reference`

use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::channel_index;
use calib_core::reference_cal::{ReferenceCal, ReferenceOptions};
use calib_core::simulate::Scenario;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // DUT `b` and reference `ref` on the driven shaft: 5 revolutions at 60 r/min, 1000 Hz.
    let scenario: Scenario = toml::from_str(
        r#"
        seed = 3
        rate_hz = 1000.0
        speed_rpm = 60.0
        [[sensor]]
        name = "b"
        harmonics = [
          { order = 6, amplitude_arcsec = 15.0, phase_deg = -120.0 },
          { order = 2, amplitude_arcsec = 2.0, phase_deg = 60.0 },
        ]
        quantization_arcsec = 0.09
        noise_arcsec = 0.05
        [[sensor]]
        name = "ref"
        harmonics = [{ order = 1, amplitude_arcsec = 0.45, phase_deg = 30.0 }]
        quantization_arcsec = 0.001
        noise_arcsec = 0.01
        [procedure]
        relative_deg = [0.0]
        revolutions = 5.0
        ramp_s = 0.25
        pause_s = 0.2
        turn_s = 0.5
        "#,
    )?;
    let channels = scenario.channels();
    let (dut, reference) = (
        channel_index(&channels, "b")?,
        channel_index(&channels, "ref")?,
    );
    let mut cal = ReferenceCal::new(ReferenceOptions::default());
    for s in scenario.samples()? {
        cal.push(s.t, s.values[dut], s.values[reference]);
    }
    let cal = cal.finish()?;

    // The map is DUT − reference: the truth is the difference of the two sensors' maps.
    let truth = scenario.truth(cal.map.len())?;
    let expected = truth[0].1.minus(&truth[1].1);
    let calib_core::TableMap::Turn(map) = &cal.map else {
        return Err("five whole revolutions give a whole-turn map".into());
    };
    let error = expected.minus(map).max_abs_arcsec();
    println!(
        "{:.2} revolutions, {} / {} passes; map {:.3}″ p-p, max |map − truth| {error:.3}″",
        cal.revolutions,
        cal.min_passes.0,
        cal.min_passes.1,
        cal.map.peak_to_peak() * ARCSEC_PER_RAD
    );
    for (name, value) in cal.iso.arcsec() {
        match value {
            Some(v) => println!("  {name:<20} {v:>8.3}″"),
            None => println!("  {name:<20}        —"),
        }
    }
    assert!(error < 0.2, "{error}″ from the truth");
    Ok(())
}
