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

/// A part of the current step worth `units`, reported in proportion as
/// `work` of its own measure gets done ([`Portion::did`]): how a part
/// counted in triangles walked moves a bar counted in vertices. What is
/// left is reported when it is dropped, so the step's parts always add up.
pub(crate) struct Portion<'a> {
    progress: &'a dyn Progress,
    units: u64,
    work: u128,
    done: u128,
    reported: u64,
}

impl<'a> Portion<'a> {
    pub fn new(progress: &'a dyn Progress, units: u64, work: u64) -> Self {
        Self {
            progress,
            units,
            work: u128::from(work.max(1)),
            done: 0,
            reported: 0,
        }
    }

    /// `work` more of the part is done.
    pub fn did(&mut self, work: u64) {
        self.done += u128::from(work);
        // units * done / work, in 128 bits: both factors can pass 2^32.
        let now =
            (u128::from(self.units) * self.done / self.work).min(u128::from(self.units)) as u64;
        if now > self.reported {
            self.progress.advance(now - self.reported);
            self.reported = now;
        }
    }
}

impl Drop for Portion<'_> {
    fn drop(&mut self) {
        if self.units > self.reported {
            self.progress.advance(self.units - self.reported);
        }
    }
}
