//! [`PagedFile`]: a whole paged hierarchy in memory, as a builder makes it
//! and as it is written to disk (`[header][root directory page][page 0]
//! ...[page N-1][directory pages 1..]`; see `FORMAT.md`).
//!
//! It lives with the format rather than in a builder because every side
//! handles it: builders produce it, the store writes it, tests and tools
//! read its pages straight into a [`crate::hierarchy::Hierarchy`].

use crate::FormatError;
use crate::directory::{Directory, lay_out_for};
use crate::file::{FileHeader, PageEntry};
use crate::hierarchy::Hierarchy;

/// A finished file: header, directory and page bytes, ready to be written.
#[derive(Debug)]
pub struct PagedFile {
    pub header: FileHeader,
    /// The whole directory.
    pub directory: Directory,
    /// The directory pages' bytes by number, the root first.
    pub directory_pages: Vec<Vec<u8>>,
    /// The scene's pages' bytes, in order.
    pub pages: Vec<Vec<u8>>,
    /// (source vertex, node index) for every leaf, when the builder was
    /// asked to record them, so tests can find a vertex's quantized
    /// sphere; empty otherwise. Not part of the file.
    pub leaf_sources: Vec<(u32, u64)>,
}

impl PagedFile {
    /// The file of `pages`, described by `entries` (lengths and checksums
    /// set; offsets are set here) under `header`, whose page counts and
    /// root directory page are set here too.
    pub fn assemble(
        mut header: FileHeader,
        mut entries: Vec<PageEntry>,
        pages: Vec<Vec<u8>>,
    ) -> Result<Self, FormatError> {
        let layout = lay_out_for(&mut header, &mut entries);
        let directory = directory_of(&header, &layout.pages)?;
        Ok(Self {
            header,
            directory,
            directory_pages: layout.pages,
            pages,
            leaf_sources: Vec::new(),
        })
    }

    /// What goes before page 0: the header and the root directory page.
    pub fn head(&self) -> Vec<u8> {
        let mut out = self.header.encode();
        out.extend_from_slice(&self.directory_pages[0]);
        out
    }

    /// What goes after the last page: the other directory pages.
    pub fn tail(&self) -> &[Vec<u8>] {
        &self.directory_pages[1..]
    }

    /// The file's bytes, in order.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = self.head();
        for p in self.pages.iter().chain(self.tail()) {
            out.extend_from_slice(p);
        }
        out
    }

    /// Page id `id`'s bytes: a scene page, or a directory page after them.
    pub fn page_bytes(&self, id: u32) -> Option<&[u8]> {
        let id = id as usize;
        self.pages
            .get(id)
            .or_else(|| self.directory_pages.get(id.checked_sub(self.pages.len())?))
            .map(Vec::as_slice)
    }

    /// A hierarchy with every page resident (the directory whole).
    pub fn hierarchy(&self) -> Result<Hierarchy, FormatError> {
        let mut h = Hierarchy::with_directory(self.header.clone(), self.directory.clone())?;
        for (i, p) in self.pages.iter().enumerate() {
            h.insert_page(i as u32, p)?;
        }
        Ok(h)
    }
}

/// The whole directory of pages `directory_pages` (by number) under
/// `header`, each checked as a reader checks it.
pub fn directory_of(
    header: &FileHeader,
    directory_pages: &[Vec<u8>],
) -> Result<Directory, FormatError> {
    let mut d = Directory::new(header);
    for (n, bytes) in directory_pages.iter().enumerate() {
        d.insert(header.page_count + n as u32, bytes)?;
    }
    Ok(d)
}

/// Reads a whole file's bytes (as stored on disk) into a hierarchy with
/// every page resident, verifying the header, the directory and each
/// page's checksum.
pub fn read_image(bytes: &[u8]) -> Result<Hierarchy, FormatError> {
    let header = FileHeader::decode(bytes)?;
    let slice = |offset: u64, length: u32, what: u32| {
        usize::try_from(offset)
            .ok()
            .and_then(|start| bytes.get(start..start.checked_add(length as usize)?))
            .ok_or(FormatError::BadPage {
                page: what,
                message: "lies past the end of the file".into(),
            })
    };
    let directory = Directory::read_all(&header, |offset, length| {
        slice(offset, length, header.page_count).map(<[u8]>::to_vec)
    })?;
    directory.check_whole()?;
    let mut h = Hierarchy::with_directory(header, directory)?;
    for i in 0..h.header.page_count {
        let e = h.directory().entry(i).ok_or(FormatError::BadPage {
            page: i,
            message: "not in the directory".into(),
        })?;
        let page = slice(e.offset, e.length, i)?;
        h.insert_page(i, page)?;
    }
    Ok(h)
}
