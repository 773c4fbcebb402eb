//! calib-core's tests against known truths: one test binary (one link) whose modules each test
//! a method or a concern. Run one module with `cargo test -p calib-core --test it csrr_accuracy::`.

mod coverage;
mod csrr_accuracy;
mod csrr_large;
mod csrr_latency;
mod csrr_outcomes;
mod multihead;
mod nufft2d;
mod numerical_guards;
mod outcomes;
mod properties;
mod reference_cal;
mod reference_setups;
mod shift_angle;
mod simulate;
#[path = "support/spin_down.rs"]
mod support;
mod tdr;
mod whole_turns;
