//! The floor every MCAP reader is measured against: the `mcap` crate's `MessageStream` over the
//! memory-mapped file, one thread, plus the least decode of each ROS 2 JointState that yields its
//! positions (CDR, either byte order). Nothing is kept: the positions are summed so that the
//! work cannot be optimised away.
//!
//! ```text
//! cargo run --release -p calib-io --example mcap_floor -- run.mcap
//! ```
//!
//! It prints the number of messages and positions read. `benches/end-to-end.sh` times it beside
//! calib's commands on the same file.

use std::process::ExitCode;

/// The positions of a CDR-encoded `sensor_msgs/msg/JointState`, added to `sum`; `None` where the
/// message is not one.
fn positions(data: &[u8], sum: &mut f64) -> Option<usize> {
    let little = match data.get(..2)? {
        [0, 1] => true,
        [0, 0] => false,
        _ => return None,
    };
    let body = &data[4..];
    let u32_at = |at: usize| -> Option<u32> {
        let b: [u8; 4] = body.get(at..at + 4)?.try_into().ok()?;
        Some(if little {
            u32::from_le_bytes(b)
        } else {
            u32::from_be_bytes(b)
        })
    };
    let align = |at: usize, to: usize| at.div_ceil(to) * to;
    // header.stamp (sec, nanosec), then header.frame_id.
    let mut at = 8;
    at += 4 + u32_at(at)? as usize;
    // name: string[]
    at = align(at, 4);
    let names = u32_at(at)? as usize;
    at += 4;
    for _ in 0..names {
        at = align(at, 4);
        at += 4 + u32_at(at)? as usize;
    }
    // position: float64[]
    at = align(at, 4);
    let count = u32_at(at)? as usize;
    at = align(at + 4, 8);
    for k in 0..count {
        let b: [u8; 8] = body.get(at + 8 * k..at + 8 * k + 8)?.try_into().ok()?;
        *sum += if little {
            f64::from_le_bytes(b)
        } else {
            f64::from_be_bytes(b)
        };
    }
    Some(count)
}

fn main() -> ExitCode {
    let Some(path) = std::env::args_os().nth(1) else {
        eprintln!("usage: mcap_floor FILE.mcap");
        return ExitCode::from(2);
    };
    let run = || -> Result<(usize, usize, f64), Box<dyn std::error::Error>> {
        let file = std::fs::File::open(&path)?;
        // SAFETY: the file is only read, and a benchmark's input is not modified while it runs.
        let map = unsafe { memmap2::Mmap::map(&file) }?;
        let (mut messages, mut values, mut sum) = (0, 0, 0.0);
        for message in mcap::MessageStream::new(&map)? {
            let message = message?;
            messages += 1;
            values += positions(&message.data, &mut sum).unwrap_or(0);
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
