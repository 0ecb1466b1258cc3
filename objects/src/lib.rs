//! Scenes in S3-compatible object storage.
//!
//! The big tile services keep immutable files in object storage and put
//! any number of stateless servers in front that read them by byte range;
//! this crate is that reading for farfield's memory server. A [`Bucket`]
//! is one store and prefix (`s3://bucket/prefix`), reached through the
//! `object_store` crate with its endpoint, region and credentials from the
//! environment; an [`ObjectScene`] is one scene in it, a
//! [`farfield_store::PageSource`] whose header and directory are read once
//! and whose pages are read by range requests and verified like a file's.
//! [`publish`] uploads a built file (and [`upload_file`] and
//! [`download_file`] any file, for builds whose inputs and parts are in a
//! store); a [`DiskTier`] may keep pages read from the store on local
//! disk, under the server's page cache.
//!
//! The server's page reads are blocking calls on its blocking pool and
//! prefetch threads, so a bucket runs its requests on a small runtime of
//! its own and waits for them there; every request has a deadline, and a
//! store that failed is not asked again until a short back-off has passed
//! (reads fail fast meanwhile), so a store that is down costs the server
//! neither threads nor time.

mod bucket;
mod files;
mod publish;
mod scene;
mod tier;
mod url;

pub use bucket::{Bucket, BucketOptions, DEFAULT_COALESCE_BYTES, Listed, RemoteError};
pub use files::{MAX_FILES, ObjectFile, download_file, list_files, upload_file};
pub use publish::publish;
pub use scene::ObjectScene;
pub use tier::DiskTier;
pub use url::StoreUrl;

/// Whether `text` names a place in object storage rather than on disk.
pub fn is_store_url(text: &str) -> bool {
    text.starts_with("s3://")
}
