//! The counting grid and the chunks cut from it, as PotreeConverter 2
//! does: a first pass counts the points in each cell of a cubic grid over
//! the scene; cells are then merged up an octree as long as the merged
//! block stays within a chunk's size, so every chunk is a cube of cells
//! that a build can hold in memory. Dense regions get small chunks, empty
//! ones none.
//!
//! A chunk's points near its faces have neighbours in the chunks beside
//! it; the points of the cells touching a chunk (its *halo*) are copied
//! into it too, so point sizes and normals, which come from the nearest
//! neighbours, do not change at chunk borders.

use std::collections::HashMap;

use glam::DVec3;

/// Cells per axis at most: 256³ counts are 64 MiB.
pub(crate) const MAX_SIDE: u32 = 256;
/// Cells per axis at least.
const MIN_SIDE: u32 = 8;
/// Cells a chunk of a surface is meant to span.
const CELLS_PER_CHUNK: f64 = 256.0;
/// Points a cell of a surface is meant to hold at least: a few times the
/// 8 neighbours a point is sized and oriented by.
const MIN_POINTS_PER_CELL: f64 = 32.0;

/// A cubic grid of `side`³ cells over a scene's bounds.
#[derive(Debug, Clone)]
pub(crate) struct Grid {
    min: DVec3,
    /// 1 / a cell's edge.
    per_cell: f64,
    side: u32,
}

impl Grid {
    /// A grid over `bounds`, fine enough that a cell of a surface sampled
    /// like the scene holds about 1/256 of a chunk (`points` spread over
    /// `side`² cells: lidar and scans are surfaces), so a chunk is about 16
    /// cells across and its halo, a cell deep, adds about a quarter to it.
    pub(crate) fn new(bounds: (DVec3, DVec3), points: u64, chunk_points: u64) -> Self {
        let edge = (bounds.1 - bounds.0).max_element();
        // A flat or one-point scene still gets cells of a positive size.
        let edge = if edge > 0.0 { edge } else { 1.0 };
        // Not so fine that a cell holds fewer points than a point's
        // neighbourhood: a chunk's halo is one cell deep.
        let cells_wanted = (points as f64 * CELLS_PER_CHUNK / chunk_points.max(1) as f64)
            .min(points as f64 / MIN_POINTS_PER_CELL)
            .sqrt();
        let side = (cells_wanted.max(1.0) as u32)
            .next_power_of_two()
            .clamp(MIN_SIDE, MAX_SIDE);
        // The last cell closes the bounds: a point on the maximum still
        // falls inside.
        let per_cell = f64::from(side) / (edge * (1.0 + 1e-9));
        Self {
            min: bounds.0,
            per_cell,
            side,
        }
    }

    pub(crate) fn side(&self) -> u32 {
        self.side
    }

    pub(crate) fn cells(&self) -> usize {
        (self.side as usize).pow(3)
    }

    /// The cell of `p`, clamped to the grid (a point outside the bounds a
    /// LAS header claimed still lands somewhere).
    pub(crate) fn cell_of(&self, p: DVec3) -> usize {
        let max = f64::from(self.side - 1);
        let c = ((p - self.min) * self.per_cell).clamp(DVec3::ZERO, DVec3::splat(max));
        self.index([c.x as u32, c.y as u32, c.z as u32])
    }

    fn index(&self, [x, y, z]: [u32; 3]) -> usize {
        let s = self.side as usize;
        x as usize + s * (y as usize + s * z as usize)
    }

    fn coords(&self, i: usize) -> [u32; 3] {
        let s = self.side as usize;
        [(i % s) as u32, ((i / s) % s) as u32, (i / (s * s)) as u32]
    }
}

/// Which chunk each cell's points go to, and which chunks' halos they are
/// copied into.
#[derive(Debug)]
pub(crate) struct Chunks {
    grid: Grid,
    /// Chunk of each cell (`u32::MAX` for an empty cell).
    chunk_of_cell: Vec<u32>,
    /// The other chunks touching a cell, for the cells that have any.
    halo_of_cell: HashMap<u32, Vec<u32>>,
    /// Points each chunk owns, by the count.
    pub(crate) points: Vec<u64>,
}

impl Chunks {
    /// Cuts `counts` (points per cell of `grid`) into chunks of at most
    /// `chunk_points` points where a cell's own count allows it (a single
    /// cell denser than that is a chunk of its own).
    pub(crate) fn cut(grid: Grid, mut counts: Vec<u32>, chunk_points: u64) -> Self {
        debug_assert_eq!(counts.len(), grid.cells());
        let levels = grid.side.trailing_zeros();
        // The count pyramid above the grid: each level halves the side by
        // summing blocks of 2³ (level 0, the grid itself, is `counts`).
        let mut pyramid: Vec<Vec<u64>> = vec![Vec::new()];
        for level in 1..=levels {
            let side = (grid.side >> level) as usize;
            let child_side = side * 2;
            let mut sums = vec![0u64; side * side * side];
            let mut add = |i: usize, c: u64| {
                let (x, y, z) = (
                    i % child_side,
                    (i / child_side) % child_side,
                    i / (child_side * child_side),
                );
                sums[x / 2 + side * (y / 2 + side * (z / 2))] += c;
            };
            if level == 1 {
                for (i, &c) in counts.iter().enumerate().filter(|(_, c)| **c > 0) {
                    add(i, u64::from(c));
                }
            } else {
                for (i, &c) in pyramid[level as usize - 1]
                    .iter()
                    .enumerate()
                    .filter(|(_, c)| **c > 0)
                {
                    add(i, c);
                }
            }
            pyramid.push(sums);
        }
        let count_at = |level: u32, [x, y, z]: [u32; 3]| {
            let side = (grid.side >> level) as usize;
            let i = x as usize + side * (y as usize + side * z as usize);
            if level == 0 {
                u64::from(counts[i])
            } else {
                pyramid[level as usize][i]
            }
        };
        // Top-down: a block within the size is a chunk; a larger one
        // splits into its 8 octants.
        let mut blocks = Vec::new();
        let mut stack = vec![(levels, [0u32; 3])];
        while let Some((level, at)) = stack.pop() {
            let count = count_at(level, at);
            if count == 0 {
                continue;
            }
            if count <= chunk_points || level == 0 {
                blocks.push((level, at, count));
                continue;
            }
            let [x, y, z] = at;
            // Pushed in reverse, so octants come off in order.
            for o in (0..8u32).rev() {
                stack.push((
                    level - 1,
                    [2 * x + (o & 1), 2 * y + ((o >> 1) & 1), 2 * z + (o >> 2)],
                ));
            }
        }
        drop(pyramid);
        // The counts become each cell's chunk: the grid is held once.
        counts.fill(u32::MAX);
        let mut chunk_of_cell = counts;
        let mut points = Vec::with_capacity(blocks.len());
        for (id, &(level, [x, y, z], count)) in blocks.iter().enumerate() {
            let n = 1u32 << level;
            for dz in 0..n {
                for dy in 0..n {
                    for dx in 0..n {
                        let i = grid.index([x * n + dx, y * n + dy, z * n + dz]);
                        chunk_of_cell[i] = id as u32;
                    }
                }
            }
            points.push(count);
        }
        // Empty cells keep u32::MAX even inside a chunk's block: no point
        // lands in them, and their neighbours' halos need no entry for them.
        let mut halo_of_cell = HashMap::new();
        let side = grid.side as i64;
        for (i, &own) in chunk_of_cell.iter().enumerate() {
            if own == u32::MAX {
                continue;
            }
            let [x, y, z] = grid.coords(i).map(i64::from);
            let mut others: Vec<u32> = Vec::new();
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        let (nx, ny, nz) = (x + dx, y + dy, z + dz);
                        if [nx, ny, nz].iter().any(|&c| c < 0 || c >= side) {
                            continue;
                        }
                        let j = grid.index([nx as u32, ny as u32, nz as u32]);
                        let other = chunk_of_cell[j];
                        if other != u32::MAX && other != own && !others.contains(&other) {
                            others.push(other);
                        }
                    }
                }
            }
            if !others.is_empty() {
                others.sort_unstable();
                halo_of_cell.insert(i as u32, others);
            }
        }
        Self {
            grid,
            chunk_of_cell,
            halo_of_cell,
            points,
        }
    }

    pub(crate) fn len(&self) -> usize {
        self.points.len()
    }

    /// The chunk that owns `p`, and the chunks whose halos `p` is in.
    pub(crate) fn place(&self, p: DVec3) -> (u32, &[u32]) {
        let cell = self.grid.cell_of(p);
        let halo = self
            .halo_of_cell
            .get(&(cell as u32))
            .map_or(&[][..], Vec::as_slice);
        (self.chunk_of_cell[cell], halo)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chunks_stay_within_their_size_and_every_point_has_one() {
        // A dense corner and a sparse rest.
        let bounds = (DVec3::ZERO, DVec3::splat(8.0));
        let grid = Grid::new(bounds, 10_000, 1_000);
        assert_eq!(grid.side(), 32);
        let mut points = Vec::new();
        let mut rnd = crate::test_random(7);
        for _ in 0..6_000 {
            points.push(DVec3::new(rnd(), rnd(), rnd()));
        }
        for _ in 0..4_000 {
            points.push(DVec3::new(rnd() * 8.0, rnd() * 8.0, rnd() * 8.0));
        }
        let mut counts = vec![0u32; grid.cells()];
        for &p in &points {
            counts[grid.cell_of(p)] += 1;
        }
        let chunks = Chunks::cut(grid, counts, 1_000);
        assert!(chunks.len() > 10, "{} chunks", chunks.len());
        assert_eq!(chunks.points.iter().sum::<u64>(), 10_000);
        let mut owned = vec![0u64; chunks.len()];
        let mut halo_copies = 0;
        for &p in &points {
            let (own, halo) = chunks.place(p);
            owned[own as usize] += 1;
            assert!(!halo.contains(&own), "a point in its own chunk's halo");
            halo_copies += halo.len();
        }
        assert_eq!(owned, chunks.points, "placing agrees with the counts");
        // No cell holds more than the size: every chunk is within it.
        for &n in &chunks.points {
            assert!(n <= 1_000, "a chunk of {n} points");
        }
        // A point is copied to the chunks of its cell's 26 neighbours at
        // most, and some are copied.
        assert!(halo_copies > 0 && halo_copies <= 26 * points.len());
        // Out of bounds is clamped, not lost.
        let (far, _) = chunks.place(DVec3::splat(1e9));
        assert!((far as usize) < chunks.len());
    }

    #[test]
    fn a_single_point_makes_one_chunk() {
        let p = DVec3::new(3.0, -2.0, 1.0);
        let grid = Grid::new((p, p), 1, 1_000);
        let mut counts = vec![0u32; grid.cells()];
        counts[grid.cell_of(p)] = 1;
        let chunks = Chunks::cut(grid, counts, 1_000);
        assert_eq!(chunks.points, vec![1]);
        assert_eq!(chunks.place(p), (0, &[][..]));
    }
}
