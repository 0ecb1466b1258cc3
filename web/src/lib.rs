//! farfield-web: the viewer on a browser page.
//!
//! The page the server serves at `/view/<scene>` loads this crate (built
//! by `web/build`: wasm32, then `wasm-bindgen --target web`) and calls
//! [`start`]. It reads the page's address (the scene from the path, the
//! camera from the fragment, options from the query), opens a session
//! over the page's `WebSocket` to the same server, and starts the viewer
//! app ([`farfield_viewer::ViewerApp`]) on the page's canvas: WebGPU where
//! the browser has it, WebGL2 otherwise (or when `?backend=webgl` asks).
//!
//! The page in turn learns from the viewer ([`page::WebPage`]): the camera
//! at rest goes into the address, so a link opens the same view, and each
//! frame's status is written on the canvas as `data-refined`,
//! `data-progress` and `data-status` (JSON), which the browser tests read,
//! with the canvas's pixels on request ([`capture_canvas`]).
//!
//! On other targets the crate is empty, so the workspace builds as usual.

#[cfg(target_arch = "wasm32")]
mod page;
#[cfg(target_arch = "wasm32")]
mod query;

#[cfg(target_arch = "wasm32")]
pub use page::{capture_canvas, screenshot, start, wasm_memory_bytes};
