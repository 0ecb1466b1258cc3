//! Clients that never read their socket while they send, against a server
//! in a child process whose memory is read from `/proc`: requests for pages
//! that do not exist (error replies), pings (pongs) and cancels of arbitrary
//! pages. Each must cost a bounded amount (issue 18 measured, before the
//! bounds, +590 MB, +519 MB and about 1 GB in 10 to 20 s), and a client
//! beside them is served its page 0 as before.

use std::time::{Duration, Instant};

use farfield_protocol::codec::encode_control;
use farfield_protocol::messages::{ClientMessage, PageWish};
use futures_util::SinkExt;
use tokio_tungstenite::tungstenite::Message;

use super::support::*;

/// How long each hostile client floods.
const FLOOD: Duration = Duration::from_secs(3);
/// Growth of the server's peak RSS over its start allowed for all floods
/// together: a few connections' bounds (about 1.3 MiB each, see
/// `farfield_memory_server::limits`) plus allocator slack, far below what one
/// unbounded flood grows in this time.
const ALLOWED_GROWTH_KIB: u64 = 48 << 10;

/// Sends `message` as fast as the socket takes it for [`FLOOD`], never
/// reading; how many went, and the server's RSS (KiB) every half second.
async fn flood(c: &mut Client, message: Message, server: &ChildServer) -> (u64, Vec<u64>) {
    let started = Instant::now();
    let until = started + FLOOD;
    let mut sent = 0;
    let mut rss = vec![server.status_kib("VmRSS")];
    while Instant::now() < until {
        if started.elapsed() >= Duration::from_millis(500) * rss.len() as u32 {
            rss.push(server.status_kib("VmRSS"));
        }
        for _ in 0..256 {
            match tokio::time::timeout(Duration::from_millis(200), c.ws.feed(message.clone())).await
            {
                Ok(Ok(())) => sent += 1,
                // The server stopped taking them (closed, or the socket is
                // full because nothing is read): keep trying until the end.
                Ok(Err(_)) => return (sent, rss),
                Err(_) => break,
            }
        }
        if let Ok(Err(_)) = tokio::time::timeout(Duration::from_millis(200), c.ws.flush()).await {
            return (sent, rss);
        }
    }
    (sent, rss)
}

#[cfg(target_os = "linux")]
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn clients_that_never_read_cost_a_bounded_amount_and_others_are_served() {
    let dir = scenes_dir("hostile");
    // The rate limit is lifted so the buffers' bounds, not it, are tested.
    let mut server = ChildServer::start(&dir, "--max-messages-per-second 1000000000");
    let addr = server.addr;
    let (_warm, _, page0) = Client::open(addr, "island", MIN_WINDOW, false).await;
    assert_eq!(page0, island().pages[0]);
    let start_kib = server.status_kib("VmRSS");

    let pages = island().pages.len() as u32;
    let attacks: [(&str, ClientMessage); 3] = [
        (
            "requests for pages that do not exist",
            ClientMessage::Request {
                pages: vec![PageWish {
                    page: u32::MAX,
                    priority: 1.0,
                }],
            },
        ),
        ("pings", ClientMessage::Received { pages: vec![] }),
        (
            "cancels of arbitrary pages",
            ClientMessage::Cancel {
                pages: (0..500).map(|i| i * 7_919 % (pages * 4)).collect(),
            },
        ),
    ];
    for (what, message) in attacks {
        let (mut hostile, _, _) = Client::open(addr, "island", MIN_WINDOW, false).await;
        let frame = if what == "pings" {
            Message::Ping(vec![7u8; 125].into())
        } else {
            Message::binary(encode_control(&message))
        };
        let (sent, rss) = flood(&mut hostile, frame, &server).await;
        let peak = server.status_kib("VmHWM");
        eprintln!(
            "{what}: {sent} sent in {FLOOD:?}; server RSS {start_kib} KiB at start, \
             every 0.5 s {rss:?} KiB, peak {peak} KiB"
        );
        assert!(sent > 1_000, "{what}: only {sent} went out");
        assert!(server.alive(), "{what}: the server died");
        assert!(
            peak.saturating_sub(start_kib) <= ALLOWED_GROWTH_KIB,
            "{what}: the server grew from {start_kib} KiB to {peak} KiB"
        );
        let (_good, _, page0) = Client::open(addr, "tree", MIN_WINDOW, false).await;
        assert_eq!(page0, tree().pages[0], "{what}: a good client after it");
        drop(hostile);
    }
}
