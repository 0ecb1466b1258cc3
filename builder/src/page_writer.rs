//! The one page writer. Every builder decides what goes in its pages (the
//! records and payload of each) and hands them here; this encodes each page
//! with its checksum, keeps the directory entry that describes it, and at
//! the end places the pages after the header and makes the [`PagedFile`].
//!
//! Two shapes of file exist (`farfield_protocol::file::PageLayout`): the
//! breadth-first pages of spheres and color cubes, which their builders cut
//! themselves through [`PageWriter`], and the two-level "skeleton first"
//! shape PLP and image caching share, written by [`SkeletonFirst`].

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use farfield_protocol::FormatError;
use farfield_protocol::directory::{Directory, lay_out_for};
use farfield_protocol::file::{AttributeFlags, FileHeader, HierarchyKind, PageEntry};
use farfield_protocol::page::{PageHeader, encode_page_with_payload};
use farfield_protocol::paged_file::directory_of;
use glam::DVec3;
use rayon::prelude::*;

use crate::PagedFile;

/// Pages handed over but not yet encoded: compression is the slow part of
/// writing a page (about 50 MB/s a core), so pages are encoded in batches
/// on every core rather than one by one as they come.
const ENCODE_BATCH: usize = 64;

/// Pages in the order of their indices, with their directory entries.
#[derive(Debug, Default)]
pub struct PageWriter {
    entries: Vec<PageEntry>,
    pages: Vec<Vec<u8>>,
    /// Where encoded pages go instead of `pages`, for builds larger than
    /// memory ([`PageWriter::spilling_to`]).
    spill: Option<Spill>,
    /// Each page's header, records and payload, in order after `pages`.
    pending: Vec<(PageHeader, Vec<u8>, Vec<u8>)>,
    /// The first page that could not be encoded (a body over the format's
    /// limit): [`PageWriter::finish`] reports it, so builders push pages
    /// without checking each.
    error: Option<FormatError>,
    pushed: usize,
}

impl PageWriter {
    /// Appends a page. `header.index` must be the number of pages so far.
    pub fn push(&mut self, header: &PageHeader, records: &[u8], payload: &[u8]) {
        debug_assert_eq!(header.index as usize, self.len(), "pages out of order");
        self.pending
            .push((*header, records.to_vec(), payload.to_vec()));
        self.pushed += 1;
        if self.pending.len() >= ENCODE_BATCH {
            self.encode_pending();
        }
    }

    /// A writer that appends each encoded page to the file at `path`
    /// instead of keeping it: memory then holds only the directory.
    pub fn spilling_to(path: &Path) -> std::io::Result<Self> {
        Ok(Self {
            spill: Some(Spill {
                path: path.to_owned(),
                out: BufWriter::with_capacity(1 << 20, File::create(path)?),
                error: None,
            }),
            ..Self::default()
        })
    }

    fn encode_pending(&mut self) {
        let encoded: Vec<_> = self
            .pending
            .par_drain(..)
            .map(|(header, records, payload)| {
                let (bytes, checksum) = encode_page_with_payload(&header, &records, &payload)?;
                Ok((PageEntry::of(&header, bytes.len(), checksum), bytes))
            })
            .collect();
        for page in encoded {
            match page {
                Ok((entry, bytes)) => {
                    self.entries.push(entry);
                    match &mut self.spill {
                        Some(spill) => spill.write(&bytes),
                        None => self.pages.push(bytes),
                    }
                }
                Err(e) => {
                    self.error.get_or_insert(e);
                }
            }
        }
    }

    /// Pages pushed so far.
    pub fn len(&self) -> usize {
        self.pushed
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// For a writer made by [`PageWriter::spilling_to`]: the header (whose
    /// directory is `header`'s replaced by the pages written) and the file
    /// of their bytes, in order; or why a page could not be written.
    pub fn finish_spilled(mut self, header: FileHeader) -> Result<SpilledFile, SpillError> {
        self.encode_pending();
        if let Some(e) = self.error {
            return Err(SpillError::Format(e));
        }
        let Some(spill) = self.spill else {
            return Err(SpillError::Io(std::io::Error::other(
                "the pages were not spilled",
            )));
        };
        if let Some(e) = spill.error {
            return Err(SpillError::Io(e));
        }
        spill
            .out
            .into_inner()
            .map_err(|e| SpillError::Io(e.into_error()))?;
        let mut header = header;
        let mut entries = self.entries;
        let layout = lay_out_for(&mut header, &mut entries);
        let directory = directory_of(&header, &layout.pages)?;
        Ok(SpilledFile {
            header,
            directory,
            directory_pages: layout.pages,
            body: spill.path,
        })
    }

    /// The file: `header` (whose page counts and root directory page are
    /// set here) with the directory of the pages written; or why a page
    /// could not be written.
    pub fn finish(mut self, header: FileHeader) -> Result<PagedFile, FormatError> {
        self.encode_pending();
        if let Some(e) = self.error {
            return Err(e);
        }
        PagedFile::assemble(header, self.entries, self.pages)
    }
}

/// The file a spilling [`PageWriter`] appends pages to.
#[derive(Debug)]
struct Spill {
    path: PathBuf,
    out: BufWriter<File>,
    /// The first write that failed; reported by `finish_spilled`.
    error: Option<std::io::Error>,
}

impl Spill {
    fn write(&mut self, bytes: &[u8]) {
        if self.error.is_none()
            && let Err(e) = self.out.write_all(bytes)
        {
            self.error = Some(e);
        }
    }
}

/// A finished file whose pages are in a file of their own: the header and
/// root directory page to write first, then `body`'s bytes, then the other
/// directory pages (`farfield_store::write_atomic_parts`).
#[derive(Debug)]
pub struct SpilledFile {
    pub header: FileHeader,
    pub directory: Directory,
    /// The directory pages' bytes by number, the root first.
    pub directory_pages: Vec<Vec<u8>>,
    /// The pages' bytes, in directory order.
    pub body: PathBuf,
}

impl SpilledFile {
    /// The whole file in memory, for tests and small scenes.
    pub fn read(&self) -> std::io::Result<PagedFile> {
        let body = std::fs::read(&self.body)?;
        let start = self.head().len() as u64;
        let pages = self
            .directory
            .entries()
            .map(|(_, e)| {
                let at = (e.offset - start) as usize;
                body.get(at..at + e.length as usize)
                    .map(<[u8]>::to_vec)
                    .ok_or_else(|| std::io::Error::other("the pages file is short"))
            })
            .collect::<std::io::Result<_>>()?;
        Ok(PagedFile {
            header: self.header.clone(),
            directory: self.directory.clone(),
            directory_pages: self.directory_pages.clone(),
            pages,
            leaf_sources: Vec::new(),
        })
    }

    /// What goes before the pages: the header and the root directory page.
    pub fn head(&self) -> Vec<u8> {
        let mut out = self.header.encode();
        out.extend_from_slice(&self.directory_pages[0]);
        out
    }

    /// What goes after the pages: the other directory pages.
    pub fn tail(&self) -> Vec<u8> {
        self.directory_pages[1..].concat()
    }
}

/// Why a spilled file could not be finished.
#[derive(Debug, thiserror::Error)]
pub enum SpillError {
    #[error(transparent)]
    Format(#[from] FormatError),
    #[error("writing pages: {0}")]
    Io(#[from] std::io::Error),
}

/// What a two-level file's header says besides its shape.
#[derive(Debug, Clone, Copy)]
pub struct SceneFacts {
    pub kind: HierarchyKind,
    pub attributes: AttributeFlags,
    pub node_bytes: u32,
    pub input_vertices: u64,
    pub bounds_min: DVec3,
    pub bounds_max: DVec3,
    /// What the skeleton's positions are relative to.
    pub root_center: DVec3,
    pub root_radius: f64,
}

/// The "skeleton first" shape (PLP's tessellation, image caching's BSP): a
/// root alone in page 0 whose payload is the skeleton, enough for a client
/// to order the whole scene from one read, and whose children are every
/// leaf; then the leaves, in pages of one or more, in the order the builder
/// chose (a page is a patch of space).
#[derive(Debug)]
pub struct SkeletonFirst {
    writer: PageWriter,
    leaves: u64,
    next_node: u64,
}

impl SkeletonFirst {
    /// Page 0: the root, with `leaves` children, carrying `skeleton`.
    pub fn new(leaves: u64, skeleton: &[u8]) -> Self {
        let mut writer = PageWriter::default();
        // The root's record: its child count, then a word kept zero.
        let mut root = (leaves as u32).to_le_bytes().to_vec();
        root.extend_from_slice(&0u32.to_le_bytes());
        writer.push(
            &PageHeader {
                index: 0,
                first_node: 0,
                first_child: 1,
                node_count: 1,
                level_min: 0,
                level_max: 0,
            },
            &root,
            skeleton,
        );
        Self {
            writer,
            leaves,
            next_node: 1,
        }
    }

    /// Appends a page of the next `count` leaves.
    pub fn push_leaves(&mut self, count: u32, records: &[u8], payload: &[u8]) {
        let header = PageHeader {
            index: self.writer.len() as u32,
            first_node: self.next_node,
            // Leaves have no children: their first child is past the last node.
            first_child: 1 + self.leaves,
            node_count: count,
            level_min: 1,
            level_max: 1,
        };
        self.writer.push(&header, records, payload);
        self.next_node += u64::from(count);
    }

    /// The file, or why a page could not be written.
    pub fn finish(self, facts: SceneFacts) -> Result<PagedFile, FormatError> {
        debug_assert_eq!(self.next_node, 1 + self.leaves, "a leaf without a page");
        self.writer.finish(FileHeader {
            kind: facts.kind,
            attributes: facts.attributes,
            node_bytes: facts.node_bytes,
            cluster: 0,
            levels: 2,
            nodes: 1 + self.leaves,
            leaves: self.leaves,
            input_vertices: facts.input_vertices,
            bounds_min: facts.bounds_min,
            bounds_max: facts.bounds_max,
            root_center: facts.root_center,
            root_radius: facts.root_radius,
            page_count: 0,
            directory_pages: 0,
            root_directory: Default::default(),
        })
    }
}
