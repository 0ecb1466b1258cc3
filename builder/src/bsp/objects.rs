//! The scene as the BSP builder sees it: objects with extents.
//!
//! A triangle geometry placed two or more times is a **prototype**: stored
//! once, in its own frame, and each placement is one object that is never
//! split (the paper's trees). Everything else (a geometry placed once: the
//! terrain, the sea; spheres, tessellated) is expanded into world
//! triangles, and each such placement is one **mesh** object, which a
//! splitting plane may divide between its sides by triangle centroids.

use farfield_protocol::bsp_codec::FlatTriangle;
use glam::{DAffine3, DVec3};

use crate::BuildError;
use crate::cubes::source::{DEFAULT_BASE, PrimRef, Source};
use crate::scene::{Primitives, Scene};
use crate::zero_area::is_zero_area;

/// A geometry stored once and placed by reference.
#[derive(Debug, Clone)]
pub struct Prototype {
    /// Its triangles in its own frame.
    pub triangles: Vec<FlatTriangle>,
    pub box_min: DVec3,
    pub box_max: DVec3,
}

/// One placement of a prototype.
#[derive(Debug, Clone, Copy)]
pub struct Placement {
    pub prototype: u32,
    pub world_from_local: DAffine3,
    /// The placed prototype box's eight corners, bounded (world).
    pub box_min: DVec3,
    pub box_max: DVec3,
    pub triangles: u64,
}

impl Placement {
    pub fn centre(&self) -> DVec3 {
        (self.box_min + self.box_max) * 0.5
    }
}

/// The world triangles of every mesh object.
#[derive(Debug, Default)]
pub struct MeshTriangles {
    pub corners: Vec<[DVec3; 3]>,
    pub rgba: Vec<[u8; 4]>,
}

impl MeshTriangles {
    pub fn centroid(&self, t: u32) -> DVec3 {
        let [a, b, c] = self.corners[t as usize];
        (a + b + c) / 3.0
    }
}

/// What one object of the build is.
#[derive(Debug, Clone, PartialEq)]
pub enum Content {
    /// World triangles (indices into [`MeshTriangles`]).
    Mesh(Vec<u32>),
    /// A placement (index into [`Collected::placements`]).
    Instance(u32),
}

/// The scene, collected.
#[derive(Debug, Default)]
pub struct Collected {
    pub prototypes: Vec<Prototype>,
    pub placements: Vec<Placement>,
    pub mesh: MeshTriangles,
    /// One per placement of the scene: its mesh or its instance.
    pub objects: Vec<Content>,
}

fn rgba(rgb: [u8; 3]) -> [u8; 4] {
    [rgb[0], rgb[1], rgb[2], 255]
}

/// Collects `scene`: prototypes for triangle geometries placed more than
/// once, world triangles for the rest. Zero-area triangles are left out.
pub fn collect(scene: &Scene) -> Result<Collected, BuildError> {
    let src = Source::new(scene).map_err(BuildError::Invalid)?;
    let mut uses = vec![0usize; scene.geometries.len()];
    for i in &scene.instances {
        uses[i.geometry] += 1;
    }
    let mut out = Collected::default();
    let mut prototype_of = vec![None; scene.geometries.len()];
    for (g, geometry) in scene.geometries.iter().enumerate() {
        let Primitives::Triangles(tris) = &geometry.primitives else {
            continue;
        };
        if uses[g] < 2 {
            continue;
        }
        let default = DEFAULT_BASE.to_array().map(|v| (v * 255.0).round() as u8);
        let mut triangles = Vec::with_capacity(tris.len());
        let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for tri in tris {
            let p = tri.map(|v| geometry.positions[v as usize]);
            if is_zero_area(p[0], p[1], p[2]) {
                continue;
            }
            for c in p {
                lo = lo.min(c);
                hi = hi.max(c);
            }
            let color = geometry
                .colors
                .as_ref()
                .map_or(default, |c| c[tri[0] as usize]);
            triangles.push(FlatTriangle {
                corners: p.map(|c| c.as_vec3().to_array()),
                rgba: rgba(color),
            });
        }
        if triangles.is_empty() {
            continue;
        }
        prototype_of[g] = Some(out.prototypes.len() as u32);
        out.prototypes.push(Prototype {
            triangles,
            box_min: lo,
            box_max: hi,
        });
    }
    let mut buffer = Vec::new();
    for (k, instance) in scene.instances.iter().enumerate() {
        let g = &scene.geometries[instance.geometry];
        if let Some(p) = prototype_of[instance.geometry] {
            let proto = &out.prototypes[p as usize];
            let (lo, hi) = placed_box(instance.world_from_local, proto.box_min, proto.box_max);
            if !(lo.is_finite() && hi.is_finite()) {
                return Err(BuildError::Invalid(format!(
                    "{}: a placement is not finite",
                    g.name
                )));
            }
            out.objects
                .push(Content::Instance(out.placements.len() as u32));
            out.placements.push(Placement {
                prototype: p,
                world_from_local: instance.world_from_local,
                box_min: lo,
                box_max: hi,
                triangles: proto.triangles.len() as u64,
            });
            continue;
        }
        let mut list = Vec::new();
        for index in 0..g.primitive_count() {
            let r = PrimRef {
                instance: k as u32,
                index: index as u32,
                min: DVec3::ZERO,
                max: DVec3::ZERO,
            };
            buffer.clear();
            src.triangles(&r, &mut buffer);
            for t in &buffer {
                let p = t.map(|c| c.position);
                if is_zero_area(p[0], p[1], p[2]) || !p.iter().all(|c| c.is_finite()) {
                    continue;
                }
                if out.mesh.corners.len() >= u32::MAX as usize {
                    return Err(BuildError::TooLarge(out.mesh.corners.len() as u64));
                }
                list.push(out.mesh.corners.len() as u32);
                out.mesh.corners.push(p);
                out.mesh.rgba.push(rgba(t[0].rgb8()));
            }
        }
        if !list.is_empty() {
            out.objects.push(Content::Mesh(list));
        }
    }
    Ok(out)
}

/// The world box of a local box's eight corners under `t`.
pub fn placed_box(t: DAffine3, lo: DVec3, hi: DVec3) -> (DVec3, DVec3) {
    let mut min = DVec3::INFINITY;
    let mut max = DVec3::NEG_INFINITY;
    for i in 0..8 {
        let c = DVec3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        );
        let w = t.transform_point3(c);
        min = min.min(w);
        max = max.max(w);
    }
    (min, max)
}
