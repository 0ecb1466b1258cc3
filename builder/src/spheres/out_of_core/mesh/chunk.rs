//! One mesh chunk's leaves, from the triangles that touch it.
//!
//! A vertex's leaf depends only on the triangles around it (QSplat 2.2:
//! the largest of their bounding spheres, their area-weighted normal, the
//! cone over their normals). The spread gives a chunk every triangle with
//! a corner in it, in the input's order, so each of the chunk's own
//! vertices sees all its triangles, those crossing the border too, and its
//! leaf is the in-memory build's, bit for bit. The corners outside the
//! chunk come along as neighbours only and are left out.

use std::fs::File;
use std::path::Path;

use super::super::chunk::{SizedChunk, write_leaves};
use super::super::grid::Chunks;
use super::super::io_error;
use super::vertices::{MeshFiles, read_triangles};
use crate::BuildError;
use crate::import::common::repair_normals;
use crate::progress::Silent;
use crate::scene::{Geometry, Primitives};
use crate::spheres::leaves::local_leaves;
use crate::spheres::measure;

/// Sizes chunk `chunk` from its triangle file (removed once read), writes
/// its own vertices' leaves to `leaves_path`; `None` when no vertex of its
/// own is on a triangle with an area. Also returns its own vertices.
pub(crate) fn size_mesh_chunk(
    triangles_path: &Path,
    chunk: u32,
    files: &MeshFiles,
    chunks: &Chunks,
    leaves_path: &Path,
) -> Result<(Option<SizedChunk>, u64), BuildError> {
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let file = File::open(triangles_path).map_err(io_error)?;
    read_triangles(file, &mut |batch| {
        triangles.extend_from_slice(batch);
        Ok(())
    })?;
    std::fs::remove_file(triangles_path).map_err(io_error)?;
    // The chunk's vertices, in the input's order: a vertex's index here is
    // its rank among them.
    let mut ids: Vec<u32> = triangles.iter().flatten().copied().collect();
    ids.sort_unstable();
    ids.dedup();
    for t in &mut triangles {
        for v in t.iter_mut() {
            // Every corner is in `ids`, which was made from them.
            *v = ids.binary_search(v).unwrap_or_default() as u32;
        }
    }
    let damaged = || BuildError::Invalid("temporary files: a triangle names no vertex".into());
    let positions = ids
        .iter()
        .map(|&i| files.position(i))
        .collect::<Option<Vec<_>>>()
        .ok_or_else(damaged)?;
    let own: Vec<bool> = positions
        .iter()
        .map(|&p| chunks.place(p).0 == chunk)
        .collect();
    let mut geometry = Geometry::new("chunk", positions, Primitives::Triangles(triangles));
    if files.has_colors() {
        geometry.colors = ids.iter().map(|&i| files.color(i)).collect();
    }
    if files.has_normals() {
        let mut normals: Vec<_> = ids
            .iter()
            .map(|&i| files.normal(i))
            .collect::<Option<_>>()
            .ok_or_else(damaged)?;
        // A streamed file's unusable normals, repaired as its importer
        // repairs them, from every triangle around their vertices.
        if let Primitives::Triangles(triangles) = &geometry.primitives {
            repair_normals(&mut normals, &geometry.positions, triangles);
        }
        geometry.normals = Some(normals);
    }
    drop(ids);
    let own_vertices = own.iter().filter(|&&o| o).count() as u64;
    let (mut leaves, _) = local_leaves(geometry, files.has_colors(), &Silent);
    leaves.retain(|l| own[l.source as usize]);
    if leaves.is_empty() {
        return Ok((None, own_vertices));
    }
    let measured = measure(&leaves);
    write_leaves(leaves_path, &leaves).map_err(io_error)?;
    let sized = SizedChunk {
        points: leaves.len() as u64,
        bounds: measured.bounds,
        smallest_radius: measured.smallest_radius,
    };
    Ok((Some(sized), own_vertices))
}
