//! farfield-client: the client core between a session and the renderer.
//!
//! Everything a front end (the CLI, a window, a browser tab) needs to show
//! a streamed scene, and nothing that ties it to one: no server, no
//! multi-thread runtime, no file format beyond the protocol's.
//!
//! - [`viewer`]: [`viewer::Viewer`], the resident pages of one scene (from
//!   a file or a session), their LRU in bytes.
//! - [`frame_loop`]: one frame of any hierarchy kind
//!   ([`frame_loop::draw_frame`]) and the resting camera's progressive
//!   refinement ([`frame_loop::Settle`]).
//! - [`flythrough`]: a camera path flown with frame-time feedback.
//! - [`render_job`]: one camera refined to a PNG (`farfield render`).
//! - [`report`]: [`report::RenderReport`], what a view did.
//! - [`camera_spec`]: cameras and orbits before the scene is known;
//!   [`path`]: camera paths.

pub mod budget;
pub mod camera_spec;
pub mod demo_link;
pub mod flythrough;
pub mod frame_loop;
pub mod path;
pub mod render_job;
pub mod report;
pub mod viewer;
