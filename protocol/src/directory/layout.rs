//! Cutting a file's page entries into directory pages and placing every
//! page in the file: `[header][root directory page][page 0]...[page N-1]
//! [directory pages 1..]`, so the header, the root and page 0 (the first
//! image) are one read from the file's start.

use super::{DirRef, DirectoryPage, FANOUT, ROOT_CHILDREN, ROOT_ENTRIES};
use crate::file::{FileHeader, PageEntry};

/// A file's directory, made by [`lay_out`].
#[derive(Debug, Clone)]
pub struct DirectoryLayout {
    /// The root's reference, for the header.
    pub root: DirRef,
    /// Every directory page's bytes by number, the root first.
    pub pages: Vec<Vec<u8>>,
}

impl DirectoryLayout {
    /// Directory pages, the root included.
    pub fn count(&self) -> u32 {
        self.pages.len() as u32
    }

    /// The root directory page's bytes (right after the header).
    pub fn root_bytes(&self) -> &[u8] {
        &self.pages[0]
    }

    /// The other directory pages' bytes, in the order they follow the
    /// scene's pages.
    pub fn tail(&self) -> &[Vec<u8>] {
        &self.pages[1..]
    }
}

/// A directory page before its bytes: a run of pages and, for an inner
/// page, the pages under it (by index into the plan).
struct Planned {
    first_page: u32,
    page_count: u32,
    entries: u32,
    children: Vec<usize>,
}

/// Sets every entry's offset and makes the directory pages of a file with
/// these pages (in order, each entry's length and checksum set) and
/// `nodes` nodes. The root holds up to [`ROOT_ENTRIES`] entries and
/// references to the rest, in pages of [`FANOUT`] entries, under pages of
/// [`FANOUT`] references as long as the root would have more than
/// [`ROOT_CHILDREN`].
pub fn lay_out(entries: &mut [PageEntry], nodes: u64) -> DirectoryLayout {
    let scene_pages = entries.len() as u32;
    let root_entries = entries.len().min(ROOT_ENTRIES);
    // Leaves, then inner levels until the root can hold the top one.
    let mut plan: Vec<Planned> = Vec::new();
    let mut level: Vec<usize> = (root_entries..entries.len())
        .step_by(FANOUT)
        .map(|start| {
            plan.push(Planned {
                first_page: start as u32,
                page_count: FANOUT.min(entries.len() - start) as u32,
                entries: FANOUT.min(entries.len() - start) as u32,
                children: Vec::new(),
            });
            plan.len() - 1
        })
        .collect();
    while level.len() > ROOT_CHILDREN {
        level = level
            .chunks(FANOUT)
            .map(|group| {
                plan.push(Planned {
                    first_page: plan[group[0]].first_page,
                    page_count: group.iter().map(|&g| plan[g].page_count).sum(),
                    entries: 0,
                    children: group.to_vec(),
                });
                plan.len() - 1
            })
            .collect();
    }
    plan.push(Planned {
        first_page: 0,
        page_count: scene_pages,
        entries: root_entries as u32,
        children: level,
    });
    let root = plan.len() - 1;

    // Numbers breadth-first from the root, so a parent's number is below
    // its children's (what readers check, so lookups end).
    let mut order = vec![root];
    let mut next = 0;
    while next < order.len() {
        order.extend(plan[order[next]].children.iter().copied());
        next += 1;
    }
    let mut number = vec![0u32; plan.len()];
    for (n, &p) in order.iter().enumerate() {
        number[p] = n as u32;
    }
    let size =
        |p: &Planned| DirectoryPage::encoded_len(p.entries as usize, p.children.len()) as u64;

    // Places: the root after the header, the scene's pages after it, the
    // other directory pages at the end.
    let mut offset = FileHeader::ENCODED_LEN as u64;
    let mut place = vec![0u64; plan.len()];
    place[root] = offset;
    offset += size(&plan[root]);
    for e in entries.iter_mut() {
        e.offset = offset;
        offset += u64::from(e.length);
    }
    for &p in &order[1..] {
        place[p] = offset;
        offset += size(&plan[p]);
    }

    // Bytes, children before parents (a reference holds its page's checksum).
    let mut refs: Vec<Option<DirRef>> = vec![None; plan.len()];
    let mut bytes: Vec<Vec<u8>> = vec![Vec::new(); plan.len()];
    for &p in order.iter().rev() {
        let planned = &plan[p];
        let first = planned.first_page as usize;
        let end = first + planned.page_count as usize;
        let page = DirectoryPage {
            number: number[p],
            first_page: planned.first_page,
            page_count: planned.page_count,
            first_node: entries.get(first).map_or(0, |e| e.first_node),
            first_child: entries.get(first).map_or(0, |e| e.first_child),
            end_first_child: entries.get(end).map_or(nodes, |e| e.first_child),
            entries: entries[first..first + planned.entries as usize].to_vec(),
            children: planned
                .children
                .iter()
                .map(|&c| refs[c].expect("children are encoded before their parent"))
                .collect(),
        };
        let (encoded, checksum) = page.encode(scene_pages);
        refs[p] = Some(DirRef {
            offset: place[p],
            length: encoded.len() as u32,
            checksum,
            number: page.number,
            first_page: page.first_page,
            page_count: page.page_count,
            first_node: page.first_node,
            first_child: page.first_child,
        });
        bytes[number[p] as usize] = encoded;
    }
    DirectoryLayout {
        root: refs[root].expect("the root is encoded"),
        pages: bytes,
    }
}

/// Lays out `entries`' directory ([`lay_out`]) for the file `header`
/// describes, and sets the header's page counts and root reference to it:
/// what a builder does last, once its pages are encoded.
pub fn lay_out_for(header: &mut FileHeader, entries: &mut [PageEntry]) -> DirectoryLayout {
    let layout = lay_out(entries, header.nodes);
    header.page_count = entries.len() as u32;
    header.directory_pages = layout.count();
    header.root_directory = layout.root;
    layout
}
