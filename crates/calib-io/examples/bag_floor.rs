//! The floor a rosbag2 SQLite bag's reading is measured against: one `rusqlite` scan of the
//! `messages` table in replay order (`ORDER BY timestamp, id`, as calib reads it, through the
//! `timestamp_idx` index rosbag2 creates), each payload borrowed from SQLite and given the least
//! decode of a ROS 2 JointState that yields its positions, one thread. Nothing is kept: the
//! positions are summed so that the work cannot be optimised away.
//!
//! ```text
//! cargo run --release -p calib-io --example bag_floor -- bag/bag_0.db3
//! ```
//!
//! It prints the number of messages and positions read. `benches/end-to-end.sh` times it beside
//! `calib inspect` and `calib csrr` on the same bag (`BAG_FLOOR`).

use std::process::ExitCode;

#[path = "floor/positions.rs"]
mod positions;
use positions::positions;

fn main() -> ExitCode {
    let mut args = std::env::args_os().skip(1);
    let (Some(path), None) = (args.next(), args.next()) else {
        eprintln!("usage: bag_floor FILE.db3");
        return ExitCode::from(2);
    };
    let run = || -> Result<(usize, usize, f64), Box<dyn std::error::Error>> {
        let db = rusqlite::Connection::open_with_flags(
            &path,
            rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY,
        )?;
        let mut statement =
            db.prepare("SELECT id, timestamp, data FROM messages ORDER BY timestamp, id")?;
        let mut rows = statement.query([])?;
        let (mut messages, mut values, mut sum) = (0, 0, 0.0);
        while let Some(row) = rows.next()? {
            let stamp: i64 = row.get(1)?;
            sum += stamp as f64 * 1e-9;
            if let rusqlite::types::ValueRef::Blob(data) = row.get_ref(2)? {
                values += positions(data, &mut sum).unwrap_or(0);
            }
            messages += 1;
        }
        Ok((messages, values, sum))
    };
    match run() {
        Ok((messages, values, sum)) => {
            println!("{messages} messages, {values} positions (sum {sum:.6e})");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("bag_floor: {}: {e}", path.to_string_lossy());
            ExitCode::from(1)
        }
    }
}
