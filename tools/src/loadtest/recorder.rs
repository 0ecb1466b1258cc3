//! What the load clients report, summed over one second and over the run.
//!
//! Clients hand in a [`Tick`] after each step; the run's loop cuts the
//! current second off once a second ([`Recorder::cut`]). Latencies go into
//! HDR histograms (microseconds, three significant digits), so quantiles
//! cost a fixed few hundred KiB however many pages a run moves.

use std::sync::Mutex;
use std::time::Duration;

use hdrhistogram::Histogram;

/// Longest latency told apart: an hour, in microseconds (longer ones are
/// recorded as an hour).
const MAX_LATENCY_US: u64 = 3_600_000_000;

/// What one client saw since its last tick.
#[derive(Debug, Default)]
pub struct Tick {
    pub latencies: Vec<Duration>,
    pub pages: u64,
    pub bytes: u64,
    /// Connections lost, sessions that ended, pages given up.
    pub errors: u64,
    /// Connections opened again after one was lost.
    pub reconnects: u64,
    /// Demo followers: from the presenter showing a view to its arrival.
    pub lags: Vec<Duration>,
    /// The lag probe's: a follower alone on its own thread (see
    /// `client::probe`), so the server's fan-out is measured apart from
    /// the load clients' contention.
    pub probe_lags: Vec<Duration>,
}

impl Tick {
    fn is_empty(&self) -> bool {
        self.latencies.is_empty()
            && self.lags.is_empty()
            && self.probe_lags.is_empty()
            && self.pages == 0
            && self.bytes == 0
            && self.errors == 0
            && self.reconnects == 0
    }
}

/// Sums over a stretch of time.
#[derive(Debug, Clone)]
pub struct Interval {
    pub latency_us: Histogram<u64>,
    pub lag_us: Histogram<u64>,
    pub probe_lag_us: Histogram<u64>,
    pub pages: u64,
    pub bytes: u64,
    pub errors: u64,
    pub reconnects: u64,
}

impl Interval {
    fn new() -> Self {
        Self {
            latency_us: microseconds(),
            lag_us: microseconds(),
            probe_lag_us: microseconds(),
            pages: 0,
            bytes: 0,
            errors: 0,
            reconnects: 0,
        }
    }

    fn add(&mut self, tick: &Tick) {
        record(&mut self.latency_us, &tick.latencies);
        record(&mut self.lag_us, &tick.lags);
        record(&mut self.probe_lag_us, &tick.probe_lags);
        self.pages += tick.pages;
        self.bytes += tick.bytes;
        self.errors += tick.errors;
        self.reconnects += tick.reconnects;
    }

    /// The latency at quantile `q` (0..=1) in milliseconds; `None` when no
    /// page arrived.
    pub fn latency_ms(&self, q: f64) -> Option<f64> {
        (!self.latency_us.is_empty()).then(|| self.latency_us.value_at_quantile(q) as f64 / 1e3)
    }

    pub fn latency_max_ms(&self) -> Option<f64> {
        (!self.latency_us.is_empty()).then(|| self.latency_us.max() as f64 / 1e3)
    }

    /// A demo follower's lag at quantile `q`, in milliseconds.
    pub fn lag_ms(&self, q: f64) -> Option<f64> {
        quantile_ms(&self.lag_us, q)
    }

    pub fn probe_lag_ms(&self, q: f64) -> Option<f64> {
        quantile_ms(&self.probe_lag_us, q)
    }
}

/// An empty histogram of 1 µs to an hour at three significant digits.
fn quantile_ms(h: &Histogram<u64>, q: f64) -> Option<f64> {
    (!h.is_empty()).then(|| h.value_at_quantile(q) as f64 / 1e3)
}

fn microseconds() -> Histogram<u64> {
    // Constant bounds that new_with_bounds accepts (low >= 1, high >= 2 *
    // low, 3 digits within 0..=5): its error cannot happen here.
    Histogram::new_with_bounds(1, MAX_LATENCY_US, 3).expect("constant, valid histogram bounds")
}

fn record(h: &mut Histogram<u64>, values: &[Duration]) {
    for v in values {
        let us = u64::try_from(v.as_micros()).unwrap_or(u64::MAX);
        h.saturating_record(us.clamp(1, MAX_LATENCY_US));
    }
}

/// The clients' shared tally.
#[derive(Debug)]
pub struct Recorder {
    inner: Mutex<(Interval, Interval)>,
}

impl Default for Recorder {
    fn default() -> Self {
        Self {
            inner: Mutex::new((Interval::new(), Interval::new())),
        }
    }
}

impl Recorder {
    fn lock(&self) -> std::sync::MutexGuard<'_, (Interval, Interval)> {
        // Plain sums: a panic elsewhere cannot leave them inconsistent.
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Adds a client's tick to this second and to the run.
    pub fn record(&self, tick: &Tick) {
        if tick.is_empty() {
            return;
        }
        let mut inner = self.lock();
        inner.0.add(tick);
        inner.1.add(tick);
    }

    /// This second's sums, and a fresh second begun.
    pub fn cut(&self) -> Interval {
        let mut inner = self.lock();
        let second = inner.0.clone();
        inner.0.latency_us.reset();
        inner.0.lag_us.reset();
        inner.0.probe_lag_us.reset();
        (
            inner.0.pages,
            inner.0.bytes,
            inner.0.errors,
            inner.0.reconnects,
        ) = (0, 0, 0, 0);
        second
    }

    /// The whole run's sums.
    pub fn total(&self) -> Interval {
        self.lock().1.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seconds_are_cut_and_the_run_keeps_everything() {
        let r = Recorder::default();
        let ms = |v: &[u64]| v.iter().map(|&m| Duration::from_millis(m)).collect();
        r.record(&Tick {
            latencies: ms(&[1, 2, 3, 4, 100]),
            pages: 5,
            bytes: 500,
            errors: 1,
            reconnects: 0,
            lags: ms(&[20]),
            probe_lags: ms(&[7]),
        });
        let first = r.cut();
        assert_eq!((first.pages, first.bytes, first.errors), (5, 500, 1));
        assert!((19.9..=20.1).contains(&first.lag_ms(0.95).unwrap()));
        assert!((6.9..=7.1).contains(&first.probe_lag_ms(0.5).unwrap()));
        let p50 = first.latency_ms(0.5).unwrap();
        assert!((2.9..=3.1).contains(&p50), "{p50}");
        assert!((99.0..=100.1).contains(&first.latency_max_ms().unwrap()));
        r.record(&Tick {
            latencies: ms(&[10]),
            pages: 1,
            reconnects: 2,
            ..Tick::default()
        });
        let second = r.cut();
        assert_eq!((second.pages, second.errors, second.reconnects), (1, 0, 2));
        assert!((9.9..=10.1).contains(&second.latency_ms(0.99).unwrap()));
        assert!(second.lag_ms(0.5).is_none(), "cut with the second");
        assert!(second.probe_lag_ms(0.5).is_none(), "cut with the second");
        assert!(r.cut().latency_ms(0.5).is_none(), "nothing came since");
        let total = r.total();
        assert_eq!((total.pages, total.errors, total.reconnects), (6, 1, 2));
        assert_eq!(total.latency_us.len(), 6);
        // Beyond an hour is an hour, not an error.
        r.record(&Tick {
            latencies: vec![Duration::from_secs(7200)],
            ..Tick::default()
        });
        assert!(r.total().latency_max_ms().unwrap() <= 3.7e6);
    }
}
