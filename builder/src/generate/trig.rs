//! Sine and cosine computed with basic IEEE arithmetic only.
//!
//! `f64::sin` and `f64::cos` call the platform's libm, whose last bit differs
//! between operating systems and C libraries. The generators promise bitwise
//! identical scenes everywhere, so they use this [`sin_cos`] instead: a
//! Cody-Waite reduction to `[-pi/4, pi/4]` followed by Taylor polynomials,
//! which needs only `+ - * round`, all correctly rounded by IEEE 754 and
//! never fused by rustc. Accuracy is a few ulps for the moderate arguments
//! the generators use (angles of a few turns), far beyond what geometry
//! needs.

/// pi/2 split in two: the f64 nearest to it, and the remainder, so that
/// the reduction `x - k * pi/2` keeps about 106 bits of pi.
const PIO2_HI: f64 = std::f64::consts::FRAC_PI_2;
const PIO2_LO: f64 = 6.123_233_995_736_766e-17;

/// `(sin x, cos x)` computed deterministically (see the module docs).
pub fn sin_cos(x: f64) -> (f64, f64) {
    let k = (x * (2.0 / std::f64::consts::PI)).round();
    let r = (x - k * PIO2_HI) - k * PIO2_LO;
    let r2 = r * r;
    // Taylor series up to r^17 / r^16: the first omitted term is below
    // (pi/4)^18 / 18! ~ 1e-18 on the reduced range.
    let s = r
        * (1.0
            + r2 * (-1.0 / 6.0
                + r2 * (1.0 / 120.0
                    + r2 * (-1.0 / 5040.0
                        + r2 * (1.0 / 362_880.0
                            + r2 * (-1.0 / 39_916_800.0
                                + r2 * (1.0 / 6_227_020_800.0
                                    + r2 * (-1.0 / 1_307_674_368_000.0
                                        + r2 * (1.0 / 355_687_428_096_000.0)))))))));
    let c = 1.0
        + r2 * (-0.5
            + r2 * (1.0 / 24.0
                + r2 * (-1.0 / 720.0
                    + r2 * (1.0 / 40_320.0
                        + r2 * (-1.0 / 3_628_800.0
                            + r2 * (1.0 / 479_001_600.0
                                + r2 * (-1.0 / 87_178_291_200.0
                                    + r2 * (1.0 / 20_922_789_888_000.0))))))));
    // `k` is a small whole number here; `rem_euclid` picks the quadrant.
    match (k as i64).rem_euclid(4) {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_libm_closely() {
        let mut x = -40.0;
        while x < 40.0 {
            let (s, c) = sin_cos(x);
            assert!((s - x.sin()).abs() < 1e-14, "sin {x}");
            assert!((c - x.cos()).abs() < 1e-14, "cos {x}");
            x += 0.0137;
        }
        assert_eq!(sin_cos(0.0), (0.0, 1.0));
    }
}
