//! What is under the cursor: the nearest drawn splat along the pixel's ray
//! (the double-click focus). On the CPU, over the cut already in memory:
//! no depth buffer is read back, which a browser could not do in a frame.

use farfield_protocol::camera::Camera;
use farfield_traverse::spheres::Splat;
use glam::DVec3;

/// The point where the ray through pixel (`x`, `y`) (from the top left)
/// first meets a drawn splat's sphere, if any does.
pub fn pick_splat(splats: &[Splat], camera: &Camera, x: f32, y: f32) -> Option<DVec3> {
    first_hit(splats, camera, x, y).map(|(point, _)| point)
}

/// The center of the splat the ray through pixel (`x`, `y`) first meets:
/// a point of the scene itself (a measurement's), not the surface of the
/// sphere drawn for it, which stands out from it by the splat's radius.
pub fn pick_point(splats: &[Splat], camera: &Camera, x: f32, y: f32) -> Option<DVec3> {
    first_hit(splats, camera, x, y).map(|(_, center)| center)
}

/// Where the ray first meets a splat's sphere, and that splat's center.
fn first_hit(splats: &[Splat], camera: &Camera, x: f32, y: f32) -> Option<(DVec3, DVec3)> {
    let view = camera.view(1.0);
    let (w, h) = (f64::from(view.width.max(1)), f64::from(view.height.max(1)));
    let ndc_x = (f64::from(x) + 0.5) / w * 2.0 - 1.0;
    let ndc_y = 1.0 - (f64::from(y) + 0.5) / h * 2.0;
    let dir = (view.forward
        + view.right * (ndc_x * view.tan_half_x)
        + view.up * (ndc_y * view.tan_half_y))
        .try_normalize()?;
    let mut best: Option<(f64, DVec3)> = None;
    for s in splats {
        let to = s.center - view.eye;
        let along = to.dot(dir);
        let miss2 = to.length_squared() - along * along;
        let r2 = s.radius * s.radius;
        if along <= 0.0 || miss2 > r2 {
            continue;
        }
        let hit = along - (r2 - miss2).sqrt();
        if hit > 0.0 && best.is_none_or(|(b, _)| hit < b) {
            best = Some((hit, s.center));
        }
    }
    best.map(|(t, center)| (view.eye + dir * t, center))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn splat(center: DVec3, radius: f64) -> Splat {
        Splat {
            center,
            radius,
            normal: None,
            color: None,
            node: 0,
        }
    }

    #[test]
    fn the_nearest_sphere_under_the_pixel_is_picked() {
        let camera = Camera {
            eye: DVec3::new(10.0, 0.0, 0.0),
            target: DVec3::ZERO,
            up: DVec3::Z,
            fov_y_deg: 45.0,
            width: 101,
            height: 101,
        };
        let far = splat(DVec3::ZERO, 1.0);
        let near = splat(DVec3::new(5.0, 0.0, 0.0), 0.5);
        let hit = pick_splat(&[far, near], &camera, 50.0, 50.0).unwrap();
        assert!((hit - DVec3::new(5.5, 0.0, 0.0)).length() < 1e-9, "{hit}");
        // A corner pixel misses both.
        assert_eq!(pick_splat(&[far, near], &camera, 0.0, 0.0), None);
    }
}
