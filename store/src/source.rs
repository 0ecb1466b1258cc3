//! [`PageSource`]: where a served scene's bytes come from.
//!
//! The memory server asks a source for the header once and for pages as
//! clients need them; it never touches a file or a map itself. The one
//! source now is [`crate::SceneFile`], a file read by positional reads; object storage
//! is a new implementation of this trait, and nothing in the server
//! changes for it.

use farfield_protocol::FormatError;
use farfield_protocol::file::FileHeader;

/// A scene's stored bytes: its header and its pages, verified on read.
pub trait PageSource: Send + Sync + std::fmt::Debug {
    /// The scene's header, decoded.
    fn header(&self) -> &FileHeader;
    /// The header as stored (fixed part, directory and checksum), which the
    /// server sends verbatim so clients decode exactly what is stored.
    fn header_bytes(&self) -> &[u8];
    /// Bytes of the whole scene as stored.
    fn stored_len(&self) -> u64;
    /// Appends page `index`'s stored bytes to `out`, after checking its
    /// checksum, its header and its agreement with the directory (on an
    /// error `out` is as it was). May block on a disk or a network: the
    /// server calls it from its blocking pool and its prefetch threads, not
    /// from its async tasks.
    fn read_page(&self, index: u32, out: &mut Vec<u8>) -> Result<(), FormatError>;
}

impl PageSource for crate::SceneFile {
    fn header(&self) -> &FileHeader {
        &self.header
    }

    fn header_bytes(&self) -> &[u8] {
        crate::SceneFile::header_bytes(self)
    }

    fn stored_len(&self) -> u64 {
        self.len()
    }

    fn read_page(&self, index: u32, out: &mut Vec<u8>) -> Result<(), FormatError> {
        self.read_page_into(index as usize, out)
    }
}
