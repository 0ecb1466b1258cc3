//! [`Bucket`]: one S3-compatible store and key prefix, with blocking calls
//! that have deadlines and a memory of the store being down.

use std::future::Future;
use std::ops::Range;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use bytes::Bytes;
use farfield_store::{ObjectStamp, RemoteStats};
use object_store::aws::{AmazonS3Builder, AmazonS3ConfigKey};
use object_store::path::Path;
use object_store::{
    BackoffConfig, ClientOptions, GetOptions, GetRange, ObjectMeta, ObjectStore, RetryConfig,
};

use crate::{DiskTier, StoreUrl};

/// The extension of scene objects a prefix is listed for.
const SCENE_EXTENSION: &str = ".ff";
/// Scenes listed at most under one prefix; past it the rest are ignored
/// (with a warning), so a prefix of millions of objects costs bounded
/// memory per listing.
pub const MAX_LISTED: usize = 10_000;
/// The default bound on one coalesced range request: a request costs a
/// round trip (milliseconds to a remote store), 4 MiB a few more at most.
pub const DEFAULT_COALESCE_BYTES: u64 = 4 << 20;
/// How long a store that failed is left alone before it is tried again,
/// first and at most: reads in between fail at once.
const FIRST_BACKOFF: Duration = Duration::from_millis(250);
const MAX_BACKOFF: Duration = Duration::from_secs(4);

/// How a bucket talks to its store. What is not given here comes from the
/// environment.
#[derive(Debug, Clone)]
pub struct BucketOptions {
    /// The longest one request may take before it counts as failed.
    pub timeout: Duration,
    /// The store's address (`http://127.0.0.1:9000`), in place of
    /// `AWS_ENDPOINT_URL`.
    pub endpoint: Option<String>,
    /// Credentials, in place of `AWS_ACCESS_KEY_ID` and
    /// `AWS_SECRET_ACCESS_KEY`.
    pub credentials: Option<(String, String)>,
    /// Neighbouring pages are read in one range request while their span
    /// is at most this many bytes (0: every page alone).
    pub coalesce_bytes: u64,
    /// A local-disk second tier: its folder and its bound in bytes.
    pub tier: Option<(PathBuf, u64)>,
}

impl Default for BucketOptions {
    fn default() -> Self {
        Self {
            timeout: Duration::from_secs(10),
            endpoint: None,
            credentials: None,
            coalesce_bytes: DEFAULT_COALESCE_BYTES,
            tier: None,
        }
    }
}

/// Why a request to the store failed.
#[derive(Debug, Clone, thiserror::Error)]
pub enum RemoteError {
    /// The object is not there (deleted, or never was).
    #[error("{0}: no such object")]
    NotFound(String),
    /// The object is there but is not the version asked for.
    #[error("{0}: the object was replaced")]
    Changed(String),
    /// The store did not answer, not in time, or refused: try again later.
    #[error("{0}")]
    Unavailable(String),
}

/// A scene object found by listing a prefix.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Listed {
    /// The object's file name without `.ff`.
    pub name: String,
    pub key: String,
    pub stamp: ObjectStamp,
}

/// When the store last failed, and how long it is left alone.
#[derive(Debug, Default)]
struct Health {
    down_until: Option<Instant>,
    backoff: Duration,
    why: String,
}

/// One store and key prefix (`s3://bucket/prefix`).
#[derive(Debug)]
pub struct Bucket {
    url: StoreUrl,
    store: Arc<dyn ObjectStore>,
    /// Requests run here, so that the server's threads can wait for them
    /// (in an `Option` only so that `Drop` can take it).
    runtime: Option<tokio::runtime::Runtime>,
    timeout: Duration,
    coalesce_bytes: u64,
    tier: Option<DiskTier>,
    stats: Arc<RemoteStats>,
    health: Mutex<Health>,
}

impl Bucket {
    /// A bucket for `url`, its endpoint, region and credentials from the
    /// environment as the AWS tools read them (`AWS_ENDPOINT_URL`,
    /// `AWS_REGION`, `AWS_ACCESS_KEY_ID`, `AWS_SECRET_ACCESS_KEY`, ...).
    /// Path-style addressing unless `AWS_VIRTUAL_HOSTED_STYLE_REQUEST` is
    /// set; plain HTTP when the endpoint is `http://` (a local store).
    /// Nothing is requested yet.
    pub fn open(
        url: &StoreUrl,
        options: &BucketOptions,
        stats: Arc<RemoteStats>,
    ) -> Result<Self, RemoteError> {
        let unavailable =
            |e: &dyn std::fmt::Display| RemoteError::Unavailable(format!("{url}: {e}"));
        let mut builder = AmazonS3Builder::from_env().with_bucket_name(&url.bucket);
        if let Some(endpoint) = &options.endpoint {
            builder = builder.with_endpoint(endpoint);
        }
        if let Some((key, secret)) = &options.credentials {
            builder = builder
                .with_access_key_id(key)
                .with_secret_access_key(secret);
        }
        if builder
            .get_config_value(&AmazonS3ConfigKey::Region)
            .is_none()
        {
            // Local stores take any region; AWS's default.
            builder = builder.with_region("us-east-1");
        }
        let endpoint = builder
            .get_config_value(&AmazonS3ConfigKey::Endpoint)
            .unwrap_or_default();
        let allow_http = endpoint.starts_with("http://")
            || std::env::var("AWS_ALLOW_HTTP")
                .is_ok_and(|v| v == "1" || v.eq_ignore_ascii_case("true"));
        // The client's own timeout is a backstop past the bucket's deadline,
        // which is what ends a request: its error says so plainly, and it is
        // counted as a timeout.
        let client = ClientOptions::new()
            .with_timeout(options.timeout + Duration::from_secs(1))
            .with_connect_timeout(options.timeout.min(Duration::from_secs(5)))
            .with_allow_http(allow_http);
        // A few quick retries inside the deadline; the bucket's own
        // back-off takes over after that.
        let retry = RetryConfig {
            backoff: BackoffConfig {
                init_backoff: Duration::from_millis(50),
                max_backoff: Duration::from_millis(500),
                base: 2.0,
            },
            max_retries: 2,
            retry_timeout: options.timeout,
        };
        let store = builder
            .with_client_options(client)
            .with_retry(retry)
            .build()
            .map_err(|e| unavailable(&e))?;
        let tier = match &options.tier {
            Some((dir, bytes)) => Some(DiskTier::open(dir, *bytes).map_err(|e| {
                RemoteError::Unavailable(format!("the second tier in {}: {e}", dir.display()))
            })?),
            None => None,
        };
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .thread_name("farfield-store")
            .enable_all()
            .build()
            .map_err(|e| unavailable(&e))?;
        Ok(Self {
            url: url.clone(),
            store: Arc::new(store),
            runtime: Some(runtime),
            timeout: options.timeout,
            coalesce_bytes: options.coalesce_bytes,
            tier,
            stats,
            health: Mutex::new(Health::default()),
        })
    }

    /// The bucket and prefix.
    pub fn url(&self) -> &StoreUrl {
        &self.url
    }

    /// The largest span read in one request for neighbouring pages.
    pub fn coalesce_bytes(&self) -> u64 {
        self.coalesce_bytes
    }

    /// The local-disk second tier, if there is one.
    pub fn tier(&self) -> Option<&DiskTier> {
        self.tier.as_ref()
    }

    pub(crate) fn stats(&self) -> &RemoteStats {
        &self.stats
    }

    /// What this bucket's requests did (shared with whoever reports it).
    pub fn stats_handle(&self) -> Arc<RemoteStats> {
        self.stats.clone()
    }

    /// The object's size and version.
    pub fn head(&self, key: &str) -> Result<ObjectStamp, RemoteError> {
        let (store, path) = (self.store.clone(), Path::from(key));
        let meta = self.run(key, "asking for", async move { store.head(&path).await })?;
        Ok(stamp(&meta))
    }

    /// Bytes `range` of object `key`, if it is still version `e_tag` (when
    /// given and the store keeps entity tags).
    pub fn get_range(
        &self,
        key: &str,
        range: Range<u64>,
        e_tag: Option<&str>,
    ) -> Result<Bytes, RemoteError> {
        let (store, path) = (self.store.clone(), Path::from(key));
        let options = GetOptions {
            range: Some(GetRange::Bounded(range)),
            if_match: e_tag.map(str::to_owned),
            ..GetOptions::default()
        };
        let bytes = self.run(key, "reading", async move {
            store.get_opts(&path, options).await?.bytes().await
        })?;
        RemoteStats::add(&self.stats.bytes, bytes.len() as u64);
        Ok(bytes)
    }

    /// The scene objects (`*.ff`) directly under the prefix, by name.
    pub fn list(&self) -> Result<Vec<Listed>, RemoteError> {
        let store = self.store.clone();
        let prefix = (!self.url.key.is_empty()).then(|| Path::from(self.url.key.as_str()));
        let listing = self.run(&self.url.key, "listing", async move {
            store.list_with_delimiter(prefix.as_ref()).await
        })?;
        let mut out: Vec<Listed> = listing
            .objects
            .iter()
            .filter_map(|meta| {
                let file = meta.location.filename()?;
                let name = file.strip_suffix(SCENE_EXTENSION)?;
                (!name.is_empty()).then(|| Listed {
                    name: name.to_owned(),
                    key: meta.location.to_string(),
                    stamp: stamp(meta),
                })
            })
            .collect();
        out.sort_by(|a, b| a.name.cmp(&b.name));
        if out.len() > MAX_LISTED {
            tracing::warn!(store = %self.url, "{} scenes listed; serving the first {MAX_LISTED}", out.len());
            out.truncate(MAX_LISTED);
        }
        Ok(out)
    }

    /// Runs one request to completion on the bucket's runtime, within the
    /// deadline, counting it, and remembering a failure so that the next
    /// calls fail at once until the back-off has passed.
    ///
    /// Must not be called from an async task (it blocks the thread until
    /// the request ends): the server calls it from its blocking pool and
    /// its own threads.
    pub(crate) fn run<T>(
        &self,
        key: &str,
        what: &str,
        request: impl Future<Output = object_store::Result<T>>,
    ) -> Result<T, RemoteError> {
        let place = format!("s3://{}/{key}", self.url.bucket);
        if let Some(why) = self.resting() {
            RemoteStats::add(&self.stats.fast_failures, 1);
            return Err(RemoteError::Unavailable(why));
        }
        let Some(runtime) = &self.runtime else {
            return Err(RemoteError::Unavailable(format!(
                "{place}: the store's client is closed"
            )));
        };
        RemoteStats::add(&self.stats.requests, 1);
        let started = Instant::now();
        let deadline = self.timeout;
        let result = runtime.block_on(async move { tokio::time::timeout(deadline, request).await });
        self.stats.latency.observe(started.elapsed());
        match result {
            Ok(Ok(value)) => {
                self.answered();
                Ok(value)
            }
            Ok(Err(object_store::Error::NotFound { .. })) => {
                self.answered();
                Err(RemoteError::NotFound(place))
            }
            Ok(Err(object_store::Error::Precondition { .. })) => {
                self.answered();
                Err(RemoteError::Changed(place))
            }
            Ok(Err(e)) => {
                RemoteStats::add(&self.stats.errors, 1);
                Err(self.failed(format!("{what} {place}: {e}")))
            }
            Err(_) => {
                RemoteStats::add(&self.stats.errors, 1);
                RemoteStats::add(&self.stats.timeouts, 1);
                Err(self.failed(format!("{what} {place}: no answer within {deadline:?}")))
            }
        }
    }

    /// Runs a longer job (an upload) on the bucket's runtime; its requests
    /// have the client's per-request timeout, the whole has none.
    pub(crate) fn block_on<T>(&self, job: impl Future<Output = T>) -> Option<T> {
        self.runtime.as_ref().map(|r| r.block_on(job))
    }

    pub(crate) fn store(&self) -> Arc<dyn ObjectStore> {
        self.store.clone()
    }

    fn health(&self) -> std::sync::MutexGuard<'_, Health> {
        self.health.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Why the store is being left alone now, if it is.
    fn resting(&self) -> Option<String> {
        let health = self.health();
        let until = health.down_until?;
        let left = until.checked_duration_since(Instant::now())?;
        Some(format!(
            "{} (asked again in {} ms)",
            health.why,
            left.as_millis()
        ))
    }

    fn answered(&self) {
        let mut health = self.health();
        if health.down_until.take().is_some() {
            tracing::info!(store = %self.url, "the store answers again");
        }
        health.backoff = Duration::ZERO;
    }

    fn failed(&self, why: String) -> RemoteError {
        let mut health = self.health();
        if health.down_until.is_none() {
            tracing::warn!(store = %self.url, "the store failed; its pages are unavailable until it answers: {why}");
        }
        health.backoff = if health.backoff.is_zero() {
            FIRST_BACKOFF
        } else {
            (health.backoff * 2).min(MAX_BACKOFF)
        };
        health.down_until = Some(Instant::now() + health.backoff);
        health.why.clone_from(&why);
        RemoteError::Unavailable(why)
    }
}

impl Drop for Bucket {
    fn drop(&mut self) {
        // A runtime dropped on an async task panics; this does not wait.
        if let Some(runtime) = self.runtime.take() {
            runtime.shutdown_background();
        }
    }
}

pub(crate) fn stamp(meta: &ObjectMeta) -> ObjectStamp {
    ObjectStamp {
        len: meta.size,
        e_tag: meta.e_tag.clone(),
        modified_s: meta.last_modified.timestamp(),
    }
}
