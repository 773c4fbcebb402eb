//! The stages of [`super::Csrr`] one by one, for the solver's benchmark
//! (`crates/calib-core/benches/csrr.rs`): binning the streamed samples, building the NUFFT
//! stencils of the binned readings, the joint solve, and the uncertainty of its maps. Not part
//! of the library's interface.

use super::bins::SessionBinner;
use super::{CsrrError, CsrrOptions, SessionData, joint};
use crate::nufft::Stencils;
use crate::segment::Segmenter;

/// The sessions of a log reduced to bins.
pub struct Binned {
    sessions: Vec<SessionData>,
}

impl Binned {
    /// Occupied bins over all sessions.
    pub fn bins(&self) -> usize {
        self.sessions.iter().map(|s| s.bins.len()).sum()
    }
}

/// A joint solution.
pub struct Solved {
    sol: joint::JointSolution,
    screen: super::Screen,
}

/// Segmentation and binning of `(t, x, y)` readings with the default options (an iterator, so
/// that a log of 10⁸ samples can be binned as it is simulated, never held).
pub fn bin(readings: impl IntoIterator<Item = (f64, f64, f64)>) -> Binned {
    let opts = CsrrOptions::default();
    let mut segmenter = Segmenter::new(opts.segments);
    let mut binner = SessionBinner::new(opts.bins_per_rev);
    for (t, x, y) in readings {
        segmenter.push(t, x, y, None, &[], &mut binner);
    }
    segmenter.finish(&mut binner);
    Binned {
        sessions: binner.into_sessions(),
    }
}

/// One build of the stencils of every bin's two readings on the grid of `max_order`, as the
/// solver builds them; returns the stencils' count.
pub fn stencils(binned: &Binned, max_order: usize) -> usize {
    let grid = joint::grid_points(max_order);
    let bins = || binned.sessions.iter().flat_map(|s| s.bins.iter());
    let a = Stencils::new(bins().map(|b| b.x), grid);
    let b = Stencils::new(bins().map(|b| b.x - b.d), grid);
    a.len() + b.len()
}

/// The joint solve at `max_order` as [`super::Csrr`] makes it (with the significance screening
/// and the residual check).
pub fn solve(binned: &Binned, max_order: usize) -> Result<Solved, CsrrError> {
    let mut jopts = joint::JointOptions::with_max_order(max_order);
    jopts.min_observability = CsrrOptions::default().min_observability;
    jopts.check_up_to =
        super::residual_check_order(super::densest_samples_per_rev(&binned.sessions));
    let weights: Vec<f64> = binned.sessions.iter().map(|s| s.samples as f64).collect();
    let (sol, screen) = super::fit_significant(&binned.sessions, &jopts, &weights)?;
    Ok(Solved { sol, screen })
}

/// The tables and their uncertainty from a solve (what [`super::Csrr::finish`] does after it);
/// returns the median u of A's table, rad.
pub fn uncertainty(solved: &Solved) -> f64 {
    super::joint_maps(&solved.sol, &solved.screen, None)
        .uncertainty
        .0
        .median()
}
