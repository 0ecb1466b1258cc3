//! Limits and timeouts on a real server: connections past the limits are
//! refused with 503 and 429, silent and slowloris connections are closed
//! at the header timeout, quiet sessions at the idle timeout, a late hello
//! at the hello timeout, and a flood of messages at the rate limit; every
//! one counted in `/metrics`, and a well-behaved client served beside them.

use std::net::SocketAddr;
use std::time::{Duration, Instant};

use farfield_memory_server::RunningServer;
use farfield_protocol::messages::{ClientMessage, ServerMessage};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpSocket, TcpStream};
use tokio_tungstenite::tungstenite::Message;

use super::support::*;

/// A TCP connection to `server` from the loopback address `from`
/// (127.0.0.0/8 is all loopback on Linux, so tests can be many clients).
pub(crate) async fn connect_from(from: [u8; 4], server: SocketAddr) -> TcpStream {
    let socket = TcpSocket::new_v4().expect("socket");
    socket
        .bind(SocketAddr::from((from, 0)))
        .expect("bind a loopback address");
    tokio::time::timeout(T, socket.connect(server))
        .await
        .expect("connect timed out")
        .expect("connect")
}

/// Reads until the server closes the connection; what it sent.
async fn until_closed(tcp: &mut TcpStream) -> String {
    let mut got = Vec::new();
    let _ = tokio::time::timeout(T, tcp.read_to_end(&mut got))
        .await
        .expect("the server never closed the connection");
    String::from_utf8_lossy(&got).into_owned()
}

async fn limit_hits(server: &RunningServer, limit: &str) -> u64 {
    let (_, text) = http_get(server.local_addr(), "/metrics").await;
    metric(
        &text,
        &format!("farfield_limit_hits_total{{limit=\"{limit}\"}}"),
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn connections_past_the_limits_are_refused_with_503_and_429() {
    let dir = scenes_dir("limits-connections");
    let server = serve_with(&dir, |c| {
        c.limits.max_connections = 4;
        c.limits.max_connections_per_address = 2;
    })
    .await;
    let addr = server.local_addr();
    let _a1 = connect_from([127, 0, 0, 2], addr).await;
    let _a2 = connect_from([127, 0, 0, 2], addr).await;
    let mut a3 = connect_from([127, 0, 0, 2], addr).await;
    let answer = until_closed(&mut a3).await;
    assert!(answer.starts_with("HTTP/1.1 429"), "{answer}");
    assert!(
        answer.contains("\"error\"") && answer.contains("this address"),
        "{answer}"
    );
    let _b1 = connect_from([127, 0, 0, 3], addr).await;
    let b2 = connect_from([127, 0, 0, 3], addr).await;
    let mut c1 = connect_from([127, 0, 0, 4], addr).await;
    let answer = until_closed(&mut c1).await;
    assert!(answer.starts_with("HTTP/1.1 503"), "{answer}");
    assert!(answer.contains("full"), "{answer}");
    // A place given back is a place to take.
    drop(b2);
    let deadline = Instant::now() + T;
    let status = loop {
        let mut tcp = connect_from([127, 0, 0, 1], addr).await;
        tcp.write_all(b"GET /healthz HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n")
            .await
            .expect("send");
        let answer = until_closed(&mut tcp).await;
        if answer.starts_with("HTTP/1.1 200") || Instant::now() > deadline {
            break answer;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    };
    assert!(status.starts_with("HTTP/1.1 200"), "{status}");
    drop((_a1, _a2, _b1));
    let deadline = Instant::now() + T;
    // /metrics needs a place too; wait for the idle ones to be dropped.
    while server.metrics().limit_hits["max_connections"] == 0 && Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let hits = server.metrics().limit_hits;
    assert!(hits["max_connections"] >= 1, "{hits:?}");
    assert!(hits["max_connections_per_address"] >= 1, "{hits:?}");
    server.shutdown().await.expect("shutdown");
}

/// A connection that sends nothing, and one that sends its headers a byte
/// every 100 ms (slowloris), are both closed at the header timeout.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn silent_and_slowloris_connections_are_closed_at_the_header_timeout() {
    let dir = scenes_dir("limits-header");
    let server = serve_with(&dir, |c| {
        c.limits.header_timeout = Duration::from_millis(400);
    })
    .await;
    let addr = server.local_addr();
    let started = Instant::now();
    let mut silent = connect_from([127, 0, 0, 1], addr).await;
    let mut slow = connect_from([127, 0, 0, 1], addr).await;
    let slowloris = tokio::spawn(async move {
        let head = b"GET /scenes HTTP/1.1\r\nHost: localhost\r\nX-Slow: aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa";
        for byte in head {
            if slow.write_all(&[*byte]).await.is_err() {
                return (true, slow);
            }
            tokio::time::sleep(Duration::from_millis(100)).await;
            // A closed connection reads as end of file (or an error).
            let mut probe = [0u8; 64];
            match tokio::time::timeout(Duration::from_millis(1), slow.read(&mut probe)).await {
                Ok(Ok(0)) | Ok(Err(_)) => return (true, slow),
                _ => {}
            }
        }
        (false, slow)
    });
    until_closed(&mut silent).await;
    let silent_after = started.elapsed();
    let (closed, _slow) = slowloris.await.expect("slowloris task");
    assert!(closed, "the slowloris connection was never closed");
    assert!(
        silent_after >= Duration::from_millis(350),
        "closed before its timeout: {silent_after:?}"
    );
    assert!(limit_hits(&server, "header_timeout").await >= 2);
    server.shutdown().await.expect("shutdown");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_hello_that_never_comes_ends_the_session_at_the_hello_timeout() {
    let dir = scenes_dir("limits-hello");
    let server = serve_with(&dir, |c| {
        c.limits.hello_timeout = Duration::from_millis(300)
    })
    .await;
    let mut c = Client::connect(server.local_addr(), "island").await;
    match c.recv().await {
        In::Control(ServerMessage::Error { message, fatal }) => {
            assert!(fatal && message.contains("no Hello"), "{message}");
        }
        other => panic!("expected a fatal error, got {other:?}"),
    }
    assert!(limit_hits(&server, "hello_timeout").await >= 1);
    server.shutdown().await.expect("shutdown");
}

/// A session that reads (so its websocket layer answers the server's
/// pings) stays open however quiet; one that reads nothing is closed at
/// the idle timeout (1001), after being pinged.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_session_that_answers_pings_stays_and_a_silent_one_is_closed_when_idle() {
    let dir = scenes_dir("limits-idle");
    let idle = Duration::from_millis(600);
    let server = serve_with(&dir, |c| c.limits.idle_timeout = idle).await;
    let addr = server.local_addr();
    let (mut silent, _, _) = Client::open(addr, "island", MIN_WINDOW, false).await;
    let (mut alive, _, _) = Client::open(addr, "tree", MIN_WINDOW, false).await;
    // Reading (and so answering pings) for three idle timeouts.
    let until = Instant::now() + idle * 3;
    while Instant::now() < until {
        if let Some(m) = alive.recv_within(Duration::from_millis(50)).await {
            panic!("nothing was asked for, got {m:?}");
        }
    }
    alive.request(&[(1, 1.0)]).await;
    assert!(matches!(alive.recv().await, In::Page(1, _)), "still served");
    // The silent one was closed meanwhile. Its buffered close frame says
    // why, when its websocket layer reads that far: answering the pings
    // before it may already fail on the closed socket.
    let In::Closed(closed) = silent.recv().await else {
        panic!("expected the close");
    };
    if let Some((code, reason)) = closed {
        assert_eq!(code, 1001, "{reason}");
        assert!(reason.contains("nothing from the client"), "{reason}");
    }
    assert_eq!(
        limit_hits(&server, "idle_timeout").await,
        1,
        "only the silent one"
    );
    server.shutdown().await.expect("shutdown");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_sending_past_the_message_rate_is_closed_with_1008() {
    let dir = scenes_dir("limits-rate");
    let server = serve_with(&dir, |c| c.limits.max_messages_per_second = 50).await;
    let addr = server.local_addr();
    let (mut c, _, _) = Client::open(addr, "island", MIN_WINDOW, false).await;
    let ack = Message::binary(farfield_protocol::codec::encode_control(
        &ClientMessage::Received { pages: vec![] },
    ));
    for _ in 0..200 {
        if !matches!(
            tokio::time::timeout(T, futures_util::SinkExt::send(&mut c.ws, ack.clone())).await,
            Ok(Ok(()))
        ) {
            break;
        }
    }
    let In::Closed(closed) = c.recv().await else {
        panic!("expected the close");
    };
    let (code, reason) = closed.expect("a close frame");
    assert_eq!(code, 1008, "{reason}");
    assert!(reason.contains("messages a second"), "{reason}");
    assert!(limit_hits(&server, "message_rate").await >= 1);
    let (_other, _, page0) = Client::open(addr, "tree", MIN_WINDOW, false).await;
    assert_eq!(page0, tree().pages[0]);
    server.shutdown().await.expect("shutdown");
}

/// Acknowledgements of pages the server sent are answers, not demands: a
/// client acknowledging every page on its own, far past the message rate,
/// is served to the end. (Counted, they closed bench-stream's one fast
/// client 1008 and cut its throughput to 0.04 of what it was.)
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn acknowledgements_of_sent_pages_do_not_count_against_the_rate() {
    let dir = scenes_dir("limits-acks");
    let server = serve_with(&dir, |c| c.limits.max_messages_per_second = 2).await;
    let addr = server.local_addr();
    let (mut c, _, _) = Client::open(addr, "island", 64 << 20, false).await;
    c.ack([0]).await;
    let n = island().pages.len() as u32;
    assert!(n > 4, "{n} pages: too few to pass the rate");
    let wishes: Vec<(u32, f32)> = (1..n).map(|p| (p, 1.0)).collect();
    c.request(&wishes).await;
    for _ in 1..n {
        match c.recv().await {
            In::Page(i, _) => c.ack([i]).await,
            other => panic!("unexpected {other:?}"),
        }
    }
    assert_eq!(limit_hits(&server, "message_rate").await, 0);
    server.shutdown().await.expect("shutdown");
}
