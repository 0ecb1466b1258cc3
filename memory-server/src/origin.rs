//! Where a server's scenes come from: a folder of `*.ff` files, a list of
//! files, or a prefix in object storage. [`Origin::listing`] says what is
//! there now (each scene's [`Location`] and the version stored), which the
//! server opens at start and the watcher ([`crate::rescan`]) compares with
//! what it serves.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use farfield_objects::{Bucket, ObjectScene};
use farfield_store::{FileStamp, PageSource, SceneFile, Stamp, StoreError};

use super::ServeError;

/// The extension of the paged files a scenes folder is scanned for.
pub const SCENE_EXTENSION: &str = "ff";

/// Where the scenes come from.
#[derive(Debug, Clone)]
pub enum Origin {
    /// Every `*.ff` file directly in a folder, named by file stem.
    Folder(PathBuf),
    /// A fixed list of (name, path).
    Files(Vec<(String, PathBuf)>),
    /// Every `*.ff` object directly under a bucket's prefix, named by file
    /// stem.
    Objects(Arc<Bucket>),
}

/// Where one scene is stored.
#[derive(Debug, Clone)]
pub enum Location {
    File(PathBuf),
    Object { bucket: Arc<Bucket>, key: String },
}

impl Location {
    /// Opens the scene stored here (blocking: reads a file's header, or
    /// asks the store).
    pub fn open(&self) -> Result<Box<dyn PageSource>, StoreError> {
        Ok(match self {
            Self::File(path) => Box::new(SceneFile::open(path)?),
            Self::Object { bucket, key } => Box::new(ObjectScene::open(bucket.clone(), key)?),
        })
    }
}

impl std::fmt::Display for Location {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::File(path) => write!(f, "{}", path.display()),
            Self::Object { bucket, key } => write!(f, "s3://{}/{key}", bucket.url().bucket),
        }
    }
}

/// One scene an origin holds now.
#[derive(Debug, Clone)]
pub struct Entry {
    pub name: String,
    pub location: Location,
    /// The version stored, or why it could not be looked at.
    pub stamp: Result<Stamp, String>,
}

impl Origin {
    /// What is there now, sorted by name (blocking: a folder is read and
    /// its files looked at, a store is asked for a listing).
    pub fn listing(&self) -> Result<Vec<Entry>, ServeError> {
        let files = |files: Vec<(String, PathBuf)>| {
            files
                .into_iter()
                .map(|(name, path)| Entry {
                    name,
                    stamp: std::fs::metadata(&path)
                        .map(|meta| Stamp::File(FileStamp::of(&meta)))
                        .map_err(|e| e.to_string()),
                    location: Location::File(path),
                })
                .collect()
        };
        Ok(match self {
            Self::Folder(dir) => files(scan_dir(dir)?),
            Self::Files(list) => files(list.clone()),
            Self::Objects(bucket) => bucket
                .list()
                .map_err(|e| ServeError::Store(e.to_string()))?
                .into_iter()
                .map(|listed| Entry {
                    name: listed.name,
                    stamp: Ok(Stamp::Object(listed.stamp)),
                    location: Location::Object {
                        bucket: bucket.clone(),
                        key: listed.key,
                    },
                })
                .collect(),
        })
    }
}

/// The `*.ff` files directly in `dir`, named by file stem, sorted by name.
pub fn scan_dir(dir: &Path) -> Result<Vec<(String, PathBuf)>, ServeError> {
    let io = |error| ServeError::ScenesDir {
        path: dir.to_owned(),
        error,
    };
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(io)? {
        let path = entry.map_err(io)?.path();
        if path.extension().and_then(|e| e.to_str()) != Some(SCENE_EXTENSION) || !path.is_file() {
            continue;
        }
        match path.file_stem().and_then(|s| s.to_str()) {
            Some(stem) if !stem.is_empty() => out.push((stem.to_owned(), path.clone())),
            _ => tracing::warn!(path = %path.display(), "skipping scene: name is not UTF-8"),
        }
    }
    out.sort();
    Ok(out)
}
