//! The inputs of an out-of-core build, read as streams of points: LAS and
//! LAZ files a batch at a time (their memory does not grow with the file),
//! and point clouds another importer has already loaded (PLY, generators),
//! handed out in batches from memory.

use std::path::PathBuf;

use glam::{DVec3, Vec3};

use crate::import::ImportError;
use crate::import::las;
use crate::scene::{Geometry, Rgb8};
use crate::spheres::leaves::DEFAULT_COLOR;

/// Points handed out per batch from memory.
const BATCH: usize = 1 << 16;

/// One batch of points: positions and, when the build has them, colors
/// and normals, all of one length.
pub(crate) struct Batch<'a> {
    pub positions: &'a [DVec3],
    pub colors: Option<&'a [Rgb8]>,
    pub normals: Option<&'a [Vec3]>,
}

/// An input of points.
#[derive(Debug)]
pub(crate) enum PointSource {
    /// A LAS or LAZ file. `wide` is learnt by the first pass: whether any
    /// color channel exceeds 255 (then all are 16-bit and divided by 257).
    Las {
        path: PathBuf,
        info: las::LasInfo,
        wide: bool,
    },
    /// A cloud already in memory (each vertex a point, placed as it is).
    Memory(Geometry),
}

impl PointSource {
    /// Points, as far as is known before reading (a LAS header's count).
    pub(crate) fn count(&self) -> u64 {
        match self {
            Self::Las { info, .. } => info.count,
            Self::Memory(g) => g.positions.len() as u64,
        }
    }

    pub(crate) fn has_color(&self) -> bool {
        match self {
            Self::Las { info, .. } => info.has_color,
            Self::Memory(g) => g.colors.is_some(),
        }
    }

    pub(crate) fn has_normals(&self) -> bool {
        match self {
            Self::Las { .. } => false,
            Self::Memory(g) => g.normals.is_some(),
        }
    }

    /// The whole input as a scene, for a build that fits in memory.
    pub(crate) fn load(
        self,
        params: &crate::import::Params,
    ) -> Result<crate::scene::Scene, ImportError> {
        match self {
            Self::Las { path, .. } => {
                crate::import::load_input(&path.display().to_string(), params)
            }
            Self::Memory(g) => Ok(crate::scene::Scene::single(g)),
        }
    }

    /// Reads every position, in batches; a LAS file's colors are looked at
    /// too, to learn whether they are 16-bit (see [`PointSource::Las`]).
    pub(crate) fn scan(
        &mut self,
        each: &mut dyn FnMut(&[DVec3]) -> Result<(), ImportError>,
    ) -> Result<(), ImportError> {
        match self {
            Self::Las { path, wide, .. } => {
                let mut any_wide = false;
                las::stream(path, &mut |positions, rgb| {
                    if let Some(rgb) = rgb {
                        any_wide |= rgb.iter().flatten().any(|&v| v > 255);
                    }
                    each(positions)
                })?;
                *wide = any_wide;
                Ok(())
            }
            Self::Memory(g) => g.positions.chunks(BATCH).try_for_each(each),
        }
    }

    /// Reads every point in batches. `colors`: whether the build carries
    /// colors (a source without them gets [`DEFAULT_COLOR`]); `normals`:
    /// whether it carries normals (only asked when every source has them).
    pub(crate) fn for_each(
        &self,
        colors: bool,
        each: &mut dyn FnMut(Batch<'_>) -> Result<(), ImportError>,
    ) -> Result<(), ImportError> {
        match self {
            Self::Las { path, wide, .. } => {
                let mut rgb8: Vec<Rgb8> = Vec::new();
                las::stream(path, &mut |positions, rgb| {
                    rgb8.clear();
                    if colors {
                        match rgb {
                            Some(rgb) => {
                                rgb8.extend(rgb.iter().map(|c| c.map(|v| las::to8(v, *wide))))
                            }
                            None => rgb8.resize(positions.len(), DEFAULT_COLOR),
                        }
                    }
                    each(Batch {
                        positions,
                        colors: colors.then_some(&rgb8[..]),
                        normals: None,
                    })
                })
                .map(|_| ())
            }
            Self::Memory(g) => {
                let defaults = vec![DEFAULT_COLOR; BATCH.min(g.positions.len())];
                for (n, positions) in g.positions.chunks(BATCH).enumerate() {
                    let range = n * BATCH..n * BATCH + positions.len();
                    let colors = colors.then(|| match &g.colors {
                        Some(c) => &c[range.clone()],
                        None => &defaults[..positions.len()],
                    });
                    each(Batch {
                        positions,
                        colors,
                        normals: g.normals.as_ref().map(|ns| &ns[range]),
                    })?;
                }
                Ok(())
            }
        }
    }
}
