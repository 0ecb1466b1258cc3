//! The viewer over a session with no socket: what arrives is verified into
//! the resident pages, what fails is reported to the session, and the LRU
//! keeps the cache within its bytes.

use std::time::Duration;

use farfield_builder::import::{Params, load_input};
use farfield_builder::{BuildOptions, PagedFile, build_spheres};
use farfield_net::queue::QueueTransport;
use farfield_net::{MAX_PAGE_FAILURES, SessionOptions, TransportEvent};
use farfield_protocol::codec::{encode_header_frame, encode_page_frame};

use super::*;

fn scene() -> PagedFile {
    let mut params = Params::default();
    params.set("size", 64);
    params.set("trees", 1);
    let options = BuildOptions {
        page_bytes: 1024,
        ..BuildOptions::default()
    };
    let scene = load_input("gen:island", &params).expect("gen:island");
    build_spheres(scene, &options).expect("build").0
}

fn frame(bytes: Vec<u8>) -> TransportEvent {
    TransportEvent::Frame(bytes.into())
}

/// A viewer whose session has opened and holds page 0 of `file`.
fn viewer(file: &PagedFile, cache_bytes: usize) -> (Viewer, QueueTransport) {
    let wire = QueueTransport::default();
    let mut v = Viewer::over(
        Box::new(wire.clone()),
        "http://test",
        "island",
        SessionOptions::default(),
        cache_bytes,
    );
    wire.push(TransportEvent::Opened);
    wire.push(frame(encode_header_frame(&file.header.encode())));
    wire.push(frame(encode_page_frame(&file.directory_pages[0])));
    wire.push(frame(encode_page_frame(&file.pages[0])));
    assert_eq!(v.pump(Duration::ZERO).expect("pump"), 2);
    assert!(v.is_connected());
    assert!(v.hierarchy().expect("header").is_resident(0));
    assert_eq!(wire.connects(), vec!["ws://test/scenes/island/stream"]);
    (v, wire)
}

#[test]
fn a_page_failing_its_checksum_is_counted_never_resident_and_given_up_after_three() {
    let file = scene();
    let (mut v, wire) = viewer(&file, usize::MAX);
    let mut bad = file.pages[1].clone();
    bad[40] ^= 0x20;
    for attempt in 1..=MAX_PAGE_FAILURES {
        wire.push(frame(encode_page_frame(&bad)));
        assert_eq!(v.pump(Duration::ZERO).expect("pump"), 0);
        assert!(!v.hierarchy().unwrap().is_resident(1));
        assert_eq!(v.stats().pages_rejected, u64::from(attempt));
    }
    let failed = v.failed_pages();
    assert_eq!(failed.len(), 1);
    assert_eq!(failed[0].page, 1);
    assert!(failed[0].reason.contains("page 1"), "{failed:?}");
    assert!(v.gave_up(1));
    // The good bytes are still taken.
    wire.push(frame(encode_page_frame(&file.pages[1])));
    assert_eq!(v.pump(Duration::ZERO).expect("pump"), 1);
    assert!(v.hierarchy().unwrap().is_resident(1));
}

#[test]
fn the_least_recently_used_pages_go_first_and_page_zero_stays() {
    let file = scene();
    assert!(file.pages.len() >= 4, "{} pages", file.pages.len());
    // Room for page 0 and about two more.
    let budget = file.pages[..3].iter().map(Vec::len).sum::<usize>() + 64;
    let (mut v, wire) = viewer(&file, budget);
    for p in 1..4 {
        wire.push(frame(encode_page_frame(&file.pages[p])));
        v.pump(Duration::ZERO).expect("pump");
        v.touch(&[0]);
    }
    let h = v.hierarchy().unwrap();
    assert!(
        h.resident_bytes() <= budget,
        "{} > {budget}",
        h.resident_bytes()
    );
    assert!(h.is_resident(0), "page 0 is never evicted");
    assert!(!h.is_resident(1), "page 1 was the least recently used");
    assert!(h.is_resident(3), "the newest page stays");
}

#[test]
fn a_zero_budget_inserts_one_page_a_call_and_keeps_the_rest_in_order() {
    let file = scene();
    assert!(file.pages.len() >= 4, "{} pages", file.pages.len());
    let (mut v, wire) = viewer(&file, usize::MAX);
    for p in 1..4 {
        wire.push(frame(encode_page_frame(&file.pages[p])));
    }
    for (call, page) in (1..4).enumerate() {
        assert_eq!(v.pump_for(Duration::ZERO).expect("pump"), 1, "call {call}");
        assert!(v.hierarchy().unwrap().is_resident(page));
        assert_eq!(v.pending_pages(), 3 - page);
    }
    assert_eq!(v.pump_for(Duration::ZERO).expect("pump"), 0);
    // A generous budget takes everything at once.
    let file2 = scene();
    let (mut w, wire2) = viewer(&file2, usize::MAX);
    for p in 1..4 {
        wire2.push(frame(encode_page_frame(&file2.pages[p])));
    }
    assert_eq!(w.pump_for(Duration::from_secs(10)).expect("pump"), 3);
}

#[test]
fn requests_stop_where_the_cache_could_not_keep_them_beside_the_frames_pages() {
    let file = scene();
    assert!(file.pages.len() >= 8, "{} pages", file.pages.len());
    let len = |p: usize| file.pages[p].len();
    // Room for pages 0 and 1 (the frame's) and for pages 2 and 3 more.
    let budget = (0..4).map(len).sum::<usize>() + 8;
    let (mut v, wire) = viewer(&file, budget);
    wire.push(frame(encode_page_frame(&file.pages[1])));
    v.pump(Duration::ZERO).expect("pump");
    v.touch(&[0, 1]);
    let wanted: Vec<PageWish> = (2..8)
        .map(|p| PageWish {
            page: p,
            priority: 100.0 - p as f32,
        })
        .collect();
    v.request(&wanted);
    assert_eq!(v.outstanding(), 2, "pages 2 and 3 fit, 4 does not");
    // A cache with room for everything asks for everything.
    let (mut roomy, _) = viewer(&file, usize::MAX);
    roomy.touch(&[0]);
    roomy.request(&wanted);
    assert_eq!(roomy.outstanding(), 6);
    // A cache the frame already fills asks for nothing (the page would
    // push out one the frame draws), and cancels what it had asked for.
    let (mut full, full_wire) = viewer(&file, len(0) + len(1));
    full_wire.push(frame(encode_page_frame(&file.pages[1])));
    full.pump(Duration::ZERO).expect("pump");
    full.request(&wanted);
    assert!(full.outstanding() > 0, "before the frame touched its pages");
    full.touch(&[0, 1]);
    full.request(&wanted);
    assert_eq!(full.outstanding(), 0);
}

/// Pages that arrived and wait for their turn to be inserted (a frame
/// inserts for a few milliseconds only) are not asked for again: the
/// session acknowledged them, so the server would send each once more.
#[test]
fn pages_waiting_to_be_inserted_are_not_asked_for_again() {
    let file = scene();
    assert!(file.pages.len() >= 5, "{} pages", file.pages.len());
    let (mut v, wire) = viewer(&file, usize::MAX);
    for p in 1..4 {
        wire.push(frame(encode_page_frame(&file.pages[p])));
    }
    assert_eq!(v.pump_for(Duration::ZERO).expect("pump"), 1);
    assert_eq!(v.pending_pages(), 2, "pages 2 and 3 wait");
    let wanted: Vec<PageWish> = (2..5)
        .map(|p| PageWish {
            page: p,
            priority: 10.0 - p as f32,
        })
        .collect();
    v.request(&wanted);
    assert_eq!(v.outstanding(), 1, "only page 4 is asked for");
    v.pump(Duration::ZERO).expect("pump");
    let h = v.hierarchy().unwrap();
    assert!(h.is_resident(2) && h.is_resident(3), "and they were kept");
}

/// A scene of small pages, its directory in several directory pages.
fn many_pages() -> PagedFile {
    let mut params = Params::default();
    params.set("size", 64);
    params.set("trees", 2);
    let options = BuildOptions {
        page_bytes: 64,
        ..BuildOptions::default()
    };
    let scene = load_input("gen:island", &params).expect("gen:island");
    let file = build_spheres(scene, &options).expect("build").0;
    assert!(file.header.directory_pages > 2, "{:?}", file.header);
    file
}

#[test]
fn a_page_past_the_root_is_wished_for_through_its_directory_page() {
    let file = many_pages();
    let (mut v, wire) = viewer(&file, usize::MAX);
    let pages = file.header.page_count;
    let last = pages - 1;
    assert!(v.hierarchy().unwrap().directory().entry(last).is_none());
    // A wish for the last page becomes one for the directory page that
    // places it, at its priority.
    wire.take_sent();
    v.request(&[PageWish {
        page: last,
        priority: 7.0,
    }]);
    let directory = file.directory.path_to(last)[1];
    assert!(directory > pages, "{directory}");
    let asked: Vec<PageWish> = wire
        .take_sent()
        .iter()
        .filter_map(|f| match farfield_protocol::codec::decode_control(f) {
            Ok(farfield_protocol::messages::ClientMessage::Request { pages }) => Some(pages),
            _ => None,
        })
        .flatten()
        .collect();
    assert_eq!(
        asked,
        vec![PageWish {
            page: directory,
            priority: 7.0
        }]
    );
    // Once it arrived (and the ones between), the page itself is placed.
    for d in file.directory.path_to(last).into_iter().skip(1) {
        let bytes = file.page_bytes(d).unwrap().to_vec();
        wire.push(frame(encode_page_frame(&bytes)));
    }
    v.pump(Duration::ZERO).expect("pump");
    assert!(v.hierarchy().unwrap().directory().entry(last).is_some());
    wire.push(frame(encode_page_frame(&file.pages[last as usize])));
    assert_eq!(v.pump(Duration::ZERO).expect("pump"), 1);
    assert!(v.hierarchy().unwrap().is_resident(last as usize));
}

#[test]
fn a_damaged_directory_page_is_refused_and_asked_for_again_like_a_page() {
    let file = many_pages();
    let (mut v, wire) = viewer(&file, usize::MAX);
    let id = file.header.page_count + 1;
    let mut bad = file.page_bytes(id).unwrap().to_vec();
    bad[60] ^= 0x20;
    for attempt in 1..=MAX_PAGE_FAILURES {
        wire.push(frame(encode_page_frame(&bad)));
        assert_eq!(v.pump(Duration::ZERO).expect("pump"), 0);
        assert!(!v.hierarchy().unwrap().is_resident(id as usize));
        assert_eq!(v.stats().pages_rejected, u64::from(attempt));
    }
    assert!(v.gave_up(id));
    // The good bytes are still taken.
    wire.push(frame(encode_page_frame(file.page_bytes(id).unwrap())));
    assert_eq!(v.pump(Duration::ZERO).expect("pump"), 1);
    assert!(v.hierarchy().unwrap().is_resident(id as usize));
}
