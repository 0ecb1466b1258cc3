//! The page cache: hot pages of every scene, shared by all connections,
//! bounded in bytes.
//!
//! Two parts share the bound. Pages a client asked for are kept by
//! recency (`served`). Pages read ahead of any request (a page's
//! children, a presenter's extrapolated view) wait apart (`ahead`) until a
//! client asks for one, which moves it to `served`. Read-ahead fills free
//! room, and makes room only by dropping its own older guesses, never a
//! page a client asked for: under a small cache it once did, and the disk
//! read 3.2 pages for every page sent. A client's page makes room by
//! dropping whichever is least recent, a served page or a guess.
//!
//! Read-ahead is also held to what its guesses are worth: every guess
//! dropped unused (or read and not kept) spends a credit, every page
//! served earns [`GUESS_SLACK`] of one, up to [`GUESS_CREDIT`]; without
//! credit, read-ahead waits ([`PageCache::may_guess`]). Guesses that
//! clients go on to ask for cost nothing, so a cache that holds the scene
//! reads ahead freely, while one too small for the guesses to live until
//! used reads at most about `1 + GUESS_SLACK` pages per page served.
//!
//! Values are ready-to-send page frames (the kind byte, then the page's
//! stored bytes) read straight into the frame, so sending a cached page to
//! any number of clients is a reference-count increment, never a copy or a
//! re-encode. A page's checksum is verified once, when it enters the cache;
//! a page that fails is reported and never cached or sent, and its verdict
//! is kept: asked for again, it is not read again, and the warning in the
//! log is written once per page, not once per request.

use std::collections::HashMap;
use std::ops::Range;
use std::sync::atomic::Ordering;
use std::sync::{Arc, Condvar, Mutex};

use axum::body::Bytes;
use farfield_protocol::FormatError;
use farfield_protocol::codec;
use farfield_store::PageError;
use lru::LruCache;

use super::catalog::ServedScene;
use super::metrics::Metrics;

/// (scene id, page index).
pub type PageKey = (u32, u32);

/// Verdicts on corrupt pages kept at most; past it they are forgotten all
/// at once (and found again by the next read), which bounds the memory a
/// folder of broken files can cost.
pub const MAX_VERDICTS: usize = 1 << 16;

/// The credit, in pages, that read-ahead may waste on guesses no client
/// asks for before it must wait for pages served to earn more; also what
/// it starts with.
pub const GUESS_CREDIT: f64 = 256.0;

/// The credit each page served earns read-ahead: the wasted reads it is
/// allowed per page served.
pub const GUESS_SLACK: f64 = 0.1;

/// Why a page is read into the cache.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Purpose {
    /// A client asked for it.
    Wanted,
    /// Read-ahead guesses a client will.
    Ahead,
}

/// A byte-bounded LRU of page frames.
#[derive(Debug)]
pub struct PageCache {
    inner: Mutex<Inner>,
    capacity: u64,
    /// Pages that failed verification, and why.
    verdicts: Mutex<HashMap<PageKey, FormatError>>,
    /// Reads under way, which later misses of the same page wait for.
    flights: Mutex<HashMap<PageKey, Arc<Flight>>>,
}

/// One page being read, and its result once read.
#[derive(Debug, Default)]
struct Flight {
    result: Mutex<Option<Result<Bytes, PageError>>>,
    landed: Condvar,
}

impl Flight {
    fn land(&self, result: Result<Bytes, PageError>) {
        *self.result.lock().unwrap_or_else(|e| e.into_inner()) = Some(result);
        self.landed.notify_all();
    }

    /// Blocks until the read lands (called on the blocking pool and the
    /// read-ahead threads only, as reads are).
    fn wait(&self) -> Result<Bytes, PageError> {
        let mut result = self.result.lock().unwrap_or_else(|e| e.into_inner());
        loop {
            if let Some(result) = result.as_ref() {
                return result.clone();
            }
            result = self.landed.wait(result).unwrap_or_else(|e| e.into_inner());
        }
    }
}

#[derive(Debug)]
struct Inner {
    /// Pages clients asked for, by recency.
    served: LruCache<PageKey, Entry>,
    /// Pages read ahead that no client has asked for yet, by recency.
    ahead: LruCache<PageKey, Entry>,
    /// Bytes of both, and of `ahead` alone.
    bytes: u64,
    ahead_bytes: u64,
    /// A clock of uses, so the least recent of the two parts is known.
    clock: u64,
    /// Read-ahead's credit, in pages (see the module's overview).
    credit: f64,
}

#[derive(Debug)]
struct Entry {
    frame: Bytes,
    /// `Inner::clock` when last used or inserted.
    used: u64,
}

impl Inner {
    fn tick(&mut self) -> u64 {
        self.clock += 1;
        self.clock
    }

    /// A guess was read for nothing.
    fn wasted(&mut self) {
        self.credit -= 1.0;
    }

    /// Drops the least recent guess; whether there was one.
    fn drop_oldest_guess(&mut self, metrics: &Metrics) -> bool {
        match self.ahead.pop_lru() {
            Some((_, old)) => {
                let len = old.frame.len() as u64;
                self.bytes -= len;
                self.ahead_bytes -= len;
                self.wasted();
                Metrics::add(&metrics.prefetch_unused, 1);
                true
            }
            None => false,
        }
    }

    /// Drops the least recent page of either part; whether there was one.
    fn drop_least_recent(&mut self, metrics: &Metrics) -> bool {
        let served = self.served.peek_lru().map(|(_, e)| e.used);
        let ahead = self.ahead.peek_lru().map(|(_, e)| e.used);
        match (served, ahead) {
            (Some(s), Some(a)) if a < s => self.drop_oldest_guess(metrics),
            (Some(_), _) => {
                if let Some((_, old)) = self.served.pop_lru() {
                    self.bytes -= old.frame.len() as u64;
                }
                true
            }
            (None, Some(_)) => self.drop_oldest_guess(metrics),
            (None, None) => false,
        }
    }

    /// Moves a guess a client now asks for to the served part.
    fn promote(&mut self, key: PageKey) -> Option<Bytes> {
        let entry = self.ahead.pop(&key)?;
        self.ahead_bytes -= entry.frame.len() as u64;
        let used = self.tick();
        let frame = entry.frame.clone();
        self.served.put(
            key,
            Entry {
                frame: frame.clone(),
                used,
            },
        );
        Some(frame)
    }

    fn show(&self, metrics: &Metrics) {
        metrics.cache_bytes.store(self.bytes, Ordering::Relaxed);
        metrics.cache_pages.store(
            (self.served.len() + self.ahead.len()) as u64,
            Ordering::Relaxed,
        );
        metrics
            .cache_ahead_bytes
            .store(self.ahead_bytes, Ordering::Relaxed);
    }
}

impl PageCache {
    pub fn new(capacity: u64, metrics: &Metrics) -> Self {
        metrics
            .cache_capacity_bytes
            .store(capacity, Ordering::Relaxed);
        Self {
            inner: Mutex::new(Inner {
                served: LruCache::unbounded(),
                ahead: LruCache::unbounded(),
                bytes: 0,
                ahead_bytes: 0,
                clock: 0,
                credit: GUESS_CREDIT,
            }),
            capacity,
            verdicts: Mutex::new(HashMap::new()),
            flights: Mutex::new(HashMap::new()),
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Inner> {
        // A panic while holding the lock cannot leave the LRU inconsistent
        // in a way that matters (worst case a byte count off), so recover.
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The cached frame for a client, made most recently used (a guess of
    /// read-ahead's becomes a served page).
    pub fn get(&self, key: PageKey) -> Option<Bytes> {
        let mut inner = self.lock();
        let used = inner.tick();
        if let Some(entry) = inner.served.get_mut(&key) {
            entry.used = used;
            return Some(entry.frame.clone());
        }
        inner.promote(key)
    }

    /// The cached frame for read-ahead: neither its recency nor its part
    /// changes (a guess is not a use).
    pub fn peek(&self, key: PageKey) -> Option<Bytes> {
        let inner = self.lock();
        inner
            .served
            .peek(&key)
            .or_else(|| inner.ahead.peek(&key))
            .map(|e| e.frame.clone())
    }

    /// Bytes held by pages read ahead that no client has asked for yet
    /// (shown in `/metrics` as of the last insert).
    pub fn ahead_bytes(&self) -> u64 {
        self.lock().ahead_bytes
    }

    /// Whether read-ahead may read a guess now: it has credit left, and
    /// there is room beside the pages clients asked for (a guess read
    /// without room would not be kept).
    pub fn may_guess(&self) -> bool {
        let inner = self.lock();
        inner.credit >= 1.0 && inner.bytes - inner.ahead_bytes < self.capacity
    }

    /// A page was served to a client: read-ahead earns its slack.
    fn served(&self) {
        let mut inner = self.lock();
        inner.credit = (inner.credit + GUESS_SLACK).min(GUESS_CREDIT);
    }

    /// Whether `key` is cached, without touching its recency.
    pub fn contains(&self, key: PageKey) -> bool {
        let inner = self.lock();
        inner.served.contains(&key) || inner.ahead.contains(&key)
    }

    /// Adds a frame for `purpose`. A client's page makes room by dropping
    /// the least recent pages of either part; read-ahead's fills free
    /// room, or drops its own older guesses, and is not kept when that is
    /// not enough. A frame larger than the whole cache is not kept.
    pub fn insert(&self, key: PageKey, frame: Bytes, purpose: Purpose, metrics: &Metrics) {
        let len = frame.len() as u64;
        if len > self.capacity {
            return;
        }
        let mut inner = self.lock();
        let used = inner.tick();
        match purpose {
            Purpose::Wanted => {
                if let Some(old) = inner.ahead.pop(&key) {
                    inner.bytes -= old.frame.len() as u64;
                    inner.ahead_bytes -= old.frame.len() as u64;
                }
                if let Some(old) = inner.served.put(key, Entry { frame, used }) {
                    inner.bytes -= old.frame.len() as u64;
                }
                inner.bytes += len;
                while inner.bytes > self.capacity && inner.drop_least_recent(metrics) {}
            }
            Purpose::Ahead => {
                if inner.served.contains(&key) || inner.ahead.contains(&key) {
                    return;
                }
                let served_bytes = inner.bytes - inner.ahead_bytes;
                if served_bytes + len > self.capacity {
                    // No guess dropped could make room: none is.
                    inner.wasted();
                    Metrics::add(&metrics.prefetch_skipped, 1);
                    return;
                }
                while inner.bytes + len > self.capacity {
                    inner.drop_oldest_guess(metrics);
                }
                inner.ahead.put(key, Entry { frame, used });
                inner.bytes += len;
                inner.ahead_bytes += len;
            }
        }
        inner.show(metrics);
    }

    /// Reads, verifies and caches a page that was not found in the cache.
    /// A scene whose file changed is retired here, by whichever read finds
    /// it first.
    pub fn read_through(
        &self,
        scene: &ServedScene,
        page: u32,
        purpose: Purpose,
        metrics: &Metrics,
    ) -> Result<Bytes, PageError> {
        let key = (scene.id, page);
        let known = self
            .verdicts
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .get(&key)
            .cloned();
        if let Some(error) = known {
            return Err(PageError::Format(error));
        }
        // One read per page at a time: clients (and read-ahead) missing the
        // same page together wait for the first one's read, so a page costs
        // the disk or the store one read however many want it at once.
        let (flight, first) = {
            let mut flights = self.flights.lock().unwrap_or_else(|e| e.into_inner());
            match flights.get(&key) {
                Some(flight) => (flight.clone(), false),
                None => {
                    let flight = Arc::new(Flight::default());
                    flights.insert(key, flight.clone());
                    (flight, true)
                }
            }
        };
        if !first {
            let result = flight.wait();
            if purpose == Purpose::Wanted && result.is_ok() {
                // Read ahead by the flight this joined: now a client's.
                let _ = self.get(key);
            }
            return result;
        }
        // Read by a flight that just ended, between the miss and here.
        let cached = match purpose {
            Purpose::Wanted => self.get(key),
            Purpose::Ahead => self.peek(key),
        };
        let result = match cached {
            Some(frame) => Ok(frame),
            None => read_verified(scene, page, metrics)
                .inspect_err(|e| self.failed(scene, page, e, metrics)),
        };
        if let Ok(frame) = &result {
            self.insert(key, frame.clone(), purpose, metrics);
        }
        self.flights
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .remove(&key);
        flight.land(result.clone());
        let frame = result?;
        Ok(frame)
    }

    /// Reads neighbouring pages `pages` of `scene` at once (one request to
    /// a store that can) into the cache, skipping none: read-ahead calls it
    /// for runs of pages it found missing. Returns how many were loaded.
    pub fn read_run_through(
        &self,
        scene: &ServedScene,
        pages: Range<u32>,
        metrics: &Metrics,
    ) -> u64 {
        let mut loaded = 0;
        for (page, read) in pages.clone().zip(scene.source.read_pages(pages)) {
            Metrics::add(&metrics.disk_reads, 1);
            match read {
                Ok(bytes) => {
                    Metrics::add(&metrics.disk_read_bytes, bytes.len() as u64);
                    self.insert(
                        (scene.id, page),
                        Bytes::from(codec::encode_page_frame(&bytes)),
                        Purpose::Ahead,
                        metrics,
                    );
                    loaded += 1;
                }
                Err(e) => self.failed(scene, page, &e, metrics),
            }
        }
        loaded
    }

    /// What a failed read of `page` means: a corrupt page's verdict is
    /// kept (and warned about once), a changed scene retired, and a store
    /// that did not answer is no verdict at all.
    fn failed(&self, scene: &ServedScene, page: u32, e: &PageError, metrics: &Metrics) {
        match e {
            PageError::Format(error) => {
                Metrics::add(&metrics.corrupt_pages, 1);
                tracing::warn!(scene = %scene.name, page, "corrupt page, never sent: {error}");
                let mut verdicts = self.verdicts.lock().unwrap_or_else(|e| e.into_inner());
                if verdicts.len() >= MAX_VERDICTS {
                    verdicts.clear();
                }
                verdicts.insert((scene.id, page), error.clone());
            }
            PageError::Changed(why) => {
                scene.retire(&format!("its file changed on disk: {why}"));
            }
            // The source logged the failure and counted it; the store may
            // answer later.
            PageError::Unavailable(_) => {}
        }
    }

    /// A cached frame, counted as a hit; `None` (not yet counted) on a miss.
    pub fn hit(&self, scene: &ServedScene, page: u32, metrics: &Metrics) -> Option<Bytes> {
        let frame = self.get((scene.id, page))?;
        Metrics::add(&metrics.cache_hits, 1);
        self.served();
        Some(frame)
    }

    /// Reads a page that [`PageCache::hit`] missed, on a blocking thread so
    /// a slow disk never stalls the runtime, and counts the miss.
    pub async fn miss(
        self: &Arc<Self>,
        scene: &Arc<ServedScene>,
        page: u32,
        metrics: &Arc<Metrics>,
    ) -> Result<Bytes, PageError> {
        Metrics::add(&metrics.cache_misses, 1);
        self.served();
        let (cache, scene2, metrics2) = (self.clone(), scene.clone(), metrics.clone());
        match tokio::task::spawn_blocking(move || {
            cache.read_through(&scene2, page, Purpose::Wanted, &metrics2)
        })
        .await
        {
            Ok(result) => result,
            // The blocking pool is gone: the runtime is shutting down, and
            // a read here could block it (a network store's would).
            Err(_) => Err(PageError::Unavailable("the server is shutting down".into())),
        }
    }
}

/// The page's stored bytes as a frame, after checking its checksum, header
/// and agreement with the directory.
fn read_verified(scene: &ServedScene, page: u32, metrics: &Metrics) -> Result<Bytes, PageError> {
    let len = scene.page_len(page).unwrap_or(0) as usize;
    let mut frame = codec::page_frame_to_fill(len);
    Metrics::add(&metrics.disk_reads, 1);
    Metrics::add(&metrics.disk_read_bytes, len as u64);
    scene.source.read_page(page, &mut frame)?;
    Ok(Bytes::from(frame))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(len: usize) -> Bytes {
        Bytes::from(vec![0u8; len])
    }

    #[test]
    fn evicts_least_recently_used_past_the_byte_bound() {
        let m = Metrics::default();
        let cache = PageCache::new(100, &m);
        cache.insert((0, 1), frame(40), Purpose::Wanted, &m);
        cache.insert((0, 2), frame(40), Purpose::Wanted, &m);
        assert!(cache.get((0, 1)).is_some(), "touch page 1");
        cache.insert((1, 1), frame(40), Purpose::Wanted, &m);
        assert!(cache.contains((0, 1)));
        assert!(!cache.contains((0, 2)), "page 2 was least recently used");
        assert!(cache.contains((1, 1)));
        assert_eq!(m.snapshot().cache_bytes, 80);
        cache.insert((2, 0), frame(101), Purpose::Wanted, &m);
        assert!(!cache.contains((2, 0)), "larger than the cache");
        assert_eq!(m.snapshot().cache_pages, 2);
    }

    /// Read-ahead fills free room, then only by dropping its own older
    /// guesses, never a page a client asked for; a guess a client asks
    /// for becomes a served page; a client's page may drop a stale guess.
    #[test]
    fn read_ahead_never_pushes_out_a_page_a_client_asked_for() {
        let m = Metrics::default();
        let cache = PageCache::new(400, &m);
        for p in 0..9 {
            cache.insert((0, p), frame(40), Purpose::Wanted, &m);
        }
        // 360 of 400 bytes served: one guess fits, the next drops it.
        cache.insert((1, 0), frame(40), Purpose::Ahead, &m);
        assert!(cache.contains((1, 0)));
        cache.insert((1, 1), frame(40), Purpose::Ahead, &m);
        assert!(!cache.contains((1, 0)) && cache.contains((1, 1)));
        assert!(
            (0..9).all(|p| cache.contains((0, p))),
            "no served page dropped"
        );
        assert_eq!(m.snapshot().prefetch_unused, 1);
        // A guess larger than the room left beside served pages is not kept.
        cache.insert((1, 2), frame(80), Purpose::Ahead, &m);
        assert!(!cache.contains((1, 2)));
        assert!((0..9).all(|p| cache.contains((0, p))));
        assert_eq!(m.snapshot().prefetch_skipped, 1);
        // Asked for, a guess is served, and read-ahead's room is free again.
        assert!(cache.get((1, 1)).is_some());
        assert_eq!(cache.ahead_bytes(), 0);
        // A client's page drops the least recent page, which is a served
        // one here (0, 0), not the newer guess.
        let fresh = PageCache::new(160, &m);
        fresh.insert((0, 0), frame(40), Purpose::Wanted, &m);
        fresh.insert((0, 1), frame(40), Purpose::Ahead, &m);
        for p in 2..5 {
            fresh.insert((0, p), frame(40), Purpose::Wanted, &m);
        }
        assert!(!fresh.contains((0, 0)) && fresh.contains((0, 1)));
        // And next the guess, now the least recent.
        fresh.insert((0, 5), frame(40), Purpose::Wanted, &m);
        assert!(!fresh.contains((0, 1)) && fresh.contains((0, 2)));
        // Into an empty cache, guesses fill all of it: one that holds the
        // scene reads each page once.
        let roomy = PageCache::new(400, &m);
        for p in 0..10 {
            roomy.insert((2, p), frame(40), Purpose::Ahead, &m);
        }
        assert!((0..10).all(|p| roomy.contains((2, p))));
        assert_eq!(roomy.ahead_bytes(), 400);
    }

    /// Guesses dropped unused spend read-ahead's credit until it stops;
    /// pages served earn it back, and guesses clients use cost nothing.
    #[test]
    fn read_ahead_stops_when_its_guesses_go_unused() {
        let m = Metrics::default();
        let cache = PageCache::new(400, &m);
        let wasted = GUESS_CREDIT as u32;
        // Ten guesses fill the cache; each one more drops one unused.
        for p in 0..10 + wasted {
            assert!(cache.may_guess(), "credit left at guess {p}");
            cache.insert((0, p), frame(40), Purpose::Ahead, &m);
        }
        assert_eq!(m.snapshot().prefetch_unused, u64::from(wasted));
        assert!(!cache.may_guess(), "every guess so far went unused");
        // Twenty pages served (five of the guesses, four times each) earn
        // two guesses back.
        let scene_page = |p| (0, 10 + wasted - 1 - p);
        for p in 0..20 {
            assert!(cache.get(scene_page(p % 5)).is_some(), "a guess used");
            cache.served();
        }
        assert!(cache.may_guess());
        for p in 0..3 {
            cache.insert((1, p), frame(40), Purpose::Ahead, &m);
        }
        assert!(!cache.may_guess(), "three more wasted, credit spent again");
        // Used guesses, now served pages, are never dropped for a guess.
        assert!(
            (0..5).all(|p| cache.contains(scene_page(p))),
            "all five still cached"
        );
        // With the cache all served, there is no room to guess into.
        let full = PageCache::new(80, &m);
        full.insert((1, 0), frame(40), Purpose::Wanted, &m);
        full.insert((1, 1), frame(40), Purpose::Wanted, &m);
        assert!(!full.may_guess(), "no room beside served pages");
    }

    /// A source whose every read takes a while, counted.
    #[derive(Debug)]
    struct Slow {
        file: farfield_store::SceneFile,
        reads: std::sync::atomic::AtomicU64,
    }

    impl farfield_store::PageSource for Slow {
        fn header(&self) -> &farfield_protocol::file::FileHeader {
            &self.file.header
        }
        fn directory(&self) -> &farfield_protocol::directory::Directory {
            &self.file.directory
        }
        fn header_bytes(&self) -> &[u8] {
            self.file.header_bytes()
        }
        fn stored_len(&self) -> u64 {
            self.file.len()
        }
        fn read_page(&self, index: u32, out: &mut Vec<u8>) -> Result<(), PageError> {
            self.reads.fetch_add(1, Ordering::Relaxed);
            std::thread::sleep(std::time::Duration::from_millis(100));
            self.file.read_page(index, out)
        }
        fn changed(&self) -> Option<String> {
            None
        }
        fn stamp(&self) -> farfield_store::Stamp {
            farfield_store::Stamp::File(self.file.stamp())
        }
        fn location(&self) -> String {
            "slow".into()
        }
    }

    #[test]
    fn clients_missing_one_page_together_share_one_read() {
        use farfield_builder::import::{Params, load_input};
        let dir = std::env::temp_dir().join(format!("farfield-flight-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("tree.ff");
        let scene = load_input("gen:tree", &Params::default()).unwrap();
        let (file, _) = farfield_builder::build_spheres(scene, &Default::default()).unwrap();
        farfield_store::write_atomic(&path, &file).unwrap();
        let slow = Slow {
            file: farfield_store::SceneFile::open(&path).unwrap(),
            reads: Default::default(),
        };
        let location = crate::origin::Location::File(path);
        let scene = ServedScene::with_source(0, "tree", &location, Box::new(slow));
        let m = Metrics::default();
        let cache = PageCache::new(1 << 30, &m);
        let frames: Vec<Bytes> = std::thread::scope(|s| {
            let readers: Vec<_> = (0..8)
                .map(|_| s.spawn(|| cache.read_through(&scene, 0, Purpose::Wanted, &m).unwrap()))
                .collect();
            readers.into_iter().map(|r| r.join().unwrap()).collect()
        });
        assert!(frames.iter().all(|f| *f == frames[0]));
        assert_eq!(m.snapshot().disk_reads, 1, "eight misses, one read");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
