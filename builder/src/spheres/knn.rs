//! Size and orientation for point clouds from their nearest neighbours.
//!
//! Without connectivity there are no triangles to size a splat by (QSplat
//! 2.2 notes this case), so each point gets the distance to its
//! [`RADIUS_NEIGHBOUR`]th nearest distinct neighbour as radius, which covers
//! the gaps between neighbours on a regularly sampled surface, and, when the
//! input has no normals, the normal of the plane fitted to its
//! [`NORMAL_NEIGHBOURS`] nearest neighbours (smallest principal axis).
//!
//! Such normals have no reliable sign, so they are turned to face +Z (up for
//! aerial lidar, the common case) and the leaves get a full normal cone:
//! they shade two-sided and are never backface-culled.
//!
//! The search is an exact k-nearest-neighbour query in a balanced, implicit
//! k-d tree ([`KdTree`], with the running best in [`Nearest`]), after
//! identical points have been collapsed. All of it but two linear passes
//! (the collapse's, and the one finding each point's place in the tree)
//! runs on all threads, and the result does not depend on their number.

use glam::{DMat3, DVec3, Vec3};
use rayon::prelude::*;

use super::leaves::{Leaf, pack_normal, round_up_f32};

/// Which neighbour's distance becomes the radius.
pub const RADIUS_NEIGHBOUR: usize = 4;
/// Neighbours in the normal fit (the point itself included).
pub const NORMAL_NEIGHBOURS: usize = 8;

/// Neighbours each search finds: enough for the radius and the normal fit.
const K: usize = if NORMAL_NEIGHBOURS > RADIUS_NEIGHBOUR + 1 {
    NORMAL_NEIGHBOURS
} else {
    RADIUS_NEIGHBOUR + 1
};

/// Distinct points per parallel task of searches.
const SEARCHES_PER_TASK: usize = 1 << 10;

/// Fills radius, normal and cone of point leaves.
///
/// The searches (the bulk of the work, one per distinct point) go in the
/// tree's own order, so consecutive searches walk the same branches while
/// they are in cache.
pub fn size_points(leaves: &mut [Leaf], normals: Option<&[Vec3]>) {
    size_points_capped(leaves, normals, true);
}

/// [`size_points`] without the outlier cap, for a part of a cloud, whose
/// median is not the whole cloud's: returns each leaf's radius as found
/// (its `radius` is that, rounded up to f32), and the caller caps them
/// later with [`radius_cap`] of the whole cloud's median.
pub fn size_points_uncapped(leaves: &mut [Leaf], normals: Option<&[Vec3]>) -> Vec<f64> {
    size_points_capped(leaves, normals, false)
}

/// How much larger than the median radius a point's radius may be.
pub const OUTLIER_CAP: f64 = 8.0;

/// The largest radius a point gets in a cloud whose median radius is
/// `median`.
pub fn radius_cap(median: f64) -> f64 {
    median * OUTLIER_CAP
}

/// Sizes and orients `leaves`; returns their radii as found, unless
/// `capped` (then empty).
fn size_points_capped(leaves: &mut [Leaf], normals: Option<&[Vec3]>, capped: bool) -> Vec<f64> {
    if leaves.is_empty() {
        return Vec::new();
    }
    // Identical points collapse to one before the search, so a million
    // copies of one point cost a sort, not a million searches among copies.
    // The sort is of the coordinates' bits themselves (not of indices into
    // the leaves), so its comparisons read memory in order.
    let mut keyed: Vec<([u64; 3], u32)> = leaves
        .par_iter()
        .zip(0..leaves.len() as u32)
        .map(|(leaf, i)| (leaf.position.to_array().map(f64::to_bits), i))
        .collect();
    keyed.par_sort_unstable();
    let mut distinct: Vec<Entry> = Vec::new();
    let mut unique_of = vec![0u32; leaves.len()];
    for (n, &(bits, i)) in keyed.iter().enumerate() {
        if n == 0 || bits != keyed[n - 1].0 {
            distinct.push(Entry {
                position: DVec3::from_array(bits.map(f64::from_bits)),
                id: distinct.len() as u32,
            });
        }
        unique_of[i as usize] = distinct.len() as u32 - 1;
    }
    drop(keyed);
    let tree = KdTree::new(distinct);
    let fit = normals.is_none();
    // (radius, fitted normal) of each distinct point, in the tree's order.
    let found: Vec<(f64, Vec3)> = tree
        .entries
        .par_iter()
        .with_min_len(SEARCHES_PER_TASK)
        .map(|entry| {
            let mut near = Nearest::default();
            tree.search(entry.position, 0, tree.entries.len(), &mut near);
            let neighbours = near.found();
            // neighbours[0] is the point itself; the rest are distinct.
            let r = neighbours
                .get(RADIUS_NEIGHBOUR)
                .or(neighbours.last())
                .map_or(0.0, |(d2, _)| d2.sqrt());
            let normal = if fit {
                fit_normal(&tree.entries, neighbours)
            } else {
                Vec3::Z
            };
            (r, normal)
        })
        .collect();
    // An isolated outlier would otherwise draw a splat the size of the gap
    // around it: clamp to a few times the typical radius.
    let cap = if capped {
        let mut sorted: Vec<f64> = found.iter().map(|f| f.0).filter(|r| *r > 0.0).collect();
        if sorted.is_empty() {
            f64::INFINITY
        } else {
            let mid = sorted.len() / 2;
            radius_cap(*sorted.select_nth_unstable_by(mid, f64::total_cmp).1)
        }
    } else {
        f64::INFINITY
    };
    // Where each distinct point's result is: its place in the tree.
    let mut slot_of = vec![0u32; found.len()];
    for (slot, entry) in tree.entries.iter().enumerate() {
        slot_of[entry.id as usize] = slot as u32;
    }
    drop(tree);
    let found_radius = |i: usize| found[slot_of[unique_of[i] as usize] as usize].0;
    let radii = if capped {
        Vec::new()
    } else {
        (0..leaves.len())
            .into_par_iter()
            .map(found_radius)
            .collect()
    };
    leaves
        .par_iter_mut()
        .with_min_len(SEARCHES_PER_TASK)
        .enumerate()
        .for_each(|(i, leaf)| {
            let (radius, fitted) = found[slot_of[unique_of[i] as usize] as usize];
            leaf.radius = round_up_f32(radius.min(cap));
            let n = match normals {
                Some(ns) => ns[i],
                None => fitted,
            };
            let n = if n.z < 0.0 { -n } else { n };
            leaf.normal = pack_normal(n);
            leaf.cone = 255;
        });
    radii
}

/// Normal of the plane through the neighbours: the eigenvector of their
/// covariance with the smallest eigenvalue (+Z when they do not span a plane).
fn fit_normal(entries: &[Entry], neighbours: &[(f64, u32)]) -> Vec3 {
    if neighbours.len() < 3 {
        return Vec3::Z;
    }
    let mean = neighbours
        .iter()
        .map(|&(_, j)| entries[j as usize].position)
        .sum::<DVec3>()
        / neighbours.len() as f64;
    let mut cov = DMat3::ZERO;
    for &(_, j) in neighbours {
        let d = entries[j as usize].position - mean;
        cov += DMat3::from_cols(d * d.x, d * d.y, d * d.z);
    }
    smallest_eigenvector(cov).map_or(Vec3::Z, |v| v.as_vec3())
}

/// Smallest-eigenvalue eigenvector of a symmetric 3x3 matrix; `None` for a
/// zero or non-finite matrix.
///
/// In closed form, as PCL's normal estimation does: the smallest root of
/// the characteristic polynomial by the trigonometric formula (Smith 1961),
/// then the eigenvector as the longest cross product of two rows of
/// A - λI (rows orthogonal to it). That takes one `acos`, one `cos` and a
/// few products, against several sweeps of rotations. When the smallest
/// eigenvalue is (nearly) double, the rows span too little to give a
/// direction, and [`smallest_eigenvector_jacobi`] answers instead.
pub fn smallest_eigenvector(m: DMat3) -> Option<DVec3> {
    let cols = m.to_cols_array_2d();
    let scale = cols.iter().flatten().fold(0.0f64, |s, v| s.max(v.abs()));
    if !(scale.is_finite() && scale > 0.0) {
        return None;
    }
    // Scaled to entries of at most 1, so the thresholds below are relative.
    let a = DMat3::from_cols_array_2d(&cols) * (1.0 / scale);
    let shift = (a.x_axis.x + a.y_axis.y + a.z_axis.z) / 3.0;
    let b = a - DMat3::from_diagonal(DVec3::splat(shift));
    let off = DVec3::new(b.y_axis.x, b.z_axis.x, b.z_axis.y);
    let diag = DVec3::new(b.x_axis.x, b.y_axis.y, b.z_axis.z);
    let p = ((diag.length_squared() + 2.0 * off.length_squared()) / 6.0).sqrt();
    if p > 1e-6 {
        // The eigenvalues are shift + 2p cos(phi + 2πk/3); k = 1 is the smallest.
        let r = (b.determinant() / (2.0 * p * p * p)).clamp(-1.0, 1.0);
        let phi = r.acos() / 3.0;
        let smallest = shift + 2.0 * p * (phi + 2.0 * std::f64::consts::FRAC_PI_3).cos();
        let rows = a - DMat3::from_diagonal(DVec3::splat(smallest));
        // Symmetric: the columns are the rows.
        let (r0, r1, r2) = (rows.x_axis, rows.y_axis, rows.z_axis);
        let candidates = [r0.cross(r1), r0.cross(r2), r1.cross(r2)];
        let best = candidates
            .into_iter()
            .max_by(|u, v| u.length_squared().total_cmp(&v.length_squared()))?;
        // Rows of a rank-2 matrix with entries up to 1: a cross product
        // this long fixes the direction to far better than the 14-bit
        // normal code resolves.
        if best.length_squared() > 1e-12 {
            return best.try_normalize();
        }
    }
    smallest_eigenvector_jacobi(m)
}

/// [`smallest_eigenvector`] by cyclic Jacobi rotations: slower, but well
/// defined for repeated eigenvalues.
fn smallest_eigenvector_jacobi(m: DMat3) -> Option<DVec3> {
    let mut a = m.to_cols_array_2d();
    let scale = a.iter().flatten().fold(0.0f64, |s, v| s.max(v.abs()));
    if !(scale.is_finite() && scale > 0.0) {
        return None;
    }
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _sweep in 0..32 {
        let off = a[0][1].abs() + a[0][2].abs() + a[1][2].abs();
        if off <= 1e-15 * scale {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q].abs() <= 1e-300 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            for row in a.iter_mut() {
                let (akp, akq) = (row[p], row[q]);
                row[p] = c * akp - s * akq;
                row[q] = s * akp + c * akq;
            }
            let (row_p, row_q) = (a[p], a[q]);
            for k in 0..3 {
                a[p][k] = c * row_p[k] - s * row_q[k];
                a[q][k] = s * row_p[k] + c * row_q[k];
            }
            for row in &mut v {
                let (vkp, vkq) = (row[p], row[q]);
                row[p] = c * vkp - s * vkq;
                row[q] = s * vkp + c * vkq;
            }
        }
    }
    let i = (0..3).min_by(|&x, &y| a[x][x].total_cmp(&a[y][y]))?;
    DVec3::new(v[0][i], v[1][i], v[2][i]).try_normalize()
}

/// A static k-d tree stored implicitly: within every range the median
/// along the range's longest axis sits at the middle, halves on either side.
/// Balanced whatever the distribution, so no input makes a search slow.
struct KdTree {
    entries: Vec<Entry>,
    /// Split axis of the range whose middle is at this index.
    axis: Vec<u8>,
}

/// A point of the tree and its index in the input.
#[derive(Clone, Copy)]
struct Entry {
    position: DVec3,
    id: u32,
}

/// Ranges this small are searched by brute force.
const KD_LEAF: usize = 8;

/// Ranges at least this large build their halves on two threads.
const PARALLEL_BUILD: usize = 1 << 14;

impl KdTree {
    /// The tree of `entries` (reordered).
    fn new(mut entries: Vec<Entry>) -> Self {
        let mut axis = vec![0; entries.len()];
        Self::build(&mut entries, &mut axis);
        Self { entries, axis }
    }

    /// Puts the median along the longest axis of `entries` in the middle
    /// (recording the axis there), and recurses into both halves.
    fn build(entries: &mut [Entry], axis: &mut [u8]) {
        let n = entries.len();
        if n <= KD_LEAF {
            return;
        }
        let (mut min, mut max) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for e in entries.iter() {
            min = min.min(e.position);
            max = max.max(e.position);
        }
        let longest = (max - min).max_position();
        let mid = n / 2;
        entries.select_nth_unstable_by(mid, |a, b| {
            a.position[longest].total_cmp(&b.position[longest])
        });
        axis[mid] = longest as u8;
        let (left, right) = entries.split_at_mut(mid);
        let (left_axis, right_axis) = axis.split_at_mut(mid);
        let (right, right_axis) = (&mut right[1..], &mut right_axis[1..]);
        if n >= PARALLEL_BUILD {
            rayon::join(
                || Self::build(left, left_axis),
                || Self::build(right, right_axis),
            );
        } else {
            Self::build(left, left_axis);
            Self::build(right, right_axis);
        }
    }

    /// Offers the entries `lo..hi` near `p` to `near`.
    fn search(&self, p: DVec3, lo: usize, hi: usize, near: &mut Nearest) {
        if hi - lo <= KD_LEAF {
            for i in lo..hi {
                near.offer(self.entries[i].position.distance_squared(p), i);
            }
            return;
        }
        let mid = (lo + hi) / 2;
        let axis = usize::from(self.axis[mid]);
        let split = self.entries[mid].position;
        let delta = p[axis] - split[axis];
        let (near_half, far_half) = if delta < 0.0 {
            ((lo, mid), (mid + 1, hi))
        } else {
            ((mid + 1, hi), (lo, mid))
        };
        self.search(p, near_half.0, near_half.1, near);
        // The split point and the far half lie at least |delta| away: once
        // the near half has been searched, usually too far to matter.
        if delta * delta < near.worst() {
            near.offer(split.distance_squared(p), mid);
            self.search(p, far_half.0, far_half.1, near);
        }
    }
}

/// The [`K`] nearest entries seen so far, nearest first, in a fixed array:
/// a search offers dozens of candidates and keeps a few.
struct Nearest {
    /// (squared distance, entry index); the first `len` are valid.
    found: [(f64, u32); K],
    len: usize,
}

impl Default for Nearest {
    fn default() -> Self {
        Self {
            found: [(0.0, 0); K],
            len: 0,
        }
    }
}

impl Nearest {
    fn found(&self) -> &[(f64, u32)] {
        &self.found[..self.len]
    }

    /// The squared distance a candidate must beat: infinite until full.
    fn worst(&self) -> f64 {
        if self.len < K {
            f64::INFINITY
        } else {
            self.found[K - 1].0
        }
    }

    /// Keeps entry `i` if it is among the nearest; after those at the same
    /// distance, so earlier offers win ties.
    fn offer(&mut self, d2: f64, i: usize) {
        if d2 >= self.worst() {
            return;
        }
        let mut at = if self.len < K {
            self.len += 1;
            self.len - 1
        } else {
            K - 1
        };
        while at > 0 && self.found[at - 1].0 > d2 {
            self.found[at] = self.found[at - 1];
            at -= 1;
        }
        self.found[at] = (d2, i as u32);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn leaf(p: DVec3) -> Leaf {
        Leaf {
            position: p,
            radius: 0.0,
            normal: 0,
            color: [0; 3],
            cone: 0,
            source: 0,
        }
    }

    #[test]
    fn plane_points_get_vertical_normals_and_neighbour_radius() {
        let mut leaves: Vec<Leaf> = (0..400)
            .map(|i| leaf(DVec3::new(f64::from(i % 20), f64::from(i / 20), 3.0)))
            .collect();
        size_points(&mut leaves, None);
        for l in &leaves {
            let n = super::super::leaves::unpack_normal(l.normal);
            assert!(n.angle_between(Vec3::Z) < 1e-3, "{n}");
            // 4th nearest: 1 inside the grid, up to 2 at a corner.
            assert!(l.radius >= 1.0 && l.radius <= 2.0, "{}", l.radius);
            assert_eq!(l.cone, 255);
        }
    }

    #[test]
    fn searches_find_the_same_distances_as_brute_force() {
        let mut rnd = crate::test_random(7);
        // Clustered and on a coarse grid, so distances tie often.
        let points: Vec<DVec3> = (0..3000)
            .map(|i| {
                let p = DVec3::new(rnd(), rnd(), rnd() * 0.1) * 20.0;
                if i % 3 == 0 { p.round() } else { p }
            })
            .collect();
        let entries = points.iter().zip(0..);
        let tree = KdTree::new(
            entries
                .map(|(&position, id)| Entry { position, id })
                .collect(),
        );
        for (slot, entry) in tree.entries.iter().enumerate().step_by(7) {
            let mut near = Nearest::default();
            tree.search(entry.position, 0, tree.entries.len(), &mut near);
            let mut all: Vec<f64> = points
                .iter()
                .map(|q| q.distance_squared(entry.position))
                .collect();
            all.sort_by(f64::total_cmp);
            let found: Vec<f64> = near.found().iter().map(|f| f.0).collect();
            assert_eq!(found, all[..K], "search from entry {slot}");
            assert_eq!(points[entry.id as usize], entry.position);
        }
    }

    #[test]
    fn closed_form_and_jacobi_eigenvectors_agree() {
        let mut rnd = crate::test_random(99);
        let mut worst = 0.0f64;
        let mut fallbacks = 0;
        for case in 0..20_000 {
            // Neighbourhoods as a point cloud has them: a tilted patch of 8
            // points, stretched (a scan line), flattened (a plane), or not.
            let stretch = [1.0, 1e-3, 1e-6][case % 3];
            let flat = [1e-2, 1e-5, 1.0][case / 3 % 3];
            let axes =
                DMat3::from_euler(glam::EulerRot::XYZ, rnd() * 6.3, rnd() * 6.3, rnd() * 6.3);
            let points: Vec<DVec3> = (0..8)
                .map(|_| axes * DVec3::new(rnd(), rnd() * stretch, rnd() * flat) * 1e3)
                .collect();
            let mean = points.iter().sum::<DVec3>() / 8.0;
            let mut cov = DMat3::ZERO;
            for p in &points {
                let d = *p - mean;
                cov += DMat3::from_cols(d * d.x, d * d.y, d * d.z);
            }
            let jacobi = smallest_eigenvector_jacobi(cov).unwrap();
            let closed = smallest_eigenvector(cov).unwrap();
            // The eigenvector's sign is arbitrary. Compare what matters: how
            // much of the matrix each leaves (its eigenvalue).
            let value = |v: DVec3| v.dot(cov * v);
            let scale = cov
                .to_cols_array()
                .iter()
                .fold(0.0f64, |s, v| s.max(v.abs()));
            let gap = (value(closed) - value(jacobi)).abs() / scale;
            worst = worst.max(gap);
            if stretch == 1.0 && flat == 1e-2 {
                // A well-defined normal: the two agree in direction too.
                let angle = closed.dot(jacobi).abs().min(1.0).acos();
                assert!(angle < 1e-6, "case {case}: {angle} rad apart");
            }
            fallbacks += usize::from(closed == jacobi);
        }
        assert!(worst < 1e-9, "eigenvalues differ by {worst} of the scale");
        assert!(fallbacks < 20_000, "the closed form never answered");
    }

    #[test]
    fn eigenvector_of_diagonal_matrix() {
        let v = smallest_eigenvector(DMat3::from_diagonal(DVec3::new(3.0, 0.5, 2.0))).unwrap();
        assert!(v.abs().distance(DVec3::Y) < 1e-9);
        assert!(smallest_eigenvector(DMat3::ZERO).is_none());
    }

    #[test]
    fn duplicates_and_single_points_do_not_hang() {
        let mut leaves = vec![leaf(DVec3::ONE); 1_000_000];
        size_points(&mut leaves, None);
        assert!(leaves.iter().all(|l| l.radius == 0.0));
        let mut one = vec![leaf(DVec3::ZERO)];
        size_points(&mut one, None);
        assert_eq!(one[0].radius, 0.0);
    }
}
