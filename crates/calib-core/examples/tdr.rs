//! Self-calibrate one encoder from a free spin-down (TDR): the shaft coasts down on an air
//! bearing, its motion is smooth in time, and what is periodic in angle is the encoder's error.
//!
//! `cargo run -p calib-core --example tdr`

use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::simulate::Scenario;
use calib_core::tdr::{Tdr, TdrOptions};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // Released at 600 r/min, coasting 15 s (about 130 revolutions at falling speed), 1 kHz.
    let scenario: Scenario = toml::from_str(
        r#"
        seed = 11
        rate_hz = 1000.0
        [spin_down]
        speed_rpm = 600.0
        duration_s = 15.0
        friction = { coulomb = 0.05, viscous = 0.015, quadratic = 1e-4 }
        [[sensor]]
        name = "enc"
        harmonics = [
          { order = 1, amplitude_arcsec = 8.0, phase_deg = 40.0 },
          { order = 2, amplitude_arcsec = 25.0, phase_deg = -70.0 },
          { order = 5, amplitude_arcsec = 6.0, phase_deg = 150.0 },
        ]
        quantization_arcsec = 0.09
        noise_arcsec = 0.05
        "#,
    )?;
    let mut tdr = Tdr::new(TdrOptions::default());
    for s in scenario.samples()? {
        tdr.push(s.t, s.values[0]);
    }
    let cal = tdr.finish()?;

    let truth = &scenario.truth(cal.map.len())?[0].1;
    let error = truth.minus(&cal.map).max_abs_arcsec();
    println!(
        "{:.0} revolutions from {:.0} to {:.0} r/min; map {:.2}″ p-p, residual {:.3}″ RMS, \
         max |map − truth| {error:.4}″",
        cal.revolutions,
        cal.speed_start.abs() * 60.0 / std::f64::consts::TAU,
        cal.speed_end.abs() * 60.0 / std::f64::consts::TAU,
        cal.map.peak_to_peak() * ARCSEC_PER_RAD,
        cal.residual_rms * ARCSEC_PER_RAD
    );
    // 0.05″ of noise and 0.09″ steps average over 15 000 samples; the orders are chosen from
    // the data, and only the three present (and those noise makes look present) are kept.
    if error > 0.05 {
        return Err(format!("map off by {error:.4}″ (expected < 0.05″)").into());
    }
    Ok(())
}
