//! The CSRR seed paper's own method (eqs. 4–7): one point of each map per session, so it needs
//! many sessions spread over the circle — here 40, 9° apart.
//!
//! `cargo run -p calib-core --example csrr_paper`

use calib_core::angle::ARCSEC_PER_RAD;
use calib_core::channel_index;
use calib_core::csrr::{Csrr, CsrrOptions, Method};
use calib_core::simulate::Scenario;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let deltas: Vec<String> = (0..40).map(|k| format!("{}", k * 9)).collect();
    let scenario: Scenario = toml::from_str(&format!(
        r#"
        seed = 7
        rate_hz = 400.0
        speed_rpm = 30.0
        [[sensor]]
        name = "a"
        mount = "a"
        harmonics = [{{ order = 3, amplitude_arcsec = 100.0, phase_deg = 10.0 }}]
        quantization_arcsec = 0.09
        noise_arcsec = 0.05
        [[sensor]]
        name = "b"
        harmonics = [{{ order = 2, amplitude_arcsec = 20.0, phase_deg = 45.0 }}]
        quantization_arcsec = 0.09
        noise_arcsec = 0.05
        [procedure]
        relative_deg = [{}]
        revolutions = 2.2
        ramp_s = 0.05
        pause_s = 0.2
        turn_s = 0.3
        "#,
        deltas.join(", ")
    ))?;
    let channels = scenario.channels();
    let (ia, ib) = (
        channel_index(&channels, "a")?,
        channel_index(&channels, "b")?,
    );
    let mut csrr = Csrr::new(CsrrOptions {
        method: Method::Paper,
        ..CsrrOptions::default()
    });
    for s in scenario.samples()? {
        csrr.push(s.t, s.values[ia], s.values[ib], None);
    }
    let cal = csrr.finish()?;

    // The method's own output: A's error at one angle per session (rad), against the truth.
    let truth = &scenario.truth(36000)?[0].1;
    let diffs: Vec<f64> = cal
        .paper_points
        .iter()
        .map(|p| p.a_error - truth.eval_linear(p.a_angle))
        .collect();
    let mean = diffs.iter().sum::<f64>() / diffs.len() as f64;
    let worst = diffs.iter().fold(0.0f64, |m, d| m.max((d - mean).abs())) * ARCSEC_PER_RAD;
    println!(
        "{} sessions → {} map points; A's map {:.2}″ p-p; max |point − truth| {worst:.3}″",
        cal.sessions.len(),
        cal.paper_points.len(),
        cal.a.peak_to_peak() * ARCSEC_PER_RAD
    );
    for p in cal.paper_points.iter().take(3) {
        println!(
            "  Δ {:>6.2}°: A {:>7.3}° {:>+8.3}″   B {:>7.3}° {:>+8.3}″",
            p.delta.to_degrees(),
            p.a_angle.to_degrees(),
            p.a_error * ARCSEC_PER_RAD,
            p.b_angle.to_degrees(),
            p.b_error * ARCSEC_PER_RAD
        );
    }
    assert!(
        cal.paper_points.len() >= 38,
        "{} points",
        cal.paper_points.len()
    );
    // One crossing per revolution carries the noise: a few tenths of an arcsecond.
    assert!(worst < 0.5, "{worst}″ from the truth");
    Ok(())
}
