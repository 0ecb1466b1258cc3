//! [`publish`]: a built scene file uploaded to a store.

use std::io::Read;
use std::path::Path;

use farfield_store::{SceneFile, StoreError};
use object_store::WriteMultipart;

use crate::{Bucket, RemoteError};

/// Bytes per part of a multipart upload (S3 wants at least 5 MiB for all
/// but the last).
const PART_BYTES: usize = 8 << 20;
/// Parts in flight at once.
const PARTS_IN_FLIGHT: usize = 4;

/// Uploads the scene file `file` to object `key` of `bucket` and returns
/// the bytes stored. The file is checked first (its header and every
/// page), so a store never receives a broken scene; the upload is one
/// multipart upload, which the store makes visible only when it completes
/// (a reader sees the old object or the new one, never half of one), and
/// which is aborted on any failure.
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
    let remote = |message: String| StoreError::Remote {
        location: location.clone(),
        message,
    };
    let io = |error| StoreError::Io {
        path: file.to_owned(),
        error,
    };
    let mut reader = std::fs::File::open(file).map_err(io)?;
    let store = bucket.store();
    let path = object_store::path::Path::from(key);
    let uploaded = bucket.block_on(async move {
        let upload = store
            .put_multipart(&path)
            .await
            .map_err(|e| e.to_string())?;
        let mut writer = WriteMultipart::new_with_chunk_size(upload, PART_BYTES);
        let mut buffer = vec![0; 1 << 20];
        loop {
            let n = match reader.read(&mut buffer) {
                Ok(0) => break,
                Ok(n) => n,
                Err(e) => {
                    let _ = writer.abort().await;
                    return Err(format!("reading {}: {e}", file.display()));
                }
            };
            if let Err(e) = writer.wait_for_capacity(PARTS_IN_FLIGHT).await {
                let _ = writer.abort().await;
                return Err(e.to_string());
            }
            writer.write(&buffer[..n]);
        }
        writer.finish().await.map_err(|e| e.to_string())?;
        Ok(())
    });
    match uploaded {
        Some(Ok(())) => {}
        Some(Err(message)) => return Err(remote(message)),
        None => return Err(remote("the store's client is closed".into())),
    }
    let stored = bucket
        .head(key)
        .map_err(|e: RemoteError| remote(e.to_string()))?;
    if stored.len != scene.len() {
        return Err(remote(format!(
            "the store holds {} bytes after the upload, not the file's {}",
            stored.len,
            scene.len()
        )));
    }
    Ok(stored.len)
}
