//! How image metrics are printed: one line of text, or JSON.
//!
//! JSON has no infinity, and `null` would read as "unknown"; an infinite
//! PSNR (identical images) is therefore written as the string `"inf"`.

use std::fmt;

use super::ImageMetrics;

impl ImageMetrics {
    /// PSNR in dB with two decimals, or `inf` for identical images.
    pub fn psnr_text(&self) -> String {
        if self.psnr_db.is_infinite() {
            "inf".to_owned()
        } else {
            format!("{:.2}", self.psnr_db)
        }
    }

    /// `{"rmse":..,"psnr_db":..,"wrong_fraction":..,"tolerance":..,"width":..,"height":..}`,
    /// with `"psnr_db":"inf"` for identical images.
    pub fn to_json(&self, width: u32, height: u32) -> serde_json::Value {
        let psnr = if self.psnr_db.is_finite() {
            serde_json::json!(self.psnr_db)
        } else {
            serde_json::json!("inf")
        };
        serde_json::json!({
            "rmse": self.rmse,
            "psnr_db": psnr,
            "wrong_fraction": self.wrong_fraction,
            "tolerance": self.tolerance,
            "width": width,
            "height": height,
        })
    }
}

impl fmt::Display for ImageMetrics {
    /// `RMSE 2.887, PSNR 38.92 dB, wrong pixels 25.000% (tolerance 8)`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "RMSE {:.3}, PSNR {} dB, wrong pixels {:.3}% (tolerance {})",
            self.rmse,
            self.psnr_text(),
            self.wrong_fraction * 100.0,
            self.tolerance
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn infinite_psnr_is_the_string_inf() {
        let m = ImageMetrics {
            rmse: 0.0,
            psnr_db: f64::INFINITY,
            wrong_fraction: 0.0,
            tolerance: 8,
        };
        assert_eq!(
            m.to_json(4, 3).to_string(),
            r#"{"height":3,"psnr_db":"inf","rmse":0.0,"tolerance":8,"width":4,"wrong_fraction":0.0}"#
        );
        assert_eq!(
            m.to_string(),
            "RMSE 0.000, PSNR inf dB, wrong pixels 0.000% (tolerance 8)"
        );
    }

    #[test]
    fn finite_psnr_is_a_number() {
        let m = ImageMetrics {
            rmse: 2.5,
            psnr_db: 40.17,
            wrong_fraction: 0.25,
            tolerance: 0,
        };
        assert_eq!(m.to_json(1, 1)["psnr_db"], 40.17);
        assert_eq!(
            m.to_string(),
            "RMSE 2.500, PSNR 40.17 dB, wrong pixels 25.000% (tolerance 0)"
        );
    }
}
