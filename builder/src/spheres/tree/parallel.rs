//! Building the tree on all threads.
//!
//! 1. The top of the tree is split into ranges of at most a 1/[`TASKS`]
//!    share of the leaves, the ranges of each level partitioned
//!    concurrently ([`Top`]).
//! 2. Each range is built whole by one task, into its own node list; the
//!    tasks are balanced by work stealing, so a thread that drew small
//!    ranges takes more.
//! 3. The lists become the parts of [`InteriorNodes`] with their references
//!    shifted to their place in the numbering, and the few nodes above the
//!    ranges are made from the ranges' summaries, in a last part.
//!
//! The splits are the same as a serial build's, so the tree is too; only
//! its nodes' numbering depends on the order tasks are listed in, which is
//! fixed.

use rayon::prelude::*;

use super::{
    Bounds, Interior, InteriorNodes, NodeRef, Summary, build_range, child_ranges,
    interior_capacity, parent_of,
};
use crate::progress::Progress;
use crate::spheres::leaves::Leaf;

/// About this many ranges are built as tasks: enough for work stealing to
/// even out ranges of unequal size on any thread count, few enough that the
/// nodes above them cost nothing.
const TASKS: usize = 64;
/// No range smaller than this is split off as its own task.
const TASK_MIN: usize = 4_096;

/// The top of the tree: the ranges tasks build, and the nodes above them.
enum Top {
    /// Leaves `start..end` with their bounds, split `depth` times already;
    /// `index` is the task's place in the list of tasks.
    Task {
        index: usize,
        start: usize,
        end: usize,
        bounds: Bounds,
        depth: u32,
    },
    /// A node above the tasks, with its 2 to 4 children.
    Joint(Vec<Top>),
}

/// What a task returns: its root, the root's summary, the duplicates it
/// collapsed and its node list (references local to the list).
type Built = (NodeRef, Summary, u64, Vec<Interior>);

/// Builds the tree of `leaves` (bounds `all`); returns its interior nodes,
/// root and collapsed-duplicate count.
pub(super) fn build(
    leaves: &mut [Leaf],
    all: Bounds,
    progress: &dyn Progress,
) -> (InteriorNodes, NodeRef, u64) {
    let cut = (leaves.len() / TASKS).max(TASK_MIN);
    let mut top = split_top(leaves, 0, all, 0, cut);
    let mut tasks = Vec::new();
    list_tasks(&mut top, &mut tasks);
    // The tasks' ranges follow each other from 0: cut the leaves there.
    let mut work = Vec::with_capacity(tasks.len());
    let mut rest = leaves;
    for &(start, end, bounds, depth) in &tasks {
        let (range, tail) = std::mem::take(&mut rest).split_at_mut(end - start);
        // The node list is allocated here, on the calling thread: its
        // allocator heap holds the scene's freed memory, which a worker
        // thread's heap cannot reuse.
        let nodes = Vec::with_capacity(interior_capacity(range.len()));
        work.push((range, start, bounds, depth, nodes));
        rest = tail;
    }
    let built: Vec<Built> = work
        .into_par_iter()
        .map(|(range, start, bounds, depth, mut nodes)| {
            let (root, summary, collapsed) = build_range(range, bounds, start, depth, &mut nodes);
            progress.advance(range.len() as u64);
            // The unused room, freed: on huge pages up to 2 MiB of it per
            // task would be resident.
            nodes.shrink_to_fit();
            (root, summary, collapsed, nodes)
        })
        .collect();

    let mut roots = Vec::with_capacity(built.len());
    let mut collapsed = 0;
    let mut lists = Vec::with_capacity(built.len());
    let mut offset = 0;
    for (root, summary, dup, nodes) in built {
        roots.push((shifted(root, offset), summary));
        collapsed += dup;
        let len = nodes.len();
        lists.push((offset, nodes));
        offset += len;
    }
    lists.par_iter_mut().for_each(|(offset, nodes)| {
        for node in nodes.iter_mut() {
            for c in &mut node.children[..usize::from(node.child_count)] {
                *c = shifted(*c, *offset);
            }
        }
    });
    let mut interior = InteriorNodes::default();
    for (_, nodes) in lists {
        interior.push_part(nodes);
    }
    let mut joints = Vec::new();
    let first_joint = interior.len();
    let (root, _) = join_top(&top, &roots, first_joint, &mut joints);
    interior.push_part(joints);
    (interior, root, collapsed)
}

/// Splits `leaves` (global start `base`) into child ranges until they hold
/// at most `cut` leaves, the children of each node concurrently.
fn split_top(leaves: &mut [Leaf], base: usize, bounds: Bounds, depth: u32, cut: usize) -> Top {
    if leaves.len() <= cut || bounds.0 == bounds.1 {
        return Top::Task {
            index: 0,
            start: base,
            end: base + leaves.len(),
            bounds,
            depth,
        };
    }
    let (ranges, count) = child_ranges(leaves, bounds, depth);
    let mut children = Vec::with_capacity(count);
    let mut rest = leaves;
    for &(start, end, b) in &ranges[..count] {
        let (range, tail) = std::mem::take(&mut rest).split_at_mut(end - start);
        children.push((range, base + start, b));
        rest = tail;
    }
    Top::Joint(
        children
            .into_par_iter()
            .map(|(range, start, b)| split_top(range, start, b, depth + 2, cut))
            .collect(),
    )
}

/// Numbers the tasks of `top` in order and lists them: (start, end,
/// bounds, depth).
fn list_tasks(top: &mut Top, out: &mut Vec<(usize, usize, Bounds, u32)>) {
    match top {
        Top::Task {
            index,
            start,
            end,
            bounds,
            depth,
        } => {
            *index = out.len();
            out.push((*start, *end, *bounds, *depth));
        }
        Top::Joint(children) => children.iter_mut().for_each(|c| list_tasks(c, out)),
    }
}

/// Makes the nodes above the tasks, bottom-up, into `joints` (whose first
/// node will have index `first_joint`); `roots` holds each task's root and
/// summary. Returns the node made for `top` and its summary.
fn join_top(
    top: &Top,
    roots: &[(NodeRef, Summary)],
    first_joint: usize,
    joints: &mut Vec<Interior>,
) -> (NodeRef, Summary) {
    match top {
        Top::Task { index, .. } => roots[*index],
        Top::Joint(children) => {
            let mut refs = [NodeRef::leaf(0); 4];
            let mut summaries = Vec::with_capacity(children.len());
            for (slot, child) in refs.iter_mut().zip(children) {
                let (r, s) = join_top(child, roots, first_joint, joints);
                *slot = r;
                summaries.push(s);
            }
            let (node, summary) = parent_of(&summaries, refs);
            joints.push(node);
            (NodeRef::interior(first_joint + joints.len() - 1), summary)
        }
    }
}

/// `r` with an interior index moved up by `offset`; leaves as they are.
fn shifted(r: NodeRef, offset: usize) -> NodeRef {
    match r.get() {
        Ok(_) => r,
        Err(j) => NodeRef::interior(j + offset),
    }
}
