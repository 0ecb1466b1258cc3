//! Where cached images live: one square texture atlas, carved into
//! power-of-two square blocks by a quadtree buddy allocator, with a byte
//! budget (the atlas's size) and least-recently-used eviction.
//!
//! Power-of-two blocks are the paper's own texture constraint ("almost
//! half of the pixels in the textures go unused"); here they buy an
//! allocator with no fragmentation to manage: a freed block merges with
//! its three siblings, so the atlas never fills with holes too small to
//! use. The planner (not the GPU) owns the atlas's layout, so the
//! renderer only copies into and samples from the blocks it is told.

/// A block of the atlas, in texels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Block {
    pub x: u32,
    pub y: u32,
    pub side: u32,
}

/// Bytes of one texel (RGBA8, premultiplied).
pub const TEXEL_BYTES: u64 = 4;

/// The smallest block handed out.
pub const MIN_SIDE: u32 = 16;

/// A quadtree of free and used blocks over a `side` x `side` atlas.
#[derive(Debug, Clone)]
pub struct Atlas {
    side: u32,
    /// Free blocks by level (level 0 is the whole atlas).
    free: Vec<Vec<(u32, u32)>>,
    used_texels: u64,
}

impl Atlas {
    /// An empty atlas of `side` texels (rounded down to a power of two, at
    /// least [`MIN_SIDE`]).
    pub fn new(side: u32) -> Self {
        let side = if side.is_power_of_two() {
            side
        } else {
            1 << (31 - side.max(1).leading_zeros())
        }
        .max(MIN_SIDE);
        let levels = (side / MIN_SIDE).trailing_zeros() as usize + 1;
        let mut free = vec![Vec::new(); levels];
        free[0].push((0, 0));
        Self {
            side,
            free,
            used_texels: 0,
        }
    }

    pub fn side(&self) -> u32 {
        self.side
    }

    /// Bytes the atlas holds in all.
    pub fn capacity_bytes(&self) -> u64 {
        u64::from(self.side).pow(2) * TEXEL_BYTES
    }

    /// Bytes of the blocks in use.
    pub fn used_bytes(&self) -> u64 {
        self.used_texels * TEXEL_BYTES
    }

    /// The side of the block a `w` x `h` image needs, if one can hold it.
    pub fn side_for(&self, w: u32, h: u32) -> Option<u32> {
        let need = w.max(h).max(MIN_SIDE).checked_next_power_of_two()?;
        (need <= self.side).then_some(need)
    }

    fn level_of(&self, side: u32) -> usize {
        (self.side / side).trailing_zeros() as usize
    }

    /// A free block for a `w` x `h` image, or `None` when none is free.
    pub fn allocate(&mut self, w: u32, h: u32) -> Option<Block> {
        let side = self.side_for(w, h)?;
        let level = self.level_of(side);
        // The deepest free block at or above the level, split down to it.
        let from = (0..=level).rev().find(|&l| !self.free[l].is_empty())?;
        let (x, y) = self.free[from].pop()?;
        let mut s = self.side >> from;
        for l in from + 1..=level {
            s /= 2;
            // Keep the first quarter; the other three are free.
            self.free[l].extend([(x + s, y), (x, y + s), (x + s, y + s)]);
        }
        self.used_texels += u64::from(side).pow(2);
        Some(Block { x, y, side })
    }

    /// Returns `block`, merging it with free siblings.
    pub fn free(&mut self, block: Block) {
        self.used_texels = self
            .used_texels
            .saturating_sub(u64::from(block.side).pow(2));
        let (mut x, mut y, mut side) = (block.x, block.y, block.side);
        let mut level = self.level_of(side);
        while level > 0 {
            let parent = side * 2;
            let (px, py) = (x - x % parent, y - y % parent);
            let siblings = [
                (px, py),
                (px + side, py),
                (px, py + side),
                (px + side, py + side),
            ];
            let others: Vec<(u32, u32)> = siblings.into_iter().filter(|&s| s != (x, y)).collect();
            let list = &mut self.free[level];
            if !others.iter().all(|o| list.contains(o)) {
                break;
            }
            list.retain(|s| !others.contains(s));
            (x, y, side) = (px, py, parent);
            level -= 1;
        }
        self.free[level].push((x, y));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_never_overlap_and_freeing_everything_merges_back() {
        let mut atlas = Atlas::new(256);
        let mut blocks = Vec::new();
        for (w, h) in [(100, 20), (10, 10), (64, 64), (65, 3), (16, 16), (30, 31)] {
            blocks.push(atlas.allocate(w, h).expect("room"));
        }
        for (i, a) in blocks.iter().enumerate() {
            assert!(a.x + a.side <= 256 && a.y + a.side <= 256);
            for b in &blocks[i + 1..] {
                let apart = a.x + a.side <= b.x
                    || b.x + b.side <= a.x
                    || a.y + a.side <= b.y
                    || b.y + b.side <= a.y;
                assert!(apart, "{a:?} overlaps {b:?}");
            }
        }
        assert_eq!(blocks[0].side, 128);
        assert_eq!(blocks[1].side, MIN_SIDE);
        let used: u64 = blocks.iter().map(|b| u64::from(b.side).pow(2) * 4).sum();
        assert_eq!(atlas.used_bytes(), used);
        for b in blocks {
            atlas.free(b);
        }
        assert_eq!(atlas.used_bytes(), 0);
        // Merged back: the whole atlas is one block again.
        assert_eq!(
            atlas.allocate(256, 256),
            Some(Block {
                x: 0,
                y: 0,
                side: 256
            })
        );
        assert_eq!(atlas.allocate(1, 1), None, "full");
    }

    #[test]
    fn an_image_larger_than_the_atlas_gets_no_block() {
        let mut atlas = Atlas::new(300);
        assert_eq!(atlas.side(), 256);
        assert_eq!(atlas.allocate(257, 10), None);
        assert_eq!(atlas.side_for(0, 0), Some(MIN_SIDE));
        assert!(atlas.allocate(256, 256).is_some());
    }
}
