//! `gen:forest`: `trees` instances of one tree on a square grid, nothing
//! else. The 1996 color-cube paper's Figure 5 scene: quadrupling `trees`
//! doubles the grid's side, so scene size grows while the tree mesh exists
//! once in memory.

use glam::{DAffine3, DMat3, DVec3};

use super::rng::{Rng, hash};
use super::tree::tree_geometry;
use super::trig::sin_cos;
use crate::scene::{Instance, Scene};

/// Distance between grid points, in tree heights (a tree is 10 units tall
/// and about 8 across).
const SPACING: f64 = 9.0;
/// Keys the random placement apart from other uses of the seed.
const PLACEMENT: u64 = 0xF0_2E57;

/// A forest of `trees` trees of `triangles` triangles each.
pub fn forest(seed: u64, trees: u64, triangles: u64) -> Scene {
    let mut scene = Scene::default();
    scene
        .geometries
        .push(tree_geometry("gen:forest tree", seed, triangles));
    let side = (trees as f64).sqrt().ceil().max(1.0) as u64;
    let mut rng = Rng::new(hash(seed, PLACEMENT));
    for k in 0..trees {
        let (i, j) = (k % side, k / side);
        let (s, c) = sin_cos(rng.range(0.0, std::f64::consts::TAU));
        let scale = rng.range(0.8, 1.2);
        let jitter = DVec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), 0.0);
        let rotation = DMat3::from_cols(DVec3::new(c, s, 0.0), DVec3::new(-s, c, 0.0), DVec3::Z);
        scene.instances.push(Instance {
            geometry: 0,
            world_from_local: DAffine3 {
                matrix3: rotation * scale,
                translation: DVec3::new(i as f64 * SPACING, j as f64 * SPACING, 0.0) + jitter,
            },
        });
    }
    scene
}
