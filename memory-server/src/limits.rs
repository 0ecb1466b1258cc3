//! What one client may cost, and how long it may take: the limits a server
//! on a public network needs, with defaults that suit one.
//!
//! Each limit, when hit, is answered the way the client can understand
//! (an HTTP status before the websocket upgrade, a close code after it) and
//! counted in `/metrics` as `farfield_limit_hits_total{limit="..."}`.
//!
//! What a connection costs at most, whatever the client sends:
//! [`crate::session::MAX_OUTBOX_BYTES`] of control replies, a websocket
//! write buffer of [`WRITE_BUFFER_BYTES`] plus the scene's largest frame
//! (its largest page, or a header part of at most
//! [`farfield_protocol::messages::HEADER_PART_BYTES`]) and
//! [`WRITE_BUFFER_SLACK_BYTES`] (where answers to pings wait), a read
//! buffer of one client message (a few KiB), and a schedule of at most one
//! entry per page of the scene (requests and cancels are both kept per
//! page, never per message).

use std::time::Duration;

/// How much the websocket layer writes at once before it waits on the
/// socket.
pub const WRITE_BUFFER_BYTES: usize = 128 << 10;
/// Room in the write buffer beyond one frame, for pongs and close frames
/// queued while the client does not read.
pub const WRITE_BUFFER_SLACK_BYTES: usize = 64 << 10;

/// The limits, all per server unless named per connection.
#[derive(Debug, Clone, PartialEq)]
pub struct Limits {
    /// Connections open at once (HTTP and websocket, every client). Past it
    /// a new connection is answered 503 and closed.
    pub max_connections: usize,
    /// Connections open at once from one IP address. Past it: 429.
    pub max_connections_per_address: usize,
    /// Time a connection has to send a request's headers, from its accept
    /// (and its TLS handshake) or from its previous response; covers idle
    /// kept-alive connections and clients that send headers a byte at a
    /// time. Past it the connection is closed (408 where hyper can say so).
    pub header_timeout: Duration,
    /// Time a websocket client has, once upgraded, to say hello. Past it:
    /// a fatal error, then close.
    pub hello_timeout: Duration,
    /// A session from which nothing arrives (no message, no pong) for this
    /// long, or whose socket takes no bytes for this long, is closed (1001).
    /// The server pings each session after a third of it without traffic,
    /// which browsers and websocket libraries answer by themselves.
    pub idle_timeout: Duration,
    /// Websocket messages (pings included) a session may send per second,
    /// sustained; a burst of a second's worth is allowed. Past it: 1008.
    /// Acknowledgements of pages in flight are not counted: they answer
    /// the server's own sending, at its rate.
    pub max_messages_per_second: u32,
    /// How long a demo session whose presenter left waits for one to come
    /// back (anyone who joins as presenter) before it closes.
    pub session_grace: Duration,
    /// Demo sessions open at once; past it a new one is refused.
    pub max_sessions: usize,
    /// Refused connections being answered at once (each holds its socket
    /// while its answer goes out); past it a refused connection is closed
    /// without one. Lowered with `max_connections` to fit the open-files
    /// limit, so refusals never take the descriptors the server needs.
    pub max_refusing: usize,
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            max_connections: 4096,
            max_connections_per_address: 128,
            header_timeout: Duration::from_secs(10),
            hello_timeout: Duration::from_secs(10),
            idle_timeout: Duration::from_secs(60),
            max_messages_per_second: 1000,
            session_grace: Duration::from_secs(30),
            max_sessions: 256,
            max_refusing: 256,
        }
    }
}

impl Limits {
    /// The limits with every count at least 1 and every timeout at least
    /// [`MIN_TIMEOUT`] (a zero idle timeout would ping without pause).
    pub fn sane(mut self) -> Self {
        self.max_connections = self.max_connections.max(1);
        self.max_connections_per_address = self.max_connections_per_address.max(1);
        self.max_messages_per_second = self.max_messages_per_second.max(1);
        self.max_sessions = self.max_sessions.max(1);
        self.max_refusing = self.max_refusing.max(1);
        for t in [
            &mut self.header_timeout,
            &mut self.hello_timeout,
            &mut self.idle_timeout,
        ] {
            *t = (*t).max(MIN_TIMEOUT);
        }
        self
    }
}

/// The shortest timeout [`Limits::sane`] keeps.
pub const MIN_TIMEOUT: Duration = Duration::from_millis(10);

/// Which limit a client ran into, for the log and `/metrics`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Limit {
    MaxConnections,
    MaxConnectionsPerAddress,
    HeaderTimeout,
    HelloTimeout,
    IdleTimeout,
    MessageRate,
    /// The client left its replies unread past the outbox bound.
    UnreadReplies,
    /// A message larger than the protocol allows.
    MessageSize,
}

impl Limit {
    pub const ALL: [Limit; 8] = [
        Limit::MaxConnections,
        Limit::MaxConnectionsPerAddress,
        Limit::HeaderTimeout,
        Limit::HelloTimeout,
        Limit::IdleTimeout,
        Limit::MessageRate,
        Limit::UnreadReplies,
        Limit::MessageSize,
    ];

    /// The label in `/metrics`.
    pub fn name(self) -> &'static str {
        match self {
            Limit::MaxConnections => "max_connections",
            Limit::MaxConnectionsPerAddress => "max_connections_per_address",
            Limit::HeaderTimeout => "header_timeout",
            Limit::HelloTimeout => "hello_timeout",
            Limit::IdleTimeout => "idle_timeout",
            Limit::MessageRate => "message_rate",
            Limit::UnreadReplies => "unread_replies",
            Limit::MessageSize => "message_size",
        }
    }
}

/// A token bucket: `rate` a second, holding at most a second's worth, and
/// more when the server fell behind: what the client may have sent while
/// the server was not reading ([`crate::lag`]), so a backlog read at once
/// after a stall is not taken for a burst.
#[derive(Debug)]
pub struct RateLimiter {
    rate: f64,
    tokens: f64,
    last: std::time::Instant,
}

impl RateLimiter {
    pub fn new(rate: u32, now: std::time::Instant) -> Self {
        let rate = f64::from(rate.max(1));
        Self {
            rate,
            tokens: rate,
            last: now,
        }
    }

    /// Takes one token; `false` when none is left. `behind` is how long
    /// the server recently went without reading (its runtime's lag): the
    /// bucket holds up to `rate` times one second plus that.
    pub fn take(&mut self, now: std::time::Instant, behind: Duration) -> bool {
        let elapsed = now.saturating_duration_since(self.last).as_secs_f64();
        self.last = now;
        let room = self.rate * (1.0 + behind.as_secs_f64());
        self.tokens = (self.tokens + elapsed * self.rate).min(room);
        if self.tokens >= 1.0 {
            self.tokens -= 1.0;
            true
        } else {
            false
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Instant;

    #[test]
    fn the_bucket_allows_a_seconds_burst_then_the_rate() {
        let t0 = Instant::now();
        let mut bucket = RateLimiter::new(100, t0);
        let on_time = Duration::ZERO;
        assert_eq!((0..150).filter(|_| bucket.take(t0, on_time)).count(), 100);
        let t1 = t0 + Duration::from_millis(500);
        assert_eq!((0..150).filter(|_| bucket.take(t1, on_time)).count(), 50);
        let t2 = t1 + Duration::from_secs(60);
        assert_eq!(
            (0..150).filter(|_| bucket.take(t2, on_time)).count(),
            100,
            "never more than a second's worth"
        );
    }

    /// A server that did not read for 3 s reads a client's 3 s of steady
    /// sending at once: the bucket holds it, as it would have had the
    /// server read on time; and only while the lag lasts.
    #[test]
    fn a_backlog_from_a_stalled_server_is_not_a_burst() {
        let t0 = Instant::now();
        let mut bucket = RateLimiter::new(100, t0);
        let t1 = t0 + Duration::from_secs(3);
        let stalled = Duration::from_secs(3);
        assert_eq!((0..300).filter(|_| bucket.take(t1, stalled)).count(), 300);
        let t2 = t1 + Duration::from_secs(60);
        assert_eq!(
            (0..400).filter(|_| bucket.take(t2, Duration::ZERO)).count(),
            100,
            "a server on time again allows a second's worth"
        );
    }
}
