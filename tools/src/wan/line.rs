//! One direction of an emulated link, as `tc netem` models it: each packet
//! may be lost at random, waits its turn to be sent at the link's rate,
//! then travels for the one-way delay. Packets leave in the order they came
//! (a constant delay never reorders). At most `limit` packets are on the
//! line at once, queued or travelling (netem's `limit`); one more is
//! dropped, as a full router queue drops it.
//!
//! Pure: time is passed in, so the model is tested without a network.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// How a link behaves in one direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LineSpec {
    /// One-way delay (half the round trip).
    pub delay: Duration,
    /// Bits a second; unlimited when `None`.
    pub rate_bits_per_s: Option<u64>,
    /// The share of packets lost at random, 0 to 1.
    pub loss: f64,
    /// Most packets queued or travelling at once.
    pub limit: usize,
}

impl Default for LineSpec {
    fn default() -> Self {
        Self {
            delay: Duration::ZERO,
            rate_bits_per_s: None,
            loss: 0.0,
            // netem's default.
            limit: 1000,
        }
    }
}

/// What became of one packet.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fate {
    /// It arrives at the far end at this time.
    Arrives(Instant),
    /// Lost at random.
    Lost,
    /// Dropped: the line held `limit` packets already.
    Overflowed,
}

/// Counts of what the line did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct LineCounts {
    pub packets: u64,
    pub bytes: u64,
    pub lost: u64,
    pub overflowed: u64,
}

/// One direction's state.
#[derive(Debug)]
pub struct Line {
    spec: LineSpec,
    /// When the sender finishes putting the last accepted packet on the wire.
    free_at: Option<Instant>,
    /// Arrival times of the packets still on the line (oldest first).
    on_line: VecDeque<Instant>,
    rng: u64,
    counts: LineCounts,
}

impl Line {
    /// A line; `seed` makes its losses repeatable.
    pub fn new(spec: LineSpec, seed: u64) -> Self {
        Self {
            spec,
            free_at: None,
            on_line: VecDeque::new(),
            // xorshift's state may not be zero.
            rng: seed | 1,
            counts: LineCounts::default(),
        }
    }

    pub fn counts(&self) -> LineCounts {
        self.counts
    }

    /// A packet of `bytes` handed to the line at `now`.
    pub fn admit(&mut self, now: Instant, bytes: usize) -> Fate {
        while self.on_line.front().is_some_and(|&t| t <= now) {
            self.on_line.pop_front();
        }
        if self.spec.loss > 0.0 && self.uniform() < self.spec.loss {
            self.counts.lost += 1;
            return Fate::Lost;
        }
        if self.on_line.len() >= self.spec.limit {
            self.counts.overflowed += 1;
            return Fate::Overflowed;
        }
        let start = self.free_at.map_or(now, |free| free.max(now));
        let sent = start + self.serialization(bytes);
        self.free_at = Some(sent);
        let arrives = sent + self.spec.delay;
        self.on_line.push_back(arrives);
        self.counts.packets += 1;
        self.counts.bytes += bytes as u64;
        Fate::Arrives(arrives)
    }

    /// How long `bytes` take to put on the wire at the line's rate.
    fn serialization(&self, bytes: usize) -> Duration {
        match self.spec.rate_bits_per_s {
            Some(rate) if rate > 0 => Duration::from_secs_f64(bytes as f64 * 8.0 / rate as f64),
            _ => Duration::ZERO,
        }
    }

    /// A uniform number in [0, 1) (xorshift64*: fast, and enough for losses).
    fn uniform(&mut self) -> f64 {
        self.rng ^= self.rng >> 12;
        self.rng ^= self.rng << 25;
        self.rng ^= self.rng >> 27;
        let x = self.rng.wrapping_mul(0x2545_f491_4f6c_dd1d);
        (x >> 11) as f64 / (1u64 << 53) as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: Duration = Duration::from_millis(1);

    fn arrives(fate: Fate) -> Instant {
        match fate {
            Fate::Arrives(t) => t,
            other => panic!("expected an arrival, got {other:?}"),
        }
    }

    #[test]
    fn a_packet_arrives_after_the_delay_plus_its_time_on_the_wire() {
        let t0 = Instant::now();
        let mut line = Line::new(
            LineSpec {
                delay: 20 * MS,
                // 1500 bytes take 1.2 ms at 10 Mbit/s.
                rate_bits_per_s: Some(10_000_000),
                ..LineSpec::default()
            },
            7,
        );
        let a = arrives(line.admit(t0, 1500));
        assert_eq!(a - t0, Duration::from_micros(21_200));
        // A second one sent at once queues behind the first.
        let b = arrives(line.admit(t0, 1500));
        assert_eq!(b - t0, Duration::from_micros(22_400));
        // One sent long after finds the wire free.
        let later = t0 + Duration::from_secs(1);
        let c = arrives(line.admit(later, 1500));
        assert_eq!(c - later, Duration::from_micros(21_200));
        assert_eq!(line.counts().packets, 3);
        assert_eq!(line.counts().bytes, 4500);
    }

    #[test]
    fn a_saturated_line_carries_its_rate_and_no_more() {
        let t0 = Instant::now();
        let rate = 8_000_000; // a megabyte a second
        let mut line = Line::new(
            LineSpec {
                rate_bits_per_s: Some(rate),
                limit: usize::MAX,
                ..LineSpec::default()
            },
            7,
        );
        let mut last = t0;
        for _ in 0..1000 {
            last = arrives(line.admit(t0, 1000));
        }
        let seconds = (last - t0).as_secs_f64();
        assert!((seconds - 1.0).abs() < 1e-6, "{seconds} s for 1 MB");
    }

    #[test]
    fn losses_come_at_the_given_share_and_repeat_with_the_seed() {
        let spec = LineSpec {
            loss: 0.01,
            limit: usize::MAX,
            ..LineSpec::default()
        };
        let t0 = Instant::now();
        let run = |seed| {
            let mut line = Line::new(spec, seed);
            for _ in 0..100_000 {
                line.admit(t0, 100);
            }
            line.counts()
        };
        let counts = run(42);
        // 1000 expected; a binomial's sd here is about 31.
        assert!(
            (850..1150).contains(&counts.lost),
            "{} lost of 100000",
            counts.lost
        );
        assert_eq!(counts.packets + counts.lost, 100_000);
        assert_eq!(run(42), counts);
        assert_ne!(run(43).lost, 0);
    }

    #[test]
    fn a_full_line_drops_and_frees_room_as_packets_arrive() {
        let t0 = Instant::now();
        let mut line = Line::new(
            LineSpec {
                delay: 10 * MS,
                limit: 3,
                ..LineSpec::default()
            },
            1,
        );
        for _ in 0..3 {
            arrives(line.admit(t0, 100));
        }
        assert_eq!(line.admit(t0, 100), Fate::Overflowed);
        assert_eq!(line.counts().overflowed, 1);
        // Once they have arrived the line takes packets again.
        arrives(line.admit(t0 + 10 * MS, 100));
    }

    #[test]
    fn an_unlimited_rate_and_no_delay_pass_packets_at_once() {
        let t0 = Instant::now();
        let mut line = Line::new(LineSpec::default(), 1);
        assert_eq!(line.admit(t0, 65_000), Fate::Arrives(t0));
    }
}
