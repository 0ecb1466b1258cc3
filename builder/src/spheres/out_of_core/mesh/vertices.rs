//! A mesh build's vertices and triangles on disk: every instance of every
//! mesh placed in the world and written once, sequentially, then read back
//! through memory maps by vertex index.
//!
//! Triangles name their corners by index, so spreading a triangle to its
//! chunks needs its corners' positions wherever they are in the file, and
//! a chunk needs its vertices' attributes: random access, which a map gives
//! without holding the vertices in the build's own memory (the operating
//! system keeps the pages in use and drops the others under pressure).

use std::fs::File;
use std::io::{self, BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};

use glam::{DAffine3, DVec3, Vec3};
use memmap2::{Mmap, MmapMut};

use crate::import::ImportError;
use crate::import::stream::{BodyOut, CornerNormals, MeshInfo, Streamed, Vertices};

use super::super::io_error;
use super::super::temp::TempDir;
use crate::BuildError;
use crate::import::common::unit_normal;
use crate::import::up::turn_normal;
use crate::import::{is_buildable, unbuildable};
use crate::progress::Progress;
use crate::scene::{Primitives, Rgb8, Scene};
use crate::spheres::leaves::DEFAULT_COLOR;

/// Bytes of a position (3 x f64), a color, a normal (3 x f32), a triangle
/// (3 x u32) in the files.
const POSITION_BYTES: usize = 24;
const COLOR_BYTES: usize = 3;
const NORMAL_BYTES: usize = 12;
pub(crate) const TRIANGLE_BYTES: usize = 12;

/// The meshes' vertices (positions, and colors and normals when the build
/// carries them) and triangles, written.
pub(crate) struct MeshFiles {
    positions: Mmap,
    colors: Option<Mmap>,
    normals: Option<Mmap>,
    triangles: PathBuf,
    pub(crate) vertices: u64,
    pub(crate) triangle_count: u64,
    pub(crate) bounds: (DVec3, DVec3),
}

/// A mesh input of an out-of-core build.
#[derive(Debug)]
pub(crate) enum MeshInput {
    /// Meshes in memory (generated, or read whole by their importer),
    /// placed by their instances.
    Scene(Scene),
    /// A mesh file (PLY, OFF or OBJ), read as a stream, and turned Z-up
    /// by `place` (a rotation, [`crate::import::up`]), as its import is.
    File {
        path: PathBuf,
        format: Streamed,
        info: MeshInfo,
        place: DAffine3,
    },
}

impl MeshInput {
    /// Vertices, every instance counted.
    pub(crate) fn vertices(&self) -> u64 {
        match self {
            Self::Scene(scene) => scene.instanced_vertex_count(),
            Self::File { info, .. } => info.vertices,
        }
    }
}

/// What the build carries besides positions, decided over every mesh.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Channels {
    /// Any mesh has colors (the others get [`DEFAULT_COLOR`]).
    pub colors: bool,
    /// Every mesh has normals (else all are computed from the faces).
    pub normals: bool,
}

impl Channels {
    pub(crate) fn of(inputs: &[MeshInput]) -> Self {
        let mut channels = Self {
            colors: false,
            normals: true,
        };
        for input in inputs {
            match input {
                MeshInput::Scene(scene) => {
                    for g in &scene.geometries {
                        channels.colors |= g.colors.is_some();
                        channels.normals &= g.normals.is_some();
                    }
                }
                MeshInput::File { info, .. } => {
                    channels.colors |= info.colors;
                    channels.normals &= info.normals;
                }
            }
        }
        channels
    }
}

/// Writes every mesh of `inputs` (each instance placed) under `temp`,
/// consuming them (each is dropped once written); the unit of `progress`
/// is a vertex.
pub(crate) fn write(
    inputs: Vec<MeshInput>,
    channels: Channels,
    temp: &TempDir,
    progress: &dyn Progress,
) -> Result<MeshFiles, BuildError> {
    let total: u64 = inputs.iter().map(MeshInput::vertices).sum();
    if total > u64::from(u32::MAX) {
        return Err(BuildError::TooLarge(total));
    }
    progress.begin("vertices", total);
    let paths = [
        "mesh.positions",
        "mesh.colors",
        "mesh.normals",
        "mesh.triangles",
    ]
    .map(|name| temp.file(name));
    let create = |path: &PathBuf| -> Result<BufWriter<File>, BuildError> {
        File::create(path)
            .map(|f| BufWriter::with_capacity(1 << 20, f))
            .map_err(io_error)
    };
    let mut out = Writers {
        positions: create(&paths[0])?,
        colors: channels.colors.then(|| create(&paths[1])).transpose()?,
        normals: channels.normals.then(|| create(&paths[2])).transpose()?,
        triangles: create(&paths[3])?,
        vertices: 0,
        triangle_count: 0,
        bounds: (DVec3::INFINITY, DVec3::NEG_INFINITY),
    };
    for input in inputs {
        match input {
            MeshInput::Scene(scene) => out.scene(&scene, progress)?,
            MeshInput::File {
                path,
                format,
                info,
                place,
            } => {
                out.file(&path, format, &info, place, temp, progress)?;
            }
        }
    }
    let (vertices, triangle_count, bounds) = (out.vertices, out.triangle_count, out.bounds);
    out.finish().map_err(io_error)?;
    if triangle_count == 0 {
        return Err(BuildError::Empty);
    }
    let map = |path: &PathBuf| -> Result<Mmap, BuildError> {
        let file = File::open(path).map_err(io_error)?;
        // SAFETY: the file is this build's, in its locked temporary folder,
        // and nothing writes it from here on. Another process truncating it
        // would make a read fault (SIGBUS): the same hazard as any file
        // changed under a map, which only a process ignoring the lock can
        // cause.
        unsafe { Mmap::map(&file) }.map_err(io_error)
    };
    Ok(MeshFiles {
        positions: map(&paths[0])?,
        colors: channels.colors.then(|| map(&paths[1])).transpose()?,
        normals: channels.normals.then(|| map(&paths[2])).transpose()?,
        triangles: paths[3].clone(),
        vertices,
        triangle_count,
        bounds,
    })
}

/// A file's body written as it is read: its normals made unit as the
/// importers make them (unusable ones kept, and repaired in their chunk),
/// its positions checked as the importers check them.
struct BodySink<'a> {
    out: &'a mut Writers,
    path: &'a Path,
    /// The file's turn to Z-up (a rotation).
    place: DAffine3,
    /// The index of the file's first vertex among all the build's.
    base: u64,
    triangles: Vec<[u32; 3]>,
    progress: &'a dyn Progress,
}

impl BodyOut for BodySink<'_> {
    fn batch(&self) -> u64 {
        1 << 16
    }

    fn vertices(&mut self, batch: Vertices) -> Result<(), ImportError> {
        let Vertices {
            positions,
            normals,
            colors,
        } = batch;
        for (i, &local) in positions.iter().enumerate() {
            if !is_buildable(local) {
                return Err(unbuildable(self.path, self.out.vertices - self.base, local));
            }
            let p = self.place.transform_point3(local);
            let color = colors.as_ref().map_or(DEFAULT_COLOR, |c| c[i]);
            let normal = normals.as_ref().map(|n| {
                let unit = unit_normal(n[i]).unwrap_or(n[i]);
                turn_normal(self.place, unit)
            });
            self.out
                .vertex(p, color, normal)
                .map_err(|e| ImportError::io(Path::new("temporary files"), e))?;
        }
        self.progress.advance(positions.len() as u64);
        Ok(())
    }

    fn triangles(&mut self) -> &mut Vec<[u32; 3]> {
        &mut self.triangles
    }

    fn triangles_done(&mut self) -> Result<(), ImportError> {
        // The importer checked each index against the file's vertex count,
        // and the build's total against u32.
        let base = self.base as u32;
        for t in self.triangles.drain(..) {
            self.out
                .triangle(t.map(|v| base + v))
                .map_err(|e| ImportError::io(Path::new("temporary files"), e))?;
        }
        Ok(())
    }
}

/// An OBJ file's normals, as its faces give them to its vertices (see
/// [`CornerNormals`]), gathered on disk: the table of normals written in
/// order, and for each vertex the table's index of its first corner's
/// normal (plus one; zero for none yet), in a map of the file's vertex
/// count. Both may be as large as the vertices themselves.
struct CornerFiles {
    table: BufWriter<File>,
    table_path: PathBuf,
    table_len: u64,
    first: MmapMut,
    first_path: PathBuf,
}

impl CornerFiles {
    fn create(temp: &TempDir, vertices: u64) -> io::Result<Self> {
        let table_path = temp.file("obj.normals");
        let first_path = temp.file("obj.corners");
        let first = File::options()
            .read(true)
            .write(true)
            .create(true)
            .truncate(true)
            .open(&first_path)?;
        first.set_len(vertices * 4)?;
        // SAFETY: the file is this build's, in its locked temporary folder,
        // sized above and written only through this map (see `write`).
        let first = unsafe { MmapMut::map_mut(&first) }?;
        Ok(Self {
            table: BufWriter::with_capacity(1 << 20, File::create(&table_path)?),
            table_path,
            table_len: 0,
            first,
            first_path,
        })
    }

    /// Writes each vertex's normal, in order, made unit as the importer
    /// makes it (a vertex no corner named gets a zero one, repaired in its
    /// chunk as the importer repairs it), and removes the files.
    fn write_normals(self, out: &mut Writers, place: DAffine3) -> io::Result<()> {
        let table = self.table.into_inner().map_err(|e| e.into_error())?;
        drop(table);
        let table = if self.table_len == 0 {
            None
        } else {
            // SAFETY: as in `write`: this build's own file, written above.
            Some(unsafe { Mmap::map(&File::open(&self.table_path)?) }?)
        };
        for slot in self.first.chunks_exact(4) {
            let index = u32::from_le_bytes(slot.try_into().unwrap_or_default());
            let n = match (index.checked_sub(1), &table) {
                (Some(i), Some(table)) => {
                    let at = i as usize * NORMAL_BYTES;
                    let b = table.get(at..at + NORMAL_BYTES).ok_or_else(|| {
                        io::Error::other("an OBJ corner names a normal past the table")
                    })?;
                    Vec3::new(f32_at(b, 0), f32_at(b, 4), f32_at(b, 8))
                }
                _ => Vec3::ZERO,
            };
            let unit = unit_normal(n).unwrap_or(n);
            out.normal(turn_normal(place, unit))?;
        }
        drop(table);
        drop(self.first);
        std::fs::remove_file(&self.table_path)?;
        std::fs::remove_file(&self.first_path)
    }
}

impl CornerNormals for CornerFiles {
    fn table(&mut self, normals: &[Vec3]) -> Result<(), ImportError> {
        for n in normals {
            for v in n.to_array() {
                self.table
                    .write_all(&v.to_le_bytes())
                    .map_err(|e| ImportError::io(Path::new("temporary files"), e))?;
            }
        }
        self.table_len += normals.len() as u64;
        Ok(())
    }

    fn corners(&mut self, corners: &[(u32, u32)]) -> Result<(), ImportError> {
        for &(v, n) in corners {
            let at = v as usize * 4;
            let changed = || {
                ImportError::io(
                    Path::new("temporary files"),
                    io::Error::other("the OBJ file changed while it was being read"),
                )
            };
            let slot = self.first.get_mut(at..at + 4).ok_or_else(changed)?;
            if slot == [0; 4] {
                slot.copy_from_slice(&(n + 1).to_le_bytes());
            }
        }
        Ok(())
    }
}

/// Corner normals dropped: a file whose normals the build does not keep.
struct NoCorners;

impl CornerNormals for NoCorners {
    fn table(&mut self, _: &[Vec3]) -> Result<(), ImportError> {
        Ok(())
    }

    fn corners(&mut self, _: &[(u32, u32)]) -> Result<(), ImportError> {
        Ok(())
    }
}

/// An input normal placed as a normal is (by the inverse transpose), and
/// kept unit; a transform that is the identity leaves it as it is, bit for
/// bit, as the in-memory build does.
fn placed_normal(n: Vec3, place: DAffine3, normal_from_local: glam::DMat3) -> Vec3 {
    if place == DAffine3::IDENTITY {
        return n;
    }
    (normal_from_local * n.as_dvec3())
        .normalize_or_zero()
        .as_vec3()
}

struct Writers {
    positions: BufWriter<File>,
    colors: Option<BufWriter<File>>,
    normals: Option<BufWriter<File>>,
    triangles: BufWriter<File>,
    /// Vertices and triangles written, and the vertices' bounds.
    vertices: u64,
    triangle_count: u64,
    bounds: (DVec3, DVec3),
}

impl Writers {
    /// Writes the mesh file at `path`, read as a stream.
    fn file(
        &mut self,
        path: &Path,
        format: Streamed,
        info: &MeshInfo,
        place: DAffine3,
        temp: &TempDir,
        progress: &dyn Progress,
    ) -> Result<(), BuildError> {
        let base = self.vertices;
        // OBJ normals come by face corner, known only at the file's end.
        let mut corners = (format == Streamed::Obj && info.normals && self.normals.is_some())
            .then(|| CornerFiles::create(temp, info.vertices))
            .transpose()
            .map_err(io_error)?;
        let mut sink = BodySink {
            out: self,
            path,
            place,
            base,
            triangles: Vec::new(),
            progress,
        };
        let corner_out: &mut dyn CornerNormals = match &mut corners {
            Some(files) => files,
            None => &mut NoCorners,
        };
        format
            .stream(path, info, &mut sink, corner_out)
            .map_err(|e| BuildError::Invalid(e.to_string()))?;
        if self.vertices - base != info.vertices {
            return Err(BuildError::Invalid(format!(
                "{}: the file changed while it was being read",
                path.display()
            )));
        }
        if let Some(corners) = corners {
            corners.write_normals(self, place).map_err(io_error)?;
        }
        Ok(())
    }

    /// Writes every instance of every mesh of `scene`, placed.
    fn scene(&mut self, scene: &Scene, progress: &dyn Progress) -> Result<(), BuildError> {
        for instance in &scene.instances {
            let g = &scene.geometries[instance.geometry];
            let Primitives::Triangles(triangles) = &g.primitives else {
                return Err(BuildError::Invalid(format!(
                    "{}: not a triangle mesh, and only meshes are built this way",
                    g.name
                )));
            };
            let place = instance.world_from_local;
            let normal_from_local = place.matrix3.inverse().transpose();
            let base = self.vertices as u32;
            for (i, &local) in g.positions.iter().enumerate() {
                let p = place.transform_point3(local);
                if !is_buildable(p) {
                    return Err(BuildError::Invalid(
                        unbuildable(Path::new(&g.name), i as u64, p).to_string(),
                    ));
                }
                self.vertex(
                    p,
                    g.colors.as_ref().map_or(DEFAULT_COLOR, |c| c[i]),
                    g.normals
                        .as_ref()
                        .map(|n| placed_normal(n[i], place, normal_from_local)),
                )
                .map_err(io_error)?;
            }
            for t in triangles {
                self.triangle(t.map(|v| base + v)).map_err(io_error)?;
            }
            progress.advance(g.positions.len() as u64);
        }
        Ok(())
    }

    /// Writes a vertex; its normal, where it comes with it (an OBJ
    /// file's come after its vertices, by [`Writers::normal`]).
    fn vertex(&mut self, p: DVec3, color: Rgb8, normal: Option<Vec3>) -> io::Result<()> {
        self.vertices += 1;
        self.bounds = (self.bounds.0.min(p), self.bounds.1.max(p));
        for v in p.to_array() {
            self.positions.write_all(&v.to_le_bytes())?;
        }
        if let Some(out) = &mut self.colors {
            out.write_all(&color)?;
        }
        if let Some(n) = normal {
            self.normal(n)?;
        }
        Ok(())
    }

    /// Writes the next vertex normal, where the build keeps normals.
    fn normal(&mut self, normal: Vec3) -> io::Result<()> {
        if let Some(out) = &mut self.normals {
            for v in normal.to_array() {
                out.write_all(&v.to_le_bytes())?;
            }
        }
        Ok(())
    }

    fn triangle(&mut self, t: [u32; 3]) -> io::Result<()> {
        self.triangle_count += 1;
        for v in t {
            self.triangles.write_all(&v.to_le_bytes())?;
        }
        Ok(())
    }

    fn finish(self) -> io::Result<()> {
        let flush = |w: BufWriter<File>| w.into_inner().map_err(|e| e.into_error()).map(drop);
        flush(self.positions)?;
        flush(self.triangles)?;
        self.colors.map(flush).transpose()?;
        self.normals.map(flush).transpose()?;
        Ok(())
    }
}

fn f64_at(bytes: &[u8], at: usize) -> f64 {
    f64::from_le_bytes(bytes[at..at + 8].try_into().unwrap_or_default())
}

fn f32_at(bytes: &[u8], at: usize) -> f32 {
    f32::from_le_bytes(bytes[at..at + 4].try_into().unwrap_or_default())
}

impl MeshFiles {
    /// Vertex `i`'s position; `None` past the last vertex.
    pub(crate) fn position(&self, i: u32) -> Option<DVec3> {
        let at = i as usize * POSITION_BYTES;
        let b = self.positions.get(at..at + POSITION_BYTES)?;
        Some(DVec3::new(f64_at(b, 0), f64_at(b, 8), f64_at(b, 16)))
    }

    /// Every position in order, for the count.
    pub(crate) fn positions(&self) -> impl Iterator<Item = DVec3> + '_ {
        self.positions
            .chunks_exact(POSITION_BYTES)
            .map(|b| DVec3::new(f64_at(b, 0), f64_at(b, 8), f64_at(b, 16)))
    }

    /// Vertex `i`'s color, when the build carries colors.
    pub(crate) fn color(&self, i: u32) -> Option<Rgb8> {
        let at = i as usize * COLOR_BYTES;
        let b = self.colors.as_ref()?.get(at..at + COLOR_BYTES)?;
        Some([b[0], b[1], b[2]])
    }

    /// Vertex `i`'s input normal, when every mesh has them.
    pub(crate) fn normal(&self, i: u32) -> Option<Vec3> {
        let at = i as usize * NORMAL_BYTES;
        let b = self.normals.as_ref()?.get(at..at + NORMAL_BYTES)?;
        Some(Vec3::new(f32_at(b, 0), f32_at(b, 4), f32_at(b, 8)))
    }

    pub(crate) fn has_colors(&self) -> bool {
        self.colors.is_some()
    }

    pub(crate) fn has_normals(&self) -> bool {
        self.normals.is_some()
    }

    /// Reads every triangle in order, in batches.
    pub(crate) fn for_each_triangles(&self, each: &mut EachBatch<'_>) -> Result<(), BuildError> {
        let file = File::open(&self.triangles).map_err(io_error)?;
        read_triangles(file, each)
    }
}

/// What is done with each batch of triangles read.
pub(crate) type EachBatch<'a> = dyn FnMut(&[[u32; 3]]) -> Result<(), BuildError> + 'a;

/// Reads a file of triangles (3 x u32 each) in batches.
pub(crate) fn read_triangles(file: File, each: &mut EachBatch<'_>) -> Result<(), BuildError> {
    const BATCH: usize = 1 << 14;
    let mut input = BufReader::with_capacity(1 << 20, file);
    let mut bytes = vec![0u8; BATCH * TRIANGLE_BYTES];
    let mut batch = Vec::with_capacity(BATCH);
    loop {
        let read = read_full(&mut input, &mut bytes).map_err(io_error)?;
        if read % TRIANGLE_BYTES != 0 {
            return Err(BuildError::Invalid(
                "temporary files: a triangle file is not whole triangles".into(),
            ));
        }
        batch.clear();
        batch.extend(bytes[..read].chunks_exact(TRIANGLE_BYTES).map(|b| {
            let u = |at: usize| u32::from_le_bytes(b[at..at + 4].try_into().unwrap_or_default());
            [u(0), u(4), u(8)]
        }));
        if !batch.is_empty() {
            each(&batch)?;
        }
        if read < bytes.len() {
            return Ok(());
        }
    }
}

/// Fills `buffer` unless the input ends first; the bytes read.
fn read_full(input: &mut impl Read, buffer: &mut [u8]) -> io::Result<usize> {
    let mut filled = 0;
    while filled < buffer.len() {
        match input.read(&mut buffer[filled..])? {
            0 => break,
            n => filled += n,
        }
    }
    Ok(filled)
}
