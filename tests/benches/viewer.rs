//! The viewer's benchmarks (issue 19), in one run:
//!
//! - time from opening the viewer's URL to its first image, on loopback,
//!   wasm load included (the page's own `performance.now()` at the first
//!   frame that drew something): the first load of a fresh browser, and
//!   the median of reloads;
//! - the size of the wasm and the JS, raw and gzipped;
//! - frame time while orbiting (the scripted flight, default budget) in
//!   headless Chromium on SwiftShader (WebGPU and WebGL2) and in a window
//!   on llvmpipe/lavapipe under Xvfb;
//! - memory over a two-minute flight over a scene larger than the
//!   viewer's page budget: the tab's wasm memory, JS heap and renderer
//!   processes' RSS; the window process's RSS.
//!
//!   cargo bench -p farfield-tests --bench viewer            # everything
//!   FLIGHT_S=30 cargo bench -p farfield-tests --bench viewer # shorter flights
//!   ONLY_MEMORY=1 CACHE_MIB=1 cargo bench ...                # the memory flights only
//!
//! Needs what the browser and window tests need (chromium, chromedriver,
//! Xvfb, and the browser viewer: built into the server, or `web/build`'s)
//! and `../shared/data`.

#[allow(dead_code)] // The tests use more of it than the benchmark.
#[path = "../integration/viewer/webdriver.rs"]
mod webdriver;
#[path = "../integration/xvfb.rs"]
mod xvfb;

use std::io::{BufRead, BufReader};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::Context;
use farfield_builder::import::{Params, load_input};
use farfield_builder::{BuildOptions, build_spheres};
use farfield_memory_server::web_assets::{self, WebViewer};
use serde_json::Value;

use webdriver::Browser;

const SIZE: (u32, u32) = (800, 600);
const CHILD_ENV: &str = "FARFIELD_BENCH_VIEW_ARGS";

fn main() -> anyhow::Result<()> {
    // The window's half: `farfield view` in-process, in a child.
    if let Ok(args) = std::env::var(CHILD_ENV) {
        use clap::Parser;
        let cli = farfield_cli::cli::Cli::try_parse_from(
            std::iter::once("farfield").chain(args.split('\t')),
        )?;
        return farfield_cli::cli::run(cli);
    }
    if std::env::args().any(|a| a == "--list") {
        return Ok(());
    }
    let number = |name: &str, default: f64| {
        std::env::var(name)
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(default)
    };
    let flight_s = number("FLIGHT_S", 120.0);
    // Small enough that the flight's pages do not fit: the LRU works.
    let cache_mib = number("CACHE_MIB", 1.0) as u64;
    let only_memory = std::env::var_os("ONLY_MEMORY").is_some();
    let data =
        farfield_tests::shared_data().context("the viewer benchmarks need ../shared/data")?;
    let viewer = web_assets::find();
    web_assets::ready(viewer.as_ref()).map_err(|why| {
        anyhow::anyhow!(
            "the viewer ({why}; {}): build with the wasm32 target, or run web/build",
            web_assets::not_embedded()
        )
    })?;
    let web = match &viewer {
        Some(WebViewer::Folder(dir)) => Some(dir.clone()),
        _ => None,
    };
    let dir = farfield_tests::scratch("bench-viewer");
    write_scene(
        &dir,
        "bunny",
        &data.join("stanford-bunny.obj").to_string_lossy(),
        &[],
    )?;
    let island = write_scene(
        &dir,
        "island",
        "gen:island",
        &[("size", 512), ("trees", 64)],
    )?;
    let island_mb = std::fs::metadata(&island)?.len() as f64 / 1e6;

    sizes(viewer.as_ref())?;
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()?;
    let server = rt
        .block_on(farfield_memory_server::start(
            farfield_memory_server::ServerConfig {
                web: web.clone(),
                ..farfield_memory_server::ServerConfig::new(&dir, ([127, 0, 0, 1], 0).into())
            },
        ))
        .context("starting the server")?;
    let addr = server.local_addr();

    if !only_memory {
        first_image(addr)?;
        for backend in ["webgpu", "webgl"] {
            let report = browser_flight(addr, "bunny", backend, 20.0, None)?;
            println!("orbit, tab ({backend}, SwiftShader), bunny, 20 s: {report}");
        }
        let window = window_flight(addr, "bunny", 20.0, None)?;
        println!("orbit, window (native wgpu, CPU driver), bunny, 20 s: {window}");
    }
    println!(
        "memory over a {flight_s:.0} s flight, island ({island_mb:.1} MB file), page budget {cache_mib} MiB:"
    );
    let report = browser_flight(addr, "island", "webgpu", flight_s, Some(cache_mib))?;
    println!("  tab flight report: {report}");
    let report = window_flight(addr, "island", flight_s, Some(cache_mib))?;
    println!("  window flight report: {report}");
    rt.block_on(server.shutdown())?;
    Ok(())
}

fn write_scene(
    dir: &Path,
    name: &str,
    input: &str,
    params: &[(&str, i64)],
) -> anyhow::Result<PathBuf> {
    let mut p = Params::default();
    for (k, v) in params {
        p.set(k, *v);
    }
    let scene = load_input(input, &p).with_context(|| format!("importing {input}"))?;
    let (file, _) = build_spheres(scene, &BuildOptions::default())?;
    let path = dir.join(format!("{name}.ff"));
    farfield_store::write_atomic(&path, &file)?;
    Ok(path)
}

fn sizes(viewer: Option<&WebViewer>) -> anyhow::Result<()> {
    let gzipped = |bytes: &[u8]| -> anyhow::Result<usize> {
        use std::io::Write;
        let mut gzip = Command::new("gzip")
            .args(["-9", "-c"])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()?;
        // Fed from a thread: gzip's output fills its pipe long before a
        // wasm's worth of input has gone in.
        let mut input = gzip.stdin.take().context("gzip's input")?;
        let bytes = bytes.to_vec();
        let feeder = std::thread::spawn(move || input.write_all(&bytes));
        let out = gzip.wait_with_output()?.stdout.len();
        feeder
            .join()
            .map_err(|_| anyhow::anyhow!("gzip's feeder panicked"))??;
        Ok(out)
    };
    for file in web_assets::FILES {
        let bytes = match viewer {
            Some(WebViewer::Folder(dir)) => std::fs::read(dir.join(file))?,
            Some(WebViewer::Embedded(v)) if file.ends_with(".wasm") => v.wasm.to_vec(),
            Some(WebViewer::Embedded(v)) => v.js.to_vec(),
            None => anyhow::bail!("no viewer"),
        };
        println!(
            "size {file}: {:.2} MB raw, {:.2} MB gzipped",
            bytes.len() as f64 / 1e6,
            gzipped(&bytes)? as f64 / 1e6
        );
    }
    if let Some(WebViewer::Embedded(v)) = viewer {
        println!(
            "size served: {:.2} MB of gzipped wasm (built in)",
            v.wasm_gzip.len() as f64 / 1e6
        );
    }
    Ok(())
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

const FIRST: &str = "return document.getElementById('farfield').dataset.firstImageMs || null";

fn first_image(addr: SocketAddr) -> anyhow::Result<()> {
    let browser = Browser::start(SIZE.0, SIZE.1);
    let url = format!("http://{addr}/view/bunny?panel=0");
    let mut loads = Vec::new();
    for _ in 0..8 {
        browser.goto("about:blank");
        browser.goto(&url);
        browser.wait_for(
            "a first image",
            &format!("return !!({})", FIRST.trim_start_matches("return ")),
            "return null",
            Duration::from_secs(60),
        );
        let ms = browser.eval(FIRST);
        let ms = ms.as_str().and_then(|v| v.parse::<f64>().ok());
        loads.push(ms.context("the page's time to first image")?);
    }
    println!(
        "first image (loopback, wasm included): first load {:.0} ms, reloads median {:.0} ms (of {:?})",
        loads[0],
        median(loads[1..].to_vec()),
        loads.iter().map(|x| x.round()).collect::<Vec<_>>()
    );
    Ok(())
}

/// Sum of the RSS of processes whose command line contains `needle`, MiB.
fn rss_mib_of(needle: &str) -> f64 {
    let mut kib = 0u64;
    for entry in std::fs::read_dir("/proc").into_iter().flatten().flatten() {
        let cmdline = std::fs::read(entry.path().join("cmdline")).unwrap_or_default();
        if !String::from_utf8_lossy(&cmdline).contains(needle) {
            continue;
        }
        kib += rss_kib(&entry.path());
    }
    kib as f64 / 1024.0
}

fn rss_kib(proc_dir: &Path) -> u64 {
    std::fs::read_to_string(proc_dir.join("status"))
        .unwrap_or_default()
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .unwrap_or(0)
}

fn browser_flight(
    addr: SocketAddr,
    scene: &str,
    backend: &str,
    seconds: f64,
    cache_mib: Option<u64>,
) -> anyhow::Result<String> {
    let browser = Browser::start(SIZE.0, SIZE.1);
    let cache = cache_mib
        .map(|m| format!("&cache_mib={m}"))
        .unwrap_or_default();
    browser.goto(&format!(
        "http://{addr}/view/{scene}?panel=0&backend={backend}&flight={seconds}{cache}"
    ));
    browser.wait_for(
        "a first image",
        "return !!document.getElementById('farfield').dataset.firstImageMs",
        "return null",
        Duration::from_secs(60),
    );
    let started = Instant::now();
    let mut samples = Vec::new();
    let done = "return document.getElementById('farfield').dataset.flight || null";
    let report = loop {
        let v = browser.eval(done);
        if let Some(r) = v.as_str() {
            break r.to_owned();
        }
        if cache_mib.is_some() {
            let wasm = browser
                .eval("return window.farfield.wasm_memory_bytes()")
                .as_f64()
                .unwrap_or(0.0)
                / 1048576.0;
            let heap = browser
                .eval("return performance.memory ? performance.memory.usedJSHeapSize : 0")
                .as_f64()
                .unwrap_or(0.0)
                / 1048576.0;
            let renderers = rss_mib_of("--type=renderer");
            let status: Value = serde_json::from_str(
                browser
                    .eval("return document.getElementById('farfield').dataset.status")
                    .as_str()
                    .unwrap_or("null"),
            )
            .unwrap_or(Value::Null);
            samples.push((
                started.elapsed().as_secs_f64(),
                wasm,
                heap,
                renderers,
                status["resident_mb"].as_f64().unwrap_or(0.0),
            ));
        }
        if started.elapsed().as_secs_f64() > seconds * 4.0 + 60.0 {
            anyhow::bail!("the tab's flight never ended");
        }
        std::thread::sleep(Duration::from_secs(if cache_mib.is_some() {
            10
        } else {
            1
        }));
    };
    for (t, wasm, heap, renderers, resident) in &samples {
        println!(
            "  tab t={t:>5.0} s: wasm memory {wasm:.1} MiB, JS heap {heap:.1} MiB, renderer RSS {renderers:.0} MiB, resident pages {resident:.1} MB"
        );
    }
    Ok(report)
}

fn window_flight(
    addr: SocketAddr,
    scene: &str,
    seconds: f64,
    cache_mib: Option<u64>,
) -> anyhow::Result<String> {
    let x = xvfb::start_xvfb().context("the window benchmark needs Xvfb")?;
    let mut args = vec![
        "view".to_owned(),
        "--server".into(),
        format!("http://{addr}"),
        "--scene".into(),
        scene.into(),
        "--size".into(),
        format!("{}x{}", SIZE.0, SIZE.1),
        "--no-panel".into(),
        "--flight".into(),
        seconds.to_string(),
    ];
    if let Some(m) = cache_mib {
        args.extend(["--cache-mib".into(), m.to_string()]);
    }
    let mut child = Command::new(std::env::current_exe()?)
        .env(CHILD_ENV, args.join("\t"))
        .env("DISPLAY", x.display())
        .env_remove("WAYLAND_DISPLAY")
        .env(
            farfield_render::DEVICE_SELECT_OFF.0,
            farfield_render::DEVICE_SELECT_OFF.1,
        )
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .context("starting the viewer")?;
    let proc_dir = PathBuf::from(format!("/proc/{}", child.id()));
    let (tx, rx) = std::sync::mpsc::channel();
    let stdout = child.stdout.take().context("the viewer's output")?;
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if let Some(r) = line.strip_prefix("flight ") {
                let _ = tx.send(r.to_owned());
            }
        }
    });
    let started = Instant::now();
    let report = loop {
        if let Ok(r) = rx.recv_timeout(Duration::from_secs(if cache_mib.is_some() {
            10
        } else {
            1
        })) {
            break r;
        }
        if cache_mib.is_some() {
            println!(
                "  window t={:>5.0} s: RSS {:.0} MiB",
                started.elapsed().as_secs_f64(),
                rss_kib(&proc_dir) as f64 / 1024.0
            );
        }
        if started.elapsed().as_secs_f64() > seconds * 4.0 + 60.0 {
            let _ = child.kill();
            anyhow::bail!("the window's flight never ended");
        }
    };
    let _ = child.wait();
    Ok(report)
}
