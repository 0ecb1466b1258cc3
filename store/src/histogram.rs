//! [`Histogram`]: durations in fixed buckets, updated without locks, and
//! [`RemoteStats`], what a page source that reads over a network counts.
//! The memory server renders both on `/metrics`.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

/// Upper bounds of the latency buckets, in seconds (`+Inf` is implicit).
pub const LATENCY_BUCKETS_S: [f64; 16] = [
    0.0001, 0.00025, 0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5,
    5.0, 10.0,
];

/// A fixed-bucket histogram of durations (non-cumulative counts per bucket;
/// rendering accumulates).
#[derive(Debug, Default)]
pub struct Histogram {
    buckets: [AtomicU64; LATENCY_BUCKETS_S.len() + 1],
    sum_us: AtomicU64,
    count: AtomicU64,
}

impl Histogram {
    pub fn observe(&self, d: Duration) {
        let s = d.as_secs_f64();
        let i = LATENCY_BUCKETS_S
            .iter()
            .position(|&b| s <= b)
            .unwrap_or(LATENCY_BUCKETS_S.len());
        self.buckets[i].fetch_add(1, Ordering::Relaxed);
        let us = u64::try_from(d.as_micros()).unwrap_or(u64::MAX);
        self.sum_us.fetch_add(us, Ordering::Relaxed);
        self.count.fetch_add(1, Ordering::Relaxed);
    }

    /// Cumulative counts per bucket (the last is `+Inf`), sum in seconds, count.
    pub fn cumulative(&self) -> (Vec<u64>, f64, u64) {
        let mut acc = 0;
        let counts = self
            .buckets
            .iter()
            .map(|b| {
                acc += b.load(Ordering::Relaxed);
                acc
            })
            .collect();
        (
            counts,
            self.sum_us.load(Ordering::Relaxed) as f64 * 1e-6,
            self.count.load(Ordering::Relaxed),
        )
    }
}

/// What a source reading from a network store (object storage) did: its
/// requests, the bytes they brought, their failures and latency, and its
/// local second tier's hits. Shared by every scene of one store.
#[derive(Debug, Default)]
pub struct RemoteStats {
    /// Range (and header) requests sent, and the bytes they returned.
    pub requests: AtomicU64,
    pub bytes: AtomicU64,
    /// Requests that failed (the store unreachable, slow, or refusing),
    /// and of those the ones cut by the timeout.
    pub errors: AtomicU64,
    pub timeouts: AtomicU64,
    /// Reads answered at once because the store was known to be down.
    pub fast_failures: AtomicU64,
    /// Pages found in the local second tier, and pages put there.
    pub tier_hits: AtomicU64,
    pub tier_writes: AtomicU64,
    pub latency: Histogram,
}

impl RemoteStats {
    pub fn add(counter: &AtomicU64, n: u64) {
        counter.fetch_add(n, Ordering::Relaxed);
    }
}
