//! The websocket session between a client and the memory server.
//!
//! Every websocket message is a binary frame whose first byte says what it
//! holds ([`FrameKind`]): a control message (a serde type encoded by
//! [`codec`](crate::codec)) or a page, whose bytes follow exactly as stored
//! in the file (checksum included: the server never re-encodes).
//!
//! A session:
//!
//! 1. client -> [`ClientMessage::Hello`] with its protocol version and limits;
//! 2. server -> [`ServerMessage::Hello`] (or [`ServerMessage::Error`] and a
//!    close, e.g. for another protocol version), then the file header as
//!    stored, in header frames of at most [`HEADER_PART_BYTES`] each, which
//!    the client joins until it holds the length the header's first 16
//!    bytes declare (at most [`MAX_HEADER_BYTES`]), then the root
//!    directory page (page id: the scene's page count) and page 0;
//!    further directory pages are asked for, and pushed, as pages are;
//! 3. client -> [`ClientMessage::Request`] (pages with priorities; a later
//!    request for a page still queued updates its priority; a request for a
//!    page sent but not yet acknowledged is ignored, and one for a page
//!    acknowledged earlier sends it again) and
//!    [`ClientMessage::Cancel`] for pages that fell out of view;
//! 4. server -> pages, highest priority first, as long as the bytes it has
//!    sent but the client has not acknowledged ([`ClientMessage::Received`])
//!    stay under the client's `max_in_flight_bytes`; when nothing is asked
//!    for, it may push pages it predicts the client will want (children of
//!    what it asked for), if the client allowed pushes in its hello. A page
//!    the server cannot send (it fails its checksum on the server's disk)
//!    is answered with [`ServerMessage::PageUnavailable`] instead, so the
//!    client stops waiting for it.
//!
//! Demo sessions ride on the same connection: a client joins a named
//! session of its scene ([`ClientMessage::Join`]) as its presenter or a
//! follower. The presenter publishes its view ([`ClientMessage::View`]);
//! the server hands the latest one to every follower
//! ([`ServerMessage::View`], coalesced: a follower behind gets only the
//! newest) and tells every member who is in it
//! ([`ServerMessage::SessionState`]) whenever that changes. Each member
//! still asks for its own pages; they come from the server's shared cache,
//! which the presenter's requests filled. The presenter may hand control
//! to a follower ([`ClientMessage::HandOver`]); one that leaves keeps its
//! seat for a grace period, after which the session closes
//! ([`ServerMessage::SessionClosed`]).

use serde::{Deserialize, Serialize};

/// Bumped whenever a message changes shape. 4: the header comes in parts.
/// 5: the header has a fixed size; the directory comes in directory pages,
/// page ids after the scene's pages, the root's before page 0.
pub const PROTOCOL_VERSION: u32 = 5;

/// The most header bytes one header frame carries. A scene's header holds
/// its page directory (40 bytes a page: 0.7 MB for 18,000 pages), and the
/// server's websocket keeps its write buffer at the largest frame it ever
/// wrote for the connection's whole life; parts keep that buffer small.
pub const HEADER_PART_BYTES: usize = 64 << 10;

/// The longest header a client joins from parts (a directory of 1.6
/// million pages), so a server cannot make it buffer without end. The
/// native websocket refused a larger single header frame before there
/// were parts (its largest message is 64 MiB).
pub const MAX_HEADER_BYTES: usize = 64 << 20;

/// The first byte of every binary frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum FrameKind {
    /// A [`ClientMessage`] or [`ServerMessage`], bincode-encoded.
    Control = 0,
    /// A page's stored bytes (its index is in its own header).
    Page = 1,
    /// A part of the scene's file header as stored (joined, `FileHeader::
    /// decode` reads it); raw bytes like a page, so its size has no
    /// control-message limit.
    Header = 2,
}

/// What a client says.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum ClientMessage {
    Hello {
        protocol_version: u32,
        /// Most page bytes the server may have sent and not yet seen acknowledged.
        max_in_flight_bytes: u64,
        /// Whether the server may push pages nobody asked for when idle.
        allow_push: bool,
    },
    /// Pages wanted, with priorities (larger first). Adds to or updates the
    /// outstanding wishes; pages already resident should not be asked for.
    Request { pages: Vec<PageWish> },
    /// Pages no longer wanted (fell out of view); unknown pages are ignored.
    Cancel { pages: Vec<u32> },
    /// Pages that arrived, so their bytes no longer count as in flight.
    /// Every page that arrives is acknowledged, even one that failed its
    /// checksum, before it is asked for again.
    Received { pages: Vec<u32> },
    /// Joins the demo session `session` of this connection's scene, as its
    /// presenter (made if it does not exist; refused if someone else
    /// presents) or as a follower (refused if it does not exist). A
    /// connection is in at most one session: joining another leaves the first.
    Join { session: String, present: bool },
    /// The presenter's view, handed to the followers; ignored (with a
    /// non-fatal error) from anyone else.
    View { view: SharedView },
    /// The presenter gives control to member `to`, who becomes the
    /// presenter; the giver follows.
    HandOver { to: u64 },
    /// Leaves the session (the connection stays, and its pages).
    Leave,
}

/// What a presenter shows: the camera (f64: it may sit far from the
/// origin) and the options a viewer draws with, as key and value (the
/// threshold, the kernel, a kind's options), so followers draw the same.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SharedView {
    pub eye: [f64; 3],
    pub target: [f64; 3],
    pub up: [f64; 3],
    pub fov_y_deg: f64,
    pub options: Vec<(String, String)>,
}

impl SharedView {
    /// This view as a camera of `width` x `height`, or `None` for a view
    /// no camera can take (not finite, eye on target, no up, a field of
    /// view outside 1..179 degrees): a presenter's bad view is neither
    /// drawn by followers nor walked by the server.
    pub fn camera(&self, width: u32, height: u32) -> Option<crate::camera::Camera> {
        use glam::DVec3;
        let (eye, target, up) = (
            DVec3::from_array(self.eye),
            DVec3::from_array(self.target),
            DVec3::from_array(self.up),
        );
        let sane = eye.is_finite()
            && target.is_finite()
            && up.is_finite()
            && (target - eye).length() > 0.0
            && (target - eye).cross(up).length() > 0.0
            && (1.0..=179.0).contains(&self.fov_y_deg);
        sane.then_some(crate::camera::Camera {
            eye,
            target,
            up,
            fov_y_deg: self.fov_y_deg,
            width,
            height,
        })
    }

    /// The value of option `key`, if the presenter gave it.
    pub fn option(&self, key: &str) -> Option<&str> {
        self.options
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    }
}

/// Most follower ids a [`SessionState`] lists.
pub const LISTED_FOLLOWERS: usize = 64;

/// Who is in a demo session, as one member is told.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SessionState {
    pub session: String,
    /// This member's id (what [`ClientMessage::HandOver`] names).
    pub you: u64,
    /// The presenter's id; it may be away (see `presenter_connected`).
    pub presenter: Option<u64>,
    pub presenter_connected: bool,
    /// Members following now.
    pub follower_count: u32,
    /// The first of them by id, at most [`LISTED_FOLLOWERS`] (whom a
    /// presenter's panel offers to hand over to): every member is told on
    /// every change, so a full list would cost the server the square of
    /// the followers.
    pub followers: Vec<u64>,
    /// Seconds left before the session closes, while its presenter is away.
    pub closes_in_s: Option<f64>,
}

/// One wanted page.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PageWish {
    pub page: u32,
    pub priority: f32,
}

/// What the server says.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum ServerMessage {
    Hello {
        protocol_version: u32,
        server: String,
    },
    /// Something went wrong; `fatal` errors are followed by a close.
    Error { message: String, fatal: bool },
    /// A requested page that cannot be sent, and why: its bytes on the
    /// server are corrupt (or unreadable). Asking again will not help, so a
    /// client draws that part of the tree from coarser pages and stops
    /// waiting for it.
    PageUnavailable { page: u32, reason: String },
    /// Who is in this connection's demo session (after a join, and
    /// whenever it changes).
    SessionState { state: SessionState },
    /// The presenter's latest view (`seq` counts the presenter's views).
    View { seq: u64, view: SharedView },
    /// The demo session ended (its presenter did not come back in time),
    /// or this connection was refused one; it is in none now.
    SessionClosed { session: String, reason: String },
}
