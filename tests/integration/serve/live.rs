//! The scenes folder while serving: files added, replaced by a rename,
//! truncated, overwritten in place and deleted. The server never crashes
//! and never sends a byte that is not the scene's: a scene whose file
//! changed under it is taken out of service with a message to its clients,
//! a replaced one serves its new version to new sessions.

use std::path::Path;
use std::time::Duration;

use farfield_builder::PagedFile;
use farfield_memory_server::RunningServer;
use farfield_protocol::messages::{ClientMessage, PageWish, ServerMessage};
use farfield_store::write_atomic;

use super::support::*;

/// Rescans often, so the tests wait little.
async fn serve_live(dir: &Path) -> RunningServer {
    serve_with(dir, |c| c.rescan_interval = Duration::from_millis(50)).await
}

/// Names `/scenes` lists now.
async fn listed(server: &RunningServer) -> Vec<String> {
    let (status, body) = http_get(server.local_addr(), "/scenes").await;
    assert_eq!(status, 200, "{body}");
    let v: serde_json::Value = serde_json::from_str(&body).expect("json");
    v.as_array()
        .expect("array")
        .iter()
        .map(|s| s["name"].as_str().expect("name").to_owned())
        .collect()
}

/// Waits until `/scenes` lists `name` (or, with `present` false, does not).
async fn until_listed(server: &RunningServer, name: &str, present: bool) {
    let deadline = tokio::time::Instant::now() + T;
    while listed(server).await.iter().any(|n| n == name) != present {
        assert!(
            tokio::time::Instant::now() < deadline,
            "{name} listed: expected {present}"
        );
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

/// Reads until the server's fatal message and its close; every page that
/// arrives first must be `file`'s. Returns the message and the close.
async fn until_retired(c: &mut Client, file: &PagedFile) -> (String, Option<(u16, String)>) {
    let mut message = None;
    loop {
        match c.recv().await {
            In::Page(i, bytes) => {
                assert!(message.is_none(), "page {i} after the fatal message");
                assert_eq!(
                    bytes, file.pages[i as usize],
                    "page {i}: not the scene's bytes"
                );
                c.try_send(&ClientMessage::Received { pages: vec![i] })
                    .await;
            }
            In::Control(ServerMessage::Error { message: m, fatal }) => {
                assert!(fatal, "{m}");
                message = Some(m);
            }
            In::Control(ServerMessage::PageUnavailable { page, reason }) => {
                panic!("page {page} unavailable ({reason}): the scene should be retired instead")
            }
            In::Closed(closed) => return (message.expect("a fatal message first"), closed),
            other => panic!("unexpected {other:?}"),
        }
    }
}

/// A file's bytes as stored.
fn file_bytes(file: &PagedFile) -> Vec<u8> {
    file.to_bytes()
}

fn all_pages(file: &PagedFile) -> Vec<(u32, f32)> {
    (1..file.pages.len() as u32).map(|p| (p, 1.0)).collect()
}

/// A request for every page but page 0.
fn wanted(file: &PagedFile) -> ClientMessage {
    ClientMessage::Request {
        pages: all_pages(file)
            .into_iter()
            .map(|(page, priority)| PageWish { page, priority })
            .collect(),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_scene_added_while_serving_appears_and_a_deleted_one_disappears() {
    let dir = scenes_dir("live-add-delete");
    let server = serve_live(&dir).await;
    assert_eq!(listed(&server).await, ["island", "tree"]);
    // Copied in by a plain write, as a user would: served once complete.
    std::fs::write(dir.join("forest.ff"), file_bytes(tree())).expect("write forest");
    until_listed(&server, "forest", true).await;
    let (_forest, header, page0) =
        Client::open(server.local_addr(), "forest", MIN_WINDOW, false).await;
    assert_eq!(header, tree().header.encode());
    assert_eq!(page0, tree().pages[0]);

    let (mut c, _, _) = Client::open(server.local_addr(), "tree", MIN_WINDOW, false).await;
    std::fs::remove_file(dir.join("tree.ff")).expect("delete");
    let (message, closed) = until_retired(&mut c, tree()).await;
    assert!(
        message.contains("\"tree\"") && message.contains("deleted"),
        "{message}"
    );
    if let Some((code, reason)) = closed {
        assert_eq!(code, 1001, "{reason}");
    }
    until_listed(&server, "tree", false).await;
    let (status, body) = http_get(server.local_addr(), "/scenes/tree").await;
    assert_eq!(status, 404, "{body}");
    // The other scenes go on.
    let (_island, _, page0) = Client::open(server.local_addr(), "island", MIN_WINDOW, false).await;
    assert_eq!(page0, island().pages[0]);
    server.shutdown().await.expect("shutdown");
}

/// A rebuild renamed over a served file (what `build --out` does): new
/// sessions get the new version; a session already open finishes on the
/// version it started with, every page its own.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_scene_replaced_by_a_rename_serves_its_new_version_to_new_sessions_only() {
    let dir = scenes_dir("live-replace");
    let server = serve_live(&dir).await;
    let addr = server.local_addr();
    let (mut old, _, _) = Client::open(addr, "island", 64 << 20, false).await;
    write_atomic(&dir.join("island.ff"), tree()).expect("replace");
    let deadline = tokio::time::Instant::now() + T;
    loop {
        let (_c, header, page0) = Client::open(addr, "island", MIN_WINDOW, false).await;
        if header == tree().header.encode() {
            assert_eq!(page0, tree().pages[0]);
            break;
        }
        assert_eq!(header, island().header.encode(), "one version or the other");
        assert!(
            tokio::time::Instant::now() < deadline,
            "new version never served"
        );
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let wanted = all_pages(island());
    old.request(&wanted).await;
    let pages = old.pages(wanted.len()).await;
    for (i, bytes) in pages {
        assert_eq!(
            bytes,
            island().pages[i as usize],
            "page {i} of the old version"
        );
    }
    server.shutdown().await.expect("shutdown");
}

/// A served file cut short under the server (another process truncating
/// it): no page past the cut is sent and none that is not the scene's;
/// the scene leaves service with a message to its client, the server and
/// the other scenes go on, and the file is served again once it is whole.
/// (When pages were read through a memory map, the first read past the new
/// end raised SIGBUS and killed the process.)
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_scene_file_truncated_while_served_is_taken_out_of_service() {
    let dir = scenes_dir("live-truncated");
    let server = serve_live(&dir).await;
    let addr = server.local_addr();
    let (mut c, _, _) = Client::open(addr, "island", 64 << 20, false).await;
    let file = island();
    let n = file.pages.len();
    assert!(n >= 6, "{n} pages");
    let cut = file.directory.entry((n * 3 / 4) as u32).unwrap().offset + 1;
    std::fs::OpenOptions::new()
        .write(true)
        .open(dir.join("island.ff"))
        .and_then(|f| f.set_len(cut))
        .expect("truncate");
    c.try_send(&wanted(file)).await;
    let (message, closed) = until_retired(&mut c, file).await;
    assert!(
        message.contains("taken out of service") && message.contains("changed on disk"),
        "{message}"
    );
    if let Some((code, reason)) = closed {
        assert_eq!(code, 1001, "{reason}");
    }
    until_listed(&server, "island", false).await;
    let (_tree, _, page0) = Client::open(addr, "tree", MIN_WINDOW, false).await;
    assert_eq!(page0, tree().pages[0]);
    write_atomic(&dir.join("island.ff"), island()).expect("restore");
    until_listed(&server, "island", true).await;
    let (_again, header, _) = Client::open(addr, "island", MIN_WINDOW, false).await;
    assert_eq!(header, island().header.encode());
    server.shutdown().await.expect("shutdown");
}

/// Another scene copied over a served file in place (`cp`: the same file,
/// truncated and rewritten): the session open on it is told and closed,
/// never handed a page of the other scene; new sessions get the new
/// contents.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_scene_file_overwritten_in_place_is_retired_then_served_anew() {
    let dir = scenes_dir("live-overwritten");
    let server = serve_live(&dir).await;
    let addr = server.local_addr();
    let (mut c, _, _) = Client::open(addr, "island", 64 << 20, false).await;
    std::fs::write(dir.join("island.ff"), file_bytes(tree())).expect("overwrite");
    // The server may have noticed and closed the session already.
    c.try_send(&wanted(island())).await;
    let (message, _) = until_retired(&mut c, island()).await;
    assert!(message.contains("changed on disk"), "{message}");
    let deadline = tokio::time::Instant::now() + T;
    loop {
        if listed(&server).await.iter().any(|n| n == "island") {
            let (_c, header, page0) = Client::open(addr, "island", MIN_WINDOW, false).await;
            assert_eq!(header, tree().header.encode());
            assert_eq!(page0, tree().pages[0]);
            break;
        }
        assert!(
            tokio::time::Instant::now() < deadline,
            "new contents never served"
        );
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    server.shutdown().await.expect("shutdown");
}
