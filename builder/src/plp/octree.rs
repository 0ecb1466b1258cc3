//! The occupancy octree whose leaf centres become the tessellation's
//! vertices (section 3.1, Figure 3b and 3c).
//!
//! Only the input's vertices are inserted, as the paper does ("instead of
//! accurately sampling the actual primitives, we simply construct an octree
//! using only the original vertices"). A node holding a vertex splits until
//! its side is shorter than `leaf_fraction` of the bounding box's longest
//! side; a node holding none is a leaf at once. Every leaf, empty or not,
//! gives one point: small cells where there is geometry, large ones where
//! there is none. The centres are then jittered (seeded), since an octree's
//! centres are as degenerate as points get (cospherical by the thousand).

use glam::DVec3;

/// The octree's leaf centres.
#[derive(Debug, Clone)]
pub struct Leaves {
    /// Centres, jittered.
    pub centres: Vec<DVec3>,
    /// Leaves that held at least one vertex.
    pub occupied: usize,
    /// The octree's depth (the root is 0).
    pub depth: u32,
}

/// The deepest the octree may go whatever the fraction: 2^-20 of the
/// scene is far finer than any useful tessellation.
const MAX_DEPTH: u32 = 20;

/// Leaf centres of the octree over `points` in the cube at `min` with
/// side `side`, splitting occupied nodes while their side is at least
/// `leaf_fraction * side`. Each centre moves by up to `jitter` of its
/// leaf's side along each axis, from `seed`.
pub fn leaf_centres(
    points: &[DVec3],
    min: DVec3,
    side: f64,
    leaf_fraction: f64,
    jitter: f64,
    seed: u64,
) -> Leaves {
    let stop = leaf_fraction * side;
    let mut out = Leaves {
        centres: Vec::new(),
        occupied: 0,
        depth: 0,
    };
    // (min corner, side, depth, the points inside) — a node's points are a
    // range of `order`, partitioned in place as it splits.
    let mut order: Vec<u32> = (0..points.len() as u32).collect();
    let mut stack = vec![(min, side, 0u32, 0usize, order.len())];
    while let Some((lo, s, depth, start, end)) = stack.pop() {
        out.depth = out.depth.max(depth);
        let centre = lo + DVec3::splat(s * 0.5);
        let occupied = end > start;
        if !occupied || s < stop || depth >= MAX_DEPTH {
            out.occupied += usize::from(occupied);
            out.centres
                .push(jittered(centre, s, jitter, seed, out.centres.len()));
            continue;
        }
        // Split the range by octant: x, then y within each half, then z.
        let slice = &mut order[start..end];
        let by = |axis: usize, v: &mut [u32]| -> usize {
            partition(v, |&i| points[i as usize][axis] < centre[axis])
        };
        let x = by(0, slice);
        let (lx, hx) = slice.split_at_mut(x);
        let (ly, hy) = (by(1, lx), by(1, hx));
        let mut bounds = [0usize; 9];
        let halves = [(&mut lx[..], ly, 0usize), (&mut hx[..], hy, 4)];
        let mut at = start;
        for (half, y, base) in halves {
            let (a, b) = half.split_at_mut(y);
            let za = partition(a, |&i| points[i as usize][2] < centre[2]);
            let zb = partition(b, |&i| points[i as usize][2] < centre[2]);
            // Octant bits: x = 4, y = 2, z = 1 (as `base + 2y + z`).
            let sizes = [za, a.len() - za, zb, b.len() - zb];
            for (k, n) in sizes.into_iter().enumerate() {
                bounds[base + k] = at;
                at += n;
            }
        }
        bounds[8] = end;
        let half = s * 0.5;
        for octant in (0..8).rev() {
            let offset = DVec3::new(
                if octant & 4 != 0 { half } else { 0.0 },
                if octant & 2 != 0 { half } else { 0.0 },
                if octant & 1 != 0 { half } else { 0.0 },
            );
            stack.push((
                lo + offset,
                half,
                depth + 1,
                bounds[octant],
                bounds[octant + 1],
            ));
        }
    }
    out
}

/// Moves `v`'s elements for which `left` holds to the front; returns how
/// many there are.
fn partition(v: &mut [u32], left: impl Fn(&u32) -> bool) -> usize {
    let mut k = 0;
    for i in 0..v.len() {
        if left(&v[i]) {
            v.swap(i, k);
            k += 1;
        }
    }
    k
}

/// A leaf centre moved by up to `jitter * side` per axis, keyed by the
/// leaf's number so the result does not depend on anything else.
fn jittered(centre: DVec3, side: f64, jitter: f64, seed: u64, leaf: usize) -> DVec3 {
    let mut state =
        seed ^ 0x504C_505F_4A49_5454 ^ (leaf as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    let mut unit = || {
        // SplitMix64.
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    centre + DVec3::new(unit(), unit(), unit()) * (jitter * side)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn occupied_leaves_are_small_and_empty_ones_large() {
        // A cluster of points in one corner of a unit cube.
        let points: Vec<DVec3> = (0..100)
            .map(|i| DVec3::splat(0.01 + 0.0001 * f64::from(i)))
            .collect();
        let leaves = leaf_centres(&points, DVec3::ZERO, 1.0, 0.05, 0.0, 1);
        // Leaves stop below 5 %: side 1/32 (depth 5) is the first under it.
        assert_eq!(leaves.depth, 5);
        // One occupied leaf, and 7 empty siblings at each of 5 levels.
        assert_eq!(leaves.occupied, 1);
        assert_eq!(leaves.centres.len(), 1 + 7 * 5);
        // Every centre is inside the root, and distinct.
        for (i, c) in leaves.centres.iter().enumerate() {
            assert!(c.cmpge(DVec3::ZERO).all() && c.cmple(DVec3::ONE).all());
            for d in &leaves.centres[..i] {
                assert_ne!(c, d);
            }
        }
    }

    #[test]
    fn all_points_in_one_leaf_and_no_points_still_give_leaves() {
        let same = vec![DVec3::splat(0.5); 10];
        let leaves = leaf_centres(&same, DVec3::ZERO, 1.0, 0.6, 0.0, 1);
        assert_eq!(leaves.occupied, 1);
        assert_eq!(leaves.centres.len(), 8);
        let none = leaf_centres(&[], DVec3::ZERO, 1.0, 0.05, 0.0, 1);
        assert_eq!(none.centres, vec![DVec3::splat(0.5)]);
    }

    #[test]
    fn jitter_is_bounded_and_seeded() {
        let points: Vec<DVec3> = (0..1000)
            .map(|i| {
                DVec3::new(
                    f64::from(i % 10),
                    f64::from(i / 10 % 10),
                    f64::from(i / 100),
                ) / 10.0
            })
            .collect();
        let plain = leaf_centres(&points, DVec3::ZERO, 1.0, 0.1, 0.0, 1);
        let a = leaf_centres(&points, DVec3::ZERO, 1.0, 0.1, 0.1, 7);
        let b = leaf_centres(&points, DVec3::ZERO, 1.0, 0.1, 0.1, 7);
        let c = leaf_centres(&points, DVec3::ZERO, 1.0, 0.1, 0.1, 8);
        assert_eq!(a.centres, b.centres);
        assert_ne!(a.centres, c.centres);
        assert_eq!(a.centres.len(), plain.centres.len());
        for (p, q) in plain.centres.iter().zip(&a.centres) {
            // Leaves here are 1/16 wide: a tenth of that per axis at most.
            assert!((*p - *q).abs().max_element() <= 0.1 / 16.0 + 1e-12);
            assert_ne!(p, q);
        }
    }
}
