//! [`PagedFile`]: a whole paged hierarchy in memory, as a builder makes it
//! and as it is written to disk (header bytes, then each page's bytes in
//! directory order; see `FORMAT.md`).
//!
//! It lives with the format rather than in a builder because every side
//! handles it: builders produce it, the store writes it, tests and tools
//! read its pages straight into a [`crate::hierarchy::Hierarchy`].

use crate::FormatError;
use crate::file::FileHeader;
use crate::hierarchy::Hierarchy;

/// A finished file: header and page bytes, ready to be written.
#[derive(Debug)]
pub struct PagedFile {
    pub header: FileHeader,
    pub pages: Vec<Vec<u8>>,
    /// (source vertex, node index) for every leaf, when the builder was
    /// asked to record them, so tests can find a vertex's quantized
    /// sphere; empty otherwise. Not part of the file.
    pub leaf_sources: Vec<(u32, u64)>,
}

/// Reads a whole file's bytes (as stored on disk) into a hierarchy with
/// every page resident, verifying the header and each page's checksum.
pub fn read_image(bytes: &[u8]) -> Result<Hierarchy, FormatError> {
    let header = FileHeader::decode(bytes)?;
    let mut h = Hierarchy::new(header)?;
    for i in 0..h.header.pages.len() {
        let e = h.header.pages[i];
        let page = usize::try_from(e.offset)
            .ok()
            .and_then(|start| bytes.get(start..start.checked_add(e.length as usize)?))
            .ok_or(FormatError::BadPage {
                page: i as u32,
                message: "lies past the end of the file".into(),
            })?;
        h.insert_page(i as u32, page)?;
    }
    Ok(h)
}
