//! farfield-client: the viewer side.
//!
//! Today it holds the file-backed page source and the `farfield traverse`
//! command, which runs the reference traversal of `farfield-protocol` on a
//! paged file and reports the cut. The websocket client, resident page
//! cache and wgpu renderer arrive with the streaming client.
//!
//! - [`local`]: reads a paged file from disk into a fully resident
//!   [`farfield_protocol::hierarchy::Hierarchy`] (the `--file` mode).

pub mod local;
