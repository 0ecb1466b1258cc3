//! The color-cube octree's bytes (hierarchy kind 2): a fixed 32-byte
//! [`CubeRecord`] per cell, and a per-cell payload after a page's records
//! holding its clustered [`SubCube`]s and, for a leaf, its [`LeafGeometry`].
//!
//! Cells carry no coordinates: a child's cell is its parent's octant
//! ([`child_min`]), the root cell is the header's cube (center
//! `root_center`, half edge `root_radius`). Leaf geometry is clipped to its
//! cell at build time and stored as 16-bit offsets within the cell, so the
//! precision is relative to the cell however deep it lies. Layout in
//! `FORMAT.md`.

use glam::DVec3;

/// Bytes of one cell record.
pub const RECORD_BYTES: usize = 32;
/// Largest cluster edge (k in k x k x k cubes per cell).
pub const MAX_CLUSTER: u8 = 16;
/// Bytes of one clustered sub-cube in a payload.
pub const SUB_CUBE_BYTES: usize = 2 + 6 * 4;
/// Leaf positions are stored in units of [`POSITION_SPAN`] x edge / this.
pub const POSITION_STEPS: f64 = 65535.0;
/// Leaf positions cover the cell grown by half its edge on every side
/// (offset 0 is at `min - edge / 2`): a small triangle is stored whole by
/// the one leaf holding its center, even where it overhangs the cell.
pub const POSITION_SPAN: f64 = 2.0;

/// Whether `k` may be a file's cluster size: a power of two, 1 to 16.
pub fn valid_cluster(k: u8) -> bool {
    (1..=MAX_CLUSTER).contains(&k) && k.is_power_of_two()
}

/// A cube face, named by its outward normal. A face is seen by a viewer on
/// its side: `PosX` is what the cell looks like from +x looking toward -x.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Face {
    PosX,
    NegX,
    PosY,
    NegY,
    PosZ,
    NegZ,
}

impl Face {
    /// All faces in record order.
    pub const ALL: [Face; 6] = [
        Face::PosX,
        Face::NegX,
        Face::PosY,
        Face::NegY,
        Face::PosZ,
        Face::NegZ,
    ];

    pub fn index(self) -> usize {
        self as usize
    }

    /// 0 = x, 1 = y, 2 = z.
    pub fn axis(self) -> usize {
        self.index() / 2
    }

    pub fn positive(self) -> bool {
        self.index().is_multiple_of(2)
    }

    /// Outward unit normal.
    pub fn normal(self) -> DVec3 {
        let mut n = DVec3::ZERO;
        n[self.axis()] = if self.positive() { 1.0 } else { -1.0 };
        n
    }
}

/// Premultiplied RGBA, 8 bits a channel; alpha is the share of the face
/// the cell's geometry covers (0: empty from that side, 255: opaque).
pub type Rgba8 = [u8; 4];

/// One cell of the octree.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CubeRecord {
    /// Bit `o` set when octant `o` has a child (0 for a leaf); children are
    /// stored in octant order.
    pub children: u8,
    /// Clustered sub-cubes in the payload (0 without clustering).
    pub sub_cubes: u16,
    /// The cell's color-cube, in [`Face::ALL`] order.
    pub faces: [Rgba8; 6],
    /// Bytes of this cell's payload (sub-cubes, then leaf geometry).
    pub payload_bytes: u32,
}

impl CubeRecord {
    pub fn pack(&self) -> [u8; RECORD_BYTES] {
        let mut b = [0u8; RECORD_BYTES];
        b[0] = self.children;
        b[2..4].copy_from_slice(&self.sub_cubes.to_le_bytes());
        for (i, f) in self.faces.iter().enumerate() {
            b[4 + 4 * i..8 + 4 * i].copy_from_slice(f);
        }
        b[28..32].copy_from_slice(&self.payload_bytes.to_le_bytes());
        b
    }

    /// Reads a record; `None` when `b` is short or its reserved byte is set.
    pub fn unpack(b: &[u8]) -> Option<Self> {
        let b = b.get(..RECORD_BYTES)?;
        if b[1] != 0 {
            return None;
        }
        let mut faces = [[0u8; 4]; 6];
        for (i, f) in faces.iter_mut().enumerate() {
            f.copy_from_slice(&b[4 + 4 * i..8 + 4 * i]);
        }
        Some(Self {
            children: b[0],
            sub_cubes: u16::from_le_bytes([b[2], b[3]]),
            faces,
            payload_bytes: u32::from_le_bytes(b[28..32].try_into().ok()?),
        })
    }

    pub fn child_count(&self) -> u32 {
        self.children.count_ones()
    }

    pub fn is_leaf(&self) -> bool {
        self.children == 0
    }
}

/// Minimum corner of octant `octant` (bit 0: upper x half, bit 1: y, bit
/// 2: z) of the cell at `min` with edge `edge`.
pub fn child_min(min: DVec3, edge: f64, octant: u8) -> DVec3 {
    let half = edge * 0.5;
    min + DVec3::new(
        f64::from(octant & 1) * half,
        f64::from((octant >> 1) & 1) * half,
        f64::from((octant >> 2) & 1) * half,
    )
}

/// One cube of a k x k x k cluster: its place in the cluster and faces.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SubCube {
    /// `x + k * (y + k * z)`.
    pub cell: u16,
    pub faces: [Rgba8; 6],
}

impl SubCube {
    /// (x, y, z) within a cluster of edge `k`.
    pub fn coords(&self, k: u8) -> [u16; 3] {
        let k = u16::from(k.max(1));
        [self.cell % k, (self.cell / k) % k, self.cell / (k * k)]
    }
}

/// Which optional vertex channels leaf geometry carries (the scene's own).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Channels {
    pub normals: bool,
    pub color: bool,
}

/// The triangles of a leaf cell, clipped to it.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LeafGeometry {
    /// Offsets within the cell, in units of edge / [`POSITION_STEPS`].
    pub positions: Vec<[u16; 3]>,
    /// Octahedral normals ([`crate::octahedral`]), when the scene has them.
    pub normals: Option<Vec<u32>>,
    pub colors: Option<Vec<[u8; 3]>>,
    pub triangles: Vec<[u32; 3]>,
}

impl LeafGeometry {
    /// Indices are 16-bit when every vertex fits, else 32-bit.
    fn wide_indices(&self) -> bool {
        self.positions.len() > usize::from(u16::MAX) + 1
    }

    /// Appends the encoding (counts, channels, indices) to `out`.
    pub fn encode_into(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&(self.positions.len() as u32).to_le_bytes());
        out.extend_from_slice(&(self.triangles.len() as u32).to_le_bytes());
        for p in &self.positions {
            for c in p {
                out.extend_from_slice(&c.to_le_bytes());
            }
        }
        for n in self.normals.iter().flatten() {
            out.extend_from_slice(&n.to_le_bytes());
        }
        for c in self.colors.iter().flatten() {
            out.extend_from_slice(c);
        }
        let wide = self.wide_indices();
        for i in self.triangles.iter().flatten() {
            if wide {
                out.extend_from_slice(&i.to_le_bytes());
            } else {
                out.extend_from_slice(&(*i as u16).to_le_bytes());
            }
        }
    }

    /// Decodes geometry from the front of `bytes`; returns it and the bytes
    /// read, or what is wrong (short, an index past the vertices).
    pub fn decode(bytes: &[u8], channels: Channels) -> Result<(Self, usize), String> {
        let mut r = Cursor { bytes, pos: 0 };
        let vertices = r.u32()? as usize;
        let triangles = r.u32()? as usize;
        let per_vertex = 6 + 4 * usize::from(channels.normals) + 3 * usize::from(channels.color);
        let wide = vertices > usize::from(u16::MAX) + 1;
        let index_bytes = if wide { 4 } else { 2 };
        let need = vertices
            .checked_mul(per_vertex)
            .and_then(|v| triangles.checked_mul(3 * index_bytes)?.checked_add(v))
            .ok_or("geometry counts overflow")?;
        if r.rest() < need {
            return Err(format!(
                "leaf geometry of {vertices} vertices and {triangles} triangles needs {need} bytes, {} left",
                r.rest()
            ));
        }
        let mut g = LeafGeometry {
            positions: (0..vertices)
                .map(|_| Ok([r.u16()?, r.u16()?, r.u16()?]))
                .collect::<Result<_, String>>()?,
            ..Default::default()
        };
        if channels.normals {
            g.normals = Some((0..vertices).map(|_| r.u32()).collect::<Result<_, _>>()?);
        }
        if channels.color {
            g.colors = Some(
                (0..vertices)
                    .map(|_| Ok([r.u8()?, r.u8()?, r.u8()?]))
                    .collect::<Result<_, String>>()?,
            );
        }
        let mut index = || -> Result<u32, String> {
            let i = if wide { r.u32()? } else { u32::from(r.u16()?) };
            if i as usize >= vertices {
                return Err(format!("triangle index {i} is past {vertices} vertices"));
            }
            Ok(i)
        };
        g.triangles = (0..triangles)
            .map(|_| Ok([index()?, index()?, index()?]))
            .collect::<Result<_, String>>()?;
        Ok((g, r.pos))
    }
}

/// A cell's payload: its sub-cubes, then (for a leaf) its geometry.
pub fn encode_payload(sub_cubes: &[SubCube], geometry: Option<&LeafGeometry>) -> Vec<u8> {
    let mut out = Vec::with_capacity(sub_cubes.len() * SUB_CUBE_BYTES);
    for s in sub_cubes {
        out.extend_from_slice(&s.cell.to_le_bytes());
        for f in &s.faces {
            out.extend_from_slice(f);
        }
    }
    if let Some(g) = geometry {
        g.encode_into(&mut out);
    }
    out
}

/// What a cell's payload holds, decoded and checked.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Payload {
    pub sub_cubes: Vec<SubCube>,
    pub geometry: Option<LeafGeometry>,
}

/// Decodes the payload of `record`; every byte must be accounted for.
pub fn decode_payload(
    record: &CubeRecord,
    bytes: &[u8],
    cluster: u8,
    channels: Channels,
) -> Result<Payload, String> {
    if bytes.len() as u64 != u64::from(record.payload_bytes) {
        return Err(format!(
            "payload is {} bytes, the record says {}",
            bytes.len(),
            record.payload_bytes
        ));
    }
    let n = usize::from(record.sub_cubes);
    let cube_bytes = n * SUB_CUBE_BYTES;
    if bytes.len() < cube_bytes {
        return Err(format!("{n} sub-cubes do not fit {} bytes", bytes.len()));
    }
    let cells = u32::from(cluster).pow(3);
    let mut sub_cubes = Vec::with_capacity(n);
    for chunk in bytes[..cube_bytes].chunks_exact(SUB_CUBE_BYTES) {
        let cell = u16::from_le_bytes([chunk[0], chunk[1]]);
        if u32::from(cell) >= cells {
            return Err(format!("sub-cube {cell} is outside a {cluster}^3 cluster"));
        }
        let mut faces = [[0u8; 4]; 6];
        for (i, f) in faces.iter_mut().enumerate() {
            f.copy_from_slice(&chunk[2 + 4 * i..6 + 4 * i]);
        }
        sub_cubes.push(SubCube { cell, faces });
    }
    let rest = &bytes[cube_bytes..];
    let geometry = if record.is_leaf() && !rest.is_empty() {
        let (g, used) = LeafGeometry::decode(rest, channels)?;
        if used != rest.len() {
            return Err(format!(
                "{} bytes after the leaf geometry",
                rest.len() - used
            ));
        }
        Some(g)
    } else if !rest.is_empty() {
        return Err(format!("{} unexplained payload bytes", rest.len()));
    } else {
        None
    };
    Ok(Payload {
        sub_cubes,
        geometry,
    })
}

/// A position as a cell-relative 16-bit offset (clamped into the cell
/// grown by half an edge on each side).
pub fn quantize_in_cell(p: DVec3, min: DVec3, edge: f64) -> [u16; 3] {
    let rel = if edge > 0.0 {
        (p - min) / edge
    } else {
        DVec3::ZERO
    };
    rel.to_array().map(|c| {
        let unit = (c + 0.5) / POSITION_SPAN;
        (unit.clamp(0.0, 1.0) * POSITION_STEPS).round() as u16
    })
}

/// Inverse of [`quantize_in_cell`], relative to `origin` (the camera, for
/// camera-relative rendering).
pub fn dequantize_in_cell(q: [u16; 3], min: DVec3, edge: f64, origin: DVec3) -> DVec3 {
    (min - origin) - DVec3::splat(0.5 * edge)
        + DVec3::from(q.map(f64::from)) * (POSITION_SPAN * edge / POSITION_STEPS)
}

/// A little-endian reader over a payload.
struct Cursor<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl Cursor<'_> {
    fn take<const N: usize>(&mut self) -> Result<[u8; N], String> {
        let b = self
            .bytes
            .get(self.pos..self.pos + N)
            .ok_or("leaf geometry is truncated")?;
        self.pos += N;
        Ok(b.try_into().unwrap_or([0; N]))
    }
    fn u8(&mut self) -> Result<u8, String> {
        Ok(self.take::<1>()?[0])
    }
    fn u16(&mut self) -> Result<u16, String> {
        Ok(u16::from_le_bytes(self.take()?))
    }
    fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.take()?))
    }
    fn rest(&self) -> usize {
        self.bytes.len() - self.pos
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_round_trip() {
        let r = CubeRecord {
            children: 0b1010_0101,
            sub_cubes: 513,
            faces: [
                [1, 2, 3, 4],
                [5, 6, 7, 8],
                [9, 10, 11, 12],
                [0; 4],
                [255; 4],
                [7; 4],
            ],
            payload_bytes: 70_000,
        };
        assert_eq!(CubeRecord::unpack(&r.pack()), Some(r));
        assert_eq!(r.child_count(), 4);
        let mut bad = r.pack();
        bad[1] = 1;
        assert_eq!(CubeRecord::unpack(&bad), None);
    }

    #[test]
    fn geometry_round_trips_with_and_without_channels() {
        for channels in [
            Channels::default(),
            Channels {
                normals: true,
                color: true,
            },
        ] {
            let g = LeafGeometry {
                positions: vec![[0, 0, 0], [65535, 0, 7], [3, 65535, 65535]],
                normals: channels.normals.then(|| vec![1, 2, 3]),
                colors: channels
                    .color
                    .then(|| vec![[1, 2, 3], [4, 5, 6], [7, 8, 9]]),
                triangles: vec![[0, 1, 2], [2, 1, 0]],
            };
            let sub = [SubCube {
                cell: 5,
                faces: [[9; 4]; 6],
            }];
            let bytes = encode_payload(&sub, Some(&g));
            let record = CubeRecord {
                sub_cubes: 1,
                payload_bytes: bytes.len() as u32,
                ..Default::default()
            };
            let p = decode_payload(&record, &bytes, 2, channels).unwrap();
            assert_eq!(p.geometry.as_ref(), Some(&g));
            assert_eq!(p.sub_cubes, sub);
            assert_eq!(sub[0].coords(2), [1, 0, 1]);
            // Every truncation is an error, never a panic.
            for cut in 0..bytes.len() {
                assert!(decode_payload(&record, &bytes[..cut], 2, channels).is_err());
            }
        }
    }

    #[test]
    fn bad_indices_and_cells_are_refused() {
        let g = LeafGeometry {
            positions: vec![[0; 3]; 2],
            triangles: vec![[0, 1, 2]],
            ..Default::default()
        };
        let bytes = encode_payload(&[], Some(&g));
        let record = CubeRecord {
            payload_bytes: bytes.len() as u32,
            ..Default::default()
        };
        let e = decode_payload(&record, &bytes, 1, Channels::default());
        assert!(e.unwrap_err().contains("index 2"));
        let sub = [SubCube {
            cell: 8,
            faces: [[0; 4]; 6],
        }];
        let bytes = encode_payload(&sub, None);
        let record = CubeRecord {
            children: 1,
            sub_cubes: 1,
            payload_bytes: bytes.len() as u32,
            ..Default::default()
        };
        let e = decode_payload(&record, &bytes, 2, Channels::default());
        assert!(e.unwrap_err().contains("outside"));
    }

    #[test]
    fn cell_quantization_is_exact_at_the_faces_and_relative() {
        // Millimetre cells 1e7 from the origin keep their precision: the
        // error is half a step plus the rounding of `p` itself in f64.
        let min = DVec3::splat(1e7);
        let edge = 1e-3;
        let p = min + DVec3::new(0.25, 1.0, 0.0) * edge;
        let q = quantize_in_cell(p, min, edge);
        let step = POSITION_SPAN * edge / POSITION_STEPS;
        let back = dequantize_in_cell(q, min, edge, min);
        let ulp = 2.0 * f64::EPSILON * 1e7;
        assert!((back - (p - min)).length() <= step + 2.0 * ulp);
        // Points past the grown cell are clamped to it.
        assert_eq!(
            quantize_in_cell(min - DVec3::splat(edge), min, edge),
            [0; 3]
        );
        assert_eq!(
            quantize_in_cell(min + DVec3::splat(2.0 * edge), min, edge),
            [65535; 3]
        );
        assert_eq!(
            child_min(DVec3::ZERO, 2.0, 0b101),
            DVec3::new(1.0, 0.0, 1.0)
        );
    }
}
