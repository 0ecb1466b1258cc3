//! [`QueueTransport`]: a transport whose bytes its owner moves.
//!
//! The session connects, sends and polls through it as through any
//! transport; whoever holds a clone plays the other end: a test queues what
//! the "server" says and reads what the session sent, and an async driver
//! ([`crate::websocket::drive`]) feeds it from a socket on the caller's own
//! runtime, so many sessions share one runtime with no thread each.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use crate::transport::{Transport, TransportEvent};

/// Both ends of a queued connection (clones share them).
#[derive(Debug, Clone, Default)]
pub struct QueueTransport {
    inner: Arc<Mutex<Inner>>,
}

#[derive(Debug, Default)]
struct Inner {
    incoming: VecDeque<TransportEvent>,
    sent: Vec<Vec<u8>>,
    connects: Vec<String>,
    /// A connection asked for and not yet taken by the driver.
    pending_connect: Option<String>,
    closes: usize,
    /// The session abandoned its connection since the driver last looked.
    pending_close: bool,
}

impl QueueTransport {
    fn lock(&self) -> MutexGuard<'_, Inner> {
        // A panic elsewhere while holding the lock leaves plain queues,
        // still consistent.
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Queues an event for the session's next poll.
    pub fn push(&self, event: TransportEvent) {
        self.lock().incoming.push_back(event);
    }

    /// Takes the frames the session sent since the last call.
    pub fn take_sent(&self) -> Vec<Vec<u8>> {
        std::mem::take(&mut self.lock().sent)
    }

    /// The URLs of every connection attempt so far.
    pub fn connects(&self) -> Vec<String> {
        self.lock().connects.clone()
    }

    /// How often the session abandoned a connection.
    pub fn closes(&self) -> usize {
        self.lock().closes
    }

    /// The URL of a connection the session asked for since the last call.
    pub fn take_connect(&self) -> Option<String> {
        self.lock().pending_connect.take()
    }

    /// Whether the session abandoned its connection since the last call.
    pub fn take_close(&self) -> bool {
        std::mem::take(&mut self.lock().pending_close)
    }
}

impl Transport for QueueTransport {
    /// Records the attempt for the driver; `hello` is queued as the first
    /// frame to send.
    fn connect(&mut self, url: &str, hello: Vec<u8>) {
        let mut inner = self.lock();
        inner.connects.push(url.to_owned());
        inner.pending_connect = Some(url.to_owned());
        // Nothing of an abandoned connection is reported or sent after this.
        inner.incoming.clear();
        inner.sent = vec![hello];
    }

    fn send(&mut self, frame: Vec<u8>) {
        self.lock().sent.push(frame);
    }

    fn close(&mut self) {
        let mut inner = self.lock();
        inner.closes += 1;
        inner.pending_close = true;
        inner.pending_connect = None;
        inner.incoming.clear();
        inner.sent.clear();
    }

    /// The next queued event; with none, waits `wait` (as a socket with
    /// nothing to say would) and returns `None`.
    fn poll(&mut self, wait: Duration) -> Option<TransportEvent> {
        let next = self.lock().incoming.pop_front();
        if next.is_none() && !wait.is_zero() {
            std::thread::sleep(wait);
        }
        next
    }
}
