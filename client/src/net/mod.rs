//! The client's side of the websocket session (protocol `messages`).
//!
//! [`Connection::open`] starts a background task on a tokio runtime that
//! connects, says hello, and forwards what arrives as [`NetEvent`]s; the
//! renderer's loop sends [`Outgoing`] wishes back. When the server goes away
//! the task reports [`NetEvent::Disconnected`] and reconnects with backoff;
//! after [`NetEvent::Connected`] the loop asks again for whatever it still
//! lacks, so nothing it already holds is fetched twice. A refusal (an
//! unknown scene's 404) ends the session with the server's reason instead,
//! since retrying cannot change it, and so does a server that could not be
//! reached at all within [`SessionOptions::first_connect_grace`].

use std::time::Duration;

use farfield_protocol::codec::{self, CodecError};
use farfield_protocol::messages::{
    ClientMessage, FrameKind, PROTOCOL_VERSION, PageWish, ServerMessage,
};
use futures_util::{SinkExt, StreamExt};
use tokio::sync::mpsc;
use tokio_tungstenite::tungstenite::Message;

/// What a client announces in its hello (`max_in_flight_bytes`,
/// `allow_push`), and how long it tries to connect at first.
#[derive(Debug, Clone, Copy)]
pub struct SessionOptions {
    pub max_in_flight_bytes: u64,
    pub allow_push: bool,
    /// How long a session that has never connected keeps trying: a wrong
    /// address or a server that is not running should fail in seconds, not
    /// at the render's timeout. Once connected, a session retries for as
    /// long as its owner waits (servers restart).
    pub first_connect_grace: Duration,
}

impl Default for SessionOptions {
    fn default() -> Self {
        Self {
            max_in_flight_bytes: 4 << 20,
            allow_push: false,
            first_connect_grace: Duration::from_secs(10),
        }
    }
}

/// What the network task reports.
#[derive(Debug)]
pub enum NetEvent {
    /// A session is open: the scene's header bytes as stored.
    Connected { header: Vec<u8> },
    /// A page's stored bytes (unverified: the receiver checks them).
    Page { bytes: Vec<u8> },
    /// The server reported a problem; fatal ones end the session.
    ServerError { message: String, fatal: bool },
    /// The client stopped trying: the server refused the session (an
    /// unknown scene) or could not be reached within the first-connection
    /// grace. The session is over.
    GaveUp { reason: String },
    /// The connection dropped (or could not be made); the task retries.
    Disconnected { reason: String },
    /// The server cannot send this page (corrupt on its disk).
    PageUnavailable { page: u32, reason: String },
}

/// What the render loop asks the network task to send.
#[derive(Debug)]
pub enum Outgoing {
    Request(Vec<PageWish>),
    Cancel(Vec<u32>),
    Received(Vec<u32>),
}

/// A live session with the memory server, reconnecting as needed.
#[derive(Debug)]
pub struct Connection {
    pub events: mpsc::UnboundedReceiver<NetEvent>,
    outgoing: mpsc::UnboundedSender<Outgoing>,
    task: tokio::task::JoinHandle<()>,
}

impl Connection {
    /// Starts connecting to `ws://SERVER/scenes/NAME/stream` on `runtime`.
    /// `server` is `http://host:port` or `host:port`.
    pub fn open(
        runtime: &tokio::runtime::Handle,
        server: &str,
        scene: &str,
        options: SessionOptions,
    ) -> Self {
        let url = stream_url(server, scene);
        let (event_tx, events) = mpsc::unbounded_channel();
        let (outgoing, out_rx) = mpsc::unbounded_channel();
        let task = runtime.spawn(run(url, options, event_tx, out_rx));
        Self {
            events,
            outgoing,
            task,
        }
    }

    /// Queues a message; false when the network task has ended.
    pub fn send(&self, message: Outgoing) -> bool {
        self.outgoing.send(message).is_ok()
    }
}

impl Drop for Connection {
    fn drop(&mut self) {
        self.task.abort();
    }
}

/// The websocket URL of a scene's stream.
pub fn stream_url(server: &str, scene: &str) -> String {
    let base = server.trim_end_matches('/');
    let base = base
        .strip_prefix("http://")
        .map(|rest| format!("ws://{rest}"))
        .or_else(|| {
            base.strip_prefix("https://")
                .map(|rest| format!("wss://{rest}"))
        })
        .unwrap_or_else(|| {
            if base.contains("://") {
                base.to_owned()
            } else {
                format!("ws://{base}")
            }
        });
    format!("{base}/scenes/{scene}/stream")
}

/// Connects, serves one session, and reconnects with backoff until the
/// receiver goes away, the server says something fatal, or a session that
/// never connected has tried for its `first_connect_grace`.
async fn run(
    url: String,
    options: SessionOptions,
    events: mpsc::UnboundedSender<NetEvent>,
    mut outgoing: mpsc::UnboundedReceiver<Outgoing>,
) {
    let mut backoff = Duration::from_millis(50);
    let first_deadline = tokio::time::Instant::now() + options.first_connect_grace;
    let mut connected_once = false;
    loop {
        // Until a first connection, an attempt may not outlast the grace
        // (a silently dropped connect would otherwise wait minutes).
        let deadline = (!connected_once).then_some(first_deadline);
        let reason = match session(
            &url,
            options,
            &events,
            &mut outgoing,
            deadline,
            &mut connected_once,
        )
        .await
        {
            Ok(SessionEnd::ReceiverGone) => return,
            Ok(SessionEnd::Fatal) => return,
            Ok(SessionEnd::Closed(reason)) => {
                backoff = Duration::from_millis(50);
                reason
            }
            Err(reason) => reason,
        };
        // Give up now rather than start an attempt the deadline would cut
        // short, whose "no answer" would hide this attempt's reason.
        if !connected_once && tokio::time::Instant::now() + backoff >= first_deadline {
            let _ = events.send(NetEvent::GaveUp {
                reason: format!(
                    "cannot reach the server within {:.0} s: {reason}",
                    options.first_connect_grace.as_secs_f64()
                ),
            });
            return;
        }
        if events.send(NetEvent::Disconnected { reason }).is_err() {
            return;
        }
        // Wishes queued while disconnected are stale: the loop re-asks after
        // the next Connected.
        while outgoing.try_recv().is_ok() {}
        tokio::time::sleep(backoff).await;
        backoff = (backoff * 2).min(Duration::from_secs(2));
    }
}

/// The server's reason when it refused the connection with a client error
/// that a retry cannot change (4xx, but not 408 Request Timeout or 429 Too
/// Many Requests): its JSON `error` field when there is one, else the
/// status line.
fn refusal(url: &str, error: &tokio_tungstenite::tungstenite::Error) -> Option<String> {
    let tokio_tungstenite::tungstenite::Error::Http(response) = error else {
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

enum SessionEnd {
    ReceiverGone,
    Fatal,
    Closed(String),
}

async fn session(
    url: &str,
    options: SessionOptions,
    events: &mpsc::UnboundedSender<NetEvent>,
    outgoing: &mut mpsc::UnboundedReceiver<Outgoing>,
    connect_deadline: Option<tokio::time::Instant>,
    connected_once: &mut bool,
) -> Result<SessionEnd, String> {
    // No Nagle: requests and acknowledgements are small and must not sit
    // waiting for the server's delayed ACKs (40 ms a round trip otherwise).
    let connecting = tokio_tungstenite::connect_async_with_config(url, None, true);
    let connected = match connect_deadline {
        Some(deadline) => tokio::time::timeout_at(deadline, connecting)
            .await
            .map_err(|_| format!("connect {url}: no answer"))?,
        None => connecting.await,
    };
    let socket = match connected {
        Ok((socket, _)) => socket,
        Err(e) => {
            // A refusal (an unknown scene) will not change on retry: end
            // the session with the server's reason instead of waiting.
            if let Some(reason) = refusal(url, &e) {
                let _ = events.send(NetEvent::GaveUp { reason });
                return Ok(SessionEnd::Fatal);
            }
            return Err(format!("connect {url}: {e}"));
        }
    };
    *connected_once = true;
    let (mut sink, mut stream) = socket.split();
    let hello = ClientMessage::Hello {
        protocol_version: PROTOCOL_VERSION,
        max_in_flight_bytes: options.max_in_flight_bytes,
        allow_push: options.allow_push,
    };
    sink.send(Message::Binary(codec::encode_control(&hello).into()))
        .await
        .map_err(|e| e.to_string())?;
    loop {
        tokio::select! {
            incoming = stream.next() => {
                let Some(incoming) = incoming else { return Ok(SessionEnd::Closed("server closed the stream".into())) };
                let message = incoming.map_err(|e| e.to_string())?;
                let event = match message {
                    Message::Binary(frame) => match decode(&frame) {
                        Ok(Some(event)) => event,
                        Ok(None) => continue,
                        Err(e) => return Err(format!("bad frame from server: {e}")),
                    },
                    Message::Close(frame) => {
                        let reason = frame.map(|f| f.reason.to_string()).unwrap_or_default();
                        return Ok(SessionEnd::Closed(format!("server closed the connection {reason}")));
                    }
                    _ => continue,
                };
                let fatal = matches!(event, NetEvent::ServerError { fatal: true, .. });
                if events.send(event).is_err() {
                    return Ok(SessionEnd::ReceiverGone);
                }
                if fatal {
                    return Ok(SessionEnd::Fatal);
                }
            }
            wish = outgoing.recv() => {
                let Some(wish) = wish else { return Ok(SessionEnd::ReceiverGone) };
                let message = match wish {
                    Outgoing::Request(pages) => ClientMessage::Request { pages },
                    Outgoing::Cancel(pages) => ClientMessage::Cancel { pages },
                    Outgoing::Received(pages) => ClientMessage::Received { pages },
                };
                sink.send(Message::Binary(codec::encode_control(&message).into())).await.map_err(|e| e.to_string())?;
            }
        }
    }
}

/// A server frame as an event; `None` for a hello of the right version,
/// which needs no action.
fn decode(frame: &[u8]) -> Result<Option<NetEvent>, CodecError> {
    let (kind, bytes) = codec::frame_kind(frame)?;
    match kind {
        FrameKind::Page => {
            return Ok(Some(NetEvent::Page {
                bytes: bytes.to_vec(),
            }));
        }
        FrameKind::Header => {
            return Ok(Some(NetEvent::Connected {
                header: bytes.to_vec(),
            }));
        }
        FrameKind::Control => {}
    }
    Ok(match codec::decode_control::<ServerMessage>(frame)? {
        ServerMessage::Hello {
            protocol_version, ..
        } if protocol_version != PROTOCOL_VERSION => Some(NetEvent::ServerError {
            message: format!(
                "server speaks protocol version {protocol_version}, this client {PROTOCOL_VERSION}"
            ),
            fatal: true,
        }),
        ServerMessage::Hello { .. } => None,
        ServerMessage::Error { message, fatal } => Some(NetEvent::ServerError { message, fatal }),
        ServerMessage::PageUnavailable { page, reason } => {
            Some(NetEvent::PageUnavailable { page, reason })
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn urls() {
        assert_eq!(
            stream_url("http://127.0.0.1:80/", "a"),
            "ws://127.0.0.1:80/scenes/a/stream"
        );
        assert_eq!(
            stream_url("127.0.0.1:80", "a"),
            "ws://127.0.0.1:80/scenes/a/stream"
        );
        assert_eq!(stream_url("ws://h:1", "b"), "ws://h:1/scenes/b/stream");
    }
}
