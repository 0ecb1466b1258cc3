//! `gen:city`: the CITY scene of the PLP paper (Klosowski & Silva): a grid
//! of furnished houses along streets. Hundreds of thousands of triangles,
//! of which a walker in the street sees only a few: the walls hide the
//! furniture, except what shows through doors and windows. That is the
//! depth complexity a visibility-prioritized renderer is measured on.
//!
//! Layout (units are metres, +Z up): `grid` x `grid` houses, each a
//! [`HOUSE_X`] x [`HOUSE_Y`] footprint on a lot one [`YARD`] wider all round,
//! with a [`STREET`]-wide street between neighbouring lots and round the
//! city's edge. House `(i, j)` is column `i` along x, row `j` along y.
//!
//! Every house is one geometry of separate closed boxes and cylinders
//! (see `shapes.rs`): a floor slab, four walls of [`WALL`] thickness built
//! around their openings (a door in the front wall, windows in every wall),
//! a roof slab, and furniture inside (tables, chairs, shelves of books).
//! Front walls face the street between rows `2k` and `2k + 1`, so on those
//! streets doors face each other. A house's random choices come from
//! `hash(seed, house index)` alone, so houses can be built in parallel and
//! in any order.

use glam::DVec3;
use rayon::prelude::*;

use super::rng::{Rng, hash};
use super::shapes::Mesh;
use crate::scene::{Geometry, Instance, Rgb8, Scene};

/// Width of every street.
pub const STREET: f64 = 8.0;
/// House footprint along x and y.
pub const HOUSE_X: f64 = 10.0;
pub const HOUSE_Y: f64 = 8.0;
/// Ground between a house and the streets round its lot.
pub const YARD: f64 = 1.0;
/// Distance from one house to the next along x and y.
pub const PITCH_X: f64 = HOUSE_X + 2.0 * YARD + STREET;
pub const PITCH_Y: f64 = HOUSE_Y + 2.0 * YARD + STREET;
/// Top of the street surface (the ground's top is at 0).
pub const STREET_TOP: f64 = 0.02;
/// Wall thickness.
pub const WALL: f64 = 0.2;
/// Roof overhang beyond the walls.
pub const EAVES: f64 = 0.3;

/// Default grid side: 16 x 16 houses of 5 items make about 500 000
/// triangles, the paper's CITY.
pub const DEFAULT_GRID: u32 = 16;
pub const MAX_GRID: u32 = 200;
/// Default furniture items per house (the mean; each house draws its own).
pub const DEFAULT_FURNITURE: u32 = 5;
/// At most this many items on average: a house has 24 places for them.
pub const MAX_FURNITURE: u32 = 16;
pub const DEFAULT_SEGMENTS: u32 = 12;

/// Floor slab height, wall top and roof top.
const FLOOR: f64 = 0.15;
const CEILING: f64 = 2.8;
const ROOF: f64 = 3.0;
const DOOR: (f64, f64) = (1.0, 2.1);
const WINDOW: (f64, f64) = (1.2, 1.0);
const SILL: f64 = 0.9;
/// Furniture places: a 6 x 4 grid of cells over the floor.
const CELLS: (u32, u32) = (6, 4);

const WALLS: [Rgb8; 6] = [
    [214, 200, 170],
    [190, 120, 95],
    [225, 220, 210],
    [160, 175, 150],
    [200, 170, 120],
    [150, 160, 180],
];
const ROOFS: [Rgb8; 3] = [[120, 60, 50], [80, 80, 90], [100, 70, 55]];
const WOODS: [Rgb8; 4] = [[120, 80, 45], [95, 60, 35], [150, 110, 70], [70, 45, 30]];
const BOOKS: [Rgb8; 8] = [
    [150, 30, 30],
    [30, 60, 130],
    [40, 110, 60],
    [200, 170, 60],
    [90, 40, 100],
    [220, 220, 210],
    [30, 30, 30],
    [170, 90, 40],
];
const GROUND: Rgb8 = [150, 150, 145];
const ASPHALT: Rgb8 = [60, 60, 65];
const FLOORING: Rgb8 = [130, 100, 75];

/// Everything `gen:city` can be asked for (see [`super::generate`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CityParams {
    pub seed: u64,
    /// Houses per side.
    pub grid: u32,
    /// Mean furniture items per house.
    pub furniture: u32,
    /// Sides of every cylinder (table and chair legs).
    pub segments: u32,
}

/// The city's extent: x and y from 0 to these.
pub fn extent(grid: u32) -> (f64, f64) {
    let g = f64::from(grid);
    (g * PITCH_X + STREET, g * PITCH_Y + STREET)
}

/// The corner of house `(i, j)` with the smallest coordinates, on the ground.
pub fn house_corner(i: u32, j: u32) -> DVec3 {
    DVec3::new(
        STREET + YARD + f64::from(i) * PITCH_X,
        STREET + YARD + f64::from(j) * PITCH_Y,
        0.0,
    )
}

/// The scene: the ground first, then one geometry per house, row by row,
/// each placed once by an identity instance (positions are in world units).
pub fn city(p: &CityParams) -> Scene {
    let houses: Vec<Geometry> = (0..p.grid * p.grid)
        .into_par_iter()
        .map(|k| house(p, k % p.grid, k / p.grid).into_geometry(format!("gen:city house {k}")))
        .collect();
    let mut scene = Scene::single(ground(p.grid).into_geometry("gen:city ground"));
    for g in houses {
        scene.instances.push(Instance {
            geometry: scene.geometries.len(),
            world_from_local: glam::DAffine3::IDENTITY,
        });
        scene.geometries.push(g);
    }
    scene
}

/// The ground slab with street strips on top, one strip per street
/// between crossings so no two strips overlap.
fn ground(grid: u32) -> Mesh {
    let (w, h) = extent(grid);
    let mut m = Mesh::default();
    m.add_box(DVec3::new(0.0, 0.0, -0.3), DVec3::new(w, h, 0.0), GROUND);
    for j in 0..=grid {
        let y = f64::from(j) * PITCH_Y;
        m.add_box(
            DVec3::new(0.0, y, 0.0),
            DVec3::new(w, y + STREET, STREET_TOP),
            ASPHALT,
        );
    }
    for i in 0..=grid {
        let x = f64::from(i) * PITCH_X;
        for j in 0..grid {
            let y = f64::from(j) * PITCH_Y;
            m.add_box(
                DVec3::new(x, y + STREET, 0.0),
                DVec3::new(x + STREET, y + PITCH_Y, STREET_TOP),
                ASPHALT,
            );
        }
    }
    m
}

/// A color scaled by `f` (a little variety between houses and books).
fn shade(c: Rgb8, f: f64) -> Rgb8 {
    c.map(|x| (f64::from(x) * f).round().clamp(0.0, 255.0) as u8)
}

/// One hole in a wall: from `start` to `end` along the wall, `bottom` to
/// `top` in z.
#[derive(Debug, Clone, Copy)]
struct Opening {
    start: f64,
    end: f64,
    bottom: f64,
    top: f64,
}

/// `slots` openings spread along a wall from `a` to `b`, one per equal
/// slot with a little jitter; slot `door` (if any) holds the door.
fn openings(rng: &mut Rng, a: f64, b: f64, slots: u32, door: Option<u32>) -> Vec<Opening> {
    let slot = (b - a) / f64::from(slots);
    (0..slots)
        .map(|s| {
            let (width, height, bottom) = if Some(s) == door {
                (DOOR.0, DOOR.1, FLOOR)
            } else {
                (WINDOW.0, WINDOW.1, FLOOR + SILL)
            };
            // At least 0.3 of wall between an opening and its slot's ends.
            let play = (slot - width - 0.6).max(0.0) * 0.5;
            let centre = a + slot * (f64::from(s) + 0.5) + rng.range(-play, play);
            Opening {
                start: centre - width * 0.5,
                end: centre + width * 0.5,
                bottom,
                top: bottom + height,
            }
        })
        .collect()
}

/// A wall along x (`along_x`) or y from `a` to `b`, `c0..c1` across, from
/// the floor to the ceiling, built as boxes around its `holes` (sorted
/// along the wall): full-height pieces between them, and pieces below and
/// above each. Every piece is a closed box of its own.
fn wall(
    m: &mut Mesh,
    along_x: bool,
    (a, b): (f64, f64),
    (c0, c1): (f64, f64),
    holes: &[Opening],
    color: Rgb8,
) {
    let mut piece = |s0: f64, s1: f64, z0: f64, z1: f64| {
        let (lo, hi) = if along_x {
            (DVec3::new(s0, c0, z0), DVec3::new(s1, c1, z1))
        } else {
            (DVec3::new(c0, s0, z0), DVec3::new(c1, s1, z1))
        };
        m.add_box(lo, hi, color);
    };
    let mut from = a;
    for h in holes {
        piece(from, h.start, FLOOR, CEILING);
        piece(h.start, h.end, FLOOR, h.bottom);
        piece(h.start, h.end, h.top, CEILING);
        from = h.end;
    }
    piece(from, b, FLOOR, CEILING);
}

/// House `(i, j)` of the city, in world coordinates.
fn house(p: &CityParams, i: u32, j: u32) -> Mesh {
    let index = u64::from(j) * u64::from(p.grid) + u64::from(i);
    let mut rng = Rng::new(hash(p.seed, index));
    let mut local = structure(&mut rng, j);
    furnish(&mut local, &mut rng, p);
    let o = house_corner(i, j);
    for q in &mut local.positions {
        *q += o;
    }
    local
}

/// A house's floor, walls and roof in house-local coordinates (the corner
/// at the origin): boxes only. Row `j` decides which side is the front.
fn structure(rng: &mut Rng, j: u32) -> Mesh {
    let mut m = Mesh::default();
    let walls = shade(
        WALLS[rng.below(WALLS.len() as u64) as usize],
        rng.range(0.9, 1.05),
    );
    let roof = ROOFS[rng.below(ROOFS.len() as u64) as usize];
    m.add_box(DVec3::ZERO, DVec3::new(HOUSE_X, HOUSE_Y, FLOOR), FLOORING);
    m.add_box(
        DVec3::new(-EAVES, -EAVES, CEILING),
        DVec3::new(HOUSE_X + EAVES, HOUSE_Y + EAVES, ROOF),
        roof,
    );
    // Even rows face +y, odd rows -y: doors meet across every other street.
    let front_is_south = j % 2 == 1;
    let door = Some(rng.below(3) as u32);
    let back_windows = rng.range_inclusive(2, 3);
    let front = openings(rng, 0.0, HOUSE_X, 3, door);
    let back = openings(rng, 0.0, HOUSE_X, back_windows, None);
    let (south, north) = if front_is_south {
        (front, back)
    } else {
        (back, front)
    };
    // Side walls run between the front and back walls.
    let (y0, y1) = (WALL, HOUSE_Y - WALL);
    let west_windows = rng.range_inclusive(1, 2);
    let west = openings(rng, y0, y1, west_windows, None);
    let east_windows = rng.range_inclusive(1, 2);
    let east = openings(rng, y0, y1, east_windows, None);
    wall(&mut m, true, (0.0, HOUSE_X), (0.0, WALL), &south, walls);
    wall(
        &mut m,
        true,
        (0.0, HOUSE_X),
        (HOUSE_Y - WALL, HOUSE_Y),
        &north,
        walls,
    );
    wall(&mut m, false, (y0, y1), (0.0, WALL), &west, walls);
    wall(
        &mut m,
        false,
        (y0, y1),
        (HOUSE_X - WALL, HOUSE_X),
        &east,
        walls,
    );
    m
}

/// Places the house's furniture in distinct cells of a grid over the
/// floor, in house-local coordinates: between `furniture / 2` and
/// `3 * furniture / 2` items, each a table, chair or shelf.
fn furnish(m: &mut Mesh, rng: &mut Rng, p: &CityParams) {
    let cells = CELLS.0 * CELLS.1;
    let count = (p.furniture / 2 + rng.below(u64::from(p.furniture) + 1) as u32).min(cells);
    let mut order: Vec<u32> = (0..cells).collect();
    let (inner_x, inner_y) = (HOUSE_X - 2.0 * WALL, HOUSE_Y - 2.0 * WALL);
    let cell = (inner_x / f64::from(CELLS.0), inner_y / f64::from(CELLS.1));
    for k in 0..count as usize {
        // A partial Fisher-Yates shuffle: distinct cells, no retries.
        let pick = k + rng.below((order.len() - k) as u64) as usize;
        order.swap(k, pick);
        let c = order[k];
        let centre = DVec3::new(
            WALL + cell.0 * (f64::from(c % CELLS.0) + 0.5) + rng.range(-0.1, 0.1),
            WALL + cell.1 * (f64::from(c / CELLS.0) + 0.5) + rng.range(-0.1, 0.1),
            FLOOR,
        );
        let wood = shade(
            WOODS[rng.below(WOODS.len() as u64) as usize],
            rng.range(0.9, 1.1),
        );
        let turned = rng.below(2) == 1;
        match rng.below(3) {
            0 => table(m, centre, turned, wood, p.segments),
            1 => chair(m, centre, rng.below(4) as u32, wood, p.segments),
            _ => shelf(m, rng, centre, turned, wood),
        }
    }
}

/// Four round legs of `radius` and `height`, `n` sides each, under the
/// corners of a top of half-size `half`, set in from its edges by `inset`.
#[derive(Debug, Clone, Copy)]
struct Legs {
    half: (f64, f64),
    height: f64,
    radius: f64,
    inset: f64,
    n: u32,
}

impl Legs {
    /// Adds the legs standing on `base`, centred under the top.
    fn add(&self, m: &mut Mesh, base: DVec3, color: Rgb8) {
        let (hx, hy) = (self.half.0 - self.inset, self.half.1 - self.inset);
        for (sx, sy) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
            let foot = base + DVec3::new(sx * hx, sy * hy, 0.0);
            m.add_cylinder(
                foot,
                foot + DVec3::Z * self.height,
                self.radius,
                self.n,
                color,
            );
        }
    }
}

/// A table 1.2 x 0.8 (or turned 0.8 x 1.2), 0.75 high: a top on four legs.
fn table(m: &mut Mesh, at: DVec3, turned: bool, wood: Rgb8, n: u32) {
    let half = if turned { (0.4, 0.6) } else { (0.6, 0.4) };
    let (under, top) = (0.71, 0.75);
    m.add_box(
        at + DVec3::new(-half.0, -half.1, under),
        at + DVec3::new(half.0, half.1, top),
        wood,
    );
    let legs = Legs {
        half,
        height: under,
        radius: 0.03,
        inset: 0.07,
        n,
    };
    legs.add(m, at, wood);
}

/// A chair: a 0.45 x 0.45 seat 0.45 high on four legs, its back on side
/// `facing` (0..4: -x, +x, -y, +y) rising to 0.95.
fn chair(m: &mut Mesh, at: DVec3, facing: u32, wood: Rgb8, n: u32) {
    let (h, under, seat) = (0.225, 0.41, 0.45);
    m.add_box(
        at + DVec3::new(-h, -h, under),
        at + DVec3::new(h, h, seat),
        wood,
    );
    let t = 0.04;
    let (lo, hi) = match facing {
        0 => (DVec3::new(-h, -h, seat), DVec3::new(-h + t, h, 0.95)),
        1 => (DVec3::new(h - t, -h, seat), DVec3::new(h, h, 0.95)),
        2 => (DVec3::new(-h, -h, seat), DVec3::new(h, -h + t, 0.95)),
        _ => (DVec3::new(-h, h - t, seat), DVec3::new(h, h, 0.95)),
    };
    m.add_box(at + lo, at + hi, shade(wood, 0.9));
    let legs = Legs {
        half: (h, h),
        height: under,
        radius: 0.02,
        inset: 0.04,
        n,
    };
    legs.add(m, at, wood);
}

/// A shelf 1.0 wide (along x, or y when `turned`), 0.3 deep, 1.8 high:
/// two sides, five boards, and rows of books of random sizes and colors
/// on the lower four boards.
fn shelf(m: &mut Mesh, rng: &mut Rng, at: DVec3, turned: bool, wood: Rgb8) {
    // Built along x, then turned by swapping x and y about `at` if asked.
    let mut s = Mesh::default();
    let (half_w, half_d, height, side, board) = (0.5, 0.15, 1.8, 0.03, 0.025);
    for x in [-half_w, half_w - side] {
        s.add_box(
            DVec3::new(x, -half_d, 0.0),
            DVec3::new(x + side, half_d, height),
            wood,
        );
    }
    let levels = [0.05, 0.45, 0.85, 1.25, 1.65];
    for (k, &z) in levels.iter().enumerate() {
        let (x0, x1) = (-half_w + side, half_w - side);
        s.add_box(
            DVec3::new(x0, -half_d, z),
            DVec3::new(x1, half_d, z + board),
            wood,
        );
        if k + 1 == levels.len() {
            continue;
        }
        // Books stand on the board, leaning on nothing, until the row is full.
        let mut x = x0 + rng.range(0.0, 0.15);
        let floor = z + board;
        loop {
            let width = rng.range(0.03, 0.07);
            if x + width > x1 - 0.01 {
                break;
            }
            let depth = rng.range(0.15, 0.22);
            let tall = rng.range(0.2, 0.33);
            let color = shade(
                BOOKS[rng.below(BOOKS.len() as u64) as usize],
                rng.range(0.8, 1.1),
            );
            s.add_box(
                DVec3::new(x, half_d - 0.01 - depth, floor),
                DVec3::new(x + width, half_d - 0.01, floor + tall),
                color,
            );
            // Now and then a gap in the row.
            x += width
                + if rng.below(6) == 0 {
                    rng.range(0.05, 0.2)
                } else {
                    0.002
                };
        }
    }
    for q in &mut s.positions {
        if turned {
            // A quarter turn about z keeps every triangle's winding.
            *q = DVec3::new(-q.y, q.x, q.z);
        }
        *q += at;
    }
    m.append(&s);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::generate::shapes::closed_parts;
    use crate::scene::Primitives;

    fn params(grid: u32) -> CityParams {
        CityParams {
            seed: 1,
            grid,
            furniture: DEFAULT_FURNITURE,
            segments: DEFAULT_SEGMENTS,
        }
    }

    #[test]
    fn houses_stay_on_their_lots() {
        let p = params(3);
        for (i, j) in [(0, 0), (2, 1), (1, 2)] {
            let m = house(&p, i, j);
            let o = house_corner(i, j);
            for q in &m.positions {
                let d = *q - o;
                // Up to rounding in the world coordinates.
                let e = 1e-9;
                assert!(d.x >= -EAVES - e && d.x <= HOUSE_X + EAVES + e, "{d}");
                assert!(d.y >= -EAVES - e && d.y <= HOUSE_Y + EAVES + e, "{d}");
                assert!(d.z >= -e && d.z <= ROOF + e, "{d}");
            }
            assert!(closed_parts(&m.positions, &m.triangles).is_ok());
        }
    }

    #[test]
    fn every_wall_has_openings_and_the_front_a_door() {
        for (index, j) in [(0, 0), (3, 1), (8, 2), (9, 3)] {
            let m = structure(&mut Rng::new(hash(1, index)), j);
            // Boxes only: every 12 triangles are one box.
            let boxes: Vec<(DVec3, DVec3)> = m
                .triangles
                .chunks(12)
                .map(|c| {
                    let ps = c.iter().flatten().map(|&v| m.positions[v as usize]);
                    ps.fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), q| {
                        (lo.min(q), hi.max(q))
                    })
                })
                .collect();
            let blocked = |q: DVec3| {
                boxes
                    .iter()
                    .any(|(lo, hi)| q.cmpgt(*lo).all() && q.cmplt(*hi).all())
            };
            // Probes along the middle of a wall: does any pass between its boxes?
            let open = |f: &dyn Fn(f64) -> DVec3| {
                (0..400).any(|k| !blocked(f((f64::from(k) + 0.5) / 400.0)))
            };
            let shut = |f: &dyn Fn(f64) -> DVec3| {
                (0..400).all(|k| blocked(f((f64::from(k) + 0.5) / 400.0)))
            };
            let (window, door) = (FLOOR + SILL + 0.5, FLOOR + 1.95);
            let (south, north) = (WALL * 0.5, HOUSE_Y - WALL * 0.5);
            let (west, east) = (WALL * 0.5, HOUSE_X - WALL * 0.5);
            assert!(open(&|s| DVec3::new(s * HOUSE_X, south, window)));
            assert!(open(&|s| DVec3::new(s * HOUSE_X, north, window)));
            assert!(open(&|s| DVec3::new(west, s * HOUSE_Y, window)));
            assert!(open(&|s| DVec3::new(east, s * HOUSE_Y, window)));
            let (front, back) = if j % 2 == 1 {
                (south, north)
            } else {
                (north, south)
            };
            assert!(open(&|s| DVec3::new(s * HOUSE_X, front, door)), "door");
            assert!(
                shut(&|s| DVec3::new(s * HOUSE_X, back, door)),
                "no back door"
            );
            assert!(shut(&|s| DVec3::new(west, s * HOUSE_Y, door)));
            // Below the sills, only the door opens.
            assert!(shut(&|s| DVec3::new(s * HOUSE_X, back, FLOOR + 0.5)));
            assert!(closed_parts(&m.positions, &m.triangles).is_ok());
        }
    }

    #[test]
    fn furniture_counts_follow_the_parameter() {
        let count = |furniture: u32| {
            let p = CityParams {
                furniture,
                ..params(4)
            };
            let scene = city(&p);
            scene.geometries[1..]
                .iter()
                .map(|g| match &g.primitives {
                    Primitives::Triangles(t) => t.len(),
                    _ => 0,
                })
                .sum::<usize>()
        };
        let (none, some, many) = (count(0), count(4), count(16));
        assert!(none < some && some < many, "{none} {some} {many}");
    }
}
