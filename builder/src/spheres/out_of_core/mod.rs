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
mod join;
mod median;
mod merge;
mod mesh;
mod part;
mod phases;
mod source;
mod spread;
mod temp;
#[cfg(test)]
mod tests;
mod top;

use std::path::PathBuf;

use crate::BuildError;
use crate::import::stream::{MeshInfo, Streamed};
use crate::import::up::InputKind;
use crate::import::{ImportError, Params, expand_folders, las, load_input};
use crate::page_writer::SpilledFile;
use crate::progress::Progress;
use crate::scene::{Primitives, Scene};
use crate::spheres::{BuildOptions, BuildStats};

pub use budget::{default_memory, parse_bytes};
pub use part::{MANIFEST, PartStats, Subset, merge};
pub(crate) use source::PointSource;
pub use temp::TempDir;

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
    /// The scene fits the budget (or mixes kinds): loaded whole.
    InMemory {
        scene: Scene,
        /// Why a scene over the budget is still built in memory.
        note: Option<String>,
    },
    /// Point clouds, or meshes, over the budget: built in chunks.
    OutOfCore(Job),
}

/// An out-of-core build, ready to run.
#[derive(Debug)]
pub struct Job {
    sources: Vec<PointSource>,
    /// Triangle meshes (a job has these or `sources`, not both).
    meshes: Vec<mesh::MeshInput>,
    budget: Budget,
    /// What a part's manifest calls the input read from a path, where it
    /// is not the path (see [`Job::name_input`]).
    names: Vec<(PathBuf, String)>,
}

/// Decides how to build `inputs` within `budget`: LAS and LAZ files are
/// counted from their headers, other inputs loaded (their importers read
/// whole files); if the points' in-memory build would pass the budget and
/// the inputs are all point clouds, or all triangle meshes, the build goes
/// out of core.
pub fn plan(inputs: &[String], params: &Params, budget: &Budget) -> Result<Plan, ImportError> {
    let entries = survey_inputs(inputs, params, budget)?;
    let points: u64 = entries
        .iter()
        .map(|e| match e {
            Input::Las(source) => source.count(),
            Input::Mesh { info, .. } => info.vertices,
            Input::Loaded(scene) => scene.instanced_vertex_count(),
        })
        .sum();
    let need = points.saturating_mul(IN_MEMORY_BYTES_PER_POINT);
    if need <= budget.memory {
        return Ok(Plan::InMemory {
            scene: load_all(entries, params)?,
            note: None,
        });
    }
    match kind_of(&entries) {
        Kinds::Points => Ok(Plan::OutOfCore(job_of(entries, budget))),
        Kinds::Meshes => Ok(Plan::OutOfCore(Job {
            sources: Vec::new(),
            meshes: entries
                .into_iter()
                .filter_map(|e| match e {
                    Input::Loaded(scene) => Some(mesh::MeshInput::Scene(scene)),
                    Input::Mesh { path, format, info } => Some(mesh::MeshInput::File {
                        path,
                        format,
                        info,
                        place: params.up.world_from_input(InputKind::MeshFile),
                    }),
                    Input::Las(_) => None,
                })
                .collect(),
            budget: budget.clone(),
            names: Vec::new(),
        })),
        Kinds::Other(why) => Ok(Plan::InMemory {
            scene: load_all(entries, params)?,
            note: Some(format!(
                "{why}: built in memory (about {} MiB, over the budget of {} MiB); only point clouds and meshes, apart, are built out of core",
                need >> 20,
                budget.memory >> 20
            )),
        }),
    }
}

/// Every input loaded whole, in the order given, as `load_inputs` does.
fn load_all(entries: Vec<Input>, params: &Params) -> Result<Scene, ImportError> {
    let mut scene = Scene::default();
    for entry in entries {
        scene.merge(match entry {
            Input::Las(source) => source.load(params)?,
            Input::Mesh { path, .. } => load_input(&path.display().to_string(), params)?,
            Input::Loaded(loaded) => loaded,
        });
    }
    Ok(scene)
}

/// What a build's inputs are, as far as building out of core goes.
enum Kinds {
    /// Point clouds only.
    Points,
    /// Triangle meshes only.
    Meshes,
    /// Anything else (spheres, clouds with meshes): why not out of core.
    Other(String),
}

fn kind_of(entries: &[Input]) -> Kinds {
    let geometries = || {
        entries.iter().flat_map(|e| match e {
            Input::Loaded(scene) => scene.geometries.iter(),
            Input::Las(_) | Input::Mesh { .. } => [].iter(),
        })
    };
    let is_mesh = |g: &&crate::scene::Geometry| matches!(g.primitives, Primitives::Triangles(_));
    let has_las = entries.iter().any(|e| matches!(e, Input::Las(_)));
    let streamed = entries.iter().find_map(|e| match e {
        Input::Mesh { path, .. } => Some(path.display().to_string()),
        _ => None,
    });
    if let Some(g) = geometries().find(|g| matches!(g.primitives, Primitives::Spheres(_))) {
        return Kinds::Other(format!("{} is made of spheres", g.name));
    }
    let mesh = geometries()
        .find(is_mesh)
        .map(|g| g.name.clone())
        .or(streamed);
    match mesh {
        None => Kinds::Points,
        Some(_) if !has_las && geometries().all(|g| is_mesh(&g)) => Kinds::Meshes,
        Some(name) => Kinds::Other(format!("{name} is a mesh among point clouds")),
    }
}

/// An out-of-core job for `inputs` whatever their size (a subset of a
/// build on many machines is always one); an error for an input that is
/// not a point cloud.
pub fn plan_out_of_core(
    inputs: &[String],
    params: &Params,
    budget: &Budget,
) -> Result<Job, ImportError> {
    let entries = survey_inputs(inputs, params, budget)?;
    if let Some(name) = first_mesh(&entries) {
        return Err(ImportError::Malformed {
            path: PathBuf::from(name),
            element: "geometry".into(),
            message: "not a point cloud: only point clouds are built in parts".into(),
        });
    }
    Ok(job_of(entries, budget))
}

/// An input as the plan first sees it.
enum Input {
    /// A LAS or LAZ file, counted from its header, not read yet.
    Las(PointSource),
    /// A mesh file, surveyed (see [`Streamed::survey`]), not read yet.
    Mesh {
        path: PathBuf,
        format: Streamed,
        info: MeshInfo,
    },
    /// Any other input, loaded whole by its importer.
    Loaded(Scene),
}

/// Each input in order: a LAS file counted from its header, a mesh file
/// surveyed, or a scene loaded whole.
fn survey_inputs(
    inputs: &[String],
    params: &Params,
    budget: &Budget,
) -> Result<Vec<Input>, ImportError> {
    let mut entries = Vec::new();
    for input in expand_folders(inputs)? {
        let path = std::path::Path::new(&input);
        let extension = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        let file = !input.starts_with("gen:");
        if file && matches!(extension.as_deref(), Some("las" | "laz")) {
            let info = las::survey(path)?;
            entries.push(Input::Las(PointSource::Las {
                path: path.to_owned(),
                info,
                wide: false,
            }));
        } else if file
            && let Some(format) = Streamed::of(path)
            && worth_surveying(path, format, budget)
            && let info = format.survey(path)?
            && info.triangles
        {
            entries.push(Input::Mesh {
                path: path.to_owned(),
                format,
                info,
            });
        } else {
            entries.push(Input::Loaded(load_input(&input, params)?));
        }
    }
    Ok(entries)
}

/// Whether a mesh file is surveyed before it is read. PLY says its counts
/// in its header; an OFF file with colors and an OBJ file are read whole
/// to be surveyed, so they are surveyed only when their size leaves room
/// for more vertices than the budget builds in memory (a vertex line is at
/// least 8 bytes: `v 0 0 0` and its newline). A file under that bound is
/// loaded whole: a build of many such files that together pass the budget
/// goes out of core from memory, not streamed.
fn worth_surveying(path: &std::path::Path, format: Streamed, budget: &Budget) -> bool {
    if format == Streamed::Ply {
        return true;
    }
    let bytes = std::fs::metadata(path).map_or(u64::MAX, |m| m.len());
    (bytes / 8).saturating_mul(IN_MEMORY_BYTES_PER_POINT) > budget.memory
}

/// The name of the first input that is not a point cloud.
fn first_mesh(entries: &[Input]) -> Option<String> {
    entries.iter().find_map(|e| match e {
        Input::Las(_) => None,
        Input::Mesh { path, .. } => Some(path.display().to_string()),
        Input::Loaded(scene) => scene
            .geometries
            .iter()
            .find(|g| !matches!(g.primitives, Primitives::Points))
            .map(|g| g.name.clone()),
    })
}

fn job_of(entries: Vec<Input>, budget: &Budget) -> Job {
    let mut sources = Vec::new();
    for entry in entries {
        match entry {
            Input::Las(source) => sources.push(source),
            // Not reached: a mesh is not built with clouds.
            Input::Mesh { .. } => {}
            // Clouds in memory are streamed from there, placed by their
            // instances.
            Input::Loaded(scene) => sources.extend(placed_clouds(scene)),
        }
    }
    Job {
        sources,
        meshes: Vec::new(),
        budget: budget.clone(),
        names: Vec::new(),
    }
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
    /// Names the input read from `path` as `name` in a part's manifest,
    /// which the merge compares across parts: a copy of an object in a
    /// store, downloaded under a temporary folder whose path differs from
    /// one machine to another, is named by its address.
    pub fn name_input(&mut self, path: &std::path::Path, name: String) {
        self.names.push((path.to_owned(), name));
    }

    /// Points the inputs hold, as far as their headers say (a mesh's
    /// vertices).
    pub fn points(&self) -> u64 {
        self.sources.iter().map(PointSource::count).sum::<u64>()
            + self
                .meshes
                .iter()
                .map(mesh::MeshInput::vertices)
                .sum::<u64>()
    }

    /// Runs the build, telling `progress` how far each phase has got.
    pub fn build(
        mut self,
        options: &BuildOptions,
        progress: &dyn Progress,
    ) -> Result<(Finished, OutOfCoreStats), BuildError> {
        let temp =
            temp::TempDir::create(&self.budget.tmp).map_err(|e| temp_error(&self.budget.tmp, e))?;
        if !self.meshes.is_empty() {
            let meshes = std::mem::take(&mut self.meshes);
            let (file, stats) = mesh::build(meshes, &self.budget, options, &temp, progress)?;
            return Ok((Finished { file, _temp: temp }, stats));
        }
        let counted = phases::count(&mut self.sources, &self.budget, progress)?;
        checkpoint("count");
        let spread = phases::spread(&self.sources, &counted, &temp, &|_| true, progress)?;
        checkpoint("spread");
        let sized = phases::size(&spread, &counted, temp.path(), progress)?;
        let (file, joined) = join::join(sized, counted.layout, options, &temp, true, progress)?;
        let build = joined.stats(
            file.header.page_count as usize,
            counted.layout,
            counted.seconds,
        );
        Ok((
            Finished { file, _temp: temp },
            OutOfCoreStats {
                build,
                chunks: joined.chunks,
                chunk_points: counted.chunk_points,
                halo_points: spread.halo_points,
                grid_side: counted.grid_side,
                seconds_count: counted.seconds,
                seconds_spread: spread.seconds,
                seconds_chunks: joined.seconds_sizes + joined.seconds_roots,
                seconds_top: joined.seconds_top,
                seconds_levels: joined.seconds_levels,
                seconds_pages: joined.seconds_pages,
            },
        ))
    }
}

/// The error of a temporary folder that cannot be made.
fn temp_error(dir: &std::path::Path, e: std::io::Error) -> BuildError {
    BuildError::Invalid(format!(
        "{}: cannot make the temporary folder: {e}",
        dir.display()
    ))
}

/// The error of a temporary file that cannot be written or read.
fn io_error(e: std::io::Error) -> BuildError {
    BuildError::Invalid(format!("temporary files: {e}"))
}
