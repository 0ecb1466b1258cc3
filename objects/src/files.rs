//! Whole files between local disk and a bucket: uploads, downloads and
//! listings under a prefix. A build on many machines reads its inputs
//! (LAS tiles) from a store and hands its parts to the merge through one,
//! as Entwine's subset builds do; the builder itself reads local files
//! only, so these are copied in and out around it.

use std::io::Read;
use std::path::Path;

use farfield_store::ObjectStamp;
use object_store::WriteMultipart;
use object_store::path::Path as ObjectPath;

use crate::bucket::stamp;
use crate::{Bucket, RemoteError};

/// Bytes per part of a multipart upload (S3 wants at least 5 MiB for all
/// but the last).
const PART_BYTES: usize = 8 << 20;
/// Parts in flight at once.
const PARTS_IN_FLIGHT: usize = 4;
/// Bytes per range request of a download: each request has the bucket's
/// deadline, so a file of any size downloads in pieces that each fit it.
const DOWNLOAD_PIECE: u64 = 8 << 20;
/// Range requests of a download in flight at once.
const PIECES_IN_FLIGHT: usize = 4;
/// Objects listed under one prefix at most: a part holds two files a
/// chunk, and a build has thousands of chunks at most; a prefix holding
/// more is refused rather than listed into unbounded memory.
pub const MAX_FILES: usize = 100_000;

/// An object under a prefix: its key, and its size and version as listed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ObjectFile {
    pub key: String,
    pub stamp: ObjectStamp,
}

/// Every object under `prefix` (a folder: `prefix/...`, at any depth), by
/// key; an error past [`MAX_FILES`].
pub fn list_files(bucket: &Bucket, prefix: &str) -> Result<Vec<ObjectFile>, RemoteError> {
    let store = bucket.store();
    let folder = prefix.trim_end_matches('/').to_owned();
    let path = (!folder.is_empty()).then(|| ObjectPath::from(folder.as_str()));
    let mut listed = bucket.run(prefix, "listing", async move {
        use futures_util::TryStreamExt;
        let mut out = Vec::new();
        let mut stream = store.list(path.as_ref());
        while let Some(meta) = stream.try_next().await? {
            out.push(ObjectFile {
                key: meta.location.to_string(),
                stamp: stamp(&meta),
            });
            if out.len() > MAX_FILES {
                break;
            }
        }
        Ok(out)
    })?;
    if listed.len() > MAX_FILES {
        return Err(RemoteError::Unavailable(format!(
            "s3://{}/{prefix}: more than {MAX_FILES} objects under it",
            bucket.url().bucket
        )));
    }
    listed.sort_by(|a, b| a.key.cmp(&b.key));
    Ok(listed)
}

/// Uploads `file` as object `key` in one multipart upload, which the store
/// makes visible only when it completes (a reader sees no object or the
/// whole one) and which is aborted on any failure; the bytes stored, as
/// the store reports them after the upload.
pub fn upload_file(bucket: &Bucket, file: &Path, key: &str) -> Result<u64, RemoteError> {
    let location = format!("s3://{}/{key}", bucket.url().bucket);
    let failed = |message: String| RemoteError::Unavailable(format!("{location}: {message}"));
    let mut reader = std::fs::File::open(file)
        .map_err(|e| failed(format!("cannot read {}: {e}", file.display())))?;
    let len = reader
        .metadata()
        .map_err(|e| failed(format!("cannot read {}: {e}", file.display())))?
        .len();
    let store = bucket.store();
    let path = ObjectPath::from(key);
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
        Some(Err(message)) => return Err(failed(message)),
        None => return Err(failed("the store's client is closed".into())),
    }
    let stored = bucket.head(key)?.len;
    if stored != len {
        return Err(failed(format!(
            "the store holds {stored} bytes after the upload, not the file's {len}"
        )));
    }
    Ok(stored)
}

/// Downloads object `key` (of `stamp`, as listed or asked for) to `file`,
/// in range requests of [`DOWNLOAD_PIECE`] bytes, [`PIECES_IN_FLIGHT`] at
/// once (one stream from a store is far slower than its bandwidth), each
/// of the version `stamp` names (an object replaced meanwhile is an error,
/// not a file of two versions). Written beside `file` and renamed when
/// whole: a download cut off leaves no file under its name.
pub fn download_file(
    bucket: &Bucket,
    key: &str,
    stamp: &ObjectStamp,
    file: &Path,
) -> Result<(), RemoteError> {
    let location = format!("s3://{}/{key}", bucket.url().bucket);
    let local = |e: std::io::Error| {
        RemoteError::Unavailable(format!("{location}: cannot write {}: {e}", file.display()))
    };
    let len = stamp.len;
    let mut partial = file.as_os_str().to_owned();
    partial.push(".partial");
    let partial = std::path::PathBuf::from(partial);
    let out = std::fs::File::create(&partial).map_err(local)?;
    let written = out
        .set_len(len)
        .map_err(local)
        .and_then(|()| download_pieces(bucket, key, len, stamp.e_tag.as_deref(), &out))
        .and_then(|()| out.sync_all().map_err(local))
        .and_then(|()| std::fs::rename(&partial, file).map_err(local));
    if written.is_err() {
        let _ = std::fs::remove_file(&partial);
    }
    written
}

/// The pieces of object `key` written at their offsets in `out`, by
/// [`PIECES_IN_FLIGHT`] threads taking the next piece as each finishes
/// (each request has the bucket's deadline); the first error stops them.
fn download_pieces(
    bucket: &Bucket,
    key: &str,
    len: u64,
    e_tag: Option<&str>,
    out: &std::fs::File,
) -> Result<(), RemoteError> {
    use std::os::unix::fs::FileExt;
    use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
    let location = format!("s3://{}/{key}", bucket.url().bucket);
    let (next, failed) = (AtomicU64::new(0), AtomicBool::new(false));
    let worker = || -> Result<(), RemoteError> {
        while !failed.load(Ordering::Relaxed) {
            let at = next.fetch_add(DOWNLOAD_PIECE, Ordering::Relaxed);
            if at >= len {
                break;
            }
            let end = (at + DOWNLOAD_PIECE).min(len);
            let piece = bucket.get_range(key, at..end, e_tag).and_then(|bytes| {
                if bytes.len() as u64 != end - at {
                    return Err(RemoteError::Changed(location.clone()));
                }
                out.write_all_at(&bytes, at).map_err(|e| {
                    RemoteError::Unavailable(format!("{location}: cannot write its copy: {e}"))
                })
            });
            if piece.is_err() {
                failed.store(true, Ordering::Relaxed);
                return piece;
            }
        }
        Ok(())
    };
    let threads = PIECES_IN_FLIGHT.min(len.div_ceil(DOWNLOAD_PIECE).max(1) as usize);
    std::thread::scope(|scope| {
        let handles: Vec<_> = (0..threads).map(|_| scope.spawn(worker)).collect();
        handles
            .into_iter()
            .map(|h| {
                h.join().unwrap_or_else(|_| {
                    Err(RemoteError::Unavailable(format!(
                        "{location}: a download thread failed"
                    )))
                })
            })
            .collect::<Result<Vec<()>, _>>()
            .map(|_| ())
    })
}
