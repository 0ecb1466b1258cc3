//! One websocket session, exactly as `protocol/src/messages.rs` describes:
//! the client's hello (or a fatal error for another protocol version), the
//! server's hello, the scene header and page 0, then requests, cancels and
//! acknowledgements answered by pages in priority order.
//!
//! The socket is split: a reader applies client messages to the shared
//! [`Schedule`] and wakes the writer, and the writer sends whatever the
//! schedule allows. Both run concurrently in the session's task, so a
//! client that reads slowly (the writer waits on the socket) still has its
//! cancels and acknowledgements read at once, and nothing one session does
//! waits on another. A frame that breaks the protocol ends only its own
//! session, with a close frame that says why.

use std::collections::VecDeque;
use std::net::SocketAddr;
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use axum::body::Bytes;
use axum::extract::ws::{CloseFrame, Message, WebSocket};
use farfield_protocol::codec::{decode_control, encode_control, frame_kind};
use farfield_protocol::messages::{ClientMessage, FrameKind, PROTOCOL_VERSION, ServerMessage};
use farfield_store::PageError;
use futures_util::stream::{SplitSink, SplitStream};
use futures_util::{SinkExt, StreamExt};
use tokio::sync::{Notify, watch};

use super::AppState;
use super::catalog::ServedScene;
use super::demo::{DemoSessions, Mailbox, Seat};
use super::limits::{Limit, RateLimiter};
use super::metrics::Metrics;
use super::schedule::{PAGE_ZERO_PRIORITY, Schedule};

/// How long a closing session waits for its last frames to go out.
const CLOSE_GRACE: Duration = Duration::from_secs(2);

/// Close codes (RFC 6455, section 7.4.1).
const CLOSE_GOING_AWAY: u16 = 1001;
const CLOSE_PROTOCOL: u16 = 1002;
const CLOSE_UNSUPPORTED: u16 = 1003;
const CLOSE_POLICY: u16 = 1008;
const CLOSE_TOO_BIG: u16 = 1009;

/// Most bytes of control replies (errors) a session keeps waiting for a
/// client that does not read them; past it the session is closed
/// ([`CLOSE_POLICY`]), so a client that asks and never reads costs a
/// bounded amount.
pub const MAX_OUTBOX_BYTES: usize = 1 << 20;
/// How soon a page that could not be read for now (its store is down or
/// slow) is tried again; the store's own back-off makes a retry against a
/// store still down cost nothing.
pub const RETRY_UNAVAILABLE: Duration = Duration::from_millis(500);

type Sink = SplitSink<WebSocket, Message>;
type Stream = SplitStream<WebSocket>;

/// Why a session ended (for the log and the close frame).
#[derive(Debug, Clone, PartialEq)]
enum End {
    /// The client closed, or the connection dropped.
    ClientGone,
    /// The client broke the protocol; close with this code and reason.
    Malformed(u16, String),
    /// The client ran into a limit; close with this code and reason.
    Limited(Limit, u16, String),
    /// A fatal error already sent; close with this reason.
    Fatal(String),
    /// The scene was taken out of service (its file changed); the client is
    /// told why, and that the server goes on.
    Retired(String),
    ShuttingDown,
}

/// Counts a session as connected for as long as it lives.
struct Connected<'a>(&'a AppState);

impl<'a> Connected<'a> {
    fn new(app: &'a AppState) -> Self {
        Metrics::add(&app.metrics.connections_total, 1);
        app.metrics.connected_clients.fetch_add(1, Ordering::SeqCst);
        Self(app)
    }
}

impl Drop for Connected<'_> {
    fn drop(&mut self) {
        self.0
            .metrics
            .connected_clients
            .fetch_sub(1, Ordering::SeqCst);
        self.0.session_ended.notify_waiters();
    }
}

/// What the reader and the writer share.
#[derive(Debug)]
struct Shared {
    state: Mutex<State>,
    /// Wakes the writer: the reader applied a message, or a demo session
    /// posted into `mailbox`.
    wake: Arc<Notify>,
    mailbox: Arc<Mailbox>,
    /// This connection's id as a demo-session member.
    member: u64,
}

#[derive(Debug)]
struct State {
    schedule: Schedule,
    /// Control frames to send before any page, and their bytes: at most
    /// `outbox_limit`, [`MAX_OUTBOX_BYTES`] beyond the hello and header.
    outbox: VecDeque<Bytes>,
    outbox_bytes: usize,
    outbox_limit: usize,
    /// Set by the reader when the session must end.
    ending: Option<End>,
    stats: Stats,
    /// The demo session this connection is in.
    seat: Option<Seat>,
    /// Whether the client was told that pages are unavailable for now (once
    /// per outage: cleared when a page is served again).
    told_unavailable: bool,
}

#[derive(Debug, Default, Clone, Copy)]
struct Stats {
    pages: u64,
    bytes: u64,
    pushed: u64,
    corrupt: u64,
    requested: u64,
    cancelled: u64,
}

impl State {
    /// Queues a control reply, or says how the session must end when the
    /// client has left [`MAX_OUTBOX_BYTES`] of them unread.
    fn queue_control(&mut self, message: &ServerMessage) -> Result<(), End> {
        let frame = Bytes::from(encode_control(message));
        if self.outbox_bytes + frame.len() > self.outbox_limit {
            return Err(End::Limited(
                Limit::UnreadReplies,
                CLOSE_POLICY,
                format!(
                    "the client leaves its replies unread ({} KiB of them wait)",
                    MAX_OUTBOX_BYTES >> 10
                ),
            ));
        }
        self.outbox_bytes += frame.len();
        self.outbox.push_back(frame);
        Ok(())
    }

    /// The next control frame to send.
    fn next_control(&mut self) -> Option<Bytes> {
        let frame = self.outbox.pop_front()?;
        self.outbox_bytes = self.outbox_bytes.saturating_sub(frame.len());
        Some(frame)
    }
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn end(&self, end: End) {
        self.lock().ending.get_or_insert(end);
        self.wake.notify_one();
    }
}

fn control(message: &ServerMessage) -> Message {
    Message::Binary(Bytes::from(encode_control(message)))
}

fn error(message: String, fatal: bool) -> ServerMessage {
    ServerMessage::Error { message, fatal }
}

/// A close frame's reason may hold at most 123 bytes.
fn close_frame(code: u16, reason: &str) -> Message {
    let mut end = reason.len().min(123);
    while !reason.is_char_boundary(end) {
        end -= 1;
    }
    Message::Close(Some(CloseFrame {
        code,
        reason: reason[..end].into(),
    }))
}

/// Sends, giving up after [`CLOSE_GRACE`]: used where the session ends
/// anyway and a client that does not read must not hold it open.
async fn send_briefly(sink: &mut Sink, message: Message) {
    let _ = tokio::time::timeout(CLOSE_GRACE, sink.send(message)).await;
}

/// A client frame, sorted.
enum Frame {
    Binary(Bytes),
    /// A ping or a pong: the client is there, and says nothing.
    Alive,
    Bad(u16, String),
    TooBig(String),
    Gone,
    /// The connection ended without a closing handshake (the client closed
    /// TCP, or its machine reset it): an ordinary disconnect, counted as
    /// one, not as a protocol violation.
    Dropped,
}

async fn next_frame(stream: &mut Stream) -> Frame {
    match stream.next().await {
        Some(Ok(Message::Binary(b))) => Frame::Binary(b),
        Some(Ok(Message::Ping(_) | Message::Pong(_))) => Frame::Alive,
        Some(Ok(Message::Text(_))) => Frame::Bad(
            CLOSE_UNSUPPORTED,
            "text frame: this protocol speaks binary frames only".into(),
        ),
        Some(Ok(Message::Close(_))) | None => Frame::Gone,
        Some(Err(e)) => read_error(e),
    }
}

/// A failed read, sorted: the websocket layer refuses frames that break
/// RFC 6455 (unmasked, bad opcodes, bad UTF-8 in a close reason) and
/// messages past the size limit; everything else is the connection going.
fn read_error(error: axum::Error) -> Frame {
    use tungstenite::error::{CapacityError, Error as WsError};
    let inner = error.into_inner();
    match inner.downcast_ref::<WsError>() {
        Some(WsError::Capacity(CapacityError::MessageTooLong { size, max_size })) => {
            Frame::TooBig(format!("a {size}-byte message; the limit is {max_size}"))
        }
        Some(WsError::Capacity(e)) => Frame::TooBig(e.to_string()),
        Some(WsError::Protocol(
            tungstenite::error::ProtocolError::ResetWithoutClosingHandshake,
        )) => Frame::Dropped,
        Some(WsError::Protocol(e)) => Frame::Bad(CLOSE_PROTOCOL, format!("websocket: {e}")),
        Some(WsError::Utf8(e)) => Frame::Bad(1007, format!("websocket: {e}")),
        Some(WsError::Io(_) | WsError::ConnectionClosed | WsError::AlreadyClosed) => Frame::Dropped,
        _ => {
            tracing::debug!("websocket read failed: {inner}");
            Frame::Gone
        }
    }
}

/// Decodes a client control frame, or says why it is not one.
fn decode(frame: &[u8]) -> Result<ClientMessage, String> {
    match frame_kind(frame) {
        Ok((FrameKind::Page | FrameKind::Header, _)) => Err(
            "page frame (or header frame) from a client: clients send control messages only".into(),
        ),
        Ok((FrameKind::Control, _)) => {
            decode_control(frame).map_err(|e| format!("undecodable control message: {e}"))
        }
        Err(e) => Err(format!("bad frame: {e}")),
    }
}

async fn shutdown_signalled(rx: &mut watch::Receiver<bool>) {
    // A dropped sender means the server is gone: stop too.
    let _ = rx.wait_for(|&stop| stop).await;
}

/// Runs one session to its end.
pub(crate) async fn run(
    socket: WebSocket,
    scene: Arc<ServedScene>,
    app: Arc<AppState>,
    peer: SocketAddr,
) {
    let _connected = Connected::new(&app);
    let started = Instant::now();
    let (mut sink, mut stream) = socket.split();
    let mut shutdown = app.shutdown.clone();

    let first = tokio::select! {
        r = tokio::time::timeout(app.limits.hello_timeout, first_message(&mut stream)) => r,
        () = shutdown_signalled(&mut shutdown) => {
            send_briefly(&mut sink, close_frame(CLOSE_GOING_AWAY, "server shutting down")).await;
            return;
        }
    };
    let (window, allow_push) = match hello(first, &app) {
        Ok(h) => h,
        Err(end) => {
            finish(&mut sink, &end).await;
            tracing::info!(%peer, scene = %scene.name, "client refused: {}", describe(&end));
            return;
        }
    };
    tracing::info!(%peer, scene = %scene.name, window, allow_push, "client connected");

    let mut outbox = VecDeque::from([Bytes::from(encode_control(&ServerMessage::Hello {
        protocol_version: PROTOCOL_VERSION,
        server: format!("farfield-server {}", env!("CARGO_PKG_VERSION")),
    }))]);
    outbox.extend(scene.header_frames().iter().cloned());
    let first_bytes: usize = outbox.iter().map(Bytes::len).sum();
    let wake = Arc::new(Notify::new());
    let shared = Shared {
        state: Mutex::new(State {
            schedule: Schedule::new(window, allow_push, scene.id_count()),
            outbox,
            outbox_bytes: first_bytes,
            outbox_limit: first_bytes + MAX_OUTBOX_BYTES,
            ending: None,
            stats: Stats::default(),
            seat: None,
            told_unavailable: false,
        }),
        mailbox: Arc::new(Mailbox::new(wake.clone())),
        wake,
        member: app.demo.member_id(),
    };
    // The root directory page, then page 0 (which it places), go ahead of
    // anything the client can ask for: with the header, the first image.
    if scene.page_count() > 0 {
        let mut st = shared.lock();
        let now = Instant::now();
        for page in [scene.page_count(), 0] {
            st.schedule.request_raw(page, PAGE_ZERO_PRIORITY, now);
        }
        drop(st);
        app.metrics.queue_depth.fetch_add(2, Ordering::Relaxed);
        app.prefetch.hint(&scene, scene.child_pages(0));
    }

    let reader = read_loop(&mut stream, &shared, &scene, &app);
    let writer = write_loop(&mut sink, &shared, &scene, &app, shutdown);
    tokio::pin!(reader, writer);
    let end = tokio::select! {
        end = &mut writer => end,
        end = &mut reader => {
            shared.end(end.clone());
            // The writer sends the close frame (or flushes the reply to the
            // client's close) and stops.
            match tokio::time::timeout(CLOSE_GRACE * 2, &mut writer).await {
                Ok(end) => end,
                Err(_) => end,
            }
        }
    };

    let mut state = shared.lock();
    if let Some(seat) = state.seat.take() {
        DemoSessions::leave(&app.demo, &seat.name, shared.member);
    }
    let left = state.schedule.queued() as i64;
    app.metrics.queue_depth.fetch_sub(left, Ordering::Relaxed);
    let s = state.stats;
    tracing::info!(
        %peer,
        scene = %scene.name,
        pages = s.pages,
        bytes = s.bytes,
        pushed = s.pushed,
        requested = s.requested,
        cancelled = s.cancelled,
        corrupt = s.corrupt,
        seconds = started.elapsed().as_secs_f64(),
        "client disconnected: {}",
        describe(&end)
    );
}

fn describe(end: &End) -> String {
    match end {
        End::ClientGone => "closed by the client".into(),
        End::Malformed(_, reason) => format!("protocol violation: {reason}"),
        End::Limited(limit, _, reason) => format!("limit {}: {reason}", limit.name()),
        End::Fatal(reason) | End::Retired(reason) => reason.clone(),
        End::ShuttingDown => "server shutting down".into(),
    }
}

/// Checks the first frame; gives the window and push permission, or how the
/// session must end.
fn hello(
    first: Result<Frame, tokio::time::error::Elapsed>,
    app: &AppState,
) -> Result<(u64, bool), End> {
    let frame = match first {
        Ok(Frame::Binary(b)) => b,
        Ok(Frame::Alive) => unreachable!("first_message skips pings"),
        Ok(Frame::Gone) => return Err(End::ClientGone),
        Ok(Frame::Dropped) => {
            Metrics::add(&app.metrics.dropped_connections, 1);
            return Err(End::ClientGone);
        }
        Ok(other) => return Err(misbehaved(other, app)),
        Err(_) => {
            app.metrics.hit(Limit::HelloTimeout);
            return Err(End::Fatal(format!(
                "no Hello within {} s",
                app.limits.hello_timeout.as_secs_f64()
            )));
        }
    };
    match decode(&frame) {
        Ok(ClientMessage::Hello {
            protocol_version,
            max_in_flight_bytes,
            allow_push,
        }) => {
            if protocol_version == PROTOCOL_VERSION {
                Ok((max_in_flight_bytes, allow_push))
            } else {
                Err(End::Fatal(format!(
                    "protocol version mismatch: the client speaks version {protocol_version}, \
                     this server speaks version {PROTOCOL_VERSION}"
                )))
            }
        }
        Ok(other) => {
            Metrics::add(&app.metrics.malformed_frames, 1);
            Err(End::Malformed(
                CLOSE_PROTOCOL,
                format!("expected Hello first, got {}", message_name(&other)),
            ))
        }
        Err(reason) => {
            Metrics::add(&app.metrics.malformed_frames, 1);
            Err(End::Malformed(CLOSE_PROTOCOL, reason))
        }
    }
}

fn message_name(m: &ClientMessage) -> &'static str {
    match m {
        ClientMessage::Hello { .. } => "Hello",
        ClientMessage::Request { .. } => "Request",
        ClientMessage::Cancel { .. } => "Cancel",
        ClientMessage::Received { .. } => "Received",
        ClientMessage::Join { .. } => "Join",
        ClientMessage::View { .. } => "View",
        ClientMessage::HandOver { .. } => "HandOver",
        ClientMessage::Leave => "Leave",
    }
}

/// Says goodbye as `end` requires: a close frame with its code and reason,
/// after a fatal error message where there is one.
async fn finish(sink: &mut Sink, end: &End) {
    match end {
        End::ClientGone => {
            // Flushes the close reply the websocket layer queued.
            let _ = tokio::time::timeout(CLOSE_GRACE, sink.close()).await;
        }
        End::Malformed(code, reason) | End::Limited(_, code, reason) => {
            send_briefly(sink, close_frame(*code, reason)).await;
        }
        End::Fatal(reason) => {
            send_briefly(sink, control(&error(reason.clone(), true))).await;
            send_briefly(sink, close_frame(CLOSE_PROTOCOL, reason)).await;
        }
        End::Retired(reason) => {
            send_briefly(sink, control(&error(reason.clone(), true))).await;
            send_briefly(sink, close_frame(CLOSE_GOING_AWAY, reason)).await;
        }
        End::ShuttingDown => {
            send_briefly(sink, close_frame(CLOSE_GOING_AWAY, "server shutting down")).await;
        }
    }
}

/// The first frame that is not a ping or a pong.
async fn first_message(stream: &mut Stream) -> Frame {
    loop {
        match next_frame(stream).await {
            Frame::Alive => continue,
            other => return other,
        }
    }
}

/// How a session ends for a frame that breaks the protocol or a limit,
/// counted.
fn misbehaved(frame: Frame, app: &AppState) -> End {
    match frame {
        Frame::TooBig(reason) => {
            app.metrics.hit(Limit::MessageSize);
            End::Limited(Limit::MessageSize, CLOSE_TOO_BIG, reason)
        }
        Frame::Bad(code, reason) => {
            Metrics::add(&app.metrics.malformed_frames, 1);
            End::Malformed(code, reason)
        }
        Frame::Binary(_) | Frame::Alive => End::Malformed(CLOSE_PROTOCOL, "unexpected".into()),
        Frame::Gone => End::ClientGone,
        Frame::Dropped => {
            Metrics::add(&app.metrics.dropped_connections, 1);
            End::ClientGone
        }
    }
}

/// Reads client frames until the client leaves, breaks the protocol, goes
/// quiet for the idle timeout or sends faster than the rate limit.
async fn read_loop(
    stream: &mut Stream,
    shared: &Shared,
    scene: &Arc<ServedScene>,
    app: &AppState,
) -> End {
    let limits = &app.limits;
    let mut rate = RateLimiter::new(limits.max_messages_per_second, Instant::now());
    loop {
        let Ok(frame) = tokio::time::timeout(limits.idle_timeout, next_frame(stream)).await else {
            app.metrics.hit(Limit::IdleTimeout);
            return End::Limited(
                Limit::IdleTimeout,
                CLOSE_GOING_AWAY,
                format!(
                    "nothing from the client for {} s, not even a pong",
                    limits.idle_timeout.as_secs_f64()
                ),
            );
        };
        let over_rate = |rate: &mut RateLimiter| {
            let now = Instant::now();
            (!rate.take(now, app.lag.recent(now))).then(|| {
                app.metrics.hit(Limit::MessageRate);
                End::Limited(
                    Limit::MessageRate,
                    CLOSE_POLICY,
                    format!(
                        "more than {} messages a second",
                        limits.max_messages_per_second
                    ),
                )
            })
        };
        let frame = match frame {
            Frame::Binary(b) => b,
            Frame::Alive => match over_rate(&mut rate) {
                Some(end) => return end,
                None => continue,
            },
            Frame::Gone => return End::ClientGone,
            other => return misbehaved(other, app),
        };
        let message = match decode(&frame) {
            Ok(message) => message,
            Err(reason) => {
                Metrics::add(&app.metrics.malformed_frames, 1);
                return End::Malformed(CLOSE_PROTOCOL, reason);
            }
        };
        match apply(message, shared, scene, app) {
            // An acknowledgement of pages the server sent is an answer, not
            // a demand: as many as the server sends, and free. Everything
            // else counts against the rate.
            Ok(Applied::Acknowledged) => {}
            Ok(Applied::Counted) => {
                if let Some(end) = over_rate(&mut rate) {
                    return end;
                }
            }
            Err(end) => {
                match &end {
                    End::Malformed(..) => Metrics::add(&app.metrics.malformed_frames, 1),
                    End::Limited(limit, ..) => app.metrics.hit(*limit),
                    _ => {}
                }
                return end;
            }
        }
        shared.wake.notify_one();
    }
}

/// Applies one client message to the schedule; an error is how the
/// session must end.
/// What applying a message was, for the rate limit.
enum Applied {
    /// An acknowledgement of at least one page in flight.
    Acknowledged,
    Counted,
}

fn apply(
    message: ClientMessage,
    shared: &Shared,
    scene: &Arc<ServedScene>,
    app: &AppState,
) -> Result<Applied, End> {
    let now = Instant::now();
    let pages = scene.id_count();
    match message {
        ClientMessage::Hello { .. } => {
            return Err(End::Malformed(CLOSE_PROTOCOL, "Hello sent twice".into()));
        }
        ClientMessage::Request { pages: wishes } => {
            let mut out_of_range = Vec::new();
            let mut added = 0i64;
            let mut wanted = Vec::with_capacity(wishes.len());
            {
                let mut st = shared.lock();
                for w in &wishes {
                    if w.page >= pages {
                        out_of_range.push(w.page);
                        continue;
                    }
                    if st.schedule.request(w.page, w.priority, now) {
                        added += 1;
                    }
                    wanted.push(w.page);
                }
                st.stats.requested += added as u64;
                if !out_of_range.is_empty() {
                    let shown: Vec<String> = out_of_range
                        .iter()
                        .take(16)
                        .map(|p| p.to_string())
                        .collect();
                    let more = out_of_range.len().saturating_sub(16);
                    let message = format!(
                        "pages out of range (scene {:?} has {pages} pages): {}{}",
                        scene.name,
                        shown.join(", "),
                        if more > 0 {
                            format!(" and {more} more")
                        } else {
                            String::new()
                        }
                    );
                    st.queue_control(&error(message, false))?;
                }
            }
            app.metrics.queue_depth.fetch_add(added, Ordering::Relaxed);
            for page in wanted {
                app.prefetch.hint(scene, scene.child_pages(page));
            }
        }
        ClientMessage::Cancel { pages } => {
            let mut st = shared.lock();
            let removed = pages.iter().filter(|&&p| st.schedule.cancel(p)).count() as u64;
            st.stats.cancelled += removed;
            drop(st);
            Metrics::add(&app.metrics.pages_cancelled, removed);
            app.metrics
                .queue_depth
                .fetch_sub(removed as i64, Ordering::Relaxed);
        }
        ClientMessage::Received { pages } => {
            let mut st = shared.lock();
            let mut acknowledged = false;
            for p in pages {
                acknowledged |= st.schedule.received(p);
            }
            if acknowledged {
                return Ok(Applied::Acknowledged);
            }
        }
        ClientMessage::Join { session, present } => {
            let mut st = shared.lock();
            if let Some(seat) = st.seat.take() {
                DemoSessions::leave(&app.demo, &seat.name, shared.member);
            }
            match app.demo.join(
                &session,
                &scene.name,
                present,
                shared.member,
                &shared.mailbox,
            ) {
                Ok(seat) => {
                    tracing::info!(scene = %scene.name, session = %seat.name, present, member = shared.member, "joined a demo session");
                    st.seat = Some(seat);
                }
                // The name is quoted back cut short: it is the client's
                // own, of any length up to a control message's.
                Err(reason) => st.queue_control(&ServerMessage::SessionClosed {
                    session: super::quote::prefix(&session),
                    reason,
                })?,
            }
        }
        ClientMessage::View { view } => with_seat(&mut shared.lock(), |seat| {
            // Only a presenter's view is taken, and walked ahead of its motion.
            app.demo.view(&seat.name, shared.member, view.clone())?;
            app.lookahead.observe(&seat.name, scene, &view);
            Ok(())
        })?,
        ClientMessage::HandOver { to } => with_seat(&mut shared.lock(), |seat| {
            app.demo.hand_over(&seat.name, shared.member, to)
        })?,
        ClientMessage::Leave => {
            if let Some(seat) = shared.lock().seat.take() {
                DemoSessions::leave(&app.demo, &seat.name, shared.member);
            }
        }
    }
    Ok(Applied::Counted)
}

/// Does `f` with the connection's demo seat; why not (no seat, or what
/// `f` says) is a non-fatal error reply.
fn with_seat(st: &mut State, f: impl FnOnce(&Seat) -> Result<(), String>) -> Result<(), End> {
    let result = match &st.seat {
        Some(seat) => f(seat),
        None => Err("not in a demo session".into()),
    };
    match result {
        Ok(()) => Ok(()),
        Err(e) => st.queue_control(&error(e, false)),
    }
}

/// What the writer does next.
enum Action {
    Send(Bytes),
    Page(super::schedule::NextPage),
    End(End),
    Wait,
}

/// Offers the children of `page` (asked for with `priority`) for pushing,
/// each after the directory pages that place it, which the client needs
/// first to check it.
fn offer_children(schedule: &mut Schedule, scene: &ServedScene, page: u32, priority: f32) {
    let children = scene.child_pages(page);
    if children.is_empty() {
        return;
    }
    for end in [children.start, children.end - 1] {
        for directory in scene.directory_path(end) {
            if !schedule.was_sent(directory) {
                schedule.offer_push(directory..directory + 1, priority);
            }
        }
    }
    schedule.offer_push(children, priority);
}

/// Whether the client has been sent every directory page that places
/// `page` (a directory page places itself once its parent went).
fn places(schedule: &Schedule, scene: &ServedScene, page: u32) -> bool {
    if page >= scene.page_count() {
        return true;
    }
    scene
        .directory_path(page)
        .iter()
        .all(|&d| schedule.was_sent(d))
}

fn next_action(shared: &Shared, scene: &ServedScene, shutting_down: bool) -> Action {
    let mut st = shared.lock();
    if shutting_down {
        return Action::End(End::ShuttingDown);
    }
    if let Some(end) = st.ending.clone() {
        return Action::End(end);
    }
    if scene.is_retired() {
        return Action::End(retired(scene));
    }
    if let Some(frame) = st.next_control() {
        return Action::Send(frame);
    }
    // Demo-session news goes before pages: a follower's view must not
    // wait behind the pages of the last one.
    if let Some(frame) = shared.mailbox.take() {
        return Action::Send(frame);
    }
    st.schedule.retry_due(Instant::now());
    match st.schedule.next(|p| scene.page_len(p).unwrap_or(0)) {
        Some(next) => Action::Page(next),
        None => Action::Wait,
    }
}

/// Sleeps until `at`, or forever when there is no `at`.
async fn sleep_until(at: Option<Instant>) {
    match at {
        Some(at) => tokio::time::sleep_until(at.into()).await,
        None => std::future::pending().await,
    }
}

/// How a session on a retired scene ends.
fn retired(scene: &ServedScene) -> End {
    End::Retired(format!(
        "scene {:?} was taken out of service: {}",
        scene.name,
        scene.retired_reason().unwrap_or_default()
    ))
}

/// Sends what the schedule allows until the session ends.
async fn write_loop(
    sink: &mut Sink,
    shared: &Shared,
    scene: &Arc<ServedScene>,
    app: &Arc<AppState>,
    mut shutdown: watch::Receiver<bool>,
) -> End {
    let stall = app.limits.idle_timeout;
    // Often enough that a client that answers pings is never idle.
    let ping_every = stall / 3;
    loop {
        let shutting_down = *shutdown.borrow();
        let frame = match next_action(shared, scene, shutting_down) {
            Action::Wait => {
                // Frames are queued with `feed`; before sleeping, everything
                // queued goes out.
                if let Err(end) = write(sink.flush(), &mut shutdown, stall, app).await {
                    return end;
                }
                let retry = shared.lock().schedule.next_retry();
                let ping = tokio::select! {
                    () = shared.wake.notified() => false,
                    () = sleep_until(retry) => false,
                    () = shutdown_signalled(&mut shutdown) => false,
                    _ = scene.retired() => false,
                    () = tokio::time::sleep(ping_every) => true,
                };
                if ping {
                    let ping = sink.feed(Message::Ping(Bytes::new()));
                    if let Err(end) = write(ping, &mut shutdown, stall, app).await {
                        return end;
                    }
                }
                continue;
            }
            Action::End(end) => {
                finish(sink, &end).await;
                return end;
            }
            Action::Send(bytes) => bytes,
            Action::Page(next)
                if next.pushed && !places(&shared.lock().schedule, scene, next.page) =>
            {
                // Its directory page was not sent (cancelled, or out of
                // the pushes' order): the client could not check it.
                shared.lock().schedule.unsend(next.page);
                continue;
            }
            Action::Page(next) => {
                // Out of the queue now, even if this future is dropped below.
                if !next.pushed {
                    app.metrics.queue_depth.fetch_sub(1, Ordering::Relaxed);
                }
                let fetched = match app.cache.hit(scene, next.page, &app.metrics) {
                    Some(frame) => Ok(frame),
                    None => {
                        // A disk read may take a while: frames already
                        // queued go out first rather than wait for it.
                        if let Err(end) = write(sink.flush(), &mut shutdown, stall, app).await {
                            return end;
                        }
                        app.cache.miss(scene, next.page, &app.metrics).await
                    }
                };
                match fetched {
                    Ok(frame) => {
                        let page_bytes = frame.len().saturating_sub(1) as u64;
                        let mut st = shared.lock();
                        st.told_unavailable = false;
                        st.stats.pages += 1;
                        st.stats.bytes += page_bytes;
                        if let Some(seat) = &st.seat {
                            seat.bytes.fetch_add(page_bytes, Ordering::Relaxed);
                        }
                        if next.pushed {
                            st.stats.pushed += 1;
                        } else {
                            offer_children(&mut st.schedule, scene, next.page, next.priority);
                        }
                        drop(st);
                        Metrics::add(&app.metrics.pages_served, 1);
                        Metrics::add(&app.metrics.bytes_served, page_bytes);
                        if next.pushed {
                            Metrics::add(&app.metrics.pages_pushed, 1);
                        }
                        if let Some(since) = next.since {
                            app.metrics.latency.observe(since.elapsed());
                        }
                        frame
                    }
                    // Retired by the read: the next action ends the session.
                    Err(PageError::Changed(_)) => continue,
                    // The store is down or slow: the page stays wanted and
                    // is tried again; the client is told once per outage
                    // (and a push is simply dropped).
                    Err(PageError::Unavailable(why)) => {
                        let mut st = shared.lock();
                        if !next.pushed {
                            st.schedule.defer(&next, Instant::now() + RETRY_UNAVAILABLE);
                            app.metrics.queue_depth.fetch_add(1, Ordering::Relaxed);
                        } else {
                            st.schedule.unsend(next.page);
                        }
                        if std::mem::replace(&mut st.told_unavailable, true) {
                            continue;
                        }
                        drop(st);
                        Bytes::from(encode_control(&error(
                            format!(
                                "scene {:?}: pages are temporarily unavailable ({why}); retrying",
                                scene.name
                            ),
                            false,
                        )))
                    }
                    Err(e) => {
                        // The cache warned once, when it found the page bad.
                        tracing::debug!(scene = %scene.name, page = next.page, "not sent: {e}");
                        let mut st = shared.lock();
                        st.schedule.unsend(next.page);
                        st.stats.corrupt += 1;
                        drop(st);
                        Bytes::from(encode_control(&ServerMessage::PageUnavailable {
                            page: next.page,
                            reason: format!("scene {:?}: {e}", scene.name),
                        }))
                    }
                }
            }
        };
        // `feed` queues the frame (the websocket layer writes to the socket
        // once its buffer fills); the flush above sends the rest when the
        // schedule runs dry, so consecutive pages share system calls.
        let sent = sink.feed(Message::Binary(frame));
        if let Err(end) = write(sent, &mut shutdown, stall, app).await {
            return end;
        }
    }
}

/// Waits for a write to the socket (a `feed` or a `flush`): how the session
/// ends when the client is gone, takes no bytes for `stall`, or the server
/// shuts down first (a client that is not reading gets no goodbye then).
async fn write(
    op: impl Future<Output = Result<(), axum::Error>>,
    shutdown: &mut watch::Receiver<bool>,
    stall: Duration,
    app: &AppState,
) -> Result<(), End> {
    tokio::select! {
        r = tokio::time::timeout(stall, op) => match r {
            Ok(Ok(())) => Ok(()),
            Ok(Err(_)) => Err(End::ClientGone),
            Err(_) => {
                app.metrics.hit(Limit::IdleTimeout);
                Err(End::Limited(
                    Limit::IdleTimeout,
                    CLOSE_GOING_AWAY,
                    format!("the client took no bytes for {} s", stall.as_secs_f64()),
                ))
            }
        },
        () = shutdown_signalled(shutdown) => Err(End::ShuttingDown),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn close_reasons_are_cut_to_123_bytes_on_a_char_boundary() {
        let long = "é".repeat(100);
        let Message::Close(Some(frame)) = close_frame(CLOSE_PROTOCOL, &long) else {
            panic!("not a close frame");
        };
        assert!(frame.reason.as_str().len() <= 123);
        assert!(frame.reason.as_str().len() >= 121);
    }

    #[test]
    fn frames_are_sorted_with_reasons() {
        assert!(decode(&[]).unwrap_err().contains("empty"));
        assert!(decode(&[7]).unwrap_err().contains("unknown frame kind 7"));
        assert!(decode(&[1, 0, 0]).unwrap_err().contains("page frame"));
        assert!(decode(&[0, 255, 255]).unwrap_err().contains("undecodable"));
        let hello = encode_control(&ClientMessage::Hello {
            protocol_version: 1,
            max_in_flight_bytes: 1,
            allow_push: false,
        });
        assert!(matches!(decode(&hello), Ok(ClientMessage::Hello { .. })));
    }
}
