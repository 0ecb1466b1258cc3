//! The levels above the chunks: a bounding-sphere tree over the chunks'
//! roots, split as the in-memory tree splits its leaves (bisection of the
//! longest axis, each half once more, 2 to 4 children), then quantized
//! top-down from the header's sphere. Its output is the file's first
//! levels, as sibling groups in breadth-first order, and the quantized
//! sphere of each chunk's root, which the chunk's own levels are quantized
//! against.

use glam::DVec3;

use super::chunk::ChunkRoot;
use crate::spheres::layout::{NodeValues, encode_node, header_sphere};
use crate::spheres::tree::{NodeRef, Summary, parent_of};
use farfield_protocol::sphere_codec::NodeLayout;

/// A child in the levels above the chunks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum TopRef {
    /// A node of the top.
    Node(usize),
    /// A chunk's root.
    Chunk(usize),
}

/// A sibling group of the top, quantized: its packed records and what each
/// record is.
#[derive(Debug)]
pub(crate) struct TopGroup {
    pub records: Vec<u8>,
    pub members: Vec<TopRef>,
}

/// The quantized levels above the chunks.
#[derive(Debug)]
pub(crate) struct TopLayout {
    /// The header's sphere, which the root is quantized against.
    pub header_sphere: (DVec3, f64),
    /// Every group: the root's alone first, then breadth-first.
    pub groups: Vec<TopGroup>,
    /// The group of each top node's children.
    pub group_of_node: Vec<usize>,
    /// Each chunk root's quantized sphere.
    pub chunk_spheres: Vec<(DVec3, f64)>,
}

struct TopNode {
    values: NodeValues,
    children: Vec<TopRef>,
}

/// Builds and quantizes the levels above `roots` (at least one).
pub(crate) fn lay_out_top(roots: &[ChunkRoot], layout: NodeLayout) -> TopLayout {
    let mut nodes = Vec::new();
    let mut items: Vec<usize> = (0..roots.len()).collect();
    let (root, root_summary) = build(roots, &mut items, &mut nodes);
    let root_values = match root {
        TopRef::Node(n) => nodes[n].values,
        TopRef::Chunk(c) => roots[c].values,
    };
    let header = header_sphere(
        (root_summary.center, root_summary.radius),
        root_values.children > 0,
    );
    let mut out = TopLayout {
        header_sphere: header,
        groups: Vec::new(),
        group_of_node: vec![usize::MAX; nodes.len()],
        chunk_spheres: vec![(DVec3::ZERO, 0.0); roots.len()],
    };
    let node_bytes = layout.bytes() as usize;
    // Breadth-first: (a group's members, their parent's quantized sphere,
    // the node whose children they are).
    let mut queue = std::collections::VecDeque::from([(vec![root], header, None)]);
    while let Some((members, (pc, pr), parent)) = queue.pop_front() {
        let mut records = Vec::with_capacity(members.len() * node_bytes);
        for &m in &members {
            let values = match m {
                TopRef::Node(n) => nodes[n].values,
                TopRef::Chunk(c) => roots[c].values,
            };
            let (record, decoded) = encode_node(values, pc, pr, layout);
            records.extend_from_slice(&record.pack(layout).to_le_bytes()[..node_bytes]);
            match m {
                TopRef::Node(n) => {
                    queue.push_back((std::mem::take(&mut nodes[n].children), decoded, Some(n)))
                }
                TopRef::Chunk(c) => out.chunk_spheres[c] = decoded,
            }
        }
        if let Some(n) = parent {
            out.group_of_node[n] = out.groups.len();
        }
        out.groups.push(TopGroup { records, members });
    }
    out
}

/// The subtree over the chunk roots `items`: a chunk alone, or a node of
/// 2 to 4 children.
fn build(roots: &[ChunkRoot], items: &mut [usize], nodes: &mut Vec<TopNode>) -> (TopRef, Summary) {
    if let [only] = items {
        return (TopRef::Chunk(*only), roots[*only].summary);
    }
    let mid = split(roots, items);
    let (left, right) = items.split_at_mut(mid);
    let mut parts: Vec<&mut [usize]> = Vec::with_capacity(4);
    for half in [left, right] {
        if half.len() > 1 {
            let m = split(roots, half);
            let (a, b) = half.split_at_mut(m);
            parts.push(a);
            parts.push(b);
        } else {
            parts.push(half);
        }
    }
    let mut children = Vec::with_capacity(4);
    let mut summaries = Vec::with_capacity(4);
    for part in parts {
        let (child, summary) = build(roots, part, nodes);
        children.push(child);
        summaries.push(summary);
    }
    // The references are the top's own (`children`); the interior node
    // made here serves for its values.
    let (interior, summary) = parent_of(&summaries, [NodeRef::leaf(0); 4]);
    nodes.push(TopNode {
        values: NodeValues::interior(&interior),
        children,
    });
    (TopRef::Node(nodes.len() - 1), summary)
}

/// Splits `items` (two or more) at the middle of their centers' box along
/// its longest axis, or at the median when that leaves a side empty;
/// returns the split index, strictly inside.
fn split(roots: &[ChunkRoot], items: &mut [usize]) -> usize {
    let center = |i: usize| roots[i].summary.center;
    let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
    for &i in items.iter() {
        lo = lo.min(center(i));
        hi = hi.max(center(i));
    }
    let axis = (hi - lo).max_position();
    items.sort_by(|&a, &b| center(a)[axis].total_cmp(&center(b)[axis]).then(a.cmp(&b)));
    let plane = lo[axis] + (hi[axis] - lo[axis]) * 0.5;
    let mid = items.partition_point(|&i| center(i)[axis] < plane);
    if mid > 0 && mid < items.len() {
        mid
    } else {
        items.len() / 2
    }
}
