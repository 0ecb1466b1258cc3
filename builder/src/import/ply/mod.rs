//! PLY (Stanford polygon format): ASCII, `binary_little_endian` and
//! `binary_big_endian`.
//!
//! A compact hand-written reader: the header becomes a list of elements with
//! typed properties, then the body is read one value at a time (a binary
//! body is decoded in place from a memory map of the file ([`mapped`]), or
//! where the file cannot be mapped, read into memory an element at a time;
//! ASCII values are
//! whitespace-separated tokens streamed through a [`BufReader`], so line
//! breaks do not matter). This reads the
//! test meshes in a few milliseconds and lets every error name the element
//! instance it failed in, which the `ply-rs-bw` crate's per-property string
//! dispatch does neither of.
//!
//! What is read:
//! - `vertex`: `x y z` of any numeric type (required); `nx ny nz` when all
//!   three are present; `red green blue` (or `diffuse_red` ...) when all three
//!   are present: 8-bit integers as they are, 16-bit integers divided by 257,
//!   floats as 0..1.
//! - `face`: the list `vertex_indices` (or `vertex_index`), fan-triangulated.
//! - `tristrips`: the list `vertex_indices`, where -1 restarts the strip;
//!   strips alternate winding and degenerate triangles are dropped.
//! - Every other element and property is skipped by its declared size.
//!
//! Without `face` or `tristrips` the vertices become a point cloud.

use std::fs::File;
use std::io::{self, BufRead, BufReader, Read};
use std::path::Path;

use glam::{DVec3, Vec3};

use super::ImportError;
use super::common::{fan, unit_color};
use super::stream::{BodyOut, Gather, MeshInfo, Vertices};
use crate::scene::Scene;

mod fast;
mod mapped;

use mapped::Mapped;

/// Longest header accepted before `end_header`.
const MAX_HEADER: u64 = 1 << 20;

/// The body length assumed for a file of unknown length (a pipe): a bound
/// on what is allocated ahead of reading, so a header's counts cannot make
/// it allocate more; the body itself is read to its end. (The decoded
/// vectors are sized from it too, at up to a few times as many bytes; that
/// is address space reserved, not memory touched, until data arrives.)
const UNKNOWN_BODY: u64 = 1 << 26;

/// Loads a PLY file as one geometry: triangles when it has `face` or
/// `tristrips`, points otherwise.
pub fn load(path: &Path) -> Result<Scene, ImportError> {
    load_from(path, true)
}

/// [`load`]; a binary body is memory-mapped when `map` is set and the file
/// can be, else read.
fn load_from(path: &Path, map: bool) -> Result<Scene, ImportError> {
    let mut gather = Gather::default();
    read_file(path, map, &mut gather)?;
    Ok(Scene::single(gather.into_geometry(path)))
}

/// Reads a PLY file's vertices and triangles into `out` a batch at a time
/// (see [`BodyOut::batch`]), for a build that writes them to disk as they
/// come; a binary body is mapped where the file can be.
pub(crate) fn stream(path: &Path, out: &mut dyn BodyOut) -> Result<(), ImportError> {
    read_file(path, true, out)
}

/// Reads a PLY file's header.
pub(crate) fn survey(path: &Path) -> Result<MeshInfo, ImportError> {
    let file = File::open(path).map_err(|e| ImportError::io(path, e))?;
    let header = read_header(path, &mut BufReader::with_capacity(64 << 10, file))?;
    let vertex = header
        .elements
        .iter()
        .find(|e| e.name == "vertex")
        .ok_or_else(|| ImportError::malformed(path, "header", "there is no element vertex"))?;
    let roles = VertexRoles::of(path, vertex)?;
    Ok(MeshInfo {
        vertices: vertex.count,
        triangles: header
            .elements
            .iter()
            .any(|e| matches!(e.name.as_str(), "face" | "tristrips") && !e.props.is_empty()),
        normals: roles.normal.is_some(),
        colors: roles.color.is_some(),
        color_scale: 1.0,
    })
}

fn read_file(path: &Path, map: bool, out: &mut dyn BodyOut) -> Result<(), ImportError> {
    let file = File::open(path).map_err(|e| ImportError::io(path, e))?;
    // A pipe has no length: its body is read to its end, and sizes taken
    // from the header are trusted only up to a bound (see `UNKNOWN_BODY`).
    let file_len = file
        .metadata()
        .ok()
        .filter(|m| m.is_file())
        .map(|m| m.len());
    // The header needs little; a binary body is read element by element
    // into its own buffer, so a larger buffer here would only add to the
    // import's memory peak.
    let mut reader = BufReader::with_capacity(64 << 10, file);
    let header = read_header(path, &mut reader)?;
    let body_len = file_len.map_or(UNKNOWN_BODY, |len| len.saturating_sub(header.bytes));
    match header.format {
        Format::Ascii => {
            let mut src = Ascii {
                r: reader,
                line: Vec::new(),
                pos: 0,
                line_no: header.lines,
            };
            read_body(path, &header, body_len, &mut src, out)
        }
        Format::BinaryLe | Format::BinaryBe => {
            let big = header.format == Format::BinaryBe;
            // Only a regular file is mapped: a pipe or a device has no
            // length to map, and is read to its end instead.
            if let Some(mut src) = (map && file_len.is_some())
                .then(|| Mapped::new(reader.get_ref(), header.bytes, big))
                .flatten()
            {
                return read_body(path, &header, body_len, &mut src, out);
            }
            let mut src = Binary {
                reader,
                unread: if file_len.is_some() {
                    body_len
                } else {
                    u64::MAX
                },
                room_bound: body_len,
                body: Vec::new(),
                pos: 0,
                big,
            };
            read_body(path, &header, body_len, &mut src, out)
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Format {
    Ascii,
    BinaryLe,
    BinaryBe,
}

/// `Some` decoding function for each listed `Scalar` variant and byte order:
/// it reads the variant's type from the front of a slice as `$out`, or
/// gives `$short` when the slice is too short; `None` for unlisted variants.
macro_rules! decoders {
    ($scalar:expr, $big:expr, $out:ty, $short:expr; $($variant:ident => $t:ty),*) => {
        #[allow(unreachable_patterns)]
        match ($scalar, $big) {
            $(
                (Scalar::$variant, false) => Some((|b: &[u8]| {
                    b.get(..size_of::<$t>())
                        .and_then(|s| s.try_into().ok())
                        .map_or($short, |a| <$out>::from(<$t>::from_le_bytes(a)))
                }) as fn(&[u8]) -> $out),
                (Scalar::$variant, true) => Some((|b: &[u8]| {
                    b.get(..size_of::<$t>())
                        .and_then(|s| s.try_into().ok())
                        .map_or($short, |a| <$out>::from(<$t>::from_be_bytes(a)))
                }) as fn(&[u8]) -> $out),
            )*
            _ => None,
        }
    };
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "char" | "int8" => Self::I8,
            "uchar" | "uint8" => Self::U8,
            "short" | "int16" => Self::I16,
            "ushort" | "uint16" => Self::U16,
            "int" | "int32" => Self::I32,
            "uint" | "uint32" => Self::U32,
            "float" | "float32" => Self::F32,
            "double" | "float64" => Self::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::F64 => 8,
        }
    }

    /// A decoder of one value of this type from the front of a slice (NaN
    /// when the slice is shorter than [`Scalar::size`], which the callers'
    /// bounds checks rule out). One function per type and byte order,
    /// chosen once per property: decoding through a `match` per value made
    /// the branch on the type the import's hottest instruction.
    fn decoder(self, big: bool) -> fn(&[u8]) -> f64 {
        decoders!(self, big, f64, f64::NAN;
            I8 => i8, U8 => u8, I16 => i16, U16 => u16, I32 => i32, U32 => u32, F32 => f32, F64 => f64)
        .unwrap_or(|_| f64::NAN)
    }

    /// A decoder of an integer type straight to `i64`, for index lists;
    /// `None` for float types. Like [`Scalar::decoder`], with `i64::MIN`
    /// for a short slice (never an index).
    fn integer_decoder(self, big: bool) -> Option<fn(&[u8]) -> i64> {
        decoders!(self, big, i64, i64::MIN;
            I8 => i8, U8 => u8, I16 => i16, U16 => u16, I32 => i32, U32 => u32)
    }
}

#[derive(Debug)]
enum Kind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug)]
struct Property {
    name: String,
    kind: Kind,
}

#[derive(Debug)]
struct Element {
    name: String,
    count: u64,
    props: Vec<Property>,
}

impl Element {
    /// Fewest body bytes one instance can take, to bound preallocation.
    fn min_bytes(&self, format: Format) -> u64 {
        let sum: usize = self
            .props
            .iter()
            .map(|p| match (format, &p.kind) {
                (Format::Ascii, _) => 2,
                (_, Kind::Scalar(s)) => s.size(),
                (_, Kind::List { count, .. }) => count.size(),
            })
            .sum();
        sum.max(1) as u64
    }

    fn list(&self, names: &[&str]) -> Option<usize> {
        self.props
            .iter()
            .position(|p| matches!(p.kind, Kind::List { .. }) && names.contains(&p.name.as_str()))
    }
}

#[derive(Debug)]
struct Header {
    format: Format,
    elements: Vec<Element>,
    /// Header size in bytes and lines.
    bytes: u64,
    lines: u64,
}

fn read_header<R: BufRead>(path: &Path, r: &mut R) -> Result<Header, ImportError> {
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut line = Vec::new();
    let (mut bytes, mut lines) = (0u64, 0u64);
    loop {
        line.clear();
        let read = r
            .by_ref()
            .take(MAX_HEADER - bytes)
            .read_until(b'\n', &mut line)
            .map_err(|e| ImportError::io(path, e))?;
        let bad = |msg: String| ImportError::malformed(path, "header", msg);
        if read == 0 {
            let why = if bytes >= MAX_HEADER {
                "is longer than 1 MiB"
            } else {
                "ends before end_header"
            };
            return Err(bad(format!("the header {why}")));
        }
        bytes += read as u64;
        lines += 1;
        let text = String::from_utf8_lossy(&line);
        let words: Vec<&str> = text.split_ascii_whitespace().collect();
        if lines == 1 {
            if words != ["ply"] {
                return Err(bad("not a PLY file (the first line is not 'ply')".into()));
            }
            continue;
        }
        let bad_line = |msg: &str| bad(format!("line {lines}: {msg}: '{}'", text.trim()));
        match words.as_slice() {
            [] | ["comment", ..] | ["obj_info", ..] => {}
            ["format", f, ..] => {
                format = Some(match *f {
                    "ascii" => Format::Ascii,
                    "binary_little_endian" => Format::BinaryLe,
                    "binary_big_endian" => Format::BinaryBe,
                    _ => return Err(bad_line("unknown format")),
                });
            }
            ["element", name, count] => {
                let count = count
                    .parse()
                    .map_err(|_| bad_line("element count is not a number"))?;
                elements.push(Element {
                    name: (*name).into(),
                    count,
                    props: Vec::new(),
                });
            }
            ["property", rest @ ..] => {
                let (kind, name) = match rest {
                    ["list", c, i, name] => match (Scalar::parse(c), Scalar::parse(i)) {
                        (Some(count), Some(item)) => (Kind::List { count, item }, name),
                        _ => return Err(bad_line("unknown property type")),
                    },
                    [t, name] => match Scalar::parse(t) {
                        Some(s) => (Kind::Scalar(s), name),
                        None => return Err(bad_line("unknown property type")),
                    },
                    _ => return Err(bad_line("malformed property")),
                };
                let element = elements
                    .last_mut()
                    .ok_or_else(|| bad_line("property before any element"))?;
                element.props.push(Property {
                    name: (*name).into(),
                    kind,
                });
            }
            ["end_header"] => break,
            _ => return Err(bad_line("unknown header line")),
        }
    }
    let format = format.ok_or_else(|| ImportError::malformed(path, "header", "no format line"))?;
    Ok(Header {
        format,
        elements,
        bytes,
        lines,
    })
}

/// Why reading a value from the body failed.
#[derive(Debug)]
enum BodyError {
    Truncated,
    Io(io::Error),
    Invalid(String),
}

impl From<io::Error> for BodyError {
    fn from(e: io::Error) -> Self {
        if e.kind() == io::ErrorKind::UnexpectedEof {
            Self::Truncated
        } else {
            Self::Io(e)
        }
    }
}

/// A source of body values, ASCII or binary.
trait Values {
    fn value(&mut self, ty: Scalar) -> Result<f64, BodyError>;
    fn skip(&mut self, ty: Scalar, n: u64) -> Result<(), BodyError>;
    /// The unread rest of a binary body and whether it is big-endian, for
    /// the [`fast`] paths; `None` for ASCII.
    fn binary_rest(&self) -> Option<(&[u8], bool)> {
        None
    }
    /// Marks `n` bytes of [`Values::binary_rest`] as read.
    fn consume(&mut self, _n: usize) {}
    /// Called before each element is read.
    fn begin_element(&mut self, _element: &Element) -> io::Result<()> {
        Ok(())
    }
    /// Called after each batch (see [`BodyOut::batch`]) has been handed
    /// over: what is behind it is not read again.
    fn batch_done(&mut self) {}
}

/// A binary body, read into memory an element at a time and decoded from
/// there: each value is a bounds-checked slice access (a value at a time
/// through a `BufReader` was 10x slower). An element of fixed-size records
/// (the vertices) is read alone and dropped before the next is read, so
/// the file's bytes are never all in memory beside what they decode to.
struct Binary<R> {
    reader: R,
    /// Body bytes not yet read from `reader` (at most; the file may be
    /// shorter than its header says, which the decoders report).
    unread: u64,
    /// Most bytes allocated ahead of a read: the body's length, or
    /// [`UNKNOWN_BODY`] for a pipe, where `unread` is unbounded.
    room_bound: u64,
    body: Vec<u8>,
    pos: usize,
    big: bool,
}

impl<R: Read> Binary<R> {
    /// Makes the next `len` body bytes (or all the rest) readable from
    /// `body`, freeing the bytes already decoded.
    fn load(&mut self, len: Option<u64>) -> io::Result<()> {
        let kept = self.body.len() - self.pos;
        let wanted = len.map_or(self.unread, |n| {
            n.saturating_sub(kept as u64).min(self.unread)
        });
        if wanted == 0 {
            return Ok(());
        }
        let capacity = usize::try_from(wanted.min(self.room_bound)).unwrap_or(usize::MAX);
        let mut body = Vec::with_capacity(kept.saturating_add(capacity));
        body.extend_from_slice(&self.body[self.pos..]);
        self.body = Vec::new();
        let read = (&mut self.reader).take(wanted).read_to_end(&mut body)?;
        self.unread -= read as u64;
        self.body = body;
        self.pos = 0;
        Ok(())
    }
}

/// Decodes the value of type `ty` at `bytes[*pos..]` and moves past it.
fn take_value(bytes: &[u8], pos: &mut usize, ty: Scalar, big: bool) -> Result<f64, BodyError> {
    let n = ty.size();
    let value = bytes.get(*pos..*pos + n).ok_or(BodyError::Truncated)?;
    *pos += n;
    Ok(ty.decoder(big)(value))
}

/// Moves `*pos` past `n` values of type `ty` in `bytes`.
fn skip_values(bytes: &[u8], pos: &mut usize, ty: Scalar, n: u64) -> Result<(), BodyError> {
    let want = n.saturating_mul(ty.size() as u64);
    let left = bytes.len().saturating_sub(*pos) as u64;
    if want > left {
        return Err(BodyError::Truncated);
    }
    *pos += want as usize;
    Ok(())
}

impl<R: Read> Values for Binary<R> {
    fn value(&mut self, ty: Scalar) -> Result<f64, BodyError> {
        take_value(&self.body, &mut self.pos, ty, self.big)
    }

    fn skip(&mut self, ty: Scalar, n: u64) -> Result<(), BodyError> {
        skip_values(&self.body, &mut self.pos, ty, n)
    }

    fn binary_rest(&self) -> Option<(&[u8], bool)> {
        Some((&self.body[self.pos..], self.big))
    }

    fn consume(&mut self, n: usize) {
        self.pos += n;
    }

    fn begin_element(&mut self, element: &Element) -> io::Result<()> {
        let fixed = fast::FixedLayout::of(element)
            .and_then(|layout| element.count.checked_mul(layout.stride as u64));
        self.load(fixed)
    }
}

struct Ascii<R> {
    r: R,
    line: Vec<u8>,
    pos: usize,
    line_no: u64,
}

impl<R: BufRead> Ascii<R> {
    /// The next whitespace-separated token, reading lines as needed.
    fn token(&mut self) -> Result<std::ops::Range<usize>, BodyError> {
        loop {
            let rest = self.line.get(self.pos..).unwrap_or_default();
            let skip = rest.iter().take_while(|b| b.is_ascii_whitespace()).count();
            let len = rest[skip..]
                .iter()
                .take_while(|b| !b.is_ascii_whitespace())
                .count();
            if len > 0 {
                let start = self.pos + skip;
                self.pos = start + len;
                return Ok(start..start + len);
            }
            self.line.clear();
            self.pos = 0;
            self.line_no += 1;
            if self.r.read_until(b'\n', &mut self.line)? == 0 {
                return Err(BodyError::Truncated);
            }
        }
    }
}

impl<R: BufRead> Values for Ascii<R> {
    fn value(&mut self, _ty: Scalar) -> Result<f64, BodyError> {
        let range = self.token()?;
        let token = self.line.get(range).unwrap_or_default();
        std::str::from_utf8(token)
            .ok()
            .and_then(|t| t.parse().ok())
            .ok_or_else(|| {
                let t = String::from_utf8_lossy(token);
                BodyError::Invalid(format!("'{t}' is not a number (line {})", self.line_no))
            })
    }

    fn skip(&mut self, _ty: Scalar, n: u64) -> Result<(), BodyError> {
        for _ in 0..n {
            self.token()?;
        }
        Ok(())
    }
}

/// Reads one instance of an element: scalar property `i` goes to
/// `scalars[i]`, the items of list property `keep` (if any) to `items`, other
/// lists are skipped.
fn read_instance<V: Values>(
    src: &mut V,
    element: &Element,
    keep: Option<usize>,
    scalars: &mut [f64],
    items: &mut Vec<f64>,
) -> Result<(), BodyError> {
    for (i, prop) in element.props.iter().enumerate() {
        match prop.kind {
            Kind::Scalar(ty) => {
                let v = src.value(ty)?;
                if let Some(slot) = scalars.get_mut(i) {
                    *slot = v;
                }
            }
            Kind::List { count, item } => {
                let n = src.value(count)?;
                if !is_u32(n) {
                    return Err(BodyError::Invalid(format!("list length {n} is invalid")));
                }
                let n = n as u64;
                if keep == Some(i) {
                    items.clear();
                    for _ in 0..n {
                        items.push(src.value(item)?);
                    }
                } else {
                    src.skip(item, n)?;
                }
            }
        }
    }
    Ok(())
}

/// The vertex property names read, in slot order.
const VERTEX_ROLES: [&[&str]; 9] = [
    &["x"],
    &["y"],
    &["z"],
    &["nx"],
    &["ny"],
    &["nz"],
    &["red", "diffuse_red", "r"],
    &["green", "diffuse_green", "g"],
    &["blue", "diffuse_blue", "b"],
];

fn read_body<V: Values>(
    path: &Path,
    header: &Header,
    body_len: u64,
    src: &mut V,
    out: &mut dyn BodyOut,
) -> Result<(), ImportError> {
    let vertex_count = header
        .elements
        .iter()
        .find(|e| e.name == "vertex")
        .map(|e| e.count);
    let vertex_count = vertex_count
        .ok_or_else(|| ImportError::malformed(path, "header", "there is no element vertex"))?;
    let mut body = Body {
        path,
        src,
        scalars: Vec::new(),
        items: Vec::new(),
    };
    for element in &header.elements {
        if element.props.is_empty() {
            continue;
        }
        body.src
            .begin_element(element)
            .map_err(|e| ImportError::io(path, e))?;
        let cap = element
            .count
            .min(body_len / element.min_bytes(header.format))
            .min(out.batch()) as usize;
        match element.name.as_str() {
            "vertex" => body.vertices(element, cap, out)?,
            "face" | "tristrips" => body.polygons(element, vertex_count, cap, out)?,
            _ => {
                for k in 0..element.count {
                    body.instance(element, k, None)?;
                }
            }
        }
    }
    Ok(())
}

/// Which properties of the vertex element are read as what.
struct VertexRoles {
    position: [usize; 3],
    normal: Option<[usize; 3]>,
    color: Option<[usize; 3]>,
}

impl VertexRoles {
    fn of(path: &Path, element: &Element) -> Result<Self, ImportError> {
        let slot = |names: &[&str]| {
            let scalar = |p: &Property| matches!(p.kind, Kind::Scalar(_));
            element
                .props
                .iter()
                .position(|p| scalar(p) && names.contains(&p.name.as_str()))
        };
        let roles: Vec<Option<usize>> = VERTEX_ROLES.iter().map(|names| slot(names)).collect();
        let [Some(x), Some(y), Some(z), nx, ny, nz, r, g, b] = roles[..] else {
            return Err(ImportError::malformed(
                path,
                "element vertex",
                "needs x, y and z",
            ));
        };
        Ok(Self {
            position: [x, y, z],
            normal: nx.zip(ny).zip(nz).map(|((a, b), c)| [a, b, c]),
            color: r.zip(g).zip(b).map(|((a, b), c)| [a, b, c]),
        })
    }
}

/// The body being read, with scratch space for one element instance.
struct Body<'a, V> {
    path: &'a Path,
    src: &'a mut V,
    scalars: Vec<f64>,
    items: Vec<f64>,
}

impl<V: Values> Body<'_, V> {
    /// Reads instance `k` of `element` into `scalars` and, for list property
    /// `keep`, `items`.
    fn instance(
        &mut self,
        element: &Element,
        k: u64,
        keep: Option<usize>,
    ) -> Result<(), ImportError> {
        self.scalars.clear();
        self.scalars.resize(element.props.len(), 0.0);
        read_instance(self.src, element, keep, &mut self.scalars, &mut self.items).map_err(|e| {
            let at = format!("element {} {k}", element.name);
            match e {
                BodyError::Truncated => {
                    ImportError::malformed(self.path, at, "file ends early (truncated)")
                }
                BodyError::Io(e) => ImportError::io(self.path, e),
                BodyError::Invalid(msg) => ImportError::malformed(self.path, at, msg),
            }
        })
    }

    /// Reads the vertex element into `out`, [`BodyOut::batch`] vertices
    /// at a time.
    fn vertices(
        &mut self,
        element: &Element,
        cap: usize,
        out: &mut dyn BodyOut,
    ) -> Result<(), ImportError> {
        let roles = VertexRoles::of(self.path, element)?;
        for (first, n) in batches(element.count, out.batch()) {
            let vertices = self.vertex_batch(element, &roles, first, n, cap)?;
            out.vertices(vertices)?;
            self.src.batch_done();
        }
        Ok(())
    }

    /// Vertices `first..first + n` of `element`.
    fn vertex_batch(
        &mut self,
        element: &Element,
        roles: &VertexRoles,
        first: u64,
        n: u64,
        cap: usize,
    ) -> Result<Vertices, ImportError> {
        let [x, y, z] = roles.position;
        let (normal, color) = (roles.normal, roles.color);
        let ty = |i: usize| match element.props.get(i).map(|p| &p.kind) {
            Some(Kind::Scalar(s)) => *s,
            _ => Scalar::F64,
        };
        let mut positions = Vec::with_capacity(cap);
        let mut normals = normal.map(|_| Vec::with_capacity(cap));
        let mut colors = color.map(|_| Vec::with_capacity(cap));
        if let Some(fields) = fast::FixedLayout::of(element)
            && let Some((rest, big)) = self.src.binary_rest()
            && let Some(records) = fields.records(rest, n)
        {
            let [x, y, z] = [x, y, z].map(|i| fields.reader(i, big));
            fields.decode_all(records, &mut positions, |r| DVec3::new(x(r), y(r), z(r)));
            if let (Some(ns), Some(n)) = (normals.as_mut(), normal) {
                let [x, y, z] = n.map(|i| fields.reader(i, big));
                fields.decode_all(records, ns, |r| {
                    Vec3::new(x(r) as f32, y(r) as f32, z(r) as f32)
                });
            }
            if let (Some(cs), Some(c)) = (colors.as_mut(), color) {
                let [r, g, b] = c.map(|i| (fields.reader(i, big), ty(i)));
                fields.decode_all(records, cs, |rec| {
                    [&r, &g, &b].map(|(read, t)| channel(read(rec), *t))
                });
            }
            self.src.consume(records.len());
            return Ok(Vertices {
                positions,
                normals,
                colors,
            });
        }
        for k in first..first + n {
            self.instance(element, k, None)?;
            let s = |i: usize| self.scalars.get(i).copied().unwrap_or(0.0);
            positions.push(DVec3::new(s(x), s(y), s(z)));
            if let (Some(ns), Some(n)) = (normals.as_mut(), normal) {
                ns.push(Vec3::new(s(n[0]) as f32, s(n[1]) as f32, s(n[2]) as f32));
            }
            if let (Some(cs), Some(c)) = (colors.as_mut(), color) {
                cs.push(c.map(|i| channel(s(i), ty(i))));
            }
        }
        Ok(Vertices {
            positions,
            normals,
            colors,
        })
    }

    /// Reads a `face` (fans) or `tristrips` element into `out`,
    /// [`BodyOut::batch`] faces at a time.
    fn polygons(
        &mut self,
        element: &Element,
        vertex_count: u64,
        cap: usize,
        out: &mut dyn BodyOut,
    ) -> Result<(), ImportError> {
        let strips = element.name == "tristrips";
        let names: &[&str] = if strips {
            &["vertex_indices"]
        } else {
            &["vertex_indices", "vertex_index"]
        };
        let Some(list) = element.list(names) else {
            let at = format!("element {}", element.name);
            return Err(ImportError::malformed(
                self.path,
                at,
                "has no list property vertex_indices",
            ));
        };
        out.triangles().reserve(if strips { 0 } else { cap });
        let mut polygon = Polygon {
            strips,
            max: vertex_count.min(1 << 32) as f64,
            vertex_count,
            indices: Vec::new(),
        };
        for (first, n) in batches(element.count, out.batch()) {
            self.polygon_batch(element, list, &mut polygon, first, n, out.triangles())?;
            out.triangles_done()?;
            self.src.batch_done();
        }
        Ok(())
    }

    /// Faces `first..first + n` of `element`, whose index list is property
    /// `list`, into `tris`.
    fn polygon_batch(
        &mut self,
        element: &Element,
        list: usize,
        polygon: &mut Polygon,
        first: u64,
        n: u64,
        tris: &mut Vec<[u32; 3]>,
    ) -> Result<(), ImportError> {
        if let Kind::List { count, item } = element.props[list].kind
            && element.props.len() == 1
            && let Some((rest, big)) = self.src.binary_rest()
        {
            let fast = fast::List { count, item, big };
            if let Some(read) = fast.polygons(rest, n, polygon, tris) {
                self.src.consume(read);
                return Ok(());
            }
            // Malformed somewhere: read it again value by value, which
            // names the instance.
        }
        for k in first..first + n {
            self.instance(element, k, Some(list))?;
            polygon.add(&self.items, tris).map_err(|msg| {
                ImportError::malformed(self.path, format!("element {} {k}", element.name), msg)
            })?;
        }
        Ok(())
    }
}

/// The batches of an element of `count` instances, `batch` at most each:
/// (first, count) pairs, one `(0, 0)` for an empty element (so its
/// owner still hears of it).
fn batches(count: u64, batch: u64) -> impl Iterator<Item = (u64, u64)> {
    let batch = batch.max(1);
    let starts = (0..count.max(1)).step_by(usize::try_from(batch).unwrap_or(usize::MAX));
    starts.map(move |first| (first, (count - first).min(batch)))
}

/// Turns one `face` or `tristrips` index list into triangles.
struct Polygon {
    strips: bool,
    /// Indices must be below this (the vertex count, at most 2^32).
    max: f64,
    vertex_count: u64,
    /// Scratch space for the validated indices.
    indices: Vec<u32>,
}

impl Polygon {
    /// Appends the triangles of `items` to `tris`, or says what is wrong.
    fn add(&mut self, items: &[f64], tris: &mut Vec<[u32; 3]>) -> Result<(), String> {
        let poly = &mut self.indices;
        poly.clear();
        for &v in items {
            if self.strips && v == -1.0 {
                strip(poly, tris);
                poly.clear();
            } else if v < self.max && is_u32(v) {
                poly.push(v as u32);
            } else {
                return Err(format!(
                    "vertex index {v} is out of range ({} vertices)",
                    self.vertex_count
                ));
            }
        }
        self.finish(tris)
    }

    /// [`Polygon::add`] for integer indices; `None` on anything amiss (the
    /// caller reads the list again through `add`, which says what).
    fn add_integers(
        &mut self,
        items: impl Iterator<Item = i64>,
        tris: &mut Vec<[u32; 3]>,
    ) -> Option<()> {
        self.indices.clear();
        for v in items {
            if self.strips && v == -1 {
                strip(&self.indices, tris);
                self.indices.clear();
            } else {
                let i = self.index(v)?;
                self.indices.push(i);
            }
        }
        self.finish(tris).ok()
    }

    /// `v` as a vertex index, if it is one.
    fn index(&self, v: i64) -> Option<u32> {
        u32::try_from(v)
            .ok()
            .filter(|&i| u64::from(i) < self.vertex_count)
    }

    /// Triangulates the indices gathered since the last restart.
    fn finish(&self, tris: &mut Vec<[u32; 3]>) -> Result<(), String> {
        let poly = &self.indices;
        if self.strips {
            strip(poly, tris);
        } else if poly.len() < 3 {
            return Err("a face needs at least 3 vertices".into());
        } else {
            fan(poly, tris);
        }
        Ok(())
    }
}

/// Whether `v` is a whole number that fits a `u32` (no `fract`: that is a
/// libm call on baseline x86-64, and was a tenth of the import's time).
fn is_u32(v: f64) -> bool {
    (0.0..=f64::from(u32::MAX)).contains(&v) && f64::from(v as u32) == v
}

/// One color channel from a PLY value of type `ty`.
fn channel(v: f64, ty: Scalar) -> u8 {
    match ty {
        Scalar::F32 | Scalar::F64 => unit_color(v),
        Scalar::I16 | Scalar::U16 => (v / 257.0).round().clamp(0.0, 255.0) as u8,
        _ => v.clamp(0.0, 255.0) as u8,
    }
}

/// Triangulates one triangle strip: triangle `j` is `(s[j], s[j+1], s[j+2])`
/// for even `j` and `(s[j+1], s[j], s[j+2])` for odd `j`, so all keep the
/// first one's winding. Triangles with a repeated index are dropped.
fn strip(s: &[u32], out: &mut Vec<[u32; 3]>) {
    let mut strip = Strip::default();
    for &i in s {
        strip.push(i, out);
    }
}

/// A triangle strip read index by index: each index after the first two
/// makes a triangle with the two before it, the winding alternating from
/// the strip's start; triangles with a repeated corner (a strip's joints)
/// are dropped. A restart is a new `Strip`.
#[derive(Default)]
struct Strip {
    last: [u32; 2],
    len: usize,
}

impl Strip {
    fn push(&mut self, i: u32, out: &mut Vec<[u32; 3]>) {
        if let Some(t) = self.next(i) {
            out.push(t);
        }
    }

    /// Adds index `i`; returns the triangle it completes, if any.
    #[inline]
    fn next(&mut self, i: u32) -> Option<[u32; 3]> {
        let [a, b] = self.last;
        let mut made = None;
        if self.len >= 2 {
            let t = if self.len.is_multiple_of(2) {
                [a, b, i]
            } else {
                [b, a, i]
            };
            if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
                made = Some(t);
            }
        }
        self.last = [b, i];
        self.len += 1;
        made
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::import::test_file::TestFile;
    use crate::scene::{Geometry, Primitives};

    /// Loads `bytes` as a file, checking that a mapped and a read binary
    /// body give the same geometry or the same error: every test of the
    /// importer covers both.
    fn load_bytes(bytes: &[u8]) -> Result<Geometry, ImportError> {
        let file = TestFile::new("t.ply", bytes);
        let mapped = load_from(file.path(), true);
        let read = load_from(file.path(), false);
        match (&mapped, &read) {
            (Ok(m), Ok(r)) => assert_eq!(m, r, "mapped and read bodies differ"),
            (Err(m), Err(r)) => assert_eq!(m.to_string(), r.to_string()),
            _ => panic!("mapped: {mapped:?}, read: {read:?}"),
        }
        mapped.map(|s| s.geometries.into_iter().next().unwrap())
    }

    fn err(bytes: &[u8]) -> String {
        load_bytes(bytes).unwrap_err().to_string()
    }

    fn tris(g: &Geometry) -> &[[u32; 3]] {
        match &g.primitives {
            Primitives::Triangles(t) => t,
            p => panic!("not triangles: {p:?}"),
        }
    }

    const QUAD_HEADER: &str = "element vertex 4\nproperty float x\nproperty double y\nproperty short z\n\
        property float nx\nproperty float ny\nproperty float nz\n\
        property uchar red\nproperty uchar green\nproperty uchar blue\n\
        element junk 1\nproperty list uchar float stuff\nproperty int more\n\
        element face 2\nproperty uchar flags\nproperty list uchar uint vertex_indices\nend_header\n";

    /// The same quad (fan-split) plus a triangle, in a binary encoding.
    fn binary_quad(big: bool) -> Vec<u8> {
        let fmt = if big {
            "binary_big_endian"
        } else {
            "binary_little_endian"
        };
        let mut b = format!("ply\nformat {fmt} 1.0\ncomment test\n{QUAD_HEADER}").into_bytes();
        macro_rules! put {
            ($v:expr) => {
                b.extend_from_slice(&if big {
                    $v.to_be_bytes()
                } else {
                    $v.to_le_bytes()
                })
            };
        }
        for (i, p) in [
            [0.0f32, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ]
        .iter()
        .enumerate()
        {
            put!(p[0]);
            put!(f64::from(p[1]));
            put!(p[2] as i16);
            put!(0.0f32);
            put!(0.0f32);
            put!(2.0f32);
            b.extend_from_slice(&[i as u8 * 10, 20, 255]);
        }
        b.push(2);
        put!(1.5f32);
        put!(-2.5f32);
        put!(7i32);
        b.extend_from_slice(&[9, 4]);
        for i in [0u32, 1, 2, 3] {
            put!(i);
        }
        b.extend_from_slice(&[0, 3]);
        for i in [3u32, 2, 1] {
            put!(i);
        }
        b
    }

    fn check_quad(g: &Geometry) {
        assert_eq!(g.positions[2], DVec3::new(1.0, 1.0, 0.0));
        assert_eq!(tris(g), &[[0, 1, 2], [0, 2, 3], [3, 2, 1]]);
        assert_eq!(g.normals.as_ref().unwrap(), &vec![Vec3::Z; 4]);
        assert_eq!(g.colors.as_ref().unwrap()[3], [30, 20, 255]);
    }

    #[test]
    fn ascii_binary_le_and_be_agree() {
        let ascii = format!(
            "ply\nformat ascii 1.0\n{QUAD_HEADER}0 0 0 0 0 2 0 20 255\n1 0 0 0 0 2 10 20 255\n\
             1 1 0 0 0 2 20 20 255\n0 1 0\n0 0 2 30 20 255\n2 1.5 -2.5 7\n9 4 0 1 2 3\n0 3 3 2 1\n"
        );
        check_quad(&load_bytes(ascii.as_bytes()).unwrap());
        check_quad(&load_bytes(&binary_quad(false)).unwrap());
        check_quad(&load_bytes(&binary_quad(true)).unwrap());
    }

    #[test]
    fn tristrips_restart_and_winding() {
        let text = "ply\nformat ascii 1.0\nelement vertex 8\nproperty float x\nproperty float y\n\
            property float z\nelement tristrips 1\nproperty list int int vertex_indices\nend_header\n\
            0 0 0\n1 0 0\n0 1 0\n1 1 0\n0 0 1\n1 0 1\n0 1 1\n1 1 1\n\
            11 0 1 2 3 -1 4 5 6 6 7 7\n";
        let g = load_bytes(text.as_bytes()).unwrap();
        assert_eq!(tris(&g), &[[0, 1, 2], [2, 1, 3], [4, 5, 6]]);
        assert!(g.normals.is_none() && g.colors.is_none());
    }

    /// A strip list long enough to be triangulated on all threads, cut
    /// into pieces at restarts, gives the triangles the ASCII reader gives
    /// value by value (strips of every parity crossing the pieces' likely
    /// cuts, degenerate corners, restarts back to back); an index out of
    /// range near its end, the same error.
    #[test]
    fn a_long_binary_strip_list_agrees_with_ascii() {
        let mut x = 99u32;
        let mut items = Vec::new();
        while items.len() < 200_000 {
            x = x.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let len = (x >> 24) % 40;
            items.extend((0..len).map(|k| ((x >> (k % 20)) % 8) as i32));
            items.push(-1);
        }
        // 0: ASCII, 1: little-endian (indices read inline), 2: big-endian.
        let file = |items: &[i32], binary: u8| {
            let format =
                ["ascii", "binary_little_endian", "binary_big_endian"][usize::from(binary)];
            let bytes = |v: [u8; 4], w: [u8; 4]| if binary == 2 { w } else { v };
            let mut b = format!(
                "ply\nformat {format} 1.0\nelement vertex 8\nproperty float x\nproperty float y\n\
                 property float z\nelement tristrips 1\nproperty list int int vertex_indices\n\
                 end_header\n"
            )
            .into_bytes();
            for i in 0..8u8 {
                let c = [i & 1, (i >> 1) & 1, i >> 2].map(f32::from);
                if binary > 0 {
                    b.extend(
                        c.iter()
                            .flat_map(|v| bytes(v.to_le_bytes(), v.to_be_bytes())),
                    );
                } else {
                    b.extend(format!("{} {} {}\n", c[0], c[1], c[2]).bytes());
                }
            }
            if binary > 0 {
                let n = items.len() as i32;
                b.extend(bytes(n.to_le_bytes(), n.to_be_bytes()));
                b.extend(
                    items
                        .iter()
                        .flat_map(|i| bytes(i.to_le_bytes(), i.to_be_bytes())),
                );
            } else {
                let text: Vec<String> = items.iter().map(i32::to_string).collect();
                b.extend(format!("{} {}\n", items.len(), text.join(" ")).bytes());
            }
            b
        };
        let serial = tris(&load_bytes(&file(&items, 0)).unwrap()).to_vec();
        assert!(serial.len() > 50_000, "{} triangles", serial.len());
        for binary in [1, 2] {
            assert_eq!(tris(&load_bytes(&file(&items, binary)).unwrap()), serial);
        }

        let at = items.len() - 5;
        items[at] = 8;
        for binary in [0, 1, 2] {
            let e = err(&file(&items, binary));
            assert!(
                e.ends_with("element tristrips 0: vertex index 8 is out of range (8 vertices)"),
                "{e}"
            );
        }
    }

    /// A body of several pages: the mapped reader hands back the pages of
    /// each decoded element (the vertices, a skipped element) as the next
    /// begins, and must still decode what follows exactly; and a long strip
    /// list after a short one appends its parallel result to triangles
    /// already read. Both compared with ASCII (and, by `load_bytes`, with
    /// the buffered reader).
    #[test]
    fn a_many_page_body_with_a_long_strip_list_after_a_short_one() {
        let vertices = 2000u32;
        let mut x = 7u32;
        let mut long = Vec::new();
        while long.len() < 100_000 {
            x = x.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let start = (x >> 8) % (vertices - 40);
            long.extend((0..(x >> 27) + 3).map(|k| (start + k) as i32));
            long.push(-1);
        }
        let lists: [&[i32]; 2] = [&[0, 1, 2, 3], &long];
        let file = |binary: bool| {
            let format = if binary {
                "binary_little_endian"
            } else {
                "ascii"
            };
            let mut b = format!(
                "ply\nformat {format} 1.0\nelement vertex {vertices}\nproperty float x\n\
                 property float y\nproperty float z\nelement junk 3000\nproperty int j\n\
                 element tristrips 2\nproperty list int int vertex_indices\nend_header\n"
            )
            .into_bytes();
            for i in 0..vertices {
                let c = [i % 50, i / 50, i % 7].map(|v| v as f32);
                if binary {
                    b.extend(c.iter().flat_map(|v| v.to_le_bytes()));
                } else {
                    b.extend(format!("{} {} {}\n", c[0], c[1], c[2]).bytes());
                }
            }
            for j in 0..3000i32 {
                if binary {
                    b.extend(j.to_le_bytes());
                } else {
                    b.extend(format!("{j}\n").bytes());
                }
            }
            for list in lists {
                if binary {
                    b.extend((list.len() as i32).to_le_bytes());
                    b.extend(list.iter().flat_map(|i| i.to_le_bytes()));
                } else {
                    let text: Vec<String> = list.iter().map(i32::to_string).collect();
                    b.extend(format!("{} {}\n", list.len(), text.join(" ")).bytes());
                }
            }
            b
        };
        let ascii = load_bytes(&file(false)).unwrap();
        let binary = load_bytes(&file(true)).unwrap();
        assert!(file(true).len() > 16 * 4096, "the body spans several pages");
        assert_eq!(&tris(&ascii)[..2], &[[0, 1, 2], [2, 1, 3]]);
        assert!(
            tris(&ascii).len() > 50_000,
            "{} triangles",
            tris(&ascii).len()
        );
        assert_eq!(binary.positions, ascii.positions);
        assert_eq!(tris(&binary), tris(&ascii));
    }

    /// The same strips in binary take the whole-element fast path; they
    /// must give what the ASCII reader gives, and a bad index in them the
    /// same error, naming the instance.
    #[test]
    fn binary_fast_path_agrees_with_ascii() {
        let head = |element: &str, count: usize| {
            format!(
                "ply\nformat binary_big_endian 1.0\nelement vertex 8\nproperty float x\n\
                 property float y\nproperty float z\nelement {element} {count}\n\
                 property list uchar int vertex_indices\nend_header\n"
            )
        };
        let corners: Vec<u8> = (0..8u8)
            .flat_map(|i| [i & 1, (i >> 1) & 1, i >> 2].map(|c| f32::from(c).to_be_bytes()))
            .flatten()
            .collect();
        let list = |items: &[i32]| -> Vec<u8> {
            let mut b = vec![items.len() as u8];
            b.extend(items.iter().flat_map(|i| i.to_be_bytes()));
            b
        };
        let strips = [
            head("tristrips", 1).into_bytes(),
            corners.clone(),
            list(&[0, 1, 2, 3, -1, 4, 5, 6, 6, 7, 7]),
        ]
        .concat();
        let g = load_bytes(&strips).unwrap();
        assert_eq!(tris(&g), &[[0, 1, 2], [2, 1, 3], [4, 5, 6]]);
        assert_eq!(g.positions[6], DVec3::new(0.0, 1.0, 1.0));

        let faces = [
            head("face", 2).into_bytes(),
            corners.clone(),
            list(&[0, 1, 3, 2]),
            list(&[4, 5, 6]),
        ]
        .concat();
        assert_eq!(
            tris(&load_bytes(&faces).unwrap()),
            &[[0, 1, 3], [0, 3, 2], [4, 5, 6]]
        );

        let bad = [
            head("face", 2).into_bytes(),
            corners.clone(),
            list(&[0, 1, 2]),
            list(&[4, 8, 6]),
        ]
        .concat();
        let e = err(&bad);
        assert!(
            e.ends_with("element face 1: vertex index 8 is out of range (8 vertices)"),
            "{e}"
        );
        let short = [
            head("face", 2).into_bytes(),
            corners,
            list(&[0, 1, 2]),
            list(&[4, 5]),
        ]
        .concat();
        let e = err(&short[..short.len() - 2]);
        assert!(
            e.ends_with("element face 1: file ends early (truncated)"),
            "{e}"
        );
    }

    #[test]
    fn points_float_colors_and_zero_normal() {
        let text = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
            property float z\nproperty float diffuse_red\nproperty float diffuse_green\n\
            property float diffuse_blue\nend_header\n1 2 3 1 0.5 0\n4 5 6 0 0 2\n";
        let g = load_bytes(text.as_bytes()).unwrap();
        assert_eq!(g.primitives, Primitives::Points);
        assert_eq!(g.colors.unwrap(), vec![[255, 128, 0], [0, 0, 255]]);
        // A zero normal on a mesh comes from its faces.
        let text = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
            property float z\nproperty float nx\nproperty float ny\nproperty float nz\n\
            element face 1\nproperty list uchar int vertex_index\nend_header\n\
            0 0 0 0 0 0\n2 0 0 0 0 5\n0 2 0 0 0 5\n3 0 1 2\n";
        assert_eq!(
            load_bytes(text.as_bytes()).unwrap().normals.unwrap(),
            vec![Vec3::Z; 3]
        );
    }

    #[test]
    fn bad_inputs() {
        let missing = load(Path::new("/nonexistent/farfield/x.ply")).unwrap_err();
        assert!(matches!(missing, ImportError::Io { .. }));
        let b = binary_quad(false);
        let header_len = b.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
        let e = err(&b[..header_len + 2 * 29 + 5]);
        assert!(
            e.ends_with("element vertex 2: file ends early (truncated)"),
            "{e}"
        );
        let e = err(&b[..b.len() - 1]);
        assert!(
            e.ends_with("element face 1: file ends early (truncated)"),
            "{e}"
        );
        let head = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
            property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
        let e = err(format!("{head}0 0 0\n3 0 0 1\n").as_bytes());
        assert!(
            e.ends_with("element face 0: vertex index 1 is out of range (1 vertices)"),
            "{e}"
        );
        let e = err(format!("{head}0 zero 0\n").as_bytes());
        assert!(
            e.ends_with("element vertex 0: 'zero' is not a number (line 10)"),
            "{e}"
        );
        assert!(err(b"ply\nformat ascii 1.0\nelement vertex 1\n").contains("header"));
        assert!(err(b"PLY\n").contains("not a PLY file"));
        assert!(
            err(b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float64 q\nend_header\n")
                .contains("x, y")
        );
        // Huge header counts must neither allocate nor hang.
        let e = err(b"ply\nformat binary_little_endian 1.0\nelement vertex 18446744073709551615\nproperty float x\nproperty float y\nproperty float z\nelement empty 18446744073709551615\nend_header\n");
        assert!(e.contains("element vertex 0: file ends early"), "{e}");
    }

    #[test]
    fn a_pipe_is_read_instead_of_mapped() {
        // A named pipe cannot be mapped: the body must be read instead.
        let fifo = TestFile::new("pipe.ply", b"");
        let path = fifo.path().to_path_buf();
        std::fs::remove_file(&path).unwrap();
        let c_path = std::ffi::CString::new(path.to_str().unwrap()).unwrap();
        // SAFETY: a valid NUL-terminated path.
        assert_eq!(unsafe { libc::mkfifo(c_path.as_ptr(), 0o600) }, 0);
        let bytes = binary_quad(false);
        let writer = {
            let (path, bytes) = (path.clone(), bytes.clone());
            std::thread::spawn(move || std::fs::write(path, bytes))
        };
        let piped = load(&path);
        writer.join().unwrap().unwrap();
        let piped = piped.unwrap().geometries.remove(0);
        let from_file = load_bytes(&bytes).unwrap();
        assert_eq!(piped.positions, from_file.positions);
        assert_eq!(piped.primitives, from_file.primitives);
        assert_eq!(
            (piped.normals, piped.colors),
            (from_file.normals, from_file.colors)
        );
    }

    #[test]
    fn nan_is_rejected_by_validate() {
        let text = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
            property float z\nend_header\n0 0 0\nnan 1 0\n0 0 1\n";
        let e = TestFile::new("nan.ply", text).load_input().unwrap_err();
        assert!(
            e.to_string()
                .contains("vertex 1: coordinate is not a finite number"),
            "{e}"
        );
    }
}
