//! MCAP logs: every record copied through the `mcap` crate's writer, the channel's messages
//! rewritten in place.
//!
//! The input is read front to back by the crate's sans-io [`LinearReader`] through a buffered
//! file: chunks are decompressed one at a time and their records handed over one by one, so
//! memory is bounded by the largest chunk. Records of the summary section (which repeats
//! schemas and channels, and indexes the data) are not copied: the writer writes a new summary
//! for the new chunks.

use super::Range;
use crate::atomic::AtomicFile;
use crate::mcap_log::cdr::{JointFormat, JointState};
use crate::mcap_log::json::field_spans;
use crate::mcap_log::read::{Encoding, read_summary};
use crate::mcap_log::records::{Checked, StreamError};
use crate::{DamagedChunk, Error, Truncation};
use calib_core::AngleUnit;
use calib_core::correction::Correction;
use mcap::records::{Header, Record};
use mcap::sans_io::LinearReaderOptions;
use mcap::{Compression, McapError, WriteOptions, Writer};
use std::borrow::Cow;
use std::collections::HashMap;
use std::fs::File;
use std::io::BufReader;
use std::ops::Range as Span;
use std::path::Path;

/// Where a message holds the channel's readings, and their values.
enum Hit<'d> {
    /// Position `index` of a JointState message, radians.
    Joint {
        message: JointState<'d>,
        index: usize,
        value: f64,
    },
    /// The spans of the field's numbers in a JSON message (a key may repeat), in the JSON unit.
    Json { fields: Vec<(Span<usize>, f64)> },
}

/// A channel record's topic and, if calib reads its messages, how.
struct Topic {
    name: String,
    encoding: Option<Encoding>,
}

fn mcap_error(path: &Path, index: Option<u64>, channel: Option<&str>, message: String) -> Error {
    Error::Mcap {
        path: path.to_path_buf(),
        message_index: index,
        channel: channel.map(str::to_string),
        message,
    }
}

/// One pass over the log's records in file order, each chunk's records after its CRC matched
/// (see the `records` module). `each(record, index, hit)` gets every record; for a message,
/// `index` is its 0-based position among the messages and `hit` says where it holds the
/// channel's readings, if it does. Returns where the file breaks off, if it does, and the damaged
/// chunks left out (with `skip_damaged`; otherwise the first is an error).
fn walk(
    path: &Path,
    channel: &str,
    skip_damaged: bool,
    mut each: impl FnMut(&Record, u64, Option<Hit>) -> Result<(), Error>,
) -> Result<(Option<Truncation>, Vec<DamagedChunk>), Error> {
    let io = |source| Error::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = File::open(path).map_err(io)?;
    let len = file.metadata().map_err(io)?.len();
    let file = BufReader::with_capacity(256 * 1024, file);
    let mut records = Checked::new(
        file,
        // No record can be longer than the file; a corrupt length must not drive an allocation.
        LinearReaderOptions::default()
            .with_record_length_limit(usize::try_from(len).unwrap_or(usize::MAX)),
        skip_damaged,
    );
    let mut schemas: HashMap<u16, String> = HashMap::new();
    let mut topics: HashMap<u16, Topic> = HashMap::new();
    // The topic carrying the channel, once met: a name on two topics is ambiguous.
    let mut carrier: Option<String> = None;
    let mut messages = 0u64;
    while let Some(next) = records.next_record() {
        let (opcode, data) = match next {
            Ok(record) => record,
            Err(StreamError::Mcap(McapError::UnexpectedEof)) => {
                return Ok((
                    Some(Truncation {
                        byte_offset: records.consumed,
                        messages_read: messages,
                    }),
                    records.damaged,
                ));
            }
            Err(StreamError::Mcap(McapError::Io(source))) => return Err(io(source)),
            Err(e @ (StreamError::Damaged(_) | StreamError::DataCrc)) => {
                return Err(mcap_error(
                    path,
                    Some(messages),
                    None,
                    format!(
                        "{e}; nothing was written: run with --skip-damaged to leave the damaged \
                         chunk's messages out of the output, or repair the file"
                    ),
                ));
            }
            Err(e) => {
                return Err(mcap_error(
                    path,
                    Some(messages),
                    None,
                    format!(
                        "the file is damaged here ({e}); repair it with `mcap recover` and apply \
                         to the repaired file"
                    ),
                ));
            }
        };
        let data = data.as_slice();
        let record = mcap::parse_record(opcode, data).map_err(|e| {
            mcap_error(
                path,
                Some(messages),
                None,
                format!("a record cannot be parsed ({e}); repair the file with `mcap recover`"),
            )
        })?;
        let mut hit = None;
        match &record {
            Record::Schema { header, .. } => {
                schemas.insert(header.id, header.name.clone());
            }
            Record::Channel(c) => {
                let schema = schemas.get(&c.schema_id).map_or("", String::as_str);
                topics.insert(
                    c.id,
                    Topic {
                        name: c.topic.clone(),
                        encoding: Encoding::from_names(&c.message_encoding, schema),
                    },
                );
            }
            Record::Message { header, data } => {
                let topic = topics.get(&header.channel_id).ok_or_else(|| {
                    mcap_error(
                        path,
                        Some(messages),
                        None,
                        format!(
                            "the message's channel ID {} has no channel record before it; \
                             repair the file with `mcap recover`",
                            header.channel_id
                        ),
                    )
                })?;
                if matches!(topic.encoding, Some(Encoding::Scalar(_))) && topic.name == channel {
                    return Err(mcap_error(
                        path,
                        Some(messages),
                        Some(&topic.name),
                        "calib apply corrects JointState and JSON channels, not std_msgs \
                         scalar topics; correct the readings where they are published"
                            .into(),
                    ));
                }
                // A qualified name `TOPIC/NAME` names the joint or field `NAME` of that topic
                // only; a short name, the one of any topic carrying it.
                let member = channel
                    .strip_prefix(topic.name.as_str())
                    .and_then(|rest| rest.strip_prefix('/'))
                    .unwrap_or(channel);
                hit = find(topic.encoding, data, member)
                    .map_err(|m| mcap_error(path, Some(messages), Some(&topic.name), m))?;
                if hit.is_some() {
                    match &carrier {
                        Some(other) if *other != topic.name => {
                            return Err(mcap_error(
                                path,
                                Some(messages),
                                Some(channel),
                                format!(
                                    "the channel appears on two topics (`{other}` and `{}`); \
                                     calib cannot tell which to correct: rename one of them",
                                    topic.name
                                ),
                            ));
                        }
                        Some(_) => {}
                        None => carrier = Some(topic.name.clone()),
                    }
                }
            }
            _ => {}
        }
        each(&record, messages, hit)?;
        if matches!(record, Record::Message { .. }) {
            messages += 1;
        }
    }
    Ok((None, records.damaged))
}

/// Where `data` (a message of this encoding) holds `channel`'s readings, if it does.
fn find<'d>(
    encoding: Option<Encoding>,
    data: &'d [u8],
    channel: &str,
) -> Result<Option<Hit<'d>>, String> {
    match encoding {
        // A scalar topic's channel is the topic itself, refused by the caller.
        None | Some(Encoding::Scalar(_) | Encoding::Field) => Ok(None),
        Some(Encoding::JointState(format)) => {
            let message = JointState::parse_as(data, format).map_err(|e| e.to_string())?;
            let Some(index) = message.joint(channel) else {
                return Ok(None);
            };
            if format == JointFormat::Dynamic {
                return Err(format!(
                    "joint `{channel}` is carried by DynamicJointState messages, which calib \
                     apply does not rewrite; correct a JointState or JSON channel"
                ));
            }
            let value = message.positions().nth(index).ok_or_else(|| {
                format!(
                    "the JointState message names {} joints but has {} positions, none for \
                     joint `{channel}`; the publisher must give a position for every joint",
                    message.name_count,
                    message.position_count()
                )
            })?;
            if !value.is_finite() {
                return Err(format!(
                    "the position of joint `{channel}` is {value}, not a finite number; cut the \
                     damaged part out of the recording"
                ));
            }
            Ok(Some(Hit::Joint {
                message,
                index,
                value,
            }))
        }
        Some(Encoding::Json) => {
            let spans = field_spans(data, channel)?;
            if spans.is_empty() {
                return Ok(None);
            }
            let mut fields = Vec::with_capacity(spans.len());
            for span in spans {
                let text = std::str::from_utf8(&data[span.clone()]).unwrap_or("");
                let value = text.parse::<f64>().ok().filter(|v| v.is_finite()).ok_or_else(|| {
                    format!(
                        "field `{channel}` is `{text}`, not a number; every message must give a \
                         number for the channel"
                    )
                })?;
                fields.push((span, value));
            }
            Ok(Some(Hit::Json { fields }))
        }
    }
}

/// The range of the channel's readings: radians for JointState, `json_unit` for JSON.
pub(super) fn scan(
    path: &Path,
    channel: &str,
    json_unit: AngleUnit,
    skip_damaged: bool,
) -> Result<Range, Error> {
    let mut range = Range::new(json_unit);
    walk(path, channel, skip_damaged, |_, _, hit| {
        match hit {
            Some(Hit::Joint { value, .. }) => range.add(value, AngleUnit::Rad),
            Some(Hit::Json { fields }) => {
                for (_, v) in fields {
                    range.add(v, json_unit);
                }
            }
            None => {}
        }
        Ok(())
    })?;
    Ok(range)
}

/// What [`rewrite`] did.
pub(super) struct Rewritten {
    pub readings: u64,
    pub copied: u64,
    pub truncated: Option<Truncation>,
    pub damaged: Vec<DamagedChunk>,
}

/// The writer's options for a copy of the log at `path`: its header's profile and library, and
/// the compression of its chunks as its summary lists them (zstd if it has no summary).
fn write_options(path: &Path, header: &Header) -> Result<WriteOptions, Error> {
    let mut file = File::open(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let len = file
        .metadata()
        .map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })?
        .len();
    let options = WriteOptions::new()
        .profile(header.profile.clone())
        .library(header.library.clone())
        // Single-threaded zstd: on a 2-core machine the worker threads cost more in locking per
        // message than they save (10e6 messages: 14.1 s CPU and 40 s wall against 15.0 s and
        // 46 s with the default one thread per core).
        .compression_threads(0);
    Ok(match read_summary(&mut file, len) {
        Some(summary) => match summary.chunk_indexes.first() {
            Some(chunk) => options.compression(match chunk.compression.as_str() {
                "lz4" => Some(Compression::Lz4),
                "" => None,
                _ => Some(Compression::Zstd),
            }),
            None if summary.stats.is_some_and(|s| s.message_count > 0) => options.use_chunks(false),
            None => options.compression(Some(Compression::Zstd)),
        },
        None => options.compression(Some(Compression::Zstd)),
    })
}

/// Writes `output`, a copy of `input` with the channel's readings corrected: JointState
/// positions by `joint_fix` (radians), JSON fields by `json_fix`.
pub(super) fn rewrite(
    input: &Path,
    output: &Path,
    channel: &str,
    joint_fix: &Correction,
    json_fix: &Correction,
    skip_damaged: bool,
) -> Result<Rewritten, Error> {
    let mut writer: Option<Writer<AtomicFile>> = None;
    let mut done = Rewritten {
        readings: 0,
        copied: 0,
        truncated: None,
        damaged: Vec::new(),
    };
    let mut buf: Vec<u8> = Vec::new();
    let mut number = ryu::Buffer::new();
    let fail = |index: Option<u64>, e: McapError| match e {
        McapError::Io(source) => Error::Io {
            path: output.to_path_buf(),
            source,
        },
        e => mcap_error(
            output,
            index,
            None,
            format!("cannot write the MCAP file ({e})"),
        ),
    };
    (done.truncated, done.damaged) = walk(input, channel, skip_damaged, |record, index, hit| {
        let w = match (record, writer.as_mut()) {
            (Record::Header(header), None) => {
                let options = write_options(input, header)?;
                writer = Some(
                    options
                        .create(AtomicFile::create(output)?)
                        .map_err(|e| fail(None, e))?,
                );
                return Ok(());
            }
            (_, Some(w)) => w,
            (_, None) => {
                return Err(mcap_error(
                    input,
                    None,
                    None,
                    "the file has no header record; repair it with `mcap recover`".into(),
                ));
            }
        };
        let rewritten = hit.is_some();
        let result = match record {
            Record::Schema { header, data } => w
                .add_schema_with_id(header.id, &header.name, &header.encoding, data)
                .map(drop),
            Record::Channel(c) => w
                .add_channel_with_id(
                    c.id,
                    c.schema_id,
                    &c.topic,
                    &c.message_encoding,
                    &c.metadata,
                )
                .map(drop),
            Record::Message { header, data } => match hit {
                None => w.write_to_known_channel(header, data),
                Some(Hit::Joint {
                    message,
                    index: joint,
                    value,
                }) => {
                    buf.clear();
                    buf.extend_from_slice(data);
                    message.set_position(&mut buf, joint, joint_fix.apply(value));
                    done.readings += 1;
                    w.write_to_known_channel(header, &buf)
                }
                Some(Hit::Json { fields }) => {
                    buf.clear();
                    let mut from = 0;
                    for (span, value) in &fields {
                        buf.extend_from_slice(&data[from..span.start]);
                        buf.extend_from_slice(
                            number.format_finite(json_fix.apply(*value)).as_bytes(),
                        );
                        from = span.end;
                    }
                    buf.extend_from_slice(&data[from..]);
                    done.readings += fields.len() as u64;
                    w.write_to_known_channel(header, &buf)
                }
            },
            Record::Metadata(m) => w.write_metadata(m),
            Record::Attachment { header, data, .. } => w.attach(&mcap::Attachment {
                log_time: header.log_time,
                create_time: header.create_time,
                name: header.name.clone(),
                media_type: header.media_type.clone(),
                data: Cow::Borrowed(data),
            }),
            Record::Unknown { opcode, data } => {
                w.write_private_record(*opcode, data, Default::default())
            }
            // The rest is structure (chunks, indexes, summary, footer) the writer makes anew,
            // or a second header, which the specification does not allow and which is dropped.
            _ => return Ok(()),
        };
        let is_message = matches!(record, Record::Message { .. });
        result.map_err(|e| fail(is_message.then_some(index), e))?;
        if is_message && !rewritten {
            done.copied += 1;
        }
        Ok(())
    })?;
    let Some(mut writer) = writer else {
        return Err(Error::Empty {
            path: input.to_path_buf(),
        });
    };
    writer.finish().map_err(|e| fail(None, e))?;
    writer.into_inner().commit()?;
    Ok(done)
}
