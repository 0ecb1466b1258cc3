//! [`Viewer`]: the client's resident state for one scene, from a file or a
//! memory server.
//!
//! It owns the [`Hierarchy`] of resident pages, a byte-bounded LRU over them,
//! and the bookkeeping of what was asked for. Each frame the render loop
//! calls [`Viewer::pump`] (take what arrived), traverses, then
//! [`Viewer::request`] with the traversal's wanted pages: new wishes are
//! sent, wishes that fell out of view are cancelled. A page that fails its
//! checksum is reported, counted and asked for again (at most
//! [`MAX_PAGE_FAILURES`] times), never drawn; a page the server says it
//! cannot send is given up at once. Given-up pages, with why
//! ([`Viewer::failed_pages`]), are no longer asked for: their parts of the
//! tree are drawn from coarser pages.

use std::collections::HashMap;
use std::path::Path;
use std::time::Duration;

use anyhow::{Context, bail};
use farfield_protocol::file::FileHeader;
use farfield_protocol::hierarchy::Hierarchy;
use farfield_protocol::messages::PageWish;
use farfield_protocol::traverse::WantedPage;
use lru::LruCache;

use crate::net::{Connection, NetEvent, Outgoing, SessionOptions};

/// Checksum failures after which a page is given up on.
pub const MAX_PAGE_FAILURES: u32 = 3;

/// A page given up on, and the last reason it could not be had.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct FailedPage {
    pub page: u32,
    pub reason: String,
}

/// Counters a render reports.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct NetStats {
    pub bytes_received: u64,
    pub pages_received: u64,
    pub pages_requested: u64,
    pub pages_cancelled: u64,
    pub pages_rejected: u64,
    /// Pages the server said it cannot send (corrupt on its disk).
    pub pages_unavailable: u64,
    pub disconnects: u64,
    /// Reported through the render report's own `last_error`.
    #[serde(skip)]
    pub last_error: Option<String>,
}

/// The resident state of one scene.
#[derive(Debug)]
pub struct Viewer {
    // Field order matters on drop: the connection's task must go before
    // the runtime that runs it.
    connection: Option<Connection>,
    runtime: Option<tokio::runtime::Runtime>,
    hierarchy: Option<Hierarchy>,
    recency: LruCache<u32, ()>,
    cache_bytes: usize,
    requested: HashMap<u32, f32>,
    /// Per page that failed: how often, and the last reason.
    failures: HashMap<u32, (u32, String)>,
    pub stats: NetStats,
    connected: bool,
}

impl Viewer {
    /// Every page of a local file resident, no server involved.
    pub fn open_file(path: &Path) -> anyhow::Result<Self> {
        let hierarchy = crate::local::load_file(path)?;
        let mut viewer = Self::empty(usize::MAX, None, None);
        viewer.hierarchy = Some(hierarchy);
        viewer.connected = true;
        Ok(viewer)
    }

    /// Starts a session with a memory server; pages arrive through [`pump`](Self::pump).
    pub fn open_remote(
        server: &str,
        scene: &str,
        options: SessionOptions,
        cache_bytes: usize,
    ) -> anyhow::Result<Self> {
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .enable_all()
            .build()
            .context("starting the network runtime")?;
        let connection = Connection::open(runtime.handle(), server, scene, options);
        Ok(Self::empty(cache_bytes, Some(connection), Some(runtime)))
    }

    fn empty(
        cache_bytes: usize,
        connection: Option<Connection>,
        runtime: Option<tokio::runtime::Runtime>,
    ) -> Self {
        Self {
            connection,
            runtime,
            hierarchy: None,
            recency: LruCache::unbounded(),
            cache_bytes,
            requested: HashMap::new(),
            failures: HashMap::new(),
            stats: NetStats::default(),
            connected: false,
        }
    }

    pub fn hierarchy(&self) -> Option<&Hierarchy> {
        self.hierarchy.as_ref()
    }

    pub fn header(&self) -> Option<&FileHeader> {
        self.hierarchy.as_ref().map(|h| &h.header)
    }

    /// `what` went wrong, followed by the last connection or server error
    /// when there was one: a client that gives up waiting should say
    /// "connection refused", not only that it timed out.
    pub fn with_last_error(&self, what: String) -> String {
        match &self.stats.last_error {
            Some(e) => format!("{what} (last error: {e})"),
            None => what,
        }
    }

    /// Why a caller gave up waiting `waited` for the scene's header, in
    /// the words every command uses, with the last error.
    pub fn no_header_error(&self, waited: Duration) -> String {
        self.with_last_error(format!(
            "no scene header after {:.1} s",
            waited.as_secs_f64()
        ))
    }

    /// Pages asked for and not yet arrived.
    pub fn outstanding(&self) -> usize {
        self.requested.len()
    }

    /// Whether a session is up (always, for a file).
    pub fn is_connected(&self) -> bool {
        self.connected
    }

    /// Takes every event that has arrived, waiting up to `wait` for the
    /// first one when none is queued. Returns the pages made resident.
    /// A fatal server error is returned as an error.
    pub fn pump(&mut self, wait: Duration) -> anyhow::Result<usize> {
        let (Some(connection), Some(runtime)) = (self.connection.as_mut(), self.runtime.as_ref())
        else {
            return Ok(0);
        };
        let mut events = Vec::new();
        while let Ok(e) = connection.events.try_recv() {
            events.push(e);
        }
        if events.is_empty() && !wait.is_zero() {
            let first = runtime
                .block_on(async { tokio::time::timeout(wait, connection.events.recv()).await });
            match first {
                Ok(Some(e)) => events.push(e),
                Ok(None) => bail!("the network task ended"),
                Err(_) => return Ok(0),
            }
            while let Ok(e) = connection.events.try_recv() {
                events.push(e);
            }
        }
        let mut inserted = 0;
        let mut acks = Vec::new();
        for event in events {
            match event {
                NetEvent::Connected { header } => self.on_connected(&header)?,
                NetEvent::Page { bytes } => {
                    if let Some(index) = self.on_page(&bytes) {
                        acks.push(index.0);
                        inserted += usize::from(index.1);
                    }
                }
                NetEvent::ServerError { message, fatal } => {
                    tracing::warn!("server: {message}");
                    self.stats.last_error = Some(message.clone());
                    if fatal {
                        bail!("server: {message}");
                    }
                }
                NetEvent::GaveUp { reason } => bail!("{reason}"),
                NetEvent::PageUnavailable { page, reason } => {
                    tracing::warn!("giving up page {page}: {reason}");
                    self.stats.pages_unavailable += 1;
                    self.stats.last_error = Some(reason.clone());
                    self.requested.remove(&page);
                    // Given up at once: the server's copy will not heal.
                    self.failures.insert(page, (MAX_PAGE_FAILURES, reason));
                }
                NetEvent::Disconnected { reason } => {
                    if self.connected {
                        tracing::warn!("connection lost: {reason}; reconnecting");
                        self.stats.disconnects += 1;
                    }
                    self.stats.last_error = Some(reason);
                    self.connected = false;
                    // The server forgot our wishes with the connection.
                    self.requested.clear();
                }
            }
        }
        if !acks.is_empty()
            && let Some(c) = &self.connection
        {
            c.send(Outgoing::Received(acks));
        }
        Ok(inserted)
    }

    fn on_connected(&mut self, header_bytes: &[u8]) -> anyhow::Result<()> {
        let header = FileHeader::decode(header_bytes).context("scene header from the server")?;
        match &self.hierarchy {
            Some(h) if h.header != header => bail!("the server's scene changed under this session"),
            Some(_) => {}
            None => {
                self.hierarchy =
                    Some(Hierarchy::new(header).context("scene header from the server")?)
            }
        }
        self.connected = true;
        self.requested.clear();
        Ok(())
    }

    /// Verifies and inserts a page; returns (index, inserted) when the bytes
    /// named a page at all.
    fn on_page(&mut self, bytes: &[u8]) -> Option<(u32, bool)> {
        self.stats.bytes_received += bytes.len() as u64;
        self.stats.pages_received += 1;
        let index = u32::from_le_bytes(bytes.get(4..8)?.try_into().ok()?);
        let h = self.hierarchy.as_mut()?;
        self.requested.remove(&index);
        if h.is_resident(index as usize) {
            return Some((index, false));
        }
        match h.insert_page(index, bytes) {
            Ok(()) => {
                self.recency.put(index, ());
                self.evict();
                Some((index, true))
            }
            Err(e) => {
                self.stats.pages_rejected += 1;
                let reason = format!("page {index}: {e}");
                let (failures, last) = self.failures.entry(index).or_default();
                *failures += 1;
                *last = reason.clone();
                tracing::warn!(
                    "page {index} rejected ({e}); attempt {failures} of {MAX_PAGE_FAILURES}"
                );
                self.stats.last_error = Some(reason);
                Some((index, false))
            }
        }
    }

    /// Sends new wishes and cancels stale ones. `wanted` is the traversal's
    /// list (most urgent first).
    pub fn request(&mut self, wanted: &[WantedPage]) {
        let Some(connection) = &self.connection else {
            return;
        };
        if !self.connected {
            return;
        }
        let mut new = Vec::new();
        let mut still: HashMap<u32, f32> = HashMap::with_capacity(wanted.len());
        for w in wanted {
            if self.gave_up(w.page) {
                continue;
            }
            let priority = w.priority.min(f64::from(f32::MAX)) as f32;
            still.insert(w.page, priority);
            match self.requested.get(&w.page) {
                Some(&p) if (p - priority).abs() <= 0.25 * p.abs() => {}
                _ => new.push(PageWish {
                    page: w.page,
                    priority,
                }),
            }
        }
        let stale: Vec<u32> = self
            .requested
            .keys()
            .copied()
            .filter(|p| !still.contains_key(p))
            .collect();
        if !stale.is_empty() {
            self.stats.pages_cancelled += stale.len() as u64;
            connection.send(Outgoing::Cancel(stale.clone()));
        }
        for p in stale {
            self.requested.remove(&p);
        }
        if !new.is_empty() {
            self.stats.pages_requested += new
                .iter()
                .filter(|w| !self.requested.contains_key(&w.page))
                .count() as u64;
            for w in &new {
                self.requested.insert(w.page, w.priority);
            }
            connection.send(Outgoing::Request(new));
        }
    }

    /// Marks pages as used this frame (most recent in the LRU).
    pub fn touch(&mut self, pages: &[u32]) {
        for &p in pages {
            self.recency.get(&p);
        }
    }

    /// Drops least recently used pages while over the byte budget; page 0
    /// (the coarse model) always stays.
    fn evict(&mut self) {
        let Some(h) = self.hierarchy.as_mut() else {
            return;
        };
        while h.resident_bytes() > self.cache_bytes {
            let Some((page, ())) = self.recency.pop_lru() else {
                break;
            };
            if page == 0 {
                self.recency.put(0, ());
                if self.recency.len() == 1 {
                    break;
                }
                continue;
            }
            h.evict_page(page);
        }
    }

    /// Pages given up on (repeated checksum failures, or the server cannot
    /// send them), by page index, with the last reason of each.
    pub fn failed_pages(&self) -> Vec<FailedPage> {
        let mut failed: Vec<FailedPage> = self
            .failures
            .iter()
            .filter(|&(&page, _)| self.gave_up(page))
            .map(|(&page, (_, reason))| FailedPage {
                page,
                reason: reason.clone(),
            })
            .collect();
        failed.sort_unstable_by_key(|f| f.page);
        failed
    }

    /// Whether `page` was given up on: it is not asked for again.
    pub fn gave_up(&self, page: u32) -> bool {
        self.failures
            .get(&page)
            .is_some_and(|&(count, _)| count >= MAX_PAGE_FAILURES)
    }
}

#[cfg(test)]
mod tests {
    use farfield_server::build::{BuildOptions, build_spheres};
    use farfield_server::import::{Params, load_input};

    use super::*;

    /// A viewer holding only page 0 of a small generated scene, and the
    /// stored bytes of every page.
    fn viewer() -> (Viewer, Vec<Vec<u8>>) {
        let mut params = Params::default();
        params.set("size", 64);
        params.set("trees", 1);
        let (file, _) = build_spheres(
            load_input("gen:island", &params).unwrap(),
            &BuildOptions::default(),
        )
        .unwrap();
        let mut v = Viewer::empty(usize::MAX, None, None);
        v.on_connected(&file.header.encode()).unwrap();
        assert_eq!(v.on_page(&file.pages[0]), Some((0, true)));
        (v, file.pages)
    }

    #[test]
    fn a_page_failing_its_checksum_is_counted_never_resident_and_given_up_after_three() {
        let (mut v, pages) = viewer();
        let mut bad = pages[1].clone();
        bad[40] ^= 0x20;
        for attempt in 1..=MAX_PAGE_FAILURES {
            assert_eq!(
                v.on_page(&bad),
                Some((1, false)),
                "still acknowledged so it can be asked again"
            );
            assert!(!v.hierarchy().unwrap().is_resident(1));
            assert_eq!(v.stats.pages_rejected, u64::from(attempt));
        }
        let failed = v.failed_pages();
        assert_eq!(failed.len(), 1);
        assert_eq!(failed[0].page, 1);
        assert!(failed[0].reason.contains("page 1"), "{failed:?}");
        // The good bytes are still taken.
        assert_eq!(v.on_page(&pages[1]), Some((1, true)));
    }

    #[test]
    fn a_different_scene_on_reconnect_is_an_error() {
        let (mut v, _) = viewer();
        let mut params = Params::default();
        params.set("size", 32);
        let (other, _) = build_spheres(
            load_input("gen:island", &params).unwrap(),
            &BuildOptions::default(),
        )
        .unwrap();
        assert!(v.on_connected(&other.header.encode()).is_err());
    }
}
