//! The native websocket, two ways: [`WebSocketTransport`], tokio-tungstenite
//! on a thread of its own, for owners that
//! pump a session from their own loop; and [`drive`], a session's sockets
//! and its protocol state in one async task, for load tests that run many
//! sessions on one runtime.
//!
//! The transport's thread runs a current-thread tokio runtime; each connection is one
//! task on it with its own pair of channels, so abandoning a connection
//! (dropping its channels and aborting its task) guarantees that nothing of
//! it is reported afterwards. The caller's thread never enters the runtime:
//! it sends frames through an unbounded channel and waits for events on a
//! standard one, with a timeout.

use std::future::Future;
use std::pin::Pin;
use std::sync::{Arc, mpsc};
use std::time::Duration;

use bytes::Bytes;
use futures_util::{FutureExt, SinkExt, StreamExt};
use tokio::sync::{mpsc as async_mpsc, oneshot};
use tokio_tungstenite::tungstenite::{self, Message};
use tokio_tungstenite::{MaybeTlsStream, WebSocketStream};

use crate::queue::QueueTransport;
use crate::session::{Session, SessionError, SessionEvent};
use crate::transport::{Closing, Target, Transport, TransportEvent, Waker};

/// The native websocket transport.
#[derive(Debug)]
pub struct WebSocketTransport {
    runtime: tokio::runtime::Handle,
    /// Ends the runtime's thread when dropped.
    _stop: oneshot::Sender<()>,
    current: Option<Connection>,
    /// For `wss://`: the roots to trust (the webpki roots when `None`).
    tls: Option<Arc<rustls::ClientConfig>>,
    /// Shared with every connection's task, the one already running too.
    waker: Arc<std::sync::OnceLock<Waker>>,
}

/// The connection task's side of the event channel: each event sent
/// wakes the owner ([`Transport::set_waker`]).
struct Events {
    tx: mpsc::Sender<TransportEvent>,
    waker: Arc<std::sync::OnceLock<Waker>>,
}

impl Events {
    /// Sends `event`; `Err` when the owner is gone.
    fn send(&self, event: TransportEvent) -> Result<(), ()> {
        self.tx.send(event).map_err(|_| ())?;
        if let Some(waker) = self.waker.get() {
            waker.wake();
        }
        Ok(())
    }
}

#[derive(Debug)]
struct Connection {
    events: mpsc::Receiver<TransportEvent>,
    outgoing: async_mpsc::UnboundedSender<Vec<u8>>,
    task: tokio::task::AbortHandle,
}

impl WebSocketTransport {
    /// Starts the transport's thread; `wss://` servers are checked
    /// against the usual public roots.
    pub fn new() -> std::io::Result<Self> {
        Self::trusting(None)
    }

    /// Like [`WebSocketTransport::new`], but a `wss://` server's certificate
    /// must chain to an authority in `ca_cert` (PEM), or be one of its
    /// certificates (pinned), instead: a private or self-signed server
    /// ([`crate::certificate`]).
    pub fn trusting(ca_cert: Option<&std::path::Path>) -> std::io::Result<Self> {
        let tls = ca_cert.map(crate::certificate::client_config).transpose()?;
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
            _stop: stop,
            current: None,
            tls,
            waker: Arc::default(),
        })
    }
}

impl Drop for WebSocketTransport {
    fn drop(&mut self) {
        self.close();
    }
}

impl Transport for WebSocketTransport {
    fn connect(&mut self, target: &Target, hello: Vec<u8>) {
        self.close();
        let (event_tx, events) = mpsc::channel();
        let (outgoing, out_rx) = async_mpsc::unbounded_channel();
        // First in line: sent the moment the socket opens.
        let _ = outgoing.send(hello);
        let task = self
            .runtime
            .spawn(connection(
                target.clone(),
                self.tls.clone(),
                Events {
                    tx: event_tx,
                    waker: self.waker.clone(),
                },
                out_rx,
            ))
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

    fn set_waker(&mut self, waker: Waker) -> bool {
        // Set once: a later waker is refused (the first owner keeps it).
        self.waker.set(waker).is_ok()
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
                    how: Closing::Failed,
                })
            }
        }
    }
}

/// One connection: connect, then pass frames both ways until either side
/// ends it. Always ends by reporting [`TransportEvent::Closed`].
async fn connection(
    target: Target,
    tls: Option<Arc<rustls::ClientConfig>>,
    events: Events,
    mut outgoing: async_mpsc::UnboundedReceiver<Vec<u8>>,
) {
    let (reason, how) = match run(&target, tls, &events, &mut outgoing).await {
        Ok(()) => return,
        Err(end) => end,
    };
    let _ = events.send(TransportEvent::Closed { reason, how });
}

/// `Ok` when the receiver went away; otherwise why the connection ended.
async fn run(
    target: &Target,
    tls: Option<Arc<rustls::ClientConfig>>,
    events: &Events,
    outgoing: &mut async_mpsc::UnboundedReceiver<Vec<u8>>,
) -> Result<(), (String, Closing)> {
    let socket = open(target, tls).await?;
    if events.send(TransportEvent::Opened).is_err() {
        return Ok(());
    }
    let (mut sink, mut stream) = socket.split();
    loop {
        tokio::select! {
            incoming = stream.next() => {
                let Some(frame) = frame_of(incoming)? else { continue };
                if events.send(TransportEvent::Frame(frame)).is_err() {
                    return Ok(());
                }
            }
            frame = outgoing.recv() => {
                let Some(frame) = frame else { return Ok(()) };
                sink.send(Message::Binary(frame.into()))
                    .await
                    .map_err(|e| (e.to_string(), Closing::Failed))?;
            }
        }
    }
}

/// A client websocket.
type Socket = WebSocketStream<MaybeTlsStream<tokio::net::TcpStream>>;

/// Connects to `target`, its token in an `Authorization` header; the error
/// is why, and whether a retry could change it.
async fn open(
    target: &Target,
    tls: Option<Arc<rustls::ClientConfig>>,
) -> Result<Socket, (String, Closing)> {
    use tokio_tungstenite::tungstenite::client::IntoClientRequest;
    let url = target.url.as_str();
    let mut request = url
        .into_client_request()
        .map_err(|e| (format!("connect {url}: {e}"), Closing::Refused))?;
    if let Some(token) = &target.token {
        let value = format!("Bearer {token}").parse().map_err(|_| {
            (
                "the token holds characters a header cannot carry".to_owned(),
                Closing::Refused,
            )
        })?;
        request
            .headers_mut()
            .insert(tungstenite::http::header::AUTHORIZATION, value);
    }
    // No Nagle: requests and acknowledgements are small and must not sit
    // waiting for the server's delayed ACKs (40 ms a round trip otherwise).
    let connector = tls.map(tokio_tungstenite::Connector::Rustls);
    match tokio_tungstenite::connect_async_tls_with_config(request, None, true, connector).await {
        Ok((socket, _)) => Ok(socket),
        Err(e) => Err(match refusal(url, &e) {
            Some(reason) => (reason, Closing::Refused),
            None => match crate::certificate::untrusted(&e) {
                Some(reason) => (format!("connect {url}: {reason}"), Closing::Refused),
                None => (format!("connect {url}: {e}"), Closing::Failed),
            },
        }),
    }
}

/// What one read from the socket brought: a binary frame, nothing of
/// interest (`None`: pings, text), or the end of the connection, why and how.
fn frame_of(
    incoming: Option<Result<Message, tungstenite::Error>>,
) -> Result<Option<Bytes>, (String, Closing)> {
    let Some(incoming) = incoming else {
        return Err(("server closed the stream".into(), Closing::ByServer));
    };
    match incoming.map_err(|e| (e.to_string(), Closing::Failed))? {
        Message::Binary(frame) => Ok(Some(frame)),
        Message::Close(frame) => {
            let reason = frame.map(|f| f.reason.to_string()).unwrap_or_default();
            Err((
                format!("server closed the connection {reason}"),
                Closing::ByServer,
            ))
        }
        _ => Ok(None),
    }
}

/// How long [`drive`] waits for a frame before it lets the session's
/// timers (reconnects, the first-connect grace) run.
const TICK: Duration = Duration::from_millis(20);

/// Most frames [`drive`] takes off a socket before pumping the session.
const BATCH: usize = 64;

/// Runs `session`'s connections inside the calling async task: its
/// socket and its protocol state on one task, no thread of its own, so a
/// load test runs many sessions on one runtime. `wire` is the session's
/// transport (a clone of it). After every pump, `each` sees the events and
/// the session, and says whether to go on; `drive` returns when it says no
/// or the session ends.
pub async fn drive(
    session: &mut Session<QueueTransport>,
    wire: &QueueTransport,
    mut each: impl FnMut(&mut Session<QueueTransport>, Vec<SessionEvent>) -> bool,
) -> Result<(), SessionError> {
    drive_wire(wire, || {
        let events = session.pump(Duration::ZERO)?;
        Ok(each(session, events))
    })
    .await
}

/// Like [`drive`], for an owner that keeps its session inside something
/// else (a load client's `Viewer`, whose session is
/// over `wire` boxed): moves `wire`'s frames to and from its sockets and
/// calls `step` after each batch, or every 20 ms when nothing came. `step`
/// pumps the session itself and says whether to go on; its error ends the
/// drive.
pub async fn drive_wire<E>(
    wire: &QueueTransport,
    mut step: impl FnMut() -> Result<bool, E>,
) -> Result<(), E> {
    let mut socket: Option<Socket> = None;
    // An attempt under way; the session's timers (the first-connect grace)
    // keep running while it is, and may abandon it.
    let mut connecting: Option<Pin<Box<dyn Future<Output = Opened> + Send>>> = None;
    loop {
        if wire.take_close() {
            (socket, connecting) = (None, None);
        }
        if let Some(target) = wire.take_connect() {
            socket = None;
            connecting = Some(Box::pin(async move { open(&target, None).await }));
        }
        if let Some(attempt) = connecting.as_mut()
            && let Ok(opened) = tokio::time::timeout(TICK, attempt).await
        {
            connecting = None;
            match opened {
                Ok(s) => {
                    socket = Some(s);
                    wire.push(TransportEvent::Opened);
                }
                Err((reason, how)) => wire.push(TransportEvent::Closed { reason, how }),
            }
        }
        if !step()? {
            return Ok(());
        }
        let Some(s) = socket.as_mut() else {
            if connecting.is_none() {
                tokio::time::sleep(TICK).await;
            }
            continue;
        };
        // The hello first, then what the session queued since.
        if let Err(reason) = send_all(s, wire.take_sent()).await {
            socket = None;
            wire.push(TransportEvent::Closed {
                reason,
                how: Closing::Failed,
            });
            continue;
        }
        // The next frame, then whatever else is ready, up to a batch; or,
        // sooner, something to send (from an owner on another task).
        let first = tokio::select! {
            next = tokio::time::timeout(TICK, s.next()) => match next {
                Ok(first) => first,
                Err(_) => continue,
            },
            () = wire.outgoing_ready() => continue,
        };
        let mut next = Some(first);
        let mut taken = 0;
        let mut ended = None;
        while let Some(incoming) = next.take() {
            match frame_of(incoming) {
                Ok(Some(frame)) => wire.push(TransportEvent::Frame(frame)),
                Ok(None) => {}
                Err(end) => {
                    ended = Some(end);
                    break;
                }
            }
            taken += 1;
            if taken < BATCH {
                next = s.next().now_or_never();
            }
        }
        if let Some((reason, how)) = ended {
            socket = None;
            wire.push(TransportEvent::Closed { reason, how });
        }
    }
}

/// Carries `wire`'s frames to and from its sockets as [`drive_wire`] does,
/// until its owner [finishes](QueueTransport::finish) it, with no step of
/// the owner's in between: the owner pumps its session on another task
/// (a load client, whose traversals are long), so frames are taken off
/// the socket, and stamped, when they come, and what the session sends
/// goes out at once. Spawn it on a runtime of its own.
pub async fn carry_wire(wire: QueueTransport) {
    let carried = drive_wire(&wire, || {
        Ok::<_, std::convert::Infallible>(!wire.is_finished())
    })
    .await;
    let Ok(()) = carried;
}

/// What an attempt to connect yields.
type Opened = Result<Socket, (String, Closing)>;

/// Sends frames and flushes once.
async fn send_all(socket: &mut Socket, frames: Vec<Vec<u8>>) -> Result<(), String> {
    if frames.is_empty() {
        return Ok(());
    }
    for frame in frames {
        socket
            .feed(Message::Binary(frame.into()))
            .await
            .map_err(|e| e.to_string())?;
    }
    socket.flush().await.map_err(|e| e.to_string())
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
