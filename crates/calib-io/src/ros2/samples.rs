//! [`Samples`]: a log's messages turned into samples — where each topic's channels sit in a
//! sample, which of them are selected, the clock's stamp order, and the aligner or the fast
//! path that bypasses it. The MCAP and the bag reader each hold one and hand it their messages;
//! only how messages come out of their files differs between them.

use calib_core::{AngleUnit, Channel, Sample, SampleBatch};

use super::decode::{decode, seconds};
use super::encoding::Encoding;
use super::registry::{IgnoredTopic, Registry, Resolved, TopicInfo};
use super::topic::Topic;
use crate::align::{AlignOptions, Aligner, Alignment};
use crate::naming::{ChannelName, names_of};
use crate::stamps::{Backward, StampOrder, Step};
use crate::{Error, ReadDiagnostics, ReadOptions, TimeSource};

/// The channels of a log's topics, the selection among them, and the samples in progress.
pub(crate) struct Samples {
    /// The topics read and skipped.
    registry: Registry,
    /// Every channel of the log, in raw order (topics, then joints).
    all_channels: Vec<Channel>,
    names: Vec<ChannelName>,
    /// The selected channels, in the order of each sample's values.
    channels: Vec<Channel>,
    time: TimeSource,
    aligner: Aligner,
    /// One topic whose messages carry every joint, each channel selected at most once: every
    /// message is a sample (its selected joints, exact on the same stamp), and the aligner is
    /// bypassed — so that stamps out of order reach `calib inspect` to be counted.
    fast: bool,
    /// Where the fast path's values come from: `None` for every channel in order, else the
    /// selected raw channels.
    pick: Option<Vec<usize>>,
    /// Samples emitted by the fast path (every channel exact).
    fast_samples: u64,
    /// One reading per raw channel of the current message, NaN where it carries none.
    raw: Vec<f64>,
    /// The raw index of the clock channel (the first selected).
    clock: usize,
    /// Each topic's stamps so far, by topic index (see [`crate::stamps`]): its exact
    /// duplicates are dropped, and a conflict or a step back of the clock's refused.
    orders: Vec<StampOrder>,
    /// The stamp, ns, from which samples are timed, set by the first message's (see
    /// [`Samples::time_origin_s`]).
    origin_ns: Option<i64>,
    /// Pass on clock stamps that do not increase (`calib inspect` counts them).
    allow_unordered_time: bool,
    /// What the number a message is known by is called in an error about stamp order: the
    /// message's index in an MCAP file, its row id in a bag.
    key_name: &'static str,
    /// What the reader noticed so far (the MCAP reader's truncation and damaged chunks).
    pub(crate) diagnostics: ReadDiagnostics,
}

/// A reader of an MCAP file or a bag, as [`crate::LogReader`] holds either: its samples, and the
/// layer it hands its messages to for the rest. `Send`: commands decode on a second thread.
pub(crate) trait Ros2Reader: Send {
    /// The channels, the selection and what was noticed.
    fn samples(&self) -> &Samples;
    /// The same, to select channels.
    fn samples_mut(&mut self) -> &mut Samples;
    /// Appends samples to `out` until it holds `max` or the log ends (a few more where the
    /// aligner completes several at once); after an error, which ends the log, nothing.
    fn fill(&mut self, out: &mut SampleBatch, max: usize) -> Result<(), Error>;
    /// How far the reader has got through its file (a SQLite bag: its messages).
    fn progress(&self) -> crate::progress::ReadProgress;
}

/// Why a message could not be read; each reader says where it is.
pub(crate) enum Failure {
    /// The message's topic was not met when the log was opened.
    NewTopic,
    /// What is wrong, and the joint or field concerned if not the whole message.
    Message {
        joint: Option<String>,
        message: String,
    },
}

impl Failure {
    fn message(message: String) -> Self {
        Failure::Message {
            joint: None,
            message,
        }
    }
}

impl Samples {
    /// Lays out the channels of the topics `registry` learnt, every one selected; `key_name`
    /// is what the reader's errors call a message's number.
    pub(crate) fn new(mut registry: Registry, opts: &ReadOptions, key_name: &'static str) -> Self {
        let (names, all_channels) = lay_out_channels(&mut registry, opts);
        let width = all_channels.len();
        let mut samples = Samples {
            registry,
            all_channels,
            names,
            channels: Vec::new(),
            time: opts.time,
            aligner: Aligner::new(vec![0], AlignOptions::default()),
            fast: false,
            pick: None,
            fast_samples: 0,
            raw: vec![f64::NAN; width],
            clock: 0,
            orders: Vec::new(),
            origin_ns: None,
            allow_unordered_time: opts.allow_unordered_time,
            key_name,
            diagnostics: ReadDiagnostics::default(),
        };
        let all: Vec<usize> = (0..width).collect();
        samples.select(&all, AlignOptions::default());
        samples
    }

    /// The selected channels, in the order of each sample's values.
    pub(crate) fn channels(&self) -> &[Channel] {
        &self.channels
    }

    /// Every channel's name, in raw order.
    pub(crate) fn names(&self) -> &[ChannelName] {
        &self.names
    }

    /// Reads only `channels` (raw indices), in this order, aligned on the first one's stamps.
    pub(crate) fn select(&mut self, channels: &[usize], opts: AlignOptions) {
        let width = self.all_channels.len();
        let distinct = channels
            .iter()
            .enumerate()
            .all(|(k, c)| *c < width && !channels[..k].contains(c));
        self.fast = self.registry.topics.len() == 1 && !self.registry.topics[0].subset && distinct;
        self.pick = (!channels.iter().copied().eq(0..width)).then(|| channels.to_vec());
        self.aligner = Aligner::new(channels.to_vec(), opts);
        self.clock = channels.first().copied().unwrap_or(0);
        self.channels = channels
            .iter()
            .map(|&i| self.all_channels[i].clone())
            .collect();
    }

    /// How the selected channels were aligned on the first one's clock, the fast path's samples
    /// counted as exact.
    pub(crate) fn alignment(&self) -> Alignment {
        let names: Vec<String> = self.names.iter().map(|n| n.display.clone()).collect();
        let mut alignment = self.aligner.report(&names);
        alignment.clock_samples += self.fast_samples;
        alignment.samples += self.fast_samples;
        for c in &mut alignment.channels {
            c.exact += self.fast_samples;
        }
        alignment
    }

    /// The stamp, seconds on the log's clock, from which the samples' times are counted: the
    /// whole second of the first message's stamp where it is beyond
    /// [`ORIGIN_FROM_S`](crate::stamps::ORIGIN_FROM_S), else 0 (and 0 until a message is read).
    /// Stamps since 1970 (~1.7·10⁹ s) as doubles are 2.4·10⁻⁷ s apart, which a fast coast
    /// feels (`calib tdr` at 600 r/min: 0.8″ of residual where the same run timed from 0 leaves
    /// 0.06″); counted from this origin they keep every nanosecond.
    pub(crate) fn time_origin_s(&self) -> f64 {
        self.origin_ns.map_or(0.0, seconds)
    }

    /// A message's stamp as a sample's time: seconds since [`Samples::time_origin_s`], which the
    /// first stamp sets.
    fn time_of(&mut self, stamp: i64) -> f64 {
        const NS: i64 = 1_000_000_000;
        let origin = *self.origin_ns.get_or_insert_with(|| {
            if stamp.div_euclid(NS).abs() >= crate::stamps::ORIGIN_FROM_S {
                stamp.div_euclid(NS) * NS
            } else {
                0
            }
        });
        seconds(stamp.saturating_sub(origin))
    }

    /// Every topic: those read with their channels, then those skipped.
    pub(crate) fn topics(&self) -> Vec<TopicInfo> {
        self.registry.topic_infos(&self.names)
    }

    /// Topics skipped because calib does not read their type, in the order met.
    pub(crate) fn ignored_topics(&self) -> &[IgnoredTopic] {
        &self.registry.ignored
    }

    /// The log has ended: what the aligner holds is decided and appended to `out`.
    pub(crate) fn finish(&mut self, out: &mut SampleBatch) {
        self.aligner.finish();
        self.drain(out);
    }

    /// Appends the samples the aligner has completed to `out` (the fast path leaves none).
    fn drain(&mut self, out: &mut SampleBatch) {
        while let Some(s) = self.aligner.pop() {
            out.push(s.t, &s.values, s.session);
        }
    }

    /// Decodes one message, known to the reader's errors by `key`, and appends to `out` the
    /// samples it completes (one on the fast path, none or several through the aligner).
    pub(crate) fn step(
        &mut self,
        message: &mcap::Message,
        key: i64,
        out: &mut SampleBatch,
    ) -> Result<(), Failure> {
        let k = match self.registry.resolve(&message.channel) {
            Ok(Resolved::Topic(k)) => k,
            Ok(Resolved::Ignored(k)) => {
                self.registry.ignored_stats[k].note(message.log_time);
                return Ok(());
            }
            Ok(Resolved::NewTopic(_)) => return Err(Failure::NewTopic),
            Err(m) => return Err(Failure::message(m)),
        };
        let topic = &mut self.registry.topics[k];
        topic.stats.note(message.log_time);
        let failed = |(joint, message)| Failure::Message { joint, message };
        if self.fast {
            // Every joint into the scratch row, then the selected ones (or all, in order) into
            // the batch.
            self.raw.fill(f64::NAN);
            let (stamp, full) = decode(topic, message, self.time, &mut self.raw).map_err(failed)?;
            if self.check_stamp(k, stamp, key, 0)? == Step::Duplicate {
                return Ok(());
            }
            let t = self.time_of(stamp);
            if full {
                self.fast_samples += 1;
                match &self.pick {
                    Some(pick) => out.push_picked(t, &self.raw, pick, None),
                    None => out.push(t, &self.raw, None),
                }
                return Ok(());
            }
            // A message with a subset of the joints: from here on, through the aligner (which
            // is empty, so the order of samples is kept), which takes the whole row.
            self.fast = false;
            self.aligner.push(stamp, t, &self.raw, None);
            self.drain(out);
            return Ok(());
        }
        let range = topic.offset..topic.offset + topic.names.len();
        self.raw.fill(f64::NAN);
        let offset = range.start;
        let (stamp, _) = decode(topic, message, self.time, &mut self.raw[range]).map_err(failed)?;
        if self.check_stamp(k, stamp, key, offset)? == Step::Duplicate {
            return Ok(());
        }
        let t = self.time_of(stamp);
        self.aligner.push(stamp, t, &self.raw, None);
        self.drain(out);
        Ok(())
    }

    /// Checks the stamp of a message of topic `k`, known by `key`, whose readings were decoded
    /// into `self.raw` from `offset` on (see [`crate::stamps`]): an exact duplicate of the topic's previous message is counted and to
    /// be dropped; a conflict or a step back is refused where the message carries the clock
    /// channel, unless told to pass it on, and otherwise passed on (the aligner leaves out a
    /// channel's samples out of order and counts them).
    fn check_stamp(
        &mut self,
        k: usize,
        stamp: i64,
        key: i64,
        offset: usize,
    ) -> Result<Step, Failure> {
        if self.orders.len() <= k {
            self.orders.resize_with(k + 1, StampOrder::default);
        }
        let width = self.registry.topics[k].names.len();
        let values = &self.raw[offset..offset + width];
        match self.orders[k].check(stamp, key, values) {
            Ok(Step::Duplicate) => {
                self.diagnostics.duplicates_dropped =
                    self.orders.iter().map(StampOrder::duplicates).sum();
                Ok(Step::Duplicate)
            }
            Ok(Step::New) => Ok(Step::New),
            Err(_) if self.allow_unordered_time || self.raw[self.clock].is_nan() => Ok(Step::New),
            Err(b) => Err(Failure::message(self.describe(&b, offset))),
        }
    }

    /// The error of a clock stamp that repeats with other readings or goes back; `offset`: where
    /// the values `b` compares start among the raw channels.
    fn describe(&self, b: &Backward, offset: usize) -> String {
        b.describe(
            &self.names[self.clock].display,
            self.key_name,
            self.time,
            |i| {
                self.names
                    .get(offset + i)
                    .map_or_else(|| (offset + i).to_string(), |n| n.display.clone())
            },
            crate::limits::readable,
        )
    }
}

/// Places each topic's joints in a sample's values, one after the other in the order the
/// topics were found, and names them; returns the names and the channels with their units.
fn lay_out_channels(
    registry: &mut Registry,
    opts: &ReadOptions,
) -> (Vec<ChannelName>, Vec<Channel>) {
    let mut offset = 0;
    for topic in &mut registry.topics {
        topic.offset = offset;
        offset += topic.names.len();
    }
    let names = names_of(registry.topics.iter().flat_map(Topic::channel_names));
    let mut all_channels: Vec<Channel> = Vec::with_capacity(names.len());
    for topic in &registry.topics {
        let unit = match topic.encoding {
            Encoding::JointState(_) => AngleUnit::Rad,
            Encoding::Json | Encoding::Scalar(_) | Encoding::Field => {
                opts.unit.unwrap_or(AngleUnit::Deg)
            }
        };
        for _ in &topic.names {
            all_channels.push(Channel {
                name: names[all_channels.len()].display.clone(),
                unit,
            });
        }
    }
    (names, all_channels)
}

/// Samples handed on one at a time from a reader that fills batches: the readers' [`Iterator`].
#[derive(Default)]
pub(crate) struct OneByOne {
    batch: SampleBatch,
    next: usize,
    /// The error that ended the log, once the samples before it are handed on.
    error: Option<Error>,
}

impl OneByOne {
    /// The next sample, reading another batch of `width` readings with `fill` when none is left.
    pub(crate) fn next(
        &mut self,
        width: usize,
        fill: impl FnOnce(&mut SampleBatch) -> Result<(), Error>,
    ) -> Option<Result<Sample, Error>> {
        if self.next == self.batch.len() {
            if let Some(e) = self.error.take() {
                return Some(Err(e));
            }
            if self.batch.width() != width {
                self.batch = SampleBatch::new(width);
            }
            self.batch.clear();
            self.next = 0;
            self.error = fill(&mut self.batch).err();
            if self.batch.is_empty() {
                return self.error.take().map(Err);
            }
        }
        let sample = self.batch.get(self.next).to_sample();
        self.next += 1;
        Some(Ok(sample))
    }
}
