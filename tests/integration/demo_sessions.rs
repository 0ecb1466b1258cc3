//! Demo sessions on a real server: a presenter and followers (the render
//! command's, and headless viewers'), detaching and re-attaching, late
//! joiners, handing over, the presenter's grace, `/sessions` and the
//! session metrics, and followers sharing the server's disk reads.

use std::net::SocketAddr;
use std::time::{Duration, Instant};

use farfield_client::camera_spec::CameraSpec;
use farfield_client::demo_link::DemoLink;
use farfield_client::frame_loop::{FrameState, traverse_frame};
use farfield_client::viewer::Viewer;
use farfield_memory_server::limits::Limits;
use farfield_memory_server::{RunningServer, ServerConfig};
use farfield_net::SessionOptions;
use farfield_protocol::camera::Camera;
use farfield_render::headless_or_skip;

use crate::streaming::{SIZE, runtime, scenes};

const WAIT: Duration = Duration::from_secs(20);

fn serve_with_grace(
    rt: &tokio::runtime::Runtime,
    dir: &std::path::Path,
    grace: Duration,
) -> RunningServer {
    let config = ServerConfig {
        limits: Limits {
            session_grace: grace,
            ..Limits::default()
        },
        ..ServerConfig::new(dir, SocketAddr::from(([127, 0, 0, 1], 0)))
    };
    rt.block_on(farfield_memory_server::start(config))
        .expect("server")
}

#[test]
fn followers_render_the_presenters_image_from_the_command_line() {
    if headless_or_skip(SIZE.0, SIZE.1).unwrap().is_none() {
        return;
    }
    let (dir, _) = scenes("demo-cli");
    let rt = runtime();
    let server = serve_with_grace(&rt, &dir, Duration::from_secs(30));
    let url = format!("http://{}", server.local_addr());
    let png = |name: &str| dir.join(format!("{name}.png"));
    let size = format!("{}x{}", SIZE.0, SIZE.1);
    let render = |name: &str, role: &[&str], orbit: &str, threshold: &str| {
        let out = png(name);
        let mut args = vec![
            "render",
            "--server",
            &url,
            "--scene",
            "island",
            "--session",
            "demo",
            "--orbit",
            orbit,
            "--threshold",
            threshold,
            "--size",
            &size,
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(role);
        crate::loadtest::cli(&args)
    };
    // A follower before any presenter is told there is no such session.
    let e = render(
        "early",
        &["--follow"],
        "azimuth=0,elevation=10,distance=3",
        "1",
    )
    .expect_err("no session yet");
    assert!(format!("{e:#}").contains("no session named"), "{e:#}");
    render(
        "presenter",
        &["--present"],
        "azimuth=200,elevation=30,distance=1.2",
        "1",
    )
    .expect("present");
    // The presenter left: its seat waits, and followers that join now get
    // its last view (with its threshold, not theirs).
    let sessions = server.sessions();
    assert_eq!(sessions.len(), 1, "{sessions:?}");
    assert!(!sessions[0].presenter_connected);
    let presenter = farfield_image::read_png(png("presenter")).unwrap();
    for i in 0..3 {
        let name = format!("follower{i}");
        render(
            &name,
            &["--follow"],
            "azimuth=0,elevation=10,distance=3",
            "8",
        )
        .expect("follow");
        let follower = farfield_image::read_png(png(&name)).unwrap();
        assert!(
            follower == presenter,
            "follower {i}'s image differs from the presenter's"
        );
    }
    // Someone else presenting while the seat waits takes it.
    render(
        "presenter2",
        &["--present"],
        "azimuth=20,elevation=30,distance=2",
        "1",
    )
    .expect("a new presenter takes the empty seat");
    rt.block_on(server.shutdown()).expect("shutdown");
}

/// A headless client: a viewer, its demo link and its traversal.
pub(crate) struct Member {
    pub(crate) viewer: Viewer,
    pub(crate) link: DemoLink,
    cut: FrameState,
}

impl Member {
    pub(crate) fn join(url: &str, present: bool) -> Self {
        let mut viewer =
            Viewer::open_remote(url, "island", SessionOptions::default(), usize::MAX).unwrap();
        let link = DemoLink::join(&mut viewer, "demo", present).unwrap();
        Self {
            viewer,
            link,
            cut: FrameState::default(),
        }
    }

    fn pump(&mut self) {
        self.viewer.pump(Duration::from_millis(5)).expect("pump");
        self.link.update(&mut self.viewer);
    }

    /// Pumps until `done` holds.
    pub(crate) fn until(&mut self, what: &str, mut done: impl FnMut(&Self) -> bool) {
        let started = Instant::now();
        while !done(self) {
            assert!(started.elapsed() < WAIT, "waited in vain for {what}");
            self.pump();
        }
    }

    fn you(&self) -> u64 {
        self.link.state.as_ref().expect("a state").you
    }

    /// Refines `camera` headless: every wanted page in.
    fn refine(&mut self, camera: &Camera) {
        let started = Instant::now();
        loop {
            self.pump();
            if self.viewer.hierarchy().is_some_and(|h| h.is_resident(0)) {
                traverse_frame(&mut self.viewer, camera, 1.0, 1, &mut self.cut).unwrap();
                if self.cut.missing(&self.viewer) == 0 && self.viewer.outstanding() == 0 {
                    return;
                }
            }
            assert!(started.elapsed() < WAIT, "not refined");
        }
    }
}

pub(crate) fn orbit(azimuth: f64, member: &Member) -> Camera {
    CameraSpec::Orbit {
        azimuth_deg: azimuth,
        elevation_deg: 25.0,
        distance: 2.0,
    }
    .resolve(member.viewer.header().expect("header"), SIZE.0, SIZE.1)
}

#[test]
fn followers_detach_and_reattach_late_joiners_catch_up_and_control_is_handed_over() {
    let (dir, _) = scenes("demo-live");
    let rt = runtime();
    let server = serve_with_grace(&rt, &dir, Duration::from_millis(500));
    let url = format!("http://{}", server.local_addr());
    let mut presenter = Member::join(&url, true);
    presenter.until("the presenter's seat", |m| {
        m.link.is_presenting() && m.viewer.header().is_some()
    });
    let mut a = Member::join(&url, false);
    let mut b = Member::join(&url, false);
    for f in [&mut a, &mut b] {
        f.until("joining", |m| m.link.state.is_some());
        assert!(f.link.camera(SIZE.0, SIZE.1).is_none(), "no view yet");
    }
    let view_a = orbit(10.0, &presenter);
    presenter
        .link
        .show(&mut presenter.viewer, &view_a, Vec::new());
    for f in [&mut a, &mut b] {
        f.until("the first view", |m| {
            m.link.camera(SIZE.0, SIZE.1) == Some(view_a)
        });
    }
    let listed = server.sessions();
    assert_eq!(
        (listed[0].followers, listed[0].presenter_connected),
        (2, true),
        "{listed:?}"
    );
    let metrics = server.metrics_text();
    assert!(
        metrics.contains("farfield_session_followers{session=\"demo\"} 2"),
        "{metrics}"
    );

    // A detaches and looks around: the presenter's next view is not drawn.
    a.link.attached = false;
    let view_b = orbit(100.0, &presenter);
    presenter
        .link
        .show(&mut presenter.viewer, &view_b, Vec::new());
    b.until("the second view", |m| {
        m.link.camera(SIZE.0, SIZE.1) == Some(view_b)
    });
    a.until("the second view's arrival", |m| {
        m.link.latest.as_ref().is_some_and(|(seq, ..)| *seq == 2)
    });
    assert_eq!(a.link.camera(SIZE.0, SIZE.1), None, "detached");
    // Re-attached: back at the presenter's view at once.
    a.link.attached = true;
    assert_eq!(a.link.camera(SIZE.0, SIZE.1), Some(view_b));

    // A late joiner starts from the presenter's view now, and its pages
    // come coarse first: page 0 before anything it asks for.
    let mut late = Member::join(&url, false);
    late.until("the view, late", |m| {
        m.link.camera(SIZE.0, SIZE.1) == Some(view_b)
    });
    late.refine(&view_b);
    b.refine(&view_b);
    let (late_h, b_h) = (
        late.viewer.hierarchy().unwrap(),
        b.viewer.hierarchy().unwrap(),
    );
    assert!(late_h.is_resident(0));
    for p in b.cut.touched_pages() {
        assert!(late_h.is_resident(*p as usize) && b_h.is_resident(*p as usize));
    }

    // The presenter hands over to B; B's views now reach A.
    let b_id = b.you();
    presenter.link.hand_over(&mut presenter.viewer, b_id);
    b.until("the seat", |m| m.link.is_presenting());
    presenter.until("following", |m| {
        m.link.state.is_some() && !m.link.is_presenting()
    });
    let view_c = orbit(250.0, &b);
    b.link.show(&mut b.viewer, &view_c, Vec::new());
    a.until("B's view", |m| {
        m.link.camera(SIZE.0, SIZE.1) == Some(view_c)
    });

    // B leaves: the followers are told, then the session closes after the grace.
    drop(b);
    a.until("the presenter away", |m| {
        m.link
            .state
            .as_ref()
            .is_some_and(|s| !s.presenter_connected && s.closes_in_s.is_some())
    });
    a.until("the session closed", |m| m.link.closed.is_some());
    assert!(server.sessions().is_empty());
    drop((a, late, presenter));
    rt.block_on(server.shutdown()).expect("shutdown");
}

#[test]
fn eight_followers_cost_the_disk_about_what_one_client_costs() {
    let (dir, _) = scenes("demo-reads");
    let rt = runtime();
    // One client alone, at the view.
    let alone = serve_with_grace(&rt, &dir, Duration::from_secs(5));
    let url = format!("http://{}", alone.local_addr());
    let mut one = Member::join(&url, true);
    one.until("the header", |m| m.viewer.header().is_some());
    let camera = orbit(200.0, &one);
    one.refine(&camera);
    let one_reads = alone.metrics().disk_reads;
    drop(one);
    rt.block_on(alone.shutdown()).expect("shutdown");

    // A presenter and 8 followers, each on its own thread, at once.
    let server = serve_with_grace(&rt, &dir, Duration::from_secs(5));
    let url = format!("http://{}", server.local_addr());
    let mut presenter = Member::join(&url, true);
    presenter.until("the seat", |m| {
        m.link.is_presenting() && m.viewer.header().is_some()
    });
    let followers: Vec<_> = (0..8)
        .map(|_| {
            let url = url.clone();
            std::thread::spawn(move || {
                let mut f = Member::join(&url, false);
                f.until("the view", |m| m.link.camera(SIZE.0, SIZE.1).is_some());
                let camera = f.link.camera(SIZE.0, SIZE.1).unwrap();
                f.refine(&camera);
                f.viewer.stats().pages_received
            })
        })
        .collect();
    presenter
        .link
        .show(&mut presenter.viewer, &camera, Vec::new());
    presenter.refine(&camera);
    let received: u64 = followers.into_iter().map(|t| t.join().unwrap()).sum();
    let reads = server.metrics().disk_reads;
    eprintln!(
        "disk reads: one client {one_reads}; presenter and 8 followers {reads} ({received} pages sent to the followers)"
    );
    assert!(received > 8, "the followers streamed their own pages");
    assert!(
        reads as f64 <= 1.2 * one_reads as f64,
        "{reads} pages read for 9 clients, {one_reads} for one"
    );
    drop(presenter);
    rt.block_on(server.shutdown()).expect("shutdown");
}

/// The server reads ahead along a presenter's motion: a presenter that
/// moves in (and asks for no pages itself) makes the server walk where it
/// will be and read those pages, so a client there finds them in the
/// cache. The same client after a presenter at rest finds the disk.
#[test]
fn the_server_reads_ahead_along_the_presenters_motion() {
    // More pages than the small island has, so a walk has work to do.
    let dir = farfield_tests::scratch("demo-lookahead");
    let mut params = farfield_builder::import::Params::default();
    params.set("trees", 12);
    farfield_store::write_atomic(
        &dir.join("island.ff"),
        &crate::build(farfield_builder::import::load_input("gen:island", &params).unwrap()),
    )
    .unwrap();
    let rt = runtime();
    let at = |distance: f64, m: &Member| {
        CameraSpec::Orbit {
            azimuth_deg: 40.0,
            elevation_deg: 20.0,
            distance,
        }
        .resolve(m.viewer.header().expect("header"), SIZE.0, SIZE.1)
    };
    // (passes walked, pages read for a client where the motion leads,
    // pages it received)
    let run = |moving: bool| {
        let server = serve_with_grace(&rt, &dir, Duration::from_secs(5));
        let url = format!("http://{}", server.local_addr());
        let mut presenter = Member::join(&url, true);
        presenter.until("the seat", |m| {
            m.link.is_presenting() && m.viewer.header().is_some()
        });
        // From 3.0 to 2.8 in 100 ms: half a second on is 1.8.
        let views = if moving { vec![3.0, 2.8] } else { vec![2.8] };
        for (i, distance) in views.into_iter().enumerate() {
            if i > 0 {
                std::thread::sleep(Duration::from_millis(100));
            }
            let camera = at(distance, &presenter);
            presenter
                .link
                .show(&mut presenter.viewer, &camera, Vec::new());
            presenter
                .viewer
                .pump(Duration::from_millis(5))
                .expect("pump");
        }
        // The walk ends before its pass is counted.
        let started = Instant::now();
        while moving && server.metrics().lookahead_passes == 0 {
            assert!(started.elapsed() < WAIT, "no look-ahead walk");
            presenter
                .viewer
                .pump(Duration::from_millis(10))
                .expect("pump");
        }
        std::thread::sleep(Duration::from_millis(200));
        let before = server.metrics();
        let mut client = Member::join(&url, false);
        client.until("the header", |m| m.viewer.header().is_some());
        let ahead = at(1.8, &client);
        client.refine(&ahead);
        let after = server.metrics();
        let result = (
            after.lookahead_passes,
            after.disk_reads - before.disk_reads,
            client.viewer.stats().pages_received,
        );
        drop((presenter, client));
        rt.block_on(server.shutdown()).expect("shutdown");
        result
    };
    let (passes, reads_ahead, received_ahead) = run(true);
    let (rest_passes, reads_rest, received_rest) = run(false);
    eprintln!(
        "look-ahead: {passes} walks; the client there made {reads_ahead} disk reads for \
         {received_ahead} pages; after a presenter at rest, {reads_rest} for {received_rest}"
    );
    assert_eq!(rest_passes, 0, "a presenter at rest is not walked ahead");
    assert!(
        received_ahead > 10 && received_rest > 10,
        "the client streamed"
    );
    assert!(
        reads_rest as f64 >= 0.5 * received_rest as f64,
        "without look-ahead the pages come from the disk"
    );
    assert!(
        (reads_ahead as f64) <= 0.25 * received_ahead as f64,
        "{reads_ahead} disk reads for {received_ahead} pages: the walk did not read ahead"
    );
}
