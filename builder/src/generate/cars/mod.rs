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
//!   every opening (windshield, rear window, side windows), so the shell
//!   is one closed solid. The fenders are closed over the tires' tops (no
//!   wheel arches), so only the windows lead inside. Its shape is a superquadric
//!   (`x^4 + y^4 + z^4 = 1` scaled to the car) with the roof lowered over
//!   hood and trunk, a flatter belly and a narrower top, tessellated on a
//!   latitude-longitude grid whose poles are the front and rear ends.
//!   Openings are grid quads left out of both surfaces.
//! - an **engine** under the hood: a V8 block with finned cylinder barrels,
//!   heads and valve covers with bolts, intake runners, exhaust headers,
//!   spark plugs and wires, the front pulleys with their belt, fan,
//!   radiator and hoses. It is the larger share of the triangles.
//! - a **cabin**: a firewall that fills the body's cross-section up to the
//!   roof (nothing is seen of the engine through the windshield),
//!   dashboard, steering wheel, four seats.
//! - four **wheels**: tire (torus), rim, hub and lug nuts.
//!
//! Every part is a closed, outward-facing shape of its own (`shapes.rs`).
//! The car is one geometry placed `cars` times along x by instances, so any
//! number of copies costs one mesh. `detail` scales every tessellation
//! count, `body` and `wheels` those two parts' on top of it (coarse by
//! default, as a CAD model's panels are: see [`DEFAULT_BODY`]); `seed`
//! picks the paint, the engine's colors and small variations.

use glam::{DAffine3, DVec3};

use super::rng::{Rng, hash};
use super::shapes::Mesh;
use super::trig::sin_cos;
use crate::scene::{Instance, Rgb8, Scene};

mod cabin;
mod engine;
mod shell;

use cabin::*;
use engine::*;
use shell::*;

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
/// The body shell's and the wheels' tessellation on top of `detail`: 44
/// rings of 32 quads, tires of 22 by 10. Coarse beside the engine, as a
/// CAD model's large panels are: at the orbit's distance a panel triangle
/// covers a few pixels, so most of a body's front-facing triangles are
/// visible. At 1 (110 rings of 80 quads) they are finer than the pixels
/// they cover, and the visible set is the few that happen to win a pixel
/// (docs/experiments.md).
pub const DEFAULT_BODY: f64 = 0.4;
pub const DEFAULT_WHEELS: f64 = 0.4;
pub const MAX_DETAIL: f64 = 8.0;
/// The engine's tessellation on top of `detail`: with the default body and
/// wheels, five cars come to about 810 000 triangles.
const ENGINE_DETAIL: f64 = 1.16;

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
/// The firewall's faces (x): behind the engine, in front of the dashboard.
const FIREWALL: (f64, f64) = (0.72, 0.75);
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
    /// Scales the body shell's grid on top of `detail` (1: 110 rings of 80
    /// quads; [`DEFAULT_BODY`]).
    pub body: f64,
    /// Scales the wheels' tessellation on top of `detail` ([`DEFAULT_WHEELS`]).
    pub wheels: f64,
}

/// The scene: one car mesh placed `cars` times, PITCH apart along +x.
pub fn cars(p: &CarsParams) -> Scene {
    let car = Car::new(p.seed, p.detail, p.body, p.wheels).mesh();
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
    fn new(seed: u64, detail: f64, body: f64, wheel_detail: f64) -> Self {
        let mut rng = Rng::new(hash(seed, 0xCA5));
        let paint = PAINTS[rng.below(PAINTS.len() as u64) as usize];
        let t = Tess::new(detail);
        Self {
            shell: shell(&t, body, paint),
            engine: engine(&Tess::new(detail * ENGINE_DETAIL), &mut rng),
            cabin: cabin(&t),
            wheels: wheels(&Tess::new(detail * wheel_detail)),
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate::shapes::closed_parts;

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
            let car = Car::new(1, detail, DEFAULT_BODY, DEFAULT_WHEELS);
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
    fn a_coarser_body_is_still_one_closed_shell_round_the_same_engine() {
        let fine = Car::new(1, DEFAULT_DETAIL, 1.0, DEFAULT_WHEELS);
        for body in [0.1, DEFAULT_BODY] {
            let coarse = Car::new(1, DEFAULT_DETAIL, body, DEFAULT_WHEELS);
            let s = &coarse.shell;
            assert_eq!(closed_parts(&s.positions, &s.triangles), Ok(1), "{body}");
            assert!(
                s.triangle_count() * 2 < fine.shell.triangle_count(),
                "body {body}: {} against {}",
                s.triangle_count(),
                fine.shell.triangle_count()
            );
            assert_eq!(coarse.engine.triangles, fine.engine.triangles);
        }
    }

    /// The shell's rim triangles: those with both outer and inner vertices
    /// (the outer surface's come first: two poles and the rings between).
    fn rims(s: &Mesh, body: f64) -> impl Iterator<Item = &[u32; 3]> {
        let (rows, around) = grid(&Tess::new(1.0), body);
        let outer_count = 2 + (rows - 1) * around;
        s.triangles.iter().filter(move |t| {
            t.iter().any(|&i| (i as usize) < outer_count)
                && t.iter().any(|&i| i as usize >= outer_count)
        })
    }

    #[test]
    fn the_shell_has_openings_with_rims() {
        let t = Tess::new(1.0);
        let s = shell(&t, 1.0, PAINTS[0]);
        let (rows, around) = grid(&t, 1.0);
        // Two full surfaces would be 2 * 2 * around * (rows - 1) triangles.
        let full = 4 * around * (rows - 1);
        assert!(
            s.triangle_count() < full - 1000,
            "{} of {full}",
            s.triangle_count()
        );
        // Rims: some triangles span the panel, both outer and inner vertices.
        let rims = rims(&s, 1.0).count();
        assert!(rims > 200, "{rims}");
    }

    /// Only the windows open the body: every rim (a quad joining the outer
    /// and inner surfaces round an opening) is above the body's middle, so
    /// no wheel arch leads into the engine bay.
    #[test]
    fn the_only_openings_are_windows() {
        for body in [0.1, DEFAULT_BODY, 1.0] {
            let s = shell(&Tess::new(1.0), body, PAINTS[0]);
            let mut count = 0;
            for tri in rims(&s, body) {
                count += 1;
                for &i in tri {
                    let p = s.positions[i as usize];
                    assert!(p.z > CENTRE_Z, "body {body}: a rim at {p}");
                }
            }
            assert!(count > 0, "body {body}: no windows");
        }
    }

    /// The firewall fills the body's cross-section from its foot to the
    /// roof: a point of that plane well inside the body is covered by its
    /// engine-side face, so no line of sight through the windshield reaches
    /// the engine bay.
    #[test]
    fn the_firewall_closes_the_engine_bay() {
        let cabin = Car::new(1, 1.0, DEFAULT_BODY, DEFAULT_WHEELS).cabin;
        // The firewall's faces toward the engine bay (x = FIREWALL.1).
        let face: Vec<[DVec3; 3]> = cabin
            .triangles
            .iter()
            .map(|t| t.map(|i| cabin.positions[i as usize]))
            .filter(|t| t.iter().all(|p| p.x == FIREWALL.1))
            .collect();
        let covered = |y: f64, z: f64| {
            face.iter().any(|t| {
                let side = |a: DVec3, b: DVec3| (b.y - a.y) * (z - a.z) - (b.z - a.z) * (y - a.y);
                let s = [side(t[0], t[1]), side(t[1], t[2]), side(t[2], t[0])];
                s.iter().all(|&v| v >= 0.0) || s.iter().all(|&v| v <= 0.0)
            })
        };
        let x = 0.5 * (FIREWALL.0 + FIREWALL.1);
        let mut checked = 0;
        for iz in 0..100 {
            let z = 0.40 + 0.01 * f64::from(iz);
            for iy in -100..=100 {
                let y = 0.01 * f64::from(iy);
                if inner_level(DVec3::new(x, y, z)) >= 0.8 {
                    continue;
                }
                checked += 1;
                assert!(covered(y, z), "({x}, {y}, {z}) is open");
            }
        }
        assert!(checked > 5000, "{checked}");
        assert_eq!(
            closed_parts(&cabin.positions, &cabin.triangles).map(|n| n > 1),
            Ok(true)
        );
    }

    #[test]
    fn the_engine_and_cabin_are_inside_the_body() {
        let car = Car::new(3, 1.0, DEFAULT_BODY, DEFAULT_WHEELS);
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
            let car = Car::new(1, detail, DEFAULT_BODY, DEFAULT_WHEELS);
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
        let (lo, hi) = bounds(&Car::new(1, 1.0, DEFAULT_BODY, DEFAULT_WHEELS).mesh());
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
