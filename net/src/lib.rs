//! farfield-net: the client's side of a session with a memory server.
//!
//! The protocol's state and the bytes on the wire are apart:
//!
//! - [`session`]: [`Session`], the state machine (hello, header, requests
//!   and cancels, acknowledgements, checksum failures, pages given up,
//!   reconnects with backoff), over any transport;
//! - [`transport`]: the [`Transport`] seam, binary frames in and out;
//! - [`websocket`]: the native transport (not built for wasm32), and
//!   [`browser`]: a page's `WebSocket` (built only for wasm32);
//! - [`queue`]: a transport whose bytes its owner moves (tests; async
//!   drivers);
//! - [`url`]: the stream URL of a scene, spelled once; [`stats`]: the
//!   session's counters.
//!
//! Nothing here needs a multi-thread runtime: the session is driven by its
//! owner's loop ([`Session::pump`]); the native transport keeps its sockets
//! on a current-thread runtime of its own, and
//! [`websocket::drive`] runs socket and session in one task of the caller's.

#[cfg(target_arch = "wasm32")]
pub mod browser;
#[cfg(not(target_arch = "wasm32"))]
pub mod certificate;
pub mod queue;
pub mod session;
pub mod stats;
pub mod transport;
pub mod url;
#[cfg(not(target_arch = "wasm32"))]
pub mod websocket;

#[cfg(test)]
mod tests;

pub use session::{
    DemoEvent, LATENCY_SAMPLES, MAX_PAGE_FAILURES, Session, SessionError, SessionEvent,
    SessionOptions,
};
pub use stats::{FailedPage, NetStats};
pub use transport::{Closing, Target, Transport, TransportEvent, Waker};
pub use url::stream_url;
