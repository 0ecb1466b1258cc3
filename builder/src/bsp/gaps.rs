//! Gaps between objects along one direction (section 4): the objects'
//! extents sorted by their lower and upper bounds, swept while counting the
//! "active" objects (those whose extent the sweep is inside); intervals
//! where that count is a local minimum are the gaps.
//!
//! **The cost of a gap**, lower is better:
//!
//! ```text
//! cost = active + BALANCE_WEIGHT * |B - F| / (B + F)
//! ```
//!
//! `active` counts the objects the plane crosses: each is split (a mesh)
//! or overhangs its side (an instance), so each costs about one object's
//! worth of trouble. `B` and `F` are the primitives on the back and front
//! (an active object counts half on each side), and `|B - F| / (B + F)`,
//! 0 for a perfect balance and 1 for nothing on one side, measures how far
//! the cut is from halving the work, which is what keeps the tree shallow
//! (the paper: "such that the number of geometric primitives on each side
//! of the gap is roughly equal"). With the weight 8, a clean gap with a
//! 75/25 split (cost 4) ties with a perfectly balanced cut through four
//! objects. Measured on the paper-sized island (1117 trees, 40.6 M
//! triangles): the weight 2 made a tree 24 levels deep, 4 made 18, 8 and
//! 16 made 14 (the paper's has 13), at the price of a few more trees
//! crossed (500, 534, 603, 636). A crossed tree is not split, only kept
//! whole on its centre's side, so balance wins.
//!
//! Between directions the builder adds `ASPECT_WEIGHT * (1 − extent /
//! greatest extent)`, so it "tends to choose" the direction along which
//! the objects spread farthest (good aspect ratios) unless another has a
//! clearly better gap.

/// How much a full imbalance costs, in crossed objects.
pub const BALANCE_WEIGHT: f64 = 8.0;
/// How much choosing a direction of no extent costs, in crossed objects.
pub const ASPECT_WEIGHT: f64 = 1.0;

/// One object's extent along a direction and its primitive count.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Extent {
    pub lo: f64,
    pub hi: f64,
    pub primitives: u64,
}

/// The best gap along one direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gap {
    /// Where the plane goes: the middle of the gap's interval.
    pub plane: f64,
    /// Objects the plane crosses.
    pub active: usize,
    /// Objects wholly behind and wholly in front (both at least 1).
    pub back: usize,
    pub front: usize,
    pub cost: f64,
}

/// The cheapest gap along a direction that leaves at least one object
/// wholly on each side, or `None` (every local minimum is at an end, or
/// the objects all overlap).
pub fn best_gap(extents: &[Extent]) -> Option<Gap> {
    let n = extents.len();
    if n < 2 {
        return None;
    }
    // Events at one position: ends first, so objects that touch leave a
    // zero-width gap between them; an object of no extent starts and ends
    // between those ends and the other starts, so no count goes below 0.
    let mut events: Vec<(f64, u8, i8)> = extents
        .iter()
        .flat_map(|e| {
            if e.hi > e.lo {
                [(e.lo, 3, 1i8), (e.hi, 0, -1i8)]
            } else {
                [(e.lo, 1, 1i8), (e.hi, 2, -1i8)]
            }
        })
        .collect();
    events.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let mut counts = Vec::with_capacity(events.len());
    let mut active = 0i64;
    for &(_, _, d) in &events {
        active += i64::from(d);
        counts.push(active);
    }
    // For the sides' sizes: objects sorted by upper bound (behind a plane:
    // hi <= plane) and by lower bound (in front: lo >= plane), with prefix
    // sums of their primitives.
    let mut by_hi: Vec<(f64, u64)> = extents.iter().map(|e| (e.hi, e.primitives)).collect();
    let mut by_lo: Vec<(f64, u64)> = extents.iter().map(|e| (e.lo, e.primitives)).collect();
    by_hi.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
    by_lo.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
    let prefix = |v: &[(f64, u64)]| {
        let mut s = vec![0u64; v.len() + 1];
        for (i, (_, p)) in v.iter().enumerate() {
            s[i + 1] = s[i] + p;
        }
        s
    };
    let (hi_sum, lo_sum) = (prefix(&by_hi), prefix(&by_lo));
    let total = hi_sum[n];
    // Objects of no extent, by position: one lying on a plane is behind
    // it, not also in front.
    let mut points: Vec<(f64, u64)> = extents
        .iter()
        .filter(|e| e.hi <= e.lo)
        .map(|e| (e.lo, e.primitives))
        .collect();
    points.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
    let point_sum = prefix(&points);
    let mut best: Option<Gap> = None;
    for i in 0..events.len() - 1 {
        let c = counts[i];
        // Before every event the count is 0.
        let before = if i == 0 { 0 } else { counts[i - 1] };
        let after = counts[i + 1];
        if c > before || c > after {
            continue;
        }
        let plane = 0.5 * (events[i].0 + events[i + 1].0);
        let back = by_hi.partition_point(|&(hi, _)| hi <= plane);
        let not_front = by_lo.partition_point(|&(lo, _)| lo < plane);
        let (first_on, after_on) = (
            points.partition_point(|&(p, _)| p < plane),
            points.partition_point(|&(p, _)| p <= plane),
        );
        let front = n - not_front - (after_on - first_on);
        if back == 0 || front == 0 {
            continue;
        }
        let active = n.saturating_sub(back + front);
        let on_plane = point_sum[after_on] - point_sum[first_on];
        let (b, f) = (hi_sum[back], total - lo_sum[not_front] - on_plane);
        let straddling = total.saturating_sub(b + f) as f64 * 0.5;
        let (b, f) = (b as f64 + straddling, f as f64 + straddling);
        let imbalance = if b + f > 0.0 {
            (b - f).abs() / (b + f)
        } else {
            0.0
        };
        let cost = active as f64 + BALANCE_WEIGHT * imbalance;
        if best.is_none_or(|g| cost < g.cost) {
            best = Some(Gap {
                plane,
                active,
                back,
                front,
                cost,
            });
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    fn e(lo: f64, hi: f64, primitives: u64) -> Extent {
        Extent { lo, hi, primitives }
    }

    #[test]
    fn a_clean_gap_in_the_middle_wins() {
        let objects = [
            e(0.0, 1.0, 10),
            e(2.0, 3.0, 10),
            e(5.0, 6.0, 10),
            e(7.0, 8.0, 10),
        ];
        let g = best_gap(&objects).expect("gaps");
        assert_eq!((g.plane, g.active, g.back, g.front), (4.0, 0, 2, 2));
        assert_eq!(g.cost, 0.0);
    }

    #[test]
    fn balance_decides_between_clean_gaps_and_touching_objects_leave_one() {
        // Primitives 100 | 60 40: the gap after the heavy object balances.
        let objects = [e(0.0, 1.0, 100), e(1.0, 2.0, 60), e(3.0, 4.0, 40)];
        let g = best_gap(&objects).unwrap();
        assert_eq!(g.plane, 1.0, "the zero-width gap where two objects touch");
        assert_eq!((g.back, g.front, g.active), (1, 2, 0));
    }

    #[test]
    fn a_terrain_under_everything_is_crossed_by_every_gap() {
        let mut objects = vec![e(0.0, 10.0, 50)];
        objects.extend((0..5).map(|i| e(2.0 * i as f64, 2.0 * i as f64 + 1.0, 10)));
        let g = best_gap(&objects).unwrap();
        assert_eq!(g.active, 1);
        assert!(g.plane == 3.5 || g.plane == 5.5, "{g:?}");
    }

    #[test]
    fn identical_or_zero_extents_or_one_object_have_no_gap() {
        assert_eq!(best_gap(&[e(1.0, 2.0, 5); 4]), None);
        assert_eq!(best_gap(&[e(3.0, 3.0, 1); 6]), None);
        assert_eq!(best_gap(&[e(0.0, 1.0, 1)]), None);
        assert_eq!(best_gap(&[]), None);
        // Nested extents: every plane cuts the outer one and leaves none
        // wholly on one side.
        assert_eq!(best_gap(&[e(0.0, 10.0, 1), e(4.0, 6.0, 1)]), None);
        // Zero extents at two places: a gap between them.
        let g = best_gap(&[e(3.0, 3.0, 1), e(3.0, 3.0, 1), e(5.0, 5.0, 1)]).unwrap();
        assert_eq!((g.plane, g.back, g.front), (4.0, 2, 1));
    }
}
