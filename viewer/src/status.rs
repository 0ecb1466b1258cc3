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
    /// Time between this frame and the last, milliseconds.
    pub frame_ms: f64,
    /// Frames per second, smoothed.
    pub fps: f64,
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
    /// The camera shown.
    #[serde(skip)]
    pub camera: Option<CameraSpec>,
    #[serde(skip)]
    pub(crate) reset_requested: bool,
}
