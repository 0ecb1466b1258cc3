//! Stiff and extreme inputs: far from the origin, tiny and huge scales,
//! degenerate point sets, and very deep trees.

use farfield_builder::scene::{Geometry, Primitives, Scene};
use farfield_protocol::hierarchy::DecodedNode;
use glam::{DAffine3, DVec3};

use crate::{build, resident};

/// A deterministic jittered grid mesh: `n` x `n` vertices `spacing` apart.
pub(crate) fn grid_mesh(n: u32, spacing: f64) -> Geometry {
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut jitter = || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.4
    };
    let mut positions = Vec::new();
    for y in 0..n {
        for x in 0..n {
            let p = DVec3::new(
                f64::from(x) + jitter(),
                f64::from(y) + jitter(),
                jitter() + (f64::from(x) * 0.1).sin(),
            );
            positions.push(p * spacing);
        }
    }
    let mut triangles = Vec::new();
    for y in 0..n - 1 {
        for x in 0..n - 1 {
            let i = y * n + x;
            triangles.push([i, i + 1, i + n]);
            triangles.push([i + 1, i + n + 1, i + n]);
        }
    }
    Geometry::new("grid", positions, Primitives::Triangles(triangles))
}

fn transformed(g: &Geometry, t: DAffine3) -> Scene {
    let mut g = g.clone();
    g.positions
        .iter_mut()
        .for_each(|p| *p = t.transform_point3(*p));
    Scene::single(g)
}

/// Decoded nodes of a scene, relative to the root's center and in units of
/// the root radius, and each page's records.
fn relative_tree(scene: Scene) -> (Vec<DecodedNode>, Vec<Vec<u8>>) {
    let file = build(scene);
    let mut nodes = resident(&file).decode_all();
    let (c, r) = (file.header.root_center, file.header.root_radius);
    for n in &mut nodes {
        n.center = (n.center - c) / r;
        n.radius /= r;
    }
    // The records decoded: compressed pages differ from the first
    // differing record on.
    let records = file
        .pages
        .iter()
        .enumerate()
        .map(|(i, page)| {
            farfield_protocol::page::Page::parse(page, i as u32, file.header.node_bytes)
                .expect("a built page")
                .records()
                .to_vec()
        })
        .collect();
    (nodes, records)
}

/// The same geometry under a translation or uniform scale gives the same
/// tree: identical structure, (nearly) identical quantized records, and
/// decoded spheres that agree relative to the root.
fn assert_same_relative_tree(t: DAffine3, what: &str) {
    let g = grid_mesh(120, 1e-3);
    let (a, pages_a) = relative_tree(transformed(&g, DAffine3::IDENTITY));
    let (b, pages_b) = relative_tree(transformed(&g, t));
    assert_eq!(a.len(), b.len(), "{what}: node count");
    assert!(
        a.iter()
            .zip(&b)
            .all(|(x, y)| x.children == y.children && x.level == y.level),
        "{what}: structure"
    );
    let bytes_a: Vec<u8> = pages_a.concat();
    let bytes_b: Vec<u8> = pages_b.concat();
    let same = bytes_a.iter().zip(&bytes_b).filter(|(x, y)| x == y).count();
    assert!(
        same as f64 >= 0.999 * bytes_a.len() as f64,
        "{what}: only {same} of {} bytes equal",
        bytes_a.len()
    );
    // Decoded spheres relative to the root agree (to 1e-6 root radii: f64
    // at 1e7 resolves 2e-9, a 1e-7 root radius here), except where rounding
    // of the input flipped a quantization code on a boundary: such a node
    // moves by a grid step of its parent (2/13 of the parent's radius).
    let moved = a
        .iter()
        .zip(&b)
        .filter(|(x, y)| x.center.distance(y.center) + (x.radius - y.radius).abs() > 1e-6)
        .count();
    assert!(
        moved as f64 <= 0.001 * a.len() as f64,
        "{what}: {moved} of {} nodes moved",
        a.len()
    );
    let worst = a
        .iter()
        .zip(&b)
        .map(|(x, y)| x.center.distance(y.center) + (x.radius - y.radius).abs())
        .fold(0.0, f64::max);
    assert!(
        worst < 0.05,
        "{what}: decoded spheres differ by {worst} root radii"
    );
    eprintln!(
        "{what}: {moved} of {} nodes moved, at most {worst:.2e} root radii; {same} of {} record bytes equal",
        a.len(),
        bytes_a.len()
    );
}

#[test]
fn translation_by_1e7_keeps_the_relative_tree() {
    assert_same_relative_tree(
        DAffine3::from_translation(DVec3::new(1e7, -1e7, 1e7)),
        "translated by 1e7",
    );
}

#[test]
fn scales_1e_minus_6_and_1e6_keep_the_relative_tree() {
    assert_same_relative_tree(DAffine3::from_scale(DVec3::splat(1e-6)), "scaled by 1e-6");
    assert_same_relative_tree(DAffine3::from_scale(DVec3::splat(1e6)), "scaled by 1e6");
}

fn points(positions: Vec<DVec3>) -> Scene {
    Scene::single(Geometry::new("points", positions, Primitives::Points))
}

/// Every input point lies inside some decoded leaf; returns the leaves.
fn leaves_cover(scene: Scene) -> Vec<DecodedNode> {
    let positions = scene.geometries[0].positions.clone();
    let file = build(scene);
    let nodes = resident(&file).decode_all();
    assert_eq!(nodes.len() as u64, file.header.nodes);
    for n in &nodes {
        assert!(
            n.center.is_finite() && n.radius.is_finite() && n.radius > 0.0,
            "{n:?}"
        );
        assert!(n.children == 0 || (2..=4).contains(&n.children));
    }
    let leaves: Vec<DecodedNode> = nodes.into_iter().filter(|n| n.children == 0).collect();
    for &(source, node) in &file.leaf_sources {
        let leaf = leaves.iter().find(|l| l.index == node).unwrap();
        let p = positions[source as usize];
        assert!(
            leaf.center.distance(p) <= leaf.radius,
            "point {p} outside its leaf {leaf:?}"
        );
    }
    leaves
}

#[test]
fn a_single_point_and_two_identical_points_build() {
    let one = leaves_cover(points(vec![DVec3::new(3.0, 4.0, 5.0)]));
    assert_eq!(one.len(), 1);
    let two = leaves_cover(points(vec![DVec3::splat(-7.0); 2]));
    assert_eq!(two.len(), 1, "identical points collapse into one leaf");
}

#[test]
fn collinear_and_coplanar_points_build() {
    let line: Vec<DVec3> = (0..1000)
        .map(|i| DVec3::new(1.0, 2.0, 3.0) * f64::from(i))
        .collect();
    assert_eq!(leaves_cover(points(line)).len(), 1000);
    let plane: Vec<DVec3> = (0..2500)
        .map(|i| DVec3::new(f64::from(i % 50), f64::from(i / 50), 0.0))
        .collect();
    let leaves = leaves_cover(points(plane));
    assert_eq!(leaves.len(), 2500);
    // Grid spacing 1: kNN radii near 1, not inflated by quantization beyond a few steps.
    assert!(
        leaves.iter().all(|l| l.radius < 4.0),
        "max radius {}",
        leaves.iter().map(|l| l.radius).fold(0.0, f64::max)
    );
}

#[test]
fn a_forty_level_tree_keeps_its_precision() {
    // Points 4^-k apart: each bisection peels one off, so the tree is as
    // deep as the builder allows before it switches to median splits.
    let mut positions: Vec<DVec3> = (0..120)
        .map(|k| DVec3::new(0.25f64.powi(k), 0.0, 0.0))
        .collect();
    positions.push(DVec3::ZERO);
    let leaves = leaves_cover(points(positions.clone()));
    let deepest = leaves.iter().map(|l| l.level).max().unwrap();
    assert!(deepest >= 40, "only {deepest} levels");
    // Deep leaves are still told apart: each is far smaller than the unit
    // root, i.e. precision was not lost on the way down.
    let deep: Vec<_> = leaves.iter().filter(|l| l.level >= 40).collect();
    assert!(!deep.is_empty());
    assert!(
        deep.iter().all(|l| l.radius < 1e-12),
        "deep leaf radii {:?}",
        deep.iter().map(|l| l.radius).collect::<Vec<_>>()
    );
}
