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
//! k-d tree ([`KdTree`]), after identical points have been collapsed.

use glam::{DMat3, DVec3, Vec3};

use super::leaves::{Leaf, pack_normal, round_up_f32};

/// Which neighbour's distance becomes the radius.
pub const RADIUS_NEIGHBOUR: usize = 4;
/// Neighbours in the normal fit (the point itself included).
pub const NORMAL_NEIGHBOURS: usize = 8;

/// Fills radius, normal and cone of point leaves.
pub fn size_points(leaves: &mut [Leaf], normals: Option<&[Vec3]>) {
    if leaves.is_empty() {
        return;
    }
    // Identical points collapse to one before the search, so a million
    // copies of one point cost a sort, not a million searches among copies.
    let mut order: Vec<u32> = (0..leaves.len() as u32).collect();
    let key = |i: u32| leaves[i as usize].position.to_array().map(f64::to_bits);
    order.sort_unstable_by_key(|&i| key(i));
    let mut unique: Vec<DVec3> = Vec::new();
    let mut unique_of = vec![0u32; leaves.len()];
    for (n, &i) in order.iter().enumerate() {
        if n == 0 || key(i) != key(order[n - 1]) {
            unique.push(leaves[i as usize].position);
        }
        unique_of[i as usize] = unique.len() as u32 - 1;
    }
    drop(order);
    let tree = KdTree::new(&unique);
    let k = NORMAL_NEIGHBOURS.max(RADIUS_NEIGHBOUR + 1);
    let mut neighbours = Vec::with_capacity(k);
    let mut radii = Vec::with_capacity(unique.len());
    let mut fitted = Vec::with_capacity(if normals.is_none() { unique.len() } else { 0 });
    for &p in &unique {
        tree.nearest(p, k, &mut neighbours);
        // neighbours[0] is the point itself; the rest are distinct.
        let r = neighbours
            .get(RADIUS_NEIGHBOUR)
            .or(neighbours.last())
            .map_or(0.0, |(d2, _)| d2.sqrt());
        radii.push(r);
        if normals.is_none() {
            fitted.push(fit_normal(&tree.points, &neighbours));
        }
    }
    // An isolated outlier would otherwise draw a splat the size of the gap
    // around it: clamp to a few times the typical radius.
    let mut sorted: Vec<f64> = radii.iter().copied().filter(|r| *r > 0.0).collect();
    let cap = if sorted.is_empty() {
        f64::INFINITY
    } else {
        let mid = sorted.len() / 2;
        *sorted.select_nth_unstable_by(mid, f64::total_cmp).1 * 8.0
    };
    for (i, leaf) in leaves.iter_mut().enumerate() {
        let u = unique_of[i] as usize;
        leaf.radius = round_up_f32(radii[u].min(cap));
        let n = match normals {
            Some(ns) => ns[i],
            None => fitted[u],
        };
        let n = if n.z < 0.0 { -n } else { n };
        leaf.normal = pack_normal(n);
        leaf.cone = 255;
    }
}

/// Normal of the plane through the neighbours: the eigenvector of their
/// covariance with the smallest eigenvalue (+Z when they do not span a plane).
fn fit_normal(points: &[DVec3], neighbours: &[(f64, u32)]) -> Vec3 {
    if neighbours.len() < 3 {
        return Vec3::Z;
    }
    let mean = neighbours
        .iter()
        .map(|&(_, j)| points[j as usize])
        .sum::<DVec3>()
        / neighbours.len() as f64;
    let mut cov = DMat3::ZERO;
    for &(_, j) in neighbours {
        let d = points[j as usize] - mean;
        cov += DMat3::from_cols(d * d.x, d * d.y, d * d.z);
    }
    smallest_eigenvector(cov).map_or(Vec3::Z, |v| v.as_vec3())
}

/// Smallest-eigenvalue eigenvector of a symmetric 3x3 matrix by cyclic
/// Jacobi rotations; `None` for a zero or non-finite matrix.
pub fn smallest_eigenvector(m: DMat3) -> Option<DVec3> {
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
    points: Vec<DVec3>,
    /// Split axis of the range whose middle is at this index.
    axis: Vec<u8>,
}

/// Ranges this small are searched by brute force.
const KD_LEAF: usize = 8;

impl KdTree {
    fn new(points: &[DVec3]) -> Self {
        let mut tree = Self {
            points: points.to_vec(),
            axis: vec![0; points.len()],
        };
        let n = tree.points.len();
        tree.build(0, n);
        tree
    }

    fn build(&mut self, lo: usize, hi: usize) {
        if hi - lo <= KD_LEAF {
            return;
        }
        let (mut min, mut max) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for p in &self.points[lo..hi] {
            min = min.min(*p);
            max = max.max(*p);
        }
        let axis = (max - min).max_position();
        let mid = (lo + hi) / 2;
        self.points[lo..hi].select_nth_unstable_by(mid - lo, |a, b| a[axis].total_cmp(&b[axis]));
        self.axis[mid] = axis as u8;
        self.build(lo, mid);
        self.build(mid + 1, hi);
    }

    /// The `k` nearest points to `p` as (squared distance, index), nearest first.
    fn nearest(&self, p: DVec3, k: usize, out: &mut Vec<(f64, u32)>) {
        out.clear();
        self.search(p, k, 0, self.points.len(), out);
    }

    fn offer(&self, p: DVec3, k: usize, i: usize, out: &mut Vec<(f64, u32)>) {
        let d2 = self.points[i].distance_squared(p);
        if out.len() == k && d2 >= out[k - 1].0 {
            return;
        }
        let at = out.partition_point(|(e, _)| *e <= d2);
        out.insert(at, (d2, i as u32));
        out.truncate(k);
    }

    fn search(&self, p: DVec3, k: usize, lo: usize, hi: usize, out: &mut Vec<(f64, u32)>) {
        if hi - lo <= KD_LEAF {
            for i in lo..hi {
                self.offer(p, k, i, out);
            }
            return;
        }
        let mid = (lo + hi) / 2;
        let axis = usize::from(self.axis[mid]);
        self.offer(p, k, mid, out);
        let delta = p[axis] - self.points[mid][axis];
        let (near, far) = if delta < 0.0 {
            ((lo, mid), (mid + 1, hi))
        } else {
            ((mid + 1, hi), (lo, mid))
        };
        self.search(p, k, near.0, near.1, out);
        if out.len() < k || delta * delta < out[k - 1].0 {
            self.search(p, k, far.0, far.1, out);
        }
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
