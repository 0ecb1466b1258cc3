//! A real client rendering beside a crowd that holds connections open:
//! 1,000 idle TCP connections (from 20 addresses, within the per-address
//! limit) and 50 slowloris connections sending their headers a byte every
//! half second. The server holds them all (none has reached the header
//! timeout yet) and the client's render still succeeds, in at most twice
//! its time on an idle server.

use std::net::SocketAddr;
use std::time::{Duration, Instant};

use farfield_render::headless_or_skip;
use tokio::io::AsyncWriteExt;
use tokio::net::TcpStream;

use crate::serve::limits::connect_from;
use crate::streaming::{SIZE, island_from, render, runtime, scenes};

const IDLE: usize = 1000;
const SLOWLORIS: usize = 50;

fn median(mut v: Vec<Duration>) -> Duration {
    v.sort();
    v[v.len() / 2]
}

/// The idle connections, and the task writing the slowloris ones a byte
/// every half second.
struct Crowd {
    idle: Vec<TcpStream>,
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
    slowloris: tokio::task::JoinHandle<usize>,
}

impl Crowd {
    async fn gather(addr: SocketAddr) -> Self {
        let mut idle = Vec::with_capacity(IDLE);
        for i in 0..IDLE {
            idle.push(connect_from([127, 0, 0, 2 + (i / 50) as u8], addr).await);
        }
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let mut slow = Vec::with_capacity(SLOWLORIS);
        for _ in 0..SLOWLORIS {
            slow.push(connect_from([127, 0, 0, 100], addr).await);
        }
        let slowloris = tokio::spawn({
            let stop = stop.clone();
            async move {
                let head = b"GET /scenes HTTP/1.1\r\nHost: localhost\r\nX-Slow: ";
                let mut written = 0usize;
                while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                    let byte = head.get(written).copied().unwrap_or(b'a');
                    for c in &mut slow {
                        let _ = c.write_all(&[byte]).await;
                    }
                    written += 1;
                    tokio::time::sleep(Duration::from_millis(500)).await;
                }
                slow.len()
            }
        });
        Self {
            idle,
            stop,
            slowloris,
        }
    }

    async fn disperse(self) {
        self.stop.store(true, std::sync::atomic::Ordering::Relaxed);
        assert_eq!(self.slowloris.await.expect("slowloris task"), SLOWLORIS);
        drop(self.idle);
    }
}

#[cfg(target_os = "linux")]
#[test]
fn a_client_renders_beside_1000_idle_and_50_slowloris_connections() {
    let Some(mut renderer) = headless_or_skip(SIZE.0, SIZE.1).unwrap() else {
        return;
    };
    let (dir, _) = scenes("crowd");
    let rt = runtime();
    let server = rt
        .block_on(farfield_memory_server::start(
            farfield_memory_server::ServerConfig::new(&dir, SocketAddr::from(([127, 0, 0, 1], 0))),
        ))
        .expect("server starts");
    let addr = server.local_addr();
    let job = island_from(format!("http://{addr}"));
    let timed = |renderer: &mut _| {
        let started = Instant::now();
        render(renderer, &job);
        started.elapsed()
    };
    timed(&mut renderer);
    // Rounds alternate, alone then beside the crowd, so whatever else the
    // machine does falls on both; the medians are compared.
    let (mut alone, mut crowded, mut held) = (Vec::new(), Vec::new(), u64::MAX);
    for _ in 0..5 {
        alone.push(timed(&mut renderer));
        let crowd = rt.block_on(Crowd::gather(addr));
        let deadline = Instant::now() + Duration::from_secs(10);
        while server.metrics().open_connections < (IDLE + SLOWLORIS) as u64 {
            assert!(
                Instant::now() < deadline,
                "crowd not admitted: {:?}",
                server.metrics()
            );
            std::thread::sleep(Duration::from_millis(20));
        }
        crowded.push(timed(&mut renderer));
        held = held.min(server.metrics().open_connections);
        rt.block_on(crowd.disperse());
    }
    let (alone, crowded) = (median(alone), median(crowded));
    eprintln!(
        "render alone {alone:?}, beside {IDLE} idle and {SLOWLORIS} slowloris connections {crowded:?} (medians of 5; at least {held} connections open)"
    );
    assert!(
        held >= (IDLE + SLOWLORIS) as u64,
        "the crowd was let go during a render: {held} open"
    );
    assert!(
        crowded <= alone * 2,
        "render took {crowded:?} beside the crowd, {alone:?} alone"
    );
    rt.block_on(server.shutdown()).expect("shutdown");
}
