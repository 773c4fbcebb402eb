//! Channel names: how a channel of any log is addressed on the command line.
//!
//! A channel carried on a topic (an MCAP or bag topic) has a **qualified name** `TOPIC/NAME`:
//! the topic, `/`, and the joint name (JointState) or field (JSON); `/sensor_a/joint_states/
//! encoder`. Its **short name** is `NAME`. The name a log reports for a channel
//! ([`ChannelName::display`]) is the short name where no other channel of the log shares it,
//! else the qualified one — the dual-arm robot whose four topics each carry `shoulder_pan` has
//! four channels `/robot/arm_left_lead/joint_states/shoulder_pan`, … . A topic of scalar
//! messages has one channel named after the topic. A CSV column's three names are its header.
//!
//! [`resolve`] accepts a qualified name always and a short name where it is unique; an ambiguous
//! short name is an error listing the qualified candidates.

/// The names of one channel.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ChannelName {
    /// `TOPIC/NAME` (for a CSV column or a scalar topic, the same as `short`).
    pub qualified: String,
    /// `NAME` alone.
    pub short: String,
    /// The name the log reports: `short` where unique in the log, else `qualified`.
    pub display: String,
}

impl ChannelName {
    /// A name that is the same in every form (a CSV column, a scalar topic).
    pub fn plain(name: &str) -> Self {
        ChannelName {
            qualified: name.to_string(),
            short: name.to_string(),
            display: name.to_string(),
        }
    }
}

/// The names of channels `(topic, name)`, in order: each channel's display name is its short
/// name where unique among them, else its qualified name. `topic = None` for a channel that is
/// a whole topic (a scalar) or a CSV column.
pub fn names_of<'a>(
    channels: impl IntoIterator<Item = (Option<&'a str>, &'a str)>,
) -> Vec<ChannelName> {
    let mut names: Vec<ChannelName> = channels
        .into_iter()
        .map(|(topic, name)| match topic {
            Some(topic) => ChannelName {
                qualified: format!("{topic}/{name}"),
                short: name.to_string(),
                display: String::new(),
            },
            None => ChannelName::plain(name),
        })
        .collect();
    // Counted once: a count per name instead of a scan per name (60,000 joints took 48 s).
    let mut count: std::collections::HashMap<&str, usize> = std::collections::HashMap::new();
    for n in &names {
        *count.entry(n.short.as_str()).or_default() += 1;
    }
    let display: Vec<String> = names
        .iter()
        .map(|n| {
            if count[n.short.as_str()] == 1 {
                n.short.clone()
            } else {
                n.qualified.clone()
            }
        })
        .collect();
    for (n, d) in names.iter_mut().zip(display) {
        n.display = d;
    }
    names
}

/// A channel name that does not name exactly one channel of the log.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ChannelLookup {
    /// No channel has that name.
    #[error(
        "no channel `{name}` in the log (it has: {}); pick one of those names",
        crate::limits::listed(available)
    )]
    Unknown {
        /// The name asked for.
        name: String,
        /// The log's channels by their display names.
        available: Vec<String>,
    },
    /// Several channels have that short name.
    #[error("channel `{name}` is ambiguous: {} topics carry it ({}); name one as TOPIC/{name}", candidates.len(), crate::limits::listed(candidates))]
    Ambiguous {
        /// The name asked for.
        name: String,
        /// The qualified names of the channels it could be.
        candidates: Vec<String>,
    },
}

/// The index of the channel `wanted` names: a qualified name, or a short name no other channel
/// shares (see the [module docs](self)).
pub fn resolve(names: &[ChannelName], wanted: &str) -> Result<usize, ChannelLookup> {
    if let Some(i) = names.iter().position(|n| n.qualified == wanted) {
        return Ok(i);
    }
    let found: Vec<usize> = (0..names.len())
        .filter(|&i| names[i].short == wanted)
        .collect();
    match found.as_slice() {
        [i] => Ok(*i),
        [] => Err(ChannelLookup::Unknown {
            name: wanted.to_string(),
            available: names.iter().map(|n| n.display.clone()).collect(),
        }),
        _ => Err(ChannelLookup::Ambiguous {
            name: wanted.to_string(),
            candidates: found.iter().map(|&i| names[i].qualified.clone()).collect(),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn short_names_where_unique_and_qualified_always() {
        let names = names_of([
            (Some("/left/joint_states"), "pan"),
            (Some("/left/joint_states"), "tilt"),
            (Some("/right/joint_states"), "pan"),
            (None, "/motor/angle"),
        ]);
        let display: Vec<&str> = names.iter().map(|n| n.display.as_str()).collect();
        assert_eq!(
            display,
            [
                "/left/joint_states/pan",
                "tilt",
                "/right/joint_states/pan",
                "/motor/angle"
            ]
        );
        assert_eq!(resolve(&names, "tilt"), Ok(1));
        assert_eq!(resolve(&names, "/left/joint_states/tilt"), Ok(1));
        assert_eq!(resolve(&names, "/right/joint_states/pan"), Ok(2));
        assert_eq!(resolve(&names, "/motor/angle"), Ok(3));
        let err = resolve(&names, "pan").unwrap_err();
        assert!(matches!(err, ChannelLookup::Ambiguous { .. }));
        assert!(
            err.to_string()
                .contains("(/left/joint_states/pan, /right/joint_states/pan)"),
            "{err}"
        );
        let err = resolve(&names, "roll").unwrap_err();
        assert!(
            err.to_string()
                .contains("it has: /left/joint_states/pan, tilt"),
            "{err}"
        );
    }
}
