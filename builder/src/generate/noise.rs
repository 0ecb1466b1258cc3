//! Deterministic 2D gradient noise and fractal sums of it.
//!
//! Terrain needs smooth, band-limited randomness: [`gradient`] is classic
//! Perlin-style gradient noise, with the lattice gradients picked by the
//! integer hash of the cell corner (no permutation table, so any seed
//! works and the field is infinite), a quintic fade so the surface has
//! continuous curvature, and f64 arithmetic throughout. [`fbm`] sums octaves
//! (fractional Brownian motion) for rolling land; [`fbm_and_ridged`] also
//! folds each octave (`1 - |n|`) into sharp crests for mountains. Each octave is rotated
//! by an exact rational rotation and shifted so lattice lines of different
//! octaves do not line up into visible grid artifacts.
//!
//! Every value depends only on `(seed, x, y)`, so the field can be evaluated
//! in any order, in parallel, at any resolution, with the same result.

/// Eight unit gradient directions (axes and diagonals).
const GRADIENTS: [(f64, f64); 8] = [
    (1.0, 0.0),
    (-1.0, 0.0),
    (0.0, 1.0),
    (0.0, -1.0),
    (
        std::f64::consts::FRAC_1_SQRT_2,
        std::f64::consts::FRAC_1_SQRT_2,
    ),
    (
        -std::f64::consts::FRAC_1_SQRT_2,
        std::f64::consts::FRAC_1_SQRT_2,
    ),
    (
        std::f64::consts::FRAC_1_SQRT_2,
        -std::f64::consts::FRAC_1_SQRT_2,
    ),
    (
        -std::f64::consts::FRAC_1_SQRT_2,
        -std::f64::consts::FRAC_1_SQRT_2,
    ),
];

/// The quintic fade `6t^5 - 15t^4 + 10t^3`: zero first and second
/// derivatives at both ends, so cell borders do not show in shading.
#[inline]
fn fade(t: f64) -> f64 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

/// Odd multipliers spreading lattice coordinates over 64 bits.
const KX: u64 = 0x9E37_79B9_7F4A_7C15;
const KY: u64 = 0xC2B2_AE3D_27D4_EB4F;

/// Dot product of the gradient picked by lattice hash `h` with the offset
/// `(dx, dy)` from that corner to the point.
///
/// The corner's hash is `seed ^ ix * KX ^ iy * KY` finished by one
/// xor-shift and multiply, whose top three bits pick the gradient. That is
/// far cheaper than a full 64-bit finalizer per corner, and noise is the
/// terrain's inner loop (15 evaluations per vertex at `size=2048`).
#[inline]
fn corner(h: u64, dx: f64, dy: f64) -> f64 {
    let h = (h ^ (h >> 31)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    let (gx, gy) = GRADIENTS[(h >> 61) as usize];
    gx * dx + gy * dy
}

/// `x` rounded down to an integer. `f64::floor` is a libm call on baseline
/// x86-64 (no SSE4.1); this is exact for the `|x| < 2^53` noise ever sees
/// and saturates beyond.
#[inline]
fn floor(x: f64) -> i64 {
    let i = x as i64;
    if (i as f64) > x { i - 1 } else { i }
}

/// Gradient noise at `(x, y)`: smooth, zero on lattice points, roughly in
/// `[-1, 1]` (scaled so typical octaves use most of that range).
pub fn gradient(seed: u64, x: f64, y: f64) -> f64 {
    let (ix, iy) = (floor(x), floor(y));
    let (fx, fy) = (x - ix as f64, y - iy as f64);
    let hx0 = (ix as u64).wrapping_mul(KX);
    let hx1 = hx0.wrapping_add(KX);
    let hy0 = (iy as u64).wrapping_mul(KY);
    let (hy0, hy1) = (seed ^ hy0, seed ^ hy0.wrapping_add(KY));
    let n00 = corner(hx0 ^ hy0, fx, fy);
    let n10 = corner(hx1 ^ hy0, fx - 1.0, fy);
    let n01 = corner(hx0 ^ hy1, fx, fy - 1.0);
    let n11 = corner(hx1 ^ hy1, fx - 1.0, fy - 1.0);
    let (u, v) = (fade(fx), fade(fy));
    let a = n00 + u * (n10 - n00);
    let b = n01 + u * (n11 - n01);
    // 2D gradient noise peaks at sqrt(1/2); scale toward [-1, 1].
    (a + v * (b - a)) * std::f64::consts::SQRT_2
}

/// Moves the sample point between octaves: a rotation by the exact
/// Pythagorean angle (cos, sin) = (4/5, 3/5) and a shift.
#[inline]
fn next_octave(x: f64, y: f64) -> (f64, f64) {
    (
        2.0 * (0.8 * x - 0.6 * y) + 17.31,
        2.0 * (0.6 * x + 0.8 * y) - 9.87,
    )
}

/// A distinct lattice seed per octave (cheap: [`corner`] mixes it anyway).
#[inline]
fn octave_seed(seed: u64, octave: u32) -> u64 {
    seed.wrapping_add(u64::from(octave).wrapping_mul(0xD6E8_FEB8_6659_FD93))
}

/// Fractional Brownian motion: `octaves` of [`gradient`] noise, each twice
/// the frequency and half the amplitude of the last, normalized by the total
/// amplitude so the result stays roughly in `[-1, 1]`.
pub fn fbm(seed: u64, x: f64, y: f64, octaves: u32) -> f64 {
    let (mut x, mut y) = (x, y);
    let (mut sum, mut amplitude, mut total) = (0.0, 1.0, 0.0);
    for octave in 0..octaves {
        sum += amplitude * gradient(octave_seed(seed, octave), x, y);
        total += amplitude;
        amplitude *= 0.5;
        (x, y) = next_octave(x, y);
    }
    if total > 0.0 { sum / total } else { 0.0 }
}

/// [`fbm`] and ridged multifractal noise from the same octaves, for the
/// price of one: terrain wants both, and noise evaluation is its cost.
///
/// The ridged sum lies in `[0, 1]`: each octave `n` is folded to
/// `(1 - |n|)^2`, which turns zero crossings into sharp crests, and finer
/// octaves are weighted by the coarser result so detail gathers on ridges.
/// Sharing octaves also makes mountain ridges follow the rolling relief.
pub fn fbm_and_ridged(seed: u64, x: f64, y: f64, octaves: u32) -> (f64, f64) {
    let (mut x, mut y) = (x, y);
    let (mut sum, mut ridges, mut amplitude, mut total, mut weight) = (0.0, 0.0, 1.0, 0.0, 1.0);
    for octave in 0..octaves {
        let n = gradient(octave_seed(seed, octave), x, y);
        sum += amplitude * n;
        let ridge = (1.0 - n.abs()).max(0.0);
        let ridge = ridge * ridge * weight;
        weight = (ridge * 2.0).clamp(0.0, 1.0);
        ridges += amplitude * ridge;
        total += amplitude;
        amplitude *= 0.5;
        (x, y) = next_octave(x, y);
    }
    if total > 0.0 {
        (sum / total, ridges / total)
    } else {
        (0.0, 0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_is_bounded_smooth_and_seeded() {
        let mut max: f64 = 0.0;
        for i in 0..200 {
            for j in 0..200 {
                let (x, y) = (i as f64 * 0.173 - 17.0, j as f64 * 0.191 - 19.0);
                let n = gradient(3, x, y);
                assert!(n.abs() <= 1.0 + 1e-12, "{n}");
                max = max.max(n.abs());
                // Continuity: a tiny step changes the value a little.
                assert!((gradient(3, x + 1e-6, y) - n).abs() < 1e-4);
                let f = fbm(3, x, y, 6);
                assert!(f.abs() <= 1.0 + 1e-12);
                let (f5, r) = fbm_and_ridged(3, x, y, 5);
                assert_eq!(f5, fbm(3, x, y, 5));
                assert!((0.0..=1.0).contains(&r));
            }
        }
        assert!(max > 0.5, "noise uses its range: {max}");
        assert_eq!(gradient(3, 2.0, 5.0), 0.0);
        assert_ne!(gradient(3, 0.5, 0.5), gradient(4, 0.5, 0.5));
    }
}
