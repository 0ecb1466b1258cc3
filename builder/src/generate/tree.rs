//! `gen:tree`: one broad-leaved tree, like the test tree of the color-cube
//! papers: a trunk, recursively branching limbs and many small leaves.
//!
//! The tree is grown in two steps:
//!
//! 1. A **skeleton** of limbs. Each limb is a slightly bent polyline with a
//!    radius per point. A limb sprouts a few lateral children along its
//!    length (golden-angle phyllotaxis, tilted away from the parent) and one
//!    apical child that continues it from its tip, until `depth` levels are
//!    reached. Every limb draws its random numbers from its own stream, keyed
//!    by its path from the trunk, so a deeper tree has the same coarse limbs
//!    as a shallower one with the same seed.
//! 2. A **mesh**. Limbs become tapered cylinders (rings of vertices,
//!    parallel-transported frames so they do not twist) in bark colors;
//!    terminal limbs get a closing cone and carry the leaves, each a small
//!    diamond of two triangles with its own green.
//!
//! The triangle budget decides the depth: the deepest skeleton whose bark
//! takes at most half of the budget and still leaves each twig a handful of
//! leaves wins, and leaves fill the rest, so the total lands within a
//! triangle of the `triangles` parameter. Small budgets switch to coarser
//! limbs (fewer ring sides and segments) when that buys more branching, and
//! leaf size scales so the crown looks equally full at any budget. Children start on their parent's
//! axis inside its cylinder, so limbs visibly connect; the apical child
//! starts exactly on its parent's last ring with the same radius.
//!
//! Leaves are single-sided: each faces away from the crown's centre (and a
//! little upward), which is what a viewer outside the crown sees, so
//! back-face culling and normal-cone culling keep working.
//!
//! Conventions: +Z up, trunk base centred at the origin, the whole tree
//! scaled to exactly [`HEIGHT`] units tall, counter-clockwise front faces,
//! unit per-vertex normals.

use glam::{DVec3, Vec3};

use super::rng::{Rng, hash};
use super::trig::sin_cos;
use crate::scene::{Geometry, Primitives, Rgb8};

/// Default triangle budget of `gen:tree`.
pub const DEFAULT_TRIANGLES: u64 = 50_000;
/// Smallest budget accepted: below it a tree has too few leaves to read as one.
pub const MIN_TRIANGLES: u64 = 1_000;
/// Largest budget accepted (about 1.5 GB of mesh); far more than a tree needs.
pub const MAX_TRIANGLES: u64 = 20_000_000;
/// Height of every generated tree, base to the top leaf.
pub const HEIGHT: f64 = 10.0;

/// The deepest skeleton tried; 3^8 twigs is plenty for any budget.
const MAX_DEPTH: usize = 8;

/// How finely limbs are tessellated, by depth.
#[derive(Debug, Clone, Copy)]
struct Detail {
    /// Vertices per ring: round trunk, triangular twigs.
    sides: [u32; MAX_DEPTH + 1],
    /// Segments per limb: long limbs bend, twigs are nearly straight.
    segments: [u32; MAX_DEPTH + 1],
}

/// For budgets that afford a well-branched tree.
const FULL: Detail = Detail {
    sides: [12, 8, 6, 5, 4, 3, 3, 3, 3],
    segments: [8, 5, 4, 3, 3, 2, 2, 2, 2],
};
/// For small budgets: coarser limbs buy more branching and leaves.
const LEAN: Detail = Detail {
    sides: [6, 4, 3, 3, 3, 3, 3, 3, 3],
    segments: [4, 3, 2, 2, 2, 1, 1, 1, 1],
};

/// The golden angle (radians): successive laterals spread evenly around.
const GOLDEN_ANGLE: f64 = 2.399_963_229_728_653;
const TAU: f64 = std::f64::consts::TAU;
/// Trunk length and base radius before the final scaling to [`HEIGHT`].
const TRUNK_LENGTH: f64 = 4.0;
const TRUNK_RADIUS: f64 = 0.32;

/// One limb of the skeleton.
#[derive(Debug, Clone)]
struct Limb {
    /// Key of the limb's random stream: hash of its path from the trunk.
    id: u64,
    depth: usize,
    /// Vertices per ring.
    sides: u32,
    /// The axis, base first; one point more than the limb has segments.
    points: Vec<DVec3>,
    /// Radius at each point.
    radii: Vec<f64>,
    /// Terminal limbs (twigs) close with a cone and carry leaves.
    terminal: bool,
}

impl Limb {
    /// Triangles of this limb's mesh: the tube, the tip cone of a twig and
    /// the bottom cap of the trunk.
    fn triangle_count(&self) -> u64 {
        let sides = u64::from(self.sides);
        let segments = self.points.len() as u64 - 1;
        let mut n = 2 * sides * segments;
        if self.terminal {
            n += sides;
        }
        if self.depth == 0 {
            n += sides;
        }
        n
    }

    /// Point, unit direction and radius at parameter `t` in `[0, 1]` along
    /// the axis.
    fn at(&self, t: f64) -> (DVec3, DVec3, f64) {
        let segments = self.points.len() - 1;
        let x = t.clamp(0.0, 1.0) * segments as f64;
        let k = (x.floor() as usize).min(segments - 1);
        let f = x - k as f64;
        let (a, b) = (self.points[k], self.points[k + 1]);
        let radius = self.radii[k] + f * (self.radii[k + 1] - self.radii[k]);
        (a + (b - a) * f, (b - a).normalize(), radius)
    }
}

/// Any unit vector perpendicular to unit `d`, chosen by a fixed rule.
fn perpendicular(d: DVec3) -> DVec3 {
    let axis = if d.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
    (axis - d * axis.dot(d)).normalize()
}

/// A random vector in the cube `[-1, 1]^3`: cheap jitter for bending.
fn jitter(rng: &mut Rng) -> DVec3 {
    DVec3::new(
        rng.range(-1.0, 1.0),
        rng.range(-1.0, 1.0),
        rng.range(-1.0, 1.0),
    )
}

/// `d` tilted by `angle` toward the azimuth `phi` around it.
fn tilt(d: DVec3, phi: f64, angle: f64) -> DVec3 {
    let u = perpendicular(d);
    let v = d.cross(u);
    let (sp, cp) = sin_cos(phi);
    let (sa, ca) = sin_cos(angle);
    (d * ca + (u * cp + v * sp) * sa).normalize()
}

/// Everything that grows a skeleton.
#[derive(Debug, Clone, Copy)]
struct Grower {
    seed: u64,
    max_depth: usize,
    detail: Detail,
}

/// Where and how a limb starts.
#[derive(Debug, Clone, Copy)]
struct Sprout {
    id: u64,
    depth: usize,
    base: DVec3,
    dir: DVec3,
    length: f64,
    radius: f64,
}

impl Grower {
    /// Grows the limb `s` and, recursively, all its children into `out`.
    fn grow(&self, s: Sprout, out: &mut Vec<Limb>) {
        let mut rng = Rng::new(hash(self.seed, s.id));
        let segments = self.detail.segments[s.depth];
        // The trunk stays fairly straight; limbs wander and bend upward.
        let (bend, tropism) = if s.depth == 0 {
            (0.05, 0.02)
        } else {
            (0.16, 0.07)
        };
        let mut points = Vec::with_capacity(segments as usize + 1);
        let mut radii = Vec::with_capacity(segments as usize + 1);
        let (mut p, mut d) = (s.base, s.dir);
        for k in 0..=segments {
            let t = f64::from(k) / f64::from(segments);
            let mut r = s.radius * (1.0 - 0.6 * t);
            if s.depth == 0 {
                // Root flare: the trunk widens where it meets the ground.
                let f = (1.0 - t) * (1.0 - t);
                r *= 1.0 + 0.6 * f * f * f;
            }
            points.push(p);
            radii.push(r);
            if k < segments {
                p += d * (s.length / f64::from(segments));
                d = (d + jitter(&mut rng) * bend + DVec3::Z * tropism).normalize();
            }
        }
        let terminal = s.depth >= self.max_depth;
        let limb = Limb {
            id: s.id,
            depth: s.depth,
            sides: self.detail.sides[s.depth],
            points,
            radii,
            terminal,
        };
        let (end, end_dir, end_radius) = limb.at(1.0);
        let mut children = Vec::new();
        if !terminal {
            let (laterals, lo, hi) = if s.depth == 0 {
                (rng.range_inclusive(4, 6), 0.4, 0.95)
            } else {
                (rng.range_inclusive(2, 3), 0.25, 0.95)
            };
            let phi0 = rng.range(0.0, TAU);
            for j in 0..laterals {
                let t =
                    lo + (hi - lo) * (f64::from(j) + rng.range(0.15, 0.85)) / f64::from(laterals);
                let (base, dir, radius) = limb.at(t);
                let phi = phi0 + f64::from(j) * GOLDEN_ANGLE + rng.range(-0.3, 0.3);
                let angle = if s.depth == 0 {
                    rng.range(0.75, 1.05)
                } else {
                    rng.range(0.45, 0.9)
                };
                // Lower laterals reach further: a rounded, slightly conical crown.
                let length = s.length * rng.range(0.55, 0.72) * (1.25 - 0.45 * t);
                children.push(Sprout {
                    id: hash(s.id, u64::from(j) + 1),
                    depth: s.depth + 1,
                    base,
                    dir: tilt(dir, phi, angle),
                    length,
                    radius: radius * rng.range(0.5, 0.7),
                });
            }
            // The apical child continues the limb from its last ring.
            let dir = (end_dir + jitter(&mut rng) * 0.12).normalize();
            children.push(Sprout {
                id: hash(s.id, 0),
                depth: s.depth + 1,
                base: end,
                dir,
                length: s.length * rng.range(0.62, 0.75),
                radius: end_radius,
            });
        }
        out.push(limb);
        for child in children {
            self.grow(child, out);
        }
    }

    fn skeleton(&self) -> Vec<Limb> {
        let mut limbs = Vec::new();
        let trunk = Sprout {
            id: 0,
            depth: 0,
            base: DVec3::ZERO,
            dir: DVec3::Z,
            length: TRUNK_LENGTH,
            radius: TRUNK_RADIUS,
        };
        self.grow(trunk, &mut limbs);
        limbs
    }
}

/// The vertex and index buffers being filled.
#[derive(Debug, Default)]
struct Mesh {
    positions: Vec<DVec3>,
    normals: Vec<Vec3>,
    colors: Vec<Rgb8>,
    triangles: Vec<[u32; 3]>,
}

impl Mesh {
    fn vertex(&mut self, p: DVec3, n: DVec3, c: Rgb8) -> u32 {
        self.positions.push(p);
        self.normals.push(n.as_vec3());
        self.colors.push(c);
        // Counts stay far below u32::MAX: MAX_TRIANGLES bounds them.
        (self.positions.len() - 1) as u32
    }
}

/// Scales an RGB color by `f`, rounding and saturating to 8 bits.
fn shade(c: [f64; 3], f: f64) -> Rgb8 {
    c.map(|x| (x * f).round().clamp(0.0, 255.0) as u8)
}

/// Appends one limb as a tapered tube.
fn add_limb(mesh: &mut Mesh, limb: &Limb) {
    let sides = limb.sides;
    let n = limb.points.len();
    let ring: Vec<(f64, f64)> = (0..sides)
        .map(|i| sin_cos(TAU * f64::from(i) / f64::from(sides)))
        .collect();
    let dir = |k: usize| {
        let (a, b) = if k == 0 {
            (limb.points[0], limb.points[1])
        } else if k == n - 1 {
            (limb.points[n - 2], limb.points[n - 1])
        } else {
            (limb.points[k - 1], limb.points[k + 1])
        };
        (b - a).normalize()
    };
    // Bark: grey-brown, lighter and greyer on thin limbs, jittered per vertex.
    let bark = if limb.depth == 0 {
        [92.0, 68.0, 47.0]
    } else {
        [104.0, 82.0, 60.0]
    };
    let color = |k: usize, i: u32| {
        let h = hash(limb.id, (k as u64) << 8 | u64::from(i));
        shade(bark, 0.85 + 0.3 * super::rng::unit_f64(h))
    };
    let first = mesh.positions.len() as u32;
    let mut u = perpendicular(dir(0));
    let mut frame0 = (DVec3::X, DVec3::Y);
    for k in 0..n {
        let d = dir(k);
        // Parallel transport: keep u as close as possible to the last ring's.
        u = (u - d * u.dot(d)).normalize();
        let v = d.cross(u);
        if k == 0 {
            frame0 = (u, v);
        }
        for (i, &(s, c)) in ring.iter().enumerate() {
            let radial = u * c + v * s;
            mesh.vertex(
                limb.points[k] + radial * limb.radii[k],
                radial,
                color(k, i as u32),
            );
        }
    }
    for k in 0..n as u32 - 1 {
        for i in 0..sides {
            let j = (i + 1) % sides;
            let a = first + k * sides + i;
            let b = first + k * sides + j;
            let c = b + sides;
            let d = a + sides;
            mesh.triangles.push([a, b, c]);
            mesh.triangles.push([a, c, d]);
        }
    }
    if limb.terminal {
        // A short cone closes the twig.
        let d = dir(n - 1);
        let last = first + (n as u32 - 1) * sides;
        let tip = mesh.vertex(
            limb.points[n - 1] + d * limb.radii[n - 1] * 0.5,
            d,
            color(n, 0),
        );
        for i in 0..sides {
            mesh.triangles.push([last + i, last + (i + 1) % sides, tip]);
        }
    }
    if limb.depth == 0 {
        // The trunk's bottom cap, with its own downward-facing vertices.
        let d = dir(0);
        let (u, v) = frame0;
        let centre = mesh.vertex(limb.points[0], -d, color(0, sides));
        let cap = mesh.positions.len() as u32;
        for (i, &(s, c)) in ring.iter().enumerate() {
            let radial = u * c + v * s;
            mesh.vertex(
                limb.points[0] + radial * limb.radii[0],
                -d,
                color(0, i as u32),
            );
        }
        for i in 0..sides {
            mesh.triangles
                .push([centre, cap + (i + 1) % sides, cap + i]);
        }
    }
}

/// Leaf layout shared by all twigs.
#[derive(Debug, Clone, Copy)]
struct LeafStyle {
    length: f64,
    crown_centre: DVec3,
}

/// Appends `count` leaves along the outer part of twig `limb`.
fn add_leaves(mesh: &mut Mesh, seed: u64, limb: &Limb, count: u64, style: LeafStyle) {
    let mut rng = Rng::new(hash(hash(seed, limb.id), 0x1EAF));
    for _ in 0..count {
        let (p, d, r) = limb.at(rng.range(0.2, 1.0));
        // Leaf axis: out from the twig, tilted toward its tip and the sky.
        let phi = rng.range(0.0, TAU);
        let elevation = rng.range(0.3, 0.9);
        let side = tilt(d, phi, std::f64::consts::FRAC_PI_2);
        let (se, ce) = sin_cos(elevation);
        let axis = (side * ce + d * se + DVec3::Z * 0.25).normalize();
        let across = d.cross(axis);
        let across = if across.length_squared() > 1e-12 {
            across.normalize()
        } else {
            perpendicular(axis)
        };
        // Roll the blade a little about its axis.
        let (sr, cr) = sin_cos(rng.range(-0.6, 0.6));
        let mut w = across * cr + axis.cross(across) * sr;
        let base = p + side * r;
        let mut normal = w.cross(axis).normalize();
        let outward = (base - style.crown_centre).normalize_or(DVec3::Z) + DVec3::Z * 0.5;
        if normal.dot(outward) < 0.0 {
            w = -w;
            normal = -normal;
        }
        let length = style.length * rng.range(0.75, 1.25);
        let half_width = length * rng.range(0.22, 0.3);
        // Greens vary per leaf; a few leaves are yellowing.
        let mut green = [
            rng.range(40.0, 85.0),
            rng.range(100.0, 160.0),
            rng.range(25.0, 55.0),
        ];
        if rng.next_f64() < 0.06 {
            green[0] += 70.0;
            green[1] += 20.0;
        }
        let a = mesh.vertex(base, normal, shade(green, 0.8));
        let b = mesh.vertex(
            base + w * half_width + axis * (0.4 * length),
            normal,
            shade(green, 1.0),
        );
        let c = mesh.vertex(base + axis * length, normal, shade(green, 1.12));
        let e = mesh.vertex(
            base - w * half_width + axis * (0.4 * length),
            normal,
            shade(green, 1.0),
        );
        // (base, +w, tip, -w) runs counter-clockwise seen from `w x axis`.
        mesh.triangles.push([a, b, c]);
        mesh.triangles.push([a, c, e]);
    }
}

/// Picks the skeleton for a triangle budget: the deepest one whose bark
/// uses at most half the budget and leaves at least 8 leaves per twig,
/// tessellated with [`FULL`] detail unless [`LEAN`] detail buys more depth.
fn skeleton_for(seed: u64, triangles: u64) -> Vec<Limb> {
    let deepest = |detail: Detail| {
        let mut best = (
            0,
            Grower {
                seed,
                max_depth: 0,
                detail,
            }
            .skeleton(),
        );
        for max_depth in 1..=MAX_DEPTH {
            let limbs = Grower {
                seed,
                max_depth,
                detail,
            }
            .skeleton();
            let bark: u64 = limbs.iter().map(Limb::triangle_count).sum();
            let twigs = limbs.iter().filter(|l| l.terminal).count() as u64;
            if bark * 2 > triangles || triangles.saturating_sub(bark) / 2 < 8 * twigs {
                break;
            }
            best = (max_depth, limbs);
        }
        best
    };
    let (full_depth, full) = deepest(FULL);
    if full_depth >= 4 {
        return full;
    }
    let (lean_depth, lean) = deepest(LEAN);
    if lean_depth > full_depth { lean } else { full }
}

/// One tree of about `triangles` triangles (see the module docs), named
/// `name`. Deterministic in `(seed, triangles)`.
pub fn tree_geometry(name: &str, seed: u64, triangles: u64) -> Geometry {
    let limbs = skeleton_for(seed, triangles);
    let bark: u64 = limbs.iter().map(Limb::triangle_count).sum();
    let twigs: Vec<&Limb> = limbs.iter().filter(|l| l.terminal).collect();
    let leaves = triangles.saturating_sub(bark) / 2;
    let mut mesh = Mesh::default();
    let reserve = (bark + 2 * leaves) as usize;
    mesh.triangles.reserve(reserve);
    mesh.positions.reserve(reserve + reserve / 2);
    mesh.normals.reserve(reserve + reserve / 2);
    mesh.colors.reserve(reserve + reserve / 2);
    for limb in &limbs {
        add_limb(&mut mesh, limb);
    }

    let skeleton_height = limbs
        .iter()
        .flat_map(|l| &l.points)
        .map(|p| p.z)
        .fold(0.0, f64::max);
    let tips = twigs
        .iter()
        .map(|l| *l.points.last().unwrap_or(&DVec3::ZERO));
    let crown_centre = tips.fold(DVec3::ZERO, |a, p| a + p) / twigs.len().max(1) as f64;
    // Keep the crown's total leaf area about constant: fewer, larger leaves
    // on small budgets, more and smaller ones on large budgets.
    let size = (20_000.0 / leaves.max(1) as f64).sqrt().clamp(0.3, 3.0);
    let style = LeafStyle {
        length: skeleton_height * 0.035 * size,
        crown_centre,
    };
    let n = twigs.len().max(1) as u64;
    for (k, limb) in twigs.iter().enumerate() {
        let count = leaves / n + u64::from((k as u64) < leaves % n);
        add_leaves(&mut mesh, seed, limb, count, style);
    }

    // Scale about the base so the tree is exactly HEIGHT tall.
    let top = mesh.positions.iter().map(|p| p.z).fold(0.0, f64::max);
    if top > 0.0 {
        let s = HEIGHT / top;
        for p in &mut mesh.positions {
            *p *= s;
        }
    }
    Geometry {
        name: name.to_owned(),
        positions: mesh.positions,
        normals: Some(mesh.normals),
        colors: Some(mesh.colors),
        primitives: Primitives::Triangles(mesh.triangles),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn triangles(g: &Geometry) -> &[[u32; 3]] {
        match &g.primitives {
            Primitives::Triangles(t) => t,
            _ => panic!("tree is not a triangle mesh"),
        }
    }

    #[test]
    fn triangle_budget_is_met() {
        for target in [MIN_TRIANGLES, 5_000, 20_000, DEFAULT_TRIANGLES, 200_000] {
            let g = tree_geometry("t", 1, target);
            let n = triangles(&g).len() as f64;
            let t = target as f64;
            assert!(
                (0.8 * t..=1.2 * t).contains(&n),
                "target {target}: {n} triangles"
            );
        }
    }

    #[test]
    fn bounding_box_is_plausible() {
        for seed in [1, 2, 3, 99] {
            let g = tree_geometry("t", seed, 20_000);
            let (lo, hi) = g
                .positions
                .iter()
                .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), &p| {
                    (lo.min(p), hi.max(p))
                });
            assert!((hi.z - HEIGHT).abs() < 1e-9, "top {}", hi.z);
            assert!(lo.z > -0.5, "bottom {}", lo.z);
            let width = (hi.x - lo.x).max(hi.y - lo.y);
            assert!(
                (3.0..=14.0).contains(&width),
                "seed {seed}: crown width {width}"
            );
            assert!(lo.x.abs() < 8.0 && hi.x.abs() < 8.0 && lo.y.abs() < 8.0 && hi.y.abs() < 8.0);
        }
    }

    #[test]
    fn faces_agree_with_normals() {
        let g = tree_geometry("t", 5, 20_000);
        let normals = g.normals.as_ref().expect("normals");
        let colors = g.colors.as_ref().expect("colors");
        assert_eq!(normals.len(), g.positions.len());
        assert_eq!(colors.len(), g.positions.len());
        for n in normals {
            assert!((n.length() - 1.0).abs() < 1e-5);
        }
        let mut checked = 0;
        for t in triangles(&g) {
            let [a, b, c] = t.map(|i| g.positions[i as usize]);
            let face = (b - a).cross(c - a);
            if face.length() < 1e-9 {
                continue;
            }
            let avg: Vec3 = t.iter().map(|&i| normals[i as usize]).sum();
            assert!(
                face.dot(avg.as_dvec3()) > 0.0,
                "triangle {t:?} faces against its normals"
            );
            checked += 1;
        }
        assert!(checked > 15_000);
    }
}
