//! What the server counts and whom it closes: refusals stay within the
//! descriptors it has, an ordinary disconnect is not a protocol violation,
//! and a server that falls behind does not close the clients it kept
//! waiting.

use std::time::{Duration, Instant};

use farfield_protocol::messages::ClientMessage;
use tokio::io::{AsyncReadExt, AsyncWriteExt};

use super::limits::connect_from;
use super::support::*;

/// `ulimit -n 400`: the server fits its connections and the refusals it
/// answers into the descriptors it has, so 600 idle connections from 6
/// addresses are admitted or refused, and not one accept fails for want of
/// a descriptor (they did: "Too many open files").
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn refusals_stay_within_the_descriptor_reserve() {
    let dir = scenes_dir("accounting-descriptors");
    let server = ChildServer::start_limited(None, dir.as_os_str(), "", &[], Some(400));
    let addr = server.addr;
    let mut held = Vec::new();
    for host in 2..8u8 {
        for _ in 0..100 {
            held.push(connect_from([127, 0, 0, host], addr).await);
        }
    }
    // Every connection is answered, refused, or sits admitted; the
    // refused ones hold their answers' descriptors for a while.
    tokio::time::sleep(Duration::from_millis(1500)).await;
    drop(held);
    let deadline = Instant::now() + T;
    let text = loop {
        let mut tcp = tokio::net::TcpStream::connect(addr).await.expect("connect");
        let head = format!("GET /metrics HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n");
        tcp.write_all(head.as_bytes()).await.expect("send");
        let mut got = String::new();
        let _ = tokio::time::timeout(T, tcp.read_to_string(&mut got)).await;
        if got.starts_with("HTTP/1.1 200") {
            break got;
        }
        assert!(Instant::now() < deadline, "never served again: {got}");
        tokio::time::sleep(Duration::from_millis(200)).await;
    };
    assert!(
        metric(
            &text,
            "farfield_limit_hits_total{limit=\"max_connections\"}"
        ) > 0,
        "the flood was refused: {text}"
    );
    assert_eq!(metric(&text, "farfield_accept_errors_total"), 0, "{text}");
}

/// A client that read everything and closed TCP without a close frame has
/// disconnected, not broken the protocol.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_clean_disconnect_is_not_counted_as_malformed() {
    let dir = scenes_dir("accounting-disconnect");
    let server = serve(&dir).await;
    let (c, _, _) = Client::open(server.local_addr(), "island", MIN_WINDOW, false).await;
    drop(c);
    eventually("the session ended", || {
        server.metrics().connected_clients == 0 && server.metrics().connections_total == 1
    })
    .await;
    eventually("counted as a disconnect", || {
        server.metrics().dropped_connections == 1
    })
    .await;
    assert_eq!(server.metrics().malformed_frames, 0);
    server.shutdown().await.expect("shutdown");
}

/// A client sending at half the rate limit to a server whose runtime is
/// stalled for 2.5 s: the server reads its 2.5 s of messages at once, more
/// than a second's worth of the limit, and must not take that for a
/// burst of the client's.
#[test]
fn a_stalled_server_does_not_close_a_client_within_the_rate() {
    const RATE: u32 = 40;
    let dir = scenes_dir("accounting-rate");
    let server_rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("server runtime");
    let server = server_rt.block_on(serve_with(&dir, |c| {
        c.limits.max_messages_per_second = RATE
    }));
    let addr = server.local_addr();
    let client_rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("client runtime");
    let (mut c, _, _) = client_rt.block_on(Client::open(addr, "island", MIN_WINDOW, false));
    // Stalls both of the server's workers (as a CPU overload would).
    let stall = Duration::from_millis(2500);
    let start_stall = Instant::now() + Duration::from_millis(300);
    for _ in 0..2 {
        server_rt.spawn(async move {
            tokio::time::sleep_until(start_stall.into()).await;
            std::thread::sleep(stall);
        });
    }
    let nothing = ClientMessage::Received { pages: vec![] };
    let every = Duration::from_secs(1) / (RATE / 2);
    client_rt.block_on(async {
        let until = Instant::now() + Duration::from_millis(3500);
        while Instant::now() < until {
            c.send(&nothing).await;
            tokio::time::sleep(every).await;
        }
        c.request(&[(1, 1.0)]).await;
        match c.recv().await {
            In::Page(1, _) => {}
            other => panic!("closed or not served: {other:?}"),
        }
    });
    assert_eq!(
        server.metrics().limit_hits.get("message_rate").copied(),
        Some(0)
    );
    server_rt.block_on(server.shutdown()).expect("shutdown");
}
