//! The file header and the entries of the page directory.
//!
//! A file is `[header][root directory page][page 0][page 1]...[directory
//! pages]`, all little-endian; `FORMAT.md` in this crate is the byte-level
//! description. The header has one size whatever the scene and checks
//! itself; it says where the root directory page is ([`crate::directory`]),
//! which holds the first pages' entries, and page 0 after it is the whole
//! model at low resolution: the first image is one short read.

use glam::DVec3;

use crate::FormatError;
use crate::directory::DirRef;

/// The eight bytes every farfield file starts with.
pub const MAGIC: [u8; 8] = *b"FARFIELD";
/// Bumped whenever a reader of the previous version would misread the
/// bytes. 3: the directory is paged; the header has a fixed size.
pub const FORMAT_VERSION: u32 = 3;
/// Bytes of the header before its checksum.
pub const FIXED_HEADER_BYTES: usize = 192;
/// Bytes of one directory entry.
pub const PAGE_ENTRY_BYTES: usize = 40;
/// The header's first bytes (magic, version, length), which say how long
/// the whole header is ([`FileHeader::peek_len`]).
pub const HEADER_PREFIX_BYTES: usize = 16;

pub use crate::kinds::{HierarchyKind, PageLayout};

/// Which optional channels the nodes carry. A scene stores only what it
/// has: a molecule of spheres has no normals, a bare scan has no color.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct AttributeFlags {
    pub color: bool,
    pub normals: bool,
    pub leaf_geometry: bool,
}

impl AttributeFlags {
    fn to_bits(self) -> u8 {
        u8::from(self.color) | u8::from(self.normals) << 1 | u8::from(self.leaf_geometry) << 2
    }

    fn from_bits(bits: u8) -> Result<Self, FormatError> {
        if bits & !0b111 != 0 {
            return Err(FormatError::BadHeader(format!(
                "unknown attribute flags {bits:#04x}"
            )));
        }
        Ok(Self {
            color: bits & 1 != 0,
            normals: bits & 2 != 0,
            leaf_geometry: bits & 4 != 0,
        })
    }
}

/// Where one page lives and which nodes it holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PageEntry {
    /// Byte offset of the page in the file.
    pub offset: u64,
    /// Bytes of the page, its header and checksum included.
    pub length: u32,
    /// Nodes in the page.
    pub node_count: u32,
    /// Breadth-first index of the page's first node.
    pub first_node: u64,
    /// Breadth-first index of the first child of the page's first parent
    /// node: with the child counts in the page it places every child.
    pub first_child: u64,
    /// Shallowest and deepest level with nodes in this page.
    pub level_min: u16,
    pub level_max: u16,
    /// CRC-32 of the page, also stored in the page's last four bytes.
    pub checksum: u32,
}

impl PageEntry {
    /// The directory entry of an encoded page (`length` bytes, checksum
    /// `checksum`); its offset is set by [`place_pages`].
    pub fn of(header: &crate::page::PageHeader, length: usize, checksum: u32) -> Self {
        Self {
            offset: 0,
            length: length as u32,
            node_count: header.node_count,
            first_node: header.first_node,
            first_child: header.first_child,
            level_min: header.level_min,
            level_max: header.level_max,
            checksum,
        }
    }
}

impl PageEntry {
    pub(crate) fn encode(&self, out: &mut Vec<u8>) {
        put_u64(out, self.offset);
        put_u32(out, self.length);
        put_u32(out, self.node_count);
        put_u64(out, self.first_node);
        put_u64(out, self.first_child);
        out.extend_from_slice(&self.level_min.to_le_bytes());
        out.extend_from_slice(&self.level_max.to_le_bytes());
        put_u32(out, self.checksum);
    }

    pub(crate) fn decode(r: &mut Reader) -> Result<Self, FormatError> {
        Ok(Self {
            offset: r.u64()?,
            length: r.u32()?,
            node_count: r.u32()?,
            first_node: r.u64()?,
            first_child: r.u64()?,
            level_min: r.u16()?,
            level_max: r.u16()?,
            checksum: r.u32()?,
        })
    }
}

/// Everything a reader needs before it touches a page.
#[derive(Debug, Clone, PartialEq)]
pub struct FileHeader {
    pub kind: HierarchyKind,
    pub attributes: AttributeFlags,
    /// Bytes of one node record in a page.
    pub node_bytes: u32,
    /// Cubes: color-cubes per cell edge (1, or k for k x k x k clusters,
    /// 1995 report section 4.2). Spheres: 0.
    pub cluster: u8,
    /// Number of levels (the root alone is one level).
    pub levels: u32,
    pub nodes: u64,
    pub leaves: u64,
    /// Vertices (or points, or atoms) of the input, for statistics.
    pub input_vertices: u64,
    /// Axis-aligned bounds of the input, in world units.
    pub bounds_min: DVec3,
    pub bounds_max: DVec3,
    /// The root node's sphere; every other node is relative to its parent.
    pub root_center: DVec3,
    pub root_radius: f64,
    /// Pages of the scene (directory pages not counted).
    pub page_count: u32,
    /// Directory pages, the root included.
    pub directory_pages: u32,
    /// Where the root directory page is: right after the header.
    pub root_directory: DirRef,
}

impl FileHeader {
    /// Bytes of the header, its checksum included: the same for every
    /// scene.
    pub const ENCODED_LEN: usize = FIXED_HEADER_BYTES + 4;

    /// Serializes the header and its checksum.
    pub fn encode(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(Self::ENCODED_LEN);
        out.extend_from_slice(&MAGIC);
        put_u32(&mut out, FORMAT_VERSION);
        put_u32(&mut out, Self::ENCODED_LEN as u32);
        out.push(self.kind as u8);
        out.push(self.attributes.to_bits());
        out.extend_from_slice(&[self.cluster, 0]);
        put_u32(&mut out, self.node_bytes);
        put_u32(&mut out, self.levels);
        put_u32(&mut out, self.page_count);
        put_u64(&mut out, self.nodes);
        put_u64(&mut out, self.leaves);
        put_u64(&mut out, self.input_vertices);
        for v in [self.bounds_min, self.bounds_max, self.root_center] {
            for c in v.to_array() {
                put_f64(&mut out, c);
            }
        }
        put_f64(&mut out, self.root_radius);
        self.root_directory.encode(&mut out);
        put_u32(&mut out, self.directory_pages);
        put_u32(&mut out, 0);
        debug_assert_eq!(out.len(), FIXED_HEADER_BYTES);
        let crc = crc32fast::hash(&out);
        put_u32(&mut out, crc);
        out
    }

    /// How many bytes the whole header occupies, read from its first
    /// [`HEADER_PREFIX_BYTES`]; lets a reader fetch exactly the header and
    /// nothing more.
    pub fn peek_len(prefix: &[u8]) -> Result<usize, FormatError> {
        let mut r = Reader::new(prefix, "header");
        if r.bytes(8)? != MAGIC {
            return Err(FormatError::BadMagic);
        }
        let version = r.u32()?;
        if version != FORMAT_VERSION {
            return Err(FormatError::UnsupportedVersion {
                found: version,
                supported: FORMAT_VERSION,
            });
        }
        Ok(r.u32()? as usize)
    }

    /// Parses and verifies a header. `bytes` may extend past the header.
    pub fn decode(bytes: &[u8]) -> Result<Self, FormatError> {
        let len = Self::peek_len(bytes)?;
        if len != Self::ENCODED_LEN {
            return Err(FormatError::BadHeader(format!(
                "header length {len} is not {}",
                Self::ENCODED_LEN
            )));
        }
        if bytes.len() < len {
            return Err(FormatError::Truncated {
                what: "header",
                needed: len as u64,
                have: bytes.len() as u64,
            });
        }
        let body = &bytes[..len - 4];
        let stored = u32::from_le_bytes([
            bytes[len - 4],
            bytes[len - 3],
            bytes[len - 2],
            bytes[len - 1],
        ]);
        if crc32fast::hash(body) != stored {
            return Err(FormatError::HeaderChecksum);
        }
        let mut r = Reader::new(body, "header");
        r.bytes(16)?;
        let kind = HierarchyKind::from_u8(r.u8()?)?;
        let attributes = AttributeFlags::from_bits(r.u8()?)?;
        let cluster = r.u8()?;
        r.u8()?;
        let node_bytes = r.u32()?;
        let levels = r.u32()?;
        let page_count = r.u32()?;
        let nodes = r.u64()?;
        let leaves = r.u64()?;
        let input_vertices = r.u64()?;
        let vec3 = |r: &mut Reader| -> Result<DVec3, FormatError> {
            Ok(DVec3::new(r.f64()?, r.f64()?, r.f64()?))
        };
        let bounds_min = vec3(&mut r)?;
        let bounds_max = vec3(&mut r)?;
        let root_center = vec3(&mut r)?;
        let root_radius = r.f64()?;
        let root_directory = DirRef::decode(&mut r)?;
        let directory_pages = r.u32()?;
        let header = Self {
            kind,
            attributes,
            node_bytes,
            cluster,
            levels,
            nodes,
            leaves,
            input_vertices,
            bounds_min,
            bounds_max,
            root_center,
            root_radius,
            page_count,
            directory_pages,
            root_directory,
        };
        header.check()?;
        Ok(header)
    }

    /// Consistency checks a reader relies on, so traversal never indexes out
    /// of range or divides by zero on a malformed header.
    fn check(&self) -> Result<(), FormatError> {
        let bad = |m: String| Err(FormatError::BadHeader(m));
        if !(self.root_center.is_finite() && self.root_radius.is_finite() && self.root_radius > 0.0)
        {
            return bad("root sphere is not finite and positive".into());
        }
        if !(self.bounds_min.is_finite() && self.bounds_max.is_finite()) {
            return bad("bounds are not finite".into());
        }
        self.kind.check_header(self).or_else(bad)?;
        let root = &self.root_directory;
        // Every page holds a node, every directory page describes a page
        // at least (leaves more, inner pages more leaves).
        if self.page_count == 0 || u64::from(self.page_count) > self.nodes {
            return bad(format!(
                "{} pages for {} nodes",
                self.page_count, self.nodes
            ));
        }
        if self.directory_pages == 0 || self.directory_pages > self.page_count {
            return bad(format!(
                "{} directory pages for {} pages",
                self.directory_pages, self.page_count
            ));
        }
        if root.number != 0
            || root.first_page != 0
            || root.page_count != self.page_count
            || root.first_node != 0
            || root.first_child > self.nodes
            || root.offset != Self::ENCODED_LEN as u64
        {
            return bad(
                "the root directory page is not the whole scene's, after the header".into(),
            );
        }
        Ok(())
    }
}

fn put_u32(out: &mut Vec<u8>, v: u32) {
    out.extend_from_slice(&v.to_le_bytes());
}
fn put_u64(out: &mut Vec<u8>, v: u64) {
    out.extend_from_slice(&v.to_le_bytes());
}
fn put_f64(out: &mut Vec<u8>, v: f64) {
    out.extend_from_slice(&v.to_le_bytes());
}

/// A bounds-checked little-endian cursor: every read either succeeds or
/// reports how many bytes were missing.
pub(crate) struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
    what: &'static str,
}

impl<'a> Reader<'a> {
    pub(crate) fn new(bytes: &'a [u8], what: &'static str) -> Self {
        Self { bytes, at: 0, what }
    }
    pub(crate) fn bytes(&mut self, n: usize) -> Result<&'a [u8], FormatError> {
        let end = self
            .at
            .checked_add(n)
            .filter(|&e| e <= self.bytes.len())
            .ok_or(FormatError::Truncated {
                what: self.what,
                needed: (self.at + n) as u64,
                have: self.bytes.len() as u64,
            })?;
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }
    fn array<const N: usize>(&mut self) -> Result<[u8; N], FormatError> {
        let mut a = [0u8; N];
        a.copy_from_slice(self.bytes(N)?);
        Ok(a)
    }
    pub(crate) fn u8(&mut self) -> Result<u8, FormatError> {
        Ok(self.array::<1>()?[0])
    }
    pub(crate) fn u16(&mut self) -> Result<u16, FormatError> {
        Ok(u16::from_le_bytes(self.array()?))
    }
    pub(crate) fn u32(&mut self) -> Result<u32, FormatError> {
        Ok(u32::from_le_bytes(self.array()?))
    }
    pub(crate) fn u64(&mut self) -> Result<u64, FormatError> {
        Ok(u64::from_le_bytes(self.array()?))
    }
    fn f64(&mut self) -> Result<f64, FormatError> {
        Ok(f64::from_le_bytes(self.array()?))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::directory::lay_out;

    /// A header over `entries` (their directory laid out).
    fn header(mut entries: Vec<PageEntry>) -> FileHeader {
        let nodes = entries.iter().map(|p| u64::from(p.node_count)).sum();
        let layout = lay_out(&mut entries, nodes);
        FileHeader {
            kind: HierarchyKind::Spheres,
            attributes: AttributeFlags::default(),
            node_bytes: 2,
            cluster: 0,
            levels: 1,
            nodes,
            leaves: 1,
            input_vertices: 1,
            bounds_min: DVec3::ZERO,
            bounds_max: DVec3::ONE,
            root_center: DVec3::splat(0.5),
            root_radius: 1.0,
            page_count: entries.len() as u32,
            directory_pages: layout.count(),
            root_directory: layout.root,
        }
    }

    fn page(length: u32, first_node: u64) -> PageEntry {
        PageEntry {
            offset: 0,
            length,
            node_count: 1,
            first_node,
            first_child: 0,
            level_min: 0,
            level_max: 0,
            checksum: 0,
        }
    }

    /// A file of version 2 (the whole directory in its header) is refused
    /// with advice, not misread.
    #[test]
    fn an_older_version_is_refused_with_advice_to_rebuild() {
        let mut bytes = header(vec![page(40, 0)]).encode();
        bytes[8..12].copy_from_slice(&2u32.to_le_bytes());
        let e = FileHeader::decode(&bytes).unwrap_err();
        assert_eq!(
            e,
            FormatError::UnsupportedVersion {
                found: 2,
                supported: 3
            }
        );
        assert!(e.to_string().contains("rebuild"), "{e}");
    }

    /// The header's size does not grow with the scene.
    #[test]
    fn the_header_has_one_size_for_10_pages_and_for_100_000() {
        let pages = |n: u64| (0..n).map(|i| page(100, i)).collect::<Vec<_>>();
        let small = header(pages(10));
        let large = header(pages(100_000));
        assert!(large.directory_pages > 1, "{}", large.directory_pages);
        assert_eq!(small.encode().len(), FileHeader::ENCODED_LEN);
        assert_eq!(large.encode().len(), FileHeader::ENCODED_LEN);
        assert_eq!(FileHeader::decode(&large.encode()).unwrap(), large);
    }

    /// Counts no file can have are refused before anything is allocated
    /// for them.
    #[test]
    fn impossible_counts_are_refused() {
        let mut h = header(vec![page(40, 0), page(40, 1)]);
        h.page_count = 3;
        assert!(
            FileHeader::decode(&h.encode()).is_err(),
            "more pages than nodes"
        );
        let mut h = header(vec![page(40, 0), page(40, 1)]);
        h.directory_pages = u32::MAX;
        assert!(FileHeader::decode(&h.encode()).is_err(), "directory pages");
        let mut h = header(vec![page(40, 0)]);
        h.root_directory.offset += 1;
        assert!(FileHeader::decode(&h.encode()).is_err(), "root elsewhere");
    }

    /// Found by the `header` fuzz target: a PLP header claiming 2^64 - 1
    /// leaves overflowed `leaves + 1` in the check of its node count.
    #[test]
    fn a_plp_header_with_every_leaf_is_refused_without_overflow() {
        let mut plp = header(vec![PageEntry {
            first_child: 1,
            ..page(40, 0)
        }]);
        plp.kind = HierarchyKind::Plp;
        plp.node_bytes = crate::plp_codec::NODE_BYTES as u32;
        plp.levels = 2;
        plp.leaves = 0;
        assert!(FileHeader::decode(&plp.encode()).is_ok(), "a root alone");
        plp.leaves = u64::MAX;
        let e = FileHeader::decode(&plp.encode()).unwrap_err();
        assert!(e.to_string().contains("PLP tessellation"), "{e}");
        plp.leaves = 0;
        plp.levels = 3;
        assert!(FileHeader::decode(&plp.encode()).is_err(), "levels");
    }
}
