//! The floor every MCAP reader is measured against: the `mcap` crate's `MessageStream` over the
//! memory-mapped file, one thread, plus the least decode of each ROS 2 JointState that yields its
//! positions (CDR, either byte order). Nothing is kept: the positions are summed so that the
//! work cannot be optimised away.
//!
//! ```text
//! cargo run --release -p calib-io --example mcap_floor -- run.mcap
//! cargo run --release -p calib-io --example mcap_floor -- run.mcap --write copy.mcap
//! ```
//!
//! With `--write OUT`, the floor of a rewriter (`calib apply`): beside the same read and decode,
//! every message is written unchanged into a new MCAP through the crate's `Writer`, the plain
//! way — the input's profile and chunk compression (zstd where the summary names none), the
//! default chunk size and compression level, one thread (`compression_threads(0)`: zstd compresses
//! on the calling thread). Each channel and its schema are added once, when its first message
//! comes, and the messages go through `write_to_known_channel`, which skips the per-message
//! lookup of the channel's content that `Writer::write` makes. Only messages are copied (a
//! `MessageStream` yields nothing else); the summary and indexes are the writer's.
//!
//! It prints the number of messages and positions read. `benches/end-to-end.sh` times it beside
//! calib's commands on the same file.

use std::collections::HashSet;
use std::io::BufWriter;
use std::process::ExitCode;

#[path = "floor/positions.rs"]
mod positions;
use positions::positions;

/// The writer of the copy: the input's profile and chunk compression, everything else default,
/// zstd on the calling thread.
fn writer(
    map: &[u8],
    out: &std::path::Path,
) -> Result<mcap::Writer<BufWriter<std::fs::File>>, Box<dyn std::error::Error>> {
    let mut profile = String::new();
    if let Some(Ok(mcap::records::Record::Header(header))) =
        mcap::read::LinearReader::new(map)?.next()
    {
        profile = header.profile;
    }
    let compression = match mcap::Summary::read(map)?
        .and_then(|s| s.chunk_indexes.first().map(|c| c.compression.clone()))
        .as_deref()
    {
        Some("") => None,
        Some("lz4") => Some(mcap::Compression::Lz4),
        _ => Some(mcap::Compression::Zstd),
    };
    let file = BufWriter::new(std::fs::File::create(out)?);
    Ok(mcap::WriteOptions::new()
        .profile(profile)
        .compression(compression)
        .compression_threads(0)
        .create(file)?)
}

fn main() -> ExitCode {
    let mut args = std::env::args_os().skip(1);
    let (Some(path), out) = (args.next(), args.next()) else {
        eprintln!("usage: mcap_floor FILE.mcap [--write OUT.mcap]");
        return ExitCode::from(2);
    };
    let out = match (out, args.next()) {
        (None, _) => None,
        (Some(flag), Some(out)) if flag == "--write" => Some(std::path::PathBuf::from(out)),
        _ => {
            eprintln!("usage: mcap_floor FILE.mcap [--write OUT.mcap]");
            return ExitCode::from(2);
        }
    };
    let run = || -> Result<(usize, usize, f64), Box<dyn std::error::Error>> {
        let file = std::fs::File::open(&path)?;
        // SAFETY: the file is only read, and a benchmark's input is not modified while it runs.
        let map = unsafe { memmap2::Mmap::map(&file) }?;
        let mut copy = out.as_deref().map(|out| writer(&map, out)).transpose()?;
        let mut added = HashSet::new();
        let (mut messages, mut values, mut sum) = (0, 0, 0.0);
        for message in mcap::MessageStream::new(&map)? {
            let message = message?;
            messages += 1;
            values += positions(&message.data, &mut sum).unwrap_or(0);
            if let Some(w) = copy.as_mut() {
                let channel = &message.channel;
                if added.insert(channel.id) {
                    let schema = match &channel.schema {
                        Some(s) => w.add_schema(&s.name, &s.encoding, &s.data)?,
                        None => 0,
                    };
                    w.add_channel_with_id(
                        channel.id,
                        schema,
                        &channel.topic,
                        &channel.message_encoding,
                        &channel.metadata,
                    )?;
                }
                let header = mcap::records::MessageHeader {
                    channel_id: channel.id,
                    sequence: message.sequence,
                    log_time: message.log_time,
                    publish_time: message.publish_time,
                };
                w.write_to_known_channel(&header, &message.data)?;
            }
        }
        if let Some(mut w) = copy {
            w.finish()?;
        }
        Ok((messages, values, sum))
    };
    match run() {
        Ok((messages, values, sum)) => {
            println!("{messages} messages, {values} positions (sum {sum:.6e})");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("mcap_floor: {}: {e}", std::path::Path::new(&path).display());
            ExitCode::from(1)
        }
    }
}
