//! The image-caching BSP's bytes (Shade et al., *Hierarchical Image
//! Caching*, section 4): the tree in page 0, each shared prototype (an
//! instanced object, stored once) in a page of its own, then one page per
//! leaf with the leaf's triangles and its placements of prototypes.
//!
//! The skeleton is what a client needs before any geometry: the splitting
//! planes (for back-to-front order), every node's bounding box (for
//! culling, screen rectangles and safety zones) and triangle count (for the
//! cost of drawing it). The file's own node tree is flat, as PLP's: the
//! root (page 0) and one child per prototype and per leaf, each alone in
//! its page, so a page is requested by the BSP leaf (or prototype) it
//! holds. A child's record says which it is, so a page decodes without the
//! skeleton. `FORMAT.md` has the bytes.

use glam::{DAffine3, DMat3, DVec3};

use crate::plp_codec::Words;

/// Bytes of a node record: page 0's root (children, 0) and every child's
/// (its tag, its number).
pub const NODE_BYTES: usize = 8;
/// A child record's tag: the page holds prototype number `index`.
pub const TAG_PROTOTYPE: u32 = 1;
/// A child record's tag: the page holds BSP leaf number `index`.
pub const TAG_LEAF: u32 = 2;
/// Bytes of one stored triangle: nine f32 coordinates, RGBA.
pub const TRIANGLE_BYTES: usize = 36 + 4;
/// Bytes of one placement: prototype, 3x3 matrix, translation (f32).
pub const PLACEMENT_BYTES: usize = 4 + 36 + 12;
/// Bytes of one BSP node in the skeleton.
pub const BSP_NODE_BYTES: usize = 48;
/// Bytes of one prototype in the skeleton.
pub const PROTOTYPE_BYTES: usize = 28;
/// The most splitting directions a file may name.
pub const MAX_DIRECTIONS: usize = 64;
const SKELETON_HEADER_BYTES: usize = 32;

/// What a BSP node is: a leaf with its page of geometry, or a split.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Split {
    /// Leaf number `leaf` (its page is `1 + prototypes + leaf`).
    Leaf { leaf: u32 },
    /// The plane `direction · (p − root centre) = offset`; `back` holds
    /// the side below it, `front` the side above. Both come after the node.
    Plane {
        direction: u8,
        offset: f64,
        back: u32,
        front: u32,
    },
}

/// One node of the BSP.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BspNode {
    /// The bounds of everything the node draws (inflated leaves included),
    /// world units; `min > max` for a node that draws nothing.
    pub box_min: DVec3,
    pub box_max: DVec3,
    /// Triangles the node draws as geometry (instances counted whole).
    pub triangles: u64,
    pub split: Split,
}

/// An instanced object, stored once in its own page.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PrototypeInfo {
    pub triangles: u32,
    /// Bounds in the prototype's own frame.
    pub box_min: DVec3,
    pub box_max: DVec3,
}

/// Page 0's payload, decoded.
#[derive(Debug, Clone, PartialEq)]
pub struct BspSkeleton {
    /// Unit splitting directions (world).
    pub directions: Vec<DVec3>,
    /// The BSP, node 0 its root; children after parents.
    pub nodes: Vec<BspNode>,
    pub prototypes: Vec<PrototypeInfo>,
    /// Leaves (their pages follow the prototypes').
    pub leaves: u32,
    /// Triangles of the whole scene, instances expanded.
    pub scene_triangles: u64,
    /// How much each leaf's region was grown for its geometry (0.17: 17 %).
    pub inflation: f32,
}

/// A flat-shaded triangle: corners relative to the page's origin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlatTriangle {
    pub corners: [[f32; 3]; 3],
    /// sRGB and alpha 255.
    pub rgba: [u8; 4],
}

/// A prototype placed in a leaf.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    pub prototype: u32,
    /// Columns of the linear part.
    pub matrix: [[f32; 3]; 3],
    /// Relative to the leaf page's anchor.
    pub translation: [f32; 3],
}

/// A leaf's page: its own triangles (and its neighbours' inside its
/// inflated region) and the prototypes it places.
#[derive(Debug, Clone, PartialEq)]
pub struct LeafPage {
    pub leaf: u32,
    pub anchor: DVec3,
    /// The first `own_triangles` triangles and `own_placements` placements
    /// are the leaf's own; the rest are borrowed from neighbours for
    /// inflation (drawn into the leaf's cached image, not as geometry).
    pub own_triangles: u32,
    pub own_placements: u32,
    pub triangles: Vec<FlatTriangle>,
    pub placements: Vec<Placement>,
}

/// A prototype's page: its triangles in its own frame.
#[derive(Debug, Clone, PartialEq)]
pub struct PrototypePage {
    pub prototype: u32,
    pub triangles: Vec<FlatTriangle>,
}

impl Placement {
    /// World from the prototype's frame, for a page anchored at `anchor`.
    pub fn world_from_local(&self, anchor: DVec3) -> DAffine3 {
        let col = |c: [f32; 3]| DVec3::from(c.map(f64::from));
        DAffine3 {
            matrix3: DMat3::from_cols(
                col(self.matrix[0]),
                col(self.matrix[1]),
                col(self.matrix[2]),
            ),
            translation: anchor + col(self.translation),
        }
    }
}

impl LeafPage {
    pub fn world(&self, corner: [f32; 3]) -> DVec3 {
        self.anchor + DVec3::from(corner.map(f64::from))
    }

    /// The record (tag, leaf) and payload.
    pub fn encode(&self) -> (Vec<u8>, Vec<u8>) {
        let mut out = Vec::with_capacity(
            40 + self.triangles.len() * TRIANGLE_BYTES + self.placements.len() * PLACEMENT_BYTES,
        );
        for c in self.anchor.to_array() {
            out.extend_from_slice(&c.to_le_bytes());
        }
        put_u32(&mut out, self.triangles.len() as u32);
        put_u32(&mut out, self.placements.len() as u32);
        put_u32(&mut out, self.own_triangles);
        put_u32(&mut out, self.own_placements);
        put_triangles(&mut out, &self.triangles);
        for p in &self.placements {
            put_u32(&mut out, p.prototype);
            for v in p.matrix.iter().chain(std::iter::once(&p.translation)) {
                put_f32s(&mut out, v);
            }
        }
        (record(TAG_LEAF, self.leaf), out)
    }

    fn decode(leaf: u32, payload: &[u8]) -> Result<Self, String> {
        let mut r = Words::new(payload);
        let anchor = DVec3::new(r.f64()?, r.f64()?, r.f64()?);
        if !anchor.is_finite() {
            return Err("the anchor is not finite".into());
        }
        let (t, p) = (r.u32()? as usize, r.u32()? as usize);
        let (own_t, own_p) = (r.u32()?, r.u32()?);
        if own_t as usize > t || own_p as usize > p {
            return Err(format!(
                "{own_t} own triangles of {t} or {own_p} own placements of {p}"
            ));
        }
        let need = t
            .checked_mul(TRIANGLE_BYTES)
            .and_then(|n| n.checked_add(p.checked_mul(PLACEMENT_BYTES)?));
        if need != Some(r.remaining()) {
            return Err(format!(
                "{t} triangles and {p} placements do not fill {} bytes",
                r.remaining()
            ));
        }
        let triangles = get_triangles(&mut r, t)?;
        let mut placements = Vec::with_capacity(p);
        for _ in 0..p {
            let prototype = r.u32()?;
            let mut m = [[0f32; 3]; 4];
            for col in &mut m {
                *col = get_f32s(&mut r)?;
            }
            placements.push(Placement {
                prototype,
                matrix: [m[0], m[1], m[2]],
                translation: m[3],
            });
        }
        Ok(Self {
            leaf,
            anchor,
            own_triangles: own_t,
            own_placements: own_p,
            triangles,
            placements,
        })
    }
}

impl PrototypePage {
    pub fn encode(&self) -> (Vec<u8>, Vec<u8>) {
        let mut out = Vec::with_capacity(4 + self.triangles.len() * TRIANGLE_BYTES);
        put_u32(&mut out, self.triangles.len() as u32);
        put_triangles(&mut out, &self.triangles);
        (record(TAG_PROTOTYPE, self.prototype), out)
    }

    fn decode(prototype: u32, payload: &[u8]) -> Result<Self, String> {
        let mut r = Words::new(payload);
        let t = r.u32()? as usize;
        if t.checked_mul(TRIANGLE_BYTES) != Some(r.remaining()) {
            return Err(format!("{t} triangles do not fill {} bytes", r.remaining()));
        }
        Ok(Self {
            prototype,
            triangles: get_triangles(&mut r, t)?,
        })
    }
}

/// A decoded page after page 0.
#[derive(Debug, Clone, PartialEq)]
pub enum ContentPage {
    Prototype(PrototypePage),
    Leaf(LeafPage),
}

impl ContentPage {
    /// Decodes a page's one record and its payload; every coordinate must
    /// be finite (a NaN corner would reach the screen).
    pub fn decode(records: &[u8], payload: &[u8]) -> Result<Self, String> {
        if records.len() != NODE_BYTES {
            return Err(format!(
                "{} record bytes, where a BSP page holds one record of {NODE_BYTES}",
                records.len()
            ));
        }
        let mut r = Words::new(records);
        let (tag, index) = (r.u32()?, r.u32()?);
        match tag {
            TAG_PROTOTYPE => PrototypePage::decode(index, payload).map(Self::Prototype),
            TAG_LEAF => LeafPage::decode(index, payload).map(Self::Leaf),
            _ => Err(format!("unknown page tag {tag}")),
        }
    }
}

impl BspSkeleton {
    /// Page 0's payload; positions as f32 offsets from `origin` (the
    /// header's root centre), boxes rounded outward so they still hold
    /// what they bound.
    pub fn encode(&self, origin: DVec3) -> Vec<u8> {
        let mut out = Vec::with_capacity(
            SKELETON_HEADER_BYTES
                + self.directions.len() * 12
                + self.nodes.len() * BSP_NODE_BYTES
                + self.prototypes.len() * PROTOTYPE_BYTES,
        );
        for v in [
            self.directions.len() as u32,
            self.nodes.len() as u32,
            self.prototypes.len() as u32,
            self.leaves,
        ] {
            put_u32(&mut out, v);
        }
        out.extend_from_slice(&self.scene_triangles.to_le_bytes());
        out.extend_from_slice(&self.inflation.to_le_bytes());
        put_u32(&mut out, 0);
        for d in &self.directions {
            put_f32s(&mut out, &d.as_vec3().to_array());
        }
        for n in &self.nodes {
            let (kind, direction, a, b, offset) = match n.split {
                Split::Leaf { leaf } => (1u8, 0u8, leaf, 0, 0.0),
                Split::Plane {
                    direction,
                    offset,
                    back,
                    front,
                } => (0, direction, back, front, offset as f32),
            };
            out.extend_from_slice(&[kind, direction, 0, 0]);
            out.extend_from_slice(&offset.to_le_bytes());
            put_u32(&mut out, a);
            put_u32(&mut out, b);
            put_box(&mut out, n.box_min - origin, n.box_max - origin);
            out.extend_from_slice(&n.triangles.to_le_bytes());
        }
        for p in &self.prototypes {
            put_u32(&mut out, p.triangles);
            put_box(&mut out, p.box_min, p.box_max);
        }
        out
    }

    /// Decodes and checks page 0's payload: the nodes a tree rooted at 0
    /// (children after their parent, each node one parent), every leaf
    /// numbered once, directions unit, numbers finite. `children` is the
    /// root's child count in the directory (prototypes plus leaves).
    pub fn decode(bytes: &[u8], origin: DVec3, children: u64) -> Result<Self, String> {
        let mut r = Words::new(bytes);
        let (d, n, p, leaves) = (
            r.u32()? as usize,
            r.u32()? as usize,
            r.u32()? as usize,
            r.u32()?,
        );
        let scene_triangles = r.u64()?;
        let inflation = r.f32()? as f32;
        if r.u32()? != 0 {
            return Err("reserved word is not 0".into());
        }
        if d == 0 || d > MAX_DIRECTIONS {
            return Err(format!("{d} directions (1 to {MAX_DIRECTIONS})"));
        }
        if p as u64 + u64::from(leaves) != children {
            return Err(format!(
                "{p} prototypes and {leaves} leaves, where the root has {children} pages"
            ));
        }
        let need = d * 12 + n.saturating_mul(BSP_NODE_BYTES) + p.saturating_mul(PROTOTYPE_BYTES);
        if need != r.remaining() {
            return Err(format!(
                "{d} directions, {n} nodes and {p} prototypes do not fill {} bytes",
                r.remaining()
            ));
        }
        if !(inflation.is_finite() && inflation >= 0.0) {
            return Err(format!(
                "inflation {inflation} is not finite and at least 0"
            ));
        }
        let mut directions = Vec::with_capacity(d);
        for _ in 0..d {
            let v = DVec3::from(get_f32s(&mut r)?.map(f64::from));
            if !v.is_finite() || (v.length() - 1.0).abs() > 1e-3 {
                return Err(format!("direction {v} is not a unit vector"));
            }
            directions.push(v);
        }
        let mut nodes = Vec::with_capacity(n);
        let mut parents = vec![0u8; n];
        let mut leaf_seen = vec![false; leaves as usize];
        for i in 0..n {
            let [kind, direction, _, _] = r.bytes::<4>()?;
            let offset = r.f32()?;
            let (a, b) = (r.u32()?, r.u32()?);
            let (box_min, box_max) = get_box(&mut r)?;
            let triangles = r.u64()?;
            let split = match kind {
                1 => {
                    let seen = leaf_seen
                        .get_mut(a as usize)
                        .ok_or_else(|| format!("node {i}: leaf {a} of {leaves}"))?;
                    if std::mem::replace(seen, true) {
                        return Err(format!("leaf {a} appears twice"));
                    }
                    Split::Leaf { leaf: a }
                }
                0 => {
                    if usize::from(direction) >= d || !offset.is_finite() {
                        return Err(format!("node {i}: a bad plane"));
                    }
                    for child in [a, b] {
                        let c = child as usize;
                        if c <= i || c >= n {
                            return Err(format!("node {i}: child {child} does not follow it"));
                        }
                        parents[c] += 1;
                        if parents[c] > 1 {
                            return Err(format!("node {child} has two parents"));
                        }
                    }
                    Split::Plane {
                        direction,
                        offset,
                        back: a,
                        front: b,
                    }
                }
                _ => return Err(format!("node {i}: unknown kind {kind}")),
            };
            nodes.push(BspNode {
                box_min: box_min + origin,
                box_max: box_max + origin,
                triangles,
                split,
            });
        }
        if n == 0 || parents.iter().skip(1).any(|&c| c != 1) {
            return Err("the nodes are not one tree rooted at node 0".into());
        }
        if leaf_seen.iter().any(|s| !s) {
            return Err("a leaf has no node".into());
        }
        let mut prototypes = Vec::with_capacity(p);
        for _ in 0..p {
            let triangles = r.u32()?;
            let (box_min, box_max) = get_box(&mut r)?;
            prototypes.push(PrototypeInfo {
                triangles,
                box_min,
                box_max,
            });
        }
        Ok(Self {
            directions,
            nodes,
            prototypes,
            leaves,
            scene_triangles,
            inflation,
        })
    }

    /// The page holding leaf `leaf`'s geometry.
    pub fn leaf_page(&self, leaf: u32) -> u32 {
        1 + self.prototypes.len() as u32 + leaf
    }

    /// The page holding prototype `prototype`.
    pub fn prototype_page(prototype: u32) -> u32 {
        1 + prototype
    }
}

fn record(tag: u32, index: u32) -> Vec<u8> {
    let mut r = tag.to_le_bytes().to_vec();
    r.extend_from_slice(&index.to_le_bytes());
    r
}

fn put_u32(out: &mut Vec<u8>, v: u32) {
    out.extend_from_slice(&v.to_le_bytes());
}

fn put_f32s(out: &mut Vec<u8>, v: &[f32; 3]) {
    for c in v {
        out.extend_from_slice(&c.to_le_bytes());
    }
}

/// A box as f32, rounded outward (an empty box stays empty).
fn put_box(out: &mut Vec<u8>, min: DVec3, max: DVec3) {
    let down = |v: f64| {
        let f = v as f32;
        if f64::from(f) > v { f.next_down() } else { f }
    };
    let up = |v: f64| {
        let f = v as f32;
        if f64::from(f) < v { f.next_up() } else { f }
    };
    put_f32s(out, &min.to_array().map(down));
    put_f32s(out, &max.to_array().map(up));
}

fn get_f32s(r: &mut Words<'_>) -> Result<[f32; 3], String> {
    let v = [r.f32()? as f32, r.f32()? as f32, r.f32()? as f32];
    if v.iter().all(|c| c.is_finite()) {
        Ok(v)
    } else {
        Err("a coordinate is not finite".into())
    }
}

/// A box: finite, or empty (every minimum above its maximum: +inf, -inf).
fn get_box(r: &mut Words<'_>) -> Result<(DVec3, DVec3), String> {
    let mut v = [0f64; 6];
    for c in &mut v {
        *c = r.f32()?;
    }
    let (min, max) = (DVec3::new(v[0], v[1], v[2]), DVec3::new(v[3], v[4], v[5]));
    let empty = min == DVec3::INFINITY && max == DVec3::NEG_INFINITY;
    if empty || (min.is_finite() && max.is_finite() && min.cmple(max).all()) {
        Ok((min, max))
    } else {
        Err(format!("box {min}..{max} is neither finite nor empty"))
    }
}

fn put_triangles(out: &mut Vec<u8>, triangles: &[FlatTriangle]) {
    for t in triangles {
        for c in &t.corners {
            put_f32s(out, c);
        }
        out.extend_from_slice(&t.rgba);
    }
}

fn get_triangles(r: &mut Words<'_>, count: usize) -> Result<Vec<FlatTriangle>, String> {
    let mut out = Vec::with_capacity(count);
    for _ in 0..count {
        let corners = [get_f32s(r)?, get_f32s(r)?, get_f32s(r)?];
        out.push(FlatTriangle {
            corners,
            rgba: r.bytes::<4>()?,
        });
    }
    Ok(out)
}

#[cfg(test)]
#[path = "bsp_codec_tests.rs"]
mod tests;
