//! Per-pixel image error: RMSE, PSNR and wrong-pixel fraction.
//!
//! Images are tightly packed RGBA8 rows (as `farfield_render::Renderer`
//! returns them and [`crate::png_file::read_png`] reads them); only the RGB
//! channels are compared, so an alpha channel never counts as error.

use thiserror::Error;

/// How two images of one size differ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageMetrics {
    /// Root mean square difference over all RGB channels, in 0..=255 units.
    pub rmse: f64,
    /// `20 log10(255 / rmse)` in decibels; [`f64::INFINITY`] when the images
    /// are identical (never NaN).
    pub psnr_db: f64,
    /// Fraction of pixels with any RGB channel off by more than `tolerance`.
    pub wrong_fraction: f64,
    /// The per-channel tolerance used for `wrong_fraction`.
    pub tolerance: u8,
}

/// Why two images could not be compared.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum MetricsError {
    /// The two images have different sizes.
    #[error("images differ in size: {a_width}x{a_height} and {b_width}x{b_height}")]
    SizeMismatch {
        a_width: u32,
        a_height: u32,
        b_width: u32,
        b_height: u32,
    },
    /// A pixel buffer does not hold `width * height` RGBA pixels.
    #[error("image {which} has {actual} bytes, expected {expected} for {width}x{height} RGBA")]
    BadLength {
        which: char,
        actual: usize,
        expected: usize,
        width: u32,
        height: u32,
    },
}

/// Compares two RGBA8 images of `width` x `height` pixels.
pub fn compare(
    a: &[u8],
    b: &[u8],
    width: u32,
    height: u32,
    tolerance: u8,
) -> Result<ImageMetrics, MetricsError> {
    let expected = width as usize * height as usize * 4;
    for (which, buf) in [('A', a), ('B', b)] {
        if buf.len() != expected {
            return Err(MetricsError::BadLength {
                which,
                actual: buf.len(),
                expected,
                width,
                height,
            });
        }
    }
    let mut sum_sq = 0u64;
    let mut wrong = 0u64;
    for (pa, pb) in a.chunks_exact(4).zip(b.chunks_exact(4)) {
        let mut worst = 0u8;
        for c in 0..3 {
            let d = pa[c].abs_diff(pb[c]);
            sum_sq += u64::from(d) * u64::from(d);
            worst = worst.max(d);
        }
        wrong += u64::from(worst > tolerance);
    }
    let pixels = expected / 4;
    let (rmse, wrong_fraction) = if pixels == 0 {
        (0.0, 0.0)
    } else {
        (
            (sum_sq as f64 / (pixels * 3) as f64).sqrt(),
            wrong as f64 / pixels as f64,
        )
    };
    let psnr_db = if sum_sq == 0 {
        f64::INFINITY
    } else {
        20.0 * (255.0 / rmse).log10()
    };
    Ok(ImageMetrics {
        rmse,
        psnr_db,
        wrong_fraction,
        tolerance,
    })
}

/// Compares two images given as `(width, height, rgba)`, refusing different
/// sizes with [`MetricsError::SizeMismatch`].
pub fn compare_images(
    a: (u32, u32, &[u8]),
    b: (u32, u32, &[u8]),
    tolerance: u8,
) -> Result<ImageMetrics, MetricsError> {
    if (a.0, a.1) != (b.0, b.1) {
        return Err(MetricsError::SizeMismatch {
            a_width: a.0,
            a_height: a.1,
            b_width: b.0,
            b_height: b.1,
        });
    }
    compare(a.2, b.2, a.0, a.1, tolerance)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gray(w: u32, h: u32, v: u8) -> Vec<u8> {
        (0..w * h).flat_map(|_| [v, v, v, 255]).collect()
    }

    #[test]
    fn identical_images_have_infinite_psnr() {
        let a = gray(3, 2, 77);
        let m = compare(&a, &a, 3, 2, 0).unwrap();
        assert_eq!(m.rmse, 0.0);
        assert!(m.psnr_db.is_infinite() && m.psnr_db > 0.0);
        assert_eq!(m.wrong_fraction, 0.0);
    }

    #[test]
    fn one_channel_off_by_ten_in_2x2() {
        let a = gray(2, 2, 100);
        let mut b = a.clone();
        b[5] = 110; // green of pixel 1
        // 12 channels, one squared error of 100: MSE 100/12, RMSE 2.88675.
        let m = compare(&a, &b, 2, 2, 8).unwrap();
        assert!((m.rmse - (100.0f64 / 12.0).sqrt()).abs() < 1e-12, "{m:?}");
        // 20 log10(255 / 2.88675) = 38.9223 dB.
        assert!((m.psnr_db - 38.9223).abs() < 1e-3, "{m:?}");
        assert_eq!(m.wrong_fraction, 0.25);
        // Within tolerance 10 the pixel is not wrong.
        assert_eq!(compare(&a, &b, 2, 2, 10).unwrap().wrong_fraction, 0.0);
    }

    #[test]
    fn alpha_is_ignored() {
        let a = gray(2, 1, 5);
        let mut b = a.clone();
        b[3] = 0;
        b[7] = 9;
        let m = compare(&a, &b, 2, 1, 0).unwrap();
        assert_eq!(m.rmse, 0.0);
        assert!(m.psnr_db.is_infinite());
    }

    #[test]
    fn black_against_white_is_zero_db() {
        let m = compare(&gray(4, 4, 0), &gray(4, 4, 255), 4, 4, 254).unwrap();
        assert_eq!(m.rmse, 255.0);
        assert_eq!(m.psnr_db, 0.0);
        assert_eq!(m.wrong_fraction, 1.0);
    }

    #[test]
    fn empty_images_compare_without_nan() {
        let m = compare(&[], &[], 0, 0, 8).unwrap();
        assert_eq!(m.rmse, 0.0);
        assert_eq!(m.wrong_fraction, 0.0);
        assert!(m.psnr_db.is_infinite());
    }

    #[test]
    fn sizes_are_refused() {
        let a = gray(2, 2, 0);
        let b = gray(4, 1, 0);
        assert!(matches!(
            compare_images((2, 2, &a), (4, 1, &b), 8),
            Err(MetricsError::SizeMismatch { .. })
        ));
        let err = compare(&a, &b[..8], 2, 2, 8).unwrap_err();
        assert!(matches!(err, MetricsError::BadLength { which: 'B', .. }));
        assert!(err.to_string().contains("expected 16"), "{err}");
    }
}
