//! farfield-client: the viewer side.
//!
//! - [`viewer`]: [`viewer::Viewer`], the resident pages of one scene (from a
//!   file or a memory server), their LRU, and what was asked for.
//! - [`net`]: the websocket session with the memory server, reconnecting.
//! - [`render`]: the wgpu renderer (headless): splats, and triangles plus
//!   color-cube faces for cube hierarchies.
//! - [`reference`]: a scene's full geometry, the reference cube renders
//!   are timed and measured against.
//! - [`bench`]: `farfield bench` and `report`: error against run time for
//!   every rendering mode, tables, plots and an HTML page.
//! - [`commands`]: `farfield render`, `traverse`, `demo` and friends.
//! - [`args`]: camera, orbit and size arguments; [`path`]: camera paths.
//! - [`image`]: PNG in and out; [`eval`]: image error metrics.
//! - [`local`]: reads a paged file from disk into a fully resident
//!   [`farfield_protocol::hierarchy::Hierarchy`] (the `--file` mode).

pub mod args;
pub mod bench;
pub mod commands;
pub mod eval;
pub mod image;
pub mod local;
pub mod net;
pub mod path;
pub mod reference;
pub mod render;
pub mod viewer;
