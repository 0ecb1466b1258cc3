//! QSplat's quantized bounding-sphere node (Rusinkiewicz & Levoy 2000, 3.1).
//!
//! A node record packs, from bit 0 up:
//!
//! | bits | field | present |
//! |---|---|---|
//! | 13 | position and radius relative to the parent: an index into [`sphere_table`] | always |
//! | 2  | child count: 0 (leaf), 2, 3 or 4 ([`ChildCount`]) | always |
//! | 14 | normal: a cell of a 52x52 grid on one of the 6 cube faces, warped | when [`NodeLayout::normals`] |
//! | 2  | normal-cone half-angle, sine 1/16, 4/16, 9/16 or 1 | when [`NodeLayout::normals`] |
//! | 16 | color, 5-6-5 | when [`NodeLayout::color`] |
//!
//! rounded up to whole bytes: 2 bytes for bare spheres, 4 with normals or
//! color, 6 with both.
//!
//! Position and radius are quantized to thirteenths: the center offset on
//! each axis is `i * 2R/13` for `i` in -6..=6 and the radius is `l * R/13`
//! for `l` in 1..=13, where R is the *quantized* parent's radius. Only
//! combinations whose sphere lies inside the parent are valid; the table of
//! them is indexed by the 13-bit code. Encoding always rounds the radius up
//! so the quantized sphere encloses the true one, which is what keeps a
//! hole-free set of leaf spheres hole-free after quantization.

use std::sync::OnceLock;

use glam::{DVec3, Vec3};

/// Quantization steps per parent radius (the paper's 13).
pub const STEPS: i32 = 13;
/// Cells per cube-face edge in the normal grid (the paper's 52).
pub const NORMAL_GRID: u32 = 52;
/// Number of representable normals: 52 * 52 * 6.
pub const NORMAL_CODES: u32 = NORMAL_GRID * NORMAL_GRID * 6;
/// Sines of the four representable normal-cone half-angles.
pub const CONE_SINES: [f64; 4] = [1.0 / 16.0, 4.0 / 16.0, 9.0 / 16.0, 1.0];

/// Which optional fields a node record carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NodeLayout {
    pub normals: bool,
    pub color: bool,
}

impl NodeLayout {
    /// Bits of one record.
    pub fn bits(self) -> u32 {
        15 + if self.normals { 16 } else { 0 } + if self.color { 16 } else { 0 }
    }

    /// Bytes of one record (bits rounded up).
    pub fn bytes(self) -> u32 {
        self.bits().div_ceil(8)
    }

    fn color_shift(self) -> u32 {
        if self.normals { 31 } else { 15 }
    }
}

/// Number of children of a node: QSplat allows no single-child nodes, so two
/// bits cover leaf, 2, 3 and 4.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ChildCount(u8);

impl ChildCount {
    pub const LEAF: Self = Self(0);

    /// `None` for 1 or more than 4 children: the builder never makes those.
    pub fn new(n: usize) -> Option<Self> {
        matches!(n, 0 | 2 | 3 | 4).then_some(Self(n as u8))
    }
    pub fn get(self) -> usize {
        usize::from(self.0)
    }
    fn code(self) -> u64 {
        match self.0 {
            0 => 0,
            n => u64::from(n - 1),
        }
    }
    fn from_code(code: u64) -> Self {
        Self(match code & 3 {
            0 => 0,
            c => c as u8 + 1,
        })
    }
}

/// One node's quantized fields, unpacked.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NodeRecord {
    /// Index into [`sphere_table`].
    pub sphere: u16,
    pub children: ChildCount,
    /// Index into [`normal_table`] (0 when the layout has no normals).
    pub normal: u16,
    /// Index into [`CONE_SINES`] (3, "no culling", without normals).
    pub cone: u8,
    /// 5-6-5 color (0 without color).
    pub color: u16,
}

impl NodeRecord {
    /// A leaf with every field zero: a placeholder, not a valid node.
    pub const EMPTY: Self = Self {
        sphere: 0,
        children: ChildCount::LEAF,
        normal: 0,
        cone: 0,
        color: 0,
    };

    /// Packs the record into the low [`NodeLayout::bits`] of a u64.
    pub fn pack(&self, layout: NodeLayout) -> u64 {
        let mut w = u64::from(self.sphere & 0x1fff) | self.children.code() << 13;
        if layout.normals {
            w |= u64::from(self.normal & 0x3fff) << 15 | u64::from(self.cone & 3) << 29;
        }
        if layout.color {
            w |= u64::from(self.color) << layout.color_shift();
        }
        w
    }

    /// Unpacks a record; fields the layout lacks get neutral values.
    #[inline]
    pub fn unpack(word: u64, layout: NodeLayout) -> Self {
        let (normal, cone) = if layout.normals {
            ((word >> 15 & 0x3fff) as u16, (word >> 29 & 3) as u8)
        } else {
            (0, 3)
        };
        let color = if layout.color {
            (word >> layout.color_shift() & 0xffff) as u16
        } else {
            0
        };
        Self {
            sphere: (word & 0x1fff) as u16,
            children: ChildCount::from_code(word >> 13),
            normal,
            cone,
            color,
        }
    }

    /// Only the child count, for page indexing without a full unpack.
    #[inline]
    pub fn child_count(word: u64) -> usize {
        ChildCount::from_code(word >> 13).get()
    }
}

/// One valid position/radius combination, as multiples of the parent radius.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SphereStep {
    /// Center offset divided by the parent radius.
    pub offset: DVec3,
    /// Radius divided by the parent radius.
    pub radius: f64,
    /// The integer grid coordinates (i, j, k, l).
    pub grid: [i8; 4],
}

struct SphereTables {
    steps: Vec<SphereStep>,
    /// (i+6, j+6, k+6, l-1) -> code, or u16::MAX when invalid.
    code_of: Vec<u16>,
}

fn sphere_tables() -> &'static SphereTables {
    static TABLES: OnceLock<SphereTables> = OnceLock::new();
    TABLES.get_or_init(|| {
        let half = STEPS / 2;
        let mut steps = Vec::new();
        let mut code_of = vec![u16::MAX; (STEPS * STEPS * STEPS * STEPS) as usize];
        for l in 1..=STEPS {
            for i in -half..=half {
                for j in -half..=half {
                    for k in -half..=half {
                        // Inside the parent: |offset| + r <= R, in thirteenths:
                        // 2*sqrt(i²+j²+k²) + l <= 13, checked in integers.
                        let slack = STEPS - l;
                        if 4 * (i * i + j * j + k * k) > slack * slack {
                            continue;
                        }
                        code_of[grid_slot(i, j, k, l)] = steps.len() as u16;
                        let scale = 2.0 / f64::from(STEPS);
                        steps.push(SphereStep {
                            offset: DVec3::new(f64::from(i), f64::from(j), f64::from(k)) * scale,
                            radius: f64::from(l) / f64::from(STEPS),
                            grid: [i as i8, j as i8, k as i8, l as i8],
                        });
                    }
                }
            }
        }
        SphereTables { steps, code_of }
    })
}

fn grid_slot(i: i32, j: i32, k: i32, l: i32) -> usize {
    let half = STEPS / 2;
    ((((i + half) * STEPS + (j + half)) * STEPS + (k + half)) * STEPS + (l - 1)) as usize
}

/// The table of valid position/radius combinations, indexed by code.
pub fn sphere_table() -> &'static [SphereStep] {
    &sphere_tables().steps
}

/// The code of the sphere equal to its parent (offset 0, radius 13/13).
pub fn identity_sphere_code() -> u16 {
    sphere_tables().code_of[grid_slot(0, 0, 0, STEPS)]
}

/// Decodes a child sphere from its code and its (quantized) parent.
#[inline]
pub fn decode_sphere(parent_center: DVec3, parent_radius: f64, code: u16) -> (DVec3, f64) {
    let step = &sphere_table()[usize::from(code)];
    (
        parent_center + step.offset * parent_radius,
        step.radius * parent_radius,
    )
}

/// Encodes `child` relative to the quantized parent so that the decoded
/// sphere encloses the child and lies inside the parent.
///
/// Grid points around the child's center are tried, nearest first (the
/// nearest point and its inward neighbours, then a 5x5x5 block, then the
/// whole grid), each with the smallest radius
/// step that encloses the child *as decoded in floating point*; the
/// smallest valid sphere of the first block that has one wins. The
/// parent-sized code qualifies for any child inside the parent, so a
/// well-formed child always gets a code; a child that pokes out of its parent
/// (a caller's bug) gets the parent-sized code.
pub fn encode_sphere(
    parent_center: DVec3,
    parent_radius: f64,
    child_center: DVec3,
    child_radius: f64,
) -> u16 {
    let tables = sphere_tables();
    let rel = (child_center - parent_center) / parent_radius;
    let rel_radius = child_radius / parent_radius;
    let steps = f64::from(STEPS);
    let half = STEPS / 2;
    let nearest = |v: f64| ((v * steps * 0.5).round() as i32).clamp(-half, half);
    let (ni, nj, nk) = (nearest(rel.x), nearest(rel.y), nearest(rel.z));
    // The nearest grid point needs the smallest radius of all points, so if
    // its sphere is valid and encloses the child, it is the answer.
    // Decoded here with the table's own arithmetic (same operations, same
    // bits as `decode_sphere`), so the common case reads no table but the
    // code's.
    let offset = DVec3::new(f64::from(ni), f64::from(nj), f64::from(nk)) * (2.0 / steps);
    let l0 = ceil_steps((rel - offset).length() + rel_radius);
    let spread = 4 * (ni * ni + nj * nj + nk * nk);
    for l in l0..=(l0 + 1).min(STEPS) {
        // Valid (inside the parent) exactly when the table has a code.
        if spread > (STEPS - l) * (STEPS - l) {
            break;
        }
        let c = parent_center + offset * parent_radius;
        let r = f64::from(l) / steps * parent_radius;
        if c.distance(child_center) + child_radius <= r {
            return tables.code_of[grid_slot(ni, nj, nk, l)];
        }
    }
    for reach in [0, 2, STEPS] {
        // (smallest radius step, i, j, k) of each grid point nearby whose
        // sphere at that step would be valid, smallest step first.
        // On the stack for the first block, which serves all but a few
        // hundred children per million; the heap for the larger ones.
        let mut small = [(0, 0, 0, 0); 8];
        let mut large = Vec::new();
        let mut count = 0;
        // First only the nearest grid point and its neighbours toward the
        // parent's center (moving inward is what makes a code valid near
        // the boundary): at most 8 points, which serve nearly every child.
        let range = |n: i32| {
            if reach == 0 {
                let inward = n - n.signum();
                n.min(inward)..=n.max(inward)
            } else {
                (n - reach).max(-half)..=(n + reach).min(half)
            }
        };
        for i in range(ni) {
            for j in range(nj) {
                for k in range(nk) {
                    let offset =
                        DVec3::new(f64::from(i), f64::from(j), f64::from(k)) * (2.0 / steps);
                    let l0 = ceil_steps((rel - offset).length() + rel_radius);
                    let slack = STEPS - l0;
                    // Integer validity: a larger step is only less valid.
                    if slack >= 0 && 4 * (i * i + j * j + k * k) <= slack * slack {
                        if reach == 0 {
                            small[count] = (l0, i, j, k);
                            count += 1;
                        } else {
                            large.push((l0, i, j, k));
                        }
                    }
                }
            }
        }
        let candidates = if reach == 0 {
            &mut small[..count]
        } else {
            &mut large[..]
        };
        candidates.sort_unstable();
        let mut best: Option<(i32, u16)> = None;
        for &(l0, i, j, k) in candidates.iter() {
            if best.is_some_and(|(bl, _)| l0 >= bl) {
                break;
            }
            // The real-number bound may miss by an ulp once decoded:
            // confirm in f64, one step larger if need be.
            for l in l0..=(l0 + 1).min(STEPS) {
                if best.is_some_and(|(bl, _)| l >= bl) {
                    break;
                }
                let code = tables.code_of[grid_slot(i, j, k, l)];
                if code == u16::MAX {
                    break;
                }
                let (c, r) = decode_sphere(parent_center, parent_radius, code);
                if c.distance(child_center) + child_radius <= r {
                    best = Some((l, code));
                    break;
                }
            }
        }
        if let Some((_, code)) = best {
            return code;
        }
    }
    identity_sphere_code()
}

/// The radius step (1 or more) that covers `need` parent radii: the ceiling
/// of `need * 13`, without a libm call; above 13 means "does not fit".
#[inline]
fn ceil_steps(need: f64) -> i32 {
    let scaled = (need * f64::from(STEPS)).min(f64::from(STEPS + 1));
    let floor = scaled as i32;
    (floor + i32::from(f64::from(floor) < scaled)).max(1)
}

/// The equal-angle warp of a cube-face coordinate in [-1, 1]: cells of the
/// grid then cover nearly equal solid angles (the paper's "warped" grid).
fn warp(g: f64) -> f64 {
    (g * std::f64::consts::FRAC_PI_4).tan()
}

/// The 16224 representable normals, indexed by code.
pub fn normal_table() -> &'static [Vec3] {
    static TABLE: OnceLock<Vec<Vec3>> = OnceLock::new();
    TABLE.get_or_init(|| {
        let n = NORMAL_GRID;
        let mut table = Vec::with_capacity(NORMAL_CODES as usize);
        for face in 0..6u32 {
            let axis = (face / 2) as usize;
            let sign = if face % 2 == 0 { 1.0 } else { -1.0 };
            for iu in 0..n {
                for iv in 0..n {
                    let center = |i: u32| warp((f64::from(i) + 0.5) / f64::from(n) * 2.0 - 1.0);
                    let mut v = [0.0f64; 3];
                    v[axis] = sign;
                    v[(axis + 1) % 3] = center(iu);
                    v[(axis + 2) % 3] = center(iv);
                    table.push(DVec3::from(v).normalize().as_vec3());
                }
            }
        }
        table
    })
}

/// Cell boundaries of the warped grid on a cube face, in face coordinates:
/// `warp(-1 + 2 i / 52)` for i = 0..=52. Finding a coordinate's cell by
/// search over these replaces an arctangent per component.
fn normal_cell_edges() -> &'static [f64; NORMAL_GRID as usize + 1] {
    static EDGES: OnceLock<[f64; NORMAL_GRID as usize + 1]> = OnceLock::new();
    EDGES.get_or_init(|| {
        std::array::from_fn(|i| warp(i as f64 / f64::from(NORMAL_GRID) * 2.0 - 1.0))
    })
}

/// Bins of [`normal_cell_lookup`] across a face coordinate's [-1, 1].
const CELL_BINS: usize = 256;

/// For each of [`CELL_BINS`] equal bins of a face coordinate, the number of
/// interior cell edges safely below the bin's start: a lower bound on the
/// cell of any coordinate in the bin, so finding the cell takes a lookup
/// and a step or two instead of a binary search. Bins (width 1/128) are
/// narrower than the narrowest cell (about 0.03), so a step or two suffices.
fn normal_cell_lookup() -> &'static [u8; CELL_BINS] {
    static LOOKUP: OnceLock<[u8; CELL_BINS]> = OnceLock::new();
    LOOKUP.get_or_init(|| {
        let edges = normal_cell_edges();
        std::array::from_fn(|bin| {
            // Margin: rounding in the caller's bin computation can put a
            // coordinate a hair below its bin's start.
            let start = bin as f64 * 2.0 / CELL_BINS as f64 - 1.0 - 1e-9;
            edges[1..NORMAL_GRID as usize].partition_point(|&e| e < start) as u8
        })
    })
}

/// The largest angle (radians) between a unit normal and its decoded code,
/// measured over the grid's cell corners; `tests` check it against samples.
pub const MAX_NORMAL_ERROR: f64 = 0.024;

/// Quantizes a unit normal to 14 bits. A zero or non-finite normal encodes
/// as +Z (callers give such nodes a full cone, so it is never culled).
pub fn encode_normal(normal: Vec3) -> u16 {
    let n = normal.as_dvec3();
    if !n.is_finite() || n.length_squared() == 0.0 {
        return encode_normal(Vec3::Z);
    }
    let a = n.abs();
    let axis = if a.x >= a.y && a.x >= a.z {
        0
    } else if a.y >= a.z {
        1
    } else {
        2
    };
    let major = n[axis];
    let face = axis as u32 * 2 + u32::from(major < 0.0);
    let (edges, first_cell) = (normal_cell_edges(), normal_cell_lookup());
    let cell = |v: f64| {
        let u = v / major.abs();
        // Interior edges at or below u: the cell index, 0..=51. The lookup
        // gives a lower bound from u's bin; at most two edges follow.
        let bin = ((u + 1.0) * CELL_BINS as f64 * 0.5).clamp(0.0, CELL_BINS as f64 - 1.0) as usize;
        let mut cell = first_cell[bin] as usize;
        while cell < NORMAL_GRID as usize - 1 && edges[cell + 1] <= u {
            cell += 1;
        }
        cell as u32
    };
    let iu = cell(n[(axis + 1) % 3]);
    let iv = cell(n[(axis + 2) % 3]);
    (face * NORMAL_GRID * NORMAL_GRID + iu * NORMAL_GRID + iv) as u16
}

/// Decodes a normal code; out-of-range codes (possible only in corrupt data
/// that passed its checksum) decode as +Z rather than panicking.
#[inline]
pub fn decode_normal(code: u16) -> Vec3 {
    normal_table()
        .get(usize::from(code))
        .copied()
        .unwrap_or(Vec3::Z)
}

/// Half-angles (radians) of the four cone codes.
#[inline]
pub fn cone_half_angle(code: u8) -> f64 {
    // asin of CONE_SINES, spelled out so hot loops need no libm call.
    const HALF_ANGLES: [f64; 4] = [
        0.062_540_761_796_491_39,
        0.252_680_255_142_078_65,
        0.597_406_416_645_350_2,
        std::f64::consts::FRAC_PI_2,
    ];
    HALF_ANGLES[usize::from(code & 3)]
}

/// The smallest cone code whose half-angle covers `half_angle` radians;
/// anything at or beyond 90 degrees (or NaN) is code 3, which never culls.
#[inline]
pub fn encode_cone(half_angle: f64) -> u8 {
    (0..3u8)
        .find(|&c| half_angle <= cone_half_angle(c))
        .unwrap_or(3)
}

/// Quantizes an sRGB color to 5-6-5 with rounding.
#[inline]
pub fn encode_color(rgb: [u8; 3]) -> u16 {
    let q = |v: u8, bits: u32| ((u32::from(v) * ((1 << bits) - 1) + 127) / 255) as u16;
    q(rgb[0], 5) << 11 | q(rgb[1], 6) << 5 | q(rgb[2], 5)
}

/// Expands a 5-6-5 color back to 8 bits per channel.
pub fn decode_color(c: u16) -> [u8; 3] {
    let e = |v: u16, bits: u32| {
        ((u32::from(v) * 255 + ((1 << bits) - 1) / 2) / ((1 << bits) - 1)) as u8
    };
    [e(c >> 11, 5), e(c >> 5 & 0x3f, 6), e(c & 0x1f, 5)]
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn table_has_only_enclosed_spheres_and_fits_13_bits() {
        let t = sphere_table();
        assert!(t.len() < 1 << 13, "{} codes", t.len());
        for s in t {
            assert!(
                s.offset.length() + s.radius <= 1.0 + 1e-12,
                "{s:?} leaves the parent"
            );
        }
        let id = t[usize::from(identity_sphere_code())];
        assert_eq!((id.offset, id.radius), (DVec3::ZERO, 1.0));
    }

    #[test]
    fn mean_normal_error_is_about_a_hundredth_of_a_radian() {
        // A deterministic spiral over the sphere.
        let n = 20_000;
        let mut total = 0.0;
        for i in 0..n {
            let z = 1.0 - 2.0 * (f64::from(i) + 0.5) / f64::from(n);
            let phi = f64::from(i) * 2.399_963_229_728_653;
            let r = (1.0 - z * z).sqrt();
            let v = DVec3::new(r * phi.cos(), r * phi.sin(), z).as_vec3();
            total += f64::from(v.angle_between(decode_normal(encode_normal(v))));
        }
        let mean = total / f64::from(n);
        assert!(mean > 0.005 && mean < 0.015, "mean normal error {mean} rad");
    }

    #[test]
    fn max_normal_error_holds_at_cell_corners() {
        // The worst case of a cell is at a corner: sweep every face's grid
        // edges and a little inside them.
        let edges = normal_cell_edges();
        let mut worst = 0.0f64;
        for face in 0..6usize {
            let (axis, sign) = (face / 2, if face % 2 == 0 { 1.0 } else { -1.0 });
            for &u in edges.iter() {
                for &v in edges.iter() {
                    for (du, dv) in [(1e-9, 1e-9), (-1e-9, -1e-9), (1e-9, -1e-9), (-1e-9, 1e-9)] {
                        let mut p = [0.0f64; 3];
                        p[axis] = sign;
                        p[(axis + 1) % 3] = (u + du).clamp(-1.0, 1.0);
                        p[(axis + 2) % 3] = (v + dv).clamp(-1.0, 1.0);
                        let n = DVec3::from(p).normalize().as_vec3();
                        worst =
                            worst.max(f64::from(n.angle_between(decode_normal(encode_normal(n)))));
                    }
                }
            }
        }
        assert!(worst <= MAX_NORMAL_ERROR, "worst normal error {worst}");
        assert!(
            worst > MAX_NORMAL_ERROR * 0.8,
            "bound {MAX_NORMAL_ERROR} is loose: worst {worst}"
        );
    }

    #[test]
    fn cell_lookup_agrees_with_a_search_of_the_edges() {
        // Every edge, a hair either side of it, and a fine sweep: the
        // lookup's cell must be the binary search's.
        let edges = normal_cell_edges();
        let interior = &edges[1..NORMAL_GRID as usize];
        let mut coordinates: Vec<f64> = (0..=100_000)
            .map(|i| f64::from(i) / 50_000.0 - 1.0)
            .collect();
        for &e in edges.iter() {
            coordinates.extend([e, e.next_down(), e.next_up(), e - 1e-12, e + 1e-12]);
        }
        for u in coordinates.into_iter().filter(|u| (-1.0..=1.0).contains(u)) {
            // A normal whose major axis is +X: its cell along Y is found
            // from the coordinate as the encoder sees it, in f32.
            let n = Vec3::new(1.0, u as f32, 0.0);
            let expected = interior.partition_point(|&e| e <= f64::from(n.y)) as u16;
            let iu = encode_normal(n) / NORMAL_GRID as u16 % NORMAL_GRID as u16;
            assert_eq!(iu, expected, "u = {u}");
        }
    }

    #[test]
    fn cone_angles_are_the_asin_of_their_sines() {
        for (code, sine) in CONE_SINES.iter().enumerate() {
            assert!((cone_half_angle(code as u8) - sine.asin()).abs() < 1e-15);
        }
    }

    #[test]
    fn cone_codes_are_conservative() {
        for deg in 0..=180 {
            let a = f64::from(deg).to_radians();
            let c = encode_cone(a);
            assert!(
                c == 3 || cone_half_angle(c) >= a,
                "{deg} degrees -> code {c}"
            );
        }
        assert_eq!(encode_cone(0.0), 0);
        assert_eq!(encode_cone(f64::NAN), 3);
    }

    #[test]
    fn record_round_trips_in_every_layout() {
        let r = NodeRecord {
            sphere: 3268,
            children: ChildCount::new(3).unwrap(),
            normal: 16223,
            cone: 2,
            color: 0xbeef,
        };
        for (normals, color, bytes) in [
            (false, false, 2),
            (true, false, 4),
            (false, true, 4),
            (true, true, 6),
        ] {
            let layout = NodeLayout { normals, color };
            assert_eq!(layout.bytes(), bytes);
            let word = r.pack(layout);
            assert!(word < 1 << layout.bits());
            let back = NodeRecord::unpack(word, layout);
            assert_eq!(back.sphere, r.sphere);
            assert_eq!(back.children, r.children);
            assert_eq!(back.normal, if normals { r.normal } else { 0 });
            assert_eq!(back.color, if color { r.color } else { 0 });
        }
    }

    proptest! {
        #[test]
        fn decoded_child_encloses_true_child_and_stays_in_parent(
            px in -1e3f64..1e3, py in -1e3f64..1e3, pz in -1e3f64..1e3,
            log_r in -6.0f64..6.0,
            dir in prop::array::uniform3(-1.0f64..1.0),
            dist_frac in 0.0f64..1.0, rad_frac in 0.0f64..1.0,
        ) {
            let parent_r = 10f64.powf(log_r);
            let parent_c = DVec3::new(px, py, pz);
            let d = DVec3::from(dir).normalize_or(DVec3::X);
            let child_r = parent_r * rad_frac;
            let child_c = parent_c + d * (parent_r - child_r) * dist_frac;
            let code = encode_sphere(parent_c, parent_r, child_c, child_r);
            let (c, r) = decode_sphere(parent_c, parent_r, code);
            prop_assert!(c.distance(child_c) + child_r <= r, "does not enclose");
            // Inside up to the rounding of f64 positions at this magnitude.
            let ulps = 8.0 * f64::EPSILON * (parent_c.length() + parent_r);
            prop_assert!(c.distance(parent_c) + r <= parent_r + ulps, "leaves parent");
        }

        #[test]
        fn color_round_trips_within_565_precision(r: u8, g: u8, b: u8) {
            let back = decode_color(encode_color([r, g, b]));
            prop_assert!((i32::from(back[0]) - i32::from(r)).abs() <= 4);
            prop_assert!((i32::from(back[1]) - i32::from(g)).abs() <= 2);
            prop_assert!((i32::from(back[2]) - i32::from(b)).abs() <= 4);
        }

        #[test]
        fn normal_error_is_bounded(x in -1.0f32..1.0, y in -1.0f32..1.0, z in -1.0f32..1.0) {
            let v = Vec3::new(x, y, z);
            prop_assume!(v.length() > 1e-3);
            let v = v.normalize();
            let error = f64::from(v.angle_between(decode_normal(encode_normal(v))));
            prop_assert!(error <= MAX_NORMAL_ERROR, "{error}");
        }
    }
}
