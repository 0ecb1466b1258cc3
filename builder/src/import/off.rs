//! Geomview OFF, ASCII only.
//!
//! The header keyword is `OFF` with optional prefixes `ST` (texture
//! coordinates, skipped), `C` (vertex colors) and `N` (vertex normals), so
//! `OFF`, `COFF`, `NOFF`, `CNOFF`/`NCOFF`; it may be left out, and the counts
//! `vertices faces [edges]` may follow it on the same line. A vertex line is
//! `x y z [nx ny nz] [r g b [a]] [s t]`, colors as 0..1 floats or, when any
//! component exceeds 1, 0..255. A face line is `n i0 ... i(n-1)` and an
//! optional face color, which is ignored; faces are fan-triangulated.
//! `#` starts a comment anywhere. Vertices and faces are one per line (every
//! OFF writer does this, and trailing face colors need it). `4OFF`, `nOFF`
//! and `OFF BINARY` are refused.

use std::fs::File;
use std::io::{self, BufRead, BufReader};
use std::path::Path;

use glam::{DVec3, Vec3};

use super::ImportError;
use super::common::{fan, unit_color};
use super::stream::{BodyOut, Gather, MeshInfo, Vertices};
use crate::scene::Scene;

/// Loads an OFF file as one triangle mesh (a point cloud if it has no faces).
pub fn load(path: &Path) -> Result<Scene, ImportError> {
    let mut gather = Gather::default();
    read(path, survey(path)?.color_scale, &mut gather)?;
    Ok(Scene::single(gather.into_geometry(path)))
}

/// What an OFF file's header says of it; a file with colors has its
/// vertices read too, to know their scale.
pub(crate) fn survey(path: &Path) -> Result<MeshInfo, ImportError> {
    let (mut lines, header) = open(path)?;
    let mut max = 0.0f64;
    if header.layout.color {
        for_each_vertex(path, &mut lines, &header, |(_, _, c)| {
            max = c.into_iter().flatten().fold(max, f64::max);
            Ok(())
        })?;
    }
    Ok(MeshInfo {
        vertices: header.vertices,
        triangles: header.faces > 0,
        normals: header.layout.normal,
        colors: header.layout.color,
        color_scale: if max > 1.0 { 1.0 / 255.0 } else { 1.0 },
    })
}

/// Reads an OFF file's vertices and triangles into `out` a batch at a
/// time (see [`BodyOut::batch`]), as [`load`] reads them, given what
/// [`survey`] found.
pub(crate) fn stream(
    path: &Path,
    info: &MeshInfo,
    out: &mut dyn BodyOut,
) -> Result<(), ImportError> {
    read(path, info.color_scale, out)
}

/// The header: which values a vertex line holds, and the counts.
struct Header {
    layout: Layout,
    vertices: u64,
    faces: u64,
    /// The file's length, a bound on what is allocated ahead of reading.
    file_len: u64,
}

/// Opens an OFF file and reads its header; the lines after it.
fn open(path: &Path) -> Result<(Lines<BufReader<File>>, Header), ImportError> {
    let file = File::open(path).map_err(|e| ImportError::io(path, e))?;
    let file_len = file.metadata().map(|m| m.len()).unwrap_or(0);
    let mut lines = Lines {
        r: BufReader::with_capacity(1 << 20, file),
        buf: Vec::new(),
        end: 0,
        no: 0,
    };
    let io = |e| ImportError::io(path, e);
    let header = |msg: &str| ImportError::malformed(path, "header", msg);
    let first = owned_words(
        lines
            .next()
            .map_err(io)?
            .ok_or_else(|| header("the file is empty"))?,
    );
    let (keyword, rest) = match first.split_first() {
        Some((w, rest)) if w.ends_with("OFF") => (w.strip_suffix("OFF").unwrap_or_default(), rest),
        Some((w, _)) if w.parse::<u64>().is_ok() => ("", &first[..]),
        _ => return Err(header("not an OFF file (no OFF keyword or counts)")),
    };
    let (mut st, mut color, mut normal) = (false, false, false);
    for c in keyword.chars() {
        match c {
            'S' | 'T' => st = true,
            'C' => color = true,
            'N' => normal = true,
            '4' | 'n' => return Err(header("4D and nD OFF are not supported")),
            _ => return Err(header("not an OFF file (unknown keyword)")),
        }
    }
    if rest.first().is_some_and(|w| w == "BINARY") {
        return Err(header("binary OFF is not supported"));
    }
    let counts = match rest {
        [] => owned_words(
            lines
                .next()
                .map_err(io)?
                .ok_or_else(|| header("the file ends before the counts"))?,
        ),
        _ => rest.to_vec(),
    };
    let count = |i: usize| {
        let w = counts
            .get(i)
            .ok_or_else(|| header("the counts line needs vertex and face counts"))?;
        w.parse::<u64>()
            .map_err(|_| header("counts are not numbers"))
    };
    let (vertices, faces) = (count(0)?, count(1)?);
    if vertices > u64::from(u32::MAX) {
        return Err(header("too many vertices for 32-bit indices"));
    }
    let layout = Layout { st, color, normal };
    Ok((
        lines,
        Header {
            layout,
            vertices,
            faces,
            file_len,
        },
    ))
}

/// Reads the file into `out`, its colors multiplied by `color_scale`.
fn read(path: &Path, color_scale: f64, out: &mut dyn BodyOut) -> Result<(), ImportError> {
    let (mut lines, header) = open(path)?;
    let batch = out.batch().min(header.vertices).min(header.file_len / 6) as usize;
    let (normal, color) = (header.layout.normal, header.layout.color);
    let empty = || Vertices {
        positions: Vec::with_capacity(batch),
        normals: normal.then(|| Vec::with_capacity(batch)),
        colors: color.then(|| Vec::with_capacity(batch)),
    };
    let mut vertices = empty();
    let mut handed = 0u64;
    for_each_vertex(path, &mut lines, &header, |(p, n, c)| {
        vertices.positions.push(p);
        vertices
            .normals
            .iter_mut()
            .zip(n)
            .for_each(|(ns, n)| ns.push(n));
        vertices.colors.iter_mut().zip(c).for_each(|(cs, c)| {
            cs.push(c.map(|v| unit_color(v * color_scale)));
        });
        if vertices.positions.len() as u64 >= out.batch() {
            handed += vertices.positions.len() as u64;
            out.vertices(std::mem::replace(&mut vertices, empty()))?;
        }
        Ok(())
    })?;
    if handed == 0 || !vertices.positions.is_empty() {
        out.vertices(vertices)?;
    }
    let mut polygon = Vec::new();
    let mut faces = 0u64;
    for k in 0..header.faces {
        let (no, line) = lines.expect(path, || format!("face {k}"))?;
        let at =
            |msg| ImportError::malformed(path, format!("line {no}"), format!("face {k}: {msg}"));
        face(line, header.vertices, &mut polygon).map_err(at)?;
        fan(&polygon, out.triangles());
        faces += 1;
        if faces >= out.batch() {
            out.triangles_done()?;
            faces = 0;
        }
    }
    if faces > 0 {
        out.triangles_done()?;
    }
    Ok(())
}

/// Parses each of the header's vertices in order.
fn for_each_vertex(
    path: &Path,
    lines: &mut Lines<BufReader<File>>,
    header: &Header,
    mut each: impl FnMut(Vertex) -> Result<(), ImportError>,
) -> Result<(), ImportError> {
    for k in 0..header.vertices {
        let (no, line) = lines.expect(path, || format!("vertex {k}"))?;
        let at =
            |msg| ImportError::malformed(path, format!("line {no}"), format!("vertex {k}: {msg}"));
        each(header.layout.vertex(line).map_err(at)?)?;
    }
    Ok(())
}

/// A position, its normal and its color as read (0..1 or 0..255).
type Vertex = (DVec3, Option<Vec3>, Option<[f64; 3]>);

/// Which optional values a vertex line holds.
struct Layout {
    st: bool,
    color: bool,
    normal: bool,
}

impl Layout {
    /// Parses `x y z [nx ny nz] [r g b [a]] [s t]`.
    fn vertex(&self, line: &[u8]) -> Result<Vertex, String> {
        let mut values = Vec::with_capacity(12);
        for w in line
            .split(u8::is_ascii_whitespace)
            .filter(|w| !w.is_empty())
        {
            values.push(number(w)?);
        }
        let need = 3 + if self.normal { 3 } else { 0 } + if self.color { 3 } else { 0 };
        let short = || format!("needs at least {need} numbers");
        let [x, y, z, ref rest @ ..] = values[..] else {
            return Err(short());
        };
        let (n, rest) = if self.normal {
            match rest {
                [a, b, c, rest @ ..] => (Some(Vec3::new(*a as f32, *b as f32, *c as f32)), rest),
                _ => return Err(short()),
            }
        } else {
            (None, rest)
        };
        let c = if self.color {
            let end = rest.len().saturating_sub(if self.st { 2 } else { 0 });
            match rest.get(..end).unwrap_or_default() {
                [r, g, b] | [r, g, b, _] => Some([*r, *g, *b]),
                _ => return Err(short()),
            }
        } else {
            None
        };
        Ok((DVec3::new(x, y, z), n, c))
    }
}

/// Parses `n i0 ... i(n-1) [color]` into `polygon`.
fn face(line: &[u8], nv: u64, polygon: &mut Vec<u32>) -> Result<(), String> {
    let mut words = line
        .split(u8::is_ascii_whitespace)
        .filter(|w| !w.is_empty());
    let first = String::from_utf8_lossy(words.next().unwrap_or_default());
    let n: u32 = first
        .parse()
        .map_err(|_| format!("the vertex count '{first}' is not a number"))?;
    if n < 3 {
        return Err(format!("a face needs at least 3 vertices, this has {n}"));
    }
    polygon.clear();
    for _ in 0..n {
        let w = words
            .next()
            .ok_or_else(|| format!("fewer than {n} vertex indices"))?;
        polygon.push(index(w, nv)?);
    }
    Ok(())
}

/// Reads lines, dropping comments and blank lines.
struct Lines<R> {
    r: R,
    buf: Vec<u8>,
    /// Length of the current line without its comment.
    end: usize,
    no: u64,
}

impl<R: BufRead> Lines<R> {
    /// The next line with content, without its comment.
    fn next(&mut self) -> io::Result<Option<&[u8]>> {
        Ok(if self.advance()? {
            self.buf.get(..self.end)
        } else {
            None
        })
    }

    fn advance(&mut self) -> io::Result<bool> {
        loop {
            self.buf.clear();
            if self.r.read_until(b'\n', &mut self.buf)? == 0 {
                return Ok(false);
            }
            self.no += 1;
            self.end = self
                .buf
                .iter()
                .position(|&b| b == b'#')
                .unwrap_or(self.buf.len());
            if self
                .buf
                .get(..self.end)
                .is_some_and(|l| l.iter().any(|b| !b.is_ascii_whitespace()))
            {
                return Ok(true);
            }
        }
    }

    /// The next line with its number; the end of the file is an error at `what`.
    fn expect(
        &mut self,
        path: &Path,
        what: impl Fn() -> String,
    ) -> Result<(u64, &[u8]), ImportError> {
        match self.advance() {
            Ok(true) => Ok((self.no, self.buf.get(..self.end).unwrap_or_default())),
            Ok(false) => Err(ImportError::malformed(
                path,
                what(),
                "file ends early (truncated)",
            )),
            Err(e) => Err(ImportError::io(path, e)),
        }
    }
}

fn owned_words(line: &[u8]) -> Vec<String> {
    let words = line
        .split(u8::is_ascii_whitespace)
        .filter(|w| !w.is_empty());
    words
        .map(|w| String::from_utf8_lossy(w).into_owned())
        .collect()
}

fn number(word: &[u8]) -> Result<f64, String> {
    std::str::from_utf8(word)
        .ok()
        .and_then(|w| w.parse().ok())
        .ok_or_else(|| format!("'{}' is not a number", String::from_utf8_lossy(word)))
}

/// A vertex index below `limit`, the vertex count.
fn index(word: &[u8], limit: u64) -> Result<u32, String> {
    let text = String::from_utf8_lossy(word);
    match text.parse::<u64>() {
        Ok(i) if i < limit && i <= u64::from(u32::MAX) => Ok(i as u32),
        Ok(i) => Err(format!(
            "vertex index {i} is out of range ({limit} vertices)"
        )),
        Err(_) => Err(format!("'{text}' is not a vertex index")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::import::test_file::TestFile;
    use crate::scene::{Geometry, Primitives};

    fn load_text(text: &str) -> Result<Geometry, ImportError> {
        let result = load(TestFile::new("t.off", text).path());
        result.map(|s| s.geometries.into_iter().next().unwrap())
    }

    fn tris(g: &Geometry) -> &[[u32; 3]] {
        match &g.primitives {
            Primitives::Triangles(t) => t,
            p => panic!("not triangles: {p:?}"),
        }
    }

    #[test]
    fn plain_off_with_comments() {
        let text = "OFF # a square\n# counts\n4 2 0\n0 0 0\n1 0 0\n\n1 1 0 # corner\n0 1 2\n\
            4 0 1 2 3 255 0 0\n3 3 2 1\n";
        let g = load_text(text).unwrap();
        assert_eq!(g.positions[3], DVec3::new(0.0, 1.0, 2.0));
        assert_eq!(tris(&g), &[[0, 1, 2], [0, 2, 3], [3, 2, 1]]);
        assert!(g.normals.is_none() && g.colors.is_none());
        // Counts on the keyword line, and no keyword at all.
        assert_eq!(
            tris(&load_text("OFF 3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n").unwrap()),
            &[[0, 1, 2]]
        );
        assert_eq!(
            tris(&load_text("3 1\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n").unwrap()),
            &[[0, 1, 2]]
        );
    }

    #[test]
    fn colors_and_normals() {
        let g = load_text(
            "COFF\n3 1 3\n0 0 0 255 0 0 255\n1 0 0 0 128 0 255\n0 1 0 0 0 255 255\n3 0 1 2\n",
        )
        .unwrap();
        assert_eq!(
            g.colors.unwrap(),
            vec![[255, 0, 0], [0, 128, 0], [0, 0, 255]]
        );
        let g = load_text("CNOFF\n2 0 0\n0 0 0 0 0 2 1 0.5 0\n1 0 0 0 3 0 0 0 1\n").unwrap();
        assert_eq!(g.primitives, Primitives::Points);
        assert_eq!(g.normals.unwrap(), vec![Vec3::Z, Vec3::Y]);
        assert_eq!(g.colors.unwrap(), vec![[255, 128, 0], [0, 0, 255]]);
    }

    #[test]
    fn bad_inputs() {
        let e = |text: &str| load_text(text).unwrap_err().to_string();
        assert!(matches!(
            load(Path::new("/nonexistent/x.off")),
            Err(ImportError::Io { .. })
        ));
        let head = "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n";
        let msg = e(&format!("{head}3 0 1 3\n"));
        assert!(
            msg.ends_with("line 6: face 0: vertex index 3 is out of range (3 vertices)"),
            "{msg}"
        );
        assert!(e(&format!("{head}2 0 1\n")).contains("face 0: a face needs at least 3"));
        assert!(e(&format!("{head}4 0 1 2\n")).contains("fewer than 4 vertex indices"));
        assert!(e(head).ends_with("face 0: file ends early (truncated)"));
        assert!(e("OFF\n3 1 0\n0 0 0\n1 0 x\n").ends_with("line 4: vertex 1: 'x' is not a number"));
        assert!(e("OFF\n3 1 0\n0 0 0\n1 0\n").contains("vertex 1: needs at least 3 numbers"));
        assert!(e("COFF\n1 0 0\n0 0 0\n").contains("needs at least 6 numbers"));
        assert!(e("OFF\n3 -1 0\n").contains("counts are not numbers"));
        assert!(
            e(&format!("{head}3.0 0 1 2\n"))
                .contains("face 0: the vertex count '3.0' is not a number")
        );
        assert!(e("OFF BINARY\n").contains("binary OFF"));
        assert!(e("PLY\n").contains("not an OFF file"));
        assert!(e("").contains("empty"));
        // A huge vertex count neither allocates nor hangs.
        assert!(e("OFF\n4000000000 1 0\n0 0 0\n").contains("vertex 1: file ends early"));
    }

    #[test]
    fn nan_is_rejected_by_validate() {
        let file = TestFile::new("nan.off", "OFF\n3 1 0\n0 0 0\n0 inf 0\n0 1 0\n3 0 1 2\n");
        let e = file.load_input().unwrap_err();
        assert!(
            e.to_string()
                .contains("vertex 1: coordinate is not a finite number"),
            "{e}"
        );
    }
}
