//! The image-caching BSP builder (Shade et al., *Hierarchical Image
//! Caching*, section 4): a [`Scene`] in, a paged file of hierarchy kind
//! `bsp` out.
//!
//! - [`objects`]: prototypes (geometries placed more than once, stored
//!   once) and their placements; every other placement a mesh of world
//!   triangles.
//! - [`gaps`]: sorted sweeps along a direction, gaps at local minima of the
//!   active count, and the cost of a gap (written down there).
//! - [`split`]: the recursion; crossed meshes divided, crossed instances
//!   kept whole; the median fallback.
//! - [`inflate`]: each leaf's geometry inside its region grown by 17 %.
//! - [`pages`]: the tree in page 0, a page per prototype, a page per leaf.

pub mod gaps;
pub mod inflate;
pub mod objects;
pub mod pages;
pub mod split;

use std::time::Instant;

use glam::DVec3;

use super::{BuildError, PagedFile};
use crate::scene::Scene;
use split::{SplitCounts, StopRule};

/// Knobs of a BSP build.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct BspOptions {
    /// Splitting directions, evenly dividing the circle around `up` (the
    /// paper's landscapes: 2, so every region is an axis-aligned box).
    pub directions: u32,
    /// The up axis the directions turn around (the generated scenes: +Z).
    #[serde(serialize_with = "as_array")]
    pub up: DVec3,
    /// A leaf's region is grown by this fraction for its geometry (0.17).
    pub inflation: f64,
    /// A node with at most this many instances and at most
    /// `leaf_triangles` mesh triangles is a leaf (the paper: most leaves
    /// hold one tree and a piece of the terrain).
    pub leaf_instances: usize,
    pub leaf_triangles: u64,
    pub max_depth: u32,
}

impl Default for BspOptions {
    fn default() -> Self {
        Self {
            directions: 2,
            up: DVec3::Z,
            inflation: 0.17,
            leaf_instances: 1,
            leaf_triangles: 4096,
            max_depth: 48,
        }
    }
}

fn as_array<S: serde::Serializer>(v: &DVec3, s: S) -> Result<S::Ok, S::Error> {
    serde::Serialize::serialize(&v.to_array(), s)
}

/// What a BSP build did.
#[derive(Debug, Clone, serde::Serialize)]
pub struct BspStats {
    /// Triangles of the scene, instances expanded.
    pub triangles: u64,
    pub mesh_triangles: u64,
    pub prototypes: usize,
    pub placements: usize,
    pub nodes: usize,
    pub leaves: usize,
    pub split: SplitCounts,
    /// Mesh triangles stored over all leaves per mesh triangle (inflation).
    pub stored_per_mesh_triangle: f64,
    /// Placements stored over all leaves per placement.
    pub stored_per_placement: f64,
    pub pages: usize,
    pub skeleton_bytes: u64,
    pub file_bytes: u64,
    /// What the leaves' geometry would take with every instance expanded
    /// and no inflation (40 bytes a triangle): the paper compares its
    /// storage with that.
    pub expanded_bytes: u64,
    pub options: BspOptions,
    pub seconds_collect: f64,
    pub seconds_split: f64,
    pub seconds_inflate: f64,
    pub seconds_layout: f64,
}

/// `n` unit directions evenly dividing the half circle around `up` (a
/// plane's normal and its opposite are the same plane).
pub fn directions(n: u32, up: DVec3) -> Result<Vec<DVec3>, BuildError> {
    let up = up
        .try_normalize()
        .ok_or_else(|| BuildError::Invalid("the up axis is not a direction".into()))?;
    if n == 0 || n as usize > farfield_protocol::bsp_codec::MAX_DIRECTIONS {
        return Err(BuildError::Invalid(format!(
            "{n} directions (1 to {})",
            farfield_protocol::bsp_codec::MAX_DIRECTIONS
        )));
    }
    let (e1, e2) = up.any_orthonormal_pair();
    // Around a coordinate axis, start on the next axis, so 2 directions
    // are two coordinate axes and every region an axis-aligned box.
    let (e1, e2) = if up.abs() == DVec3::Z {
        (DVec3::X, up.cross(DVec3::X))
    } else if up.abs() == DVec3::Y {
        (DVec3::Z, up.cross(DVec3::Z))
    } else if up.abs() == DVec3::X {
        (DVec3::Y, up.cross(DVec3::Y))
    } else {
        (e1, e2)
    };
    Ok((0..n)
        .map(|k| {
            let a = std::f64::consts::PI * f64::from(k) / f64::from(n);
            let (s, c) = a.sin_cos();
            // Exact zeros on the axes.
            let snap = |v: f64| if v.abs() < 1e-15 { 0.0 } else { v };
            (e1 * snap(c) + e2 * snap(s)).normalize()
        })
        .collect())
}

/// Builds the image-caching BSP of a scene.
pub fn build_bsp(scene: &Scene, options: &BspOptions) -> Result<(PagedFile, BspStats), BuildError> {
    if !(options.inflation.is_finite() && (0.0..=4.0).contains(&options.inflation)) {
        return Err(BuildError::Invalid(format!(
            "inflation {} is not in [0, 4]",
            options.inflation
        )));
    }
    if options.leaf_triangles == 0 {
        return Err(BuildError::Invalid(
            "leaf triangles must be at least 1".into(),
        ));
    }
    let dirs = directions(options.directions, options.up)?;
    let started = Instant::now();
    let collected = objects::collect(scene)?;
    if collected.objects.is_empty() {
        return Err(BuildError::Empty);
    }
    let seconds_collect = started.elapsed().as_secs_f64();
    let started = Instant::now();
    let tree = split::split(
        &collected,
        &dirs,
        StopRule {
            leaf_instances: options.leaf_instances,
            leaf_triangles: options.leaf_triangles,
            max_depth: options.max_depth.min(200),
        },
    );
    let seconds_split = started.elapsed().as_secs_f64();
    let started = Instant::now();
    let inflated = inflate::inflate(&collected, &dirs, &tree.leaves, options.inflation);
    let seconds_inflate = started.elapsed().as_secs_f64();
    let started = Instant::now();
    let laid = pages::lay_out(
        &collected,
        &dirs,
        &tree,
        &inflated,
        &pages::LayoutInfo {
            input_vertices: scene.instanced_vertex_count(),
            inflation: options.inflation as f32,
        },
    )?;
    let mesh = collected.mesh.corners.len() as u64;
    let ratio = |a: u64, b: u64| if b > 0 { a as f64 / b as f64 } else { 0.0 };
    let stats = BspStats {
        triangles: laid.scene_triangles,
        mesh_triangles: mesh,
        prototypes: collected.prototypes.len(),
        placements: collected.placements.len(),
        nodes: tree.nodes.len(),
        leaves: tree.leaves.len(),
        split: tree.counts,
        stored_per_mesh_triangle: ratio(laid.stored_triangles, mesh),
        stored_per_placement: ratio(laid.stored_placements, collected.placements.len() as u64),
        pages: laid.file.pages.len(),
        skeleton_bytes: laid.file.pages.first().map_or(0, |p| p.len() as u64),
        file_bytes: laid.file.directory.file_len(),
        expanded_bytes: laid.scene_triangles * farfield_protocol::bsp_codec::TRIANGLE_BYTES as u64,
        options: *options,
        seconds_collect,
        seconds_split,
        seconds_inflate,
        seconds_layout: started.elapsed().as_secs_f64(),
    };
    Ok((laid.file, stats))
}

#[cfg(test)]
#[path = "tests.rs"]
mod tests;
