//! One load client: a real client without a GPU.
//!
//! Its own [`Viewer`] (resident pages, LRU, verification) over its own
//! [`Session`](farfield_net::Session) (hello, requests, cancels,
//! acknowledgements, reconnects), traversed by the scene kind's own
//! traversal ([`traverse_frame`]) a few times a second; only the draw is
//! left out. Clients are tasks on a few threads, so a thousand clients
//! need no thousand threads; their sockets are carried on a thread of
//! their own ([`carried`]), so a page is taken off its socket, and its
//! request-to-arrival time measured, when it comes, not when its client's
//! thread is done traversing for the others.
//!
//! A client first holds its path's start camera until the view is
//! refined (or for [`LoadJob::hold`]), as a user who opens a model and
//! looks; then flies its path back and forth, starting at its own phase
//! so the clients do not all look at the same place.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, AtomicI64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use farfield_client::demo_link::DemoLink;
use farfield_client::frame_loop::{FrameState, traverse_frame};
use farfield_client::path::CameraPath;
use farfield_client::viewer::Viewer;
use farfield_net::queue::QueueTransport;
use farfield_net::websocket::{carry_wire, drive_wire};
use farfield_net::{NetStats, SessionOptions};
use farfield_protocol::camera::Camera;
use serde::{Deserialize, Serialize};

use super::LoadJob;
use super::recorder::{Recorder, Tick};
use super::static_files::{FileServer, drive_static};

/// What every client shares.
#[derive(Debug)]
pub struct Shared {
    /// The runtime that carries every client's socket ([`carried`]).
    pub io: tokio::runtime::Handle,
    pub job: LoadJob,
    pub path: CameraPath,
    pub recorder: Recorder,
    pub stop: AtomicBool,
    /// Clients whose session is up now.
    pub connected: AtomicI64,
    pub started: Instant,
    /// A demo presenter's latest views (the eye's bits) and when each
    /// was shown, for the followers' lag.
    pub shown: Mutex<VecDeque<([u64; 3], Instant)>>,
}

/// Views remembered for the followers' lag.
const SHOWN_KEPT: usize = 1024;

fn eye_bits(eye: [f64; 3]) -> [u64; 3] {
    eye.map(f64::to_bits)
}

/// One client's figures, a row of `clients.csv`.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct ClientRow {
    pub client: usize,
    /// Seconds after the run began that this client started.
    pub started_s: f64,
    /// From its start to the first traversal that drew something.
    pub first_image_ms: Option<f64>,
    /// From its start to a view with nothing missing at the start camera.
    pub refined_ms: Option<f64>,
    pub pages: u64,
    pub bytes: u64,
    pub errors: u64,
    pub reconnects: u64,
    /// Sessions opened again after one ended with an error.
    pub restarts: u64,
    pub last_error: String,
}

/// Runs client `index` of `clients` until the run stops.
pub async fn run(index: usize, clients: usize, shared: Arc<Shared>) -> ClientRow {
    let job = &shared.job;
    let start_after = job.ramp.mul_f64(index as f64 / clients.max(1) as f64);
    let mut row = ClientRow {
        client: index,
        started_s: start_after.as_secs_f64(),
        ..ClientRow::default()
    };
    while shared.started.elapsed() < start_after {
        if shared.stop.load(Ordering::Relaxed) {
            return row;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let files = if job.static_files {
        match FileServer::resolve(&job.server).await {
            Ok(files) => Some(files),
            Err(e) => {
                row.errors += 1;
                row.last_error = format!("{e:#}");
                return row;
            }
        }
    } else {
        None
    };
    let phase = shared.path.duration() * index as f64 / clients.max(1) as f64;
    let mut client = Client::new(phase);
    while !shared.stop.load(Ordering::Relaxed) {
        let (wire, mut viewer) = connect(job, job.push, job.client_cache_bytes);
        client.seen = NetStats::default();
        client.last_frame = None;
        client.demo = job
            .session
            .as_deref()
            .and_then(|name| DemoLink::join(&mut viewer, name, index == 0));
        let step = || client.step(&mut viewer, &shared, &mut row);
        let ended = match &files {
            Some(files) => drive_static(&wire, files, &job.scene, step).await,
            None => carried(&shared.io, &wire, step).await,
        };
        client.set_connected(false, &shared);
        let Err(e) = ended else { break };
        // The session ended (refused, unreachable, a fatal server error):
        // counted, and opened again after a second, as a user reloads.
        row.errors += 1;
        row.last_error = format!("{e:#}");
        shared.recorder.record(&Tick {
            errors: 1,
            ..Tick::default()
        });
        row.restarts += 1;
        for _ in 0..20 {
            if shared.stop.load(Ordering::Relaxed) {
                break;
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    }
    row
}

/// Steps a client while its connection is carried on the socket runtime
/// `io` ([`carry_wire`]): frames come off the socket, stamped, when they
/// arrive, and requests go out when made, however long a traversal keeps
/// this thread. Steps again when something arrived, or after [`TICK`].
async fn carried<E>(
    io: &tokio::runtime::Handle,
    wire: &QueueTransport,
    mut step: impl FnMut() -> Result<bool, E>,
) -> Result<(), E> {
    let carrier = io.spawn(carry_wire(wire.clone()));
    let result = loop {
        match step() {
            Ok(true) => {}
            Ok(false) => break Ok(()),
            Err(e) => break Err(e),
        }
        tokio::select! {
            () = wire.incoming_ready() => {}
            () = tokio::time::sleep(TICK) => {}
        }
    };
    wire.finish();
    if let Err(e) = carrier.await {
        tracing::warn!("a load client's socket task ended badly: {e}");
    }
    result
}

/// How long a client waits for news before it steps anyway (its
/// traversals have their own rate).
const TICK: Duration = Duration::from_millis(20);

/// A viewer of the job's scene over a fresh queue, holding at most
/// `cache_bytes` of pages, connecting now (the queue's owner drives it).
fn connect(job: &LoadJob, push: bool, cache_bytes: usize) -> (QueueTransport, Viewer) {
    let wire = QueueTransport::default();
    let options = SessionOptions {
        token: job.token.clone(),
        allow_push: push,
        max_outstanding: job.max_outstanding,
        ..SessionOptions::default()
    };
    let viewer = Viewer::over(
        Box::new(wire.clone()),
        &job.server,
        &job.scene,
        options,
        cache_bytes,
    );
    (wire, viewer)
}

/// The demo session's lag probe: a follower that only listens (no
/// traversal, no pages beyond the first), alone on its own thread, so the
/// lag it sees is the server's fan-out and the socket's, not the wait for
/// a turn on a core the load clients keep busy. Its lags are reported
/// beside the followers'; it is not one of the clients.
pub async fn probe(shared: Arc<Shared>) {
    let job = &shared.job;
    let Some(name) = job.session.clone() else {
        return;
    };
    let mut last_seq = 0;
    while !shared.stop.load(Ordering::Relaxed) {
        let (wire, mut viewer) = connect(job, false, 1 << 20);
        let Some(mut link) = DemoLink::join(&mut viewer, &name, false) else {
            return;
        };
        let step = || -> anyhow::Result<bool> {
            viewer.pump(Duration::ZERO)?;
            link.update(&mut viewer);
            if let Some((seq, view, arrived)) = &link.latest
                && *seq != last_seq
            {
                last_seq = *seq;
                let key = eye_bits(view.eye);
                let shown = shared.shown.lock().unwrap_or_else(|e| e.into_inner());
                if let Some((_, at)) = shown.iter().rev().find(|(k, _)| *k == key) {
                    shared.recorder.record(&Tick {
                        probe_lags: vec![arrived.saturating_duration_since(*at)],
                        ..Tick::default()
                    });
                }
            }
            // Refused before the presenter made the session: joined again.
            Ok(link.closed.is_none() && !shared.stop.load(Ordering::Relaxed))
        };
        let _ = drive_wire(&wire, step).await;
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
}

/// A client's state between steps.
#[derive(Debug)]
struct Client {
    started: Instant,
    /// Seconds into the path this client starts flying at.
    phase: f64,
    cut: FrameState,
    next_frame: Instant,
    /// When it began to fly (after the hold).
    flying_since: Option<Instant>,
    /// The session's counters at the last step.
    seen: NetStats,
    connected: bool,
    /// In a demo session: client 0 presents, the others follow.
    demo: Option<DemoLink>,
    /// The presenter's last view this follower saw.
    last_seq: u64,
    /// When a follower refused (its session not made yet) asks again.
    rejoin_at: Option<Instant>,
    /// The last traversal's camera and the pages received by then.
    last_frame: Option<(Camera, u64)>,
}

impl Client {
    fn new(phase: f64) -> Self {
        let now = Instant::now();
        Self {
            started: now,
            phase,
            cut: FrameState::default(),
            next_frame: now,
            flying_since: None,
            seen: NetStats::default(),
            connected: false,
            demo: None,
            last_seq: 0,
            rejoin_at: None,
            last_frame: None,
        }
    }

    /// Takes a demo session's news: a follower's lag for a new view, and
    /// a refused follower's next try (the presenter may not have made the
    /// session yet).
    fn follow(&mut self, viewer: &mut Viewer, shared: &Shared, lags: &mut Vec<Duration>) {
        let Some(link) = self.demo.as_mut() else {
            return;
        };
        link.update(viewer);
        if let Some((seq, view, arrived)) = &link.latest
            && *seq != self.last_seq
        {
            self.last_seq = *seq;
            let key = eye_bits(view.eye);
            let shown = shared.shown.lock().unwrap_or_else(|e| e.into_inner());
            if let Some((_, at)) = shown.iter().rev().find(|(k, _)| *k == key) {
                lags.push(arrived.saturating_duration_since(*at));
            }
        }
        if link.closed.is_some() {
            let now = Instant::now();
            match self.rejoin_at {
                None => self.rejoin_at = Some(now + Duration::from_millis(200)),
                Some(at) if now >= at => {
                    self.rejoin_at = None;
                    let name = link.name.clone();
                    self.demo = DemoLink::join(viewer, &name, false);
                }
                Some(_) => {}
            }
        }
    }

    fn set_connected(&mut self, now: bool, shared: &Shared) {
        if now != self.connected {
            self.connected = now;
            shared
                .connected
                .fetch_add(if now { 1 } else { -1 }, Ordering::Relaxed);
        }
    }

    /// Takes what arrived, traverses when a frame is due, reports.
    fn step(
        &mut self,
        viewer: &mut Viewer,
        shared: &Shared,
        row: &mut ClientRow,
    ) -> anyhow::Result<bool> {
        viewer.pump(Duration::ZERO)?;
        self.set_connected(viewer.is_connected(), shared);
        let mut lags = Vec::new();
        self.follow(viewer, shared, &mut lags);
        let job = &shared.job;
        let now = Instant::now();
        if now >= self.next_frame {
            self.next_frame = now + job.frame_interval();
            self.frame(viewer, shared, row, now)?;
        }
        let latencies = viewer.take_latencies();
        let stats = viewer.stats();
        let gave_up = viewer.failed_pages().len() as u64;
        let tick = Tick {
            latencies,
            pages: stats.pages_received - self.seen.pages_received,
            bytes: stats.bytes_received - self.seen.bytes_received,
            // A lost connection, and a page given up on, are errors even
            // when the session recovers.
            errors: (stats.disconnects - self.seen.disconnects)
                + gave_up.saturating_sub(self.seen.pages_unavailable),
            reconnects: stats.reconnects - self.seen.reconnects,
            lags,
            probe_lags: Vec::new(),
        };
        self.seen = NetStats {
            pages_unavailable: gave_up,
            ..viewer.stats().clone()
        };
        row.pages += tick.pages;
        row.bytes += tick.bytes;
        row.errors += tick.errors;
        row.reconnects += tick.reconnects;
        if tick.errors > 0
            && let Some(e) = &viewer.stats().last_error
        {
            row.last_error.clone_from(e);
        }
        shared.recorder.record(&tick);
        Ok(!shared.stop.load(Ordering::Relaxed))
    }

    /// One traversal at this moment's camera, once page 0 is resident.
    fn frame(
        &mut self,
        viewer: &mut Viewer,
        shared: &Shared,
        row: &mut ClientRow,
        now: Instant,
    ) -> anyhow::Result<()> {
        let job = &shared.job;
        let Some(header) = viewer.header().cloned() else {
            return Ok(());
        };
        if !viewer.hierarchy().is_some_and(|h| h.is_resident(0)) {
            return Ok(());
        }
        let since_start = now - self.started;
        if self.flying_since.is_none() && since_start >= job.hold() {
            self.flying_since = Some(now);
        }
        let t = match self.flying_since {
            None => self.phase,
            Some(since) => ping_pong(
                self.phase + (now - since).as_secs_f64(),
                shared.path.duration(),
            ),
        };
        let own = shared.path.camera_at(t, &header, job.width, job.height);
        let camera = match self.demo.as_mut() {
            Some(link) if link.is_presenting() => {
                link.show(viewer, &own, Vec::new());
                let mut shown = shared.shown.lock().unwrap_or_else(|e| e.into_inner());
                let key = eye_bits(own.eye.to_array());
                if shown.back().is_none_or(|(k, _)| *k != key) {
                    if shown.len() >= SHOWN_KEPT {
                        shown.pop_front();
                    }
                    shown.push_back((key, Instant::now()));
                }
                own
            }
            // A follower draws the presenter's view once one came.
            Some(link) => link.camera(job.width, job.height).unwrap_or(own),
            None => own,
        };
        // As a viewer at rest draws nothing new: the same camera over the
        // same pages gives the same cut and asks for nothing new.
        let received = viewer.stats().pages_received;
        if self.last_frame == Some((camera, received)) {
            return Ok(());
        }
        self.last_frame = Some((camera, received));
        traverse_frame(viewer, &camera, job.threshold_px, 1, &mut self.cut)?;
        let ms = since_start.as_secs_f64() * 1e3;
        if row.first_image_ms.is_none() && self.cut.drawn() > 0 {
            row.first_image_ms = Some(ms);
        }
        if self.flying_since.is_none()
            && row.refined_ms.is_none()
            && self.cut.missing(viewer) == 0
            && viewer.outstanding() == 0
        {
            row.refined_ms = Some(ms);
            self.flying_since = Some(now);
        }
        Ok(())
    }
}

/// `t` folded into `0..=length`, back and forth, so a path flown past its
/// end turns round instead of jumping to its start.
fn ping_pong(t: f64, length: f64) -> f64 {
    if !length.is_finite() || length <= 0.0 || !t.is_finite() {
        return 0.0;
    }
    let period = 2.0 * length;
    let u = t.rem_euclid(period);
    if u <= length { u } else { period - u }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_path_is_flown_back_and_forth() {
        assert_eq!(ping_pong(3.0, 10.0), 3.0);
        assert_eq!(ping_pong(13.0, 10.0), 7.0);
        assert_eq!(ping_pong(23.0, 10.0), 3.0);
        assert_eq!(ping_pong(5.0, 0.0), 0.0, "a path of one keyframe");
        assert_eq!(ping_pong(f64::NAN, 10.0), 0.0);
    }
}
