//! The paged directory end to end: a viewer against a real server on port
//! 0 reaches every page of a scene whose directory spans many directory
//! pages, learning the directory as it goes, each page sent once.

use std::net::SocketAddr;
use std::time::{Duration, Instant};

use farfield_builder::import::{Params, load_input};
use farfield_builder::{BuildOptions, build_spheres};
use farfield_client::viewer::Viewer;
use farfield_memory_server::{ServerConfig, start};
use farfield_net::SessionOptions;
use farfield_protocol::messages::PageWish;
use farfield_store::write_atomic;
use farfield_tests::scratch;

use crate::streaming::runtime;

#[test]
fn a_viewer_reaches_every_page_through_directory_pages() {
    let dir = scratch("directory-every-page");
    let mut params = Params::default();
    params.set("size", 64);
    params.set("trees", 4);
    let scene = load_input("gen:island", &params).expect("gen:island");
    let options = BuildOptions {
        page_bytes: 128,
        ..BuildOptions::default()
    };
    let file = build_spheres(scene, &options).expect("build").0;
    let (pages, directory_pages) = (file.header.page_count, file.header.directory_pages);
    assert!(
        directory_pages > 3,
        "{pages} pages in {directory_pages} directory pages"
    );
    write_atomic(&dir.join("island.ff"), &file).expect("write");

    let rt = runtime();
    let mut config = ServerConfig::new(&dir, SocketAddr::from(([127, 0, 0, 1], 0)));
    config.rescan_interval = Duration::ZERO;
    let server = rt.block_on(start(config)).expect("server");
    let url = format!("http://{}", server.local_addr());
    let mut viewer =
        Viewer::open_remote(&url, "island", SessionOptions::default(), usize::MAX).expect("viewer");
    let deadline = Instant::now() + Duration::from_secs(120);
    while viewer.header().is_none() {
        viewer.pump(Duration::from_millis(50)).expect("header");
        assert!(Instant::now() < deadline, "no header");
    }
    // The first image: the header, the root directory page and page 0.
    while !viewer.hierarchy().is_some_and(|h| h.is_resident(0)) {
        viewer.pump(Duration::from_millis(50)).expect("page 0");
        assert!(Instant::now() < deadline, "no page 0");
    }
    let first = viewer.hierarchy().unwrap().directory().inserted();
    assert_eq!(
        first, 1,
        "only the root directory page before the first image"
    );

    // Every page wished for, coarse first: a wish for a page the viewer
    // cannot place yet goes out as one for the directory page that does.
    loop {
        viewer.pump(Duration::from_millis(5)).expect("pump");
        let h = viewer.hierarchy().expect("hierarchy");
        let wanted: Vec<PageWish> = (0..pages)
            .filter(|&p| !h.is_resident(p as usize))
            .map(|page| PageWish {
                page,
                priority: (pages - page) as f32,
            })
            .collect();
        if wanted.is_empty() {
            break;
        }
        viewer.request(&wanted);
        assert!(Instant::now() < deadline, "not every page in 120 s");
    }
    let h = viewer.hierarchy().expect("hierarchy");
    let resident = (0..pages as usize).filter(|&p| h.is_resident(p)).count();
    assert_eq!(resident, pages as usize, "every page resident");
    assert!(h.directory().is_complete(), "every directory page arrived");
    // Each sent once (a page's directory page is never pushed after it).
    let sent = server.metrics().pages_served;
    assert_eq!(sent, u64::from(pages + directory_pages), "pages sent once");
    rt.block_on(server.shutdown()).expect("shutdown");
}
