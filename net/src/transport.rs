//! The seam between a session and the bytes on the wire.
//!
//! A [`Transport`] carries binary websocket frames and says when a
//! connection opened or ended; it knows nothing of the protocol. The
//! session ([`crate::Session`]) decides when to connect, what to send and
//! what a frame means. Implementations: [`crate::websocket`] (native,
//! tokio-tungstenite on a thread of its own), [`crate::memory`] (tests),
//! and a browser `WebSocket` next.

use std::time::Duration;

use bytes::Bytes;

/// What a transport reports.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum TransportEvent {
    /// The connection asked for by [`Transport::connect`] is open: frames
    /// may be sent.
    Opened,
    /// One binary frame from the server.
    Frame(Bytes),
    /// The attempt failed or the open connection ended, with why.
    /// `refused` when the server answered with a reason a retry cannot
    /// change (a 4xx other than 408 and 429, such as an unknown scene's
    /// 404); `reason` is then the server's own words.
    Closed { reason: String, refused: bool },
}

/// Binary frames to and from one server, one connection at a time.
pub trait Transport: std::fmt::Debug {
    /// Starts a connection attempt to `url`, abandoning any current one
    /// (nothing of an abandoned connection is reported after this call).
    fn connect(&mut self, url: &str);
    /// Queues a frame on the open connection; dropped when none is open
    /// (the session asks again after the next connection).
    fn send(&mut self, frame: Vec<u8>);
    /// Abandons the current connection or attempt, if any.
    fn close(&mut self);
    /// The next event, waiting at most `wait` for one (a transport that
    /// cannot block, such as a browser's, returns at once).
    fn poll(&mut self, wait: Duration) -> Option<TransportEvent>;
}

impl<T: Transport + ?Sized> Transport for Box<T> {
    fn connect(&mut self, url: &str) {
        (**self).connect(url);
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
}
