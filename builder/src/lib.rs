//! farfield-builder: an input file in, a paged hierarchy out, in memory.
//!
//! Data flows one way: [`import`] (OBJ, PLY, OFF, LAS/LAZ, PDB and the
//! `gen:` generators) produces a [`scene::Scene`] (geometries in f64,
//! placed by instances; no file format beyond this point); a builder turns
//! the scene into a [`PagedFile`] (header and page bytes); writing it to
//! disk is `farfield-store`'s job. One folder per hierarchy kind:
//! [`spheres`] (QSplat), [`cubes`] (the color-cube octree), [`plp`] (PLP's
//! tessellation), [`bsp`] (image caching's BSP); [`kinds`] lists them, and
//! each hands its pages to the one [`page_writer`]. [`generate`] makes the
//! built-in scenes (`gen:NAME`) and their camera paths. [`allocator`] is
//! the allocator the binaries that build use (huge pages for the large
//! arrays).

pub mod allocator;
pub mod bsp;
pub mod import;
pub mod scene;

pub mod cubes;
pub mod generate;
pub mod kinds;
pub mod page_writer;
pub mod plp;
pub mod progress;
pub mod spheres;
pub mod zero_area;

pub use farfield_protocol::paged_file::PagedFile;
pub use progress::{Progress, Silent};
/// Sphere builds bounded by a memory budget, under their kind's module
/// since only spheres are built so; here for the command line's sake.
pub use spheres::out_of_core;
pub use spheres::{
    BuildOptions, BuildStats, DEFAULT_PAGE_BYTES, build_spheres, build_spheres_reporting,
};

/// Why a scene could not be built.
#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    /// Nothing to build: no points, no spheres, and no triangle with an
    /// area (a mesh of zero-area faces alone has no surface).
    #[error("the scene has nothing to build from: no points, spheres or triangles with an area")]
    Empty,
    #[error("the scene has {0} vertices; this format holds at most 2^31 - 1 leaves")]
    TooLarge(u64),
    #[error("{0}")]
    Invalid(String),
    /// A page the format cannot hold (a body over its size limit).
    #[error(transparent)]
    Format(#[from] farfield_protocol::FormatError),
}

/// The triangles of a `side` x `side` grid of vertices numbered row by row,
/// each square cut in two along the same diagonal, for tests.
#[cfg(test)]
pub(crate) fn grid_triangles(side: u32) -> Vec<[u32; 3]> {
    let mut triangles = Vec::new();
    for v in 0..side - 1 {
        for u in 0..side - 1 {
            let i = v * side + u;
            triangles.push([i, i + 1, i + side]);
            triangles.push([i + 1, i + side + 1, i + side]);
        }
    }
    triangles
}

/// A deterministic source of numbers in [0, 1) for tests (xorshift64).
#[cfg(test)]
pub(crate) fn test_random(seed: u64) -> impl FnMut() -> f64 {
    let mut x = seed;
    move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        (x >> 11) as f64 / (1u64 << 53) as f64
    }
}
