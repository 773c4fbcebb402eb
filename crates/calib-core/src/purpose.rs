//! What a log is for: which calibration method its motion suits, told from what
//! [`crate::inspect::Inspector`] found, so that `calib inspect` can say which command to run next
//! and with which channels.
//!
//! The rules read the motion, not the channel names (a name only picks which of two channels is
//! the reference): sessions of two sensors turning together at different relative angles are a
//! CSRR run; a channel that never turns a whole revolution beside another is a joint measured
//! against a reference; three or more channels turning together are heads on one scale; one
//! shaft turning many revolutions may be a spin-down (whether it coasted freely, only the fit
//! can tell).

use crate::angle::{AngleUnit, wrap_pi};
use crate::inspect::{ChannelStats, Inspection};
use crate::segment::SegmentKind;
use std::f64::consts::TAU;

/// Revolutions of travel a spin-down needs before calib's TDR fit is worth trying.
const COAST_REVOLUTIONS: f64 = 10.0;
/// Relative angles of sessions closer than this are one (CSRR's sessions differ by degrees).
const DISTINCT_ANGLE: f64 = 1.0 * std::f64::consts::PI / 180.0;

/// A method the log suits, with the channels to give it.
#[derive(Debug, Clone, PartialEq, serde::Serialize, schemars::JsonSchema)]
pub struct Suggestion {
    /// The method (`csrr`, `reference`, `multihead` or `tdr`).
    pub method: String,
    /// The channels, in the method's order: `[a, b]` (csrr), `[dut, ref]` (reference), the heads
    /// (multihead), `[channel]` or `[channel, ref]` (tdr).
    pub channels: Vec<String>,
    /// What in the log suits it.
    pub why: String,
    /// Options beyond the channels (`--ref-ratio auto` for an actuator).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub options: Vec<String>,
}

/// The methods `inspection`'s log suits, the likeliest first; none when it suits none.
pub fn suggestions(inspection: &Inspection) -> Vec<Suggestion> {
    let ch = &inspection.channels;
    let mut out = Vec::new();
    let angles = relative_angles(inspection);
    if let (Some((a, b)), true) = (&inspection.pair, angles >= 2) {
        out.push(Suggestion {
            method: "csrr".into(),
            channels: vec![a.clone(), b.clone()],
            why: format!(
                "`{a}` and `{b}` turn together in sessions at {angles} different relative angles"
            ),
            options: Vec::new(),
        });
    }
    let turning: Vec<&ChannelStats> = ch.iter().filter(|c| c.travel_revolutions >= 1.0).collect();
    // Three or more channels turning together are heads, unless one is named a reference.
    let heads =
        turning.len() >= 3 && together(&turning) && !ch.iter().any(|c| is_reference(&c.name));
    if heads {
        out.push(Suggestion {
            method: "multihead".into(),
            channels: turning.iter().map(|c| c.name.clone()).collect(),
            why: format!(
                "{} channels turn together ({:.1} revolutions): heads reading one scale",
                turning.len(),
                turning[0].travel_revolutions
            ),
            options: Vec::new(),
        });
    }
    let geared = geared(ch);
    if !geared.is_empty() {
        for &(output, motor, ratio) in &geared {
            out.push(Suggestion {
            method: "reference".into(),
            channels: vec![output.name.clone(), motor.name.clone()],
            why: format!(
                "`{}` travels {ratio:.2} times as far as `{}`: an actuator, its motor's encoder behind a gear of \
                 about {ratio:.2}:1 and its output's encoder; both maps come from the run",
                motor.name, output.name
            ),
            options: vec!["--ref-ratio".into(), "auto".into()],
        });
        }
    } else if ch.len() >= 2
        && let Some(joint) = ch.iter().find(|c| span_revolutions(c) < 0.999)
    {
        let other = other_than(ch, &joint.name);
        // A joint channel named like a reference is the reference.
        let (dut, reference) = if is_reference(&joint.name) {
            (other, joint)
        } else {
            (joint, other)
        };
        out.push(Suggestion {
            method: "reference".into(),
            channels: vec![dut.name.clone(), reference.name.clone()],
            why: format!(
                "`{}` sweeps {:.1}° and never turns a whole revolution: a joint, calibrated \
                 against a reference",
                joint.name,
                span_revolutions(joint) * 360.0
            ),
            options: Vec::new(),
        });
    } else if let (Some((a, b)), 1, false) = (&inspection.pair, angles, heads) {
        let (dut, reference) = if is_reference(a) { (b, a) } else { (a, b) };
        out.push(Suggestion {
            method: "reference".into(),
            channels: vec![dut.clone(), reference.clone()],
            why: format!(
                "`{a}` and `{b}` turn together at one relative angle: an encoder and a reference \
                 on one shaft"
            ),
            options: Vec::new(),
        });
    }
    if angles < 2
        && let Some(shaft) = ch
            .iter()
            .find(|c| c.travel_revolutions >= COAST_REVOLUTIONS)
    {
        let mut channels = vec![shaft.name.clone()];
        // Through a gear the other channel is no reference of this shaft.
        channels.extend(
            geared.is_empty().then_some(()).and(
                ch.iter()
                    .filter(|c| c.name != shaft.name)
                    .find(|c| c.travel_revolutions >= COAST_REVOLUTIONS)
                    .map(|c| c.name.clone()),
            ),
        );
        out.push(Suggestion {
            method: "tdr".into(),
            channels,
            why: format!(
                "`{}` turns {:.1} revolutions: if the shaft coasted freely (a spin-down) or was \
                 driven at a steady speed (a motor at constant voltage), TDR calibrates it alone",
                shaft.name, shaft.travel_revolutions
            ),
            options: Vec::new(),
        });
    }
    out
}

/// Pairs of channels of which one travels at least [`GEAR_RATIO`] times as far as the other:
/// an actuator's output encoder, its motor's encoder and the ratio of their travels. With more
/// than two channels (several joints in one log), each channel is paired once, the pairs whose
/// names share the longest prefix and suffix first (`abs_enc1` with `motor_enc1`).
fn geared(channels: &[ChannelStats]) -> Vec<(&ChannelStats, &ChannelStats, f64)> {
    let mut pairs: Vec<(usize, &ChannelStats, &ChannelStats, f64)> = channels
        .iter()
        .flat_map(|slow| channels.iter().map(move |fast| (slow, fast)))
        .filter_map(|(slow, fast)| {
            let ratio = fast.travel_revolutions / slow.travel_revolutions;
            (slow.travel_revolutions > 0.0 && ratio.is_finite() && ratio >= GEAR_RATIO)
                .then(|| (shared_affixes(&slow.name, &fast.name), slow, fast, ratio))
        })
        .collect();
    pairs.sort_by_key(|p| std::cmp::Reverse(p.0));
    let mut used: Vec<&str> = Vec::new();
    let mut out = Vec::new();
    for (_, slow, fast, ratio) in pairs {
        if !used.contains(&slow.name.as_str()) && !used.contains(&fast.name.as_str()) {
            used.extend([slow.name.as_str(), fast.name.as_str()]);
            out.push((slow, fast, ratio));
        }
    }
    out
}

/// Characters two names share at their start and at their end.
fn shared_affixes(a: &str, b: &str) -> usize {
    let prefix = a.chars().zip(b.chars()).take_while(|(x, y)| x == y).count();
    let suffix = a
        .chars()
        .rev()
        .zip(b.chars().rev())
        .take_while(|(x, y)| x == y)
        .count();
    prefix + suffix
}

/// The ratio of two channels' travels from which they are taken for an actuator's two encoders
/// (far from 1: two encoders on one shaft travel alike, whatever their errors).
const GEAR_RATIO: f64 = 1.5;

/// Relative angles, 1° apart or more, of the sessions of at least one revolution the pair's
/// segmentation found: CSRR needs two or more.
fn relative_angles(inspection: &Inspection) -> usize {
    let mut angles: Vec<f64> = Vec::new();
    let sessions = inspection
        .segments
        .iter()
        .filter(|s| s.kind == SegmentKind::Rotating && s.session.is_some());
    for s in sessions {
        if angles
            .iter()
            .all(|&a| wrap_pi(s.relative_angle - a).abs() > DISTINCT_ANGLE)
        {
            angles.push(s.relative_angle);
        }
    }
    angles.len()
}

/// Whether a channel's name says it is a reference.
fn is_reference(name: &str) -> bool {
    name.to_lowercase().contains("ref")
}

/// A channel other than `name`, one named like a reference first.
fn other_than<'a>(channels: &'a [ChannelStats], name: &str) -> &'a ChannelStats {
    let others = || channels.iter().filter(move |c| c.name != name);
    others()
        .find(|c| is_reference(&c.name))
        .or_else(|| others().next())
        .expect("two channels")
}

/// The part of a revolution a channel's readings span (1 for a channel that wraps or whose
/// unit is not known).
fn span_revolutions(c: &ChannelStats) -> f64 {
    match c.unit.parse::<AngleUnit>() {
        Ok(unit) if !c.wrapped => (unit.to_rad(c.max) - unit.to_rad(c.min)) / TAU,
        _ => 1.0,
    }
}

/// Whether channels travel the same revolutions, within 1 %.
fn together(channels: &[&ChannelStats]) -> bool {
    let first = channels[0].travel_revolutions;
    channels
        .iter()
        .all(|c| (c.travel_revolutions - first).abs() <= 0.01 * first)
}
