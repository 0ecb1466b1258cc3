//! Sampling a memory server's `/metrics` (Prometheus text) during a load
//! test: its memory, cache, queues and connections over the run.

use std::collections::HashMap;
use std::time::Duration;

use serde::Serialize;

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
        }
    }
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
    }
}
