//! Shade et al.'s error metric and safety zones (*Hierarchical Image
//! Caching*, section 3): how wrong a node's cached image looks from a new
//! eye, and how far the eye may move before it is wrong by more than ε.
//!
//! A cache made from eye `v0` is drawn on a quad in the plane of constant
//! depth (along `v0`'s view direction) through the node's box centre. A
//! point `a` of the node shows on the quad at `ã`, where the ray from `v0`
//! through `a` meets that plane; from `v0` they coincide. From another eye
//! `v` they subtend an angle θ, and the error is the largest θ over the
//! node's points, taken (as the paper does) over its box's eight corners:
//! fast, and not conservative for the points between them.
//!
//! Every eye from which `a` and `ã` subtend exactly ε lies on circles of
//! radius `r = |a − ã| / (2 sin ε)` through both (formula 3), so a sphere
//! round `v0` that stays outside them is safe. Its radius, formula (4),
//! `d = sqrt(h² + r² + 2hr sin ε) − r`, is computed here in an equal form
//! without the subtraction of two nearly equal numbers (as ε goes to 0, `r`
//! grows without bound and the printed form loses every digit), and with
//! `h` the distance from `v0` to the *nearer* of `a` and `ã`: the paper's
//! `h = |v0 − a|` is the distance to the nearer end of the chord only when
//! the corner is in front of the quad; behind it, the printed radius is too
//! large and eyes inside it see more than ε.

use glam::DVec3;

/// The plane of a cached image's quad: the eye it was made from, its view
/// direction, and the depth of the node's box centre along it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QuadPlane {
    pub eye: DVec3,
    /// Unit view direction at the time the cache was made.
    pub forward: DVec3,
    /// Depth of the quad (the box centre's) along `forward`, positive.
    pub depth: f64,
}

impl QuadPlane {
    /// The quad of a node whose box centre is `centre`, cached from `eye`
    /// looking along `forward`; `None` when `forward` is not a direction
    /// or the centre is not in front of the eye.
    pub fn new(eye: DVec3, forward: DVec3, centre: DVec3) -> Option<Self> {
        let forward = forward.try_normalize()?;
        let depth = (centre - eye).dot(forward);
        (depth > 0.0 && depth.is_finite()).then_some(Self {
            eye,
            forward,
            depth,
        })
    }

    /// `ã`: where `a` shows on the quad, the point of its plane on the ray
    /// from the eye through `a`; `None` when `a` is not in front of the eye
    /// (a cache is never made of a node with a corner behind the eye).
    pub fn project(&self, a: DVec3) -> Option<DVec3> {
        let depth = (a - self.eye).dot(self.forward);
        (depth > 0.0).then(|| self.eye + (a - self.eye) * (self.depth / depth))
    }
}

/// The angle at `v` between the directions to `a` and `b`, in radians; 0
/// when `v` is at either. `atan2` of the cross and dot products keeps its
/// precision at small angles, where `acos` of a dot product loses it.
pub fn angle(v: DVec3, a: DVec3, b: DVec3) -> f64 {
    let (x, y) = (a - v, b - v);
    let sin = x.cross(y).length();
    let cos = x.dot(y);
    if sin == 0.0 && cos == 0.0 {
        return 0.0;
    }
    sin.atan2(cos)
}

/// `Error(v, v0)` (formula 1) over `corners`: the largest angle at `v`
/// between a corner and its image on the quad; `None` when a corner is not
/// in front of the quad's eye.
pub fn error(quad: &QuadPlane, corners: &[DVec3], v: DVec3) -> Option<f64> {
    let mut worst = 0.0f64;
    for &a in corners {
        worst = worst.max(angle(v, a, quad.project(a)?));
    }
    Some(worst)
}

/// The safety radius round `v0` for a point `a` and its image `a_tilde`
/// at tolerance `epsilon` (radians): no eye closer to `v0` than this sees
/// them more than `epsilon` apart.
///
/// With `m = |a − ã|` and `s = sin ε`, `r = m / 2s`, and formula (4)
/// multiplied through by its conjugate and by `2s` reads
/// `d = 2s (h² + hm) / (sqrt(4s²h² + 4s²hm + m²) + m)`: no subtraction,
/// no infinite `r` at ε = 0 (it gives 0), and `h` (the point on the
/// quad, `m` = 0) for a corner that lies on the quad.
pub fn safety_radius(v0: DVec3, a: DVec3, a_tilde: DVec3, epsilon: f64) -> f64 {
    // Also refuses NaN: no tolerance, no zone.
    if epsilon.is_nan() || epsilon <= 0.0 {
        return 0.0;
    }
    let s = epsilon.min(std::f64::consts::FRAC_PI_2).sin();
    let m = a.distance(a_tilde);
    // The nearer end of the chord: the circles are measured from it.
    let h = v0.distance(a).min(v0.distance(a_tilde));
    let numerator = 2.0 * s * (h * h + h * m);
    let denominator = (4.0 * s * s * h * (h + m) + m * m).sqrt() + m;
    if denominator > 0.0 && numerator.is_finite() {
        numerator / denominator
    } else {
        0.0
    }
}

/// An axis-aligned box of eye positions; empty when `min` exceeds `max`
/// on some axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Zone {
    pub min: DVec3,
    pub max: DVec3,
}

impl Zone {
    /// The zone that holds no eye.
    pub const EMPTY: Self = Self {
        min: DVec3::splat(f64::INFINITY),
        max: DVec3::splat(f64::NEG_INFINITY),
    };

    /// The zone that holds every eye: what geometry drawn exactly asks of
    /// an enclosing cache.
    pub const EVERYWHERE: Self = Self {
        min: DVec3::splat(f64::NEG_INFINITY),
        max: DVec3::splat(f64::INFINITY),
    };

    /// The axis-aligned cube inscribed in the sphere of radius `d` round
    /// `centre` (half its side `d / √3`); empty for no radius.
    pub fn around(centre: DVec3, d: f64) -> Self {
        if d.is_nan() || d <= 0.0 || !centre.is_finite() {
            return Self::EMPTY;
        }
        let half = DVec3::splat(d / 3f64.sqrt());
        Self {
            min: centre - half,
            max: centre + half,
        }
    }

    /// The eyes in both zones (an interior node's zone is its own
    /// intersected with its children's).
    pub fn intersect(&self, other: &Self) -> Self {
        let z = Self {
            min: self.min.max(other.min),
            max: self.max.min(other.max),
        };
        if z.is_empty() { Self::EMPTY } else { z }
    }

    pub fn is_empty(&self) -> bool {
        !(self.min.cmple(self.max).all())
    }

    pub fn contains(&self, v: DVec3) -> bool {
        v.cmpge(self.min).all() && v.cmple(self.max).all()
    }

    /// Frames before an eye at `eye`, moving `velocity` per frame and
    /// speeding up by `acceleration` per frame squared, first leaves the
    /// zone: the paper's non-conservative life span, extrapolated from the
    /// viewer's motion. 0 outside the zone; `cap` for a viewer that never
    /// leaves (standing still, say), so no life span is unbounded.
    pub fn frames_until_exit(
        &self,
        eye: DVec3,
        velocity: DVec3,
        acceleration: DVec3,
        cap: u32,
    ) -> u32 {
        if !self.contains(eye) {
            return 0;
        }
        let mut exit = f64::INFINITY;
        for axis in 0..3 {
            let (p, v, a) = (eye[axis], velocity[axis], acceleration[axis]);
            for bound in [self.min[axis], self.max[axis]] {
                if let Some(t) = first_positive_root(0.5 * a, v, p - bound) {
                    exit = exit.min(t);
                }
            }
        }
        if exit.is_finite() {
            // Frames wholly inside: the eye is still in at frame floor(t).
            exit.floor().clamp(0.0, f64::from(cap)) as u32
        } else {
            cap
        }
    }
}

/// The smallest `t > 0` with `a t² + b t + c = 0`, or `None`. The roots
/// are taken as `q / a` and `c / q` with `q = −(b + sign(b) sqrt(disc)) / 2`,
/// so neither subtracts nearly equal numbers.
fn first_positive_root(a: f64, b: f64, c: f64) -> Option<f64> {
    let roots: [Option<f64>; 2] = if a == 0.0 {
        [(b != 0.0).then(|| -c / b), None]
    } else {
        let disc = b * b - 4.0 * a * c;
        if disc < 0.0 {
            return None;
        }
        let q = -0.5 * (b + b.signum() * disc.sqrt());
        if q == 0.0 {
            // b = 0 and c = 0: a root at 0 only.
            [Some(0.0), None]
        } else {
            [Some(q / a), Some(c / q)]
        }
    };
    roots
        .into_iter()
        .flatten()
        .filter(|t| *t > 0.0 && t.is_finite())
        .min_by(f64::total_cmp)
}

/// A node's safety zone for a cache made on `quad`: the cube inscribed in
/// the sphere of the smallest corner radius (section 3); `None` when a
/// corner is not in front of the quad's eye.
pub fn safety_zone(quad: &QuadPlane, corners: &[DVec3], epsilon: f64) -> Option<Zone> {
    let mut d = f64::INFINITY;
    for &a in corners {
        d = d.min(safety_radius(quad.eye, a, quad.project(a)?, epsilon));
    }
    Some(if d.is_finite() {
        Zone::around(quad.eye, d)
    } else {
        Zone::EMPTY
    })
}

/// ε given in pixels as an angle: what `epsilon_px` pixels subtend at the
/// centre of an image `height_px` tall with a vertical field of view of
/// `fov_y_deg` (the paper converts "using the current resolution and
/// field-of-view angle"). 0 for a degenerate view.
pub fn epsilon_angle(epsilon_px: f64, fov_y_deg: f64, height_px: u32) -> f64 {
    let tan_half = (fov_y_deg.to_radians() * 0.5).tan();
    if !(epsilon_px > 0.0 && height_px > 0 && tan_half > 0.0 && tan_half.is_finite()) {
        return 0.0;
    }
    // A pixel at the centre spans 2 tan_half / height on the unit plane.
    2.0 * (epsilon_px * tan_half / f64::from(height_px)).atan()
}

#[cfg(test)]
#[path = "safety_tests.rs"]
mod tests;
