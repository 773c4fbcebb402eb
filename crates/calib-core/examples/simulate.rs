//! Simulate a recorded CSRR run in memory and look at its samples and its truth.
//!
//! `cargo run -p calib-core --example simulate`

use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::simulate::Scenario;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // Two sensors, five sessions of two revolutions at 60 r/min, 200 Hz.
    let scenario: Scenario = toml::from_str(
        r#"
        seed = 1
        rate_hz = 200.0
        speed_rpm = 60.0
        [[sensor]]
        name = "a"
        mount = "a"
        harmonics = [{ order = 8, amplitude_arcsec = 20.0, phase_deg = 30.0 }]
        noise_arcsec = 0.05
        [[sensor]]
        name = "b"
        harmonics = [{ order = 6, amplitude_arcsec = 15.0 }]
        noise_arcsec = 0.05
        [procedure]
        relative_deg = [0.0, 7.3, 23.9, 61.7, 151.1]
        revolutions = 2.0
        ramp_s = 0.25
        pause_s = 0.2
        turn_s = 0.5
        "#,
    )?;
    scenario.validate()?;
    let channels: Vec<String> = scenario.channels().into_iter().map(|c| c.name).collect();
    let samples = scenario.samples()?;
    let duration = samples.duration_s();
    let (mut n, mut last) = (0usize, None);
    for sample in samples {
        n += 1;
        last = Some(sample);
    }
    let last = last.ok_or("the scenario gave no samples")?;
    println!(
        "{n} samples of {channels:?} over {duration:.2} s; the last at t = {:.3} s",
        last.t
    );
    assert_eq!(n as f64, (duration * 200.0).round() + 1.0);

    // The truth: each sensor's error map over its own reading, zero mean.
    for (name, map) in scenario.truth(3600)? {
        let pp = map.peak_to_peak() * ARCSEC_PER_RAD;
        println!(
            "truth of {name}: {} points, {pp:.3}″ peak to peak",
            map.len()
        );
        // One harmonic of amplitude A has a peak-to-peak of 2A.
        let amplitude = if name == "a" { 20.0 } else { 15.0 };
        assert!((pp - 2.0 * amplitude).abs() < 0.01, "{name}: {pp}");
    }
    Ok(())
}
