//! Pages sent once: one viewer opening a scene of every kind, as the
//! window and browser viewers do (pages inserted for a few milliseconds a
//! frame, a traversal every frame, with the default settings), against a
//! real server on port 0. The server's count of pages sent, over the
//! pages the viewer keeps, must stay at most 1.05 (it was 2.6 on the PLP
//! city: pages that had arrived and were still waiting to be inserted were
//! asked for again, and the server sent them again).

use std::net::SocketAddr;
use std::time::{Duration, Instant};

use farfield_builder::bsp::{BspOptions, build_bsp};
use farfield_builder::cubes::{CubeOptions, build_cubes};
use farfield_builder::import::{Params, load_input};
use farfield_builder::plp::{PlpOptions, build_plp};
use farfield_builder::{BuildOptions, PagedFile, build_spheres};
use farfield_client::camera_spec::CameraSpec;
use farfield_client::frame_loop::{FrameState, traverse_frame};
use farfield_client::viewer::Viewer;
use farfield_memory_server::{ServerConfig, start};
use farfield_net::SessionOptions;
use farfield_store::write_atomic;
use farfield_tests::{scratch, shared_data};

use crate::streaming::runtime;

/// What the viewer app inserts a frame (its `PAGE_BUDGET`).
const INSERT_BUDGET: Duration = Duration::from_millis(4);
/// The viewers' default page cache (`Settings::cache_mib`).
const CACHE_BYTES: usize = 512 << 20;

/// The scenes: every hierarchy kind from a generator with the default
/// build options, and the bunny when the shared data is there.
fn scenes() -> Vec<(&'static str, PagedFile)> {
    let load = |input: &str, params: &[(&str, u32)]| {
        let mut p = Params::default();
        for &(k, v) in params {
            p.set(k, v);
        }
        load_input(input, &p).expect(input)
    };
    let spheres = |scene| {
        build_spheres(scene, &BuildOptions::default())
            .expect("spheres")
            .0
    };
    let mut scenes = vec![
        (
            "island",
            spheres(load("gen:island", &[("size", 96), ("trees", 8)])),
        ),
        (
            "tree-cubes",
            build_cubes(load("gen:tree", &[]), &CubeOptions::default())
                .expect("cubes")
                .0,
        ),
        (
            "city-plp",
            build_plp(&load("gen:city", &[("grid", 4)]), &PlpOptions::default())
                .expect("plp")
                .0,
        ),
        (
            "island-bsp",
            build_bsp(
                &load("gen:island", &[("size", 64), ("trees", 4)]),
                &BspOptions::default(),
            )
            .expect("bsp")
            .0,
        ),
    ];
    if let Some(data) = shared_data() {
        let bunny = load_input(
            data.join("stanford-bunny.obj").to_str().unwrap(),
            &Params::default(),
        )
        .expect("bunny");
        scenes.push(("bunny", spheres(bunny)));
    }
    scenes
}

#[test]
fn one_viewer_is_sent_each_page_it_keeps_once() {
    let dir = scratch("repeats");
    let scenes = scenes();
    for (name, file) in &scenes {
        write_atomic(&dir.join(format!("{name}.ff")), file).expect("write");
    }
    let mut over = Vec::new();
    // The viewers' budget; and one page a frame, as a slow machine or a
    // scene of large pages gets, where arrived pages wait longest.
    for (name, budget) in scenes
        .iter()
        .flat_map(|(name, _)| [(name, INSERT_BUDGET), (name, Duration::ZERO)])
    {
        let rt = runtime();
        let mut config = ServerConfig::new(&dir, SocketAddr::from(([127, 0, 0, 1], 0)));
        config.rescan_interval = Duration::ZERO;
        let server = rt.block_on(start(config)).expect("server");
        let url = format!("http://{}", server.local_addr());
        let mut viewer = Viewer::open_remote(&url, name, SessionOptions::default(), CACHE_BYTES)
            .expect("viewer");
        let deadline = Instant::now() + Duration::from_secs(60);
        while viewer.header().is_none() {
            viewer.pump(Duration::from_millis(50)).expect("header");
            assert!(Instant::now() < deadline, "{name}: no header");
        }
        let camera = CameraSpec::default().resolve(viewer.header().expect("header"), 800, 600);
        let mut cut = FrameState::default();
        let mut frames = 0;
        loop {
            viewer.pump_for(budget).expect("pump");
            traverse_frame(&mut viewer, &camera, 1.0, 1, &mut cut).expect("traverse");
            frames += 1;
            let refined =
                cut.wanted().is_empty() && viewer.outstanding() == 0 && viewer.pending_pages() == 0;
            if refined {
                break;
            }
            assert!(Instant::now() < deadline, "{name}: not refined in 60 s");
            // A frame's drawing, in which pages keep arriving.
            std::thread::sleep(Duration::from_millis(10));
        }
        let h = viewer.hierarchy().expect("hierarchy");
        // Pages and the directory pages that placed them.
        let kept = (0..h.id_count() as usize)
            .filter(|&p| h.is_resident(p))
            .count() as u64;
        let sent = server.metrics().pages_served;
        let ratio = sent as f64 / kept.max(1) as f64;
        println!(
            "{name} ({budget:?} a frame): {sent} pages sent, {kept} kept ({ratio:.3}), {frames} frames"
        );
        assert!(kept > 1, "{name}: the view needs more than the root");
        if ratio > 1.05 {
            over.push(format!(
                "{name} ({budget:?} a frame): {sent} pages sent for {kept} kept ({ratio:.2})"
            ));
        }
        rt.block_on(server.shutdown()).expect("shutdown");
    }
    assert!(
        over.is_empty(),
        "pages sent more than once:\n{}",
        over.join("\n")
    );
}
