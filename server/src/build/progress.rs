//! How far a build has got, for a progress bar.
//!
//! The sphere builder's steps (leaves, tree, layout) each announce their
//! amount of work with [`Progress::begin`] and report finished parts with
//! [`Progress::advance`]: the leaves by vertices, the tree by leaves, the
//! layout by nodes placed. Parts are coarse (64 Ki triangles walked by one
//! thread, a geometry's points or instances, one of the tree's about 64
//! tasks, one of the layout's windows), so reporting costs nothing next to
//! the work, and a single large scan's bar moves in every step.
//! The command line turns it into a bar with a percentage and an estimate
//! of the time left, which a build of many minutes needs.

/// What a build reports as it goes. Called from the build's worker
/// threads, hence `Sync`.
pub trait Progress: Sync {
    /// A step begins: its name and its total amount of work.
    fn begin(&self, step: &'static str, total: u64);
    /// `done` more units of the current step are finished.
    fn advance(&self, done: u64);
}

/// Reports nothing: for benchmarks, tests and library callers.
#[derive(Debug, Clone, Copy, Default)]
pub struct Silent;

impl Progress for Silent {
    fn begin(&self, _step: &'static str, _total: u64) {}
    fn advance(&self, _done: u64) {}
}
