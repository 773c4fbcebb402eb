//! Recordings written by hand as ROS tools write them, for the tests of reading them
//! (`rosbag_cli`, `recordings_cli`): the scenarios' samples, CDR messages, MCAP files of any
//! schema, and the comparison of the maps two logs of the same run give.
//!
//! Declared by the tests that use all of it: `#[path = "common/ros.rs"] mod ros;`.

use crate::common::{read_table, testdata};
use calib_core::Sample;
use calib_core::simulate::Scenario;
use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

/// The scenario `testdata/scenarios/NAME`.
pub fn load_scenario(name: &str) -> Scenario {
    let text = std::fs::read_to_string(testdata(&format!("scenarios/{name}"))).unwrap();
    toml::from_str(&text).unwrap()
}

/// The samples of the scenario `testdata/scenarios/NAME`.
pub fn scenario_samples(name: &str) -> Vec<Sample> {
    load_scenario(name).samples().unwrap().collect()
}

/// A stamp in nanoseconds as `McapWriter` rounds it: whole seconds, then the fraction to the
/// nanosecond.
pub fn ns(t: f64) -> u64 {
    let sec = t.floor();
    sec as u64 * 1_000_000_000 + ((t - sec) * 1e9).round() as u64
}

/// A message in little-endian CDR as `rmw` serializes it: the encapsulation header, then each
/// field aligned to its size, counted from the end of the header.
pub struct Cdr(Vec<u8>);

impl Cdr {
    /// An empty message: the encapsulation header alone.
    pub fn message() -> Self {
        Self(vec![0, 1, 0, 0])
    }

    /// Pads with zeros to a multiple of `n` bytes after the header.
    fn align(&mut self, n: usize) -> &mut Self {
        while (self.0.len() - 4) % n != 0 {
            self.0.push(0);
        }
        self
    }

    /// A primitive of `N` bytes, given as its little-endian bytes, aligned to its size.
    pub fn primitive<const N: usize>(&mut self, le_bytes: [u8; N]) -> &mut Self {
        self.align(N).0.extend_from_slice(&le_bytes);
        self
    }

    pub fn u32(&mut self, v: u32) -> &mut Self {
        self.primitive(v.to_le_bytes())
    }

    pub fn f64(&mut self, v: f64) -> &mut Self {
        self.primitive(v.to_le_bytes())
    }

    /// A string: its length with the NUL, the bytes, the NUL.
    pub fn string(&mut self, s: &str) -> &mut Self {
        self.u32(s.len() as u32 + 1);
        self.0.extend_from_slice(s.as_bytes());
        self.0.push(0);
        self
    }

    /// A `builtin_interfaces/Time`: `int32 sec`, `uint32 nanosec`.
    pub fn stamp(&mut self, stamp_ns: u64) -> &mut Self {
        self.primitive(((stamp_ns / 1_000_000_000) as i32).to_le_bytes())
            .u32((stamp_ns % 1_000_000_000) as u32)
    }

    pub fn bytes(&self) -> Vec<u8> {
        self.0.clone()
    }
}

/// An MCAP file written record by record through the `mcap` crate, with one schema and any
/// channels of it: the files ROS tools write, which `McapWriter` (JointState only) cannot.
pub struct RawMcap {
    writer: mcap::Writer<BufWriter<File>>,
    schema: u16,
}

impl RawMcap {
    /// A new file at `path` with the schema `name` in `encoding` (`ros2msg`, `ros1msg`).
    pub fn create(path: &Path, name: &str, encoding: &str, definition: &[u8]) -> Self {
        let file = BufWriter::new(File::create(path).unwrap());
        let mut writer = mcap::Writer::new(file).unwrap();
        let schema = writer.add_schema(name, encoding, definition).unwrap();
        Self { writer, schema }
    }

    /// A channel of the schema on `topic`, its messages in `encoding` (`cdr`, `ros1`); its id.
    pub fn channel(&mut self, topic: &str, encoding: &str) -> u16 {
        self.writer
            .add_channel(self.schema, topic, encoding, &Default::default())
            .unwrap()
    }

    /// One message on `channel`, published when it was logged.
    pub fn write(&mut self, channel: u16, sequence: u32, log_time: u64, data: &[u8]) {
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence,
            log_time,
            publish_time: log_time,
        };
        self.writer.write_to_known_channel(&header, data).unwrap();
    }

    pub fn finish(mut self) {
        self.writer.finish().unwrap();
    }
}

/// The largest |difference| of the error column between two tables on the same grid, arcsec;
/// asserts the grids are the same.
pub fn table_difference(want: &Path, got: &Path) -> f64 {
    let (w, g) = (read_table(want), read_table(got));
    assert_eq!(w.len(), g.len(), "{}", got.display());
    w.iter()
        .zip(&g)
        .map(|(w, g)| {
            assert_eq!(w.0, g.0, "{}: grid", got.display());
            (w.1 - g.1).abs()
        })
        .fold(0.0, f64::max)
}
