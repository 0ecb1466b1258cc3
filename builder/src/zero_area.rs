//! Zero-area triangles: faces whose corners repeat or lie on one line.
//!
//! Scanners and CAD exports leave such faces behind (a corner repeated to
//! close a strip, a T-junction filled with a flat sliver, a stray face
//! between two far-apart vertices). They have no surface, so they must not
//! change what a hierarchy renders: the leaf sizing skips them (a long one
//! would otherwise size its corners' spheres by half its length, and its
//! rounding-noise normal would bend vertex normals and widen cones), and so
//! does the cube builder (a face with no area covers no sample and costs
//! nothing to draw). A vertex that only such faces use is left out like a
//! vertex no face uses.
//!
//! Exactly zero is not a usable test: corners that are collinear in the
//! model are rarely collinear after rounding, and a long face with a
//! rounding-noise height can outweigh every real face around a vertex. So
//! "zero area" is relative to the face's own size, which makes the verdict
//! independent of scale and units ([`ZERO_AREA_EPS`]).

use glam::DVec3;

/// A face has zero area when its height over its longest edge is at most
/// this: `|ab x ac| <= ZERO_AREA_EPS * |longest edge|^2` (the cross
/// product's length is the longest edge times the height).
///
/// Why a millionth:
/// - Flat faces read as flat. f64 arithmetic noise is far below it, and
///   collinear corners stored as f32 (PLY, STL) are off their line by at
///   most about 1e-7 of their distance from the origin, so such a face
///   reads as flat wherever it lies within ten of its lengths of the
///   origin: every long stray face of a model around the origin.
/// - Real faces stay. The thinnest face of the shared scans (bunny, horse,
///   igea, beast, spot) is 4e-3 as high as long, and a CAD export's long
///   facets can be far thinner (a pipe a thousand times as long as wide,
///   in 64 facets around, has faces 1e-4 as high as long): a looser bound
///   would drop surface. A face under a millionth as high as long is under a pixel
///   wide wherever it is under a million pixels long, and its corners stay
///   joined along its other edges, so leaving it out opens no visible hole.
/// - What it cannot tell: a point rounded to f32 on a short edge far from
///   the origin (an edge a hundredth of its coordinates) is off its line
///   by up to 1e-5 of the edge; no bound that does not know the file's
///   precision can tell that face from a real sliver, and it is kept.
pub const ZERO_AREA_EPS: f64 = 1e-6;

/// Whether the triangle `a b c` has zero area in the sense of
/// [`ZERO_AREA_EPS`] (true for a triangle that is one point).
pub fn is_zero_area(a: DVec3, b: DVec3, c: DVec3) -> bool {
    face_with_area(a, b, c).is_none()
}

/// The face vector `(b - a) x (c - a)` (twice the area long) of a face
/// with an area; `None` for a face of zero area.
#[inline]
pub(crate) fn face_with_area(a: DVec3, b: DVec3, c: DVec3) -> Option<DVec3> {
    let face = (b - a).cross(c - a);
    let longest_squared = a
        .distance_squared(b)
        .max(b.distance_squared(c))
        .max(c.distance_squared(a));
    (!zero_area(face.length_squared(), longest_squared)).then_some(face)
}

/// [`is_zero_area`] from what the leaf sizing already has: the squared
/// length of the face vector `(b - a) x (c - a)` and the squared length of
/// the longest edge. Compared as squares, so no root is taken per face.
#[inline]
pub(crate) fn zero_area(face_length_squared: f64, longest_squared: f64) -> bool {
    let bound = ZERO_AREA_EPS * longest_squared;
    face_length_squared <= bound * bound
}

#[cfg(test)]
mod tests;
