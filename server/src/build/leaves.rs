//! Leaf spheres: one per input vertex, point or atom (QSplat 2.2).
//!
//! - Triangle meshes: a vertex's sphere has the radius of the largest
//!   bounding sphere of the triangles around it, so the spheres of two
//!   vertices joined by an edge always touch and the splats leave no holes.
//!   The normal is the input's, or the area-weighted face normal; the
//!   normal cone covers every incident face.
//! - Point clouds: radius and normal from the nearest neighbours ([`knn`]).
//! - Spheres (atoms): their own radius, and no orientation.
//!
//! Leaves are produced per geometry in its local frame and then placed by
//! each instance, so an instanced tree is sized once however often it is
//! planted. Each geometry is dropped as soon as its leaves exist, which keeps
//! the peak memory of a build near the leaves' own size.
//!
//! [`knn`]: super::knn

use glam::{DAffine3, DVec3, Vec3};
use rayon::prelude::*;

pub use farfield_protocol::octahedral::{pack_normal, unpack_normal};

use crate::scene::{Geometry, Primitives, Rgb8, Scene};

/// Color given to geometry without colors in a scene where others have them.
pub const DEFAULT_COLOR: Rgb8 = [200, 200, 200];

/// One leaf sphere with everything its node will carry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Leaf {
    pub position: DVec3,
    pub radius: f32,
    /// Unit normal packed as octahedral 16:16 (see [`pack_normal`]).
    pub normal: u32,
    pub color: Rgb8,
    /// Half-angle of the leaf's normal cone in 255ths of pi, rounded up;
    /// 255 means "faces every way" (never culled).
    pub cone: u8,
    /// Index of the vertex in its geometry, so tests can follow a vertex
    /// into the file (fits in the struct's padding: no extra memory).
    pub source: u32,
}

/// Counts that the build summary reports.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LeafStats {
    pub input_vertices: u64,
    /// Mesh vertices that no triangle uses; they have no size and are left out.
    pub unreferenced_vertices: u64,
}

/// Turns a scene into leaves, consuming it geometry by geometry.
pub fn make_leaves(scene: Scene, has_color: bool) -> (Vec<Leaf>, LeafStats) {
    let Scene {
        geometries,
        instances,
    } = scene;
    let total: u64 = instances
        .iter()
        .map(|i| geometries[i.geometry].positions.len() as u64)
        .sum();
    let mut leaves = Vec::with_capacity(total as usize);
    let mut stats = LeafStats {
        input_vertices: total,
        unreferenced_vertices: 0,
    };
    let mut by_geometry: Vec<Vec<DAffine3>> = vec![Vec::new(); geometries.len()];
    for instance in &instances {
        by_geometry[instance.geometry].push(instance.world_from_local);
    }
    for (geometry, transforms) in geometries.into_iter().zip(by_geometry) {
        if transforms.is_empty() {
            continue;
        }
        let (local, unreferenced) = local_leaves(geometry, has_color);
        stats.unreferenced_vertices += unreferenced * transforms.len() as u64;
        if let [only] = transforms[..]
            && only == DAffine3::IDENTITY
        {
            leaves.extend_from_slice(&local);
            continue;
        }
        // Instances are independent: place them on all threads, each into
        // its own slice of the output (no intermediate copies).
        let Some(&filler) = local.first() else {
            continue;
        };
        let start = leaves.len();
        leaves.resize(start + local.len() * transforms.len(), filler);
        leaves[start..]
            .par_chunks_mut(local.len())
            .zip(transforms.par_iter())
            .for_each(|(out, &world_from_local)| place(&local, world_from_local, out));
    }
    (leaves, stats)
}

/// A geometry's local leaves placed by one instance, written to `out`.
fn place(local: &[Leaf], world_from_local: DAffine3, out: &mut [Leaf]) {
    let scale = max_stretch(world_from_local);
    let normal_matrix = world_from_local.matrix3.inverse().transpose();
    for (leaf, slot) in local.iter().zip(out) {
        let n = normal_matrix * unpack_normal(leaf.normal).as_dvec3();
        *slot = Leaf {
            position: world_from_local.transform_point3(leaf.position),
            radius: round_up_f32(f64::from(leaf.radius) * scale),
            normal: pack_normal(n.as_vec3()),
            ..*leaf
        };
    }
}

/// The largest factor by which a transform can lengthen a vector: the
/// largest column length when the columns are orthogonal (rotation and
/// scale), else the Frobenius norm, an upper bound.
pub(crate) fn max_stretch(t: DAffine3) -> f64 {
    let [x, y, z] = [t.matrix3.x_axis, t.matrix3.y_axis, t.matrix3.z_axis];
    let longest = x.length().max(y.length()).max(z.length());
    let orthogonal = [x.dot(y), y.dot(z), z.dot(x)]
        .iter()
        .all(|d| d.abs() <= 1e-9 * longest * longest);
    if orthogonal {
        longest
    } else {
        (x.length_squared() + y.length_squared() + z.length_squared()).sqrt()
    }
}

/// Leaves of one geometry in its local frame, and how many vertices were
/// left out for not being used by any triangle.
fn local_leaves(geometry: Geometry, has_color: bool) -> (Vec<Leaf>, u64) {
    let Geometry {
        positions,
        normals,
        colors,
        primitives,
        ..
    } = geometry;
    let color_of = |i: usize| -> Rgb8 {
        match &colors {
            Some(c) => c[i],
            None if has_color => DEFAULT_COLOR,
            None => [0; 3],
        }
    };
    let mut leaves: Vec<Leaf> = positions
        .iter()
        .enumerate()
        .map(|(i, &position)| Leaf {
            position,
            radius: 0.0,
            normal: pack_normal(Vec3::Z),
            color: color_of(i),
            cone: 255,
            source: i as u32,
        })
        .collect();
    drop(positions);
    drop(colors);
    match primitives {
        Primitives::Triangles(triangles) => {
            let unreferenced = size_from_triangles(&mut leaves, &triangles, normals);
            drop(triangles);
            if unreferenced > 0 {
                leaves.retain(|l| !is_unreferenced(l));
            }
            (leaves, unreferenced)
        }
        Primitives::Points => {
            super::knn::size_points(&mut leaves, normals.as_deref());
            (leaves, 0)
        }
        Primitives::Spheres(radii) => {
            for (leaf, r) in leaves.iter_mut().zip(radii) {
                leaf.radius = r as f32;
            }
            (leaves, 0)
        }
    }
}

/// Vertices no triangle touched carry a negative radius until dropped.
fn is_unreferenced(leaf: &Leaf) -> bool {
    leaf.radius < 0.0
}

/// Sizes mesh vertices from their triangles; returns the number of vertices
/// no triangle uses, which are marked with a negative radius and dropped.
fn size_from_triangles(
    leaves: &mut [Leaf],
    triangles: &[[u32; 3]],
    normals: Option<Vec<Vec3>>,
) -> u64 {
    // Working memory is one f32 normal and one f32 cosine per vertex: the
    // radius accumulates in the leaf itself, -1 meaning "no triangle yet".
    let n = leaves.len();
    for leaf in leaves.iter_mut() {
        leaf.radius = -1.0;
    }
    let have_normals = normals.is_some();
    let mut normal = normals.unwrap_or_else(|| vec![Vec3::ZERO; n]);
    // Per-triangle geometry is computed on all threads a chunk at a time
    // (bounded memory), then scattered to the vertices in order.
    let mut faces: Vec<(f32, Vec3)> = Vec::with_capacity(TRIANGLE_CHUNK.min(triangles.len()));
    for chunk in triangles.chunks(TRIANGLE_CHUNK) {
        let positions = &*leaves;
        faces.clear();
        faces.par_extend(chunk.par_iter().map(|tri| {
            let [a, b, c] = tri.map(|i| positions[i as usize].position);
            // Rounded up to f32 per triangle: the max of round-ups never shrinks.
            let r = round_up_f32(triangle_bounding_radius(a, b, c));
            (r, (b - a).cross(c - a).as_vec3()) // length = 2 * area
        }));
        for (tri, &(r, face)) in chunk.iter().zip(&faces) {
            for v in tri.map(|i| i as usize) {
                leaves[v].radius = leaves[v].radius.max(r);
                if !have_normals {
                    normal[v] += face;
                }
            }
        }
    }
    normal
        .par_iter_mut()
        .for_each(|nv| *nv = nv.try_normalize().unwrap_or(Vec3::ZERO));
    // Cone: the widest angle between a vertex normal and its faces' normals,
    // tracked as the smallest cosine (one acos per vertex, not per corner).
    let mut min_cos = vec![1.0f32; n];
    for tri in triangles {
        let [a, b, c] = tri.map(|i| i as usize);
        let face = (leaves[b].position - leaves[a].position)
            .cross(leaves[c].position - leaves[a].position);
        let Some(face) = face.try_normalize() else {
            continue;
        };
        let face = face.as_vec3();
        for v in [a, b, c] {
            min_cos[v] = min_cos[v].min(normal[v].dot(face));
        }
    }
    let mut unreferenced = 0;
    for (v, leaf) in leaves.iter_mut().enumerate() {
        if leaf.radius < 0.0 {
            unreferenced += 1;
        } else if normal[v] != Vec3::ZERO {
            leaf.normal = pack_normal(normal[v]);
            // A little margin for the f32 arithmetic of the cosines.
            leaf.cone = cone_to_u8(f64::from(min_cos[v]).clamp(-1.0, 1.0).acos() + 1e-4);
        } else {
            leaf.cone = 255;
        }
    }
    unreferenced
}

/// Triangles whose geometry is computed per parallel batch.
const TRIANGLE_CHUNK: usize = 1 << 18;

/// Radius of the smallest sphere holding a triangle: half the longest edge
/// for a right or obtuse triangle, else the circumradius.
pub fn triangle_bounding_radius(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let (ab, bc, ca) = (
        a.distance_squared(b),
        b.distance_squared(c),
        c.distance_squared(a),
    );
    let longest = ab.max(bc).max(ca);
    let half_longest = longest.sqrt() * 0.5;
    // Obtuse or right at some corner: the longest edge's midpoint sphere holds all.
    if longest >= ab + bc + ca - longest {
        return half_longest;
    }
    let twice_area = (b - a).cross(c - a).length();
    if twice_area <= 0.0 {
        return half_longest;
    }
    let circumradius = (ab * bc * ca).sqrt() / (2.0 * twice_area);
    circumradius.max(half_longest)
}

/// The next f32 at or above `v`, so a stored radius never shrinks.
pub fn round_up_f32(v: f64) -> f32 {
    let f = v as f32;
    if f64::from(f) >= v { f } else { f.next_up() }
}

/// A cone half-angle in 255ths of pi, rounded up (so it stays conservative).
pub fn cone_to_u8(angle: f64) -> u8 {
    if !(angle.is_finite()) {
        return 255;
    }
    (angle / std::f64::consts::PI * 255.0)
        .ceil()
        .clamp(0.0, 255.0) as u8
}

/// The cone half-angle a leaf's u8 stands for, in radians.
pub fn cone_from_u8(cone: u8) -> f64 {
    f64::from(cone) / 255.0 * std::f64::consts::PI
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn triangle_radius_covers_every_corner() {
        let cases = [
            [DVec3::ZERO, DVec3::X, DVec3::Y],
            [
                DVec3::ZERO,
                DVec3::new(10.0, 0.0, 0.0),
                DVec3::new(5.0, 0.1, 0.0),
            ],
            [
                DVec3::ZERO,
                DVec3::new(1.0, 0.0, 0.0),
                DVec3::new(0.5, 0.8, 0.0),
            ],
            [DVec3::ZERO, DVec3::ZERO, DVec3::ZERO],
            [DVec3::ZERO, DVec3::X, DVec3::X * 2.0],
        ];
        for [a, b, c] in cases {
            let r = triangle_bounding_radius(a, b, c);
            // Every edge fits in the diameter: the two end spheres touch.
            for (p, q) in [(a, b), (b, c), (c, a)] {
                assert!(2.0 * r >= p.distance(q) - 1e-12, "{a} {b} {c}: r {r}");
            }
        }
        // Equilateral triangle of side 1: circumradius 1/sqrt(3).
        let r = triangle_bounding_radius(
            DVec3::ZERO,
            DVec3::X,
            DVec3::new(0.5, 3f64.sqrt() / 2.0, 0.0),
        );
        assert!((r - 1.0 / 3f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn normals_pack_precisely() {
        for v in [
            Vec3::X,
            Vec3::NEG_Z,
            Vec3::new(1.0, -2.0, -3.0).normalize(),
            Vec3::new(-0.3, 0.1, 0.9).normalize(),
        ] {
            assert!(unpack_normal(pack_normal(v)).angle_between(v) < 1e-3, "{v}");
        }
    }

    #[test]
    fn unused_vertices_are_dropped_and_used_ones_sized() {
        let positions = vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::splat(5.0)];
        let g = Geometry::new("t", positions, Primitives::Triangles(vec![[0, 1, 2]]));
        let (leaves, stats) = make_leaves(Scene::single(g), false);
        assert_eq!(stats.unreferenced_vertices, 1);
        assert_eq!(leaves.len(), 3);
        assert!(leaves.iter().all(|l| l.radius >= 0.5 && l.cone < 255));
        assert!(unpack_normal(leaves[0].normal).angle_between(Vec3::Z) < 1e-3);
    }
}
