//! The system end to end: a real memory server on port 0, real clients
//! rendering through the GPU (lavapipe on CPU machines).

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use farfield_builder::import::{Params, load_input};
use farfield_client::camera_spec::CameraSpec;
use farfield_client::frame_loop::{FrameState, Settle, Until, draw_frame};
use farfield_client::render_job::{RenderJob, Rendered, Source, run};
use farfield_client::viewer::Viewer;
use farfield_image::compare;
use farfield_memory_server::{RunningServer, ServerConfig, start};
use farfield_net::SessionOptions;
use farfield_render::{Kernel, Renderer, SplatStyle, headless_or_skip};
use farfield_store::write_atomic;
use farfield_tests::{scratch, shared_data};
use farfield_traverse::DrawList;

use crate::build;

pub(crate) const SIZE: (u32, u32) = (320, 240);

/// Writes the small generated island (and the bunny, when the shared data
/// is there) into a fresh scenes folder.
pub(crate) fn scenes(name: &str) -> (PathBuf, Vec<&'static str>) {
    let dir = scratch(name);
    let mut params = Params::default();
    params.set("size", 96);
    params.set("trees", 3);
    write_atomic(
        &dir.join("island.ff"),
        &build(load_input("gen:island", &params).unwrap()),
    )
    .unwrap();
    let mut names = vec!["island"];
    if let Some(data) = shared_data() {
        let bunny = load_input(
            data.join("stanford-bunny.obj").to_str().unwrap(),
            &Params::default(),
        )
        .unwrap();
        write_atomic(&dir.join("bunny.ff"), &build(bunny)).unwrap();
        names.push("bunny");
    }
    (dir, names)
}

pub(crate) fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap()
}

pub(crate) fn serve(rt: &tokio::runtime::Runtime, dir: &Path, port: u16) -> RunningServer {
    let config = ServerConfig::new(dir, SocketAddr::from(([127, 0, 0, 1], port)));
    rt.block_on(start(config)).expect("server starts")
}

pub(crate) fn job(source: Source, camera: CameraSpec) -> RenderJob {
    RenderJob {
        source,
        camera,
        width: SIZE.0,
        height: SIZE.1,
        out: None,
        until: Until::Refined,
        threshold_px: 1.0,
        kernel: Kernel::Square,
        edl: None,
        color_by: Default::default(),
        clip: None,
        coverage: Default::default(),
        session: SessionOptions::default(),
        cache_bytes: 256 << 20,
        timeout: Duration::from_secs(60),
        budget: Default::default(),
    }
}

/// A job streaming the island from the server at `url`, at [`camera`].
pub(crate) fn island_from(url: String) -> RenderJob {
    job(
        Source::Server {
            url,
            scene: "island".into(),
        },
        camera(),
    )
}

fn camera() -> CameraSpec {
    CameraSpec::Orbit {
        azimuth_deg: 200.0,
        elevation_deg: 35.0,
        distance: 2.0,
    }
}

fn psnr(a: &[u8], b: &[u8]) -> f64 {
    compare(a, b, SIZE.0, SIZE.1, 8).unwrap().psnr_db
}

pub(crate) fn render(renderer: &mut Renderer, job: &RenderJob) -> Rendered {
    let r = run(job, renderer, false).expect("render");
    assert!(r.report.refined, "not refined: {:?}", r.report.last_error);
    r
}

#[test]
fn streamed_images_equal_file_images_and_overfetch_is_low() {
    let Some(mut renderer) = headless_or_skip(SIZE.0, SIZE.1).unwrap() else {
        return;
    };
    let (dir, names) = scenes("stream-eq");
    let rt = runtime();
    let server = serve(&rt, &dir, 0);
    let url = format!("http://{}", server.local_addr());
    for name in names {
        let file = render(
            &mut renderer,
            &job(Source::File(dir.join(format!("{name}.ff"))), camera()),
        );
        let streamed = render(
            &mut renderer,
            &job(
                Source::Server {
                    url: url.clone(),
                    scene: name.into(),
                },
                camera(),
            ),
        );
        let p = psnr(&file.rgba, &streamed.rgba);
        assert!(
            p >= 40.0,
            "{name}: streamed image differs from the file's: PSNR {p} dB"
        );
        // The picture is not empty: some pixel differs from the background.
        assert!(
            file.rgba.chunks_exact(4).any(|px| px[..3] != [0, 0, 0]),
            "{name}: blank image"
        );
        let r = &streamed.report;
        assert!(r.time_to_first_image_ms.is_some() && r.net.bytes_received > 0);
        let overfetch = r.overfetch_ratio.unwrap();
        assert!(overfetch <= 1.5, "{name}: overfetch {overfetch}");
    }
    rt.block_on(server.shutdown()).unwrap();
}

#[test]
fn the_first_image_comes_from_page_zero_and_error_never_grows() {
    let Some(mut renderer) = headless_or_skip(SIZE.0, SIZE.1).unwrap() else {
        return;
    };
    let (dir, _) = scenes("progressive");
    let rt = runtime();
    let server = serve(&rt, &dir, 0);
    let url = format!("http://{}", server.local_addr());
    let mut viewer =
        Viewer::open_remote(&url, "island", SessionOptions::default(), 256 << 20).unwrap();
    let started = Instant::now();
    while viewer.hierarchy().is_none_or(|h| !h.is_resident(0)) {
        assert!(started.elapsed() < Duration::from_secs(20), "no page 0");
        viewer.pump(Duration::from_millis(50)).unwrap();
    }
    let h = viewer.hierarchy().unwrap();
    assert_eq!(
        h.resident_pages(),
        1,
        "only page 0 before anything was asked for"
    );
    let page0_nodes = u64::from(h.directory().entry(0).unwrap().node_count);
    let style = SplatStyle {
        kernel: Kernel::Square,
        ..SplatStyle::default()
    };
    let header = h.header.clone();
    let cam = camera().resolve(&header, SIZE.0, SIZE.1);
    let (mut cuts, mut first) = (FrameState::default(), Vec::new());
    draw_frame(
        &mut viewer,
        &mut renderer,
        &cam,
        1.0,
        &style,
        &mut cuts,
        &mut first,
    )
    .unwrap();
    let Some(DrawList::Splats(splats)) = cuts.draw_list() else {
        panic!("a sphere hierarchy draws splats");
    };
    assert!(!splats.is_empty() && splats.iter().all(|s| s.node < page0_nodes));
    assert!(
        !cuts.wanted().is_empty(),
        "page 0 alone should not be the whole model"
    );

    // Refine at the final threshold and keep every frame.
    let mut settle = Settle::new(1.0, Until::Refined, started, Duration::from_secs(60));
    settle.threshold = 1.0;
    settle.keep_frames = true;
    settle
        .run(&mut viewer, &mut renderer, &style, &|hd| {
            camera().resolve(hd, SIZE.0, SIZE.1)
        })
        .unwrap();
    assert!(settle.time_to_refined_ms.is_some(), "{:?}", settle.error);
    let last = settle.rgba.clone();
    let mut frames = vec![first];
    frames.extend(settle.frames.clone());
    assert!(
        frames.len() >= 3,
        "too few frames ({}) to see refinement",
        frames.len()
    );
    let errors: Vec<f64> = frames
        .iter()
        .map(|f| compare(f, &last, SIZE.0, SIZE.1, 8).unwrap().rmse)
        .collect();
    assert!(
        errors[0] > 0.0,
        "the first image already equals the final one"
    );
    for w in errors.windows(2) {
        // Allow a sliver of noise: a finer splat can differ on a few edge pixels.
        assert!(
            w[1] <= w[0] * 1.02 + 0.05,
            "error grew as pages arrived: {errors:?}"
        );
    }
    drop(viewer);
    rt.block_on(server.shutdown()).unwrap();
}

#[test]
fn two_clients_at_once_and_a_stalled_reader_does_not_stall_others() {
    use futures_util::SinkExt;
    use tokio_tungstenite::tungstenite::Message;
    let Some(mut renderer) = headless_or_skip(SIZE.0, SIZE.1).unwrap() else {
        return;
    };
    let (dir, _) = scenes("two-clients");
    let rt = runtime();
    let server = serve(&rt, &dir, 0);
    let url = format!("http://{}", server.local_addr());
    // A client that asks for every page with a tiny window and never reads.
    let ws = farfield_net::stream_url(&url, "island");
    let pages = farfield_store::SceneFile::open(&dir.join("island.ff"))
        .unwrap()
        .header
        .page_count;
    let stalled = rt.block_on(async move {
        let (mut socket, _) = tokio_tungstenite::connect_async(ws).await.unwrap();
        use farfield_protocol::codec::encode_control;
        use farfield_protocol::messages::{ClientMessage, PROTOCOL_VERSION, PageWish};
        let hello = ClientMessage::Hello {
            protocol_version: PROTOCOL_VERSION,
            max_in_flight_bytes: 64 << 10,
            allow_push: true,
        };
        socket
            .send(Message::Binary(encode_control(&hello).into()))
            .await
            .unwrap();
        let wishes = (0..pages)
            .map(|page| PageWish {
                page,
                priority: 1.0,
            })
            .collect();
        socket
            .send(Message::Binary(
                encode_control(&ClientMessage::Request { pages: wishes }).into(),
            ))
            .await
            .unwrap();
        socket // kept open, never read
    });
    let file = render(
        &mut renderer,
        &job(Source::File(dir.join("island.ff")), camera()),
    );
    let other = CameraSpec::Orbit {
        azimuth_deg: 20.0,
        elevation_deg: 60.0,
        distance: 3.0,
    };
    let file_other = render(
        &mut renderer,
        &job(Source::File(dir.join("island.ff")), other),
    );
    let url2 = url.clone();
    let second = std::thread::spawn(move || {
        let mut r = Renderer::new_headless(SIZE.0, SIZE.1).unwrap();
        render(
            &mut r,
            &job(
                Source::Server {
                    url: url2,
                    scene: "island".into(),
                },
                other,
            ),
        )
    });
    let first = render(&mut renderer, &island_from(url));
    let second = second.join().unwrap();
    assert!(psnr(&first.rgba, &file.rgba) >= 40.0);
    assert!(psnr(&second.rgba, &file_other.rgba) >= 40.0);
    drop(stalled);
    rt.block_on(server.shutdown()).unwrap();
}

#[test]
fn a_client_survives_a_server_restart_and_finishes_correctly() {
    let Some(mut renderer) = headless_or_skip(SIZE.0, SIZE.1).unwrap() else {
        return;
    };
    let (dir, _) = scenes("restart");
    let file = render(
        &mut renderer,
        &job(Source::File(dir.join("island.ff")), camera()),
    );
    let rt = runtime();
    let server = serve(&rt, &dir, 0);
    let addr = server.local_addr();
    // A small window makes the stream slow enough to be cut in the middle.
    let mut j = island_from(format!("http://{addr}"));
    j.session.max_in_flight_bytes = 64 << 10;
    let client = std::thread::spawn(move || {
        let mut r = Renderer::new_headless(SIZE.0, SIZE.1).unwrap();
        run(&j, &mut r, false).unwrap()
    });
    // Stop once some pages went out, then come back on the same port.
    let deadline = Instant::now() + Duration::from_secs(20);
    while server.metrics().pages_served < 3 && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(5));
    }
    rt.block_on(server.shutdown()).unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let server = serve(&rt, &dir, addr.port());
    let done = client.join().unwrap();
    assert!(done.report.refined, "{:?}", done.report.last_error);
    assert!(
        done.report.net.disconnects >= 1,
        "the client never noticed the restart"
    );
    // Recovered: the report says nothing is wrong now.
    assert_eq!(done.report.last_error, None, "after recovering");
    let p = psnr(&done.rgba, &file.rgba);
    assert!(p >= 40.0, "after a restart the image differs: PSNR {p}");
    rt.block_on(server.shutdown()).unwrap();
}

#[test]
fn a_client_with_no_server_says_why_it_drew_nothing() {
    let Some(mut renderer) = headless_or_skip(SIZE.0, SIZE.1).unwrap() else {
        return;
    };
    // A port bound but never listened on, held for the whole test: every
    // connection to it is refused, and no other test's server can take it.
    let refusing = tokio::net::TcpSocket::new_v4().unwrap();
    refusing
        .bind(std::net::SocketAddr::from(([127, 0, 0, 1], 0)))
        .unwrap();
    let port = refusing.local_addr().unwrap().port();
    let out = scratch("no-server").join("never.png");
    let mut j = island_from(format!("http://127.0.0.1:{port}"));
    j.out = Some(out.clone());
    // A render timeout inside the first-connection grace: the timeout ends
    // it, and says what the connection attempts met.
    j.timeout = Duration::from_secs(2);
    let Err(err) = run(&j, &mut renderer, false) else {
        panic!("no server, yet the render succeeded");
    };
    let message = format!("{err:#}");
    assert!(message.contains("no scene header after"), "{message}");
    assert!(message.to_lowercase().contains("refused"), "{message}");
    assert!(!out.exists(), "an image was written");
    // A grace shorter than the timeout: the session gives up first.
    j.timeout = Duration::from_secs(60);
    j.session.first_connect_grace = Duration::from_secs(1);
    let started = Instant::now();
    let Err(err) = run(&j, &mut renderer, false) else {
        panic!("no server, yet the render succeeded");
    };
    let message = format!("{err:#}");
    assert!(
        started.elapsed() < Duration::from_secs(20),
        "gave up only after {:?}: {message}",
        started.elapsed()
    );
    assert!(message.contains("cannot reach the server"), "{message}");
    assert!(message.to_lowercase().contains("refused"), "{message}");
    assert!(!out.exists(), "an image was written");
}

#[test]
fn an_unknown_scene_ends_the_session_at_once_with_the_servers_reason() {
    let rt = runtime();
    let server = serve(&rt, &scratch("unknown-scene"), 0);
    let url = format!("http://{}", server.local_addr());
    let mut viewer = Viewer::open_remote(&url, "nosuch", SessionOptions::default(), 1 << 20)
        .expect("the session starts");
    let started = Instant::now();
    let err = loop {
        if let Err(e) = viewer.pump(Duration::from_millis(50)) {
            break e;
        }
        // Retrying a 404 with backoff would run past this.
        assert!(
            started.elapsed() < Duration::from_secs(10),
            "the client kept retrying an unknown scene"
        );
    };
    let message = format!("{err:#}");
    assert!(message.contains(r#"no scene named "nosuch""#), "{message}");
    rt.block_on(server.shutdown()).unwrap();
}

#[test]
fn a_page_corrupt_on_the_server_is_given_up_and_the_rest_refines() {
    let Some(mut renderer) = headless_or_skip(SIZE.0, SIZE.1).unwrap() else {
        return;
    };
    let (dir, _) = scenes("corrupt-on-server");
    let path = dir.join("island.ff");
    let mut bytes = std::fs::read(&path).unwrap();
    let image = farfield_protocol::paged_file::read_image(&bytes).unwrap();
    assert!(
        image.header.page_count > 2,
        "the scene needs pages below page 0"
    );
    bytes[image.directory().entry(1).unwrap().offset as usize + 40] ^= 0x10;
    std::fs::write(&path, &bytes).unwrap();
    let rt = runtime();
    let server = serve(&rt, &dir, 0);
    let j = island_from(format!("http://{}", server.local_addr()));
    let started = Instant::now();
    let r = run(&j, &mut renderer, false).expect("render");
    // Waiting for a page that never comes would run to the 60 s timeout.
    assert!(
        started.elapsed() < Duration::from_secs(30),
        "waited {:?} for a page the server cannot send",
        started.elapsed()
    );
    assert!(r.report.refined, "{:?}", r.report.last_error);
    let failed = &r.report.pages_failed;
    assert_eq!(failed.len(), 1, "{failed:?}");
    assert_eq!(failed[0].page, 1);
    assert!(failed[0].reason.contains("checksum"), "{failed:?}");
    assert!(r.report.net.pages_unavailable >= 1);
    assert!(r.report.nodes_drawn > 0);
    rt.block_on(server.shutdown()).unwrap();
}

#[test]
fn the_demo_writes_frames_a_csv_and_a_summary() {
    use farfield_cli::commands::demo::{DemoJob, run as demo};
    if headless_or_skip(8, 8).unwrap().is_none() {
        return;
    }
    let out = scratch("demo");
    let job = DemoJob {
        out: out.clone(),
        width: 160,
        height: 90,
        path_seconds: 1.0,
        fps: 4.0,
    };
    let first = demo(&job).expect("demo runs");
    assert!(
        first.built && first.time_to_refined_ms.is_some(),
        "{}",
        first.text
    );
    let csv = std::fs::read_to_string(out.join("frames.csv")).unwrap();
    let rows = csv.lines().count() - 1;
    assert_eq!(rows, first.frames);
    assert!(rows >= 5, "{rows} frames");
    assert!(csv.starts_with(farfield_client::flythrough::CSV_HEADER));
    let pngs = std::fs::read_dir(out.join("frames")).unwrap().count();
    assert_eq!(pngs, rows);
    assert!(
        std::fs::read_to_string(out.join("summary.txt"))
            .unwrap()
            .contains("first image")
    );
    // The second run reuses the built scene.
    let second = demo(&job).expect("demo runs again");
    assert!(!second.built);
}

/// Sessions driven as tasks on one runtime (`farfield_net::websocket::drive`,
/// as load tests run them) fetch every page of a scene, verified, and stop
/// when asked.
#[test]
fn sessions_driven_as_tasks_fetch_every_page() {
    use farfield_net::queue::QueueTransport;
    use farfield_net::websocket::drive;
    use farfield_net::{Session, SessionEvent, stream_url};
    use farfield_protocol::hierarchy::Hierarchy;
    use farfield_protocol::messages::PageWish;
    let (dir, _) = scenes("driven");
    let rt = runtime();
    let server = serve(&rt, &dir, 0);
    let url = stream_url(&format!("http://{}", server.local_addr()), "island");
    let clients: Vec<_> = (0..3)
        .map(|_| {
            let url = url.clone();
            rt.spawn(async move {
                let wire = QueueTransport::default();
                let mut session = Session::open(wire.clone(), url, SessionOptions::default());
                let mut hierarchy: Option<Hierarchy> = None;
                let mut asked = false;
                let started = Instant::now();
                let outcome = drive(&mut session, &wire, |session, events| {
                    for event in events {
                        match event {
                            SessionEvent::Header(header) => {
                                hierarchy = Some(Hierarchy::new(header).expect("header"));
                            }
                            SessionEvent::Page { index, bytes } => {
                                let h = hierarchy.as_mut().expect("the header comes first");
                                h.insert_page(index, &bytes).expect("a verified page");
                            }
                            SessionEvent::Demo(e) => panic!("not in a demo session: {e:?}"),
                        }
                    }
                    let Some(h) = &hierarchy else { return true };
                    let missing: Vec<PageWish> = (0..h.header.page_count)
                        .filter(|&p| !h.is_resident(p as usize))
                        .map(|page| PageWish {
                            page,
                            priority: 1.0,
                        })
                        .collect();
                    if !asked && session.is_connected() {
                        session.request(&missing);
                        asked = true;
                    }
                    !missing.is_empty() && started.elapsed() < Duration::from_secs(30)
                })
                .await;
                (outcome, hierarchy)
            })
        })
        .collect();
    for client in clients {
        let (outcome, hierarchy) = rt.block_on(client).expect("the task");
        outcome.expect("the session did not end in error");
        let h = hierarchy.expect("a header arrived");
        assert_eq!(
            h.resident_pages(),
            h.header.page_count as usize,
            "every page arrived within 30 s"
        );
    }
    rt.block_on(server.shutdown()).unwrap();
}

/// Page 0 corrupt on the server: nothing can be drawn, so the render is
/// not refined, says why, and stops without waiting for its timeout. (It
/// reported `refined: true` over an empty image.)
#[test]
fn a_root_page_that_never_arrives_is_not_refined() {
    let Some(mut renderer) = headless_or_skip(SIZE.0, SIZE.1).unwrap() else {
        return;
    };
    let (dir, _) = scenes("root-corrupt-on-server");
    let path = dir.join("island.ff");
    let mut bytes = std::fs::read(&path).unwrap();
    let image = farfield_protocol::paged_file::read_image(&bytes).unwrap();
    bytes[image.directory().entry(0).unwrap().offset as usize + 40] ^= 0x10;
    std::fs::write(&path, &bytes).unwrap();
    let rt = runtime();
    let server = serve(&rt, &dir, 0);
    let j = island_from(format!("http://{}", server.local_addr()));
    let started = Instant::now();
    let r = run(&j, &mut renderer, false).expect("render");
    assert!(
        started.elapsed() < Duration::from_secs(30),
        "waited {:?} for a root that cannot come",
        started.elapsed()
    );
    assert!(!r.report.refined, "refined over nothing");
    let why = r.report.last_error.clone().unwrap_or_default();
    assert!(why.contains("page 0"), "{why}");
    assert_eq!(r.report.nodes_drawn, 0);
    rt.block_on(server.shutdown()).unwrap();
}
