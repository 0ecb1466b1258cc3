//! [`InteriorNodes`]: the interior nodes of a tree, numbered as one list but
//! held as the lists the build's tasks produced.
//!
//! Joining those lists into one vector would hold every node twice at the
//! build's memory peak, so they stay apart, and an index finds its list
//! through a table with one entry per [`BLOCK`] indices: one load and,
//! nearly always, one comparison.

use super::Interior;

/// Indices per entry of the lookup table.
const BLOCK_SHIFT: u32 = 12;
const BLOCK: usize = 1 << BLOCK_SHIFT;

/// See the module docs.
#[derive(Debug, Default)]
pub struct InteriorNodes {
    parts: Vec<Vec<Interior>>,
    /// Index of each part's first node.
    starts: Vec<usize>,
    len: usize,
    /// For each block of [`BLOCK`] indices, the part holding its first.
    block_part: Vec<u32>,
}

impl InteriorNodes {
    /// Appends a part; its nodes take the next indices.
    pub(super) fn push_part(&mut self, part: Vec<Interior>) {
        if part.is_empty() {
            return;
        }
        let (first, end) = (self.len, self.len + part.len());
        let index = self.parts.len() as u32;
        for _ in first.div_ceil(BLOCK)..=(end - 1) >> BLOCK_SHIFT {
            self.block_part.push(index);
        }
        self.starts.push(first);
        self.parts.push(part);
        self.len = end;
    }

    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

impl std::ops::Index<usize> for InteriorNodes {
    type Output = Interior;
    fn index(&self, i: usize) -> &Interior {
        // A later part when the block holds the ends of several.
        let mut part = self.block_part[i >> BLOCK_SHIFT] as usize;
        while i >= self.starts[part] + self.parts[part].len() {
            part += 1;
        }
        &self.parts[part][i - self.starts[part]]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::build::tree::NodeRef;
    use glam::{DVec3, Vec3};

    fn node(tag: usize) -> Interior {
        Interior {
            center: DVec3::splat(tag as f64),
            radius: 1.0,
            normal: Vec3::Z,
            cone: 0.0,
            color: [0; 3],
            child_count: 2,
            leaf_count: 2,
            children: [NodeRef::leaf(0); 4],
        }
    }

    #[test]
    fn every_index_finds_its_node_across_parts_of_any_size() {
        // Parts smaller than a block, empty, exactly a block, and larger.
        let sizes = [3, 0, 1, BLOCK, 5, 2 * BLOCK + 7, 1, BLOCK - 1, 9];
        let mut nodes = InteriorNodes::default();
        let mut next = 0;
        for size in sizes {
            nodes.push_part((next..next + size).map(node).collect());
            next += size;
        }
        assert_eq!(nodes.len(), next);
        for i in 0..next {
            assert_eq!(nodes[i].center.x, i as f64, "index {i}");
        }
    }
}
