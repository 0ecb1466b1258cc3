//! [`Hierarchy`]: a file header plus the pages that are resident so far.
//!
//! The client fills it page by page as they stream in; `--file` rendering
//! and the tests fill it all at once. Each resident page keeps its records
//! as stored plus one prefix sum per node, so a node finds its first child
//! without reading the rest of its page (the file stores no pointers:
//! breadth-first order makes children positions a running sum of child
//! counts, see `FORMAT.md`).

use glam::{DVec3, Vec3};

use crate::FormatError;
use crate::bsp_codec::{BspSkeleton, ContentPage};
use crate::cube_codec::{self, Channels, CubeRecord, Payload};
use crate::directory::Directory;
use crate::file::FileHeader;
use crate::page::{Page, PageHeader};
use crate::plp_codec::{CellPage, Skeleton};
use crate::sphere_codec::{self, NodeLayout, NodeRecord};

/// One verified page, ready for traversal.
#[derive(Debug, Clone)]
pub struct ResidentPage {
    pub header: PageHeader,
    /// The records as stored, followed by 8 zero bytes so any record can be
    /// read as one unaligned little-endian u64 without a bounds-sized copy.
    records: Vec<u8>,
    /// For node i of the page: its first child's index minus
    /// `header.first_child`.
    child_offset: Vec<u32>,
    /// Bytes of the page as received (for cache accounting).
    pub byte_len: usize,
    /// What the page holds beyond its node records, decoded once on
    /// arrival: one payload, of the file's kind.
    payload: PagePayload,
}

/// A resident page's decoded contents, by hierarchy kind.
#[derive(Debug, Clone)]
pub enum PagePayload {
    /// Sphere pages are their node records (`ResidentPage::records`).
    Spheres,
    /// Color-cube pages: each cell's record and decoded payload.
    Cubes(CubePage),
    /// PLP pages: the skeleton (page 0) or cells' triangles.
    Plp(PlpPage),
    /// Image-caching BSP pages: the tree (page 0), a prototype or a leaf.
    Bsp(BspPage),
}

impl ResidentPage {
    /// The page's payload, whichever the kind.
    pub fn payload(&self) -> &PagePayload {
        &self.payload
    }

    /// A color-cube page's cells; `None` for other kinds.
    pub fn cubes(&self) -> Option<&CubePage> {
        match &self.payload {
            PagePayload::Cubes(c) => Some(c),
            _ => None,
        }
    }

    /// A PLP page's skeleton or cells; `None` for other kinds.
    pub fn plp(&self) -> Option<&PlpPage> {
        match &self.payload {
            PagePayload::Plp(p) => Some(p),
            _ => None,
        }
    }

    /// An image-caching BSP page's tree or content; `None` for other kinds.
    pub fn bsp(&self) -> Option<&BspPage> {
        match &self.payload {
            PagePayload::Bsp(b) => Some(b),
            _ => None,
        }
    }
}

/// A resident BSP page, decoded once on arrival.
#[derive(Debug, Clone)]
pub enum BspPage {
    /// Page 0: the tree, its boxes and the prototypes' sizes.
    Skeleton(Box<BspSkeleton>),
    /// A prototype's or a leaf's geometry.
    Content(ContentPage),
}

/// A resident PLP page, decoded once on arrival.
#[derive(Debug, Clone)]
pub enum PlpPage {
    /// Page 0: the whole tessellation.
    Skeleton(Box<Skeleton>),
    /// Cells and their triangles.
    Cells(CellPage),
}

/// The cells of a resident color-cube page, decoded once on arrival.
#[derive(Debug, Clone, Default)]
pub struct CubePage {
    pub records: Vec<CubeRecord>,
    /// Payloads of the cells that have one.
    pub payloads: Vec<Payload>,
    /// For each cell, its index in `payloads` ([`NO_PAYLOAD`] for none).
    pub payload_of: Vec<u32>,
}

/// [`CubePage::payload_of`] of a cell without payload.
pub const NO_PAYLOAD: u32 = u32::MAX;

impl CubePage {
    pub fn payload(&self, local: usize) -> Option<&Payload> {
        let i = *self.payload_of.get(local)?;
        self.payloads.get(i as usize)
    }
}

/// A node decoded to world units: what the reference decoder yields.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DecodedNode {
    pub index: u64,
    pub level: u32,
    pub center: DVec3,
    pub radius: f64,
    pub normal: Option<Vec3>,
    /// Cone half-angle in radians (`None` without normals).
    pub cone: Option<f64>,
    pub color: Option<[u8; 3]>,
    pub children: usize,
    pub first_child: u64,
}

/// The header of a scene and whichever of its pages are resident.
#[derive(Debug, Clone)]
pub struct Hierarchy {
    pub header: FileHeader,
    pub layout: NodeLayout,
    /// The directory known so far (all of it for a file read whole).
    directory: Directory,
    /// By page index, grown as pages arrive: a header's page count is
    /// never allocated for, so memory follows what was visited.
    pages: Vec<Option<Box<ResidentPage>>>,
    resident_bytes: usize,
}

impl Hierarchy {
    /// An empty hierarchy: nothing resident yet, not even the directory.
    pub fn new(header: FileHeader) -> Result<Self, FormatError> {
        let directory = Directory::new(&header);
        Self::with_directory(header, directory)
    }

    /// An empty hierarchy over a directory already read (whole, by a
    /// reader of the whole file).
    pub fn with_directory(header: FileHeader, directory: Directory) -> Result<Self, FormatError> {
        let layout = NodeLayout {
            normals: header.attributes.normals,
            color: header.attributes.color,
        };
        header.kind.check_node_layout(layout, header.node_bytes)?;
        Ok(Self {
            header,
            layout,
            directory,
            pages: Vec::new(),
            resident_bytes: 0,
        })
    }

    /// The page directory known so far.
    pub fn directory(&self) -> &Directory {
        &self.directory
    }

    /// Every page id there is: the scene's pages, then the directory's
    /// ([`Directory::id_count`]).
    pub fn id_count(&self) -> u32 {
        self.directory.id_count()
    }

    /// Verifies page `index` and makes it resident. A page that fails its
    /// checksum, carries another checksum than the directory's, or does
    /// not agree with the directory is rejected whole, as is a page whose
    /// directory page has not arrived. A directory page (an index past the
    /// scene's pages) joins the directory.
    pub fn insert_page(&mut self, index: u32, bytes: &[u8]) -> Result<(), FormatError> {
        if self.directory.is_directory(index) {
            return self.directory.insert(index, bytes);
        }
        let page = crate::page::check_page(&self.header, &self.directory, index, bytes)?;
        let h = page.header;
        let (child_counts, payload) = self.header.kind.decode_page(self, &page)?;
        // Every child must be a real node after its parent, and the page's
        // children exactly the nodes from its first child to the next
        // page's (the directory's first children then split the nodes
        // after the root into one range per page, so no node has two
        // parents). This is what keeps traversal of a corrupt-but-
        // checksummed file in bounds, finite and linear: a child range over
        // its own node looped forever, and two pages sharing children
        // doubled the nodes reached at every level.
        let bad = |message: String| FormatError::BadPage {
            page: index,
            message,
        };
        let mut child_offset = Vec::with_capacity(h.node_count as usize);
        let mut sum = 0u64;
        for (i, count) in child_counts.into_iter().enumerate() {
            if count > 0 && h.first_child.saturating_add(sum) <= h.first_node + i as u64 {
                return Err(bad(format!("node {i}'s children do not come after it")));
            }
            child_offset.push(sum as u32);
            sum += u64::from(count);
        }
        // Known whenever the page's entry is (the check above found it).
        let next_first_child = self
            .directory
            .children_end(index)
            .unwrap_or(self.header.nodes);
        if h.first_child.checked_add(sum) != Some(next_first_child) || sum > u64::from(u32::MAX) {
            return Err(bad(format!(
                "child indices out of range: {sum} children from node {}, where the directory has {}",
                h.first_child,
                next_first_child.saturating_sub(h.first_child)
            )));
        }
        let slot = index as usize;
        if self.pages.len() <= slot {
            self.pages.resize_with(slot + 1, || None);
        }
        if let Some(old) = &self.pages[slot] {
            self.resident_bytes -= old.byte_len;
        }
        self.resident_bytes += bytes.len();
        self.pages[slot] = Some(Box::new(ResidentPage {
            header: h,
            // Other kinds' records live decoded in their payload.
            records: if matches!(payload, PagePayload::Spheres) {
                let mut r = Vec::with_capacity(page.records().len() + 8);
                r.extend_from_slice(page.records());
                r.extend_from_slice(&[0; 8]);
                r
            } else {
                Vec::new()
            },
            child_offset,
            byte_len: bytes.len(),
            payload,
        }));
        Ok(())
    }

    /// Child counts of a sphere page's nodes, checking every code.
    pub(crate) fn sphere_child_counts(&self, page: &Page) -> Result<Vec<u32>, FormatError> {
        let node_bytes = self.header.node_bytes as usize;
        let sphere_codes = sphere_codec::sphere_table().len();
        (0..page.header.node_count as usize)
            .map(|i| {
                let rec = NodeRecord::unpack(page.record(i, node_bytes), self.layout);
                if usize::from(rec.sphere) >= sphere_codes
                    || u32::from(rec.normal) >= sphere_codec::NORMAL_CODES
                {
                    return Err(FormatError::BadPage {
                        page: page.header.index,
                        message: format!("node {i} has an invalid code"),
                    });
                }
                Ok(rec.children.get() as u32)
            })
            .collect()
    }

    /// Decodes a cube page's records and payloads; every payload byte must
    /// belong to a cell and decode cleanly.
    pub(crate) fn cube_page(&self, page: &Page) -> Result<CubePage, FormatError> {
        let bad = |message: String| FormatError::BadPage {
            page: page.header.index,
            message,
        };
        let channels = Channels {
            normals: self.header.attributes.normals,
            color: self.header.attributes.color,
        };
        let mut cubes = CubePage::default();
        let mut at = 0usize;
        for (i, bytes) in page
            .records()
            .chunks_exact(cube_codec::RECORD_BYTES)
            .enumerate()
        {
            let rec =
                CubeRecord::unpack(bytes).ok_or_else(|| bad(format!("cell {i}: bad record")))?;
            let len = rec.payload_bytes as usize;
            let slice = page
                .payload()
                .get(at..at.saturating_add(len))
                .ok_or_else(|| bad(format!("cell {i}: payload runs past the page")))?;
            at += len;
            if len > 0 {
                let payload =
                    cube_codec::decode_payload(&rec, slice, self.header.cluster, channels)
                        .map_err(|e| bad(format!("cell {i}: {e}")))?;
                cubes.payload_of.push(cubes.payloads.len() as u32);
                cubes.payloads.push(payload);
            } else {
                cubes.payload_of.push(NO_PAYLOAD);
            }
            cubes.records.push(rec);
        }
        if at != page.payload().len() {
            return Err(bad(format!(
                "{} payload bytes belong to no cell",
                page.payload().len() - at
            )));
        }
        Ok(cubes)
    }

    /// The record of a flat file's root (PLP, BSP: u32 child count, u32
    /// 0), which must count every node after it; `what` names them.
    fn flat_root(&self, page: &Page, what: &str) -> Result<u32, FormatError> {
        let mut word = [0u8; 4];
        let first = page
            .records()
            .get(..4)
            .ok_or_else(|| FormatError::BadPage {
                page: page.header.index,
                message: "no root".into(),
            })?;
        word.copy_from_slice(first);
        let count = u32::from_le_bytes(word);
        if u64::from(count) != self.header.leaves || page.records().get(4..8) != Some(&[0; 4]) {
            return Err(FormatError::BadPage {
                page: page.header.index,
                message: format!(
                    "the root has {count} {what}, the directory {}",
                    self.header.leaves
                ),
            });
        }
        Ok(count)
    }

    /// Decodes a PLP page: page 0 is the root (its record the cell count)
    /// and the skeleton; every other page holds cells, which have no
    /// children.
    pub(crate) fn plp_page(&self, page: &Page) -> Result<(Vec<u32>, PlpPage), FormatError> {
        let bad = |message: String| FormatError::BadPage {
            page: page.header.index,
            message,
        };
        if page.header.index == 0 {
            let cells = self.flat_root(page, "cells")?;
            let skeleton =
                Skeleton::decode(page.payload(), self.header.root_center, self.header.leaves)
                    .map_err(|e| bad(format!("skeleton: {e}")))?;
            return Ok((vec![cells], PlpPage::Skeleton(Box::new(skeleton))));
        }
        let cells = CellPage::decode(page.records(), page.payload()).map_err(bad)?;
        Ok((
            vec![0; page.header.node_count as usize],
            PlpPage::Cells(cells),
        ))
    }

    /// Decodes a BSP page: page 0 is the root (its record the number of
    /// pages after it) and the tree; every other page one prototype or
    /// leaf, which have no children in the file.
    pub(crate) fn bsp_page(&self, page: &Page) -> Result<(Vec<u32>, BspPage), FormatError> {
        let bad = |message: String| FormatError::BadPage {
            page: page.header.index,
            message,
        };
        if page.header.index == 0 {
            let children = self.flat_root(page, "children")?;
            let skeleton =
                BspSkeleton::decode(page.payload(), self.header.root_center, self.header.leaves)
                    .map_err(|e| bad(format!("BSP tree: {e}")))?;
            return Ok((vec![children], BspPage::Skeleton(Box::new(skeleton))));
        }
        let content = ContentPage::decode(page.records(), page.payload()).map_err(bad)?;
        Ok((vec![0], BspPage::Content(content)))
    }

    /// The BSP tree, once page 0 is resident.
    pub fn bsp_skeleton(&self) -> Option<&BspSkeleton> {
        match self.page(0)?.bsp()? {
            BspPage::Skeleton(s) => Some(s),
            BspPage::Content(_) => None,
        }
    }

    /// The PLP skeleton, once page 0 is resident.
    pub fn plp_skeleton(&self) -> Option<&Skeleton> {
        match self.page(0)?.plp()? {
            PlpPage::Skeleton(s) => Some(s),
            PlpPage::Cells(_) => None,
        }
    }

    /// Drops a page (cache eviction). Its descendants stay resident but are
    /// unreachable until it returns.
    pub fn evict_page(&mut self, index: u32) {
        if let Some(old) = self.pages.get_mut(index as usize).and_then(Option::take) {
            self.resident_bytes -= old.byte_len;
        }
    }

    pub fn page(&self, index: usize) -> Option<&ResidentPage> {
        self.pages.get(index).and_then(Option::as_deref)
    }

    /// Whether page id `index` is here: a resident page, or a directory
    /// page inserted.
    pub fn is_resident(&self, index: usize) -> bool {
        self.page(index).is_some() || u32::try_from(index).is_ok_and(|id| self.directory.has(id))
    }

    pub fn resident_pages(&self) -> usize {
        self.pages.iter().filter(|p| p.is_some()).count()
    }

    pub fn resident_bytes(&self) -> usize {
        self.resident_bytes
    }

    /// The record of node `local` in a resident page.
    #[inline]
    pub fn record(&self, page: &ResidentPage, local: usize) -> NodeRecord {
        let nb = self.header.node_bytes as usize;
        let mut word = [0u8; 8];
        word.copy_from_slice(&page.records[local * nb..local * nb + 8]);
        let mask = if nb >= 8 {
            u64::MAX
        } else {
            (1u64 << (8 * nb)) - 1
        };
        NodeRecord::unpack(u64::from_le_bytes(word) & mask, self.layout)
    }

    /// Breadth-first index of the first child of node `local` of `page`.
    #[inline]
    pub fn first_child(page: &ResidentPage, local: usize) -> u64 {
        page.header.first_child + u64::from(page.child_offset[local])
    }

    /// Decodes every node reachable through resident pages, in breadth-first
    /// order: the reference decoder that tests compare against.
    pub fn decode_all(&self) -> Vec<DecodedNode> {
        let mut out = Vec::new();
        if !self.header.kind.nodes_are_spheres() {
            return out;
        }
        let Some(root_page) = self.page(0) else {
            return out;
        };
        let root = self.decode(
            root_page,
            0,
            self.header.root_center,
            self.header.root_radius,
            0,
            0,
        );
        out.push(root);
        let mut next = 0;
        while next < out.len() {
            let parent = out[next];
            next += 1;
            if parent.children == 0 {
                continue;
            }
            let Some(page_index) = self.directory.page_of(parent.first_child) else {
                continue;
            };
            let Some(page) = self.page(page_index as usize) else {
                continue;
            };
            if !Self::group_fits(page, parent.first_child, parent.children) {
                continue;
            }
            for c in 0..parent.children as u64 {
                let index = parent.first_child + c;
                let local = (index - page.header.first_node) as usize;
                out.push(self.decode(
                    page,
                    local,
                    parent.center,
                    parent.radius,
                    index,
                    parent.level + 1,
                ));
            }
        }
        out
    }

    /// True when a sibling group lies wholly inside `page` (always, in a
    /// well-formed file; checked so a bad one cannot index out of bounds).
    #[inline]
    pub fn group_fits(page: &ResidentPage, first: u64, count: usize) -> bool {
        first >= page.header.first_node
            && first + count as u64 <= page.header.first_node + u64::from(page.header.node_count)
    }

    /// Decodes one node given its quantized parent sphere.
    pub(crate) fn decode(
        &self,
        page: &ResidentPage,
        local: usize,
        parent_center: DVec3,
        parent_radius: f64,
        index: u64,
        level: u32,
    ) -> DecodedNode {
        let rec = self.record(page, local);
        let (center, radius) =
            sphere_codec::decode_sphere(parent_center, parent_radius, rec.sphere);
        DecodedNode {
            index,
            level,
            center,
            radius,
            normal: self
                .layout
                .normals
                .then(|| sphere_codec::decode_normal(rec.normal)),
            cone: self
                .layout
                .normals
                .then(|| sphere_codec::cone_half_angle(rec.cone)),
            color: self
                .layout
                .color
                .then(|| sphere_codec::decode_color(rec.color)),
            children: rec.children.get(),
            first_child: Self::first_child(page, local),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::file::{AttributeFlags, HierarchyKind, PageEntry};
    use crate::page::encode_page;
    use crate::sphere_codec::{ChildCount, identity_sphere_code};

    /// Page 0 of a sphere hierarchy: one node (the root, its sphere the
    /// header's) with `children` children from `first_child`, and the
    /// header of a file where a second page holds `rest` nodes, its first
    /// child `next_first_child`.
    fn root_page(
        children: usize,
        first_child: u64,
        rest: u32,
        next_first_child: u64,
    ) -> (FileHeader, Vec<PageEntry>, Vec<u8>) {
        let layout = NodeLayout {
            normals: false,
            color: false,
        };
        let root = NodeRecord {
            sphere: identity_sphere_code(),
            children: ChildCount::new(children).unwrap(),
            ..NodeRecord::EMPTY
        };
        let records = &root.pack(layout).to_le_bytes()[..layout.bytes() as usize];
        let page_header = PageHeader {
            index: 0,
            first_node: 0,
            first_child,
            node_count: 1,
            level_min: 0,
            level_max: 0,
        };
        let (bytes, checksum) = encode_page(&page_header, records).unwrap();
        let entry = |first_node, node_count, first_child| PageEntry {
            offset: 0,
            length: bytes.len() as u32,
            node_count,
            first_node,
            first_child,
            level_min: 0,
            level_max: 0,
            checksum,
        };
        let header = FileHeader {
            kind: HierarchyKind::Spheres,
            attributes: AttributeFlags::default(),
            node_bytes: layout.bytes(),
            cluster: 0,
            levels: 2,
            nodes: 1 + u64::from(rest),
            leaves: u64::from(rest),
            input_vertices: u64::from(rest),
            bounds_min: DVec3::ZERO,
            bounds_max: DVec3::ONE,
            root_center: DVec3::splat(0.5),
            root_radius: 1.0,
            page_count: 0,
            directory_pages: 0,
            root_directory: Default::default(),
        };
        let entries = vec![entry(0, 1, first_child), entry(1, rest, next_first_child)];
        (header, entries, bytes)
    }

    /// A hierarchy over `header` and the directory of `entries`, its
    /// directory pages inserted (as a client has it once they arrived).
    fn with_directory(
        mut header: FileHeader,
        mut entries: Vec<PageEntry>,
    ) -> Result<Hierarchy, FormatError> {
        let layout = crate::directory::lay_out_for(&mut header, &mut entries);
        let mut h = Hierarchy::new(FileHeader::decode(&header.encode())?)?;
        for (n, b) in layout.pages.iter().enumerate() {
            h.insert_page(header.page_count + n as u32, b)?;
        }
        Ok(h)
    }

    /// Found by the `page` fuzz target: a page whose first child lies so
    /// far on that adding its children's count passed 2^64 overflowed in
    /// the range check meant to refuse it. Such a directory is refused.
    #[test]
    fn children_past_2_to_the_64_are_out_of_range() {
        let (header, entries, page) = root_page(2, 1, 2, 3);
        let mut h = with_directory(header, entries).unwrap();
        h.insert_page(0, &page).unwrap();
        let (header, entries, _) = root_page(2, u64::MAX - 1, 2, 3);
        let e = with_directory(header, entries).unwrap_err();
        assert!(e.to_string().contains("root directory page"), "{e}");
    }

    /// A page replaced by another valid page (its own checksum recomputed)
    /// is refused: its checksum is not the one the directory holds.
    #[test]
    fn a_page_with_a_valid_checksum_other_than_the_directorys_is_refused() {
        let (header, entries, page) = root_page(2, 1, 2, 3);
        // The same page with its only record's child count edited, and its
        // checksum made to fit the edit.
        let (_, _, edited) = root_page(3, 1, 2, 3);
        assert_ne!(page, edited);
        assert!(
            Page::parse(&edited, 0, header.node_bytes).is_ok(),
            "self-consistent"
        );
        let mut h = with_directory(header, entries).unwrap();
        let e = h.insert_page(0, &edited).unwrap_err();
        assert!(e.to_string().contains("not the directory's"), "{e}");
        assert!(h.page(0).is_none(), "nothing was made resident");
        h.insert_page(0, &page).unwrap();
    }

    /// A page's children must be exactly the nodes up to the next page's
    /// first child: the root's 2 children where the directory leaves room
    /// for 3 (or 1) are refused.
    #[test]
    fn children_must_fill_the_directorys_range() {
        for next in [2, 4] {
            let (header, entries, page) = root_page(2, 1, 3, next);
            let mut h = with_directory(header, entries).unwrap();
            let e = h.insert_page(0, &page).unwrap_err();
            assert!(
                e.to_string().ends_with(&format!(
                    "child indices out of range: 2 children from node 1, where the directory has {}",
                    next - 1
                )),
                "{e}"
            );
        }
    }

    /// The one page check refuses a page whose header says another node
    /// count or first child than its directory entry (checksums agreeing),
    /// a page the directory does not have, and passes the page as stored;
    /// the hierarchy refuses what it refuses.
    #[test]
    fn one_page_check_compares_the_page_with_its_directory_entry() {
        let (header, entries, page) = root_page(2, 1, 2, 3);
        let h = with_directory(header.clone(), entries.clone()).unwrap();
        assert!(crate::page::check_page(&h.header, h.directory(), 0, &page).is_ok());
        for edit in [
            |e: &mut [PageEntry]| {
                e[0].node_count += 1;
                e[1].first_node += 1;
                e[1].node_count -= 1;
            },
            |e: &mut [PageEntry]| e[0].first_child += 1,
        ] {
            let mut forged = entries.clone();
            edit(&mut forged);
            let mut h = with_directory(header.clone(), forged).unwrap();
            let e = crate::page::check_page(&h.header, h.directory(), 0, &page).unwrap_err();
            assert!(
                e.to_string().contains("disagrees with the directory"),
                "{e}"
            );
            assert!(h.insert_page(0, &page).is_err());
        }
        let missing = crate::page::check_page(&h.header, h.directory(), 5, &page).unwrap_err();
        assert!(missing.to_string().contains("no such page"), "{missing}");
        // Before its directory page, a page cannot be checked.
        let mut bare = Hierarchy::new(h.header.clone()).unwrap();
        let early = bare.insert_page(0, &page).unwrap_err();
        assert!(early.to_string().contains("has not arrived"), "{early}");
    }

    /// The pages of a sphere file (records of identity spheres, so no
    /// node is ever smaller than the root) from (first node, first child,
    /// child counts) per page, and its header.
    fn tree_file(pages: &[(u64, u64, &[usize])]) -> (FileHeader, Vec<PageEntry>, Vec<Vec<u8>>) {
        let layout = NodeLayout {
            normals: false,
            color: false,
        };
        let (mut entries, mut bytes) = (Vec::new(), Vec::new());
        for (i, &(first_node, first_child, counts)) in pages.iter().enumerate() {
            let records: Vec<u8> = counts
                .iter()
                .flat_map(|&c| {
                    let record = NodeRecord {
                        sphere: identity_sphere_code(),
                        children: ChildCount::new(c).unwrap(),
                        ..NodeRecord::EMPTY
                    };
                    record.pack(layout).to_le_bytes()[..2].to_vec()
                })
                .collect();
            let page = PageHeader {
                index: i as u32,
                first_node,
                first_child,
                node_count: counts.len() as u32,
                level_min: 0,
                level_max: 0,
            };
            let (b, checksum) = encode_page(&page, &records).unwrap();
            entries.push(PageEntry::of(&page, b.len(), checksum));
            bytes.push(b);
        }
        let nodes = entries.iter().map(|e| u64::from(e.node_count)).sum();
        let header = FileHeader {
            kind: HierarchyKind::Spheres,
            attributes: AttributeFlags::default(),
            node_bytes: layout.bytes(),
            cluster: 0,
            levels: 1,
            nodes,
            leaves: 1,
            input_vertices: 1,
            bounds_min: DVec3::ZERO,
            bounds_max: DVec3::ONE,
            root_center: DVec3::splat(0.5),
            root_radius: 1.0,
            page_count: 0,
            directory_pages: 0,
            root_directory: Default::default(),
        };
        (header, entries, bytes)
    }

    fn insert_all(pages: &[(u64, u64, &[usize])]) -> Result<Hierarchy, String> {
        let (header, entries, bytes) = tree_file(pages);
        let mut h = with_directory(header, entries).map_err(|e| e.to_string())?;
        for (i, b) in bytes.iter().enumerate() {
            h.insert_page(i as u32, b).map_err(|e| e.to_string())?;
        }
        Ok(h)
    }

    /// Found while writing the fuzz targets (crafted; the header target
    /// replays both files from its corpus): checksummed pages whose child
    /// ranges made a node its own child, or gave a level's nodes two
    /// parents each in two pages, were accepted, and decoding or
    /// traversing them never ended (out of memory from a 400-byte file,
    /// or 2^30 nodes reached from a 5 KB one).
    #[test]
    fn a_node_cannot_be_its_own_descendant_or_have_two_parents() {
        // A well-formed tree: root, two children, two grandchildren.
        let h = insert_all(&[(0, 1, &[2]), (1, 3, &[2, 0]), (3, 5, &[0, 0])]).unwrap();
        assert_eq!(h.decode_all().len(), 5);
        // Node 2's children are nodes 2 and 3: itself (the root's two
        // children then leave the directory's next first child behind).
        let e = insert_all(&[(0, 1, &[2]), (1, 2, &[0, 2, 0])]).unwrap_err();
        assert!(
            e.ends_with("page 0: child indices out of range: 2 children from node 1, where the directory has 1"),
            "{e}"
        );
        // With the directory right, node 3's children would be 3 and 4.
        let e = insert_all(&[(0, 1, &[2]), (1, 3, &[0, 0, 2, 0])]).unwrap_err();
        assert!(
            e.ends_with("page 1: node 2's children do not come after it"),
            "{e}"
        );
        // Pages 1 and 2 both hold nodes 5 to 8 as their children.
        let dag: &[(u64, u64, &[usize])] = &[
            (0, 1, &[2]),
            (1, 5, &[2, 2]),
            (3, 5, &[2, 2]),
            (5, 9, &[0, 0]),
            (7, 9, &[0, 0]),
        ];
        let e = insert_all(dag).unwrap_err();
        assert!(e.contains("child indices out of range"), "{e}");
    }
}
