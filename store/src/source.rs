//! [`PageSource`]: where a served scene's bytes come from.
//!
//! The memory server asks a source for the header once and for pages as
//! clients need them; it never touches a file or a map itself. The one
//! sources are [`crate::SceneFile`], a file read by positional reads, and
//! (in `farfield-objects`) an object read by range requests; the server
//! never names either.

use std::ops::Range;

use farfield_protocol::FormatError;
use farfield_protocol::directory::Directory;
use farfield_protocol::file::FileHeader;

/// Why a page could not be read.
#[derive(Debug, Clone, thiserror::Error)]
pub enum PageError {
    /// The page's bytes are not a valid page of this scene.
    #[error(transparent)]
    Format(#[from] FormatError),
    /// The stored scene is no longer the version that was opened, so none
    /// of its pages can be trusted (a page of the new version could pass
    /// every check and still not fit the header clients hold).
    #[error("the scene's file changed on disk: {0}")]
    Changed(String),
    /// The store did not answer, or not in time (a network store that is
    /// down or slow). Nothing is known about the page: ask again later.
    #[error("temporarily unavailable: {0}")]
    Unavailable(String),
}

/// A scene's stored bytes: its header and its pages, verified on read.
pub trait PageSource: Send + Sync + std::fmt::Debug {
    /// The scene's header, decoded.
    fn header(&self) -> &FileHeader;
    /// The scene's whole directory, read when the source was opened.
    fn directory(&self) -> &Directory;
    /// The header as stored (its fixed bytes and checksum), which the
    /// server sends verbatim so clients decode exactly what is stored.
    fn header_bytes(&self) -> &[u8];
    /// Bytes of the whole scene as stored.
    fn stored_len(&self) -> u64;
    /// Appends page `index`'s stored bytes to `out`, after checking its
    /// checksum, its header and its agreement with the directory (on an
    /// error `out` is as it was). May block on a disk or a network: the
    /// server calls it from its blocking pool and its prefetch threads, not
    /// from its async tasks. A source that finds its stored version gone
    /// says [`PageError::Changed`], whatever the bytes it read.
    fn read_page(&self, index: u32, out: &mut Vec<u8>) -> Result<(), PageError>;
    /// Reads each page of `pages` (neighbours in the scene), verified as
    /// [`PageSource::read_page`] does, one result per page in order. A
    /// source that can fetch neighbours at once (one range request to a
    /// store) overrides it; the default reads them one by one.
    fn read_pages(&self, pages: Range<u32>) -> Vec<Result<Vec<u8>, PageError>> {
        read_each(self, pages)
    }
    /// How the stored scene changed since it was opened, if it did.
    fn changed(&self) -> Option<String>;
    /// The version opened, which the server's watcher compares with what
    /// is stored now.
    fn stamp(&self) -> crate::Stamp;
    /// Where it is stored, for logs (a path, or a store's URL).
    fn location(&self) -> String;
}

/// Reads `pages` one [`PageSource::read_page`] at a time.
pub fn read_each<S: PageSource + ?Sized>(
    source: &S,
    pages: Range<u32>,
) -> Vec<Result<Vec<u8>, PageError>> {
    pages
        .map(|page| {
            let mut out = Vec::new();
            source.read_page(page, &mut out).map(|()| out)
        })
        .collect()
}

impl PageSource for crate::SceneFile {
    fn header(&self) -> &FileHeader {
        &self.header
    }

    fn directory(&self) -> &Directory {
        &self.directory
    }

    fn header_bytes(&self) -> &[u8] {
        crate::SceneFile::header_bytes(self)
    }

    fn stored_len(&self) -> u64 {
        self.len()
    }

    fn read_page(&self, index: u32, out: &mut Vec<u8>) -> Result<(), PageError> {
        let start = out.len();
        let read = self.read_page_into(index as usize, out);
        // Checked after the read: bytes read while a writer was at work are
        // thrown away even when they happen to pass the page's checks.
        if let Some(why) = self.changed() {
            out.truncate(start);
            return Err(PageError::Changed(why));
        }
        Ok(read?)
    }

    fn changed(&self) -> Option<String> {
        crate::SceneFile::changed(self)
    }

    fn stamp(&self) -> crate::Stamp {
        crate::Stamp::File(crate::SceneFile::stamp(self))
    }

    fn location(&self) -> String {
        self.path.display().to_string()
    }
}
