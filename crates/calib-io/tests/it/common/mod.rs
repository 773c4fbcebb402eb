//! Helpers shared by the writer tests of calib-io (`csv_writer`, `mcap_write`).

use calib_core::{AngleUnit, Channel};

/// Channels of these names, in radians.
pub fn channels(names: &[&str]) -> Vec<Channel> {
    names
        .iter()
        .map(|n| Channel {
            name: n.to_string(),
            unit: AngleUnit::Rad,
        })
        .collect()
}
