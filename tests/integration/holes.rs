//! Hole-freeness (QSplat 2.2): for every edge of the bunny, the quantized
//! leaf spheres of its two vertices touch, so square and round splats leave
//! no gap along the surface.

use std::collections::HashMap;

use farfield_builder::import::{Params, load_input};
use farfield_builder::scene::Primitives;
use farfield_tests::shared_data;

use crate::{build, resident};

#[test]
fn every_bunny_edge_has_touching_quantized_leaves() {
    let Some(data) = shared_data() else { return };
    let scene = load_input(
        data.join("stanford-bunny.obj").to_str().unwrap(),
        &Params::default(),
    )
    .unwrap();
    let geometry = scene.geometries[0].clone();
    let Primitives::Triangles(triangles) = &geometry.primitives else {
        panic!("bunny is a mesh")
    };
    let file = build(scene);
    let nodes = resident(&file).decode_all();

    // Vertex -> its leaf node. Vertices at one position share a leaf.
    let key = |v: usize| geometry.positions[v].to_array().map(f64::to_bits);
    let mut node_at: HashMap<[u64; 3], u64> = HashMap::new();
    for &(source, node) in &file.leaf_sources {
        node_at.insert(key(source as usize), node);
    }
    let sphere = |v: u32| {
        let node = node_at[&key(v as usize)];
        let n = nodes[node as usize];
        assert_eq!(n.index, node);
        assert_eq!(n.children, 0, "vertex {v} maps to an interior node");
        (n.center, n.radius)
    };
    let mut edges = 0;
    for tri in triangles {
        for (a, b) in [(tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])] {
            let ((ca, ra), (cb, rb)) = (sphere(a), sphere(b));
            // Each decoded sphere holds its vertex ...
            for (c, r, v) in [(ca, ra, a), (cb, rb, b)] {
                assert!(
                    c.distance(geometry.positions[v as usize]) <= r,
                    "vertex {v} outside its leaf"
                );
            }
            // ... and the two spheres of an edge touch.
            assert!(
                ca.distance(cb) <= ra + rb,
                "edge {a}-{b}: gap {}",
                ca.distance(cb) - ra - rb
            );
            edges += 1;
        }
    }
    assert_eq!(edges, 3 * triangles.len());
    assert_eq!(edges, 3 * 69_451);
}
