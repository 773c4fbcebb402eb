//! One module per subcommand that is not a calibration method (those are in [`crate::method`]):
//! each loads its inputs, computes with `calib-core`, and renders.

pub mod apply;
pub mod compare;
pub mod compose;
pub mod export;
pub mod import;
pub mod inspect;
pub mod moteus_dump;
pub mod plan;
pub mod simulate;
pub mod uncertainty;
