//! One part of an OBJ block: counted ([`count`]), then parsed ([`parse`])
//! on its own thread, knowing what precedes it ([`Counts`]).

use std::ops::Range;

use glam::{DVec3, Vec3};

use crate::import::common::fan;

/// Lines, vertices and normals in a stretch of the file.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(super) struct Counts {
    pub lines: u64,
    pub vertices: u64,
    pub normals: u64,
}

impl Counts {
    pub fn plus(self, other: &Counts) -> Counts {
        Counts {
            lines: self.lines + other.lines,
            vertices: self.vertices + other.vertices,
            normals: self.normals + other.normals,
        }
    }
}

/// What a part holds, ready to append after the parts before it.
#[derive(Debug, Default)]
pub(super) struct Part {
    pub positions: Vec<DVec3>,
    /// One per vertex when every vertex of the part has a color; `None`
    /// when one lacks it, or the part has no vertices.
    pub colors: Option<Vec<[f64; 3]>>,
    pub normals: Vec<Vec3>,
    /// (vertex, normal) of each face corner that names a normal, in order.
    pub corner_normals: Vec<(u32, u32)>,
    /// A face corner had no normal.
    pub corner_without_normal: bool,
    pub triangles: Vec<[u32; 3]>,
}

/// Cuts `block` into about `parts` ranges of whole lines.
pub(super) fn cut(block: &[u8], parts: usize) -> Vec<Range<usize>> {
    let step = block.len().div_ceil(parts.max(1)).max(1);
    let mut ranges = Vec::with_capacity(parts);
    let mut start = 0;
    while start < block.len() {
        let end = match block[(start + step).min(block.len())..]
            .iter()
            .position(|&b| b == b'\n')
        {
            Some(i) => (start + step).min(block.len()) + i + 1,
            None => block.len(),
        };
        ranges.push(start..end);
        start = end;
    }
    ranges
}

/// The statement a line begins with (its first word), as bytes.
fn statement(line: &[u8]) -> &[u8] {
    let mut words = line
        .split(u8::is_ascii_whitespace)
        .filter(|w| !w.is_empty());
    words.next().unwrap_or_default()
}

/// Lines, `v` and `vn` statements of `text`: what [`parse`] will find,
/// found without parsing a number.
pub(super) fn count(text: &[u8]) -> Counts {
    let mut counts = Counts::default();
    for line in lines(text) {
        counts.lines += 1;
        match statement(line) {
            b"v" => counts.vertices += 1,
            b"vn" => counts.normals += 1,
            _ => {}
        }
    }
    counts
}

/// The lines of `text`, each with its newline; a last line without one.
fn lines(text: &[u8]) -> impl Iterator<Item = &[u8]> {
    text.split_inclusive(|&b| b == b'\n')
}

/// Parses `text`, which follows what `before` counts; on a malformed line,
/// its number in the file (from 1) and what is wrong.
pub(super) fn parse(text: &[u8], before: &Counts) -> Result<Part, (u64, String)> {
    let mut reader = Reader {
        part: Part::default(),
        all_colored: true,
        first_vertex: before.vertices,
        first_normal: before.normals,
        polygon: Vec::new(),
    };
    for (n, line) in lines(text).enumerate() {
        reader
            .line(line)
            .map_err(|msg| (before.lines + n as u64 + 1, msg))?;
    }
    let mut part = reader.part;
    if !reader.all_colored || part.positions.is_empty() {
        part.colors = None;
    }
    Ok(part)
}

/// A part being read.
struct Reader {
    part: Part,
    /// Every vertex so far had a color.
    all_colored: bool,
    /// Vertices and normals before this part.
    first_vertex: u64,
    first_normal: u64,
    polygon: Vec<u32>,
}

impl Reader {
    fn line(&mut self, line: &[u8]) -> Result<(), String> {
        let lossy;
        let text = match std::str::from_utf8(line) {
            Ok(text) => text,
            Err(_) => {
                lossy = String::from_utf8_lossy(line);
                &lossy
            }
        };
        let mut words = text.split_ascii_whitespace();
        let part = &mut self.part;
        match words.next() {
            Some("v") => {
                let mut c = [0.0; 7];
                let mut n = 0;
                for (slot, w) in c.iter_mut().zip(&mut words) {
                    *slot = number(w)?;
                    n += 1;
                }
                if n < 3 {
                    return Err("a vertex needs x, y and z".into());
                }
                part.positions.push(DVec3::new(c[0], c[1], c[2]));
                if matches!(n, 6 | 7) && self.all_colored {
                    part.colors
                        .get_or_insert_with(Vec::new)
                        .push([c[3], c[4], c[5]]);
                } else {
                    self.all_colored = false;
                }
            }
            Some("vn") => {
                let mut c = [0.0f32; 3];
                for slot in &mut c {
                    *slot = number(words.next().ok_or("a normal needs x, y and z")?)? as f32;
                }
                part.normals.push(Vec3::from(c));
            }
            Some("f") => {
                let vertices = self.first_vertex + part.positions.len() as u64;
                let normals = self.first_normal + part.normals.len() as u64;
                self.polygon.clear();
                for corner in words {
                    let mut parts = corner.split('/');
                    let v = index(parts.next().unwrap_or_default(), vertices, "vertex")?;
                    match parts.nth(1).filter(|p| !p.is_empty()) {
                        Some(p) => part.corner_normals.push((v, index(p, normals, "normal")?)),
                        None => part.corner_without_normal = true,
                    }
                    self.polygon.push(v);
                }
                if self.polygon.len() < 3 {
                    return Err(format!(
                        "a face needs at least 3 vertices, this has {}",
                        self.polygon.len()
                    ));
                }
                fan(&self.polygon, &mut part.triangles);
            }
            _ => {}
        }
        Ok(())
    }
}

fn number(word: &str) -> Result<f64, String> {
    word.parse()
        .map_err(|_| format!("'{word}' is not a number"))
}

/// Resolves a 1-based or negative (relative) OBJ index against `count`
/// items defined so far.
fn index(word: &str, count: u64, what: &str) -> Result<u32, String> {
    let i = integer(word).ok_or_else(|| format!("'{word}' is not a {what} index"))?;
    let resolved = if i < 0 { count as i64 + i } else { i - 1 };
    if i == 0 || resolved < 0 || resolved >= count as i64 {
        return Err(format!(
            "{what} index {i} is out of range ({count} defined so far)"
        ));
    }
    Ok(resolved as u32)
}

/// An optionally signed decimal integer of at most 18 digits (every index
/// a 32-bit count allows, without overflow), read by hand: faces hold most
/// of a mesh's numbers, and the general parser's checks cost more than the
/// digits.
fn integer(word: &str) -> Option<i64> {
    let (negative, digits) = match word.as_bytes() {
        [b'-', rest @ ..] => (true, rest),
        [b'+', rest @ ..] => (false, rest),
        all => (false, all),
    };
    if digits.is_empty() || digits.len() > 18 {
        return None;
    }
    let mut value = 0i64;
    for &d in digits {
        if !d.is_ascii_digit() {
            return None;
        }
        value = value * 10 + i64::from(d - b'0');
    }
    Some(if negative { -value } else { value })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn indices_are_read_as_the_standard_parser_reads_them() {
        for word in [
            "1",
            "-1",
            "+7",
            "0",
            "007",
            "4294967296",
            "999999999999999999",
        ] {
            assert_eq!(integer(word), word.parse::<i64>().ok(), "{word}");
        }
        for word in [
            "",
            "-",
            "+",
            "1.0",
            "1e3",
            "x",
            "--1",
            "1 ",
            "9999999999999999999",
        ] {
            assert_eq!(integer(word), None, "{word:?}");
        }
    }
}
