//! The server's HTTP and websocket session layer: bytes from a client into
//! a real server (`farfield_memory_server::start`, serving a small tree), over an
//! in-memory pipe instead of a socket (`RunningServer::serve_stream`).
//!
//! The first byte picks what the rest is:
//! - even: raw bytes of one HTTP/1.1 connection (request heads, bodies,
//!   upgrades; the access checks and every route);
//! - odd: a websocket upgrade of `/scenes/tree/stream`, then websocket
//!   frames, each `[opcode][length: u16 LE][payload]` masked as a client's
//!   must be; with bit 1 set a valid Hello goes first, so mutations reach
//!   the session's state machine (requests, cancels, acknowledgements,
//!   demo sessions) rather than stop at the handshake.
//!
//! The client side then closes; the connection must end within a few
//! seconds, without a panic, and the server must stay up for the next
//! input (a healthz request is answered after every input).
#![no_main]

use std::net::SocketAddr;
use std::sync::OnceLock;
use std::time::Duration;

use farfield_builder::import::{Params, load_input};
use farfield_protocol::codec::encode_control;
use farfield_protocol::messages::{ClientMessage, PROTOCOL_VERSION};
use farfield_memory_server::{RunningServer, ServerConfig};
use libfuzzer_sys::fuzz_target;
use tokio::io::{AsyncReadExt, AsyncWriteExt};

/// How long one connection may take to end after the client closed.
const END_WITHIN: Duration = Duration::from_secs(8);

struct Fixture {
    runtime: tokio::runtime::Runtime,
    server: RunningServer,
}

fn fixture() -> &'static Fixture {
    static FIXTURE: OnceLock<Fixture> = OnceLock::new();
    FIXTURE.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("farfield-fuzz-session-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("scratch folder");
        let scene = load_input("gen:tree", &Params::default()).expect("gen:tree");
        let (file, _) = farfield_builder::build_spheres(scene, &Default::default()).expect("build");
        farfield_store::write_atomic(&dir.join("tree.ff"), &file).expect("write");
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .enable_all()
            .build()
            .expect("runtime");
        let mut config = ServerConfig::new(&dir, SocketAddr::from(([127, 0, 0, 1], 0)));
        config.rescan_interval = Duration::ZERO;
        config.limits.hello_timeout = Duration::from_millis(500);
        config.limits.header_timeout = Duration::from_millis(500);
        config.limits.idle_timeout = Duration::from_secs(2);
        let server = runtime
            .block_on(farfield_memory_server::start(config))
            .expect("server starts");
        Fixture { runtime, server }
    })
}

const UPGRADE: &str = "GET /scenes/tree/stream HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\n\
    Connection: Upgrade\r\nSec-WebSocket-Version: 13\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n\r\n";

/// One masked client frame (FIN set).
fn frame(opcode: u8, payload: &[u8], out: &mut Vec<u8>) {
    const MASK: [u8; 4] = [0x37, 0xfa, 0x21, 0x3d];
    out.push(0x80 | (opcode & 0x0f));
    match payload.len() {
        n if n < 126 => out.push(0x80 | n as u8),
        n if n <= 0xffff => {
            out.push(0x80 | 126);
            out.extend_from_slice(&(n as u16).to_be_bytes());
        }
        n => {
            out.push(0x80 | 127);
            out.extend_from_slice(&(n as u64).to_be_bytes());
        }
    }
    out.extend_from_slice(&MASK);
    out.extend(payload.iter().enumerate().map(|(i, b)| b ^ MASK[i % 4]));
}

/// The bytes the client sends for `data`.
fn client_bytes(data: &[u8]) -> Vec<u8> {
    let Some((&mode, rest)) = data.split_first() else {
        return Vec::new();
    };
    if mode & 1 == 0 {
        return rest.to_vec();
    }
    let mut out = UPGRADE.as_bytes().to_vec();
    if mode & 2 != 0 {
        let hello = encode_control(&ClientMessage::Hello {
            protocol_version: PROTOCOL_VERSION,
            max_in_flight_bytes: 1 << 20,
            allow_push: mode & 4 != 0,
        });
        frame(2, &hello, &mut out);
    }
    let mut rest = rest;
    while let [opcode, a, b, tail @ ..] = rest {
        let len = usize::from(u16::from_le_bytes([*a, *b])).min(tail.len());
        frame(*opcode, &tail[..len], &mut out);
        rest = &tail[len..];
    }
    out
}

async fn connection(server: &RunningServer, bytes: Vec<u8>) {
    let (mut client, server_end) = tokio::io::duplex(64 << 10);
    let serving = server.serve_stream(server_end, SocketAddr::from(([127, 0, 0, 1], 40000)));
    let talking = async move {
        let _ = client.write_all(&bytes).await;
        let _ = client.shutdown().await;
        // Whatever the server answers, read to its end.
        let mut sink = vec![0u8; 64 << 10];
        while matches!(client.read(&mut sink).await, Ok(n) if n > 0) {}
    };
    let ended = tokio::time::timeout(END_WITHIN, async { tokio::join!(serving, talking) }).await;
    assert!(ended.is_ok(), "the connection did not end within {END_WITHIN:?}");
}

fuzz_target!(|data: &[u8]| {
    let fixture = fixture();
    let server = &fixture.server;
    fixture.runtime.block_on(async {
        connection(server, client_bytes(data)).await;
        // Still serving.
        let (mut client, server_end) = tokio::io::duplex(4096);
        let serving = server.serve_stream(server_end, SocketAddr::from(([127, 0, 0, 1], 40001)));
        let asking = async move {
            client
                .write_all(b"GET /healthz HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n")
                .await
                .expect("ask");
            let mut answer = Vec::new();
            let _ = client.read_to_end(&mut answer).await;
            answer
        };
        let (_, answer) = tokio::time::timeout(END_WITHIN, async { tokio::join!(serving, asking) })
            .await
            .expect("health answered in time");
        assert!(answer.starts_with(b"HTTP/1.1 200"), "{}", String::from_utf8_lossy(&answer));
    });
});
