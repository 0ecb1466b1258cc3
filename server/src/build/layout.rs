//! Quantization and the breadth-first page layout (QSplat 3.1 and 3.2).
//!
//! Nodes are visited level by level. Each sibling group is quantized
//! against its parent's *quantized* sphere, top-down, so quantization error
//! never accumulates with depth; an interior node's quantized sphere then
//! replaces its true one, since only its children still need it. Records go
//! into pages in breadth-first order; a page holds whole sibling groups and
//! page 0 ends on a level boundary, so it is a complete coarse model.

use farfield_protocol::file::{AttributeFlags, FileHeader, HierarchyKind, PageEntry, place_pages};
use farfield_protocol::page::{PAGE_CHECKSUM_BYTES, PAGE_HEADER_BYTES, PageHeader, encode_page};
use farfield_protocol::sphere_codec::{self, ChildCount, NodeLayout, NodeRecord};
use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::leaves::{cone_from_u8, unpack_normal};
use super::tree::{NodeRef, Tree};

/// A finished file: header and page bytes, ready to be written.
#[derive(Debug)]
pub struct PagedFile {
    pub header: FileHeader,
    pub pages: Vec<Vec<u8>>,
    /// With [`LayoutInput::record_leaf_sources`]: (source vertex, node
    /// index) for every leaf, so tests can find a vertex's quantized sphere.
    pub leaf_sources: Vec<(u32, u64)>,
}

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
pub fn lay_out(mut tree: Tree, input: LayoutInput) -> PagedFile {
    let node_bytes = input.layout.bytes() as usize;
    let mut pages = PageCutter::new(input.page_bytes, node_bytes);
    let (root_center, root_radius) = match tree.root.get() {
        Ok(l) => (tree.leaves[l].position, f64::from(tree.leaves[l].radius)),
        Err(i) => (tree.interior[i].center, tree.interior[i].radius),
    };
    // A zero-size root (one point of radius 0) still needs a positive scale.
    let root_radius = if root_radius > 0.0 { root_radius } else { 1.0 };
    // The header sphere holds the root as it will be stored (with its slack
    // when it has children), so the root's own code is the identity.
    let root_radius = if tree.root.get().is_err() {
        root_radius * (1.0 + INTERIOR_SLACK) * (1.0 + 1e-12)
    } else {
        root_radius
    };

    let mut level: Vec<NodeRef> = vec![tree.root];
    let mut next: Vec<NodeRef> = Vec::new();
    let mut depth = 0u32;
    let mut nodes = 0u64;
    let mut leaves = 0u64;
    // Breadth-first index of the next child to be placed.
    let mut next_child = 1u64;
    let mut leaf_sources = Vec::new();
    // The root forms its own group, quantized against the header sphere.
    let root = tree.root;
    let (root_record, root_update) = quantize(&tree, root, root_center, root_radius, input.layout);
    apply(&mut tree, root_update);
    pages.start_group(depth);
    pages.push(root_record.pack(input.layout), next_child);
    next_child += root_record.children.get() as u64;
    nodes += 1;
    if let Ok(l) = root.get() {
        leaves += 1;
        if input.record_leaf_sources {
            leaf_sources.push((tree.leaves[l].source, 0));
        }
    }
    pages.end_group();
    while !level.is_empty() {
        pages.end_level();
        depth += 1;
        next.clear();
        let parents: Vec<usize> = level.iter().filter_map(|r| r.get().err()).collect();
        for chunk in parents.chunks(LAYOUT_CHUNK) {
            // Quantize this chunk's sibling groups on all threads (each reads
            // only its parent's already-quantized sphere), then place them in
            // order and record the children's quantized spheres.
            let groups: Vec<[(NodeRecord, NodeRef, Update); 4]> = chunk
                .par_iter()
                .map(|&p| {
                    let node = &tree.interior[p];
                    let mut group = [(NodeRecord::EMPTY, NodeRef::leaf(0), None); 4];
                    for (slot, &child) in group
                        .iter_mut()
                        .zip(&node.children[..usize::from(node.child_count)])
                    {
                        let (record, update) =
                            quantize(&tree, child, node.center, node.radius, input.layout);
                        *slot = (record, child, update);
                    }
                    group
                })
                .collect();
            for (&p, group) in chunk.iter().zip(&groups) {
                pages.start_group(depth);
                for &(record, child, update) in &group[..usize::from(tree.interior[p].child_count)]
                {
                    pages.push(record.pack(input.layout), next_child);
                    next_child += record.children.get() as u64;
                    apply(&mut tree, update);
                    match child.get() {
                        Err(_) => next.push(child),
                        Ok(l) => {
                            leaves += 1;
                            if input.record_leaf_sources {
                                leaf_sources.push((tree.leaves[l].source, nodes));
                            }
                        }
                    }
                    nodes += 1;
                }
                pages.end_group();
            }
        }
        std::mem::swap(&mut level, &mut next);
    }
    let (mut pages_dir, page_bytes) = pages.finish();
    // Pages follow the header; offsets are known once the page count is.
    place_pages(&mut pages_dir);
    let header = FileHeader {
        cluster: 0,
        kind: HierarchyKind::Spheres,
        attributes: AttributeFlags {
            color: input.layout.color,
            normals: input.layout.normals,
            leaf_geometry: false,
        },
        node_bytes: node_bytes as u32,
        levels: depth,
        nodes,
        leaves,
        input_vertices: input.input_vertices,
        bounds_min: input.bounds_min,
        bounds_max: input.bounds_max,
        root_center,
        root_radius,
        pages: pages_dir,
    };
    PagedFile {
        header,
        pages: page_bytes,
        leaf_sources,
    }
}

/// Parents quantized per parallel batch: enough work to share between
/// threads, little enough memory to hold the batch's records.
const LAYOUT_CHUNK: usize = 1 << 14;

/// An interior node's quantized sphere, to replace its true one.
type Update = Option<(usize, DVec3, f64)>;

fn apply(tree: &mut Tree, update: Update) {
    if let Some((i, center, radius)) = update {
        tree.interior[i].center = center;
        tree.interior[i].radius = radius;
    }
}

/// Quantizes one node against its parent's quantized sphere. For an
/// interior node also returns its quantized sphere, which replaces the true
/// one once the level is placed: only its children still need it.
fn quantize(
    tree: &Tree,
    node: NodeRef,
    parent_center: DVec3,
    parent_radius: f64,
    layout: NodeLayout,
) -> (NodeRecord, Update) {
    let (center, radius, normal, cone, color, children) = match node.get() {
        Ok(l) => {
            let leaf = tree.leaves[l];
            (
                leaf.position,
                f64::from(leaf.radius),
                unpack_normal(leaf.normal),
                cone_from_u8(leaf.cone),
                leaf.color,
                0,
            )
        }
        Err(i) => {
            let n = tree.interior[i];
            (
                n.center,
                n.radius,
                n.normal,
                f64::from(n.cone),
                n.color,
                usize::from(n.child_count),
            )
        }
    };
    // An interior node is stored a little larger than its children need, so
    // that children touching its true boundary still quantize to spheres
    // inside it (see INTERIOR_SLACK).
    let stored_radius = if children > 0 {
        radius * (1.0 + INTERIOR_SLACK)
    } else {
        radius
    };
    let sphere = sphere_codec::encode_sphere(parent_center, parent_radius, center, stored_radius);
    let update = node.get().err().map(|i| {
        let (qc, qr) = sphere_codec::decode_sphere(parent_center, parent_radius, sphere);
        (i, qc, qr)
    });
    let (normal_code, cone_code) = if layout.normals {
        encode_orientation(normal, cone)
    } else {
        (0, 3)
    };
    let record = NodeRecord {
        sphere,
        children: ChildCount::new(children).unwrap_or(ChildCount::LEAF),
        normal: normal_code,
        cone: cone_code,
        color: if layout.color {
            sphere_codec::encode_color(color)
        } else {
            0
        },
    };
    (record, update)
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

/// Accumulates records into pages of at most `page_bytes`, never splitting a
/// sibling group, ending page 0 on a level boundary.
struct PageCutter {
    page_bytes: usize,
    node_bytes: usize,
    records: Vec<u8>,
    group: Vec<u8>,
    group_level: u32,
    /// first_child of the first node in the current group / page.
    group_first_child: Option<u64>,
    page: Option<PageHeader>,
    /// Page 0's records up to the last complete level.
    page0_done: bool,
    page0_level_end: usize,
    page0_level_count: (u32, u64),
    entries: Vec<PageEntry>,
    pages: Vec<Vec<u8>>,
    next_node: u64,
}

impl PageCutter {
    fn new(page_bytes: usize, node_bytes: usize) -> Self {
        let page_bytes = page_bytes.max(PAGE_HEADER_BYTES + PAGE_CHECKSUM_BYTES + 4 * node_bytes);
        Self {
            page_bytes,
            node_bytes,
            records: Vec::new(),
            group: Vec::new(),
            group_level: 0,
            group_first_child: None,
            page: None,
            page0_done: false,
            page0_level_end: 0,
            page0_level_count: (0, 0),
            entries: Vec::new(),
            pages: Vec::new(),
            next_node: 0,
        }
    }

    fn capacity(&self) -> usize {
        self.page_bytes - PAGE_HEADER_BYTES - PAGE_CHECKSUM_BYTES
    }

    fn start_group(&mut self, level: u32) {
        self.group.clear();
        self.group_level = level;
        self.group_first_child = None;
    }

    fn push(&mut self, record: u64, first_child: u64) {
        self.group_first_child.get_or_insert(first_child);
        self.group
            .extend_from_slice(&record.to_le_bytes()[..self.node_bytes]);
    }

    fn end_group(&mut self) {
        let group_nodes = (self.group.len() / self.node_bytes) as u64;
        if self.page.is_some() && self.records.len() + self.group.len() > self.capacity() {
            if self.entries.is_empty() {
                self.flush_page0();
            } else {
                self.flush();
            }
        }
        let first_child = self.group_first_child.unwrap_or(0);
        let level = self.group_level as u16;
        let page = self.page.get_or_insert(PageHeader {
            index: self.entries.len() as u32,
            first_node: self.next_node,
            first_child,
            node_count: 0,
            level_min: level,
            level_max: level,
        });
        page.node_count += group_nodes as u32;
        page.level_max = level;
        self.next_node += group_nodes;
        self.records.extend_from_slice(&self.group);
    }

    /// Called after each complete level: remembers where page 0 could end.
    fn end_level(&mut self) {
        if self.entries.is_empty()
            && !self.page0_done
            && let Some(p) = &self.page
        {
            self.page0_level_end = self.records.len();
            self.page0_level_count = (u32::from(p.level_max), u64::from(p.node_count));
        }
    }

    /// Ends page 0 at the last complete level; what follows starts page 1.
    fn flush_page0(&mut self) {
        self.page0_done = true;
        let Some(page) = self.page.take() else { return };
        let (level_max, count) = self.page0_level_count;
        if count == 0 || count == u64::from(page.node_count) {
            self.page = Some(page);
            self.flush();
            return;
        }
        let head = PageHeader {
            node_count: count as u32,
            level_max: level_max as u16,
            ..page
        };
        let tail_records = self.records.split_off(self.page0_level_end);
        self.page = Some(head);
        self.flush();
        // The rest of the open page becomes the start of page 1. Its first
        // child is found by walking the child counts of page 0's records.
        let first_child = page0_next_child(&self.pages[0], head, self.node_bytes);
        self.records = tail_records;
        self.page = Some(PageHeader {
            index: 1,
            first_node: head.first_node + count,
            first_child,
            node_count: page.node_count - count as u32,
            level_min: level_max as u16 + 1,
            level_max: page.level_max,
        });
        if self.records.len() > self.capacity() {
            self.flush();
        }
    }

    fn flush(&mut self) {
        let Some(header) = self.page.take() else {
            return;
        };
        let (bytes, checksum) = encode_page(&header, &self.records);
        self.entries
            .push(PageEntry::of(&header, bytes.len(), checksum));
        self.pages.push(bytes);
        self.records.clear();
    }

    fn finish(mut self) -> (Vec<PageEntry>, Vec<Vec<u8>>) {
        self.flush();
        (self.entries, self.pages)
    }
}

/// The breadth-first index of the first child of the node after page 0.
fn page0_next_child(page0: &[u8], header: PageHeader, node_bytes: usize) -> u64 {
    let records = &page0[PAGE_HEADER_BYTES..page0.len() - PAGE_CHECKSUM_BYTES];
    let mut next = header.first_child;
    for chunk in records.chunks_exact(node_bytes) {
        let mut word = [0u8; 8];
        word[..node_bytes].copy_from_slice(chunk);
        next += NodeRecord::child_count(u64::from_le_bytes(word)) as u64;
    }
    next
}
