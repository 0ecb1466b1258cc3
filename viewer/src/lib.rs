//! farfield-viewer: the interactive viewer, one code for a native window
//! and a browser tab.
//!
//! An eframe app ([`app::ViewerApp`]) over the client core
//! (`farfield-client`'s `Viewer` and frame loop): the scene drawn into a
//! texture on egui's wgpu device, a panel beside it, camera controls that
//! people expect from Potree or a CAD viewer. The front ends are thin: the
//! `farfield view` command opens a window; `farfield-web` starts the same
//! app on a page's canvas with the page's `WebSocket`.
//!
//! - [`rig`]: the camera (orbit, pan, zoom toward the cursor, fly, focus,
//!   reset), eased toward where input put it;
//! - [`input`]: egui's pointer, wheel, touch and keys as the rig's input;
//! - [`refine`]: the frame budget while moving, refinement at rest, progress;
//! - [`panel`]: stats and settings; [`status`]: what a frame reports;
//! - [`demo_panel`]: a demo session: present, follow (or look around and
//!   follow again), hand over;
//! - [`link`]: the camera in a URL fragment; [`pick`]: what is under the cursor;
//! - [`flight`]: a scripted flight for benchmarks (frame times while orbiting).

pub mod app;
pub mod demo_panel;
pub mod flight;
pub mod input;
pub mod link;
pub mod measure;
pub mod panel;
pub mod pick;
pub mod refine;
pub mod rig;
pub mod status;

pub use app::{AppOptions, Platform, Shot, ViewerApp, WAIT_FOR_SERVER};
