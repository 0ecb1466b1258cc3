//! The body shell: a superquadric with the roof lowered over hood and
//! trunk, two surfaces a panel's thickness apart, rims round the openings.

use super::*;

/// Linear interpolation.
pub(super) fn lerp(a: f64, b: f64, t: f64) -> f64 {
    a + (b - a) * t
}

/// Hermite smoothstep of `t` clamped to 0..1: a profile without kinks.
pub(super) fn smooth(t: f64) -> f64 {
    let t = t.clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Roof height, as a fraction of SEMI.z, at `x`: low over the hood, rising
/// along the windshield, full over the cabin, falling to the trunk.
pub(super) fn roof(x: f64) -> f64 {
    if x > 0.45 {
        lerp(1.0, 0.55, smooth((x - 0.45) / 0.55))
    } else if x < -1.35 {
        lerp(1.0, 0.7, smooth((-1.35 - x) / 0.4))
    } else {
        1.0
    }
}

/// Maps a point of the plain superquadric frame (centre at the origin) to
/// the car's body: roof profile above the centre, flat belly below, the
/// sides drawn in toward the top. Orientation-preserving and invertible
/// ([`undeform`]), so a surface stays closed and outward and the inside of
/// the inner surface stays inside.
pub(super) fn deform(p: DVec3) -> DVec3 {
    let h = if p.z > 0.0 { roof(p.x) } else { BELLY };
    let up = p.z.max(0.0) / SEMI.z;
    DVec3::new(p.x, p.y * (1.0 - TUMBLE * up * up), CENTRE_Z + p.z * h)
}

/// The inverse of [`deform`].
pub(super) fn undeform(q: DVec3) -> DVec3 {
    let z = q.z - CENTRE_Z;
    let h = if z > 0.0 { roof(q.x) } else { BELLY };
    let pz = z / h;
    let up = pz.max(0.0) / SEMI.z;
    DVec3::new(q.x, q.y / (1.0 - TUMBLE * up * up), pz)
}

/// The point of the unit superquadric `x^4 + y^4 + z^4 = 1` in direction
/// `d` (fourth roots by two square roots, which are exact in IEEE).
pub(super) fn superquadric(d: DVec3) -> DVec3 {
    let d2 = d * d;
    d / (d2.dot(d2)).sqrt().sqrt()
}

/// How far inside the body's inner surface `p` is: below 1 inside.
pub(super) fn inner_level(p: DVec3) -> f64 {
    let q = undeform(p) / (SEMI - DVec3::splat(THICKNESS));
    let q2 = q * q;
    q2.dot(q2)
}

/// Whether the grid quad with unit-superquadric centre `c` is an opening.
pub(super) fn opening(c: DVec3) -> bool {
    let x = c.x * SEMI.x;
    let (y, z) = (c.y.abs(), c.z);
    let top = z > 0.55 && y < 0.72;
    let side = y > 0.6 && z > 0.3 && z < 0.82;
    let windshield = top && (0.5..0.98).contains(&x);
    let rear = top && (-1.72..-1.4).contains(&x);
    // Front and rear side windows, with a B-pillar between them.
    let sides = side && ((-1.25..-0.42).contains(&x) || (-0.3..0.42).contains(&x));
    // No wheel arches: the fenders are closed over the tires' tops (as
    // fender skirts are), so nothing but the windows leads into the body.
    // Open arches would let a visibility order walk through empty space
    // into the engine bay, which a real car's wheel housings close off.
    windshield || rear || sides
}

/// The shell's grid at `body`: rings from front to rear pole, and quads
/// round each ring.
pub(super) fn grid(t: &Tess, body: f64) -> (usize, usize) {
    let rows = t.count(110.0 * body).max(8);
    let around = 4 * t.count(20.0 * body).max(2);
    (rows as usize, around as usize)
}

/// The closed body shell (see the module docs).
pub(super) fn shell(t: &Tess, body: f64, paint: Rgb8) -> Mesh {
    let (m, n) = grid(t, body);
    // Unit-superquadric points: rings 1..m-1 and the two poles.
    let unit = |j: usize, i: usize| {
        let (sa, ca) = sin_cos(PI * j as f64 / m as f64);
        let (st, ct) = sin_cos(TAU * (i % n) as f64 / n as f64);
        superquadric(DVec3::new(ca, sa * ct, sa * st))
    };
    // Openings, then no two that meet only at a corner: a shell pinched at
    // a vertex would not be a clean solid.
    let mut open = vec![false; m * n];
    for j in 1..m - 1 {
        for i in 0..n {
            let c = (unit(j, i) + unit(j + 1, i) + unit(j + 1, i + 1) + unit(j, i + 1)) * 0.25;
            open[j * n + i] = opening(c);
        }
    }
    loop {
        let mut changed = false;
        for j in 1..m - 1 {
            for i in 0..n {
                let i1 = (i + 1) % n;
                let (a, b, c, d) = (j * n + i, j * n + i1, (j + 1) * n + i, (j + 1) * n + i1);
                if (open[a] && open[d] && !open[b] && !open[c])
                    || (open[b] && open[c] && !open[a] && !open[d])
                {
                    open[d] = false;
                    open[c] = false;
                    changed = true;
                }
            }
        }
        if !changed {
            break;
        }
    }
    let is_open = |j: isize, i: isize| {
        j >= 0 && (j as usize) < m && open[j as usize * n + i.rem_euclid(n as isize) as usize]
    };

    let mut mesh = Mesh::default();
    let mut layer = |semi: DVec3, color: Rgb8| {
        let base = mesh.positions.len() as u32;
        mesh.vertex(deform(unit(0, 0) * semi), color);
        for j in 1..m {
            for i in 0..n {
                mesh.vertex(deform(unit(j, i) * semi), color);
            }
        }
        mesh.vertex(deform(unit(m, 0) * semi), color);
        base
    };
    let outer = layer(SEMI, paint);
    let inner = layer(SEMI - DVec3::splat(THICKNESS), UPHOLSTERY);
    let id = |base: u32, j: usize, i: usize| -> u32 {
        if j == 0 {
            base
        } else if j == m {
            base + 1 + ((m - 1) * n) as u32
        } else {
            base + 1 + ((j - 1) * n + i % n) as u32
        }
    };
    for j in 0..m {
        for i in 0..n {
            if open[j * n + i] {
                continue;
            }
            let corners = [(j, i), (j + 1, i), (j + 1, i + 1), (j, i + 1)];
            let o = corners.map(|(a, b)| id(outer, a, b));
            let q = corners.map(|(a, b)| id(inner, a, b));
            // Outer counter-clockwise seen from outside, inner reversed
            // (seen from the cabin); the poles make the end rows fans.
            if j == 0 {
                mesh.triangle(o[0], o[1], o[2]);
                mesh.triangle(q[0], q[2], q[1]);
            } else if j == m - 1 {
                mesh.triangle(o[0], o[2], o[3]);
                mesh.triangle(q[0], q[3], q[2]);
            } else {
                mesh.quad(o[0], o[1], o[2], o[3]);
                mesh.quad(q[0], q[3], q[2], q[1]);
            }
            // A rim quad on every edge shared with an opening, its outer
            // edge reversed against the surface's.
            let (ji, ii) = (j as isize, i as isize);
            let across = [(ji, ii - 1), (ji + 1, ii), (ji, ii + 1), (ji - 1, ii)];
            for (k, (nj, ni)) in across.into_iter().enumerate() {
                if is_open(nj, ni) {
                    let (a, b) = (k, (k + 1) % 4);
                    mesh.quad(o[b], o[a], q[a], q[b]);
                }
            }
        }
    }
    mesh
}
