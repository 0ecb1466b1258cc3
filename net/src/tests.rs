//! The session's state machine without a socket: an in-memory transport
//! plays the server, byte for byte.

use std::time::Duration;

use farfield_builder::import::{Params, load_input};
use farfield_builder::{BuildOptions, PagedFile, build_spheres};
use farfield_protocol::codec::{
    decode_control, encode_control, encode_header_frame, encode_page_frame,
};
use farfield_protocol::hierarchy::Hierarchy;
use farfield_protocol::messages::{
    ClientMessage, MAX_HEADER_BYTES, PROTOCOL_VERSION, PageWish, ServerMessage,
};

use super::*;
use crate::queue::QueueTransport;
use crate::transport::Closing;

/// A small generated scene with several pages.
fn scene() -> PagedFile {
    let mut params = Params::default();
    params.set("size", 64);
    params.set("trees", 1);
    let (file, _) = build_spheres(
        load_input("gen:island", &params).expect("gen:island"),
        &BuildOptions {
            page_bytes: 1024,
            ..BuildOptions::default()
        },
    )
    .expect("build");
    assert!(file.pages.len() >= 4, "{} pages", file.pages.len());
    file
}

fn frame(bytes: Vec<u8>) -> TransportEvent {
    TransportEvent::Frame(bytes.into())
}

fn server_hello() -> TransportEvent {
    frame(encode_control(&ServerMessage::Hello {
        protocol_version: PROTOCOL_VERSION,
        server: "test".into(),
    }))
}

/// A session whose transport has opened and delivered the header.
fn connected(file: &PagedFile) -> (Session<QueueTransport>, QueueTransport) {
    let wire = QueueTransport::default();
    let mut s = Session::open(
        wire.clone(),
        "ws://test/scenes/a/stream".into(),
        SessionOptions::default(),
    );
    wire.push(TransportEvent::Opened);
    wire.push(server_hello());
    wire.push(frame(encode_header_frame(&file.header.encode())));
    let events = s.pump(Duration::ZERO).expect("pump");
    assert_eq!(events, vec![SessionEvent::Header(file.header.clone())]);
    assert!(s.is_connected());
    (s, wire)
}

/// The control messages the session sent since the last call.
fn sent(wire: &QueueTransport) -> Vec<ClientMessage> {
    wire.take_sent()
        .iter()
        .map(|f| decode_control(f).expect("client message"))
        .collect()
}

fn wanted(pages: &[u32]) -> Vec<PageWish> {
    pages
        .iter()
        .map(|&page| PageWish {
            page,
            priority: 10.0,
        })
        .collect()
}

fn requested(messages: &[ClientMessage]) -> Vec<u32> {
    let mut pages: Vec<u32> = messages
        .iter()
        .flat_map(|m| match m {
            ClientMessage::Request { pages } => pages.iter().map(|w| w.page).collect(),
            _ => Vec::new(),
        })
        .collect();
    pages.sort_unstable();
    pages
}

#[test]
fn hello_first_then_requests_cancels_and_acknowledgements() {
    let file = scene();
    let (mut s, wire) = connected(&file);
    let hello = sent(&wire);
    assert!(
        matches!(hello.as_slice(), [ClientMessage::Hello { protocol_version, .. }] if *protocol_version == PROTOCOL_VERSION),
        "{hello:?}"
    );
    s.request(&wanted(&[1, 2, 3]));
    assert_eq!(requested(&sent(&wire)), vec![1, 2, 3]);
    assert_eq!(s.outstanding(), 3);
    // The same wishes again send nothing; one dropped is cancelled.
    s.request(&wanted(&[1, 2, 3]));
    assert!(sent(&wire).is_empty());
    s.request(&wanted(&[1, 2]));
    assert!(matches!(sent(&wire).as_slice(), [ClientMessage::Cancel { pages }] if pages == &[3]),);
    assert_eq!(s.stats.pages_cancelled, 1);
    // A page that arrives is handed out and acknowledged in the same pump.
    wire.push(frame(encode_page_frame(&file.pages[1])));
    let events = s.pump(Duration::ZERO).expect("pump");
    assert!(
        matches!(events.as_slice(), [SessionEvent::Page { index: 1, bytes }] if bytes[..] == file.pages[1][..])
    );
    assert!(matches!(sent(&wire).as_slice(), [ClientMessage::Received { pages }] if pages == &[1]));
    assert_eq!(s.outstanding(), 1);
    assert_eq!(s.stats.pages_received, 1);
    assert_eq!(s.stats.bytes_received, file.pages[1].len() as u64);
}

#[test]
fn a_corrupt_page_is_asked_for_again_and_given_up_after_three_failures() {
    let file = scene();
    let (mut s, wire) = connected(&file);
    let mut h =
        Hierarchy::with_directory(file.header.clone(), file.directory.clone()).expect("header");
    h.insert_page(0, &file.pages[0]).expect("page 0");
    let mut bad = file.pages[2].clone();
    bad[40] ^= 0x20;
    sent(&wire);
    for attempt in 1..=MAX_PAGE_FAILURES {
        s.request(&wanted(&[2]));
        assert_eq!(
            requested(&sent(&wire)),
            vec![2],
            "attempt {attempt} asks again"
        );
        wire.push(frame(encode_page_frame(&bad)));
        for event in s.pump(Duration::ZERO).expect("pump") {
            if let SessionEvent::Page { index, bytes } = event {
                let error = h.insert_page(index, &bytes).expect_err("corrupt");
                s.page_rejected(index, &error);
            }
        }
        // Still acknowledged, so that it can be asked for again.
        assert!(
            matches!(sent(&wire).as_slice(), [ClientMessage::Received { pages }] if pages == &[2])
        );
        assert!(!h.is_resident(2));
        assert_eq!(s.stats.pages_rejected, u64::from(attempt));
    }
    assert!(s.gave_up(2));
    s.request(&wanted(&[2, 3]));
    assert_eq!(
        requested(&sent(&wire)),
        vec![3],
        "a page given up is not asked for"
    );
    let failed = s.failed_pages();
    assert_eq!(failed.len(), 1);
    assert_eq!(failed[0].page, 2);
    assert!(failed[0].reason.contains("page 2"), "{failed:?}");
    // The good bytes are still taken.
    assert!(h.insert_page(2, &file.pages[2]).is_ok());
}

#[test]
fn a_page_the_server_cannot_send_is_given_up_at_once() {
    let file = scene();
    let (mut s, wire) = connected(&file);
    s.request(&wanted(&[1, 2]));
    sent(&wire);
    wire.push(frame(encode_control(&ServerMessage::PageUnavailable {
        page: 2,
        reason: "corrupt on disk".into(),
    })));
    assert!(s.pump(Duration::ZERO).expect("pump").is_empty());
    assert!(s.gave_up(2));
    assert_eq!(s.stats.pages_unavailable, 1);
    assert_eq!(s.outstanding(), 1);
}

#[test]
fn a_reconnect_waits_then_asks_again_only_for_what_is_missing() {
    let file = scene();
    let (mut s, wire) = connected(&file);
    s.request(&wanted(&[1, 2, 3]));
    wire.push(frame(encode_page_frame(&file.pages[1])));
    s.pump(Duration::ZERO).expect("pump");
    sent(&wire);
    wire.push(TransportEvent::Closed {
        reason: "server went away".into(),
        how: Closing::ByServer,
    });
    s.pump(Duration::ZERO)
        .expect("a lost connection is not an error");
    assert!(!s.is_connected());
    assert_eq!(s.stats.disconnects, 1);
    assert_eq!(s.stats.last_error.as_deref(), Some("server went away"));
    assert_eq!(s.outstanding(), 0, "the server forgot the wishes");
    // Wishes while disconnected are not sent.
    s.request(&wanted(&[2, 3]));
    assert!(sent(&wire).is_empty());
    assert_eq!(wire.connects().len(), 1);
    // After the backoff the session connects again by itself.
    s.pump(Duration::from_millis(200)).expect("pump");
    s.pump(Duration::ZERO).expect("pump");
    assert_eq!(wire.connects().len(), 2);
    wire.push(TransportEvent::Opened);
    wire.push(frame(encode_header_frame(&file.header.encode())));
    let events = s.pump(Duration::ZERO).expect("pump");
    assert!(
        events.is_empty(),
        "the same scene again says nothing: {events:?}"
    );
    assert!(s.is_connected());
    assert_eq!(s.stats.reconnects, 1);
    // What the traversal still lacks (page 1 is resident) is asked for.
    s.request(&wanted(&[2, 3]));
    let messages = sent(&wire);
    assert!(matches!(
        messages.first(),
        Some(ClientMessage::Hello { .. })
    ));
    assert_eq!(requested(&messages), vec![2, 3]);
}

#[test]
fn latencies_run_from_the_first_request_to_arrival_and_only_for_pages_asked_for() {
    let file = scene();
    let (mut s, wire) = connected(&file);
    // Page 0 arrives unasked (as the server sends it): no latency.
    wire.push(frame(encode_page_frame(&file.pages[0])));
    s.pump(Duration::ZERO).expect("pump");
    assert!(s.take_latencies().is_empty());
    s.request(&wanted(&[1, 2]));
    std::thread::sleep(Duration::from_millis(30));
    // A new priority for page 1 does not restart its clock.
    s.request(&[
        PageWish {
            page: 1,
            priority: 100.0,
        },
        PageWish {
            page: 2,
            priority: 10.0,
        },
    ]);
    wire.push(frame(encode_page_frame(&file.pages[1])));
    s.pump(Duration::ZERO).expect("pump");
    let took = s.take_latencies();
    assert_eq!(took.len(), 1, "{took:?}");
    assert!(took[0] >= Duration::from_millis(30), "{took:?}");
    assert!(s.take_latencies().is_empty(), "taken once");
    // A page cancelled before it arrives counts for nothing.
    s.request(&wanted(&[1]));
    wire.push(frame(encode_page_frame(&file.pages[2])));
    s.pump(Duration::ZERO).expect("pump");
    assert!(s.take_latencies().is_empty());
    // An owner that never takes them holds at most LATENCY_SAMPLES.
    for _ in 0..(LATENCY_SAMPLES / 2 + 1) {
        s.request(&wanted(&[3, 4]));
        wire.push(frame(encode_page_frame(&file.pages[3])));
        wire.push(frame(encode_page_frame(&file.pages[4])));
        s.pump(Duration::ZERO).expect("pump");
        s.request(&[]);
    }
    assert_eq!(s.take_latencies().len(), LATENCY_SAMPLES);
}

#[test]
fn another_scene_after_a_reconnect_ends_the_session() {
    let file = scene();
    let (mut s, wire) = connected(&file);
    wire.push(TransportEvent::Closed {
        reason: "restart".into(),
        how: Closing::ByServer,
    });
    s.pump(Duration::ZERO).expect("pump");
    s.pump(Duration::from_millis(200)).expect("pump");
    s.pump(Duration::ZERO).expect("pump");
    let mut params = Params::default();
    params.set("size", 32);
    let (other, _) = build_spheres(
        load_input("gen:island", &params).expect("gen:island"),
        &BuildOptions::default(),
    )
    .expect("build");
    wire.push(TransportEvent::Opened);
    wire.push(frame(encode_header_frame(&other.header.encode())));
    assert_eq!(s.pump(Duration::ZERO), Err(SessionError::SceneChanged));
    assert_eq!(s.pump(Duration::ZERO), Err(SessionError::Ended));
}

#[test]
fn a_refusal_ends_the_session_with_the_servers_reason() {
    let wire = QueueTransport::default();
    let mut s = Session::open(
        wire.clone(),
        "ws://x/scenes/nope/stream".into(),
        SessionOptions::default(),
    );
    wire.push(TransportEvent::Closed {
        reason: "ws://x/scenes/nope/stream: no scene named nope".into(),
        how: Closing::Refused,
    });
    let error = s.pump(Duration::ZERO).expect_err("refused");
    assert_eq!(
        error.to_string(),
        "ws://x/scenes/nope/stream: no scene named nope"
    );
}

#[test]
fn a_server_never_reached_is_given_up_after_the_grace() {
    let wire = QueueTransport::default();
    let options = SessionOptions {
        first_connect_grace: Duration::from_millis(300),
        ..SessionOptions::default()
    };
    let mut s = Session::open(wire.clone(), "ws://x/s".into(), options);
    let started = web_time::Instant::now();
    let mut refused = 0;
    let error = loop {
        // Each attempt is refused, as by a port nobody listens on.
        if wire.connects().len() > refused {
            refused += 1;
            wire.push(TransportEvent::Closed {
                reason: "connect ws://x/s: connection refused".into(),
                how: Closing::Failed,
            });
        }
        match s.pump(Duration::from_millis(20)) {
            Ok(_) => assert!(started.elapsed() < Duration::from_secs(5), "never gave up"),
            Err(e) => break e,
        }
    };
    let text = error.to_string();
    assert!(
        text.starts_with("cannot reach the server within 0 s"),
        "{text}"
    );
    assert!(text.contains("connection refused"), "{text}");
    assert!(wire.connects().len() >= 2, "it retried first");
}

#[test]
fn a_server_of_another_protocol_version_ends_the_session() {
    let wire = QueueTransport::default();
    let mut s = Session::open(wire.clone(), "ws://x/s".into(), SessionOptions::default());
    wire.push(TransportEvent::Opened);
    wire.push(frame(encode_control(&ServerMessage::Hello {
        protocol_version: PROTOCOL_VERSION + 1,
        server: "test".into(),
    })));
    let error = s.pump(Duration::ZERO).expect_err("other version");
    assert!(error.to_string().contains("protocol version"), "{error}");
}

/// Opens and at once loses a connection, `how`; returns the connects so far.
fn open_and_lose(s: &mut Session<QueueTransport>, wire: &QueueTransport, how: Closing) -> usize {
    wire.push(TransportEvent::Opened);
    wire.push(TransportEvent::Closed {
        reason: "lost".into(),
        how,
    });
    s.pump(Duration::ZERO)
        .expect("a lost connection is not an error");
    wire.connects().len()
}

#[test]
fn broken_connections_back_off_and_a_server_that_closes_is_retried_soon() {
    // Broken again and again: 50, 100, 200 ms, then 400 ms.
    let wire = QueueTransport::default();
    let mut s = Session::open(wire.clone(), "ws://x/s".into(), SessionOptions::default());
    for (wait_ms, connects) in [(100, 2), (150, 3), (250, 4)] {
        open_and_lose(&mut s, &wire, Closing::Failed);
        s.pump(Duration::from_millis(wait_ms)).expect("pump");
        assert_eq!(
            wire.connects().len(),
            connects,
            "reconnected within {wait_ms} ms"
        );
    }
    open_and_lose(&mut s, &wire, Closing::Failed);
    s.pump(Duration::from_millis(150)).expect("pump");
    assert_eq!(wire.connects().len(), 4, "the fourth break waits 400 ms");
    // Closed by the server each time: always the first, short wait.
    let wire = QueueTransport::default();
    let mut s = Session::open(wire.clone(), "ws://x/s".into(), SessionOptions::default());
    for connects in 2..=5 {
        open_and_lose(&mut s, &wire, Closing::ByServer);
        s.pump(Duration::from_millis(150)).expect("pump");
        assert_eq!(wire.connects().len(), connects);
    }
}

#[test]
fn the_hello_goes_out_with_every_connection_before_anything_else() {
    let wire = QueueTransport::default();
    let mut s = Session::open(wire.clone(), "ws://x/s".into(), SessionOptions::default());
    // Queued with the attempt, before the owner pumps the opened connection.
    assert!(matches!(
        sent(&wire).as_slice(),
        [ClientMessage::Hello { .. }]
    ));
    open_and_lose(&mut s, &wire, Closing::ByServer);
    s.pump(Duration::from_millis(150)).expect("pump");
    assert_eq!(wire.connects().len(), 2);
    assert!(matches!(
        sent(&wire).as_slice(),
        [ClientMessage::Hello { .. }]
    ));
}

/// A session whose transport has opened, with the server's hello queued.
fn opened() -> (Session<QueueTransport>, QueueTransport) {
    let wire = QueueTransport::default();
    let s = Session::open(
        wire.clone(),
        "ws://test/scenes/a/stream".into(),
        SessionOptions::default(),
    );
    wire.push(TransportEvent::Opened);
    wire.push(server_hello());
    (s, wire)
}

#[test]
fn a_header_in_parts_is_joined_even_across_a_lost_connection() {
    let file = scene();
    let header = file.header.encode();
    // Parts of 7 bytes: even the length prefix comes split.
    let parts: Vec<&[u8]> = header.chunks(7).collect();
    let (mut s, wire) = opened();
    for part in &parts[..parts.len() / 2] {
        wire.push(frame(encode_header_frame(part)));
    }
    assert_eq!(s.pump(Duration::ZERO), Ok(Vec::new()));
    assert!(!s.is_connected(), "half a header is no header");
    // The connection drops mid-header: the next one starts from nothing.
    wire.push(TransportEvent::Closed {
        reason: "lost".into(),
        how: Closing::ByServer,
    });
    s.pump(Duration::ZERO).expect("pump");
    s.pump(Duration::from_millis(200)).expect("pump");
    wire.push(TransportEvent::Opened);
    wire.push(server_hello());
    for part in &parts[..parts.len() - 1] {
        wire.push(frame(encode_header_frame(part)));
    }
    assert_eq!(s.pump(Duration::ZERO), Ok(Vec::new()));
    assert!(!s.is_connected());
    wire.push(frame(encode_header_frame(parts[parts.len() - 1])));
    assert_eq!(
        s.pump(Duration::ZERO),
        Ok(vec![SessionEvent::Header(file.header.clone())])
    );
    assert!(s.is_connected());
    assert_eq!(s.header(), Some(&file.header));
}

#[test]
fn header_parts_that_do_not_add_up_end_the_session() {
    let file = scene();
    let header = file.header.encode();
    let ends = |frames: Vec<Vec<u8>>, why: &str| {
        let (mut s, wire) = opened();
        for f in frames {
            wire.push(frame(f));
        }
        match s.pump(Duration::ZERO) {
            Err(e @ SessionError::BadHeader(_)) => {
                assert!(e.to_string().contains(why), "{e} lacks {why:?}")
            }
            other => panic!("expected a bad header ({why}), got {other:?}"),
        }
    };
    // Bytes past the length the header declares.
    let mut long = header.clone();
    long.extend_from_slice(&[0; 3]);
    ends(
        vec![encode_header_frame(&long)],
        &format!(
            "carry {} bytes for a header of {}",
            long.len(),
            header.len()
        ),
    );
    // A part after the whole header.
    ends(
        vec![encode_header_frame(&header), encode_header_frame(&[1])],
        "after the whole header",
    );
    // A declared length no client should buffer: bytes 12..16 are it.
    let mut huge = header[..16].to_vec();
    huge[12..16].copy_from_slice(&(MAX_HEADER_BYTES as u32 + 1).to_le_bytes());
    ends(vec![encode_header_frame(&huge)], "more than the");
    // Not a header at all.
    ends(vec![encode_header_frame(&[0; 16])], "magic");
}

#[test]
fn a_bound_on_outstanding_pages_asks_for_the_most_urgent_first_and_the_rest_as_pages_arrive() {
    let file = scene();
    let wire = QueueTransport::default();
    let mut s = Session::open(
        wire.clone(),
        "ws://test/scenes/a/stream".into(),
        SessionOptions {
            max_outstanding: Some(2),
            ..SessionOptions::default()
        },
    );
    wire.push(TransportEvent::Opened);
    wire.push(server_hello());
    wire.push(frame(encode_header_frame(&file.header.encode())));
    s.pump(Duration::ZERO).expect("pump");
    sent(&wire);
    let wish = |page, priority| PageWish { page, priority };
    s.request(&[wish(1, 10.0), wish(2, 30.0), wish(3, 20.0)]);
    assert_eq!(requested(&sent(&wire)), vec![2, 3]);
    assert_eq!(s.outstanding(), 2);
    // Full: asking again adds nothing.
    s.request(&[wish(1, 10.0), wish(2, 30.0), wish(3, 20.0)]);
    assert!(sent(&wire).is_empty());
    // Page 2 arrives: the room it leaves goes to page 1 in the same pump,
    // before the owner asks again.
    wire.push(frame(encode_page_frame(&file.pages[2])));
    s.pump(Duration::ZERO).expect("pump");
    let after = sent(&wire);
    assert_eq!(requested(&after), vec![1]);
    assert!(
        after
            .iter()
            .any(|m| matches!(m, ClientMessage::Received { pages } if pages == &[2]))
    );
    assert_eq!(s.outstanding(), 2);
    s.request(&[wish(1, 10.0), wish(3, 20.0)]);
    assert!(sent(&wire).is_empty(), "both are on their way");
    // A new wish list replaces the backlog: page 4 waits, page 5 does not
    // come back once it is no longer wanted.
    s.request(&[wish(1, 10.0), wish(3, 20.0), wish(4, 5.0), wish(5, 1.0)]);
    assert!(sent(&wire).is_empty());
    s.request(&[wish(1, 10.0), wish(3, 20.0), wish(4, 5.0)]);
    wire.push(frame(encode_page_frame(&file.pages[3])));
    wire.push(frame(encode_page_frame(&file.pages[1])));
    s.pump(Duration::ZERO).expect("pump");
    assert_eq!(requested(&sent(&wire)), vec![4]);
    assert_eq!(s.outstanding(), 1);
    // Without a bound, everything wanted goes at once.
    let (mut open, wire) = connected(&file);
    sent(&wire);
    open.request(&[wish(1, 10.0), wish(2, 30.0), wish(3, 20.0)]);
    assert_eq!(requested(&sent(&wire)), vec![1, 2, 3]);
}

#[test]
fn a_page_is_timed_when_it_came_off_the_wire_not_when_its_owner_got_round_to_it() {
    let file = scene();
    let (mut s, wire) = connected(&file);
    s.request(&wanted(&[1]));
    wire.push(frame(encode_page_frame(&file.pages[1])));
    // The owner is busy (a traversal) before it pumps.
    std::thread::sleep(Duration::from_millis(80));
    s.pump(Duration::ZERO).expect("pump");
    let took = s.take_latencies();
    assert_eq!(took.len(), 1, "{took:?}");
    assert!(took[0] < Duration::from_millis(40), "{took:?}");
}

#[tokio::test(flavor = "current_thread")]
async fn a_queue_wakes_its_driver_and_its_owner_on_another_task() {
    async fn within(what: impl std::future::Future<Output = ()>) {
        tokio::time::timeout(Duration::from_secs(5), what)
            .await
            .expect("woken in time");
    }
    let wire = QueueTransport::default();
    // The driver waits for something to send; a send wakes it.
    let driver = tokio::spawn({
        let wire = wire.clone();
        async move { within(wire.outgoing_ready()).await }
    });
    tokio::task::yield_now().await;
    assert!(!driver.is_finished(), "nothing to send yet");
    let mut session_side = wire.clone();
    session_side.send(vec![1]);
    driver.await.expect("driver");
    assert_eq!(wire.take_sent(), vec![vec![1]]);
    // The owner waits for an event; a push wakes it.
    let owner = tokio::spawn({
        let wire = wire.clone();
        async move { within(wire.incoming_ready()).await }
    });
    tokio::task::yield_now().await;
    assert!(!owner.is_finished(), "nothing arrived yet");
    wire.push(TransportEvent::Opened);
    owner.await.expect("owner");
    // Finishing wakes a driver and stays ready.
    assert!(!wire.is_finished());
    wire.finish();
    within(wire.outgoing_ready()).await;
    assert!(wire.is_finished());
}

#[test]
fn a_presenters_view_is_stamped_when_it_came_off_the_wire() {
    let file = scene();
    let (mut s, wire) = connected(&file);
    let view = farfield_protocol::messages::SharedView {
        eye: [1.0, 2.0, 3.0],
        target: [0.0; 3],
        up: [0.0, 0.0, 1.0],
        fov_y_deg: 60.0,
        options: Vec::new(),
    };
    let pushed = web_time::Instant::now();
    wire.push(frame(encode_control(&ServerMessage::View {
        seq: 7,
        view: view.clone(),
    })));
    std::thread::sleep(Duration::from_millis(80));
    let events = s.pump(Duration::ZERO).expect("pump");
    match events.as_slice() {
        [
            SessionEvent::Demo(DemoEvent::View {
                seq: 7,
                view: got,
                arrived,
            }),
        ] => {
            assert_eq!(got, &view);
            assert!(
                arrived.saturating_duration_since(pushed) < Duration::from_millis(40),
                "stamped when polled, not when it came"
            );
        }
        other => panic!("expected the view, got {other:?}"),
    }
}
