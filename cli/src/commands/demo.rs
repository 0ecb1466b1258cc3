//! `farfield demo`: the whole system on the built-in scene, in one process.
//!
//! Builds `gen:island` (once; the file is reused on later runs), starts an
//! embedded memory server, with the browser viewer built into it, and
//! prints where to browse the scene; flies a client along a built-in path
//! while pages stream, lets the last view refine, sweeps the splat
//! threshold against the 1-pixel reference (`farfield bench`) and writes
//! the frames, a per-frame CSV, the sweep's report and a summary. Then it
//! keeps serving, and opens the window viewer where there is a display,
//! until the window closes or Ctrl-C (`--exit` ends it once the files are
//! written, as scripts want).

use std::fmt::Write as _;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::Context;
use farfield_builder::generate::DEFAULT_SCENE;
use farfield_builder::import::{Params, load_input};
use farfield_builder::{BuildOptions, build_spheres};
use farfield_store::{SceneFile, write_atomic};

use farfield_client::flythrough::{FlyJob, fly, write_csv};
use farfield_client::path::CameraPath;
use farfield_client::viewer::Viewer;
use farfield_net::SessionOptions;
use farfield_render::{Renderer, SplatStyle};

/// The demo's knobs (all have defaults; the command takes only `--out`).
#[derive(Debug, Clone)]
pub struct DemoJob {
    pub out: PathBuf,
    pub width: u32,
    pub height: u32,
    pub path_seconds: f64,
    pub fps: f64,
}

impl Default for DemoJob {
    fn default() -> Self {
        Self {
            out: PathBuf::from("farfield-demo"),
            width: 640,
            height: 360,
            path_seconds: 6.0,
            fps: 10.0,
        }
    }
}

/// What the demo did, also written to `summary.txt`.
#[derive(Debug, Clone)]
pub struct DemoSummary {
    pub scene: PathBuf,
    pub built: bool,
    pub frames: usize,
    pub time_to_first_image_ms: f64,
    pub time_to_refined_ms: Option<f64>,
    pub bytes_received: u64,
    pub text: String,
}

/// The built-in scene's file in `dir`, built if it is missing or unreadable.
pub fn ensure_scene(dir: &Path) -> anyhow::Result<(PathBuf, bool)> {
    let path = dir.join("island.ff");
    if SceneFile::open(&path).is_ok_and(|f| f.corrupt_pages().is_empty()) {
        return Ok((path, false));
    }
    let scene = load_input(DEFAULT_SCENE, &Params::default())?;
    let (file, _) = build_spheres(scene, &BuildOptions::default())?;
    write_atomic(&path, &file)?;
    Ok((path, true))
}

/// Runs the demo against a server of its own on a free loopback port,
/// stopped once the files are written.
pub fn run(job: &DemoJob) -> anyhow::Result<DemoSummary> {
    let demo = Served::start(job, SocketAddr::from(([127, 0, 0, 1], 0)))?;
    let summary = demo.run(job)?;
    demo.stop()?;
    Ok(summary)
}

/// The demo's scene, built, and served by a memory server in this process.
struct Served {
    runtime: tokio::runtime::Runtime,
    server: farfield_memory_server::RunningServer,
    scene: PathBuf,
    built: bool,
}

impl Served {
    /// Builds the scene into `job.out` if needed and serves that folder on
    /// `listen`; on a port already taken, on a free one instead.
    fn start(job: &DemoJob, listen: SocketAddr) -> anyhow::Result<Self> {
        std::fs::create_dir_all(&job.out)
            .with_context(|| format!("creating {}", job.out.display()))?;
        let (scene, built) = ensure_scene(&job.out)?;
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .enable_all()
            .build()?;
        let config = |listen| farfield_memory_server::ServerConfig {
            cache_bytes: 64 << 20,
            ..farfield_memory_server::ServerConfig::new(&job.out, listen)
        };
        let server = match runtime.block_on(farfield_memory_server::start(config(listen))) {
            Ok(server) => server,
            Err(e) if listen.port() != 0 => {
                eprintln!("{listen} is not free ({e}); serving on another port");
                let free = SocketAddr::new(listen.ip(), 0);
                runtime
                    .block_on(farfield_memory_server::start(config(free)))
                    .context("starting the embedded server")?
            }
            Err(e) => return Err(e).context("starting the embedded server"),
        };
        Ok(Self {
            runtime,
            server,
            scene,
            built,
        })
    }

    /// The server's address, `http://IP:PORT`.
    fn url(&self) -> String {
        format!("http://{}", self.server.local_addr())
    }

    /// Where a browser shows the scene.
    fn browser_url(&self) -> String {
        format!("{}/view/island", self.url())
    }

    /// Runs until Ctrl-C (SIGINT) or SIGTERM.
    fn wait_for_interrupt(&self) -> anyhow::Result<()> {
        self.runtime.block_on(async {
            #[cfg(unix)]
            {
                use tokio::signal::unix::{SignalKind, signal};
                let mut term = signal(SignalKind::terminate())?;
                tokio::select! {
                    r = tokio::signal::ctrl_c() => r,
                    _ = term.recv() => Ok(()),
                }
            }
            #[cfg(not(unix))]
            tokio::signal::ctrl_c().await
        })?;
        Ok(())
    }

    fn stop(self) -> anyhow::Result<()> {
        self.runtime
            .block_on(self.server.shutdown())
            .context("stopping the embedded server")?;
        Ok(())
    }

    /// The demo's flight, sweep and files, against this server.
    fn run(&self, job: &DemoJob) -> anyhow::Result<DemoSummary> {
        let (scene, built) = (self.scene.clone(), self.built);
        let url = self.url();
        fly_and_measure(job, &url, scene, built)
    }
}

fn fly_and_measure(
    job: &DemoJob,
    url: &str,
    scene: PathBuf,
    built: bool,
) -> anyhow::Result<DemoSummary> {
    let url = url.to_owned();
    let mut renderer = Renderer::new_headless(job.width, job.height)?;
    let started = Instant::now();
    let mut viewer = Viewer::open_remote(&url, "island", SessionOptions::default(), 512 << 20)?;
    let fly_job = FlyJob {
        path: CameraPath::builtin(job.path_seconds),
        fps: job.fps,
        width: job.width,
        height: job.height,
        final_threshold_px: 1.0,
        target_frame_ms: 100.0,
        style: SplatStyle::default(),
        frames_dir: Some(job.out.join("frames")),
        settle: true,
        timeout: Duration::from_secs(300),
        budget: Default::default(),
        known_path: false,
    };
    let (stats, settle) = fly(&mut viewer, &mut renderer, &fly_job, started)?;
    drop(viewer);
    // A small sweep of the splat threshold, streamed, and its report: the
    // trade-off between error and frame time of the built-in scene.
    let sweep = farfield_tools::bench::BenchJob {
        source: farfield_client::render_job::Source::Server {
            url: url.clone(),
            scene: "island".into(),
        },
        path: Some(CameraPath::from_keyframes(&[
            farfield_client::path::Keyframe {
                t: 0.0,
                orbit: Some(farfield_client::path::OrbitKey {
                    azimuth: 30.0,
                    elevation: 25.0,
                    distance: 1.6,
                }),
                eye: None,
                target: None,
                fov: None,
            },
        ])?),
        mode: "spheres".into(),
        param: "threshold".into(),
        values: ["1", "2", "4", "8", "16"].map(String::from).to_vec(),
        fixed: Vec::new(),
        inputs: Vec::new(),
        input_params: Vec::new(),
        width: 320,
        height: 180,
        repeats: 3,
        out: job.out.join("bench"),
        timeout: Duration::from_secs(120),
    };
    farfield_tools::bench::run(&sweep, &mut renderer).context("the demo's sweep")?;
    let report = farfield_tools::bench::report::write_report(
        std::slice::from_ref(&sweep.out),
        &job.out.join("report"),
    )?;
    write_csv(&job.out.join("frames.csv"), &stats)?;
    let first = stats.first().map_or(0.0, |s| s.time_ms);
    let bytes = stats.last().map_or(0, |s| s.bytes_received);
    let mut text = String::new();
    let _ = writeln!(
        text,
        "farfield demo: {} ({})",
        scene.display(),
        if built { "built now" } else { "reused" }
    );
    let _ = writeln!(text, "adapter: {}", renderer.adapter_description());
    let _ = writeln!(
        text,
        "frames: {} at {}x{} ({} along the path, then resting)",
        stats.len(),
        job.width,
        job.height,
        stats.iter().filter(|s| !s.resting).count()
    );
    let _ = writeln!(text, "first image: {first:.1} ms after connecting");
    match settle.time_to_refined_ms {
        Some(ms) => {
            let _ = writeln!(
                text,
                "refined to 1 px at the last view: {ms:.0} ms after connecting"
            );
        }
        None => {
            let _ = writeln!(
                text,
                "not refined: {}",
                settle.error.clone().unwrap_or_default()
            );
        }
    }
    let _ = writeln!(text, "bytes received: {bytes}");
    if let Some(last) = stats.last() {
        let _ = writeln!(
            text,
            "last frame: {} splats at threshold {:.2} px",
            last.nodes_drawn, last.threshold_px
        );
    }
    let _ = writeln!(
        text,
        "error against frame time (threshold 1 to 16 px): {}",
        report.display()
    );
    let _ = writeln!(
        text,
        "files: frames/frame_NNNN.png, frames.csv, bench/ (bench.csv, progress.csv), report/index.html, summary.txt"
    );
    std::fs::write(job.out.join("summary.txt"), &text)?;
    Ok(DemoSummary {
        scene,
        built,
        frames: stats.len(),
        time_to_first_image_ms: first,
        time_to_refined_ms: settle.time_to_refined_ms,
        bytes_received: bytes,
        text,
    })
}

/// How `farfield demo` ends once its files are written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AfterDemo {
    /// Stop at once.
    Exit,
    /// Keep serving until Ctrl-C; open the window viewer too where there
    /// is a display (and `window` is set), and stop when it closes.
    Serve { window: bool },
}

/// `farfield demo`: runs the demo into `out` against a server on `listen`,
/// printing where to browse the scene first and the summary after; then
/// what `after` says (`view` makes the window viewer's job for the
/// server's address, as `farfield view` would).
pub fn print(
    out: PathBuf,
    listen: SocketAddr,
    after: AfterDemo,
    view: impl FnOnce(&str) -> anyhow::Result<super::view::ViewJob>,
) -> anyhow::Result<()> {
    let job = DemoJob {
        out,
        ..Default::default()
    };
    let demo = Served::start(&job, listen)?;
    let browse = demo.browser_url();
    println!(
        "farfield demo: serving {} at {}",
        job.out.display(),
        demo.url()
    );
    println!("browse the island: {browse}");
    let summary = demo.run(&job)?;
    print!("{}", summary.text);
    let AfterDemo::Serve { window } = after else {
        return demo.stop();
    };
    if window && has_display() {
        println!("browse the island: {browse} (the window viewer is open; close it to stop)");
        let shown = view(&demo.url()).and_then(super::view::run);
        demo.stop()?;
        return shown;
    }
    println!("browse the island: {browse} (Ctrl-C to stop)");
    demo.wait_for_interrupt()?;
    demo.stop()
}

/// Whether a window can open: an X11 or Wayland display is named.
fn has_display() -> bool {
    ["DISPLAY", "WAYLAND_DISPLAY"]
        .iter()
        .any(|v| std::env::var_os(v).is_some_and(|d| !d.is_empty()))
}
