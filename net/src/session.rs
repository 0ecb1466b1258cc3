//! [`Session`]: the protocol's state on the client, over any [`Transport`].
//!
//! Everything a client must remember about a session lives here and
//! nowhere else: the hello, the scene's header, which pages were asked for
//! (with what priority) and which were cancelled, the acknowledgements,
//! the pages that failed their checksum (asked for again, given up after
//! [`MAX_PAGE_FAILURES`]) or that the server cannot send (given up at
//! once), and reconnecting with backoff. The transport only moves frames;
//! the caller (the viewer's resident pages) only verifies and keeps pages.
//!
//! When the connection drops the session reports it, waits (50 ms,
//! doubling to 2 s) and reconnects; the server forgot the wishes, so the
//! caller's next [`Session::request`] asks again for whatever it still
//! lacks, and nothing it holds is fetched twice. A refusal (an unknown
//! scene's 404) ends the session with the server's reason, since retrying
//! cannot change it, and so does a server never reached within
//! [`SessionOptions::first_connect_grace`].

use std::collections::{HashMap, VecDeque};
use std::time::Duration;

use bytes::Bytes;
use farfield_protocol::FormatError;
use farfield_protocol::codec::{self, CodecError};
use farfield_protocol::file::{FileHeader, HEADER_PREFIX_BYTES};
use farfield_protocol::messages::{
    ClientMessage, FrameKind, MAX_HEADER_BYTES, PROTOCOL_VERSION, PageWish, ServerMessage,
    SessionState, SharedView,
};
use farfield_protocol::page::claimed_index;
use web_time::Instant;

use crate::stats::{FailedPage, NetStats};
use crate::transport::{Closing, Target, Transport, TransportEvent};

/// Checksum failures after which a page is given up on.
pub const MAX_PAGE_FAILURES: u32 = 3;

/// The first wait before reconnecting; it doubles up to [`MAX_BACKOFF`].
const FIRST_BACKOFF: Duration = Duration::from_millis(50);
const MAX_BACKOFF: Duration = Duration::from_secs(2);

/// The hello frame for `options`: sent first on every connection.
fn hello(options: &SessionOptions) -> Vec<u8> {
    codec::encode_control(&ClientMessage::Hello {
        protocol_version: PROTOCOL_VERSION,
        max_in_flight_bytes: options.max_in_flight_bytes,
        allow_push: options.allow_push,
    })
}

/// What a client announces in its hello (`max_in_flight_bytes`,
/// `allow_push`), how long it tries to connect at first, and what it shows
/// a server that wants a token or speaks TLS with a private certificate.
#[derive(Clone)]
pub struct SessionOptions {
    pub max_in_flight_bytes: u64,
    pub allow_push: bool,
    /// How long a session that has never connected keeps trying: a wrong
    /// address or a server that is not running should fail in seconds, not
    /// at the render's timeout. Once connected, a session retries for as
    /// long as its owner waits (servers restart).
    pub first_connect_grace: Duration,
    /// The server's access token, sent in a header (natively) or a
    /// websocket subprotocol (in a browser), never in the URL
    /// ([`crate::Target`]); `Debug` does not show it.
    pub token: Option<String>,
    /// A certificate authority (PEM) to trust for `wss://` servers instead
    /// of the public roots; the native transport only.
    pub ca_cert: Option<std::path::PathBuf>,
    /// Pages asked for and not yet arrived, at most (`None`: every wanted
    /// page is asked for at once). Like Potree's `maxNodesLoading` or
    /// Cesium's simultaneous tile loads: the rest are asked for as pages
    /// arrive, highest priority first, so no request waits behind a long
    /// queue of the client's own.
    pub max_outstanding: Option<usize>,
}

impl std::fmt::Debug for SessionOptions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SessionOptions")
            .field("max_in_flight_bytes", &self.max_in_flight_bytes)
            .field("allow_push", &self.allow_push)
            .field("first_connect_grace", &self.first_connect_grace)
            .field("token", &self.token.as_ref().map(|_| "<redacted>"))
            .field("ca_cert", &self.ca_cert)
            .field("max_outstanding", &self.max_outstanding)
            .finish()
    }
}

impl Default for SessionOptions {
    fn default() -> Self {
        Self {
            max_in_flight_bytes: 4 << 20,
            allow_push: false,
            first_connect_grace: Duration::from_secs(10),
            token: None,
            ca_cert: None,
            max_outstanding: None,
        }
    }
}

/// What a session hands its owner.
#[derive(Debug, Clone, PartialEq)]
pub enum SessionEvent {
    /// The scene's header, on the first connection (a reconnect to the
    /// same scene says nothing).
    Header(FileHeader),
    /// A page's stored bytes, unverified: the owner checks them and calls
    /// [`Session::page_rejected`] when they fail. Already acknowledged.
    Page { index: u32, bytes: Bytes },
    /// News of the demo session this connection is in.
    Demo(DemoEvent),
}

/// What a demo session tells its members.
#[derive(Debug, Clone, PartialEq)]
pub enum DemoEvent {
    /// Who is in it now.
    State(SessionState),
    /// The presenter's latest view, and when it came off the wire.
    View {
        seq: u64,
        view: SharedView,
        arrived: Instant,
    },
    /// It closed, or refused this client, and why; the client is in no
    /// session now.
    Closed { session: String, reason: String },
}

/// The demo session a session is to be in, joined again on every connection.
#[derive(Debug, Clone, PartialEq)]
struct DemoSeat {
    name: String,
    present: bool,
}

/// Why a session ended. It does not recover: the owner stops.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SessionError {
    /// Refused by the server, or not reached within the first-connection
    /// grace.
    #[error("{0}")]
    GaveUp(String),
    /// The server said something fatal (or speaks another version).
    #[error("server: {0}")]
    Server(String),
    #[error("scene header from the server: {0}")]
    BadHeader(FormatError),
    #[error("the server's scene changed under this session")]
    SceneChanged,
    #[error("the session has ended")]
    Ended,
}

/// Where the connection stands.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Link {
    /// An attempt is under way.
    Connecting,
    /// Open (frames flow); `header` once this connection sent the header.
    Open {
        header: bool,
    },
    /// Waiting to try again.
    Waiting {
        until: Instant,
    },
    Ended,
}

/// Most request-to-arrival times a session keeps for its owner to take:
/// an owner that never takes them (a viewer) holds a bounded few.
pub const LATENCY_SAMPLES: usize = 4096;

/// A page asked for: the priority last sent, and when it was first asked
/// for on this connection (its latency runs from there).
#[derive(Debug, Clone, Copy)]
struct Wish {
    priority: f32,
    since: Instant,
}

/// The client's side of one scene's session.
#[derive(Debug)]
pub struct Session<T: Transport> {
    transport: T,
    target: Target,
    options: SessionOptions,
    link: Link,
    connected_once: bool,
    first_deadline: Instant,
    backoff: Duration,
    header: Option<FileHeader>,
    /// This connection's header frames so far, until they hold the whole
    /// header (the server sends it in parts).
    header_parts: Vec<u8>,
    /// Asked for and not yet arrived.
    requested: HashMap<u32, Wish>,
    /// Under [`SessionOptions::max_outstanding`]: what the last
    /// [`Session::request`] wanted and had no room for, most urgent first;
    /// asked for as pages arrive, without waiting for the next request.
    backlog: VecDeque<PageWish>,
    /// Request-to-arrival times of the latest pages that were asked for
    /// (at most [`LATENCY_SAMPLES`]; see [`Session::take_latencies`]).
    latencies: VecDeque<Duration>,
    /// Per page that failed: how often, and the last reason.
    failures: HashMap<u32, (u32, String)>,
    /// The demo session to be in, if any.
    demo: Option<DemoSeat>,
    /// The last error about the scene itself (a page, a server message), which
    /// still stands after a reconnect; `stats.last_error` goes back to it
    /// once a lost connection is back.
    last_scene_error: Option<String>,
    pub stats: NetStats,
}

impl<T: Transport> Session<T> {
    /// Has `waker` called whenever the transport has something to pump
    /// ([`Transport::set_waker`]); `false` when it cannot.
    pub fn set_waker(&mut self, waker: crate::transport::Waker) -> bool {
        self.transport.set_waker(waker)
    }

    /// Starts connecting to `url` (see [`crate::stream_url`]), with the
    /// options' token if they have one.
    pub fn open(mut transport: T, url: String, options: SessionOptions) -> Self {
        let target = Target {
            url,
            token: options.token.clone(),
        };
        transport.connect(&target, hello(&options));
        let first_deadline = Instant::now() + options.first_connect_grace;
        Self {
            transport,
            target,
            options,
            link: Link::Connecting,
            connected_once: false,
            first_deadline,
            backoff: FIRST_BACKOFF,
            header: None,
            header_parts: Vec::new(),
            requested: HashMap::new(),
            backlog: VecDeque::new(),
            latencies: VecDeque::new(),
            demo: None,
            failures: HashMap::new(),
            last_scene_error: None,
            stats: NetStats::default(),
        }
    }

    /// The scene's header, once it arrived.
    pub fn header(&self) -> Option<&FileHeader> {
        self.header.as_ref()
    }

    /// Whether this connection is open and has sent the scene's header (a
    /// request now reaches the server).
    pub fn is_connected(&self) -> bool {
        self.link == Link::Open { header: true }
    }

    /// Pages asked for and not yet arrived.
    pub fn outstanding(&self) -> usize {
        self.requested.len()
    }

    /// Takes everything that has arrived, waiting up to `wait` for the
    /// first event when none is queued, and acknowledges the pages. An
    /// error ends the session.
    pub fn pump(&mut self, wait: Duration) -> Result<Vec<SessionEvent>, SessionError> {
        let mut out = Vec::new();
        let mut acks = Vec::new();
        let result = self.pump_into(wait, &mut out, &mut acks);
        if result.is_err() {
            self.transport.close();
            self.link = Link::Ended;
        }
        if !acks.is_empty() && matches!(self.link, Link::Open { .. }) {
            self.refill(&acks);
            self.send(&ClientMessage::Received { pages: acks });
        }
        result.map(|()| out)
    }

    fn pump_into(
        &mut self,
        wait: Duration,
        out: &mut Vec<SessionEvent>,
        acks: &mut Vec<u32>,
    ) -> Result<(), SessionError> {
        self.on_timers()?;
        let wait = match self.link {
            Link::Ended => return Err(SessionError::Ended),
            // Wake for the timers: a reconnect, or the first-connect grace.
            Link::Waiting { until } => wait.min(until.saturating_duration_since(Instant::now())),
            Link::Connecting if !self.connected_once => wait.min(
                self.first_deadline
                    .saturating_duration_since(Instant::now()),
            ),
            _ => wait,
        };
        let mut next = self.transport.poll(wait);
        if next.is_none() {
            self.on_timers()?;
        }
        while let Some(event) = next {
            self.on_transport(event, out, acks)?;
            next = self.transport.poll(Duration::ZERO);
        }
        Ok(())
    }

    /// Reconnects when the wait is over; gives up an attempt that the
    /// first-connect grace has run out on.
    fn on_timers(&mut self) -> Result<(), SessionError> {
        let now = Instant::now();
        match self.link {
            Link::Waiting { until } if now >= until => {
                self.transport.connect(&self.target, hello(&self.options));
                self.link = Link::Connecting;
            }
            // An attempt may not outlast the grace (a silently dropped
            // connect would otherwise wait minutes).
            Link::Connecting if !self.connected_once && now >= self.first_deadline => {
                self.transport.close();
                let reason = format!("connect {}: no answer", self.target.url);
                return Err(self.give_up_reaching(&reason));
            }
            _ => {}
        }
        Ok(())
    }

    fn give_up_reaching(&self, reason: &str) -> SessionError {
        SessionError::GaveUp(format!(
            "cannot reach the server within {:.0} s: {reason}",
            self.options.first_connect_grace.as_secs_f64()
        ))
    }

    fn on_transport(
        &mut self,
        event: TransportEvent,
        out: &mut Vec<SessionEvent>,
        acks: &mut Vec<u32>,
    ) -> Result<(), SessionError> {
        match event {
            // The transport sent the hello it was given with `connect`.
            TransportEvent::Opened => {
                self.connected_once = true;
                self.link = Link::Open { header: false };
                self.header_parts = Vec::new();
                Ok(())
            }
            TransportEvent::Frame(frame) => match self.on_frame(frame, out, acks) {
                Ok(result) => result,
                Err(e) => {
                    self.transport.close();
                    self.disconnected(format!("bad frame from server: {e}"), Closing::Failed)
                }
            },
            // Nothing is connecting: stale news of an abandoned attempt.
            TransportEvent::Closed { .. } if matches!(self.link, Link::Waiting { .. }) => Ok(()),
            TransportEvent::Closed { reason, how } => {
                if how == Closing::Refused {
                    return Err(SessionError::GaveUp(reason));
                }
                self.disconnected(reason, how)
            }
        }
    }

    /// One frame from the server. The outer error is a frame that does not
    /// decode (the connection is dropped); the inner one ends the session.
    fn on_frame(
        &mut self,
        frame: Bytes,
        out: &mut Vec<SessionEvent>,
        acks: &mut Vec<u32>,
    ) -> Result<Result<(), SessionError>, CodecError> {
        let (kind, _) = codec::frame_kind(&frame)?;
        let body = frame.slice(1..);
        match kind {
            FrameKind::Page => self.on_page(body, out, acks),
            FrameKind::Header => return Ok(self.on_header(&body, out)),
            FrameKind::Control => match codec::decode_control::<ServerMessage>(&frame)? {
                ServerMessage::Hello {
                    protocol_version, ..
                } if protocol_version != PROTOCOL_VERSION => {
                    let message = format!(
                        "server speaks protocol version {protocol_version}, this client {PROTOCOL_VERSION}"
                    );
                    tracing::warn!("server: {message}");
                    self.stats.last_error = Some(message.clone());
                    return Ok(Err(SessionError::Server(message)));
                }
                ServerMessage::Hello { .. } => {}
                ServerMessage::Error { message, fatal } => {
                    tracing::warn!("server: {message}");
                    self.stats.last_error = Some(message.clone());
                    self.last_scene_error = Some(message.clone());
                    if fatal {
                        return Ok(Err(SessionError::Server(message)));
                    }
                }
                ServerMessage::SessionState { state } => {
                    out.push(SessionEvent::Demo(DemoEvent::State(state)));
                }
                ServerMessage::View { seq, view } => {
                    let arrived = self.arrival();
                    out.push(SessionEvent::Demo(DemoEvent::View { seq, view, arrived }));
                }
                ServerMessage::SessionClosed { session, reason } => {
                    if self.demo.as_ref().is_some_and(|d| d.name == session) {
                        self.demo = None;
                    }
                    out.push(SessionEvent::Demo(DemoEvent::Closed { session, reason }));
                }
                ServerMessage::PageUnavailable { page, reason } => {
                    tracing::warn!("giving up page {page}: {reason}");
                    self.stats.pages_unavailable += 1;
                    self.stats.last_error = Some(reason.clone());
                    self.last_scene_error = Some(reason.clone());
                    self.requested.remove(&page);
                    // Given up at once: the server's copy will not heal.
                    self.failures.insert(page, (MAX_PAGE_FAILURES, reason));
                }
            },
        }
        Ok(Ok(()))
    }

    /// One header frame: a part of the header, joined to those before it
    /// until they hold the length its first bytes declare.
    fn on_header(&mut self, part: &[u8], out: &mut Vec<SessionEvent>) -> Result<(), SessionError> {
        let bad = |why: String| SessionError::BadHeader(FormatError::BadHeader(why));
        if self.link == (Link::Open { header: true }) {
            return Err(bad("a header frame after the whole header".into()));
        }
        self.header_parts.extend_from_slice(part);
        let have = self.header_parts.len();
        if have < HEADER_PREFIX_BYTES {
            return Ok(());
        }
        let len = FileHeader::peek_len(&self.header_parts).map_err(SessionError::BadHeader)?;
        if len > MAX_HEADER_BYTES {
            return Err(bad(format!(
                "the header declares {len} bytes, more than the {MAX_HEADER_BYTES} a client takes"
            )));
        }
        if have < len {
            return Ok(());
        }
        if have > len {
            return Err(bad(format!(
                "header frames carry {have} bytes for a header of {len}"
            )));
        }
        // Taken, not cleared: the buffer's memory goes with it.
        let bytes = std::mem::take(&mut self.header_parts);
        let header = FileHeader::decode(&bytes).map_err(SessionError::BadHeader)?;
        match &self.header {
            Some(h) if *h != header => return Err(SessionError::SceneChanged),
            // The same scene again, on a new connection.
            Some(_) => self.stats.reconnects += 1,
            None => {
                out.push(SessionEvent::Header(header.clone()));
                self.header = Some(header);
            }
        }
        self.link = Link::Open { header: true };
        self.requested.clear();
        // The demo session is the connection's: join it again on a new one.
        if let Some(seat) = self.demo.clone() {
            self.send(&ClientMessage::Join {
                session: seat.name,
                present: seat.present,
            });
        }
        // Connected again: what went wrong with the connection is over.
        self.stats.last_error = self.last_scene_error.clone();
        Ok(())
    }

    /// When the frame being handled came off the wire: the transport's
    /// stamp where it keeps one, else now.
    fn arrival(&self) -> Instant {
        self.transport.arrived_at().unwrap_or_else(Instant::now)
    }

    fn on_page(&mut self, bytes: Bytes, out: &mut Vec<SessionEvent>, acks: &mut Vec<u32>) {
        self.stats.bytes_received += bytes.len() as u64;
        self.stats.pages_received += 1;
        // Bytes that do not even name a page cannot be filed or acknowledged.
        let Some(index) = claimed_index(&bytes) else {
            return;
        };
        if self.header.is_none() {
            return;
        }
        if let Some(wish) = self.requested.remove(&index) {
            if self.latencies.len() >= LATENCY_SAMPLES {
                self.latencies.pop_front();
            }
            let arrived = self.arrival();
            self.latencies
                .push_back(arrived.saturating_duration_since(wish.since));
        }
        acks.push(index);
        out.push(SessionEvent::Page { index, bytes });
    }

    /// The connection is gone: forget what the server forgot and wait
    /// before trying again, or give up when the server was never reached
    /// and the grace would run out first.
    fn disconnected(&mut self, reason: String, how: Closing) -> Result<(), SessionError> {
        // A server that closed an open connection (a restart) is tried
        // again soon; one that breaks connections keeps the backoff growing.
        if how == Closing::ByServer && matches!(self.link, Link::Open { .. }) {
            self.backoff = FIRST_BACKOFF;
        }
        let now = Instant::now();
        // Give up now rather than start an attempt the deadline would cut
        // short, whose "no answer" would hide this attempt's reason.
        if !self.connected_once && now + self.backoff >= self.first_deadline {
            return Err(self.give_up_reaching(&reason));
        }
        if self.link == (Link::Open { header: true }) {
            tracing::warn!("connection lost: {reason}; reconnecting");
            self.stats.disconnects += 1;
        }
        self.stats.last_error = Some(reason);
        // The server forgot our wishes with the connection.
        self.requested.clear();
        self.link = Link::Waiting {
            until: now + self.backoff,
        };
        self.backoff = (self.backoff * 2).min(MAX_BACKOFF);
        Ok(())
    }

    /// Reports that the page `index` just handed out failed verification:
    /// it is counted and asked for again until it has failed
    /// [`MAX_PAGE_FAILURES`] times.
    pub fn page_rejected(&mut self, index: u32, error: &FormatError) {
        self.stats.pages_rejected += 1;
        let reason = format!("page {index}: {error}");
        let (failures, last) = self.failures.entry(index).or_default();
        *failures += 1;
        *last = reason.clone();
        tracing::warn!(
            "page {index} rejected ({error}); attempt {failures} of {MAX_PAGE_FAILURES}"
        );
        self.stats.last_error = Some(reason.clone());
        self.last_scene_error = Some(reason);
    }

    /// Sends new wishes and cancels stale ones. `wanted` is the traversal's
    /// list (most urgent first); a wish whose priority moved by less than a
    /// quarter is not sent again.
    pub fn request(&mut self, wanted: &[PageWish]) {
        if !self.is_connected() {
            return;
        }
        let mut new = Vec::new();
        let now = Instant::now();
        let mut still: HashMap<u32, f32> = HashMap::with_capacity(wanted.len());
        // Under a bound, pages already on their way stay; new ones are
        // admitted highest priority first into the room left.
        let mut order: Vec<&PageWish> = wanted.iter().collect();
        let mut held_back = VecDeque::new();
        let mut room = usize::MAX;
        if let Some(bound) = self.options.max_outstanding {
            order.sort_by(|a, b| b.priority.total_cmp(&a.priority));
            let on_the_way = wanted
                .iter()
                .filter(|w| self.requested.contains_key(&w.page))
                .count();
            room = bound.saturating_sub(on_the_way);
        }
        for w in order {
            if self.gave_up(w.page) {
                continue;
            }
            let priority = w.priority.min(f32::MAX);
            match self.requested.get(&w.page).map(|w| w.priority) {
                Some(p) if (p - priority).abs() <= 0.25 * p.abs() => {}
                Some(_) => new.push(PageWish {
                    page: w.page,
                    priority,
                }),
                None if room == 0 => {
                    held_back.push_back(PageWish {
                        page: w.page,
                        priority,
                    });
                    continue;
                }
                None => {
                    room -= 1;
                    new.push(PageWish {
                        page: w.page,
                        priority,
                    });
                }
            }
            still.insert(w.page, priority);
        }
        self.backlog = held_back;
        let stale: Vec<u32> = self
            .requested
            .keys()
            .copied()
            .filter(|p| !still.contains_key(p))
            .collect();
        if !stale.is_empty() {
            self.stats.pages_cancelled += stale.len() as u64;
            for p in &stale {
                self.requested.remove(p);
            }
            self.send(&ClientMessage::Cancel { pages: stale });
        }
        if !new.is_empty() {
            self.stats.pages_requested += new
                .iter()
                .filter(|w| !self.requested.contains_key(&w.page))
                .count() as u64;
            for w in &new {
                // A new priority for a page already asked for keeps its start.
                let since = self.requested.get(&w.page).map_or(now, |old| old.since);
                self.requested.insert(
                    w.page,
                    Wish {
                        priority: w.priority,
                        since,
                    },
                );
            }
            self.send(&ClientMessage::Request { pages: new });
        }
    }

    /// Pages arrived (`arrived`): their room goes to the backlog's most
    /// urgent pages, in one request.
    fn refill(&mut self, arrived: &[u32]) {
        let Some(bound) = self.options.max_outstanding else {
            return;
        };
        let mut room = bound.saturating_sub(self.requested.len());
        let mut new = Vec::new();
        let now = Instant::now();
        while room > 0 {
            let Some(w) = self.backlog.pop_front() else {
                break;
            };
            if self.requested.contains_key(&w.page)
                || arrived.contains(&w.page)
                || self.gave_up(w.page)
            {
                continue;
            }
            room -= 1;
            self.requested.insert(
                w.page,
                Wish {
                    priority: w.priority,
                    since: now,
                },
            );
            new.push(w);
        }
        if !new.is_empty() {
            self.stats.pages_requested += new.len() as u64;
            self.send(&ClientMessage::Request { pages: new });
        }
    }

    /// Joins demo session `name` as its presenter or a follower, now if
    /// connected, else once connected; and again after every reconnect.
    /// The answer comes as [`SessionEvent::Demo`].
    pub fn join_demo(&mut self, name: &str, present: bool) {
        self.demo = Some(DemoSeat {
            name: name.to_owned(),
            present,
        });
        if self.is_connected() {
            self.send(&ClientMessage::Join {
                session: name.to_owned(),
                present,
            });
        }
    }

    /// Leaves the demo session (pages keep coming as before).
    pub fn leave_demo(&mut self) {
        if self.demo.take().is_some() && self.is_connected() {
            self.send(&ClientMessage::Leave);
        }
    }

    /// The demo session this session is in (or is joining), if any.
    pub fn demo(&self) -> Option<&str> {
        self.demo.as_ref().map(|d| d.name.as_str())
    }

    /// Shows `view` to the demo session's followers (the server refuses
    /// it from anyone but the presenter). Not sent while disconnected:
    /// the next view will be.
    pub fn show_view(&mut self, view: SharedView) {
        if self.demo.is_some() && self.is_connected() {
            self.send(&ClientMessage::View { view });
        }
    }

    /// Gives the presenter's seat to member `to`; from now on this client
    /// follows (and joins as a follower after a reconnect).
    pub fn hand_over(&mut self, to: u64) {
        if let Some(seat) = self.demo.as_mut()
            && self.link == (Link::Open { header: true })
        {
            seat.present = false;
            self.send(&ClientMessage::HandOver { to });
        }
    }

    /// Records that this client was handed the presenter's seat, so a
    /// reconnect joins as presenter.
    pub fn took_over(&mut self) {
        if let Some(seat) = self.demo.as_mut() {
            seat.present = true;
        }
    }

    fn send(&mut self, message: &ClientMessage) {
        self.transport.send(codec::encode_control(message));
    }

    /// The request-to-arrival times of pages asked for (not page 0 nor
    /// pushes, which nobody asked for) since the last call, oldest first;
    /// at most the latest [`LATENCY_SAMPLES`]. A load test takes them every
    /// tick; a viewer may never.
    pub fn take_latencies(&mut self) -> Vec<Duration> {
        self.latencies.drain(..).collect()
    }

    /// Pages given up on (repeated checksum failures, or the server cannot
    /// send them), by page index, with the last reason of each.
    pub fn failed_pages(&self) -> Vec<FailedPage> {
        let mut failed: Vec<FailedPage> = self
            .failures
            .iter()
            .filter(|&(&page, _)| self.gave_up(page))
            .map(|(&page, (_, reason))| FailedPage {
                page,
                reason: reason.clone(),
            })
            .collect();
        failed.sort_unstable_by_key(|f| f.page);
        failed
    }

    /// Whether `page` was given up on: it is not asked for again.
    pub fn gave_up(&self, page: u32) -> bool {
        self.failures
            .get(&page)
            .is_some_and(|&(count, _)| count >= MAX_PAGE_FAILURES)
    }
}
