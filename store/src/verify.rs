//! Reading a stored scene's header and checking its pages, the same for
//! every [`crate::PageSource`]: a file read by positional reads and an
//! object read by range requests fail the same checks with the same errors.

use farfield_protocol::FormatError;
use farfield_protocol::directory::{Directory, Extent};
use farfield_protocol::file::FileHeader;
use farfield_protocol::page::check_stored_page;

/// How much of a scene is read first: the header, the root directory page
/// and, usually, page 0.
pub const HEADER_PROBE_BYTES: u64 = 64 << 10;

/// The most bytes read at once for the directory pages after the scene's
/// pages (they lie together at the file's end); a directory larger than
/// this is read a page at a time.
const DIRECTORY_TAIL_READ_BYTES: u64 = 256 << 20;

/// Why a header could not be read: the store failed, or its bytes are not
/// a header.
#[derive(Debug)]
pub enum HeaderError<E> {
    Read(E),
    Format(FormatError),
}

/// A stored scene's header, its bytes, and its whole directory.
#[derive(Debug, Clone)]
pub struct StoredHeader {
    pub header: FileHeader,
    /// The header as stored (its fixed bytes and checksum), which the
    /// memory server sends verbatim so clients decode what is on disk.
    pub bytes: Vec<u8>,
    pub directory: Directory,
}

/// Reads and decodes the header and the whole directory of a stored scene
/// of `len` bytes through `read(offset, length)`: one read of
/// [`HEADER_PROBE_BYTES`] from the start (the header and the root
/// directory page), one of the directory pages at the file's end, each
/// checked against its parent; then checks that the scene is as long as
/// its directory says.
pub fn read_header<E>(
    len: u64,
    mut read: impl FnMut(u64, u64) -> Result<Vec<u8>, E>,
) -> Result<StoredHeader, HeaderError<E>> {
    let probe = read(0, len.min(HEADER_PROBE_BYTES)).map_err(HeaderError::Read)?;
    let header = FileHeader::decode(&probe).map_err(HeaderError::Format)?;
    let truncated = |needed: u64| {
        HeaderError::Format(FormatError::Truncated {
            what: "file",
            needed,
            have: len,
        })
    };
    // The tail (directory pages after the scene's pages), read once when
    // the first of them is asked for; a read error is kept for the caller.
    let mut tail: Option<(u64, Vec<u8>)> = None;
    let mut failed: Option<E> = None;
    let directory = Directory::read_all(&header, |offset, length| {
        let end = offset.saturating_add(u64::from(length));
        if end > len {
            return Err(FormatError::Truncated {
                what: "file",
                needed: end,
                have: len,
            });
        }
        if let Some(bytes) = probe.get(offset as usize..end as usize) {
            return Ok(bytes.to_vec());
        }
        if tail.is_none() && len - offset <= DIRECTORY_TAIL_READ_BYTES {
            match read(offset, len - offset) {
                Ok(bytes) => tail = Some((offset, bytes)),
                Err(e) => {
                    failed = Some(e);
                    return Err(FormatError::BadHeader(
                        "the directory could not be read".into(),
                    ));
                }
            }
        }
        if let Some((start, bytes)) = &tail
            && let Some(found) = offset
                .checked_sub(*start)
                .and_then(|at| bytes.get(at as usize..(at + u64::from(length)) as usize))
        {
            return Ok(found.to_vec());
        }
        read(offset, u64::from(length)).map_err(|e| {
            failed = Some(e);
            FormatError::BadHeader("the directory could not be read".into())
        })
    });
    if let Some(e) = failed {
        return Err(HeaderError::Read(e));
    }
    let directory = directory.map_err(HeaderError::Format)?;
    directory.check_whole().map_err(HeaderError::Format)?;
    if directory.file_len() > len {
        return Err(truncated(directory.file_len()));
    }
    let bytes = probe[..FileHeader::ENCODED_LEN].to_vec();
    Ok(StoredHeader {
        header,
        bytes,
        directory,
    })
}

/// Where page id `index` is (a scene page or a directory page), or why
/// there is none.
pub fn page_extent(directory: &Directory, index: usize) -> Result<Extent, FormatError> {
    u32::try_from(index)
        .ok()
        .and_then(|id| directory.extent(id))
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
pub fn verify_page(
    header: &FileHeader,
    directory: &Directory,
    index: usize,
    bytes: &[u8],
) -> Result<(), FormatError> {
    let entry = page_extent(directory, index)?;
    if bytes.len() != entry.length as usize {
        return Err(FormatError::Truncated {
            what: "page",
            needed: u64::from(entry.length),
            have: bytes.len() as u64,
        });
    }
    if directory.is_directory(index as u32) {
        return directory.verify(index as u32, bytes);
    }
    check_stored_page(header, directory, index as u32, bytes).map(|_| ())
}
