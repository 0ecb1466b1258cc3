//! Closed mesh pieces for the procedural scenes: boxes, capped cylinders
//! and frustums, tubes along polylines and closed planar loops (tori).
//!
//! Every shape is **closed** and **outward-facing**: its triangles run
//! counter-clockwise seen from outside, so `(b - a) x (c - a)` points out of
//! the solid. The PLP renderer culls back faces and counts depth complexity
//! per pixel; a single wrongly wound triangle would show as a hole, and an
//! open shape would let a viewer see into a solid. Each call adds its own
//! fresh vertices (nothing is shared between shapes), so a geometry's
//! connected components by vertex index are exactly its shapes, and each can
//! be checked on its own (`closed_parts`, in the tests).
//!
//! Meshes carry one color per vertex and no normals: the shapes are
//! faceted, and the builders derive normals from faces where they need them.

use glam::DVec3;

use super::trig::sin_cos;
use crate::scene::{Geometry, Primitives, Rgb8};

const TAU: f64 = std::f64::consts::TAU;

/// An indexed triangle mesh with per-vertex colors, filled shape by shape.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    pub positions: Vec<DVec3>,
    pub colors: Vec<Rgb8>,
    pub triangles: Vec<[u32; 3]>,
}

/// Any unit vector perpendicular to unit `d`, chosen by a fixed rule so the
/// same axis always gets the same frame.
pub fn perpendicular(d: DVec3) -> DVec3 {
    let axis = if d.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
    (axis - d * axis.dot(d)).normalize()
}

/// `n` points `(sin, cos)` evenly around a circle, computed once per shape.
fn circle(n: u32) -> Vec<(f64, f64)> {
    (0..n)
        .map(|i| sin_cos(TAU * f64::from(i) / f64::from(n)))
        .collect()
}

impl Mesh {
    /// Triangles so far.
    #[cfg(test)]
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Adds one vertex and returns its index. The generators stay far below
    /// `u32::MAX` vertices per mesh (their parameter ranges bound them).
    pub fn vertex(&mut self, p: DVec3, color: Rgb8) -> u32 {
        self.positions.push(p);
        self.colors.push(color);
        (self.positions.len() - 1) as u32
    }

    pub fn triangle(&mut self, a: u32, b: u32, c: u32) {
        self.triangles.push([a, b, c]);
    }

    /// A quad `a b c d`, counter-clockwise seen from its front, as two
    /// triangles sharing the diagonal `a c`.
    pub fn quad(&mut self, a: u32, b: u32, c: u32, d: u32) {
        self.triangles.push([a, b, c]);
        self.triangles.push([a, c, d]);
    }

    /// Appends another mesh (its indices shifted past ours).
    pub fn append(&mut self, other: &Mesh) {
        let offset = self.positions.len() as u32;
        self.positions.extend_from_slice(&other.positions);
        self.colors.extend_from_slice(&other.colors);
        self.triangles
            .extend(other.triangles.iter().map(|t| t.map(|i| i + offset)));
    }

    /// The axis-aligned box `lo..hi` (12 triangles). Empty or inverted
    /// extents are skipped: a wall piece of zero width is no piece.
    pub fn add_box(&mut self, lo: DVec3, hi: DVec3, color: Rgb8) {
        if !(lo.x < hi.x && lo.y < hi.y && lo.z < hi.z) {
            return;
        }
        let h = (hi - lo) * 0.5;
        self.add_oriented_box(
            lo + h,
            [DVec3::X * h.x, DVec3::Y * h.y, DVec3::Z * h.z],
            color,
        );
    }

    /// A prism along x from `x0` to `x1` over a convex `outline` of (y, z)
    /// points, counter-clockwise seen from +x: side quads and two caps fanned
    /// from the outline's centroid, all facing out.
    pub fn add_prism_x(&mut self, outline: &[(f64, f64)], x0: f64, x1: f64, color: Rgb8) {
        let n = outline.len();
        if n < 3 {
            return;
        }
        let (sy, sz) = outline
            .iter()
            .fold((0.0, 0.0), |(a, b), &(y, z)| (a + y, b + z));
        let (cy, cz) = (sy / n as f64, sz / n as f64);
        let c0 = self.vertex(DVec3::new(x0, cy, cz), color);
        let c1 = self.vertex(DVec3::new(x1, cy, cz), color);
        let near: Vec<u32> = outline
            .iter()
            .map(|&(y, z)| self.vertex(DVec3::new(x0, y, z), color))
            .collect();
        let far: Vec<u32> = outline
            .iter()
            .map(|&(y, z)| self.vertex(DVec3::new(x1, y, z), color))
            .collect();
        for k in 0..n {
            let k1 = (k + 1) % n;
            self.triangle(c1, far[k], far[k1]);
            self.triangle(c0, near[k1], near[k]);
            self.quad(near[k], near[k1], far[k1], far[k]);
        }
    }

    /// A box around `centre` with edges along `half[0..3]`, each the
    /// half-extent vector of one axis (12 triangles). The axes must be
    /// mutually perpendicular; a left-handed set is flipped, which leaves the
    /// box itself unchanged.
    pub fn add_oriented_box(&mut self, centre: DVec3, half: [DVec3; 3], color: Rgb8) {
        let [a, b, mut c] = half;
        if a.cross(b).dot(c) < 0.0 {
            c = -c;
        }
        let base = self.positions.len() as u32;
        // Corner k has bit 0 for +a, bit 1 for +b, bit 2 for +c.
        for k in 0..8u32 {
            let s = |bit: u32| if k >> bit & 1 == 1 { 1.0 } else { -1.0 };
            self.vertex(centre + a * s(0) + b * s(1) + c * s(2), color);
        }
        // Each face counter-clockwise seen from outside (-a, +a, -b, +b, -c, +c).
        const FACES: [[u32; 4]; 6] = [
            [0, 4, 6, 2],
            [1, 3, 7, 5],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 2, 3, 1],
            [4, 5, 7, 6],
        ];
        for f in FACES {
            self.quad(base + f[0], base + f[1], base + f[2], base + f[3]);
        }
    }

    /// A capped cylinder (an `n`-sided prism) from `a` to `b` (4n triangles).
    pub fn add_cylinder(&mut self, a: DVec3, b: DVec3, radius: f64, n: u32, color: Rgb8) {
        self.add_frustum(a, b, radius, radius, n, color);
    }

    /// A capped frustum from `a` (radius `ra`) to `b` (radius `rb`),
    /// `n` sides (4n triangles). Both radii must be positive.
    pub fn add_frustum(&mut self, a: DVec3, b: DVec3, ra: f64, rb: f64, n: u32, color: Rgb8) {
        let d = (b - a).normalize();
        let frame = Frame::around(d);
        self.tube_rings(&[(a, frame, ra), (b, frame, rb)], n, color);
    }

    /// A tube of `radius` along the polyline `points`, capped at both ends:
    /// `n`-sided rings in parallel-transported frames, so the tube does not
    /// twist (2n triangles per segment plus 2n for the caps). Bends must be
    /// gentle compared with the radius, or the tube folds into itself.
    pub fn add_tube(&mut self, points: &[DVec3], radius: f64, n: u32, color: Rgb8) {
        if points.len() < 2 {
            return;
        }
        let last = points.len() - 1;
        let mut rings = Vec::with_capacity(points.len());
        let mut u = DVec3::ZERO;
        for (k, &p) in points.iter().enumerate() {
            let d = (points[(k + 1).min(last)] - points[k.saturating_sub(1)]).normalize();
            u = if k == 0 {
                perpendicular(d)
            } else {
                (u - d * u.dot(d)).normalize()
            };
            rings.push((p, Frame { u, v: d.cross(u) }, radius));
        }
        self.tube_rings(&rings, n, color);
    }

    /// A closed tube of `radius` along the closed planar loop `points`
    /// (the last point joins the first), whose plane has unit `normal`: a
    /// torus when the loop is a circle, a belt round pulleys. No caps:
    /// 2n triangles per point.
    pub fn add_loop_tube(
        &mut self,
        points: &[DVec3],
        normal: DVec3,
        radius: f64,
        n: u32,
        color: Rgb8,
    ) {
        let m = points.len();
        if m < 3 {
            return;
        }
        let ring = circle(n);
        let base = self.positions.len() as u32;
        for k in 0..m {
            let d = (points[(k + 1) % m] - points[(k + m - 1) % m]).normalize();
            // In a plane the normal is a frame that never twists: (u, v, d)
            // is right-handed because d lies in the plane.
            let frame = Frame {
                u: normal,
                v: d.cross(normal),
            };
            for &(s, c) in &ring {
                self.vertex(points[k] + (frame.u * c + frame.v * s) * radius, color);
            }
        }
        for k in 0..m as u32 {
            let next = (k + 1) % m as u32;
            for i in 0..n {
                let j = (i + 1) % n;
                self.quad(
                    base + k * n + i,
                    base + k * n + j,
                    base + next * n + j,
                    base + next * n + i,
                );
            }
        }
    }

    /// A torus around `axis` (unit) through `centre`: `major` radius of the
    /// ring, `minor` radius of the tube, `around` x `n` quads.
    pub fn add_torus(
        &mut self,
        centre: DVec3,
        axis: DVec3,
        radii: (f64, f64),
        around: u32,
        n: u32,
        color: Rgb8,
    ) {
        let frame = Frame::around(axis);
        let points: Vec<DVec3> = circle(around)
            .into_iter()
            .map(|(s, c)| centre + (frame.u * c + frame.v * s) * radii.0)
            .collect();
        self.add_loop_tube(&points, axis, radii.1, n, color);
    }

    /// Rings joined into a capped tube: ring `k` is `(centre, frame, radius)`
    /// with the tube running from ring 0 to the last, each frame's `u x v`
    /// along the tube's direction there.
    fn tube_rings(&mut self, rings: &[(DVec3, Frame, f64)], n: u32, color: Rgb8) {
        let ring = circle(n);
        let base = self.positions.len() as u32;
        for &(p, f, r) in rings {
            for &(s, c) in &ring {
                self.vertex(p + (f.u * c + f.v * s) * r, color);
            }
        }
        let m = rings.len() as u32;
        for k in 0..m - 1 {
            for i in 0..n {
                let j = (i + 1) % n;
                let (a, b) = (base + k * n + i, base + k * n + j);
                self.quad(a, b, b + n, a + n);
            }
        }
        // Caps: the first faces back along the tube, the last forward.
        let start = self.vertex(rings[0].0, color);
        let end = self.vertex(rings[m as usize - 1].0, color);
        let last = base + (m - 1) * n;
        for i in 0..n {
            let j = (i + 1) % n;
            self.triangle(start, base + j, base + i);
            self.triangle(end, last + i, last + j);
        }
    }

    /// The mesh as a scene geometry: colors per vertex, no normals.
    pub fn into_geometry(self, name: impl Into<String>) -> Geometry {
        Geometry {
            name: name.into(),
            positions: self.positions,
            normals: None,
            colors: Some(self.colors),
            primitives: Primitives::Triangles(self.triangles),
        }
    }
}

/// Two unit vectors spanning a ring's plane, with `u x v` along the axis.
#[derive(Debug, Clone, Copy)]
struct Frame {
    u: DVec3,
    v: DVec3,
}

impl Frame {
    /// The fixed frame of unit axis `d`: `(u, v, d)` right-handed.
    fn around(d: DVec3) -> Self {
        let u = perpendicular(d);
        Self { u, v: d.cross(u) }
    }
}

/// Checks that a mesh is made of closed, consistently outward-facing
/// shapes, and returns how many there are.
///
/// The shapes are the connected components by vertex index (every shape
/// owns its vertices). Within one, vertices are merged by exact position
/// (a seam may repeat a position), and then every directed edge must occur
/// exactly once and its reverse exactly once (closed, and each edge's two
/// triangles agree on orientation), no triangle may repeat a corner, and
/// the signed volume (divergence theorem) must be positive (outward, not
/// inside-out).
#[cfg(test)]
pub(crate) fn closed_parts(positions: &[DVec3], triangles: &[[u32; 3]]) -> Result<usize, String> {
    use std::collections::HashMap;

    // Union-find over vertex indices.
    let mut parent: Vec<usize> = (0..positions.len()).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for t in triangles {
        let a = root(&mut parent, t[0] as usize);
        for &v in &t[1..] {
            let b = root(&mut parent, v as usize);
            parent[b] = a;
        }
    }
    let mut parts: HashMap<usize, Vec<[u32; 3]>> = HashMap::new();
    for t in triangles {
        let r = root(&mut parent, t[0] as usize);
        parts.entry(r).or_default().push(*t);
    }
    for (root_vertex, tris) in &parts {
        let mut ids: HashMap<[u64; 3], u32> = HashMap::new();
        let mut id = |i: u32| {
            // `+ 0.0` turns -0.0 into 0.0, so both merge.
            let key = positions[i as usize]
                .to_array()
                .map(|x| (x + 0.0).to_bits());
            let next = ids.len() as u32;
            *ids.entry(key).or_insert(next)
        };
        let mut edges: HashMap<(u32, u32), u32> = HashMap::new();
        let mut volume = 0.0;
        for t in tris {
            let m = t.map(&mut id);
            if m[0] == m[1] || m[1] == m[2] || m[0] == m[2] {
                return Err(format!(
                    "part at vertex {root_vertex}: degenerate triangle {t:?}"
                ));
            }
            for k in 0..3 {
                *edges.entry((m[k], m[(k + 1) % 3])).or_default() += 1;
            }
            let [a, b, c] = t.map(|i| positions[i as usize]);
            volume += a.dot(b.cross(c)) / 6.0;
        }
        for (&(a, b), &count) in &edges {
            let back = edges.get(&(b, a)).copied().unwrap_or(0);
            if count != 1 || back != 1 {
                return Err(format!(
                    "part at vertex {root_vertex}: edge {a}->{b} used {count} times, reverse {back} times"
                ));
            }
        }
        if volume <= 0.0 {
            return Err(format!(
                "part at vertex {root_vertex}: signed volume {volume} is not positive"
            ));
        }
    }
    Ok(parts.len())
}

#[cfg(test)]
mod tests {
    use super::*;

    const RED: Rgb8 = [200, 0, 0];

    fn volume(m: &Mesh) -> f64 {
        m.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| m.positions[i as usize]);
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }

    #[test]
    fn a_box_is_closed_outward_and_exact() {
        let mut m = Mesh::default();
        m.add_box(DVec3::new(1.0, 2.0, 3.0), DVec3::new(2.0, 4.0, 7.0), RED);
        assert_eq!(m.triangle_count(), 12);
        assert_eq!(closed_parts(&m.positions, &m.triangles), Ok(1));
        assert!((volume(&m) - 8.0).abs() < 1e-12);
        // Every face's normal points away from the centre.
        let centre = DVec3::new(1.5, 3.0, 5.0);
        for t in &m.triangles {
            let [a, b, c] = t.map(|i| m.positions[i as usize]);
            assert!((b - a).cross(c - a).dot((a + b + c) / 3.0 - centre) > 0.0);
        }
        // Empty extents add nothing.
        m.add_box(DVec3::ZERO, DVec3::new(1.0, 0.0, 1.0), RED);
        assert_eq!(m.triangle_count(), 12);
    }

    #[test]
    fn left_handed_axes_still_give_an_outward_box() {
        let mut m = Mesh::default();
        let (s, c) = sin_cos(0.3);
        let x = DVec3::new(c, s, 0.0);
        let y = DVec3::new(-s, c, 0.0);
        m.add_oriented_box(DVec3::ONE, [x, y, -DVec3::Z * 2.0], RED);
        assert_eq!(closed_parts(&m.positions, &m.triangles), Ok(1));
        assert!((volume(&m) - 16.0).abs() < 1e-9);
    }

    #[test]
    fn cylinders_frustums_and_tubes_are_closed_and_outward() {
        let mut m = Mesh::default();
        let a = DVec3::new(0.5, -1.0, 2.0);
        m.add_cylinder(a, a + DVec3::new(0.3, 0.2, 1.0), 0.2, 12, RED);
        assert_eq!(m.triangle_count(), 48);
        m.add_frustum(DVec3::ZERO, DVec3::X * 2.0, 0.5, 0.1, 3, RED);
        m.add_cylinder(DVec3::ZERO, -DVec3::Y, 0.5, 64, RED);
        let bend: Vec<DVec3> = (0..10)
            .map(|k| {
                let (s, c) = sin_cos(0.15 * f64::from(k));
                DVec3::new(5.0 * c, 5.0 * s, 0.2 * f64::from(k))
            })
            .collect();
        m.add_tube(&bend, 0.3, 8, RED);
        assert_eq!(closed_parts(&m.positions, &m.triangles), Ok(4));
        // A prism of 64 sides has nearly the cylinder's volume.
        let mut c = Mesh::default();
        c.add_cylinder(DVec3::ZERO, DVec3::Z * 2.0, 1.0, 64, RED);
        let v = volume(&c);
        assert!((v - 2.0 * std::f64::consts::PI).abs() < 0.02, "{v}");
    }

    #[test]
    fn a_prism_is_closed_outward_and_exact() {
        let mut m = Mesh::default();
        let square = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)];
        m.add_prism_x(&square, 0.0, 2.0, RED);
        assert_eq!(m.triangle_count(), 4 * 4);
        assert_eq!(closed_parts(&m.positions, &m.triangles), Ok(1));
        assert!((volume(&m) - 2.0).abs() < 1e-12, "{}", volume(&m));
        // Fewer than three points make nothing.
        m.add_prism_x(&square[..2], 0.0, 2.0, RED);
        assert_eq!(m.triangle_count(), 16);
    }

    #[test]
    fn a_torus_is_closed_and_outward() {
        let mut m = Mesh::default();
        m.add_torus(
            DVec3::ONE,
            DVec3::new(0.0, 0.6, 0.8),
            (1.0, 0.25),
            24,
            8,
            RED,
        );
        assert_eq!(m.triangle_count(), 2 * 24 * 8);
        assert_eq!(closed_parts(&m.positions, &m.triangles), Ok(1));
        // Pappus: 2 pi R * pi r^2, less for the polygonal approximation.
        let exact = 2.0 * std::f64::consts::PI * std::f64::consts::PI * 0.0625;
        let v = volume(&m);
        assert!(v > 0.85 * exact && v < exact, "{v} vs {exact}");
    }

    #[test]
    fn the_check_catches_holes_flips_and_inside_out_shapes() {
        let mut m = Mesh::default();
        m.add_box(DVec3::ZERO, DVec3::ONE, RED);
        let mut open = m.clone();
        open.triangles.pop();
        assert!(closed_parts(&open.positions, &open.triangles).is_err());
        let mut flipped = m.clone();
        flipped.triangles[3].swap(0, 1);
        assert!(closed_parts(&flipped.positions, &flipped.triangles).is_err());
        let mut inside_out = m.clone();
        inside_out.triangles.iter_mut().for_each(|t| t.swap(0, 1));
        assert!(closed_parts(&inside_out.positions, &inside_out.triangles).is_err());
        let mut doubled = m.clone();
        let again = m.clone();
        doubled.triangles.extend_from_slice(&again.triangles);
        assert!(closed_parts(&doubled.positions, &doubled.triangles).is_err());
    }

    #[test]
    fn append_shifts_indices() {
        let mut a = Mesh::default();
        a.add_box(DVec3::ZERO, DVec3::ONE, RED);
        let mut b = Mesh::default();
        b.add_cylinder(DVec3::ZERO, DVec3::Z, 1.0, 5, RED);
        a.append(&b);
        assert_eq!(a.triangle_count(), 12 + 20);
        assert_eq!(closed_parts(&a.positions, &a.triangles), Ok(2));
        let g = a.into_geometry("g");
        assert!(g.normals.is_none());
        assert_eq!(g.colors.as_ref().map(Vec::len), Some(g.positions.len()));
    }
}
