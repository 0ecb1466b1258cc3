//! [`Viewer`]: the client's resident state for one scene, from a file or a
//! memory server.
//!
//! It owns the [`Hierarchy`] of resident pages and a byte-bounded LRU over
//! them; what was asked for, acknowledged, rejected or given up is the
//! session's ([`Session`]). Each frame the frame loop calls
//! [`Viewer::pump`] (take what arrived), traverses, then
//! [`Viewer::request`] with the traversal's wanted pages. A page that
//! fails verification is reported to the session (which asks again, at
//! most [`farfield_net::MAX_PAGE_FAILURES`] times), never drawn. Given-up
//! pages, with why ([`Viewer::failed_pages`]), are no longer asked for:
//! their parts of the tree are drawn from coarser pages.

use std::collections::{HashSet, VecDeque};
use std::path::Path;
use std::time::Duration;

use anyhow::Context;
use farfield_net::{
    DemoEvent, FailedPage, NetStats, Session, SessionEvent, SessionOptions, Transport, stream_url,
};
use farfield_protocol::file::FileHeader;
use farfield_protocol::hierarchy::Hierarchy;
use farfield_protocol::messages::PageWish;
use lru::LruCache;
use web_time::Instant;

/// Reads the paged file at `path` whole, every page resident and verified
/// (the `--file` mode).
pub fn load_file(path: &Path) -> anyhow::Result<Hierarchy> {
    let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    farfield_protocol::paged_file::read_image(&bytes).with_context(|| format!("{}", path.display()))
}

/// The resident state of one scene.
#[derive(Debug)]
pub struct Viewer {
    session: Option<Session<Box<dyn Transport>>>,
    hierarchy: Option<Hierarchy>,
    recency: LruCache<u32, ()>,
    cache_bytes: usize,
    /// Bytes of the resident pages the last frame used ([`Viewer::touch`]):
    /// the part of the cache new requests must not push out.
    frame_bytes: u64,
    /// Events taken from the session and not yet applied (see [`Viewer::pump_for`]).
    pending: VecDeque<SessionEvent>,
    /// The pages among `pending`: arrived (and acknowledged), not yet
    /// resident. Never asked for again: the server would send each again
    /// (it was once 2.6 pages sent for each kept, on a scene whose pages
    /// take long to insert).
    arrived: HashSet<u32>,
    /// Demo-session news not yet taken ([`Viewer::take_demo_events`]).
    demo_events: VecDeque<DemoEvent>,
    /// A file's viewer has no session; its counters stay zero.
    no_stats: NetStats,
}

/// Most demo events a viewer keeps for an owner that does not take them
/// (the newest; a view supersedes the ones before it anyway).
const MAX_DEMO_EVENTS: usize = 64;

impl Viewer {
    /// Every page of a local file resident, no server involved.
    pub fn open_file(path: &Path) -> anyhow::Result<Self> {
        Ok(Self::resident(load_file(path)?))
    }

    /// A viewer of a hierarchy already in memory (every page it holds).
    pub fn resident(hierarchy: Hierarchy) -> Self {
        let mut viewer = Self::with_session(None, usize::MAX);
        viewer.hierarchy = Some(hierarchy);
        viewer
    }

    /// Starts a session with a memory server over the native websocket;
    /// pages arrive through [`pump`](Self::pump).
    #[cfg(not(target_arch = "wasm32"))]
    pub fn open_remote(
        server: &str,
        scene: &str,
        options: SessionOptions,
        cache_bytes: usize,
    ) -> anyhow::Result<Self> {
        let transport =
            farfield_net::websocket::WebSocketTransport::trusting(options.ca_cert.as_deref())
                .context("starting the network thread")?;
        Ok(Self::over(
            Box::new(transport),
            server,
            scene,
            options,
            cache_bytes,
        ))
    }

    /// Starts a session with `scene` on `server` over `transport` (a
    /// browser's websocket, or an in-memory one in tests).
    pub fn over(
        transport: Box<dyn Transport>,
        server: &str,
        scene: &str,
        options: SessionOptions,
        cache_bytes: usize,
    ) -> Self {
        let session = Session::open(transport, stream_url(server, scene), options);
        Self::with_session(Some(session), cache_bytes)
    }

    fn with_session(session: Option<Session<Box<dyn Transport>>>, cache_bytes: usize) -> Self {
        Self {
            session,
            hierarchy: None,
            recency: LruCache::unbounded(),
            cache_bytes,
            frame_bytes: 0,
            pending: VecDeque::new(),
            arrived: HashSet::new(),
            demo_events: VecDeque::new(),
            no_stats: NetStats::default(),
        }
    }

    pub fn hierarchy(&self) -> Option<&Hierarchy> {
        self.hierarchy.as_ref()
    }

    pub fn header(&self) -> Option<&FileHeader> {
        self.hierarchy.as_ref().map(|h| &h.header)
    }

    /// Has `waker` called whenever the session has something to pump, so
    /// an owner at rest need not poll; `false` for a file, or a transport
    /// that cannot.
    pub fn set_waker(&mut self, waker: impl Fn() + Send + Sync + 'static) -> bool {
        let waker = farfield_net::Waker(std::sync::Arc::new(waker));
        self.session
            .as_mut()
            .is_some_and(|session| session.set_waker(waker))
    }

    /// Whether the pages come from a server (and so can be over-fetched).
    pub fn is_streamed(&self) -> bool {
        self.session.is_some()
    }

    /// The session's counters (all zero for a file).
    pub fn stats(&self) -> &NetStats {
        self.session.as_ref().map_or(&self.no_stats, |s| &s.stats)
    }

    /// `what` went wrong, followed by the last connection or server error
    /// when there was one: a client that gives up waiting should say
    /// "connection refused", not only that it timed out.
    pub fn with_last_error(&self, what: String) -> String {
        match &self.stats().last_error {
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
        self.session.as_ref().map_or(0, Session::outstanding)
    }

    /// Whether a session is up and has the scene (always, for a file).
    pub fn is_connected(&self) -> bool {
        self.session.as_ref().is_none_or(Session::is_connected)
    }

    /// Takes every event that has arrived, waiting up to `wait` for the
    /// first one when none is queued. Returns the pages made resident.
    /// A session that ended (refused, never reached, a fatal server error)
    /// is returned as an error.
    pub fn pump(&mut self, wait: Duration) -> anyhow::Result<usize> {
        self.receive(wait)?;
        self.apply_pending(None)
    }

    /// Like [`Self::pump`] without waiting, but verifies and inserts
    /// arrived pages only for about `budget` (at least one page), leaving
    /// the rest for the next call: a burst of pages never stalls an
    /// interactive frame (the viewer's; in a browser nothing else can run
    /// meanwhile).
    pub fn pump_for(&mut self, budget: Duration) -> anyhow::Result<usize> {
        self.receive(Duration::ZERO)?;
        self.apply_pending(Some(Instant::now() + budget))
    }

    /// Arrived pages not yet verified and inserted ([`Self::pump_for`]).
    pub fn pending_pages(&self) -> usize {
        self.pending.len()
    }

    /// Moves what the session has into the pending queue.
    fn receive(&mut self, wait: Duration) -> anyhow::Result<()> {
        if let Some(session) = self.session.as_mut() {
            let wait = if self.pending.is_empty() {
                wait
            } else {
                Duration::ZERO
            };
            for event in session.pump(wait)? {
                if let SessionEvent::Page { index, .. } = &event {
                    self.arrived.insert(*index);
                }
                self.pending.push_back(event);
            }
        }
        Ok(())
    }

    /// Applies pending events in order until `deadline` (all without one).
    fn apply_pending(&mut self, deadline: Option<Instant>) -> anyhow::Result<usize> {
        let Self {
            session: Some(session),
            hierarchy,
            recency,
            cache_bytes,
            pending,
            arrived,
            demo_events,
            ..
        } = self
        else {
            return Ok(0);
        };
        let mut inserted = 0;
        while let Some(event) = pending.pop_front() {
            match event {
                SessionEvent::Header(header) => {
                    *hierarchy =
                        Some(Hierarchy::new(header).context("scene header from the server")?);
                }
                SessionEvent::Page { index, bytes } => {
                    arrived.remove(&index);
                    let Some(h) = hierarchy.as_mut() else {
                        continue;
                    };
                    if h.is_resident(index as usize) {
                        continue;
                    }
                    match h.insert_page(index, &bytes) {
                        Ok(()) => {
                            // Directory pages stay: small, and what
                            // places the rest.
                            if !h.directory().is_directory(index) {
                                recency.put(index, ());
                            }
                            inserted += 1;
                            evict(h, recency, *cache_bytes);
                        }
                        Err(e) => session.page_rejected(index, &e),
                    }
                }
                SessionEvent::Demo(event) => {
                    if demo_events.len() >= MAX_DEMO_EVENTS {
                        demo_events.pop_front();
                    }
                    demo_events.push_back(event);
                }
            }
            if deadline.is_some_and(|d| Instant::now() >= d) {
                break;
            }
        }
        Ok(inserted)
    }

    /// Changes the byte budget of resident pages, evicting at once when
    /// it shrank.
    pub fn set_cache_bytes(&mut self, bytes: usize) {
        self.cache_bytes = bytes;
        if let Some(h) = self.hierarchy.as_mut() {
            evict(h, &mut self.recency, bytes);
        }
    }

    /// Sends new wishes and cancels stale ones. `wanted` is the traversal's
    /// list (most urgent first).
    ///
    /// Only as many as the cache can keep beside the pages the frame uses
    /// (most urgent first): asking for more would evict the frame's own
    /// pages to make room, ask for those again, and thrash the network
    /// without ever refining. Less urgent pages wait until the view needs
    /// fewer. When none fits, none is asked for: a page that pushed out
    /// one the frame draws would be asked for again by the next frame
    /// (measured: a 200 KB page and 136 KB of leaves traded places every
    /// frame, 40 MB in 8 s). A view whose pages outgrow the cache stays
    /// as it is and does not refine, as Potree's memory limit does.
    ///
    /// Pages that arrived and wait to be inserted are not asked for: they
    /// are here already.
    ///
    /// A wish for a page whose directory page has not arrived becomes a
    /// wish for that directory page, with its priority: every kind's
    /// traversal reaches the directory as it reaches the pages.
    pub fn request(&mut self, wanted: &[PageWish]) {
        let placed;
        let wanted = match self.hierarchy.as_ref() {
            Some(h) if wanted.iter().any(|w| !placeable(h, w.page)) => {
                placed = place_wishes(h, wanted);
                &placed[..]
            }
            _ => wanted,
        };
        let kept = self.affordable(wanted);
        let Some(s) = self.session.as_mut() else {
            return;
        };
        if self.arrived.is_empty() {
            s.request(&wanted[..kept]);
        } else {
            let missing: Vec<PageWish> = wanted[..kept]
                .iter()
                .filter(|w| !self.arrived.contains(&w.page))
                .copied()
                .collect();
            s.request(&missing);
        }
    }

    /// How many of `wanted` (most urgent first) fit the cache beside the
    /// last frame's pages.
    fn affordable(&self, wanted: &[PageWish]) -> usize {
        let Some(h) = self.hierarchy.as_ref() else {
            return wanted.len();
        };
        let mut room = (self.cache_bytes as u64).saturating_sub(self.frame_bytes);
        let mut kept = 0;
        for w in wanted {
            if h.is_resident(w.page as usize) {
                kept += 1;
                continue;
            }
            let bytes = h
                .directory()
                .extent(w.page)
                .map_or(0, |p| u64::from(p.length));
            if bytes > room {
                break;
            }
            room = room.saturating_sub(bytes);
            kept += 1;
        }
        kept
    }

    /// Marks pages as used this frame (most recent in the LRU), and
    /// remembers their bytes (see [`Viewer::request`]).
    pub fn touch(&mut self, pages: &[u32]) {
        for &p in pages {
            self.recency.get(&p);
        }
        self.frame_bytes = self.hierarchy.as_ref().map_or(0, |h| {
            pages
                .iter()
                .filter(|&&p| h.is_resident(p as usize))
                .filter_map(|&p| h.directory().extent(p))
                .map(|p| u64::from(p.length))
                .sum()
        });
    }

    /// The demo-session news that arrived since the last call, oldest first.
    pub fn take_demo_events(&mut self) -> Vec<DemoEvent> {
        self.demo_events.drain(..).collect()
    }

    /// The session with the server (none for a file): for demo sessions,
    /// [`Session::join_demo`] and the rest.
    pub fn session_mut(&mut self) -> Option<&mut Session<Box<dyn Transport>>> {
        self.session.as_mut()
    }

    /// Request-to-arrival times of the pages asked for since the last
    /// call (see [`Session::take_latencies`]); none for a file.
    pub fn take_latencies(&mut self) -> Vec<Duration> {
        self.session
            .as_mut()
            .map_or_else(Vec::new, Session::take_latencies)
    }

    /// Pages given up on (repeated checksum failures, or the server cannot
    /// send them), by page index, with the last reason of each.
    pub fn failed_pages(&self) -> Vec<FailedPage> {
        self.session
            .as_ref()
            .map_or_else(Vec::new, Session::failed_pages)
    }

    /// Whether `page` was given up on: it is not asked for again.
    pub fn gave_up(&self, page: u32) -> bool {
        self.session.as_ref().is_some_and(|s| s.gave_up(page))
    }
}

/// Drops least recently used pages while over the byte budget; page 0
/// (the coarse model) always stays.
fn evict(h: &mut Hierarchy, recency: &mut LruCache<u32, ()>, cache_bytes: usize) {
    while h.resident_bytes() > cache_bytes {
        let Some((page, ())) = recency.pop_lru() else {
            break;
        };
        if page == 0 {
            recency.put(0, ());
            if recency.len() == 1 {
                break;
            }
            continue;
        }
        h.evict_page(page);
    }
}

/// Whether the client can check page id `page` when it arrives: a
/// directory page whose parent arrived, or a page whose entry did.
fn placeable(h: &Hierarchy, page: u32) -> bool {
    h.directory().extent(page).is_some()
}

/// `wanted` with each page the client cannot place yet replaced by the
/// first directory page on its way there, each page once (at its most
/// urgent wish's priority: `wanted` is most urgent first).
fn place_wishes(h: &Hierarchy, wanted: &[PageWish]) -> Vec<PageWish> {
    let mut seen = std::collections::HashSet::new();
    wanted
        .iter()
        .filter_map(|w| {
            let page = if placeable(h, w.page) {
                w.page
            } else {
                h.directory()
                    .path_to(w.page)
                    .into_iter()
                    .find(|&d| !h.directory().has(d))?
            };
            seen.insert(page).then_some(PageWish { page, ..*w })
        })
        .collect()
}

#[cfg(test)]
#[path = "viewer_tests.rs"]
mod tests;
