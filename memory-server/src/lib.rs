//! The memory server: scenes on disk, streamed page by page
//! to websocket clients (the 1995 report's section 6.2, with QSplat's
//! breadth-first pages).
//!
//! [`start`] opens every `*.ff` file in a folder (or a list of files),
//! binds, and serves in the background of the current tokio runtime;
//! the [`RunningServer`] it returns gives the bound address, metrics, and a
//! graceful [`RunningServer::shutdown`]. The CLI's `serve` subcommand and
//! the client's demo both embed it this way.
//!
//! - [`catalog`]: the scenes and their child-page ranges;
//! - [`rescan`]: the catalog kept in step with the disk while serving;
//! - [`cache`]: the byte-bounded LRU of verified page frames;
//! - [`prefetch`]: read-ahead of child pages on a small thread pool;
//! - [`lookahead`]: read-ahead along a demo presenter's extrapolated
//!   motion, walked with the client's own traversal;
//! - [`schedule`]: one connection's priority queue and in-flight window;
//! - [`limits`]: what one client may cost and how long it may take;
//!   `admission` and `listen` enforce them at the socket, `session` after
//!   the upgrade; [`rlimit`] raises the open-files limit to fit;
//! - `session`: the websocket session itself;
//! - `routes`: the HTTP endpoints; `pages` and [`web_assets`]: the
//!   browser's list of scenes and viewer page, and the viewer's files;
//! - [`metrics`]: atomics and the Prometheus text.

pub mod access;
mod admission;
pub mod cache;
pub mod catalog;
pub mod demo;
pub mod hosts;
pub mod lag;
pub mod limits;
mod listen;
pub mod logs;
pub mod lookahead;
pub mod metrics;
pub mod origin;
mod pages;
pub mod prefetch;
pub mod quote;
pub mod rescan;
pub mod rlimit;
mod routes;
pub mod schedule;
mod session;
pub mod tls;
pub mod web_assets;

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::Duration;

use tokio::sync::{Notify, watch};
use tokio::task::JoinHandle;

use self::access::Access;
use self::admission::Admission;
use self::cache::PageCache;
use self::catalog::Catalog;
use self::limits::Limits;
use self::lookahead::Lookahead;
use self::metrics::{Metrics, MetricsSnapshot};
use self::origin::Origin;
use self::prefetch::Prefetcher;
use self::rescan::{DEFAULT_RESCAN_INTERVAL, Rescanner};
use self::tls::TlsFiles;

/// The page cache's default bound.
pub const DEFAULT_CACHE_BYTES: u64 = 256 << 20;

/// How long [`RunningServer::shutdown`] waits for open sessions to close.
pub const SHUTDOWN_GRACE: Duration = Duration::from_secs(5);

/// Why the server could not start or stop cleanly. Causes are fields named
/// `error`, printed in the message (as in the importers' `ImportError`).
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    #[error("scenes folder {path}: {error}")]
    ScenesDir {
        path: PathBuf,
        error: std::io::Error,
    },
    #[error("object store: {0}")]
    Store(String),
    #[error("two scenes are named {0:?}")]
    DuplicateScene(String),
    #[error("cannot listen on {addr}: {error}")]
    Bind {
        addr: SocketAddr,
        error: std::io::Error,
    },
    #[error("cannot start the prefetch threads: {0}")]
    Threads(std::io::Error),
    #[error("server task failed: {0}")]
    Task(String),
    #[error("TLS: {0}")]
    Tls(String),
}

/// What to serve and where.
#[derive(Debug, Clone)]
pub struct ServerConfig {
    /// A folder (every `*.ff` file directly in it is a scene named by its
    /// stem), a list of files, or a prefix in object storage.
    pub scenes: Origin,
    /// Port 0 picks a free port; [`RunningServer::local_addr`] says which.
    pub listen: SocketAddr,
    /// Bound on the shared page cache, in bytes.
    pub cache_bytes: u64,
    /// How often the scenes are looked at again for files added, replaced,
    /// changed or deleted; zero never looks again.
    pub rescan_interval: Duration,
    /// Connections, timeouts, rates.
    pub limits: Limits,
    /// Tokens and allowed origins.
    pub access: Access,
    /// Serve HTTPS and `wss://` with this certificate; plain HTTP without.
    pub tls: Option<TlsFiles>,
    /// A folder of the browser viewer's built files; `None` serves the
    /// viewer built into this binary, or looks in the usual places
    /// ([`web_assets::find`]).
    pub web: Option<PathBuf>,
}

impl ServerConfig {
    /// Serves a folder, with the default cache size and rescan interval.
    pub fn new(scenes_dir: impl Into<PathBuf>, listen: SocketAddr) -> Self {
        Self::with_origin(Origin::Folder(scenes_dir.into()), listen)
    }

    /// Serves the given (name, path) pairs.
    pub fn files(scenes: Vec<(String, PathBuf)>, listen: SocketAddr) -> Self {
        Self::with_origin(Origin::Files(scenes), listen)
    }

    /// Serves the `*.ff` objects under a bucket's prefix.
    pub fn objects(bucket: Arc<farfield_objects::Bucket>, listen: SocketAddr) -> Self {
        Self::with_origin(Origin::Objects(bucket), listen)
    }

    pub fn with_origin(scenes: Origin, listen: SocketAddr) -> Self {
        Self {
            scenes,
            listen,
            cache_bytes: DEFAULT_CACHE_BYTES,
            rescan_interval: DEFAULT_RESCAN_INTERVAL,
            limits: Limits::default(),
            access: Access::default(),
            tls: None,
            web: None,
        }
    }
}

/// Everything the handlers share.
#[derive(Debug)]
pub(crate) struct AppState {
    pub catalog: Arc<Catalog>,
    pub cache: Arc<PageCache>,
    pub metrics: Arc<Metrics>,
    pub prefetch: Prefetcher,
    /// Read-ahead along demo presenters' motion.
    pub lookahead: Lookahead,
    pub limits: Limits,
    pub access: Access,
    /// How far behind the runtime is (the message-rate limit allows for it).
    pub lag: Arc<lag::Lag>,
    /// The names requests may be for (DNS rebinding is refused).
    pub hosts: hosts::Hosts,
    /// `https` with TLS, else `http`: the scheme of the server's own origin.
    pub scheme: &'static str,
    /// Becomes `true` when the server is shutting down.
    pub shutdown: watch::Receiver<bool>,
    /// Signalled whenever a session ends.
    pub session_ended: Notify,
    /// The browser viewer's files, if this server has them.
    pub web: Option<web_assets::WebViewer>,
    /// Demo sessions: presenters and their followers.
    pub demo: Arc<demo::DemoSessions>,
}

/// A server running in the background of the current tokio runtime.
/// Dropping it starts a shutdown without waiting for it.
#[derive(Debug)]
pub struct RunningServer {
    local_addr: SocketAddr,
    state: Arc<AppState>,
    shutdown_tx: Arc<watch::Sender<bool>>,
    task: Option<JoinHandle<()>>,
    admission: Arc<Admission>,
}

/// Starts shutting a server down from anywhere (a signal handler, a test).
#[derive(Debug, Clone)]
pub struct ShutdownHandle(Arc<watch::Sender<bool>>);

impl ShutdownHandle {
    /// Stops accepting connections and tells every session to close.
    pub fn shutdown(&self) {
        self.0.send_replace(true);
    }
}

/// Serves the scenes `config` names. Files that fail to open are logged
/// and skipped (and served once they can be, when rescanning).
pub async fn start(config: ServerConfig) -> Result<RunningServer, ServeError> {
    let ServerConfig {
        scenes: origin,
        listen,
        cache_bytes,
        rescan_interval,
        limits,
        access,
        tls,
        web,
    } = config;
    let web = web
        .map(web_assets::WebViewer::Folder)
        .or_else(web_assets::find);
    match &web {
        Some(viewer) => tracing::info!("serving {}", viewer.describe()),
        None => tracing::warn!(
            "no browser viewer: {} (web/build builds one into web/dist)",
            web_assets::not_embedded()
        ),
    }
    let cert_names = match &tls {
        Some(files) => tls::read_certs(&files.cert)
            .map_err(ServeError::Tls)?
            .first()
            .map(hosts::certificate_names)
            .unwrap_or_default(),
        None => Vec::new(),
    };
    let scheme = if tls.is_some() { "https" } else { "http" };
    let tls = tls
        .as_ref()
        .map(tls::acceptor)
        .transpose()
        .map_err(ServeError::Tls)?;
    let mut limits = limits.sane();
    fit_open_files(&mut limits);
    // Blocking (files are read, a store is asked), so off the runtime.
    let first = origin.clone();
    let catalog = tokio::task::spawn_blocking(move || {
        let listing = match first.listing() {
            // A replica may start before its store answers: it serves
            // what the watcher finds once it does.
            Err(ServeError::Store(e)) => {
                tracing::warn!("the scenes' store cannot be listed yet: {e}");
                Vec::new()
            }
            listing => listing?,
        };
        let entries: Vec<_> = listing.into_iter().map(|e| (e.name, e.location)).collect();
        Catalog::open(&entries)
    })
    .await
    .map_err(|e| ServeError::Task(e.to_string()))??;
    let catalog = Arc::new(catalog);
    if catalog.is_empty() {
        tracing::warn!("no scenes to serve");
    }
    let metrics = Arc::new(Metrics {
        store: match &origin {
            Origin::Objects(bucket) => bucket.stats_handle(),
            _ => Default::default(),
        },
        ..Metrics::default()
    });
    metrics
        .scenes
        .store(catalog.len() as u64, Ordering::Relaxed);
    let cache = Arc::new(PageCache::new(cache_bytes, &metrics));
    let prefetch =
        Prefetcher::start(cache.clone(), metrics.clone()).map_err(ServeError::Threads)?;
    let lookahead =
        Lookahead::start(cache.clone(), metrics.clone()).map_err(ServeError::Threads)?;
    let listener = tokio::net::TcpListener::bind(listen)
        .await
        .map_err(|error| ServeError::Bind {
            addr: listen,
            error,
        })?;
    let local_addr = listener.local_addr().map_err(|error| ServeError::Bind {
        addr: listen,
        error,
    })?;
    let hosts = hosts::Hosts::new(local_addr, &cert_names, &access.allowed_hosts);
    let (shutdown_tx, shutdown_rx) = watch::channel(false);
    let state = Arc::new(AppState {
        catalog,
        cache,
        metrics,
        prefetch,
        lookahead,
        limits: limits.clone(),
        access,
        hosts,
        scheme,
        lag: lag::Lag::new(),
        shutdown: shutdown_rx.clone(),
        session_ended: Notify::new(),
        web,
        demo: Arc::new(demo::DemoSessions::new(&limits)),
    });
    let admission = Admission::new(
        limits.max_connections,
        limits.max_connections_per_address,
        state.metrics.clone(),
    );
    tokio::spawn(state.lag.clone().run(shutdown_rx.clone()));
    let task = tokio::spawn(listen::accept_loop(
        listener,
        routes::router(state.clone()),
        state.clone(),
        admission.clone(),
        tls,
        shutdown_rx,
    ));
    if !rescan_interval.is_zero() {
        tokio::spawn(rescan_loop(
            Rescanner::new(origin),
            state.clone(),
            rescan_interval,
        ));
    }
    tracing::info!(%local_addr, scenes = state.catalog.len(), cache_bytes, "listening");
    Ok(RunningServer {
        local_addr,
        state,
        shutdown_tx: Arc::new(shutdown_tx),
        task: Some(task),
        admission,
    })
}

/// Raises the open-files limit to what `limits` needs (connections,
/// refusals being answered, and the server's own files), or lowers the
/// connection and refusal limits to what the open-files limit allows (with
/// a warning): a server that runs out of descriptors refuses everyone, and
/// cannot open its scenes.
fn fit_open_files(limits: &mut Limits) {
    let wanted = (limits.max_connections + limits.max_refusing) as u64 + rlimit::RESERVED_FILES;
    if let Some(files) = rlimit::raise_open_files(wanted) {
        let (connections, refusing) = rlimit::share_open_files(files, limits);
        if connections < limits.max_connections || refusing < limits.max_refusing {
            tracing::warn!(
                open_files = files,
                "the open-files limit allows {connections} connections (and {refusing} refusals \
                 answered at once), not {}; serving at most {connections}",
                limits.max_connections
            );
        }
        limits.max_connections = connections;
        limits.max_refusing = refusing;
    }
}

/// Rescans every `interval` until the server shuts down; each pass runs on
/// the blocking pool (it stats and opens files).
async fn rescan_loop(rescanner: Rescanner, state: Arc<AppState>, interval: Duration) {
    let rescanner = Arc::new(rescanner);
    let mut shutdown = state.shutdown.clone();
    let mut tick = tokio::time::interval(interval);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    tick.tick().await;
    loop {
        tokio::select! {
            _ = tick.tick() => {}
            _ = shutdown.wait_for(|&stop| stop) => return,
        }
        let (rescanner, state) = (rescanner.clone(), state.clone());
        let pass = tokio::task::spawn_blocking(move || {
            rescanner.pass(&state.catalog);
            let scenes = state.catalog.len() as u64;
            state.metrics.scenes.store(scenes, Ordering::Relaxed);
        });
        if pass.await.is_err() {
            // The runtime is shutting down.
            return;
        }
    }
}

impl RunningServer {
    /// The address actually bound (the real port when asked for port 0).
    pub fn local_addr(&self) -> SocketAddr {
        self.local_addr
    }

    /// The counters now.
    pub fn metrics(&self) -> MetricsSnapshot {
        self.state.metrics.snapshot()
    }

    /// The counters now, as `GET /metrics` renders them.
    pub fn metrics_text(&self) -> String {
        let mut text = self.state.metrics.render();
        self.state.demo.render_metrics(&mut text, |_| true);
        text
    }

    /// Serves one connection over `io` as if it had been accepted from
    /// `peer`, through everything an accepted connection goes through
    /// after admission (HTTP/1.1, the access checks, the routes, a
    /// websocket session), and returns when it ends: how the fuzz target
    /// puts arbitrary bytes into the server without a socket.
    pub async fn serve_stream<S>(&self, io: S, peer: SocketAddr)
    where
        S: tokio::io::AsyncRead + tokio::io::AsyncWrite + Unpin + Send + 'static,
    {
        listen::serve_connection(
            io,
            peer,
            routes::router(self.state.clone()),
            self.state.clone(),
            self.state.shutdown.clone(),
        )
        .await;
    }

    /// The demo sessions now, as `GET /sessions` lists them.
    pub fn sessions(&self) -> Vec<demo::SessionSummary> {
        self.state.demo.list()
    }

    /// Names of the scenes being served.
    pub fn scenes(&self) -> Vec<String> {
        self.state
            .catalog
            .list()
            .iter()
            .map(|s| s.name.clone())
            .collect()
    }

    /// A handle that starts the shutdown from elsewhere; await
    /// [`RunningServer::shutdown`] to see it finish.
    pub fn shutdown_handle(&self) -> ShutdownHandle {
        ShutdownHandle(self.shutdown_tx.clone())
    }

    /// Whether a shutdown was asked for (by this server or a handle).
    pub fn is_shutting_down(&self) -> bool {
        *self.shutdown_tx.borrow()
    }

    /// Resolves once someone asks for a shutdown through a handle.
    pub async fn shutdown_requested(&self) {
        let mut rx = self.shutdown_tx.subscribe();
        let _ = rx.wait_for(|&stop| stop).await;
    }

    /// Stops accepting, closes every session with a close frame ("server
    /// shutting down"), waits up to [`SHUTDOWN_GRACE`] for them, and returns
    /// the final counters.
    pub async fn shutdown(mut self) -> Result<MetricsSnapshot, ServeError> {
        self.shutdown_tx.send_replace(true);
        if let Some(task) = self.task.take()
            && let Err(e) = task.await
        {
            return Err(ServeError::Task(e.to_string()));
        }
        // Every connection, HTTP or websocket, holds an admission ticket.
        let drained = tokio::time::timeout(SHUTDOWN_GRACE, async {
            loop {
                let closed = self.admission.closed.notified();
                tokio::pin!(closed);
                closed.as_mut().enable();
                if self.admission.open() == 0 {
                    break;
                }
                closed.await;
            }
        })
        .await;
        if drained.is_err() {
            tracing::warn!(
                open = self.admission.open(),
                "connections still open after the grace period"
            );
        }
        let snapshot = self.state.metrics.snapshot();
        tracing::info!(
            pages_served = snapshot.pages_served,
            bytes_served = snapshot.bytes_served,
            connections = snapshot.connections_total,
            "server stopped"
        );
        Ok(snapshot)
    }
}

impl Drop for RunningServer {
    fn drop(&mut self) {
        self.shutdown_tx.send_replace(true);
    }
}
