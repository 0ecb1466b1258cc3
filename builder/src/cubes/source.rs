//! The scene's primitives as the octree builder sees them: a [`PrimRef`]
//! per instanced triangle or sphere, with its world bounding box, its
//! drawing cost in triangles, and its world-space triangles on demand.
//!
//! Instances are expanded as references (instance, primitive), never as
//! copies of the geometry, so a forest of one instanced tree costs a
//! reference per triangle, not a mesh per tree.
//!
//! Triangles of zero area ([`zero_area`]) get no reference: they cover no
//! sample of a cube face, so they would only cost (deepening the octree
//! along them, a long one across the whole scene), widen the bounds and be
//! stored as leaf geometry that draws nothing.
//!
//! [`zero_area`]: crate::zero_area

use glam::{DMat3, DVec3, Vec3};

use crate::spheres::leaves::max_stretch;

use crate::scene::{Primitives, Rgb8, Scene};
use crate::zero_area::is_zero_area;

/// Triangles a sphere (an atom) is drawn with: an icosahedron subdivided
/// twice. The 1996 paper drew its atoms with 800 polygons.
pub const SPHERE_TRIANGLES: usize = 320;

/// Color of geometry without colors, 0..1 (the splat renderer's default).
pub const DEFAULT_BASE: Vec3 = Vec3::new(200.0 / 255.0, 200.0 / 255.0, 200.0 / 255.0);

/// One primitive of one instance, with its world bounds.
#[derive(Debug, Clone, Copy)]
pub struct PrimRef {
    pub instance: u32,
    pub index: u32,
    pub min: DVec3,
    pub max: DVec3,
}

/// A corner of a world-space triangle, with what shading needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Corner {
    pub position: DVec3,
    /// Unit normal when the primitive has one (input normals, spheres).
    pub normal: Option<Vec3>,
    /// Base color, 0..1.
    pub color: Vec3,
}

impl Corner {
    /// The base color as sRGB bytes.
    pub fn rgb8(&self) -> Rgb8 {
        self.color
            .to_array()
            .map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)
    }
}

/// A world-space triangle.
pub type Triangle = [Corner; 3];

/// The scene, read-only, with per-instance transforms prepared.
#[derive(Debug)]
pub struct Source<'a> {
    scene: &'a Scene,
    /// Per instance: the inverse-transpose for normals.
    normal_from_local: Vec<DMat3>,
    /// Unit icosphere, for atoms.
    sphere: (Vec<DVec3>, Vec<[u32; 3]>),
}

impl<'a> Source<'a> {
    /// `Err` names the first geometry the cube builder cannot draw.
    pub fn new(scene: &'a Scene) -> Result<Self, String> {
        if let Some(g) = scene
            .geometries
            .iter()
            .find(|g| matches!(g.primitives, Primitives::Points))
        {
            return Err(format!(
                "{}: a point cloud has no surfaces to render into color-cubes; build it with --kind spheres",
                g.name
            ));
        }
        Ok(Self {
            scene,
            normal_from_local: scene
                .instances
                .iter()
                .map(|i| i.world_from_local.matrix3.inverse().transpose())
                .collect(),
            sphere: icosphere(2),
        })
    }

    /// Whether leaf geometry stores normals: spheres have them always,
    /// meshes when their input did.
    pub fn has_normals(&self) -> bool {
        self.scene.geometries.iter().all(|g| match g.primitives {
            Primitives::Spheres(_) => true,
            _ => g.normals.is_some(),
        })
    }

    pub fn has_color(&self) -> bool {
        self.scene.has_color()
    }

    /// Every primitive of every instance with its world bounds, but for
    /// triangles of zero area (in world space: what is drawn).
    pub fn refs(&self) -> Vec<PrimRef> {
        let mut out = Vec::with_capacity(self.scene.instanced_primitive_count() as usize);
        for (k, inst) in self.scene.instances.iter().enumerate() {
            let g = &self.scene.geometries[inst.geometry];
            let t = inst.world_from_local;
            match &g.primitives {
                Primitives::Triangles(tris) => {
                    for (i, tri) in tris.iter().enumerate() {
                        let p = tri.map(|v| t.transform_point3(g.positions[v as usize]));
                        if is_zero_area(p[0], p[1], p[2]) {
                            continue;
                        }
                        out.push(PrimRef {
                            instance: k as u32,
                            index: i as u32,
                            min: p[0].min(p[1]).min(p[2]),
                            max: p[0].max(p[1]).max(p[2]),
                        });
                    }
                }
                Primitives::Spheres(radii) => {
                    let stretch = max_stretch(t);
                    for (i, (&c, &r)) in g.positions.iter().zip(radii).enumerate() {
                        let c = t.transform_point3(c);
                        let r = DVec3::splat(r * stretch);
                        out.push(PrimRef {
                            instance: k as u32,
                            index: i as u32,
                            min: c - r,
                            max: c + r,
                        });
                    }
                }
                Primitives::Points => {}
            }
        }
        out
    }

    /// Drawing cost of a primitive, in triangles.
    pub fn cost(&self, r: &PrimRef) -> f64 {
        match self.primitives(r) {
            Primitives::Spheres(_) => SPHERE_TRIANGLES as f64,
            _ => 1.0,
        }
    }

    fn primitives(&self, r: &PrimRef) -> &Primitives {
        let inst = &self.scene.instances[r.instance as usize];
        &self.scene.geometries[inst.geometry].primitives
    }

    /// Appends the world-space triangles of a primitive to `out`.
    pub fn triangles(&self, r: &PrimRef, out: &mut Vec<Triangle>) {
        let inst = &self.scene.instances[r.instance as usize];
        let g = &self.scene.geometries[inst.geometry];
        let t = inst.world_from_local;
        let color_of = |v: usize| g.colors.as_ref().map_or(DEFAULT_BASE, |c| unit_color(c[v]));
        match &g.primitives {
            Primitives::Triangles(tris) => {
                let tri = tris[r.index as usize];
                let nm = self.normal_from_local[r.instance as usize];
                out.push(tri.map(|v| {
                    let v = v as usize;
                    Corner {
                        position: t.transform_point3(g.positions[v]),
                        normal: g.normals.as_ref().map(|n| {
                            (nm * n[v].as_dvec3())
                                .try_normalize()
                                .unwrap_or(DVec3::Z)
                                .as_vec3()
                        }),
                        color: color_of(v),
                    }
                }));
            }
            Primitives::Spheres(radii) => {
                let i = r.index as usize;
                let c = t.transform_point3(g.positions[i]);
                let radius = radii[i] * max_stretch(t);
                let color = color_of(i);
                let (dirs, faces) = &self.sphere;
                for f in faces {
                    out.push(f.map(|v| {
                        let d = dirs[v as usize];
                        Corner {
                            position: c + d * radius,
                            normal: Some(d.as_vec3()),
                            color,
                        }
                    }));
                }
            }
            Primitives::Points => {}
        }
    }
}

fn unit_color(c: Rgb8) -> Vec3 {
    Vec3::from(c.map(|v| f32::from(v) / 255.0))
}

/// A unit icosphere: 20 * 4^subdivisions triangles, outward winding.
fn icosphere(subdivisions: u32) -> (Vec<DVec3>, Vec<[u32; 3]>) {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut v: Vec<DVec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| DVec3::new(x, y, z).normalize())
    .collect();
    let mut f: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut mid = std::collections::HashMap::new();
        let mut midpoint = |a: u32, b: u32, v: &mut Vec<DVec3>| -> u32 {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                v.push(((v[a as usize] + v[b as usize]) * 0.5).normalize());
                (v.len() - 1) as u32
            })
        };
        let mut next = Vec::with_capacity(f.len() * 4);
        for [a, b, c] in f {
            let ab = midpoint(a, b, &mut v);
            let bc = midpoint(b, c, &mut v);
            let ca = midpoint(c, a, &mut v);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        f = next;
    }
    (v, f)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn icosphere_is_closed_and_outward() {
        let (v, f) = icosphere(2);
        assert_eq!(f.len(), SPHERE_TRIANGLES);
        for t in &f {
            let [a, b, c] = t.map(|i| v[i as usize]);
            let n = (b - a).cross(c - a);
            assert!(n.dot(a + b + c) > 0.0, "inward triangle");
        }
    }
}
