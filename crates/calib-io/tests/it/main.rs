//! calib-io's tests: one test binary (one link) whose modules each test a reader, a writer or
//! a format. Run one module with `cargo test -p calib-io --test it table_io::`.

mod apply;
mod common;
mod controller_firmware;
mod csv_reader;
mod csv_stamps;
mod csv_writer;
mod fuzz_regressions;
mod mcap_read;
mod mcap_write;
mod read_progress;
mod reader_findings;
mod rosbag_read;
mod table_io;
