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

#[cfg(target_os = "linux")]
#[test]
fn a_client_renders_beside_1000_idle_and_50_slowloris_connections() {
    let Some(mut renderer) = headless_or_skip(SIZE.0, SIZE.1).unwrap() else {
        return;
    };
    let (dir, _) = scenes("crowd");
    let rt = runtime();
    let server = rt
        .block_on(farfield_serve::start(farfield_serve::ServerConfig::new(
            &dir,
            SocketAddr::from(([127, 0, 0, 1], 0)),
        )))
        .expect("server starts");
    let addr = server.local_addr();
    let job = island_from(format!("http://{addr}"));
    let timed = |renderer: &mut _| {
        let started = Instant::now();
        render(renderer, &job);
        started.elapsed()
    };
    timed(&mut renderer);
    let alone = median((0..3).map(|_| timed(&mut renderer)).collect());

    let idle: Vec<TcpStream> = rt.block_on(async {
        let mut out = Vec::with_capacity(IDLE);
        for i in 0..IDLE {
            out.push(connect_from([127, 0, 0, 2 + (i / 50) as u8], addr).await);
        }
        out
    });
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let slow = rt.spawn({
        let stop = stop.clone();
        async move {
            let mut conns = Vec::with_capacity(SLOWLORIS);
            for _ in 0..SLOWLORIS {
                conns.push(connect_from([127, 0, 0, 100], addr).await);
            }
            let head = b"GET /scenes HTTP/1.1\r\nHost: x\r\nX-Slow: ";
            let mut written = 0usize;
            while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                let byte = head.get(written).copied().unwrap_or(b'a');
                for c in &mut conns {
                    let _ = c.write_all(&[byte]).await;
                }
                written += 1;
                tokio::time::sleep(Duration::from_millis(500)).await;
            }
            conns.len()
        }
    });
    // Every crowd connection is admitted and held before the client runs.
    let deadline = Instant::now() + Duration::from_secs(10);
    while server.metrics().open_connections < (IDLE + SLOWLORIS) as u64 {
        assert!(
            Instant::now() < deadline,
            "crowd not admitted: {:?}",
            server.metrics()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let crowded = median((0..3).map(|_| timed(&mut renderer)).collect());
    let open = server.metrics().open_connections;
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    assert_eq!(rt.block_on(slow).expect("slowloris task"), SLOWLORIS);
    drop(idle);
    eprintln!(
        "render alone {alone:?}, beside {IDLE} idle and {SLOWLORIS} slowloris connections {crowded:?} ({open} connections open)"
    );
    assert!(
        open >= (IDLE + SLOWLORIS) as u64,
        "the crowd was let go during the render: {open} open"
    );
    assert!(
        crowded <= alone * 2,
        "render took {crowded:?} beside the crowd, {alone:?} alone"
    );
    rt.block_on(server.shutdown()).expect("shutdown");
}
