//! Planning a run before it is recorded: which set-up lets a method see the orders asked for,
//! and the uncertainty it will give.
//!
//! Every method calib implements has a design question that decides its result before a single
//! sample is recorded. Each planner answers it with the same formulas the method uses for its
//! observability and its `u`, evaluated on the planned set-up instead of a recorded one:
//!
//! - [`csrr`]: the relative rotations `Δ_k` (CSRR paper, eqs. 5–7).
//! - [`multihead`]: the head positions (shift-angle paper, eqs. 8–9; SelfA's head sets).
//! - [`shift_angle`]: the shifts and readings, and the Table 3 budget (shift-angle paper).
//! - [`tdr`]: the coast-down, its duration and sample rate (the TDR method's own rules).
//! - [`reference`](mod@reference): ISO 230-2 targets, passes and the approach for a backlash.
pub mod csrr;
pub mod multihead;
pub mod reference;
pub(crate) mod search;
pub mod shift_angle;
pub mod tdr;

/// The most angles a CSRR or multi-head plan proposes or evaluates (`--sessions`, `--heads`,
/// the lists of `--deltas` and `--positions`): far more than any rig mounts. Below it a
/// proposal's time grows linearly with the angles (see `search`'s cost).
pub const MAX_PLANNED_ANGLES: usize = 1000;
