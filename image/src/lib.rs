//! farfield-image: rendered images as files and as measurements.
//!
//! Every rendering mode reports its error against run time (DESIGN.md,
//! "Measuring"); this crate holds the per-pixel measures that tests, the
//! `farfield compare` command and the benchmarks share, and the PNG files
//! images travel in. No GPU and no runtime, so the browser build can use it.
//!
//! - [`png_file`]: write RGBA8 PNGs atomically, read RGB8 or RGBA8 ones.
//! - [`metrics`]: RMSE, PSNR and the fraction of wrong pixels of two RGBA
//!   images of one size.
//! - [`files`]: the same for two PNG files (`farfield compare`).
//! - `report`: those numbers as one line of text or as JSON (`"inf"` for
//!   the PSNR of identical images).

pub mod files;
pub mod metrics;
pub mod png_file;
mod report;

pub use files::{CompareError, FileComparison, compare_files};
pub use metrics::{ImageMetrics, MetricsError, compare, compare_images};
pub use png_file::{ImageError, encode_png, read_png, write_png};
