//! Zero-area faces, tested where they matter: a mesh with such faces added
//! gives the same leaves (radius, normal, cone) and the same cube pages as
//! the mesh without them.

use glam::{DVec3, Vec3};

use super::*;
use crate::cubes::{CubeOptions, build_cubes};
use crate::progress::Silent;
use crate::scene::{Geometry, Primitives, Scene};
use crate::spheres::leaves::{Leaf, LeafStats, cone_from_u8, make_leaves, unpack_normal};

/// How far the far-off triangles lie from the grid: much farther than the
/// grid is wide, as a stray face in a large scan spans much of the model.
const FAR: f64 = 1e5;

/// A skew direction, about unit length, with no coordinate zero and none a
/// short binary fraction: points along it are rounded, so faces along it
/// are not collinear exactly.
const SKEW: DVec3 = DVec3::new(0.601_234_5, 0.480_987_6, 0.640_123_4);

/// Vertices per side of the flat grid.
const SIDE: u32 = 17;
/// The grid's middle vertex, and one corner of each far-off triangle.
const CENTRE: u32 = SIDE * SIDE / 2;
const FAR_X: u32 = SIDE * SIDE;
const FAR_SKEW: u32 = FAR_X + 3;
/// The first vertex a test appends.
const EXTRA: u32 = FAR_SKEW + 3;

/// A flat grid of unit squares in z = 0, each cut in two (so a vertex has
/// six triangles and the normal +z), and two small triangles far off: one
/// along +x from the centre (at [`FAR_X`]), one along [`SKEW`] (at
/// [`FAR_SKEW`]).
fn clean() -> (Vec<DVec3>, Vec<[u32; 3]>) {
    let mut positions: Vec<DVec3> = (0..SIDE * SIDE)
        .map(|i| DVec3::new(f64::from(i % SIDE), f64::from(i / SIDE), 0.0))
        .collect();
    let mut triangles = crate::grid_triangles(SIDE);
    let centre = positions[CENTRE as usize];
    for corner in [centre + DVec3::X * FAR, centre + SKEW * FAR] {
        let first = positions.len() as u32;
        positions.extend([corner, corner + DVec3::X, corner + DVec3::Y]);
        triangles.push([first, first + 1, first + 2]);
    }
    (positions, triangles)
}

/// The point a fraction `t` of the way from vertex `a` to vertex `b`.
fn on_line(a: u32, b: u32, t: f64) -> DVec3 {
    let (positions, _) = clean();
    let (a, b) = (positions[a as usize], positions[b as usize]);
    a + (b - a) * t
}

/// The clean mesh with `extra` vertices appended and `faces` added, with
/// input normals (+z everywhere) or without.
fn scene(extra: &[DVec3], faces: &[[u32; 3]], normals: bool) -> Scene {
    let (mut positions, mut triangles) = clean();
    positions.extend_from_slice(extra);
    triangles.extend_from_slice(faces);
    let n = positions.len();
    let mut g = Geometry::new("grid", positions, Primitives::Triangles(triangles));
    g.normals = normals.then(|| vec![Vec3::Z; n]);
    Scene::single(g)
}

fn leaves(scene: Scene) -> (Vec<Leaf>, LeafStats) {
    make_leaves(scene, false, &Silent)
}

/// What differs between two leaves of one vertex, in words.
fn difference(clean: &Leaf, dirty: &Leaf) -> String {
    let bend = unpack_normal(clean.normal).angle_between(unpack_normal(dirty.normal));
    format!(
        "vertex {}: radius {} -> {}, normal bent {:.1} degrees, cone {:.1} -> {:.1} degrees",
        clean.source,
        clean.radius,
        dirty.radius,
        bend.to_degrees(),
        cone_from_u8(clean.cone).to_degrees(),
        cone_from_u8(dirty.cone).to_degrees(),
    )
}

/// The mesh with `faces` (and the `extra` vertices only they use) has the
/// clean mesh's leaves, bit for bit, with and without input normals; the
/// extra vertices are left out as unreferenced; its cube pages are the
/// clean mesh's too. Every difference is listed before the test fails.
fn assert_faces_change_nothing(extra: &[DVec3], faces: &[[u32; 3]]) {
    let mut changed = Vec::new();
    for normals in [false, true] {
        let (clean_leaves, clean_stats) = leaves(scene(&[], &[], normals));
        let (dirty_leaves, dirty_stats) = leaves(scene(extra, faces, normals));
        let what = format!("leaves with input normals {normals}");
        changed.extend(
            clean_leaves
                .iter()
                .zip(&dirty_leaves)
                .filter(|(c, d)| c != d)
                .map(|(c, d)| format!("{what}: {}", difference(c, d))),
        );
        if dirty_leaves.len() != clean_leaves.len() {
            changed.push(format!(
                "{what}: {} leaves for {}",
                dirty_leaves.len(),
                clean_leaves.len()
            ));
        }
        let unreferenced = clean_stats.unreferenced_vertices + extra.len() as u64;
        if dirty_stats.unreferenced_vertices != unreferenced {
            changed.push(format!(
                "{what}: {} unreferenced vertices, not {unreferenced}",
                dirty_stats.unreferenced_vertices
            ));
        }
    }
    let cubes = |s: Scene| {
        build_cubes(s, &CubeOptions::default())
            .expect("cube build")
            .0
    };
    let (clean, dirty) = (
        cubes(scene(&[], &[], true)),
        cubes(scene(extra, faces, true)),
    );
    let bounds = |f: &crate::PagedFile| (f.header.bounds_min, f.header.bounds_max);
    if bounds(&dirty) != bounds(&clean) {
        changed.push(format!(
            "cube bounds {:?} -> {:?}",
            bounds(&clean),
            bounds(&dirty)
        ));
    }
    if (dirty.header.nodes, &dirty.pages) != (clean.header.nodes, &clean.pages) {
        changed.push(format!(
            "cube pages differ ({} nodes -> {})",
            clean.header.nodes, dirty.header.nodes
        ));
    }
    assert!(changed.is_empty(), "{changed:#?}");
}

#[test]
fn faces_repeating_a_corner_change_no_leaf_and_no_cube() {
    let (positions, _) = clean();
    // A second vertex at the far corner's position.
    let copy = positions[FAR_X as usize];
    assert_faces_change_nothing(
        &[copy],
        &[
            // Long: from the grid's centre to the far triangles.
            [CENTRE, FAR_X, FAR_X],
            [FAR_X, CENTRE, CENTRE],
            [CENTRE, FAR_SKEW, FAR_SKEW],
            // Distinct indices, one position twice.
            [CENTRE, FAR_X, EXTRA],
            // Short, and one that is a single point.
            [1, 2, 2],
            [CENTRE, CENTRE, CENTRE],
        ],
    );
}

#[test]
fn collinear_faces_change_no_leaf_and_no_cube() {
    // Exactly halfway to the far corner along x; halfway along a grid
    // edge; 0.29 of the way along the skew line (rounded in f64, so
    // that face's vector is small but not zero).
    let extra = [
        on_line(CENTRE, FAR_X, 0.5),
        on_line(CENTRE, CENTRE + 1, 0.5),
        on_line(CENTRE, FAR_SKEW, 0.29),
    ];
    let (positions, _) = clean();
    let skew = [
        positions[CENTRE as usize],
        positions[FAR_SKEW as usize],
        extra[2],
    ];
    let face = (skew[1] - skew[0]).cross(skew[2] - skew[0]);
    assert!(
        face != DVec3::ZERO,
        "the rounded skew face should not be exactly flat"
    );
    assert!(is_zero_area(skew[0], skew[1], skew[2]));
    assert_faces_change_nothing(
        &extra,
        &[
            [CENTRE, EXTRA, FAR_X],
            [EXTRA, CENTRE, FAR_X],
            [CENTRE, CENTRE + 1, EXTRA + 1],
            [CENTRE, FAR_SKEW, EXTRA + 2],
            [EXTRA + 2, FAR_SKEW, CENTRE],
        ],
    );
}

/// A point on the long skew line stored as f32, as a PLY or STL file
/// stores it: off the line by a rounding error that, times the face's
/// length, is a face vector larger than those of all the centre's real
/// faces together. Without input normals it would tip the centre's normal
/// towards its own.
#[test]
fn a_long_collinear_face_rounded_to_f32_changes_no_leaf_and_no_cube() {
    let point = on_line(CENTRE, FAR_SKEW, 0.61).as_vec3().as_dvec3();
    let (positions, triangles) = clean();
    let [a, b] = [CENTRE, FAR_SKEW].map(|i| positions[i as usize]);
    let face = (b - a).cross(point - a).length();
    let around: f64 = triangles
        .iter()
        .filter(|t| t.contains(&CENTRE))
        .map(|t| {
            let [p, q, r] = t.map(|i| positions[i as usize]);
            (q - p).cross(r - p).length()
        })
        .sum();
    assert!(
        face > around,
        "face vector {face} against the centre's {around}"
    );
    assert!(is_zero_area(a, b, point));
    // One winding only: two opposite ones would cancel in the normal sum.
    assert_faces_change_nothing(&[point], &[[CENTRE, FAR_SKEW, EXTRA]]);
}

#[test]
fn zero_area_is_relative_to_the_face_and_independent_of_scale() {
    let flat = [
        [DVec3::ZERO, DVec3::ZERO, DVec3::ZERO],
        [DVec3::ZERO, DVec3::X, DVec3::X],
        [DVec3::ZERO, DVec3::X, DVec3::X * 2.0],
        [DVec3::ZERO, SKEW * 3.0, SKEW * 1.3],
        // Height a ten-millionth of the length.
        [DVec3::ZERO, DVec3::X, DVec3::new(0.5, 1e-7, 0.0)],
    ];
    let real = [
        [DVec3::ZERO, DVec3::X, DVec3::Y],
        // A thin sliver, but a hundred times thicker than the bound.
        [DVec3::ZERO, DVec3::X, DVec3::new(0.5, 1e-4, 0.0)],
        [DVec3::ZERO, DVec3::X * 1e5, DVec3::new(3.0, 0.5, 0.0)],
    ];
    for scale in [1e-30, 1e-3, 1.0, 1e3, 1e30] {
        let at = |t: [DVec3; 3]| {
            let [a, b, c] = t.map(|p| p * scale + DVec3::splat(0.25 * scale));
            is_zero_area(a, b, c)
        };
        for t in flat {
            assert!(at(t), "{t:?} at scale {scale} should have zero area");
        }
        for t in real {
            assert!(!at(t), "{t:?} at scale {scale} has an area");
        }
    }
}
