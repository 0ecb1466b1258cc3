//! The page cache: hot pages of every scene, shared by all connections,
//! bounded in bytes.
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
use farfield_protocol::messages::FrameKind;
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
    lru: LruCache<PageKey, Bytes>,
    bytes: u64,
}

impl PageCache {
    pub fn new(capacity: u64, metrics: &Metrics) -> Self {
        metrics
            .cache_capacity_bytes
            .store(capacity, Ordering::Relaxed);
        Self {
            inner: Mutex::new(Inner {
                lru: LruCache::unbounded(),
                bytes: 0,
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

    /// The cached frame, made most recently used.
    pub fn get(&self, key: PageKey) -> Option<Bytes> {
        self.lock().lru.get(&key).cloned()
    }

    /// Whether `key` is cached, without touching its recency.
    pub fn contains(&self, key: PageKey) -> bool {
        self.lock().lru.contains(&key)
    }

    /// Adds a frame, evicting least recently used frames past the bound. A
    /// frame larger than the whole cache is not kept.
    pub fn insert(&self, key: PageKey, frame: Bytes, metrics: &Metrics) {
        let len = frame.len() as u64;
        if len > self.capacity {
            return;
        }
        let mut inner = self.lock();
        if let Some(old) = inner.lru.put(key, frame) {
            inner.bytes -= old.len() as u64;
        }
        inner.bytes += len;
        while inner.bytes > self.capacity {
            match inner.lru.pop_lru() {
                Some((_, old)) => inner.bytes -= old.len() as u64,
                None => break,
            }
        }
        metrics.cache_bytes.store(inner.bytes, Ordering::Relaxed);
        metrics
            .cache_pages
            .store(inner.lru.len() as u64, Ordering::Relaxed);
    }

    /// Reads, verifies and caches a page that was not found in the cache.
    /// A scene whose file changed is retired here, by whichever read finds
    /// it first.
    pub fn read_through(
        &self,
        scene: &ServedScene,
        page: u32,
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
            return flight.wait();
        }
        // Read by a flight that just ended, between the miss and here.
        let result = match self.get(key) {
            Some(frame) => Ok(frame),
            None => read_verified(scene, page, metrics)
                .inspect_err(|e| self.failed(scene, page, e, metrics)),
        };
        if let Ok(frame) = &result {
            self.insert(key, frame.clone(), metrics);
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
                    let mut frame = Vec::with_capacity(bytes.len() + 1);
                    frame.push(FrameKind::Page as u8);
                    frame.extend_from_slice(&bytes);
                    self.insert((scene.id, page), Bytes::from(frame), metrics);
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
        let (cache, scene2, metrics2) = (self.clone(), scene.clone(), metrics.clone());
        match tokio::task::spawn_blocking(move || cache.read_through(&scene2, page, &metrics2))
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
    let mut frame = Vec::with_capacity(len + 1);
    frame.push(FrameKind::Page as u8);
    Metrics::add(&metrics.disk_reads, 1);
    Metrics::add(&metrics.disk_read_bytes, len as u64);
    scene.source.read_page(page, &mut frame)?;
    Ok(Bytes::from(frame))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn evicts_least_recently_used_past_the_byte_bound() {
        let m = Metrics::default();
        let cache = PageCache::new(100, &m);
        cache.insert((0, 1), Bytes::from(vec![0u8; 40]), &m);
        cache.insert((0, 2), Bytes::from(vec![0u8; 40]), &m);
        assert!(cache.get((0, 1)).is_some(), "touch page 1");
        cache.insert((1, 1), Bytes::from(vec![0u8; 40]), &m);
        assert!(cache.contains((0, 1)));
        assert!(!cache.contains((0, 2)), "page 2 was least recently used");
        assert!(cache.contains((1, 1)));
        assert_eq!(m.snapshot().cache_bytes, 80);
        cache.insert((2, 0), Bytes::from(vec![0u8; 101]), &m);
        assert!(!cache.contains((2, 0)), "larger than the cache");
        assert_eq!(m.snapshot().cache_pages, 2);
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
                .map(|_| s.spawn(|| cache.read_through(&scene, 0, &m).unwrap()))
                .collect();
            readers.into_iter().map(|r| r.join().unwrap()).collect()
        });
        assert!(frames.iter().all(|f| *f == frames[0]));
        assert_eq!(m.snapshot().disk_reads, 1, "eight misses, one read");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
