//! A scripted flight for benchmarks: the camera circles the scene and
//! swings in and out for a set time, as a user orbiting and zooming would,
//! while the frame loop runs exactly as under a hand (frame budget, pages
//! streaming, LRU); at the end, the frame times.
//!
//! The path is a function of time alone, so two runs (a window, a tab,
//! two machines) fly the same path.

use serde::Serialize;

use crate::rig::Orbit;

/// Degrees of azimuth a second.
const TURN_DEG_PER_S: f64 = 30.0;
/// The distance swings by up to this factor either way...
const SWING: f64 = 3.0;
/// ...once every this many seconds.
const SWING_PERIOD_S: f64 = 20.0;

/// A flight under way.
#[derive(Debug, Clone)]
pub struct Flight {
    seconds: f64,
    start: Option<Orbit>,
    elapsed: f64,
    frame_ms: Vec<f64>,
    thresholds: Vec<f64>,
    peak_resident_mb: f64,
}

/// What a flight measured.
#[derive(Debug, Clone, Serialize)]
pub struct FlightReport {
    pub seconds: f64,
    pub frames: usize,
    pub median_frame_ms: f64,
    pub p90_frame_ms: f64,
    pub median_threshold: f64,
    /// The most page bytes resident at once during the flight, MB.
    pub peak_resident_mb: f64,
    /// What drew it (filled in by the app).
    pub adapter: String,
}

impl Flight {
    pub fn new(seconds: f64) -> Self {
        Self {
            seconds: seconds.max(0.0),
            start: None,
            elapsed: 0.0,
            frame_ms: Vec::new(),
            thresholds: Vec::new(),
            peak_resident_mb: 0.0,
        }
    }

    /// The camera `dt` seconds on from the last call, starting from `from`.
    pub fn next(&mut self, from: &Orbit, dt: f64) -> Orbit {
        let start = *self.start.get_or_insert(*from);
        self.elapsed += dt;
        let t = self.elapsed;
        let swing = (t / SWING_PERIOD_S * std::f64::consts::TAU).sin();
        Orbit {
            yaw: start.yaw + (TURN_DEG_PER_S * t).to_radians(),
            distance: start.distance * SWING.powf(swing),
            ..start
        }
    }

    /// Records one frame (not the first, whose time includes start-up).
    pub fn record(&mut self, frame_ms: f64, threshold: f64, resident_mb: f64) {
        self.peak_resident_mb = self.peak_resident_mb.max(resident_mb);
        if self.elapsed > 0.0 {
            self.frame_ms.push(frame_ms);
            self.thresholds.push(threshold);
        }
    }

    /// The report, once the time is up.
    pub fn finished(&self) -> Option<FlightReport> {
        (self.elapsed >= self.seconds).then(|| FlightReport {
            seconds: self.elapsed,
            frames: self.frame_ms.len(),
            median_frame_ms: quantile(&self.frame_ms, 0.5),
            p90_frame_ms: quantile(&self.frame_ms, 0.9),
            median_threshold: quantile(&self.thresholds, 0.5),
            peak_resident_mb: self.peak_resident_mb,
            adapter: String::new(),
        })
    }
}

/// The `q` quantile (nearest rank) of `values`; 0 for none.
fn quantile(values: &[f64], q: f64) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    let rank = ((sorted.len() - 1) as f64 * q.clamp(0.0, 1.0)).round() as usize;
    sorted[rank]
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn the_path_circles_and_swings_and_the_report_has_quantiles() {
        let start = Orbit::from_eye(DVec3::new(4.0, 0.0, 1.0), DVec3::ZERO, 45.0);
        let mut f = Flight::new(6.0);
        let a = f.next(&start, 3.0);
        assert!((a.yaw - start.yaw - 90f64.to_radians()).abs() < 1e-12);
        assert!(a.distance > start.distance, "swinging out first");
        assert_eq!(a.target, start.target);
        assert!(f.finished().is_none());
        for ms in [10.0, 30.0, 20.0, 40.0, 50.0] {
            f.record(ms, 2.0, ms / 10.0);
        }
        let b = f.next(&a, 3.0);
        assert!(
            (b.yaw - start.yaw - 180f64.to_radians()).abs() < 1e-12,
            "from the start, not from `a`"
        );
        let r = f.finished().expect("6 s flown");
        assert_eq!(r.frames, 5);
        assert_eq!(r.median_frame_ms, 30.0);
        assert_eq!(r.p90_frame_ms, 50.0);
        assert_eq!(r.median_threshold, 2.0);
        assert_eq!(r.peak_resident_mb, 5.0);
    }
}
