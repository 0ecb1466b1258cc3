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
//!    close, e.g. for another protocol version), then a header frame with
//!    the file header as stored (any size: it carries the page directory),
//!    then page 0;
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

use serde::{Deserialize, Serialize};

/// Bumped whenever a message changes shape.
pub const PROTOCOL_VERSION: u32 = 2;

/// The first byte of every binary frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum FrameKind {
    /// A [`ClientMessage`] or [`ServerMessage`], bincode-encoded.
    Control = 0,
    /// A page's stored bytes (its index is in its own header).
    Page = 1,
    /// The scene's file header as stored (`FileHeader::decode` reads it);
    /// raw bytes like a page, so its size has no control-message limit.
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
}
