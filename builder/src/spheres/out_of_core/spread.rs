//! Points spread to their chunks' files, and read back a chunk at a time.
//!
//! A record is the point's position (3 x f64: positions stay exact), its
//! color, a flag byte (bit 0: a halo copy, there only for its neighbours)
//! and, when the build has them, its normal (3 x f32). Each chunk's records
//! gather in a buffer that is appended to the chunk's file when full
//! ([`ChunkFiles`], which meshes' triangles share).

use std::fs::OpenOptions;
use std::io::{self, Read, Write};
use std::path::{Path, PathBuf};

use glam::{DVec3, Vec3};

use super::source::Batch;
use crate::scene::Rgb8;

/// One chunk's points as read back: its own, then its halo.
#[derive(Debug, Default)]
pub(crate) struct ChunkPoints {
    pub positions: Vec<DVec3>,
    pub colors: Vec<Rgb8>,
    pub normals: Vec<Vec3>,
    /// How many of the points, from the start, are the chunk's own.
    pub own: usize,
}

/// The record's size in bytes.
fn record_bytes(normals: bool) -> usize {
    24 + 4 + if normals { 12 } else { 0 }
}

/// A buffer per chunk, appended to the chunk's file when full: the file
/// is opened only for that, so thousands of chunks never hold thousands of
/// open files.
pub(crate) struct ChunkFiles {
    paths: Vec<PathBuf>,
    buffers: Vec<Vec<u8>>,
    buffer_bytes: usize,
}

impl ChunkFiles {
    /// `paths`: a file per chunk (made by the first append); `buffer_bytes`
    /// per chunk before it is written out.
    pub(crate) fn new(paths: Vec<PathBuf>, buffer_bytes: usize) -> Self {
        let buffers = (0..paths.len()).map(|_| Vec::new()).collect();
        Self {
            paths,
            buffers,
            buffer_bytes,
        }
    }

    /// The buffer of `chunk`, to append a record to; call
    /// [`ChunkFiles::written`] after.
    pub(crate) fn buffer(&mut self, chunk: u32) -> &mut Vec<u8> {
        &mut self.buffers[chunk as usize]
    }

    /// Writes out `chunk`'s buffer if it is full.
    pub(crate) fn written(&mut self, chunk: u32) -> io::Result<()> {
        if self.buffers[chunk as usize].len() >= self.buffer_bytes {
            self.flush(chunk as usize)?;
        }
        Ok(())
    }

    fn flush(&mut self, chunk: usize) -> io::Result<()> {
        let buffer = &mut self.buffers[chunk];
        if buffer.is_empty() {
            return Ok(());
        }
        let mut file = OpenOptions::new()
            .create(true)
            .append(true)
            .open(&self.paths[chunk])?;
        file.write_all(buffer)?;
        buffer.clear();
        Ok(())
    }

    /// Writes out every buffer.
    pub(crate) fn finish(mut self) -> io::Result<()> {
        for chunk in 0..self.paths.len() {
            self.flush(chunk)?;
            self.buffers[chunk] = Vec::new();
        }
        Ok(())
    }
}

/// Writes points to their chunks' files.
pub(crate) struct Spreader {
    files: ChunkFiles,
    colors: bool,
    normals: bool,
    /// Records written, own and halo.
    pub(crate) written: u64,
    pub(crate) halo: u64,
}

impl Spreader {
    /// `paths`: a file per chunk (made by the first append); `buffer_bytes`
    /// per chunk before it is written out.
    pub(crate) fn new(
        paths: Vec<PathBuf>,
        buffer_bytes: usize,
        colors: bool,
        normals: bool,
    ) -> Self {
        Self {
            files: ChunkFiles::new(paths, buffer_bytes.max(record_bytes(normals))),
            colors,
            normals,
            written: 0,
            halo: 0,
        }
    }

    /// Adds the `i`th point of `batch` to `chunk` (as a halo copy when
    /// `halo`).
    pub(crate) fn add(
        &mut self,
        chunk: u32,
        batch: &Batch<'_>,
        i: usize,
        halo: bool,
    ) -> io::Result<()> {
        let buffer = self.files.buffer(chunk);
        for v in batch.positions[i].to_array() {
            buffer.extend_from_slice(&v.to_le_bytes());
        }
        let rgb = match (self.colors, batch.colors) {
            (true, Some(c)) => c[i],
            _ => [0; 3],
        };
        buffer.extend_from_slice(&rgb);
        buffer.push(u8::from(halo));
        if self.normals {
            let n = batch.normals.map_or(Vec3::Z, |ns| ns[i]);
            for v in n.to_array() {
                buffer.extend_from_slice(&v.to_le_bytes());
            }
        }
        self.written += 1;
        self.halo += u64::from(halo);
        self.files.written(chunk)
    }

    /// Writes out every buffer.
    pub(crate) fn finish(self) -> io::Result<()> {
        self.files.finish()
    }
}

/// Reads a chunk's file back, its own points first; the file is removed.
/// Records are read through a buffer, not the whole file at once: a
/// chunk's points are its build's largest input and are held only once.
pub(crate) fn read_chunk(path: &Path, colors: bool, normals: bool) -> io::Result<ChunkPoints> {
    let file = std::fs::File::open(path)?;
    let bytes = file.metadata()?.len();
    let size = record_bytes(normals);
    if bytes % size as u64 != 0 {
        return Err(io::Error::other(format!(
            "{}: a chunk file of {bytes} bytes is not whole records",
            path.display()
        )));
    }
    let count = (bytes / size as u64) as usize;
    let mut input = io::BufReader::with_capacity(1 << 20, file);
    let mut own = ChunkPoints::default();
    let mut halo = ChunkPoints::default();
    own.positions.reserve(count);
    let mut record = vec![0u8; size];
    for _ in 0..count {
        input.read_exact(&mut record)?;
        let f64_at =
            |at: usize| f64::from_le_bytes(record[at..at + 8].try_into().unwrap_or_default());
        let f32_at =
            |at: usize| f32::from_le_bytes(record[at..at + 4].try_into().unwrap_or_default());
        let into = if record[27] & 1 != 0 {
            &mut halo
        } else {
            &mut own
        };
        into.positions
            .push(DVec3::new(f64_at(0), f64_at(8), f64_at(16)));
        if colors {
            into.colors.push([record[24], record[25], record[26]]);
        }
        if normals {
            into.normals
                .push(Vec3::new(f32_at(28), f32_at(32), f32_at(36)));
        }
    }
    drop(input);
    std::fs::remove_file(path)?;
    own.own = own.positions.len();
    own.positions.append(&mut halo.positions);
    own.colors.append(&mut halo.colors);
    own.normals.append(&mut halo.normals);
    Ok(own)
}
