//! Read-ahead: when a client asks for a page, the pages holding its nodes'
//! children are loaded into the page cache before anyone asks for them
//! (the 1995 report's memory server, section 6.2).
//!
//! A small pool of plain threads does the reading, because a read may wait
//! on the disk and must not stall the async runtime. The children of a
//! page lie side by side, so the pages missing from the cache are queued
//! as runs of neighbours, each read at once where the source can (one
//! range request to an object store). The queue in front of the threads is
//! bounded: a hint that does not fit is dropped (and counted), since
//! read-ahead is only ever an optimisation. So is a hint while the cache
//! says guessing does not pay ([`PageCache::may_guess`]: too many recent
//! guesses went unused, or no room is left for them), asked when the hint
//! is given and again before each read.

use std::collections::HashSet;
use std::ops::Range;
use std::sync::mpsc::{Receiver, SyncSender, TrySendError, sync_channel};
use std::sync::{Arc, Mutex};

use super::cache::{PageCache, PageKey, Purpose};
use super::catalog::ServedScene;
use super::metrics::Metrics;

/// Threads reading ahead; the machine this targets has two cores.
pub const PREFETCH_THREADS: usize = 2;
/// Hints (runs of pages) waiting for a thread.
pub const PREFETCH_QUEUE: usize = 4096;
/// Pages in one run at most.
pub const MAX_RUN: u32 = 64;

type Job = (Arc<ServedScene>, Range<u32>);

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
    /// there or on their way are skipped, and the rest queued as runs of
    /// neighbours. Never blocks.
    pub fn hint(&self, scene: &Arc<ServedScene>, pages: Range<u32>) {
        if !self.cache.may_guess() {
            Metrics::add(&self.metrics.prefetch_throttled, pages.len() as u64);
            return;
        }
        let mut run: Option<Range<u32>> = None;
        for page in pages {
            let key = (scene.id, page);
            let wanted = !self.cache.contains(key) && lock(&self.pending).insert(key);
            match &mut run {
                Some(r) if wanted && r.end == page && r.end - r.start < MAX_RUN => r.end += 1,
                _ => {
                    if let Some(done) = run.take() {
                        self.queue(scene, done);
                    }
                    run = wanted.then_some(page..page + 1);
                }
            }
        }
        if let Some(done) = run {
            self.queue(scene, done);
        }
    }

    fn queue(&self, scene: &Arc<ServedScene>, run: Range<u32>) {
        match self.tx.try_send((scene.clone(), run.clone())) {
            Ok(()) => {}
            Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) => {
                let mut pending = lock(&self.pending);
                for page in run {
                    pending.remove(&(scene.id, page));
                    Metrics::add(&self.metrics.prefetch_dropped, 1);
                }
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
        let Ok((scene, run)) = job else { return };
        // Pages a client's own read brought in meanwhile are not read
        // again: the run is read as its stretches still missing now.
        let mut loaded = 0;
        let mut page = run.start;
        while page < run.end {
            if cache.contains((scene.id, page)) {
                page += 1;
                continue;
            }
            let start = page;
            while page < run.end && !cache.contains((scene.id, page)) {
                page += 1;
            }
            if !cache.may_guess() {
                Metrics::add(&metrics.prefetch_throttled, u64::from(page - start));
                continue;
            }
            // Failures are told to the session that asks for the page, if
            // one does (and corrupt pages are remembered by the cache).
            loaded += match page - start {
                1 => u64::from(
                    cache
                        .read_through(&scene, start, Purpose::Ahead, metrics)
                        .is_ok(),
                ),
                _ => cache.read_run_through(&scene, start..page, metrics),
            };
        }
        Metrics::add(&metrics.prefetch_loads, loaded);
        let mut pending = lock(pending);
        for page in run {
            pending.remove(&(scene.id, page));
        }
    }
}
