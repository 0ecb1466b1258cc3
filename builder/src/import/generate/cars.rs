//! `gen:cars`: the 5CBEM scene of the PLP paper (Klosowski & Silva): copies
//! of one car, a body shell around a densely tessellated engine. Most of
//! the triangles are hidden inside the body, which is the depth complexity
//! a visibility-prioritized renderer is measured on.
//!
//! One car (local frame: +x forward, +z up, wheels on z = 0, about
//! [`LENGTH`] x [`WIDTH`] x [`HEIGHT`], centred on x = y = 0):
//!
//! - a **shell** with real thickness: an outer surface facing out, an
//!   inner surface facing the cabin, and rim quads joining the two round
//!   every opening (windshield, rear window, side windows, wheel arches),
//!   so the shell is one closed solid. Its shape is a superquadric
//!   (`x^4 + y^4 + z^4 = 1` scaled to the car) with the roof lowered over
//!   hood and trunk, a flatter belly and a narrower top, tessellated on a
//!   latitude-longitude grid whose poles are the front and rear ends.
//!   Openings are grid quads left out of both surfaces.
//! - an **engine** under the hood: a V8 block with finned cylinder barrels,
//!   heads and valve covers with bolts, intake runners, exhaust headers,
//!   spark plugs and wires, the front pulleys with their belt, fan,
//!   radiator and hoses. It is the larger share of the triangles.
//! - a **cabin**: firewall, dashboard, steering wheel, four seats.
//! - four **wheels**: tire (torus), rim, hub and lug nuts.
//!
//! Every part is a closed, outward-facing shape of its own (`shapes.rs`).
//! The car is one geometry placed `cars` times along x by instances, so any
//! number of copies costs one mesh. `detail` scales every tessellation
//! count; `seed` picks the paint, the engine's colors and small variations.

use glam::{DAffine3, DVec3};

use super::rng::{Rng, hash};
use super::shapes::Mesh;
use super::trig::sin_cos;
use crate::scene::{Instance, Rgb8, Scene};

/// The car's outer size: x from -LENGTH/2, y from -WIDTH/2, z from 0.
pub const LENGTH: f64 = 4.5;
pub const WIDTH: f64 = 1.8;
pub const HEIGHT: f64 = 1.4;
/// Space between neighbouring cars, and the distance between their centres.
pub const GAP: f64 = 1.5;
pub const PITCH: f64 = LENGTH + GAP;
pub const DEFAULT_CARS: u32 = 5;
pub const MAX_CARS: u32 = 1000;
/// The default detail makes five cars about 810 000 triangles, the paper's
/// 5CBEM.
pub const DEFAULT_DETAIL: f64 = 1.0;
pub const MIN_DETAIL: f64 = 0.1;
pub const MAX_DETAIL: f64 = 8.0;

const PI: f64 = std::f64::consts::PI;
const TAU: f64 = std::f64::consts::TAU;
/// Semi-axes of the outer superquadric before the roof profile.
const SEMI: DVec3 = DVec3::new(LENGTH / 2.0, WIDTH / 2.0, 0.7);
/// Body panel thickness: the inner surface's semi-axes are this smaller.
const THICKNESS: f64 = 0.04;
/// Height of the superquadric's centre: the roof is at CENTRE_Z + SEMI.z.
const CENTRE_Z: f64 = HEIGHT - SEMI.z;
/// The lower half is flattened to this fraction of SEMI.z.
const BELLY: f64 = 0.64;
/// How much narrower the body gets toward the roof.
const TUMBLE: f64 = 0.18;
/// Wheel centres (x, |y|, z) and tire radii (ring, tube).
const WHEEL: DVec3 = DVec3::new(1.42, 0.8, 0.34);
const TIRE: (f64, f64) = (0.24, 0.095);

const PAINTS: [Rgb8; 5] = [
    [170, 25, 30],
    [25, 60, 140],
    [200, 200, 205],
    [215, 170, 40],
    [30, 110, 70],
];
const BLOCKS: [Rgb8; 3] = [[140, 40, 35], [45, 70, 140], [90, 95, 100]];
const STEEL: Rgb8 = [175, 178, 185];
const DARK: Rgb8 = [55, 57, 60];
const RUBBER: Rgb8 = [25, 25, 27];
const RUST: Rgb8 = [120, 75, 50];
const UPHOLSTERY: Rgb8 = [80, 70, 65];

/// Everything `gen:cars` can be asked for (see [`super::generate`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CarsParams {
    pub seed: u64,
    /// Copies in the row.
    pub cars: u32,
    /// Scales every tessellation count (1: the default scene).
    pub detail: f64,
}

/// The scene: one car mesh placed `cars` times, PITCH apart along +x.
pub fn cars(p: &CarsParams) -> Scene {
    let car = Car::new(p.seed, p.detail).mesh();
    Scene {
        geometries: vec![car.into_geometry("gen:cars car")],
        instances: (0..p.cars)
            .map(|k| Instance {
                geometry: 0,
                world_from_local: DAffine3::from_translation(DVec3::X * (f64::from(k) * PITCH)),
            })
            .collect(),
    }
}

/// The centre of car `k` of the row, on the ground.
pub fn car_centre(k: u32) -> DVec3 {
    DVec3::X * (f64::from(k) * PITCH)
}

/// One car's parts, kept apart so that tests can weigh and check each.
#[derive(Debug)]
struct Car {
    shell: Mesh,
    engine: Mesh,
    cabin: Mesh,
    wheels: Mesh,
}

impl Car {
    fn new(seed: u64, detail: f64) -> Self {
        let mut rng = Rng::new(hash(seed, 0xCA5));
        let paint = PAINTS[rng.below(PAINTS.len() as u64) as usize];
        let t = Tess::new(detail);
        Self {
            shell: shell(&t, paint),
            engine: engine(&t, &mut rng),
            cabin: cabin(&t),
            wheels: wheels(&t),
        }
    }

    fn mesh(&self) -> Mesh {
        let mut m = Mesh::default();
        for part in [&self.shell, &self.engine, &self.cabin, &self.wheels] {
            m.append(part);
        }
        m
    }
}

/// Tessellation counts for one `detail`: sides of large, medium and small
/// round parts, and points along a curved tube.
#[derive(Debug, Clone, Copy)]
struct Tess {
    detail: f64,
    big: u32,
    mid: u32,
    small: u32,
    path: u32,
}

impl Tess {
    fn new(detail: f64) -> Self {
        Self {
            detail,
            big: scaled(56.0, detail),
            mid: scaled(24.0, detail),
            small: scaled(12.0, detail),
            path: scaled(32.0, detail),
        }
    }

    /// `base * detail` rounded, at least 3.
    fn count(&self, base: f64) -> u32 {
        scaled(base, self.detail)
    }
}

fn scaled(base: f64, detail: f64) -> u32 {
    (base * detail).round().max(3.0) as u32
}

// ---------------------------------------------------------------- shell

/// Linear interpolation.
fn lerp(a: f64, b: f64, t: f64) -> f64 {
    a + (b - a) * t
}

/// Hermite smoothstep of `t` clamped to 0..1: a profile without kinks.
fn smooth(t: f64) -> f64 {
    let t = t.clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Roof height, as a fraction of SEMI.z, at `x`: low over the hood, rising
/// along the windshield, full over the cabin, falling to the trunk.
fn roof(x: f64) -> f64 {
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
fn deform(p: DVec3) -> DVec3 {
    let h = if p.z > 0.0 { roof(p.x) } else { BELLY };
    let up = p.z.max(0.0) / SEMI.z;
    DVec3::new(p.x, p.y * (1.0 - TUMBLE * up * up), CENTRE_Z + p.z * h)
}

/// The inverse of [`deform`].
#[cfg(test)]
fn undeform(q: DVec3) -> DVec3 {
    let z = q.z - CENTRE_Z;
    let h = if z > 0.0 { roof(q.x) } else { BELLY };
    let pz = z / h;
    let up = pz.max(0.0) / SEMI.z;
    DVec3::new(q.x, q.y / (1.0 - TUMBLE * up * up), pz)
}

/// The point of the unit superquadric `x^4 + y^4 + z^4 = 1` in direction
/// `d` (fourth roots by two square roots, which are exact in IEEE).
fn superquadric(d: DVec3) -> DVec3 {
    let d2 = d * d;
    d / (d2.dot(d2)).sqrt().sqrt()
}

/// How far inside the body's inner surface `p` is: below 1 inside.
#[cfg(test)]
fn inner_level(p: DVec3) -> f64 {
    let q = undeform(p) / (SEMI - DVec3::splat(THICKNESS));
    let q2 = q * q;
    q2.dot(q2)
}

/// Whether the grid quad with unit-superquadric centre `c` is an opening.
fn opening(c: DVec3) -> bool {
    let x = c.x * SEMI.x;
    let (y, z) = (c.y.abs(), c.z);
    let top = z > 0.55 && y < 0.72;
    let side = y > 0.6 && z > 0.3 && z < 0.82;
    let windshield = top && (0.5..0.98).contains(&x);
    let rear = top && (-1.72..-1.4).contains(&x);
    // Front and rear side windows, with a B-pillar between them.
    let sides = side && ((-1.25..-0.42).contains(&x) || (-0.3..0.42).contains(&x));
    // Wheel arches: round the wheels, on the lower sides.
    let arch = y > 0.45 && z < 0.0 && {
        let pz = CENTRE_Z + z * SEMI.z * BELLY;
        let (dx, dz) = (x.abs() - WHEEL.x, pz - WHEEL.z);
        dx * dx + dz * dz < 0.42 * 0.42
    };
    windshield || rear || sides || arch
}

/// The closed body shell (see the module docs).
fn shell(t: &Tess, paint: Rgb8) -> Mesh {
    let rows = t.count(110.0).max(8);
    let around = 4 * t.count(20.0).max(2);
    let (m, n) = (rows as usize, around as usize);
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

// ---------------------------------------------------------------- engine

/// A cubic Bezier curve sampled at `n` points, ends included.
fn bezier(p: [DVec3; 4], n: u32) -> Vec<DVec3> {
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
fn bolt(m: &mut Mesh, t: &Tess, at: DVec3, axis: DVec3, size: f64, color: Rgb8) {
    let washer = at + axis * (0.25 * size);
    m.add_cylinder(at, washer, 1.5 * size, t.small, color);
    m.add_cylinder(washer, washer + axis * (0.7 * size), size, 6, color);
}

/// A pulley on an axis along x: a disc with a hub, grooves as rings round
/// its rim, and three hub bolts.
fn pulley(m: &mut Mesh, t: &Tess, centre: DVec3, radius: f64) {
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
fn belt(m: &mut Mesh, t: &Tess, x: f64, pulleys: &[((f64, f64), f64)]) {
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
fn engine(t: &Tess, rng: &mut Rng) -> Mesh {
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
fn bank(
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
fn front(m: &mut Mesh, t: &Tess, rng: &mut Rng) {
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

// ---------------------------------------------------------------- cabin, wheels

/// Firewall, dashboard, steering wheel and four seats.
fn cabin(t: &Tess) -> Mesh {
    let mut m = Mesh::default();
    m.add_box(
        DVec3::new(0.72, -0.6, 0.38),
        DVec3::new(0.75, 0.6, 0.88),
        DARK,
    );
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

/// Four wheels: tire, rim, hub cap, five lug nuts each.
fn wheels(t: &Tess) -> Mesh {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::import::generate::shapes::closed_parts;

    fn bounds(m: &Mesh) -> (DVec3, DVec3) {
        m.positions
            .iter()
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), &p| {
                (lo.min(p), hi.max(p))
            })
    }

    #[test]
    fn deform_and_undeform_are_inverses() {
        for k in 0..200 {
            let f = f64::from(k);
            let p = DVec3::new(
                2.0 * (f * 0.37).sin(),
                0.8 * (f * 0.71).cos(),
                0.6 * (f * 1.3).sin(),
            );
            assert!((undeform(deform(p)) - p).length() < 1e-12, "{p}");
        }
    }

    #[test]
    fn every_part_is_closed_and_outward() {
        for detail in [0.1, 0.5, DEFAULT_DETAIL] {
            let car = Car::new(1, detail);
            let s = &car.shell;
            assert_eq!(
                closed_parts(&s.positions, &s.triangles),
                Ok(1),
                "shell at {detail}"
            );
            let m = car.mesh();
            let parts = closed_parts(&m.positions, &m.triangles).expect("closed");
            assert!(parts > 100, "{parts}");
        }
    }

    #[test]
    fn the_shell_has_openings_with_rims() {
        let t = Tess::new(1.0);
        let s = shell(&t, PAINTS[0]);
        let rows = t.count(110.0) as usize;
        let around = 4 * t.count(20.0) as usize;
        // Two full surfaces would be 2 * 2 * around * (rows - 1) triangles.
        let full = 4 * around * (rows - 1);
        assert!(
            s.triangle_count() < full - 1000,
            "{} of {full}",
            s.triangle_count()
        );
        // Rims: some triangles span the panel, both outer and inner vertices.
        let outer_count = 2 + (rows - 1) * around;
        let rims = s
            .triangles
            .iter()
            .filter(|t| {
                t.iter().any(|&i| (i as usize) < outer_count)
                    && t.iter().any(|&i| i as usize >= outer_count)
            })
            .count();
        assert!(rims > 200, "{rims}");
    }

    #[test]
    fn the_engine_and_cabin_are_inside_the_body() {
        let car = Car::new(3, 1.0);
        for part in [&car.engine, &car.cabin] {
            for &p in &part.positions {
                assert!(
                    inner_level(p) < 1.0,
                    "{p} is outside the body ({})",
                    inner_level(p)
                );
            }
        }
        // And the shell's own inner surface is where the level says.
        assert!(inner_level(DVec3::new(0.0, 0.0, CENTRE_Z)) < 0.01);
    }

    #[test]
    fn the_engine_is_the_larger_share() {
        for detail in [0.5, 1.0, 2.0] {
            let car = Car::new(1, detail);
            let total = car.mesh().triangle_count();
            let engine = car.engine.triangle_count();
            assert!(
                2 * engine > total,
                "detail {detail}: engine {engine} of {total}"
            );
        }
    }

    #[test]
    fn the_car_fits_its_nominal_box() {
        let (lo, hi) = bounds(&Car::new(1, 1.0).mesh());
        let eps = 1e-9;
        assert!(
            lo.x >= -LENGTH / 2.0 - eps && hi.x <= LENGTH / 2.0 + eps,
            "{lo} {hi}"
        );
        assert!(
            lo.y >= -WIDTH / 2.0 - eps && hi.y <= WIDTH / 2.0 + eps,
            "{lo} {hi}"
        );
        assert!(lo.z >= 0.0 && hi.z <= HEIGHT + eps, "{lo} {hi}");
        assert!(hi.z > HEIGHT - 0.01 && lo.z < 0.01, "{lo} {hi}");
    }
}
