//! Octahedral packing of unit vectors into 32 bits (two 16-bit snorms):
//! error about 3e-5 radians, used for the sphere builder's working normals
//! and the color-cube octree's leaf-geometry normals.

use glam::Vec3;

/// Octahedral packing of a unit vector into two 16-bit snorms; error about
/// 3e-5 radians, far below the 14-bit file normals'. Zero packs as +Z.
#[inline]
pub fn pack_normal(n: Vec3) -> u32 {
    // The projection divides by the L1 norm, so any length works: no
    // normalization first, only a guard against zero and non-finite input.
    let l1 = n.x.abs() + n.y.abs() + n.z.abs();
    let (n, l1) = if l1 > 0.0 && l1.is_finite() {
        (n, l1)
    } else {
        (Vec3::Z, 1.0)
    };
    let (mut x, mut y) = (n.x / l1, n.y / l1);
    if n.z < 0.0 {
        let (ox, oy) = (x, y);
        x = (1.0 - oy.abs()) * ox.signum();
        y = (1.0 - ox.abs()) * oy.signum();
    }
    let q = |v: f32| ((v.clamp(-1.0, 1.0) * 32767.0).round() as i16) as u16;
    u32::from(q(x)) | u32::from(q(y)) << 16
}

/// Inverse of [`pack_normal`].
#[inline]
pub fn unpack_normal(p: u32) -> Vec3 {
    let x = f32::from(p as u16 as i16) / 32767.0;
    let y = f32::from((p >> 16) as u16 as i16) / 32767.0;
    let z = 1.0 - x.abs() - y.abs();
    let (x, y) = if z < 0.0 {
        ((1.0 - y.abs()) * x.signum(), (1.0 - x.abs()) * y.signum())
    } else {
        (x, y)
    };
    Vec3::new(x, y, z).try_normalize().unwrap_or(Vec3::Z)
}
