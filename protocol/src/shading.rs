//! The one fixed light that both the color-cube builder and the client's
//! geometry pass shade with.
//!
//! A color-cube face is the cell's geometry *as shaded*, baked at build
//! time (Chamberlain et al. 1996, section 4), so the builder and the
//! renderer must agree on the light or cubes and geometry would not match
//! where they meet. Lighting is two-sided: a face is lit by its side that
//! faces the viewer, since an orthographic view through a cell face sees
//! whichever side of a triangle turns toward it. The client's WGSL repeats
//! these constants (`geometry.wgsl`); a test compares the two.

use glam::Vec3;

/// Unit direction toward the light, world space (the splat renderer's
/// default light too).
pub fn light_dir() -> Vec3 {
    Vec3::new(0.4, 0.3, 0.866).normalize()
}

/// Share of the color that is lit whatever the orientation.
pub const AMBIENT: f32 = 0.3;
/// Share lit by `max(n . l, 0)`.
pub const DIFFUSE: f32 = 0.7;

/// Color of a surface with `normal`, seen from direction `toward_viewer`
/// (both world space; need not be unit), base color in 0..1.
pub fn shade(base: Vec3, normal: Vec3, toward_viewer: Vec3) -> Vec3 {
    let n = normal.try_normalize().unwrap_or(Vec3::Z);
    // Two-sided: light the side that faces the viewer.
    let n = if n.dot(toward_viewer) < 0.0 { -n } else { n };
    base * (AMBIENT + DIFFUSE * n.dot(light_dir()).max(0.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_back_of_a_surface_is_lit_like_its_front() {
        let c = Vec3::ONE;
        let front = shade(c, Vec3::Z, Vec3::Z);
        let back = shade(c, -Vec3::Z, Vec3::Z);
        assert_eq!(front, back);
        assert!((front.x - (AMBIENT + DIFFUSE * light_dir().z)).abs() < 1e-6);
        // Facing away from the light: ambient only.
        let dark = shade(c, -light_dir(), -light_dir());
        assert!((dark.x - AMBIENT).abs() < 1e-6);
    }
}
