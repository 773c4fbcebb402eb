//! Calibrate an encoder at every angle with a polygon and an autocollimator (shift-angle
//! method), from readings made in memory by the paper's eq. 3.
//!
//! `cargo run -p calib-core --example shift_angle`

use calib_core::shift_angle::{Method, Readings, Shift, StartFaceRow, calibrate};

/// The encoder's error, arcsec, at encoder angle `deg`: orders 2 and 3 (an 8-face polygon is
/// blind to orders 8, 16, … only).
fn alpha(deg: f64) -> f64 {
    let t = deg.to_radians();
    2.0 * (2.0 * t + 0.4).cos() + 0.5 * (3.0 * t - 1.0).cos()
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let n = 8;
    let pitch = 360.0 / n as f64;
    // The polygon's pitch deviations β (Σβ = 0), arcsec.
    let beta = [0.8, -0.3, 0.1, -0.6, 0.4, 0.2, -0.5, -0.1];
    // ε_ij = α((i−1)·P + S) + Σ_{k=j}^{j+i−1} β_k + U_j, with a setup error U_j per row and a
    // hundredth of an arcsecond of deterministic "noise".
    let row = |shift: f64, j: usize| StartFaceRow {
        start_face: j,
        readings_arcsec: (1..=n)
            .map(|i| {
                let sum: f64 = (j..j + i).map(|k| beta[(k - 1) % n]).sum();
                let setup = 3.0 + 0.1 * j as f64 + shift / 10.0;
                let noise = 0.01 * ((i * 7 + j * 3) as f64 + shift).sin();
                alpha((i - 1) as f64 * pitch + shift) + sum + setup + noise
            })
            .collect(),
    };
    // The paper's design: the full matrix at S = 0, start face 1 at the other shifts.
    let mut shifts = vec![Shift {
        shift_deg: 0.0,
        rows: (1..=n).map(|j| row(0.0, j)).collect(),
    }];
    for s in [15.0, 30.0] {
        shifts.push(Shift {
            shift_deg: s,
            rows: vec![row(s, 1)],
        });
    }
    let readings = Readings::new(n, shifts)?;
    let result = calibrate(&readings, Method::Joint)?;

    let worst = result
        .points
        .iter()
        .map(|p| (p.error_arcsec - alpha(p.angle_deg)).abs())
        .fold(0.0, f64::max);
    println!(
        "{} encoder points, max |α − truth| {worst:.4}″; residual RMS {:.4}″ ({} dof)",
        result.points.len(),
        result.residuals.rms_arcsec,
        result.residuals.dof
    );
    for f in &result.polygon {
        println!(
            "  face {}: β = {:+.4}″ (truth {:+.1}″), u = {:.4}″",
            f.face,
            f.pitch_deviation_arcsec,
            beta[f.face - 1],
            f.u_arcsec.unwrap_or(f64::NAN)
        );
        assert!((f.pitch_deviation_arcsec - beta[f.face - 1]).abs() < 0.02);
    }
    assert_eq!(result.points.len(), 3 * n);
    assert!(worst < 0.03, "{worst}″ from the truth");
    Ok(())
}
