//! [`decode`]: one message's readings in radians and its stamp, the same for a message from an
//! MCAP file or a bag's row.

use super::encoding::Encoding;
use super::topic::{NO_POSITION, SameLayout, Topic};
use crate::TimeSource;
use crate::mcap_log::cdr::{JointFormat, JointState};
use crate::mcap_log::json;

/// A stamp in nanoseconds as seconds, rounded once to the nearest double: within a
/// nanosecond for stamps below 2²³ s (97 days: a log timed from its start, or stamps counted
/// from the first one's second as samples are), but stamps since 1970 (~1.7·10⁹ s) land on
/// doubles 2.4·10⁻⁷ s apart.
pub(crate) fn seconds(ns: i64) -> f64 {
    const NS: i64 = 1_000_000_000;
    ns.div_euclid(NS) as f64 + ns.rem_euclid(NS) as f64 * 1e-9
}

/// A message's log time as a stamp; an error past what an `i64` of nanoseconds holds.
fn log_time_ns(log_time: u64) -> Result<i64, String> {
    i64::try_from(log_time).map_err(|_| {
        format!("log time {log_time} ns is beyond the year 2262; the recorder's clock is wrong")
    })
}

/// Puts `rad`, the reading of channel `i` of `names`, into `out`; an error naming the channel if
/// it is not a reading.
fn put_reading(
    names: &[String],
    out: &mut [f64],
    i: usize,
    rad: f64,
) -> Result<(), (Option<String>, String)> {
    match crate::limits::reading_problem(crate::limits::Readable(rad), rad, rad) {
        Some(problem) => Err((Some(names[i].clone()), problem)),
        None => {
            out[i] = rad;
            Ok(())
        }
    }
}

/// A JointState's stamp in nanoseconds: its header's `sec` and `nanosec`, or the message's log
/// time with [`TimeSource::Log`] or a zero stamp; an error for `nanosec` past a second.
fn stamp_of(
    sec: i64,
    nanosec: u32,
    message: &mcap::Message,
    time: TimeSource,
) -> Result<i64, (Option<String>, String)> {
    if nanosec >= 1_000_000_000 {
        return Err((
            None,
            format!(
                "header.stamp.nanosec is {nanosec}, not below 10⁹; the publisher's stamps are \
                 broken (nanoseconds must be the fraction of the second)"
            ),
        ));
    }
    if time == TimeSource::Log || (sec == 0 && nanosec == 0) {
        log_time_ns(message.log_time).map_err(|m| (None, m))
    } else {
        Ok(sec * 1_000_000_000 + i64::from(nanosec))
    }
}

/// Decodes a message of `topic` into `out` (radians, one slot per channel of the topic, left
/// as they are for channels the message does not carry) and returns its stamp in nanoseconds
/// and whether it carried every channel in the topic's order. Errors carry the channel
/// concerned (if not the topic) and the message.
pub(crate) fn decode(
    topic: &mut Topic,
    message: &mcap::Message,
    time: TimeSource,
    out: &mut [f64],
) -> Result<(i64, bool), (Option<String>, String)> {
    match topic.encoding {
        Encoding::JointState(format) => {
            if let Some(same) = topic.same.as_ref().filter(|s| s.fits(&message.data)) {
                for (i, rad) in same.positions(&message.data).enumerate() {
                    put_reading(&topic.names, out, i, rad)?;
                }
                let (sec, nanosec) = same.stamp(&message.data);
                return Ok((stamp_of(sec, nanosec, message, time)?, same.full));
            }
            let js =
                JointState::parse_as(&message.data, format).map_err(|e| (None, e.to_string()))?;
            if js.position_count() != js.name_count {
                return Err((
                    None,
                    format!(
                        "the JointState message has {} names but {} positions; the publisher \
                         must give a position for every joint",
                        js.name_count,
                        js.position_count()
                    ),
                ));
            }
            // Fast path: the same names serialize to the same bytes.
            let layout = if js.name_block == topic.name_block.as_slice() {
                None
            } else {
                Some(topic.layout(&js).map_err(|m| (None, m))?)
            };
            let names = &topic.names;
            let mut put = |i: usize, rad: f64| put_reading(names, out, i, rad);
            // A DynamicJointState joint without a `position` interface carries no reading.
            let dynamic = format == JointFormat::Dynamic;
            let mut missing = false;
            let mut put = |i: usize, rad: f64| {
                if dynamic && rad.is_nan() {
                    missing = true;
                    return Ok(());
                }
                put(i, rad)
            };
            let same_names = layout.is_none();
            let full = if let Some(layout) = layout {
                for (&i, rad) in layout.iter().zip(js.positions()) {
                    if i != NO_POSITION {
                        put(i, rad)?;
                    }
                }
                layout
                    .iter()
                    .copied()
                    .filter(|&i| i != NO_POSITION)
                    .eq(0..names.len())
            } else {
                for (i, rad) in js.positions().enumerate() {
                    put(i, rad)?;
                }
                js.name_count == names.len()
            };
            let full = full && !missing;
            let stamp = stamp_of(js.sec, js.nanosec, message, time)?;
            if format == JointFormat::Cdr && same_names {
                topic.same = Some(SameLayout::of(&js, &message.data, full));
            }
            Ok((stamp, full))
        }
        Encoding::Scalar(kind) => {
            let stamp = log_time_ns(message.log_time).map_err(|m| (None, m))?;
            let v = kind
                .decode_in(&message.data, &topic.message_encoding)
                .map_err(|e| (None, e.to_string()))?;
            let rad = v * topic.scale;
            if let Some(problem) = crate::limits::reading_problem(v, v, rad) {
                return Err((None, problem));
            }
            out[0] = rad;
            Ok((stamp, true))
        }
        Encoding::Field => {
            let Some(plan) = topic.plan.as_deref() else {
                return Err((None, "the topic's fields were never named".into()));
            };
            let header = plan
                .read(&message.data, out)
                .map_err(|e| (None, e.to_string()))?;
            for (i, slot) in out.iter_mut().enumerate() {
                let v = *slot;
                let rad = v * topic.scale;
                if let Some(problem) = crate::limits::reading_problem(v, v, rad) {
                    return Err((Some(topic.names[i].clone()), problem));
                }
                *slot = rad;
            }
            let stamp = match header {
                Some((sec, nanosec))
                    if time == TimeSource::Header
                        && (sec, nanosec) != (0, 0)
                        && nanosec < 1_000_000_000 =>
                {
                    sec * 1_000_000_000 + i64::from(nanosec)
                }
                _ => log_time_ns(message.log_time).map_err(|m| (None, m))?,
            };
            Ok((stamp, true))
        }
        Encoding::Json => {
            let stamp = log_time_ns(message.log_time).map_err(|m| (None, m))?;
            topic.seen.iter_mut().for_each(|s| *s = false);
            let (names, seen, scale) = (&topic.names, &mut topic.seen, topic.scale);
            // Fields usually come in the first message's order: try the next expected one first.
            let mut next = 0;
            json::for_each_field(&message.data, |key, value| {
                let i = if names.get(next).is_some_and(|n| n == key) {
                    Some(next)
                } else {
                    names.iter().position(|n| n == key)
                };
                match (i, value) {
                    (Some(i), Some(v)) => {
                        let rad = v * scale;
                        if let Some(problem) = crate::limits::reading_problem(v, v, rad) {
                            return Err(format!("field `{key}`: {problem}"));
                        }
                        out[i] = rad;
                        seen[i] = true;
                        next = i + 1;
                        Ok(())
                    }
                    (Some(_), None) => Err(format!(
                        "field `{key}` is not a number in this message; every message must give \
                         a number for every channel"
                    )),
                    (None, Some(_)) => Err(format!(
                        "numeric field `{key}` is new (the topic's first message has [{}]); \
                         calib needs one channel set per topic: split the recording where it \
                         changes",
                        crate::limits::listed(names)
                    )),
                    (None, None) => Ok(()),
                }
            })
            .map_err(|m| (None, m))?;
            if let Some(i) = seen.iter().position(|s| !s) {
                return Err((
                    Some(names[i].clone()),
                    "the field is missing from this message; every message must give a number \
                     for every channel"
                        .into(),
                ));
            }
            Ok((stamp, true))
        }
    }
}
