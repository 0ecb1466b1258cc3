//! The adaptive octree (Chamberlain et al. 1996, section 4): a cell is
//! split while drawing its primitives costs more than drawing its
//! children's color-cubes. A primitive's cost (its triangles) is divided
//! among the cells of the cell's level that its bounding box overlaps;
//! empty cells are never made. Leaves render their cubes from their
//! primitives clipped to the cell and keep their geometry (see [`leaf`]);
//! interior cubes are composited from the children's, post-order.
//!
//! Recursion is bounded by `max_depth` (so all primitives at one point
//! stop there), and cells are handed to other threads near the top.

use std::collections::HashMap;

use farfield_protocol::cube_codec::{Channels, LeafGeometry, child_min, quantize_in_cell};
use farfield_protocol::octahedral::pack_normal;
use glam::DVec3;

use super::clip::clip_to_box;
use super::composite::{Composite, Faces, SubCubes, combine, combine_clusters};
use super::raster::leaf_cubes;
use super::source::{PrimRef, Source, Triangle};

/// What drawing one color-cube costs, in triangles, by default: at most
/// three quads of two triangles.
pub const CUBE_COST: f64 = 6.0;
/// A split may at most multiply a cell's references by this.
const MAX_DUPLICATION: usize = 4;
/// Primitive references above which a cell's children are built in parallel.
const PARALLEL_REFS: usize = 4096;

/// One built cell.
#[derive(Debug, Clone)]
pub struct Cell {
    /// Children in octant order; `mask` says which octants they fill.
    pub children: Vec<Cell>,
    pub mask: u8,
    pub faces: Faces,
    /// The cell's cluster when `k > 1` (empty otherwise).
    pub sub: SubCubes,
    /// A leaf's clipped, quantized triangles.
    pub geometry: Option<LeafGeometry>,
}

/// Build settings shared by every cell.
#[derive(Debug, Clone, Copy)]
pub struct Settings {
    pub cluster: usize,
    pub samples: usize,
    pub max_depth: u32,
    pub composite: Composite,
    /// Cost of drawing one cube, in triangles ([`CUBE_COST`]).
    pub cube_cost: f64,
    pub channels: Channels,
    /// The root cell's minimum corner (cost splitting counts cells on the
    /// grid anchored there).
    pub root_min: DVec3,
}

/// Builds the cell `[min, min + edge]` at `level` over `refs`; `None` when
/// no primitive is in it.
pub fn build_cell(
    src: &Source,
    refs: Vec<PrimRef>,
    min: DVec3,
    edge: f64,
    level: u32,
    s: &Settings,
) -> Option<Cell> {
    if refs.is_empty() {
        return None;
    }
    let cost: f64 = refs
        .iter()
        .map(|r| src.cost(r) / overlapped_cells(r, s.root_min, edge))
        .sum();
    let parts = if level < s.max_depth && cost > s.cube_cost {
        partition(&refs, min, edge)
    } else {
        Default::default()
    };
    let occupied = parts.iter().filter(|p| !p.is_empty()).count();
    // Split while the primitives cost more than the children's cubes, and
    // only while splitting separates them: when the children would hold
    // more than MAX_DUPLICATION times the references (primitives all at one
    // point, or all spanning the cell) every level would multiply the work.
    let references: usize = parts.iter().map(Vec::len).sum();
    let split = occupied > 0
        && cost > s.cube_cost * occupied as f64
        && references <= MAX_DUPLICATION * refs.len();
    if !split {
        return Some(leaf(src, &refs, min, edge, s));
    }
    drop(refs);
    let half = edge * 0.5;
    let build_child = |(o, part): (usize, Vec<PrimRef>)| {
        build_cell(src, part, child_min(min, edge, o as u8), half, level + 1, s)
    };
    let parallel = parts.iter().map(Vec::len).sum::<usize>() > PARALLEL_REFS;
    let built: Vec<Option<Cell>> = if parallel {
        use rayon::prelude::*;
        parts.into_par_iter().enumerate().map(build_child).collect()
    } else {
        parts.into_iter().enumerate().map(build_child).collect()
    };
    let eight: [Option<&Faces>; 8] = std::array::from_fn(|o| built[o].as_ref().map(|c| &c.faces));
    let faces = combine(&eight, s.composite);
    let sub = if s.cluster > 1 {
        let clusters: [Option<&SubCubes>; 8] =
            std::array::from_fn(|o| built[o].as_ref().map(|c| &c.sub));
        combine_clusters(&clusters, s.cluster, s.composite)
    } else {
        Vec::new()
    };
    let mask = built
        .iter()
        .enumerate()
        .fold(0u8, |m, (o, c)| m | (u8::from(c.is_some()) << o));
    Some(Cell {
        children: built.into_iter().flatten().collect(),
        mask,
        faces,
        sub,
        geometry: None,
    })
}

/// How many cells of edge `edge` (on the grid from `root_min`) a
/// primitive's bounding box overlaps: its cost is shared among them.
fn overlapped_cells(r: &PrimRef, root_min: DVec3, edge: f64) -> f64 {
    (0..3)
        .map(|a| {
            let lo = ((r.min[a] - root_min[a]) / edge).floor();
            let hi = ((r.max[a] - root_min[a]) / edge).floor();
            (hi - lo + 1.0).max(1.0)
        })
        .product()
}

/// The references overlapping each child octant (closed boxes).
fn partition(refs: &[PrimRef], min: DVec3, edge: f64) -> [Vec<PrimRef>; 8] {
    let mid = min + DVec3::splat(edge * 0.5);
    let mut parts: [Vec<PrimRef>; 8] = Default::default();
    for r in refs {
        let sides = |a: usize| -> [bool; 2] { [r.min[a] <= mid[a], r.max[a] >= mid[a]] };
        let (x, y, z) = (sides(0), sides(1), sides(2));
        for (o, part) in parts.iter_mut().enumerate() {
            if x[o & 1] && y[(o >> 1) & 1] && z[(o >> 2) & 1] {
                part.push(*r);
            }
        }
    }
    parts
}

/// A leaf: its cubes rendered from the primitives clipped to the cell, and
/// its geometry: whole the triangles it owns (those whose bounding-box
/// center it holds, small enough to fit the cell grown by half an edge),
/// clipped to the cell the ones too large for that. Each small triangle is
/// then stored once, not cut into pieces at every cell it crosses; its
/// owner is unique, since the leaf holding that center overlaps the
/// primitive's box and so was given the primitive.
fn leaf(src: &Source, refs: &[PrimRef], min: DVec3, edge: f64, s: &Settings) -> Cell {
    let max = min + DVec3::splat(edge);
    let (grown_min, grown_max) = (
        min - DVec3::splat(edge * 0.5),
        max + DVec3::splat(edge * 0.5),
    );
    let mut whole = Vec::new();
    let mut clipped: Vec<Triangle> = Vec::new();
    let mut stored: Vec<Triangle> = Vec::new();
    for r in refs {
        whole.clear();
        src.triangles(r, &mut whole);
        for t in &whole {
            let first_piece = clipped.len();
            clip_to_box(t, min, max, &mut clipped);
            let [a, b, c] = t.map(|c| c.position);
            let (lo, hi) = (a.min(b).min(c), a.max(b).max(c));
            let center = (lo + hi) * 0.5;
            if !(lo.cmpge(grown_min).all() && hi.cmple(grown_max).all()) {
                stored.extend_from_slice(&clipped[first_piece..]);
            } else if center.cmpge(min).all() && center.cmplt(max).all() {
                stored.push(*t);
            }
        }
    }
    let cubes = leaf_cubes(&clipped, min, edge, s.cluster, s.samples);
    Cell {
        children: Vec::new(),
        mask: 0,
        faces: cubes.whole,
        sub: if s.cluster > 1 { cubes.sub } else { Vec::new() },
        geometry: Some(quantize(&stored, min, edge, s.channels)),
    }
}

/// Cell-relative 16-bit geometry, vertices shared where they quantize to
/// the same position, normal and color.
fn quantize(tris: &[Triangle], min: DVec3, edge: f64, channels: Channels) -> LeafGeometry {
    let mut g = LeafGeometry {
        normals: channels.normals.then(Vec::new),
        colors: channels.color.then(Vec::new),
        ..Default::default()
    };
    let mut seen: HashMap<([u16; 3], u32, [u8; 3]), u32> = HashMap::new();
    for t in tris {
        let geometric = {
            let [a, b, c] = t.map(|c| c.position);
            (b - a).cross(c - a).as_vec3()
        };
        let idx = t.map(|c| {
            let q = quantize_in_cell(c.position, min, edge);
            let n = if channels.normals {
                pack_normal(c.normal.unwrap_or(geometric))
            } else {
                0
            };
            let rgb = if channels.color { c.rgb8() } else { [0; 3] };
            *seen.entry((q, n, rgb)).or_insert_with(|| {
                g.positions.push(q);
                if let Some(ns) = g.normals.as_mut() {
                    ns.push(n);
                }
                if let Some(cs) = g.colors.as_mut() {
                    cs.push(rgb);
                }
                (g.positions.len() - 1) as u32
            })
        });
        // Quantization may collapse a sliver to a line: nothing to draw.
        if idx[0] != idx[1] && idx[1] != idx[2] && idx[0] != idx[2] {
            g.triangles.push(idx);
        }
    }
    g
}
