//! [`publish`]: a built scene file uploaded to a store.

use std::path::Path;

use farfield_store::{SceneFile, StoreError};

use crate::Bucket;
use crate::files::upload_file;

/// Uploads the scene file `file` to object `key` of `bucket` and returns
/// the bytes stored. The file is checked first (its header and every
/// page), so a store never receives a broken scene; the upload is
/// [`upload_file`]'s (a reader sees the old object or the new one, never
/// half of one).
pub fn publish(file: &Path, bucket: &Bucket, key: &str) -> Result<u64, StoreError> {
    let scene = SceneFile::open(file)?;
    if let Some((page, error)) = scene.corrupt_pages().into_iter().next() {
        return Err(StoreError::Format {
            path: file.to_owned(),
            error: farfield_protocol::FormatError::BadPage {
                page: page as u32,
                message: format!("not published: {error}"),
            },
        });
    }
    let location = format!("s3://{}/{key}", bucket.url().bucket);
    let stored = upload_file(bucket, file, key).map_err(|e| StoreError::Remote {
        location: location.clone(),
        message: e.to_string(),
    })?;
    if stored != scene.len() {
        return Err(StoreError::Remote {
            location,
            message: format!(
                "the store holds {stored} bytes after the upload, not the checked file's {}",
                scene.len()
            ),
        });
    }
    Ok(stored)
}
