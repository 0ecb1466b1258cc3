//! Inflated leaves (section 4): each leaf also stores the geometry of its
//! neighbours that lies inside its region grown by a fraction, so two
//! adjacent leaves drawn from separate cached images overlap a little and
//! no crack shows where their images meet.
//!
//! A region is one interval per direction; inflating by `f` grows each
//! interval by `f` times its width, half on each side (the paper's 17 %
//! makes each side 8.5 % longer). A mesh triangle belongs to a grown region
//! when its centroid does, an instance when its box centre does: the same
//! rule that sent them to their own leaf, so a leaf's own geometry is always
//! inside its grown region too. The up direction is not bounded.

use glam::DVec3;
use rayon::prelude::*;

use super::objects::Collected;
use super::split::{Leaf, Region};

/// One leaf's geometry after inflation: its own first, then the borrowed,
/// each part sorted. Drawn as geometry a leaf draws only its own (every
/// triangle and placement is some leaf's own exactly once); its cached
/// image draws both.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Inflated {
    pub mesh: Vec<u32>,
    pub instances: Vec<u32>,
    /// How many of `mesh` are the leaf's own.
    pub own_mesh: usize,
    /// How many of `instances` are the leaf's own.
    pub own_instances: usize,
}

/// `region` grown by `fraction` of each interval's width.
pub fn grow(region: &Region, fraction: f64) -> Region {
    region
        .iter()
        .map(|&(lo, hi)| {
            let pad = (hi - lo).max(0.0) * fraction * 0.5;
            (lo - pad, hi + pad)
        })
        .collect()
}

/// Every leaf's geometry inside its region grown by `fraction`.
pub fn inflate(
    scene: &Collected,
    directions: &[DVec3],
    leaves: &[Leaf],
    fraction: f64,
) -> Vec<Inflated> {
    // Keys along each direction, and the triangles sorted along the first
    // so a region's candidates are one binary-searched run.
    let keys = |points: Vec<DVec3>| -> Vec<Vec<f64>> {
        directions
            .iter()
            .map(|d| points.iter().map(|p| d.dot(*p)).collect())
            .collect()
    };
    let tri_keys = keys(
        (0..scene.mesh.corners.len() as u32)
            .map(|t| scene.mesh.centroid(t))
            .collect(),
    );
    let inst_keys = keys(scene.placements.iter().map(|p| p.centre()).collect());
    let sorted = |keys: &[Vec<f64>]| {
        let n = keys.first().map_or(0, Vec::len);
        let mut order: Vec<u32> = (0..n as u32).collect();
        if let Some(first) = keys.first() {
            order.sort_unstable_by(|&a, &b| first[a as usize].total_cmp(&first[b as usize]));
        }
        order
    };
    let (tri_order, inst_order) = (sorted(&tri_keys), sorted(&inst_keys));
    let inside = |keys: &[Vec<f64>], region: &Region, i: u32| {
        region
            .iter()
            .zip(keys)
            .all(|(&(lo, hi), k)| (lo..=hi).contains(&k[i as usize]))
    };
    let within = |keys: &[Vec<f64>], order: &[u32], region: &Region| -> Vec<u32> {
        let Some((first, (lo, hi))) = keys.first().zip(region.first().copied()) else {
            return Vec::new();
        };
        let start = order.partition_point(|&i| first[i as usize] < lo);
        let end = order.partition_point(|&i| first[i as usize] <= hi);
        order[start..end.max(start)]
            .iter()
            .copied()
            .filter(|&i| inside(keys, region, i))
            .collect()
    };
    leaves
        .par_iter()
        .map(|leaf| {
            let grown = grow(&leaf.region, fraction);
            let (mesh, own_mesh) =
                own_then_borrowed(&leaf.mesh, within(&tri_keys, &tri_order, &grown));
            let (instances, own_instances) =
                own_then_borrowed(&leaf.instances, within(&inst_keys, &inst_order, &grown));
            Inflated {
                mesh,
                instances,
                own_mesh,
                own_instances,
            }
        })
        .collect()
}

/// `own` sorted, then the rest of `grown` sorted; and `own`'s length.
fn own_then_borrowed(own: &[u32], mut grown: Vec<u32>) -> (Vec<u32>, usize) {
    let mut list = own.to_vec();
    list.sort_unstable();
    list.dedup();
    grown.sort_unstable();
    grown.retain(|i| list.binary_search(i).is_err());
    let n = list.len();
    list.extend(grown);
    (list, n)
}
