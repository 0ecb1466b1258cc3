//! The phases after the chunks are sized, which need only their leaves:
//! the radius fix (the whole cloud's median and floor), each chunk's root,
//! the **top**, each chunk's **levels**, and the **pages**. A whole build
//! runs them on its own chunks; a merge, on the chunks of its parts.

use std::time::Instant;

use glam::DVec3;

use super::chunk::{self, RadiusFix};
use super::phases::Sized;
use super::temp::TempDir;
use super::{checkpoint, io_error, merge, top};
use crate::BuildError;
use crate::page_writer::{SpillError, SpilledFile};
use crate::progress::Progress;
use crate::spheres::BuildOptions;
use farfield_protocol::file::{AttributeFlags, FileHeader, HierarchyKind};
use farfield_protocol::sphere_codec::NodeLayout;

/// What the join made, for the build's figures.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Joined {
    pub chunks: usize,
    /// Leaves before duplicates collapse: points, or vertices on a
    /// triangle with an area.
    pub points: u64,
    pub input_vertices: u64,
    pub nodes: u64,
    pub leaves: u64,
    pub levels: u32,
    pub collapsed: u64,
    pub seconds_sizes: f64,
    pub seconds_roots: f64,
    pub seconds_top: f64,
    pub seconds_levels: f64,
    pub seconds_pages: f64,
}

impl Joined {
    /// The build's figures, as the in-memory build reports them;
    /// `seconds_before` is what came before the join (the count).
    pub(crate) fn stats(
        &self,
        pages: usize,
        layout: NodeLayout,
        seconds_before: f64,
    ) -> crate::BuildStats {
        crate::BuildStats {
            input_vertices: self.input_vertices,
            input_primitives: self.points,
            unreferenced_vertices: self.input_vertices.saturating_sub(self.points),
            collapsed_duplicates: self.collapsed,
            leaves: self.leaves,
            nodes: self.nodes,
            levels: self.levels,
            pages,
            has_color: layout.color,
            has_normals: layout.normals,
            seconds_leaves: seconds_before + self.seconds_sizes + self.seconds_roots,
            seconds_tree: self.seconds_top,
            seconds_layout: self.seconds_levels + self.seconds_pages,
        }
    }
}

/// Builds the file from sized chunks (in chunk order). Level files and
/// the pages go under `temp`; the leaves and radii files are removed as
/// they are used when `own_files` (a merge leaves its parts as they are).
pub(crate) fn join(
    sized: Sized,
    layout: NodeLayout,
    options: &BuildOptions,
    temp: &TempDir,
    own_files: bool,
    progress: &dyn Progress,
) -> Result<(SpilledFile, Joined), BuildError> {
    let Sized {
        mut entries,
        input_vertices,
        median,
        seconds: seconds_sizes,
    } = sized;
    if entries.is_empty() {
        return Err(BuildError::Empty);
    }
    entries.sort_by_key(|e| e.chunk);
    let points: u64 = entries.iter().map(|e| e.sized.points).sum();

    // The cloud's radii are capped and floored as the in-memory build
    // does, by the whole cloud's median and smallest radius.
    let started = Instant::now();
    let sizes: Vec<_> = entries.iter().map(|e| e.sized).collect();
    let fix = RadiusFix::new(median.median(own_files).map_err(io_error)?, &sizes);
    let mut roots = Vec::with_capacity(entries.len());
    for e in &entries {
        roots.push(chunk::chunk_root(&e.leaves, &fix).map_err(io_error)?);
    }
    let seconds_roots = started.elapsed().as_secs_f64();
    checkpoint("chunks");

    // The levels above the chunks.
    let started = Instant::now();
    let top = top::lay_out_top(&roots, layout);
    let seconds_top = started.elapsed().as_secs_f64();
    checkpoint("top");

    // Each chunk's levels, below its quantized root.
    let started = Instant::now();
    progress.begin("levels", points);
    let mut levels = Vec::with_capacity(entries.len());
    let (mut nodes_in_chunks, mut leaves) = (0u64, 0u64);
    for (r, e) in entries.iter().enumerate() {
        let (files, placed) = chunk::lay_out_chunk(
            &e.leaves,
            own_files,
            &fix,
            top.chunk_spheres[r],
            layout,
            temp.file(&format!("chunk-{}.groups", e.chunk)),
            temp.file(&format!("chunk-{}.records", e.chunk)),
        )
        .map_err(io_error)?;
        nodes_in_chunks += placed.nodes;
        leaves += placed.leaves;
        levels.push(Some(files));
        progress.advance(e.sized.points);
    }
    let seconds_levels = started.elapsed().as_secs_f64();
    checkpoint("levels");

    // Pages.
    let started = Instant::now();
    let top_nodes = top
        .groups
        .iter()
        .map(|g| g.members.len() as u64)
        .sum::<u64>()
        - roots.len() as u64;
    progress.begin("pages", top_nodes + nodes_in_chunks);
    let node_bytes = layout.bytes() as usize;
    let merged = merge::merge(
        &top,
        &levels,
        node_bytes,
        options.page_bytes,
        &temp.file("pages"),
        progress,
    )
    .map_err(io_error)?;
    debug_assert_eq!(merged.nodes, top_nodes + nodes_in_chunks);
    let bounds = sizes
        .iter()
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), s| {
            (lo.min(s.bounds.0), hi.max(s.bounds.1))
        });
    let (root_center, root_radius) = top.header_sphere;
    let file = merged
        .pages
        .finish_spilled(FileHeader {
            cluster: 0,
            kind: HierarchyKind::Spheres,
            attributes: AttributeFlags {
                color: layout.color,
                normals: layout.normals,
                leaf_geometry: false,
            },
            node_bytes: node_bytes as u32,
            levels: merged.levels,
            nodes: merged.nodes,
            leaves,
            input_vertices,
            bounds_min: bounds.0,
            bounds_max: bounds.1,
            root_center,
            root_radius,
            page_count: 0,
            directory_pages: 0,
            root_directory: Default::default(),
        })
        .map_err(|e| match e {
            SpillError::Format(e) => BuildError::Format(e),
            SpillError::Io(e) => io_error(e),
        })?;
    let seconds_pages = started.elapsed().as_secs_f64();
    checkpoint("pages");
    let joined = Joined {
        chunks: entries.len(),
        points,
        input_vertices,
        nodes: merged.nodes,
        leaves,
        levels: merged.levels,
        collapsed: roots.iter().map(|r| r.collapsed).sum(),
        seconds_sizes,
        seconds_roots,
        seconds_top,
        seconds_levels,
        seconds_pages,
    };
    Ok((file, joined))
}
