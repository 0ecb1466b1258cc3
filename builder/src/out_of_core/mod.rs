//! Sphere builds of point clouds larger than memory, in the manner of
//! PotreeConverter 2: count, spread to chunks, build chunks, join.
//!
//! 1. **count**: every input is read once as a stream ([`source`]); its
//!    points are counted in the cells of a grid over the scene ([`grid`]).
//! 2. **spread**: the cells are merged into chunks small enough to build in
//!    memory, and every point is read again and written to its chunk's file
//!    under the temporary folder ([`temp`]), with copies of the points
//!    along its faces as its neighbours' halos ([`spread`]).
//! 3. **chunks**: one chunk at a time, every core on it, its leaves are
//!    sized (its halo as neighbours only) and its subtree built
//!    ([`chunk`]); the leaves go back to disk, the root's summary stays.
//! 4. **top**: the levels above the chunks are built over their roots and
//!    quantized ([`top`]); each chunk root's quantized sphere is then known.
//! 5. **levels**: each chunk's subtree, rebuilt from its leaves, is
//!    quantized below its root into level files.
//! 6. **pages**: the top's groups and the chunks' levels are cut into
//!    breadth-first pages ([`merge`]).
//!
//! The leaves are the in-memory build's: sized among the same neighbours
//! (the halos), capped by the whole cloud's median radius (found exactly,
//! [`median`]; the in-memory build counts a position held by several
//! points once, this counts each), floored by its smallest. The tree
//! differs: above the chunks it splits the chunks' roots, not all leaves,
//! and within a chunk it bisects the chunk's box, so the leaves are
//! quantized against other parents; a build of one chunk is the in-memory
//! build, byte for byte. Memory holds the grid, one chunk's build and the
//! page directory: pages are written to disk as they are made. The
//! temporary folder goes when the build ends, however it ends (or at the
//! next build, for a killed one).

mod budget;
mod chunk;
mod grid;
mod median;
mod merge;
mod source;
mod spread;
mod temp;
#[cfg(test)]
mod tests;
mod top;

use std::path::PathBuf;
use std::time::Instant;

use farfield_protocol::file::{AttributeFlags, FileHeader, HierarchyKind};
use farfield_protocol::sphere_codec::NodeLayout;
use glam::DVec3;

use crate::BuildError;
use crate::import::{ImportError, Params, expand_folders, las, load_input};
use crate::page_writer::{SpillError, SpilledFile};
use crate::progress::Progress;
use crate::scene::{Primitives, Scene};
use crate::spheres::{BuildOptions, BuildStats};

pub use budget::{default_memory, parse_bytes};
pub(crate) use source::PointSource;

/// Bytes of memory an in-memory sphere build takes per point at its peak
/// (measured: 82 at 50 million generated lidar points, more for small
/// clouds; rounded up).
pub const IN_MEMORY_BYTES_PER_POINT: u64 = 100;

/// Bytes per point a chunk's build takes at its peak: its points as read
/// (positions, colors), the leaves, the neighbour search's tables, and the
/// halo's share of all of these.
const CHUNK_BYTES_PER_POINT: u64 = 200;

/// Bytes the median's bins take (see `median`).
const MEDIAN_BYTES: u64 = 8 << 20;

/// Bytes of chunk buffers in the spread, all chunks together, at most.
const SPREAD_BUFFERS: u64 = 64 << 20;

/// The fewest points a chunk is cut for, whatever the budget: smaller
/// chunks would be all halo.
const MIN_CHUNK_POINTS: u64 = 1_000;

/// The environment variable naming a phase after which the build aborts
/// (`count`, `spread`, `chunks`, `top`, `levels`, `pages`): no destructor
/// runs, as when the process is killed. The tests' way of killing a build
/// at a known point.
pub const ABORT_AFTER_ENV: &str = "FARFIELD_BUILD_ABORT_AFTER";

/// Aborts the process if [`ABORT_AFTER_ENV`] names `phase`.
fn checkpoint(phase: &str) {
    if std::env::var(ABORT_AFTER_ENV).is_ok_and(|p| p == phase) {
        eprintln!("{ABORT_AFTER_ENV}={phase}: aborting");
        std::process::abort();
    }
}

/// How much memory a build may use, and where it may spill.
#[derive(Debug, Clone)]
pub struct Budget {
    /// Bytes of resident memory the build aims to stay within.
    pub memory: u64,
    /// The folder its temporary files go under.
    pub tmp: PathBuf,
}

/// How a build will run.
#[derive(Debug)]
pub enum Plan {
    /// The scene fits the budget (or is not only points): loaded whole.
    InMemory {
        scene: Scene,
        /// Why a scene over the budget is still built in memory.
        note: Option<String>,
    },
    /// Point clouds over the budget: built in chunks.
    OutOfCore(Job),
}

/// An out-of-core build, ready to run.
#[derive(Debug)]
pub struct Job {
    sources: Vec<PointSource>,
    budget: Budget,
}

/// Decides how to build `inputs` within `budget`: LAS and LAZ files are
/// counted from their headers, other inputs loaded (their importers read
/// whole files); if the points' in-memory build would pass the budget and
/// every input is a point cloud, the build goes out of core.
pub fn plan(inputs: &[String], params: &Params, budget: &Budget) -> Result<Plan, ImportError> {
    // Each input in order: a LAS file counted from its header, or a scene
    // loaded whole.
    let mut entries: Vec<Result<PointSource, Scene>> = Vec::new();
    for input in expand_folders(inputs)? {
        let path = std::path::Path::new(&input);
        let extension = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        if !input.starts_with("gen:") && matches!(extension.as_deref(), Some("las" | "laz")) {
            let info = las::survey(path)?;
            entries.push(Ok(PointSource::Las {
                path: path.to_owned(),
                info,
                wide: false,
            }));
        } else {
            entries.push(Err(load_input(&input, params)?));
        }
    }
    let points: u64 = entries
        .iter()
        .map(|e| match e {
            Ok(source) => source.count(),
            Err(scene) => scene.instanced_vertex_count(),
        })
        .sum();
    let need = points.saturating_mul(IN_MEMORY_BYTES_PER_POINT);
    let mesh = entries.iter().find_map(|e| {
        e.as_ref()
            .err()?
            .geometries
            .iter()
            .find(|g| !matches!(g.primitives, Primitives::Points))
    });
    let note = (need > budget.memory).then(|| mesh.map(|g| {
        format!(
            "{} is not a point cloud: built in memory (about {} MiB, over the budget of {} MiB); only point clouds are built out of core yet",
            g.name,
            need >> 20,
            budget.memory >> 20
        )
    }));
    if need <= budget.memory || mesh.is_some() {
        // Loaded whole, in the order given, as `load_inputs` does.
        let mut scene = Scene::default();
        for entry in entries {
            scene.merge(match entry {
                Ok(source) => match source {
                    PointSource::Las { path, .. } => {
                        load_input(&path.display().to_string(), params)?
                    }
                    PointSource::Memory(g) => Scene::single(g),
                },
                Err(loaded) => loaded,
            });
        }
        return Ok(Plan::InMemory {
            scene,
            note: note.flatten(),
        });
    }
    let mut sources = Vec::new();
    for entry in entries {
        match entry {
            Ok(source) => sources.push(source),
            // Clouds in memory are streamed from there, placed by their
            // instances.
            Err(scene) => sources.extend(placed_clouds(scene)),
        }
    }
    Ok(Plan::OutOfCore(Job {
        sources,
        budget: budget.clone(),
    }))
}

/// A scene of point clouds as sources, one per instance, placed.
fn placed_clouds(scene: Scene) -> Vec<PointSource> {
    let Scene {
        geometries,
        instances,
    } = scene;
    instances
        .into_iter()
        .map(|instance| {
            let mut placed = geometries[instance.geometry].clone();
            if instance.world_from_local != glam::DAffine3::IDENTITY {
                for p in &mut placed.positions {
                    *p = instance.world_from_local.transform_point3(*p);
                }
                if let Some(ns) = &mut placed.normals {
                    let m = instance.world_from_local.matrix3.inverse().transpose();
                    for n in ns {
                        *n = (m * n.as_dvec3()).normalize_or_zero().as_vec3();
                    }
                }
            }
            PointSource::Memory(placed)
        })
        .collect()
}

/// An out-of-core build's file: its header, and its pages in a file under
/// the build's temporary folder, which goes when this is dropped (write it
/// first: `farfield_store::write_atomic_parts`).
#[derive(Debug)]
pub struct Finished {
    pub file: SpilledFile,
    _temp: temp::TempDir,
}

/// What an out-of-core build did besides the in-memory build's figures.
#[derive(Debug, Clone, serde::Serialize)]
pub struct OutOfCoreStats {
    #[serde(flatten)]
    pub build: BuildStats,
    pub chunks: usize,
    /// The most points a chunk was cut for.
    pub chunk_points: u64,
    /// Points copied into neighbouring chunks' halos.
    pub halo_points: u64,
    pub grid_side: u32,
    pub seconds_count: f64,
    pub seconds_spread: f64,
    pub seconds_chunks: f64,
    pub seconds_top: f64,
    pub seconds_levels: f64,
    pub seconds_pages: f64,
}

impl Job {
    /// Points the inputs hold, as far as their headers say.
    pub fn points(&self) -> u64 {
        self.sources.iter().map(PointSource::count).sum()
    }

    /// Runs the build, telling `progress` how far each phase has got.
    pub fn build(
        mut self,
        options: &BuildOptions,
        progress: &dyn Progress,
    ) -> Result<(Finished, OutOfCoreStats), BuildError> {
        let io = |e: std::io::Error| BuildError::Invalid(format!("temporary files: {e}"));
        let colors = self.sources.iter().any(PointSource::has_color);
        let normals = self.sources.iter().all(PointSource::has_normals);
        let layout = NodeLayout {
            normals: true,
            color: colors,
        };
        let points = self.points();
        let temp = temp::TempDir::create(&self.budget.tmp).map_err(|e| {
            BuildError::Invalid(format!(
                "{}: cannot make the temporary folder: {e}",
                self.budget.tmp.display()
            ))
        })?;

        // 1. Count. The grid needs bounds first: LAS headers give theirs,
        // clouds in memory are measured.
        let started = Instant::now();
        let mut hint = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for s in &self.sources {
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
        let spread_buffers = SPREAD_BUFFERS.min(self.budget.memory / 8);
        // Held beside a chunk: the counting grid, the spread's buffers, the
        // median's bins. Pages are written to disk as they are made.
        let reserved = (u64::from(grid::MAX_SIDE).pow(3) * 4).min(points.saturating_mul(8))
            + spread_buffers
            + MEDIAN_BYTES;
        let chunk_points = (self.budget.memory.saturating_sub(reserved) / CHUNK_BYTES_PER_POINT)
            .max(MIN_CHUNK_POINTS);
        let grid = grid::Grid::new(hint, points, chunk_points);
        let mut counts = vec![0u32; grid.cells()];
        let mut counted = 0u64;
        progress.begin("count", points);
        for s in &mut self.sources {
            s.scan(&mut |positions| {
                for &p in positions {
                    let c = &mut counts[grid.cell_of(p)];
                    *c = c.checked_add(1).ok_or_else(|| ImportError::Malformed {
                        path: PathBuf::from("input"),
                        element: "points".into(),
                        message: "over 4 billion points in one cell of the counting grid".into(),
                    })?;
                }
                counted += positions.len() as u64;
                progress.advance(positions.len() as u64);
                Ok(())
            })
            .map_err(|e| BuildError::Invalid(e.to_string()))?;
        }
        if counted == 0 {
            return Err(BuildError::Empty);
        }
        let seconds_count = started.elapsed().as_secs_f64();
        checkpoint("count");

        // 2. Spread.
        let started = Instant::now();
        let grid_side = grid.side();
        let chunks = grid::Chunks::cut(grid, counts, chunk_points);
        let chunk_files: Vec<PathBuf> = (0..chunks.len())
            .map(|c| temp.file(&format!("chunk-{c}.points")))
            .collect();
        let buffer = (spread_buffers / chunks.len().max(1) as u64).clamp(4 << 10, 4 << 20);
        let mut spreader =
            spread::Spreader::new(chunk_files.clone(), buffer as usize, colors, normals);
        progress.begin("spread", counted);
        let mut spread_error: Option<std::io::Error> = None;
        for s in &self.sources {
            s.for_each(colors, &mut |batch| {
                for i in 0..batch.positions.len() {
                    let (own, halo) = chunks.place(batch.positions[i]);
                    if own == u32::MAX {
                        return Err(ImportError::Malformed {
                            path: PathBuf::from("input"),
                            element: "points".into(),
                            message: "an input changed while it was being built".into(),
                        });
                    }
                    let written = std::iter::once((own, false))
                        .chain(halo.iter().map(|&h| (h, true)))
                        .try_for_each(|(c, is_halo)| spreader.add(c, &batch, i, is_halo));
                    if let Err(e) = written {
                        spread_error = Some(e);
                        return Err(ImportError::Malformed {
                            path: temp.path().to_owned(),
                            element: "chunk files".into(),
                            message: "cannot be written".into(),
                        });
                    }
                }
                progress.advance(batch.positions.len() as u64);
                Ok(())
            })
            .map_err(|e| match spread_error.take() {
                Some(io_error) => io(io_error),
                None => BuildError::Invalid(e.to_string()),
            })?;
        }
        let halo_points = spreader.halo;
        let spread_total = spreader.written;
        spreader.finish().map_err(io)?;
        let chunk_count = chunks.len();
        drop(chunks);
        if spread_total - halo_points != counted {
            return Err(BuildError::Invalid(
                "an input changed while it was being built (its points were read twice)".into(),
            ));
        }
        let seconds_spread = started.elapsed().as_secs_f64();
        checkpoint("spread");

        // 3. Chunks: sized one at a time, every core on each.
        let started = Instant::now();
        progress.begin("chunks", counted);
        let mut median = median::RadiusMedian::new();
        let mut sized = Vec::with_capacity(chunk_count);
        let mut sized_chunks = Vec::with_capacity(chunk_count);
        for (c, path) in chunk_files.iter().enumerate() {
            if !path.exists() {
                continue;
            }
            let points = spread::read_chunk(path, colors, normals).map_err(io)?;
            let own = points.own as u64;
            let leaves = temp.file(&format!("chunk-{c}.leaves"));
            let radii = temp.file(&format!("chunk-{c}.radii"));
            if let Some(s) =
                chunk::size_chunk(points, colors, &leaves, &mut median, &radii).map_err(io)?
            {
                sized.push(s);
                sized_chunks.push(c);
            }
            progress.advance(own);
        }
        if sized.is_empty() {
            return Err(BuildError::Empty);
        }
        // The cloud's radii are capped and floored as the in-memory build
        // does, by the whole cloud's median and smallest radius.
        let fix = chunk::RadiusFix::new(median.median().map_err(io)?, &sized);
        let mut roots = Vec::with_capacity(sized.len());
        for &c in &sized_chunks {
            roots.push(
                chunk::chunk_root(&temp.file(&format!("chunk-{c}.leaves")), &fix).map_err(io)?,
            );
        }
        let seconds_chunks = started.elapsed().as_secs_f64();
        checkpoint("chunks");

        // 4. The levels above the chunks.
        let started = Instant::now();
        let top = top::lay_out_top(&roots, layout);
        let seconds_top = started.elapsed().as_secs_f64();
        checkpoint("top");

        // 5. Each chunk's levels, below its quantized root.
        let started = Instant::now();
        progress.begin("levels", counted);
        let mut levels: Vec<Option<chunk::ChunkLevels>> = Vec::with_capacity(roots.len());
        let mut nodes_in_chunks = 0u64;
        let mut leaves_in_chunks = 0u64;
        for (r, &c) in sized_chunks.iter().enumerate() {
            let files = chunk::lay_out_chunk(
                &temp.file(&format!("chunk-{c}.leaves")),
                &fix,
                top.chunk_spheres[r],
                layout,
                temp.file(&format!("chunk-{c}.groups")),
                temp.file(&format!("chunk-{c}.records")),
            )
            .map_err(io)?;
            nodes_in_chunks += files.1.nodes;
            leaves_in_chunks += files.1.leaves;
            levels.push(Some(files.0));
            progress.advance(sized[r].points);
        }
        let seconds_levels = started.elapsed().as_secs_f64();
        checkpoint("levels");

        // 6. Pages.
        let started = Instant::now();
        let top_nodes = top
            .groups
            .iter()
            .map(|g| g.members.len() as u64)
            .sum::<u64>()
            - roots.len() as u64;
        let total_nodes = top_nodes + nodes_in_chunks;
        progress.begin("pages", total_nodes);
        let node_bytes = layout.bytes() as usize;
        let merged = merge::merge(
            &top,
            &levels,
            node_bytes,
            options.page_bytes,
            &temp.file("pages"),
            progress,
        )
        .map_err(io)?;
        debug_assert_eq!(merged.nodes, total_nodes);
        let bounds = sized
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
                leaves: leaves_in_chunks,
                input_vertices: counted,
                bounds_min: bounds.0,
                bounds_max: bounds.1,
                root_center,
                root_radius,
                pages: Vec::new(),
            })
            .map_err(|e| match e {
                SpillError::Format(e) => BuildError::Format(e),
                SpillError::Io(e) => io(e),
            })?;
        let seconds_pages = started.elapsed().as_secs_f64();
        checkpoint("pages");
        let build = BuildStats {
            input_vertices: counted,
            input_primitives: counted,
            unreferenced_vertices: 0,
            collapsed_duplicates: roots.iter().map(|r| r.collapsed).sum(),
            leaves: file.header.leaves,
            nodes: file.header.nodes,
            levels: file.header.levels,
            pages: file.header.pages.len(),
            has_color: layout.color,
            has_normals: layout.normals,
            seconds_leaves: seconds_count + seconds_spread + seconds_chunks,
            seconds_tree: seconds_top,
            seconds_layout: seconds_levels + seconds_pages,
        };
        Ok((
            Finished { file, _temp: temp },
            OutOfCoreStats {
                build,
                chunks: roots.len(),
                chunk_points,
                halo_points,
                grid_side,
                seconds_count,
                seconds_spread,
                seconds_chunks,
                seconds_top,
                seconds_levels,
                seconds_pages,
            },
        ))
    }
}
