//! The paged file on disk: written atomically, read through a memory map.
//!
//! [`write_atomic`] writes to a temporary file beside the target and renames
//! it into place only after everything is on disk, so a failed or
//! interrupted build never leaves a half file under the target's name;
//! [`check_target`] tells a build before it starts that it could not.
//! [`SceneFile`] maps a file and hands out page bytes, verified on request;
//! it is the one [`PageSource`] (the server's view of a stored scene) so far.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use farfield_protocol::FormatError;
use farfield_protocol::file::{FileHeader, HierarchyKind};
use farfield_protocol::page::Page;
use memmap2::Mmap;

use farfield_protocol::paged_file::PagedFile;

mod source;
pub use source::PageSource;

/// Why a file could not be written or read. The cause is a field named
/// `error`, printed in the message (as in the importers' `ImportError`).
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    #[error("{path}: {error}")]
    Io {
        path: PathBuf,
        error: std::io::Error,
    },
    #[error("{path}: {error}")]
    Format { path: PathBuf, error: FormatError },
}

/// Checks, before a long build, that `path` can be written: its folder
/// exists and takes a new file (one is created and removed), and `path` is
/// not a folder. A build that could only fail at its end should fail first.
pub fn check_target(path: &Path) -> Result<(), StoreError> {
    let io = |error| StoreError::Io {
        path: path.to_owned(),
        error,
    };
    if path.is_dir() {
        return Err(io(std::io::Error::other("is a folder, not a file")));
    }
    // Not the name `write_atomic` uses: a write of the same path in this
    // process may be under way.
    let probe = temp_path(path, "tmp-check")?;
    File::create(&probe).map_err(io)?;
    std::fs::remove_file(&probe).map_err(io)
}

/// A temporary file for `path`: hidden, next to `path` (so a rename stays on
/// one file system), named by `kind` and process.
fn temp_path(path: &Path, kind: &str) -> Result<PathBuf, StoreError> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = path.file_name().ok_or_else(|| StoreError::Io {
        path: path.to_owned(),
        error: std::io::Error::other("no file name"),
    })?;
    Ok(dir.join(format!(
        ".{}.{kind}-{}",
        name.to_string_lossy(),
        std::process::id()
    )))
}

/// Writes `file` to `path` through a temporary file and a rename.
pub fn write_atomic(path: &Path, file: &PagedFile) -> Result<u64, StoreError> {
    let io = |error| StoreError::Io {
        path: path.to_owned(),
        error,
    };
    let tmp = temp_path(path, "tmp")?;
    let result = (|| -> std::io::Result<u64> {
        let mut out = BufWriter::new(File::create(&tmp)?);
        let header = file.header.encode();
        out.write_all(&header)?;
        let mut written = header.len() as u64;
        for page in &file.pages {
            out.write_all(page)?;
            written += page.len() as u64;
        }
        out.into_inner().map_err(|e| e.into_error())?.sync_all()?;
        std::fs::rename(&tmp, path)?;
        Ok(written)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result.map_err(io)
}

/// A paged file opened for reading.
#[derive(Debug)]
pub struct SceneFile {
    pub path: PathBuf,
    pub header: FileHeader,
    map: Mmap,
}

impl SceneFile {
    /// Maps `path` and parses its header (pages are verified on use).
    pub fn open(path: &Path) -> Result<Self, StoreError> {
        let file = File::open(path).map_err(|error| StoreError::Io {
            path: path.to_owned(),
            error,
        })?;
        // SAFETY: the map is read-only and farfield never writes a file in
        // place (builds write a new file and rename it over the old one), so
        // the mapped bytes do not change under us. If another process
        // truncates the file anyway, reads past the new end raise SIGBUS; that
        // is the documented hazard of memory maps and not something a reader
        // can guard against without giving up the map.
        let map = unsafe { Mmap::map(&file) }.map_err(|error| StoreError::Io {
            path: path.to_owned(),
            error,
        })?;
        let header = FileHeader::decode(&map).map_err(|error| StoreError::Format {
            path: path.to_owned(),
            error,
        })?;
        let scene = Self {
            path: path.to_owned(),
            header,
            map,
        };
        if scene.header.file_len() > scene.map.len() as u64 {
            return Err(StoreError::Format {
                path: path.to_owned(),
                error: FormatError::Truncated {
                    what: "file",
                    needed: scene.header.file_len(),
                    have: scene.map.len() as u64,
                },
            });
        }
        Ok(scene)
    }

    /// The stored bytes of page `index` (unverified), as sent on the wire.
    pub fn page_bytes(&self, index: usize) -> Option<&[u8]> {
        let e = self.header.pages.get(index)?;
        let start = usize::try_from(e.offset).ok()?;
        self.map.get(start..start.checked_add(e.length as usize)?)
    }

    /// The file's header bytes as stored (fixed part, directory and CRC),
    /// which the memory server sends verbatim so clients decode exactly
    /// what is on disk.
    pub fn header_bytes(&self) -> &[u8] {
        let len = FileHeader::encoded_len(self.header.pages.len()).min(self.map.len());
        &self.map[..len]
    }

    /// Checks page `index`'s checksum and header.
    pub fn verify_page(&self, index: usize) -> Result<(), FormatError> {
        let bytes = self.page_bytes(index).ok_or(FormatError::BadPage {
            page: index as u32,
            message: "outside the file".into(),
        })?;
        let page = match self.header.kind {
            HierarchyKind::Spheres => Page::parse(bytes, index as u32, self.header.node_bytes)?,
            HierarchyKind::Cubes => {
                Page::parse_with_payload(bytes, index as u32, self.header.node_bytes)?
            }
        };
        if page.header.first_node != self.header.pages[index].first_node {
            return Err(FormatError::BadPage {
                page: index as u32,
                message: "disagrees with the directory".into(),
            });
        }
        Ok(())
    }

    /// Indices of pages that fail verification, with the reason.
    pub fn corrupt_pages(&self) -> Vec<(usize, FormatError)> {
        (0..self.header.pages.len())
            .filter_map(|i| self.verify_page(i).err().map(|e| (i, e)))
            .collect()
    }

    /// Bytes of the whole file.
    pub fn len(&self) -> u64 {
        self.map.len() as u64
    }

    pub fn is_empty(&self) -> bool {
        self.map.is_empty()
    }

    /// Every page made resident in a fresh hierarchy; corrupt pages are
    /// reported, not loaded.
    pub fn load_all(&self) -> Result<farfield_protocol::hierarchy::Hierarchy, FormatError> {
        let mut h = farfield_protocol::hierarchy::Hierarchy::new(self.header.clone())?;
        for i in 0..self.header.pages.len() {
            let bytes = self.page_bytes(i).ok_or(FormatError::BadPage {
                page: i as u32,
                message: "outside the file".into(),
            })?;
            h.insert_page(i as u32, bytes)?;
        }
        Ok(h)
    }
}
