//! The bounding-sphere tree over the leaves (QSplat 2.2's BuildTree).
//!
//! A range of leaves is split at the middle of its bounding box's longest
//! axis (a bisection, as in the paper, so split planes stay centred and the
//! quantized child positions stay accurate); each half is split once more,
//! which gives every interior node 2 to 4 children and a branching factor
//! near 4 without ever a single child. Leaves at one position collapse into
//! one leaf. Bisection of pathological inputs (points spaced 2^-k apart)
//! could recurse as deep as f64 allows, so past [`BISECT_DEPTH`] levels the
//! split switches to the median, which bounds the depth by log2 of the
//! count; the tree is never deeper than about 96 + 2 log2(n) binary splits.
//!
//! Interior spheres enclose their children's spheres; normals and colors are
//! leaf-count-weighted averages; a normal cone covers the children's cones.
//!
//! [`parallel`] runs the build on all threads; [`InteriorNodes`] holds the
//! interior nodes as the lists its tasks made.

use glam::{DVec3, Vec3};

mod nodes;
mod parallel;

pub use nodes::{InteriorNodes, SharedNodes};

use super::leaves::{Leaf, acos_upper, cone_from_u8, cone_to_u8, pack_normal, unpack_normal};
use crate::progress::{Progress, Silent};

/// Binary splits by bisection before falling back to median splits.
pub const BISECT_DEPTH: u32 = 96;

/// A child or root: a leaf index (high bit set) or an interior-node index.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NodeRef(u32);

impl NodeRef {
    const LEAF_BIT: u32 = 1 << 31;
    pub fn leaf(i: usize) -> Self {
        Self(i as u32 | Self::LEAF_BIT)
    }
    fn interior(i: usize) -> Self {
        Self(i as u32)
    }
    /// `Ok(leaf index)` or `Err(interior index)`.
    pub fn get(self) -> Result<usize, usize> {
        if self.0 & Self::LEAF_BIT != 0 {
            Ok((self.0 & !Self::LEAF_BIT) as usize)
        } else {
            Err(self.0 as usize)
        }
    }
}

/// An interior node of the tree being built.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Interior {
    pub center: DVec3,
    pub radius: f64,
    pub normal: Vec3,
    /// Normal-cone half-angle in radians.
    pub cone: f32,
    pub color: [u8; 3],
    pub child_count: u8,
    pub leaf_count: u32,
    pub children: [NodeRef; 4],
}

/// The built tree: leaves (reordered) and interior nodes.
#[derive(Debug)]
pub struct Tree {
    pub leaves: Vec<Leaf>,
    pub interior: InteriorNodes,
    pub root: NodeRef,
    /// Leaves that stand for several input points at one position.
    pub collapsed_duplicates: u64,
}

impl Tree {
    /// The root's true sphere: center and radius.
    pub fn root_sphere(&self) -> (DVec3, f64) {
        match self.root.get() {
            Ok(l) => (self.leaves[l].position, f64::from(self.leaves[l].radius)),
            Err(i) => (self.interior[i].center, self.interior[i].radius),
        }
    }
}

/// The properties a parent needs of a child, whatever its kind.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Summary {
    pub center: DVec3,
    pub radius: f64,
    pub normal: DVec3,
    pub cone: f64,
    pub color: DVec3,
    pub leaves: u32,
}

impl Summary {
    /// The summary of `tree`'s root, as its parent would see it.
    pub(crate) fn of_root(tree: &Tree) -> Self {
        match tree.root.get() {
            Ok(l) => leaf_summary(&tree.leaves[l]),
            Err(i) => {
                let n = &tree.interior[i];
                Self {
                    center: n.center,
                    radius: n.radius,
                    normal: n.normal.as_dvec3(),
                    cone: f64::from(n.cone),
                    color: DVec3::from(n.color.map(f64::from)),
                    leaves: n.leaf_count,
                }
            }
        }
    }
}

/// A placeholder for unused slots of fixed arrays of summaries.
const EMPTY_SUMMARY: Summary = Summary {
    center: DVec3::ZERO,
    radius: 0.0,
    normal: DVec3::ZERO,
    cone: 0.0,
    color: DVec3::ZERO,
    leaves: 0,
};

/// Builds the tree; `leaves` must not be empty.
pub fn build_tree(leaves: Vec<Leaf>) -> Tree {
    let all = bounds(&leaves);
    build_tree_within(leaves, all, &Silent)
}

/// [`build_tree`] when the leaves' bounds are already known, telling
/// `progress` how many leaves are in finished subtrees.
pub fn build_tree_within(mut leaves: Vec<Leaf>, all: Bounds, progress: &dyn Progress) -> Tree {
    assert!(!leaves.is_empty(), "build_tree needs at least one leaf");
    assert!(
        leaves.len() < (1 << 31),
        "too many leaves for 31-bit references"
    );
    progress.begin("tree", leaves.len() as u64);
    let (interior, root, collapsed) = parallel::build(&mut leaves, all, progress);
    Tree {
        leaves,
        interior,
        root,
        collapsed_duplicates: collapsed,
    }
}

/// Room for the interior nodes of `leaves` leaves: bisection of real scenes
/// makes about 0.51 per leaf, and a vector that outgrows its capacity is
/// briefly held twice while it moves.
fn interior_capacity(leaves: usize) -> usize {
    leaves / 2 + leaves / 16
}

/// Builds the subtree of `leaves` (which start at global index `base`),
/// appending interior nodes to `out`. Returns the subtree's root, its
/// summary, and how many leaves were collapsed as duplicates.
fn build_range(
    leaves: &mut [Leaf],
    bounds: Bounds,
    base: usize,
    depth: u32,
    out: &mut Vec<Interior>,
) -> (NodeRef, Summary, u64) {
    if leaves.len() == 1 {
        return (NodeRef::leaf(base), leaf_summary(&leaves[0]), 0);
    }
    if bounds.0 == bounds.1 {
        let collapsed = leaves.len() as u64 - 1;
        collapse(leaves);
        return (NodeRef::leaf(base), leaf_summary(&leaves[0]), collapsed);
    }
    let (ranges, count) = child_ranges(leaves, bounds, depth);
    let mut children = [NodeRef::leaf(0); 4];
    let mut summaries = [EMPTY_SUMMARY; 4];
    let mut collapsed = 0;
    for (i, &(start, end, b)) in ranges[..count].iter().enumerate() {
        let (child, summary, dup) =
            build_range(&mut leaves[start..end], b, base + start, depth + 2, out);
        children[i] = child;
        summaries[i] = summary;
        collapsed += dup;
    }
    let (node, summary) = parent_of(&summaries[..count], children);
    out.push(node);
    (NodeRef::interior(out.len() - 1), summary, collapsed)
}

/// A child range of a node: start, end and bounds of its leaves.
type ChildRange = (usize, usize, Bounds);

/// Splits a range (of more than one position) into two halves, then each
/// half with more than one distinct position into two again: 2 to 4 child
/// ranges, in a fixed array (this runs once per interior node). Each split
/// also measures the bounds of its two sides, so no range's bounds are
/// computed twice.
fn child_ranges(leaves: &mut [Leaf], (lo, hi): Bounds, depth: u32) -> ([ChildRange; 4], usize) {
    let (mid, left, right) = split(leaves, lo, hi, depth);
    let mut ranges = [(0, 0, EMPTY_BOUNDS); 4];
    let mut count = 0;
    for (start, end, (plo, phi)) in [(0, mid, left), (mid, leaves.len(), right)] {
        let part = &mut leaves[start..end];
        if part.len() > 1 && plo != phi {
            let (m, a, b) = split(part, plo, phi, depth + 1);
            ranges[count] = (start, start + m, a);
            ranges[count + 1] = (start + m, end, b);
            count += 2;
        } else {
            ranges[count] = (start, end, (plo, phi));
            count += 1;
        }
    }
    (ranges, count)
}

/// Axis-aligned bounds of a range's positions: (min, max).
pub type Bounds = (DVec3, DVec3);

const EMPTY_BOUNDS: Bounds = (DVec3::INFINITY, DVec3::NEG_INFINITY);

/// Grows bounds by a point. Positions are finite (the importers refuse
/// NaN), so a plain comparison serves: one `minsd`/`maxsd` per coordinate,
/// where `f64::min` adds NaN handling to the build's hottest loop.
#[inline(always)]
fn grow((lo, hi): &mut Bounds, p: DVec3) {
    let min = |a: f64, b: f64| if a < b { a } else { b };
    let max = |a: f64, b: f64| if a > b { a } else { b };
    *lo = DVec3::new(min(p.x, lo.x), min(p.y, lo.y), min(p.z, lo.z));
    *hi = DVec3::new(max(p.x, hi.x), max(p.y, hi.y), max(p.z, hi.z));
}

fn bounds(leaves: &[Leaf]) -> Bounds {
    let mut b = EMPTY_BOUNDS;
    for l in leaves {
        grow(&mut b, l.position);
    }
    b
}

/// Partitions `leaves` (not all at one position); returns the split index,
/// strictly inside the range, and the bounds of the two sides.
fn split(leaves: &mut [Leaf], lo: DVec3, hi: DVec3, depth: u32) -> (usize, Bounds, Bounds) {
    let axis = (hi - lo).max_position();
    if depth < BISECT_DEPTH {
        let plane = lo[axis] + (hi[axis] - lo[axis]) * 0.5;
        // One partition per axis, so the loop reads a field, not an index.
        let (mid, left, right) = match axis {
            0 => partition(leaves, |l| l.position.x < plane),
            1 => partition(leaves, |l| l.position.y < plane),
            _ => partition(leaves, |l| l.position.z < plane),
        };
        if mid > 0 && mid < leaves.len() {
            return (mid, left, right);
        }
    }
    // Median split: balanced whatever the spacing. Equal coordinates may
    // straddle the median, which is fine: both sides are non-empty.
    let mid = leaves.len() / 2;
    leaves.select_nth_unstable_by(mid, |a, b| a.position[axis].total_cmp(&b.position[axis]));
    (mid, bounds(&leaves[..mid]), bounds(&leaves[mid..]))
}

/// In-place partition: elements satisfying `pred` first. Returns their
/// count and the bounds of both sides, gathered in the same pass.
fn partition(leaves: &mut [Leaf], pred: impl Fn(&Leaf) -> bool) -> (usize, Bounds, Bounds) {
    let (mut left, mut right) = (EMPTY_BOUNDS, EMPTY_BOUNDS);
    let mut first = 0;
    let mut last = leaves.len();
    loop {
        while first < last && pred(&leaves[first]) {
            grow(&mut left, leaves[first].position);
            first += 1;
        }
        while first < last && !pred(&leaves[last - 1]) {
            grow(&mut right, leaves[last - 1].position);
            last -= 1;
        }
        if first + 1 >= last {
            return (first, left, right);
        }
        leaves.swap(first, last - 1);
        grow(&mut left, leaves[first].position);
        grow(&mut right, leaves[last - 1].position);
        first += 1;
        last -= 1;
    }
}

/// Merges leaves at one position into `leaves[0]`: the largest radius, the
/// averaged normal and color, a cone covering all of them.
fn collapse(leaves: &mut [Leaf]) {
    let summaries: Vec<Summary> = leaves.iter().map(leaf_summary).collect();
    let merged = combine(&summaries);
    let first = &mut leaves[0];
    first.radius = leaves_max_radius(&summaries);
    first.normal = pack_normal(merged.normal.as_vec3());
    first.cone = cone_to_u8(merged.cone);
    first.color = merged
        .color
        .round()
        .to_array()
        .map(|c| c.clamp(0.0, 255.0) as u8);
}

fn leaves_max_radius(s: &[Summary]) -> f32 {
    s.iter().map(|s| s.radius as f32).fold(0.0, f32::max)
}

fn leaf_summary(l: &Leaf) -> Summary {
    Summary {
        center: l.position,
        radius: f64::from(l.radius),
        normal: unpack_normal(l.normal).as_dvec3(),
        cone: cone_from_u8(l.cone),
        color: DVec3::from(l.color.map(f64::from)),
        leaves: 1,
    }
}

/// Normal, cone and color of a set of children (center/radius not set).
fn combine(children: &[Summary]) -> Summary {
    let mut total = 0.0;
    let mut normal_sum = DVec3::ZERO;
    let mut color_sum = DVec3::ZERO;
    let mut leaves = 0;
    for c in children {
        let weight = f64::from(c.leaves);
        total += weight;
        normal_sum += c.normal * weight;
        color_sum += c.color * weight;
        leaves += c.leaves;
    }
    let normal = (normal_sum / total)
        .try_normalize()
        .unwrap_or(children[0].normal);
    let cone = children
        .iter()
        .map(|c| acos_upper(normal.dot(c.normal)) + c.cone)
        .fold(0.0, f64::max)
        .min(std::f64::consts::PI);
    Summary {
        center: DVec3::ZERO,
        radius: 0.0,
        normal,
        cone,
        color: color_sum / total,
        leaves,
    }
}

/// The parent node of 2 to 4 children: the sphere around the box of their
/// spheres, grown until it encloses each child in f64 arithmetic.
pub(crate) fn parent_of(children: &[Summary], refs: [NodeRef; 4]) -> (Interior, Summary) {
    let mut lo = DVec3::INFINITY;
    let mut hi = DVec3::NEG_INFINITY;
    for c in children {
        lo = lo.min(c.center - c.radius);
        hi = hi.max(c.center + c.radius);
    }
    let center = (lo + hi) * 0.5;
    let mut radius = children
        .iter()
        .map(|c| center.distance(c.center) + c.radius)
        .fold(0.0, f64::max);
    // A hair of slack so rounding in later distance computations never puts
    // a child outside: enclosure is what keeps splats hole-free.
    radius += radius * 4.0 * f64::EPSILON + center.abs().max_element() * 4.0 * f64::EPSILON;
    let mut s = combine(children);
    s.center = center;
    s.radius = radius;
    let node = Interior {
        center,
        radius,
        normal: s.normal.as_vec3(),
        cone: s.cone as f32,
        color: s
            .color
            .round()
            .to_array()
            .map(|c| c.clamp(0.0, 255.0) as u8),
        child_count: children.len() as u8,
        leaf_count: s.leaves,
        children: refs,
    };
    (node, s)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn leaf(p: DVec3) -> Leaf {
        Leaf {
            position: p,
            radius: 0.1,
            normal: pack_normal(Vec3::Z),
            color: [10, 20, 30],
            cone: 0,
            source: 0,
        }
    }

    fn check(tree: &Tree, node: NodeRef, depth: u32, max_depth: &mut u32) -> u32 {
        *max_depth = (*max_depth).max(depth);
        match node.get() {
            Ok(_) => 1,
            Err(i) => {
                let n = tree.interior[i];
                assert!(
                    (2..=4).contains(&n.child_count),
                    "node with {} children",
                    n.child_count
                );
                let mut count = 0;
                for c in &n.children[..usize::from(n.child_count)] {
                    let (cc, cr) = match c.get() {
                        Ok(l) => (tree.leaves[l].position, f64::from(tree.leaves[l].radius)),
                        Err(j) => (tree.interior[j].center, tree.interior[j].radius),
                    };
                    assert!(
                        n.center.distance(cc) + cr <= n.radius,
                        "child outside parent"
                    );
                    count += check(tree, *c, depth + 1, max_depth);
                }
                assert_eq!(count, n.leaf_count);
                count
            }
        }
    }

    #[test]
    fn random_points_give_a_valid_tree_on_any_thread_count() {
        let mut rnd = crate::test_random(12345);
        let leaves: Vec<Leaf> = (0..120_000)
            .map(|_| leaf(DVec3::new(rnd(), rnd(), rnd() * 0.01)))
            .collect();
        let tree = build_tree(leaves);
        let mut depth = 0;
        assert_eq!(check(&tree, tree.root, 0, &mut depth), 120_000);
        assert!(depth < 20, "depth {depth}");
    }

    #[test]
    fn duplicates_collapse_and_exponential_spacing_stays_shallow() {
        let tree = build_tree(vec![leaf(DVec3::ONE); 1_000_000]);
        assert!(tree.root.get().is_ok());
        assert_eq!(tree.collapsed_duplicates, 999_999);

        let leaves: Vec<Leaf> = (0..2000)
            .map(|i| {
                leaf(DVec3::new(
                    0.5f64.powi(i % 1000) * (1 + i / 1000) as f64,
                    0.0,
                    0.0,
                ))
            })
            .collect();
        let tree = build_tree(leaves);
        let mut depth = 0;
        check(&tree, tree.root, 0, &mut depth);
        assert!(depth <= BISECT_DEPTH / 2 + 2 * 11 + 2, "depth {depth}");
    }
}
