//! Clipping a triangle to a cell (Sutherland-Hodgman against the six
//! planes of an axis-aligned box), so a leaf stores exactly the part of
//! the geometry inside it: no triangle is drawn twice by two leaves, and
//! every stored vertex lies in its cell, where 16-bit cell-relative
//! offsets are exact at the faces (neighbours agree on shared edges).

use glam::DVec3;

use super::source::{Corner, Triangle};

/// The part of `tri` inside the box `[min, max]`, fanned into triangles
/// appended to `out`. Degenerate pieces (no area) are dropped.
pub fn clip_to_box(tri: &Triangle, min: DVec3, max: DVec3, out: &mut Vec<Triangle>) {
    let (tmin, tmax) = (
        tri[0].position.min(tri[1].position).min(tri[2].position),
        tri[0].position.max(tri[1].position).max(tri[2].position),
    );
    if (0..3).any(|a| tmax[a] < min[a] || tmin[a] > max[a]) {
        return;
    }
    let inside = (0..3).all(|a| tmin[a] >= min[a] && tmax[a] <= max[a]);
    if inside {
        if has_area(tri) {
            out.push(*tri);
        }
        return;
    }
    let mut poly: Vec<Corner> = tri.to_vec();
    let mut next = Vec::with_capacity(9);
    for axis in 0..3 {
        for (bound, keep_above) in [(min[axis], true), (max[axis], false)] {
            next.clear();
            let inside = |c: &Corner| {
                if keep_above {
                    c.position[axis] >= bound
                } else {
                    c.position[axis] <= bound
                }
            };
            for i in 0..poly.len() {
                let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
                let (ia, ib) = (inside(&a), inside(&b));
                if ia {
                    next.push(a);
                }
                if ia != ib {
                    let t = (bound - a.position[axis]) / (b.position[axis] - a.position[axis]);
                    let mut c = lerp(&a, &b, t.clamp(0.0, 1.0));
                    // Exactly on the plane, so both cells agree on it.
                    c.position[axis] = bound;
                    next.push(c);
                }
            }
            std::mem::swap(&mut poly, &mut next);
            if poly.len() < 3 {
                return;
            }
        }
    }
    for i in 1..poly.len() - 1 {
        let t = [poly[0], poly[i], poly[i + 1]];
        if has_area(&t) {
            out.push(t);
        }
    }
}

fn lerp(a: &Corner, b: &Corner, t: f64) -> Corner {
    let tf = t as f32;
    Corner {
        position: a.position + (b.position - a.position) * t,
        normal: match (a.normal, b.normal) {
            (Some(x), Some(y)) => Some(x.lerp(y, tf).try_normalize().unwrap_or(x)),
            (n, _) => n,
        },
        color: a.color.lerp(b.color, tf),
    }
}

fn has_area(t: &Triangle) -> bool {
    let [a, b, c] = t.map(|c| c.position);
    (b - a).cross(c - a).length_squared() > 0.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn corner(x: f64, y: f64, z: f64) -> Corner {
        Corner {
            position: DVec3::new(x, y, z),
            normal: None,
            color: Vec3::ONE,
        }
    }

    fn area(ts: &[Triangle]) -> f64 {
        ts.iter()
            .map(|t| {
                let [a, b, c] = t.map(|c| c.position);
                (b - a).cross(c - a).length() * 0.5
            })
            .sum()
    }

    #[test]
    fn pieces_in_the_eight_octants_add_up_to_the_triangle() {
        let tri = [
            corner(-1.0, -0.8, -0.3),
            corner(0.9, -0.2, 0.4),
            corner(-0.1, 0.95, 0.1),
        ];
        let mut total = 0.0;
        for o in 0..8u8 {
            let min = DVec3::new(
                if o & 1 != 0 { 0.0 } else { -1.0 },
                if o & 2 != 0 { 0.0 } else { -1.0 },
                if o & 4 != 0 { 0.0 } else { -1.0 },
            );
            let mut out = Vec::new();
            clip_to_box(&tri, min, min + DVec3::ONE, &mut out);
            for t in &out {
                for c in t {
                    let p = c.position;
                    assert!(
                        (p - min).min_element() >= -1e-12
                            && (min + DVec3::ONE - p).min_element() >= -1e-12
                    );
                }
            }
            total += area(&out);
        }
        assert!((total - area(&[tri])).abs() < 1e-12, "{total}");
    }

    #[test]
    fn a_triangle_outside_or_edge_on_leaves_nothing() {
        let mut out = Vec::new();
        let tri = [
            corner(2.0, 2.0, 2.0),
            corner(3.0, 2.0, 2.0),
            corner(2.0, 3.0, 2.0),
        ];
        clip_to_box(&tri, DVec3::ZERO, DVec3::ONE, &mut out);
        let flat = [
            corner(0.0, 0.0, 0.0),
            corner(1.0, 0.0, 0.0),
            corner(2.0, 0.0, 0.0),
        ];
        clip_to_box(&flat, DVec3::ZERO, DVec3::ONE, &mut out);
        assert!(out.is_empty());
    }
}
