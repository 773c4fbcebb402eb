//! Self-calibrate one scale read by four heads at 0°, 90°, 180° and 270° plus a fifth at 45°,
//! jointly: the scale's map as the first head reads it, and each head's angle error.
//!
//! `cargo run -p calib-core --example multihead`

use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::multihead::{Head, Multihead, MultiheadOptions};
use calib_core::simulate::Scenario;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // A scale with errors at orders 2, 4 (which four equally spaced heads cannot see: the fifth
    // head reveals it), 7 and 30; heads with small angle errors; 2 revolutions at 400 Hz.
    let head = |name: &str, deg: f64, err: f64| {
        format!(
            "[[sensor]]\nname = \"{name}\"\nscale = \"disc\"\nhead_deg = {deg}\n\
             head_error_arcsec = {err}\nquantization_arcsec = 0.01\nnoise_arcsec = 0.01\n"
        )
    };
    let text = format!(
        r#"
        seed = 5
        rate_hz = 400.0
        speed_rpm = 10.0
        [[scale]]
        name = "disc"
        mount = "b"
        harmonics = [
          {{ order = 2, amplitude_arcsec = 1.0, phase_deg = 30.0 }},
          {{ order = 4, amplitude_arcsec = 0.4, phase_deg = -80.0 }},
          {{ order = 7, amplitude_arcsec = 0.2, phase_deg = 120.0 }},
          {{ order = 30, amplitude_arcsec = 0.05, phase_deg = 0.0 }},
        ]
        {}{}{}{}{}
        [procedure]
        relative_deg = [0.0]
        revolutions = 2.0
        ramp_s = 1.0
        pause_s = 1.0
        turn_s = 0.0
        "#,
        head("h1", 0.0, 0.0),
        head("h2", 90.0, 2.0),
        head("h3", 180.0, -1.5),
        head("h4", 270.0, 0.8),
        head("h5", 45.0, -2.2),
    );
    let scenario: Scenario = toml::from_str(&text)?;
    let heads: Vec<Head> = scenario
        .sensors
        .iter()
        .map(|s| Head {
            name: s.name.clone(),
            nominal: s.head_deg.unwrap_or(0.0).to_radians(),
        })
        .collect();
    let mut mh = Multihead::new(
        heads,
        MultiheadOptions {
            max_order: Some(60),
            ..MultiheadOptions::default()
        },
    )?;
    for s in scenario.samples()? {
        mh.push(&s.values);
    }
    let cal = mh.finish()?;

    let truth = &scenario.truth(cal.map.len())?[0].1;
    let error = truth.minus(&cal.map).max_abs_arcsec();
    println!(
        "map {:.3}″ p-p, max |map − truth| {error:.4}″, blind orders {:?}",
        cal.map.peak_to_peak() * ARCSEC_PER_RAD,
        cal.blind.iter().map(|b| b.order).collect::<Vec<_>>()
    );
    for h in &cal.heads {
        println!(
            "  {:<3} at {:>6.1}°: angle error {:+.3}″",
            h.name,
            h.nominal.to_degrees(),
            h.angle_error * ARCSEC_PER_RAD
        );
    }
    // Noise and quantization of 0.01″ average over ~10⁴ samples and 4 head differences.
    if error > 0.02 {
        return Err(format!("map off by {error:.4}″ (expected < 0.02″)").into());
    }
    Ok(())
}
