//! [`WebSocketTransport`]: the native transport, tokio-tungstenite on a
//! thread of its own.
//!
//! The thread runs a current-thread tokio runtime; each connection is one
//! task on it with its own pair of channels, so abandoning a connection
//! (dropping its channels and aborting its task) guarantees that nothing of
//! it is reported afterwards. The caller's thread never enters the runtime:
//! it sends frames through an unbounded channel and waits for events on a
//! standard one, with a timeout.

use std::sync::mpsc;
use std::time::Duration;

use futures_util::{SinkExt, StreamExt};
use tokio::sync::{mpsc as async_mpsc, oneshot};
use tokio_tungstenite::tungstenite::{self, Message};

use crate::transport::{Transport, TransportEvent};

/// The native websocket transport.
#[derive(Debug)]
pub struct WebSocketTransport {
    runtime: tokio::runtime::Handle,
    /// Ends the runtime's thread when dropped (none on a borrowed runtime).
    _stop: Option<oneshot::Sender<()>>,
    current: Option<Connection>,
}

#[derive(Debug)]
struct Connection {
    events: mpsc::Receiver<TransportEvent>,
    outgoing: async_mpsc::UnboundedSender<Vec<u8>>,
    task: tokio::task::AbortHandle,
}

impl WebSocketTransport {
    /// Starts the transport's thread.
    pub fn new() -> std::io::Result<Self> {
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()?;
        let handle = runtime.handle().clone();
        let (stop, stopped) = oneshot::channel::<()>();
        std::thread::Builder::new()
            .name("farfield-net".into())
            .spawn(move || {
                // Runs spawned connections until the transport is dropped.
                let _ = runtime.block_on(stopped);
            })?;
        Ok(Self {
            runtime: handle,
            _stop: Some(stop),
            current: None,
        })
    }

    /// A transport whose sockets live on `runtime`, a runtime the caller
    /// already runs (a load test's, or an embedded server's), instead of a
    /// thread of its own.
    pub fn on(runtime: tokio::runtime::Handle) -> Self {
        Self {
            runtime,
            _stop: None,
            current: None,
        }
    }
}

impl Drop for WebSocketTransport {
    fn drop(&mut self) {
        self.close();
    }
}

impl Transport for WebSocketTransport {
    fn connect(&mut self, url: &str) {
        self.close();
        let (event_tx, events) = mpsc::channel();
        let (outgoing, out_rx) = async_mpsc::unbounded_channel();
        let task = self
            .runtime
            .spawn(connection(url.to_owned(), event_tx, out_rx))
            .abort_handle();
        self.current = Some(Connection {
            events,
            outgoing,
            task,
        });
    }

    fn send(&mut self, frame: Vec<u8>) {
        if let Some(c) = &self.current {
            // A closed channel means the connection ended; its Closed event
            // is already queued.
            let _ = c.outgoing.send(frame);
        }
    }

    fn close(&mut self) {
        if let Some(c) = self.current.take() {
            c.task.abort();
        }
    }

    fn poll(&mut self, wait: Duration) -> Option<TransportEvent> {
        let Some(c) = &self.current else {
            if !wait.is_zero() {
                std::thread::sleep(wait);
            }
            return None;
        };
        let event = if wait.is_zero() {
            c.events
                .try_recv()
                .map_err(|e| e == mpsc::TryRecvError::Disconnected)
        } else {
            c.events
                .recv_timeout(wait)
                .map_err(|e| e == mpsc::RecvTimeoutError::Disconnected)
        };
        match event {
            Ok(event) => {
                if matches!(event, TransportEvent::Closed { .. }) {
                    self.current = None;
                }
                Some(event)
            }
            Err(false) => None,
            Err(true) => {
                // The task is gone without saying why (it always says why
                // before returning; a panic is the only other way out).
                self.current = None;
                Some(TransportEvent::Closed {
                    reason: "the network task ended".into(),
                    refused: false,
                })
            }
        }
    }
}

/// One connection: connect, then pass frames both ways until either side
/// ends it. Always ends by reporting [`TransportEvent::Closed`].
async fn connection(
    url: String,
    events: mpsc::Sender<TransportEvent>,
    mut outgoing: async_mpsc::UnboundedReceiver<Vec<u8>>,
) {
    let (reason, refused) = match run(&url, &events, &mut outgoing).await {
        Ok(()) => return,
        Err(end) => end,
    };
    let _ = events.send(TransportEvent::Closed { reason, refused });
}

/// `Ok` when the receiver went away; otherwise why the connection ended.
async fn run(
    url: &str,
    events: &mpsc::Sender<TransportEvent>,
    outgoing: &mut async_mpsc::UnboundedReceiver<Vec<u8>>,
) -> Result<(), (String, bool)> {
    let lost = |reason: String| (reason, false);
    // No Nagle: requests and acknowledgements are small and must not sit
    // waiting for the server's delayed ACKs (40 ms a round trip otherwise).
    let socket = match tokio_tungstenite::connect_async_with_config(url, None, true).await {
        Ok((socket, _)) => socket,
        Err(e) => {
            return Err(match refusal(url, &e) {
                Some(reason) => (reason, true),
                None => lost(format!("connect {url}: {e}")),
            });
        }
    };
    if events.send(TransportEvent::Opened).is_err() {
        return Ok(());
    }
    let (mut sink, mut stream) = socket.split();
    loop {
        tokio::select! {
            incoming = stream.next() => {
                let Some(incoming) = incoming else {
                    return Err(lost("server closed the stream".into()));
                };
                let frame = match incoming.map_err(|e| lost(e.to_string()))? {
                    Message::Binary(frame) => frame,
                    Message::Close(frame) => {
                        let reason = frame.map(|f| f.reason.to_string()).unwrap_or_default();
                        return Err(lost(format!("server closed the connection {reason}")));
                    }
                    _ => continue,
                };
                if events.send(TransportEvent::Frame(frame)).is_err() {
                    return Ok(());
                }
            }
            frame = outgoing.recv() => {
                let Some(frame) = frame else { return Ok(()) };
                sink.send(Message::Binary(frame.into())).await.map_err(|e| lost(e.to_string()))?;
            }
        }
    }
}

/// The server's reason when it refused the connection with a client error
/// that a retry cannot change (4xx, but not 408 Request Timeout or 429 Too
/// Many Requests): its JSON `error` field when there is one, else the
/// status line.
fn refusal(url: &str, error: &tungstenite::Error) -> Option<String> {
    let tungstenite::Error::Http(response) = error else {
        return None;
    };
    let status = response.status();
    if !status.is_client_error() || matches!(status.as_u16(), 408 | 429) {
        return None;
    }
    let reason = response
        .body()
        .as_deref()
        .and_then(|body| serde_json::from_slice::<serde_json::Value>(body).ok())
        .and_then(|json| json.get("error")?.as_str().map(str::to_owned))
        .unwrap_or_else(|| status.to_string());
    Some(format!("{url}: {reason}"))
}
