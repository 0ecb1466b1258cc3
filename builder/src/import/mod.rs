//! Importers: files and generators in, one [`Scene`] out.
//!
//! Each format has its own module with one entry point `load(path) ->
//! Result<Scene, ImportError>`; [`load_input`] picks one by extension, or by
//! the `gen:NAME` prefix for the procedural [`generate`](crate::generate) scenes. After a
//! format parses, [`validate`] checks what every builder relies on (finite
//! coordinates, indices in range, something to build), so no importer has to
//! repeat those checks and no builder ever sees NaN.
//!
//! Importers produce scenes, never files: they know nothing of hierarchies.

pub(crate) mod common;
pub(crate) mod las;
pub(crate) mod obj;
pub(crate) mod off;
mod params;
mod pdb;
pub(crate) mod ply;
pub(crate) mod stream;
#[cfg(test)]
mod test_file;
pub mod up;

use std::path::{Path, PathBuf};

pub use params::Params;

use glam::DVec3;
use rayon::prelude::*;

use crate::scene::{Primitives, Scene};

/// Why an input could not become a scene. Every message names the input and,
/// where there is one, the element (line, vertex, face) that is wrong.
///
/// A cause is kept in a field named `error`, not `source`: the message
/// already prints it, and as a `source` the command line's error chain would
/// print it a second time.
#[derive(Debug, thiserror::Error)]
pub enum ImportError {
    #[error("{path}: {error}")]
    Io {
        path: PathBuf,
        error: std::io::Error,
    },
    #[error(
        "{path}: unknown input format '{extension}' (expected .obj, .ply, .off, .las, .laz, .pdb or gen:NAME)"
    )]
    UnknownFormat { path: PathBuf, extension: String },
    #[error("{path}: {element}: {message}")]
    Malformed {
        path: PathBuf,
        element: String,
        message: String,
    },
    #[error("{path}: the input holds no geometry")]
    Empty { path: PathBuf },
    #[error("gen:{name}: {message}")]
    Generator { name: String, message: String },
}

impl ImportError {
    /// Shorthand for the most common error: something at `element` is wrong.
    pub fn malformed(path: &Path, element: impl Into<String>, message: impl Into<String>) -> Self {
        Self::Malformed {
            path: path.to_owned(),
            element: element.into(),
            message: message.into(),
        }
    }

    pub fn io(path: &Path, error: std::io::Error) -> Self {
        Self::Io {
            path: path.to_owned(),
            error,
        }
    }
}

/// Loads one input: a file path, or `gen:NAME` for a generated scene.
///
/// `params` are the `--param key=value` pairs; only generators read them, and
/// a file input with params is not an error (they may be meant for another
/// input of the same build).
pub fn load_input(input: &str, params: &Params) -> Result<Scene, ImportError> {
    if let Some(name) = input.strip_prefix("gen:") {
        let scene = crate::generate::generate(name, params)?;
        validate(Path::new(input), &scene)?;
        return Ok(params.up.apply(up::InputKind::Other, scene));
    }
    let path = Path::new(input);
    let extension = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    let scene = match extension.as_str() {
        "obj" => obj::load(path)?,
        "ply" => ply::load(path)?,
        "off" => off::load(path)?,
        "las" | "laz" => las::load(path)?,
        "pdb" | "ent" => pdb::load(path)?,
        _ => {
            return Err(ImportError::UnknownFormat {
                path: path.to_owned(),
                extension,
            });
        }
    };
    validate(path, &scene)?;
    let has_faces = scene
        .geometries
        .iter()
        .any(|g| matches!(g.primitives, crate::scene::Primitives::Triangles(_)));
    Ok(params.up.apply(up::InputKind::of(input, has_faces), scene))
}

/// Loads every input and merges them into one scene (a build of several
/// files, or a tool's reference of the same inputs). A folder stands for
/// the files in it of the formats read here, in name order: a survey's
/// tiles as delivered.
pub fn load_inputs(inputs: &[String], params: &Params) -> Result<Scene, ImportError> {
    let mut scene = Scene::default();
    for input in expand_folders(inputs)? {
        scene.merge(load_input(&input, params)?);
    }
    Ok(scene)
}

/// Extensions [`load_input`] reads.
pub const READABLE: [&str; 7] = ["obj", "ply", "off", "las", "laz", "pdb", "ent"];

/// Whether a file named `name` has an extension [`load_input`] reads (any
/// case): what a folder, on disk or in a store, contributes to a build.
pub fn is_readable(name: &std::path::Path) -> bool {
    name.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| READABLE.contains(&e.to_ascii_lowercase().as_str()))
}

/// `inputs` with each folder replaced by its readable files, sorted; a
/// folder with none is an error (a wrong folder must not build nothing).
pub fn expand_folders(inputs: &[String]) -> Result<Vec<String>, ImportError> {
    let mut out = Vec::new();
    for input in inputs {
        let path = Path::new(input);
        if !path.is_dir() {
            out.push(input.clone());
            continue;
        }
        let io = |error| ImportError::Io {
            path: path.to_owned(),
            error,
        };
        let mut files = Vec::new();
        for entry in std::fs::read_dir(path).map_err(io)? {
            let file = entry.map_err(io)?.path();
            if is_readable(&file) && file.is_file() {
                files.push(file.to_string_lossy().into_owned());
            }
        }
        if files.is_empty() {
            return Err(ImportError::Empty {
                path: path.to_owned(),
            });
        }
        files.sort();
        out.extend(files);
    }
    Ok(out)
}

/// Largest coordinate (and sphere radius) a scene may have, in either
/// direction. The builders keep radii in f32 (at most about 3.4e38), so a
/// scene much larger than this built a file whose root sphere was
/// infinite, which no reader accepts; no scan, CAD model or molecule
/// comes near it.
pub const MAX_COORDINATE: f64 = 1e30;

/// Whether a position is finite and within [`MAX_COORDINATE`].
pub(crate) fn is_buildable(p: DVec3) -> bool {
    p.is_finite() && p.abs().max_element() <= MAX_COORDINATE
}

/// The error of vertex `i` of `path`, at `p`, which is not
/// [`is_buildable`].
pub(crate) fn unbuildable(path: &Path, i: u64, p: DVec3) -> ImportError {
    let what = if p.is_finite() {
        format!("is beyond ±{MAX_COORDINATE:e}, too large to build")
    } else {
        "is not a finite number".into()
    };
    ImportError::malformed(
        path,
        format!("vertex {i}"),
        format!("coordinate {what} ({}, {}, {})", p.x, p.y, p.z),
    )
}

/// Checks what the builders rely on: at least one primitive, finite
/// coordinates and radii within [`MAX_COORDINATE`], triangle indices in
/// range, channel lengths that match the positions.
pub fn validate(path: &Path, scene: &Scene) -> Result<(), ImportError> {
    if scene.instanced_primitive_count() == 0 {
        return Err(ImportError::Empty {
            path: path.to_owned(),
        });
    }
    for geometry in &scene.geometries {
        let n = geometry.positions.len();
        // On all threads: for a scanned mesh these two scans were a fifth of
        // its (otherwise serial) import. The first offender is still the
        // one reported.
        if let Some(i) = first_where(&geometry.positions, |p| !is_buildable(*p)) {
            return Err(unbuildable(path, i as u64, geometry.positions[i]));
        }
        if geometry.normals.as_ref().is_some_and(|v| v.len() != n) {
            return Err(ImportError::malformed(
                path,
                "normals",
                "count differs from vertex count",
            ));
        }
        if geometry.colors.as_ref().is_some_and(|v| v.len() != n) {
            return Err(ImportError::malformed(
                path,
                "colors",
                "count differs from vertex count",
            ));
        }
        match &geometry.primitives {
            Primitives::Triangles(triangles) => {
                let out_of_range = |tri: &[u32; 3]| tri.iter().any(|&i| i as usize >= n);
                if let Some(t) = first_where(triangles, out_of_range) {
                    let bad = triangles[t].iter().find(|&&i| i as usize >= n);
                    return Err(ImportError::malformed(
                        path,
                        format!("face {t}"),
                        format!(
                            "vertex index {} is out of range ({n} vertices)",
                            bad.copied().unwrap_or_default()
                        ),
                    ));
                }
            }
            Primitives::Points => {}
            Primitives::Spheres(radii) => {
                if radii.len() != n {
                    return Err(ImportError::malformed(
                        path,
                        "radii",
                        "count differs from sphere count",
                    ));
                }
                if let Some(i) = radii
                    .iter()
                    .position(|r| !(*r >= 0.0 && *r <= MAX_COORDINATE))
                {
                    return Err(ImportError::malformed(
                        path,
                        format!("sphere {i}"),
                        format!(
                            "radius {} is not a number from 0 to {MAX_COORDINATE:e}",
                            radii[i]
                        ),
                    ));
                }
            }
        }
    }
    for (k, instance) in scene.instances.iter().enumerate() {
        if instance.geometry >= scene.geometries.len() || !instance.world_from_local.is_finite() {
            return Err(ImportError::malformed(
                path,
                format!("instance {k}"),
                "invalid placement",
            ));
        }
    }
    Ok(())
}

/// The index of the first item for which `pred` holds, searched on all
/// threads a chunk at a time. Rayon's per-item `position_first` splits the
/// slice down to single items: on a 48 000-vertex mesh it took 4 to 20
/// times as long as a serial scan, and on 4 million items 3.6 times as long
/// as this.
fn first_where<T: Sync>(items: &[T], pred: impl Fn(&T) -> bool + Sync) -> Option<usize> {
    const CHUNK: usize = 1 << 14;
    let chunk = items
        .par_chunks(CHUNK)
        .position_first(|c| c.iter().any(&pred))?;
    let start = chunk * CHUNK;
    items[start..].iter().position(pred).map(|i| start + i)
}

#[cfg(test)]
mod tests {
    use super::first_where;
    use super::test_file::TestFile;
    use crate::cubes::{CubeOptions, build_cubes};
    use crate::{BuildOptions, PagedFile, build_spheres};
    use farfield_protocol::paged_file::read_image;

    /// A mesh file is turned Z-up by its convention (OBJ: Y-up), its
    /// normals with it; `--up z` keeps it as it is, and a point cloud in
    /// PLY is Z-up already.
    #[test]
    fn a_y_up_mesh_is_imported_z_up() {
        let text = "v 0 0 0\nv 1 0 0\nv 0 10 2\nvn 0 1 0\nf 1//1 2//1 3//1\n";
        let file = TestFile::new("tall.obj", text);
        let load = |up: super::up::Up| {
            let mut params = super::Params::default();
            params.up = up;
            let scene = super::load_input(file.path().to_str().unwrap(), &params).unwrap();
            scene.geometries[0].clone()
        };
        let turned = load(super::up::Up::Auto);
        assert_eq!(turned.positions[2], glam::DVec3::new(0.0, -2.0, 10.0));
        assert_eq!(turned.normals.as_ref().unwrap()[0], glam::Vec3::Z);
        let kept = load(super::up::Up::Z);
        assert_eq!(kept.positions[2], glam::DVec3::new(0.0, 10.0, 2.0));
        let cloud = TestFile::new(
            "cloud.ply",
            "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n0 10 2\n",
        );
        let scene = super::load_input(cloud.path().to_str().unwrap(), &Default::default()).unwrap();
        assert_eq!(
            scene.geometries[0].positions[1],
            glam::DVec3::new(0.0, 10.0, 2.0)
        );
    }

    fn read_back(file: &PagedFile) {
        let bytes = file.to_bytes();
        read_image(&bytes).expect("the built file reads back");
    }

    /// Found by the `off`, `obj` and `las` fuzz targets: a finite
    /// coordinate past f32's range (1e39 here) imported, and both builders
    /// then wrote a file whose root sphere was infinite, which every
    /// reader refuses. Coordinates at the bound build files that read back.
    #[test]
    fn coordinates_too_large_to_build_are_refused() {
        // The face's corners span x and y alike, so it keeps an area at any
        // scale (a unit-high face 1e30 long has none, and builds nothing).
        let off = |x: &str| format!("OFF\n3 1\n0 0 0\n{x} 0 0\n0 {x} 0\n3 0 1 2\n");
        for big in ["1e39", "-1e31", "1e300"] {
            let e = TestFile::new("big.off", off(big)).load_input().unwrap_err();
            assert!(
                e.to_string()
                    .contains("vertex 1: coordinate is beyond ±1e30, too large to build"),
                "{e}"
            );
        }
        let points = "OFF\n3 0\n0 0 0\n1e30 0 0\n0 -1e30 1\n".to_string();
        for text in [off("1e30"), off("-1e30"), points] {
            let scene = TestFile::new("edge.off", text).load_input().unwrap();
            read_back(
                &build_spheres(scene.clone(), &BuildOptions::default())
                    .unwrap()
                    .0,
            );
            let options = CubeOptions {
                samples: 2,
                ..CubeOptions::default()
            };
            if let Ok((file, _)) = build_cubes(scene, &options) {
                read_back(&file);
            }
        }
    }

    #[test]
    fn first_where_finds_the_first_match_in_any_chunk() {
        let mut items = vec![0u32; 100_000];
        assert_eq!(first_where(&items, |&v| v != 0), None);
        // Matches in a late chunk, then an earlier one, then at the very
        // start: each time the lowest index wins.
        items[99_999] = 1;
        items[70_000] = 1;
        assert_eq!(first_where(&items, |&v| v != 0), Some(70_000));
        items[16_385] = 1;
        assert_eq!(first_where(&items, |&v| v != 0), Some(16_385));
        items[0] = 1;
        assert_eq!(first_where(&items, |&v| v != 0), Some(0));
    }
}
