//! [`SceneFile`]: a paged file opened for reading, page by page.
//!
//! Pages are read with positional reads (`pread`) into memory the reader
//! owns, never through a memory map: a file that another process truncates
//! or overwrites while it is served then yields a short read or a page that
//! fails its checks, reported as an error, where a map would raise SIGBUS
//! and take the whole process down. The header and its directory are read
//! once, at open, with the file's [`FileStamp`]; [`SceneFile::changed`]
//! says whether the open file has been written to since.

use std::fs::File;
use std::path::{Path, PathBuf};

use farfield_protocol::FormatError;
use farfield_protocol::directory::Directory;
use farfield_protocol::file::FileHeader;
use farfield_protocol::hierarchy::Hierarchy;
use farfield_protocol::page::{PAGE_CHECKSUM_BYTES, PAGE_HEADER_BYTES, check_page};

use crate::StoreError;
use crate::stamp::FileStamp;
use crate::verify::{HeaderError, page_extent, read_header, verify_page};

/// A paged file opened for reading.
#[derive(Debug)]
pub struct SceneFile {
    pub path: PathBuf,
    pub header: FileHeader,
    /// The whole directory, read and checked when the file was opened.
    pub directory: Directory,
    /// The header as stored (its fixed bytes and checksum).
    header_bytes: Vec<u8>,
    file: File,
    /// The file when it was opened (its length is the file's bytes).
    stamp: FileStamp,
}

impl SceneFile {
    /// Opens `path` and reads and checks its header (pages are verified
    /// when read).
    pub fn open(path: &Path) -> Result<Self, StoreError> {
        let io = |error| StoreError::Io {
            path: path.to_owned(),
            error,
        };
        let format = |error| StoreError::Format {
            path: path.to_owned(),
            error,
        };
        let file = File::open(path).map_err(io)?;
        let stamp = FileStamp::of(&file.metadata().map_err(io)?);
        let stored = read_header(stamp.len, |offset, n| {
            let mut bytes = vec![0; n as usize];
            read_exact_at(&file, &mut bytes, offset).map(|()| bytes)
        })
        .map_err(|e| match e {
            HeaderError::Read(error) => io(error),
            HeaderError::Format(error) => format(error),
        })?;
        Ok(Self {
            path: path.to_owned(),
            header: stored.header,
            directory: stored.directory,
            header_bytes: stored.bytes,
            file,
            stamp,
        })
    }

    /// The file as it was when opened.
    pub fn stamp(&self) -> FileStamp {
        self.stamp
    }

    /// How the open file changed since it was opened (truncated, extended,
    /// written to), if it did. A file renamed over this one's path is not
    /// a change: this file is still whole.
    pub fn changed(&self) -> Option<String> {
        match self.file.metadata() {
            Ok(now) => self.stamp.change_to(&FileStamp::of(&now)),
            Err(e) => Some(format!("it cannot be examined: {e}")),
        }
    }

    /// The file's header bytes as stored (fixed part and CRC),
    /// which the memory server sends verbatim so clients decode exactly
    /// what is on disk.
    pub fn header_bytes(&self) -> &[u8] {
        &self.header_bytes
    }

    /// Appends page `index`'s stored bytes to `out` after checking its
    /// checksum, its header and its agreement with the directory; on an
    /// error `out` is as it was. A file cut short under the reader is a
    /// truncated page, not a fault.
    pub fn read_page_into(&self, index: usize, out: &mut Vec<u8>) -> Result<(), FormatError> {
        let e = page_extent(&self.directory, index)?;
        let start = out.len();
        out.resize(start + e.length as usize, 0);
        let read = read_exact_at(&self.file, &mut out[start..], e.offset)
            .map_err(|error| match error.kind() {
                std::io::ErrorKind::UnexpectedEof => FormatError::Truncated {
                    what: "page",
                    needed: e.offset + u64::from(e.length),
                    have: self.file.metadata().map_or(0, |m| m.len()),
                },
                _ => FormatError::BadPage {
                    page: index as u32,
                    message: format!("cannot be read: {error}"),
                },
            })
            .and_then(|()| verify_page(&self.header, &self.directory, index, &out[start..]));
        if read.is_err() {
            out.truncate(start);
        }
        read
    }

    /// Checks page `index`'s checksum and header.
    pub fn verify_page(&self, index: usize) -> Result<(), FormatError> {
        self.read_page_into(index, &mut Vec::new())
    }

    /// Indices of pages that fail verification, with the reason: every
    /// check a client makes of a page's bytes (`check_page`), its body
    /// inflated.
    pub fn corrupt_pages(&self) -> Vec<(usize, FormatError)> {
        self.survey_pages().corrupt
    }

    /// Every page read and checked as a client would (`check_page`): the
    /// ones that fail, and how the others are stored.
    pub fn survey_pages(&self) -> PageSurvey {
        let mut survey = PageSurvey::default();
        let mut buffer = Vec::new();
        for i in 0..self.header.page_count as usize {
            buffer.clear();
            let checked = self
                .read_page_into(i, &mut buffer)
                .and_then(|()| check_page(&self.header, &self.directory, i as u32, &buffer));
            match checked {
                Ok(page) => {
                    let decoded = page.records().len() + page.payload().len();
                    survey.decoded_bytes += decoded as u64;
                    survey.stored_bytes +=
                        (buffer.len() - PAGE_HEADER_BYTES - PAGE_CHECKSUM_BYTES) as u64;
                    survey.compressed += usize::from(page.body_is_inflated());
                }
                Err(e) => survey.corrupt.push((i, e)),
            }
        }
        survey
    }

    /// Bytes of the whole file when it was opened.
    pub fn len(&self) -> u64 {
        self.stamp.len
    }

    pub fn is_empty(&self) -> bool {
        self.stamp.len == 0
    }

    /// Every page made resident in a fresh hierarchy; corrupt pages are
    /// reported, not loaded.
    pub fn load_all(&self) -> Result<Hierarchy, FormatError> {
        let mut h = Hierarchy::with_directory(self.header.clone(), self.directory.clone())?;
        let mut buffer = Vec::new();
        for i in 0..self.header.page_count as usize {
            buffer.clear();
            self.read_page_into(i, &mut buffer)?;
            h.insert_page(i as u32, &buffer)?;
        }
        Ok(h)
    }
}

/// Fills `buf` from `file` at `offset`, whatever the platform.
#[cfg(unix)]
fn read_exact_at(file: &File, buf: &mut [u8], offset: u64) -> std::io::Result<()> {
    std::os::unix::fs::FileExt::read_exact_at(file, buf, offset)
}

#[cfg(windows)]
fn read_exact_at(file: &File, mut buf: &mut [u8], mut offset: u64) -> std::io::Result<()> {
    use std::os::windows::fs::FileExt;
    while !buf.is_empty() {
        match file.seek_read(buf, offset)? {
            0 => return Err(std::io::ErrorKind::UnexpectedEof.into()),
            n => {
                buf = &mut buf[n..];
                offset += n as u64;
            }
        }
    }
    Ok(())
}

/// What [`SceneFile::survey_pages`] found.
#[derive(Debug, Default)]
pub struct PageSurvey {
    /// Pages that fail a check, with the reason.
    pub corrupt: Vec<(usize, FormatError)>,
    /// Sound pages stored compressed.
    pub compressed: usize,
    /// Bodies of the sound pages as stored, and decoded.
    pub stored_bytes: u64,
    pub decoded_bytes: u64,
}
