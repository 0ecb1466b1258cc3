//! [`PageCutter`]: sibling groups of packed records in, breadth-first
//! pages out, the way QSplat 3.2 lays a tree out. A page holds whole sibling
//! groups and page 0 ends on a level boundary, so one read of it is a
//! complete coarse model. The in-memory layout ([`super::layout`]) and the
//! out-of-core merge (`crate::out_of_core`) both feed it, in breadth-first
//! order, through [`GroupSink`].

use farfield_protocol::page::{PAGE_CHECKSUM_BYTES, PAGE_HEADER_BYTES, PageHeader};
use farfield_protocol::sphere_codec::NodeRecord;

use crate::page_writer::PageWriter;

/// Where quantized sibling groups go, in breadth-first order: pages
/// ([`PageCutter`]), or a chunk's level files in an out-of-core build.
pub(crate) trait GroupSink {
    /// A new level begins (called before its first group, from level 1 on).
    fn end_level(&mut self);
    /// One sibling group of packed records at `level`; `first_child` is the
    /// breadth-first index of its first node's first child.
    fn add_group(&mut self, level: u32, group: &[u8], first_child: u64);
}

/// Accumulates records into pages of at most `page_bytes`, never splitting a
/// sibling group, ending page 0 on a level boundary.
pub(crate) struct PageCutter {
    page_bytes: usize,
    node_bytes: usize,
    records: Vec<u8>,
    page: Option<PageHeader>,
    /// Page 0's records up to the last complete level.
    page0_done: bool,
    page0_level_end: usize,
    page0_level_count: (u32, u64),
    /// The pages finished so far.
    written: PageWriter,
    next_node: u64,
}

impl PageCutter {
    pub(crate) fn new(page_bytes: usize, node_bytes: usize) -> Self {
        Self::with_writer(page_bytes, node_bytes, PageWriter::default())
    }

    /// A cutter handing its pages to `written` (a spilling writer, say).
    pub(crate) fn with_writer(page_bytes: usize, node_bytes: usize, written: PageWriter) -> Self {
        let page_bytes = page_bytes.max(PAGE_HEADER_BYTES + PAGE_CHECKSUM_BYTES + 4 * node_bytes);
        Self {
            page_bytes,
            node_bytes,
            records: Vec::new(),
            page: None,
            page0_done: false,
            page0_level_end: 0,
            page0_level_count: (0, 0),
            written,
            next_node: 0,
        }
    }

    fn capacity(&self) -> usize {
        self.page_bytes - PAGE_HEADER_BYTES - PAGE_CHECKSUM_BYTES
    }

    /// Adds one sibling group of packed records at `level`; `first_child`
    /// is the breadth-first index of its first node's first child.
    fn add_group(&mut self, level: u32, group: &[u8], first_child: u64) {
        let group_nodes = (group.len() / self.node_bytes) as u64;
        if self.page.is_some() && self.records.len() + group.len() > self.capacity() {
            if self.written.is_empty() {
                self.flush_page0();
            } else {
                self.flush();
            }
        }
        let level = level as u16;
        let page = self.page.get_or_insert(PageHeader {
            index: self.written.len() as u32,
            first_node: self.next_node,
            first_child,
            node_count: 0,
            level_min: level,
            level_max: level,
        });
        page.node_count += group_nodes as u32;
        page.level_max = level;
        self.next_node += group_nodes;
        self.records.extend_from_slice(group);
    }

    /// Called after each complete level: remembers where page 0 could end.
    fn end_level(&mut self) {
        if self.written.is_empty()
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
        // The rest of the open page becomes the start of page 1. Its first
        // child is found by walking the child counts of page 0's records.
        let first_child = page0_next_child(&self.records, head, self.node_bytes);
        self.page = Some(head);
        self.flush();
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
        self.written.push(&header, &self.records, &[]);
        self.records.clear();
    }

    pub(crate) fn finish(mut self) -> PageWriter {
        self.flush();
        self.written
    }
}

/// The breadth-first index of the first child of the node after page 0.
fn page0_next_child(records: &[u8], header: PageHeader, node_bytes: usize) -> u64 {
    let mut next = header.first_child;
    for chunk in records.chunks_exact(node_bytes) {
        let mut word = [0u8; 8];
        word[..node_bytes].copy_from_slice(chunk);
        next += NodeRecord::child_count(u64::from_le_bytes(word)) as u64;
    }
    next
}

impl GroupSink for PageCutter {
    fn end_level(&mut self) {
        PageCutter::end_level(self);
    }

    fn add_group(&mut self, level: u32, group: &[u8], first_child: u64) {
        PageCutter::add_group(self, level, group, first_child);
    }
}
