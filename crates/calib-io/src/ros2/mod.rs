//! The ROS 2 layer both log readers share: the MCAP reader (an MCAP file's chunks and records)
//! and the bag reader (a rosbag2 bag's SQLite rows) each turn their bytes into
//! [`mcap::Message`]s — a bag row becomes a message on a channel standing for its topic — and
//! hand them here, so that both accept the same topics, name and lay out the same channels,
//! decode the same messages and align them the same way.
//!
//! - [`encoding`]: which messages calib reads, from their encoding and type name.
//! - [`topic`]: a topic's channels, learnt from its first messages.
//! - [`registry`]: the topics read and skipped, by channel ID.
//! - [`decode`]: a message's readings and stamp.
//! - [`samples`]: the channels laid out and selected, and messages turned into samples.

pub(crate) mod decode;
pub(crate) mod encoding;
pub(crate) mod registry;
pub(crate) mod samples;
pub(crate) mod topic;

/// Messages the peek pass reads on after every topic has shown itself, gathering the joints of
/// topics whose messages carry subsets of them: several hundred messages of each of a few
/// publishers.
pub const PEEK_WINDOW: u64 = 4096;
