//! The recursion of section 4: place a plane in the best gap, recurse on
//! each side; split only the objects the plane crosses.
//!
//! A crossed mesh (the terrain) is divided by its triangles' centroids; a
//! crossed instance is never split and goes, whole, to the side holding
//! its box's centre (its geometry then overhangs the plane a little; the
//! node boxes bound what is really there). When no gap leaves an object
//! wholly on each side (identical or nested extents, or one big mesh),
//! the **median fallback** cuts the elements (instances by their centres,
//! mesh triangles by their centroids), sorted along the direction of
//! greatest extent, at their primitive-weighted median, and always leaves
//! at least one on each side: every split makes progress, so the
//! recursion ends.

use glam::DVec3;

use super::gaps::{ASPECT_WEIGHT, Extent, best_gap};
use super::objects::{Collected, Content};

/// A node's region: one interval per direction (every plane is
/// perpendicular to one of them, so a region is an intersection of slabs).
pub type Region = Vec<(f64, f64)>;

/// When to stop splitting.
#[derive(Debug, Clone, Copy)]
pub struct StopRule {
    /// A node with at most this many instances...
    pub leaf_instances: usize,
    /// ...and at most this many mesh triangles is a leaf.
    pub leaf_triangles: u64,
    pub max_depth: u32,
}

/// A node of the tree as built (preorder: children after parents).
#[derive(Debug, Clone, PartialEq)]
pub enum Built {
    Leaf(u32),
    Plane {
        direction: usize,
        /// `direction · p = offset` (world).
        offset: f64,
        back: u32,
        front: u32,
    },
}

/// A leaf's own objects (before inflation).
#[derive(Debug, Clone, Default)]
pub struct Leaf {
    pub mesh: Vec<u32>,
    pub instances: Vec<u32>,
    pub region: Region,
}

/// How the tree was made.
#[derive(Debug, Clone, Copy, Default, serde::Serialize)]
pub struct SplitCounts {
    /// Planes placed in a gap between objects.
    pub gaps: u64,
    /// Planes placed by the median fallback.
    pub medians: u64,
    /// Meshes divided between two sides.
    pub meshes_split: u64,
    /// Instances a plane crossed (kept whole, on their centre's side).
    pub instances_crossed: u64,
    pub depth: u32,
}

/// The tree.
#[derive(Debug, Default)]
pub struct Tree {
    pub nodes: Vec<Built>,
    pub leaves: Vec<Leaf>,
    pub counts: SplitCounts,
}

struct Builder<'a> {
    scene: &'a Collected,
    directions: &'a [DVec3],
    rule: StopRule,
    tree: Tree,
}

/// Builds the BSP of `scene`'s objects along `directions`.
pub fn split(scene: &Collected, directions: &[DVec3], rule: StopRule) -> Tree {
    let mut b = Builder {
        scene,
        directions,
        rule,
        tree: Tree::default(),
    };
    let objects = scene.objects.clone();
    let region: Region = (0..directions.len())
        .map(|k| {
            objects
                .iter()
                .map(|o| b.extent(o, k))
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), e| {
                    (lo.min(e.lo), hi.max(e.hi))
                })
        })
        .collect();
    b.node(objects, region, 0);
    b.tree
}

impl Builder<'_> {
    fn project(&self, p: DVec3, k: usize) -> f64 {
        self.directions[k].dot(p)
    }

    fn extent(&self, o: &Content, k: usize) -> Extent {
        match o {
            Content::Instance(i) => {
                let p = &self.scene.placements[*i as usize];
                let (lo, hi) = box_extent(self.directions[k], p.box_min, p.box_max);
                Extent {
                    lo,
                    hi,
                    primitives: p.triangles,
                }
            }
            Content::Mesh(tris) => {
                let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
                for &t in tris {
                    for c in self.scene.mesh.corners[t as usize] {
                        let x = self.project(c, k);
                        lo = lo.min(x);
                        hi = hi.max(x);
                    }
                }
                Extent {
                    lo,
                    hi,
                    primitives: tris.len() as u64,
                }
            }
        }
    }

    /// The position along `k` by which an element goes to a side.
    fn instance_key(&self, i: u32, k: usize) -> f64 {
        self.project(self.scene.placements[i as usize].centre(), k)
    }

    fn triangle_key(&self, t: u32, k: usize) -> f64 {
        self.project(self.scene.mesh.centroid(t), k)
    }

    fn node(&mut self, objects: Vec<Content>, region: Region, depth: u32) -> u32 {
        let index = self.tree.nodes.len() as u32;
        self.tree.counts.depth = self.tree.counts.depth.max(depth);
        self.tree.nodes.push(Built::Leaf(0));
        let instances = objects
            .iter()
            .filter(|o| matches!(o, Content::Instance(_)))
            .count();
        let triangles: u64 = objects
            .iter()
            .map(|o| match o {
                Content::Mesh(t) => t.len() as u64,
                Content::Instance(_) => 0,
            })
            .sum();
        let small = instances <= self.rule.leaf_instances && triangles <= self.rule.leaf_triangles;
        let elements = instances as u64 + triangles;
        let parts = if small || depth >= self.rule.max_depth || elements < 2 {
            None
        } else {
            self.cut(&objects)
        };
        let Some((k, offset, back, front)) = parts else {
            self.leaf(index, objects, region);
            return index;
        };
        let (mut back_region, mut front_region) = (region.clone(), region);
        back_region[k].1 = offset;
        front_region[k].0 = offset;
        let back = self.node(back, back_region, depth + 1);
        let front = self.node(front, front_region, depth + 1);
        self.tree.nodes[index as usize] = Built::Plane {
            direction: k,
            offset,
            back,
            front,
        };
        index
    }

    fn leaf(&mut self, index: u32, objects: Vec<Content>, region: Region) {
        let mut leaf = Leaf {
            region,
            ..Leaf::default()
        };
        for o in objects {
            match o {
                Content::Mesh(t) => leaf.mesh.extend(t),
                Content::Instance(i) => leaf.instances.push(i),
            }
        }
        self.tree.nodes[index as usize] = Built::Leaf(self.tree.leaves.len() as u32);
        self.tree.leaves.push(leaf);
    }

    /// The plane and the two sides, both non-empty; `None` when the
    /// objects cannot be told apart at all.
    #[allow(clippy::type_complexity)]
    fn cut(&mut self, objects: &[Content]) -> Option<(usize, f64, Vec<Content>, Vec<Content>)> {
        let extents: Vec<Vec<Extent>> = (0..self.directions.len())
            .map(|k| objects.iter().map(|o| self.extent(o, k)).collect())
            .collect();
        let spread: Vec<f64> = extents
            .iter()
            .map(|es| {
                let lo = es.iter().map(|e| e.lo).fold(f64::INFINITY, f64::min);
                let hi = es.iter().map(|e| e.hi).fold(f64::NEG_INFINITY, f64::max);
                (hi - lo).max(0.0)
            })
            .collect();
        let widest = spread.iter().copied().fold(0.0, f64::max);
        let mut best: Option<(f64, usize, f64)> = None;
        for (k, es) in extents.iter().enumerate() {
            let Some(gap) = best_gap(es) else { continue };
            let aspect = if widest > 0.0 {
                ASPECT_WEIGHT * (1.0 - spread[k] / widest)
            } else {
                0.0
            };
            let cost = gap.cost + aspect;
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, k, gap.plane));
            }
        }
        if let Some((_, k, plane)) = best {
            self.tree.counts.gaps += 1;
            let (back, front) = self.by_plane(objects, &extents[k], k, plane);
            return Some((k, plane, back, front));
        }
        // The direction of greatest extent (the first, if all are equal).
        let k = (0..spread.len())
            .max_by(|&a, &b| spread[a].total_cmp(&spread[b]).then(b.cmp(&a)))
            .unwrap_or(0);
        self.tree.counts.medians += 1;
        self.by_median(objects, k)
    }

    /// Objects wholly behind or in front go whole; crossed ones are split
    /// (meshes) or sent by their centre (instances).
    fn by_plane(
        &mut self,
        objects: &[Content],
        extents: &[Extent],
        k: usize,
        plane: f64,
    ) -> (Vec<Content>, Vec<Content>) {
        let (mut back, mut front) = (Vec::new(), Vec::new());
        for (o, e) in objects.iter().zip(extents) {
            if e.hi <= plane {
                back.push(o.clone());
            } else if e.lo >= plane {
                front.push(o.clone());
            } else {
                match o {
                    Content::Instance(i) => {
                        self.tree.counts.instances_crossed += 1;
                        if self.instance_key(*i, k) < plane {
                            back.push(o.clone());
                        } else {
                            front.push(o.clone());
                        }
                    }
                    Content::Mesh(tris) => {
                        let (b, f): (Vec<u32>, Vec<u32>) =
                            tris.iter().partition(|&&t| self.triangle_key(t, k) < plane);
                        if !b.is_empty() && !f.is_empty() {
                            self.tree.counts.meshes_split += 1;
                        }
                        if !b.is_empty() {
                            back.push(Content::Mesh(b));
                        }
                        if !f.is_empty() {
                            front.push(Content::Mesh(f));
                        }
                    }
                }
            }
        }
        (back, front)
    }

    /// The weighted-median cut along `k`.
    #[allow(clippy::type_complexity)]
    fn by_median(
        &mut self,
        objects: &[Content],
        k: usize,
    ) -> Option<(usize, f64, Vec<Content>, Vec<Content>)> {
        // (position, weight, object, triangle or u32::MAX for an instance)
        let mut elements: Vec<(f64, u64, usize, u32)> = Vec::new();
        for (o, object) in objects.iter().enumerate() {
            match object {
                Content::Instance(i) => {
                    let p = &self.scene.placements[*i as usize];
                    elements.push((self.instance_key(*i, k), p.triangles.max(1), o, u32::MAX));
                }
                Content::Mesh(tris) => {
                    elements.extend(tris.iter().map(|&t| (self.triangle_key(t, k), 1, o, t)));
                }
            }
        }
        if elements.len() < 2 {
            return None;
        }
        // Stable: equal positions keep the objects' order.
        elements.sort_by(|a, b| a.0.total_cmp(&b.0));
        let total: u64 = elements.iter().map(|e| e.1).sum();
        let mut sum = 0u64;
        let mut at = elements.len() - 1;
        for (i, e) in elements.iter().enumerate() {
            sum += e.1;
            if sum * 2 >= total {
                at = i + 1;
                break;
            }
        }
        let at = at.clamp(1, elements.len() - 1);
        let plane = 0.5 * (elements[at - 1].0 + elements[at].0);
        let side = |part: &[(f64, u64, usize, u32)]| {
            let mut meshes: Vec<Vec<u32>> = vec![Vec::new(); objects.len()];
            let mut out = Vec::new();
            for &(_, _, o, t) in part {
                match objects[o] {
                    Content::Instance(_) => out.push(objects[o].clone()),
                    Content::Mesh(_) => meshes[o].push(t),
                }
            }
            out.extend(
                meshes
                    .into_iter()
                    .filter(|m| !m.is_empty())
                    .map(Content::Mesh),
            );
            out
        };
        let (back, front) = (side(&elements[..at]), side(&elements[at..]));
        Some((k, plane, back, front))
    }
}

/// A box's extent along a unit direction.
pub fn box_extent(d: DVec3, min: DVec3, max: DVec3) -> (f64, f64) {
    let centre = (min + max) * 0.5;
    let half = (max - min) * 0.5;
    let c = d.dot(centre);
    let r = d.abs().dot(half);
    (c - r, c + r)
}
