//! The color-cube octree builder (Chamberlain et al. 1995 and 1996): a
//! [`Scene`] in, a paged file of hierarchy kind `cubes` out.
//!
//! - [`source`]: the scene's triangles and spheres as references with world
//!   bounds and costs (instances are never copied).
//! - [`octree`]: the adaptive subdivision, leaves and post-order cubes.
//! - [`clip`]: a triangle clipped to a cell; [`raster`]: a leaf's six faces
//!   rendered orthographically into premultiplied RGBA.
//! - [`composite`]: interior cubes from the children, front over back then
//!   averaged (the 1995 disjoint variant or the 1996 over).
//! - [`pages`]: breadth-first order, records and payloads cut into pages.

pub mod clip;
pub mod composite;
pub mod octree;
pub mod pages;
pub mod raster;
pub mod source;

use std::time::Instant;

use farfield_protocol::cube_codec::{self, Channels};
use farfield_protocol::file::AttributeFlags;
use glam::DVec3;

pub use composite::Composite;

use super::{BuildError, PagedFile};
use crate::scene::Scene;

/// Default page size for cubes: leaf geometry makes cells larger than
/// sphere nodes, so pages are larger too.
pub const DEFAULT_CUBE_PAGE_BYTES: usize = 64 * 1024;

/// Knobs of a cube build.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct CubeOptions {
    /// Samples per cube-face edge (16 = the papers' 4 x 4 image, each pixel
    /// antialiased by 4 x 4 samples).
    pub samples: usize,
    /// k for k x k x k cubes per cell (1995, section 4.2); 1 = none.
    pub cluster: u8,
    /// Deepest level a cell may have (the root is level 0).
    pub max_depth: u32,
    pub composite: Composite,
    /// What one cube costs to draw, in triangles: a cell splits while its
    /// primitives cost more than its children's cubes. Larger values make
    /// larger leaves (fewer cells, more triangles each).
    pub cube_cost: f64,
    pub page_bytes: usize,
}

impl Default for CubeOptions {
    fn default() -> Self {
        Self {
            samples: 16,
            cluster: 1,
            max_depth: 32,
            composite: Composite::Disjoint,
            cube_cost: octree::CUBE_COST,
            page_bytes: DEFAULT_CUBE_PAGE_BYTES,
        }
    }
}

/// What a cube build did.
#[derive(Debug, Clone, serde::Serialize)]
pub struct CubeStats {
    pub input_vertices: u64,
    pub input_primitives: u64,
    pub nodes: u64,
    pub leaves: u64,
    pub levels: u32,
    pub pages: usize,
    /// Triangles stored in leaves (after clipping to cells).
    pub leaf_triangles: u64,
    pub has_color: bool,
    pub has_normals: bool,
    pub options: CubeOptions,
    pub seconds_octree: f64,
    pub seconds_layout: f64,
}

/// Builds the color-cube octree of a scene.
pub fn build_cubes(
    scene: Scene,
    options: &CubeOptions,
) -> Result<(PagedFile, CubeStats), BuildError> {
    if !cube_codec::valid_cluster(options.cluster) {
        return Err(BuildError::Invalid(format!(
            "cluster size {} is not a power of two from 1 to {}",
            options.cluster,
            cube_codec::MAX_CLUSTER
        )));
    }
    if !(options.cube_cost.is_finite() && options.cube_cost > 0.0) {
        return Err(BuildError::Invalid(format!(
            "cube cost {} is not a positive number",
            options.cube_cost
        )));
    }
    if options.samples == 0 || options.samples > 256 {
        return Err(BuildError::Invalid(format!(
            "{} samples per face edge is outside 1..=256",
            options.samples
        )));
    }
    let src = source::Source::new(&scene).map_err(BuildError::Invalid)?;
    let started = Instant::now();
    let refs = src.refs();
    if refs.is_empty() {
        return Err(BuildError::Empty);
    }
    let (lo, hi) = refs
        .iter()
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), r| {
            (lo.min(r.min), hi.max(r.max))
        });
    // The root cube: the bounds' longest side, a hair larger so nothing
    // lies exactly on its far faces; a scene that is one point gets a unit
    // cube (the quantizer needs a positive edge).
    let extent = (hi - lo).max_element();
    let edge = if extent > 0.0 {
        extent * (1.0 + 1e-9)
    } else {
        1.0
    };
    let center = (lo + hi) * 0.5;
    let root_min = center - DVec3::splat(edge * 0.5);
    let channels = Channels {
        normals: src.has_normals(),
        color: src.has_color(),
    };
    let settings = octree::Settings {
        cluster: usize::from(options.cluster),
        samples: options.samples,
        max_depth: options.max_depth,
        composite: options.composite,
        cube_cost: options.cube_cost,
        channels,
        root_min,
    };
    // Counted from the scene: zero-area triangles have no reference.
    let input_primitives = scene.instanced_primitive_count();
    let root =
        octree::build_cell(&src, refs, root_min, edge, 0, &settings).ok_or(BuildError::Empty)?;
    let seconds_octree = started.elapsed().as_secs_f64();
    let started = Instant::now();
    let leaf_triangles = count_triangles(&root);
    let file = pages::lay_out(
        &root,
        pages::LayoutInfo {
            page_bytes: options.page_bytes,
            cluster: options.cluster,
            attributes: AttributeFlags {
                color: channels.color,
                normals: channels.normals,
                leaf_geometry: true,
            },
            input_vertices: scene.instanced_vertex_count(),
            bounds_min: lo,
            bounds_max: hi,
            root_center: center,
            root_half_edge: edge * 0.5,
        },
    )?;
    let stats = CubeStats {
        input_vertices: scene.instanced_vertex_count(),
        input_primitives,
        nodes: file.header.nodes,
        leaves: file.header.leaves,
        levels: file.header.levels,
        pages: file.pages.len(),
        leaf_triangles,
        has_color: channels.color,
        has_normals: channels.normals,
        options: *options,
        seconds_octree,
        seconds_layout: started.elapsed().as_secs_f64(),
    };
    Ok((file, stats))
}

fn count_triangles(cell: &octree::Cell) -> u64 {
    cell.geometry
        .as_ref()
        .map_or(0, |g| g.triangles.len() as u64)
        + cell.children.iter().map(count_triangles).sum::<u64>()
}
