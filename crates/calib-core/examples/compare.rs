//! Compare two calibrations of one sensor point by point with the En number.
//!
//! `cargo run -p calib-core --example compare`

use calib_core::compare::{MapPoint, compare};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // A stored calibration on a 1° grid (U = 0.2″) and a new one on a 0.5° grid (U = 0.3″)
    // that differs by 0.1″ of order 5 — and by 2″ at 90°, where something went wrong.
    let error = |deg: f64| 12.0 * (2.0 * deg.to_radians()).cos();
    let stored: Vec<MapPoint> = (0..360)
        .map(|i| MapPoint {
            angle_deg: i as f64,
            error_arcsec: error(i as f64),
            expanded_uncertainty_arcsec: 0.2,
        })
        .collect();
    let new: Vec<MapPoint> = (0..720)
        .map(|i| {
            let deg = i as f64 * 0.5;
            let bump = if deg == 90.0 { 2.0 } else { 0.0 };
            MapPoint {
                angle_deg: deg,
                error_arcsec: error(deg) + 0.1 * (5.0 * deg.to_radians()).sin() + bump,
                expanded_uncertainty_arcsec: 0.3,
            }
        })
        .collect();
    let c = compare(&stored, &new, false)?;
    println!(
        "{} points: max |Δ| {:.3}″, RMS {:.3}″, max En {:.2}, {} with En > 1",
        c.points.len(),
        c.max_abs_difference_arcsec,
        c.rms_difference_arcsec,
        c.max_en,
        c.failures
    );
    for p in c.points.iter().filter(|p| p.en > 1.0) {
        println!(
            "  {:.1}°: Δ = {:+.3}″, En = {:.2}",
            p.angle_deg, p.difference_arcsec, p.en
        );
    }
    assert_eq!(c.failures, 1);
    assert_eq!(
        c.points.iter().find(|p| p.en > 1.0).map(|p| p.angle_deg),
        Some(90.0)
    );
    Ok(())
}
