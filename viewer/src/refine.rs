//! How fine to draw: the frame budget while the camera moves, progressive
//! refinement while it rests, and how far the refinement has come.
//!
//! Moving, the projected-size threshold follows the frame time (QSplat
//! 2.1, the same feedback as a flythrough's,
//! [`farfield_client::flythrough::follow_frame_time`]). At rest it halves
//! each frame down to the final threshold with the steps `farfield render`
//! takes ([`farfield_client::frame_loop::Settle`], `finer_threshold`), then
//! waits for pages. A node
//! budget (Potree's point budget) puts a floor under the threshold for as
//! long as the camera rests: a cut that would draw more nodes than the
//! budget is drawn coarser instead.
//!
//! Progress is the share of the current view's wanted cut that is
//! resident: pages the final cut used, over those plus the ones it still
//! wants. It is 0 while moving, never falls while the camera rests (a
//! newly arrived page can reveal finer pages wanted below it, which would
//! lower the plain ratio, so the highest value so far is kept), and is 1
//! exactly when the view is refined, never before.

use farfield_client::flythrough::follow_frame_time;
use farfield_client::frame_loop::{coarse_threshold, finer_threshold};

/// Largest share shown before the view is refined.
const ALMOST: f64 = 0.999;

/// What one frame's cut said about the view.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CutState {
    /// Nodes (splats, faces, triangles) drawn.
    pub drawn: u64,
    /// Resident pages the traversal used.
    pub used_pages: usize,
    /// Pages it would have descended into and that may still come.
    pub missing_pages: usize,
    /// Whether the root page is resident (without it nothing is drawn).
    pub root: bool,
}

/// The threshold and refinement state of a view.
#[derive(Debug, Clone)]
pub struct Refinement {
    /// The threshold the resting camera refines to (spheres: pixels; cubes: eps).
    pub final_threshold: f64,
    /// The frame time the moving camera aims for.
    pub target_frame_ms: f64,
    /// Most nodes a frame may draw; 0 is no budget.
    pub node_budget: u64,
    threshold: f64,
    /// The budget's floor under the threshold while resting.
    floor: f64,
    progress: f64,
    refined: bool,
}

impl Refinement {
    pub fn new(final_threshold: f64, target_frame_ms: f64, node_budget: u64) -> Self {
        let final_threshold = final_threshold.max(0.0);
        Self {
            final_threshold,
            target_frame_ms,
            node_budget,
            threshold: coarse_threshold(final_threshold),
            floor: 0.0,
            progress: 0.0,
            refined: false,
        }
    }

    /// The threshold to draw the next frame with.
    pub fn threshold(&self) -> f64 {
        self.threshold
    }

    /// Whether every page the resting view's final cut needs is resident
    /// and drawn at the final threshold (or the budget's floor).
    pub fn refined(&self) -> bool {
        self.refined
    }

    /// 0 to 1, see the module's notes.
    pub fn progress(&self) -> f64 {
        self.progress
    }

    /// The finest threshold the view may reach now.
    fn finest(&self) -> f64 {
        self.final_threshold.max(self.floor)
    }

    /// Starts refining again from coarse (a setting changed).
    pub fn restart(&mut self) {
        self.threshold = coarse_threshold(self.final_threshold);
        self.floor = 0.0;
        self.progress = 0.0;
        self.refined = false;
    }

    /// Takes in what the last frame did and sets the next threshold.
    pub fn after_frame(&mut self, moving: bool, frame_ms: f64, cut: CutState) {
        let over_budget = self.node_budget > 0 && cut.drawn > self.node_budget;
        if moving {
            self.floor = 0.0;
            self.progress = 0.0;
            self.refined = false;
            let mut next = follow_frame_time(
                self.threshold,
                frame_ms,
                self.target_frame_ms,
                self.final_threshold,
            );
            if over_budget {
                next = next.max(self.threshold * budget_ratio(cut.drawn, self.node_budget));
            }
            self.threshold = next;
            return;
        }
        if over_budget {
            // Coarser until under the budget, and no finer while resting.
            self.floor = self.threshold * budget_ratio(cut.drawn, self.node_budget);
            self.threshold = self.floor;
            self.refined = false;
            return;
        }
        let at_finest = self.threshold <= self.finest();
        self.refined = at_finest && cut.root && cut.missing_pages == 0;
        if self.refined {
            self.progress = 1.0;
        } else if at_finest {
            let wanted = cut.used_pages + cut.missing_pages;
            let share = if wanted == 0 {
                0.0
            } else {
                cut.used_pages as f64 / wanted as f64
            };
            self.progress = self.progress.max(share.min(ALMOST));
        }
        if !at_finest {
            self.threshold = finer_threshold(self.threshold, self.finest());
        }
    }
}

/// How much coarser a threshold must be to draw `budget` nodes instead of
/// `drawn`: nodes go with the inverse square of the projected size.
fn budget_ratio(drawn: u64, budget: u64) -> f64 {
    (drawn as f64 / budget.max(1) as f64).sqrt().max(1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn resting(used: usize, missing: usize) -> CutState {
        CutState {
            drawn: 100,
            used_pages: used,
            missing_pages: missing,
            root: true,
        }
    }

    #[test]
    fn rest_halves_to_the_final_threshold_then_waits_for_pages() {
        let mut r = Refinement::new(1.0, 30.0, 0);
        assert_eq!(r.threshold(), 16.0);
        for expected in [8.0, 4.0, 2.0, 1.0, 1.0] {
            r.after_frame(false, 5.0, resting(3, 5));
            assert_eq!(r.threshold(), expected);
            assert!(!r.refined());
        }
        r.after_frame(false, 5.0, resting(8, 0));
        assert!(r.refined());
        assert_eq!(r.progress(), 1.0);
    }

    #[test]
    fn progress_never_falls_at_rest_and_is_whole_only_when_refined() {
        let mut r = Refinement::new(1.0, 30.0, 0);
        for _ in 0..5 {
            r.after_frame(false, 5.0, resting(1, 9));
        }
        let mut last = r.progress();
        assert!((last - 0.1).abs() < 1e-12, "{last}");
        // A page arrives and reveals four more below it: the plain ratio
        // falls (2 / 14), the progress does not.
        for (used, missing) in [(2, 12), (6, 8), (13, 1), (14, 1)] {
            r.after_frame(false, 5.0, resting(used, missing));
            assert!(r.progress() >= last);
            assert!(r.progress() < 1.0, "not refined: {}", r.progress());
            last = r.progress();
        }
        // Everything used is resident but the root is not: not refined.
        r.after_frame(
            false,
            5.0,
            CutState {
                root: false,
                ..resting(15, 0)
            },
        );
        assert!(!r.refined() && r.progress() < 1.0);
        r.after_frame(false, 5.0, resting(15, 0));
        assert!(r.refined() && r.progress() == 1.0);
        // Moving starts over.
        r.after_frame(true, 5.0, resting(15, 0));
        assert_eq!((r.progress(), r.refined()), (0.0, false));
    }

    #[test]
    fn moving_follows_the_frame_time() {
        let mut r = Refinement::new(1.0, 20.0, 0);
        let start = r.threshold();
        r.after_frame(true, 80.0, resting(1, 0));
        assert!(r.threshold() > start, "slow frames coarsen");
        let slow = r.threshold();
        r.after_frame(true, 5.0, resting(1, 0));
        assert!(r.threshold() < slow, "fast frames refine");
    }

    #[test]
    fn the_node_budget_floors_the_threshold_while_resting() {
        let mut r = Refinement::new(1.0, 20.0, 1000);
        for _ in 0..4 {
            r.after_frame(false, 5.0, resting(3, 0));
        }
        assert_eq!(r.threshold(), 1.0);
        // 4000 nodes against a budget of 1000: twice as coarse, and it stays.
        r.after_frame(
            false,
            5.0,
            CutState {
                drawn: 4000,
                ..resting(3, 0)
            },
        );
        assert_eq!(r.threshold(), 2.0);
        r.after_frame(
            false,
            5.0,
            CutState {
                drawn: 900,
                ..resting(3, 0)
            },
        );
        assert_eq!(r.threshold(), 2.0);
        assert!(r.refined(), "refined as far as the budget allows");
    }
}
