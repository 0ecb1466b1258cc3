//! The memory server end to end: a real server on a loopback port, in
//! process, serving small generated scenes; HTTP through a raw TCP GET and
//! websocket sessions through tokio-tungstenite, speaking the protocol byte
//! for byte (not through the client's `Session`, which would hide the
//! frames, close codes and misbehaviour these tests need to control). Every wait is bounded, so a broken server fails a test instead
//! of hanging it.

mod access;
mod accounting;
mod hostile;
pub(crate) mod limits;
mod live;
mod refusals;
pub(crate) mod support;

use std::collections::HashSet;
use std::time::Duration;

use farfield_builder::import::{Params, load_input};
use farfield_net::stream_url;
use farfield_protocol::codec::{encode_control, encode_page_frame};
use farfield_protocol::file::FileHeader;
use farfield_protocol::messages::{ClientMessage, PROTOCOL_VERSION, PageWish, ServerMessage};
use farfield_store::write_atomic;
use farfield_tests::scratch;
use futures_util::SinkExt;
use tokio::net::TcpStream;
use tokio_tungstenite::MaybeTlsStream;
use tokio_tungstenite::tungstenite::Message;

use support::*;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn http_lists_scenes_health_metrics_and_404s() {
    let dir = scenes_dir("serve-http");
    let server = serve(&dir).await;
    let addr = server.local_addr();
    assert_eq!(server.scenes(), vec!["island", "tree"], "broken.ff skipped");

    assert_eq!(http_get(addr, "/healthz").await, (200, "ok".into()));

    let (status, body) = http_get(addr, "/scenes").await;
    assert_eq!(status, 200);
    let list: serde_json::Value = serde_json::from_str(&body).expect("JSON list");
    let list = list.as_array().expect("array");
    assert_eq!(list.len(), 2);
    assert_eq!(list[0]["name"], "island");
    assert_eq!(list[0]["kind"], "spheres");
    assert_eq!(list[0]["nodes"], island().header.nodes);
    assert_eq!(
        list[0]["bytes"],
        std::fs::metadata(dir.join("island.ff")).unwrap().len()
    );
    assert_eq!(list[0]["bounds_min"][0], island().header.bounds_min.x);
    assert_eq!(list[1]["name"], "tree");

    let (status, body) = http_get(addr, "/scenes/tree").await;
    assert_eq!(status, 200);
    let one: serde_json::Value = serde_json::from_str(&body).expect("JSON object");
    assert_eq!(one["pages"], (tree().header.page_count as usize));
    assert_eq!(one["attributes"]["color"], tree().header.attributes.color);

    for path in ["/scenes/nope", "/scenes/nope/stream", "/nowhere"] {
        let (status, body) = http_get(addr, path).await;
        assert_eq!(status, 404, "{path}");
        let err: serde_json::Value = serde_json::from_str(&body).expect("JSON error");
        assert!(err["error"].is_string(), "{path}: {body}");
    }

    let (status, text) = http_get(addr, "/metrics").await;
    assert_eq!(status, 200);
    for name in [
        "farfield_pages_served_total",
        "farfield_bytes_served_total",
        "farfield_page_cache_hits_total",
        "farfield_page_cache_misses_total",
        "farfield_page_cache_bytes",
        "farfield_queue_depth",
        "farfield_connected_clients",
        "farfield_pages_pushed_total",
        "farfield_malformed_frames_total",
        "farfield_request_latency_seconds_count",
    ] {
        metric(&text, name);
    }
    assert!(text.contains("farfield_request_latency_seconds_bucket{le=\"+Inf\"} 0"));
    server.shutdown().await.expect("shutdown");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn pages_arrive_in_priority_order_with_the_stored_bytes() {
    let dir = scenes_dir("serve-order");
    let server = serve(&dir).await;
    let file = island();
    let n = file.header.page_count;
    assert!(n >= 8, "test scene needs pages, has {n}");

    let (mut c, header, page0) = Client::open(server.local_addr(), "island", 16 << 20, false).await;
    let header_len = FileHeader::ENCODED_LEN;
    let on_disk = std::fs::read(dir.join("island.ff")).expect("read file");
    assert_eq!(header, on_disk[..header_len], "header bytes as stored");
    assert_eq!(
        c.root_directory, file.directory_pages[0],
        "root directory page as stored"
    );
    assert_eq!(FileHeader::decode(&header).expect("decodes"), file.header);
    assert_eq!(page0, file.pages[0]);

    // Priorities in a scrambled order, then in the same request an update
    // that ties page 2 with page 3 (page 3 was first) and one that moves
    // page 1 to the front. One message is applied at once, so the order is
    // exact.
    let mut wishes: Vec<(u32, f32)> = (1..n).map(|p| (p, ((p * 7) % n) as f32)).collect();
    wishes.push((2, wishes[2].1));
    wishes.push((1, 1000.0));
    c.request(&wishes).await;
    let mut latest = std::collections::HashMap::new();
    for (seq, &(page, priority)) in wishes.iter().enumerate() {
        latest.insert(page, (priority, seq));
    }
    let mut want: Vec<(u32, (f32, usize))> = latest.into_iter().collect();
    want.sort_by(|a, b| b.1.0.total_cmp(&a.1.0).then(a.1.1.cmp(&b.1.1)));
    let want: Vec<u32> = want.into_iter().map(|(p, _)| p).collect();
    assert_eq!(want[0], 1);

    let got = c.pages(want.len()).await;
    assert!(c.pages_until_quiet().await.is_empty(), "each page once");
    let order: Vec<u32> = got.iter().map(|(p, _)| *p).collect();
    assert_eq!(order, want, "priority order");
    let at = |p: u32| order.iter().position(|&q| q == p).unwrap();
    assert_eq!(at(3) + 1, at(2), "tie broken by arrival");
    for (p, bytes) in &got {
        assert_eq!(bytes, &file.pages[*p as usize], "page {p} bytes as stored");
    }

    // Asked again after it arrived (lost, say): sent again.
    c.ack(0..n).await;
    c.request(&[(3, 1.0)]).await;
    match c.recv().await {
        In::Page(3, bytes) => assert_eq!(bytes, file.pages[3]),
        other => panic!("expected page 3 again, got {other:?}"),
    }
    assert!(c.pages_until_quiet().await.is_empty());

    let m = server.metrics();
    // Every page, page 3 again, and the root directory page.
    assert_eq!(m.pages_served, u64::from(n) + 2);
    assert!(m.latency_count >= u64::from(n));
    assert_eq!(m.queue_depth, 0);
    assert!(m.cache_misses > 0);
    server.shutdown().await.expect("shutdown");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_that_never_acknowledges_gets_at_most_its_window() {
    let dir = scenes_dir("serve-window");
    let server = serve(&dir).await;
    let file = island();
    let n = file.header.page_count;
    let biggest = file.pages.iter().map(|p| p.len()).max().unwrap() as u64;
    // Asking for 1 byte gets the smallest window the server allows.
    let (mut c, _, page0) = Client::open(server.local_addr(), "island", 1, false).await;
    c.request(&(1..n).map(|p| (p, 1.0)).collect::<Vec<_>>())
        .await;
    let mut got = c.pages_worth(MIN_WINDOW, page0.len() as u64).await;
    got.extend(c.pages_until_quiet().await);
    let bytes: u64 = page0.len() as u64 + got.iter().map(|(_, b)| b.len() as u64).sum::<u64>();
    assert!(
        bytes >= MIN_WINDOW && bytes < MIN_WINDOW + biggest,
        "{bytes} bytes in flight for a {MIN_WINDOW}-byte window (pages up to {biggest})"
    );
    assert!((got.len() as u32) < n - 1, "window held back some pages");
    let queued = server.metrics().queue_depth;
    assert_eq!(queued, u64::from(n - 1) - got.len() as u64);

    // Acknowledging opens the window again.
    c.ack(std::iter::once(0).chain(got.iter().map(|(p, _)| *p)))
        .await;
    assert!(matches!(c.recv().await, In::Page(..)));
    server.shutdown().await.expect("shutdown");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_cancelled_page_never_arrives() {
    let dir = scenes_dir("serve-cancel");
    let server = serve(&dir).await;
    let n = island().header.page_count;
    let (mut c, _, page0) = Client::open(server.local_addr(), "island", 1, false).await;
    // Page n-1 has the lowest priority, so a full window cannot hold it yet.
    let wishes: Vec<(u32, f32)> = (1..n).map(|p| (p, (n - p) as f32)).collect();
    let last = n - 1;
    c.request(&wishes).await;
    let mut seen: HashSet<u32> = c
        .pages_worth(MIN_WINDOW, page0.len() as u64)
        .await
        .iter()
        .map(|(p, _)| *p)
        .collect();
    assert!(!seen.contains(&last));
    c.send(&ClientMessage::Cancel {
        pages: vec![last, 9999],
    })
    .await;
    // Acknowledge as pages arrive until every other page is in.
    c.ack(std::iter::once(0).chain(seen.iter().copied())).await;
    while seen.len() < (n - 2) as usize {
        match c.recv().await {
            In::Page(p, _) => {
                assert_ne!(p, last, "cancelled page sent");
                assert!(seen.insert(p), "page {p} sent twice");
                c.ack([p]).await;
            }
            other => panic!("expected a page, got {other:?}"),
        }
    }
    assert!(
        c.pages_until_quiet().await.is_empty(),
        "nothing after the rest"
    );
    let m = server.metrics();
    assert_eq!(m.pages_cancelled, 1);
    assert_eq!(m.queue_depth, 0);
    server.shutdown().await.expect("shutdown");
}

/// A client with a tiny socket buffer that never reads: the server's writer
/// for it blocks on the socket, yet its cancels are still read, and another
/// client is served as if nothing happened.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_that_stops_reading_still_has_its_cancels_read_and_stalls_no_one() {
    let dir = scenes_dir("serve-stalled");
    let server = serve(&dir).await;
    let addr = server.local_addr();
    let file = tree();
    let n = file.header.page_count;

    let socket = tokio::net::TcpSocket::new_v4().expect("socket");
    socket.set_recv_buffer_size(4096).expect("small buffer");
    let stream = socket.connect(addr).await.expect("connect");
    let url = stream_url(&addr.to_string(), "tree");
    let (ws, _) = tokio::time::timeout(
        T,
        tokio_tungstenite::client_async(url, MaybeTlsStream::Plain(stream)),
    )
    .await
    .expect("timed out")
    .expect("handshake");
    let mut stalled = Client::over(ws);
    stalled
        .send(&ClientMessage::Hello {
            protocol_version: PROTOCOL_VERSION,
            max_in_flight_bytes: u64::MAX,
            allow_push: false,
        })
        .await;
    // The scene fits in the kernel's socket buffers, so ask for it again
    // and again, acknowledging without reading (the server trusts acks),
    // until the writer blocks: pages stay queued and none go out.
    let all: Vec<(u32, f32)> = (1..n).map(|p| (p, 1.0)).collect();
    let mut blocked = false;
    for _ in 0..200 {
        stalled.request(&all).await;
        tokio::time::sleep(Duration::from_millis(30)).await;
        let a = server.metrics();
        tokio::time::sleep(Duration::from_millis(150)).await;
        let b = server.metrics();
        if b.queue_depth > 0 && a.pages_served == b.pages_served {
            blocked = true;
            break;
        }
        stalled.ack(1..n).await;
    }
    assert!(blocked, "the writer never blocked on the socket");
    stalled
        .send(&ClientMessage::Cancel {
            pages: (1..n).collect(),
        })
        .await;
    eventually("cancels read while the writer is blocked", || {
        server.metrics().queue_depth == 0
    })
    .await;

    let (mut other, _, _) = Client::open(addr, "tree", 1 << 20, false).await;
    other.request(&all).await;
    let got = other.pages((n - 1) as usize).await;
    for (p, bytes) in &got {
        assert_eq!(bytes, &file.pages[*p as usize]);
    }
    drop(stalled);
    server.shutdown().await.expect("shutdown");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn another_protocol_version_gets_a_fatal_error_naming_both() {
    let dir = scenes_dir("serve-version");
    let server = serve(&dir).await;
    let mut c = Client::connect(server.local_addr(), "island").await;
    c.send(&ClientMessage::Hello {
        protocol_version: 99,
        max_in_flight_bytes: 1 << 20,
        allow_push: false,
    })
    .await;
    match c.recv().await {
        In::Control(ServerMessage::Error { message, fatal }) => {
            assert!(fatal);
            assert!(message.contains("99"), "{message}");
            assert!(message.contains(&PROTOCOL_VERSION.to_string()), "{message}");
        }
        other => panic!("expected a fatal error, got {other:?}"),
    }
    assert!(matches!(c.recv().await, In::Closed(_)));
    server.shutdown().await.expect("shutdown");
}

/// A scene of many pages (its directory in several directory pages)
/// starts with the same small header as any other: one frame, the root
/// directory page, page 0.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_scene_of_many_pages_starts_with_the_same_small_header() {
    let dir = scratch("serve-many-pages");
    let mut params = Params::default();
    params.set("size", 64);
    params.set("trees", 2);
    let scene = load_input("gen:island", &params).expect("gen:island");
    let options = farfield_builder::BuildOptions {
        page_bytes: 64,
        ..Default::default()
    };
    let (file, _) = farfield_builder::build_spheres(scene, &options).expect("build");
    assert!(file.header.directory_pages > 1, "{:?}", file.header);
    write_atomic(&dir.join("many.ff"), &file).expect("write");
    let server = serve(&dir).await;
    let (c, header, page0) = Client::open(server.local_addr(), "many", 1 << 20, false).await;
    assert_eq!(header, file.header.encode());
    assert_eq!(header.len(), FileHeader::ENCODED_LEN);
    assert_eq!(c.header_frames, 1);
    assert_eq!(c.root_directory, file.directory_pages[0]);
    assert_eq!(page0, file.pages[0]);
    server.shutdown().await.expect("shutdown");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn malformed_frames_close_only_their_own_connection() {
    let dir = scenes_dir("serve-malformed");
    let server = serve(&dir).await;
    let addr = server.local_addr();
    let (mut good, _, _) = Client::open(addr, "island", 1 << 20, false).await;

    let page = island().pages[1].clone();
    let hello = ClientMessage::Hello {
        protocol_version: PROTOCOL_VERSION,
        max_in_flight_bytes: 1,
        allow_push: false,
    };
    let bad: Vec<(Message, &str)> = vec![
        (Message::binary(vec![9u8, 1, 2]), "unknown frame kind 9"),
        (Message::binary(Vec::<u8>::new()), "empty frame"),
        (Message::text("hello?"), "text frame"),
        (Message::binary(encode_page_frame(&page)), "page frame"),
        (Message::binary(vec![0u8, 0xff, 0xff, 0xff]), "undecodable"),
        (Message::binary(encode_control(&hello)), "Hello sent twice"),
    ];
    let count = bad.len() as u64;
    for (frame, why) in bad {
        let (mut c, _, _) = Client::open(addr, "island", 1 << 20, false).await;
        c.send_raw(frame).await;
        match c.recv().await {
            In::Closed(Some((code, reason))) => {
                assert!(code == 1002 || code == 1003, "close code {code}");
                assert!(reason.contains(why), "reason {reason:?} should say {why:?}");
            }
            other => panic!("expected a close for {why}, got {other:?}"),
        }
    }
    // A first message that is not a hello.
    let mut c = Client::connect(addr, "island").await;
    c.request(&[(1, 1.0)]).await;
    match c.recv().await {
        In::Closed(Some((_, reason))) => assert!(reason.contains("expected Hello"), "{reason}"),
        other => panic!("expected a close, got {other:?}"),
    }

    // The first connection is unaffected.
    good.request(&[(2, 1.0)]).await;
    match good.recv().await {
        In::Page(2, bytes) => assert_eq!(bytes, island().pages[2]),
        other => panic!("expected page 2, got {other:?}"),
    }
    let (_, text) = http_get(addr, "/metrics").await;
    assert_eq!(metric(&text, "farfield_malformed_frames_total"), count + 1);
    eventually("closed sessions leave", || {
        server.metrics().connected_clients == 1
    })
    .await;
    server.shutdown().await.expect("shutdown");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn requests_out_of_range_are_reported_and_the_session_goes_on() {
    let dir = scenes_dir("serve-range");
    let server = serve(&dir).await;
    let (mut c, _, _) = Client::open(server.local_addr(), "tree", 1 << 20, false).await;
    c.request(&[(5000, 1.0), (1, 0.5)]).await;
    let mut got_error = false;
    let mut got_page = false;
    while !(got_error && got_page) {
        match c.recv().await {
            In::Control(ServerMessage::Error { message, fatal }) => {
                assert!(!fatal);
                assert!(message.contains("5000"), "{message}");
                got_error = true;
            }
            In::Page(1, bytes) => {
                assert_eq!(bytes, tree().pages[1]);
                got_page = true;
            }
            other => panic!("unexpected {other:?}"),
        }
    }
    server.shutdown().await.expect("shutdown");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn pushes_arrive_only_when_allowed_and_are_counted() {
    let dir = scenes_dir("serve-push");
    let server = serve(&dir).await;
    let addr = server.local_addr();

    let (mut quiet, _, _) = Client::open(addr, "island", 16 << 20, false).await;
    assert!(
        quiet.pages_until_quiet().await.is_empty(),
        "nothing unasked without pushes"
    );

    // Children of page 0 (the pages holding the breadth-first range from
    // its first child to page 1's) are pushed once it is sent, unasked.
    let d = &island().directory;
    let first = d.page_of(d.entry(0).unwrap().first_child).unwrap().max(1);
    let last = d.page_of(d.entry(1).unwrap().first_child - 1).unwrap();
    let children: HashSet<u32> = (first..=last).collect();
    assert!(!children.is_empty());
    let (mut c, _, _) = Client::open(addr, "island", 16 << 20, true).await;
    let pushed = c.pages(children.len()).await;
    assert!(c.pages_until_quiet().await.is_empty(), "only children");
    let pages: HashSet<u32> = pushed.iter().map(|(p, _)| *p).collect();
    assert_eq!(pages, children, "each child of page 0 pushed once");
    for (p, bytes) in &pushed {
        assert_eq!(bytes, &island().pages[*p as usize]);
    }
    // A pushed page still in flight is not sent again when asked for.
    let some = *pages.iter().next().unwrap();
    c.request(&[(some, 1.0)]).await;
    assert!(c.pages_until_quiet().await.is_empty());

    let (_, text) = http_get(addr, "/metrics").await;
    assert_eq!(
        metric(&text, "farfield_pages_pushed_total"),
        pushed.len() as u64
    );
    // Read-ahead loaded those children into the cache (on its own threads).
    eventually("read-ahead", || server.metrics().prefetch_loads > 0).await;
    server.shutdown().await.expect("shutdown");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_corrupt_page_is_reported_and_never_sent() {
    let dir = scratch("serve-corrupt");
    let path = dir.join("island.ff");
    write_atomic(&path, island()).expect("write");
    let mut bytes = std::fs::read(&path).expect("read");
    let entry = &island().directory.entry(2).unwrap();
    bytes[entry.offset as usize + 40] ^= 0x10;
    std::fs::write(&path, &bytes).expect("write corrupt copy");
    let server = serve(&dir).await;

    let (mut c, _, _) = Client::open(server.local_addr(), "island", 16 << 20, false).await;
    c.request(&[(2, 5.0), (1, 1.0)]).await;
    let mut reported = false;
    let mut got_one = false;
    while !(reported && got_one) {
        match c.recv().await {
            In::Control(ServerMessage::PageUnavailable { page, reason }) => {
                assert_eq!(page, 2);
                assert!(reason.contains("page 2"), "{reason}");
                reported = true;
            }
            In::Page(1, b) => {
                assert_eq!(b, island().pages[1]);
                got_one = true;
            }
            other => panic!("unexpected {other:?}"),
        }
    }
    assert!(c.recv_within(QUIET).await.is_none(), "page 2 never sent");
    let reads = server.metrics().corrupt_pages;
    assert!(reads >= 1);
    // Asked for again and again, the verdict stands without a read (and
    // without a warning each time: 10,000 lines in 0.8 s before).
    for _ in 0..50 {
        c.request(&[(2, 5.0)]).await;
        match c.recv().await {
            In::Control(ServerMessage::PageUnavailable { page: 2, .. }) => {}
            other => panic!("unexpected {other:?}"),
        }
    }
    assert_eq!(server.metrics().corrupt_pages, reads, "read again");
    server.shutdown().await.expect("shutdown");
}

/// A page edited in place with its own checksum recomputed (and the file's
/// modification time put back, so nothing but the bytes says it changed)
/// passes its own check; the server compares it with the directory's copy
/// of its checksum and refuses it.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_page_edited_with_its_checksum_recomputed_is_refused() {
    let dir = scratch("serve-forged");
    let path = dir.join("island.ff");
    write_atomic(&path, island()).expect("write");
    let modified = std::fs::metadata(&path)
        .and_then(|m| m.modified())
        .expect("mtime");
    let entry = island().directory.entry(2).unwrap();
    let (start, end) = (
        entry.offset as usize,
        (entry.offset + u64::from(entry.length)) as usize,
    );
    let mut bytes = std::fs::read(&path).expect("read");
    // One record changed and the page encoded again: the first change
    // whose compressed page is as long as the original fits in place.
    let node_bytes = island().header.node_bytes;
    let page = farfield_protocol::page::Page::parse(&bytes[start..end], 2, node_bytes)
        .expect("page 2 as built");
    let forged = (0..page.header.node_count as usize)
        .find_map(|i| {
            let mut records = page.records().to_vec();
            records[i * node_bytes as usize + 1] ^= 0x10;
            let (forged, _) = farfield_protocol::page::encode_page(&page.header, &records).unwrap();
            (forged.len() == end - start).then_some(forged)
        })
        .expect("an edit that keeps the page's length");
    bytes[start..end].copy_from_slice(&forged);
    assert!(
        farfield_protocol::page::Page::parse_with_payload(
            &bytes[start..end],
            2,
            island().header.node_bytes
        )
        .is_ok(),
        "the edited page is consistent in itself"
    );
    {
        use std::io::{Seek, SeekFrom, Write};
        let mut file = std::fs::OpenOptions::new()
            .write(true)
            .open(&path)
            .expect("open");
        file.seek(SeekFrom::Start(start as u64)).expect("seek");
        file.write_all(&bytes[start..end]).expect("edit in place");
        file.set_modified(modified).expect("restore the mtime");
    }
    let server = serve(&dir).await;
    let (mut c, _, _) = Client::open(server.local_addr(), "island", 16 << 20, false).await;
    c.request(&[(2, 5.0)]).await;
    match c.recv().await {
        In::Control(ServerMessage::PageUnavailable { page, reason }) => {
            assert_eq!(page, 2);
            assert!(reason.contains("directory"), "{reason}");
        }
        other => panic!("unexpected {other:?}"),
    }
    assert!(c.recv_within(QUIET).await.is_none(), "page 2 never sent");
    assert!(server.metrics().corrupt_pages >= 1);
    server.shutdown().await.expect("shutdown");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_error_status_has_a_json_body() {
    let dir = scenes_dir("serve-json-errors");
    let server = serve(&dir).await;
    let addr = server.local_addr();
    let cases = [
        (
            "POST /scenes HTTP/1.1\r\nHost: localhost\r\nContent-Length: 0\r\nConnection: close\r\n\r\n",
            "405",
        ),
        (
            "GET /scenes/island/stream HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n",
            "4",
        ),
        (
            "GET /nowhere HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n",
            "404",
        ),
    ];
    for (head, status) in cases {
        let answer = raw_request(addr, head).await;
        let (first, rest) = answer.split_once("\r\n").expect("status line");
        assert!(first.starts_with(&format!("HTTP/1.1 {status}")), "{answer}");
        assert!(
            rest.to_ascii_lowercase()
                .contains("content-type: application/json"),
            "{answer}"
        );
        let body = answer.split_once("\r\n\r\n").expect("body").1;
        let v: serde_json::Value = serde_json::from_str(body).expect("a JSON body");
        assert!(
            !v["error"].as_str().expect("error text").is_empty(),
            "{answer}"
        );
    }
    server.shutdown().await.expect("shutdown");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn unknown_scene_stream_is_refused_with_404() {
    let dir = scenes_dir("serve-unknown");
    let server = serve(&dir).await;
    let url = stream_url(&server.local_addr().to_string(), "nope");
    match tokio::time::timeout(T, tokio_tungstenite::connect_async(url))
        .await
        .expect("timed out")
    {
        Err(tokio_tungstenite::tungstenite::Error::Http(response)) => {
            assert_eq!(response.status().as_u16(), 404);
        }
        other => panic!("expected a 404, got {:?}", other.map(|_| ())),
    }
    server.shutdown().await.expect("shutdown");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn shutdown_closes_sessions_with_a_reason() {
    let dir = scenes_dir("serve-shutdown");
    let server = serve(&dir).await;
    let addr = server.local_addr();
    let (mut c, _, _) = Client::open(addr, "island", 16 << 20, false).await;
    let stopping = tokio::spawn(server.shutdown());
    match c.recv().await {
        In::Closed(Some((code, reason))) => {
            assert_eq!(code, 1001);
            assert!(reason.contains("shutting down"), "{reason}");
        }
        other => panic!("expected a close, got {other:?}"),
    }
    let m = tokio::time::timeout(T, stopping)
        .await
        .expect("shutdown timed out")
        .expect("join")
        .expect("shutdown");
    assert_eq!(m.connected_clients, 0);
    assert!(TcpStream::connect(addr).await.is_err(), "still accepting");
}

/// Runs `farfield-server serve` in a child process (this test binary,
/// re-run on [`serve_cli_child`]), reads the address from its first line,
/// checks it answers, and stops it with SIGTERM.
#[cfg(unix)]
#[test]
fn serve_command_prints_its_address_and_stops_on_sigterm() {
    let dir = scenes_dir("serve-cli");
    let mut server = ChildServer::start(&dir, "");
    let addr = server.addr;
    let runtime = tokio::runtime::Runtime::new().expect("runtime");
    assert_eq!(
        runtime.block_on(http_get(addr, "/healthz")),
        (200, "ok".into())
    );
    let (_, body) = runtime.block_on(http_get(addr, "/scenes"));
    assert!(body.contains("island") && body.contains("tree"), "{body}");

    let status = std::process::Command::new("kill")
        .args(["-TERM", &server.child.id().to_string()])
        .status()
        .expect("kill");
    assert!(status.success());
    let deadline = std::time::Instant::now() + T;
    let exit = loop {
        if let Some(exit) = server.child.try_wait().expect("wait") {
            break exit;
        }
        assert!(std::time::Instant::now() < deadline, "server did not stop");
        std::thread::sleep(Duration::from_millis(20));
    };
    assert!(exit.success(), "{exit:?}");
    let rest: Vec<String> = server.lines.try_iter().collect();
    assert!(
        rest.iter().any(|l| l.contains("\"connections_total\"")),
        "final JSON report: {rest:?}"
    );
}

/// The child half of the test above: does nothing unless that test started
/// this binary with `FARFIELD_SERVE_CHILD_DIR` set.
#[test]
#[ignore = "subprocess entry point: run by its parent test"]
fn serve_cli_child() {
    let Some(dir) = std::env::var_os("FARFIELD_SERVE_CHILD_DIR") else {
        return;
    };
    let dir = dir.to_string_lossy().into_owned();
    let extra = std::env::var("FARFIELD_SERVE_CHILD_ARGS").unwrap_or_default();
    let mut args = vec!["serve", "--scenes", &dir, "--json"];
    if !extra.contains("--listen") {
        args.extend(["--listen", "127.0.0.1:0"]);
    }
    args.extend(extra.split_whitespace());
    let report = crate::cli(&args).expect("serve");
    println!("{}", report.json);
}

/// A client that keeps asking for pages the scene lacks and never reads
/// the error replies is closed (1008, policy, when the close frame can
/// still reach it) once a bounded amount of them waits (`MAX_OUTBOX_BYTES`); the server queued no more, and serves a
/// client beside it. (Before, every reply waited: +590 MB in 10 s.)
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_that_never_reads_its_error_replies_is_closed_at_the_bound() {
    let dir = scenes_dir("serve-outbox");
    // The rate limit would close it first: lifted, so the bound is tested.
    let server = serve_with(&dir, |c| c.limits.max_messages_per_second = u32::MAX).await;
    let addr = server.local_addr();
    let (mut c, _, _) = Client::open(addr, "island", MIN_WINDOW, false).await;
    let bogus = Message::binary(encode_control(&ClientMessage::Request {
        pages: vec![PageWish {
            page: u32::MAX,
            priority: 1.0,
        }],
    }));
    // Replies of about 80 bytes each: far more than the socket buffers and
    // the bound together hold. Sending stops once the server has closed.
    let mut sent = 0u32;
    'flood: for _ in 0..1000 {
        for _ in 0..500 {
            match tokio::time::timeout(T, c.ws.feed(bogus.clone())).await {
                Ok(Ok(())) => sent += 1,
                _ => break 'flood,
            }
        }
        if !matches!(tokio::time::timeout(T, c.ws.flush()).await, Ok(Ok(()))) {
            break;
        }
    }
    assert!(sent > 10_000, "only {sent} requests went out");
    eprintln!("{sent} requests sent before the close");
    let closed = loop {
        match c.recv().await {
            In::Control(ServerMessage::Error { fatal: false, .. }) => continue,
            In::Closed(closed) => break closed,
            other => panic!("unexpected {other:?}"),
        }
    };
    // The close frame says why, when it fits into the buffers of a client
    // that does not read (it waits at most the close grace); either way the
    // connection is over.
    if let Some((code, reason)) = closed {
        assert_eq!(code, 1008, "{reason}");
        assert!(reason.contains("unread"), "{reason}");
    }
    let (_other, _, page0) = Client::open(addr, "tree", MIN_WINDOW, false).await;
    assert_eq!(page0, tree().pages[0]);
    server.shutdown().await.expect("shutdown");
}

/// A frame that breaks RFC 6455 itself (here: unmasked, from a client) is
/// closed with 1002 and counted as malformed. (It was dropped without a
/// close code and logged as "closed by the client".)
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_websocket_protocol_violation_is_closed_with_1002() {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let dir = scenes_dir("serve-unmasked");
    let server = serve(&dir).await;
    let addr = server.local_addr();
    let mut tcp = TcpStream::connect(addr).await.expect("connect");
    tcp.write_all(
        b"GET /scenes/island/stream HTTP/1.1\r\nHost: localhost\r\nUpgrade: websocket\r\n\
          Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n\
          Sec-WebSocket-Version: 13\r\n\r\n",
    )
    .await
    .expect("upgrade");
    let mut head = Vec::new();
    while !head.ends_with(b"\r\n\r\n") {
        let mut byte = [0u8];
        tokio::time::timeout(T, tcp.read_exact(&mut byte))
            .await
            .expect("upgrade answer timed out")
            .expect("read");
        head.push(byte[0]);
    }
    assert!(
        head.starts_with(b"HTTP/1.1 101"),
        "{}",
        String::from_utf8_lossy(&head)
    );
    // A binary frame of one byte, without the mask every client frame must have.
    tcp.write_all(&[0x82, 0x01, 0x00]).await.expect("send");
    let mut rest = Vec::new();
    let _ = tokio::time::timeout(T, tcp.read_to_end(&mut rest)).await;
    // Server frames are unmasked: 0x88 (close), a length, then the code.
    assert!(
        rest.len() >= 4 && rest[0] == 0x88,
        "no close frame: {rest:?}"
    );
    let code = u16::from_be_bytes([rest[2], rest[3]]);
    assert_eq!(code, 1002, "{}", String::from_utf8_lossy(&rest[4..]));
    assert!(server.metrics().malformed_frames >= 1);
    server.shutdown().await.expect("shutdown");
}
