//! `gen:island`: the built-in default scene. A noise-built island rising
//! from a shallow sea, with instanced trees on its lowlands.
//!
//! The scene holds three geometries:
//!
//! - **terrain**: one `size x size` heightfield mesh over a square of
//!   `extent` units centred on the origin. Heights are fBm gradient noise
//!   plus ridged noise for mountains, multiplied by a radial island mask
//!   whose radius is itself warped by noise (an irregular coastline), and
//!   rescaled so the highest peak is exactly `height` units; outside the
//!   mask the ground falls to a sea floor about `height / 8` deep. Colors
//!   follow height and slope (sea-floor sand, beach, grass darkening
//!   uphill, rock on steep or high ground, snow on high gentle ground);
//!   normals are central differences of the height grid.
//! - **sea**: a flat quad grid at z = 0 with half the terrain's resolution
//!   (at least 8 x 8). Water needs no detail, but a point renderer draws
//!   each vertex as a splat about one grid cell wide: a coarse sea would
//!   draw discs tens of units across that cover the beaches.
//! - **tree**: ONE tree mesh from [`super::tree`], placed `trees` times by
//!   [`Instance`]s (rotation about Z, scale 0.7..1.3, base sunk slightly into
//!   the ground). Any number of trees costs one mesh plus 104 bytes each.
//!
//! Noise is evaluated on continuous coordinates, and the number of octaves
//! grows with `size` only as far as the grid can resolve them, so every
//! `size` shows the same island at a different resolution.
//!
//! Tree placement never loops: the cells fit for trees (every corner above
//! the beach and below the rock line, normals within about 30 degrees of
//! vertical) are listed once; trees take distinct random cells while there
//! are more cells than trees (a partial Fisher-Yates shuffle) and share
//! cells once there are not, so the cost is O(cells + trees) however little
//! land there is. If no cell is fit, any all-land cell is used; with no land
//! at all (a tiny `size`, say) no trees are placed and the tree geometry is
//! left out, so the scene may hold fewer than `trees` trees.

use glam::{DAffine3, DMat3, DVec3, Vec3};
use rayon::prelude::*;

use super::noise::{fbm, fbm_and_ridged};
use super::rng::{Rng, hash, unit_f64};
use super::tree::tree_geometry;
use super::trig::sin_cos;
use crate::scene::{Geometry, Instance, Primitives, Rgb8, Scene};

/// Everything `gen:island` can be asked for (see [`super::generate`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IslandParams {
    pub seed: u64,
    /// Trees to place.
    pub trees: u64,
    /// Heightfield vertices per side.
    pub size: u32,
    /// Triangle budget of the one shared tree mesh.
    pub tree_triangles: u64,
    /// Width of the terrain square.
    pub extent: f64,
    /// Height of the highest peak.
    pub height: f64,
}

/// Sub-seeds, so each part's randomness is independent of the others.
const WARP: u64 = 1;
const RELIEF: u64 = 2;
const TREE: u64 = 3;
const PLACEMENT: u64 = 4;
const COLOR: u64 = 5;

/// Below this normal z a cell is too steep for trees (about 32 degrees).
const TREE_MAX_SLOPE_NZ: f32 = 0.85;
/// Trees grow between these fractions of the peak height.
const TREE_MIN_HEIGHT: f64 = 0.035;
const TREE_MAX_HEIGHT: f64 = 0.5;
/// How far a tree's base sinks into the ground (tree units), so trunks on
/// slopes do not float.
const TREE_SINK: f64 = 0.3;

/// `0` below `a`, `1` above `b`, smooth in between (`a > b` reverses it).
fn smoothstep(a: f64, b: f64, x: f64) -> f64 {
    let t = ((x - a) / (b - a)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

fn lerp3(a: [f64; 3], b: [f64; 3], t: f64) -> [f64; 3] {
    [
        a[0] + (b[0] - a[0]) * t,
        a[1] + (b[1] - a[1]) * t,
        a[2] + (b[2] - a[2]) * t,
    ]
}

/// The noise field, sampled at normalized coordinates `(u, v)` in
/// `[-1, 1]^2`.
#[derive(Debug, Clone, Copy)]
struct Field {
    seed: u64,
    /// Octaves of the relief and mountain noise.
    octaves: u32,
}

impl Field {
    /// Octaves the grid can resolve: the finest octave keeps at least eight
    /// vertices per wavelength (finer ones would only alias, and cost time).
    fn for_size(seed: u64, size: u32) -> Self {
        // The relief starts at 4 cycles across the square.
        let mut octaves = 1;
        while octaves < 12 && (4u64 << octaves) * 8 <= u64::from(size) {
            octaves += 1;
        }
        Self { seed, octaves }
    }

    /// Unscaled height: positive is land (later rescaled to the peak
    /// height), negative is sea floor.
    fn raw(&self, u: f64, v: f64) -> f64 {
        let warp = fbm(hash(self.seed, WARP), u * 1.3 + 11.0, v * 1.3 - 7.0, 2);
        let distance = (u * u + v * v).sqrt() + 0.4 * warp;
        let mask = smoothstep(0.95, 0.45, distance);
        let (relief, ridges) =
            fbm_and_ridged(hash(self.seed, RELIEF), u * 2.0, v * 2.0, self.octaves);
        // Mountains rise only well inside the island.
        let h = mask * (0.4 + 0.3 * relief + 0.9 * mask * mask * ridges) - 0.14
            + 0.08 * relief * (1.0 - mask);
        if h > 0.0 {
            // Flatter lowlands, steeper peaks.
            h * (0.5 + h)
        } else {
            h
        }
    }
}

/// The terrain mesh of `p` (see the module docs).
fn terrain(p: &IslandParams) -> Geometry {
    let g = p.size as usize;
    let field = Field::for_size(p.seed, p.size);
    let half = p.extent / 2.0;
    let step = 2.0 / (g - 1) as f64;
    let mut positions = vec![DVec3::ZERO; g * g];
    positions
        .par_chunks_mut(g)
        .enumerate()
        .for_each(|(j, row)| {
            let v = -1.0 + j as f64 * step;
            for (i, p) in row.iter_mut().enumerate() {
                let u = -1.0 + i as f64 * step;
                *p = DVec3::new(u * half, v * half, field.raw(u, v));
            }
        });
    let peak = positions.par_iter().map(|p| p.z).reduce(|| 0.0, f64::max);
    let land_scale = if peak > 0.0 { p.height / peak } else { 0.0 };
    let sea_scale = p.height * 0.6;
    positions
        .par_iter_mut()
        .for_each(|q| q.z *= if q.z > 0.0 { land_scale } else { sea_scale });

    // Normals by central differences (one-sided at the border), then colors.
    let spacing = p.extent / (g - 1) as f64;
    let mut normals = vec![Vec3::Z; g * g];
    let mut colors = vec![[0u8; 3]; g * g];
    let positions_ref = &positions;
    normals
        .par_chunks_mut(g)
        .zip(colors.par_chunks_mut(g))
        .enumerate()
        .for_each(|(j, (nrow, crow))| {
            let z = |i: usize, j: usize| positions_ref[j * g + i].z;
            let (j0, j1) = (j.saturating_sub(1), (j + 1).min(g - 1));
            for i in 0..g {
                let (i0, i1) = (i.saturating_sub(1), (i + 1).min(g - 1));
                let dzdx = (z(i1, j) - z(i0, j)) / ((i1 - i0) as f64 * spacing);
                let dzdy = (z(i, j1) - z(i, j0)) / ((j1 - j0) as f64 * spacing);
                let n = DVec3::new(-dzdx, -dzdy, 1.0).normalize();
                nrow[i] = n.as_vec3();
                crow[i] = ground_color(
                    p,
                    z(i, j),
                    n.z,
                    hash(hash(p.seed, COLOR), (j * g + i) as u64),
                );
            }
        });

    let cells = g - 1;
    let mut triangles = vec![[0u32; 3]; 2 * cells * cells];
    triangles
        .par_chunks_mut(2 * cells)
        .enumerate()
        .for_each(|(j, row)| {
            for i in 0..cells {
                let a = (j * g + i) as u32;
                let (b, c, d) = (a + 1, a + 1 + g as u32, a + g as u32);
                // Counter-clockwise seen from +Z; the diagonal runs a-c.
                row[2 * i] = [a, b, c];
                row[2 * i + 1] = [a, c, d];
            }
        });
    Geometry {
        name: "gen:island terrain".to_owned(),
        positions,
        normals: Some(normals),
        colors: Some(colors),
        primitives: Primitives::Triangles(triangles),
    }
}

/// Ground color by height `z`, normal z `nz` and 64 random bits `noise`.
fn ground_color(p: &IslandParams, z: f64, nz: f64, noise: u64) -> Rgb8 {
    let h = p.height;
    let jitter = unit_f64(noise) - 0.5;
    let sand = [196.0, 180.0, 130.0];
    let color = if z <= 0.0 {
        // Wet sand darkening with depth.
        lerp3(sand, [96.0, 92.0, 74.0], (-z / (0.1 * h)).clamp(0.0, 1.0))
    } else {
        let beach_top = h * (0.02 + 0.008 * jitter);
        let grass = lerp3(
            [112.0, 152.0, 62.0],
            [48.0, 92.0, 40.0],
            smoothstep(0.04 * h, 0.45 * h, z),
        );
        let mut c = lerp3(sand, grass, smoothstep(beach_top, beach_top + 0.012 * h, z));
        let rock = smoothstep(0.8, 0.62, nz).max(smoothstep(0.5 * h, 0.65 * h, z));
        c = lerp3(c, [122.0, 116.0, 108.0], rock);
        let snow = smoothstep(0.74 * h, 0.84 * h, z + 0.03 * h * jitter) * smoothstep(0.5, 0.7, nz);
        lerp3(c, [242.0, 244.0, 248.0], snow)
    };
    let brightness = 1.0 + 0.12 * jitter;
    color.map(|x| (x * brightness).round().clamp(0.0, 255.0) as u8)
}

/// The sea: a flat quad grid at z = 0 over the terrain's square, at half
/// the terrain's resolution.
fn sea(p: &IslandParams) -> Geometry {
    let cells = (p.size / 2).max(8);
    let half = p.extent / 2.0;
    let mut positions = Vec::with_capacity(((cells + 1) * (cells + 1)) as usize);
    for j in 0..=cells {
        for i in 0..=cells {
            let (u, v) = (
                f64::from(i) / f64::from(cells),
                f64::from(j) / f64::from(cells),
            );
            positions.push(DVec3::new(-half + u * p.extent, -half + v * p.extent, 0.0));
        }
    }
    let mut triangles = Vec::with_capacity((2 * cells * cells) as usize);
    for j in 0..cells {
        for i in 0..cells {
            let a = j * (cells + 1) + i;
            triangles.push([a, a + 1, a + cells + 2]);
            triangles.push([a, a + cells + 2, a + cells + 1]);
        }
    }
    let n = positions.len();
    Geometry {
        name: "gen:island sea".to_owned(),
        positions,
        normals: Some(vec![Vec3::Z; n]),
        colors: Some(vec![[28, 84, 140]; n]),
        primitives: Primitives::Triangles(triangles),
    }
}

/// Height of the terrain mesh's surface at `(fx, fy)` inside cell `(i, j)`,
/// interpolated on the same two triangles the mesh draws.
fn surface(t: &Geometry, g: usize, i: usize, j: usize, fx: f64, fy: f64) -> f64 {
    let z = |i: usize, j: usize| t.positions[j * g + i].z;
    let (a, b, c, d) = (z(i, j), z(i + 1, j), z(i + 1, j + 1), z(i, j + 1));
    if fx >= fy {
        a + fx * (b - a) + fy * (c - b)
    } else {
        a + fy * (d - a) + fx * (c - d)
    }
}

/// Cells (index `j * (size - 1) + i`) where a tree may stand: all four
/// corners pass `fit`.
fn cells_where(g: usize, fit: impl Fn(usize) -> bool) -> Vec<u32> {
    let cells = g - 1;
    let mut out = Vec::new();
    for j in 0..cells {
        for i in 0..cells {
            let a = j * g + i;
            if fit(a) && fit(a + 1) && fit(a + g) && fit(a + g + 1) {
                out.push((j * cells + i) as u32);
            }
        }
    }
    out
}

/// Tree placements on `t` (see the module docs for the strategy).
fn place_trees(p: &IslandParams, t: &Geometry) -> Vec<DAffine3> {
    let g = p.size as usize;
    let normals = t.normals.as_deref().unwrap_or_default();
    let (lo, hi) = (TREE_MIN_HEIGHT * p.height, TREE_MAX_HEIGHT * p.height);
    let mut cells = cells_where(g, |k| {
        let z = t.positions[k].z;
        (lo..=hi).contains(&z) && normals.get(k).is_some_and(|n| n.z >= TREE_MAX_SLOPE_NZ)
    });
    if cells.is_empty() {
        cells = cells_where(g, |k| t.positions[k].z > 0.0);
    }
    if cells.is_empty() || p.trees == 0 {
        return Vec::new();
    }
    let mut rng = Rng::new(hash(p.seed, PLACEMENT));
    let spacing = p.extent / (g - 1) as f64;
    let half = p.extent / 2.0;
    let len = cells.len();
    (0..p.trees)
        .map(|k| {
            let k = k as usize;
            let cell = if k < len {
                // Partial Fisher-Yates: distinct cells while they last.
                let pick = k + rng.below((len - k) as u64) as usize;
                cells.swap(k, pick);
                cells[k]
            } else {
                cells[rng.below(len as u64) as usize]
            } as usize;
            let (i, j) = (cell % (g - 1), cell / (g - 1));
            let (fx, fy) = (rng.next_f64(), rng.next_f64());
            let (s, c) = sin_cos(rng.range(0.0, std::f64::consts::TAU));
            let scale = rng.range(0.7, 1.3);
            let base = DVec3::new(
                -half + (i as f64 + fx) * spacing,
                -half + (j as f64 + fy) * spacing,
                surface(t, g, i, j, fx, fy) - TREE_SINK * scale,
            );
            let rotation =
                DMat3::from_cols(DVec3::new(c, s, 0.0), DVec3::new(-s, c, 0.0), DVec3::Z);
            DAffine3 {
                matrix3: rotation * scale,
                translation: base,
            }
        })
        .collect()
}

/// The whole island scene for `p`.
pub fn island(p: &IslandParams) -> Scene {
    let terrain = terrain(p);
    let placements = place_trees(p, &terrain);
    let mut scene = Scene::default();
    scene.instances.push(Instance {
        geometry: 0,
        world_from_local: DAffine3::IDENTITY,
    });
    scene.instances.push(Instance {
        geometry: 1,
        world_from_local: DAffine3::IDENTITY,
    });
    scene.geometries.push(terrain);
    scene.geometries.push(sea(p));
    if !placements.is_empty() {
        let tree = tree_geometry("gen:island tree", hash(p.seed, TREE), p.tree_triangles);
        scene.geometries.push(tree);
        scene
            .instances
            .extend(placements.into_iter().map(|world_from_local| Instance {
                geometry: 2,
                world_from_local,
            }));
    }
    scene
}
