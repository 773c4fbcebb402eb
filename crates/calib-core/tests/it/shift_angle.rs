//! Shift-angle calibration against a simulated truth.
//!
//! The simulator follows the paper's eq. 3: a true encoder error (harmonics, including orders 24
//! and 48 that a 24-face polygon cannot see), true pitch deviations (random, Σβ = 0), a new
//! setup error for every start face of every shift, autocollimator noise σ and resolution.
//!
//! The committed fixture `testdata/shift-angle/readings.csv` (with `truth_encoder.csv` and
//! `truth_polygon.csv`) is [`paper_design`]'s output; `fixture_is_current` checks it, and
//! `CALIB_REGENERATE=1 cargo test -p calib-core --test it shift_angle::fixture_is_current` rewrites it.

use calib_core::shift_angle::{Method, Readings, Shift, StartFaceRow, calibrate};
use std::f64::consts::TAU;
use std::fmt::Write as _;
use std::path::PathBuf;

/// splitmix64: a tiny, well-mixed, reproducible generator (no rand dependency).
struct Rng(u64);
impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Standard normal by Box–Muller.
    fn normal(&mut self) -> f64 {
        let u1 = 1.0 - self.uniform();
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (TAU * u2).cos()
    }
}

const FACES: usize = 24;
/// (order, amplitude arcsec, phase deg) of the true encoder error.
const HARMONICS: [(usize, f64, f64); 8] = [
    (1, 12.0, 30.0),
    (2, 5.0, -40.0),
    (3, 0.8, 100.0),
    (5, 0.4, 10.0),
    (11, 0.25, -120.0),
    (24, 0.2, 60.0),
    (37, 0.1, 0.0),
    (48, 0.05, 45.0),
];

fn alpha_true(deg: f64) -> f64 {
    HARMONICS
        .iter()
        .map(|&(h, a, p)| a * (h as f64 * deg.to_radians() + p.to_radians()).cos())
        .sum()
}
/// What a shift-angle map can see: the truth less its orders that are multiples of n.
fn alpha_visible(deg: f64) -> f64 {
    HARMONICS
        .iter()
        .filter(|&&(h, _, _)| h % FACES != 0)
        .map(|&(h, a, p)| a * (h as f64 * deg.to_radians() + p.to_radians()).cos())
        .sum()
}

struct Sim {
    readings: Readings,
    beta: Vec<f64>,
    sigma: f64,
}

/// Simulated readings: shifts 0..14° (1° steps, n = 24); `faces_at(shift index)` lists the start
/// faces measured there. Noise σ arcsec, resolution 0.001″.
fn simulate(seed: u64, sigma: f64, faces_at: impl Fn(usize) -> Vec<usize>) -> Sim {
    let n = FACES;
    let mut rng = Rng(seed);
    let raw: Vec<f64> = (0..n).map(|_| 0.5 * rng.normal()).collect();
    let mean = raw.iter().sum::<f64>() / n as f64;
    let beta: Vec<f64> = raw.iter().map(|b| b - mean).collect();
    let resolution = 0.001;
    let mut shifts = Vec::new();
    for s in 0..15 {
        let shift_deg = s as f64;
        let rows = faces_at(s)
            .into_iter()
            .map(|j| {
                let setup = 2.0 * (rng.uniform() - 0.5) * 2.0;
                let readings_arcsec = (0..n)
                    .map(|i| {
                        let angle = i as f64 * 15.0 + shift_deg;
                        let pitch_sum: f64 = (0..=i).map(|m| beta[(j - 1 + m) % n]).sum();
                        let eps = alpha_true(angle) + pitch_sum + setup + sigma * rng.normal();
                        (eps / resolution).round() * resolution
                    })
                    .collect();
                StartFaceRow {
                    start_face: j,
                    readings_arcsec,
                }
            })
            .collect();
        shifts.push(Shift { shift_deg, rows });
    }
    Sim {
        readings: Readings::new(n, shifts).unwrap(),
        beta,
        sigma,
    }
}

/// The paper's design: the full 24×24 matrix at S = 0, start face 1 only at S = 1..14°.
fn paper_design(seed: u64, sigma: f64) -> Sim {
    simulate(seed, sigma, |s| {
        if s == 0 {
            (1..=FACES).collect()
        } else {
            vec![1]
        }
    })
}

struct Errors {
    rms_s0: f64,
    rms_other: f64,
    max: f64,
    beta_rms: f64,
}

fn errors(sim: &Sim, method: Method) -> (Errors, calib_core::shift_angle::ShiftAngleResult) {
    let r = calibrate(&sim.readings, method).unwrap();
    let (mut ss0, mut n0, mut ss1, mut n1, mut max) = (0.0, 0, 0.0, 0, 0.0f64);
    for p in &r.points {
        let e = p.error_arcsec - alpha_visible(p.angle_deg);
        max = max.max(e.abs());
        if p.shift_deg == 0.0 {
            ss0 += e * e;
            n0 += 1;
        } else {
            ss1 += e * e;
            n1 += 1;
        }
    }
    let beta_ss: f64 = r
        .polygon
        .iter()
        .map(|f| (f.pitch_deviation_arcsec - sim.beta[f.face - 1]).powi(2))
        .sum();
    let errs = Errors {
        rms_s0: (ss0 / n0 as f64).sqrt(),
        rms_other: if n1 > 0 {
            (ss1 / n1 as f64).sqrt()
        } else {
            0.0
        },
        max,
        beta_rms: (beta_ss / FACES as f64).sqrt(),
    };
    (errs, r)
}

#[test]
fn both_methods_recover_the_visible_truth_in_the_papers_design() {
    let sim = paper_design(7, 0.03);
    let s = sim.sigma;
    for method in [Method::Joint, Method::Paper] {
        let (e, r) = errors(&sim, method);
        eprintln!(
            "{method:?}: S=0 rms {:.4}, S>0 rms {:.4}, max {:.4}, beta rms {:.4}",
            e.rms_s0, e.rms_other, e.max, e.beta_rms
        );
        assert_eq!(r.points.len(), 360);
        // S = 0: each α is the mean of 24 start faces, so its noise is ≈ σ/√24 ≈ 0.2σ, plus the
        // error of the cumulative β sums (≈ 0.2σ); 0.45σ leaves room for the sample RMS of 24.
        assert!(e.rms_s0 < 0.45 * s, "{method:?} S=0 rms {}", e.rms_s0);
        // S > 0: one reading per α, so ≈ σ·sqrt(1 − 1/24) plus the β-sum error: within
        // 0.8σ … 1.3σ for 336 points.
        assert!(
            (0.8 * s..1.3 * s).contains(&e.rms_other),
            "{method:?} S>0 rms {}",
            e.rms_other
        );
        // Largest of 360 roughly normal errors of ≤ 1.1σ: 4.5·1.1σ is a 1-in-10⁴ event.
        assert!(e.max < 5.0 * s, "{method:?} max {}", e.max);
        // β_k is a mean of 24 differences of two readings: ≈ σ·sqrt(2/24) ≈ 0.29σ.
        assert!(e.beta_rms < 0.45 * s, "{method:?} beta rms {}", e.beta_rms);
        // Residual σ̂ estimates the simulated σ (dof = 576 − 70 = 506: ±10 % is > 3 sd).
        let sig = r.residuals.sigma_arcsec.unwrap();
        assert!((0.9 * s..1.1 * s).contains(&sig), "{method:?} sigma {sig}");
    }
}

#[test]
fn in_the_papers_design_the_two_methods_agree_to_rounding() {
    let sim = paper_design(11, 0.05);
    let joint = calibrate(&sim.readings, Method::Joint).unwrap();
    let paper = calibrate(&sim.readings, Method::Paper).unwrap();
    let max_alpha = joint
        .points
        .iter()
        .zip(&paper.points)
        .map(|(a, b)| (a.error_arcsec - b.error_arcsec).abs())
        .fold(0.0, f64::max);
    let max_beta = joint
        .polygon
        .iter()
        .zip(&paper.polygon)
        .map(|(a, b)| (a.pitch_deviation_arcsec - b.pitch_deviation_arcsec).abs())
        .fold(0.0, f64::max);
    eprintln!("joint vs paper: alpha {max_alpha:e}, beta {max_beta:e}");
    // Both are the least-squares estimate of this balanced design (module docs).
    assert!(
        max_alpha < 1e-9 && max_beta < 1e-9,
        "{max_alpha} {max_beta}"
    );
}

#[test]
fn redundant_start_faces_average_down_and_uncertainties_match() {
    // Full matrix at S = 0, and faces 1, 7, 13, 19 at every other shift (4 rows each).
    let sim = simulate(23, 0.05, |s| {
        if s == 0 {
            (1..=FACES).collect()
        } else {
            vec![1, 7, 13, 19]
        }
    });
    let (joint, jr) = errors(&sim, Method::Joint);
    let (paper, _) = errors(&sim, Method::Paper);
    eprintln!(
        "4 faces/shift: joint S>0 rms {:.4}, paper {:.4}",
        joint.rms_other, paper.rms_other
    );
    // Averaging 4 start faces: ≈ σ/2 for both (with evenly spaced faces their α agree exactly).
    assert!(joint.rms_other < 0.7 * sim.sigma);
    assert!(joint.rms_other <= paper.rms_other * 1.02);
    // The fit's uncertainties describe its errors: mean of (error/u)² ≈ 1 (360 points, ±30 %).
    let z2 = jr
        .points
        .iter()
        .map(|p| ((p.error_arcsec - alpha_visible(p.angle_deg)) / p.u_arcsec.unwrap()).powi(2))
        .sum::<f64>()
        / jr.points.len() as f64;
    assert!((0.7..1.3).contains(&z2), "mean z² {z2}");
}

#[test]
fn uncertainties_from_the_fit_match_the_errors_in_the_papers_design() {
    let sim = paper_design(5, 0.03);
    let (_, r) = errors(&sim, Method::Joint);
    let z2 = r
        .points
        .iter()
        .map(|p| ((p.error_arcsec - alpha_visible(p.angle_deg)) / p.u_arcsec.unwrap()).powi(2))
        .sum::<f64>()
        / r.points.len() as f64;
    assert!((0.7..1.3).contains(&z2), "mean z² {z2}");
    for f in &r.polygon {
        // β's standard uncertainty ≈ σ·sqrt(2/24)… within a factor 2.
        let u = f.u_arcsec.unwrap();
        assert!((0.1 * sim.sigma..0.6 * sim.sigma).contains(&u), "{u}");
    }
}

#[test]
fn noise_free_readings_give_the_visible_truth_and_the_sin_fit_identity() {
    let sim = paper_design(3, 0.0);
    for method in [Method::Joint, Method::Paper] {
        let (e, r) = errors(&sim, method);
        // Only the 0.001″ resolution remains (≤ 0.0005″ per reading, ~a few readings summed).
        assert!(e.max < 0.003, "{method:?} {}", e.max);
        assert!(e.beta_rms < 0.001);
        // The orders 24 and 48 are invisible: the estimate is far from the raw truth there.
        let raw_max = r
            .points
            .iter()
            .map(|p| (p.error_arcsec - alpha_true(p.angle_deg)).abs())
            .fold(0.0, f64::max);
        assert!(raw_max > 0.15, "{raw_max}");
        // The sin fit finds the order-2 amplitude (5″) from S = 0 alone, to within the orders
        // 22 and 26 that alias onto order 2 on a 24-point grid (none here) and rounding.
        assert!((r.sin_fit.amplitude_arcsec - 5.0).abs() < 0.01);
        for s in &r.sin_fit.shifts {
            assert!(s.difference_arcsec.abs() < 1e-9);
        }
    }
}

fn fixture_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../testdata/shift-angle")
}

/// The fixture files' contents, from the paper's design with seed 2022 and σ = 0.03″.
fn fixture_files() -> Vec<(&'static str, String)> {
    let sim = paper_design(2022, 0.03);
    let mut readings = String::from("shift_deg,start_face,step,reading_arcsec\n");
    for shift in sim.readings.shifts() {
        for row in &shift.rows {
            for (i, v) in row.readings_arcsec.iter().enumerate() {
                writeln!(
                    readings,
                    "{},{},{},{:.3}",
                    shift.shift_deg,
                    row.start_face,
                    i + 1,
                    v
                )
                .unwrap();
            }
        }
    }
    let mut encoder = String::from("angle_deg,error_arcsec,visible_error_arcsec\n");
    for a in 0..360 {
        let a = a as f64;
        writeln!(encoder, "{a},{:.6},{:.6}", alpha_true(a), alpha_visible(a)).unwrap();
    }
    let mut polygon = String::from("face,pitch_deviation_arcsec\n");
    for (k, b) in sim.beta.iter().enumerate() {
        writeln!(polygon, "{},{:.6}", k + 1, b).unwrap();
    }
    vec![
        ("readings.csv", readings),
        ("truth_encoder.csv", encoder),
        ("truth_polygon.csv", polygon),
    ]
}

#[test]
fn fixture_is_current() {
    let dir = fixture_dir();
    for (name, text) in fixture_files() {
        let path = dir.join(name);
        if std::env::var_os("CALIB_REGENERATE").is_some() {
            std::fs::create_dir_all(&dir).unwrap();
            std::fs::write(&path, &text).unwrap();
        }
        let committed = std::fs::read_to_string(&path).unwrap_or_default();
        assert!(
            committed == text,
            "{} differs from the simulator's output; regenerate with CALIB_REGENERATE=1",
            path.display()
        );
    }
}

#[test]
fn partial_matrices_sharpen_beta_in_the_joint_fit_only() {
    // Full matrix at S = 0, faces 1 and 2 at every other shift: the paper's β ignores the 14
    // extra pairs of rows, the joint fit uses them. Summed over 5 seeds to compare variances,
    // not luck.
    let (mut joint_ss, mut paper_ss) = (0.0, 0.0);
    for seed in 30..35 {
        let sim = simulate(seed, 0.05, |s| {
            if s == 0 {
                (1..=FACES).collect()
            } else {
                vec![1, 2]
            }
        });
        joint_ss += errors(&sim, Method::Joint).0.beta_rms.powi(2);
        paper_ss += errors(&sim, Method::Paper).0.beta_rms.powi(2);
    }
    let (joint, paper) = ((joint_ss / 5.0).sqrt(), (paper_ss / 5.0).sqrt());
    eprintln!("faces 1,2 at S>0: beta rms error joint {joint:.4}, paper {paper:.4}");
    assert!(joint < 0.85 * paper, "{joint} vs {paper}");
}

#[test]
fn the_joint_fit_needs_no_full_matrix() {
    // Start faces 1 and 2 at every shift, nothing else: the paper's Table 2 cannot run; the
    // joint fit determines β (faces 1 apart: gcd(24, 1) = 1) and every α.
    let sim = simulate(41, 0.03, |_| vec![1, 2]);
    assert!(calibrate(&sim.readings, Method::Paper).is_err());
    let (e, _) = errors(&sim, Method::Joint);
    eprintln!(
        "faces 1,2 only: S=0 rms {:.4}, S>0 rms {:.4}, max {:.4}, beta rms {:.4}",
        e.rms_s0, e.rms_other, e.max, e.beta_rms
    );
    // Two readings per α (≈ σ/√2) plus the β sums, which now rest on 15 pairs of rows instead
    // of a full matrix: β errors ≈ σ/√(2·15)… cumulated over up to 12 faces. σ is a safe RMS bound
    // and 5σ a safe maximum.
    assert!(e.rms_other < 1.0 * sim.sigma && e.rms_s0 < 1.0 * sim.sigma);
    assert!(e.max < 5.0 * sim.sigma);
}
