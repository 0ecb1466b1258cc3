//! `farfield loadtest`: many real clients against one memory server.
//!
//! N headless clients in this process ([`client`]: traversal, requests,
//! acknowledgements and residency as the viewers do them, no GPU), each on
//! its own staggered path, started over a ramp. Once a second the run
//! cuts a row: pages and bytes, request-to-arrival latency quantiles,
//! errors and reconnects, and a sample of the server's `/metrics` (memory,
//! cache hit rate, queue depth, connections). At the end it writes
//! `seconds.csv`, `clients.csv`, `loadtest.json` (the summary), plots and
//! `index.html` ([`output`]).
//!
//! With `--session NAME` the clients are a demo session: client 0 presents
//! (flies its path, showing each view), the others follow (draw the
//! presenter's view as it comes); the followers' lag behind the presenter
//! is measured here, on one clock.
//!
//! The load is bounded: at most [`MAX_CLIENTS`] clients for at most
//! [`MAX_DURATION`], and every connection goes to the server given (its
//! stream and its `/metrics`), nowhere else.

pub mod client;
pub mod output;
pub mod recorder;
pub mod scrape;
pub mod static_files;

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicI64, Ordering};
use std::time::{Duration, Instant};

use anyhow::Context;
use farfield_client::path::CameraPath;
use serde::{Deserialize, Serialize};

use client::{ClientRow, Shared};
use recorder::Recorder;
use scrape::{Scraper, ServerSample};

/// Most clients one run may start.
pub const MAX_CLIENTS: usize = 4096;
/// Longest run.
pub const MAX_DURATION: Duration = Duration::from_secs(3600);

/// What to run.
#[derive(Debug, Clone)]
pub struct LoadJob {
    /// The server (`http://host:port`, `ws://...`, or `host:port`).
    pub server: String,
    pub scene: String,
    pub clients: usize,
    pub duration: Duration,
    /// Clients start evenly over this long.
    pub ramp: Duration,
    /// A camera path file; the demo's built-in flight when `None`.
    pub path: Option<PathBuf>,
    pub out: PathBuf,
    pub width: u32,
    pub height: u32,
    pub threshold_px: f64,
    /// Traversals a second, per client.
    pub fps: f64,
    /// Each client's resident pages, in bytes.
    pub client_cache_bytes: usize,
    pub token: Option<String>,
    /// A demo session: client 0 presents, the others follow.
    pub session: Option<String>,
    /// Let the server push pages nobody asked for yet when a client's
    /// queue is empty (the hello's `allow_push`).
    pub push: bool,
    /// `server` is a static file server holding `farfield-server
    /// export`'s files: pages come by HTTP GET ([`static_files`]).
    pub static_files: bool,
    /// Each client's bound on pages asked for and not yet arrived
    /// ([`farfield_net::SessionOptions::max_outstanding`]).
    pub max_outstanding: Option<usize>,
}

impl LoadJob {
    /// The job's defaults for `server`, `scene`, `clients` and `duration`.
    pub fn new(
        server: &str,
        scene: &str,
        clients: usize,
        duration: Duration,
        out: PathBuf,
    ) -> Self {
        Self {
            server: server.to_owned(),
            scene: scene.to_owned(),
            clients,
            duration,
            ramp: Duration::ZERO,
            path: None,
            out,
            width: 800,
            height: 600,
            threshold_px: 1.0,
            fps: 10.0,
            client_cache_bytes: 64 << 20,
            token: None,
            session: None,
            push: false,
            static_files: false,
            max_outstanding: None,
        }
    }

    /// Refuses a job out of bounds or nonsensical.
    pub fn validate(&self) -> anyhow::Result<()> {
        anyhow::ensure!(
            (1..=MAX_CLIENTS).contains(&self.clients),
            "--clients must be between 1 and {MAX_CLIENTS}, not {}",
            self.clients
        );
        anyhow::ensure!(
            !self.duration.is_zero() && self.duration <= MAX_DURATION,
            "--duration must be above 0 and at most {} s",
            MAX_DURATION.as_secs()
        );
        anyhow::ensure!(
            self.ramp <= self.duration,
            "--ramp ({:.1} s) must not be longer than --duration ({:.1} s)",
            self.ramp.as_secs_f64(),
            self.duration.as_secs_f64()
        );
        anyhow::ensure!(
            self.fps.is_finite() && self.fps > 0.0 && self.fps <= 240.0,
            "--fps must be above 0 and at most 240"
        );
        anyhow::ensure!(
            self.threshold_px.is_finite() && self.threshold_px > 0.0,
            "--threshold must be a number above 0"
        );
        anyhow::ensure!(self.width > 0 && self.height > 0, "--size must not be 0");
        anyhow::ensure!(!self.scene.is_empty(), "--scene must not be empty");
        anyhow::ensure!(
            !self.static_files || (self.session.is_none() && !self.push),
            "--static: a file server has no demo sessions and pushes nothing"
        );
        if let Some(name) = &self.session {
            anyhow::ensure!(
                farfield_memory_server::demo::valid_name(name),
                "--session: a session name is 1 to {} letters, digits, '-', '_' or '.'",
                farfield_memory_server::demo::MAX_NAME_BYTES
            );
            anyhow::ensure!(
                self.clients >= 2,
                "--session needs at least 2 clients (a presenter and a follower)"
            );
        }
        Ok(())
    }

    fn frame_interval(&self) -> Duration {
        Duration::from_secs_f64(1.0 / self.fps)
    }

    /// How long a client holds its start camera at most before it flies.
    fn hold(&self) -> Duration {
        (self.duration / 4).min(Duration::from_secs(10))
    }
}

/// One second of the run, a row of `seconds.csv`.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct SecondRow {
    /// Seconds since the run began, at the end of this second.
    pub t_s: f64,
    pub clients_connected: i64,
    pub pages: u64,
    pub bytes: u64,
    pub pages_per_s: f64,
    pub mb_per_s: f64,
    pub latency_p50_ms: Option<f64>,
    pub latency_p95_ms: Option<f64>,
    pub latency_p99_ms: Option<f64>,
    pub latency_max_ms: Option<f64>,
    pub errors: u64,
    pub reconnects: u64,
    /// Demo followers' lag behind the presenter's view.
    pub follower_lag_p95_ms: Option<f64>,
    pub server_resident_mib: Option<f64>,
    /// Of this second's page lookups, the share the cache answered.
    pub server_cache_hit_rate: Option<f64>,
    pub server_disk_reads: Option<f64>,
    pub server_queue_depth: Option<f64>,
    pub server_connections: Option<f64>,
}

/// The summary, `loadtest.json`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct LoadReport {
    pub server: String,
    pub scene: String,
    pub clients: usize,
    pub duration_s: f64,
    pub ramp_s: f64,
    pub path: String,
    pub seconds: f64,
    pub pages: u64,
    pub bytes: u64,
    pub pages_per_s: f64,
    pub mb_per_s: f64,
    pub latency_p50_ms: Option<f64>,
    pub latency_p95_ms: Option<f64>,
    pub latency_p99_ms: Option<f64>,
    pub latency_max_ms: Option<f64>,
    pub latency_samples: u64,
    pub errors: u64,
    pub reconnects: u64,
    pub session: Option<String>,
    /// Whether the clients allowed the server to push.
    #[serde(default)]
    pub push: bool,
    /// Whether the server was a static file server (`--static`).
    #[serde(default)]
    pub static_files: bool,
    /// Each client's bound on outstanding pages (`--max-outstanding`).
    #[serde(default)]
    pub max_outstanding: Option<usize>,
    pub follower_lag_p50_ms: Option<f64>,
    pub follower_lag_p95_ms: Option<f64>,
    pub follower_lag_max_ms: Option<f64>,
    pub follower_views: u64,
    /// The lag of a probe follower alone on its own thread, which never
    /// traverses: the server's and the socket's share of the lag, without
    /// the load clients' contention for this machine's cores.
    #[serde(default)]
    pub probe_lag_p50_ms: Option<f64>,
    #[serde(default)]
    pub probe_lag_p95_ms: Option<f64>,
    #[serde(default)]
    pub probe_lag_max_ms: Option<f64>,
    /// Pages the server read from disk per page it sent, over the run.
    pub server_disk_reads_per_page_served: Option<f64>,
    pub clients_with_first_image: usize,
    pub first_image_p50_ms: Option<f64>,
    pub first_image_max_ms: Option<f64>,
    pub clients_refined: usize,
    pub refined_p50_ms: Option<f64>,
    pub refined_max_ms: Option<f64>,
    /// The server's own request latency over the run (a page wanted to
    /// its frame sent, from its `/metrics` histogram): the upper bound of
    /// the bucket the quantile falls in; infinite (null) past 10 s.
    #[serde(default)]
    pub server_latency_p50_ms: Option<f64>,
    #[serde(default)]
    pub server_latency_p99_ms: Option<f64>,
    pub server_resident_min_mib: Option<f64>,
    pub server_resident_max_mib: Option<f64>,
    pub server_cache_hit_rate: Option<f64>,
    pub server_disk_reads: Option<f64>,
    /// Why the server's metrics were not sampled, when they were not.
    pub metrics_error: Option<String>,
    pub cpu: String,
    pub cores: usize,
}

/// Runs the load and writes every output into `job.out`.
pub fn run(job: &LoadJob) -> anyhow::Result<LoadReport> {
    job.validate()?;
    std::fs::create_dir_all(&job.out).with_context(|| format!("creating {}", job.out.display()))?;
    let path = match &job.path {
        Some(p) => CameraPath::load(p)?,
        None => CameraPath::builtin(20.0),
    };
    // The clients' sockets, on a thread of their own: a page comes off
    // its socket (and is timed) when it arrives, not when its client is
    // done traversing.
    let io = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .thread_name("farfield-load-io")
        .enable_all()
        .build()
        .context("starting the load test's socket thread")?;
    let shared = Arc::new(Shared {
        io: io.handle().clone(),
        job: job.clone(),
        path,
        recorder: Recorder::default(),
        stop: AtomicBool::new(false),
        connected: AtomicI64::new(0),
        started: Instant::now(),
        shown: std::sync::Mutex::new(std::collections::VecDeque::new()),
    });
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let workers = start_clients(&shared, threads)?;
    let probe = match job.session {
        Some(_) => Some(start_probe(&shared)?),
        None => None,
    };
    let watched = watch(&shared);
    shared.stop.store(true, Ordering::Relaxed);
    if let Some(probe) = probe {
        probe
            .join()
            .map_err(|_| anyhow::anyhow!("the lag probe panicked"))??;
    }
    let mut clients = Vec::with_capacity(job.clients);
    for w in workers {
        clients.extend(
            w.join()
                .map_err(|_| anyhow::anyhow!("a load thread panicked"))??,
        );
    }
    io.shutdown_timeout(Duration::from_secs(1));
    clients.sort_by_key(|c| c.client);
    let report = summarize(job, &shared, &watched, &clients);
    output::write_all(&job.out, &report, &watched.seconds, &clients)?;
    Ok(report)
}

/// Starts the clients on `threads` threads, each a current-thread runtime
/// whose clients are local tasks (a client's viewer is not `Send`: the
/// transport seam also serves a browser).
fn start_clients(
    shared: &Arc<Shared>,
    threads: usize,
) -> anyhow::Result<Vec<std::thread::JoinHandle<anyhow::Result<Vec<ClientRow>>>>> {
    let clients = shared.job.clients;
    let threads = threads.clamp(1, clients);
    (0..threads)
        .map(|t| {
            let shared = shared.clone();
            std::thread::Builder::new()
                .name(format!("farfield-load-{t}"))
                .spawn(move || {
                    let rt = tokio::runtime::Builder::new_current_thread()
                        .enable_all()
                        .build()?;
                    let local = tokio::task::LocalSet::new();
                    let tasks: Vec<_> = (t..clients)
                        .step_by(threads)
                        .map(|i| local.spawn_local(client::run(i, clients, shared.clone())))
                        .collect();
                    local.block_on(&rt, async move {
                        let mut rows = Vec::with_capacity(tasks.len());
                        for task in tasks {
                            rows.push(task.await?);
                        }
                        Ok(rows)
                    })
                })
                .context("starting a load thread")
        })
        .collect()
}

/// Starts the demo session's lag probe on a thread of its own.
fn start_probe(
    shared: &Arc<Shared>,
) -> anyhow::Result<std::thread::JoinHandle<anyhow::Result<()>>> {
    let shared = shared.clone();
    std::thread::Builder::new()
        .name("farfield-load-probe".into())
        .spawn(move || {
            let rt = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()?;
            let local = tokio::task::LocalSet::new();
            local.block_on(&rt, client::probe(shared));
            Ok(())
        })
        .context("starting the lag probe")
}

/// Cuts a row every second until the run's duration is over; samples the
/// server's metrics for each. Returns the rows, why the metrics could not
/// be read when they never could, and the disk reads per page served.
fn watch(shared: &Shared) -> Watched {
    let job = &shared.job;
    let scraper = Scraper::new(&job.server, job.token.clone());
    let mut last = scraper.sample().ok();
    let first = last;
    let (mut rows, mut error, mut any) = (Vec::new(), None, last.is_some());
    let seconds = job.duration.as_secs_f64().ceil() as u64;
    for s in 1..=seconds {
        let end = (s as f64).min(job.duration.as_secs_f64());
        let due = shared.started + Duration::from_secs_f64(end);
        std::thread::sleep(due.saturating_duration_since(Instant::now()));
        let interval = shared.recorder.cut();
        let span = (end - rows.last().map_or(0.0, |r: &SecondRow| r.t_s)).max(1e-3);
        let sample = scraper.sample();
        let now = match sample {
            Ok(s) => {
                any = true;
                Some(s)
            }
            Err(e) => {
                error = Some(e);
                None
            }
        };
        rows.push(second_row(end, span, shared, &interval, now, last));
        if now.is_some() {
            last = now;
        }
    }
    let reads_per_page = (|| {
        let (a, b) = (first?, last?);
        let pages = b.pages_served? - a.pages_served?;
        let reads = b.disk_reads? - a.disk_reads?;
        (pages > 0.0).then(|| reads / pages)
    })();
    let server_latency = (|| Some((first?.request_latency?, last?.request_latency?)))();
    Watched {
        seconds: rows,
        metrics_error: if any { None } else { error },
        reads_per_page,
        server_latency,
    }
}

/// What watching the run gave.
struct Watched {
    seconds: Vec<SecondRow>,
    metrics_error: Option<String>,
    reads_per_page: Option<f64>,
    /// The server's request latency histogram at the start and the end.
    server_latency: Option<(scrape::Buckets, scrape::Buckets)>,
}

fn second_row(
    t_s: f64,
    span: f64,
    shared: &Shared,
    i: &recorder::Interval,
    now: Option<ServerSample>,
    before: Option<ServerSample>,
) -> SecondRow {
    let delta = |f: fn(&ServerSample) -> Option<f64>| -> Option<f64> {
        Some(f(now.as_ref()?)? - f(before.as_ref()?)?)
    };
    let hits = delta(|s| s.cache_hits);
    let misses = delta(|s| s.cache_misses);
    let hit_rate = match (hits, misses) {
        (Some(h), Some(m)) if h + m > 0.0 => Some(h / (h + m)),
        _ => None,
    };
    let gauge = |f: fn(&ServerSample) -> Option<f64>| now.as_ref().and_then(f);
    SecondRow {
        t_s,
        clients_connected: shared.connected.load(Ordering::Relaxed),
        pages: i.pages,
        bytes: i.bytes,
        pages_per_s: i.pages as f64 / span,
        mb_per_s: i.bytes as f64 / span / 1e6,
        latency_p50_ms: i.latency_ms(0.5),
        latency_p95_ms: i.latency_ms(0.95),
        latency_p99_ms: i.latency_ms(0.99),
        latency_max_ms: i.latency_max_ms(),
        errors: i.errors,
        reconnects: i.reconnects,
        follower_lag_p95_ms: i.lag_ms(0.95),
        server_resident_mib: gauge(|s| s.resident_bytes).map(|b| b / (1 << 20) as f64),
        server_cache_hit_rate: hit_rate,
        server_disk_reads: delta(|s| s.disk_reads),
        server_queue_depth: gauge(|s| s.queue_depth),
        server_connections: gauge(|s| s.connected_clients),
    }
}

fn quantile(values: &mut [f64], q: f64) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    values.sort_by(f64::total_cmp);
    let i = ((values.len() - 1) as f64 * q).round() as usize;
    values.get(i).copied()
}

fn summarize(
    job: &LoadJob,
    shared: &Shared,
    watched: &Watched,
    clients: &[ClientRow],
) -> LoadReport {
    let seconds = &watched.seconds;
    let total = shared.recorder.total();
    let run_s = seconds.last().map_or(0.0, |r| r.t_s).max(1e-3);
    let mut first: Vec<f64> = clients.iter().filter_map(|c| c.first_image_ms).collect();
    let mut refined: Vec<f64> = clients.iter().filter_map(|c| c.refined_ms).collect();
    let rss: Vec<f64> = seconds
        .iter()
        .filter_map(|r| r.server_resident_mib)
        .collect();
    let (hits_reads, disk): (Vec<f64>, Vec<f64>) = (
        seconds
            .iter()
            .filter_map(|r| r.server_cache_hit_rate)
            .collect(),
        seconds.iter().filter_map(|r| r.server_disk_reads).collect(),
    );
    LoadReport {
        server: job.server.clone(),
        scene: job.scene.clone(),
        clients: job.clients,
        duration_s: job.duration.as_secs_f64(),
        ramp_s: job.ramp.as_secs_f64(),
        path: job
            .path
            .as_ref()
            .map_or("built-in".into(), |p| p.display().to_string()),
        seconds: run_s,
        pages: total.pages,
        bytes: total.bytes,
        pages_per_s: total.pages as f64 / run_s,
        mb_per_s: total.bytes as f64 / run_s / 1e6,
        latency_p50_ms: total.latency_ms(0.5),
        latency_p95_ms: total.latency_ms(0.95),
        latency_p99_ms: total.latency_ms(0.99),
        latency_max_ms: total.latency_max_ms(),
        latency_samples: total.latency_us.len(),
        errors: total.errors,
        reconnects: total.reconnects,
        session: job.session.clone(),
        push: job.push,
        static_files: job.static_files,
        max_outstanding: job.max_outstanding,
        follower_lag_p50_ms: total.lag_ms(0.5),
        follower_lag_p95_ms: total.lag_ms(0.95),
        follower_lag_max_ms: (!total.lag_us.is_empty()).then(|| total.lag_us.max() as f64 / 1e3),
        follower_views: total.lag_us.len(),
        probe_lag_p50_ms: total.probe_lag_ms(0.5),
        probe_lag_p95_ms: total.probe_lag_ms(0.95),
        probe_lag_max_ms: (!total.probe_lag_us.is_empty())
            .then(|| total.probe_lag_us.max() as f64 / 1e3),
        server_disk_reads_per_page_served: watched.reads_per_page,
        clients_with_first_image: first.len(),
        first_image_p50_ms: quantile(&mut first, 0.5),
        first_image_max_ms: first.iter().copied().reduce(f64::max),
        clients_refined: refined.len(),
        refined_p50_ms: quantile(&mut refined, 0.5),
        refined_max_ms: refined.iter().copied().reduce(f64::max),
        server_latency_p50_ms: watched
            .server_latency
            .and_then(|(a, b)| scrape::bucket_quantile_ms(&a, &b, 0.5)),
        server_latency_p99_ms: watched
            .server_latency
            .and_then(|(a, b)| scrape::bucket_quantile_ms(&a, &b, 0.99)),
        server_resident_min_mib: rss.iter().copied().reduce(f64::min),
        server_resident_max_mib: rss.iter().copied().reduce(f64::max),
        // The run's mean of the seconds' rates.
        server_cache_hit_rate: (!hits_reads.is_empty())
            .then(|| hits_reads.iter().sum::<f64>() / hits_reads.len() as f64),
        server_disk_reads: (!disk.is_empty()).then(|| disk.iter().sum()),
        metrics_error: watched.metrics_error.clone(),
        cpu: crate::bench::report::cpu_model(),
        cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
    }
}

/// The summary as text.
pub fn describe(r: &LoadReport) -> String {
    let ms = |v: Option<f64>| v.map_or("-".into(), |v| format!("{v:.1}"));
    format!(
        "{} clients on {} ({}) for {:.0} s: {} pages, {:.0} pages/s, {:.2} MB/s\n\
         request latency ms: p50 {}, p95 {}, p99 {}, max {} ({} pages)\n\
         the server's own (wanted to sent): p50 at most {} ms, p99 at most {} ms\n\
         errors {}, reconnects {}\n\
         first image: {} of {} clients, p50 {} ms, max {} ms; refined: {} clients, p50 {} ms\n\
         server: resident {}..{} MiB, cache hit rate {}, disk reads {} ({} a page served){}\n{}",
        r.clients,
        r.server,
        r.scene,
        r.seconds,
        r.pages,
        r.pages_per_s,
        r.mb_per_s,
        ms(r.latency_p50_ms),
        ms(r.latency_p95_ms),
        ms(r.latency_p99_ms),
        ms(r.latency_max_ms),
        r.latency_samples,
        ms(r.server_latency_p50_ms),
        ms(r.server_latency_p99_ms),
        r.errors,
        r.reconnects,
        r.clients_with_first_image,
        r.clients,
        ms(r.first_image_p50_ms),
        ms(r.first_image_max_ms),
        r.clients_refined,
        ms(r.refined_p50_ms),
        ms(r.server_resident_min_mib),
        ms(r.server_resident_max_mib),
        r.server_cache_hit_rate
            .map_or("-".into(), |h| format!("{:.1} %", h * 100.0)),
        r.server_disk_reads
            .map_or("-".into(), |d| format!("{d:.0}")),
        r.server_disk_reads_per_page_served
            .map_or("-".into(), |d| format!("{d:.3}")),
        r.metrics_error
            .as_ref()
            .map_or(String::new(), |e| format!(" (metrics not sampled: {e})")),
        r.session.as_ref().map_or(String::new(), |s| format!(
            "demo session {s}: 1 presenter, {} followers; follower lag ms p50 {}, p95 {}, max {} ({} views); \
             probe follower's lag ms p50 {}, p95 {}, max {}\n",
            r.clients - 1,
            ms(r.follower_lag_p50_ms),
            ms(r.follower_lag_p95_ms),
            ms(r.follower_lag_max_ms),
            r.follower_views,
            ms(r.probe_lag_p50_ms),
            ms(r.probe_lag_p95_ms),
            ms(r.probe_lag_max_ms),
        )),
    )
}
