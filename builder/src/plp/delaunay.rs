//! The Delaunay tetrahedralization of the leaf centres (section 3.1):
//! Bowyer–Watson insertion on Shewchuk's exact adaptive predicates (the
//! `robust` crate).
//!
//! Why not a Delaunay crate: `delaunay` 0.7.8 (pure Rust, exact) took 9.4 s
//! for 1,000 random points and 128 s for 4,000 on this machine (it grows
//! quadratically, and CITY needs tens of thousands); `tritet`'s TetGen
//! turns the whole project AGPL. Exact predicates are the hard part of a
//! robust tetrahedralization, and those come from a crate; the insertion
//! around them is short.
//!
//! The hull is fixed first: the enlarged bounding box's eight corners,
//! split into six tetrahedra, so every later point lies strictly inside the
//! triangulation and every primitive inside the hull, as the paper asks.
//! Each point is located by a walk from the last insertion (points come in
//! Morton order, so the walk is short), and its cavity, the cells whose
//! circumsphere strictly contains it, is replaced by a fan. Cospherical
//! points (an exact lattice) are not in each other's conflict: ties keep
//! the old cells, which is still a Delaunay tetrahedralization, and exact
//! orientation tests refuse any flat cell instead of storing it.

use std::collections::HashMap;

use glam::DVec3;
use robust::Coord3D;

/// A face or vertex with none.
pub const NONE: u32 = u32::MAX;

/// A tetrahedralization: positively oriented cells and their neighbours.
#[derive(Debug, Clone, Default)]
pub struct Tetrahedralization {
    /// The box's eight corners first, then the inserted points.
    pub points: Vec<DVec3>,
    /// Positively oriented: [`orient`] of the four corners is > 0.
    pub cells: Vec<[u32; 4]>,
    /// `neighbours[c][i]` shares the face opposite `cells[c][i]`.
    pub neighbours: Vec<[u32; 4]>,
    /// Points skipped because another point was at the same place.
    pub duplicates: usize,
}

/// Six times the signed volume of (a, b, c, d), exactly signed: positive
/// when d lies on the side (b - a) x (c - a) points to.
pub fn orient(a: DVec3, b: DVec3, c: DVec3, d: DVec3) -> f64 {
    // Shewchuk's orient3d is positive for d *below* abc: the opposite sign.
    -robust::orient3d(coord(a), coord(b), coord(c), coord(d))
}

/// Positive when `p` lies strictly inside the circumsphere of the
/// positively oriented cell (a, b, c, d), zero on it, exactly signed.
pub fn in_sphere(a: DVec3, b: DVec3, c: DVec3, d: DVec3, p: DVec3) -> f64 {
    // Shewchuk's insphere wants his positive order: swap a and b.
    robust::insphere(coord(b), coord(a), coord(c), coord(d), coord(p))
}

fn coord(p: DVec3) -> Coord3D<f64> {
    Coord3D {
        x: p.x,
        y: p.y,
        z: p.z,
    }
}

/// The corners of face `i` (opposite vertex i), wound so that its normal
/// points out of the cell.
pub fn face(v: [u32; 4], i: usize) -> [u32; 3] {
    farfield_protocol::plp_codec::face_corners(v, i)
}

/// Tetrahedralizes `points` inside the box `min..max`, whose corners are
/// added first. Points outside the box (or on it) are an error.
pub fn tetrahedralize(
    min: DVec3,
    max: DVec3,
    points: &[DVec3],
) -> Result<Tetrahedralization, String> {
    if !(min.is_finite() && max.is_finite() && min.cmplt(max).all()) {
        return Err(format!("the box {min}..{max} is empty or not finite"));
    }
    if let Some(p) = points
        .iter()
        .find(|p| !(p.is_finite() && p.cmpgt(min).all() && p.cmplt(max).all()))
    {
        return Err(format!("point {p} is not strictly inside the box"));
    }
    let mut t = Tetrahedralization::default();
    for k in 0..8u32 {
        t.points.push(DVec3::new(
            if k & 1 != 0 { max.x } else { min.x },
            if k & 2 != 0 { max.y } else { min.y },
            if k & 4 != 0 { max.z } else { min.z },
        ));
    }
    // Kuhn's six: from corner 0 to corner 7 along each order of the axes.
    for axes in [
        [1, 2, 4],
        [1, 4, 2],
        [2, 1, 4],
        [2, 4, 1],
        [4, 1, 2],
        [4, 2, 1],
    ] {
        let mut cell = [0, axes[0], axes[0] | axes[1], 7];
        if orient_cell(&t.points, cell) < 0.0 {
            cell.swap(0, 1);
        }
        t.cells.push(cell);
    }
    t.neighbours = link(&t.cells);
    // Morton order keeps each walk short.
    let mut order: Vec<(u64, u32)> = points
        .iter()
        .enumerate()
        .map(|(i, p)| (morton((*p - min) / (max - min)), i as u32))
        .collect();
    order.sort_unstable();
    let mut inserter = Inserter::default();
    let mut last = 0u32;
    for (_, i) in order {
        let p = points[i as usize];
        let index = t.points.len() as u32;
        t.points.push(p);
        match inserter.insert(&mut t, index, last)? {
            Some(cell) => last = cell,
            None => {
                t.points.pop();
                t.duplicates += 1;
            }
        }
    }
    compact(&mut t, &inserter.free);
    Ok(t)
}

fn orient_cell(points: &[DVec3], c: [u32; 4]) -> f64 {
    let [a, b, c, d] = c.map(|i| points[i as usize]);
    orient(a, b, c, d)
}

/// Neighbours of a set of cells by matching their faces.
fn link(cells: &[[u32; 4]]) -> Vec<[u32; 4]> {
    let mut open: HashMap<[u32; 3], (u32, usize)> = HashMap::new();
    let mut out = vec![[NONE; 4]; cells.len()];
    for (c, cell) in cells.iter().enumerate() {
        for i in 0..4 {
            let mut key = face(*cell, i);
            key.sort_unstable();
            if let Some((other, j)) = open.remove(&key) {
                out[c][i] = other;
                out[other as usize][j] = c as u32;
            } else {
                open.insert(key, (c as u32, i));
            }
        }
    }
    out
}

/// A 63-bit Morton code of a point in the unit cube.
pub(crate) fn morton(p: DVec3) -> u64 {
    let spread = |v: f64| -> u64 {
        let mut x = (v.clamp(0.0, 1.0) * f64::from((1u32 << 21) - 1)) as u64;
        x &= 0x1F_FFFF;
        x = (x | x << 32) & 0x1F_0000_0000_FFFF;
        x = (x | x << 16) & 0x1F_0000_FF00_00FF;
        x = (x | x << 8) & 0x100F_00F0_0F00_F00F;
        x = (x | x << 4) & 0x10C3_0C30_C30C_30C3;
        x = (x | x << 2) & 0x1249_2492_4924_9249;
        x
    };
    spread(p.x) | spread(p.y) << 1 | spread(p.z) << 2
}

/// Scratch space reused across insertions.
#[derive(Debug, Default)]
struct Inserter {
    /// Per cell, the insertion that last visited it.
    stamp: Vec<u32>,
    in_cavity: Vec<bool>,
    cavity: Vec<u32>,
    /// Slots of removed cells, reused by new ones.
    free: Vec<u32>,
    /// New cells' open faces by their edge (the face's two old corners).
    open: HashMap<(u32, u32), (u32, usize)>,
    round: u32,
}

impl Inserter {
    /// Inserts point `p` (already pushed); returns a new cell, or `None`
    /// when the point is a duplicate of a vertex.
    fn insert(
        &mut self,
        t: &mut Tetrahedralization,
        p: u32,
        start: u32,
    ) -> Result<Option<u32>, String> {
        let pos = t.points[p as usize];
        let found = locate(t, pos, start)?;
        self.round = self.round.wrapping_add(1);
        self.stamp.resize(t.cells.len(), 0);
        self.in_cavity.resize(t.cells.len(), false);
        let conflict = |t: &Tetrahedralization, c: u32| {
            let [a, b, cc, d] = t.cells[c as usize].map(|i| t.points[i as usize]);
            in_sphere(a, b, cc, d, pos) > 0.0
        };
        if !conflict(t, found) {
            // Inside (or on) the cell yet not inside its sphere: a vertex.
            return Ok(None);
        }
        self.cavity.clear();
        self.cavity.push(found);
        self.stamp[found as usize] = self.round;
        self.in_cavity[found as usize] = true;
        let mut k = 0;
        while k < self.cavity.len() {
            let c = self.cavity[k];
            k += 1;
            for &n in &t.neighbours[c as usize] {
                if n == NONE || self.stamp[n as usize] == self.round {
                    continue;
                }
                self.stamp[n as usize] = self.round;
                if conflict(t, n) {
                    self.in_cavity[n as usize] = true;
                    self.cavity.push(n);
                }
            }
        }
        // The cavity's boundary faces, each coned to p.
        let mut boundary = Vec::new();
        for &c in &self.cavity {
            let cell = t.cells[c as usize];
            for i in 0..4 {
                let n = t.neighbours[c as usize][i];
                if n != NONE && self.in_cavity[n as usize] {
                    continue;
                }
                // Which of the outside cell's faces points back here.
                let back = if n == NONE {
                    0
                } else {
                    t.neighbours[n as usize]
                        .iter()
                        .position(|&m| m == c)
                        .ok_or_else(|| {
                            format!("cells {c} and {n} disagree about being neighbours")
                        })?
                };
                boundary.push((face(cell, i), n, back));
            }
        }
        for &c in &self.cavity {
            self.in_cavity[c as usize] = false;
            self.free.push(c);
        }
        self.open.clear();
        let mut last = NONE;
        for ([a, b, c], outside, back) in boundary {
            // The face's normal points away from p: (a, c, b, p) is positive.
            let cell = [a, c, b, p];
            if orient_cell(&t.points, cell) <= 0.0 {
                return Err(format!(
                    "point {pos} makes a flat cell: the input is degenerate beyond repair"
                ));
            }
            let slot = match self.free.pop() {
                Some(s) => s,
                None => {
                    t.cells.push([0; 4]);
                    t.neighbours.push([NONE; 4]);
                    self.stamp.push(0);
                    self.in_cavity.push(false);
                    (t.cells.len() - 1) as u32
                }
            };
            t.cells[slot as usize] = cell;
            t.neighbours[slot as usize] = [NONE, NONE, NONE, outside];
            if outside != NONE {
                t.neighbours[outside as usize][back] = slot;
            }
            // Faces 0..3 each hold p and one edge of the old face.
            for i in 0..3 {
                let others: Vec<u32> = (0..3).filter(|&j| j != i).map(|j| cell[j]).collect();
                let key = (others[0].min(others[1]), others[0].max(others[1]));
                if let Some((n, j)) = self.open.remove(&key) {
                    t.neighbours[slot as usize][i] = n;
                    t.neighbours[n as usize][j] = slot;
                } else {
                    self.open.insert(key, (slot, i));
                }
            }
            last = slot;
        }
        if !self.open.is_empty() {
            return Err(format!("point {pos}: the cavity is not closed"));
        }
        Ok(Some(last))
    }
}

/// The cell containing `p` (or holding it on its boundary), by a walk
/// from `start` that steps through any face `p` lies strictly beyond.
pub(crate) fn locate(t: &Tetrahedralization, p: DVec3, start: u32) -> Result<u32, String> {
    let mut c = start;
    // The face to try first rotates, so the walk cannot cycle.
    let mut turn = 0usize;
    let limit = 64 + 4 * t.cells.len();
    for _ in 0..limit {
        let cell = t.cells[c as usize];
        let mut moved = false;
        for k in 0..4 {
            let i = (k + turn) % 4;
            let [a, b, cc] = face(cell, i).map(|v| t.points[v as usize]);
            if orient(a, b, cc, p) > 0.0 {
                let n = t.neighbours[c as usize][i];
                if n == NONE {
                    return Err(format!("point {p} lies outside the hull"));
                }
                c = n;
                moved = true;
                break;
            }
        }
        turn = turn.wrapping_add(1);
        if !moved {
            return Ok(c);
        }
    }
    Err(format!("the walk to {p} did not end"))
}

/// Removes the cells in `free` (slots left unused) and renumbers.
fn compact(t: &mut Tetrahedralization, free: &[u32]) {
    if free.is_empty() {
        return;
    }
    let mut dead = vec![false; t.cells.len()];
    for &f in free {
        dead[f as usize] = true;
    }
    let mut new_index = vec![NONE; t.cells.len()];
    let mut next = 0u32;
    for (i, d) in dead.iter().enumerate() {
        if !d {
            new_index[i] = next;
            next += 1;
        }
    }
    let mut cells = Vec::with_capacity(next as usize);
    let mut neighbours = Vec::with_capacity(next as usize);
    for ((cell, around), d) in t.cells.iter().zip(&t.neighbours).zip(&dead) {
        if *d {
            continue;
        }
        cells.push(*cell);
        neighbours.push(around.map(|n| {
            if n == NONE {
                NONE
            } else {
                new_index[n as usize]
            }
        }));
    }
    t.cells = cells;
    t.neighbours = neighbours;
}

/// Checks a tetrahedralization with exact predicates: every cell
/// positive, neighbours mutual across a shared face, hull faces exactly
/// on the box, the cells' volumes summing to the box's, and every
/// face locally Delaunay (which makes the whole Delaunay).
pub fn check(t: &Tetrahedralization) -> Result<(), String> {
    let mut volume = 0.0;
    for (c, cell) in t.cells.iter().enumerate() {
        let o = orient_cell(&t.points, *cell);
        if o <= 0.0 {
            return Err(format!("cell {c} is not positively oriented ({o})"));
        }
        volume += o / 6.0;
        for i in 0..4 {
            let n = t.neighbours[c][i];
            let mut mine = face(*cell, i);
            mine.sort_unstable();
            if n == NONE {
                let corners = mine.map(|v| t.points[v as usize]);
                let on_box_plane = (0..3).any(|axis| {
                    let x = corners[0][axis];
                    corners.iter().all(|p| p[axis] == x)
                        && (x == t.points[0][axis] || x == t.points[7][axis])
                });
                if !on_box_plane {
                    return Err(format!("cell {c}: face {i} is open inside the box"));
                }
                continue;
            }
            let other = t.cells[n as usize];
            let Some(j) = t.neighbours[n as usize].iter().position(|&m| m == c as u32) else {
                return Err(format!("cells {c} and {n} disagree about being neighbours"));
            };
            let mut theirs = face(other, j);
            theirs.sort_unstable();
            if mine != theirs {
                return Err(format!(
                    "cells {c} and {n} do not share the face between them"
                ));
            }
            let [a, b, cc, d] = cell.map(|v| t.points[v as usize]);
            if in_sphere(a, b, cc, d, t.points[other[j] as usize]) > 0.0 {
                return Err(format!("cells {c} and {n} are not locally Delaunay"));
            }
        }
    }
    let size = t.points[7] - t.points[0];
    let expected = size.x * size.y * size.z;
    if (volume - expected).abs() > 1e-9 * expected {
        return Err(format!(
            "the cells' volume {volume} is not the box's {expected}"
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_box() -> (DVec3, DVec3) {
        (DVec3::splat(-1.0), DVec3::splat(2.0))
    }

    fn random_points(n: usize, seed: u64) -> Vec<DVec3> {
        let mut s = seed;
        let mut next = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        (0..n).map(|_| DVec3::new(next(), next(), next())).collect()
    }

    #[test]
    fn random_points_give_a_valid_delaunay_tetrahedralization() {
        let (lo, hi) = unit_box();
        let points = random_points(2000, 99);
        let t = tetrahedralize(lo, hi, &points).expect("builds");
        check(&t).expect("valid");
        assert_eq!(t.points.len(), 2008);
        assert_eq!(t.duplicates, 0);
        // Every point is a vertex of some cell.
        let mut used = vec![false; t.points.len()];
        for c in &t.cells {
            for &v in c {
                used[v as usize] = true;
            }
        }
        assert!(used.iter().all(|&u| u));
    }

    #[test]
    fn an_exact_lattice_with_and_without_jitter_is_valid() {
        // Cospherical and cocircular points by the hundred.
        let lattice: Vec<DVec3> = (0..512)
            .map(|i| DVec3::new(f64::from(i % 8), f64::from(i / 8 % 8), f64::from(i / 64)) / 8.0)
            .collect();
        let (lo, hi) = unit_box();
        let exact = tetrahedralize(lo, hi, &lattice).expect("an exact lattice builds");
        check(&exact).expect("and is valid");
        assert_eq!(exact.duplicates, 0);
        let jittered: Vec<DVec3> = lattice
            .iter()
            .zip(random_points(512, 5))
            .map(|(p, r)| *p + (r - DVec3::splat(0.5)) * 1e-3)
            .collect();
        let t = tetrahedralize(lo, hi, &jittered).expect("builds");
        check(&t).expect("valid");
    }

    #[test]
    fn duplicates_are_skipped_and_bad_input_refused() {
        let (lo, hi) = unit_box();
        let p = DVec3::new(0.25, 0.5, 0.75);
        let t = tetrahedralize(lo, hi, &[p, p, DVec3::splat(0.1)]).expect("builds");
        check(&t).expect("valid");
        assert_eq!(t.duplicates, 1);
        assert!(tetrahedralize(lo, hi, &[DVec3::splat(3.0)]).is_err());
        assert!(tetrahedralize(lo, hi, &[DVec3::new(f64::NAN, 0.0, 0.0)]).is_err());
        assert!(tetrahedralize(hi, lo, &[]).is_err());
        let empty = tetrahedralize(lo, hi, &[]).expect("the box alone");
        assert_eq!(empty.cells.len(), 6);
        check(&empty).expect("valid");
    }

    #[test]
    fn a_broken_tetrahedralization_fails_the_check() {
        let (lo, hi) = unit_box();
        let t = tetrahedralize(lo, hi, &random_points(50, 3)).expect("builds");
        let mut flipped = t.clone();
        flipped.cells[0].swap(0, 1);
        assert!(check(&flipped).is_err());
        let mut unlinked = t.clone();
        let n = unlinked.neighbours[0]
            .iter()
            .position(|&n| n != NONE)
            .unwrap_or(0);
        unlinked.neighbours[0][n] = NONE;
        assert!(check(&unlinked).is_err());
        let mut moved = t;
        // Moving an inner vertex breaks the empty-sphere property somewhere
        // (or the orientation of a cell).
        moved.points[8] = DVec3::new(1.9, 1.9, 1.9);
        assert!(check(&moved).is_err());
    }
}
