//! Reading a stored scene's header and checking its pages, the same for
//! every [`crate::PageSource`]: a file read by positional reads and an
//! object read by range requests fail the same checks with the same errors.

use farfield_protocol::FormatError;
use farfield_protocol::file::{FileHeader, PageEntry};
use farfield_protocol::page::check_stored_page;

/// How much of a scene is read first to find its header's length.
pub const HEADER_PROBE_BYTES: u64 = 64 << 10;

/// Why a header could not be read: the store failed, or its bytes are not
/// a header.
#[derive(Debug)]
pub enum HeaderError<E> {
    Read(E),
    Format(FormatError),
}

/// Reads and decodes the header of a stored scene of `len` bytes through
/// `read_prefix(n)` (the first `n` bytes): one read of
/// [`HEADER_PROBE_BYTES`], and a second only when the directory is longer.
/// Returns the header and its stored bytes (fixed part, directory, CRC),
/// after checking that the scene is as long as its directory says.
pub fn read_header<E>(
    len: u64,
    mut read_prefix: impl FnMut(u64) -> Result<Vec<u8>, E>,
) -> Result<(FileHeader, Vec<u8>), HeaderError<E>> {
    let mut bytes = read_prefix(len.min(HEADER_PROBE_BYTES)).map_err(HeaderError::Read)?;
    let header = match FileHeader::decode(&bytes) {
        // A directory longer than the probe: read all of it (it cannot be
        // longer than the scene, or the scene is truncated).
        Err(FormatError::Truncated {
            what: "header",
            needed,
            ..
        }) if needed <= len => {
            bytes = read_prefix(needed).map_err(HeaderError::Read)?;
            FileHeader::decode(&bytes).map_err(HeaderError::Format)?
        }
        decoded => decoded.map_err(HeaderError::Format)?,
    };
    bytes.truncate(FileHeader::encoded_len(header.pages.len()));
    if header.file_len() > len {
        return Err(HeaderError::Format(FormatError::Truncated {
            what: "file",
            needed: header.file_len(),
            have: len,
        }));
    }
    Ok((header, bytes))
}

/// Page `index`'s directory entry, or why there is none.
pub fn page_entry(header: &FileHeader, index: usize) -> Result<PageEntry, FormatError> {
    header
        .pages
        .get(index)
        .copied()
        .ok_or(FormatError::BadPage {
            page: index as u32,
            message: "outside the file".into(),
        })
}

/// Checks `bytes`, read for page `index` of the scene `header` describes,
/// as the client will check them, less the inflating of the body
/// ([`check_stored_page`]: its length, its checksum and the directory's
/// copy of it, its page header, and its agreement with the directory). A
/// read that came back short is a truncated page.
pub fn verify_page(header: &FileHeader, index: usize, bytes: &[u8]) -> Result<(), FormatError> {
    let entry = page_entry(header, index)?;
    if bytes.len() != entry.length as usize {
        return Err(FormatError::Truncated {
            what: "page",
            needed: u64::from(entry.length),
            have: bytes.len() as u64,
        });
    }
    check_stored_page(header, index as u32, bytes).map(|_| ())
}
