//! Small pieces several importers share: polygon fans, unit colors and
//! the repair of unusable input normals.

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::zero_area::is_zero_area;

/// Fan-triangulates a convex polygon: `(p0, p[i], p[i+1])`.
pub(crate) fn fan(polygon: &[u32], out: &mut Vec<[u32; 3]>) {
    if let Some((&first, rest)) = polygon.split_first() {
        out.extend(rest.windows(2).map(|w| [first, w[0], w[1]]));
    }
}

/// A 0..1 color value as 8 bits (clamped; NaN becomes 0).
pub(crate) fn unit_color(v: f64) -> u8 {
    (v.clamp(0.0, 1.0) * 255.0).round() as u8
}

/// Normalizes input normals. A zero or non-finite normal is replaced by the
/// area-weighted normal of the triangles around its vertex, zero-area ones
/// left out as the leaf sizing leaves them out (or +Z where there are none
/// with an area); without triangles such a normal drops all normals, and
/// the builder estimates them from neighbours instead.
pub(crate) fn unit_normals(
    mut normals: Vec<Vec3>,
    positions: &[DVec3],
    triangles: Option<&[[u32; 3]]>,
) -> Option<Vec<Vec3>> {
    // On all threads; an unusable normal is left as it is and found again
    // below (there are none in nearly every file).
    let all_usable = normals
        .par_chunks_mut(1 << 12)
        .map(|chunk| {
            let mut usable = true;
            for n in chunk {
                match unit_normal(*n) {
                    Some(unit) => *n = unit,
                    None => usable = false,
                }
            }
            usable
        })
        .reduce(|| true, |a, b| a && b);
    if all_usable {
        return Some(normals);
    }
    let triangles = triangles.filter(|t| !t.is_empty())?;
    repair_normals(&mut normals, positions, triangles);
    Some(normals)
}

/// Whether a normal can be made unit: of a length that is finite and not
/// zero.
pub(crate) fn is_usable(n: Vec3) -> bool {
    unit_normal(n).is_some()
}

/// A normal made unit as [`unit_normals`] makes it, if it is usable.
pub(crate) fn unit_normal(n: Vec3) -> Option<Vec3> {
    let d = n.as_dvec3();
    let len = d.length();
    (len > 0.0 && len.is_finite()).then(|| (d / len).as_vec3())
}

/// Replaces each normal that is not [`is_usable`] by the area-weighted
/// normal of the triangles around its vertex (zero-area ones left out), or
/// +Z where there are none with an area. A vertex's result depends only
/// on its own triangles, in their order: a chunk of a mesh holding every
/// triangle around its vertices repairs them as the whole mesh does.
pub(crate) fn repair_normals(normals: &mut [Vec3], positions: &[DVec3], triangles: &[[u32; 3]]) {
    let bad: Vec<usize> = (0..normals.len())
        .filter(|&i| !is_usable(normals[i]))
        .collect();
    if bad.is_empty() {
        return;
    }
    let mut sums = vec![DVec3::ZERO; positions.len()];
    for t in triangles {
        let p = t.map(|i| positions.get(i as usize).copied().unwrap_or_default());
        if is_zero_area(p[0], p[1], p[2]) {
            continue;
        }
        let n = (p[1] - p[0]).cross(p[2] - p[0]);
        for &i in t {
            if let Some(s) = sums.get_mut(i as usize) {
                *s += n;
            }
        }
    }
    for i in bad {
        let s = sums.get(i).copied().unwrap_or_default();
        let n = s.try_normalize().map_or(Vec3::Z, |s| s.as_vec3());
        if let Some(slot) = normals.get_mut(i) {
            *slot = n;
        }
    }
}
