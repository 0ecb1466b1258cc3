//! The one in-memory scene every importer produces and every builder reads.
//!
//! A [`Scene`] is a list of [`Geometry`] values (positions in f64, optional
//! per-vertex normals and colors, and one kind of [`Primitives`]) placed in
//! the world by [`Instance`]s. Instancing is what lets `gen:island` grow to
//! tens of thousands of trees while the tree mesh exists once in memory: the
//! builders expand instances as they stream leaves, never as one big mesh.

use glam::{DAffine3, DVec3, Vec3};

/// An 8-bit-per-channel sRGB color.
pub type Rgb8 = [u8; 3];

/// What the vertices of a [`Geometry`] are.
#[derive(Debug, Clone, PartialEq)]
pub enum Primitives {
    /// Triangles indexing into the positions (counter-clockwise front faces).
    Triangles(Vec<[u32; 3]>),
    /// Unconnected points (scans, lidar): size and normal come from neighbours.
    Points,
    /// One sphere per vertex with its own radius (atoms). Spheres have no
    /// orientation, so a scene of spheres alone stores no normals.
    Spheres(Vec<f64>),
}

/// One mesh, cloud or set of spheres, in its own local frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Geometry {
    /// Where the data came from, for error messages and summaries.
    pub name: String,
    pub positions: Vec<DVec3>,
    /// Unit normals per vertex, when the input has them.
    pub normals: Option<Vec<Vec3>>,
    /// Colors per vertex, when the input has them.
    pub colors: Option<Vec<Rgb8>>,
    pub primitives: Primitives,
}

/// A placement of a geometry in the world.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Instance {
    /// Index into [`Scene::geometries`].
    pub geometry: usize,
    pub world_from_local: DAffine3,
}

/// Everything an input (or several merged inputs) describes.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Scene {
    pub geometries: Vec<Geometry>,
    pub instances: Vec<Instance>,
}

impl Geometry {
    /// A geometry with no optional channels.
    pub fn new(name: impl Into<String>, positions: Vec<DVec3>, primitives: Primitives) -> Self {
        Self {
            name: name.into(),
            positions,
            normals: None,
            colors: None,
            primitives,
        }
    }

    /// Number of primitives: triangles, points or spheres.
    pub fn primitive_count(&self) -> usize {
        match &self.primitives {
            Primitives::Triangles(t) => t.len(),
            Primitives::Points => self.positions.len(),
            Primitives::Spheres(r) => r.len(),
        }
    }
}

impl Scene {
    /// A scene holding one geometry placed once, untransformed.
    pub fn single(geometry: Geometry) -> Self {
        Self {
            geometries: vec![geometry],
            instances: vec![Instance {
                geometry: 0,
                world_from_local: DAffine3::IDENTITY,
            }],
        }
    }

    /// Adds another scene's geometries and instances to this one.
    pub fn merge(&mut self, other: Scene) {
        let offset = self.geometries.len();
        self.geometries.extend(other.geometries);
        self.instances
            .extend(other.instances.into_iter().map(|i| Instance {
                geometry: i.geometry + offset,
                ..i
            }));
    }

    /// Vertices as the builder will see them: every instance counts its
    /// geometry's vertices again.
    pub fn instanced_vertex_count(&self) -> u64 {
        self.instances
            .iter()
            .map(|i| self.geometries[i.geometry].positions.len() as u64)
            .sum()
    }

    /// Primitives (triangles, points, spheres) over all instances.
    pub fn instanced_primitive_count(&self) -> u64 {
        self.instances
            .iter()
            .map(|i| self.geometries[i.geometry].primitive_count() as u64)
            .sum()
    }

    /// True when any geometry carries per-vertex colors.
    pub fn has_color(&self) -> bool {
        self.geometries.iter().any(|g| g.colors.is_some())
    }

    /// True when any geometry is oriented (triangles or points); a scene made
    /// only of spheres needs no normals.
    pub fn has_orientation(&self) -> bool {
        self.geometries
            .iter()
            .any(|g| !matches!(g.primitives, Primitives::Spheres(_)))
    }
}
