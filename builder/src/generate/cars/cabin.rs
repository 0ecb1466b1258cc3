//! The cabin (firewall, dashboard, steering wheel, seats) and the wheels.

use super::*;

/// Firewall, dashboard, steering wheel and four seats.
pub(super) fn cabin(t: &Tess) -> Mesh {
    let mut m = Mesh::default();
    firewall(&mut m);
    m.add_box(
        DVec3::new(0.45, -0.62, 0.72),
        DVec3::new(0.68, 0.62, 0.88),
        DARK,
    );
    let wheel = DVec3::new(0.3, 0.35, 0.9);
    let axis = DVec3::new(-0.8, 0.0, 0.6);
    m.add_torus(wheel, axis, (0.17, 0.015), t.big, t.count(8.0), RUBBER);
    m.add_cylinder(wheel, DVec3::new(0.5, 0.35, 0.78), 0.025, t.mid, DARK);
    for x in [0.0, -0.9] {
        for y in [-0.35, 0.35] {
            m.add_box(
                DVec3::new(x - 0.25, y - 0.22, 0.4),
                DVec3::new(x + 0.25, y + 0.22, 0.52),
                UPHOLSTERY,
            );
            m.add_oriented_box(
                DVec3::new(x - 0.28, y, 0.78),
                [
                    DVec3::new(0.96, 0.0, 0.28) * 0.05,
                    DVec3::Y * 0.22,
                    DVec3::new(-0.28, 0.0, 0.96) * 0.26,
                ],
                UPHOLSTERY,
            );
        }
    }
    m
}

/// The firewall between cabin and engine bay, x from [`FIREWALL`].0 to .1:
/// a prism whose outline follows the body's cross-section from the floor
/// up to the roof, so that no line of sight through the windshield passes
/// over it into the engine bay (a real car's bulkhead meets its cowl).
fn firewall(m: &mut Mesh) {
    const FOOT: f64 = 0.38;
    const STEP: f64 = 0.01;
    let (x0, x1) = FIREWALL;
    // Half-width at height z that keeps both faces well inside the inner
    // surface (0.9 of its level leaves room for the coarsest facets).
    let half_width = |z: f64| {
        let inside = |y: f64| {
            [x0, x1]
                .iter()
                .all(|&x| inner_level(DVec3::new(x, y, z)) < 0.9)
        };
        if !inside(0.0) {
            return 0.0;
        }
        let (mut lo, mut hi) = (0.0, WIDTH);
        for _ in 0..40 {
            let mid = 0.5 * (lo + hi);
            if inside(mid) { lo = mid } else { hi = mid }
        }
        lo
    };
    // The right side going up, then the left side coming down:
    // counter-clockwise seen from +x (y to the right, z up).
    let mut right = Vec::new();
    let mut z = FOOT;
    loop {
        let w = half_width(z);
        if w < 0.02 {
            break;
        }
        right.push((w, z));
        z += STEP;
    }
    let outline: Vec<(f64, f64)> = right
        .iter()
        .copied()
        .chain(right.iter().rev().map(|&(w, z)| (-w, z)))
        .collect();
    m.add_prism_x(&outline, x0, x1, DARK);
}

/// Four wheels: tire, rim, hub cap, five lug nuts each.
pub(super) fn wheels(t: &Tess) -> Mesh {
    let mut m = Mesh::default();
    for sx in [-1.0, 1.0] {
        for sy in [-1.0, 1.0] {
            let c = DVec3::new(sx * WHEEL.x, sy * WHEEL.y, WHEEL.z);
            let out = DVec3::Y * sy;
            m.add_torus(c, DVec3::Y, TIRE, t.count(64.0), t.count(20.0), RUBBER);
            m.add_cylinder(
                c - out * 0.07,
                c + out * 0.07,
                TIRE.0 - TIRE.1 * 0.5,
                t.big,
                STEEL,
            );
            m.add_frustum(c + out * 0.07, c + out * 0.085, 0.06, 0.04, t.mid, STEEL);
            for k in 0..5 {
                let (s, co) = sin_cos(TAU * f64::from(k) / 5.0);
                let at = c + out * 0.07 + DVec3::new(0.09 * co, 0.0, 0.09 * s);
                bolt(&mut m, t, at, out, 0.01, DARK);
            }
        }
    }
    m
}
