//! One connection's send schedule: what the client wants, in what order,
//! and how much it may still receive before it acknowledges.
//!
//! Pure bookkeeping, no I/O, so the rules are unit-tested on their own:
//!
//! - wishes form a priority queue (larger first, ties in arrival order); a
//!   later request for a queued page updates its priority in place;
//! - a page leaves the queue when it is sent or cancelled;
//! - pages are handed out only while the bytes sent and not yet
//!   acknowledged stay under the client's window, so at most one page
//!   overshoots it;
//! - a page is sent again only when requested after the client
//!   acknowledged it (it lost or rejected it); a request for a page still
//!   in flight is already being answered and is ignored;
//! - when nothing is wanted and the client allowed pushes, children of
//!   pages it asked for are offered, highest parent priority first, never
//!   one it has, wants, or cancelled;
//! - a wanted page that could not be read for now (its store is down) is
//!   deferred: still wanted, it goes back in the queue once its retry time
//!   has come ([`Schedule::retry_due`]), unless cancelled meanwhile.

use std::cmp::Ordering;
use std::collections::hash_map::Entry;
use std::collections::{BinaryHeap, HashMap, HashSet};
use std::ops::Range;
use std::time::Instant;

/// The smallest and largest in-flight windows a client may choose.
pub const MIN_IN_FLIGHT_BYTES: u64 = 64 << 10;
pub const MAX_IN_FLIGHT_BYTES: u64 = 64 << 20;

/// Page 0 goes first, ahead of anything a client can ask for.
pub const PAGE_ZERO_PRIORITY: f32 = f32::INFINITY;

#[derive(Debug, Clone, Copy)]
struct Wish {
    priority: f32,
    seq: u64,
    since: Instant,
}

/// A heap entry; stale ones (whose wish changed or went) are skipped.
#[derive(Debug, Clone, Copy)]
struct Queued {
    priority: f32,
    seq: u64,
    page: u32,
}

impl PartialEq for Queued {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}
impl Eq for Queued {}
impl PartialOrd for Queued {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Queued {
    fn cmp(&self, other: &Self) -> Ordering {
        self.priority
            .total_cmp(&other.priority)
            .then_with(|| other.seq.cmp(&self.seq))
    }
}

/// What the writer should send next.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NextPage {
    pub page: u32,
    /// When the page became wanted (none for pushes).
    pub since: Option<Instant>,
    pub pushed: bool,
    /// The wish's priority, or for a push its parent's.
    pub priority: f32,
}

/// Per-connection queue, sent set and in-flight window.
#[derive(Debug)]
pub struct Schedule {
    wishes: HashMap<u32, Wish>,
    heap: BinaryHeap<Queued>,
    seq: u64,
    /// Pages sent on this connection, acknowledged or not.
    sent: HashSet<u32>,
    /// Sent and not yet acknowledged, with the bytes each holds.
    in_flight: HashMap<u32, u64>,
    in_flight_bytes: u64,
    window: u64,
    cancelled: HashSet<u32>,
    /// The scene's page count: the bound of every set above.
    pages: u32,
    allow_push: bool,
    push: BinaryHeap<Queued>,
    push_seen: HashSet<u32>,
    /// Wanted pages waiting to be tried again, by page: when, and the wish.
    deferred: HashMap<u32, (Instant, Wish)>,
}

impl Schedule {
    /// A schedule for a client that asked for `window` bytes in flight
    /// (clamped to [`MIN_IN_FLIGHT_BYTES`, `MAX_IN_FLIGHT_BYTES`]) of a
    /// scene of `pages` pages: no set it keeps holds a page past that, so a
    /// client naming arbitrary pages cannot grow it.
    pub fn new(window: u64, allow_push: bool, pages: u32) -> Self {
        Self {
            pages,
            wishes: HashMap::new(),
            heap: BinaryHeap::new(),
            seq: 0,
            sent: HashSet::new(),
            in_flight: HashMap::new(),
            in_flight_bytes: 0,
            window: window.clamp(MIN_IN_FLIGHT_BYTES, MAX_IN_FLIGHT_BYTES),
            cancelled: HashSet::new(),
            allow_push,
            push: BinaryHeap::new(),
            push_seen: HashSet::new(),
            deferred: HashMap::new(),
        }
    }

    pub fn window(&self) -> u64 {
        self.window
    }

    pub fn in_flight_bytes(&self) -> u64 {
        self.in_flight_bytes
    }

    /// Pages wanted and not yet sent (deferred ones among them).
    pub fn queued(&self) -> usize {
        self.wishes.len() + self.deferred.len()
    }

    fn next_seq(&mut self) -> u64 {
        self.seq += 1;
        self.seq
    }

    /// Adds or updates a wish. Returns whether the queue grew. NaN counts as
    /// the lowest priority; a client's infinities are kept finite so page 0
    /// stays first.
    pub fn request(&mut self, page: u32, priority: f32, now: Instant) -> bool {
        let priority = if priority.is_nan() {
            f32::MIN
        } else {
            priority.clamp(f32::MIN, f32::MAX)
        };
        self.request_raw(page, priority, now)
    }

    /// [`Schedule::request`] without the clamp (page 0 at infinity).
    pub fn request_raw(&mut self, page: u32, priority: f32, now: Instant) -> bool {
        if self.in_flight.contains_key(&page) {
            return false;
        }
        if let Some((_, wish)) = self.deferred.get_mut(&page) {
            // Still waiting for its retry: a new priority for when it comes.
            wish.priority = priority;
            return false;
        }
        self.cancelled.remove(&page);
        let seq = self.next_seq();
        let grew = match self.wishes.entry(page) {
            Entry::Occupied(mut e) => {
                let w = e.get_mut();
                if w.priority == priority {
                    return false;
                }
                w.priority = priority;
                w.seq = seq;
                false
            }
            Entry::Vacant(e) => {
                e.insert(Wish {
                    priority,
                    seq,
                    since: now,
                });
                true
            }
        };
        self.heap.push(Queued {
            priority,
            seq,
            page,
        });
        self.compact();
        grew
    }

    /// Drops a wish; returns whether one was queued. A cancelled page is
    /// never pushed until asked for again.
    pub fn cancel(&mut self, page: u32) -> bool {
        if page >= self.pages {
            return false;
        }
        self.cancelled.insert(page);
        self.wishes.remove(&page).is_some() | self.deferred.remove(&page).is_some()
    }

    /// The client has the page: its bytes leave the window.
    /// Whether `page` was in flight.
    pub fn received(&mut self, page: u32) -> bool {
        match self.in_flight.remove(&page) {
            Some(bytes) => {
                self.in_flight_bytes -= bytes;
                true
            }
            None => false,
        }
    }

    /// Offers `pages` (children of a page asked for with `priority`) for
    /// pushing when the connection is otherwise idle.
    pub fn offer_push(&mut self, pages: Range<u32>, priority: f32) {
        if !self.allow_push {
            return;
        }
        for page in pages {
            if self.push_seen.insert(page) {
                let seq = self.next_seq();
                self.push.push(Queued {
                    priority,
                    seq,
                    page,
                });
            }
        }
    }

    /// Whether the window has room for another page.
    pub fn window_open(&self) -> bool {
        self.in_flight_bytes < self.window
    }

    /// The next page to send, if the window has room: the highest wish, or,
    /// with an empty queue, a push. The page is counted as sent and in
    /// flight at once (`len(page)` gives its bytes).
    pub fn next(&mut self, len: impl Fn(u32) -> u64) -> Option<NextPage> {
        if !self.window_open() {
            return None;
        }
        while let Some(q) = self.heap.pop() {
            match self.wishes.get(&q.page) {
                Some(w) if w.seq == q.seq => {
                    let since = w.since;
                    self.wishes.remove(&q.page);
                    self.mark_sent(q.page, len(q.page));
                    return Some(NextPage {
                        page: q.page,
                        since: Some(since),
                        pushed: false,
                        priority: q.priority,
                    });
                }
                _ => continue,
            }
        }
        while let Some(q) = self.push.pop() {
            if self.sent.contains(&q.page)
                || self.cancelled.contains(&q.page)
                || self.wishes.contains_key(&q.page)
            {
                continue;
            }
            self.mark_sent(q.page, len(q.page));
            return Some(NextPage {
                page: q.page,
                since: None,
                pushed: true,
                priority: q.priority,
            });
        }
        None
    }

    fn mark_sent(&mut self, page: u32, bytes: u64) {
        self.sent.insert(page);
        *self.in_flight.entry(page).or_insert(0) += bytes;
        self.in_flight_bytes += bytes;
    }

    /// Takes back a page handed out by [`Schedule::next`] that could not be
    /// sent (it failed verification): it no longer counts as sent.
    pub fn unsend(&mut self, page: u32) {
        self.sent.remove(&page);
        self.received(page);
    }

    /// Takes back a wanted page handed out by [`Schedule::next`] that could
    /// not be read for now, to be queued again at `at` (with its priority
    /// and its first wish's time, so its latency counts the wait).
    pub fn defer(&mut self, next: &NextPage, at: Instant) {
        self.unsend(next.page);
        if let Some(since) = next.since {
            let wish = Wish {
                priority: next.priority,
                seq: 0,
                since,
            };
            self.deferred.insert(next.page, (at, wish));
        }
    }

    /// The earliest time a deferred page is due, if one is waiting.
    pub fn next_retry(&self) -> Option<Instant> {
        self.deferred.values().map(|&(at, _)| at).min()
    }

    /// Queues again the deferred pages whose time has come by `now`.
    pub fn retry_due(&mut self, now: Instant) {
        if self.next_retry().is_none_or(|at| at > now) {
            return;
        }
        let due: Vec<u32> = self
            .deferred
            .iter()
            .filter(|(_, (at, _))| *at <= now)
            .map(|(&page, _)| page)
            .collect();
        for page in due {
            if let Some((_, wish)) = self.deferred.remove(&page) {
                let seq = self.next_seq();
                self.wishes.insert(page, Wish { seq, ..wish });
                self.heap.push(Queued {
                    priority: wish.priority,
                    seq,
                    page,
                });
            }
        }
    }

    /// Whether `page` was ever sent on this connection.
    pub fn was_sent(&self, page: u32) -> bool {
        self.sent.contains(&page)
    }

    /// Rebuilds the heap when stale entries outnumber live ones, so a client
    /// that keeps re-prioritising cannot grow it without bound.
    fn compact(&mut self) {
        if self.heap.len() > 2 * self.wishes.len() + 64 {
            let live = self.wishes.iter().map(|(&page, w)| Queued {
                priority: w.priority,
                seq: w.seq,
                page,
            });
            self.heap = live.collect();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn drain(s: &mut Schedule) -> Vec<u32> {
        std::iter::from_fn(|| s.next(|_| 10).map(|n| n.page)).collect()
    }

    #[test]
    fn highest_priority_first_ties_in_order_and_updates_in_place() {
        let now = Instant::now();
        let mut s = Schedule::new(1 << 20, false, 1000);
        assert!(s.request(1, 1.0, now));
        assert!(s.request(2, 5.0, now));
        assert!(s.request(3, 1.0, now));
        assert!(s.request(4, f32::NAN, now));
        assert!(!s.request(1, 9.0, now), "an update does not grow the queue");
        assert_eq!(s.queued(), 4);
        assert_eq!(drain(&mut s), vec![1, 2, 3, 4]);
        assert_eq!(s.queued(), 0);
    }

    #[test]
    fn cancel_removes_and_blocks_pushes() {
        let now = Instant::now();
        let mut s = Schedule::new(1 << 20, true, 1000);
        s.request(1, 1.0, now);
        s.request(2, 2.0, now);
        assert!(s.cancel(2));
        assert!(!s.cancel(7));
        s.offer_push(6..9, 1.0);
        assert_eq!(drain(&mut s), vec![1, 6, 8], "7 was cancelled");
    }

    #[test]
    fn window_caps_bytes_in_flight_and_acks_reopen_it() {
        let now = Instant::now();
        let mut s = Schedule::new(0, false, 1000);
        assert_eq!(s.window(), MIN_IN_FLIGHT_BYTES);
        for p in 0..100 {
            s.request(p, 0.0, now);
        }
        let page = 10_000;
        let sent: Vec<u32> = std::iter::from_fn(|| s.next(|_| page).map(|n| n.page)).collect();
        assert_eq!(sent.len() as u64, MIN_IN_FLIGHT_BYTES.div_ceil(page));
        assert!(s.in_flight_bytes() < MIN_IN_FLIGHT_BYTES + page);
        s.received(sent[0]);
        s.received(sent[0]);
        assert!(s.next(|_| page).is_some());
        assert!(s.next(|_| page).is_none());
    }

    #[test]
    fn resend_only_after_acknowledgement() {
        let now = Instant::now();
        let mut s = Schedule::new(1 << 20, false, 1000);
        s.request(5, 1.0, now);
        assert_eq!(drain(&mut s), vec![5]);
        assert!(!s.request(5, 2.0, now), "still in flight: ignored");
        assert!(drain(&mut s).is_empty());
        s.received(5);
        assert!(s.request(5, 2.0, now), "acknowledged, asked again: lost");
        assert_eq!(drain(&mut s), vec![5]);
    }

    #[test]
    fn pushes_only_when_allowed_idle_and_new() {
        let now = Instant::now();
        let mut s = Schedule::new(1 << 20, false, 1000);
        s.offer_push(1..3, 1.0);
        assert!(drain(&mut s).is_empty(), "pushes not allowed");
        let mut s = Schedule::new(1 << 20, true, 1000);
        s.request(1, 1.0, now);
        s.offer_push(1..4, 1.0);
        s.offer_push(10..11, 5.0);
        let order: Vec<NextPage> = std::iter::from_fn(|| s.next(|_| 1)).collect();
        let pages: Vec<u32> = order.iter().map(|n| n.page).collect();
        assert_eq!(
            pages,
            vec![1, 10, 2, 3],
            "wish first, then by parent priority"
        );
        assert!(!order[0].pushed && order[1..].iter().all(|n| n.pushed));
        s.offer_push(1..4, 9.0);
        assert!(drain(&mut s).is_empty(), "never pushed twice");
    }

    #[test]
    fn reprioritising_forever_keeps_the_heap_bounded() {
        let now = Instant::now();
        let mut s = Schedule::new(1 << 20, false, 1000);
        for i in 0..10_000 {
            s.request(i % 3, i as f32, now);
        }
        assert!(s.heap.len() <= 2 * 3 + 65);
        assert_eq!(drain(&mut s).len(), 3);
    }

    #[test]
    fn unsend_forgets_a_page_that_failed() {
        let now = Instant::now();
        let mut s = Schedule::new(1 << 20, false, 1000);
        s.request(3, 1.0, now);
        assert_eq!(drain(&mut s), vec![3]);
        s.unsend(3);
        assert!(!s.was_sent(3));
        assert_eq!(s.in_flight_bytes(), 0);
        assert!(s.request(3, 1.0, now));
    }

    #[test]
    fn cancels_of_pages_the_scene_lacks_are_not_kept() {
        let mut s = Schedule::new(1 << 20, false, 10);
        for page in (10..100_000).chain([u32::MAX]) {
            assert!(!s.cancel(page));
        }
        assert!(s.cancelled.is_empty(), "{} kept", s.cancelled.len());
        assert!(s.request(3, 1.0, Instant::now()));
        assert!(s.cancel(3), "a page of the scene is still cancelled");
        assert_eq!(s.cancelled.len(), 1);
    }

    #[test]
    fn a_deferred_page_comes_back_when_due_unless_cancelled() {
        let t0 = Instant::now();
        let later = t0 + std::time::Duration::from_secs(1);
        let mut s = Schedule::new(1 << 20, false, 100);
        s.request(3, 2.0, t0);
        s.request(4, 1.0, t0);
        let next = s.next(|_| 10).unwrap();
        assert_eq!(next.page, 3);
        s.defer(&next, later);
        assert_eq!(s.queued(), 2, "still wanted");
        assert_eq!(s.in_flight_bytes(), 0);
        assert_eq!(s.next_retry(), Some(later));
        assert!(!s.request(3, 5.0, t0), "a new priority, not a second wish");
        s.retry_due(t0);
        assert_eq!(drain(&mut s), vec![4], "not due yet");
        s.retry_due(later);
        let again = s.next(|_| 10).unwrap();
        assert_eq!((again.page, again.priority), (3, 5.0));
        assert_eq!(again.since, Some(t0), "its wait counts from the first wish");
        s.defer(&again, later);
        assert!(s.cancel(3));
        assert_eq!((s.queued(), s.next_retry()), (0, None));
        s.retry_due(later);
        assert_eq!(drain(&mut s), Vec::<u32>::new());
    }
}
