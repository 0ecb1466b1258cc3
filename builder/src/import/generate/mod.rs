//! Procedural scenes: `gen:NAME` inputs that need no file.
//!
//! - `gen:tree` (`tree.rs`): one broad-leaved tree, trunk to leaves, about
//!   `triangles` triangles (default 50 000), 10 units tall on the origin.
//!   Params: `seed` (1), `triangles` (50000, 1000..=20000000).
//! - `gen:island` (`island.rs`): the built-in default scene ([`DEFAULT_SCENE`]):
//!   a heightfield island in a flat sea with `trees` instances of one shared
//!   tree mesh. Params: `seed` (1), `trees` (16, 0..=10000000), `size`
//!   (512 heightfield vertices per side, 2..=16384), `tree_triangles`
//!   (20000), `extent` (1000 units across), `height` (80, the highest peak).
//! - `gen:forest` (`forest.rs`): `trees` (1, 1..=1048576) instances of one
//!   `gen:tree` on a square grid, for the color-cube paper's scaling
//!   experiment. Params: `seed` (1), `trees`, `triangles` (50000).
//!
//! Generators are the project's reproducible test inputs, so they are
//! **deterministic**: the same name and params give bitwise the same
//! [`Scene`] on every platform. Randomness comes from our own SplitMix64
//! (`rng.rs`) keyed by position or path, noise from integer lattice hashes
//! (`noise.rs`), trigonometry from plain IEEE arithmetic (`trig.rs`), and
//! parallel loops only ever write values that depend on their own index.
//!
//! Unknown names, unknown params and bad values are errors naming what is
//! accepted, never silently ignored: a typo in a benchmark's params must not
//! quietly benchmark the default scene.

mod forest;
mod island;
mod noise;
mod rng;
mod tree;
mod trig;

use std::fmt::Display;
use std::str::FromStr;

use super::{ImportError, Params};
use crate::scene::Scene;

/// The scene built when no input is given.
pub const DEFAULT_SCENE: &str = "gen:island";

/// Names accepted after `gen:`.
pub const GENERATORS: [&str; 3] = ["tree", "island", "forest"];

const TREE_KEYS: [&str; 2] = ["seed", "triangles"];
const FOREST_KEYS: [&str; 3] = ["seed", "trees", "triangles"];
const ISLAND_KEYS: [&str; 6] = [
    "seed",
    "trees",
    "size",
    "tree_triangles",
    "extent",
    "height",
];

/// Builds the procedural scene `name` (without the `gen:` prefix) from
/// `params`; see the module docs for names and params.
pub fn generate(name: &str, params: &Params) -> Result<Scene, ImportError> {
    match name {
        "tree" => {
            let p = Reader::new(name, params, &TREE_KEYS)?;
            let seed = p.get("seed", 1u64)?;
            let triangles = p.range(
                "triangles",
                tree::DEFAULT_TRIANGLES,
                tree::MIN_TRIANGLES,
                tree::MAX_TRIANGLES,
            )?;
            Ok(Scene::single(tree::tree_geometry(
                "gen:tree", seed, triangles,
            )))
        }
        "forest" => {
            let p = Reader::new(name, params, &FOREST_KEYS)?;
            Ok(forest::forest(
                p.get("seed", 1u64)?,
                p.range("trees", 1, 1, 1 << 20)?,
                p.range(
                    "triangles",
                    tree::DEFAULT_TRIANGLES,
                    tree::MIN_TRIANGLES,
                    tree::MAX_TRIANGLES,
                )?,
            ))
        }
        "island" => {
            let p = Reader::new(name, params, &ISLAND_KEYS)?;
            let island = island::IslandParams {
                seed: p.get("seed", 1u64)?,
                trees: p.range("trees", 16, 0, 10_000_000)?,
                size: p.range("size", 512, 2, 16_384)?,
                tree_triangles: p.range(
                    "tree_triangles",
                    20_000,
                    tree::MIN_TRIANGLES,
                    tree::MAX_TRIANGLES,
                )?,
                extent: p.range("extent", 1000.0, 1e-3, 1e9)?,
                height: p.range("height", 80.0, 1e-3, 1e7)?,
            };
            Ok(island::island(&island))
        }
        _ => Err(ImportError::Generator {
            name: name.to_owned(),
            message: format!(
                "unknown generator (known: {})",
                GENERATORS.map(|g| format!("gen:{g}")).join(", ")
            ),
        }),
    }
}

/// Reads and checks one generator's params, turning every problem into an
/// [`ImportError::Generator`] that lists the accepted keys.
#[derive(Debug)]
struct Reader<'a> {
    name: &'a str,
    params: &'a Params,
    known: &'a [&'a str],
}

impl<'a> Reader<'a> {
    /// Fails if `params` holds keys outside `known`.
    fn new(name: &'a str, params: &'a Params, known: &'a [&'a str]) -> Result<Self, ImportError> {
        let reader = Self {
            name,
            params,
            known,
        };
        let unknown = params.unknown_keys(known);
        if unknown.is_empty() {
            Ok(reader)
        } else {
            Err(reader.error(format!("unknown parameter {}", unknown.join(", "))))
        }
    }

    fn error(&self, message: String) -> ImportError {
        ImportError::Generator {
            name: self.name.to_owned(),
            message: format!(
                "{message} (gen:{} takes {})",
                self.name,
                self.known.join(", ")
            ),
        }
    }

    /// `key` parsed as `T`, or `default` when absent.
    fn get<T: FromStr>(&self, key: &str, default: T) -> Result<T, ImportError> {
        self.params
            .parse_or(key, default)
            .map_err(|e| self.error(e))
    }

    /// `key` parsed as `T` and checked to lie in `lo..=hi` (which also
    /// rejects NaN).
    fn range<T: FromStr + PartialOrd + Display>(
        &self,
        key: &str,
        default: T,
        lo: T,
        hi: T,
    ) -> Result<T, ImportError> {
        let value = self.get(key, default)?;
        if lo <= value && value <= hi {
            Ok(value)
        } else {
            Err(self.error(format!(
                "parameter {key}={value} is out of range {lo}..={hi}"
            )))
        }
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;
    use crate::import::validate;
    use crate::scene::{Geometry, Primitives};
    use glam::DVec3;

    fn params(pairs: &[&str]) -> Params {
        Params::parse(pairs).expect("params")
    }

    fn gen_ok(name: &str, pairs: &[&str]) -> Scene {
        let scene = generate(name, &params(pairs)).expect("generates");
        validate(Path::new(name), &scene).expect("valid scene");
        scene
    }

    fn message(name: &str, pairs: &[&str]) -> String {
        match generate(name, &params(pairs)) {
            Err(ImportError::Generator { name: n, message }) => {
                assert_eq!(n, name);
                message
            }
            other => panic!("expected a generator error, got {other:?}"),
        }
    }

    fn triangles(g: &Geometry) -> usize {
        match &g.primitives {
            Primitives::Triangles(t) => t.len(),
            _ => panic!("not triangles"),
        }
    }

    /// FNV-1a over every bit of the scene: equal hashes mean bitwise equal
    /// scenes (PartialEq would call 0.0 and -0.0 equal).
    fn fingerprint(scene: &Scene) -> u64 {
        let mut h = 0xCBF2_9CE4_8422_2325u64;
        let mut eat = |x: u64| {
            for b in x.to_le_bytes() {
                h = (h ^ u64::from(b)).wrapping_mul(0x100_0000_01B3);
            }
        };
        for g in &scene.geometries {
            eat(g.positions.len() as u64);
            for p in &g.positions {
                p.to_array().into_iter().for_each(|x| eat(x.to_bits()));
            }
            for n in g.normals.iter().flatten() {
                n.to_array()
                    .into_iter()
                    .for_each(|x| eat(u64::from(x.to_bits())));
            }
            for c in g.colors.iter().flatten() {
                eat(u64::from(c[0]) | u64::from(c[1]) << 8 | u64::from(c[2]) << 16);
            }
            if let Primitives::Triangles(t) = &g.primitives {
                t.iter().flatten().for_each(|&i| eat(u64::from(i)));
            }
        }
        for i in &scene.instances {
            eat(i.geometry as u64);
            i.world_from_local
                .to_cols_array()
                .into_iter()
                .for_each(|x| eat(x.to_bits()));
        }
        h
    }

    fn tree_instances(scene: &Scene) -> usize {
        scene.instances.iter().filter(|i| i.geometry == 2).count()
    }

    #[test]
    fn tree_is_deterministic_and_seeded() {
        let a = gen_ok("tree", &["triangles=5000"]);
        let b = gen_ok("tree", &["triangles=5000", "seed=1"]);
        let c = gen_ok("tree", &["triangles=5000", "seed=2"]);
        assert_eq!(a, b);
        assert_eq!(fingerprint(&a), fingerprint(&b));
        assert_ne!(fingerprint(&a), fingerprint(&c));
    }

    #[test]
    fn default_tree_has_the_asked_triangles() {
        let scene = gen_ok("tree", &[]);
        assert_eq!(scene.geometries.len(), 1);
        assert_eq!(scene.instances.len(), 1);
        let n = triangles(&scene.geometries[0]) as f64;
        assert!((40_000.0..=60_000.0).contains(&n), "{n}");
        assert!(scene.has_color());
        assert!(scene.geometries[0].normals.is_some());
    }

    #[test]
    fn island_is_deterministic_and_seeded() {
        let p = ["size=96", "trees=50", "tree_triangles=2000"];
        let a = gen_ok("island", &p);
        let b = gen_ok("island", &p);
        assert_eq!(a, b);
        assert_eq!(fingerprint(&a), fingerprint(&b));
        let c = gen_ok("island", &[p[0], p[1], p[2], "seed=2"]);
        assert_ne!(fingerprint(&a), fingerprint(&c));
        assert_ne!(a.geometries[0].positions, c.geometries[0].positions);
    }

    /// Pins the exact output, so a change of platform, compiler, glam or of
    /// the generators themselves that alters any bit is noticed. When a
    /// generator is changed on purpose, update the constants from the
    /// failure message (and expect rebuilt hierarchies to differ).
    #[test]
    fn output_is_pinned() {
        let tree = gen_ok("tree", &["triangles=1000", "seed=7"]);
        let island = gen_ok(
            "island",
            &["size=33", "trees=8", "tree_triangles=1000", "seed=7"],
        );
        let got = (fingerprint(&tree), fingerprint(&island));
        assert_eq!(
            got,
            (0xe707_fb58_ab10_5850, 0x6785_6ff3_e8b0_34c4),
            "generator output changed: {got:#x?}"
        );
    }

    #[test]
    fn island_has_terrain_sea_and_shared_tree() {
        let scene = gen_ok("island", &["size=128"]);
        assert_eq!(scene.geometries.len(), 3);
        assert_eq!(triangles(&scene.geometries[0]), 2 * 127 * 127);
        assert_eq!(scene.geometries[0].positions.len(), 128 * 128);
        // The sea at half the terrain resolution: 64 x 64 quads.
        assert_eq!(triangles(&scene.geometries[1]), 2 * 64 * 64);
        let tree = triangles(&scene.geometries[2]) as f64;
        assert!((16_000.0..=24_000.0).contains(&tree));
        assert_eq!(tree_instances(&scene), 16);
        for g in &scene.geometries {
            assert_eq!(
                g.normals.as_ref().map(Vec::len),
                Some(g.positions.len()),
                "{}",
                g.name
            );
            assert_eq!(
                g.colors.as_ref().map(Vec::len),
                Some(g.positions.len()),
                "{}",
                g.name
            );
        }
        // Land and sea, the peak at the asked height, sea floor below zero.
        let z: Vec<f64> = scene.geometries[0].positions.iter().map(|p| p.z).collect();
        let top = z.iter().copied().fold(f64::MIN, f64::max);
        let bottom = z.iter().copied().fold(f64::MAX, f64::min);
        assert!((top - 80.0).abs() < 1e-9, "peak {top}");
        assert!((-30.0..-2.0).contains(&bottom), "sea floor {bottom}");
        let land = z.iter().filter(|&&z| z > 0.0).count() as f64 / z.len() as f64;
        assert!((0.15..0.7).contains(&land), "land fraction {land}");
        // Several ground colors.
        let mut colors = scene.geometries[0].colors.clone().unwrap_or_default();
        colors.sort_unstable();
        colors.dedup();
        assert!(colors.len() > 100);
        // Trees stand on land, not too high, upright, scaled 0.7..1.3.
        for i in scene.instances.iter().filter(|i| i.geometry == 2) {
            let t = i.world_from_local;
            assert!(
                t.translation.z > 0.0 && t.translation.z < 0.5 * 80.0,
                "{t:?}"
            );
            let scale = t.matrix3.z_axis.z;
            assert!((0.7..=1.3).contains(&scale));
            assert!((t.matrix3.x_axis.length() - scale).abs() < 1e-12);
            assert_eq!(t.matrix3.x_axis.z, 0.0);
        }
    }

    #[test]
    fn tree_counts_are_honoured() {
        let base = ["size=64", "tree_triangles=1000"];
        let zero = gen_ok("island", &[base[0], base[1], "trees=0"]);
        assert_eq!(zero.geometries.len(), 2, "no tree mesh without trees");
        assert_eq!(zero.instances.len(), 2);
        for (n, want) in [("trees=1", 1), ("trees=4096", 4096)] {
            let scene = gen_ok("island", &[base[0], base[1], n]);
            assert_eq!(tree_instances(&scene), want);
            assert_eq!(scene.instances.len(), want + 2);
            assert_eq!(scene.geometries.len(), 3, "one shared tree mesh");
        }
    }

    #[test]
    fn tiny_grids_do_not_hang() {
        // A 2 x 2 grid is all sea: no tree fits, none is placed.
        let scene = gen_ok("island", &["size=2", "trees=1000", "tree_triangles=1000"]);
        assert_eq!(triangles(&scene.geometries[0]), 2);
        assert_eq!(tree_instances(&scene), 0);
        let scene = gen_ok("island", &["size=9", "trees=1000", "tree_triangles=1000"]);
        assert!(tree_instances(&scene) <= 1000);
    }

    #[test]
    fn a_forest_instances_one_tree_on_a_grid() {
        let scene = generate("forest", &params(&["trees=5", "triangles=2000"])).unwrap();
        assert_eq!(scene.geometries.len(), 1);
        assert_eq!(scene.instances.len(), 5);
        // A 3 x 3 grid, filled row by row: distinct places, spaced apart.
        let places: Vec<DVec3> = scene
            .instances
            .iter()
            .map(|i| i.world_from_local.translation)
            .collect();
        for (a, p) in places.iter().enumerate() {
            for q in &places[a + 1..] {
                assert!(p.distance(*q) > 5.0, "{p} {q}");
            }
        }
    }

    #[test]
    fn bad_names_and_params_are_errors() {
        let m = message("meadow", &[]);
        assert!(m.contains("gen:tree") && m.contains("gen:forest"), "{m}");
        let m = message("forest", &["trees=0"]);
        assert!(m.contains("trees"), "{m}");
        let m = message("island", &["sizee=10"]);
        assert!(m.contains("sizee") && m.contains("tree_triangles"), "{m}");
        let m = message("tree", &["trees=10"]);
        assert!(m.contains("trees") && m.contains("triangles"), "{m}");
        for bad in [
            "size=1",
            "size=16385",
            "size=abc",
            "trees=-1",
            "trees=10000001",
            "height=nan",
            "extent=0",
        ] {
            let m = message("island", &[bad]);
            let key = bad.split('=').next().unwrap_or_default();
            assert!(m.contains(key), "{bad}: {m}");
        }
        for bad in ["triangles=10", "triangles=1e9", "seed=x"] {
            message("tree", &[bad]);
        }
    }

    #[test]
    fn terrain_faces_agree_with_normals() {
        let scene = gen_ok("island", &["size=64", "trees=0"]);
        let g = &scene.geometries[0];
        let normals = g.normals.as_ref().expect("normals");
        let Primitives::Triangles(tris) = &g.primitives else {
            panic!("triangles")
        };
        for t in tris {
            let [a, b, c] = t.map(|i| g.positions[i as usize]);
            let face = (b - a).cross(c - a);
            assert!(face.z > 0.0);
            let avg: glam::Vec3 = t.iter().map(|&i| normals[i as usize]).sum();
            assert!(face.dot(avg.as_dvec3()) > 0.0);
        }
    }

    #[test]
    fn default_scene_names_a_generator() {
        let name = DEFAULT_SCENE.strip_prefix("gen:").expect("gen: prefix");
        assert!(GENERATORS.contains(&name));
    }
}
