//! What refusals tell a client: no path of the server's machine, and no
//! more of the client's own input than a short prefix.

use farfield_protocol::messages::{ClientMessage, ServerMessage};

use super::support::*;

/// A viewer folder that lacks the viewer's files: the 404 and the page
/// that says the viewer is not built name no folder of the server's.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn errors_to_clients_name_no_local_path() {
    let dir = scenes_dir("refusals-paths");
    let web = dir.join("empty-viewer-folder");
    std::fs::create_dir_all(&web).expect("mkdir");
    let server = serve_with(&dir, |c| c.web = Some(web.clone())).await;
    let addr = server.local_addr();
    let folder = dir.to_str().expect("utf-8 path");
    for path in [
        "/web/farfield_web.js",
        "/web/farfield_web_bg.wasm",
        "/view/island",
    ] {
        let (status, body) = http_get(addr, path).await;
        assert!(status == 404 || status == 503, "{path}: {status} {body}");
        assert!(!body.contains(folder), "{path} shows the path: {body}");
        assert!(!body.contains("empty-viewer-folder"), "{path}: {body}");
    }
    server.shutdown().await.expect("shutdown");
}

/// A session name of 100 KB, and one of 900 KB (which once overflowed
/// the write buffer and dropped the connection without a close frame),
/// are refused with a reply that quotes a short prefix; the connection
/// goes on.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_long_session_name_is_refused_with_a_short_quote() {
    let dir = scenes_dir("refusals-names");
    let server = serve(&dir).await;
    let (mut c, _, _) = Client::open(server.local_addr(), "island", MIN_WINDOW, false).await;
    c.ack([0]).await;
    for bytes in [100_000, 900_000] {
        c.send(&ClientMessage::Join {
            session: "n".repeat(bytes),
            present: true,
        })
        .await;
        match c.recv().await {
            In::Control(ServerMessage::SessionClosed { session, reason }) => {
                assert!(session.len() < 100, "{} bytes quoted", session.len());
                assert!(session.starts_with("nnnn"), "{session}");
                assert!(reason.contains("1 to 64"), "{reason}");
            }
            other => panic!("unexpected {other:?}"),
        }
    }
    c.request(&[(1, 1.0)]).await;
    assert!(matches!(c.recv().await, In::Page(1, _)), "still served");
    server.shutdown().await.expect("shutdown");
}

/// A request head of 114 KB written at once (hyper's buffer bound let it
/// through) is refused: 431, with a JSON reason, or the connection closed
/// unanswered; never served.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_request_head_past_64_kib_in_one_write_is_refused() {
    let dir = scenes_dir("refusals-head");
    let server = serve(&dir).await;
    let addr = server.local_addr();
    let padding = "a".repeat(114_000);
    let head = format!(
        "GET /scenes HTTP/1.1\r\nHost: {addr}\r\nX-Padding: {padding}\r\nConnection: close\r\n\r\n"
    );
    let answer = raw_request(addr, &head).await;
    assert!(
        answer.is_empty() || answer.starts_with("HTTP/1.1 431"),
        "{}",
        &answer[..answer.len().min(300)]
    );
    let small = format!(
        "GET /scenes HTTP/1.1\r\nHost: {addr}\r\nX-Padding: {}\r\nConnection: close\r\n\r\n",
        "a".repeat(60_000)
    );
    let answer = raw_request(addr, &small).await;
    assert!(
        answer.starts_with("HTTP/1.1 200"),
        "{}",
        &answer[..answer.len().min(300)]
    );
    server.shutdown().await.expect("shutdown");
}
