//! The paged page directory: where every page lives, itself in pages.
//!
//! A file's header has a fixed size whatever the scene; it names one
//! directory page, the root, which holds the entries of the first pages
//! (the coarse levels the first image needs) and references to further
//! directory pages for the rest, each covering a run of consecutive pages,
//! as COPC's hierarchy pages and 3D Tiles' implicit subtrees hang off their
//! header. Pages are breadth-first, so a run of pages is a band of one or
//! two levels of neighbouring nodes: a view that reaches a region reaches a
//! few directory pages, and a client holds the directory it has visited.
//!
//! Directory pages travel as pages do: numbered after the scene's pages
//! (directory page `n` is page id `page_count + n`), asked for, pushed,
//! cancelled and checked the same way. Each is covered by the checksum in
//! its parent's reference, and the root's by the header's, so a directory
//! page that arrives verified is the builder's.
//!
//! [`Directory`] is both the client's partial directory (pages inserted as
//! they arrive) and a reader's whole one ([`Directory::read_all`]).

mod layout;
mod page;
#[cfg(test)]
mod tests;

pub use layout::{DirectoryLayout, lay_out, lay_out_for};
pub use page::{
    DIRECTORY_HEADER_BYTES, DIRECTORY_MAGIC, DIRECTORY_REF_BYTES, DirRef, DirectoryPage,
};

use std::collections::HashMap;
use std::sync::Arc;

use crate::FormatError;
use crate::file::{FileHeader, PageEntry};

/// The most page entries the root holds itself: the top of the hierarchy,
/// what the first frames draw, reachable from the header with one read.
pub const ROOT_ENTRIES: usize = 256;
/// The most references to further directory pages the root holds.
pub const ROOT_CHILDREN: usize = 256;
/// Entries (or references) in every other directory page: about 20 KiB,
/// the directory of about 4 MB of pages at this project's page sizes.
pub const FANOUT: usize = 512;

/// Where a page's bytes are and what they must hash to: a data page's
/// directory entry or a directory page's reference, whichever it is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Extent {
    pub offset: u64,
    pub length: u32,
    pub checksum: u32,
}

/// Where a node's page is, as far as the directory known so far says.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Locate {
    /// The node is in this page.
    Page(u32),
    /// The entry is in a directory page not yet inserted: this page id
    /// (ask for it as for a page).
    Missing(u32),
    /// No page holds the node (past the scene, or a damaged reference).
    Outside,
}

/// The directory pages of one file known so far.
#[derive(Debug, Clone)]
pub struct Directory {
    page_count: u32,
    directory_pages: u32,
    nodes: u64,
    /// Whether the first page must hold the root alone (its kind says).
    root_alone: bool,
    /// Each directory page's reference by number, once its parent is
    /// inserted (the root's comes from the header). Maps, not vectors: a
    /// client's memory follows what it visited, and a header's counts,
    /// which nothing bounds, are never allocated for.
    refs: HashMap<u32, DirRef>,
    /// Shared, not copied, by a clone: the server hands its whole
    /// directory to every read-ahead walker of every session, and a
    /// directory page never changes once inserted.
    pages: HashMap<u32, Arc<DirectoryPage>>,
    bytes: usize,
}

impl Directory {
    /// The directory of the file `header` describes, nothing inserted yet.
    pub fn new(header: &FileHeader) -> Self {
        Self {
            page_count: header.page_count,
            directory_pages: header.directory_pages,
            nodes: header.nodes,
            root_alone: header.kind.root_page_alone(),
            refs: HashMap::from([(0, header.root_directory)]),
            pages: HashMap::new(),
            bytes: 0,
        }
    }

    /// Reads every directory page through `read` (offset and length to
    /// bytes), root first: the whole directory, for readers that hold the
    /// whole file (the server, `inspect`, a file opened directly).
    pub fn read_all(
        header: &FileHeader,
        mut read: impl FnMut(u64, u32) -> Result<Vec<u8>, FormatError>,
    ) -> Result<Self, FormatError> {
        let mut dir = Self::new(header);
        // Parents come before their children in the numbering (a check of
        // every reference), so one pass in order reads them all.
        for number in 0..dir.directory_pages {
            let r = *dir.refs.get(&number).ok_or_else(|| {
                FormatError::BadHeader(format!("directory page {number} is not referenced"))
            })?;
            let bytes = read(r.offset, r.length)?;
            dir.insert(dir.page_count + number, &bytes)?;
        }
        Ok(dir)
    }

    /// The scene's pages (directory pages not counted).
    pub fn page_count(&self) -> u32 {
        self.page_count
    }

    /// Directory pages in the file, the root included.
    pub fn directory_pages(&self) -> u32 {
        self.directory_pages
    }

    /// Every page id a client may ask for: the scene's pages, then the
    /// directory's.
    pub fn id_count(&self) -> u32 {
        self.page_count.saturating_add(self.directory_pages)
    }

    /// The page id of the root directory page.
    pub fn root_id(&self) -> u32 {
        self.page_count
    }

    /// Whether page id `id` is a directory page.
    pub fn is_directory(&self, id: u32) -> bool {
        id >= self.page_count && id < self.id_count()
    }

    /// Whether every directory page is inserted.
    pub fn is_complete(&self) -> bool {
        self.pages.len() == self.directory_pages as usize
    }

    /// Whether directory page `id` is inserted.
    pub fn has(&self, id: u32) -> bool {
        self.number(id).is_some_and(|n| self.pages.contains_key(&n))
    }

    /// Directory pages inserted so far.
    pub fn inserted(&self) -> usize {
        self.pages.len()
    }

    /// Bytes of the directory pages inserted (their stored size).
    pub fn bytes(&self) -> usize {
        self.bytes
    }

    fn number(&self, id: u32) -> Option<u32> {
        self.is_directory(id).then(|| id - self.page_count)
    }

    /// Checks directory page `id` against its reference and keeps it. Its
    /// parent must be inserted first (the reference, with the checksum
    /// that proves the page, is in the parent).
    pub fn insert(&mut self, id: u32, bytes: &[u8]) -> Result<(), FormatError> {
        let number = self.number(id).ok_or_else(|| FormatError::BadPage {
            page: id,
            message: format!("no such directory page ({} pages)", self.id_count()),
        })?;
        let r = *self.refs.get(&number).ok_or_else(|| FormatError::BadPage {
            page: id,
            message: "a directory page whose parent has not arrived".into(),
        })?;
        let page =
            DirectoryPage::decode(bytes, &r, self.page_count, self.nodes, self.directory_pages)?;
        if number == 0 && self.root_alone && page.entries.first().is_some_and(|e| e.node_count != 1)
        {
            return Err(FormatError::BadPage {
                page: id,
                message: "this kind's first page holds the root alone".into(),
            });
        }
        for c in &page.children {
            self.refs.insert(c.number, *c);
        }
        if self.pages.insert(number, Arc::new(page)).is_none() {
            self.bytes += bytes.len();
        }
        Ok(())
    }

    /// Checks directory page `id`'s bytes as [`Directory::insert`] would,
    /// without keeping them: what a server does before sending one.
    pub fn verify(&self, id: u32, bytes: &[u8]) -> Result<(), FormatError> {
        let r = self
            .number(id)
            .and_then(|n| self.refs.get(&n))
            .ok_or_else(|| FormatError::BadPage {
                page: id,
                message: "not a directory page this directory knows".into(),
            })?;
        DirectoryPage::decode(bytes, r, self.page_count, self.nodes, self.directory_pages)
            .map(|_| ())
    }

    /// Where page id `id` lies and what it hashes to, if known: a scene
    /// page's entry or a directory page's reference.
    pub fn extent(&self, id: u32) -> Option<Extent> {
        if let Some(n) = self.number(id) {
            let r = self.refs.get(&n)?;
            return Some(Extent {
                offset: r.offset,
                length: r.length,
                checksum: r.checksum,
            });
        }
        self.entry(id).map(|e| Extent {
            offset: e.offset,
            length: e.length,
            checksum: e.checksum,
        })
    }

    /// The directory page holding scene page `page`'s entry, and the
    /// entry's place in it; `None` when it is not inserted (or no such page).
    fn holder(&self, page: u32) -> Option<(&DirectoryPage, usize)> {
        let mut at = self.pages.get(&0)?;
        loop {
            let local = page.checked_sub(at.first_page)? as usize;
            if local < at.entries.len() {
                return Some((at, local));
            }
            let k = at
                .children
                .partition_point(|c| c.first_page <= page)
                .checked_sub(1)?;
            let c = &at.children[k];
            if page - c.first_page >= c.page_count {
                return None;
            }
            // Children are numbered after their parent (checked), so this
            // descends and ends.
            at = self.pages.get(&c.number)?;
        }
    }

    /// The page ids of the directory pages a client needs, root first, to
    /// learn scene page `page`'s entry (as far as this directory knows:
    /// all of them for a whole one).
    pub fn path_to(&self, page: u32) -> Vec<u32> {
        let mut path = vec![self.root_id()];
        let Some(mut at) = self.pages.get(&0) else {
            return path;
        };
        while let Some(local) = page.checked_sub(at.first_page) {
            if (local as usize) < at.entries.len() {
                break;
            }
            let Some(k) = at
                .children
                .partition_point(|c| c.first_page <= page)
                .checked_sub(1)
            else {
                break;
            };
            let c = &at.children[k];
            path.push(self.page_count + c.number);
            match self.pages.get(&c.number) {
                Some(next) => at = next,
                None => break,
            }
        }
        path
    }

    /// Scene page `page`'s entry, if its directory page is inserted.
    pub fn entry(&self, page: u32) -> Option<PageEntry> {
        self.holder(page).map(|(d, i)| d.entries[i])
    }

    /// The first child of the page after `page` (the scene's node count
    /// after the last): `page`'s children end there. Known whenever
    /// `page`'s entry is.
    pub fn children_end(&self, page: u32) -> Option<u64> {
        let (d, i) = self.holder(page)?;
        Some(match (d.entries.get(i + 1), d.children.first()) {
            (Some(next), _) => next.first_child,
            (None, Some(child)) => child.first_child,
            (None, None) => d.end_first_child,
        })
    }

    /// The page that holds breadth-first node `node`, or the directory
    /// page to ask for to learn it.
    pub fn locate(&self, node: u64) -> Locate {
        if node >= self.nodes {
            return Locate::Outside;
        }
        let Some(mut at) = self.pages.get(&0) else {
            return Locate::Missing(self.root_id());
        };
        loop {
            let entries_end = at
                .entries
                .last()
                .map_or(at.first_node, |e| e.first_node + u64::from(e.node_count));
            if node < entries_end {
                let i = at.entries.partition_point(|e| e.first_node <= node);
                return match i.checked_sub(1) {
                    Some(i) => Locate::Page(at.first_page + i as u32),
                    None => Locate::Outside,
                };
            }
            let Some(k) = at
                .children
                .partition_point(|c| c.first_node <= node)
                .checked_sub(1)
            else {
                return Locate::Outside;
            };
            let c = &at.children[k];
            match self.pages.get(&c.number) {
                Some(next) => at = next,
                None => return Locate::Missing(self.page_count + c.number),
            }
        }
    }

    /// The scene page holding `node`, if the directory known says.
    pub fn page_of(&self, node: u64) -> Option<u32> {
        match self.locate(node) {
            Locate::Page(p) => Some(p),
            Locate::Missing(_) | Locate::Outside => None,
        }
    }

    /// Every entry known, in page order (all of them for a whole
    /// directory).
    pub fn entries(&self) -> impl Iterator<Item = (u32, PageEntry)> + '_ {
        let mut out: Vec<(u32, PageEntry)> = self
            .pages
            .values()
            .flat_map(|d| {
                d.entries
                    .iter()
                    .enumerate()
                    .map(move |(i, e)| (d.first_page + i as u32, *e))
            })
            .collect();
        out.sort_unstable_by_key(|(i, _)| *i);
        out.into_iter()
    }

    /// Every directory page's id and extent known, root first.
    pub fn directory_extents(&self) -> impl Iterator<Item = (u32, Extent)> + '_ {
        let mut known: Vec<(u32, Extent)> = self
            .refs
            .values()
            .map(|r| {
                let extent = Extent {
                    offset: r.offset,
                    length: r.length,
                    checksum: r.checksum,
                };
                (self.page_count + r.number, extent)
            })
            .collect();
        known.sort_unstable_by_key(|(id, _)| *id);
        known.into_iter()
    }

    /// Total bytes of the file: its furthest page's end (the header's
    /// length when there is nothing else).
    pub fn file_len(&self) -> u64 {
        let ends = self
            .entries()
            .map(|(_, e)| (e.offset, e.length))
            .chain(self.refs.values().map(|r| (r.offset, r.length)))
            .map(|(offset, length)| offset.saturating_add(u64::from(length)));
        ends.max().unwrap_or(0).max(FileHeader::ENCODED_LEN as u64)
    }

    /// The checks a whole directory allows beyond each page's own: the
    /// entries continue the node order from node 0 to the header's count.
    pub fn check_whole(&self) -> Result<(), FormatError> {
        let bad = |m: String| Err(FormatError::BadHeader(m));
        if !self.is_complete() {
            return bad("the directory is not whole".into());
        }
        let mut next = 0u64;
        let mut pages = 0u32;
        for (i, e) in self.entries() {
            if i != pages || e.first_node != next {
                return bad(format!("page {i} does not continue the node order"));
            }
            next += u64::from(e.node_count);
            pages += 1;
        }
        if pages != self.page_count || next != self.nodes {
            return bad(format!(
                "the directory's {pages} pages hold {next} nodes, the header says {} pages and {} nodes",
                self.page_count, self.nodes
            ));
        }
        Ok(())
    }
}
