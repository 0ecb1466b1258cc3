//! Evaluation: how far a rendered image is from a reference image.
//!
//! Every rendering mode reports its error against run time (DESIGN.md,
//! "Measuring"); this module holds the per-pixel measures that the
//! `farfield compare` command and the reports share.
//!
//! - [`metrics`]: RMSE, PSNR and the fraction of wrong pixels of two RGBA
//!   images of one size.
//! - [`files`]: the same for two PNG files (`farfield compare`).
//! - `report`: those numbers as one line of text or as JSON (`"inf"` for
//!   the PSNR of identical images).

pub mod files;
pub mod metrics;
mod report;

pub use files::{CompareError, FileComparison, compare_files};
pub use metrics::{ImageMetrics, MetricsError, compare, compare_images};
