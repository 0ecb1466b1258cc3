//! Who may open a connection: at most `max_connections` at once, and at
//! most `max_connections_per_address` from one IP address.
//!
//! A [`Ticket`] is a connection's place; it lives inside the connection's
//! I/O object ([`Admitted`]), so it is given back when the socket closes,
//! whether the connection ended as HTTP or lived on as a websocket.

use std::collections::HashMap;
use std::net::IpAddr;
use std::pin::Pin;
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll};

use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::sync::Notify;

use super::limits::Limit;
use super::metrics::Metrics;

/// The connections open now, by address.
#[derive(Debug)]
pub(crate) struct Admission {
    max_total: usize,
    max_per_address: usize,
    open: Mutex<Open>,
    /// Signalled whenever a connection closes.
    pub closed: Notify,
    /// Where the count of open connections is shown.
    metrics: Arc<Metrics>,
}

#[derive(Debug, Default)]
struct Open {
    total: usize,
    by_address: HashMap<IpAddr, usize>,
}

impl Admission {
    pub fn new(max_total: usize, max_per_address: usize, metrics: Arc<Metrics>) -> Arc<Self> {
        Arc::new(Self {
            max_total,
            max_per_address,
            open: Mutex::new(Open::default()),
            closed: Notify::new(),
            metrics,
        })
    }

    fn show(&self, open: &Open) {
        let n = i64::try_from(open.total).unwrap_or(i64::MAX);
        self.metrics
            .open_connections
            .store(n, std::sync::atomic::Ordering::Relaxed);
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Open> {
        self.open.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// A place for a connection from `ip`, or the limit that refuses it.
    pub fn admit(self: &Arc<Self>, ip: IpAddr) -> Result<Ticket, Limit> {
        let mut open = self.lock();
        if open.total >= self.max_total {
            return Err(Limit::MaxConnections);
        }
        let from_ip = open.by_address.entry(ip).or_insert(0);
        if *from_ip >= self.max_per_address {
            return Err(Limit::MaxConnectionsPerAddress);
        }
        *from_ip += 1;
        open.total += 1;
        self.show(&open);
        Ok(Ticket {
            admission: self.clone(),
            ip,
        })
    }

    /// Connections open now.
    pub fn open(&self) -> usize {
        self.lock().total
    }

    pub fn max_total(&self) -> usize {
        self.max_total
    }

    pub fn max_per_address(&self) -> usize {
        self.max_per_address
    }
}

/// One admitted connection's place, given back on drop.
#[derive(Debug)]
pub(crate) struct Ticket {
    admission: Arc<Admission>,
    ip: IpAddr,
}

impl Drop for Ticket {
    fn drop(&mut self) {
        let mut open = self.admission.lock();
        open.total = open.total.saturating_sub(1);
        if let Some(n) = open.by_address.get_mut(&self.ip) {
            *n = n.saturating_sub(1);
            if *n == 0 {
                open.by_address.remove(&self.ip);
            }
        }
        self.admission.show(&open);
        drop(open);
        self.admission.closed.notify_waiters();
    }
}

/// A connection's I/O with its ticket: reads and writes go to `io`.
#[derive(Debug)]
pub(crate) struct Admitted<S> {
    pub io: S,
    pub _ticket: Ticket,
}

impl<S: AsyncRead + Unpin> AsyncRead for Admitted<S> {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<std::io::Result<()>> {
        Pin::new(&mut self.io).poll_read(cx, buf)
    }
}

impl<S: AsyncWrite + Unpin> AsyncWrite for Admitted<S> {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<std::io::Result<usize>> {
        Pin::new(&mut self.io).poll_write(cx, buf)
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        Pin::new(&mut self.io).poll_flush(cx)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        Pin::new(&mut self.io).poll_shutdown(cx)
    }

    fn poll_write_vectored(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[std::io::IoSlice<'_>],
    ) -> Poll<std::io::Result<usize>> {
        Pin::new(&mut self.io).poll_write_vectored(cx, bufs)
    }

    fn is_write_vectored(&self) -> bool {
        self.io.is_write_vectored()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn places_are_counted_per_address_and_given_back() {
        let a: IpAddr = "10.0.0.1".parse().unwrap();
        let b: IpAddr = "10.0.0.2".parse().unwrap();
        let admission = Admission::new(3, 2, Arc::default());
        let t1 = admission.admit(a).unwrap();
        let _t2 = admission.admit(a).unwrap();
        assert_eq!(
            admission.admit(a).unwrap_err(),
            Limit::MaxConnectionsPerAddress
        );
        let _t3 = admission.admit(b).unwrap();
        assert_eq!(admission.admit(b).unwrap_err(), Limit::MaxConnections);
        drop(t1);
        assert_eq!(admission.open(), 2);
        assert!(admission.admit(a).is_ok(), "a place came back");
    }
}
