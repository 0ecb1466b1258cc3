//! One chunk, in memory. First its leaves are sized among its own and its
//! halo's points ([`size_chunk`]: the neighbour searches, the bulk of a
//! build); once the whole cloud's median radius is known, its radii are
//! capped as the in-memory build caps them and its subtree is built for
//! its root's summary ([`chunk_root`]); once the levels above the chunks
//! have quantized that root, the subtree is built again from the same
//! leaves and quantized into level files ([`lay_out_chunk`]), which the
//! merge reads in breadth-first order.
//!
//! The subtree is built again rather than kept: a tree holds about twice
//! its leaves' bytes, and bisection is a small share of a build next to
//! the neighbour searches, which run once.

use std::fs::File;
use std::io::{self, BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};

use glam::{DVec3, Vec3};

use super::median::RadiusMedian;
use super::spread::ChunkPoints;
use crate::progress::Silent;
use crate::spheres::layout::{LevelOptions, NodeValues, Placed, place_levels};
use crate::spheres::leaves::{DEFAULT_COLOR, Leaf, pack_normal, round_up_f32};
use crate::spheres::page_cutter::GroupSink;
use crate::spheres::tree::{Bounds, Summary, Tree, build_tree_within};
use crate::spheres::{knn, measure, radius_floor};
use farfield_protocol::sphere_codec::NodeLayout;

/// Bytes of a leaf in a leaves file: position, radius, normal, color, cone.
const LEAF_BYTES: usize = 24 + 4 + 4 + 3 + 1;

/// What sizing a chunk learnt of it.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SizedChunk {
    /// Its own points.
    pub points: u64,
    pub bounds: Bounds,
    /// Its smallest positive radius (infinite when none is positive).
    pub smallest_radius: f32,
}

/// Sizes a chunk's points (its halo's among them, as neighbours only),
/// writes its leaves to `leaves_path` and counts their radii in `median`
/// (written to `radii_path`); `None` for a chunk without points of its own.
pub(crate) fn size_chunk(
    points: ChunkPoints,
    colors: bool,
    leaves_path: &Path,
    median: &mut RadiusMedian,
    radii_path: &Path,
) -> io::Result<Option<SizedChunk>> {
    let ChunkPoints {
        positions,
        colors: rgb,
        normals,
        own,
    } = points;
    if own == 0 {
        return Ok(None);
    }
    let up = pack_normal(Vec3::Z);
    let mut leaves: Vec<Leaf> = positions
        .iter()
        .enumerate()
        .map(|(i, &position)| Leaf {
            position,
            radius: 0.0,
            normal: up,
            color: if colors {
                rgb.get(i).copied().unwrap_or(DEFAULT_COLOR)
            } else {
                [0; 3]
            },
            cone: 255,
            source: i as u32,
        })
        .collect();
    drop(positions);
    drop(rgb);
    let normals = (!normals.is_empty()).then_some(normals);
    let mut radii = knn::size_points_uncapped(&mut leaves, normals.as_deref());
    drop(normals);
    // The halo's points were neighbours only.
    leaves.truncate(own);
    radii.truncate(own);
    median.add(&radii, radii_path)?;
    drop(radii);
    let measured = measure(&leaves);
    write_leaves(leaves_path, &leaves)?;
    Ok(Some(SizedChunk {
        points: own as u64,
        bounds: measured.bounds,
        smallest_radius: measured.smallest_radius,
    }))
}

/// The whole cloud's corrections of its leaves' radii, as the in-memory
/// build makes them: outliers capped at a multiple of the median, leaves of
/// no size given the floor.
#[derive(Debug, Clone, Copy)]
pub(crate) struct RadiusFix {
    cap: f32,
    floor: f32,
}

impl RadiusFix {
    /// From the cloud's median radius (`None`: no radius is positive) and
    /// what sizing learnt of every chunk.
    pub(crate) fn new(median: Option<f64>, chunks: &[SizedChunk]) -> Self {
        // Rounding up commutes with the minimum: capping the f32 radius
        // at the rounded cap is rounding the capped f64 radius.
        let cap = median.map_or(f32::INFINITY, |m| round_up_f32(knn::radius_cap(m)));
        let bounds = chunks
            .iter()
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), c| {
                (lo.min(c.bounds.0), hi.max(c.bounds.1))
            });
        let smallest = chunks
            .iter()
            .map(|c| c.smallest_radius)
            .fold(f32::INFINITY, f32::min)
            .min(cap);
        Self {
            cap,
            floor: radius_floor(smallest, bounds),
        }
    }

    fn apply(&self, leaves: &mut [Leaf]) {
        for l in leaves {
            l.radius = if l.radius.is_nan() || l.radius <= 0.0 {
                self.floor
            } else {
                l.radius.min(self.cap)
            };
        }
    }
}

/// What the levels above a chunk need of it.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ChunkRoot {
    /// The root as its parent sees it (sphere, normal, color, leaf count).
    pub summary: Summary,
    /// The root's record values (its child count among them).
    pub values: NodeValues,
    /// Leaves that stand for several points at one position.
    pub collapsed: u64,
}

/// The leaves of `leaves_path`, their radii fixed, as a tree.
fn chunk_tree(leaves_path: &Path, fix: &RadiusFix) -> io::Result<Tree> {
    let mut leaves = read_leaves(leaves_path)?;
    fix.apply(&mut leaves);
    let bounds = measure(&leaves).bounds;
    Ok(build_tree_within(leaves, bounds, &Silent))
}

/// Builds a chunk's subtree from its leaves and returns its root.
pub(crate) fn chunk_root(leaves_path: &Path, fix: &RadiusFix) -> io::Result<ChunkRoot> {
    let tree = chunk_tree(leaves_path, fix)?;
    Ok(ChunkRoot {
        summary: Summary::of_root(&tree),
        values: root_values(&tree),
        collapsed: tree.collapsed_duplicates,
    })
}

fn root_values(tree: &Tree) -> NodeValues {
    match tree.root.get() {
        Ok(l) => NodeValues::leaf(&tree.leaves[l]),
        Err(i) => NodeValues::interior(&tree.interior[i]),
    }
}

pub(crate) fn write_leaves(path: &Path, leaves: &[Leaf]) -> io::Result<()> {
    let mut out = BufWriter::with_capacity(1 << 20, File::create(path)?);
    for l in leaves {
        for v in l.position.to_array() {
            out.write_all(&v.to_le_bytes())?;
        }
        out.write_all(&l.radius.to_le_bytes())?;
        out.write_all(&l.normal.to_le_bytes())?;
        out.write_all(&l.color)?;
        out.write_all(&[l.cone])?;
    }
    out.into_inner().map_err(|e| e.into_error())?;
    Ok(())
}

pub(crate) fn read_leaves(path: &Path) -> io::Result<Vec<Leaf>> {
    let file = File::open(path)?;
    let count = file.metadata()?.len() as usize / LEAF_BYTES;
    let mut input = BufReader::with_capacity(1 << 20, file);
    let mut leaves = Vec::with_capacity(count);
    let mut record = [0u8; LEAF_BYTES];
    for source in 0..count {
        input.read_exact(&mut record)?;
        let f64_at =
            |at: usize| f64::from_le_bytes(record[at..at + 8].try_into().unwrap_or_default());
        let u32_at =
            |at: usize| u32::from_le_bytes(record[at..at + 4].try_into().unwrap_or_default());
        let position = DVec3::new(f64_at(0), f64_at(8), f64_at(16));
        // A merge reads parts made elsewhere: a damaged one must not reach
        // the tree with a position that is not a number.
        if !position.is_finite() {
            return Err(io::Error::new(
                io::ErrorKind::InvalidData,
                format!(
                    "{}: leaf {source} has a position that is not finite (the file is damaged)",
                    path.display()
                ),
            ));
        }
        leaves.push(Leaf {
            position,
            radius: f32::from_bits(u32_at(24)),
            normal: u32_at(28),
            color: [record[32], record[33], record[34]],
            cone: record[35],
            source: source as u32,
        });
    }
    Ok(leaves)
}

/// A chunk's quantized levels below its root: each level's group sizes
/// (one byte a group) in one file and its records in another.
#[derive(Debug)]
pub(crate) struct ChunkLevels {
    pub groups_path: PathBuf,
    pub records_path: PathBuf,
    /// Per level below the root (the root's children first): groups, nodes.
    pub levels: Vec<(u64, u64)>,
}

/// Rebuilds the chunk's subtree from `leaves_path` (removed after when
/// `remove`) and quantizes it below its root, whose quantized sphere is
/// `root_sphere`, into level files; returns what was placed, the root
/// included.
pub(crate) fn lay_out_chunk(
    leaves_path: &Path,
    remove: bool,
    fix: &RadiusFix,
    root_sphere: (DVec3, f64),
    layout: NodeLayout,
    groups_path: PathBuf,
    records_path: PathBuf,
) -> io::Result<(ChunkLevels, Placed)> {
    let tree = chunk_tree(leaves_path, fix)?;
    if remove {
        std::fs::remove_file(leaves_path)?;
    }
    let mut sink = LevelFiles {
        groups: BufWriter::with_capacity(1 << 16, File::create(&groups_path)?),
        records: BufWriter::with_capacity(1 << 20, File::create(&records_path)?),
        levels: Vec::new(),
        level: 0,
        node_bytes: layout.bytes() as usize,
        error: None,
    };
    let placed = place_levels(
        tree,
        root_sphere,
        LevelOptions {
            layout,
            first_child: 0,
            leaf_sources: None,
        },
        &mut sink,
        &Silent,
    );
    if let Some(e) = sink.error {
        return Err(e);
    }
    sink.groups.into_inner().map_err(|e| e.into_error())?;
    sink.records.into_inner().map_err(|e| e.into_error())?;
    Ok((
        ChunkLevels {
            groups_path,
            records_path,
            levels: sink.levels,
        },
        placed,
    ))
}

/// The level files being written.
struct LevelFiles {
    groups: BufWriter<File>,
    records: BufWriter<File>,
    levels: Vec<(u64, u64)>,
    level: u32,
    node_bytes: usize,
    /// The first write that failed: the sink cannot return it.
    error: Option<io::Error>,
}

impl GroupSink for LevelFiles {
    fn end_level(&mut self) {}

    fn add_group(&mut self, level: u32, group: &[u8], _first_child: u64) {
        if self.error.is_some() {
            return;
        }
        if level != self.level {
            self.level = level;
            self.levels.push((0, 0));
        }
        let count = group.len() / self.node_bytes;
        if let Some(last) = self.levels.last_mut() {
            last.0 += 1;
            last.1 += count as u64;
        }
        let written = self
            .groups
            .write_all(&[count as u8])
            .and_then(|()| self.records.write_all(group));
        if let Err(e) = written {
            self.error = Some(e);
        }
    }
}
