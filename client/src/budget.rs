//! PLP's time-critical budget (section 3: "a triangle-count budget can be
//! used to make it time-critical"): a frame time in milliseconds turned
//! into a triangle count each frame from the draw rate measured on the
//! frames before.

use farfield_traverse::Budget;

/// A job's budget as the user gave it: triangles (a count or a share),
/// or milliseconds a frame; and the kind to draw with where the file's
/// hierarchy has several (`--mode culling` for a BSP file).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BudgetSpec {
    pub triangles: Budget,
    /// Time-critical: overrides `triangles`.
    pub ms: Option<f64>,
    /// The registered kind to draw with, if not the file's first.
    pub mode: Option<&'static farfield_traverse::Registered>,
}

impl BudgetSpec {
    /// Sets a frame loop's cut to this budget.
    pub fn apply(&self, cut: &mut crate::frame_loop::FrameState) {
        cut.budget = self.triangles;
        cut.time_budget = self.ms.map(TimeBudget::new);
        if let Some(kind) = self.mode {
            cut.prefer(kind);
        }
    }
}

/// A budget in milliseconds, and what the last frames cost.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimeBudget {
    /// The frame time to aim for.
    pub target_ms: f64,
    /// Measured milliseconds per triangle (smoothed); `None` before the
    /// first frame.
    ms_per_triangle: Option<f64>,
    /// Frame time that does not grow with triangles (traversal, upload,
    /// the pass itself), smoothed.
    fixed_ms: f64,
}

/// Triangles the first frame may draw, before any rate is known.
const FIRST_FRAME_TRIANGLES: u64 = 10_000;
/// Weight of the newest frame in the smoothed rate.
const SMOOTHING: f64 = 0.3;

impl TimeBudget {
    pub fn new(target_ms: f64) -> Self {
        Self {
            target_ms: target_ms.max(0.0),
            ms_per_triangle: None,
            fixed_ms: 0.0,
        }
    }

    /// This frame's budget in triangles.
    pub fn budget(&self) -> Budget {
        let Some(rate) = self.ms_per_triangle else {
            return Budget::Triangles(FIRST_FRAME_TRIANGLES);
        };
        let room = (self.target_ms - self.fixed_ms).max(0.0);
        // The rate is positive (see `observe`), so this is finite.
        Budget::Triangles((room / rate).floor().min(u64::MAX as f64) as u64)
    }

    /// Records a frame that drew `triangles` in `frame_ms` (traversal and
    /// draw), of which `fixed_ms` did not depend on the count.
    pub fn observe(&mut self, triangles: u64, frame_ms: f64, fixed_ms: f64) {
        if !(frame_ms.is_finite() && fixed_ms.is_finite()) {
            return;
        }
        self.fixed_ms += SMOOTHING * (fixed_ms.max(0.0) - self.fixed_ms);
        if triangles == 0 {
            return;
        }
        // A frame too fast to time still costs something per triangle.
        let rate = ((frame_ms - fixed_ms).max(0.0) / triangles as f64).max(1e-9);
        self.ms_per_triangle = Some(match self.ms_per_triangle {
            None => rate,
            Some(old) => old + SMOOTHING * (rate - old),
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_budget_follows_the_measured_rate() {
        let mut b = TimeBudget::new(20.0);
        assert_eq!(b.budget(), Budget::Triangles(FIRST_FRAME_TRIANGLES));
        // A machine drawing 1,000 triangles a millisecond, 2 ms fixed.
        for _ in 0..50 {
            let Budget::Triangles(n) = b.budget() else {
                panic!("a time budget is a count");
            };
            b.observe(n, 2.0 + n as f64 / 1000.0, 2.0);
        }
        let Budget::Triangles(n) = b.budget() else {
            panic!("a time budget is a count");
        };
        assert!((17_000..=18_000).contains(&n), "{n}");
        // Slower: the budget shrinks.
        for _ in 0..50 {
            b.observe(n, 2.0 + n as f64 / 100.0, 2.0);
        }
        let Budget::Triangles(m) = b.budget() else {
            panic!("a time budget is a count");
        };
        assert!(m < 2_000, "{m}");
    }

    #[test]
    fn zero_triangles_or_zero_time_divide_by_nothing() {
        let mut b = TimeBudget::new(10.0);
        b.observe(0, 5.0, 5.0);
        b.observe(100, 0.0, 0.0);
        b.observe(100, f64::NAN, 0.0);
        let Budget::Triangles(n) = b.budget() else {
            panic!("a time budget is a count");
        };
        assert!(n > 0);
        let over = TimeBudget {
            fixed_ms: 50.0,
            ..b
        };
        assert_eq!(over.budget(), Budget::Triangles(0));
    }
}
