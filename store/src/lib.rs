//! The paged file on disk: written atomically, read by positional reads.
//!
//! [`write_atomic`] writes to a temporary file beside the target and renames
//! it into place only after everything is on disk, so a failed or
//! interrupted build never leaves a half file under the target's name;
//! [`check_target`] tells a build before it starts that it could not.
//! [`SceneFile`] reads a file's pages with positional reads, verified on
//! request; it is one [`PageSource`] (the server's view of a stored
//! scene), and [`verify`] holds what every source checks the same way.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use farfield_protocol::FormatError;

use farfield_protocol::paged_file::PagedFile;

pub mod histogram;
mod scene_file;
mod source;
mod stamp;
pub mod verify;
pub use histogram::{Histogram, RemoteStats};
pub use scene_file::{PageSurvey, SceneFile};
pub use source::{PageError, PageSource, read_each};
pub use stamp::{FileStamp, ObjectStamp, Stamp};

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
    /// A store other than the local disk (object storage) failed.
    #[error("{location}: {message}")]
    Remote { location: String, message: String },
    /// A scene in a store is not a valid scene.
    #[error("{location}: {error}")]
    RemoteFormat {
        location: String,
        error: FormatError,
    },
}

/// Checks, before a long build, that `path` can be written: its folder
/// exists and takes a new file (one is created and removed), and `path` is
/// not a folder. A build that could only fail at its end should fail first.
/// Temporary files a killed writer of `path` left behind are removed.
pub fn check_target(path: &Path) -> Result<(), StoreError> {
    let io = |error| StoreError::Io {
        path: path.to_owned(),
        error,
    };
    if path.is_dir() {
        return Err(io(std::io::Error::other("is a folder, not a file")));
    }
    remove_abandoned_temps(path);
    // Not the name `write_atomic` uses: a write of the same path in this
    // process may be under way.
    let probe = temp_path(path, "tmp-check")?;
    File::create(&probe).map_err(io)?;
    std::fs::remove_file(&probe).map_err(io)
}

/// Removes the temporary files of writes of `path` (see [`temp_path`]) by
/// processes that are no longer running: a build killed while it wrote.
/// Only where processes can be looked up (`/proc`); elsewhere nothing.
fn remove_abandoned_temps(path: &Path) {
    let proc = Path::new("/proc/self");
    let (Ok(probe), Some(name)) = (temp_path(path, "tmp"), path.file_name()) else {
        return;
    };
    if !proc.exists() {
        return;
    }
    let prefix = format!(".{}.tmp-", name.to_string_lossy());
    let Some(dir) = probe.parent() else { return };
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let file = entry.file_name();
        let Some(pid) = file
            .to_str()
            .and_then(|f| f.strip_prefix(&prefix))
            .and_then(|p| p.parse::<u32>().ok())
        else {
            continue;
        };
        if pid != std::process::id() && !Path::new(&format!("/proc/{pid}")).exists() {
            let _ = std::fs::remove_file(entry.path());
        }
    }
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

/// Writes a file made of `head` (the encoded header and root directory
/// page), the bytes of the file at `body` (pages a build spilled to disk)
/// and `tail` (the other directory pages) to `path`, through a temporary
/// file and a rename, as [`write_atomic`] does. The body is copied by the
/// kernel where it can (`copy_file_range`), never through memory whole.
pub fn write_atomic_parts(
    path: &Path,
    head: &[u8],
    body: &Path,
    tail: &[u8],
) -> Result<u64, StoreError> {
    let io = |error| StoreError::Io {
        path: path.to_owned(),
        error,
    };
    let tmp = temp_path(path, "tmp")?;
    let result = (|| -> std::io::Result<u64> {
        let mut out = File::create(&tmp)?;
        out.write_all(head)?;
        let copied = std::io::copy(&mut File::open(body)?, &mut out)?;
        out.write_all(tail)?;
        out.sync_all()?;
        std::fs::rename(&tmp, path)?;
        Ok(head.len() as u64 + copied + tail.len() as u64)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result.map_err(io)
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
        let head = file.head();
        out.write_all(&head)?;
        let mut written = head.len() as u64;
        for page in file.pages.iter().chain(file.tail()) {
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
