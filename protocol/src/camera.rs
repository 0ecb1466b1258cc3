//! A pinhole camera with f64 frustum planes and projected-size math.
//!
//! Everything here is in world units and f64, so a scene far from the origin
//! culls as precisely as one at the origin; the renderer later subtracts
//! [`Camera::eye`] before anything becomes f32 (camera-relative rendering).

use glam::{DMat4, DVec3};

/// Where the viewer is and what the image is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    pub eye: DVec3,
    pub target: DVec3,
    pub up: DVec3,
    /// Vertical field of view in degrees.
    pub fov_y_deg: f64,
    pub width: u32,
    pub height: u32,
}

/// How a sphere relates to the view frustum.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Containment {
    Outside,
    Intersecting,
    Inside,
}

/// The camera's frame and planes, computed once per frame.
#[derive(Debug, Clone, Copy)]
pub struct View {
    pub eye: DVec3,
    pub forward: DVec3,
    pub right: DVec3,
    pub up: DVec3,
    /// Inward unit normals of the four side planes (all pass through the eye).
    planes: [DVec3; 4],
    /// Distance of the near plane along `forward`.
    pub near: f64,
    /// Pixels per world unit at distance 1: `height / (2 tan(fov/2))`.
    pub pixels_per_unit_at_1: f64,
    pub width: u32,
    pub height: u32,
    pub tan_half_x: f64,
    pub tan_half_y: f64,
}

impl Camera {
    /// Looks at a sphere from a direction given by azimuth and elevation
    /// (degrees, +Z up) at `distance` radii from its center.
    pub fn orbit(
        center: DVec3,
        radius: f64,
        azimuth_deg: f64,
        elevation_deg: f64,
        distance: f64,
        width: u32,
        height: u32,
    ) -> Self {
        let (az, el) = (azimuth_deg.to_radians(), elevation_deg.to_radians());
        let dir = DVec3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin());
        Self {
            eye: center + dir * radius * distance,
            target: center,
            up: DVec3::Z,
            fov_y_deg: 45.0,
            width,
            height,
        }
    }

    /// The per-frame view; `near` is in world units and must be positive.
    pub fn view(&self, near: f64) -> View {
        let forward = (self.target - self.eye)
            .try_normalize()
            .unwrap_or(DVec3::NEG_Z);
        // An up vector parallel to the view direction falls back to another axis.
        let right = forward
            .cross(self.up)
            .try_normalize()
            .unwrap_or_else(|| forward.any_orthonormal_vector());
        let up = right.cross(forward);
        let aspect = f64::from(self.width.max(1)) / f64::from(self.height.max(1));
        let fov = self.fov_y_deg.clamp(1e-3, 179.0).to_radians();
        let tan_half_y = (fov * 0.5).tan();
        let tan_half_x = tan_half_y * aspect;
        let planes = [
            (right + forward * tan_half_x).normalize(),
            (-right + forward * tan_half_x).normalize(),
            (up + forward * tan_half_y).normalize(),
            (-up + forward * tan_half_y).normalize(),
        ];
        View {
            eye: self.eye,
            forward,
            right,
            up,
            planes,
            near: near.max(f64::MIN_POSITIVE),
            pixels_per_unit_at_1: f64::from(self.height.max(1)) / (2.0 * tan_half_y),
            width: self.width,
            height: self.height,
            tan_half_x,
            tan_half_y,
        }
    }
}

impl View {
    /// Classifies a sphere against the side planes and the near plane.
    #[inline]
    pub fn classify(&self, center: DVec3, radius: f64) -> Containment {
        let rel = center - self.eye;
        let mut inside = true;
        let depth = rel.dot(self.forward) - self.near;
        if depth < -radius {
            return Containment::Outside;
        }
        inside &= depth >= radius;
        for n in &self.planes {
            let s = rel.dot(*n);
            if s < -radius {
                return Containment::Outside;
            }
            inside &= s >= radius;
        }
        if inside {
            Containment::Inside
        } else {
            Containment::Intersecting
        }
    }

    /// Whether `points` all lie strictly behind one side plane, or all
    /// behind the eye: a conservative test that their convex hull (a
    /// triangle, a tetrahedron) is out of view.
    pub fn all_outside(&self, points: &[DVec3]) -> bool {
        let behind = |n: DVec3| points.iter().all(|p| (*p - self.eye).dot(n) < 0.0);
        behind(self.forward) || self.planes.iter().any(|n| behind(*n))
    }

    /// Projected diameter of a sphere in pixels; infinite when the eye is
    /// inside or at the sphere, so such a node is always refined.
    #[inline]
    pub fn projected_diameter_px(&self, center: DVec3, radius: f64) -> f64 {
        let depth = (center - self.eye).dot(self.forward);
        if depth <= radius {
            return f64::INFINITY;
        }
        2.0 * radius * self.pixels_per_unit_at_1 / depth
    }

    /// Distance of a point's projection from the image centre, in units of
    /// the half-diagonal (0 at the centre, about 1 at a corner).
    pub fn distance_from_center(&self, point: DVec3) -> f64 {
        let rel = point - self.eye;
        let depth = rel.dot(self.forward);
        if depth <= 0.0 {
            return 2.0;
        }
        let x = rel.dot(self.right) / (depth * self.tan_half_x);
        let y = rel.dot(self.up) / (depth * self.tan_half_y);
        ((x * x + y * y) * 0.5).sqrt()
    }

    /// The view matrix with the eye at the origin (camera-relative).
    pub fn view_from_world_rotation(&self) -> DMat4 {
        DMat4::look_to_rh(DVec3::ZERO, self.forward, self.up)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> View {
        Camera {
            eye: DVec3::ZERO,
            target: DVec3::X,
            up: DVec3::Z,
            fov_y_deg: 90.0,
            width: 100,
            height: 100,
        }
        .view(0.1)
    }

    #[test]
    fn classifies_spheres() {
        let v = camera();
        assert_eq!(
            v.classify(DVec3::new(10.0, 0.0, 0.0), 1.0),
            Containment::Inside
        );
        assert_eq!(
            v.classify(DVec3::new(-10.0, 0.0, 0.0), 1.0),
            Containment::Outside
        );
        assert_eq!(
            v.classify(DVec3::new(10.0, 10.0, 0.0), 1.0),
            Containment::Intersecting
        );
        assert_eq!(
            v.classify(DVec3::new(10.0, 30.0, 0.0), 1.0),
            Containment::Outside
        );
    }

    #[test]
    fn projected_size_halves_with_distance() {
        let v = camera();
        let a = v.projected_diameter_px(DVec3::new(10.0, 0.0, 0.0), 1.0);
        let b = v.projected_diameter_px(DVec3::new(20.0, 0.0, 0.0), 1.0);
        assert!((a - 10.0).abs() < 1e-9, "{a}");
        assert!((a / b - 2.0).abs() < 1e-12);
        assert!(
            v.projected_diameter_px(DVec3::new(0.5, 0.0, 0.0), 1.0)
                .is_infinite()
        );
    }

    #[test]
    fn degenerate_up_vector_does_not_produce_nan() {
        let v = Camera {
            eye: DVec3::ZERO,
            target: DVec3::Z,
            up: DVec3::Z,
            fov_y_deg: 45.0,
            width: 10,
            height: 10,
        }
        .view(0.1);
        assert!(v.right.is_finite() && v.up.is_finite());
        assert_eq!(
            v.classify(DVec3::new(0.0, 0.0, 5.0), 0.1),
            Containment::Inside
        );
    }
}
