//! Measurements on picked points (Potree's measuring tools): with the tool
//! on, each click picks the drawn point under the cursor; the panel shows
//! the path's length, the height from the first point to the last, and,
//! from three points, the area of the polygon they close; the picture
//! shows the path.

use glam::DVec3;
use serde::Serialize;

/// The tool's points, in world units, in the order they were picked.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Measure {
    /// Clicks pick points.
    pub on: bool,
    pub points: Vec<DVec3>,
}

/// What the points measure, for the panel and the page's status.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Measured {
    pub points: Vec<[f64; 3]>,
    /// Along the path through every point.
    pub distance: f64,
    /// From the first point's height (Z) to the last's.
    pub height: f64,
    /// Of the polygon the points close (three or more), in its own plane.
    pub area: Option<f64>,
}

impl Measure {
    /// Turns the tool on or off; off forgets the points.
    pub fn toggle(&mut self) {
        self.on = !self.on;
        if !self.on {
            self.points.clear();
        }
    }

    /// What the points measure; `None` before the first point.
    pub fn measured(&self) -> Option<Measured> {
        let (first, last) = (self.points.first()?, self.points.last()?);
        let distance = self.points.windows(2).map(|w| w[0].distance(w[1])).sum();
        Some(Measured {
            points: self.points.iter().map(|p| p.to_array()).collect(),
            distance,
            height: last.z - first.z,
            area: (self.points.len() >= 3).then(|| polygon_area(&self.points)),
        })
    }
}

/// The area of the polygon through `points`, closed, by Newell's normal:
/// exact for a planar polygon in any orientation, and relative to the
/// first point, so large coordinates lose no precision.
fn polygon_area(points: &[DVec3]) -> f64 {
    let origin = points[0];
    let mut normal = DVec3::ZERO;
    for (i, p) in points.iter().enumerate() {
        let q = points[(i + 1) % points.len()];
        normal += (*p - origin).cross(q - origin);
    }
    normal.length() * 0.5
}

/// Where `p` is on a `camera`'s image, in pixels from the top left; `None`
/// behind the eye.
pub fn project(camera: &farfield_protocol::camera::Camera, p: DVec3) -> Option<(f64, f64)> {
    let view = camera.view(1.0);
    let rel = p - view.eye;
    let depth = rel.dot(view.forward);
    if depth <= 0.0 || view.tan_half_x <= 0.0 || view.tan_half_y <= 0.0 {
        return None;
    }
    let ndc_x = rel.dot(view.right) / (depth * view.tan_half_x);
    let ndc_y = rel.dot(view.up) / (depth * view.tan_half_y);
    let (w, h) = (f64::from(view.width), f64::from(view.height));
    Some(((ndc_x + 1.0) * 0.5 * w, (1.0 - ndc_y) * 0.5 * h))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_path_measures_its_length_height_and_closed_area() {
        let mut m = Measure::default();
        assert_eq!(m.measured(), None);
        m.toggle();
        let base = DVec3::new(5e6, -3e6, 100.0);
        for p in [(0.0, 0.0, 0.0), (3.0, 0.0, 0.0), (3.0, 4.0, 2.0)] {
            m.points.push(base + DVec3::from(p));
        }
        let r = m.measured().unwrap();
        assert!((r.distance - (3.0 + 20f64.sqrt())).abs() < 1e-9, "{r:?}");
        assert_eq!(r.height, 2.0);
        // A right triangle with legs 3 and |(0, 4, 2)| = sqrt(20).
        let area = r.area.unwrap();
        assert!((area - 0.5 * 3.0 * 20f64.sqrt()).abs() < 1e-9, "{area}");
        m.toggle();
        assert!(m.points.is_empty() && !m.on);
    }

    /// Projecting a picked point gives back the pixel it was picked at.
    #[test]
    fn a_picked_point_projects_to_its_pixel() {
        use farfield_traverse::spheres::Splat;
        let camera = farfield_protocol::camera::Camera {
            eye: DVec3::new(10.0, -20.0, 30.0),
            target: DVec3::new(10.0, 0.0, 0.0),
            up: DVec3::Z,
            fov_y_deg: 50.0,
            width: 320,
            height: 240,
        };
        // A large ball beyond the target, in front of the eye.
        let forward = (camera.target - camera.eye).normalize();
        let wall = Splat {
            center: camera.target + forward * 2000.0,
            radius: 1e3,
            normal: None,
            color: None,
            node: 0,
        };
        let p = crate::pick::pick_splat(&[wall], &camera, 100.0, 60.0).unwrap();
        let (x, y) = project(&camera, p).unwrap();
        assert!(
            (x - 100.5).abs() < 1e-6 && (y - 60.5).abs() < 1e-6,
            "{x} {y}"
        );
        assert_eq!(project(&camera, DVec3::new(10.0, -30.0, 30.0)), None);
    }
}
