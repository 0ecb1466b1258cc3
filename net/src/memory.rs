//! [`MemoryTransport`]: a transport with no socket, for tests of the
//! session and of what sits on it. The test holds a clone, queues what the
//! "server" says and reads what the session sent.

use std::cell::RefCell;
use std::collections::VecDeque;
use std::rc::Rc;
use std::time::Duration;

use crate::transport::{Transport, TransportEvent};

/// Both ends of an in-memory connection (clones share them).
#[derive(Debug, Clone, Default)]
pub struct MemoryTransport {
    inner: Rc<RefCell<Inner>>,
}

#[derive(Debug, Default)]
struct Inner {
    incoming: VecDeque<TransportEvent>,
    sent: Vec<Vec<u8>>,
    connects: Vec<String>,
    closes: usize,
}

impl MemoryTransport {
    /// Queues an event for the session's next poll.
    pub fn push(&self, event: TransportEvent) {
        self.inner.borrow_mut().incoming.push_back(event);
    }

    /// Takes the frames the session sent since the last call.
    pub fn take_sent(&self) -> Vec<Vec<u8>> {
        std::mem::take(&mut self.inner.borrow_mut().sent)
    }

    /// The URLs of every connection attempt so far.
    pub fn connects(&self) -> Vec<String> {
        self.inner.borrow().connects.clone()
    }

    /// How often the session abandoned a connection.
    pub fn closes(&self) -> usize {
        self.inner.borrow().closes
    }
}

impl Transport for MemoryTransport {
    fn connect(&mut self, url: &str) {
        self.inner.borrow_mut().connects.push(url.to_owned());
    }

    fn send(&mut self, frame: Vec<u8>) {
        self.inner.borrow_mut().sent.push(frame);
    }

    fn close(&mut self) {
        self.inner.borrow_mut().closes += 1;
    }

    /// The next queued event; with none, waits `wait` (as a socket with
    /// nothing to say would) and returns `None`.
    fn poll(&mut self, wait: Duration) -> Option<TransportEvent> {
        let next = self.inner.borrow_mut().incoming.pop_front();
        if next.is_none() && !wait.is_zero() {
            std::thread::sleep(wait);
        }
        next
    }
}
