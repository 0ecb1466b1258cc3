//! [`InteriorNodes`]: the interior nodes of a tree, numbered as one list but
//! held as the lists the build's tasks produced.
//!
//! Joining those lists into one vector would hold every node twice at the
//! build's memory peak, so they stay apart, and an index finds its list
//! through a table with one entry per [`BLOCK`] indices: one load and,
//! nearly always, one comparison.
//!
//! [`SharedNodes`] lets the layout's tasks replace nodes' spheres by their
//! quantized ones in place, all at once, so no list of quantized spheres
//! has to be held beside the nodes.

use std::marker::PhantomData;

use glam::DVec3;

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

/// The part holding index `i` and the index within it; `len_of` gives a
/// part's length. Panics (through a bounds check) if `i` is out of range.
fn locate(
    block_part: &[u32],
    starts: &[usize],
    len_of: impl Fn(usize) -> usize,
    i: usize,
) -> (usize, usize) {
    // A later part when the block holds the ends of several.
    let mut part = block_part[i >> BLOCK_SHIFT] as usize;
    while i >= starts[part] + len_of(part) {
        part += 1;
    }
    (part, i - starts[part])
}

impl std::ops::Index<usize> for InteriorNodes {
    type Output = Interior;
    fn index(&self, i: usize) -> &Interior {
        let (part, offset) = locate(&self.block_part, &self.starts, |p| self.parts[p].len(), i);
        &self.parts[part][offset]
    }
}

impl InteriorNodes {
    /// Access for tasks that read some nodes while replacing the spheres of
    /// others; see [`SharedNodes`].
    pub fn shared(&mut self) -> SharedNodes<'_> {
        SharedNodes {
            parts: self
                .parts
                .iter_mut()
                .map(|p| (p.as_mut_ptr(), p.len()))
                .collect(),
            starts: &self.starts,
            block_part: &self.block_part,
            len: self.len,
            _nodes: PhantomData,
        }
    }
}

/// The nodes of an [`InteriorNodes`], readable and writable from several
/// threads at once, for the layout: the tasks of one level each read their
/// parents and then, for each child, read its true sphere and replace it by
/// its quantized one. Every node has one parent, which is in one task, so
/// no node is written by two tasks or read by one task while another
/// writes it; the methods are `unsafe` because that rule is the caller's
/// to keep.
#[derive(Debug)]
pub struct SharedNodes<'a> {
    /// Each part's first node and length.
    parts: Vec<(*mut Interior, usize)>,
    starts: &'a [usize],
    block_part: &'a [u32],
    len: usize,
    /// Holds the nodes borrowed mutably, so nothing else reads them meanwhile.
    _nodes: PhantomData<&'a mut InteriorNodes>,
}

// SAFETY: the pointers are into vectors borrowed mutably for 'a, so only
// this handle reaches them; every access through it is an `unsafe` method
// whose contract rules out concurrent access to the same node.
unsafe impl Send for SharedNodes<'_> {}
unsafe impl Sync for SharedNodes<'_> {}

impl SharedNodes<'_> {
    /// Node `i`'s slot; panics if `i` is out of range.
    fn slot(&self, i: usize) -> *mut Interior {
        assert!(i < self.len, "interior node {i} of {}", self.len);
        let (part, offset) = locate(self.block_part, self.starts, |p| self.parts[p].1, i);
        // SAFETY: `locate` put `offset` below the part's length.
        unsafe { self.parts[part].0.add(offset) }
    }

    /// Asks the CPU to start loading node `i` into the cache; a hint only,
    /// it reads nothing the caller can see.
    pub fn prefetch(&self, i: usize) {
        crate::spheres::prefetch(self.slot(i));
    }

    /// A copy of node `i`.
    ///
    /// # Safety
    ///
    /// No other thread may be writing node `i` during the call.
    pub unsafe fn get(&self, i: usize) -> Interior {
        // SAFETY: the slot is in bounds, and the caller rules out a
        // concurrent write.
        unsafe { self.slot(i).read() }
    }

    /// Replaces node `i`'s sphere.
    ///
    /// # Safety
    ///
    /// No other thread may be reading or writing node `i` during the call.
    pub unsafe fn set_sphere(&self, i: usize, center: DVec3, radius: f64) {
        let node = self.slot(i);
        // SAFETY: the slot is in bounds, and the caller rules out any
        // concurrent access; no reference to the node is made.
        unsafe {
            (&raw mut (*node).center).write(center);
            (&raw mut (*node).radius).write(radius);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spheres::tree::NodeRef;
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
        // Through the shared handle, from two threads writing distinct nodes.
        let shared = nodes.shared();
        std::thread::scope(|s| {
            for half in 0..2 {
                let shared = &shared;
                s.spawn(move || {
                    for i in (half..next).step_by(2) {
                        // SAFETY: each thread touches only its own indices.
                        unsafe {
                            assert_eq!(shared.get(i).center.x, i as f64);
                            shared.set_sphere(i, DVec3::splat(-(i as f64)), 2.0);
                        }
                    }
                });
            }
        });
        for i in 0..next {
            assert_eq!(nodes[i].center, DVec3::splat(-(i as f64)), "index {i}");
            assert_eq!(nodes[i].radius, 2.0);
            assert_eq!(nodes[i].child_count, 2, "other fields kept");
        }
    }
}
