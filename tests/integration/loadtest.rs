//! `farfield loadtest` from the command line against a real server on
//! port 0: every output, real figures in them; behind a proxy that cuts
//! every connection, errors and reconnects are counted; loads out of
//! bounds are refused.

use std::net::SocketAddr;
use std::path::Path;
use std::time::Duration;

use clap::Parser;
use farfield_cli::cli::{Cli, run};
use farfield_tests::scratch;
use farfield_tools::bench::rows;
use farfield_tools::loadtest::client::ClientRow;
use farfield_tools::loadtest::{LoadReport, SecondRow};

use crate::serve_dir;
use crate::streaming::scenes;

pub(crate) fn cli(args: &[&str]) -> anyhow::Result<()> {
    run(Cli::try_parse_from(
        std::iter::once("farfield").chain(args.iter().copied()),
    )?)
}

/// `farfield loadtest` of the scene `island` on `url`: `clients` clients
/// for `seconds`, then the `extra` flags, writing into `out`.
fn load(url: &str, clients: &str, seconds: &str, extra: &[&str], out: &Path) -> anyhow::Result<()> {
    let out = out.to_str().expect("a UTF-8 scratch path");
    let mut args = vec![
        "loadtest",
        "--server",
        url,
        "--scene",
        "island",
        "--clients",
        clients,
        "--duration",
        seconds,
    ];
    args.extend_from_slice(extra);
    args.extend(["--out", out]);
    cli(&args)
}

fn seconds_of(out: &Path) -> Vec<SecondRow> {
    rows::read(&out.join("seconds.csv")).expect("seconds.csv")
}

fn clients_of(out: &Path) -> Vec<ClientRow> {
    rows::read(&out.join("clients.csv")).expect("clients.csv")
}

fn summary(out: &Path) -> LoadReport {
    let text = std::fs::read_to_string(out.join("loadtest.json")).expect("loadtest.json");
    serde_json::from_str(&text).expect("summary")
}

#[test]
fn a_few_clients_for_a_few_seconds_produce_every_output() {
    let (dir, _) = scenes("loadtest");
    let (rt, server, url) = serve_dir(&dir);
    let out = dir.join("run");
    load(&url, "3", "3", &["--ramp", "1", "--size", "320x240"], &out).expect("loadtest");
    let served = server.metrics();
    rt.block_on(server.shutdown()).expect("shutdown");

    let r = summary(&out);
    assert_eq!(r.clients, 3);
    assert!(r.pages > 0, "{r:?}");
    assert_eq!(r.errors, 0, "{r:?}");
    assert_eq!(r.clients_with_first_image, 3, "{r:?}");
    assert!(r.first_image_p50_ms.is_some_and(|ms| ms > 0.0));
    let (p50, p99, max) = (
        r.latency_p50_ms.expect("p50"),
        r.latency_p99_ms.expect("p99"),
        r.latency_max_ms.expect("max"),
    );
    assert!(0.0 < p50 && p50 <= p99 && p99 <= max, "{r:?}");
    // The clients counted what the server sent them (page 0 included;
    // nothing else was connected), less what was on its way at the end.
    assert!(
        r.pages <= served.pages_served && r.pages * 2 >= served.pages_served,
        "{r:?} {served:?}"
    );
    assert!(r.metrics_error.is_none(), "{r:?}");
    #[cfg(target_os = "linux")]
    assert!(r.server_resident_max_mib.is_some_and(|m| m > 1.0), "{r:?}");
    // The server's own latency, from its histogram over the run.
    let (s50, s99) = (
        r.server_latency_p50_ms.expect("server p50"),
        r.server_latency_p99_ms.expect("server p99"),
    );
    assert!(0.0 < s50 && s50 <= s99, "{r:?}");

    let seconds = seconds_of(&out);
    assert_eq!(seconds.len(), 3, "{seconds:?}");
    assert_eq!(seconds.iter().map(|s| s.pages).sum::<u64>(), r.pages);
    assert!(seconds.iter().any(|s| s.server_queue_depth.is_some()));
    assert!(seconds.iter().all(|s| s.clients_connected <= 3));
    let clients = clients_of(&out);
    assert_eq!(clients.len(), 3);
    // The ramp staggers the starts.
    assert!(clients[0].started_s < clients[2].started_s, "{clients:?}");
    assert_eq!(clients.iter().map(|c| c.pages).sum::<u64>(), r.pages);
    for plot in ["latency", "throughput", "server", "clients"] {
        let svg = std::fs::read_to_string(out.join(format!("load0-{plot}.svg"))).expect(plot);
        assert!(svg.contains("<svg"), "{plot}");
    }
    let html = std::fs::read_to_string(out.join("index.html")).expect("index.html");
    assert!(html.contains("Load test: 3 clients"), "{html}");
    assert!(html.contains("load0-latency.svg"));
}

/// A TCP proxy to `upstream` that cuts every connection `after` it opened.
async fn cutting_proxy(upstream: SocketAddr, after: Duration) -> SocketAddr {
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0")
        .await
        .expect("bind");
    let addr = listener.local_addr().expect("addr");
    tokio::spawn(async move {
        while let Ok((mut client, _)) = listener.accept().await {
            tokio::spawn(async move {
                let Ok(mut server) = tokio::net::TcpStream::connect(upstream).await else {
                    return;
                };
                let _ = tokio::time::timeout(
                    after,
                    tokio::io::copy_bidirectional(&mut client, &mut server),
                )
                .await;
                // Dropping both ends cuts the connection mid-stream.
            });
        }
    });
    addr
}

#[test]
fn connections_cut_by_the_network_are_counted_as_errors_and_reconnects() {
    let (dir, _) = scenes("loadtest-cut");
    let (rt, server, _) = serve_dir(&dir);
    let proxy = rt.block_on(cutting_proxy(
        server.local_addr(),
        Duration::from_millis(700),
    ));
    let out = dir.join("run");
    load(
        &format!("http://{proxy}"),
        "2",
        "4",
        &["--size", "320x240"],
        &out,
    )
    .expect("loadtest");
    rt.block_on(server.shutdown()).expect("shutdown");
    let r = summary(&out);
    assert!(r.errors >= 2, "every client lost connections: {r:?}");
    assert!(r.reconnects >= 2, "and came back: {r:?}");
    assert!(r.pages > 0, "{r:?}");
    let clients = clients_of(&out);
    for c in &clients {
        assert!(c.errors >= 1 && c.reconnects >= 1, "{c:?}");
        assert!(!c.last_error.is_empty(), "{c:?}");
    }
    let seconds = seconds_of(&out);
    assert_eq!(seconds.iter().map(|s| s.errors).sum::<u64>(), r.errors);
    assert_eq!(
        seconds.iter().map(|s| s.reconnects).sum::<u64>(),
        r.reconnects
    );
}

#[test]
fn loads_out_of_bounds_are_refused_before_anything_connects() {
    let dir = scratch("loadtest-bounds");
    let out = dir.join("run");
    let out_s = out.to_str().unwrap();
    // Nothing listens on port 9: a refused bound must say so before trying.
    let base = ["loadtest", "--server", "http://127.0.0.1:9", "--scene", "x"];
    for (extra, why) in [
        (["--clients", "0", "--duration", "1"], "--clients"),
        (["--clients", "5000", "--duration", "1"], "--clients"),
        (["--clients", "1", "--duration", "0"], "--duration"),
        (["--clients", "1", "--duration", "4000"], "--duration"),
        (
            ["--clients", "1", "--duration=-1", "--ramp=0"],
            "--duration",
        ),
    ] {
        let args: Vec<&str> = base
            .iter()
            .copied()
            .chain(extra)
            .chain(["--out", out_s])
            .collect();
        let e = cli(&args).expect_err("out of bounds");
        assert!(format!("{e:#}").contains(why), "{args:?}: {e:#}");
    }
    let e = cli(&[
        "loadtest",
        "--server",
        "http://127.0.0.1:9",
        "--scene",
        "x",
        "--clients",
        "1",
        "--duration",
        "1",
        "--ramp",
        "2",
        "--out",
        out_s,
    ])
    .expect_err("ramp longer than the run");
    assert!(format!("{e:#}").contains("--ramp"), "{e:#}");
    assert!(!out.exists(), "nothing written for a refused load");
}

#[test]
fn a_load_as_a_demo_session_measures_the_followers_lag() {
    let (dir, _) = scenes("loadtest-session");
    let (rt, server, url) = serve_dir(&dir);
    let out = dir.join("run");
    load(
        &url,
        "4",
        "4",
        &["--size", "320x240", "--session", "load"],
        &out,
    )
    .expect("loadtest");
    rt.block_on(server.shutdown()).expect("shutdown");
    let r = summary(&out);
    assert_eq!(r.errors, 0, "{r:?}");
    assert_eq!(r.session.as_deref(), Some("load"));
    assert!(r.follower_views >= 3, "each follower saw views: {r:?}");
    let (p50, p95) = (
        r.follower_lag_p50_ms.expect("lag"),
        r.follower_lag_p95_ms.expect("lag"),
    );
    assert!(0.0 < p50 && p50 <= p95, "{r:?}");
    // The probe follower on its own thread saw the views too.
    let probe = r.probe_lag_p50_ms.expect("the probe's lag");
    assert!(probe > 0.0 && probe <= r.probe_lag_max_ms.unwrap(), "{r:?}");
    assert!(r.server_disk_reads_per_page_served.is_some(), "{r:?}");
    assert!(
        seconds_of(&out)
            .iter()
            .any(|s| s.follower_lag_p95_ms.is_some())
    );
    // A session of one client, or with a bad name, is refused.
    for (clients, name) in [("1", "load"), ("2", "bad name")] {
        let e = load(&url, clients, "1", &["--session", name], &out).expect_err("refused");
        assert!(format!("{e:#}").contains("--session"), "{e:#}");
    }
}

/// A static file server over `root` that counts the GETs it answered:
/// what nginx does for `--static`, in-process.
async fn static_files(
    root: std::path::PathBuf,
    gets: std::sync::Arc<std::sync::atomic::AtomicU64>,
) -> SocketAddr {
    use axum::extract::Path as UrlPath;
    use axum::http::StatusCode;
    let app = axum::Router::new().route(
        "/{*path}",
        axum::routing::get(move |UrlPath(path): UrlPath<String>| {
            let (root, gets) = (root.clone(), gets.clone());
            async move {
                gets.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                if path.split('/').any(|part| part == "..") {
                    return Err(StatusCode::BAD_REQUEST);
                }
                std::fs::read(root.join(path)).map_err(|_| StatusCode::NOT_FOUND)
            }
        }),
    );
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0")
        .await
        .expect("bind");
    let addr = listener.local_addr().expect("addr");
    tokio::spawn(async move { axum::serve(listener, app).await });
    addr
}

/// The same clients against the scene exported as plain files
/// (`farfield-server export`, then `loadtest --static`): they stream and
/// draw from a file server too, and a scene it does not have is an error
/// each client counts.
#[test]
fn load_clients_stream_an_exported_scene_from_a_static_file_server() {
    let (dir, _) = scenes("loadtest-static");
    let files = dir.join("static");
    crate::cli(&[
        "export",
        dir.join("island.ff").to_str().unwrap(),
        "--out",
        files.to_str().unwrap(),
    ])
    .expect("export");
    let header = farfield_store::SceneFile::open(&dir.join("island.ff")).unwrap();
    // The scene's pages and its directory pages.
    let pages = header.directory.id_count() as usize;
    assert_eq!(
        std::fs::read_dir(files.join("island/pages"))
            .unwrap()
            .count(),
        pages,
        "one file a page"
    );
    let rt = tokio::runtime::Runtime::new().expect("runtime");
    let gets = std::sync::Arc::new(std::sync::atomic::AtomicU64::new(0));
    let addr = rt.block_on(static_files(files, gets.clone()));
    let url = format!("http://{addr}");
    let run = |scene: &str, out: &Path| {
        cli(&[
            "loadtest",
            "--server",
            &url,
            "--static",
            "--scene",
            scene,
            "--clients",
            "2",
            "--duration",
            "3",
            "--size",
            "320x240",
            "--out",
            out.to_str().unwrap(),
        ])
        .expect("loadtest");
        summary(out)
    };
    let r = run("island", &dir.join("run"));
    assert!(r.static_files);
    assert_eq!(r.errors, 0, "{r:?}");
    assert_eq!(r.clients_with_first_image, 2, "{r:?}");
    assert!(r.pages > 2, "{r:?}");
    // Every page came by its own GET (and each client's header by one).
    let answered = gets.load(std::sync::atomic::Ordering::Relaxed);
    assert!(
        r.pages + 2 <= answered,
        "{} pages, {answered} GETs",
        r.pages
    );
    assert!(r.latency_p50_ms.is_some(), "{r:?}");

    let missing = run("nowhere", &dir.join("missing"));
    assert_eq!(missing.pages, 0, "{missing:?}");
    let clients = clients_of(&dir.join("missing"));
    for c in &clients {
        assert!(c.errors >= 1, "{c:?}");
        assert!(c.last_error.contains("404"), "{c:?}");
    }
}

/// `--max-outstanding` reaches the clients' sessions: the server never
/// holds more of their requests than the bound allows (plus the page 0 it
/// queues itself for each).
#[test]
fn a_bound_on_outstanding_pages_keeps_the_servers_queue_within_it() {
    let (dir, _) = scenes("loadtest-bound");
    let (rt, server, url) = serve_dir(&dir);
    let out = dir.join("run");
    load(
        &url,
        "3",
        "2",
        &["--size", "320x240", "--max-outstanding", "2"],
        &out,
    )
    .expect("loadtest");
    rt.block_on(server.shutdown()).expect("shutdown");
    let r = summary(&out);
    assert_eq!(r.max_outstanding, Some(2));
    assert!(r.pages > 3, "pages kept coming as others arrived: {r:?}");
    assert_eq!(r.errors, 0, "{r:?}");
    let depths: Vec<f64> = seconds_of(&out)
        .iter()
        .filter_map(|s| s.server_queue_depth)
        .collect();
    assert!(!depths.is_empty());
    assert!(depths.iter().all(|&d| d <= 3.0 * 3.0), "{depths:?}");
    assert!(
        load(&url, "1", "1", &["--max-outstanding", "0"], &out).is_err(),
        "a bound of 0 is refused"
    );
}
