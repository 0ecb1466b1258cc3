//! Comparing two PNG files (the `farfield compare` command).

use std::path::{Path, PathBuf};

use thiserror::Error;

use super::{ImageMetrics, MetricsError, compare_images};
use crate::png_file::{ImageError, read_png};

/// The metrics of two PNGs and their common size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FileComparison {
    pub metrics: ImageMetrics,
    pub width: u32,
    pub height: u32,
}

/// Why two PNG files could not be compared.
#[derive(Debug, Error)]
pub enum CompareError {
    #[error(transparent)]
    Image(#[from] ImageError),
    #[error("cannot compare {} with {}: {error}", a.display(), b.display())]
    Metrics {
        a: PathBuf,
        b: PathBuf,
        error: MetricsError,
    },
}

impl CompareError {
    /// The images were read but differ in size (`farfield compare` exits 2).
    pub fn is_size_mismatch(&self) -> bool {
        matches!(
            self,
            Self::Metrics {
                error: MetricsError::SizeMismatch { .. },
                ..
            }
        )
    }
}

/// Reads two PNGs and measures `b` against the reference `a`.
pub fn compare_files(a: &Path, b: &Path, tolerance: u8) -> Result<FileComparison, CompareError> {
    let (aw, ah, ap) = read_png(a)?;
    let (bw, bh, bp) = read_png(b)?;
    let metrics = compare_images((aw, ah, &ap), (bw, bh, &bp), tolerance).map_err(|error| {
        CompareError::Metrics {
            a: a.to_owned(),
            b: b.to_owned(),
            error,
        }
    })?;
    Ok(FileComparison {
        metrics,
        width: aw,
        height: ah,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::png_file::write_png;

    #[test]
    fn compares_files_and_refuses_sizes() {
        let dir = std::env::temp_dir();
        let id = std::process::id();
        let a = dir.join(format!("farfield-cmp-{id}-a.png"));
        let b = dir.join(format!("farfield-cmp-{id}-b.png"));
        let c = dir.join(format!("farfield-cmp-{id}-c.png"));
        write_png(&a, 2, 2, &[100; 16]).unwrap();
        let mut off = [100; 16];
        off[0] = 110;
        write_png(&b, 2, 2, &off).unwrap();
        write_png(&c, 4, 1, &[100; 16]).unwrap();
        let same = compare_files(&a, &a, 8).unwrap();
        assert!(same.metrics.psnr_db.is_infinite());
        let r = compare_files(&a, &b, 8).unwrap();
        assert_eq!((r.width, r.height), (2, 2));
        assert_eq!(r.metrics.wrong_fraction, 0.25);
        let err = compare_files(&a, &c, 8).unwrap_err();
        assert!(err.is_size_mismatch());
        assert!(err.to_string().contains("2x2 and 4x1"), "{err}");
        let missing = compare_files(&a, &dir.join("farfield-no-such.png"), 8).unwrap_err();
        assert!(!missing.is_size_mismatch());
        for p in [a, b, c] {
            std::fs::remove_file(p).unwrap();
        }
    }
}
