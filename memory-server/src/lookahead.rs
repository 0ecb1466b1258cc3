//! Read-ahead along a presenter's motion: when a demo session's presenter
//! moves, the server walks the scene for where the camera will be a moment
//! later (its motion extrapolated) and reads the pages that view needs into
//! the shared cache, before the presenter or any follower asks. A
//! follower, which trails the presenter, then finds them there; the
//! session costs the disk about one client, and reads happen ahead of need
//! rather than on it.
//!
//! The walk is the client's own traversal (`farfield-traverse`, the kind
//! the scene's header names) over a hierarchy of decoded pages this module
//! keeps per session, so the server asks for exactly what a client at that
//! camera would. One thread does every walk, fed by a bounded queue; each
//! session is walked at most every [`MIN_INTERVAL`], and a walk reads at
//! most [`MAX_PAGES_PER_PASS`] pages, so a presenter cannot make the server
//! read without bound.

use std::collections::HashMap;
use std::sync::mpsc::{Receiver, SyncSender, TrySendError, sync_channel};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use farfield_protocol::camera::Camera;
use farfield_protocol::hierarchy::Hierarchy;
use farfield_protocol::messages::SharedView;
use farfield_traverse::{Traversal, TraversalOptions, for_hierarchy};
use glam::DVec3;

use super::cache::{PageCache, Purpose};
use super::catalog::ServedScene;
use super::metrics::Metrics;

/// How far ahead the presenter's motion is extrapolated.
pub const HORIZON: Duration = Duration::from_millis(500);
/// Least time between two walks for one session.
pub const MIN_INTERVAL: Duration = Duration::from_millis(200);
/// Least time between two sightings a motion is measured over.
const MIN_SPAN: Duration = Duration::from_millis(40);
/// Most pages one walk reads.
pub const MAX_PAGES_PER_PASS: usize = 512;
/// Walks waiting for the thread.
const QUEUE: usize = 64;
/// Decoded pages kept per session; past this its hierarchy starts afresh
/// (its pages are still in the shared cache, so that costs no disk).
const HIERARCHY_BYTES: usize = 32 << 20;
/// Sessions whose hierarchies are kept; past this all start afresh.
const KEPT_SESSIONS: usize = 16;
/// The view walked when the presenter did not say its size.
const DEFAULT_SIZE: (u32, u32) = (1280, 720);

/// One walk: a session's extrapolated camera over its scene.
#[derive(Debug)]
struct Pass {
    session: String,
    scene: Arc<ServedScene>,
    camera: Camera,
    threshold_px: f64,
}

/// Where each presenter was last seen, to extrapolate from.
#[derive(Debug)]
struct Seen {
    at: Instant,
    eye: DVec3,
    target: DVec3,
    last_pass: Option<Instant>,
}

/// The handle sessions report presenters' views to; the thread stops when
/// it drops.
#[derive(Debug)]
pub struct Lookahead {
    tx: SyncSender<Pass>,
    seen: Mutex<HashMap<String, Seen>>,
    metrics: Arc<Metrics>,
}

impl Lookahead {
    pub fn start(cache: Arc<PageCache>, metrics: Arc<Metrics>) -> std::io::Result<Self> {
        let (tx, rx) = sync_channel::<Pass>(QUEUE);
        let worker_metrics = metrics.clone();
        std::thread::Builder::new()
            .name("farfield-lookahead".into())
            .spawn(move || worker(&rx, &cache, &worker_metrics))?;
        Ok(Self {
            tx,
            seen: Mutex::new(HashMap::new()),
            metrics,
        })
    }

    /// The presenter of `session` (on `scene`) shows `view` now. Queues a
    /// walk of where its camera will be [`HORIZON`] later, when it moves.
    pub fn observe(&self, session: &str, scene: &Arc<ServedScene>, view: &SharedView) {
        self.observe_at(Instant::now(), session, scene, view);
    }

    fn observe_at(&self, now: Instant, session: &str, scene: &Arc<ServedScene>, view: &SharedView) {
        let (eye, target) = (DVec3::from_array(view.eye), DVec3::from_array(view.target));
        let mut seen = self.seen.lock().unwrap_or_else(|e| e.into_inner());
        if seen.len() >= 4 * KEPT_SESSIONS && !seen.contains_key(session) {
            // Sessions come and go; forgetting them all costs one walk each.
            seen.clear();
        }
        let entry = seen.entry(session.to_owned()).or_insert(Seen {
            at: now,
            eye,
            target,
            last_pass: None,
        });
        if now.duration_since(entry.at) < MIN_SPAN {
            // Too close to the last sighting to tell the motion from the
            // jitter: kept until later views span enough time.
            return;
        }
        let ahead = extrapolate(entry, now, eye, target);
        *entry = Seen {
            at: now,
            eye,
            target,
            last_pass: entry.last_pass,
        };
        let Some((eye_ahead, target_ahead)) = ahead else {
            return;
        };
        if entry
            .last_pass
            .is_some_and(|t| now.duration_since(t) < MIN_INTERVAL)
        {
            return;
        }
        let (width, height) = view
            .option("size")
            .and_then(parse_size)
            .unwrap_or(DEFAULT_SIZE);
        let ahead_view = SharedView {
            eye: eye_ahead.to_array(),
            target: target_ahead.to_array(),
            ..view.clone()
        };
        let Some(camera) = ahead_view.camera(width, height) else {
            return;
        };
        let threshold_px = view
            .option("threshold")
            .and_then(|t| t.parse::<f64>().ok())
            .filter(|t| t.is_finite() && *t > 0.0)
            .unwrap_or(1.0);
        let pass = Pass {
            session: session.to_owned(),
            scene: scene.clone(),
            camera,
            threshold_px,
        };
        match self.tx.try_send(pass) {
            Ok(()) => entry.last_pass = Some(now),
            Err(TrySendError::Full(_)) => Metrics::add(&self.metrics.lookahead_dropped, 1),
            Err(TrySendError::Disconnected(_)) => {}
        }
    }
}

/// Where a camera last at `seen` and now at `eye`, `target` will be
/// [`HORIZON`] from now, moving as it did; `None` when it is at rest or
/// the two sightings are too close or too far apart in time to say.
fn extrapolate(seen: &Seen, now: Instant, eye: DVec3, target: DVec3) -> Option<(DVec3, DVec3)> {
    let dt = now.checked_duration_since(seen.at)?.as_secs_f64();
    if !(MIN_SPAN.as_secs_f64()..=1.0).contains(&dt) {
        return None;
    }
    let (eye_v, target_v) = ((eye - seen.eye) / dt, (target - seen.target) / dt);
    if eye_v == DVec3::ZERO && target_v == DVec3::ZERO {
        return None;
    }
    let h = HORIZON.as_secs_f64();
    let ahead = (eye + eye_v * h, target + target_v * h);
    (ahead.0.is_finite() && ahead.1.is_finite()).then_some(ahead)
}

/// `WxH`, each from 1 to 16384.
fn parse_size(text: &str) -> Option<(u32, u32)> {
    let (w, h) = text.split_once('x')?;
    let (w, h) = (w.trim().parse().ok()?, h.trim().parse().ok()?);
    ((1..=16384).contains(&w) && (1..=16384).contains(&h)).then_some((w, h))
}

/// A session's walk state: its scene's pages decoded so far.
struct Walker {
    scene_id: u32,
    hierarchy: Hierarchy,
    traversal: Box<dyn Traversal>,
}

fn worker(rx: &Receiver<Pass>, cache: &PageCache, metrics: &Metrics) {
    let mut walkers: HashMap<String, Walker> = HashMap::new();
    while let Ok(pass) = rx.recv() {
        if pass.scene.is_retired() {
            continue;
        }
        let fresh = walkers.get(&pass.session).is_none_or(|w| {
            w.scene_id != pass.scene.id || w.hierarchy.resident_bytes() > HIERARCHY_BYTES
        });
        if fresh {
            if walkers.len() >= KEPT_SESSIONS {
                walkers.clear();
            }
            let header = pass.scene.source.header().clone();
            let kind = header.kind;
            // The server holds the whole directory: the walk never waits
            // for a directory page.
            let directory = pass.scene.source.directory().clone();
            let Ok(hierarchy) = Hierarchy::with_directory(header, directory) else {
                continue;
            };
            walkers.insert(
                pass.session.clone(),
                Walker {
                    scene_id: pass.scene.id,
                    hierarchy,
                    traversal: for_hierarchy(kind),
                },
            );
        }
        let Some(walker) = walkers.get_mut(&pass.session) else {
            continue;
        };
        let loads = walk(walker, &pass, cache, metrics);
        Metrics::add(&metrics.lookahead_passes, 1);
        Metrics::add(&metrics.lookahead_loads, loads);
    }
}

/// Walks `pass`'s camera to the end (nothing more wanted) or to the page
/// bound, reading what it wants through the cache; the pages it read from
/// the disk.
fn walk(walker: &mut Walker, pass: &Pass, cache: &PageCache, metrics: &Metrics) -> u64 {
    let options = TraversalOptions {
        threshold_px: pass.threshold_px,
        ..TraversalOptions::default()
    };
    let (mut pages, mut loads) = (0, 0);
    let mut wanted: Vec<u32> = vec![0];
    while pages < MAX_PAGES_PER_PASS {
        wanted.retain(|&p| !walker.hierarchy.is_resident(p as usize));
        if wanted.is_empty() {
            walker
                .traversal
                .traverse(&walker.hierarchy, &pass.camera, &options);
            wanted = walker.traversal.wanted().iter().map(|w| w.page).collect();
            wanted.retain(|&p| !walker.hierarchy.is_resident(p as usize));
            if wanted.is_empty() {
                break;
            }
        }
        for page in std::mem::take(&mut wanted) {
            if pages >= MAX_PAGES_PER_PASS {
                break;
            }
            pages += 1;
            let frame = match cache.peek((pass.scene.id, page)) {
                Some(frame) => frame,
                None => match cache.read_through(&pass.scene, page, Purpose::Ahead, metrics) {
                    Ok(frame) => {
                        loads += 1;
                        frame
                    }
                    // A corrupt page is the sessions' to report; the walk
                    // goes on without it (never wanting it again this pass).
                    Err(_) => continue,
                },
            };
            if walker.hierarchy.insert_page(page, &frame[1..]).is_err() {
                continue;
            }
        }
    }
    loads
}

#[cfg(test)]
mod tests {
    use super::*;

    fn seen(eye: DVec3, target: DVec3, at: Instant) -> Seen {
        Seen {
            at,
            eye,
            target,
            last_pass: None,
        }
    }

    #[test]
    fn a_moving_camera_is_extrapolated_over_the_horizon_and_one_at_rest_is_not() {
        let t0 = Instant::now();
        let s = seen(DVec3::ZERO, DVec3::X, t0);
        // 1 unit in 100 ms: 10 units a second, 5 over the half-second horizon.
        let now = t0 + Duration::from_millis(100);
        let (eye, target) = extrapolate(&s, now, DVec3::Y, DVec3::X + DVec3::Y).unwrap();
        assert!((eye - DVec3::new(0.0, 6.0, 0.0)).length() < 1e-9, "{eye}");
        assert!(
            (target - DVec3::new(1.0, 6.0, 0.0)).length() < 1e-9,
            "{target}"
        );
        assert_eq!(extrapolate(&s, now, DVec3::ZERO, DVec3::X), None);
        // Sightings too close or too far apart say nothing of the motion.
        assert_eq!(extrapolate(&s, t0, DVec3::Y, DVec3::X), None);
        assert_eq!(
            extrapolate(&s, t0 + Duration::from_secs(2), DVec3::Y, DVec3::X),
            None
        );
    }

    #[test]
    fn sizes_parse_within_bounds() {
        assert_eq!(parse_size("800x600"), Some((800, 600)));
        assert_eq!(parse_size("0x600"), None);
        assert_eq!(parse_size("800"), None);
        assert_eq!(parse_size("99999x2"), None);
    }
}
