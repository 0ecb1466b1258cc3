//! The V8 under the hood: block, banks of finned cylinders, heads, valve
//! covers, intake, exhaust, plugs and wires, pulleys, belt, fan, radiator.
//! Most of the car's triangles are here.

use super::*;

/// A cubic Bezier curve sampled at `n` points, ends included.
pub(super) fn bezier(p: [DVec3; 4], n: u32) -> Vec<DVec3> {
    let n = n.max(2);
    (0..n)
        .map(|k| {
            let t = f64::from(k) / f64::from(n - 1);
            let s = 1.0 - t;
            p[0] * (s * s * s)
                + p[1] * (3.0 * s * s * t)
                + p[2] * (3.0 * s * t * t)
                + p[3] * (t * t * t)
        })
        .collect()
}

/// A bolt standing on `at` along unit `axis`: a washer and a hex head.
pub(super) fn bolt(m: &mut Mesh, t: &Tess, at: DVec3, axis: DVec3, size: f64, color: Rgb8) {
    let washer = at + axis * (0.25 * size);
    m.add_cylinder(at, washer, 1.5 * size, t.small, color);
    m.add_cylinder(washer, washer + axis * (0.7 * size), size, 6, color);
}

/// A pulley on an axis along x: a disc with a hub, grooves as rings round
/// its rim, and three hub bolts.
pub(super) fn pulley(m: &mut Mesh, t: &Tess, centre: DVec3, radius: f64) {
    let width = 0.03;
    m.add_cylinder(centre - DVec3::X * width, centre, radius, t.big, STEEL);
    m.add_cylinder(
        centre,
        centre + DVec3::X * 0.012,
        radius * 0.35,
        t.mid,
        DARK,
    );
    let grooves = 5;
    for g in 0..grooves {
        let x = centre.x - width * (f64::from(g) + 0.5) / f64::from(grooves);
        m.add_torus(
            DVec3::new(x, centre.y, centre.z),
            DVec3::X,
            (radius, 0.0028),
            t.big,
            t.count(8.0),
            STEEL,
        );
    }
    for k in 0..3 {
        let (s, c) = sin_cos(TAU * f64::from(k) / 3.0);
        let at = centre + DVec3::new(0.012, radius * 0.2 * c, radius * 0.2 * s);
        bolt(m, t, at, DVec3::X, 0.006, DARK);
    }
}

/// The belt round pulleys (`(y, z)` centre, radius) listed counter-clockwise
/// round their hull, in the plane at `x`: an arc on each pulley between the
/// normals of its two straight runs, as a closed tube.
pub(super) fn belt(m: &mut Mesh, t: &Tess, x: f64, pulleys: &[((f64, f64), f64)]) {
    let k = pulleys.len();
    let normal = |a: (f64, f64), b: (f64, f64)| {
        let (dy, dz) = (b.0 - a.0, b.1 - a.1);
        let l = (dy * dy + dz * dz).sqrt();
        (dz / l, -dy / l)
    };
    let mut points = Vec::new();
    for p in 0..k {
        let (c, r) = pulleys[p];
        let n_in = normal(pulleys[(p + k - 1) % k].0, c);
        let n_out = normal(c, pulleys[(p + 1) % k].0);
        let steps = t.count(10.0);
        for s in 0..=steps {
            // Normalised linear blend: a fine arc for turns under 180 degrees.
            let f = f64::from(s) / f64::from(steps);
            let (ny, nz) = (lerp(n_in.0, n_out.0, f), lerp(n_in.1, n_out.1, f));
            let l = (ny * ny + nz * nz).sqrt();
            let rr = r + 0.006;
            points.push(DVec3::new(x, c.0 + ny / l * rr, c.1 + nz / l * rr));
        }
    }
    m.add_loop_tube(&points, DVec3::X, 0.005, t.count(8.0), RUBBER);
}

/// The V8 engine and its front end (see the module docs).
pub(super) fn engine(t: &Tess, rng: &mut Rng) -> Mesh {
    let mut m = Mesh::default();
    let block = BLOCKS[rng.below(BLOCKS.len() as u64) as usize];
    // Block, oil pan, bell housing, mounts.
    m.add_box(
        DVec3::new(0.92, -0.2, 0.42),
        DVec3::new(1.52, 0.2, 0.68),
        block,
    );
    m.add_box(
        DVec3::new(0.96, -0.17, 0.38),
        DVec3::new(1.48, 0.17, 0.42),
        DARK,
    );
    m.add_frustum(
        DVec3::new(0.92, 0.0, 0.53),
        DVec3::new(0.78, 0.0, 0.53),
        0.16,
        0.2,
        t.big,
        block,
    );
    for b in [-1.0, 1.0] {
        // Mount: a bracket off the block's side on a rubber block.
        let (y0, y1) = if b > 0.0 { (0.2, 0.33) } else { (-0.33, -0.2) };
        m.add_box(DVec3::new(1.1, y0, 0.48), DVec3::new(1.2, y1, 0.53), DARK);
        let foot = DVec3::new(1.15, b * 0.3, 0.42);
        m.add_cylinder(foot, foot + DVec3::Z * 0.06, 0.035, t.mid, RUBBER);
        // Oil pan flange bolts.
        for k in 0..8 {
            let at = DVec3::new(0.99 + 0.065 * f64::from(k), b * 0.17, 0.405);
            bolt(&mut m, t, at, DVec3::Y * b, 0.007, STEEL);
        }
    }
    let wire_color = [[30, 30, 30], [170, 40, 30], [30, 60, 150]][rng.below(3) as usize];
    let distributor = DVec3::new(0.86, 0.0, 0.72);
    m.add_cylinder(
        distributor - DVec3::Z * 0.04,
        distributor + DVec3::Z * 0.06,
        0.03,
        t.mid,
        DARK,
    );
    m.add_frustum(
        distributor + DVec3::Z * 0.06,
        distributor + DVec3::Z * 0.1,
        0.045,
        0.04,
        t.mid,
        RUBBER,
    );
    for b in [-1.0, 1.0] {
        bank(&mut m, t, rng, b, block, wire_color, distributor);
    }
    // Intake: plenum between the banks, throttle body in front.
    let plenum = (DVec3::new(0.98, 0.0, 0.87), DVec3::new(1.52, 0.0, 0.87));
    m.add_cylinder(plenum.0, plenum.1, 0.055, t.big, STEEL);
    m.add_cylinder(plenum.1, plenum.1 + DVec3::X * 0.05, 0.04, t.big, DARK);
    let intake = bezier(
        [
            plenum.1 + DVec3::X * 0.05,
            DVec3::new(1.62, 0.0, 0.9),
            DVec3::new(1.6, 0.2, 0.92),
            DVec3::new(1.45, 0.3, 0.9),
        ],
        t.path,
    );
    m.add_tube(&intake, 0.035, t.big, RUBBER);
    front(&mut m, t, rng);
    m
}

/// One cylinder bank (`b` = +1 left, -1 right, as y): finned barrels
/// leaning out 45 degrees, head, valve cover with ribs and bolts, intake
/// runners from the plenum, spark plugs and wires, exhaust headers.
pub(super) fn bank(
    m: &mut Mesh,
    t: &Tess,
    rng: &mut Rng,
    b: f64,
    block: Rgb8,
    wire: Rgb8,
    distributor: DVec3,
) {
    let h = std::f64::consts::FRAC_1_SQRT_2;
    let up = DVec3::new(0.0, b * h, h);
    let out = DVec3::new(0.0, b * h, -h);
    let stagger = if b > 0.0 { 0.04 } else { 0.0 };
    let xs: Vec<f64> = (0..4)
        .map(|c| 1.0 + stagger + 0.14 * f64::from(c))
        .collect();
    let deck = |x: f64| DVec3::new(x, b * 0.09, 0.66);
    let fins = t.count(20.0);
    for &x in &xs {
        let base = deck(x);
        m.add_cylinder(base, base + up * 0.17, 0.05, t.big, block);
        for f in 0..fins {
            let c = base + up * (0.02 + 0.135 * (f64::from(f) + 0.5) / f64::from(fins));
            m.add_cylinder(c - up * 0.0015, c + up * 0.0015, 0.064, t.big, block);
        }
    }
    let mid = (xs[0] + xs[3]) * 0.5;
    let head = deck(mid) + up * 0.2;
    m.add_oriented_box(head, [DVec3::X * 0.3, out * 0.085, up * 0.035], block);
    let cover = head + up * 0.065;
    m.add_oriented_box(cover, [DVec3::X * 0.28, out * 0.07, up * 0.03], STEEL);
    for r in 0..6 {
        let c = cover + up * 0.034 + out * (0.022 * (f64::from(r) - 2.5));
        m.add_oriented_box(c, [DVec3::X * 0.25, out * 0.004, up * 0.004], STEEL);
    }
    for k in 0..5 {
        for s in [-1.0, 1.0] {
            let at =
                cover + up * 0.03 + out * (0.058 * s) + DVec3::X * (0.12 * (f64::from(k) - 2.0));
            bolt(m, t, at, up, 0.006, DARK);
        }
    }
    if b > 0.0 {
        let cap = cover + up * 0.03 + DVec3::X * 0.2;
        m.add_cylinder(cap, cap + up * 0.02, 0.022, t.mid, RUBBER);
    }
    let rail = head - out * 0.11 + up * 0.02;
    m.add_cylinder(
        rail - DVec3::X * 0.28,
        rail + DVec3::X * 0.28,
        0.008,
        t.mid,
        STEEL,
    );
    for (c, &x) in xs.iter().enumerate() {
        // Runner: up out of the plenum, over, down into the head's inner side.
        let port = DVec3::new(x, head.y, head.z) - out * 0.09;
        let runner = bezier(
            [
                DVec3::new(x, b * 0.03, 0.9),
                DVec3::new(x, b * 0.05, 0.95),
                port + up * 0.06 - out * 0.02,
                port,
            ],
            t.path,
        );
        m.add_tube(&runner, 0.015, t.mid, STEEL);
        // Spark plug on the head's outer side, leaning up.
        let plug_dir = (out * 0.8 + up * 0.6).normalize();
        let seat = DVec3::new(x, head.y, head.z) + out * 0.085 + up * 0.01;
        m.add_cylinder(seat, seat + plug_dir * 0.012, 0.01, 6, STEEL);
        let porcelain = seat + plug_dir * 0.012;
        m.add_cylinder(
            porcelain,
            porcelain + plug_dir * 0.025,
            0.006,
            t.small,
            [230, 230, 225],
        );
        let boot = porcelain + plug_dir * 0.02;
        m.add_cylinder(boot, boot + plug_dir * 0.035, 0.011, t.small, wire);
        // Wire from the boot, arching over the cover to the distributor cap.
        let end = boot + plug_dir * 0.035;
        let (s, co) = sin_cos(TAU * (f64::from(c as u32) + if b > 0.0 { 0.0 } else { 4.0 }) / 8.0);
        let post = distributor + DVec3::new(0.028 * co, 0.028 * s, 0.1);
        m.add_cylinder(
            post - DVec3::Z * 0.005,
            post + DVec3::Z * 0.015,
            0.006,
            t.small,
            RUBBER,
        );
        let lift = rng.range(0.02, 0.05);
        let wire_path = bezier(
            [
                end,
                end + plug_dir * 0.04 + DVec3::Z * lift,
                post + DVec3::new(0.06, 0.0, 0.08 + lift),
                post + DVec3::Z * 0.015,
            ],
            t.count(32.0),
        );
        m.add_tube(&wire_path, 0.004, t.count(8.0), wire);
        // Header: out of the head's outer face, down and back to the collector.
        let exhaust = DVec3::new(x, head.y, head.z) + out * 0.09 - up * 0.025;
        let header = bezier(
            [
                exhaust,
                exhaust + out * 0.08,
                DVec3::new(x - 0.05, b * 0.41, 0.52),
                DVec3::new(0.92, b * 0.36, 0.47),
            ],
            t.path,
        );
        m.add_tube(&header, 0.014, t.mid, RUST);
    }
    let collector = (
        DVec3::new(0.92, b * 0.36, 0.47),
        DVec3::new(0.8, b * 0.33, 0.45),
    );
    m.add_frustum(
        collector.0 + DVec3::X * 0.02,
        collector.1,
        0.035,
        0.028,
        t.big,
        RUST,
    );
    let pipe = bezier(
        [
            collector.1,
            DVec3::new(0.5, b * 0.3, 0.42),
            DVec3::new(0.0, b * 0.3, 0.36),
            DVec3::new(-0.5, b * 0.3, 0.35),
        ],
        t.path,
    );
    m.add_tube(&pipe, 0.025, t.big, RUST);
}

/// The front end: crank snout and accessory pulleys with their bodies,
/// the belt, the fan, the radiator and its hoses.
pub(super) fn front(m: &mut Mesh, t: &Tess, rng: &mut Rng) {
    let plane = 1.66;
    // (y, z) centre, radius, body length behind the pulley.
    let accessories: [((f64, f64), f64, f64); 5] = [
        ((0.0, 0.5), 0.075, 0.12),    // crank
        ((-0.2, 0.47), 0.05, 0.1),    // air conditioning
        ((-0.22, 0.68), 0.045, 0.08), // power steering
        ((0.22, 0.72), 0.035, 0.1),   // alternator
        ((0.16, 0.55), 0.03, 0.02),   // idler
    ];
    for &((y, z), r, body) in &accessories {
        let centre = DVec3::new(plane, y, z);
        pulley(m, t, centre, r);
        let back = centre - DVec3::X * (0.03 + body);
        let radius = if body > 0.05 { r.max(0.05) } else { r * 0.5 };
        m.add_cylinder(back, centre - DVec3::X * 0.03, radius, t.big, DARK);
    }
    // Alternator cooling ribs round its body.
    let alternator = DVec3::new(plane - 0.08, 0.22, 0.72);
    let ribs = t.count(16.0);
    for k in 0..ribs {
        let (s, c) = sin_cos(TAU * f64::from(k) / f64::from(ribs));
        let radial = DVec3::new(0.0, c, s);
        let tangent = DVec3::new(0.0, -s, c);
        m.add_oriented_box(
            alternator + radial * 0.055,
            [DVec3::X * 0.045, radial * 0.006, tangent * 0.002],
            STEEL,
        );
    }
    // The belt, counter-clockwise seen from the front (+x): crank, idler,
    // alternator, power steering, air conditioning.
    let order = [0, 4, 3, 2, 1];
    let ring: Vec<((f64, f64), f64)> = order
        .iter()
        .map(|&k| (accessories[k].0, accessories[k].1))
        .collect();
    belt(m, t, plane - 0.015, &ring);
    // Water pump and fan on its shaft.
    let pump = DVec3::new(plane, 0.0, 0.65);
    m.add_cylinder(pump - DVec3::X * 0.1, pump, 0.045, t.big, DARK);
    let hub = pump + DVec3::X * 0.05;
    m.add_cylinder(pump, hub, 0.03, t.big, STEEL);
    let blades = 7;
    let (sp, cp) = sin_cos(0.45);
    for k in 0..blades {
        let (s, c) = sin_cos(TAU * f64::from(k) / f64::from(blades) + rng.range(-0.02, 0.02));
        let radial = DVec3::new(0.0, c, s);
        let width = DVec3::new(0.0, -s, c) * cp + DVec3::X * sp;
        m.add_oriented_box(
            hub - DVec3::X * 0.015 + radial * 0.1,
            [radial * 0.065, width * 0.028, radial.cross(width) * 0.002],
            DARK,
        );
    }
    // Radiator: tanks and sides, a core of fins and tubes, cap, hoses.
    let (x0, x1) = (1.76, 1.79);
    let (y0, y1, z0, z1) = (-0.42, 0.42, 0.45, 0.88);
    m.add_box(DVec3::new(x0, y0, z1 - 0.05), DVec3::new(x1, y1, z1), DARK);
    m.add_box(DVec3::new(x0, y0, z0), DVec3::new(x1, y1, z0 + 0.05), DARK);
    m.add_box(
        DVec3::new(x0, y0, z0 + 0.05),
        DVec3::new(x1, y0 + 0.02, z1 - 0.05),
        DARK,
    );
    m.add_box(
        DVec3::new(x0, y1 - 0.02, z0 + 0.05),
        DVec3::new(x1, y1, z1 - 0.05),
        DARK,
    );
    let fins = t.count(48.0);
    for k in 0..fins {
        let z = z0 + 0.05 + (z1 - z0 - 0.1) * (f64::from(k) + 0.5) / f64::from(fins);
        m.add_box(
            DVec3::new(x0 + 0.003, y0 + 0.02, z - 0.0008),
            DVec3::new(x1 - 0.003, y1 - 0.02, z + 0.0008),
            STEEL,
        );
    }
    let tubes = t.count(24.0);
    for k in 0..tubes {
        let y = y0 + 0.02 + (y1 - y0 - 0.04) * (f64::from(k) + 0.5) / f64::from(tubes);
        let x = (x0 + x1) * 0.5;
        m.add_cylinder(
            DVec3::new(x, y, z0 + 0.05),
            DVec3::new(x, y, z1 - 0.05),
            0.004,
            t.small,
            DARK,
        );
    }
    let cap = DVec3::new((x0 + x1) * 0.5, 0.3, z1);
    m.add_cylinder(cap, cap + DVec3::Z * 0.02, 0.02, t.mid, STEEL);
    let upper = bezier(
        [
            DVec3::new(x0, 0.25, z1 - 0.03),
            DVec3::new(1.66, 0.22, 0.9),
            DVec3::new(1.6, 0.05, 0.86),
            DVec3::new(1.53, 0.0, 0.84),
        ],
        t.path,
    );
    m.add_tube(&upper, 0.018, t.mid, RUBBER);
    let lower = bezier(
        [
            DVec3::new(x0, -0.3, z0 + 0.03),
            DVec3::new(1.66, -0.3, 0.5),
            DVec3::new(1.62, -0.08, 0.56),
            DVec3::new(1.57, -0.04, 0.6),
        ],
        t.path,
    );
    m.add_tube(&lower, 0.018, t.mid, RUBBER);
}
