//! What the viewer reports each frame: the panel's numbers, and what a
//! browser page hands to scripts (tests read `refined` and `progress`).

use farfield_client::camera_spec::CameraSpec;
use serde::Serialize;

/// The connection as the panel names it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Connection {
    /// A local file: nothing to connect to.
    File,
    #[default]
    Connecting,
    Connected,
    /// The scene was here and the server went away; trying again.
    Reconnecting,
}

impl Connection {
    pub fn label(self) -> &'static str {
        match self {
            Self::File => "local file",
            Self::Connecting => "connecting",
            Self::Connected => "connected",
            Self::Reconnecting => "reconnecting",
        }
    }
}

/// One frame's report.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Status {
    /// Time between frames drawn one after another, milliseconds,
    /// smoothed (see [`FrameClock`]).
    pub frame_ms: f64,
    /// Frames per second: `1000 / frame_ms`, the same measure.
    pub fps: f64,
    /// Nothing changes on screen: the viewer draws no frame until
    /// something does (input, a page, the network).
    pub at_rest: bool,
    /// A notice for the user (what of a damaged link was ignored), shown
    /// on screen for a while after start.
    pub notice: Option<String>,
    /// Traversal, upload and draw of the scene, milliseconds.
    pub draw_ms: f64,
    /// The threshold the frame was drawn with (pixels, or eps for cubes).
    pub threshold: f64,
    pub nodes_drawn: u64,
    pub resident_pages: usize,
    pub resident_mb: f64,
    pub in_flight_pages: usize,
    /// Pages the view wants that are not resident.
    pub wanted_pages: usize,
    pub mb_received: f64,
    /// Share of the view's wanted cut that is resident, 0 to 1.
    pub progress: f64,
    /// Everything the resting view needs is drawn at the final threshold.
    pub refined: bool,
    pub connection: Connection,
    /// The adapter the scene is drawn with (name / backend).
    pub adapter: String,
    /// The session's last connection or server error.
    pub last_error: Option<String>,
    /// What stops the viewer from drawing (a GPU error, a session ended).
    pub error: Option<String>,
    /// The demo session, in a line ("following demo (member 3); ...").
    pub demo: Option<String>,
    /// What the measuring tool's points measure, while it has some.
    pub measure: Option<crate::measure::Measured>,
    /// The measuring tool is on: clicks pick points.
    pub measuring: bool,
    #[serde(skip)]
    pub(crate) measure_toggled: bool,
    /// The scene's lowest and highest heights (the elevation ramp's ends).
    #[serde(skip)]
    pub heights: Option<[f64; 2]>,
    /// Where the panel's screenshot button is (x, y, width, height in
    /// points, a page's CSS pixels), while the panel shows: what a script
    /// clicks.
    pub screenshot_button: Option<[f32; 4]>,
    /// The camera shown.
    #[serde(skip)]
    pub camera: Option<CameraSpec>,
    #[serde(skip)]
    pub(crate) reset_requested: bool,
    #[serde(skip)]
    pub(crate) preset_requested: Option<crate::rig::Preset>,
}

/// The frame time the panel shows, from the gaps between frames drawn one
/// after another. A frame that follows a rest (the viewer drew nothing
/// until something changed) ends no frame time: a gap of seconds there is
/// the user's pause, not the frame rate, and showing it beside the
/// smoothed rate made lines like "6479.4 ms, 7 fps".
#[derive(Debug, Clone, Copy, Default)]
pub struct FrameClock {
    /// Smoothed milliseconds between frames; 0 before the first.
    ms: f64,
}

impl FrameClock {
    /// A frame drawn `dt` seconds after the last; `continuous`: the last
    /// frame asked for this one at once (it was not at rest).
    pub fn frame(&mut self, dt: f64, continuous: bool) {
        if !(continuous && dt > 0.0 && dt.is_finite()) {
            return;
        }
        let ms = dt * 1e3;
        self.ms = if self.ms == 0.0 {
            ms
        } else {
            self.ms * 0.9 + ms * 0.1
        };
    }

    pub fn ms(&self) -> f64 {
        self.ms
    }

    pub fn fps(&self) -> f64 {
        if self.ms > 0.0 { 1e3 / self.ms } else { 0.0 }
    }
}

/// The panel's frame line: one measure, as a time and as a rate, or that
/// nothing is being drawn.
pub fn frame_line(status: &Status) -> String {
    if status.at_rest {
        "at rest".into()
    } else if status.frame_ms > 0.0 {
        format!("{:.1} ms ({:.0} fps)", status.frame_ms, status.fps)
    } else {
        "-".into()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_larger_than_the_device_allows_keep_their_shape_within_it() {
        use crate::app::fit_within;
        assert_eq!(fit_within(800.0, 600.0, 8192), (800, 600));
        assert_eq!(fit_within(9000.0, 9000.0, 8192), (8192, 8192));
        let (w, h) = fit_within(16000.0, 4000.0, 8192);
        assert_eq!(w, 8192);
        assert!((f64::from(w) / f64::from(h) - 4.0).abs() < 0.01, "{w}x{h}");
        assert_eq!(fit_within(0.0, 0.0, 8192), (1, 1));
    }

    #[test]
    fn the_frame_line_is_one_measure_and_a_pause_is_not_a_frame() {
        let mut clock = FrameClock::default();
        for _ in 0..50 {
            clock.frame(0.020, true);
        }
        // Six seconds at rest, then a frame: not a frame time.
        clock.frame(6.4794, false);
        assert!((clock.ms() - 20.0).abs() < 1e-9, "{}", clock.ms());
        for dt in [0.016, 0.050, 0.033] {
            clock.frame(dt, true);
            assert!((clock.ms() * clock.fps() - 1e3).abs() < 1e-6);
        }
        let status = Status {
            frame_ms: clock.ms(),
            fps: clock.fps(),
            ..Status::default()
        };
        let line = frame_line(&status);
        let (ms, fps): (f64, f64) = {
            let mut words = line.split(|c: char| !(c.is_ascii_digit() || c == '.'));
            let mut numbers = words
                .by_ref()
                .filter(|w| !w.is_empty())
                .map(|w| w.parse().unwrap());
            (numbers.next().unwrap(), numbers.next().unwrap())
        };
        assert!((ms * fps - 1e3).abs() / 1e3 < 0.05, "{line}");
        let resting = Status {
            at_rest: true,
            ..status
        };
        assert_eq!(frame_line(&resting), "at rest");
    }
}
