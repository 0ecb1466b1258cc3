//! The accept loop: every TCP connection is admitted or refused here, then
//! served as HTTP/1.1 by hyper (whose header-read timeout needs a timer,
//! which `axum::serve` does not give it), and upgraded to a websocket
//! session where asked.
//!
//! A refused connection gets a short JSON answer (503 when the server is
//! full, 429 when its address has too many connections open) and is
//! closed; at most `Limits::max_refusing` such answers are under way at
//! once (fitted to the open-files limit with the connections), and past
//! that a refused connection is closed without one, so a flood can grow
//! neither the server's work nor its descriptors.

use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use axum::Router;
use axum::extract::ConnectInfo;
use hyper::body::Incoming;
use hyper::server::conn::http1;
use hyper_util::rt::{TokioIo, TokioTimer};
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::watch;
use tokio_rustls::TlsAcceptor;
use tower::ServiceExt;

use super::AppState;
use super::admission::{Admission, Admitted};
use super::limits::Limit;
use super::metrics::Metrics;

/// How long a refusal may take to write its answer and see the client go.
const REFUSAL_GRACE: Duration = Duration::from_secs(2);
/// Bytes of request head hyper buffers per connection, at most.
const MAX_HEAD_BYTES: usize = 64 << 10;

/// Accepts until the server shuts down.
pub(crate) async fn accept_loop(
    listener: TcpListener,
    router: Router,
    state: Arc<AppState>,
    admission: Arc<Admission>,
    tls: Option<TlsAcceptor>,
    mut shutdown: watch::Receiver<bool>,
) {
    let refusing = Arc::new(AtomicUsize::new(0));
    let mut last_accept_warning: Option<Instant> = None;
    loop {
        let accepted = tokio::select! {
            r = listener.accept() => r,
            _ = shutdown.wait_for(|&stop| stop) => return,
        };
        let (tcp, peer) = match accepted {
            Ok(accepted) => accepted,
            Err(e) => {
                // Out of descriptors, most likely: wait for some to close
                // rather than spin, and say so once in a while.
                Metrics::add(&state.metrics.accept_errors, 1);
                if last_accept_warning.is_none_or(|t| t.elapsed() > Duration::from_secs(10)) {
                    tracing::warn!("cannot accept connections: {e}");
                    last_accept_warning = Some(Instant::now());
                }
                tokio::time::sleep(Duration::from_millis(50)).await;
                continue;
            }
        };
        if let Err(e) = tcp.set_nodelay(true) {
            // Pages are written one frame at a time, each smaller than a
            // loopback segment: with Nagle's algorithm on, every one would
            // wait for the previous one's acknowledgement.
            tracing::debug!("TCP_NODELAY: {e}");
        }
        match admission.admit(peer.ip()) {
            Ok(ticket) => {
                let io = Admitted {
                    io: tcp,
                    _ticket: ticket,
                };
                let (router, state) = (router.clone(), state.clone());
                let shutdown = shutdown.clone();
                match tls.clone() {
                    None => {
                        tokio::spawn(serve_connection(io, peer, router, state, shutdown));
                    }
                    Some(tls) => {
                        tokio::spawn(async move {
                            let timeout = state.limits.header_timeout;
                            match tokio::time::timeout(timeout, tls.accept(io)).await {
                                Ok(Ok(io)) => {
                                    serve_connection(io, peer, router, state, shutdown).await
                                }
                                Ok(Err(e)) => tracing::debug!(%peer, "TLS handshake failed: {e}"),
                                Err(_) => {
                                    state.metrics.hit(Limit::HeaderTimeout);
                                    tracing::debug!(%peer, "closed: no TLS handshake within {timeout:?}");
                                }
                            }
                        });
                    }
                }
            }
            Err(limit) => {
                state.metrics.hit(limit);
                tracing::debug!(%peer, "connection refused: {}", limit.name());
                if refusing.fetch_add(1, Ordering::Relaxed) < state.limits.max_refusing {
                    let refusing = refusing.clone();
                    let answer = refusal(limit, &admission);
                    tokio::spawn(async move {
                        refuse(tcp, answer).await;
                        refusing.fetch_sub(1, Ordering::Relaxed);
                    });
                } else {
                    refusing.fetch_sub(1, Ordering::Relaxed);
                }
            }
        }
    }
}

/// The HTTP answer to a refused connection.
fn refusal(limit: Limit, admission: &Admission) -> String {
    let (status, message) = match limit {
        Limit::MaxConnectionsPerAddress => (
            "429 Too Many Requests",
            format!(
                "too many connections from this address (the limit is {})",
                admission.max_per_address()
            ),
        ),
        _ => (
            "503 Service Unavailable",
            format!(
                "the server is full ({} connections open, its limit); try again later",
                admission.max_total()
            ),
        ),
    };
    let body = serde_json::json!({ "error": message }).to_string();
    format!(
        "HTTP/1.1 {status}\r\ncontent-type: application/json\r\ncontent-length: {}\r\n\
         retry-after: 1\r\nconnection: close\r\n\r\n{body}",
        body.len()
    )
}

/// Writes `answer`, then reads what the client sent until it leaves (so the
/// close does not reset the connection before the answer is read), within
/// [`REFUSAL_GRACE`].
async fn refuse(mut tcp: TcpStream, answer: String) {
    let _ = tokio::time::timeout(REFUSAL_GRACE, async {
        tcp.write_all(answer.as_bytes()).await?;
        tcp.shutdown().await?;
        let mut sink = [0u8; 4096];
        while tcp.read(&mut sink).await? > 0 {}
        std::io::Result::Ok(())
    })
    .await;
}

/// The bytes of a request's head as sent: its request line and its header
/// lines.
fn head_bytes<B>(request: &hyper::Request<B>) -> usize {
    let line = request.method().as_str().len()
        + request
            .uri()
            .path_and_query()
            .map_or(1, |p| p.as_str().len())
        + " HTTP/1.1\r\n".len()
        + 1;
    let headers: usize = request
        .headers()
        .iter()
        .map(|(name, value)| name.as_str().len() + value.len() + ": \r\n".len())
        .sum();
    line + headers + "\r\n".len()
}

/// The answer to a request whose head is past [`MAX_HEAD_BYTES`].
fn head_too_large() -> axum::response::Response {
    use axum::response::IntoResponse;
    let message = format!(
        "the request's headers are larger than {} KiB",
        MAX_HEAD_BYTES >> 10
    );
    (
        axum::http::StatusCode::REQUEST_HEADER_FIELDS_TOO_LARGE,
        [(axum::http::header::CONNECTION, "close")],
        axum::Json(serde_json::json!({ "error": message })),
    )
        .into_response()
}

/// Serves one admitted connection as HTTP/1.1 (with upgrades) until it
/// closes, or until the server shuts down and its current request ends.
pub(crate) async fn serve_connection<S>(
    io: S,
    peer: SocketAddr,
    router: Router,
    state: Arc<AppState>,
    mut shutdown: watch::Receiver<bool>,
) where
    S: AsyncRead + AsyncWrite + Unpin + Send + 'static,
{
    let service = hyper::service::service_fn(move |mut request: hyper::Request<Incoming>| {
        request.extensions_mut().insert(ConnectInfo(peer));
        let router = router.clone();
        async move {
            // hyper's buffer bound is soft (a head sent in one write can pass
            // it); the head's own size is not.
            if head_bytes(&request) > MAX_HEAD_BYTES {
                return Ok::<_, std::convert::Infallible>(head_too_large());
            }
            router.oneshot(request).await
        }
    });
    let mut builder = http1::Builder::new();
    builder
        .timer(TokioTimer::new())
        .header_read_timeout(state.limits.header_timeout)
        .max_buf_size(MAX_HEAD_BYTES);
    let connection = builder
        .serve_connection(TokioIo::new(io), service)
        .with_upgrades();
    tokio::pin!(connection);
    let stopping = async move {
        let _ = shutdown.wait_for(|&stop| stop).await;
    };
    let result = tokio::select! {
        r = connection.as_mut() => r,
        () = stopping => {
            connection.as_mut().graceful_shutdown();
            connection.await
        }
    };
    if let Err(e) = result {
        if e.is_timeout() {
            state.metrics.hit(Limit::HeaderTimeout);
            tracing::debug!(%peer, "closed: no request headers within {:?}", state.limits.header_timeout);
        } else {
            tracing::debug!(%peer, "connection ended: {e}");
        }
    }
}
