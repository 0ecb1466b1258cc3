//! Wavefront OBJ: a hand-written line parser, run on all threads.
//!
//! - `v x y z [w]` gives a position; `v x y z r g b` also a color. Colors are
//!   kept only when every vertex has one; they are 0..1 floats, or 0..255
//!   when any component exceeds 1.
//! - `vn` gives a normal. OBJ normals belong to face corners; the first
//!   corner that names a vertex gives that vertex its normal, and normals are
//!   kept only when every vertex used by a face got one.
//! - `f` takes corners `i`, `i/t`, `i//n` or `i/t/n`, 1-based or negative
//!   (relative to the last vertex so far); polygons are fan-triangulated.
//! - A file with vertices and no faces becomes a point cloud.
//! - `vt`, `o`, `g`, `s`, `usemtl`, `mtllib`, `l`, `p`, comments and unknown
//!   statements are ignored; line continuations (`\`) are not supported.
//!
//! The file is read in blocks of whole lines ([`BLOCK_BYTES`], so memory
//! stays bounded for any file size, a pipe included). A first quick pass
//! over a block counts, for each of a few parts of it, its lines, vertices
//! and normals; then the parts are parsed on all threads
//! ([`part::parse`]), each knowing how many vertices and normals precede
//! it, so negative indices and range checks see exactly what a reader from
//! the top sees; then the parts are appended in file order ([`Obj`]), which
//! keeps "the first corner wins" and "the first error is reported" as a
//! serial reader has them. Lines are checked as text once, not per word; a
//! line that is not UTF-8 reads with replacement characters, harmless in a
//! comment and a clear "not a number" in a statement.

mod part;

use std::fs::File;
use std::io::Read;
use std::path::Path;

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::ImportError;
use super::common::{unit_color, unit_normals};
use super::stream::{BodyOut, CornerNormals, MeshInfo, Vertices};
use crate::scene::{Geometry, Primitives, Scene};
use part::{Counts, Part};

/// Bytes of text read and parsed at a time (whole lines; a longer line
/// grows the block). Small, because the block and what its parts decode to
/// are held beside everything read before: with 1 MiB blocks beast.obj's
/// peak memory was about 10 bytes per vertex higher; 256 KiB is still
/// dozens of parts of whole lines, as fast.
const BLOCK_BYTES: usize = 1 << 18;

/// Parts a block is cut into per thread: a few, so a part of long lines
/// does not leave the other threads idle.
const PARTS_PER_THREAD: usize = 4;

/// Loads an OBJ file as one geometry: triangles, or points when it has no
/// faces.
pub fn load(path: &Path) -> Result<Scene, ImportError> {
    load_in_blocks(path, BLOCK_BYTES)
}

/// [`load`], reading `block_bytes` at a time (small in tests, to cut lines,
/// parts and blocks everywhere).
fn load_in_blocks(path: &Path, block_bytes: usize) -> Result<Scene, ImportError> {
    let mut obj = Obj::default();
    read_blocks(path, block_bytes, &mut obj)?;
    Ok(Scene::single(obj.finish(path)))
}

/// What an OBJ file holds, as [`load`] would keep it: a parse of the whole
/// file that keeps only counts and flags.
pub(crate) fn survey(path: &Path) -> Result<MeshInfo, ImportError> {
    let mut survey = Survey::default();
    read_blocks(path, BLOCK_BYTES, &mut survey)?;
    Ok(survey.info())
}

/// Reads an OBJ file into `out` a block at a time, as [`load`] reads it,
/// given what [`survey`] found: vertices (with colors, scaled as `load`
/// scales them, where `info` keeps them), triangles, and, where `info`
/// keeps normals, the normals and the corners that give them to vertices
/// to `corners`.
pub(crate) fn stream(
    path: &Path,
    info: &MeshInfo,
    out: &mut dyn BodyOut,
    corners: &mut dyn CornerNormals,
) -> Result<(), ImportError> {
    let mut stream = Stream {
        path,
        info,
        out,
        corners,
    };
    read_blocks(path, BLOCK_BYTES, &mut stream)
}

/// Where parsed parts go, in file order.
trait Parts {
    fn append(&mut self, part: Part) -> Result<(), ImportError>;
}

/// Reads `path` in blocks of whole lines of about `block_bytes`, each
/// parsed on all threads, into `out`.
fn read_blocks(path: &Path, block_bytes: usize, out: &mut dyn Parts) -> Result<(), ImportError> {
    let mut file = File::open(path).map_err(|e| ImportError::io(path, e))?;
    // A small file is one block of its own size, not a whole empty block;
    // a pipe has no size, and gets whole blocks.
    let file_bytes = file
        .metadata()
        .ok()
        .filter(|m| m.is_file())
        .map_or(u64::MAX, |m| m.len());
    let block_bytes = block_bytes.min(usize::try_from(file_bytes).unwrap_or(usize::MAX).max(1));
    let mut before = Counts::default();
    let mut block: Vec<u8> = Vec::new();
    let mut at_end = false;
    while !at_end {
        // Top the block up, after the unfinished line carried over; a line
        // longer than a block doubles it.
        let want = if block.len() < block_bytes {
            block_bytes - block.len()
        } else {
            block.len()
        };
        block.reserve_exact(want);
        let read = (&mut file)
            .take(want as u64)
            .read_to_end(&mut block)
            .map_err(|e| ImportError::io(path, e))?;
        at_end = read < want;
        // Whole lines only, unless the file ends here.
        let whole = if at_end {
            block.len()
        } else {
            match block.iter().rposition(|&b| b == b'\n') {
                Some(last) => last + 1,
                // One line longer than the block: read on with a larger one.
                None => continue,
            }
        };
        before = add_block(&block[..whole], before, out).map_err(|e| match e {
            BlockError::Line(line, msg) => {
                ImportError::malformed(path, format!("line {line}"), msg)
            }
            BlockError::Out(e) => e,
        })?;
        block.drain(..whole);
    }
    Ok(())
}

/// Why a block could not be added.
enum BlockError {
    /// A malformed line: its number (from 1) and what is wrong.
    Line(u64, String),
    /// Where the parts go refused one.
    Out(ImportError),
}

/// Parses a block of whole lines, which follows what `before` counts, on
/// all threads, and appends its parts to `out` in order; what precedes
/// the next block.
fn add_block(block: &[u8], before: Counts, out: &mut dyn Parts) -> Result<Counts, BlockError> {
    let parts = rayon::current_num_threads().max(1) * PARTS_PER_THREAD;
    let ranges = part::cut(block, parts);
    // What precedes each part: the counts of those before it.
    let counts: Vec<Counts> = ranges
        .par_iter()
        .map(|r| part::count(&block[r.clone()]))
        .collect();
    let mut after = before;
    let mut starts = Vec::with_capacity(counts.len());
    for c in &counts {
        starts.push(after);
        after = after.plus(c);
    }
    if after.vertices > u64::from(u32::MAX) {
        let line = starts.last().map_or(before.lines, |s| s.lines) + 1;
        return Err(BlockError::Line(
            line,
            "too many vertices for 32-bit indices".into(),
        ));
    }
    let parsed: Vec<Result<Part, (u64, String)>> = ranges
        .par_iter()
        .zip(&starts)
        .map(|(r, start)| part::parse(&block[r.clone()], start))
        .collect();
    for (result, count) in parsed.into_iter().zip(&counts) {
        let part = result.map_err(|(line, msg)| BlockError::Line(line, msg))?;
        // The offsets given to later parts came from the counting pass.
        debug_assert_eq!(part.positions.len() as u64, count.vertices);
        debug_assert_eq!(part.normals.len() as u64, count.normals);
        out.append(part).map_err(BlockError::Out)?;
    }
    Ok(after)
}

/// The geometry read so far: parts are appended to it in file order.
#[derive(Default)]
struct Obj {
    positions: Vec<DVec3>,
    /// Colors as read, while every vertex so far had one.
    colors: Option<Vec<[f64; 3]>>,
    normals: Vec<Vec3>,
    /// Per vertex: index into `normals`, or `u32::MAX` when none yet.
    vertex_normal: Vec<u32>,
    /// A face corner had no normal.
    corner_without_normal: bool,
    triangles: Vec<[u32; 3]>,
}

impl Parts for Obj {
    fn append(&mut self, part: Part) -> Result<(), ImportError> {
        self.extend(part);
        Ok(())
    }
}

impl Obj {
    fn extend(&mut self, part: Part) {
        let first_vertex = self.positions.len();
        self.positions.extend_from_slice(&part.positions);
        self.colors = match (self.colors.take(), part.colors) {
            (Some(mut all), Some(more)) => {
                all.extend_from_slice(&more);
                Some(all)
            }
            // The first vertices decide whether colors are read at all.
            (None, Some(more)) if first_vertex == 0 => Some(more),
            (all, None) if part.positions.is_empty() => all,
            _ => None,
        };
        self.normals.extend_from_slice(&part.normals);
        self.vertex_normal.resize(self.positions.len(), u32::MAX);
        for (v, n) in part.corner_normals {
            let slot = &mut self.vertex_normal[v as usize];
            if *slot == u32::MAX {
                *slot = n;
            }
        }
        self.corner_without_normal |= part.corner_without_normal;
        self.triangles.extend_from_slice(&part.triangles);
    }

    fn finish(self, path: &Path) -> Geometry {
        let Obj {
            positions,
            colors,
            normals,
            vertex_normal,
            triangles,
            corner_without_normal,
            ..
        } = self;
        let primitives = if triangles.is_empty() {
            Primitives::Points
        } else {
            Primitives::Triangles(triangles)
        };
        let normals = match &primitives {
            Primitives::Triangles(t) if !corner_without_normal => {
                // Vertices no face uses may lack a normal: they get a zero one,
                // which `unit_normals` replaces.
                let n = vertex_normal
                    .iter()
                    .map(|&i| normals.get(i as usize).copied().unwrap_or(Vec3::ZERO));
                unit_normals(n.collect(), &positions, Some(t))
            }
            _ => None,
        };
        let colors = colors.filter(|c| c.len() == positions.len()).map(|c| {
            let scale = color_scale(c.iter().flatten().fold(0.0f64, |m, &v| m.max(v)));
            c.iter()
                .map(|rgb| rgb.map(|v| unit_color(v * scale)))
                .collect()
        });
        let mut geometry = Geometry::new(path.display().to_string(), positions, primitives);
        geometry.normals = normals;
        geometry.colors = colors;
        geometry
    }
}

/// What [`survey`] gathers from each part.
struct Survey {
    vertices: u64,
    triangles: bool,
    /// Every vertex so far had a color, and the largest component.
    all_colored: bool,
    color_max: f64,
    corner_without_normal: bool,
}

impl Default for Survey {
    fn default() -> Self {
        Self {
            vertices: 0,
            triangles: false,
            all_colored: true,
            color_max: 0.0,
            corner_without_normal: false,
        }
    }
}

impl Parts for Survey {
    fn append(&mut self, part: Part) -> Result<(), ImportError> {
        self.vertices += part.positions.len() as u64;
        self.triangles |= !part.triangles.is_empty();
        self.corner_without_normal |= part.corner_without_normal;
        match &part.colors {
            Some(colors) => {
                self.color_max = colors
                    .iter()
                    .flatten()
                    .fold(self.color_max, |m, &v| m.max(v));
            }
            None if !part.positions.is_empty() => self.all_colored = false,
            None => {}
        }
        Ok(())
    }
}

impl Survey {
    /// What [`Obj::finish`] would keep.
    fn info(&self) -> MeshInfo {
        MeshInfo {
            vertices: self.vertices,
            triangles: self.triangles,
            normals: self.triangles && !self.corner_without_normal,
            colors: self.all_colored && self.vertices > 0,
            color_scale: color_scale(self.color_max),
        }
    }
}

/// What OBJ colors are multiplied by to be 0..1: they are 0..1 floats, or
/// 0..255 when any component exceeds 1.
fn color_scale(max: f64) -> f64 {
    if max > 1.0 { 1.0 / 255.0 } else { 1.0 }
}

/// Parts handed on to a build's files as they come (see [`stream`]).
struct Stream<'a> {
    path: &'a Path,
    info: &'a MeshInfo,
    out: &'a mut dyn BodyOut,
    corners: &'a mut dyn CornerNormals,
}

impl Parts for Stream<'_> {
    fn append(&mut self, part: Part) -> Result<(), ImportError> {
        let Part {
            positions,
            colors,
            normals,
            corner_normals,
            triangles,
            ..
        } = part;
        let colors = match (self.info.colors, colors) {
            (false, _) => None,
            (true, Some(colors)) => Some(
                colors
                    .iter()
                    .map(|rgb| rgb.map(|v| unit_color(v * self.info.color_scale)))
                    .collect(),
            ),
            (true, None) if positions.is_empty() => Some(Vec::new()),
            (true, None) => {
                return Err(ImportError::malformed(
                    self.path,
                    "body",
                    "the file changed while it was being read",
                ));
            }
        };
        if !positions.is_empty() {
            self.out.vertices(Vertices {
                positions,
                normals: None,
                colors,
            })?;
        }
        if self.info.normals {
            self.corners.table(&normals)?;
            self.corners.corners(&corner_normals)?;
        }
        if !triangles.is_empty() {
            self.out.triangles().extend_from_slice(&triangles);
            self.out.triangles_done()?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::import::test_file::TestFile;

    fn load_text(text: &str) -> Result<Geometry, ImportError> {
        load_text_in_blocks(text, BLOCK_BYTES)
    }

    fn load_text_in_blocks(text: &str, block_bytes: usize) -> Result<Geometry, ImportError> {
        let file = TestFile::new("t.obj", text);
        let result = load_in_blocks(file.path(), block_bytes);
        result.map(|s| s.geometries.into_iter().next().unwrap())
    }

    /// A mesh with every feature whose meaning depends on what came
    /// before: colors, negative indices, first-corner normals (on every
    /// corner, or not).
    fn tricky(colored_to_the_end: bool, all_normals: bool) -> String {
        let mut text = String::from("# a grid\r\n");
        for y in 0..12 {
            for x in 0..12 {
                let color = if colored_to_the_end || y < 6 {
                    " 0.5 1 0.25"
                } else {
                    ""
                };
                text += &format!("v {x} {y} {}{color}\n", (x * y) % 5);
                if x % 5 == 0 {
                    text += &format!("vn 0 {} 1\n", f64::from(x) * 0.1);
                }
            }
            if y > 0 {
                for x in 0..11 {
                    let (a, b) = (y * 12 + x - 11, y * 12 + x + 1);
                    let n = if all_normals { "//2" } else { "" };
                    match x % 3 {
                        0 => text += &format!("f {a}//1 {}{n} {b}/1/2 -1//3\n", a + 1),
                        1 => text += &format!("  f\t-{}{n} {}//3 {b}//2\n", 12 - x, a + 1),
                        _ => text += &format!("f {a}/5/1 {}/5/3 {b}/5/2 {}//1\n", a + 1, b - 1),
                    }
                }
            }
        }
        text + "vt 0 0\nf 1//1 2//1 -1//2"
    }

    #[test]
    fn any_block_size_reads_the_same_geometry() {
        for (colored, all_normals) in [(true, true), (false, true), (true, false)] {
            let text = tricky(colored, all_normals);
            let whole = load_text(&text).unwrap();
            assert!(tris(&whole).len() > 150, "{}", tris(&whole).len());
            assert_eq!(whole.colors.is_some(), colored);
            assert_eq!(whole.normals.is_some(), all_normals);
            for block in [1, 7, 64, 1000] {
                let cut = load_text_in_blocks(&text, block).unwrap();
                assert_eq!(cut.positions, whole.positions, "block {block}");
                assert_eq!(tris(&cut), tris(&whole), "block {block}");
                assert_eq!(cut.normals, whole.normals, "block {block}");
                assert_eq!(cut.colors, whole.colors, "block {block}");
            }
        }
    }

    #[test]
    fn the_first_error_is_reported_at_its_line_in_any_block() {
        let mut text = tricky(true, true);
        let lines = text.lines().count();
        text += "\nf 1 2 999999\nv 1 2\n";
        for block in [7, 64, 1000, BLOCK_BYTES] {
            let e = load_text_in_blocks(&text, block).unwrap_err().to_string();
            assert!(
                e.ends_with(&format!(
                    "line {}: vertex index 999999 is out of range (144 defined so far)",
                    lines + 1
                )),
                "block {block}: {e}"
            );
        }
    }

    fn tris(g: &Geometry) -> &[[u32; 3]] {
        match &g.primitives {
            Primitives::Triangles(t) => t,
            p => panic!("not triangles: {p:?}"),
        }
    }

    const SQUARE: &str = "# square\nmtllib x.mtl\no sq\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0.5\n\
        vt 0 0\nvn 0 0 3\nvn 0 0 -1\ng g\nusemtl m\ns off\n";

    #[test]
    fn faces_fans_and_negative_indices() {
        let g = load_text(&format!("{SQUARE}f 1 2 3 4\nf -4/1 -2/1 -1/1\n")).unwrap();
        assert_eq!(g.positions[3], DVec3::new(0.0, 1.0, 0.5));
        assert_eq!(tris(&g), &[[0, 1, 2], [0, 2, 3], [0, 2, 3]]);
        assert!(g.normals.is_none() && g.colors.is_none());
    }

    #[test]
    fn normals_first_corner_wins() {
        let g = load_text(&format!(
            "{SQUARE}f 1//1 2/1/1 3//2 4//1\nf 3//1 4//1 1//2\n"
        ))
        .unwrap();
        let n = g.normals.unwrap();
        assert_eq!(n, vec![Vec3::Z, Vec3::Z, -Vec3::Z, Vec3::Z]);
        // One corner without a normal drops them all.
        let g = load_text(&format!("{SQUARE}f 1//1 2//1 3//2\nf 1//1 3 4//1\n")).unwrap();
        assert!(g.normals.is_none());
    }

    #[test]
    fn colors_and_points() {
        let g = load_text("v 0 0 0 1 0.5 0\nv 1 2 3 0 0 1\r\nv 4 5 6 0.2 0.2 0.2\n").unwrap();
        assert_eq!(g.primitives, Primitives::Points);
        assert_eq!(g.positions[1], DVec3::new(1.0, 2.0, 3.0));
        assert_eq!(
            g.colors.unwrap(),
            vec![[255, 128, 0], [0, 0, 255], [51, 51, 51]]
        );
        let g = load_text("v 0 0 0 255 0 0\nv 1 2 3 0 0 1\n").unwrap();
        assert_eq!(g.colors.unwrap(), vec![[255, 0, 0], [0, 0, 1]]);
        let g = load_text("v 0 0 0 1 0.5 0\nv 1 2 3\nv 1 2 3 1 1 1\n").unwrap();
        assert!(g.colors.is_none());
    }

    #[test]
    fn bad_inputs() {
        let e = |text: &str| load_text(text).unwrap_err().to_string();
        assert!(matches!(
            load(Path::new("/nonexistent/x.obj")),
            Err(ImportError::Io { .. })
        ));
        let msg = e(&format!("{SQUARE}f 1 2 5\n"));
        assert!(
            msg.ends_with("line 14: vertex index 5 is out of range (4 defined so far)"),
            "{msg}"
        );
        assert!(
            e(&format!("{SQUARE}f 1 2 -5\n")).contains("line 14: vertex index -5 is out of range")
        );
        assert!(e(&format!("{SQUARE}f 0 1 2\n")).contains("line 14: vertex index 0"));
        assert!(e(&format!("{SQUARE}f 1//3 2 3\n")).contains("normal index 3 is out of range"));
        assert!(e(&format!("{SQUARE}f 1 2\n")).contains("line 14: a face needs at least 3"));
        assert!(e(&format!("{SQUARE}f 1 2 x\n")).contains("'x' is not a vertex index"));
        assert!(e("v 1 2 1e999x\n").ends_with("line 1: '1e999x' is not a number"));
        assert!(e("v 1 2\n").contains("line 1: a vertex needs x, y and z"));
        assert!(e("vn 1 2\n").contains("a normal needs"));
    }

    #[test]
    fn nan_is_rejected_by_validate() {
        let file = TestFile::new("nan.obj", "v 0 0 0\nv NaN 0 0\nv 0 1 0\nf 1 2 3\n");
        let e = file.load_input().unwrap_err();
        assert!(
            e.to_string()
                .contains("vertex 1: coordinate is not a finite number"),
            "{e}"
        );
    }
}
