//! [`QueueTransport`]: a transport whose bytes its owner moves.
//!
//! The session connects, sends and polls through it as through any
//! transport; whoever holds a clone plays the other end: a test queues what
//! the "server" says and reads what the session sent, and an async driver
//! ([`crate::websocket::drive`]) feeds it from a socket on the caller's own
//! runtime, so many sessions share one runtime with no thread each.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex, MutexGuard};
use std::task::{Poll, Waker};
use std::time::Duration;

use web_time::Instant;

use crate::transport::{Target, Transport, TransportEvent};

/// Both ends of a queued connection (clones share them).
#[derive(Debug, Clone, Default)]
pub struct QueueTransport {
    inner: Arc<Mutex<Inner>>,
}

#[derive(Debug, Default)]
struct Inner {
    /// Events for the session, each with when it was queued.
    incoming: VecDeque<(TransportEvent, Instant)>,
    /// When the event the session polled last was queued.
    last_arrival: Option<Instant>,
    /// Woken when an event is queued ([`QueueTransport::incoming_ready`]).
    incoming_waker: Option<Waker>,
    sent: Vec<Vec<u8>>,
    /// Woken when there is something for the driver
    /// ([`QueueTransport::outgoing_ready`]).
    outgoing_waker: Option<Waker>,
    /// The owner is done with the connection: its driver stops.
    finished: bool,
    connects: Vec<String>,
    /// A connection asked for and not yet taken by the driver.
    pending_connect: Option<Target>,
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

    /// Queues an event for the session's next poll, stamped now: a frame
    /// arrived when its driver took it off the socket, however long the
    /// session's owner takes to poll it.
    pub fn push(&self, event: TransportEvent) {
        let mut inner = self.lock();
        inner.incoming.push_back((event, Instant::now()));
        if let Some(waker) = inner.incoming_waker.take() {
            waker.wake();
        }
    }

    /// Ready once an event is queued for the session (for an owner that
    /// waits for its driver on another task).
    pub async fn incoming_ready(&self) {
        std::future::poll_fn(|cx| {
            let mut inner = self.lock();
            if inner.incoming.is_empty() {
                inner.incoming_waker = Some(cx.waker().clone());
                Poll::Pending
            } else {
                Poll::Ready(())
            }
        })
        .await;
    }

    /// Ready once the session sent a frame, asked to connect or close, or
    /// the owner finished (for a driver on another task than the owner).
    pub async fn outgoing_ready(&self) {
        std::future::poll_fn(|cx| {
            let mut inner = self.lock();
            if inner.sent.is_empty()
                && inner.pending_connect.is_none()
                && !inner.pending_close
                && !inner.finished
            {
                inner.outgoing_waker = Some(cx.waker().clone());
                Poll::Pending
            } else {
                Poll::Ready(())
            }
        })
        .await;
    }

    /// The owner is done: a driver carrying this connection stops.
    pub fn finish(&self) {
        let mut inner = self.lock();
        inner.finished = true;
        inner.wake_driver();
    }

    pub fn is_finished(&self) -> bool {
        self.lock().finished
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

    /// The connection the session asked for since the last call.
    pub fn take_connect(&self) -> Option<Target> {
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
    fn connect(&mut self, target: &Target, hello: Vec<u8>) {
        let mut inner = self.lock();
        inner.connects.push(target.url.clone());
        inner.pending_connect = Some(target.clone());
        // Nothing of an abandoned connection is reported or sent after this.
        inner.incoming.clear();
        inner.sent = vec![hello];
        inner.wake_driver();
    }

    fn send(&mut self, frame: Vec<u8>) {
        let mut inner = self.lock();
        inner.sent.push(frame);
        inner.wake_driver();
    }

    fn close(&mut self) {
        let mut inner = self.lock();
        inner.closes += 1;
        inner.pending_close = true;
        inner.pending_connect = None;
        inner.incoming.clear();
        inner.sent.clear();
        inner.wake_driver();
    }

    /// The next queued event; with none, waits `wait` (as a socket with
    /// nothing to say would) and returns `None`.
    fn poll(&mut self, wait: Duration) -> Option<TransportEvent> {
        let next = {
            let mut inner = self.lock();
            let next = inner.incoming.pop_front();
            if let Some((_, at)) = &next {
                inner.last_arrival = Some(*at);
            }
            next
        };
        if next.is_none() && !wait.is_zero() {
            std::thread::sleep(wait);
        }
        next.map(|(event, _)| event)
    }

    fn arrived_at(&self) -> Option<Instant> {
        self.lock().last_arrival
    }
}

impl Inner {
    fn wake_driver(&mut self) {
        if let Some(waker) = self.outgoing_waker.take() {
            waker.wake();
        }
    }
}
