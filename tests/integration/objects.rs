//! Scenes in S3-compatible object storage (issue 23), against a real store
//! on loopback (`s3s-fs`, see [`crate::s3`]): built straight into the store
//! and served from it with the local file's image; a page damaged in the
//! store refused by its checksum; and the store stopped and started again
//! while a client streams, which then gets every page right.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::Duration;

use farfield_memory_server::{RunningServer, ServerConfig, start};
use farfield_protocol::messages::ServerMessage;
use farfield_render::headless_or_skip;
use std::sync::atomic::Ordering;

use farfield_objects::ObjectScene;
use farfield_store::{PageError, PageSource, SceneFile};
use farfield_tests::scratch;

use crate::s3::S3Store;
use crate::serve::support::{Client, In, eventually, http_get, metric};
use crate::streaming::runtime;

const ISLAND: [&str; 4] = ["--param", "size=96", "--param", "trees=3"];
const SIZE: &str = "160x120";

fn any_port() -> SocketAddr {
    SocketAddr::from(([127, 0, 0, 1], 0))
}

/// Runs the server's command line in a child process (this test binary,
/// running [`server_cli_child`]) whose environment names the store, as a
/// user's shell would; fails the test if it fails.
fn cli_in_child(store: &S3Store, args: &[&str]) -> String {
    let out = farfield_tests::child_test("objects::server_cli_child")
        .env("FARFIELD_CLI_CHILD_ARGS", args.join("\n"))
        .envs(store.env())
        .output()
        .expect("run the child");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "farfield-server {args:?} failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        farfield_tests::child_ran(&out.stdout),
        "the child test did not run: {stdout}"
    );
    stdout
}

/// The child half of [`cli_in_child`]: does nothing unless started by it.
#[test]
#[ignore = "subprocess entry point: run by its parent test"]
fn server_cli_child() {
    let Ok(args) = std::env::var("FARFIELD_CLI_CHILD_ARGS") else {
        return;
    };
    let args: Vec<&str> = args.lines().collect();
    let report = crate::cli(&args).expect("farfield-server");
    println!("{}", report.json);
}

/// Renders `scene` from `server` at the 1-pixel threshold.
fn render(server: &RunningServer, scene: &str, out: &Path) -> (u32, u32, Vec<u8>) {
    let url = format!("http://{}", server.local_addr());
    crate::loadtest::cli(&[
        "render",
        "--server",
        &url,
        "--scene",
        scene,
        "--orbit",
        "azimuth=30,elevation=25,distance=1.6",
        "--threshold",
        "1",
        "--size",
        SIZE,
        "--out",
        out.to_str().unwrap(),
    ])
    .expect("render");
    farfield_image::read_png(out).expect("png")
}

/// Builds the island into `dir/island.ff` with the command line.
fn build_island(dir: &Path) -> PathBuf {
    let local = dir.join("island.ff");
    let mut build = vec!["build", "gen:island"];
    build.extend(ISLAND);
    crate::cli(&[build.as_slice(), &["--out", local.to_str().unwrap()]].concat()).expect("build");
    local
}

/// A scratch folder, a store with a bucket `scenes`, and the island built
/// there and published as `island.ff`: (folder, store, the local file).
/// `None` when there is no store and the test may skip.
fn island_in_store(name: &str) -> Option<(PathBuf, S3Store, PathBuf)> {
    let dir = scratch(name);
    let store = S3Store::start_or_skip(&dir.join("store"), &["scenes"])?;
    let local = build_island(&dir);
    let publisher = store.bucket("s3://scenes", Duration::from_secs(5));
    farfield_objects::publish(&local, &publisher, "island.ff").expect("publish");
    Some((dir, store, local))
}

#[test]
fn a_scene_built_into_a_store_renders_as_the_local_file_and_a_damaged_page_is_refused() {
    let dir = scratch("objects-publish");
    let Some(store) = S3Store::start_or_skip(&dir.join("store"), &["scenes"]) else {
        return;
    };
    let local_dir = dir.join("local");
    std::fs::create_dir_all(&local_dir).unwrap();
    let local = build_island(&local_dir);
    let mut build = vec!["build", "gen:island"];
    build.extend(ISLAND);
    // Straight into the store, its address from the environment.
    cli_in_child(
        &store,
        &[build.as_slice(), &["--out", "s3://scenes/island.ff"]].concat(),
    );
    let stored = store.object_file("scenes", "island.ff");
    assert!(
        std::fs::read(&stored).unwrap() == std::fs::read(&local).unwrap(),
        "the store holds other bytes than the local build"
    );

    let rt = runtime();
    let bucket = store.bucket("s3://scenes", Duration::from_secs(5));
    let remote = rt
        .block_on(start(ServerConfig {
            rescan_interval: Duration::from_millis(100),
            ..ServerConfig::objects(bucket, any_port())
        }))
        .expect("server over the store");
    let nearby = rt
        .block_on(start(ServerConfig::new(&local_dir, any_port())))
        .expect("server over the folder");
    let (status, listing) = rt.block_on(http_get(remote.local_addr(), "/scenes"));
    assert_eq!(status, 200);
    assert!(listing.contains("\"island\""), "{listing}");

    if headless_or_skip(160, 120).unwrap().is_some() {
        let from_store = render(&remote, "island", &dir.join("store.png"));
        let from_file = render(&nearby, "island", &dir.join("file.png"));
        assert!(
            from_store == from_file,
            "the scene from the store draws another image than the file"
        );
    }
    let m = remote.metrics();
    assert!(m.store_requests > 2, "{m:?}");
    assert!(m.store_bytes > 0 && m.store_errors == 0, "{m:?}");
    let (_, text) = rt.block_on(http_get(remote.local_addr(), "/metrics"));
    assert!(metric(&text, "farfield_store_requests_total") >= m.store_requests);
    assert!(metric(&text, "farfield_store_request_seconds_count") > 0);

    // A copy damaged in the store, after its upload: one byte of page 1.
    let bytes = std::fs::read(&local).unwrap();
    let page = 1u32;
    let entry = farfield_protocol::paged_file::read_image(&bytes)
        .unwrap()
        .directory()
        .entry(page)
        .unwrap();
    let mut damaged = bytes.clone();
    damaged[(entry.offset + u64::from(entry.length) / 2) as usize] ^= 0x5a;
    std::fs::write(store.object_file("scenes", "bad.ff"), &damaged).unwrap();
    rt.block_on(async {
        let addr = remote.local_addr();
        eventually("the damaged copy is listed", || {
            remote.metrics().scenes == 2
        })
        .await;
        let (mut client, _, _) = Client::open(addr, "bad", 1 << 20, false).await;
        client.request(&[(page, 1.0)]).await;
        match client.recv().await {
            In::Control(ServerMessage::PageUnavailable { page: p, reason }) => {
                assert_eq!(p, page);
                assert!(
                    reason.contains("checksum") || reason.contains("page"),
                    "{reason}"
                );
            }
            other => panic!("expected the page refused, got {other:?}"),
        }
    });
    // Found by the client's read or by read-ahead (both, when they race).
    let corrupt = remote.metrics().corrupt_pages;
    assert!(
        (1..=2).contains(&corrupt),
        "{corrupt} corrupt pages counted"
    );
}

#[test]
fn the_store_stopped_and_started_while_a_client_streams_then_every_page_arrives_right() {
    let Some((_dir, mut store, local)) = island_in_store("objects-outage") else {
        return;
    };
    let bucket = store.bucket("s3://scenes", Duration::from_secs(2));
    let file = SceneFile::open(&local).unwrap();
    let pages = file.header.page_count;
    assert!(pages > 4, "{pages} pages");

    let rt = runtime();
    // No page cache (none fits), so every page comes from the store, and
    // read-ahead cannot have fetched them before the outage.
    let server = rt
        .block_on(start(ServerConfig {
            cache_bytes: 1,
            ..ServerConfig::objects(bucket, any_port())
        }))
        .expect("server over the store");
    rt.block_on(async {
        let (mut client, header, page0) =
            Client::open(server.local_addr(), "island", 1 << 20, false).await;
        assert_eq!(header, file.header_bytes());
        let mut want = Vec::new();
        file.read_page_into(0, &mut want).unwrap();
        assert!(page0 == want, "page 0 differs from the file's");

        store.stop();
        let wishes: Vec<(u32, f32)> = (1..pages).map(|p| (p, (pages - p) as f32)).collect();
        client.request(&wishes).await;
        // Told once that pages are unavailable for now; no page comes.
        match client.recv().await {
            In::Control(ServerMessage::Error { message, fatal }) => {
                assert!(!fatal, "{message}");
                assert!(message.contains("temporarily unavailable"), "{message}");
            }
            In::Page(index, _) => panic!("page {index} sent while the store is down"),
            other => panic!("expected the outage told, got {other:?}"),
        }
        let quiet = client.recv_within(Duration::from_millis(1500)).await;
        assert!(quiet.is_none(), "while the store is down: {quiet:?}");
        let m = server.metrics();
        assert!(m.store_errors > 0, "{m:?}");
        assert!(
            m.store_fast_failures > 0,
            "a store known down is not asked every time: {m:?}"
        );

        let port = store.port;
        store.start_on(port);
        let mut got = std::collections::BTreeSet::new();
        while got.len() < (pages - 1) as usize {
            match client.recv().await {
                In::Page(index, bytes) => {
                    let mut want = Vec::new();
                    file.read_page_into(index as usize, &mut want).unwrap();
                    assert!(bytes == want, "page {index} differs from the file's");
                    assert!(got.insert(index), "page {index} sent twice");
                    client.ack([index]).await;
                }
                other => panic!("expected pages once the store is back, got {other:?}"),
            }
        }
    });
    assert_eq!(server.metrics().corrupt_pages, 0);
}

#[test]
fn neighbouring_pages_come_in_one_range_request_and_are_checked_one_by_one() {
    let Some((_dir, store, local)) = island_in_store("objects-coalesce") else {
        return;
    };
    let file = SceneFile::open(&local).unwrap();
    let run = 1..6u32;
    // One byte of page 3 damaged in the store.
    let entry = file.directory.entry(3).unwrap();
    let stored = store.object_file("scenes", "island.ff");
    let mut bytes = std::fs::read(&stored).unwrap();
    bytes[(entry.offset + u64::from(entry.length) / 2) as usize] ^= 0x5a;
    std::fs::write(&stored, &bytes).unwrap();

    for (coalesce, requests) in [
        (farfield_objects::DEFAULT_COALESCE_BYTES, 1),
        (0, run.len() as u64),
    ] {
        let bucket = store.bucket_with("s3://scenes", Duration::from_secs(5), coalesce);
        let stats = bucket.stats_handle();
        let scene = ObjectScene::open(bucket, "island.ff").expect("open");
        let before = stats.requests.load(Ordering::Relaxed);
        let pages = scene.read_pages(run.clone());
        let asked = stats.requests.load(Ordering::Relaxed) - before;
        assert_eq!(asked, requests, "coalescing up to {coalesce} bytes");
        for (page, read) in run.clone().zip(pages) {
            if page == 3 {
                assert!(
                    matches!(read, Err(PageError::Format(_))),
                    "page 3: {read:?}"
                );
            } else {
                let mut want = Vec::new();
                file.read_page_into(page as usize, &mut want).unwrap();
                assert!(read.expect("a good page") == want, "page {page}");
            }
        }
    }
}

#[test]
fn a_second_tier_on_disk_serves_pages_again_and_through_an_outage() {
    let Some((dir, mut store, local)) = island_in_store("objects-tier") else {
        return;
    };
    let file = SceneFile::open(&local).unwrap();
    let tier_dir = dir.join("tier");
    let bucket = store.bucket_options(
        "s3://scenes",
        farfield_objects::BucketOptions {
            timeout: Duration::from_secs(2),
            tier: Some((tier_dir.clone(), 64 << 20)),
            ..Default::default()
        },
    );
    let stats = bucket.stats_handle();
    let scene = ObjectScene::open(bucket, "island.ff").expect("open");
    let want = |page: u32| {
        let mut bytes = Vec::new();
        file.read_page_into(page as usize, &mut bytes).unwrap();
        bytes
    };
    let read = |page: u32| {
        let mut bytes = Vec::new();
        scene.read_page(page, &mut bytes).map(|()| bytes)
    };
    let count = |c: &std::sync::atomic::AtomicU64| c.load(Ordering::Relaxed);

    // Read from the store once (a run of neighbours and a page alone),
    // kept in the tier.
    let run = scene.read_pages(1..5);
    assert!(read(6).unwrap() == want(6));
    assert_eq!(count(&stats.tier_writes), 5);
    let asked = count(&stats.requests);
    // Again: from the tier, no request; a run half in the tier asks only
    // for the rest.
    assert!(read(2).unwrap() == want(2));
    assert_eq!(count(&stats.requests), asked, "page 2 came from the tier");
    let mixed = scene.read_pages(3..9);
    assert_eq!(
        count(&stats.requests),
        asked + 1,
        "5, 7 and 8 in one request (their span)"
    );
    for (page, bytes) in (1..5).zip(run).chain((3..9).zip(mixed)) {
        assert!(bytes.unwrap() == want(page), "page {page}");
    }
    // A damaged copy in the tier is dropped and read from the store.
    let name = std::fs::read_dir(&tier_dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .find(|n| n.ends_with("-4"))
        .expect("page 4 in the tier");
    let mut damaged = std::fs::read(tier_dir.join(&name)).unwrap();
    let middle = damaged.len() / 2;
    damaged[middle] ^= 0x5a;
    std::fs::write(tier_dir.join(&name), damaged).unwrap();
    assert!(read(4).unwrap() == want(4));
    assert_eq!(count(&stats.requests), asked + 2, "page 4 asked for again");
    // With the store down, what the tier holds is still served.
    store.stop();
    let hits = count(&stats.tier_hits);
    assert!(read(5).unwrap() == want(5));
    assert_eq!(count(&stats.tier_hits), hits + 1);
    assert!(
        matches!(read(10), Err(PageError::Unavailable(_))),
        "page 10 was never read"
    );
}

/// A store that takes connections and never answers (slow, or hung): every
/// request ends at its deadline with a clear error, counted as a timeout,
/// and the next reads fail at once until the back-off has passed. Needs no
/// real store.
#[test]
fn a_store_that_never_answers_times_out_with_a_clear_error() {
    let silent = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let endpoint = format!("http://{}", silent.local_addr().unwrap());
    // Accept and hold every connection, answering nothing.
    std::thread::spawn(move || {
        let mut held = Vec::new();
        for stream in silent.incoming().flatten() {
            held.push(stream);
        }
    });
    let options = farfield_objects::BucketOptions {
        timeout: Duration::from_millis(500),
        endpoint: Some(endpoint),
        credentials: Some(("k".into(), "s".into())),
        ..Default::default()
    };
    let url = farfield_objects::StoreUrl::parse("s3://scenes").unwrap();
    let bucket = farfield_objects::Bucket::open(&url, &options, Default::default()).unwrap();
    let stats = bucket.stats_handle();
    let started = std::time::Instant::now();
    let e = bucket.head("island.ff").expect_err("no answer");
    let waited = started.elapsed();
    assert!(e.to_string().contains("no answer within 500ms"), "{e}");
    assert!(waited < Duration::from_secs(5), "waited {waited:?}");
    assert!(
        matches!(e, farfield_objects::RemoteError::Unavailable(_)),
        "{e:?}"
    );
    assert_eq!(stats.errors.load(Ordering::Relaxed), 1);
    assert_eq!(
        stats.timeouts.load(Ordering::Relaxed),
        1,
        "cut by the deadline"
    );
    // Known down: the next read fails at once, without a request.
    let again = bucket
        .get_range("island.ff", 0..10, None)
        .expect_err("still down");
    assert!(again.to_string().contains("asked again in"), "{again}");
    assert_eq!(stats.fast_failures.load(Ordering::Relaxed), 1);
    assert_eq!(stats.requests.load(Ordering::Relaxed), 1);
}
