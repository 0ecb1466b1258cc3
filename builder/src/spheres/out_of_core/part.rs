//! Builds on many machines, as Entwine runs them: `build --subset I/N`
//! makes part I of N (a folder), `merge` joins the N parts into the scene.
//!
//! Every part counts all the inputs (a cheap pass), so every part cuts the
//! same chunks; part I takes the I-th of N runs of consecutive chunks
//! (chunks are numbered in octree order, so a run is a region of space),
//! spreads and sizes only those (the neighbour searches, the bulk of a
//! build) and writes their leaves and radii with a manifest, `part.json`,
//! written last: a folder without one is not a part. The merge checks that
//! the parts are the N parts of one build, finds the median radius over
//! all of them, and runs the rest of a build (roots, top, levels, pages)
//! on their leaves, which it leaves in place. N parts merged are the
//! whole build made with the same budget, byte for byte.

use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::DVec3;
use serde::{Deserialize, Serialize};

use super::chunk::SizedChunk;
use super::median::RadiusMedian;
use super::phases::{self, Sized, SizedEntry};
use super::temp::TempDir;
use super::{Finished, Job, OutOfCoreStats, PointSource, join, temp_error};
use crate::BuildError;
use crate::progress::Progress;
use crate::spheres::BuildOptions;
use farfield_protocol::sphere_codec::NodeLayout;

/// The manifest's name in a part's folder.
pub const MANIFEST: &str = "part.json";
const FORMAT: &str = "farfield-part";
const VERSION: u32 = 1;

/// Bytes of a leaf in a leaves file (see `chunk`).
const LEAF_BYTES: u64 = 36;

/// Which part of how many: `I/N`, I from 1 to N.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Subset {
    pub index: u32,
    pub count: u32,
}

impl std::str::FromStr for Subset {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, String> {
        let bad = || format!("{text:?}: write the subset as I/N, I from 1 to N (2/4)");
        let (i, n) = text.split_once('/').ok_or_else(bad)?;
        let (index, count) = (
            i.trim().parse::<u32>().map_err(|_| bad())?,
            n.trim().parse::<u32>().map_err(|_| bad())?,
        );
        if index == 0 || index > count {
            return Err(bad());
        }
        Ok(Self { index, count })
    }
}

impl Subset {
    /// Whether chunk `c` of `chunks` is in this part: the parts are runs
    /// of consecutive chunks, as even as the count allows.
    fn takes(self, c: u32, chunks: u32) -> bool {
        (u64::from(c) * u64::from(self.count) / u64::from(chunks.max(1))) as u32 == self.index - 1
    }
}

/// What every part of one build has in common; the merge refuses parts
/// that differ in it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct Shared {
    /// The inputs as given, each with its size in bytes (0 for a generator).
    inputs: Vec<(String, u64)>,
    points: u64,
    chunks: u32,
    chunk_points: u64,
    colors: bool,
    normals: bool,
}

/// A chunk of a part.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct PartChunk {
    chunk: usize,
    points: u64,
    bounds_min: [f64; 3],
    bounds_max: [f64; 3],
    /// The smallest positive radius; none when no radius is positive.
    smallest_radius: Option<f32>,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
struct Manifest {
    format: String,
    version: u32,
    subset: Subset,
    shared: Shared,
    chunks: Vec<PartChunk>,
}

/// What a part's build did.
#[derive(Debug, Clone, Serialize)]
pub struct PartStats {
    pub subset: Subset,
    /// Chunks of the whole build, and of this part.
    pub chunks: u32,
    pub part_chunks: usize,
    /// Points of the whole build, and of this part.
    pub points: u64,
    pub part_points: u64,
    pub halo_points: u64,
    pub seconds_count: f64,
    pub seconds_spread: f64,
    pub seconds_chunks: f64,
}

impl Job {
    /// Builds part `subset` into the folder `out` (made if missing; it
    /// must hold no part already).
    pub fn build_subset(
        mut self,
        subset: Subset,
        out: &Path,
        progress: &dyn Progress,
    ) -> Result<PartStats, BuildError> {
        let part_error = |e: std::io::Error| {
            BuildError::Invalid(format!("{}: cannot write the part: {e}", out.display()))
        };
        std::fs::create_dir_all(out).map_err(part_error)?;
        if out.join(MANIFEST).exists() {
            return Err(BuildError::Invalid(format!(
                "{}: already holds a part; remove it or choose another folder",
                out.display()
            )));
        }
        let temp =
            TempDir::create(&self.budget.tmp).map_err(|e| temp_error(&self.budget.tmp, e))?;
        let counted = phases::count(&mut self.sources, &self.budget, progress)?;
        let chunks = counted.chunks.len() as u32;
        let takes = |c: u32| subset.takes(c, chunks);
        let spread = phases::spread(&self.sources, &counted, &temp, &takes, progress)?;
        let sized = phases::size(&spread, &counted, out, progress)?;
        let manifest = Manifest {
            format: FORMAT.into(),
            version: VERSION,
            subset,
            shared: Shared {
                inputs: self
                    .sources
                    .iter()
                    .map(|s| input_id(s, &self.names))
                    .collect(),
                points: counted.points,
                chunks,
                chunk_points: counted.chunk_points,
                colors: counted.colors,
                normals: counted.normals,
            },
            chunks: sized
                .entries
                .iter()
                .map(|e| PartChunk {
                    chunk: e.chunk,
                    points: e.sized.points,
                    bounds_min: e.sized.bounds.0.to_array(),
                    bounds_max: e.sized.bounds.1.to_array(),
                    smallest_radius: e
                        .sized
                        .smallest_radius
                        .is_finite()
                        .then_some(e.sized.smallest_radius),
                })
                .collect(),
        };
        let text = serde_json::to_string_pretty(&manifest)
            .map_err(|e| BuildError::Invalid(e.to_string()))?;
        // Written last, through a rename: its presence says the part is whole.
        let partial = out.join(format!("{MANIFEST}.partial"));
        std::fs::write(&partial, text)
            .and_then(|()| std::fs::rename(&partial, out.join(MANIFEST)))
            .map_err(part_error)?;
        Ok(PartStats {
            subset,
            chunks,
            part_chunks: sized.entries.len(),
            points: counted.points,
            part_points: sized.entries.iter().map(|e| e.sized.points).sum(),
            halo_points: spread.halo_points,
            seconds_count: counted.seconds,
            seconds_spread: spread.seconds,
            seconds_chunks: sized.seconds,
        })
    }
}

/// An input as the parts' manifests name it: its path, or the name
/// `names` gives that path.
fn input_id(source: &PointSource, names: &[(PathBuf, String)]) -> (String, u64) {
    match source {
        PointSource::Las { path, .. } => (
            names
                .iter()
                .find(|(p, _)| p == path)
                .map_or_else(|| path.display().to_string(), |(_, name)| name.clone()),
            std::fs::metadata(path).map_or(0, |m| m.len()),
        ),
        PointSource::Memory(g) => (g.name.clone(), 0),
    }
}

/// Joins `parts` (folders of `build --subset`, all N of one build, in any
/// order) into a scene; level files and pages go under `tmp`. The parts
/// are left as they are.
pub fn merge(
    parts: &[PathBuf],
    options: &BuildOptions,
    tmp: &Path,
    progress: &dyn Progress,
) -> Result<(Finished, OutOfCoreStats), BuildError> {
    let invalid =
        |part: &Path, why: String| BuildError::Invalid(format!("{}: {why}", part.display()));
    let mut manifests = Vec::with_capacity(parts.len());
    for part in parts {
        let path = part.join(MANIFEST);
        let text = std::fs::read_to_string(&path)
            .map_err(|e| invalid(part, format!("not a finished part (no {MANIFEST}: {e})")))?;
        let m: Manifest = serde_json::from_str(&text)
            .map_err(|e| invalid(part, format!("{MANIFEST} is not a part's manifest: {e}")))?;
        if m.format != FORMAT || m.version != VERSION {
            return Err(invalid(
                part,
                format!(
                    "a part of format {} {}, not {FORMAT} {VERSION}",
                    m.format, m.version
                ),
            ));
        }
        manifests.push(m);
    }
    let Some(first) = manifests.first() else {
        return Err(BuildError::Invalid("no parts to merge".into()));
    };
    let count = first.subset.count;
    let mut seen = vec![None; count as usize];
    for (m, part) in manifests.iter().zip(parts) {
        if m.shared != first.shared || m.subset.count != count {
            return Err(invalid(
                part,
                format!("a part of another build than {}", parts[0].display()),
            ));
        }
        let slot = &mut seen[(m.subset.index - 1) as usize];
        if let Some(other) = slot.replace(part) {
            return Err(invalid(
                part,
                format!(
                    "part {}/{count} again (also {})",
                    m.subset.index,
                    other.display()
                ),
            ));
        }
    }
    if let Some(missing) = seen.iter().position(Option::is_none) {
        return Err(BuildError::Invalid(format!(
            "part {}/{count} is missing",
            missing + 1
        )));
    }
    let started = Instant::now();
    let mut median = RadiusMedian::new();
    let mut entries = Vec::new();
    let mut taken = std::collections::HashSet::new();
    for (m, part) in manifests.iter().zip(parts) {
        for c in &m.chunks {
            // Each chunk from the one part whose region holds it, once.
            let owned = u32::try_from(c.chunk).is_ok_and(|id| {
                id < first.shared.chunks && m.subset.takes(id, first.shared.chunks)
            });
            if !owned || !taken.insert(c.chunk) {
                return Err(invalid(
                    part,
                    format!(
                        "its manifest names chunk {}, which is not part {}/{count}'s (the part is damaged)",
                        c.chunk, m.subset.index
                    ),
                ));
            }
            let leaves = part.join(format!("chunk-{}.leaves", c.chunk));
            let bytes = std::fs::metadata(&leaves).map_or(0, |meta| meta.len());
            if bytes != c.points * LEAF_BYTES {
                return Err(invalid(
                    part,
                    format!(
                        "{} holds {bytes} bytes, not the {} of its {} points",
                        leaves.display(),
                        c.points * LEAF_BYTES,
                        c.points
                    ),
                ));
            }
            median
                .add_file(&part.join(format!("chunk-{}.radii", c.chunk)))
                .map_err(|e| invalid(part, e.to_string()))?;
            entries.push(SizedEntry {
                chunk: c.chunk,
                sized: SizedChunk {
                    points: c.points,
                    bounds: (
                        DVec3::from_array(c.bounds_min),
                        DVec3::from_array(c.bounds_max),
                    ),
                    smallest_radius: c.smallest_radius.unwrap_or(f32::INFINITY),
                },
                leaves,
            });
        }
    }
    let seconds = started.elapsed().as_secs_f64();
    let temp = TempDir::create(tmp).map_err(|e| temp_error(tmp, e))?;
    let layout = NodeLayout {
        normals: true,
        color: first.shared.colors,
    };
    let sized = Sized {
        input_vertices: entries.iter().map(|e| e.sized.points).sum(),
        entries,
        median,
        seconds,
    };
    let (file, joined) = join::join(sized, layout, options, &temp, false, progress)?;
    let build = joined.stats(file.header.page_count as usize, layout, 0.0);
    Ok((
        Finished { file, _temp: temp },
        OutOfCoreStats {
            build,
            chunks: joined.chunks,
            chunk_points: first.shared.chunk_points,
            halo_points: 0,
            grid_side: 0,
            seconds_count: 0.0,
            seconds_spread: 0.0,
            seconds_chunks: joined.seconds_sizes + joined.seconds_roots,
            seconds_top: joined.seconds_top,
            seconds_levels: joined.seconds_levels,
            seconds_pages: joined.seconds_pages,
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn subsets_parse_and_split_the_chunks_into_runs() {
        assert_eq!("2/4".parse(), Ok(Subset { index: 2, count: 4 }));
        for bad in ["0/4", "5/4", "2", "a/4", "2/b", ""] {
            assert!(bad.parse::<Subset>().is_err(), "{bad:?} accepted");
        }
        // Every chunk in exactly one part, the parts runs in order.
        for (chunks, count) in [(10u32, 3u32), (3, 4), (1, 1), (64, 7)] {
            let mut owner = Vec::new();
            for c in 0..chunks {
                let parts: Vec<u32> = (1..=count)
                    .filter(|&i| Subset { index: i, count }.takes(c, chunks))
                    .collect();
                assert_eq!(parts.len(), 1, "chunk {c} of {chunks} in {parts:?}");
                owner.push(parts[0]);
            }
            assert!(owner.windows(2).all(|w| w[0] <= w[1]), "{owner:?}");
        }
    }
}
