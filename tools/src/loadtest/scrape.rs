//! Sampling a memory server's `/metrics` (Prometheus text) during a load
//! test: its memory, cache, queues and connections over the run.

use std::collections::HashMap;
use std::time::Duration;

use farfield_store::histogram::LATENCY_BUCKETS_S;
use serde::Serialize;

/// The server's histogram of its own request latency (a page wanted to its
/// frame sent), read from `/metrics`.
pub const REQUEST_LATENCY: &str = "farfield_request_latency_seconds_bucket";

/// Cumulative counts per bucket of [`LATENCY_BUCKETS_S`], then `+Inf`.
pub type Buckets = [f64; LATENCY_BUCKETS_S.len() + 1];

/// The figures of one sample that a load test reports.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct ServerSample {
    pub resident_bytes: Option<f64>,
    pub cache_hits: Option<f64>,
    pub cache_misses: Option<f64>,
    pub disk_reads: Option<f64>,
    pub disk_read_bytes: Option<f64>,
    pub bytes_served: Option<f64>,
    pub pages_served: Option<f64>,
    pub queue_depth: Option<f64>,
    pub connected_clients: Option<f64>,
    pub open_connections: Option<f64>,
    /// The server's request latency histogram, when every bucket was read.
    pub request_latency: Option<Buckets>,
}

impl ServerSample {
    /// The figures a load test wants, out of the exposition text; lines it
    /// does not know (and labelled series) are skipped.
    pub fn parse(text: &str) -> Self {
        let values: HashMap<&str, f64> = text
            .lines()
            .filter(|l| !l.starts_with('#'))
            .filter_map(|l| {
                let (name, value) = l.split_once(' ')?;
                Some((name, value.trim().parse().ok()?))
            })
            .collect();
        let v = |name: &str| values.get(name).copied();
        Self {
            resident_bytes: v("process_resident_memory_bytes"),
            cache_hits: v("farfield_page_cache_hits_total"),
            cache_misses: v("farfield_page_cache_misses_total"),
            disk_reads: v("farfield_disk_reads_total"),
            disk_read_bytes: v("farfield_disk_read_bytes_total"),
            bytes_served: v("farfield_bytes_served_total"),
            pages_served: v("farfield_pages_served_total"),
            queue_depth: v("farfield_queue_depth"),
            connected_clients: v("farfield_connected_clients"),
            open_connections: v("farfield_open_connections"),
            request_latency: request_latency(text),
        }
    }
}

/// The request latency buckets out of the exposition text.
fn request_latency(text: &str) -> Option<Buckets> {
    let mut buckets = [f64::NAN; LATENCY_BUCKETS_S.len() + 1];
    for line in text.lines() {
        let Some(rest) = line.strip_prefix(REQUEST_LATENCY) else {
            continue;
        };
        let Some((label, value)) = rest.split_once(' ') else {
            continue;
        };
        let Some(le) = label
            .strip_prefix("{le=\"")
            .and_then(|l| l.strip_suffix("\"}"))
        else {
            continue;
        };
        let index = if le == "+Inf" {
            Some(LATENCY_BUCKETS_S.len())
        } else {
            let le: f64 = le.parse().ok()?;
            LATENCY_BUCKETS_S
                .iter()
                .position(|b| (b - le).abs() <= 1e-9 * b)
        };
        if let (Some(i), Ok(count)) = (index, value.trim().parse()) {
            buckets[i] = count;
        }
    }
    buckets.iter().all(|c| c.is_finite()).then_some(buckets)
}

/// The `q` quantile of what a histogram counted between two samples, as
/// the upper bound of the bucket it falls in, in milliseconds (infinite
/// past the last bound); `None` when nothing was counted.
pub fn bucket_quantile_ms(before: &Buckets, after: &Buckets, q: f64) -> Option<f64> {
    let total = after[LATENCY_BUCKETS_S.len()] - before[LATENCY_BUCKETS_S.len()];
    if total <= 0.0 {
        return None;
    }
    let bound = LATENCY_BUCKETS_S
        .iter()
        .enumerate()
        .find(|&(i, _)| after[i] - before[i] >= q * total)
        .map_or(f64::INFINITY, |(_, le)| *le);
    Some(bound * 1e3)
}

/// Reads one server's `/metrics`.
#[derive(Debug)]
pub struct Scraper {
    agent: ureq::Agent,
    url: String,
    token: Option<String>,
}

impl Scraper {
    /// `server` as the load test was given it (`http://`, `ws://` or a bare
    /// `host:port`); the metrics are read from the same host and port.
    pub fn new(server: &str, token: Option<String>) -> Self {
        let base = server.trim_end_matches('/');
        let base = if let Some(rest) = base.strip_prefix("ws://") {
            format!("http://{rest}")
        } else if let Some(rest) = base.strip_prefix("wss://") {
            format!("https://{rest}")
        } else if base.contains("://") {
            base.to_owned()
        } else {
            format!("http://{base}")
        };
        let agent = ureq::Agent::config_builder()
            // A server too busy to answer in time is a gap in the plot,
            // not a stalled run.
            .timeout_global(Some(Duration::from_millis(800)))
            .build()
            .into();
        Self {
            agent,
            url: format!("{base}/metrics"),
            token,
        }
    }

    /// One sample, or why there is none.
    pub fn sample(&self) -> Result<ServerSample, String> {
        let mut request = self.agent.get(&self.url);
        if let Some(t) = &self.token {
            request = request.header("Authorization", format!("Bearer {t}"));
        }
        let mut response = request.call().map_err(|e| format!("{}: {e}", self.url))?;
        let text = response
            .body_mut()
            .with_config()
            .limit(4 << 20)
            .read_to_string()
            .map_err(|e| format!("{}: {e}", self.url))?;
        Ok(ServerSample::parse(&text))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_figures_are_read_and_the_rest_skipped() {
        let text = "# HELP farfield_queue_depth x\n# TYPE farfield_queue_depth gauge\n\
                    farfield_queue_depth 7\nfarfield_page_cache_hits_total 1e3\n\
                    farfield_limit_hits_total{limit=\"idle\"} 4\nprocess_resident_memory_bytes 123456\n\
                    garbage line\nfarfield_disk_reads_total nope\n";
        let s = ServerSample::parse(text);
        assert_eq!(s.queue_depth, Some(7.0));
        assert_eq!(s.cache_hits, Some(1000.0));
        assert_eq!(s.resident_bytes, Some(123456.0));
        assert_eq!(s.disk_reads, None, "not a number");
        assert_eq!(s.cache_misses, None, "absent");
        assert_eq!(s.request_latency, None, "no histogram");
    }

    /// The histogram as the server renders it, with `counts` cumulative.
    fn exposition(counts: [u64; 17]) -> String {
        let mut text = String::new();
        for (le, c) in LATENCY_BUCKETS_S.iter().zip(&counts) {
            text += &format!("{REQUEST_LATENCY}{{le=\"{le}\"}} {c}\n");
        }
        text + &format!("{REQUEST_LATENCY}{{le=\"+Inf\"}} {}\n", counts[16])
    }

    #[test]
    fn the_servers_latency_quantiles_come_from_its_buckets_between_two_samples() {
        // Buckets end at 0.1, 0.25, 0.5, 1, 2.5, 5, 10, 25 ms, ...
        let before = ServerSample::parse(&exposition([0; 17]))
            .request_latency
            .unwrap();
        // 100 requests: 50 within 1 ms, 49 more within 10 ms, 1 over 10 s.
        let mut counts = [0u64; 17];
        for (i, c) in counts.iter_mut().enumerate() {
            *c = match i {
                0..=2 => 0,
                3..=5 => 50,
                6..=15 => 99,
                _ => 100,
            };
        }
        let after = ServerSample::parse(&exposition(counts))
            .request_latency
            .unwrap();
        assert_eq!(bucket_quantile_ms(&before, &after, 0.5), Some(1.0));
        assert_eq!(bucket_quantile_ms(&before, &after, 0.99), Some(10.0));
        assert_eq!(
            bucket_quantile_ms(&before, &after, 1.0),
            Some(f64::INFINITY)
        );
        assert_eq!(
            bucket_quantile_ms(&after, &after, 0.5),
            None,
            "nothing counted"
        );
        // A bucket missing from the text is no histogram at all.
        let partial: String = exposition(counts)
            .lines()
            .skip(1)
            .map(|l| format!("{l}\n"))
            .collect();
        assert_eq!(ServerSample::parse(&partial).request_latency, None);
    }
}
