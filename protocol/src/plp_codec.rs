//! The PLP tessellation's bytes (Klosowski & Silva, *Rendering on a
//! Budget*, section 3.1): the cell skeleton in page 0, the cells'
//! triangles in the pages after it.
//!
//! The skeleton is everything the traversal needs to order the whole
//! scene: the Delaunay cells (four vertices, four face neighbours, the
//! triangle count `|c|`) and `ρmax`. It is one read after the header, so a
//! client can run PLP's projection order before any triangle arrives, and
//! that order is what it asks the server for. Shared-face normals are not
//! stored: they are a cross product of the cell's own vertices, computed
//! once on arrival ([`Skeleton::face_normal`]), so a stored normal can never
//! disagree with the geometry it belongs to.
//!
//! A cell page holds consecutive cells (the tree's nodes 1..): one 8-byte
//! record each (its triangle count in the page's lists), then the payload:
//! an anchor, the page's distinct triangles (each once, with its scene-wide
//! id, corners relative to the anchor), and each cell's list of indices
//! into them. A triangle that crosses several cells of one page is stored
//! once; one that crosses cells of two pages is stored in both (the id
//! lets the client draw it once a frame). `FORMAT.md` has the bytes.

use glam::DVec3;

/// Bytes of a PLP node record: page 0's root (cell count, 0) and every
/// cell's (triangles in its list, 0).
pub const NODE_BYTES: usize = 8;
/// A cell face on the hull has no neighbour.
pub const NO_NEIGHBOUR: u32 = u32::MAX;
/// Bytes of one stored triangle: id, nine f32 coordinates, RGBA.
pub const TRIANGLE_BYTES: usize = 4 + 36 + 4;
/// Bytes of one stored cell in the skeleton.
pub const CELL_BYTES: usize = 10 * 4;
/// Bytes before the skeleton's vertices.
const SKELETON_HEADER_BYTES: usize = 24;

/// One Delaunay cell as stored.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cell {
    /// Indices into [`Skeleton::vertices`], positively oriented:
    /// `orient3d(v0, v1, v2, v3) > 0`.
    pub vertices: [u32; 4],
    /// `neighbours[i]` shares the face opposite `vertices[i]`
    /// ([`NO_NEIGHBOUR`] on the hull).
    pub neighbours: [u32; 4],
    /// `|c|`: triangles assigned to the cell (contained or crossing).
    pub triangles: u32,
    /// The assigned triangles' area over the cell's volume to the 2/3: about
    /// how many times they could cover the cell's cross-section (a wall
    /// through the cell is about 1 or more, empty space 0). The area-based
    /// solidity reads it; PLP's own reads `triangles`.
    pub coverage: f32,
}

/// The whole tessellation, decoded.
#[derive(Debug, Clone, PartialEq)]
pub struct Skeleton {
    /// World positions (stored as f32 offsets from the header's root centre).
    pub vertices: Vec<DVec3>,
    pub cells: Vec<Cell>,
    /// `ρmax`, the largest `|c|` (at least 1, so it can divide).
    pub rho_max: u32,
    /// Distinct triangles in the scene: ids run below it.
    pub scene_triangles: u64,
    /// Outward unit normal of each cell's face opposite vertex i (zero for
    /// a face too thin to have one), computed on decode.
    pub normals: Vec<[DVec3; 4]>,
}

/// The three corners of face `i` of a cell (the face opposite vertex i),
/// in an order whose right-hand normal points out of the cell.
pub fn face_corners(v: [u32; 4], i: usize) -> [u32; 3] {
    // For a positively oriented (v0, v1, v2, v3), these faces wind outward.
    match i {
        0 => [v[1], v[2], v[3]],
        1 => [v[0], v[3], v[2]],
        2 => [v[0], v[1], v[3]],
        _ => [v[0], v[2], v[1]],
    }
}

impl Skeleton {
    /// The outward unit normal of face `face` of `cell`, or zero when the
    /// face has no area to speak of (a sliver): such a face transfers no
    /// solidity instead of a NaN.
    pub fn face_normal(vertices: &[DVec3], cell: &Cell, face: usize) -> DVec3 {
        let [a, b, c] = face_corners(cell.vertices, face).map(|i| vertices[i as usize]);
        let n = (b - a).cross(c - a);
        let scale = (b - a).length_squared().max((c - a).length_squared());
        // A normal under 1e-12 of the face's edge squared is noise (and a
        // NaN is no normal either).
        let big_enough = n.length_squared() > 1e-24 * scale * scale;
        if !big_enough {
            return DVec3::ZERO;
        }
        n.normalize_or_zero()
    }

    /// Serializes the skeleton as page 0's payload; positions as f32
    /// offsets from `origin` (the header's root centre).
    pub fn encode(&self, origin: DVec3) -> Vec<u8> {
        let mut out = Vec::with_capacity(
            SKELETON_HEADER_BYTES + self.vertices.len() * 12 + self.cells.len() * CELL_BYTES,
        );
        for v in [
            self.vertices.len() as u32,
            self.cells.len() as u32,
            self.rho_max,
            0,
        ] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&self.scene_triangles.to_le_bytes());
        for p in &self.vertices {
            for c in (*p - origin).to_array() {
                out.extend_from_slice(&(c as f32).to_le_bytes());
            }
        }
        for cell in &self.cells {
            for v in cell
                .vertices
                .iter()
                .chain(&cell.neighbours)
                .chain(std::iter::once(&cell.triangles))
            {
                out.extend_from_slice(&v.to_le_bytes());
            }
            out.extend_from_slice(&cell.coverage.to_le_bytes());
        }
        out
    }

    /// Decodes and checks page 0's payload: every index in range, every
    /// neighbour relation mutual, `ρmax` the largest count. `cells` is the
    /// count the directory implies.
    pub fn decode(bytes: &[u8], origin: DVec3, cells: u64) -> Result<Self, String> {
        let mut r = Words::new(bytes);
        let vertex_count = r.u32()? as usize;
        let cell_count = r.u32()? as usize;
        let rho_max = r.u32()?;
        if r.u32()? != 0 {
            return Err("reserved skeleton field is not 0".into());
        }
        let scene_triangles = r.u64()?;
        if cell_count as u64 != cells {
            return Err(format!(
                "the skeleton has {cell_count} cells, the directory {cells}"
            ));
        }
        let expected = SKELETON_HEADER_BYTES as u64
            + vertex_count as u64 * 12
            + cell_count as u64 * CELL_BYTES as u64;
        if bytes.len() as u64 != expected {
            return Err(format!(
                "{} skeleton bytes for {vertex_count} vertices and {cell_count} cells ({expected} expected)",
                bytes.len()
            ));
        }
        let mut vertices = Vec::with_capacity(vertex_count);
        for _ in 0..vertex_count {
            let p = DVec3::new(r.f32()?, r.f32()?, r.f32()?);
            if !p.is_finite() {
                return Err("a skeleton vertex is not finite".into());
            }
            vertices.push(origin + p);
        }
        let mut out = Vec::with_capacity(cell_count);
        let mut largest = 0;
        for i in 0..cell_count {
            let mut w = [0u32; 9];
            for x in &mut w {
                *x = r.u32()?;
            }
            let coverage = f32::from_bits(r.u32()?);
            if !(coverage.is_finite() && coverage >= 0.0) {
                return Err(format!(
                    "cell {i}: coverage {coverage} is not a finite non-negative number"
                ));
            }
            let cell = Cell {
                vertices: [w[0], w[1], w[2], w[3]],
                neighbours: [w[4], w[5], w[6], w[7]],
                triangles: w[8],
                coverage,
            };
            if cell.vertices.iter().any(|&v| v as usize >= vertex_count) {
                return Err(format!("cell {i}: a vertex index is out of range"));
            }
            if cell
                .neighbours
                .iter()
                .any(|&n| n != NO_NEIGHBOUR && (n as usize >= cell_count || n as usize == i))
            {
                return Err(format!("cell {i}: a neighbour index is out of range"));
            }
            if u64::from(cell.triangles) > scene_triangles {
                return Err(format!("cell {i}: more triangles than the scene has"));
            }
            largest = largest.max(cell.triangles);
            out.push(cell);
        }
        if rho_max != largest.max(1) {
            return Err(format!(
                "ρmax is {rho_max}, but the largest cell holds {largest}"
            ));
        }
        for (i, cell) in out.iter().enumerate() {
            for &n in &cell.neighbours {
                if n != NO_NEIGHBOUR && !out[n as usize].neighbours.contains(&(i as u32)) {
                    return Err(format!("cells {i} and {n} disagree about being neighbours"));
                }
            }
        }
        let normals = out
            .iter()
            .map(|c| std::array::from_fn(|f| Self::face_normal(&vertices, c, f)))
            .collect();
        Ok(Self {
            vertices,
            cells: out,
            rho_max,
            scene_triangles,
            normals,
        })
    }
}

/// One stored triangle: its scene-wide id, corners, color.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StoredTriangle {
    pub id: u32,
    /// Corners relative to the page's anchor, counter-clockwise seen from
    /// the front.
    pub corners: [[f32; 3]; 3],
    /// sRGB; alpha unused (255).
    pub rgba: [u8; 4],
}

/// The cells of one page and their triangles, decoded.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct CellPage {
    /// World position the corners are relative to.
    pub anchor: DVec3,
    pub triangles: Vec<StoredTriangle>,
    /// Indices into `triangles`, cell after cell.
    pub lists: Vec<u32>,
    /// Cell i's list is `lists[starts[i]..starts[i + 1]]`.
    pub starts: Vec<u32>,
}

impl CellPage {
    /// The triangles of the page's `local`th cell.
    pub fn cell(&self, local: usize) -> impl Iterator<Item = &StoredTriangle> {
        self.cell_indexed(local).map(|(_, t)| t)
    }

    /// The triangles of the page's `local`th cell with their indices among
    /// the page's triangles (what a draw list names them by).
    pub fn cell_indexed(&self, local: usize) -> impl Iterator<Item = (u32, &StoredTriangle)> {
        let lo = self.starts.get(local).copied().unwrap_or(0) as usize;
        let hi = self.starts.get(local + 1).copied().unwrap_or(0) as usize;
        self.lists
            .get(lo..hi)
            .unwrap_or(&[])
            .iter()
            .filter_map(|&i| self.triangles.get(i as usize).map(|t| (i, t)))
    }

    /// World position of a stored corner.
    pub fn world(&self, corner: [f32; 3]) -> DVec3 {
        self.anchor + DVec3::from(corner.map(f64::from))
    }

    /// The node records and payload of a page holding these cells.
    pub fn encode(&self) -> (Vec<u8>, Vec<u8>) {
        let cells = self.starts.len().saturating_sub(1);
        let mut records = Vec::with_capacity(cells * NODE_BYTES);
        for w in self.starts.windows(2) {
            records.extend_from_slice(&(w[1] - w[0]).to_le_bytes());
            records.extend_from_slice(&0u32.to_le_bytes());
        }
        let mut payload =
            Vec::with_capacity(28 + self.triangles.len() * TRIANGLE_BYTES + self.lists.len() * 4);
        for c in self.anchor.to_array() {
            payload.extend_from_slice(&c.to_le_bytes());
        }
        payload.extend_from_slice(&(self.triangles.len() as u32).to_le_bytes());
        for t in &self.triangles {
            payload.extend_from_slice(&t.id.to_le_bytes());
            for c in t.corners.iter().flatten() {
                payload.extend_from_slice(&c.to_le_bytes());
            }
            payload.extend_from_slice(&t.rgba);
        }
        for i in &self.lists {
            payload.extend_from_slice(&i.to_le_bytes());
        }
        (records, payload)
    }

    /// Decodes a cell page: `records` are its cells' 8-byte records.
    /// Every list index must name a stored triangle and every byte belong
    /// to something.
    pub fn decode(records: &[u8], payload: &[u8]) -> Result<Self, String> {
        let mut starts = Vec::with_capacity(records.len() / NODE_BYTES + 1);
        starts.push(0u32);
        let mut total = 0u64;
        for (i, rec) in records.chunks_exact(NODE_BYTES).enumerate() {
            let mut w = Words::new(rec);
            let count = w.u32()?;
            if w.u32()? != 0 {
                return Err(format!("cell {i}: reserved record field is not 0"));
            }
            total += u64::from(count);
            if total > u64::from(u32::MAX) {
                return Err("too many list entries".into());
            }
            starts.push(total as u32);
        }
        let mut r = Words::new(payload);
        let anchor = DVec3::new(r.f64()?, r.f64()?, r.f64()?);
        if !anchor.is_finite() {
            return Err("the anchor is not finite".into());
        }
        let count = r.u32()? as u64;
        let expected = 28 + count * TRIANGLE_BYTES as u64 + total * 4;
        if payload.len() as u64 != expected {
            return Err(format!(
                "{} payload bytes for {count} triangles and {total} list entries ({expected} expected)",
                payload.len()
            ));
        }
        let mut triangles = Vec::with_capacity(count as usize);
        for _ in 0..count {
            let id = r.u32()?;
            let mut corners = [[0f32; 3]; 3];
            for c in corners.iter_mut().flatten() {
                *c = r.f32()? as f32;
                if !c.is_finite() {
                    return Err(format!("triangle {id}: a corner is not finite"));
                }
            }
            let rgba = r.bytes::<4>()?;
            triangles.push(StoredTriangle { id, corners, rgba });
        }
        let mut lists = Vec::with_capacity(total as usize);
        for _ in 0..total {
            let t = r.u32()?;
            if u64::from(t) >= count {
                return Err(format!("list entry {t} names no triangle ({count} stored)"));
            }
            lists.push(t);
        }
        Ok(Self {
            anchor,
            triangles,
            lists,
            starts,
        })
    }
}

/// Little-endian words from a slice, each read checked.
pub(crate) struct Words<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Words<'a> {
    pub(crate) fn new(bytes: &'a [u8]) -> Self {
        Self { bytes, at: 0 }
    }

    pub(crate) fn bytes<const N: usize>(&mut self) -> Result<[u8; N], String> {
        let end = self.at.checked_add(N).ok_or("length overflow")?;
        let slice = self
            .bytes
            .get(self.at..end)
            .ok_or_else(|| format!("truncated at byte {}", self.at))?;
        self.at = end;
        let mut out = [0u8; N];
        out.copy_from_slice(slice);
        Ok(out)
    }

    /// Bytes not read yet.
    pub(crate) fn remaining(&self) -> usize {
        self.bytes.len().saturating_sub(self.at)
    }

    pub(crate) fn u32(&mut self) -> Result<u32, String> {
        self.bytes::<4>().map(u32::from_le_bytes)
    }

    pub(crate) fn u64(&mut self) -> Result<u64, String> {
        self.bytes::<8>().map(u64::from_le_bytes)
    }

    pub(crate) fn f32(&mut self) -> Result<f64, String> {
        self.bytes::<4>().map(|b| f64::from(f32::from_le_bytes(b)))
    }

    pub(crate) fn f64(&mut self) -> Result<f64, String> {
        self.bytes::<8>().map(f64::from_le_bytes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two cells sharing face (1, 2, 3): a double pyramid.
    fn two_cells() -> Skeleton {
        let vertices = vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
            DVec3::new(0.0, 0.0, 1.0),
            DVec3::new(1.0, 1.0, 1.0),
        ];
        // (0,1,2,3) is positive; (4,1,3,2) too (4 lies beyond face 123).
        let cells = vec![
            Cell {
                vertices: [0, 1, 2, 3],
                neighbours: [1, NO_NEIGHBOUR, NO_NEIGHBOUR, NO_NEIGHBOUR],
                triangles: 3,
                coverage: 0.5,
            },
            Cell {
                vertices: [4, 1, 3, 2],
                neighbours: [0, NO_NEIGHBOUR, NO_NEIGHBOUR, NO_NEIGHBOUR],
                triangles: 1,
                coverage: 2.0,
            },
        ];
        let normals = cells
            .iter()
            .map(|c| std::array::from_fn(|f| Skeleton::face_normal(&vertices, c, f)))
            .collect();
        Skeleton {
            vertices,
            cells,
            rho_max: 3,
            scene_triangles: 4,
            normals,
        }
    }

    #[test]
    fn the_skeleton_round_trips_and_its_normals_point_out() {
        let s = two_cells();
        let origin = DVec3::new(10.0, -5.0, 2.0);
        let moved = Skeleton {
            vertices: s.vertices.iter().map(|v| *v + origin).collect(),
            ..s.clone()
        };
        let back = Skeleton::decode(&moved.encode(origin), origin, 2).expect("decodes");
        assert_eq!(back, moved);
        // Face 0 of cell 0 (opposite the origin corner) faces +x+y+z.
        let n = back.normals[0][0];
        assert!((n - DVec3::ONE.normalize()).length() < 1e-9, "{n}");
        // The shared face seen from the other cell faces the other way.
        assert!((back.normals[1][0] + n).length() < 1e-9);
        for (cell, normals) in back.cells.iter().zip(&back.normals) {
            let centroid = cell
                .vertices
                .iter()
                .map(|&v| back.vertices[v as usize])
                .sum::<DVec3>()
                / 4.0;
            for (f, normal) in normals.iter().enumerate() {
                let on_face = back.vertices[face_corners(cell.vertices, f)[0] as usize];
                assert!(normal.dot(on_face - centroid) > 0.0, "face {f} points in");
            }
        }
    }

    #[test]
    fn bad_skeletons_are_refused() {
        let s = two_cells();
        let good = s.encode(DVec3::ZERO);
        assert!(
            Skeleton::decode(&good, DVec3::ZERO, 3).is_err(),
            "cell count"
        );
        assert!(Skeleton::decode(&good[..good.len() - 1], DVec3::ZERO, 2).is_err());
        let mut one_sided = s.clone();
        one_sided.cells[1].neighbours[0] = NO_NEIGHBOUR;
        assert!(Skeleton::decode(&one_sided.encode(DVec3::ZERO), DVec3::ZERO, 2).is_err());
        let mut far = s.clone();
        far.cells[0].vertices[2] = 5;
        assert!(Skeleton::decode(&far.encode(DVec3::ZERO), DVec3::ZERO, 2).is_err());
        let mut rho = s.clone();
        rho.rho_max = 2;
        assert!(Skeleton::decode(&rho.encode(DVec3::ZERO), DVec3::ZERO, 2).is_err());
        let mut nan = s.clone();
        nan.vertices[0].x = f64::NAN;
        assert!(Skeleton::decode(&nan.encode(DVec3::ZERO), DVec3::ZERO, 2).is_err());
        let mut negative = s;
        negative.cells[0].coverage = -1.0;
        assert!(Skeleton::decode(&negative.encode(DVec3::ZERO), DVec3::ZERO, 2).is_err());
    }

    #[test]
    fn a_sliver_face_has_a_zero_normal_not_nan() {
        let vertices = vec![DVec3::ZERO, DVec3::X, DVec3::new(2.0, 0.0, 0.0), DVec3::Z];
        let cell = Cell {
            vertices: [0, 1, 2, 3],
            neighbours: [NO_NEIGHBOUR; 4],
            triangles: 0,
            coverage: 0.0,
        };
        // Face 3 is (0, 2, 1): three collinear points.
        assert_eq!(Skeleton::face_normal(&vertices, &cell, 3), DVec3::ZERO);
        for f in 0..4 {
            assert!(Skeleton::face_normal(&vertices, &cell, f).is_finite());
        }
    }

    #[test]
    fn a_cell_page_round_trips_and_bad_lists_are_refused() {
        let tri = |id, x: f32| StoredTriangle {
            id,
            corners: [[x, 0.0, 0.0], [x + 1.0, 0.0, 0.0], [x, 1.0, 0.0]],
            rgba: [10, 20, 30, 255],
        };
        let page = CellPage {
            anchor: DVec3::new(1.0, 2.0, 3.0),
            triangles: vec![tri(7, 0.0), tri(9, 2.0)],
            lists: vec![0, 1, 1],
            starts: vec![0, 2, 2, 3],
        };
        let (records, payload) = page.encode();
        let back = CellPage::decode(&records, &payload).expect("decodes");
        assert_eq!(back, page);
        assert_eq!(back.cell(0).map(|t| t.id).collect::<Vec<_>>(), vec![7, 9]);
        assert_eq!(back.cell(1).count(), 0);
        assert_eq!(back.cell(2).map(|t| t.id).collect::<Vec<_>>(), vec![9]);
        assert_eq!(back.world([1.0, 0.0, 0.0]), DVec3::new(2.0, 2.0, 3.0));

        let mut bad_index = payload.clone();
        let last = bad_index.len() - 4;
        bad_index[last..].copy_from_slice(&2u32.to_le_bytes());
        assert!(CellPage::decode(&records, &bad_index).is_err());
        assert!(CellPage::decode(&records, &payload[..payload.len() - 1]).is_err());
        let mut extra = payload;
        extra.push(0);
        assert!(CellPage::decode(&records, &extra).is_err());
    }
}
