//! The memory server's counters and their Prometheus text rendering.
//!
//! Plain atomics, updated on the hot path without locks, and one histogram
//! with fixed buckets for request latency (the time from a page becoming
//! wanted to its frame being handed to the socket). `/metrics` renders them
//! by hand in the Prometheus text exposition format; [`Metrics::snapshot`]
//! gives the same numbers as a struct for in-process callers and reports.

use std::fmt::Write as _;
use std::sync::atomic::{AtomicI64, AtomicU64, Ordering};

use serde::Serialize;

use crate::limits::Limit;
pub use farfield_store::histogram::{Histogram, LATENCY_BUCKETS_S, RemoteStats};

/// Every counter the server keeps; shared by all connections.
#[derive(Debug, Default)]
pub struct Metrics {
    pub pages_served: AtomicU64,
    pub bytes_served: AtomicU64,
    pub pages_pushed: AtomicU64,
    pub cache_hits: AtomicU64,
    pub cache_misses: AtomicU64,
    /// Pages read from the scenes' files (misses and read-ahead), and
    /// their bytes: what the disk served.
    pub disk_reads: AtomicU64,
    pub disk_read_bytes: AtomicU64,
    pub cache_bytes: AtomicU64,
    pub cache_pages: AtomicU64,
    pub cache_capacity_bytes: AtomicU64,
    pub prefetch_loads: AtomicU64,
    pub prefetch_dropped: AtomicU64,
    /// Pages read ahead and dropped before any client asked for them (the
    /// reads read-ahead wasted), and pages read ahead but not kept (no
    /// room without dropping a page a client asked for).
    pub prefetch_unused: AtomicU64,
    pub prefetch_skipped: AtomicU64,
    pub prefetch_throttled: AtomicU64,
    /// Bytes of the cache holding pages read ahead that no client has
    /// asked for yet.
    pub cache_ahead_bytes: AtomicU64,
    /// Look-ahead along presenters' motion: passes walked, pages it read
    /// into the cache, and passes dropped because the queue was full.
    pub lookahead_passes: AtomicU64,
    pub lookahead_loads: AtomicU64,
    pub lookahead_dropped: AtomicU64,
    pub corrupt_pages: AtomicU64,
    pub malformed_frames: AtomicU64,
    /// Sessions whose client went without a closing handshake (closed
    /// TCP, or reset): ordinary disconnects, apart from violations.
    pub dropped_connections: AtomicU64,
    /// Failed accepts (out of descriptors, most likely).
    pub accept_errors: AtomicU64,
    pub connections_total: AtomicU64,
    /// Signed so a decrement racing an increment can never wrap.
    pub connected_clients: AtomicI64,
    /// TCP connections open now (HTTP and websocket).
    pub open_connections: AtomicI64,
    /// Pages wanted and not yet sent, over all connections.
    pub queue_depth: AtomicI64,
    pub pages_cancelled: AtomicU64,
    pub scenes: AtomicU64,
    /// Per [`Limit`], in [`Limit::ALL`]'s order: how often a client ran
    /// into it.
    pub limit_hits: [AtomicU64; Limit::ALL.len()],
    pub latency: Histogram,
    /// Requests to the object store the scenes are in, when they are
    /// (shared with the store's bucket, which counts them).
    pub store: std::sync::Arc<RemoteStats>,
}

/// The counters at one moment, for reports and tests.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MetricsSnapshot {
    pub pages_served: u64,
    pub bytes_served: u64,
    pub pages_pushed: u64,
    pub cache_hits: u64,
    pub cache_misses: u64,
    pub disk_reads: u64,
    pub disk_read_bytes: u64,
    pub cache_bytes: u64,
    pub cache_pages: u64,
    pub cache_capacity_bytes: u64,
    pub prefetch_loads: u64,
    pub prefetch_dropped: u64,
    pub prefetch_unused: u64,
    pub prefetch_skipped: u64,
    pub prefetch_throttled: u64,
    pub cache_ahead_bytes: u64,
    pub lookahead_passes: u64,
    pub lookahead_loads: u64,
    pub lookahead_dropped: u64,
    pub corrupt_pages: u64,
    pub malformed_frames: u64,
    pub dropped_connections: u64,
    pub accept_errors: u64,
    pub connections_total: u64,
    pub connected_clients: u64,
    pub open_connections: u64,
    pub queue_depth: u64,
    pub pages_cancelled: u64,
    pub scenes: u64,
    /// Limit name -> times a client ran into it.
    pub limit_hits: std::collections::BTreeMap<&'static str, u64>,
    pub latency_count: u64,
    pub latency_sum_s: f64,
    /// Requests to the object store, their bytes, failures (timeouts among
    /// them), and reads failed at once while it was down.
    pub store_requests: u64,
    pub store_bytes: u64,
    pub store_errors: u64,
    pub store_timeouts: u64,
    pub store_fast_failures: u64,
    /// Pages the store's local second tier served, and pages put there.
    pub store_tier_hits: u64,
    pub store_tier_writes: u64,
    /// The server process's resident memory (Linux; `None` elsewhere).
    pub resident_bytes: Option<u64>,
}

/// The process's resident set in bytes, from `/proc/self/statm` (Linux).
#[cfg(not(target_os = "linux"))]
pub fn resident_bytes() -> Option<u64> {
    None
}

/// The process's resident set in bytes, from `/proc/self/statm` (Linux).
#[cfg(target_os = "linux")]
pub fn resident_bytes() -> Option<u64> {
    let statm = std::fs::read_to_string("/proc/self/statm").ok()?;
    let pages: u64 = statm.split_whitespace().nth(1)?.parse().ok()?;
    // SAFETY: sysconf has no preconditions; it returns -1 on error.
    let page = unsafe { libc::sysconf(libc::_SC_PAGESIZE) };
    Some(pages * u64::try_from(page).ok()?)
}

fn get(a: &AtomicU64) -> u64 {
    a.load(Ordering::Relaxed)
}

fn gauge(a: &AtomicI64) -> u64 {
    u64::try_from(a.load(Ordering::Relaxed)).unwrap_or(0)
}

impl Metrics {
    pub fn add(a: &AtomicU64, n: u64) {
        a.fetch_add(n, Ordering::Relaxed);
    }

    /// Counts a client running into `limit`.
    pub fn hit(&self, limit: Limit) {
        if let Some(i) = Limit::ALL.iter().position(|&l| l == limit) {
            Self::add(&self.limit_hits[i], 1);
        }
    }

    pub fn snapshot(&self) -> MetricsSnapshot {
        let (_, latency_sum_s, latency_count) = self.latency.cumulative();
        MetricsSnapshot {
            pages_served: get(&self.pages_served),
            bytes_served: get(&self.bytes_served),
            pages_pushed: get(&self.pages_pushed),
            cache_hits: get(&self.cache_hits),
            cache_misses: get(&self.cache_misses),
            disk_reads: get(&self.disk_reads),
            disk_read_bytes: get(&self.disk_read_bytes),
            cache_bytes: get(&self.cache_bytes),
            cache_pages: get(&self.cache_pages),
            cache_capacity_bytes: get(&self.cache_capacity_bytes),
            prefetch_loads: get(&self.prefetch_loads),
            prefetch_dropped: get(&self.prefetch_dropped),
            prefetch_unused: get(&self.prefetch_unused),
            prefetch_skipped: get(&self.prefetch_skipped),
            prefetch_throttled: get(&self.prefetch_throttled),
            cache_ahead_bytes: get(&self.cache_ahead_bytes),
            lookahead_passes: get(&self.lookahead_passes),
            lookahead_loads: get(&self.lookahead_loads),
            lookahead_dropped: get(&self.lookahead_dropped),
            corrupt_pages: get(&self.corrupt_pages),
            malformed_frames: get(&self.malformed_frames),
            dropped_connections: get(&self.dropped_connections),
            accept_errors: get(&self.accept_errors),
            connections_total: get(&self.connections_total),
            connected_clients: gauge(&self.connected_clients),
            open_connections: gauge(&self.open_connections),
            queue_depth: gauge(&self.queue_depth),
            pages_cancelled: get(&self.pages_cancelled),
            scenes: get(&self.scenes),
            limit_hits: Limit::ALL
                .iter()
                .zip(&self.limit_hits)
                .map(|(l, n)| (l.name(), get(n)))
                .collect(),
            latency_count,
            latency_sum_s,
            store_requests: get(&self.store.requests),
            store_bytes: get(&self.store.bytes),
            store_errors: get(&self.store.errors),
            store_timeouts: get(&self.store.timeouts),
            store_fast_failures: get(&self.store.fast_failures),
            store_tier_hits: get(&self.store.tier_hits),
            store_tier_writes: get(&self.store.tier_writes),
            resident_bytes: resident_bytes(),
        }
    }

    /// The Prometheus text exposition (format 0.0.4).
    pub fn render(&self) -> String {
        let s = self.snapshot();
        let mut out = String::with_capacity(4096);
        let mut metric = |name: &str, kind: &str, help: &str, value: u64| {
            let _ = write!(
                out,
                "# HELP {name} {help}\n# TYPE {name} {kind}\n{name} {value}\n"
            );
        };
        metric(
            "farfield_pages_served_total",
            "counter",
            "Page frames sent to clients (requested, page 0 and pushed).",
            s.pages_served,
        );
        metric(
            "farfield_bytes_served_total",
            "counter",
            "Page bytes sent to clients.",
            s.bytes_served,
        );
        metric(
            "farfield_pages_pushed_total",
            "counter",
            "Pages pushed to clients that allowed pushes, unrequested.",
            s.pages_pushed,
        );
        metric(
            "farfield_page_cache_hits_total",
            "counter",
            "Page lookups answered from the page cache.",
            s.cache_hits,
        );
        metric(
            "farfield_page_cache_misses_total",
            "counter",
            "Page lookups that read the scene's file.",
            s.cache_misses,
        );
        metric(
            "farfield_disk_reads_total",
            "counter",
            "Pages read from the scenes' files (cache misses and read-ahead).",
            s.disk_reads,
        );
        metric(
            "farfield_disk_read_bytes_total",
            "counter",
            "Bytes read from the scenes' files.",
            s.disk_read_bytes,
        );
        metric(
            "farfield_page_cache_bytes",
            "gauge",
            "Bytes held in the page cache.",
            s.cache_bytes,
        );
        metric(
            "farfield_page_cache_pages",
            "gauge",
            "Pages held in the page cache.",
            s.cache_pages,
        );
        metric(
            "farfield_page_cache_capacity_bytes",
            "gauge",
            "Byte bound of the page cache.",
            s.cache_capacity_bytes,
        );
        metric(
            "farfield_prefetch_loads_total",
            "counter",
            "Child pages read ahead into the cache.",
            s.prefetch_loads,
        );
        metric(
            "farfield_prefetch_dropped_total",
            "counter",
            "Read-ahead hints dropped because the prefetch queue was full.",
            s.prefetch_dropped,
        );
        metric(
            "farfield_prefetch_unused_total",
            "counter",
            "Pages read ahead and dropped from the cache before any client asked for them.",
            s.prefetch_unused,
        );
        metric(
            "farfield_prefetch_skipped_total",
            "counter",
            "Pages read ahead but not kept: no room without dropping a page a client asked for.",
            s.prefetch_skipped,
        );
        metric(
            "farfield_prefetch_throttled_total",
            "counter",
            "Pages not read ahead because recent guesses went unused too often, or no room was left for guesses.",
            s.prefetch_throttled,
        );
        metric(
            "farfield_page_cache_ahead_bytes",
            "gauge",
            "Bytes of the page cache holding pages read ahead that no client has asked for yet.",
            s.cache_ahead_bytes,
        );
        metric(
            "farfield_lookahead_passes_total",
            "counter",
            "Walks of a presenter's extrapolated view, ahead of its motion.",
            s.lookahead_passes,
        );
        metric(
            "farfield_lookahead_loads_total",
            "counter",
            "Pages read into the cache for a presenter's extrapolated view.",
            s.lookahead_loads,
        );
        metric(
            "farfield_lookahead_dropped_total",
            "counter",
            "Look-ahead walks dropped because their queue was full.",
            s.lookahead_dropped,
        );
        metric(
            "farfield_corrupt_pages_total",
            "counter",
            "Page loads that failed verification (reported, never sent).",
            s.corrupt_pages,
        );
        metric(
            "farfield_malformed_frames_total",
            "counter",
            "Client frames that broke the protocol and closed their connection.",
            s.malformed_frames,
        );
        metric(
            "farfield_connections_dropped_total",
            "counter",
            "Websocket sessions whose client left without a closing handshake (an ordinary disconnect).",
            s.dropped_connections,
        );
        metric(
            "farfield_accept_errors_total",
            "counter",
            "Connections the server could not accept (out of descriptors, most likely).",
            s.accept_errors,
        );
        metric(
            "farfield_connections_total",
            "counter",
            "Websocket sessions accepted.",
            s.connections_total,
        );
        metric(
            "farfield_connected_clients",
            "gauge",
            "Websocket sessions open now.",
            s.connected_clients,
        );
        metric(
            "farfield_open_connections",
            "gauge",
            "TCP connections open now, HTTP and websocket.",
            s.open_connections,
        );
        metric(
            "farfield_queue_depth",
            "gauge",
            "Pages requested and not yet sent, over all connections.",
            s.queue_depth,
        );
        metric(
            "farfield_pages_cancelled_total",
            "counter",
            "Queued pages cancelled by clients before being sent.",
            s.pages_cancelled,
        );
        metric("farfield_scenes", "gauge", "Scenes being served.", s.scenes);
        metric(
            "farfield_store_requests_total",
            "counter",
            "Requests to the object store (headers, pages, listings).",
            s.store_requests,
        );
        metric(
            "farfield_store_bytes_total",
            "counter",
            "Bytes the object store's range requests returned.",
            s.store_bytes,
        );
        metric(
            "farfield_store_errors_total",
            "counter",
            "Requests to the object store that failed or timed out.",
            s.store_errors,
        );
        metric(
            "farfield_store_timeouts_total",
            "counter",
            "Requests to the object store cut by their deadline.",
            s.store_timeouts,
        );
        metric(
            "farfield_store_fast_failures_total",
            "counter",
            "Reads refused at once while the object store was known to be down.",
            s.store_fast_failures,
        );
        metric(
            "farfield_store_tier_hits_total",
            "counter",
            "Pages served from the store's local second tier.",
            s.store_tier_hits,
        );
        metric(
            "farfield_store_tier_writes_total",
            "counter",
            "Pages read from the store and kept in its local second tier.",
            s.store_tier_writes,
        );
        if let Some(rss) = s.resident_bytes {
            // The name Prometheus's own process collectors use.
            metric(
                "process_resident_memory_bytes",
                "gauge",
                "Resident memory size in bytes.",
                rss,
            );
        }
        let name = "farfield_limit_hits_total";
        let _ = writeln!(
            out,
            "# HELP {name} Connections refused or closed by a limit, per limit."
        );
        let _ = writeln!(out, "# TYPE {name} counter");
        for (limit, n) in &s.limit_hits {
            let _ = writeln!(out, "{name}{{limit=\"{limit}\"}} {n}");
        }
        histogram(
            &mut out,
            "farfield_request_latency_seconds",
            "Time from a page becoming wanted to its frame being sent.",
            &self.latency,
        );
        histogram(
            &mut out,
            "farfield_store_request_seconds",
            "Time an object store request took, failed ones included.",
            &self.store.latency,
        );
        out
    }
}

/// Renders `h` as a Prometheus histogram.
fn histogram(out: &mut String, name: &str, help: &str, h: &Histogram) {
    let (counts, sum, count) = h.cumulative();
    let _ = writeln!(out, "# HELP {name} {help}");
    let _ = writeln!(out, "# TYPE {name} histogram");
    for (bound, c) in LATENCY_BUCKETS_S.iter().zip(&counts) {
        let _ = writeln!(out, "{name}_bucket{{le=\"{bound}\"}} {c}");
    }
    let _ = writeln!(
        out,
        "{name}_bucket{{le=\"+Inf\"}} {}",
        counts.last().copied().unwrap_or(0)
    );
    let _ = writeln!(out, "{name}_sum {sum}");
    let _ = writeln!(out, "{name}_count {count}");
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn histogram_is_cumulative_and_rendered() {
        let m = Metrics::default();
        m.latency.observe(Duration::from_micros(50));
        m.latency.observe(Duration::from_millis(3));
        m.latency.observe(Duration::from_secs(100));
        let (counts, sum, count) = m.latency.cumulative();
        assert_eq!(count, 3);
        assert_eq!(counts[0], 1);
        assert_eq!(counts[5], 2, "0.005 bucket holds 50 us and 3 ms");
        assert_eq!(*counts.last().unwrap(), 3);
        assert!((sum - 100.00305).abs() < 1e-6);
        let text = m.render();
        assert!(text.contains("farfield_request_latency_seconds_bucket{le=\"+Inf\"} 3"));
        assert!(text.contains("farfield_request_latency_seconds_count 3"));
        assert!(text.contains("# TYPE farfield_queue_depth gauge"));
        m.hit(Limit::IdleTimeout);
        assert!(
            m.render()
                .contains("farfield_limit_hits_total{limit=\"idle_timeout\"} 1")
        );
    }

    #[test]
    fn negative_gauges_render_as_zero() {
        let m = Metrics::default();
        m.queue_depth.fetch_sub(1, Ordering::Relaxed);
        assert_eq!(m.snapshot().queue_depth, 0);
    }
}
