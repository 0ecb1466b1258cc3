//! What the server's tests share: scenes, a server on port 0, a raw HTTP GET
//! and a websocket client that speaks the protocol byte for byte.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::Duration;

use farfield_builder::PagedFile;
use farfield_builder::import::{Params, load_input};
use farfield_memory_server::{RunningServer, ServerConfig, start};
use farfield_net::stream_url;
use farfield_protocol::codec::{decode_control, encode_control, frame_kind};
use farfield_protocol::file::{FileHeader, HEADER_PREFIX_BYTES};
use farfield_protocol::messages::{
    ClientMessage, FrameKind, HEADER_PART_BYTES, PROTOCOL_VERSION, PageWish, ServerMessage,
};
use farfield_protocol::page::claimed_index;
use farfield_store::write_atomic;
use farfield_tests::scratch;
use futures_util::{SinkExt, StreamExt};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::{MaybeTlsStream, WebSocketStream};

use crate::build;

/// Longest any single wait may take before the test fails.
pub(crate) const T: Duration = Duration::from_secs(10);
/// How long without a frame counts as "the server has nothing more to send".
pub(crate) const QUIET: Duration = Duration::from_millis(400);
/// The server's smallest in-flight window (clients asking for less get this).
pub(crate) const MIN_WINDOW: u64 = 64 << 10;

pub(crate) fn island() -> &'static PagedFile {
    static FILE: OnceLock<PagedFile> = OnceLock::new();
    FILE.get_or_init(|| {
        let mut params = Params::default();
        params.set("size", 64);
        params.set("trees", 2);
        build(load_input("gen:island", &params).expect("gen:island"))
    })
}

pub(crate) fn tree() -> &'static PagedFile {
    static FILE: OnceLock<PagedFile> = OnceLock::new();
    FILE.get_or_init(|| build(load_input("gen:tree", &Params::default()).expect("gen:tree")))
}

/// A scratch folder with `island.ff`, `tree.ff`, a `.ff` that is not a
/// scene (skipped) and a file of another extension (ignored).
pub(crate) fn scenes_dir(name: &str) -> PathBuf {
    let dir = scratch(name);
    write_atomic(&dir.join("island.ff"), island()).expect("write island");
    write_atomic(&dir.join("tree.ff"), tree()).expect("write tree");
    std::fs::write(dir.join("broken.ff"), b"not a farfield file").expect("write broken");
    std::fs::write(dir.join("notes.txt"), b"ignored").expect("write notes");
    dir
}

pub(crate) async fn serve(dir: &Path) -> RunningServer {
    serve_with(dir, |_| {}).await
}

/// A server on port 0 for `dir`, its config changed by `tweak` first.
pub(crate) async fn serve_with(dir: &Path, tweak: impl FnOnce(&mut ServerConfig)) -> RunningServer {
    let listen: SocketAddr = "127.0.0.1:0".parse().expect("address");
    let mut config = ServerConfig::new(dir, listen);
    tweak(&mut config);
    tokio::time::timeout(T, start(config))
        .await
        .expect("start timed out")
        .expect("start")
}

/// `GET path` over a fresh connection; (status, body).
pub(crate) async fn http_get(addr: SocketAddr, path: &str) -> (u16, String) {
    tokio::time::timeout(T, async {
        let mut s = TcpStream::connect(addr).await.expect("connect");
        let request = format!("GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n");
        s.write_all(request.as_bytes()).await.expect("send");
        let mut buf = Vec::new();
        s.read_to_end(&mut buf).await.expect("read");
        let text = String::from_utf8(buf).expect("utf-8 response");
        let (head, body) = text.split_once("\r\n\r\n").expect("header end");
        let status = head
            .split(' ')
            .nth(1)
            .and_then(|s| s.parse().ok())
            .expect("status");
        (status, body.to_owned())
    })
    .await
    .expect("GET timed out")
}

/// Polls `cond` until it holds, failing the test after [`T`].
pub(crate) async fn eventually(what: &str, mut cond: impl FnMut() -> bool) {
    let deadline = tokio::time::Instant::now() + T;
    while !cond() {
        assert!(
            tokio::time::Instant::now() < deadline,
            "timed out waiting: {what}"
        );
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

/// One counter's value from the Prometheus text.
pub(crate) fn metric(text: &str, name: &str) -> u64 {
    text.lines()
        .find_map(|l| l.strip_prefix(name)?.strip_prefix(' ')?.parse().ok())
        .unwrap_or_else(|| panic!("{name} missing from /metrics:\n{text}"))
}

/// What a test client receives.
#[derive(Debug)]
pub(crate) enum In {
    Control(ServerMessage),
    Header(Vec<u8>),
    Page(u32, Vec<u8>),
    /// Close code and reason (none when the connection just ended).
    Closed(Option<(u16, String)>),
}

pub(crate) struct Client {
    pub(crate) ws: WebSocketStream<MaybeTlsStream<TcpStream>>,
    /// How many frames the header came in ([`Client::open`]).
    pub(crate) header_frames: usize,
    /// The root directory page, which comes before page 0.
    pub(crate) root_directory: Vec<u8>,
}

impl Client {
    pub(crate) async fn connect(addr: SocketAddr, scene: &str) -> Self {
        let url = stream_url(&addr.to_string(), scene);
        let (ws, _) = tokio::time::timeout(T, tokio_tungstenite::connect_async(url))
            .await
            .expect("connect timed out")
            .expect("websocket connect");
        Self::over(ws)
    }

    /// A client over a websocket opened some other way.
    pub(crate) fn over(ws: WebSocketStream<MaybeTlsStream<TcpStream>>) -> Self {
        Self {
            ws,
            header_frames: 0,
            root_directory: Vec::new(),
        }
    }

    /// Connects, says hello, and checks the server's hello, the scene header
    /// and page 0. Returns the client, the header bytes and page 0.
    pub(crate) async fn open(
        addr: SocketAddr,
        scene: &str,
        window: u64,
        allow_push: bool,
    ) -> (Self, Vec<u8>, Vec<u8>) {
        let mut c = Self::connect(addr, scene).await;
        c.send(&ClientMessage::Hello {
            protocol_version: PROTOCOL_VERSION,
            max_in_flight_bytes: window,
            allow_push,
        })
        .await;
        match c.recv().await {
            In::Control(ServerMessage::Hello {
                protocol_version, ..
            }) => assert_eq!(protocol_version, PROTOCOL_VERSION),
            other => panic!("expected Hello, got {other:?}"),
        }
        // The header in parts of at most HEADER_PART_BYTES, joined until
        // they hold the length its first bytes declare.
        let mut header = Vec::new();
        c.header_frames = 0;
        while header.len() < HEADER_PREFIX_BYTES
            || header.len() < FileHeader::peek_len(&header).expect("header prefix")
        {
            match c.recv().await {
                In::Header(part) => {
                    assert!(part.len() <= HEADER_PART_BYTES, "{} bytes", part.len());
                    header.extend_from_slice(&part);
                    c.header_frames += 1;
                }
                other => panic!("expected the header, got {other:?}"),
            }
        }
        // The root directory page (numbered after the scene's pages), then
        // page 0: with the header, the first image.
        let pages = FileHeader::decode(&header).expect("header").page_count;
        match c.recv().await {
            In::Page(root, bytes) if root == pages => c.root_directory = bytes,
            other => panic!("expected the root directory page {pages}, got {other:?}"),
        }
        let page0 = match c.recv().await {
            In::Page(0, bytes) => bytes,
            other => panic!("expected page 0, got {other:?}"),
        };
        (c, header, page0)
    }

    pub(crate) async fn send(&mut self, m: &ClientMessage) {
        self.send_raw(Message::binary(encode_control(m))).await;
    }

    /// Sends `m` if the connection still takes it (the server may have
    /// closed it already, which some tests expect); whether it went.
    pub(crate) async fn try_send(&mut self, m: &ClientMessage) -> bool {
        let frame = Message::binary(encode_control(m));
        matches!(
            tokio::time::timeout(T, self.ws.send(frame)).await,
            Ok(Ok(()))
        )
    }

    pub(crate) async fn send_raw(&mut self, m: Message) {
        tokio::time::timeout(T, self.ws.send(m))
            .await
            .expect("send timed out")
            .expect("send");
    }

    /// The next message, failing the test after [`T`].
    pub(crate) async fn recv(&mut self) -> In {
        self.recv_within(T).await.expect("nothing received in time")
    }

    /// The next message, or `None` if nothing came within `wait`.
    pub(crate) async fn recv_within(&mut self, wait: Duration) -> Option<In> {
        loop {
            let next = tokio::time::timeout(wait, self.ws.next()).await.ok()?;
            return Some(match next {
                Some(Ok(Message::Binary(b))) => match frame_kind(&b).expect("frame kind") {
                    (FrameKind::Page, page) => {
                        let index = claimed_index(page).expect("index");
                        In::Page(index, page.to_vec())
                    }
                    (FrameKind::Header, header) => In::Header(header.to_vec()),
                    (FrameKind::Control, _) => {
                        In::Control(decode_control(&b).expect("server control message"))
                    }
                },
                Some(Ok(Message::Close(frame))) => {
                    In::Closed(frame.map(|f| (u16::from(f.code), f.reason.to_string())))
                }
                Some(Ok(Message::Ping(_) | Message::Pong(_) | Message::Frame(_))) => continue,
                Some(Ok(Message::Text(t))) => panic!("server sent a text frame: {t}"),
                Some(Err(_)) | None => In::Closed(None),
            });
        }
    }

    /// Every page that arrives until the server goes quiet; other messages
    /// fail the test.
    pub(crate) async fn pages_until_quiet(&mut self) -> Vec<(u32, Vec<u8>)> {
        let mut pages = Vec::new();
        while let Some(m) = self.recv_within(QUIET).await {
            match m {
                In::Page(i, bytes) => pages.push((i, bytes)),
                other => panic!("expected pages, got {other:?}"),
            }
        }
        pages
    }

    /// The next `k` messages, which must all be pages.
    pub(crate) async fn pages(&mut self, k: usize) -> Vec<(u32, Vec<u8>)> {
        let mut pages = Vec::with_capacity(k);
        while pages.len() < k {
            match self.recv().await {
                In::Page(i, bytes) => pages.push((i, bytes)),
                other => panic!("expected a page, got {other:?}"),
            }
        }
        pages
    }

    /// Pages until at least `bytes` of them arrived (page bytes, counted
    /// from `already`).
    pub(crate) async fn pages_worth(&mut self, bytes: u64, already: u64) -> Vec<(u32, Vec<u8>)> {
        let mut got = Vec::new();
        let mut total = already;
        while total < bytes {
            match self.recv().await {
                In::Page(i, b) => {
                    total += b.len() as u64;
                    got.push((i, b));
                }
                other => panic!("expected a page, got {other:?}"),
            }
        }
        got
    }

    pub(crate) async fn ack(&mut self, pages: impl IntoIterator<Item = u32>) {
        self.send(&ClientMessage::Received {
            pages: pages.into_iter().collect(),
        })
        .await;
    }

    pub(crate) async fn request(&mut self, wishes: &[(u32, f32)]) {
        self.send(&ClientMessage::Request {
            pages: wishes
                .iter()
                .map(|&(page, priority)| PageWish { page, priority })
                .collect(),
        })
        .await;
    }
}

/// `farfield-server serve` in a child process (this test binary, running
/// `serve::serve_cli_child`), so its memory can be read from `/proc`
/// apart from the tests'. Killed on drop.
pub(crate) struct ChildServer {
    pub(crate) child: std::process::Child,
    pub(crate) addr: SocketAddr,
    /// Its stdout after the address line.
    pub(crate) lines: std::sync::mpsc::Receiver<String>,
}

impl ChildServer {
    pub(crate) fn start(dir: &Path, extra_args: &str) -> Self {
        Self::start_in(None, dir, extra_args)
    }

    /// As [`ChildServer::start`], inside network namespace `netns` (run
    /// through `ip netns exec`) when one is given.
    pub(crate) fn start_in(netns: Option<&str>, dir: &Path, extra_args: &str) -> Self {
        Self::start_with(netns, dir.as_os_str(), extra_args, &[])
    }

    /// As [`ChildServer::start`] for `scenes` (a folder, or an `s3://`
    /// prefix), with `envs` added to its environment.
    pub(crate) fn start_with(
        netns: Option<&str>,
        scenes: &std::ffi::OsStr,
        extra_args: &str,
        envs: &[(&'static str, String)],
    ) -> Self {
        Self::start_limited(netns, scenes, extra_args, envs, None)
    }

    /// As [`ChildServer::start_with`], with its open-files limit (soft and
    /// hard, as `ulimit -n` sets them) at `open_files` when given.
    pub(crate) fn start_limited(
        netns: Option<&str>,
        scenes: &std::ffi::OsStr,
        extra_args: &str,
        envs: &[(&'static str, String)],
        open_files: Option<u64>,
    ) -> Self {
        use std::io::{BufRead, BufReader};
        use std::os::unix::process::CommandExt;
        use std::process::{Command, Stdio};
        let exe = std::env::current_exe().expect("test binary");
        let mut command = match netns {
            Some(ns) => {
                let mut c = Command::new("ip");
                c.args(["netns", "exec", ns]).arg(exe);
                c
            }
            None => Command::new(exe),
        };
        if let Some(limit) = open_files {
            let limit = libc::rlimit {
                rlim_cur: limit as libc::rlim_t,
                rlim_max: limit as libc::rlim_t,
            };
            // SAFETY: between fork and exec only setrlimit runs, which is
            // async-signal-safe, on a value copied into the closure.
            unsafe {
                command.pre_exec(move || {
                    if libc::setrlimit(libc::RLIMIT_NOFILE, &limit) == 0 {
                        Ok(())
                    } else {
                        Err(std::io::Error::last_os_error())
                    }
                });
            }
        }
        let mut child = command
            .args(farfield_tests::child_test_args("serve::serve_cli_child"))
            .env("FARFIELD_SERVE_CHILD_DIR", scenes)
            .env("FARFIELD_SERVE_CHILD_ARGS", extra_args)
            .envs(envs.iter().map(|(k, v)| (k, v)))
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("spawn");
        let stdout = child.stdout.take().expect("stdout");
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        let addr = loop {
            let line = rx.recv_timeout(T).expect("no address printed");
            if let Some(addr) = line.strip_prefix("listening on ") {
                break addr.parse().expect("address");
            }
        };
        Self {
            child,
            addr,
            lines: rx,
        }
    }

    /// A field of `/proc/PID/status` in KiB (`VmRSS`, `VmHWM`).
    pub(crate) fn status_kib(&self, field: &str) -> u64 {
        let status = std::fs::read_to_string(format!("/proc/{}/status", self.child.id()))
            .expect("server process status");
        status
            .lines()
            .find_map(|l| l.strip_prefix(field)?.strip_prefix(':'))
            .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
            .unwrap_or_else(|| panic!("{field} missing from the status"))
    }

    /// Whether the process is still running.
    pub(crate) fn alive(&mut self) -> bool {
        matches!(self.child.try_wait(), Ok(None))
    }
}

impl Drop for ChildServer {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// `METHOD path` over a fresh connection; the whole response.
pub(crate) async fn raw_request(addr: SocketAddr, head: &str) -> String {
    let mut tcp = TcpStream::connect(addr).await.expect("connect");
    tcp.write_all(head.as_bytes()).await.expect("send");
    let mut got = Vec::new();
    tokio::time::timeout(T, tcp.read_to_end(&mut got))
        .await
        .expect("answer timed out")
        .expect("read");
    String::from_utf8_lossy(&got).into_owned()
}
