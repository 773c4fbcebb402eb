//! [`Registry`]: the topics of a log — those read, by channel ID for a lookup per message, and
//! those skipped, with what `calib inspect` lists of them.

use super::encoding::Encoding;
use super::topic::{Topic, TopicStats, first_message, schema_name};
use crate::mcap_log::msgdef::Definition;
use crate::naming::ChannelName;

/// A topic of the file, as `calib inspect` lists it.
#[derive(Debug, Clone, PartialEq, serde::Serialize, schemars::JsonSchema)]
pub struct TopicInfo {
    /// The topic.
    pub topic: String,
    /// Its message type (schema name; empty if it has none).
    pub schema: String,
    /// Its message encoding (`cdr`, `json`, …).
    pub message_encoding: String,
    /// Messages read (every message of the file once iteration has ended).
    pub messages: u64,
    /// Messages per second of log time, from the first to the last; `None` below two messages.
    pub rate_hz: Option<f64>,
    /// Its channels by the names the commands accept; empty for a topic calib does not read.
    pub channels: Vec<String>,
}

/// A topic the reader skipped because its messages are neither JointState (CDR) nor JSON.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct IgnoredTopic {
    /// The topic.
    pub topic: String,
    /// Its schema name (empty if it has none).
    pub schema: String,
    /// Its message encoding.
    pub message_encoding: String,
}

/// What a channel ID is known as.
#[derive(Debug, Clone, Copy)]
enum Slot {
    Unknown,
    Ignored(usize),
    Topic(usize),
}

/// Channel IDs resolved to topics.
#[derive(Default)]
pub(crate) struct Registry {
    /// Indexed by channel ID: a vector lookup per message instead of hashing the topic.
    slots: Vec<Slot>,
    pub(crate) topics: Vec<Topic>,
    pub(crate) ignored: Vec<IgnoredTopic>,
    pub(crate) ignored_stats: Vec<TopicStats>,
    /// The schema encoding and text of each skipped topic, for field paths.
    definitions: Vec<Option<(String, Vec<u8>)>>,
    /// The index of each topic read by name.
    topic_by_name: std::collections::HashMap<String, usize>,
    /// Whether each skipped topic's definition came from the data section.
    from_data: Vec<bool>,
    /// The index of each skipped topic by name: a lookup that does not grow with their number.
    pub(crate) ignored_by_name: std::collections::HashMap<String, usize>,
}

/// What a channel ID resolves to.
#[derive(Clone, Copy)]
pub(crate) enum Resolved {
    /// A topic read: its index in [`Registry::topics`].
    Topic(usize),
    /// A topic skipped: its index in [`Registry::ignored`].
    Ignored(usize),
    /// A topic calib reads, not met yet: its first message names its channels.
    NewTopic(Encoding),
}

impl Registry {
    /// Every topic: those read with their channels (by the names in `names`), then those
    /// skipped. Message counts and rates are of the messages counted so far.
    pub(crate) fn topic_infos(&self, names: &[ChannelName]) -> Vec<TopicInfo> {
        let read = self.topics.iter().map(|t| TopicInfo {
            topic: t.name.clone(),
            schema: t.schema.clone(),
            message_encoding: t.message_encoding.clone(),
            messages: t.stats.messages,
            rate_hz: t.stats.rate_hz(),
            channels: names[t.offset..t.offset + t.names.len()]
                .iter()
                .map(|n| n.display.clone())
                .collect(),
        });
        let skipped = self
            .ignored
            .iter()
            .zip(&self.ignored_stats)
            .map(|(t, stats)| TopicInfo {
                topic: t.topic.clone(),
                schema: t.schema.clone(),
                message_encoding: t.message_encoding.clone(),
                messages: stats.messages,
                rate_hz: stats.rate_hz(),
                channels: Vec::new(),
            });
        read.chain(skipped).collect()
    }

    /// The topic of `channel`; an error if it carries a second message type on a topic read,
    /// or is one topic more than calib reads.
    pub(crate) fn resolve(&mut self, channel: &mcap::Channel) -> Result<Resolved, String> {
        let id = usize::from(channel.id);
        if let Some(slot) = self.slots.get(id) {
            match slot {
                Slot::Topic(k) => return Ok(Resolved::Topic(*k)),
                Slot::Ignored(k) => return Ok(Resolved::Ignored(*k)),
                Slot::Unknown => {}
            }
        }
        if self.topics.len() + self.ignored.len() >= crate::limits::MAX_TOPICS {
            return Err(too_many_topics());
        }
        if self.slots.len() <= id {
            self.slots.resize(id + 1, Slot::Unknown);
        }
        let Some(encoding) = Encoding::of(channel) else {
            // A topic whose fields are read by path: first met after they were added.
            if let Some(k) = self
                .topic_by_name
                .get(&channel.topic)
                .copied()
                .filter(|&k| self.topics[k].encoding == Encoding::Field)
            {
                self.slots[id] = Slot::Topic(k);
                return Ok(Resolved::Topic(k));
            }
            let k = self.ignore(channel);
            self.slots[id] = Slot::Ignored(k);
            return Ok(Resolved::Ignored(k));
        };
        match self.topic_by_name.get(&channel.topic).copied() {
            Some(k) if self.topics[k].encoding == encoding => {
                self.slots[id] = Slot::Topic(k);
                Ok(Resolved::Topic(k))
            }
            Some(_) => Err(format!(
                "topic `{}` carries both JointState and JSON messages; calib cannot tell which \
                 to read: re-record or filter the topic to one message type",
                channel.topic
            )),
            None => Ok(Resolved::NewTopic(encoding)),
        }
    }

    /// Learns from a message of the peek pass: a new topic's channels from its first message,
    /// the joints a later message adds; what the message resolved to. A bad later message is
    /// left for the reading to report, at the same message.
    pub(crate) fn learn(
        &mut self,
        message: &mcap::Message,
        scale: f64,
    ) -> Result<Resolved, String> {
        let resolved = self.resolve(&message.channel)?;
        match resolved {
            Resolved::NewTopic(encoding) => {
                self.add_topic(first_message(message, encoding, scale)?);
                // Resolve again to record the channel ID's slot.
                self.resolve(&message.channel)?;
            }
            Resolved::Topic(k) => {
                let _ = self.topics[k].learn(message);
            }
            Resolved::Ignored(_) => {}
        }
        Ok(resolved)
    }

    /// Adds a topic read (from its first message).
    pub(crate) fn add_topic(&mut self, topic: Topic) {
        self.topic_by_name
            .insert(topic.name.clone(), self.topics.len());
        self.topics.push(topic);
    }

    /// Takes the message definition of skipped topic `k` from `channel` as the data section
    /// holds it, once: the summary's copy, which the summary's CRC may not cover, is replaced by
    /// the one the messages were written with.
    pub(crate) fn adopt_definition(&mut self, k: usize, channel: &mcap::Channel) {
        if self.from_data[k] {
            return;
        }
        self.from_data[k] = true;
        self.definitions[k] = channel
            .schema
            .as_ref()
            .map(|s| (s.encoding.clone(), s.data.to_vec()));
    }

    /// Lists a topic calib does not read; its index in the list.
    pub(crate) fn ignore(&mut self, channel: &mcap::Channel) -> usize {
        if let Some(&k) = self.ignored_by_name.get(&channel.topic) {
            return k;
        }
        self.ignored_by_name
            .insert(channel.topic.clone(), self.ignored.len());
        self.from_data.push(false);
        self.ignored.push(IgnoredTopic {
            topic: channel.topic.clone(),
            schema: schema_name(channel),
            message_encoding: channel.message_encoding.clone(),
        });
        self.ignored_stats.push(TopicStats::default());
        self.definitions.push(
            channel
                .schema
                .as_ref()
                .map(|s| (s.encoding.clone(), s.data.to_vec())),
        );
        self.ignored.len() - 1
    }

    /// Reads the names among `wanted` of the form `TOPIC.field.path` whose `TOPIC` is a topic
    /// calib skips otherwise (see [`read_fields`](Self::read_fields)); other names are left
    /// for [`crate::naming::resolve`] to judge. The error names the topic.
    pub(crate) fn read_wanted_fields(
        &mut self,
        wanted: &[String],
        scale: f64,
    ) -> Result<(), (String, String)> {
        let mut by_topic: Vec<(&str, Vec<String>)> = Vec::new();
        for name in wanted {
            let Some((topic, path)) = name.split_once('.') else {
                continue;
            };
            if path.is_empty() || !self.ignored.iter().any(|t| t.topic == topic) {
                continue;
            }
            match by_topic.iter_mut().find(|(t, _)| *t == topic) {
                Some((_, names)) if names.contains(name) => {}
                Some((_, names)) => names.push(name.clone()),
                None => by_topic.push((topic, vec![name.clone()])),
            }
        }
        for (topic, names) in by_topic {
            self.read_fields(topic, &names, scale)
                .map_err(|m| (topic.to_string(), m))?;
        }
        Ok(())
    }

    /// Reads the numeric fields `names` (`TOPIC.field.path`, all of topic `topic`, which calib
    /// skips otherwise) through the message definition the file carries for it: the topic moves
    /// from the skipped ones to those read. The error says why the topic or a path cannot be
    /// read.
    fn read_fields(&mut self, topic: &str, names: &[String], scale: f64) -> Result<(), String> {
        let Some(k) = self.ignored.iter().position(|t| t.topic == topic) else {
            return Err("the file has no such topic".into());
        };
        let skipped = &self.ignored[k];
        let text = match &self.definitions[k] {
            Some((encoding, text))
                if encoding == "ros2msg" && skipped.message_encoding == "cdr" =>
            {
                text
            }
            other => {
                return Err(format!(
                    "its messages are `{}` with a schema of encoding `{}`; calib reads fields \
                     by path only from CDR messages whose file carries their `ros2msg` message \
                     definition (as rosbag2 writes MCAP)",
                    skipped.message_encoding,
                    other.as_ref().map_or("none", |(e, _)| e.as_str())
                ));
            }
        };
        let text = std::str::from_utf8(text)
            .map_err(|_| "its message definition is not UTF-8 text".to_string())?;
        let definition = Definition::parse(&skipped.schema, text).map_err(|e| {
            format!(
                "its message definition ({}) does not parse: {e}; the recording's schema \
                 record is damaged or not a ros2msg text",
                skipped.schema
            )
        })?;
        let paths: Vec<String> = names
            .iter()
            .map(|n| n[topic.len() + 1..].to_string())
            .collect();
        let plan = definition.plan(&paths)?;
        let skipped = self.ignored.remove(k);
        self.ignored_stats.remove(k);
        self.definitions.remove(k);
        self.from_data.remove(k);
        self.ignored_by_name.remove(&skipped.topic);
        for j in self.ignored_by_name.values_mut() {
            if *j > k {
                *j -= 1;
            }
        }
        let new = self.topics.len();
        for slot in &mut self.slots {
            match *slot {
                Slot::Ignored(j) if j == k => *slot = Slot::Topic(new),
                Slot::Ignored(j) if j > k => *slot = Slot::Ignored(j - 1),
                _ => {}
            }
        }
        let mut topic = Topic::new(
            skipped.topic,
            skipped.schema,
            skipped.message_encoding,
            Encoding::Field,
            scale,
        );
        topic.names = names.to_vec();
        topic.plan = Some(Box::new(plan));
        self.add_topic(topic);
        Ok(())
    }
}

/// The error for a file with more than [`MAX_TOPICS`](crate::limits::MAX_TOPICS) topics.
pub(crate) fn too_many_topics() -> String {
    format!(
        "the file has more than {} topics, more than calib reads; record the encoders' topics \
         alone, or filter the file (`mcap filter`, `ros2 bag convert`)",
        crate::limits::MAX_TOPICS
    )
}
