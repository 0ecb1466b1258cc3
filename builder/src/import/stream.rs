//! Mesh files read as streams, for a build that writes what it reads to
//! disk instead of holding it: what a first look at a file says of it
//! ([`MeshInfo`]), and where its body goes, a batch at a time
//! ([`BodyOut`]).
//!
//! PLY and OFF say their counts in their headers; OBJ says nothing ahead,
//! so its survey is a parse of the whole file that keeps only the counts
//! and flags. Each format's `stream` gives exactly what its `load` would
//! hold, in the same order.

use std::path::Path;

use glam::{DVec3, Vec3};

use super::common::unit_normals;
use super::{ImportError, obj, off, ply};
use crate::scene::{Geometry, Primitives, Rgb8};

/// What a mesh file holds, learned before its body is streamed.
#[derive(Debug, Clone, Copy)]
pub(crate) struct MeshInfo {
    pub vertices: u64,
    /// It has faces (a mesh; else a point cloud).
    pub triangles: bool,
    /// Its vertices have normals, which the build keeps.
    pub normals: bool,
    /// Its vertices have colors, which the build keeps.
    pub colors: bool,
    /// What colors read as numbers are multiplied by to be 0..1 (OBJ and
    /// OFF colors are 0..1, or 0..255 when any component of any vertex
    /// exceeds 1, which only the whole file tells); 1 for PLY.
    pub color_scale: f64,
}

/// The mesh formats a build can stream.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Streamed {
    Ply,
    Off,
    Obj,
}

impl Streamed {
    /// The format of a file, by its extension.
    pub(crate) fn of(path: &Path) -> Option<Self> {
        let extension = path.extension()?.to_str()?.to_ascii_lowercase();
        match extension.as_str() {
            "ply" => Some(Self::Ply),
            "off" => Some(Self::Off),
            "obj" => Some(Self::Obj),
            _ => None,
        }
    }

    /// What `path` holds: from its header, or (OBJ) a parse of it.
    pub(crate) fn survey(self, path: &Path) -> Result<MeshInfo, ImportError> {
        match self {
            Self::Ply => ply::survey(path),
            Self::Off => off::survey(path),
            Self::Obj => obj::survey(path),
        }
    }

    /// Reads `path`'s vertices and triangles into `out`, as its survey
    /// `info` found them. An OBJ file's
    /// normals belong to face corners, not vertices: they go to `corners`
    /// (and its vertices to `out` without normals).
    pub(crate) fn stream(
        self,
        path: &Path,
        info: &MeshInfo,
        out: &mut dyn BodyOut,
        corners: &mut dyn CornerNormals,
    ) -> Result<(), ImportError> {
        match self {
            Self::Ply => ply::stream(path, out),
            Self::Off => off::stream(path, info, out),
            Self::Obj => obj::stream(path, info, out, corners),
        }
    }
}

/// Where a body's vertices and triangles go: into memory whole (an
/// import) or, a batch at a time, to a build's files.
pub(crate) trait BodyOut {
    /// The most vertices, or faces, read before they are handed over.
    fn batch(&self) -> u64;
    /// The next vertices, in order.
    fn vertices(&mut self, batch: Vertices) -> Result<(), ImportError>;
    /// Where the faces' triangles gather; [`BodyOut::triangles_done`] is
    /// called after each batch of faces.
    fn triangles(&mut self) -> &mut Vec<[u32; 3]>;
    fn triangles_done(&mut self) -> Result<(), ImportError>;
}

/// A whole file in memory: one batch of everything.
#[derive(Default)]
pub(crate) struct Gather {
    vertices: Vertices,
    triangles: Option<Vec<[u32; 3]>>,
}

impl BodyOut for Gather {
    fn batch(&self) -> u64 {
        u64::MAX
    }

    fn vertices(&mut self, batch: Vertices) -> Result<(), ImportError> {
        self.vertices = batch;
        Ok(())
    }

    fn triangles(&mut self) -> &mut Vec<[u32; 3]> {
        self.triangles.get_or_insert_with(Vec::new)
    }

    fn triangles_done(&mut self) -> Result<(), ImportError> {
        Ok(())
    }
}

impl Gather {
    pub(crate) fn into_geometry(self, path: &Path) -> Geometry {
        let Vertices {
            positions,
            normals,
            colors,
        } = self.vertices;
        let triangles = self.triangles;
        let normals = normals.and_then(|n| unit_normals(n, &positions, triangles.as_deref()));
        let primitives = match triangles {
            Some(t) => Primitives::Triangles(t),
            None => Primitives::Points,
        };
        let mut geometry = Geometry::new(path.display().to_string(), positions, primitives);
        geometry.normals = normals;
        geometry.colors = colors;
        geometry
    }
}

/// A batch of vertices: positions, and normals and colors where the file
/// has them.
#[derive(Default)]
pub(crate) struct Vertices {
    pub positions: Vec<DVec3>,
    pub normals: Option<Vec<Vec3>>,
    pub colors: Option<Vec<Rgb8>>,
}

/// OBJ's normals, as its faces give them: a table of normals (`vn`), and
/// face corners naming a vertex and a normal. The first corner that names
/// a vertex gives it its normal.
pub(crate) trait CornerNormals {
    /// The next normals of the table, in order.
    fn table(&mut self, normals: &[Vec3]) -> Result<(), ImportError>;
    /// The next corners, in order: (vertex, index into the table), both
    /// counted from the file's first, and in range.
    fn corners(&mut self, corners: &[(u32, u32)]) -> Result<(), ImportError>;
}
