//! Meshes larger than memory, built in chunks as clouds are, with what a
//! mesh needs instead of halos of points:
//!
//! 1. **vertices**: every instance of every mesh is placed and written to
//!    files under the temporary folder, read back through maps by index
//!    ([`vertices`]); the meshes' own memory goes. A PLY file is read as a
//!    stream, a batch of vertices or faces at a time; other files are
//!    read whole by their importers first.
//! 2. **count**: the vertices are counted in the grid's cells, which are
//!    cut into chunks as a cloud's are.
//! 3. **spread**: each triangle goes to the chunk of each of its corners
//!    (once per chunk), in the input's order.
//! 4. **chunks**: a chunk's vertices are sized from its triangles
//!    ([`chunk`]); those on its border see the triangles across it, so
//!    radii, normals and cones are the in-memory build's exactly.
//! 5. The rest is the clouds' ([`super::join`]): the top, each chunk's
//!    levels, the pages. Meshes have no radius cap (their radii are their
//!    triangles'), so no median is taken; leaves of no size get the same
//!    floor.

mod chunk;
#[cfg(test)]
mod tests;
mod vertices;

use std::time::Instant;

use farfield_protocol::sphere_codec::NodeLayout;

use super::grid::{Chunks, Grid};
use super::median::RadiusMedian;
use super::phases::{Sized, SizedEntry, chunk_size};
use super::spread::ChunkFiles;
use super::temp::TempDir;
use super::{Budget, OutOfCoreStats, checkpoint, io_error, join};
use crate::BuildError;
use crate::page_writer::SpilledFile;
use crate::progress::Progress;
use crate::spheres::BuildOptions;

pub(crate) use vertices::{Channels, MeshInput};

/// Builds the triangle meshes of `inputs` in chunks under `temp`.
pub(crate) fn build(
    inputs: Vec<MeshInput>,
    budget: &Budget,
    options: &BuildOptions,
    temp: &TempDir,
    progress: &dyn Progress,
) -> Result<(SpilledFile, OutOfCoreStats), BuildError> {
    let colors = Channels::of(&inputs).colors;
    let (sized, figures) = size(inputs, budget, temp, progress)?;
    let layout = NodeLayout {
        normals: true,
        color: colors,
    };
    let (file, joined) = join::join(sized, layout, options, temp, true, progress)?;
    let mut build = joined.stats(
        file.header.page_count as usize,
        layout,
        figures.seconds_count,
    );
    build.input_primitives = figures.triangles;
    Ok((
        file,
        OutOfCoreStats {
            build,
            chunks: joined.chunks,
            chunk_points: figures.chunk_points,
            halo_points: figures.copies - figures.triangles,
            grid_side: figures.grid_side,
            seconds_count: figures.seconds_count,
            seconds_spread: figures.seconds_spread,
            seconds_chunks: joined.seconds_sizes + joined.seconds_roots,
            seconds_top: joined.seconds_top,
            seconds_levels: joined.seconds_levels,
            seconds_pages: joined.seconds_pages,
        },
    ))
}

/// What the phases before the join learnt, for the build's figures.
pub(crate) struct Figures {
    pub triangles: u64,
    /// Triangles written to chunk files: each once per chunk it touches.
    pub copies: u64,
    pub chunk_points: u64,
    pub grid_side: u32,
    pub seconds_count: f64,
    pub seconds_spread: f64,
}

/// Runs the phases up to the chunks' leaves (written under `temp`).
pub(crate) fn size(
    inputs: Vec<MeshInput>,
    budget: &Budget,
    temp: &TempDir,
    progress: &dyn Progress,
) -> Result<(Sized, Figures), BuildError> {
    let started = Instant::now();
    let channels = Channels::of(&inputs);
    let files = vertices::write(inputs, channels, temp, progress)?;
    if files.vertices == 0 {
        return Err(BuildError::Empty);
    }

    // Count. The bounds were measured as the vertices were written; no
    // cell can hold more than u32::MAX of them, as no mesh can.
    let (spread_buffers, chunk_points) = chunk_size(budget, files.vertices, false);
    let grid = Grid::new(files.bounds, files.vertices, chunk_points);
    let grid_side = grid.side();
    progress.begin("count", files.vertices);
    let mut counts = vec![0u32; grid.cells()];
    for p in files.positions() {
        counts[grid.cell_of(p)] += 1;
    }
    progress.advance(files.vertices);
    let chunks = Chunks::cut(grid, counts, chunk_points);
    let seconds_count = started.elapsed().as_secs_f64();
    checkpoint("count");

    // Spread.
    let started = Instant::now();
    let paths: Vec<_> = (0..chunks.len())
        .map(|c| temp.file(&format!("chunk-{c}.triangles")))
        .collect();
    let buffer = (spread_buffers / chunks.len().max(1) as u64).clamp(4 << 10, 4 << 20);
    let mut out = ChunkFiles::new(paths.clone(), buffer as usize);
    progress.begin("spread", files.triangle_count);
    let mut copies = 0u64;
    files.for_each_triangles(&mut |batch| {
        for t in batch {
            let mut seen = [u32::MAX; 3];
            for (k, &v) in t.iter().enumerate() {
                let c = files
                    .position(v)
                    .map(|p| chunks.place(p).0)
                    .filter(|&c| c != u32::MAX)
                    .ok_or_else(damaged)?;
                if seen[..k].contains(&c) {
                    continue;
                }
                seen[k] = c;
                let buffer = out.buffer(c);
                for corner in t {
                    buffer.extend_from_slice(&corner.to_le_bytes());
                }
                out.written(c).map_err(io_error)?;
                copies += 1;
            }
        }
        progress.advance(batch.len() as u64);
        Ok(())
    })?;
    out.finish().map_err(io_error)?;
    let seconds_spread = started.elapsed().as_secs_f64();
    checkpoint("spread");

    // Each chunk's leaves.
    let started = Instant::now();
    progress.begin("chunks", files.vertices);
    let mut entries = Vec::new();
    for (c, path) in paths.iter().enumerate() {
        if !path.exists() {
            continue;
        }
        let leaves = temp.file(&format!("chunk-{c}.leaves"));
        let (sized, own) = chunk::size_mesh_chunk(path, c as u32, &files, &chunks, &leaves)?;
        if let Some(sized) = sized {
            entries.push(SizedEntry {
                chunk: c,
                sized,
                leaves,
            });
        }
        progress.advance(own);
    }
    let (vertices, triangles) = (files.vertices, files.triangle_count);
    drop(files);
    let sized = Sized {
        entries,
        input_vertices: vertices,
        median: RadiusMedian::new(),
        seconds: started.elapsed().as_secs_f64(),
    };
    let figures = Figures {
        triangles,
        copies,
        chunk_points,
        grid_side,
        seconds_count,
        seconds_spread,
    };
    Ok((sized, figures))
}

fn damaged() -> BuildError {
    BuildError::Invalid(
        "temporary files: a triangle names a vertex that is not there, or one the count did not place".into(),
    )
}
