//! [`Topic`]: one topic calib reads — its channels, learnt from its first messages, and how a
//! message's joints map onto them — whichever log the messages come from.

use super::encoding::Encoding;
use crate::mcap_log::cdr::{JointFormat, JointState};
use crate::mcap_log::json;
use crate::mcap_log::msgdef::Plan;

/// Joint sets per topic whose channel positions are remembered (beyond it they are looked up
/// name by name): more publishers than any robot shares one topic between.
const LAYOUT_CACHE: usize = 64;

/// Messages and log-time span of one topic.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct TopicStats {
    pub(crate) messages: u64,
    pub(crate) first: u64,
    pub(crate) last: u64,
}

impl TopicStats {
    /// Counts a message logged at `log_time` (ns).
    pub(crate) fn note(&mut self, log_time: u64) {
        if self.messages == 0 {
            self.first = log_time;
        }
        self.messages += 1;
        self.last = log_time;
    }

    /// Messages per second of log time, from the first to the last; `None` below two messages.
    pub(crate) fn rate_hz(&self) -> Option<f64> {
        (self.messages > 1 && self.last > self.first)
            .then(|| (self.messages - 1) as f64 / ((self.last - self.first) as f64 * 1e-9))
    }
}

/// A topic read, with its channels.
pub(crate) struct Topic {
    pub(crate) name: String,
    pub(crate) schema: String,
    pub(crate) message_encoding: String,
    pub(crate) encoding: Encoding,
    /// JointState: the `name` block of the first message, compared byte for byte with later ones.
    pub(super) name_block: Vec<u8>,
    /// The channel names: joint names or JSON fields.
    pub(crate) names: Vec<String>,
    /// Index of the topic's first channel among the file's.
    pub(crate) offset: usize,
    /// JointState: whether messages carry different joint sets.
    pub(crate) subset: bool,
    /// JointState: name blocks other than the first message's, with the channel of each name
    /// ([`NO_POSITION`] for a joint that has no channel).
    layouts: Vec<(Vec<u8>, Vec<usize>)>,
    /// DynamicJointState: joints met without a `position` interface, which are not channels.
    pub(super) no_position: Vec<String>,
    /// Radians per unit of a JSON, scalar or field value.
    pub(super) scale: f64,
    /// Field paths: the walk that reads them.
    pub(super) plan: Option<Box<Plan>>,
    /// JSON: which channels a message has given, reused between messages.
    pub(super) seen: Vec<bool>,
    /// CDR JointState: the last message of the first message's names (see [`SameLayout`]).
    pub(super) same: Option<SameLayout>,
    pub(crate) stats: TopicStats,
}

/// A CDR JointState message whose names are the topic's first message's. Another message of the
/// same length whose bytes equal this one's but in the header's stamp and the `position`
/// elements decodes the same way — the same names, counts and offsets: no field the parse
/// checks differs — so its stamp and positions are read where this one's are, without a parse.
pub(crate) struct SameLayout {
    message: Vec<u8>,
    /// The `position` elements' span.
    positions: std::ops::Range<usize>,
    big_endian: bool,
    /// Whether the message carries every channel of the topic, in order.
    pub(super) full: bool,
}

/// Bytes 4–12 of a CDR JointState: `header.stamp` (`sec`, `nanosec`) after the encapsulation.
const STAMP: std::ops::Range<usize> = 4..12;

impl SameLayout {
    /// The layout of `data`, a CDR JointState parsed as `js`.
    pub(super) fn of(js: &JointState, data: &[u8], full: bool) -> Self {
        SameLayout {
            message: data.to_vec(),
            positions: js.positions_span(),
            // The encapsulation header: [0, 0] big-endian, [0, 1] little-endian.
            big_endian: data[1] == 0,
            full,
        }
    }

    /// Whether `data` has this layout.
    pub(super) fn fits(&self, data: &[u8]) -> bool {
        let m = &self.message;
        data.len() == m.len()
            && data[..STAMP.start] == m[..STAMP.start]
            && data[STAMP.end..self.positions.start] == m[STAMP.end..self.positions.start]
            && data[self.positions.end..] == m[self.positions.end..]
    }

    /// `header.stamp` of `data`: seconds (signed, as the parse reads them) and nanoseconds.
    pub(super) fn stamp(&self, data: &[u8]) -> (i64, u32) {
        let u32_at = |at: usize| {
            let b: [u8; 4] = data[at..at + 4].try_into().unwrap_or_default();
            if self.big_endian {
                u32::from_be_bytes(b)
            } else {
                u32::from_le_bytes(b)
            }
        };
        (
            i64::from(u32_at(STAMP.start) as i32),
            u32_at(STAMP.start + 4),
        )
    }

    /// The positions of `data`, in order.
    pub(super) fn positions<'d>(&self, data: &'d [u8]) -> impl Iterator<Item = f64> + 'd {
        let big_endian = self.big_endian;
        data[self.positions.clone()].chunks_exact(8).map(move |b| {
            let b: [u8; 8] = b.try_into().unwrap_or_default();
            if big_endian {
                f64::from_be_bytes(b)
            } else {
                f64::from_le_bytes(b)
            }
        })
    }
}

/// The type name of an MCAP channel's messages; empty if it has no schema.
pub(super) fn schema_name(channel: &mcap::Channel) -> String {
    channel
        .schema
        .as_ref()
        .map_or_else(String::new, |s| s.name.clone())
}

/// The layout entry of a DynamicJointState joint without a `position` interface: no channel.
pub(super) const NO_POSITION: usize = usize::MAX;

/// A topic's channels from its first message.
pub(super) fn first_message(
    message: &mcap::Message,
    encoding: Encoding,
    scale: f64,
) -> Result<Topic, String> {
    let mut topic = Topic::new(
        message.channel.topic.clone(),
        schema_name(&message.channel),
        message.channel.message_encoding.clone(),
        encoding,
        scale,
    );
    match encoding {
        Encoding::JointState(format) => {
            let js = JointState::parse_as(&message.data, format).map_err(|e| e.to_string())?;
            for (name, position) in js.names().zip(js.positions()) {
                let name = name.map_err(|e| e.to_string())?;
                if topic
                    .names
                    .iter()
                    .chain(&topic.no_position)
                    .any(|n| n == name)
                {
                    return Err(repeated_joint(name));
                }
                if format == JointFormat::Dynamic && position.is_nan() {
                    topic.no_position.push(name.to_string());
                } else {
                    topic.names.push(name.to_string());
                }
            }
            // The fast path takes the message's joints as the channels in order; with joints
            // left out, every message goes through its layout.
            if topic.no_position.is_empty() {
                topic.name_block = js.name_block.to_vec();
            }
        }
        Encoding::Json => {
            let mut fields = 0;
            json::for_each_field(&message.data, |key, value| {
                fields += 1;
                if fields > crate::limits::MAX_JSON_FIELDS {
                    return Err(format!(
                        "the topic's first JSON message has more than {} fields, more than \
                         calib reads in one message; publish one numeric field per encoder",
                        crate::limits::MAX_JSON_FIELDS
                    ));
                }
                if value.is_some() {
                    topic.names.push(key.to_string());
                }
                Ok(())
            })?;
            topic.seen = vec![false; topic.names.len()];
        }
        Encoding::Scalar(kind) => {
            kind.decode_in(&message.data, &message.channel.message_encoding)
                .map_err(|e| e.to_string())?;
            topic.names.push(topic.name.clone());
        }
        // Added by name ([`Registry::read_fields`]), not from a first message.
        Encoding::Field => {}
    }
    if topic.names.is_empty() {
        return Err(match encoding {
            Encoding::JointState(JointFormat::Dynamic) => "the topic's first DynamicJointState \
                                                           message has no joint with a \
                                                           `position` interface"
                .into(),
            Encoding::JointState(_) => "the topic's first JointState message names no joints; \
                                     publish the encoders' names and positions"
                .into(),
            Encoding::Json | Encoding::Scalar(_) | Encoding::Field => {
                "the topic's first JSON message has no \
                                                     numeric field; publish one numeric field \
                                                     per encoder"
                    .into()
            }
        });
    }
    Ok(topic)
}

fn repeated_joint(name: &str) -> String {
    format!(
        "joint `{name}` appears twice in one message; a message can hold one position per \
         joint: fix the publisher"
    )
}

impl Topic {
    /// A topic without channels yet: its first message, or the field paths asked for, name
    /// them.
    pub(super) fn new(
        name: String,
        schema: String,
        message_encoding: String,
        encoding: Encoding,
        scale: f64,
    ) -> Self {
        Topic {
            name,
            schema,
            message_encoding,
            encoding,
            name_block: Vec::new(),
            names: Vec::new(),
            offset: 0,
            subset: false,
            layouts: Vec::new(),
            no_position: Vec::new(),
            scale,
            plan: None,
            seen: Vec::new(),
            same: None,
            stats: TopicStats::default(),
        }
    }

    /// `(topic, name)` of each channel, as [`names_of`](crate::naming::names_of) takes them: a scalar topic's one
    /// channel is the topic itself.
    pub(crate) fn channel_names(&self) -> impl Iterator<Item = (Option<&str>, &str)> {
        let topic = match self.encoding {
            // Named in full: the topic itself, or `TOPIC.field.path`.
            Encoding::Scalar(_) | Encoding::Field => None,
            _ => Some(self.name.as_str()),
        };
        self.names.iter().map(move |n| (topic, n.as_str()))
    }

    /// Adds the joints of a later message the topic's first did not name (peek pass).
    pub(crate) fn learn(&mut self, message: &mcap::Message) -> Result<(), String> {
        let Encoding::JointState(format) = self.encoding else {
            return Ok(());
        };
        let js = JointState::parse_as(&message.data, format).map_err(|e| e.to_string())?;
        if js.name_block == self.name_block.as_slice() {
            return Ok(());
        }
        if format == JointFormat::Dynamic {
            // Joints without a `position` interface are not channels; a joint with one that the
            // first message lacked is a channel of its own series.
            for (name, position) in js.names().zip(js.positions()) {
                let name = name.map_err(|e| e.to_string())?;
                let known = self.names.iter().any(|n| n == name);
                if position.is_nan() {
                    if !known && !self.no_position.iter().any(|n| n == name) {
                        self.no_position.push(name.to_string());
                    }
                } else if !known {
                    self.names.push(name.to_string());
                    self.subset = true;
                }
            }
            return Ok(());
        }
        let mut names = Vec::with_capacity(js.name_count);
        for name in js.names() {
            let name = name.map_err(|e| e.to_string())?;
            if names.contains(&name) {
                return Err(repeated_joint(name));
            }
            names.push(name);
        }
        if names.len() == self.names.len() && names.iter().zip(&self.names).all(|(a, b)| a == b) {
            // The same names, serialized with other padding.
            return Ok(());
        }
        self.subset = true;
        for name in names {
            if !self.names.iter().any(|n| n == name) {
                self.names.push(name.to_string());
            }
        }
        Ok(())
    }

    /// The channel (within the topic) of each joint of `js`, whose name block differs from the
    /// first message's.
    pub(super) fn layout(&mut self, js: &JointState) -> Result<Vec<usize>, String> {
        if let Some((_, layout)) = self.layouts.iter().find(|(b, _)| b == js.name_block) {
            return Ok(layout.clone());
        }
        let mut layout = Vec::with_capacity(js.name_count);
        for name in js.names() {
            let name = name.map_err(|e| e.to_string())?;
            let Some(i) = self.names.iter().position(|n| n == name).or_else(|| {
                self.no_position
                    .iter()
                    .any(|n| n == name)
                    .then_some(NO_POSITION)
            }) else {
                return Err(format!(
                    "joint `{name}` is new: the topic's joints [{}] were gathered from its \
                     first messages when the file was opened; calib needs every joint to \
                     appear early: split the recording where the joint set changes",
                    crate::limits::listed(&self.names)
                ));
            };
            if i != NO_POSITION && layout.contains(&i) {
                return Err(repeated_joint(name));
            }
            layout.push(i);
        }
        if self.layouts.len() < LAYOUT_CACHE {
            self.layouts.push((js.name_block.to_vec(), layout.clone()));
        }
        Ok(layout)
    }
}
