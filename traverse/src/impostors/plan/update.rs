//! `UpdateCaches` and `UpdateNode`: cull, keep valid caches, and cache a
//! node when its amortized cost beats drawing its contents.

use farfield_protocol::bsp_codec::Split;

use super::super::atlas::Block;
use super::super::safety::{QuadPlane, Zone, safety_zone};
use super::screen::{quad_corners, screen_rect};
use super::{Cache, ImpostorCut, Planner, Status, Walk};
use super::{CacheJob, Candidate};
use crate::bsp::{box_corners, box_culled};

impl Planner {
    /// `UpdateCaches(node)`: returns nothing; fills the node's status,
    /// drawing cost and zone.
    pub(super) fn update_caches(&mut self, w: &mut Walk, n: u32, cut: &mut ImpostorCut) {
        let i = n as usize;
        let Some(node) = w.s.nodes.get(i).copied() else {
            return;
        };
        cut.visited += 1;
        if box_culled(&w.view, node.box_min, node.box_max) {
            cut.frustum_culled += 1;
            self.status[i] = Status::Cull;
            return;
        }
        if let Some(c) = self.caches[i].as_mut() {
            if c.zone.contains(w.camera.eye) {
                c.last_used = self.frame;
                self.status[i] = Status::DrawCache;
                self.cost[i] = w
                    .options
                    .costs
                    .quad_ms(u64::from(c.width) * u64::from(c.height));
                self.zone[i] = c.zone;
                return;
            }
            self.drop_cache(i);
        }
        if let Split::Plane { back, front, .. } = node.split {
            self.update_caches(w, back, cut);
            self.update_caches(w, front, cut);
        }
        self.update_node(w, n, cut);
    }

    /// `UpdateNode(node)`: cache the node, or draw its contents.
    fn update_node(&mut self, w: &mut Walk, n: u32, cut: &mut ImpostorCut) {
        let i = n as usize;
        let Some(node) = w.s.nodes.get(i).copied() else {
            return;
        };
        let costs = &w.options.costs;
        let (contents, children_zone, leaf) = match node.split {
            Split::Leaf { .. } => (costs.geometry_ms(node.triangles), Zone::EVERYWHERE, true),
            Split::Plane { back, front, .. } => {
                let (b, f) = (back as usize, front as usize);
                (
                    self.cost[b] + self.cost[f],
                    self.zone[b].intersect(&self.zone[f]),
                    false,
                )
            }
        };
        let fallback = if leaf {
            Status::DrawGeometry
        } else {
            Status::Recurse
        };
        self.status[i] = fallback;
        self.cost[i] = contents;
        self.zone[i] = children_zone;
        let Some(candidate) = self.candidate(w, n, children_zone) else {
            return;
        };
        // Making the cache draws the contents once more (a leaf's with
        // the inflation's borrowed part, estimated by the inflation).
        let drawn = if leaf {
            contents * (1.0 + f64::from(w.s.inflation).max(0.0))
        } else {
            contents
        };
        let [_, _, rw, rh] = candidate.rect.map(|v| v.max(1) as u32);
        let pixels = u64::from(rw) * u64::from(rh);
        let create = costs.create_ms(pixels, drawn);
        let amortized = create / f64::from(candidate.life.max(1)) + costs.quad_ms(pixels);
        if amortized >= contents || w.made >= w.options.max_caches_per_frame {
            return;
        }
        let Some(block) = self.allocate(rw + 2, rh + 2, cut) else {
            return;
        };
        w.made += 1;
        self.serial += 1;
        let serial = self.serial;
        // The contents, back to front, as they stand this frame.
        let start = cut.job_items.len();
        let mut missing = Vec::new();
        self.contents(w, n, true, cut, &mut missing);
        cut.jobs.push(CacheJob {
            node: n,
            serial,
            block,
            rect: candidate.rect,
            items: start..cut.job_items.len(),
        });
        cut.stats.caches_made += 1;
        self.caches[i] = Some(Cache {
            serial,
            block,
            width: rw,
            height: rh,
            corners: candidate.corners,
            quad: candidate.quad,
            zone: candidate.zone,
            missing,
            last_used: self.frame,
        });
        self.status[i] = Status::DrawCache;
        self.cost[i] = costs.quad_ms(pixels);
        self.zone[i] = candidate.zone;
    }

    /// Whether node `n` may be cached from here, and its rectangle, quad,
    /// zone and life span if so.
    fn candidate(&self, w: &Walk, n: u32, children_zone: Zone) -> Option<Candidate> {
        let node = w.s.nodes.get(n as usize)?;
        if w.epsilon <= 0.0 {
            return None;
        }
        let eye = w.camera.eye;
        // Never from inside (its box is the inflated region's bounds).
        if eye.cmpge(node.box_min).all() && eye.cmple(node.box_max).all() {
            return None;
        }
        let corners = box_corners(node.box_min, node.box_max);
        let rect = screen_rect(&w.view, &corners)?;
        let centre = (node.box_min + node.box_max) * 0.5;
        let quad = QuadPlane::new(eye, w.view.forward, centre)?;
        let zone = safety_zone(&quad, &corners, w.epsilon)?.intersect(&children_zone);
        let life = self.life_span(&zone, eye, w.options.life_cap);
        if life == 0 {
            return None;
        }
        Some(Candidate {
            corners: quad_corners(&w.view, rect, quad.depth),
            rect,
            quad,
            zone,
            life,
        })
    }

    /// A block for a `w` x `h` image, evicting the least recently used
    /// caches not drawn this frame until one is free.
    fn allocate(&mut self, w: u32, h: u32, cut: &mut ImpostorCut) -> Option<Block> {
        loop {
            let atlas = self.atlas.as_mut()?;
            atlas.side_for(w, h)?;
            if let Some(b) = atlas.allocate(w, h) {
                return Some(b);
            }
            let victim = self
                .caches
                .iter()
                .enumerate()
                .filter_map(|(i, c)| c.as_ref().map(|c| (c.last_used, i)))
                .filter(|&(used, _)| used < self.frame)
                .min()?;
            self.drop_cache(victim.1);
            cut.stats.evicted += 1;
        }
    }
}
