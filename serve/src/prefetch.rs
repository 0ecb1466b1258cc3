//! Read-ahead: when a client asks for a page, the pages holding its nodes'
//! children are loaded into the page cache before anyone asks for them
//! (the 1995 report's memory server, section 6.2).
//!
//! A small pool of plain threads does the reading, because a read may wait
//! on the disk and must not stall the async runtime. The
//! queue in front of it is bounded: a hint that does not fit is dropped
//! (and counted), since read-ahead is only ever an optimisation.

use std::collections::HashSet;
use std::ops::Range;
use std::sync::mpsc::{Receiver, SyncSender, TrySendError, sync_channel};
use std::sync::{Arc, Mutex};

use super::cache::{PageCache, PageKey};
use super::catalog::ServedScene;
use super::metrics::Metrics;

/// Threads reading ahead; the machine this targets has two cores.
pub const PREFETCH_THREADS: usize = 2;
/// Hints waiting for a thread.
pub const PREFETCH_QUEUE: usize = 4096;

type Job = (Arc<ServedScene>, u32);

/// The handle connections give hints to; the threads stop when it drops.
#[derive(Debug)]
pub struct Prefetcher {
    tx: SyncSender<Job>,
    cache: Arc<PageCache>,
    metrics: Arc<Metrics>,
    /// Pages queued or being read, so many clients asking for the same
    /// parent queue its children once.
    pending: Arc<Pending>,
}

type Pending = Mutex<HashSet<PageKey>>;

fn lock(pending: &Pending) -> std::sync::MutexGuard<'_, HashSet<PageKey>> {
    pending.lock().unwrap_or_else(|e| e.into_inner())
}

impl Prefetcher {
    pub fn start(cache: Arc<PageCache>, metrics: Arc<Metrics>) -> std::io::Result<Self> {
        let (tx, rx) = sync_channel::<Job>(PREFETCH_QUEUE);
        let rx = Arc::new(Mutex::new(rx));
        let pending = Arc::new(Pending::default());
        for i in 0..PREFETCH_THREADS {
            let (rx, cache, metrics) = (rx.clone(), cache.clone(), metrics.clone());
            let pending = pending.clone();
            std::thread::Builder::new()
                .name(format!("farfield-prefetch-{i}"))
                .spawn(move || worker(&rx, &cache, &metrics, &pending))?;
        }
        Ok(Self {
            tx,
            cache,
            metrics,
            pending,
        })
    }

    /// Asks for `pages` of `scene` to be read into the cache; pages already
    /// there are skipped. Never blocks.
    pub fn hint(&self, scene: &Arc<ServedScene>, pages: Range<u32>) {
        for page in pages {
            let key = (scene.id, page);
            if self.cache.contains(key) || !lock(&self.pending).insert(key) {
                continue;
            }
            match self.tx.try_send((scene.clone(), page)) {
                Ok(()) => {}
                Err(TrySendError::Full(_)) => {
                    lock(&self.pending).remove(&key);
                    Metrics::add(&self.metrics.prefetch_dropped, 1);
                }
                Err(TrySendError::Disconnected(_)) => return,
            }
        }
    }
}

fn worker(rx: &Mutex<Receiver<Job>>, cache: &PageCache, metrics: &Metrics, pending: &Pending) {
    loop {
        let job = match rx.lock() {
            Ok(rx) => rx.recv(),
            Err(_) => return,
        };
        let Ok((scene, page)) = job else { return };
        let key = (scene.id, page);
        if !cache.contains(key) {
            match cache.read_through(&scene, page, metrics) {
                Ok(_) => Metrics::add(&metrics.prefetch_loads, 1),
                // Told to the session that asks for the page, if one does.
                Err(e) => tracing::debug!(scene = %scene.name, "read-ahead: {e}"),
            }
        }
        lock(pending).remove(&key);
    }
}
