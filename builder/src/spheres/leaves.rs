//! Leaf spheres: one per input vertex, point or atom (QSplat 2.2).
//!
//! - Triangle meshes: a vertex's sphere has the radius of the largest
//!   bounding sphere of the triangles around it, so the spheres of two
//!   vertices joined by an edge always touch and the splats leave no holes.
//!   The normal is the input's, or the area-weighted face normal; the
//!   normal cone covers every incident face. Faces of zero area (repeated
//!   or collinear corners, [`zero_area`]) have no surface and count for
//!   nothing: a vertex only they use is left out like one no face uses.
//! - Point clouds: radius and normal from the nearest neighbours ([`knn`]).
//! - Spheres (atoms): their own radius, and no orientation.
//!
//! Leaves are produced per geometry in its local frame and then placed by
//! each instance, so an instanced tree is sized once however often it is
//! planted. Each geometry is dropped as soon as its leaves exist, which keeps
//! the peak memory of a build near the leaves' own size.
//!
//! [`knn`]: super::knn
//! [`zero_area`]: crate::zero_area

use glam::{DAffine3, DVec3, Vec3};
use rayon::prelude::*;

pub use farfield_protocol::octahedral::{pack_normal, unpack_normal};

use crate::progress::{Portion, Progress};
use crate::scene::{Geometry, Primitives, Rgb8, Scene};
use crate::zero_area::{face_with_area, zero_area};

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
    /// Mesh vertices that no triangle with an area uses; they have no size
    /// and are left out.
    pub unreferenced_vertices: u64,
}

/// Turns a scene into leaves, consuming it geometry by geometry (the unit
/// of its `progress`, in vertices).
pub fn make_leaves(
    scene: Scene,
    has_color: bool,
    progress: &dyn Progress,
) -> (Vec<Leaf>, LeafStats) {
    let Scene {
        geometries,
        instances,
    } = scene;
    let total: u64 = instances
        .iter()
        .map(|i| geometries[i.geometry].positions.len() as u64)
        .sum();
    let mut stats = LeafStats {
        input_vertices: total,
        unreferenced_vertices: 0,
    };
    progress.begin("leaves", total);
    // One geometry placed as it is (any scanned mesh): its leaves are the
    // result, with no copy into a second array of the same size.
    let mut geometries = geometries;
    if let [only] = &instances[..]
        && only.world_from_local == DAffine3::IDENTITY
        && geometries.len() == 1
        && let Some(geometry) = geometries.pop()
    {
        let (local, unreferenced) = local_leaves(geometry, has_color, progress);
        stats.unreferenced_vertices = unreferenced;
        return (local, stats);
    }
    let mut leaves = Vec::with_capacity(total as usize);
    let mut by_geometry: Vec<Vec<DAffine3>> = vec![Vec::new(); geometries.len()];
    for instance in &instances {
        by_geometry[instance.geometry].push(instance.world_from_local);
    }
    for (geometry, transforms) in geometries.into_iter().zip(by_geometry) {
        if transforms.is_empty() {
            continue;
        }
        let vertices = geometry.positions.len() as u64 * transforms.len() as u64;
        // `local_leaves` reports the geometry's own vertices; placing its
        // instances accounts for the rest.
        let placed = vertices - geometry.positions.len() as u64;
        let (local, unreferenced) = local_leaves(geometry, has_color, progress);
        stats.unreferenced_vertices += unreferenced * transforms.len() as u64;
        if let [only] = transforms[..]
            && only == DAffine3::IDENTITY
        {
            leaves.extend_from_slice(&local);
            progress.advance(placed);
            continue;
        }
        // Instances are independent: place them on all threads, each into
        // its own slice of the output (no intermediate copies).
        let Some(&filler) = local.first() else {
            progress.advance(placed);
            continue;
        };
        let start = leaves.len();
        leaves.resize(start + local.len() * transforms.len(), filler);
        leaves[start..]
            .par_chunks_mut(local.len())
            .zip(transforms.par_iter())
            .for_each(|(out, &world_from_local)| place(&local, world_from_local, out));
        progress.advance(placed);
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
/// left out for not being used by any triangle. Reports the geometry's
/// vertices to `progress`: a mesh's as its triangles are walked, so a
/// single large scan's bar moves too.
pub(crate) fn local_leaves(
    geometry: Geometry,
    has_color: bool,
    progress: &dyn Progress,
) -> (Vec<Leaf>, u64) {
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
    let up = pack_normal(Vec3::Z);
    let bare = |i: usize| Leaf {
        position: positions[i],
        radius: 0.0,
        normal: up,
        color: color_of(i),
        cone: 255,
        source: i as u32,
    };
    match primitives {
        Primitives::Triangles(triangles) => {
            // Sized from the compact positions, before the leaves exist:
            // the triangle walks read 24 bytes a corner, not a 40-byte leaf,
            // and each leaf is then written once, whole, on all threads.
            let sizes = size_from_triangles(&positions, &triangles, normals, progress);
            // Released, not kept for reuse: the leaves, allocated next, are
            // larger and cannot reuse the block, which would sit idle at
            // this step's memory peak.
            crate::allocator::drop_releasing(triangles);
            let unreferenced = sizes.radius.iter().filter(|&&r| r < 0.0).count() as u64;
            let mut leaves: Vec<Leaf> = (0..positions.len())
                .into_par_iter()
                .with_min_len(LEAVES_PER_TASK)
                .map(|i| sizes.apply(i, bare(i)))
                .collect();
            if unreferenced > 0 {
                leaves.retain(|l| !is_unreferenced(l));
            }
            (leaves, unreferenced)
        }
        Primitives::Points => {
            let mut leaves: Vec<Leaf> = (0..positions.len()).map(bare).collect();
            drop(positions);
            drop(colors);
            super::knn::size_points(&mut leaves, normals.as_deref());
            progress.advance(leaves.len() as u64);
            (leaves, 0)
        }
        Primitives::Spheres(radii) => {
            let leaves = (0..positions.len())
                .map(|i| Leaf {
                    radius: radii[i] as f32,
                    ..bare(i)
                })
                .collect();
            progress.advance(positions.len() as u64);
            (leaves, 0)
        }
    }
}

/// Leaves per parallel task where each leaf is little work.
const LEAVES_PER_TASK: usize = 1 << 12;

/// Triangles walked between progress reports: a few milliseconds of work.
const WALK_CHUNK: usize = 1 << 16;

/// Vertices no triangle with an area touched carry a negative radius until
/// dropped.
fn is_unreferenced(leaf: &Leaf) -> bool {
    leaf.radius < 0.0
}

/// What the triangles around each vertex say about its leaf.
struct VertexSizes {
    /// Largest bounding radius of the incident triangles, rounded up to
    /// f32; -1 for none (zero-area triangles are not counted).
    radius: Vec<f32>,
    /// Unit vertex normal (the input's, or the area-weighted face normal);
    /// zero where there is none.
    normal: Vec<Vec3>,
    /// Smallest cosine between the vertex normal and an incident face's.
    min_cos: Vec<f32>,
}

impl VertexSizes {
    /// `leaf` (vertex `i`) with its radius, normal and cone.
    fn apply(&self, i: usize, leaf: Leaf) -> Leaf {
        let (r, nv, c) = (self.radius[i], self.normal[i], self.min_cos[i]);
        if r >= 0.0 && nv != Vec3::ZERO {
            Leaf {
                radius: r,
                normal: pack_normal(nv),
                // A little margin for the f32 arithmetic of the cosines.
                cone: cone_to_u8(acos_upper(f64::from(c)) + 1e-4),
                ..leaf
            }
        } else {
            Leaf {
                radius: r,
                cone: 255,
                ..leaf
            }
        }
    }
}

/// Sizes mesh vertices from their triangles, skipping those of zero area.
/// Vertices no other triangle uses get a negative radius (they are dropped).
///
/// The vertices are cut into one contiguous range per thread, and each
/// thread walks all the triangles, doing the work of those corners that
/// fall in its range: every vertex is written by one thread only, in
/// triangle order (so the result does not depend on the thread count), and
/// no per-triangle buffer is needed. A triangle with corners in two ranges
/// is measured twice; meshes keep neighbours close in the vertex order, so
/// that is rare.
fn size_from_triangles(
    positions: &[DVec3],
    triangles: &[[u32; 3]],
    normals: Option<Vec<Vec3>>,
    progress: &dyn Progress,
) -> VertexSizes {
    // Working memory is a squared radius, a normal and a cosine per vertex.
    let n = positions.len();
    let have_normals = normals.is_some();
    let mut normal = normals.unwrap_or_else(|| vec![Vec3::ZERO; n]);
    let mut radius_squared = vec![-1.0f64; n];
    let mut min_cos = vec![1.0f32; n];
    let range_len = n.div_ceil(rayon::current_num_threads().max(1)).max(1 << 14);
    // Each range walks every triangle once with input normals, else twice.
    let walk_work = triangles.len() as u64 * if have_normals { 1 } else { 2 };
    radius_squared
        .par_chunks_mut(range_len)
        .zip(normal.par_chunks_mut(range_len))
        .zip(min_cos.par_chunks_mut(range_len))
        .enumerate()
        .for_each(|(part, ((radius_squared, normal), min_cos))| {
            let first = part * range_len;
            // This range's vertices, reported in step with its walks.
            let share = radius_squared.len() as u64;
            let mut walked = Portion::new(progress, share, walk_work);
            let mut range = VertexRange {
                first,
                radius_squared,
                normal,
                min_cos,
            };
            range.size(positions, triangles, have_normals, &mut walked);
        });
    // The square root and the round-up are monotonic, so taking them once,
    // of the largest square, gives the largest of the triangles' rounded-up
    // radii: the same f32, for a sixth of the roots. Converted here, so the
    // 8-byte squares are gone before the leaves are made (the leaf step's
    // memory peak).
    let radius = radius_squared
        .par_iter()
        .with_min_len(LEAVES_PER_TASK)
        .map(|&r2| {
            if r2 >= 0.0 {
                round_up_f32(r2.sqrt())
            } else {
                -1.0
            }
        })
        .collect();
    VertexSizes {
        radius,
        normal,
        min_cos,
    }
}

/// One thread's share of [`size_from_triangles`]: the working values of the
/// vertices `first..first + radius_squared.len()`.
struct VertexRange<'a> {
    first: usize,
    /// Square of the largest bounding radius of the incident triangles; -1
    /// for none yet.
    radius_squared: &'a mut [f64],
    /// Area-weighted sum of the face normals, then its direction.
    normal: &'a mut [Vec3],
    /// Smallest cosine between the vertex normal and an incident face's.
    min_cos: &'a mut [f32],
}

impl VertexRange<'_> {
    /// The index in this range of each corner of `tri`, if it has one.
    fn owned(&self, tri: &[u32; 3]) -> [Option<usize>; 3] {
        tri.map(|i| {
            let local = (i as usize).wrapping_sub(self.first);
            (local < self.radius_squared.len()).then_some(local)
        })
    }

    /// Sizes the range's vertices, telling `walked` every [`WALK_CHUNK`]
    /// triangles.
    fn size(
        &mut self,
        positions: &[DVec3],
        triangles: &[[u32; 3]],
        have_normals: bool,
        walked: &mut Portion,
    ) {
        if have_normals {
            // The vertex normals are known before any triangle is seen, so
            // one walk gives both the radius and the cone: half the
            // triangle work of the walks below.
            self.normalize_normals();
            for chunk in triangles.chunks(WALK_CHUNK) {
                self.size_and_cone(positions, chunk);
                walked.did(chunk.len() as u64);
            }
            return;
        }
        for chunk in triangles.chunks(WALK_CHUNK) {
            self.radius_and_normal_sum(positions, chunk);
            walked.did(chunk.len() as u64);
        }
        self.normalize_normals();
        for chunk in triangles.chunks(WALK_CHUNK) {
            self.cone(positions, chunk);
            walked.did(chunk.len() as u64);
        }
    }

    /// First walk without input normals: radii, and face normals summed.
    fn radius_and_normal_sum(&mut self, positions: &[DVec3], triangles: &[[u32; 3]]) {
        for tri in triangles {
            let owned = self.owned(tri);
            if owned == [None; 3] {
                continue;
            }
            let [a, b, c] = tri.map(|i| positions[i as usize]);
            let Some((r2, face)) = face_sizing(a, b, c) else {
                continue;
            };
            let face = face.as_vec3(); // length = 2 * area
            for v in owned.into_iter().flatten() {
                self.radius_squared[v] = self.radius_squared[v].max(r2);
                self.normal[v] += face;
            }
        }
    }

    /// Second walk: the cone, the widest angle between a vertex normal and
    /// its faces' normals, tracked as the smallest cosine (one acos per
    /// vertex, not per corner).
    fn cone(&mut self, positions: &[DVec3], triangles: &[[u32; 3]]) {
        for tri in triangles {
            let owned = self.owned(tri);
            if owned == [None; 3] {
                continue;
            }
            let [a, b, c] = tri.map(|i| positions[i as usize]);
            let Some(face) = face_with_area(a, b, c).and_then(DVec3::try_normalize) else {
                continue;
            };
            self.widen_cones(owned, face.as_vec3());
        }
    }

    /// [`Self::size`] when the vertex normals are the input's (already
    /// normalized): radius and cone in one walk over the triangles.
    fn size_and_cone(&mut self, positions: &[DVec3], triangles: &[[u32; 3]]) {
        for tri in triangles {
            let owned = self.owned(tri);
            if owned == [None; 3] {
                continue;
            }
            let [a, b, c] = tri.map(|i| positions[i as usize]);
            let Some((r2, face)) = face_sizing(a, b, c) else {
                continue;
            };
            for v in owned.into_iter().flatten() {
                self.radius_squared[v] = self.radius_squared[v].max(r2);
            }
            // The same face vector the separate cone walk computes, so the
            // cones are bit for bit those of that walk.
            if let Some(face) = face.try_normalize() {
                self.widen_cones(owned, face.as_vec3());
            }
        }
    }

    fn normalize_normals(&mut self) {
        for nv in self.normal.iter_mut() {
            *nv = nv.try_normalize().unwrap_or(Vec3::ZERO);
        }
    }

    /// Widens the owned corners' cones to cover a face: lowers their
    /// smallest normal-to-face cosine.
    #[inline]
    fn widen_cones(&mut self, owned: [Option<usize>; 3], unit_face: Vec3) {
        for v in owned.into_iter().flatten() {
            self.min_cos[v] = self.min_cos[v].min(self.normal[v].dot(unit_face));
        }
    }
}

/// Radius of the smallest sphere holding a triangle: half the longest edge
/// for a right or obtuse triangle, else the circumradius.
pub fn triangle_bounding_radius(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    squared_bounding_radius_and_face(a, b, c).0.sqrt()
}

/// What a face gives its corners' leaves: the square of its bounding
/// radius and its face vector; nothing for a face of zero area, whose
/// bounding sphere (half its longest edge) would size its corners by its
/// length and whose rounding-noise normal would bend theirs.
#[inline]
fn face_sizing(a: DVec3, b: DVec3, c: DVec3) -> Option<(f64, DVec3)> {
    let (squared, face, longest) = squared_bounding_radius_and_face(a, b, c);
    (!zero_area(face.length_squared(), longest)).then_some((squared, face))
}

/// The square of [`triangle_bounding_radius`], the face vector
/// `(b - a) x (c - a)` (its length is twice the area), sharing the cross
/// product, and the square of the longest edge (for the zero-area test).
/// No square root: the circumradius R = |ab| |bc| |ca| / (4 area) is taken
/// as |ab|² |bc|² |ca|² / (4 |face|²), and callers take the root once per
/// vertex, of the largest square.
#[inline]
fn squared_bounding_radius_and_face(a: DVec3, b: DVec3, c: DVec3) -> (f64, DVec3, f64) {
    let face = (b - a).cross(c - a);
    let (ab, bc, ca) = (
        a.distance_squared(b),
        b.distance_squared(c),
        c.distance_squared(a),
    );
    let longest = ab.max(bc).max(ca);
    let half_longest_squared = longest * 0.25;
    let twice_area_squared = face.length_squared();
    // Obtuse or right at some corner: the longest edge's midpoint sphere
    // holds all. A degenerate triangle has no circumcircle either.
    let squared = if longest >= ab + bc + ca - longest || twice_area_squared <= 0.0 {
        half_longest_squared
    } else {
        (ab * bc * ca / (4.0 * twice_area_squared)).max(half_longest_squared)
    };
    (squared, face, longest)
}

/// An upper bound on `acos(x)` within 2e-4 radians, without a libm call
/// (Abramowitz and Stegun 4.4.45, |error| about 5e-5, plus twice that): cones
/// are built per leaf and bottom-up over every node, and only need to be
/// conservative.
pub(crate) fn acos_upper(x: f64) -> f64 {
    let x = x.clamp(-1.0, 1.0);
    let a = x.abs();
    let r =
        (1.0 - a).sqrt() * (1.570_728_8 + a * (-0.212_114_4 + a * (0.074_261_0 - a * 0.018_729_3)));
    let angle = if x >= 0.0 {
        r
    } else {
        std::f64::consts::PI - r
    };
    angle + 1e-4
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
    use crate::progress::Silent;

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
    fn fast_acos_is_a_tight_upper_bound() {
        for i in -1000..=1000 {
            let x = f64::from(i) / 1000.0;
            let (fast, exact) = (acos_upper(x), x.acos());
            assert!(
                fast >= exact && fast - exact < 2e-4,
                "acos({x}): {fast} vs {exact}"
            );
        }
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
        let (leaves, stats) = make_leaves(Scene::single(g), false, &Silent);
        assert_eq!(stats.unreferenced_vertices, 1);
        assert_eq!(leaves.len(), 3);
        assert!(leaves.iter().all(|l| l.radius >= 0.5 && l.cone < 255));
        assert!(unpack_normal(leaves[0].normal).angle_between(Vec3::Z) < 1e-3);
    }

    /// A bumpy grid of 60 000 vertices, its triangles of varied sizes and
    /// shapes (some obtuse), in an order that crosses the threads' ranges.
    fn bumpy_mesh() -> (Vec<DVec3>, Vec<[u32; 3]>) {
        let side = 245u32;
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        let mut jitter = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let positions = (0..side * side)
            .map(|i| {
                let (u, v) = (f64::from(i % side), f64::from(i / side));
                DVec3::new(
                    u + 0.4 * jitter(),
                    v + 0.4 * jitter(),
                    (u * 0.3).sin() + jitter(),
                )
            })
            .collect();
        let mut triangles = crate::grid_triangles(side);
        triangles.reverse();
        (positions, triangles)
    }

    #[test]
    fn a_vertex_gets_the_largest_rounded_up_radius_of_its_triangles() {
        let (positions, triangles) = bumpy_mesh();
        let sizes = size_from_triangles(&positions, &triangles, None, &Silent);
        // The definition, per triangle: its bounding radius rounded up to
        // f32, the largest over the vertex's triangles.
        let mut expected = vec![-1.0f32; positions.len()];
        for t in &triangles {
            let [a, b, c] = t.map(|i| positions[i as usize]);
            let r = round_up_f32(triangle_bounding_radius(a, b, c));
            for &i in t {
                expected[i as usize] = expected[i as usize].max(r);
            }
        }
        assert_eq!(sizes.radius, expected);
    }

    /// The cone's cosine by its definition: for each vertex, the smallest
    /// cosine between its normal and the unit normals of its faces.
    fn min_cos_by_definition(
        positions: &[DVec3],
        triangles: &[[u32; 3]],
        normal: &[Vec3],
    ) -> Vec<f32> {
        let mut min_cos = vec![1.0f32; positions.len()];
        for t in triangles {
            let [a, b, c] = t.map(|i| positions[i as usize]);
            if let Some(face) = (b - a).cross(c - a).try_normalize() {
                for &i in t {
                    let i = i as usize;
                    min_cos[i] = min_cos[i].min(normal[i].dot(face.as_vec3()));
                }
            }
        }
        min_cos
    }

    #[test]
    fn cones_from_one_walk_and_from_two_walks_follow_their_definition() {
        let (positions, triangles) = bumpy_mesh();
        // Two walks: the normals summed from the faces, then the cones.
        let computed = size_from_triangles(&positions, &triangles, None, &Silent);
        let expected = min_cos_by_definition(&positions, &triangles, &computed.normal);
        assert!(computed.min_cos == expected, "two-walk cones differ");
        assert!(
            computed.min_cos.iter().any(|&c| c < 0.99),
            "cones too narrow to test"
        );
        // One walk, with those normals given as the input's.
        let given = size_from_triangles(
            &positions,
            &triangles,
            Some(computed.normal.clone()),
            &Silent,
        );
        let expected = min_cos_by_definition(&positions, &triangles, &given.normal);
        assert!(given.min_cos == expected, "one-walk cones differ");
        assert!(
            given.radius == computed.radius,
            "radii depend on the normals"
        );
    }
}
