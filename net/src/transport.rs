//! The seam between a session and the bytes on the wire.
//!
//! A [`Transport`] carries binary websocket frames and says when a
//! connection opened or ended; it knows nothing of the protocol. The
//! session ([`crate::Session`]) decides when to connect, what to send and
//! what a frame means. Implementations: [`crate::websocket`] (native,
//! tokio-tungstenite on a thread of its own), [`crate::queue`] (tests, and
//! async drivers that move the bytes themselves) and [`crate::browser`]
//! (a page's `WebSocket`).

use std::time::Duration;

use bytes::Bytes;
use web_time::Instant;

/// What a transport reports.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum TransportEvent {
    /// The connection asked for by [`Transport::connect`] is open: frames
    /// may be sent.
    Opened,
    /// One binary frame from the server.
    Frame(Bytes),
    /// The attempt failed or the open connection ended, with why and how.
    Closed { reason: String, how: Closing },
}

/// How a connection ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Closing {
    /// The server answered with a reason a retry cannot change (a 4xx
    /// other than 408 and 429, such as an unknown scene's 404); the reason
    /// is the server's own words.
    Refused,
    /// The server ended an open connection (a close frame, or the end of
    /// the stream): a restart, say. The next attempt comes soon.
    ByServer,
    /// The attempt failed or the connection broke (refused by the host,
    /// reset, a read or write error): retries back off.
    Failed,
}

/// Where a connection goes, and the token it proves itself with: sent in
/// an `Authorization` header natively, in a websocket subprotocol from a
/// browser ([`farfield_protocol::auth`]), and never in the URL, which
/// proxies log and errors print. Its `Debug` does not show the token.
#[derive(Clone, PartialEq, Eq)]
pub struct Target {
    pub url: String,
    pub token: Option<String>,
}

impl Target {
    /// A target that needs no token.
    pub fn open(url: impl Into<String>) -> Self {
        Self {
            url: url.into(),
            token: None,
        }
    }
}

impl std::fmt::Debug for Target {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Target")
            .field("url", &self.url)
            .field("token", &self.token.as_ref().map(|_| "<redacted>"))
            .finish()
    }
}

/// Binary frames to and from one server, one connection at a time.
pub trait Transport: std::fmt::Debug {
    /// Starts a connection attempt to `target`, abandoning any current one
    /// (nothing of an abandoned connection is reported or sent after this
    /// call). `hello` is the first frame, sent the moment the connection
    /// opens, whenever the owner next pumps the session: a server waits
    /// for it only so long.
    fn connect(&mut self, target: &Target, hello: Vec<u8>);
    /// Queues a frame on the open connection; dropped when none is open
    /// (the session asks again after the next connection).
    fn send(&mut self, frame: Vec<u8>);
    /// Abandons the current connection or attempt, if any.
    fn close(&mut self);
    /// The next event, waiting at most `wait` for one (a transport that
    /// cannot block, such as a browser's, returns at once).
    fn poll(&mut self, wait: Duration) -> Option<TransportEvent>;
    /// When the event `poll` returned last came off the wire, where the
    /// transport knows it apart from when it was polled (a queue its
    /// driver fills from another task). The session times pages by it, so
    /// an owner busy elsewhere (a load client traversing) is not counted
    /// as the server's or the network's time.
    fn arrived_at(&self) -> Option<Instant> {
        None
    }
    /// Calls `waker` whenever an event arrives, from whatever thread
    /// receives it, so an owner at rest can sleep until then instead of
    /// polling; `false` for a transport that cannot (its owner polls).
    fn set_waker(&mut self, _waker: Waker) -> bool {
        false
    }
}

/// Called when a transport has an event to poll.
#[derive(Clone)]
pub struct Waker(pub std::sync::Arc<dyn Fn() + Send + Sync>);

impl Waker {
    pub fn wake(&self) {
        (self.0)();
    }
}

impl std::fmt::Debug for Waker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Waker")
    }
}

impl<T: Transport + ?Sized> Transport for Box<T> {
    fn connect(&mut self, target: &Target, hello: Vec<u8>) {
        (**self).connect(target, hello);
    }

    fn send(&mut self, frame: Vec<u8>) {
        (**self).send(frame);
    }

    fn close(&mut self) {
        (**self).close();
    }

    fn poll(&mut self, wait: Duration) -> Option<TransportEvent> {
        (**self).poll(wait)
    }

    fn arrived_at(&self) -> Option<Instant> {
        (**self).arrived_at()
    }

    fn set_waker(&mut self, waker: Waker) -> bool {
        (**self).set_waker(waker)
    }
}
