//! `farfield bench-stream`: the memory server's figures on loopback, all
//! taken in one process and one run (these machines are noisy: compare the
//! numbers of one run with each other, not across runs).
//!
//! - time to first image: connect, receive header and page 0, traverse and
//!   draw one frame, with the renderer already initialised (median of
//!   repeats);
//! - overfetch once refined: one full render's bytes received over the
//!   bytes of the pages its final cut touched;
//! - page throughput with 1 and with N clients, each asking for every page
//!   of the scene over and over with a window of in-flight bytes, next to a
//!   plain loopback TCP stream measured the same way;
//! - the process's resident memory sampled while the clients stream, with a
//!   page cache smaller than the scene, to show it stays flat.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use anyhow::Context;
use farfield_client::camera_spec::CameraSpec;
use farfield_client::frame_loop::{FrameState, Until, draw_frame};
use farfield_client::render_job::{RenderJob, Source, run};
use farfield_client::viewer::Viewer;
use farfield_net::queue::QueueTransport;
use farfield_net::websocket::drive;
use farfield_net::{Session, SessionEvent, SessionOptions, stream_url};
use farfield_protocol::messages::PageWish;
use farfield_render::{Kernel, Renderer, SplatStyle};
use serde::Serialize;
use tokio::io::{AsyncReadExt, AsyncWriteExt};

use crate::meters::memory::current_rss_bytes;

/// Settings of one benchmark run.
#[derive(Debug, Clone)]
pub struct BenchStreamJob {
    pub scene: PathBuf,
    pub clients: Vec<usize>,
    pub seconds: f64,
    pub cache_bytes: u64,
    pub repeats: usize,
    pub width: u32,
    pub height: u32,
}

/// Throughput of one client count.
#[derive(Debug, Clone, Serialize)]
pub struct Throughput {
    pub clients: usize,
    pub seconds: f64,
    pub pages: u64,
    pub bytes: u64,
    pub pages_per_s: f64,
    pub mb_per_s: f64,
    pub rss_min_bytes: Option<u64>,
    pub rss_max_bytes: Option<u64>,
}

/// Everything measured.
#[derive(Debug, Clone, Serialize)]
pub struct BenchStreamReport {
    pub scene: PathBuf,
    pub scene_bytes: u64,
    pub cache_bytes: u64,
    pub adapter: String,
    pub time_to_first_image_ms: Vec<f64>,
    pub time_to_first_image_median_ms: f64,
    /// Bytes that arrived before the first image: the header and every
    /// page received by then (the root directory page and page 0, and any
    /// page pushed meanwhile), median of the repeats.
    pub bytes_to_first_image: u64,
    pub overfetch_ratio: Option<f64>,
    pub refined_ms: Option<f64>,
    pub tcp_loopback_mb_per_s: f64,
    pub throughput: Vec<Throughput>,
}

pub fn run_bench(job: &BenchStreamJob) -> anyhow::Result<BenchStreamReport> {
    let scene_bytes = std::fs::metadata(&job.scene)
        .with_context(|| format!("{}", job.scene.display()))?
        .len();
    let name = job
        .scene
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("scene")
        .to_owned();
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()?;
    let server = rt.block_on(farfield_memory_server::start(
        farfield_memory_server::ServerConfig {
            cache_bytes: job.cache_bytes,
            ..farfield_memory_server::ServerConfig::files(
                vec![(name.clone(), job.scene.clone())],
                SocketAddr::from(([127, 0, 0, 1], 0)),
            )
        },
    ))?;
    let addr = server.local_addr();
    let url = format!("http://{addr}");
    let mut renderer = Renderer::new_headless(job.width, job.height)?;
    let camera = CameraSpec::Orbit {
        azimuth_deg: 30.0,
        elevation_deg: 25.0,
        distance: 2.5,
    };

    let (mut ttfi, mut first_bytes) = (Vec::new(), Vec::new());
    for _ in 0..job.repeats.max(1) {
        let (ms, bytes) = first_image(&url, &name, &mut renderer, camera, job.width, job.height)?;
        ttfi.push(ms);
        first_bytes.push(bytes);
    }
    first_bytes.sort_unstable();
    let mut sorted = ttfi.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];

    let render_job = RenderJob {
        source: Source::Server {
            url: url.clone(),
            scene: name.clone(),
        },
        camera,
        width: job.width,
        height: job.height,
        out: None,
        until: Until::Refined,
        threshold_px: 1.0,
        kernel: Kernel::Square,
        edl: None,
        color_by: Default::default(),
        clip: None,
        coverage: Default::default(),
        session: SessionOptions::default(),
        cache_bytes: usize::MAX,
        timeout: Duration::from_secs(600),
        budget: Default::default(),
    };
    let refined = run(&render_job, &mut renderer, false)?;

    let tcp = rt.block_on(tcp_loopback_mb_per_s(job.seconds.min(3.0)))?;
    let pages = farfield_store::SceneFile::open(&job.scene)?
        .header
        .page_count;
    let mut throughput = Vec::new();
    for &clients in &job.clients {
        throughput.push(load(&rt, &url, &name, pages, clients, job.seconds)?);
    }
    let _ = rt.block_on(server.shutdown());
    Ok(BenchStreamReport {
        scene: job.scene.clone(),
        scene_bytes,
        cache_bytes: job.cache_bytes,
        adapter: renderer.adapter_description(),
        time_to_first_image_ms: ttfi,
        time_to_first_image_median_ms: median,
        bytes_to_first_image: first_bytes[first_bytes.len() / 2],
        overfetch_ratio: refined.report.overfetch_ratio,
        refined_ms: refined.report.time_to_refined_ms,
        tcp_loopback_mb_per_s: tcp,
        throughput,
    })
}

/// Connect to first frame drawn, in milliseconds, and the bytes that had
/// arrived by then.
fn first_image(
    url: &str,
    scene: &str,
    renderer: &mut Renderer,
    camera: CameraSpec,
    w: u32,
    h: u32,
) -> anyhow::Result<(f64, u64)> {
    let started = Instant::now();
    let mut viewer = Viewer::open_remote(url, scene, SessionOptions::default(), usize::MAX)?;
    while viewer.hierarchy().is_none_or(|h| !h.is_resident(0)) {
        anyhow::ensure!(
            started.elapsed() < Duration::from_secs(30),
            "{}",
            viewer.with_last_error("no page 0 after 30 s".into())
        );
        viewer.pump(Duration::from_millis(20))?;
    }
    let header = viewer.header().cloned().context("header")?;
    let bytes = header.encode().len() as u64 + viewer.stats().bytes_received;
    let cam = camera.resolve(&header, w, h);
    let (mut cut, mut rgba) = (FrameState::default(), Vec::new());
    draw_frame(
        &mut viewer,
        renderer,
        &cam,
        1.0,
        &SplatStyle::default(),
        &mut cut,
        &mut rgba,
    )?;
    Ok((started.elapsed().as_secs_f64() * 1e3, bytes))
}

/// One TCP stream over loopback, 64 KiB writes, for `seconds`.
async fn tcp_loopback_mb_per_s(seconds: f64) -> anyhow::Result<f64> {
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await?;
    let addr = listener.local_addr()?;
    let deadline = Instant::now() + Duration::from_secs_f64(seconds);
    let writer = tokio::spawn(async move {
        let (mut socket, _) = listener.accept().await?;
        let chunk = vec![7u8; 64 << 10];
        while Instant::now() < deadline {
            socket.write_all(&chunk).await?;
        }
        anyhow::Ok(())
    });
    let mut socket = tokio::net::TcpStream::connect(addr).await?;
    let started = Instant::now();
    let mut buf = vec![0u8; 64 << 10];
    let mut total = 0u64;
    loop {
        let n = socket.read(&mut buf).await?;
        if n == 0 {
            break;
        }
        total += n as u64;
    }
    writer.await??;
    Ok(total as f64 / started.elapsed().as_secs_f64() / 1e6)
}

/// `clients` sessions asking for every page again and again for `seconds`,
/// each the client's own [`Session`] driven as a task on the embedded
/// server's runtime ([`drive`]: socket and session in one task, as a load
/// test runs many); the process's RSS is sampled every 100 ms meanwhile.
fn load(
    runtime: &tokio::runtime::Runtime,
    url: &str,
    scene: &str,
    pages: u32,
    clients: usize,
    seconds: f64,
) -> anyhow::Result<Throughput> {
    let stop = Arc::new(AtomicBool::new(false));
    let (page_count, byte_count) = (Arc::new(AtomicU64::new(0)), Arc::new(AtomicU64::new(0)));
    let url = stream_url(url, scene);
    let mut tasks = Vec::new();
    for _ in 0..clients.max(1) {
        let (url, stop, pc, bc) = (
            url.clone(),
            stop.clone(),
            page_count.clone(),
            byte_count.clone(),
        );
        tasks.push(runtime.spawn(async move { stream_all(url, pages, &stop, &pc, &bc).await }));
    }
    let started = Instant::now();
    let mut rss = Vec::new();
    while started.elapsed().as_secs_f64() < seconds {
        std::thread::sleep(Duration::from_millis(100));
        // Skip the first second: the cache fills then.
        if started.elapsed() > Duration::from_secs(1)
            && let Some(r) = current_rss_bytes()
        {
            rss.push(r);
        }
    }
    let elapsed = started.elapsed().as_secs_f64();
    let (pages_done, bytes_done) = (
        page_count.load(Ordering::Relaxed),
        byte_count.load(Ordering::Relaxed),
    );
    stop.store(true, Ordering::Relaxed);
    for t in tasks {
        runtime.block_on(t)??;
    }
    Ok(Throughput {
        clients,
        seconds: elapsed,
        pages: pages_done,
        bytes: bytes_done,
        pages_per_s: pages_done as f64 / elapsed,
        mb_per_s: bytes_done as f64 / elapsed / 1e6,
        rss_min_bytes: rss.iter().copied().min(),
        rss_max_bytes: rss.iter().copied().max(),
    })
}

/// One session asking for every page, then again once they all came.
async fn stream_all(
    url: String,
    pages: u32,
    stop: &AtomicBool,
    page_count: &AtomicU64,
    byte_count: &AtomicU64,
) -> anyhow::Result<()> {
    let options = SessionOptions {
        max_in_flight_bytes: 8 << 20,
        ..SessionOptions::default()
    };
    let wire = QueueTransport::default();
    let mut session = Session::open(wire.clone(), url, options);
    let all: Vec<PageWish> = (0..pages)
        .map(|page| PageWish {
            page,
            priority: 1.0,
        })
        .collect();
    let (mut received, mut asked) = (0u32, false);
    drive(&mut session, &wire, |session, events| {
        for event in events {
            if let SessionEvent::Page { bytes, .. } = event {
                page_count.fetch_add(1, Ordering::Relaxed);
                byte_count.fetch_add(bytes.len() as u64, Ordering::Relaxed);
                received += 1;
                if received >= pages {
                    // Everything arrived (page 0 came unasked): ask for it all again.
                    (received, asked) = (0, false);
                }
            }
        }
        if !asked && session.is_connected() {
            session.request(&all);
            asked = true;
        }
        !stop.load(Ordering::Relaxed)
    })
    .await?;
    Ok(())
}

/// Prints a report as text.
pub fn describe(r: &BenchStreamReport) -> String {
    let mut s = format!(
        "{} ({} bytes, server page cache {} bytes) on {}\n\
         time to first image: median {:.1} ms of {} (min {:.1}, max {:.1}), {} bytes before it\n\
         refined in {} ms, overfetch {}\n\
         plain TCP loopback, one stream: {:.0} MB/s\n",
        r.scene.display(),
        r.scene_bytes,
        r.cache_bytes,
        r.adapter,
        r.time_to_first_image_median_ms,
        r.time_to_first_image_ms.len(),
        r.time_to_first_image_ms
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min),
        r.time_to_first_image_ms.iter().copied().fold(0.0, f64::max),
        r.bytes_to_first_image,
        r.refined_ms.map_or("-".into(), |m| format!("{m:.0}")),
        r.overfetch_ratio.map_or("-".into(), |o| format!("{o:.3}")),
        r.tcp_loopback_mb_per_s
    );
    for t in &r.throughput {
        s.push_str(&format!(
            "{} client(s): {:.0} pages/s, {:.0} MB/s over {:.1} s; process RSS {}..{} MiB\n",
            t.clients,
            t.pages_per_s,
            t.mb_per_s,
            t.seconds,
            t.rss_min_bytes
                .map_or("-".into(), |b| (b >> 20).to_string()),
            t.rss_max_bytes
                .map_or("-".into(), |b| (b >> 20).to_string())
        ));
    }
    s
}

/// For callers that only have a path.
pub fn default_job(scene: &Path) -> BenchStreamJob {
    BenchStreamJob {
        scene: scene.to_owned(),
        clients: vec![1, 16],
        seconds: 5.0,
        cache_bytes: 16 << 20,
        repeats: 9,
        width: 800,
        height: 600,
    }
}
