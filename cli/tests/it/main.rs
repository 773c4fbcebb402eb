//! The end-to-end tests of `calib`: one test binary (one link) whose modules each test a
//! command or a concern, sharing the helpers in `common`. Run one module with
//! `cargo test -p calib-cli --test it csrr_cli::`.

mod adversarial;
mod apply_cli;
mod batch_cli;
mod common;
mod compare_against_cli;
mod compose_cli;
mod csrr_cli;
mod export_cli;
mod gaps_cli;
mod gear_cli;
#[cfg(feature = "hdf5")]
mod hdf5_cli;
mod import_cli;
mod inspect_cli;
mod labfiles_cli;
mod mat_cli;
mod messages_cli;
mod multihead_cli;
mod outputs_cli;
#[cfg(feature = "parquet")]
mod parquet_cli;
mod point_lists_cli;
mod range_cli;
mod readme;
mod recordings_cli;
mod reference_cli;
mod reference_setups_cli;
mod reliability;
#[cfg(feature = "remote")]
mod remote_cli;
mod report_cli;
mod ros1bag_cli;
mod rosbag_cli;
mod schema_cli;
mod shift_angle_cli;
mod simulate_cli;
mod snapshots;
mod stamps_cli;
mod tdms_cli;
mod tdr_cli;
mod threads_cli;
mod unit_hints_cli;
