//! One directory page's bytes: a header, page entries, references to
//! further directory pages, a checksum (`FORMAT.md`, "Directory page").

use crate::FormatError;
use crate::file::{PAGE_ENTRY_BYTES, PageEntry, Reader};

/// The four bytes every directory page starts with.
pub const DIRECTORY_MAGIC: [u8; 4] = *b"FFDR";
/// Bytes of a directory page's header.
pub const DIRECTORY_HEADER_BYTES: usize = 48;
/// Bytes of one reference to a directory page.
pub const DIRECTORY_REF_BYTES: usize = 48;

/// A reference to a directory page: where it is, what it hashes to and
/// which pages it describes. The header holds the root's.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DirRef {
    pub offset: u64,
    pub length: u32,
    /// CRC-32 of the directory page (as stored at its end).
    pub checksum: u32,
    /// The directory page's number, 0 for the root (its page id is the
    /// scene's page count plus this).
    pub number: u32,
    /// The first scene page it describes, and how many (its own entries
    /// and its children's, consecutive).
    pub first_page: u32,
    pub page_count: u32,
    /// Its first page's first node and first child.
    pub first_node: u64,
    pub first_child: u64,
}

impl DirRef {
    pub(crate) fn encode(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.offset.to_le_bytes());
        out.extend_from_slice(&self.length.to_le_bytes());
        out.extend_from_slice(&self.checksum.to_le_bytes());
        out.extend_from_slice(&self.number.to_le_bytes());
        out.extend_from_slice(&self.first_page.to_le_bytes());
        out.extend_from_slice(&self.page_count.to_le_bytes());
        out.extend_from_slice(&0u32.to_le_bytes());
        out.extend_from_slice(&self.first_node.to_le_bytes());
        out.extend_from_slice(&self.first_child.to_le_bytes());
    }

    pub(crate) fn decode(r: &mut Reader) -> Result<Self, FormatError> {
        let offset = r.u64()?;
        let length = r.u32()?;
        let checksum = r.u32()?;
        let number = r.u32()?;
        let first_page = r.u32()?;
        let page_count = r.u32()?;
        r.u32()?;
        Ok(Self {
            offset,
            length,
            checksum,
            number,
            first_page,
            page_count,
            first_node: r.u64()?,
            first_child: r.u64()?,
        })
    }
}

/// A decoded, verified directory page.
#[derive(Debug, Clone, PartialEq)]
pub struct DirectoryPage {
    pub number: u32,
    pub first_page: u32,
    /// Scene pages it describes: its entries, then its children's.
    pub page_count: u32,
    pub first_node: u64,
    pub first_child: u64,
    /// The first child of the page after its last (the scene's node count
    /// after the scene's last page), where its last page's children end.
    pub end_first_child: u64,
    /// The entries of its first pages.
    pub entries: Vec<PageEntry>,
    /// The directory pages describing the rest, in page order.
    pub children: Vec<DirRef>,
}

impl DirectoryPage {
    /// Bytes of a directory page with `entries` entries and `children`
    /// references.
    pub fn encoded_len(entries: usize, children: usize) -> usize {
        DIRECTORY_HEADER_BYTES + entries * PAGE_ENTRY_BYTES + children * DIRECTORY_REF_BYTES + 4
    }

    /// The page's bytes, its id being `scene_pages + number`; returns them
    /// and their checksum (also their last four bytes).
    pub fn encode(&self, scene_pages: u32) -> (Vec<u8>, u32) {
        let mut out =
            Vec::with_capacity(Self::encoded_len(self.entries.len(), self.children.len()));
        out.extend_from_slice(&DIRECTORY_MAGIC);
        out.extend_from_slice(&(scene_pages + self.number).to_le_bytes());
        out.extend_from_slice(&self.first_page.to_le_bytes());
        out.extend_from_slice(&self.page_count.to_le_bytes());
        out.extend_from_slice(&self.first_node.to_le_bytes());
        out.extend_from_slice(&self.first_child.to_le_bytes());
        out.extend_from_slice(&self.end_first_child.to_le_bytes());
        out.extend_from_slice(&(self.entries.len() as u32).to_le_bytes());
        out.extend_from_slice(&(self.children.len() as u32).to_le_bytes());
        for e in &self.entries {
            e.encode(&mut out);
        }
        for c in &self.children {
            c.encode(&mut out);
        }
        let crc = crc32fast::hash(&out);
        out.extend_from_slice(&crc.to_le_bytes());
        (out, crc)
    }

    /// Checks `bytes` against the reference `expected` (length, checksum,
    /// and that they describe the pages it says) and decodes them; the
    /// file has `scene_pages` pages, `nodes` nodes and `directory_pages`
    /// directory pages. Everything a lookup indexes by is checked here, so
    /// a lookup in a verified directory stays in range and ends.
    pub fn decode(
        bytes: &[u8],
        expected: &DirRef,
        scene_pages: u32,
        nodes: u64,
        directory_pages: u32,
    ) -> Result<Self, FormatError> {
        let id = scene_pages.saturating_add(expected.number);
        let bad = |message: String| FormatError::BadPage { page: id, message };
        crate::page::check_against_entry(
            &PageEntry {
                offset: expected.offset,
                length: expected.length,
                checksum: expected.checksum,
                ..PageEntry::default()
            },
            id,
            bytes,
        )?;
        let body = &bytes[..bytes.len() - 4];
        let computed = crc32fast::hash(body);
        if computed != expected.checksum {
            return Err(FormatError::PageChecksum {
                page: id,
                stored: expected.checksum,
                computed,
            });
        }
        let mut r = Reader::new(body, "directory page");
        if r.bytes(4)? != DIRECTORY_MAGIC {
            return Err(bad("not a directory page (bad magic)".into()));
        }
        let claimed = r.u32()?;
        let page = Self {
            number: expected.number,
            first_page: r.u32()?,
            page_count: r.u32()?,
            first_node: r.u64()?,
            first_child: r.u64()?,
            end_first_child: r.u64()?,
            entries: Vec::new(),
            children: Vec::new(),
        };
        let entry_count = r.u32()? as usize;
        let child_count = r.u32()? as usize;
        if claimed != id
            || page.first_page != expected.first_page
            || page.page_count != expected.page_count
            || page.first_node != expected.first_node
            || page.first_child != expected.first_child
        {
            return Err(bad(
                "the directory page is not the one its parent names".into()
            ));
        }
        let fits = entry_count
            .checked_mul(PAGE_ENTRY_BYTES)
            .zip(child_count.checked_mul(DIRECTORY_REF_BYTES))
            .and_then(|(a, b)| a.checked_add(b)?.checked_add(DIRECTORY_HEADER_BYTES + 4));
        if fits != Some(bytes.len()) {
            return Err(bad(format!(
                "{entry_count} entries and {child_count} references do not fill {} bytes",
                bytes.len()
            )));
        }
        let mut page = page;
        page.entries = (0..entry_count)
            .map(|_| PageEntry::decode(&mut r))
            .collect::<Result<_, _>>()?;
        page.children = (0..child_count)
            .map(|_| DirRef::decode(&mut r))
            .collect::<Result<_, _>>()?;
        page.check(scene_pages, nodes, directory_pages)
            .map_err(bad)?;
        Ok(page)
    }

    /// The page's own consistency: its entries and children continue one
    /// another in page and node order, within the scene's counts, and
    /// children are numbered after it (so a lookup descends and ends).
    fn check(&self, scene_pages: u32, nodes: u64, directory_pages: u32) -> Result<(), String> {
        let end_page = self
            .first_page
            .checked_add(self.page_count)
            .filter(|&e| e <= scene_pages)
            .ok_or("describes pages past the scene's")?;
        if self.page_count == 0 || self.entries.len() + self.children.len() == 0 {
            return Err("describes no page".into());
        }
        let mut page = self.first_page;
        let mut node = self.first_node;
        let mut first_child = self.first_child;
        let check_child = |at: u64, after: u64| {
            if at < after || at > nodes {
                Err(format!("first child {at} is out of order"))
            } else {
                Ok(())
            }
        };
        for (i, e) in self.entries.iter().enumerate() {
            if e.first_node != node || e.node_count == 0 {
                return Err(format!("entry {i} does not continue the node order"));
            }
            if i == 0 && e.first_child != self.first_child {
                return Err("its first entry is not the page its parent names".into());
            }
            if e.offset.checked_add(u64::from(e.length)).is_none() {
                return Err(format!("entry {i} ends past the largest possible file"));
            }
            check_child(e.first_child, first_child)?;
            first_child = e.first_child;
            node += u64::from(e.node_count);
            page += 1;
        }
        if node > nodes {
            return Err(format!("its pages hold nodes past the scene's {nodes}"));
        }
        for (i, c) in self.children.iter().enumerate() {
            let continues = if i == 0 && self.entries.is_empty() {
                c.first_node == node && c.first_child == self.first_child
            } else if i == 0 {
                c.first_node == node
            } else {
                c.first_node >= node
            };
            if c.first_page != page || c.page_count == 0 || !continues || c.first_node >= nodes {
                return Err(format!("reference {i} does not continue the page order"));
            }
            if c.number <= self.number || c.number >= directory_pages {
                return Err(format!("reference {i} names directory page {}", c.number));
            }
            if c.offset.checked_add(u64::from(c.length)).is_none() {
                return Err(format!("reference {i} ends past the largest possible file"));
            }
            check_child(c.first_child, first_child)?;
            first_child = c.first_child;
            // Each of its pages holds a node at least.
            node = c.first_node + u64::from(c.page_count);
            page += c.page_count;
        }
        if page != end_page {
            return Err(format!(
                "its entries and references cover {} pages, not {}",
                page - self.first_page,
                self.page_count
            ));
        }
        check_child(self.end_first_child, first_child)?;
        if end_page == scene_pages && self.end_first_child != nodes {
            return Err("the scene's last page's children do not end at its last node".into());
        }
        Ok(())
    }
}
