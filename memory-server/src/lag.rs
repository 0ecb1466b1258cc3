//! How far behind the server's runtime is: the time a task that asked to
//! wake every [`TICK`] waited beyond it.
//!
//! The message-rate limit counts a client's messages when the server reads
//! them. Under CPU overload a session's reader is not run for a while, and
//! then reads at once what its client sent, at a steady pace, over that
//! while: counted at reading time it looks like a burst, and well-behaved
//! clients were closed for "more than 1000 messages a second". What a
//! client sent is what the limit is about, so the bucket may hold, beyond
//! its second's worth, what the client could have sent while the server
//! was not reading: [`Lag::recent`] says how long that was.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use tokio::sync::watch;

/// How often the runtime is sampled.
pub const TICK: Duration = Duration::from_millis(50);
/// Of the largest lag seen, the share kept from one tick to the next: it
/// halves in about 3.5 s, longer than a session takes to read a backlog.
const KEEP_PER_TICK: f64 = 0.99;

/// The runtime's recent lag, shared by every session.
#[derive(Debug)]
pub struct Lag {
    origin: Instant,
    /// When the ticker last ran, in microseconds after `origin`.
    last_tick_us: AtomicU64,
    /// The largest lag seen, decaying, in microseconds.
    recent_us: AtomicU64,
}

impl Lag {
    /// A lag meter with no lag yet, and no ticker ([`Lag::run`] is it).
    pub fn new() -> Arc<Self> {
        Arc::new(Self {
            origin: Instant::now(),
            last_tick_us: AtomicU64::new(0),
            recent_us: AtomicU64::new(0),
        })
    }

    fn micros_since_origin(&self, at: Instant) -> u64 {
        u64::try_from(at.saturating_duration_since(self.origin).as_micros()).unwrap_or(u64::MAX)
    }

    /// Ticks on the runtime until the server shuts down.
    pub async fn run(self: Arc<Self>, mut shutdown: watch::Receiver<bool>) {
        let mut expected = Instant::now() + TICK;
        loop {
            tokio::select! {
                () = tokio::time::sleep_until(expected.into()) => {}
                _ = shutdown.wait_for(|&stop| stop) => return,
            }
            let now = Instant::now();
            self.observe(now.saturating_duration_since(expected), now);
            expected = now + TICK;
        }
    }

    /// Records a tick at `now` that came `late`.
    fn observe(&self, late: Duration, now: Instant) {
        let late_us = u64::try_from(late.as_micros()).unwrap_or(u64::MAX);
        let kept = (self.recent_us.load(Ordering::Relaxed) as f64 * KEEP_PER_TICK) as u64;
        self.recent_us.store(kept.max(late_us), Ordering::Relaxed);
        self.last_tick_us
            .store(self.micros_since_origin(now), Ordering::Relaxed);
    }

    /// The runtime's recent lag at `now`: the largest seen lately, or, if
    /// the ticker itself has not run for longer (the runtime is stalled
    /// now, and a session runs before the ticker), how long it has not.
    pub fn recent(&self, now: Instant) -> Duration {
        let since_tick = self
            .micros_since_origin(now)
            .saturating_sub(self.last_tick_us.load(Ordering::Relaxed));
        let stalled = since_tick.saturating_sub(TICK.as_micros() as u64);
        Duration::from_micros(self.recent_us.load(Ordering::Relaxed).max(stalled))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_late_tick_is_remembered_and_fades() {
        let lag = Lag::new();
        let t0 = lag.origin;
        lag.observe(Duration::ZERO, t0);
        assert!(lag.recent(t0) < Duration::from_millis(1));
        lag.observe(Duration::from_secs(2), t0 + Duration::from_secs(2));
        let after = lag.recent(t0 + Duration::from_secs(2));
        assert!(after >= Duration::from_secs(2), "{after:?}");
        for i in 1..=200 {
            lag.observe(Duration::ZERO, t0 + Duration::from_secs(2) + TICK * i);
        }
        let faded = lag.recent(t0 + Duration::from_secs(2) + TICK * 200);
        assert!(faded < Duration::from_millis(500), "{faded:?}");
    }

    #[test]
    fn a_ticker_that_has_not_run_for_a_while_is_lag_now() {
        let lag = Lag::new();
        let t0 = lag.origin;
        lag.observe(Duration::ZERO, t0);
        let stalled = lag.recent(t0 + Duration::from_secs(3));
        assert!(stalled >= Duration::from_millis(2900), "{stalled:?}");
    }
}
