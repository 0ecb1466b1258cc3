//! Wavefront OBJ: a hand-written streaming line parser.
//!
//! Lines are read as bytes through a [`BufReader`] (so a stray non-UTF-8
//! comment does no harm) and split on ASCII whitespace.
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

use std::fs::File;
use std::io::{BufRead, BufReader};
use std::path::Path;

use glam::{DVec3, Vec3};

use super::ImportError;
use super::common::{fan, unit_color, unit_normals};
use crate::scene::{Geometry, Primitives, Scene};

/// Loads an OBJ file as one geometry: triangles, or points when it has no
/// faces.
pub fn load(path: &Path) -> Result<Scene, ImportError> {
    let file = File::open(path).map_err(|e| ImportError::io(path, e))?;
    let mut reader = BufReader::with_capacity(1 << 20, file);
    let mut obj = Obj::default();
    let mut line = Vec::new();
    let mut line_no = 0u64;
    loop {
        line.clear();
        if reader
            .read_until(b'\n', &mut line)
            .map_err(|e| ImportError::io(path, e))?
            == 0
        {
            break;
        }
        line_no += 1;
        obj.line(&line)
            .map_err(|msg| ImportError::malformed(path, format!("line {line_no}"), msg))?;
    }
    Ok(Scene::single(obj.finish(path)))
}

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
    polygon: Vec<u32>,
}

impl Obj {
    fn line(&mut self, line: &[u8]) -> Result<(), String> {
        let mut words = line
            .split(u8::is_ascii_whitespace)
            .filter(|w| !w.is_empty());
        match words.next() {
            Some(b"v") => {
                let mut c = [0.0; 7];
                let mut n = 0;
                for (slot, w) in c.iter_mut().zip(&mut words) {
                    *slot = number(w)?;
                    n += 1;
                }
                if n < 3 {
                    return Err("a vertex needs x, y and z".into());
                }
                if self.positions.len() >= u32::MAX as usize {
                    return Err("too many vertices for 32-bit indices".into());
                }
                self.positions.push(DVec3::new(c[0], c[1], c[2]));
                self.vertex_normal.push(u32::MAX);
                match (&mut self.colors, n) {
                    (Some(colors), 6 | 7) => colors.push([c[3], c[4], c[5]]),
                    (None, 6 | 7) if self.positions.len() == 1 => {
                        self.colors = Some(vec![[c[3], c[4], c[5]]]);
                    }
                    _ => self.colors = None,
                }
            }
            Some(b"vn") => {
                let mut c = [0.0f32; 3];
                for slot in &mut c {
                    *slot = number(words.next().ok_or("a normal needs x, y and z")?)? as f32;
                }
                self.normals.push(Vec3::from(c));
            }
            Some(b"f") => {
                self.polygon.clear();
                for corner in words {
                    let mut parts = corner.split(|&b| b == b'/');
                    let v = index(
                        parts.next().unwrap_or_default(),
                        self.positions.len(),
                        "vertex",
                    )?;
                    let n = match parts.nth(1).filter(|p| !p.is_empty()) {
                        Some(p) => Some(index(p, self.normals.len(), "normal")?),
                        None => None,
                    };
                    match (n, self.vertex_normal.get_mut(v as usize)) {
                        (Some(n), Some(slot)) if *slot == u32::MAX => *slot = n,
                        (None, _) => self.corner_without_normal = true,
                        _ => {}
                    }
                    self.polygon.push(v);
                }
                if self.polygon.len() < 3 {
                    return Err(format!(
                        "a face needs at least 3 vertices, this has {}",
                        self.polygon.len()
                    ));
                }
                fan(&self.polygon, &mut self.triangles);
            }
            _ => {}
        }
        Ok(())
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
            let max = c.iter().flatten().fold(0.0f64, |m, &v| m.max(v));
            let scale = if max > 1.0 { 1.0 / 255.0 } else { 1.0 };
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

fn number(word: &[u8]) -> Result<f64, String> {
    std::str::from_utf8(word)
        .ok()
        .and_then(|w| w.parse().ok())
        .ok_or_else(|| format!("'{}' is not a number", String::from_utf8_lossy(word)))
}

/// Resolves a 1-based or negative (relative) OBJ index against `count`
/// items defined so far.
fn index(word: &[u8], count: usize, what: &str) -> Result<u32, String> {
    let bad = || format!("'{}' is not a {what} index", String::from_utf8_lossy(word));
    let i: i64 = std::str::from_utf8(word)
        .ok()
        .and_then(|w| w.parse().ok())
        .ok_or_else(bad)?;
    let resolved = if i < 0 { count as i64 + i } else { i - 1 };
    if i == 0 || resolved < 0 || resolved >= count as i64 {
        return Err(format!(
            "{what} index {i} is out of range ({count} defined so far)"
        ));
    }
    Ok(resolved as u32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};

    fn load_text(text: &str) -> Result<Geometry, ImportError> {
        static N: AtomicUsize = AtomicUsize::new(0);
        let n = N.fetch_add(1, Ordering::Relaxed);
        let path = std::env::temp_dir().join(format!("ff-obj-{}-{n}.obj", std::process::id()));
        std::fs::write(&path, text).unwrap();
        let result = load(&path);
        std::fs::remove_file(&path).unwrap();
        result.map(|s| s.geometries.into_iter().next().unwrap())
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
        let path = std::env::temp_dir().join(format!("ff-obj-nan-{}.obj", std::process::id()));
        std::fs::write(&path, "v 0 0 0\nv NaN 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
        let e = crate::import::load_input(path.to_str().unwrap(), &Default::default()).unwrap_err();
        std::fs::remove_file(&path).unwrap();
        assert!(
            e.to_string()
                .contains("vertex 1: coordinate is not a finite number"),
            "{e}"
        );
    }
}
