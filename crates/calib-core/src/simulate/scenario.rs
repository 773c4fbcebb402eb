//! The scenario file's types (deserialized by the CLI from TOML) and their validation.
//!
//! Every table rejects unknown keys, so a typo (`noise_arcsecs`) is an error rather than a
//! silently ignored setting. The field docs below are the file format's reference; the module
//! documentation of [`crate::simulate`] has a complete annotated example.

use serde::{Deserialize, Serialize};
use std::collections::HashSet;

/// A simulated recorded run: the rig, its sensors, and the procedure it follows.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Scenario {
    /// Seed of the pseudo-random noise and time jitter (default 0). The same scenario and seed
    /// give the same samples (bit-identical on one platform).
    pub seed: u64,
    /// Sample rate, Hz (default 400, the paper's Table I). Samples are at `t = n / rate_hz`.
    pub rate_hz: f64,
    /// Nominal speed of the driven shaft while it turns, revolutions per minute (default 10).
    pub speed_rpm: f64,
    /// `true` (default): readings wrapped to `[0, 360°)`; `false`: readings accumulate over
    /// revolutions.
    pub wrap: bool,
    /// Standard deviation of the sampling instant, seconds (default 0): sample `n` is stamped
    /// `n / rate_hz` but taken at `n / rate_hz + δ_n`, `δ_n` Gaussian, the same instant for all
    /// channels (they are synchronized, as the paper's DAQ is).
    pub time_jitter_s: f64,
    /// Mark each sample of session `k`'s constant-speed revolutions with `session = k`
    /// (default `false`: no marks, as most real logs have none).
    pub mark_sessions: bool,
    /// The driven shaft's speed non-uniformity.
    pub speed: Speed,
    /// Shared scales (graduated discs) read by several heads: `[[scale]]` tables.
    #[serde(rename = "scale", skip_serializing_if = "Vec::is_empty")]
    pub scales: Vec<Scale>,
    /// The channels of the log, in this order: `[[sensor]]` tables.
    #[serde(rename = "sensor")]
    pub sensors: Vec<Sensor>,
    /// The CSRR procedure: sessions, ramps, pauses and relative turns.
    pub procedure: Procedure,
    /// A free coast-down instead of the CSRR procedure (`[spin_down]`, for `calib tdr`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub spin_down: Option<SpinDown>,
    /// A joint swept back and forth over part of a revolution instead of the CSRR procedure
    /// (`[sweep]`, for `calib reference` over a range).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sweep: Option<Sweep>,
}

impl Default for Scenario {
    fn default() -> Self {
        Scenario {
            seed: 0,
            rate_hz: 400.0,
            speed_rpm: 10.0,
            wrap: true,
            time_jitter_s: 0.0,
            mark_sessions: false,
            speed: Speed::default(),
            scales: Vec::new(),
            sensors: Vec::new(),
            procedure: Procedure::default(),
            spin_down: None,
            sweep: None,
        }
    }
}

/// One harmonic `amplitude_arcsec · cos(order·θ + phase_deg)` — the interface's convention.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HarmonicSpec {
    /// Cycles per revolution, ≥ 1.
    pub order: u32,
    /// Amplitude, arcseconds.
    pub amplitude_arcsec: f64,
    /// Phase, degrees (default 0). The paper's `m·sin(x + φ)` is phase `φ − 90°` here.
    #[serde(default)]
    pub phase_deg: f64,
}

/// Which rotor a sensor (or scale) turns with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Mount {
    /// Rotor A, locked to the shaft at the session's relative rotation: `θ_A = θ_B + Δ_k`.
    A,
    /// Rotor B, the driven shaft (also where a reference encoder or a multi-head scale sits).
    #[default]
    B,
}

/// The driven shaft's sampling non-uniformity, the paper's eq. (9):
/// `θ(φ) = φ + Σ m_Ω cos(Ω·φ + ψ_Ω)`, `φ` the nominal (uniform-speed) shaft angle.
///
/// The modulation is locked to the shaft's position (it repeats every revolution, as bearing and
/// motor-pole effects do), which makes the speed ripple `1 + Σ Ω·m_Ω·(−sin …)` relative to the
/// nominal speed — including during ramps.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Speed {
    /// Shorthand for a once-per-revolution speed ripple of ± this many percent: adds an order-1
    /// position modulation of amplitude `variation_percent / 100` rad (= 2062.6″ per percent),
    /// phase 0 (default 0: none).
    pub variation_percent: f64,
    /// Position modulation harmonics `m_Ω`, `[[speed.harmonic]]` tables (the paper's Table III
    /// lists an open-loop rig's).
    #[serde(rename = "harmonic", skip_serializing_if = "Vec::is_empty")]
    pub harmonics: Vec<HarmonicSpec>,
}

/// A graduated scale shared by several heads (multi-head self-calibration).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scale {
    /// Name that `[[sensor]] scale = "..."` refers to.
    pub name: String,
    /// The scale's graduation error `e_s(s)` as a function of the true scale position `s`.
    #[serde(default)]
    pub harmonics: Vec<HarmonicSpec>,
    /// The rotor the scale turns with (default `"b"`).
    #[serde(default)]
    pub mount: Mount,
}

/// One channel of the simulated log: either a sensor with its own error model (`harmonics`,
/// `mount`), or a head reading a shared `scale` at `head_deg`.
///
/// A head at nominal angle `α` with angle error `δ` sees the scale at `s = θ + α + δ` and reports
/// `s + e_s(s) − α`; its error is therefore `δ + e_s(θ + α + δ)`. A multi-head method sees the
/// actual head angles `α + δ` in the readings' differences and can estimate `δ`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sensor {
    /// Channel name (CSV header, JointState name). Unique.
    pub name: String,
    /// Rotor the sensor turns with (default `"b"`). Not allowed with `scale` (the scale has one).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mount: Option<Mount>,
    /// The sensor's own error `e(θ)`, a function of the true angle `θ` it measures. Not allowed
    /// with `scale`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub harmonics: Vec<HarmonicSpec>,
    /// Name of the `[[scale]]` this head reads.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scale: Option<String>,
    /// Nominal angle of the head around the scale, degrees (default 0; only with `scale`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub head_deg: Option<f64>,
    /// Actual minus nominal head angle, arcseconds (default 0; only with `scale`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub head_error_arcsec: Option<f64>,
    /// Resolution: readings are rounded to multiples of this step, arcseconds (default 0: none).
    /// The paper's time-grating sensors resolve 0.09″.
    #[serde(default)]
    pub quantization_arcsec: f64,
    /// Standard deviation of Gaussian reading noise, arcseconds (default 0), independent per
    /// sample and channel, added before quantization.
    #[serde(default)]
    pub noise_arcsec: f64,
    /// Latency of the channel, seconds (default 0): the sample stamped `t` is the reading at
    /// `t − delay_s` (an interface that samples earlier than the log's clock says).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub delay_s: f64,
    /// Play of the coupling between the shaft and this sensor, arcseconds (default 0): the
    /// sensor's side stays put until the shaft has taken up the play, then is dragged along
    /// `backlash_arcsec / 2` behind it (a reversal of ISO 230-2's `B = backlash_arcsec`).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub backlash_arcsec: f64,
    /// The channel reads the drive's commanded (nominal) angle `φ`, not the rotor's true angle
    /// (default `false`): an open-loop reference, which the rotor follows with the `[speed]`
    /// modulation as its ripple (`[[speed.harmonic]]` at orders `k·p` for a motor of `p` pole
    /// pairs). Not allowed with `scale`.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub commanded: bool,
    /// Turns of this sensor per turn of its rotor (default 1): a sensor behind a gear, as an
    /// actuator's motor encoder is behind the gear whose output the rotor is (`ratio = 50.0`;
    /// negative where it turns the other way). Its error `harmonics` are a function of its own
    /// angle `ratio·θ`, and it reads `ratio·θ + e(ratio·θ)`. Not allowed with `scale`.
    #[serde(default = "unit_ratio", skip_serializing_if = "is_unit_ratio")]
    pub ratio: f64,
}

fn unit_ratio() -> f64 {
    1.0
}

fn is_unit_ratio(v: &f64) -> bool {
    *v == 1.0
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

/// The CSRR procedure (paper section III-B): sessions at constant speed, rotor A locked to the
/// shaft at a relative rotation `Δ_k`, turned relative to the stationary shaft between sessions.
///
/// Give the sessions either as `relative_deg = [...]` with a common `revolutions`, or as
/// `[[procedure.sessions]]` tables (each may override `revolutions`) — not both.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Procedure {
    /// Relative rotation `Δ_k = θ_A − θ_B` of each session, degrees (the CSRR equation
    /// `e_a(x) − e_b(y) + Δ_k = wrap(x − y)` with readings x of a, y of b).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub relative_deg: Vec<f64>,
    /// Constant-speed revolutions per session (default 3), counted on the nominal angle; the
    /// shaft's true angle covers the same whole revolutions, since ε_θ is periodic.
    pub revolutions: f64,
    /// Sessions given one by one, instead of `relative_deg`.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub sessions: Vec<SessionSpec>,
    /// Duration of the raised-cosine speed ramp at the start and at the end of each session,
    /// seconds (default 1). A ramp covers `ω·ramp_s/2` of shaft angle.
    pub ramp_s: f64,
    /// Stationary pause before the first session, after each session, and after each relative
    /// turn, seconds (default 1).
    pub pause_s: f64,
    /// Duration of each relative turn of rotor A (shaft stationary), seconds (default 2).
    pub turn_s: f64,
}

impl Default for Procedure {
    fn default() -> Self {
        Procedure {
            relative_deg: Vec::new(),
            revolutions: 3.0,
            sessions: Vec::new(),
            ramp_s: 1.0,
            pause_s: 1.0,
            turn_s: 2.0,
        }
    }
}

/// A free coast-down (spin-down) of the shaft: at `t = 0` it turns at `speed_rpm`, the drive
/// just released, and decelerates by its friction alone,
///
/// `dω/dt = −(c₀ + c₁·ω + c₂·ω²) − Σ a_h·cos(h·θ + φ_h)`  (ω > 0),
///
/// `c₀, c₁, c₂` the [`Friction`] terms and `a_h` the angle-dependent [`drag_harmonics`]
/// (rolling-element bearings, motor cogging). Once ω reaches 0 the shaft stays at rest (static
/// friction holds it). Rotor A, if used, turns with the shaft (`Δ = 0`). The `[procedure]` and
/// `[speed]` tables must be absent.
///
/// [`drag_harmonics`]: SpinDown::drag_harmonics
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpinDown {
    /// Speed at `t = 0`, revolutions per minute (> 0).
    pub speed_rpm: f64,
    /// Length of the recorded coast, seconds (> 0).
    pub duration_s: f64,
    /// The smooth, speed-dependent friction.
    #[serde(default)]
    pub friction: Friction,
    /// Angle-dependent drag: terms `a_h·cos(h·θ + φ_h)` of angular deceleration (default none).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub drag_harmonics: Vec<DragHarmonic>,
    /// A motor driving the shaft at constant voltage (default none: the shaft coasts).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drive: Option<Drive>,
}

/// A DC (or field-oriented) motor at constant voltage: its torque falls linearly with speed
/// (back-EMF), so it adds `(ω_v − ω)/τ` to the shaft's acceleration, `ω_v` the no-load speed of
/// the voltage applied and `τ` the mechanical time constant. The shaft then settles
/// exponentially to the speed where the drive balances the friction, and its inertia keeps it
/// smooth; cogging and torque ripple are [`SpinDown::drag_harmonics`] at the motor's orders
/// (`k·6·pole pairs`). For example, a run at ~300 r/min then one at ~600 r/min:
/// ```toml
/// drive = { time_constant_s = 1.5, steps = [
///   { from_s = 0.0, speed_rpm = 305.0 }, { from_s = 20.0, speed_rpm = 610.0 },
/// ] }
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Drive {
    /// `τ`, seconds (> 0).
    pub time_constant_s: f64,
    /// The voltage steps in time order; before the first the shaft coasts.
    pub steps: Vec<DriveStep>,
}

/// From `from_s` on (until the next step) the motor's voltage gives a no-load speed of
/// `speed_rpm`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DriveStep {
    /// When the voltage is applied, seconds (≥ 0, increasing from step to step).
    pub from_s: f64,
    /// No-load speed of that voltage, revolutions per minute (≥ 0).
    pub speed_rpm: f64,
}

/// A joint swept back and forth over part of a revolution: at rest at `from_deg` for `pause_s`,
/// then `cycles` times `from_deg → to_deg → from_deg`, each stroke with raised-cosine ramps of
/// `ramp_s` at both ends and followed by a pause of `pause_s`. Stroke `k` (from 0) runs at
/// `speeds_deg_s[k mod len]`, so a list of speeds gives a run at varying speed. Rotor A, if
/// used, turns with the shaft (`Δ = 0`); `[speed]` modulates the position as for the CSRR
/// procedure. The `[procedure]` table must be absent. For example:
/// ```toml
/// [sweep]
/// from_deg = 15.0
/// to_deg = 135.0
/// cycles = 4
/// speeds_deg_s = [10.0, 25.0, 15.0, 40.0]
/// ramp_s = 0.5
/// pause_s = 1.0
/// ```
/// The truth tables of a swept run are range tables over each channel's swept readings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sweep {
    /// Start and end of each there-and-back cycle, degrees of the shaft's nominal angle.
    pub from_deg: f64,
    /// The other end of the stroke, degrees (≠ `from_deg`; may be more than a revolution away).
    pub to_deg: f64,
    /// There-and-back cycles (≥ 1, default 1).
    #[serde(default = "one")]
    pub cycles: u32,
    /// Cruise speed of each stroke in turn, degrees per second (> 0; default: `speed_rpm`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub speeds_deg_s: Vec<f64>,
    /// Duration of the speed ramp at each end of a stroke, seconds (default 0.5).
    #[serde(default = "half")]
    pub ramp_s: f64,
    /// Rest before the first stroke and after each, seconds (default 1).
    #[serde(default = "one_s")]
    pub pause_s: f64,
    /// A joint moved by hand (default `false`): each stroke reverses at a point drawn in the far
    /// half of the range, at a speed drawn between the smallest and largest of `speeds_deg_s`,
    /// and rests for a time drawn up to `pause_s` (seeded by `seed`).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub random: bool,
}

fn one() -> u32 {
    1
}
fn half() -> f64 {
    0.5
}
fn one_s() -> f64 {
    1.0
}

/// The smooth part of the deceleration `c₀ + c₁·ω + c₂·ω²` (all ≥ 0; default 0).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Friction {
    /// `c₀`, Coulomb (dry) friction, rad/s².
    pub coulomb: f64,
    /// `c₁`, viscous friction (air or oil shear), 1/s.
    pub viscous: f64,
    /// `c₂`, aerodynamic drag, 1/rad.
    pub quadratic: f64,
}

/// One term `amplitude·cos(order·θ + phase_deg)` of angle-dependent angular deceleration.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DragHarmonic {
    /// Cycles per revolution, ≥ 1.
    pub order: u32,
    /// Amplitude, rad/s² (a torque divided by the rotor's moment of inertia).
    pub amplitude: f64,
    /// Phase, degrees (default 0).
    #[serde(default)]
    pub phase_deg: f64,
}

/// One session of `[[procedure.sessions]]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SessionSpec {
    /// Relative rotation `Δ_k = θ_A − θ_B`, degrees.
    pub relative_deg: f64,
    /// Constant-speed revolutions (default: the procedure's `revolutions`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub revolutions: Option<f64>,
    /// This session's cruise speed, revolutions per minute (> 0; default: the scenario's
    /// `speed_rpm`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed_rpm: Option<f64>,
    /// The shaft turns backwards (its readings decrease) in this session (default `false`).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub backward: bool,
}

impl Procedure {
    /// Each session's signed cruise speed, revolutions per minute (negative: backwards), from
    /// its `speed_rpm` and `backward`, `default_rpm` where it gives none.
    pub fn session_speeds_rpm(&self, default_rpm: f64) -> Vec<f64> {
        if self.sessions.is_empty() {
            return vec![default_rpm; self.relative_deg.len()];
        }
        self.sessions
            .iter()
            .map(|s| {
                let rpm = s.speed_rpm.unwrap_or(default_rpm);
                if s.backward { -rpm } else { rpm }
            })
            .collect()
    }

    /// The sessions as `(relative_deg, revolutions)`, from whichever form the file used.
    pub fn resolved_sessions(&self) -> Vec<(f64, f64)> {
        if self.sessions.is_empty() {
            self.relative_deg
                .iter()
                .map(|&d| (d, self.revolutions))
                .collect()
        } else {
            self.sessions
                .iter()
                .map(|s| (s.relative_deg, s.revolutions.unwrap_or(self.revolutions)))
                .collect()
        }
    }
}

/// A scenario that cannot be simulated. Each variant names the field concerned.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ScenarioError {
    /// A number out of its range.
    #[error("{field} = {value}: must be {expected}")]
    InvalidValue {
        /// Where, e.g. `sensor "a" noise_arcsec`.
        field: String,
        /// What was given.
        value: f64,
        /// What is allowed.
        expected: &'static str,
    },
    /// No `[[sensor]]` table.
    #[error("the scenario has no [[sensor]]: add at least one")]
    NoSensors,
    /// A sensor or scale without a name.
    #[error("{what} number {index} (counting from 1) has an empty name")]
    EmptyName {
        /// `sensor` or `scale`.
        what: &'static str,
        /// Its position in the file, from 1.
        index: usize,
    },
    /// Two sensors (channels) or two scales with the same name.
    #[error("{what} name `{name}` is used twice: names must be unique")]
    DuplicateName {
        /// `sensor` or `scale`.
        what: &'static str,
        /// The repeated name.
        name: String,
    },
    /// A head refers to a scale that is not defined.
    #[error("sensor `{sensor}` reads scale `{scale}`, which no [[scale]] defines (defined: {})", if available.is_empty() { "none".to_string() } else { available.join(", ") })]
    UnknownScale {
        /// The head.
        sensor: String,
        /// The scale it names.
        scale: String,
        /// The scales defined.
        available: Vec<String>,
    },
    /// Two fields that exclude each other, or one that needs another.
    #[error("sensor `{sensor}`: {problem}")]
    Conflict {
        /// The sensor.
        sensor: String,
        /// What is wrong and what to do.
        problem: &'static str,
    },
    /// `[sweep]` together with a table it replaces.
    #[error(
        "[sweep] replaces [{table}]: remove [{table}] (a swept joint has no CSRR sessions and does not coast)"
    )]
    SweepConflict {
        /// `procedure` or `spin_down`.
        table: &'static str,
    },
    /// `[spin_down]` together with a table it replaces.
    #[error(
        "[spin_down] replaces [{table}]: remove [{table}] (a coasting shaft has no procedure and no driven speed modulation; model bearing effects with `drag_harmonics`)"
    )]
    SpinDownConflict {
        /// `procedure` or `speed`.
        table: &'static str,
    },
    /// Both session forms, or neither.
    #[error("[procedure]: {problem}")]
    Sessions {
        /// What is wrong and what to do.
        problem: &'static str,
    },
    /// An error model (or the speed modulation) so steep that `θ ↦ θ + e(θ)` may not increase
    /// monotonically: readings would not determine the angle (or the shaft would run backwards).
    #[error(
        "{what}: Σ order·|amplitude| = {bound:.3} rad/rad ≥ 1, so θ + e(θ) need not increase with θ and a reading would not determine one angle; reduce the high-order amplitudes"
    )]
    TooSteep {
        /// `sensor "a"`, `scale "disc"` or `speed`.
        what: String,
        /// The bound `Σ order·|amplitude|` (radians per radian).
        bound: f64,
    },
}

fn check(
    field: impl FnOnce() -> String,
    value: f64,
    ok: bool,
    expected: &'static str,
) -> Result<(), ScenarioError> {
    if ok && value.is_finite() {
        Ok(())
    } else {
        Err(ScenarioError::InvalidValue {
            field: field(),
            value,
            expected,
        })
    }
}

fn check_harmonics(what: &str, harmonics: &[HarmonicSpec]) -> Result<(), ScenarioError> {
    for (i, h) in harmonics.iter().enumerate() {
        let at = |key: &str| format!("{what} harmonic {} {key}", i + 1);
        check(
            || at("order"),
            h.order as f64,
            h.order >= 1,
            "an order ≥ 1 (order 0 is an offset, which no map holds)",
        )?;
        check(
            || at("amplitude_arcsec"),
            h.amplitude_arcsec,
            true,
            "finite",
        )?;
        check(|| at("phase_deg"), h.phase_deg, true, "finite")?;
    }
    Ok(())
}

/// `Σ order·|amplitude|` in radians per radian.
pub(crate) fn slope_bound(harmonics: &[HarmonicSpec]) -> f64 {
    harmonics
        .iter()
        .map(|h| h.order as f64 * h.amplitude_arcsec.abs())
        .sum::<f64>()
        / crate::angle::ARCSEC_PER_RAD
}

fn check_slope(what: impl FnOnce() -> String, bound: f64) -> Result<(), ScenarioError> {
    if bound < 1.0 {
        Ok(())
    } else {
        Err(ScenarioError::TooSteep {
            what: what(),
            bound,
        })
    }
}

impl Scenario {
    /// Checks everything [`Scenario::samples`] and [`Scenario::truth`] rely on; the first problem
    /// found is returned, naming its field.
    pub fn validate(&self) -> Result<(), ScenarioError> {
        check(|| "rate_hz".into(), self.rate_hz, self.rate_hz > 0.0, "> 0")?;
        check(
            || "speed_rpm".into(),
            self.speed_rpm,
            self.speed_rpm > 0.0,
            "> 0",
        )?;
        check(
            || "time_jitter_s".into(),
            self.time_jitter_s,
            self.time_jitter_s >= 0.0,
            "≥ 0",
        )?;

        let v = self.speed.variation_percent;
        check(|| "speed.variation_percent".into(), v, v >= 0.0, "≥ 0")?;
        check_harmonics("speed", &self.speed.harmonics)?;
        check_slope(
            || "speed".into(),
            slope_bound(&self.speed.harmonics) + v / 100.0,
        )?;

        let mut scale_names = HashSet::new();
        for (i, s) in self.scales.iter().enumerate() {
            if s.name.is_empty() {
                return Err(ScenarioError::EmptyName {
                    what: "scale",
                    index: i + 1,
                });
            }
            if !scale_names.insert(s.name.as_str()) {
                return Err(ScenarioError::DuplicateName {
                    what: "scale",
                    name: s.name.clone(),
                });
            }
            let what = format!("scale `{}`", s.name);
            check_harmonics(&what, &s.harmonics)?;
            check_slope(|| what.clone(), slope_bound(&s.harmonics))?;
        }

        if self.sensors.is_empty() {
            return Err(ScenarioError::NoSensors);
        }
        let mut names = HashSet::new();
        for (i, s) in self.sensors.iter().enumerate() {
            if s.name.is_empty() {
                return Err(ScenarioError::EmptyName {
                    what: "sensor",
                    index: i + 1,
                });
            }
            if !names.insert(s.name.as_str()) {
                return Err(ScenarioError::DuplicateName {
                    what: "sensor",
                    name: s.name.clone(),
                });
            }
            let what = format!("sensor `{}`", s.name);
            let field = |key: &str| format!("{what} {key}");
            check(
                || field("quantization_arcsec"),
                s.quantization_arcsec,
                s.quantization_arcsec >= 0.0,
                "≥ 0 (0: no quantization)",
            )?;
            check(
                || field("noise_arcsec"),
                s.noise_arcsec,
                s.noise_arcsec >= 0.0,
                "≥ 0",
            )?;
            check(|| field("delay_s"), s.delay_s, true, "finite")?;
            check(
                || field("backlash_arcsec"),
                s.backlash_arcsec,
                s.backlash_arcsec >= 0.0,
                "≥ 0 (0: a rigid coupling)",
            )?;
            let conflict = |problem| ScenarioError::Conflict {
                sensor: s.name.clone(),
                problem,
            };
            check(
                || field("ratio"),
                s.ratio,
                s.ratio != 0.0 && s.ratio.abs() <= 1e4,
                "a real number other than 0, at most 10⁴ in size",
            )?;
            match &s.scale {
                Some(scale) => {
                    if s.ratio != 1.0 {
                        return Err(conflict(
                            "`ratio` is not allowed with `scale`: a head turns with its scale",
                        ));
                    }
                    if s.commanded {
                        return Err(conflict(
                            "`commanded` is not allowed with `scale`: a commanded angle is the drive's, not a head's",
                        ));
                    }
                    if s.mount.is_some() {
                        return Err(conflict(
                            "`mount` is not allowed with `scale`: a head turns with its scale; set `mount` in the [[scale]]",
                        ));
                    }
                    if !s.harmonics.is_empty() {
                        return Err(conflict(
                            "`harmonics` are not allowed with `scale`: the head's error is the scale's; move them to the [[scale]]",
                        ));
                    }
                    if !self.scales.iter().any(|sc| &sc.name == scale) {
                        return Err(ScenarioError::UnknownScale {
                            sensor: s.name.clone(),
                            scale: scale.clone(),
                            available: self.scales.iter().map(|sc| sc.name.clone()).collect(),
                        });
                    }
                    // The scale's slope bound, checked above, covers its heads: their terms
                    // are the scale's with shifted phases.
                    let head = s.head_deg.unwrap_or(0.0);
                    check(|| field("head_deg"), head, true, "finite")?;
                    let herr = s.head_error_arcsec.unwrap_or(0.0);
                    check(|| field("head_error_arcsec"), herr, true, "finite")?;
                }
                None => {
                    if s.head_deg.is_some() || s.head_error_arcsec.is_some() {
                        return Err(conflict(
                            "`head_deg` and `head_error_arcsec` need `scale`: name the [[scale]] this head reads",
                        ));
                    }
                    check_harmonics(&what, &s.harmonics)?;
                    check_slope(|| what.clone(), slope_bound(&s.harmonics))?;
                }
            }
        }

        if let Some(sw) = &self.sweep {
            return validate_sweep(self, sw);
        }
        if let Some(sd) = &self.spin_down {
            return validate_spin_down(self, sd);
        }
        let p = &self.procedure;
        if !p.sessions.is_empty() && !p.relative_deg.is_empty() {
            return Err(ScenarioError::Sessions {
                problem: "give either `relative_deg = [...]` or `[[procedure.sessions]]`, not both",
            });
        }
        let sessions = p.resolved_sessions();
        if sessions.is_empty() {
            return Err(ScenarioError::Sessions {
                problem: "no sessions: add e.g. `relative_deg = [0.0, 7.3, 23.9]` (one relative rotation per session)",
            });
        }
        check(
            || "procedure.revolutions".into(),
            p.revolutions,
            p.revolutions > 0.0,
            "> 0",
        )?;
        check(
            || "procedure.ramp_s".into(),
            p.ramp_s,
            p.ramp_s >= 0.0,
            "≥ 0",
        )?;
        check(
            || "procedure.pause_s".into(),
            p.pause_s,
            p.pause_s >= 0.0,
            "≥ 0",
        )?;
        check(
            || "procedure.turn_s".into(),
            p.turn_s,
            p.turn_s >= 0.0,
            "≥ 0",
        )?;
        for (k, (delta, revs)) in sessions.iter().enumerate() {
            check(
                || format!("procedure session {} relative_deg", k + 1),
                *delta,
                true,
                "finite",
            )?;
            check(
                || format!("procedure session {} revolutions", k + 1),
                *revs,
                *revs > 0.0,
                "> 0",
            )?;
        }
        for (k, rpm) in p.sessions.iter().enumerate() {
            if let Some(rpm) = rpm.speed_rpm {
                check(
                    || format!("procedure session {} speed_rpm", k + 1),
                    rpm,
                    rpm > 0.0,
                    "> 0 (turn a session backwards with `backward = true`)",
                )?;
            }
        }
        Ok(())
    }
}

fn validate_sweep(scenario: &Scenario, sw: &Sweep) -> Result<(), ScenarioError> {
    if scenario.procedure != Procedure::default() {
        return Err(ScenarioError::SweepConflict { table: "procedure" });
    }
    if scenario.spin_down.is_some() {
        return Err(ScenarioError::SweepConflict { table: "spin_down" });
    }
    check(|| "sweep.from_deg".into(), sw.from_deg, true, "finite")?;
    check(
        || "sweep.to_deg".into(),
        sw.to_deg,
        sw.to_deg != sw.from_deg,
        "finite and different from from_deg",
    )?;
    check(
        || "sweep.cycles".into(),
        f64::from(sw.cycles),
        sw.cycles >= 1,
        "≥ 1",
    )?;
    for (i, &v) in sw.speeds_deg_s.iter().enumerate() {
        check(|| format!("sweep.speeds_deg_s[{i}]"), v, v > 0.0, "> 0")?;
    }
    check(|| "sweep.ramp_s".into(), sw.ramp_s, sw.ramp_s >= 0.0, "≥ 0")?;
    check(
        || "sweep.pause_s".into(),
        sw.pause_s,
        sw.pause_s >= 0.0,
        "≥ 0",
    )?;
    Ok(())
}

fn validate_spin_down(scenario: &Scenario, sd: &SpinDown) -> Result<(), ScenarioError> {
    if scenario.procedure != Procedure::default() {
        return Err(ScenarioError::SpinDownConflict { table: "procedure" });
    }
    if scenario.speed != Speed::default() {
        return Err(ScenarioError::SpinDownConflict { table: "speed" });
    }
    check(
        || "spin_down.speed_rpm".into(),
        sd.speed_rpm,
        sd.speed_rpm > 0.0,
        "> 0",
    )?;
    check(
        || "spin_down.duration_s".into(),
        sd.duration_s,
        sd.duration_s > 0.0,
        "> 0",
    )?;
    let f = &sd.friction;
    for (key, v) in [
        ("coulomb", f.coulomb),
        ("viscous", f.viscous),
        ("quadratic", f.quadratic),
    ] {
        check(
            || format!("spin_down.friction.{key}"),
            v,
            v >= 0.0,
            "≥ 0 (friction decelerates)",
        )?;
    }
    for (i, d) in sd.drag_harmonics.iter().enumerate() {
        let at = |key: &str| format!("spin_down drag harmonic {} {key}", i + 1);
        check(|| at("order"), f64::from(d.order), d.order >= 1, "≥ 1")?;
        check(|| at("amplitude"), d.amplitude, true, "finite")?;
        check(|| at("phase_deg"), d.phase_deg, true, "finite")?;
    }
    if let Some(drive) = &sd.drive {
        check(
            || "spin_down.drive.time_constant_s".into(),
            drive.time_constant_s,
            drive.time_constant_s > 0.0,
            "> 0",
        )?;
        let mut last = 0.0;
        for (i, step) in drive.steps.iter().enumerate() {
            let at = |key: &str| format!("spin_down drive step {} {key}", i + 1);
            check(
                || at("from_s"),
                step.from_s,
                step.from_s >= last,
                "≥ 0 and ≥ the step before",
            )?;
            check(
                || at("speed_rpm"),
                step.speed_rpm,
                step.speed_rpm >= 0.0,
                "≥ 0",
            )?;
            last = step.from_s;
        }
    }
    Ok(())
}
