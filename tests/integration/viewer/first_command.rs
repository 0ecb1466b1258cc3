//! The README's first command, `farfield demo`, as a new user meets it:
//! it prints where to browse the scene and serves the browser viewer built
//! into the binary (no `web/build` run), writes its files, and keeps
//! serving; where there is a display it opens the window viewer too.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::time::Duration;

use farfield_memory_server::web_assets;
use farfield_tests::scratch;

use super::window::{ViewerProcess, xdotool};
use super::{have, missing};
use crate::xvfb::start_xvfb;

/// The demo's arguments for a child (tab-separated): a free port.
fn demo_args(out: &std::path::Path) -> String {
    format!("demo\t--out\t{}\t--listen\t127.0.0.1:0", out.display())
}

/// The server's address in `browse the island: http://ADDR/view/island`.
fn address_of(line: &str) -> SocketAddr {
    let rest = line
        .trim()
        .strip_prefix("http://")
        .expect("an http address");
    let addr = rest.split('/').next().unwrap_or_default();
    addr.parse()
        .unwrap_or_else(|_| panic!("an address in {line:?}"))
}

/// A GET with `headers`: the status, the response's head and its body.
fn get(addr: SocketAddr, path: &str, headers: &str) -> (u16, String, Vec<u8>) {
    let mut s = TcpStream::connect(addr).expect("connect");
    s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    let request =
        format!("GET {path} HTTP/1.1\r\nHost: {addr}\r\n{headers}Connection: close\r\n\r\n");
    s.write_all(request.as_bytes()).expect("send");
    let mut bytes = Vec::new();
    s.read_to_end(&mut bytes).expect("read");
    let end = bytes
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .expect("a head");
    let head = String::from_utf8_lossy(&bytes[..end]).to_ascii_lowercase();
    let status = head
        .split(' ')
        .nth(1)
        .and_then(|s| s.parse().ok())
        .expect("a status");
    (status, head, bytes[end + 4..].to_vec())
}

/// A header's value in a lowercased head.
fn header<'a>(head: &'a str, name: &str) -> Option<&'a str> {
    head.lines()
        .find_map(|l| l.strip_prefix(name)?.strip_prefix(':'))
        .map(str::trim)
}

/// Without a display: the address first, the viewer's files served from
/// the binary (gzipped where asked, and not sent again to a page that has
/// them), the demo's files written, then serving until Ctrl-C, which ends
/// it cleanly.
#[test]
fn the_first_command_serves_the_browser_viewer_built_into_it() {
    let Some(viewer) = web_assets::embedded() else {
        return missing(&format!(
            "the first command's test needs the viewer built into the server ({})",
            web_assets::not_embedded()
        ));
    };
    let out = scratch("first-command");
    let mut demo = ViewerProcess::spawn("", &demo_args(&out));
    let addr = address_of(&demo.next("browse the island: "));
    let (status, head, body) = get(addr, "/web/farfield_web_bg.wasm", "");
    assert_eq!(status, 200, "{head}");
    assert_eq!(header(&head, "content-type"), Some("application/wasm"));
    assert!(
        body == viewer.wasm,
        "the wasm built in ({} bytes)",
        body.len()
    );
    let tag = header(&head, "etag").expect("an entity tag").to_owned();
    let (status, head, body) = get(
        addr,
        "/web/farfield_web_bg.wasm",
        "Accept-Encoding: gzip, deflate, br\r\n",
    );
    assert_eq!(status, 200, "{head}");
    assert_eq!(header(&head, "content-encoding"), Some("gzip"));
    assert!(body == viewer.wasm_gzip, "{} bytes gzipped", body.len());
    let (status, head, body) = get(addr, "/web/farfield_web.js", "");
    assert_eq!((status, body.as_slice()), (200, viewer.js), "{head}");
    let again = format!("If-None-Match: {tag}\r\n");
    let (status, _, body) = get(addr, "/web/farfield_web_bg.wasm", &again);
    assert_eq!((status, body.len()), (304, 0), "a page that has it");
    let (status, _, page) = get(addr, "/view/island", "");
    let page = String::from_utf8_lossy(&page);
    assert_eq!(status, 200, "{page}");
    assert!(page.contains("farfield_web.js"), "{page}");
    // The demo's files, then serving on.
    demo.next("files: ");
    let rest = demo.next("browse the island: ");
    assert!(rest.ends_with("(Ctrl-C to stop)"), "{rest}");
    assert!(out.join("summary.txt").is_file() && out.join("frames.csv").is_file());
    assert_eq!(get(addr, "/view/island", "").0, 200, "still serving");
    assert!(demo.interrupt(), "Ctrl-C ends the demo with success");
}

/// With a display, the demo opens the window viewer on its server once
/// its files are written.
#[test]
fn the_first_command_opens_the_window_viewer_where_there_is_a_display() {
    let Some(xvfb) = start_xvfb() else {
        return missing("the window test needs Xvfb (apt-get install xvfb)");
    };
    if !have("xdotool") {
        return missing("the window test needs xdotool (apt-get install xdotool)");
    }
    let out = scratch("first-command-window");
    let mut demo = ViewerProcess::spawn(xvfb.display(), &demo_args(&out));
    let addr = address_of(&demo.next("browse the island: "));
    let rest = demo.next("browse the island: ");
    assert!(rest.contains("the window viewer is open"), "{rest}");
    let mut names = Vec::new();
    for _ in 0..150 {
        let out = std::process::Command::new("xdotool")
            .args(["search", "--name", "farfield"])
            .env("DISPLAY", xvfb.display())
            .output()
            .expect("xdotool");
        let found = String::from_utf8_lossy(&out.stdout).to_string();
        names = found
            .lines()
            .map(|w| xdotool(xvfb.display(), &["getwindowname", w]))
            .collect();
        if !names.is_empty() {
            break;
        }
        std::thread::sleep(Duration::from_millis(200));
    }
    let title = format!("farfield · island on http://{addr}");
    assert!(names.contains(&title), "windows: {names:?}, not {title:?}");
}
