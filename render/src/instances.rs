//! Splats to GPU instances: camera-relative, in view space, f32.
//!
//! Scenes sit up to 1e7 units from the origin, where f32 keeps about one
//! unit of precision. So each center is made relative to the eye and
//! rotated into the camera frame in f64, and only then becomes f32: what
//! the GPU sees is small near the camera, where precision matters.

use bytemuck::{Pod, Zeroable};
use farfield_protocol::camera::View;
use farfield_traverse::spheres::Splat;

use crate::{Clip, ColorBy};

/// Color of splats whose scene has no colors.
pub const DEFAULT_COLOR: [u8; 3] = [200, 200, 200];

/// One splat as the vertex shader reads it (instance step, 28 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub(crate) struct GpuSplat {
    /// Center in view space: (right, up, depth along forward).
    pub center: [f32; 3],
    pub radius: f32,
    /// World-space unit normal as snorm16; w = 32767 when the splat has a
    /// normal, 0 for a sphere (shaded as a ball impostor).
    pub normal: [i16; 4],
    /// sRGB bytes; alpha unused.
    pub color: [u8; 4],
}

/// Bytes per instance.
pub(crate) const STRIDE: u64 = std::mem::size_of::<GpuSplat>() as u64;

/// Fills `out` with the splats whose center lies in front of the eye and
/// returns the near-plane distance: the smallest `depth - radius` of those
/// splats, but at least 1e-6 of the farthest `depth + radius`.
pub(crate) fn pack(
    view: &View,
    splats: &[Splat],
    color_by: ColorBy,
    clip: Option<Clip>,
    out: &mut Vec<GpuSplat>,
) -> f64 {
    out.clear();
    out.reserve(splats.len());
    let (mut nearest, mut farthest) = (f64::INFINITY, 0.0f64);
    for s in splats {
        let rel = s.center - view.eye;
        let depth = rel.dot(view.forward);
        // Also drops NaN: a quad is drawn at its center's depth, so a center
        // behind the eye is never visible.
        if !(depth > 0.0 && s.radius.is_finite()) || clip.is_some_and(|c| !c.keeps(s.center)) {
            continue;
        }
        let radius = s.radius.max(0.0);
        nearest = nearest.min(depth - radius);
        farthest = farthest.max(depth + radius);
        let normal = match s.normal {
            Some(n) => [snorm16(n.x), snorm16(n.y), snorm16(n.z), i16::MAX],
            None => [0; 4],
        };
        let [r, g, b] = color_by.color(s.center, s.color.unwrap_or(DEFAULT_COLOR));
        out.push(GpuSplat {
            center: [
                rel.dot(view.right) as f32,
                rel.dot(view.up) as f32,
                depth as f32,
            ],
            radius: radius as f32,
            normal,
            color: [r, g, b, 255],
        });
    }
    if out.is_empty() {
        return 1.0;
    }
    nearest.max(farthest * 1e-6).max(f64::MIN_POSITIVE)
}

pub(crate) fn snorm16(x: f32) -> i16 {
    // `as` saturates and maps NaN to 0.
    (x.clamp(-1.0, 1.0) * 32767.0).round() as i16
}

#[cfg(test)]
mod tests {
    use super::*;
    use farfield_protocol::camera::Camera;
    use glam::{DVec3, Vec3};

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
    fn stride_is_28_bytes() {
        assert_eq!(STRIDE, 28);
    }

    #[test]
    fn far_from_origin_keeps_precision() {
        // Eye at 1e7: absolute f32 positions would be quantized to 1 unit.
        let base = DVec3::new(1e7, -2e7, 3e6);
        let camera = Camera {
            eye: base,
            target: base + DVec3::X,
            up: DVec3::Z,
            fov_y_deg: 60.0,
            width: 64,
            height: 64,
        };
        let view = camera.view(1.0);
        let splats = [splat(base + DVec3::new(2.0, 0.25, -0.125), 0.01)];
        let mut out = Vec::new();
        pack(&view, &splats, ColorBy::Rgb, None, &mut out);
        // Looking along +X with Z up, right is -Y.
        assert_eq!(out[0].center, [-0.25, -0.125, 2.0]);
        assert_eq!(out[0].radius, 0.01);
        assert_eq!(out[0].color, [200, 200, 200, 255]);
        assert_eq!(out[0].normal, [0; 4]);
    }

    /// A 64x64 camera at the origin looking down +X, +Z up.
    fn camera_down_x() -> Camera {
        Camera {
            eye: DVec3::ZERO,
            target: DVec3::X,
            up: DVec3::Z,
            fov_y_deg: 60.0,
            width: 64,
            height: 64,
        }
    }

    #[test]
    fn near_plane_follows_the_depth_range_and_drops_splats_behind() {
        let camera = camera_down_x();
        let view = camera.view(1.0);
        let mut out = Vec::new();
        let near = pack(
            &view,
            &[
                splat(DVec3::new(10.0, 0.0, 0.0), 1.0),
                splat(DVec3::new(100.0, 0.0, 0.0), 1.0),
                splat(DVec3::new(-5.0, 0.0, 0.0), 1.0),
                splat(DVec3::new(f64::NAN, 0.0, 0.0), 1.0),
            ],
            ColorBy::Rgb,
            None,
            &mut out,
        );
        assert_eq!(out.len(), 2);
        assert_eq!(near, 9.0);
        // A splat around the eye: the floor at 1e-6 of the far distance.
        let near = pack(
            &view,
            &[splat(DVec3::new(0.5, 0.0, 0.0), 1e3)],
            ColorBy::Rgb,
            None,
            &mut out,
        );
        assert!((near - 1000.5e-6).abs() < 1e-12, "{near}");
        assert_eq!(pack(&view, &[], ColorBy::Rgb, None, &mut out), 1.0);
        assert!(out.is_empty());
    }

    #[test]
    fn normals_and_colors_are_packed() {
        let camera = camera_down_x();
        let mut out = Vec::new();
        let s = Splat {
            normal: Some(Vec3::new(0.0, -1.0, 0.5)),
            color: Some([1, 2, 3]),
            ..splat(DVec3::new(3.0, 0.0, 0.0), 1.0)
        };
        pack(&camera.view(1.0), &[s], ColorBy::Rgb, None, &mut out);
        assert_eq!(out[0].normal, [0, -32767, 16384, 32767]);
        assert_eq!(out[0].color, [1, 2, 3, 255]);
    }
}
