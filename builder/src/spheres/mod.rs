//! The sphere (QSplat) builder, in three steps, one module each:
//! [`leaves`] (a sized, oriented sphere per vertex; [`knn`] for point
//! clouds), [`tree`] (bisection into a 2-to-4-ary bounding-sphere tree),
//! [`layout`] (top-down quantization and breadth-first pages). Each step
//! reports how far it has got through [`Progress`].

pub mod knn;
pub mod layout;
pub mod leaves;
pub mod out_of_core;
pub(crate) mod page_cutter;
pub mod tree;

use std::time::Instant;

use farfield_protocol::paged_file::PagedFile;
use farfield_protocol::sphere_codec::NodeLayout;
use glam::DVec3;
use rayon::prelude::*;

use crate::BuildError;
use crate::progress::{Progress, Silent};
use crate::scene::Scene;

/// Default upper bound on a page's size: 16 KiB holds about 4000 nodes,
/// small enough to stream in well under a millisecond on loopback and
/// large enough that per-page headers cost under 0.01 bytes per node.
pub const DEFAULT_PAGE_BYTES: usize = 16 * 1024;

/// Asks the CPU to load the cache lines holding the `T` at `at`: its
/// first and its last byte, as a leaf or node may straddle two lines (a
/// hint: it never faults, whatever the address). The layout visits nodes
/// scattered over hundreds of megabytes, a level at a time; asking for a
/// batch of them before using any overlaps their memory latencies.
#[inline(always)]
pub(crate) fn prefetch<T>(at: *const T) {
    let last = at
        .cast::<u8>()
        .wrapping_add(size_of::<T>().saturating_sub(1));
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch is a hint with no architectural effect; it does not
    // dereference the pointer in the language's sense.
    unsafe {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        _mm_prefetch(at.cast::<i8>(), _MM_HINT_T0);
        _mm_prefetch(last.cast::<i8>(), _MM_HINT_T0);
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (at, last);
}

/// Knobs of a build.
#[derive(Debug, Clone, Copy)]
pub struct BuildOptions {
    pub page_bytes: usize,
    /// Keep (source vertex, node) pairs in [`PagedFile::leaf_sources`]; for
    /// tests that follow vertices into the file.
    pub record_leaf_sources: bool,
}

impl Default for BuildOptions {
    fn default() -> Self {
        Self {
            page_bytes: DEFAULT_PAGE_BYTES,
            record_leaf_sources: false,
        }
    }
}

/// What a build did, for `--json` summaries and benchmarks.
#[derive(Debug, Clone, serde::Serialize)]
pub struct BuildStats {
    pub input_vertices: u64,
    pub input_primitives: u64,
    pub unreferenced_vertices: u64,
    pub collapsed_duplicates: u64,
    pub leaves: u64,
    pub nodes: u64,
    pub levels: u32,
    pub pages: usize,
    pub has_color: bool,
    pub has_normals: bool,
    pub seconds_leaves: f64,
    pub seconds_tree: f64,
    pub seconds_layout: f64,
}

/// Builds the QSplat sphere hierarchy of a scene, consuming it (each
/// geometry is freed as soon as its leaves exist).
pub fn build_spheres(
    scene: Scene,
    options: &BuildOptions,
) -> Result<(PagedFile, BuildStats), BuildError> {
    build_spheres_reporting(scene, options, &Silent)
}

/// [`build_spheres`], telling `progress` how far each step has got.
pub fn build_spheres_reporting(
    scene: Scene,
    options: &BuildOptions,
    progress: &dyn Progress,
) -> Result<(PagedFile, BuildStats), BuildError> {
    let layout = NodeLayout {
        normals: scene.has_orientation(),
        color: scene.has_color(),
    };
    let input_primitives = scene.instanced_primitive_count();
    let vertices = scene.instanced_vertex_count();
    if vertices == 0 {
        return Err(BuildError::Empty);
    }
    if vertices >= 1 << 31 {
        return Err(BuildError::TooLarge(vertices));
    }
    let started = Instant::now();
    let (mut leaf_list, leaf_stats) = leaves::make_leaves(scene, layout.color, progress);
    if leaf_list.is_empty() {
        return Err(BuildError::Empty);
    }
    let measured = measure(&leaf_list);
    let (bounds_min, bounds_max) = measured.bounds;
    apply_radius_floor(&mut leaf_list, &measured);
    let seconds_leaves = started.elapsed().as_secs_f64();

    let started = Instant::now();
    let tree = tree::build_tree_within(leaf_list, measured.bounds, progress);
    let collapsed_duplicates = tree.collapsed_duplicates;
    let seconds_tree = started.elapsed().as_secs_f64();

    let started = Instant::now();
    let file = layout::lay_out(
        tree,
        layout::LayoutInput {
            layout,
            page_bytes: options.page_bytes,
            input_vertices: leaf_stats.input_vertices,
            bounds_min,
            bounds_max,
            record_leaf_sources: options.record_leaf_sources,
        },
        progress,
    )?;
    let seconds_layout = started.elapsed().as_secs_f64();
    let stats = BuildStats {
        input_vertices: leaf_stats.input_vertices,
        input_primitives,
        unreferenced_vertices: leaf_stats.unreferenced_vertices,
        collapsed_duplicates,
        leaves: file.header.leaves,
        nodes: file.header.nodes,
        levels: file.header.levels,
        pages: file.pages.len(),
        has_color: layout.color,
        has_normals: layout.normals,
        seconds_leaves,
        seconds_tree,
        seconds_layout,
    };
    Ok((file, stats))
}

/// What one pass over the leaves learns: their bounds, their smallest
/// positive radius, and whether any radius needs the floor.
pub(crate) struct Measured {
    pub bounds: tree::Bounds,
    pub smallest_radius: f32,
    pub needs_floor: bool,
}

/// Measures the leaves on all threads in one pass.
pub(crate) fn measure(leaves: &[leaves::Leaf]) -> Measured {
    let empty = || Measured {
        bounds: (DVec3::INFINITY, DVec3::NEG_INFINITY),
        smallest_radius: f32::INFINITY,
        needs_floor: false,
    };
    leaves
        .par_chunks(1 << 16)
        .map(|chunk| {
            let mut m = empty();
            for l in chunk {
                m.bounds = (m.bounds.0.min(l.position), m.bounds.1.max(l.position));
                if l.radius > 0.0 {
                    m.smallest_radius = m.smallest_radius.min(l.radius);
                } else {
                    // Zero, negative or NaN.
                    m.needs_floor = true;
                }
            }
            m
        })
        .reduce(empty, |a, b| Measured {
            bounds: (a.bounds.0.min(b.bounds.0), a.bounds.1.max(b.bounds.1)),
            smallest_radius: a.smallest_radius.min(b.smallest_radius),
            needs_floor: a.needs_floor || b.needs_floor,
        })
}

/// Leaves of zero size (a lone point, a collapsed degenerate triangle) get
/// the smallest radius another leaf has, else a millionth of the scene's
/// extent, else 1 when the scene is a single point: a splat needs a size,
/// and the quantizer a positive scale.
pub(crate) fn apply_radius_floor(leaves: &mut [leaves::Leaf], measured: &Measured) {
    if !measured.needs_floor {
        return;
    }
    let floor = radius_floor(measured.smallest_radius, measured.bounds);
    for l in leaves.iter_mut() {
        if l.radius.is_nan() || l.radius <= 0.0 {
            l.radius = floor;
        }
    }
}

/// The radius a leaf of zero size gets, from the smallest positive radius
/// of the scene's leaves (infinite when none has one) and their bounds.
pub(crate) fn radius_floor(smallest_radius: f32, bounds: tree::Bounds) -> f32 {
    let diameter = (bounds.1 - bounds.0).length();
    if smallest_radius.is_finite() {
        smallest_radius
    } else if diameter > 0.0 {
        leaves::round_up_f32(diameter * 1e-6)
    } else {
        1.0
    }
}
