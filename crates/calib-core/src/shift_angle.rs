//! Shift-angle cross-calibration of a rotary encoder with a polygon and an autocollimator.
//!
//! After Hsieh, Watanabe, Hsu, *Calibration of Rotary Encoders Using a Shift-Angle Method*,
//! Appl. Sci. 12 (2022) 5008.
//!
//! # The measurement (eq. 3)
//! An `n`-face polygon sits on the encoder; the encoder is stepped by the pitch `P = 360°/n`.
//! For a shift angle `S`, a start face `j` (set at encoder angle `S`) and a step `i = 1..n`, the
//! autocollimator reads
//!
//! ```text
//! ε_ij = α((i−1)·P + S) + Σ_{k=j}^{j+i−1 (mod n)} β_k + U_j
//! ```
//!
//! with `α` the encoder's error, `β_k` the polygon's pitch deviations and `U_j` the setup error of
//! that start face (a new one for every start face and every shift). A shift may hold the full
//! `n×n` matrix of Table 1 or only some start faces (the paper measures only face 1 for `S ≠ 0`).
//!
//! # Gauge freedoms and the closures (eqs. 1, 2)
//! Two families of changes leave every `ε_ij` unchanged, so the readings cannot fix them:
//!
//! - `β_k → β_k + c` together with `α((i−1)P + S) → α(…) − i·c` for every shift; fixed by the
//!   polygon's closure `Σβ = 0` (eq. 1), which is true of every polygon.
//! - `α(· + S) → α(· + S) + c_S` with `U_j → U_j − c_S`, one `c_S` per shift; fixed by eq. 2,
//!   `Σ_i α((i−1)P + S) = 0`.
//!
//! # What the method cannot see
//! Eq. 2 is not a law of the encoder: the sum of `α` over `n` equally spaced angles is `n` times
//! the value at `S` of `α`'s harmonics of orders `n, 2n, 3n, …` (the only harmonics that take the
//! same value at all `n` points). Imposing eq. 2 removes exactly that part: the estimated map is
//! `α(θ) − g(θ)`, where `g` is the sum of `α`'s harmonics of orders that are multiples of `n`
//! (period `P`). **Orders `n, 2n, …` are blind**, as in the traditional polygon calibration; the
//! shift angles only fill in the angles between the polygon's faces. The merged map is zero-mean
//! (each shift's points are).
//!
//! # Two estimators
//! - [`Method::Paper`], the paper's two steps: `β` from Table 2 — `β_k` is the mean over `m` of
//!   `ε_{m+1,j} − ε_{m,j}` with `j = k − m (mod n)`, in which the encoder's differences telescope
//!   away (the paper's 25th reading `ε_{n+1,j}` is `ε_{1,j}` under eq. 3, so the mean also meets
//!   eq. 1 exactly) — averaged over every shift that holds the full matrix; then, for every start
//!   face present, `U_j` by eq. 7 (`U_j = mean_i(ε_ij − Σβ)`, using eq. 2) and `α` by eq. 3,
//!   averaged over the start faces present (the paper shows start face 1 only; with one start
//!   face this is literally eqs. 7 and 3).
//! - [`Method::Joint`] (the default): one least-squares estimate of every `α`, `β` and `U` from
//!   every reading present, under the constraints of eqs. 1 and 2, with the residuals and a
//!   standard uncertainty for each unknown from the fit (`σ̂² (AᵀA)⁺` with `σ̂` from the residuals).
//!
//! ## When they agree, and why the joint one is better
//! With noise-free readings both return the truth (less the blind orders). When every shift holds
//! either all `n` start faces or just one — the paper's design, the full matrix at `S = 0` and
//! start face 1 elsewhere — they agree to rounding (1e-12″ in the tests): the Table 2 means and
//! eq. 7 are then the least-squares estimates of the balanced full matrix, and a single-face
//! shift has no redundancy, so its `α` is eq. 3 with the same `β` in both. They differ when a shift
//! holds several but not all start faces: the paper's `β` ignores those rows, the joint fit uses
//! them (simulated: faces 1 and 2 at S = 1…14°, `β` RMS error 0.0115″ joint vs 0.0150″ paper, test
//! `partial_matrices_sharpen_beta_in_the_joint_fit_only`). The joint fit also runs without any full
//! matrix (any start faces whose spacings share no factor with `n`), and it gives what the
//! paper's steps do not: residuals (a check of the measurement and of the model, with `σ̂`) and
//! a standard uncertainty for every `α`, `β` and `U`, valid for equal, independent reading noise.
//!
//! # Sin-fit check (section 3.1)
//! The paper checks the setup error by fitting `α(θ) + U = A·sin(2θ + B) + U_fit` to one row of a
//! shift, with `A` and `B` fitted at the reference shift and held for the others. For a complete
//! row of `n ≥ 3` equally spaced angles, `Σ sin(2θ_i + B) = 0`, so `U_fit` equals eq. 7's `U`
//! identically (the paper's "difference below 10⁻⁴″" is that identity); the useful parts of the
//! diagnostic are the fitted `A`, `B` and the residual RMS (how much of `α` is not of order 2).
//! See [`SinFit`].

use nalgebra::{DMatrix, DVector};
use std::collections::BTreeSet;

/// The readings of one start face at one shift: `ε_ij` for `i = 1..n`, arcsec.
#[derive(Debug, Clone, PartialEq)]
pub struct StartFaceRow {
    /// The start face `j`, 1-based.
    pub start_face: usize,
    /// `ε_ij` at index `i − 1`, arcsec.
    pub readings_arcsec: Vec<f64>,
}

/// The readings of one shift angle.
#[derive(Debug, Clone, PartialEq)]
pub struct Shift {
    /// The shift angle `S`, degrees, in `[0, 360/n)`.
    pub shift_deg: f64,
    /// The start faces measured at this shift, one row each.
    pub rows: Vec<StartFaceRow>,
}

/// A validated set of shift-angle readings (see the module docs for the model).
#[derive(Debug, Clone, PartialEq)]
pub struct Readings {
    faces: usize,
    shifts: Vec<Shift>,
}

/// Why readings cannot be used or a method cannot run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ShiftAngleError {
    /// Fewer than 3 faces.
    #[error("a polygon needs at least 3 faces, the readings have {faces}")]
    TooFewFaces {
        /// Faces found.
        faces: usize,
    },
    /// No shift at all.
    #[error("there are no readings")]
    NoReadings,
    /// A shift angle outside `[0, P)` or not finite.
    #[error(
        "shift {shift_deg}°: shift angles must lie in [0, {pitch_deg}°) (the pitch 360/n); a shift of one pitch or more repeats the angles of a smaller one"
    )]
    ShiftOutOfRange {
        /// The shift.
        shift_deg: f64,
        /// The pitch.
        pitch_deg: f64,
    },
    /// Two shifts with the same angle.
    #[error("shift {shift_deg}° appears twice: merge its rows into one shift")]
    DuplicateShift {
        /// The shift.
        shift_deg: f64,
    },
    /// A shift without any start-face row.
    #[error("shift {shift_deg}° has no readings: measure at least one start face over all steps")]
    EmptyShift {
        /// The shift.
        shift_deg: f64,
    },
    /// A start face outside `1..=n`.
    #[error("shift {shift_deg}°: start face {start_face} does not exist on a {faces}-face polygon")]
    BadStartFace {
        /// The shift.
        shift_deg: f64,
        /// The start face.
        start_face: usize,
        /// Faces.
        faces: usize,
    },
    /// The same start face twice in a shift.
    #[error("shift {shift_deg}°: start face {start_face} appears twice")]
    DuplicateStartFace {
        /// The shift.
        shift_deg: f64,
        /// The start face.
        start_face: usize,
    },
    /// A row with the wrong number of steps.
    #[error(
        "shift {shift_deg}°, start face {start_face}: {found} readings, a {faces}-face polygon needs one per step 1..{faces}"
    )]
    RowLength {
        /// The shift.
        shift_deg: f64,
        /// The start face.
        start_face: usize,
        /// Readings found.
        found: usize,
        /// Faces.
        faces: usize,
    },
    /// A reading that is NaN or infinite.
    #[error("shift {shift_deg}°, start face {start_face}, step {step}: the reading is not finite")]
    NotFinite {
        /// The shift.
        shift_deg: f64,
        /// The start face.
        start_face: usize,
        /// The step.
        step: usize,
    },
    /// The pitch deviations are not determined by the readings.
    #[error(
        "the polygon's pitch deviations are not determined: {reason}; measure more start faces at one shift (the paper's full {faces}×{faces} matrix at S = 0 is enough)"
    )]
    PolygonUndetermined {
        /// Why.
        reason: String,
        /// Faces.
        faces: usize,
    },
    /// `--method paper` without a full matrix.
    #[error(
        "the paper's method needs one shift with all {faces} start faces (Table 1's full matrix) to compute β by Table 2; none has them. Use the joint method (the default), which works with partial matrices"
    )]
    NoFullMatrix {
        /// Faces.
        faces: usize,
    },
    /// The normal equations could not be solved (numerically singular).
    #[error("the least-squares system is numerically singular: {0}")]
    Singular(String),
}

impl Readings {
    /// Validated readings of an `faces`-face polygon. Shifts are sorted by angle and rows by
    /// start face.
    pub fn new(faces: usize, mut shifts: Vec<Shift>) -> Result<Self, ShiftAngleError> {
        if faces < 3 {
            return Err(ShiftAngleError::TooFewFaces { faces });
        }
        if shifts.is_empty() {
            return Err(ShiftAngleError::NoReadings);
        }
        let pitch_deg = 360.0 / faces as f64;
        for shift in &mut shifts {
            let s = shift.shift_deg;
            if !s.is_finite() || s < 0.0 || s >= pitch_deg {
                return Err(ShiftAngleError::ShiftOutOfRange {
                    shift_deg: s,
                    pitch_deg,
                });
            }
            if shift.rows.is_empty() {
                return Err(ShiftAngleError::EmptyShift { shift_deg: s });
            }
            shift.rows.sort_by_key(|r| r.start_face);
            let mut seen = BTreeSet::new();
            for row in &shift.rows {
                if !(1..=faces).contains(&row.start_face) {
                    return Err(ShiftAngleError::BadStartFace {
                        shift_deg: s,
                        start_face: row.start_face,
                        faces,
                    });
                }
                if !seen.insert(row.start_face) {
                    return Err(ShiftAngleError::DuplicateStartFace {
                        shift_deg: s,
                        start_face: row.start_face,
                    });
                }
                if row.readings_arcsec.len() != faces {
                    return Err(ShiftAngleError::RowLength {
                        shift_deg: s,
                        start_face: row.start_face,
                        found: row.readings_arcsec.len(),
                        faces,
                    });
                }
                if let Some(i) = row.readings_arcsec.iter().position(|v| !v.is_finite()) {
                    return Err(ShiftAngleError::NotFinite {
                        shift_deg: s,
                        start_face: row.start_face,
                        step: i + 1,
                    });
                }
            }
        }
        shifts.sort_by(|a, b| a.shift_deg.total_cmp(&b.shift_deg));
        if let Some(w) = shifts.windows(2).find(|w| w[0].shift_deg == w[1].shift_deg) {
            return Err(ShiftAngleError::DuplicateShift {
                shift_deg: w[0].shift_deg,
            });
        }
        Ok(Readings { faces, shifts })
    }

    /// Number of polygon faces `n`.
    pub fn faces(&self) -> usize {
        self.faces
    }
    /// The shifts, by increasing angle.
    pub fn shifts(&self) -> &[Shift] {
        &self.shifts
    }
    /// Total number of readings.
    pub fn len(&self) -> usize {
        self.shifts.iter().map(|s| s.rows.len()).sum::<usize>() * self.faces
    }
    /// Always false: validated readings hold at least one row.
    pub fn is_empty(&self) -> bool {
        false
    }
}

/// Which estimator [`calibrate`] uses.
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Eq,
    Default,
    serde::Serialize,
    serde::Deserialize,
    schemars::JsonSchema,
)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// One constrained least-squares fit of all unknowns (see the module docs).
    #[default]
    Joint,
    /// The paper's two steps: Table 2 for β, eq. 7 for U, eq. 3 for α.
    Paper,
}

/// One point of the encoder's map.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct EncoderPoint {
    /// Encoder angle `(i−1)·360/n + S`, degrees.
    pub angle_deg: f64,
    /// The shift it was measured at, degrees.
    pub shift_deg: f64,
    /// The step `i`.
    pub step: usize,
    /// The encoder's error `α`, arcsec.
    pub error_arcsec: f64,
    /// Its standard uncertainty from the fit (joint method with redundant readings), arcsec.
    pub u_arcsec: Option<f64>,
}

/// One polygon face's pitch deviation.
#[derive(
    Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema,
)]
pub struct PolygonFace {
    /// The face `k`, 1-based.
    pub face: usize,
    /// `β_k`, arcsec.
    pub pitch_deviation_arcsec: f64,
    /// Its standard uncertainty from the fit, arcsec.
    pub u_arcsec: Option<f64>,
}

/// The setup error of one start face at one shift.
#[derive(
    Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema,
)]
pub struct SetupError {
    /// The shift, degrees.
    pub shift_deg: f64,
    /// The start face.
    pub start_face: usize,
    /// `U`, arcsec.
    pub value_arcsec: f64,
    /// Its standard uncertainty from the fit, arcsec.
    pub u_arcsec: Option<f64>,
}

/// The residuals `ε − model` of an estimate: a check of the measurement.
#[derive(
    Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema,
)]
pub struct Residuals {
    /// Root mean square over all readings, arcsec.
    pub rms_arcsec: f64,
    /// Degrees of freedom: readings less independent unknowns.
    pub dof: usize,
    /// `σ̂ = sqrt(Σr² / dof)`, the noise of one reading estimated from the data (None if dof = 0).
    pub sigma_arcsec: Option<f64>,
    /// The largest residual, arcsec, and where.
    pub max_abs_arcsec: f64,
    /// Shift of the largest residual, degrees.
    pub max_at_shift_deg: f64,
    /// Start face of the largest residual.
    pub max_at_start_face: usize,
    /// Step of the largest residual.
    pub max_at_step: usize,
}

/// The residual `ε − model` of one reading.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ReadingResidual {
    /// The shift, degrees.
    pub shift_deg: f64,
    /// The start face `j`.
    pub start_face: usize,
    /// The step `i` (1..n).
    pub step: usize,
    /// The encoder angle of the reading, `(i−1)·360°/n + S`, degrees.
    pub angle_deg: f64,
    /// `ε_ij − model`, arcsec.
    pub residual_arcsec: f64,
}

/// The sin-fit check of section 3.1 for one shift.
#[derive(
    Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema,
)]
pub struct SinFitShift {
    /// The shift, degrees.
    pub shift_deg: f64,
    /// The start face whose row was fitted (the lowest present).
    pub start_face: usize,
    /// `U_fit`, arcsec.
    pub u_fit_arcsec: f64,
    /// The estimate's `U` for that row, arcsec.
    pub u_estimate_arcsec: f64,
    /// `U_fit − U_estimate`, arcsec.
    pub difference_arcsec: f64,
    /// RMS of `α + U − (A sin(2θ + B) + U_fit)` over the row, arcsec.
    pub residual_rms_arcsec: f64,
}

/// The sin-fit diagnostic: `α(θ) + U = A·sin(2θ + B) + U_fit`, `A`, `B` fitted at the reference
/// (first) shift and held fixed for the others; `θ` in radians of encoder angle.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
pub struct SinFit {
    /// The shift where `A` and `B` were fitted, degrees.
    pub reference_shift_deg: f64,
    /// `A`, arcsec.
    pub amplitude_arcsec: f64,
    /// `B`, radians (the paper's unit: its `B = −2.4233`).
    pub phase_rad: f64,
    /// One entry per shift.
    pub shifts: Vec<SinFitShift>,
}

/// The result of [`calibrate`].
#[derive(Debug, Clone, PartialEq)]
pub struct ShiftAngleResult {
    /// The estimator used.
    pub method: Method,
    /// Polygon faces `n`.
    pub faces: usize,
    /// The encoder's error at every measured angle, sorted by angle.
    pub points: Vec<EncoderPoint>,
    /// The polygon's pitch deviations, faces `1..=n`.
    pub polygon: Vec<PolygonFace>,
    /// The setup error of every start face of every shift.
    pub setup_errors: Vec<SetupError>,
    /// The residuals of the estimate.
    pub residuals: Residuals,
    /// The residual of every reading, in the order of the readings.
    pub reading_residuals: Vec<ReadingResidual>,
    /// The sin-fit check.
    pub sin_fit: SinFit,
}

/// Calibrates the encoder (and the polygon) from the readings by `method`.
pub fn calibrate(readings: &Readings, method: Method) -> Result<ShiftAngleResult, ShiftAngleError> {
    check_polygon_determined(readings)?;
    let est = match method {
        Method::Joint => joint(readings)?,
        Method::Paper => paper(readings)?,
    };
    let n = readings.faces;
    let pitch = 360.0 / n as f64;
    let residuals = residuals(readings, &est);
    let mut reading_residuals = Vec::with_capacity(readings.len());
    for_each_residual(readings, &est, |s, r, i, res| {
        let shift = &readings.shifts[s];
        reading_residuals.push(ReadingResidual {
            shift_deg: shift.shift_deg,
            start_face: shift.rows[r].start_face,
            step: i + 1,
            angle_deg: i as f64 * pitch + shift.shift_deg,
            residual_arcsec: res,
        });
    });
    let mut points = Vec::with_capacity(readings.shifts.len() * n);
    for (s, shift) in readings.shifts.iter().enumerate() {
        for i in 0..n {
            points.push(EncoderPoint {
                angle_deg: i as f64 * pitch + shift.shift_deg,
                shift_deg: shift.shift_deg,
                step: i + 1,
                error_arcsec: est.alpha[s][i],
                u_arcsec: est.u_alpha.as_ref().map(|u| u[s][i]),
            });
        }
    }
    points.sort_by(|a, b| a.angle_deg.total_cmp(&b.angle_deg));
    let polygon = (0..n)
        .map(|k| PolygonFace {
            face: k + 1,
            pitch_deviation_arcsec: est.beta[k],
            u_arcsec: est.u_beta.as_ref().map(|u| u[k]),
        })
        .collect();
    let mut setup_errors = Vec::new();
    for (s, shift) in readings.shifts.iter().enumerate() {
        for (r, row) in shift.rows.iter().enumerate() {
            setup_errors.push(SetupError {
                shift_deg: shift.shift_deg,
                start_face: row.start_face,
                value_arcsec: est.setup[s][r],
                u_arcsec: est.u_setup.as_ref().map(|u| u[s][r]),
            });
        }
    }
    let sin_fit = sin_fit(readings, &est);
    Ok(ShiftAngleResult {
        method,
        faces: n,
        points,
        polygon,
        setup_errors,
        residuals,
        reading_residuals,
        sin_fit,
    })
}

/// Estimates in index form: `alpha[shift][step−1]`, `beta[face−1]`, `setup[shift][row]`.
struct Estimate {
    alpha: Vec<Vec<f64>>,
    beta: Vec<f64>,
    setup: Vec<Vec<f64>>,
    u_alpha: Option<Vec<Vec<f64>>>,
    u_beta: Option<Vec<f64>>,
    u_setup: Option<Vec<Vec<f64>>>,
    /// Readings less independent unknowns.
    dof: usize,
}

/// `Σ_{k=j}^{j+i−1 (mod n)} β_k` for 0-based `face0 = j − 1`, `step0 = i − 1`.
fn beta_sum(beta: &[f64], face0: usize, step0: usize) -> f64 {
    let n = beta.len();
    (0..=step0).map(|m| beta[(face0 + m) % n]).sum()
}

fn gcd(a: usize, b: usize) -> usize {
    if b == 0 { a } else { gcd(b, a % b) }
}

/// β is determined (modulo eq. 1) iff the start-face differences within shifts generate the
/// integers mod n: two faces `d` apart give every `β_{m+d} − β_m`, which connect all faces iff
/// `gcd(n, d, …) = 1`. With that, every `α` (each shift has a full row) and `U` follow.
fn check_polygon_determined(readings: &Readings) -> Result<(), ShiftAngleError> {
    let n = readings.faces;
    let mut g = n;
    let mut any_pair = false;
    for shift in &readings.shifts {
        let first = shift.rows[0].start_face;
        for row in &shift.rows[1..] {
            any_pair = true;
            g = gcd(g, row.start_face - first);
        }
    }
    if !any_pair {
        return Err(ShiftAngleError::PolygonUndetermined {
            reason: "no shift has readings from more than one start face".into(),
            faces: n,
        });
    }
    if g != 1 {
        return Err(ShiftAngleError::PolygonUndetermined {
            reason: format!(
                "the start faces within each shift differ only by multiples of {g}, which leaves a pattern of period {g} faces free"
            ),
            faces: n,
        });
    }
    Ok(())
}

/// The paper's two-step estimate.
fn paper(readings: &Readings) -> Result<Estimate, ShiftAngleError> {
    let n = readings.faces;
    let full: Vec<&Shift> = readings
        .shifts
        .iter()
        .filter(|s| s.rows.len() == n)
        .collect();
    if full.is_empty() {
        return Err(ShiftAngleError::NoFullMatrix { faces: n });
    }
    // Table 2: β_k = mean_m (ε_{m+1, j} − ε_{m, j}), j = k − m (mod n), ε_{n+1,j} ≡ ε_{1,j}.
    let mut beta = vec![0.0; n];
    for shift in &full {
        // rows sorted by start face and complete: row index = face − 1.
        let eps = |step0: usize, face0: usize| shift.rows[face0].readings_arcsec[step0 % n];
        for (k, b) in beta.iter_mut().enumerate() {
            let mut sum = 0.0;
            for m in 0..n {
                // Step i = m+1 (0-based m) to i = m+2 (0-based m+1) adds face j + m + 1 … in
                // 0-based terms face0 + m + 1 ≡ k.
                let face0 = (k + 2 * n - m - 1) % n;
                sum += eps(m + 1, face0) - eps(m, face0);
            }
            *b += sum / n as f64 / full.len() as f64;
        }
    }
    let mut alpha = Vec::new();
    let mut setup = Vec::new();
    for shift in &readings.shifts {
        let mut a = vec![0.0; n];
        let mut u_row = Vec::new();
        for row in &shift.rows {
            let face0 = row.start_face - 1;
            let reduced: Vec<f64> = (0..n)
                .map(|i| row.readings_arcsec[i] - beta_sum(&beta, face0, i))
                .collect();
            // Eq. 7 with eq. 2: U_j = mean_i (ε_ij − Σβ).
            let u = reduced.iter().sum::<f64>() / n as f64;
            u_row.push(u);
            for (ai, r) in a.iter_mut().zip(&reduced) {
                *ai += (r - u) / shift.rows.len() as f64;
            }
        }
        alpha.push(a);
        setup.push(u_row);
    }
    Ok(Estimate {
        alpha,
        beta,
        setup,
        u_alpha: None,
        u_beta: None,
        u_setup: None,
        dof: dof(readings),
    })
}

/// Readings less independent unknowns (`n` α per shift, `n` β, one U per row, less the
/// `1 + shifts` gauge constraints).
fn dof(readings: &Readings) -> usize {
    let n = readings.faces;
    let rows: usize = readings.shifts.iter().map(|s| s.rows.len()).sum();
    let unknowns = readings.shifts.len() * n + n + rows;
    let independent = unknowns - 1 - readings.shifts.len();
    readings.len().saturating_sub(independent)
}

/// The joint constrained least-squares estimate.
///
/// Unknowns `x = [α (shift-major), β, U (row order)]`. The gauge constraints `Cx = 0` (eqs. 1, 2)
/// are added to the normal equations as `(AᵀA + CᵀC) x = Aᵀε`: because they fix only directions
/// that `A` does not see, the solution meets them exactly and is the constrained least-squares
/// solution. Its covariance is `σ̂² M⁻¹AᵀA M⁻¹ = σ̂² (M⁻¹ − (M⁻¹Cᵀ)(M⁻¹Cᵀ)ᵀ)` with
/// `M = AᵀA + CᵀC`.
fn joint(readings: &Readings) -> Result<Estimate, ShiftAngleError> {
    let n = readings.faces;
    let shifts = readings.shifts.len();
    let (m, rhs, c) = joint_system(readings);
    let chol = m.cholesky().ok_or_else(|| {
        ShiftAngleError::Singular(
            "the readings do not determine every α, β and U; check for repeated identical rows"
                .into(),
        )
    })?;
    let x = chol.solve(&rhs);
    let est_dof = dof(readings);
    let mut est = unpack(readings, &x, est_dof);
    let sigma = residual_sigma(readings, &est);
    if let Some(sigma) = sigma {
        let v = unit_variances(&chol, &c);
        let var = |k: usize| sigma * v[k].max(0.0).sqrt();
        let (b0, u0) = (shifts * n, shifts * n + n);
        est.u_alpha = Some(
            (0..shifts)
                .map(|s| (0..n).map(|i| var(s * n + i)).collect())
                .collect(),
        );
        est.u_beta = Some((0..n).map(|k| var(b0 + k)).collect());
        let mut idx = u0;
        est.u_setup = Some(
            readings
                .shifts
                .iter()
                .map(|s| {
                    s.rows
                        .iter()
                        .map(|_| {
                            idx += 1;
                            var(idx - 1)
                        })
                        .collect()
                })
                .collect(),
        );
    }
    Ok(est)
}

/// The joint fit's system: `M = AᵀA + CᵀC`, `Aᵀε` and the constraint rows `C` (eqs. 1, 2), for
/// the unknowns `x = [α (shift-major), β, U (row order)]`.
fn joint_system(readings: &Readings) -> (DMatrix<f64>, DVector<f64>, DMatrix<f64>) {
    let n = readings.faces;
    let shifts = readings.shifts.len();
    let rows: usize = readings.shifts.iter().map(|s| s.rows.len()).sum();
    let (a0, b0, u0) = (0, shifts * n, shifts * n + n);
    let p = u0 + rows;
    let mut m = DMatrix::<f64>::zeros(p, p);
    let mut rhs = DVector::<f64>::zeros(p);
    let mut cols = Vec::with_capacity(n + 2);
    let mut row_index = 0;
    for (s, shift) in readings.shifts.iter().enumerate() {
        for row in &shift.rows {
            let face0 = row.start_face - 1;
            for (i, &eps) in row.readings_arcsec.iter().enumerate() {
                cols.clear();
                cols.push(a0 + s * n + i);
                cols.extend((0..=i).map(|k| b0 + (face0 + k) % n));
                cols.push(u0 + row_index);
                for &c in &cols {
                    rhs[c] += eps;
                    for &d in &cols {
                        m[(c, d)] += 1.0;
                    }
                }
            }
            row_index += 1;
        }
    }
    // Constraint rows: Σβ = 0, and Σ_i α_{s,i} = 0 per shift.
    let mut c = DMatrix::<f64>::zeros(1 + shifts, p);
    for k in 0..n {
        c[(0, b0 + k)] = 1.0;
    }
    for s in 0..shifts {
        for i in 0..n {
            c[(1 + s, a0 + s * n + i)] = 1.0;
        }
    }
    m += c.transpose() * &c;
    (m, rhs, c)
}

/// The diagonal of `M⁻¹ − (M⁻¹Cᵀ)(M⁻¹Cᵀ)ᵀ`: every unknown's variance for readings of unit noise.
fn unit_variances(chol: &nalgebra::Cholesky<f64, nalgebra::Dyn>, c: &DMatrix<f64>) -> Vec<f64> {
    let minv = chol.inverse();
    let mc = &minv * c.transpose();
    (0..minv.nrows())
        .map(|k| minv[(k, k)] - mc.row(k).iter().map(|v| v * v).sum::<f64>())
        .collect()
}

/// The standard uncertainty the joint method gives each encoder point (`u[shift][step − 1]`,
/// arcsec) for readings laid out as `readings` (their values do not matter) with independent
/// noise `sigma_arcsec` each: `σ·√[M⁻¹ − (M⁻¹Cᵀ)(M⁻¹Cᵀ)ᵀ]_kk`, the covariance [`calibrate`]
/// reports with `σ̂` from the residuals. For planning a measurement before it is made.
pub fn joint_point_uncertainty(
    readings: &Readings,
    sigma_arcsec: f64,
) -> Result<Vec<Vec<f64>>, ShiftAngleError> {
    check_polygon_determined(readings)?;
    let n = readings.faces;
    let (m, _, c) = joint_system(readings);
    let chol = m.cholesky().ok_or_else(|| {
        ShiftAngleError::Singular("the layout does not determine every α, β and U".into())
    })?;
    let v = unit_variances(&chol, &c);
    Ok((0..readings.shifts.len())
        .map(|s| {
            (0..n)
                .map(|i| sigma_arcsec * v[s * n + i].max(0.0).sqrt())
                .collect()
        })
        .collect())
}

fn unpack(readings: &Readings, x: &DVector<f64>, dof: usize) -> Estimate {
    let n = readings.faces;
    let shifts = readings.shifts.len();
    let alpha = (0..shifts)
        .map(|s| (0..n).map(|i| x[s * n + i]).collect())
        .collect();
    let beta = (0..n).map(|k| x[shifts * n + k]).collect();
    let mut idx = shifts * n + n;
    let setup = readings
        .shifts
        .iter()
        .map(|s| {
            s.rows
                .iter()
                .map(|_| {
                    idx += 1;
                    x[idx - 1]
                })
                .collect()
        })
        .collect();
    Estimate {
        alpha,
        beta,
        setup,
        u_alpha: None,
        u_beta: None,
        u_setup: None,
        dof,
    }
}

/// Calls `f(shift index, row index, step0, residual)` for every reading.
fn for_each_residual(
    readings: &Readings,
    est: &Estimate,
    mut f: impl FnMut(usize, usize, usize, f64),
) {
    for (s, shift) in readings.shifts.iter().enumerate() {
        for (r, row) in shift.rows.iter().enumerate() {
            let face0 = row.start_face - 1;
            for (i, &eps) in row.readings_arcsec.iter().enumerate() {
                let model = est.alpha[s][i] + beta_sum(&est.beta, face0, i) + est.setup[s][r];
                f(s, r, i, eps - model);
            }
        }
    }
}

fn residual_sigma(readings: &Readings, est: &Estimate) -> Option<f64> {
    let mut ss = 0.0;
    for_each_residual(readings, est, |_, _, _, r| ss += r * r);
    (est.dof > 0).then(|| (ss / est.dof as f64).sqrt())
}

fn residuals(readings: &Readings, est: &Estimate) -> Residuals {
    let mut ss = 0.0;
    let mut worst = (0.0f64, 0, 0, 0);
    for_each_residual(readings, est, |s, r, i, res| {
        ss += res * res;
        if res.abs() > worst.0.abs() {
            worst = (res, s, r, i);
        }
    });
    let (w, s, r, i) = worst;
    let shift = &readings.shifts[s];
    Residuals {
        rms_arcsec: (ss / readings.len() as f64).sqrt(),
        dof: est.dof,
        sigma_arcsec: (est.dof > 0).then(|| (ss / est.dof as f64).sqrt()),
        max_abs_arcsec: w.abs(),
        max_at_shift_deg: shift.shift_deg,
        max_at_start_face: shift.rows[r].start_face,
        max_at_step: i + 1,
    }
}

/// Section 3.1's check, on the lowest start face of each shift: `y_i = α_i + U = ε_ij − Σβ`.
fn sin_fit(readings: &Readings, est: &Estimate) -> SinFit {
    let n = readings.faces;
    let pitch = std::f64::consts::TAU / n as f64;
    let row_of = |s: usize| {
        let shift = &readings.shifts[s];
        let theta: Vec<f64> = (0..n)
            .map(|i| i as f64 * pitch + shift.shift_deg.to_radians())
            .collect();
        let y: Vec<f64> = (0..n).map(|i| est.alpha[s][i] + est.setup[s][0]).collect();
        (theta, y)
    };
    // Reference: y = a·sin 2θ + b·cos 2θ + U by least squares; A sin(2θ + B) = A cos B sin 2θ
    // + A sin B cos 2θ.
    let (theta, y) = row_of(0);
    let design = DMatrix::from_fn(n, 3, |i, j| match j {
        0 => (2.0 * theta[i]).sin(),
        1 => (2.0 * theta[i]).cos(),
        _ => 1.0,
    });
    let coef = design
        .clone()
        .svd(true, true)
        .solve(&DVector::from_vec(y), 1e-12)
        .unwrap_or_else(|_| DVector::zeros(3));
    let (amplitude, phase) = (coef[0].hypot(coef[1]), coef[1].atan2(coef[0]));
    let shifts = (0..readings.shifts.len())
        .map(|s| {
            let (theta, y) = row_of(s);
            let model: Vec<f64> = theta
                .iter()
                .map(|t| amplitude * (2.0 * t + phase).sin())
                .collect();
            let u_fit = y.iter().zip(&model).map(|(y, m)| y - m).sum::<f64>() / n as f64;
            let ss: f64 = y
                .iter()
                .zip(&model)
                .map(|(y, m)| (y - m - u_fit).powi(2))
                .sum();
            let u_est = est.setup[s][0];
            SinFitShift {
                shift_deg: readings.shifts[s].shift_deg,
                start_face: readings.shifts[s].rows[0].start_face,
                u_fit_arcsec: u_fit,
                u_estimate_arcsec: u_est,
                difference_arcsec: u_fit - u_est,
                residual_rms_arcsec: (ss / n as f64).sqrt(),
            }
        })
        .collect();
    SinFit {
        reference_shift_deg: readings.shifts[0].shift_deg,
        amplitude_arcsec: amplitude,
        phase_rad: phase,
        shifts,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Noise-free readings of a tiny polygon; both methods must return the truth exactly.
    fn exact(faces: usize, start_faces_later: &[usize]) -> (Readings, Vec<Vec<f64>>, Vec<f64>) {
        let n = faces;
        let beta: Vec<f64> = (0..n).map(|k| ((k * 7 % 5) as f64 - 2.0) * 0.3).collect();
        let mean = beta.iter().sum::<f64>() / n as f64;
        let beta: Vec<f64> = beta.iter().map(|b| b - mean).collect();
        let truth = |deg: f64| {
            let t = deg.to_radians();
            1.2 * (2.0 * t + 0.4).sin() + 0.5 * t.cos()
        };
        let shifts_deg = [0.0, 360.0 / n as f64 / 3.0, 2.0 * 360.0 / n as f64 / 3.0];
        let mut shifts = Vec::new();
        let mut alphas = Vec::new();
        for (s, &sd) in shifts_deg.iter().enumerate() {
            let alpha: Vec<f64> = (0..n)
                .map(|i| truth(i as f64 * 360.0 / n as f64 + sd))
                .collect();
            let m = alpha.iter().sum::<f64>() / n as f64;
            alphas.push(alpha.iter().map(|a| a - m).collect());
            let faces_here: Vec<usize> = if s == 0 {
                (1..=n).collect()
            } else {
                start_faces_later.to_vec()
            };
            let rows = faces_here
                .iter()
                .map(|&j| StartFaceRow {
                    start_face: j,
                    readings_arcsec: (0..n)
                        .map(|i| alpha[i] + beta_sum(&beta, j - 1, i) + 0.1 * j as f64 + s as f64)
                        .collect(),
                })
                .collect();
            shifts.push(Shift {
                shift_deg: sd,
                rows,
            });
        }
        (Readings::new(n, shifts).unwrap(), alphas, beta)
    }

    #[test]
    fn both_methods_are_exact_on_noise_free_readings() {
        for method in [Method::Joint, Method::Paper] {
            let (readings, alphas, beta) = exact(6, &[1]);
            let r = calibrate(&readings, method).unwrap();
            for (k, b) in beta.iter().enumerate() {
                assert!(
                    (r.polygon[k].pitch_deviation_arcsec - b).abs() < 1e-9,
                    "{method:?}"
                );
            }
            for p in &r.points {
                let s = readings
                    .shifts()
                    .iter()
                    .position(|s| s.shift_deg == p.shift_deg)
                    .unwrap();
                assert!((p.error_arcsec - alphas[s][p.step - 1]).abs() < 1e-9);
            }
            assert!(r.residuals.rms_arcsec < 1e-9);
            // Complete rows: the sin-fit's U equals eq. 7's (see the module docs).
            for s in &r.sin_fit.shifts {
                assert!(s.difference_arcsec.abs() < 1e-9);
            }
        }
    }

    #[test]
    fn two_coprime_start_faces_determine_the_polygon() {
        // No full matrix, but faces 1 and 2 at shift 0: the joint method works, the paper's not.
        let (full, alphas, beta) = exact(5, &[1]);
        let mut shifts = full.shifts().to_vec();
        shifts[0].rows.retain(|r| r.start_face <= 2);
        let readings = Readings::new(5, shifts).unwrap();
        let r = calibrate(&readings, Method::Joint).unwrap();
        for (k, b) in beta.iter().enumerate() {
            assert!((r.polygon[k].pitch_deviation_arcsec - b).abs() < 1e-9);
        }
        assert!((r.points[1].error_arcsec - alphas[1][0]).abs() < 1e-9);
        assert_eq!(
            calibrate(&readings, Method::Paper),
            Err(ShiftAngleError::NoFullMatrix { faces: 5 })
        );
    }

    #[test]
    fn undetermined_polygons_are_reported() {
        let (full, _, _) = exact(6, &[1]);
        let mut shifts = full.shifts().to_vec();
        shifts[0]
            .rows
            .retain(|r| r.start_face == 1 || r.start_face == 3);
        let err = calibrate(&Readings::new(6, shifts.clone()).unwrap(), Method::Joint);
        assert!(matches!(
            err,
            Err(ShiftAngleError::PolygonUndetermined { .. })
        ));
        shifts[0].rows.truncate(1);
        let err = calibrate(&Readings::new(6, shifts).unwrap(), Method::Joint).unwrap_err();
        assert!(
            err.to_string()
                .contains("no shift has readings from more than one")
        );
    }

    #[test]
    fn validation_names_the_problem() {
        let row = |j, len| StartFaceRow {
            start_face: j,
            readings_arcsec: vec![0.0; len],
        };
        let shift = |s, rows| Shift { shift_deg: s, rows };
        assert!(matches!(
            Readings::new(4, vec![shift(0.0, vec![row(1, 3)])]),
            Err(ShiftAngleError::RowLength { found: 3, .. })
        ));
        assert!(matches!(
            Readings::new(4, vec![shift(90.0, vec![row(1, 4)])]),
            Err(ShiftAngleError::ShiftOutOfRange { .. })
        ));
        assert!(matches!(
            Readings::new(4, vec![shift(0.0, vec![row(1, 4), row(1, 4)])]),
            Err(ShiftAngleError::DuplicateStartFace { .. })
        ));
        assert!(matches!(
            Readings::new(4, vec![shift(0.0, vec![row(5, 4)])]),
            Err(ShiftAngleError::BadStartFace { .. })
        ));
        assert!(matches!(
            Readings::new(
                4,
                vec![shift(0.0, vec![row(1, 4)]), shift(0.0, vec![row(2, 4)])]
            ),
            Err(ShiftAngleError::DuplicateShift { .. })
        ));
        assert!(matches!(
            Readings::new(4, vec![shift(0.0, vec![])]),
            Err(ShiftAngleError::EmptyShift { .. })
        ));
    }
}
