//! The phases that need the inputs: **count** (the grid and its chunks),
//! **spread** (points to chunk files, with halos) and **size** (each
//! chunk's leaves). A whole build runs them for every chunk; a subset
//! (`part`) spreads and sizes only its own chunks.

use std::path::{Path, PathBuf};
use std::time::Instant;

use farfield_protocol::sphere_codec::NodeLayout;
use glam::DVec3;

use super::chunk::{self, SizedChunk};
use super::grid::{self, Chunks, Grid};
use super::median::RadiusMedian;
use super::temp::TempDir;
use super::{
    Budget, CHUNK_BYTES_PER_POINT, MEDIAN_BYTES, MIN_CHUNK_POINTS, PointSource, SPREAD_BUFFERS,
    io_error, spread,
};
use crate::BuildError;
use crate::import::ImportError;
use crate::progress::Progress;

/// What the count learnt: the chunks, and what every later phase shares.
pub(crate) struct Counted {
    pub chunks: Chunks,
    /// Points read.
    pub points: u64,
    /// The most points a chunk is cut for.
    pub chunk_points: u64,
    pub grid_side: u32,
    pub colors: bool,
    pub normals: bool,
    pub layout: NodeLayout,
    pub spread_buffers: u64,
    pub seconds: f64,
}

/// The bytes of the spread's buffers, and the most points a chunk can
/// hold, for a build of `points` points within `budget`; `median`: whether
/// the build takes the radii's median (a cloud's does, a mesh's not).
pub(crate) fn chunk_size(budget: &Budget, points: u64, median: bool) -> (u64, u64) {
    let spread_buffers = SPREAD_BUFFERS.min(budget.memory / 8);
    // Held beside a chunk: the counting grid, the spread's buffers, the
    // median's bins. Pages are written to disk as they are made.
    let reserved = (u64::from(grid::MAX_SIDE).pow(3) * 4).min(points.saturating_mul(8))
        + spread_buffers
        + if median { MEDIAN_BYTES } else { 0 };
    let chunk_points =
        (budget.memory.saturating_sub(reserved) / CHUNK_BYTES_PER_POINT).max(MIN_CHUNK_POINTS);
    (spread_buffers, chunk_points)
}

/// Counts every input's points in a grid over the scene and cuts the
/// chunks a budget of `budget.memory` can build.
pub(crate) fn count(
    sources: &mut [PointSource],
    budget: &Budget,
    progress: &dyn Progress,
) -> Result<Counted, BuildError> {
    let started = Instant::now();
    let colors = sources.iter().any(PointSource::has_color);
    let normals = sources.iter().all(PointSource::has_normals);
    let points: u64 = sources.iter().map(PointSource::count).sum();
    // The grid needs bounds first: LAS headers give theirs, clouds in
    // memory are measured.
    let mut hint = (DVec3::INFINITY, DVec3::NEG_INFINITY);
    for s in sources.iter() {
        let b = match s {
            PointSource::Las { info, .. } => info.bounds,
            PointSource::Memory(g) => g
                .positions
                .iter()
                .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), &p| {
                    (lo.min(p), hi.max(p))
                }),
        };
        hint = (hint.0.min(b.0), hint.1.max(b.1));
    }
    if !(hint.0.is_finite() && hint.1.is_finite()) {
        hint = (DVec3::ZERO, DVec3::ZERO);
    }
    let (spread_buffers, chunk_points) = chunk_size(budget, points, true);
    // LAS headers' bounds are a hint: a scan that finds points well
    // outside them counts again over the bounds it measured (a grid too
    // small would put them all in its edge cells, as chunks too large).
    let mut grid = Grid::new(hint, points, chunk_points);
    let (counts, read) = loop {
        let mut counts = vec![0u32; grid.cells()];
        let mut read = 0u64;
        let mut measured = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        progress.begin("count", points);
        for s in sources.iter_mut() {
            s.scan(&mut |positions| {
                for &p in positions {
                    if !p.is_finite() {
                        return Err(ImportError::Malformed {
                            path: PathBuf::from("input"),
                            element: format!("point {}", read),
                            message: "a coordinate is not a finite number".into(),
                        });
                    }
                    measured = (measured.0.min(p), measured.1.max(p));
                    let c = &mut counts[grid.cell_of(p)];
                    *c = c.checked_add(1).ok_or_else(|| ImportError::Malformed {
                        path: PathBuf::from("input"),
                        element: "points".into(),
                        message: "over 4 billion points in one cell of the counting grid".into(),
                    })?;
                }
                read += positions.len() as u64;
                progress.advance(positions.len() as u64);
                Ok(())
            })
            .map_err(|e| BuildError::Invalid(e.to_string()))?;
        }
        if read == 0 {
            return Err(BuildError::Empty);
        }
        // Points a hair outside (the header's rounding) land in the edge
        // cells, which is harmless; a box a hundredth larger is not a hint.
        let slack = (hint.1 - hint.0).max_element().max(0.0) * 0.01;
        let inside =
            measured.0.cmpge(hint.0 - slack).all() && measured.1.cmple(hint.1 + slack).all();
        if inside {
            break (counts, read);
        }
        hint = measured;
        grid = Grid::new(hint, points, chunk_points);
    };
    let grid_side = grid.side();
    Ok(Counted {
        chunks: Chunks::cut(grid, counts, chunk_points),
        points: read,
        chunk_points,
        grid_side,
        colors,
        normals,
        layout: NodeLayout {
            normals: true,
            color: colors,
        },
        spread_buffers,
        seconds: started.elapsed().as_secs_f64(),
    })
}

/// The spread's chunk files.
pub(crate) struct Spread {
    /// Each chunk's file (absent for a chunk not selected).
    pub files: Vec<PathBuf>,
    pub halo_points: u64,
    pub seconds: f64,
}

/// Writes the points of the chunks `selected` takes (their own and their
/// halos) to chunk files under `temp`.
pub(crate) fn spread(
    sources: &[PointSource],
    counted: &Counted,
    temp: &TempDir,
    selected: &dyn Fn(u32) -> bool,
    progress: &dyn Progress,
) -> Result<Spread, BuildError> {
    let started = Instant::now();
    let chunks = &counted.chunks;
    let files: Vec<PathBuf> = (0..chunks.len())
        .map(|c| temp.file(&format!("chunk-{c}.points")))
        .collect();
    let buffer = (counted.spread_buffers / chunks.len().max(1) as u64).clamp(4 << 10, 4 << 20);
    let mut spreader = spread::Spreader::new(
        files.clone(),
        buffer as usize,
        counted.colors,
        counted.normals,
    );
    progress.begin("spread", counted.points);
    let mut failed: Option<std::io::Error> = None;
    let mut own_points = 0u64;
    let mut selected_points = 0u64;
    for s in sources {
        s.for_each(counted.colors, &mut |batch| {
            for i in 0..batch.positions.len() {
                let (own, halo) = chunks.place(batch.positions[i]);
                if own == u32::MAX {
                    return Err(changed());
                }
                own_points += 1;
                let copies = std::iter::once((own, false))
                    .chain(halo.iter().map(|&h| (h, true)))
                    .filter(|&(c, _)| selected(c));
                for (c, is_halo) in copies {
                    selected_points += u64::from(!is_halo);
                    if let Err(e) = spreader.add(c, &batch, i, is_halo) {
                        failed = Some(e);
                        return Err(changed());
                    }
                }
            }
            progress.advance(batch.positions.len() as u64);
            Ok(())
        })
        .map_err(|e| match failed.take() {
            Some(e) => io_error(e),
            None => BuildError::Invalid(e.to_string()),
        })?;
    }
    let halo_points = spreader.halo;
    spreader.finish().map_err(io_error)?;
    let expected: u64 = (0..chunks.len() as u32)
        .filter(|&c| selected(c))
        .map(|c| chunks.points[c as usize])
        .sum();
    if own_points != counted.points || selected_points != expected {
        return Err(BuildError::Invalid(
            "an input changed while it was being built (its points were read twice)".into(),
        ));
    }
    Ok(Spread {
        files,
        halo_points,
        seconds: started.elapsed().as_secs_f64(),
    })
}

fn changed() -> ImportError {
    ImportError::Malformed {
        path: PathBuf::from("input"),
        element: "points".into(),
        message: "an input changed while it was being built".into(),
    }
}

/// A sized chunk and where its leaves are.
#[derive(Debug, Clone)]
pub(crate) struct SizedEntry {
    pub chunk: usize,
    pub sized: SizedChunk,
    pub leaves: PathBuf,
}

/// The chunks' leaves, sized, and their radii's counts for the median.
pub(crate) struct Sized {
    pub entries: Vec<SizedEntry>,
    /// The input's vertices, the header's `input_vertices`: a cloud's
    /// points, a mesh's vertices (those no triangle uses among them).
    pub input_vertices: u64,
    pub median: RadiusMedian,
    pub seconds: f64,
}

/// Sizes every chunk that has a file, one at a time, every core on each;
/// leaves and radii files go to `dir`, chunk files are removed as read.
pub(crate) fn size(
    spread: &Spread,
    counted: &Counted,
    dir: &Path,
    progress: &dyn Progress,
) -> Result<Sized, BuildError> {
    let started = Instant::now();
    progress.begin("chunks", counted.points);
    let mut median = RadiusMedian::new();
    let mut entries = Vec::new();
    for (c, path) in spread.files.iter().enumerate() {
        if !path.exists() {
            continue;
        }
        let points = spread::read_chunk(path, counted.colors, counted.normals).map_err(io_error)?;
        let own = points.own as u64;
        let leaves = dir.join(format!("chunk-{c}.leaves"));
        let radii = dir.join(format!("chunk-{c}.radii"));
        if let Some(sized) = chunk::size_chunk(points, counted.colors, &leaves, &mut median, &radii)
            .map_err(io_error)?
        {
            entries.push(SizedEntry {
                chunk: c,
                sized,
                leaves,
            });
        }
        progress.advance(own);
    }
    Ok(Sized {
        input_vertices: entries.iter().map(|e| e.sized.points).sum(),
        entries,
        median,
        seconds: started.elapsed().as_secs_f64(),
    })
}
