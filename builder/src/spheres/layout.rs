//! Quantization and the breadth-first page layout (QSplat 3.1 and 3.2).
//!
//! Nodes are visited level by level. Each sibling group is quantized
//! against its parent's *quantized* sphere, top-down, so quantization error
//! never accumulates with depth; an interior node's quantized sphere
//! replaces its true one in the tree (through [`SharedNodes`]), where its
//! children find it at the next level. Records go
//! into pages in breadth-first order; a page holds whole sibling groups and
//! page 0 ends on a level boundary, so it is a complete coarse model.

use farfield_protocol::FormatError;
use farfield_protocol::file::{AttributeFlags, FileHeader, HierarchyKind};
use farfield_protocol::paged_file::PagedFile;
use farfield_protocol::sphere_codec::{self, ChildCount, NodeLayout, NodeRecord};
use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::leaves::{Leaf, cone_from_u8, unpack_normal};
use super::page_cutter::{GroupSink, PageCutter};
use super::tree::{Interior, NodeRef, SharedNodes, Tree};
use crate::progress::Progress;

/// What `lay_out` needs besides the tree.
#[derive(Debug, Clone, Copy)]
pub struct LayoutInput {
    pub layout: NodeLayout,
    pub page_bytes: usize,
    pub input_vertices: u64,
    pub bounds_min: DVec3,
    pub bounds_max: DVec3,
    pub record_leaf_sources: bool,
}

/// Quantizes the tree and cuts it into pages.
/// `progress` counts the nodes placed in pages.
pub fn lay_out(
    tree: Tree,
    input: LayoutInput,
    progress: &dyn Progress,
) -> Result<PagedFile, FormatError> {
    let node_bytes = input.layout.bytes() as usize;
    let mut pages = PageCutter::new(input.page_bytes, node_bytes);
    // Every node is placed once: the interior ones and the leaves the tree
    // references (a collapsed duplicate stays in the list, unreferenced).
    let total_nodes = (tree.interior.len() + tree.leaves.len()) as u64 - tree.collapsed_duplicates;
    let (root_center, root_radius) = header_sphere(tree.root_sphere(), tree.root.get().is_err());
    let root = tree.root;
    // The root forms its own group, quantized against the header sphere.
    let (root_record, decoded) = encode_node(
        NodeValues::of(&tree, root),
        root_center,
        root_radius,
        input.layout,
    );
    let root_bytes = root_record.pack(input.layout).to_le_bytes();
    pages.add_group(0, &root_bytes[..node_bytes], 1);
    progress.begin("layout", total_nodes);
    progress.advance(1);
    let mut leaf_sources = Vec::new();
    if let Ok(l) = root.get()
        && input.record_leaf_sources
    {
        leaf_sources.push((tree.leaves[l].source, 0));
    }
    let placed = place_levels(
        tree,
        decoded,
        LevelOptions {
            layout: input.layout,
            first_child: 1 + root_record.children.get() as u64,
            leaf_sources: input.record_leaf_sources.then_some(&mut leaf_sources),
        },
        &mut pages,
        progress,
    );
    let mut file = pages.finish().finish(FileHeader {
        cluster: 0,
        kind: HierarchyKind::Spheres,
        attributes: AttributeFlags {
            color: input.layout.color,
            normals: input.layout.normals,
            leaf_geometry: false,
        },
        node_bytes: node_bytes as u32,
        levels: placed.levels,
        nodes: placed.nodes,
        leaves: placed.leaves,
        input_vertices: input.input_vertices,
        bounds_min: input.bounds_min,
        bounds_max: input.bounds_max,
        root_center,
        root_radius,
        page_count: 0,
        directory_pages: 0,
        root_directory: Default::default(),
    })?;
    file.leaf_sources = leaf_sources;
    Ok(file)
}

/// The sphere the header stores for a root of `center` and `radius`: the
/// root as it will be stored (with its slack when it has children), so the
/// root's own code is the identity; a zero-size root (one point of radius
/// 0) still gets a positive scale.
pub(crate) fn header_sphere((center, radius): (DVec3, f64), has_children: bool) -> (DVec3, f64) {
    let radius = if radius > 0.0 { radius } else { 1.0 };
    if has_children {
        (center, radius * (1.0 + INTERIOR_SLACK) * (1.0 + 1e-12))
    } else {
        (center, radius)
    }
}

/// What [`place_levels`] needs besides the tree and its root's sphere.
pub(crate) struct LevelOptions<'a> {
    pub layout: NodeLayout,
    /// Breadth-first index of the first child of the root's first child.
    pub first_child: u64,
    /// (source vertex, node index) of each leaf placed, when asked for;
    /// node indices count from the root, which is node 0.
    pub leaf_sources: Option<&'a mut Vec<(u32, u64)>>,
}

/// What [`place_levels`] placed, the root included.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Placed {
    pub nodes: u64,
    pub leaves: u64,
    /// Levels, the root's counting as one.
    pub levels: u32,
}

/// Quantizes every level of `tree` below its root, whose quantized sphere
/// is `root_sphere`, into `sink` in breadth-first order. `progress` is
/// advanced by the nodes placed (the root is the caller's).
pub(crate) fn place_levels(
    tree: Tree,
    root_sphere: (DVec3, f64),
    options: LevelOptions<'_>,
    sink: &mut dyn GroupSink,
    progress: &dyn Progress,
) -> Placed {
    let node_bytes = options.layout.bytes() as usize;
    let layout = options.layout;
    let mut leaf_sources = options.leaf_sources;
    let Tree {
        leaves: leaf_list,
        mut interior,
        root,
        ..
    } = tree;
    // Each interior node's sphere is replaced by its quantized one as soon
    // as it is quantized: its children are quantized against that, and its
    // true sphere is not needed again. So a level is a list of node
    // indices, not of spheres.
    let tree = LayoutTree {
        leaves: &leaf_list,
        nodes: interior.shared(),
    };

    let mut nodes = 1u64;
    let mut leaves = 0u64;
    // Breadth-first index of the next child to be placed.
    let mut next_child = options.first_child;
    let mut windows = Windows::default();
    match root.get() {
        Err(node) => {
            // SAFETY: no other thread runs yet.
            unsafe { tree.nodes.set_sphere(node, root_sphere.0, root_sphere.1) };
            windows.next.push(vec![node as u32]);
        }
        Ok(_) => leaves += 1,
    }
    let mut nodes_reported = 1;
    // Records are placed in order, on one thread: the only serial
    // work. Each window is placed while the next one is quantized on the
    // pool's threads, so they are not idle meanwhile. The placing stays on
    // this thread, whose allocator heap holds the memory freed by earlier
    // steps: pages made on a worker thread came from fresh memory and
    // raised the island's peak by 4 %.
    let mut place = |window: Window, placed: Vec<PlacedGroups>| {
        if window.starts_level {
            sink.end_level();
        }
        debug_assert_eq!(window.tasks().count(), placed.len());
        for (parents, placed) in window.tasks().zip(placed) {
            let mut offset = 0;
            for (&parent, &(count, grandchildren)) in parents.iter().zip(&placed.groups) {
                let end = offset + usize::from(count) * node_bytes;
                sink.add_group(window.depth, &placed.bytes[offset..end], next_child);
                offset = end;
                if let Some(sources) = leaf_sources.as_deref_mut() {
                    // SAFETY: a read of a parent of this window; the tasks
                    // running now write only children of the next window's
                    // parents, which lie a level or two below it.
                    let node = unsafe { tree.nodes.get(parent as usize) };
                    for (i, child) in node.children[..usize::from(count)].iter().enumerate() {
                        if let Ok(l) = child.get() {
                            sources.push((leaf_list[l].source, nodes + i as u64));
                        }
                    }
                }
                next_child += u64::from(grandchildren);
                nodes += u64::from(count);
            }
            leaves += placed.leaves;
        }
        progress.advance(nodes - nodes_reported);
        nodes_reported = nodes;
    };
    let mut pending = None;
    loop {
        let window = windows.take();
        if window.is_none() && pending.is_none() {
            break;
        }
        let mut quantized = None;
        rayon::in_place_scope(|scope| {
            scope.spawn(|_| {
                quantized = window.map(|window| {
                    let tasks: Vec<&[u32]> = window.tasks().collect();
                    let placed: Vec<PlacedGroups> = tasks
                        .par_iter()
                        // SAFETY: a task reads its parents (quantized at
                        // the level above, by tasks that have finished) and
                        // reads, then writes, their children. A node has one
                        // parent and a parent is in one task, so no node is
                        // written by two tasks or read by one while another
                        // writes it; the placement beside only reads
                        // parents of its own window.
                        .map(|parents| unsafe { tree.quantize_groups(parents, layout) })
                        .collect();
                    (window, placed)
                });
            });
            if let Some((window, placed)) = pending.take() {
                place(window, placed);
            }
        });
        if let Some((_, placed)) = &mut quantized {
            // The next level, in order: complete once this level's last
            // window is quantized, before its first window is taken.
            for p in placed {
                let next = std::mem::take(&mut p.next);
                if !next.is_empty() {
                    windows.next.push(next);
                }
            }
        }
        pending = quantized;
    }
    Placed {
        nodes,
        leaves,
        // `depth` is the deepest level's index (the root's is 0); the
        // header counts levels, the root alone being one.
        levels: windows.depth + 1,
    }
}

/// Parents whose sibling groups are quantized per window: enough work to
/// share between threads, little enough memory to hold their records.
const LAYOUT_CHUNK: usize = 1 << 15;
/// Parents per parallel task within a window, at most.
const LAYOUT_GRAIN: usize = 1 << 10;

/// Parents per parallel task for a window of `parents`: at most
/// [`LAYOUT_GRAIN`], and small enough that the window makes about four
/// tasks per thread, so the levels of a small model (a few thousand
/// parents) are shared between threads too instead of running as one or
/// two tasks; not so small that a task's bookkeeping outweighs its work.
/// (horse.ply's and igea.ply's layouts ran 5-6 % faster than with a fixed
/// 1024; the records and pages do not depend on it. On many threads a large
/// model's tasks get smaller too, and the next level is held as more,
/// shorter lists.)
fn layout_grain(parents: usize) -> usize {
    (parents / (4 * rayon::current_num_threads())).clamp(64, LAYOUT_GRAIN)
}

/// The parents whose sibling groups are quantized together (about
/// [`LAYOUT_CHUNK`] of them, all of one level), as the lists they came in.
struct Window {
    /// The level of its parents' children, which its records are.
    depth: u32,
    /// Whether this is its level's first window: pages mark level ends.
    starts_level: bool,
    lists: Vec<Vec<u32>>,
    parents: usize,
    /// Parents per task, fixed when the window is cut: the quantizing and
    /// the placing must cut the same tasks, and they run on different
    /// threads.
    grain: usize,
}

impl Window {
    /// The parents of each parallel task, in order.
    fn tasks(&self) -> impl Iterator<Item = &[u32]> {
        self.lists.iter().flat_map(|list| list.chunks(self.grain))
    }
}

/// The levels' interior nodes, cut into windows of about [`LAYOUT_CHUNK`]
/// parents. A level is held as the lists the tasks of the level above
/// produced (each exactly sized): joining them into one vector would hold a
/// level twice, and growing it would hold it up to three times, at the
/// build's memory peak. Windows are freed once placed.
#[derive(Default)]
struct Windows {
    current: std::vec::IntoIter<Vec<u32>>,
    /// The next level's lists, pushed as this level's windows are quantized.
    next: Vec<Vec<u32>>,
    /// The level of the current windows' children (the root's is 0); once
    /// all are taken, the deepest level.
    depth: u32,
}

impl Windows {
    /// The next window, moving on to the next level when this one is used
    /// up; `None` once the next level is empty too.
    fn take(&mut self) -> Option<Window> {
        let starts_level = self.current.as_slice().is_empty();
        if starts_level {
            if self.next.is_empty() {
                return None;
            }
            self.current = std::mem::take(&mut self.next).into_iter();
            self.depth += 1;
        }
        let mut window = Window {
            depth: self.depth,
            starts_level,
            lists: Vec::new(),
            parents: 0,
            grain: 0,
        };
        while window.parents < LAYOUT_CHUNK
            && let Some(list) = self.current.next()
        {
            window.parents += list.len();
            window.lists.push(list);
        }
        window.grain = layout_grain(window.parents);
        Some(window)
    }
}

/// One task's output: the packed records of its parents' children, in
/// order; per parent, the number of children and of grandchildren (the
/// group's size and how far it moves the next child index); how many of
/// the children are leaves; and those that are interior nodes, for the
/// next level.
struct PlacedGroups {
    bytes: Vec<u8>,
    groups: Vec<(u8, u8)>,
    leaves: u64,
    next: Vec<u32>,
}

/// The tree as the layout sees it: leaves to read, and interior nodes whose
/// spheres become their quantized ones as the levels are placed.
struct LayoutTree<'a> {
    leaves: &'a [Leaf],
    nodes: SharedNodes<'a>,
}

impl LayoutTree<'_> {
    /// Quantizes the children of `parents`, whose spheres are already the
    /// quantized ones.
    ///
    /// # Safety
    ///
    /// While this runs, no other thread may write `parents`, nor touch
    /// their children.
    unsafe fn quantize_groups(&self, parents: &[u32], layout: NodeLayout) -> PlacedGroups {
        let node_bytes = layout.bytes() as usize;
        // SAFETY (here and below): the parents are only read, and their
        // children are this task's alone (the caller's contract).
        let parent_nodes = || {
            parents
                .iter()
                .map(|&p| unsafe { self.nodes.get(p as usize) })
        };
        // Exact sizes, from the child references alone: these lists make up
        // the next level, which lives through the memory peak. (When a level
        // held 40-byte spheres, room for four children each, shrunk
        // afterwards, raised horse's peak by about 5 %: the heap's small
        // blocks are resident, used or not.)
        let (mut children, mut interior) = (0, 0);
        for node in parent_nodes() {
            let refs = &node.children[..usize::from(node.child_count)];
            children += refs.len();
            for child in refs {
                // Asked for now, used by the loop below: the children lie
                // scattered over the node and leaf arrays, and a task's
                // few thousand fit in the cache, so their loads overlap
                // instead of the quantizer waiting on each in turn (the
                // layout of gen:island ran 11-14 % faster).
                match child.get() {
                    Ok(l) => super::prefetch(&self.leaves[l]),
                    Err(i) => {
                        interior += 1;
                        self.nodes.prefetch(i);
                    }
                }
            }
        }
        let mut placed = PlacedGroups {
            bytes: Vec::with_capacity(children * node_bytes),
            groups: Vec::with_capacity(parents.len()),
            leaves: 0,
            next: Vec::with_capacity(interior),
        };
        for parent in parent_nodes() {
            let mut grandchildren = 0;
            for &child in &parent.children[..usize::from(parent.child_count)] {
                let record = unsafe { self.quantize(child, parent.center, parent.radius, layout) };
                placed
                    .bytes
                    .extend_from_slice(&record.pack(layout).to_le_bytes()[..node_bytes]);
                grandchildren += record.children.get() as u8;
                match child.get() {
                    Err(i) => placed.next.push(i as u32),
                    Ok(_) => placed.leaves += 1,
                }
            }
            placed.groups.push((parent.child_count, grandchildren));
        }
        placed
    }

    /// Quantizes one node against its parent's quantized sphere; an
    /// interior node's sphere is then replaced by its quantized one, the
    /// frame its own children are quantized in.
    ///
    /// # Safety
    ///
    /// While this runs, no other thread may touch `node`.
    unsafe fn quantize(
        &self,
        node: NodeRef,
        parent_center: DVec3,
        parent_radius: f64,
        layout: NodeLayout,
    ) -> NodeRecord {
        let values = match node.get() {
            Ok(l) => NodeValues::leaf(&self.leaves[l]),
            // SAFETY: the caller rules out other threads on this node.
            Err(i) => NodeValues::interior(&unsafe { self.nodes.get(i) }),
        };
        let (record, (center, radius)) = encode_node(values, parent_center, parent_radius, layout);
        if let Err(i) = node.get() {
            // SAFETY: as above.
            unsafe { self.nodes.set_sphere(i, center, radius) };
        }
        record
    }
}

/// What a node's record is made from, leaf or interior.
#[derive(Debug, Clone, Copy)]
pub(crate) struct NodeValues {
    pub center: DVec3,
    pub radius: f64,
    pub normal: Vec3,
    /// Normal-cone half-angle in radians.
    pub cone: f64,
    pub color: [u8; 3],
    pub children: usize,
}

impl NodeValues {
    pub(crate) fn leaf(leaf: &Leaf) -> Self {
        Self {
            center: leaf.position,
            radius: f64::from(leaf.radius),
            normal: unpack_normal(leaf.normal),
            cone: cone_from_u8(leaf.cone),
            color: leaf.color,
            children: 0,
        }
    }

    pub(crate) fn interior(node: &Interior) -> Self {
        Self {
            center: node.center,
            radius: node.radius,
            normal: node.normal,
            cone: f64::from(node.cone),
            color: node.color,
            children: usize::from(node.child_count),
        }
    }

    /// The values of `tree`'s node `node` (before any quantization).
    fn of(tree: &Tree, node: NodeRef) -> Self {
        match node.get() {
            Ok(l) => Self::leaf(&tree.leaves[l]),
            Err(i) => Self::interior(&tree.interior[i]),
        }
    }
}

/// A node's record, quantized against its parent's quantized sphere, and,
/// for an interior node, the sphere it decodes to (the frame of its own
/// children; a leaf's is not decoded).
pub(crate) fn encode_node(
    node: NodeValues,
    parent_center: DVec3,
    parent_radius: f64,
    layout: NodeLayout,
) -> (NodeRecord, (DVec3, f64)) {
    // An interior node is stored a little larger than its children need, so
    // that children touching its true boundary still quantize to spheres
    // inside it (see INTERIOR_SLACK).
    let stored_radius = if node.children > 0 {
        node.radius * (1.0 + INTERIOR_SLACK)
    } else {
        node.radius
    };
    let sphere =
        sphere_codec::encode_sphere(parent_center, parent_radius, node.center, stored_radius);
    // Only a parent's decoded sphere is ever used: leaves skip the decode,
    // which runs once per node of the build.
    let decoded = if node.children > 0 {
        sphere_codec::decode_sphere(parent_center, parent_radius, sphere)
    } else {
        (node.center, stored_radius)
    };
    let (normal_code, cone_code) = if layout.normals {
        encode_orientation(node.normal, node.cone)
    } else {
        (0, 3)
    };
    let record = NodeRecord {
        sphere,
        children: ChildCount::new(node.children).unwrap_or(ChildCount::LEAF),
        normal: normal_code,
        cone: cone_code,
        color: if layout.color {
            sphere_codec::encode_color(node.color)
        } else {
            0
        },
    };
    (record, decoded)
}

/// How much larger than its true sphere an interior node is stored.
///
/// Every bounding sphere touches some child from inside. A child touching
/// its parent's boundary can only be quantized inside the parent if it sits
/// exactly on a grid point; otherwise the smallest valid code is the parent
/// itself, and along a chain of such children (the corner of a flat scan)
/// a leaf decodes as large as the root. Storing each interior sphere 15%
/// larger leaves its children room to round into. Measured on a 500x500
/// grid of points: without slack the largest decoded leaf had the root's
/// radius (355 units for leaves of about 1.2); with 10% it was 2.6, with
/// 20% 2.3, while the bunny's mean leaf radius changed by under 2%.
/// (QSplat reports a mean radius error of 0.15 parent radii; its
/// quantizer pays this cost in another way the paper does not detail.)
pub const INTERIOR_SLACK: f64 = 0.15;

/// Normal and cone codes; the cone is widened by the largest normal
/// quantization error so culling by the stored values stays conservative.
fn encode_orientation(normal: Vec3, cone: f64) -> (u16, u8) {
    let code = sphere_codec::encode_normal(normal);
    (
        code,
        sphere_codec::encode_cone(cone + sphere_codec::MAX_NORMAL_ERROR),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_cut_levels_at_the_chunk_and_mark_each_levels_first() {
        let list = |start: u32, len: u32| (start..start + len).collect::<Vec<u32>>();
        let chunk = LAYOUT_CHUNK as u32;
        let mut windows = Windows::default();
        assert!(windows.take().is_none(), "no levels, no windows");
        windows.next = vec![list(0, chunk + 10), list(2 * chunk, 5)];

        let first = windows.take().unwrap();
        assert!(first.starts_level);
        assert_eq!((first.depth, first.parents), (1, chunk as usize + 10));
        // Its tasks are its parents, in order, each once; one long list
        // is shared between several tasks.
        let parents: Vec<u32> = first.tasks().flatten().copied().collect();
        assert_eq!(parents, list(0, chunk + 10));
        assert!(first.tasks().count() > 1, "one list, one task");

        let second = windows.take().unwrap();
        assert!(!second.starts_level);
        assert_eq!(
            (second.depth, second.lists.clone()),
            (1, vec![list(2 * chunk, 5)])
        );

        // The next level arrives as the last window is quantized.
        windows.next.push(list(7, 3));
        let third = windows.take().unwrap();
        assert!(third.starts_level);
        assert_eq!((third.depth, third.parents), (2, 3));
        assert!(windows.take().is_none());
        assert_eq!(windows.depth, 2, "the deepest level's depth is kept");
    }
}
