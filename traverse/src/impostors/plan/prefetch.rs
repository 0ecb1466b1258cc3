//! The pages a frame asks for beyond what it draws (the paper's
//! pre-caching, section 2): those of drawn caches whose zone the viewer
//! leaves soon, and those of leaves about to enter the view. Both are
//! wanted below anything the frame itself needs, so they only use
//! bandwidth the frame leaves free.

use farfield_protocol::bsp_codec::{BspSkeleton, Split};
use farfield_protocol::camera::Camera;

use super::{Planner, Status, Walk};
use crate::bsp::{box_culled, leaf_page, node_priority};

/// How much a wanted page ranks below the frame's own: a prefetched
/// page's projected size is scaled by this.
const PRECACHE_RANK: f64 = 1e-3;
/// Leaves about to enter the view rank below expiring caches.
const ENTERING_RANK: f64 = 1e-4;

impl Planner {
    /// Pre-caching: the pages of caches drawn this frame whose zone the
    /// viewer leaves soon, wanted at a low priority, so the geometry is
    /// resident when they must be made again; those already resident (and
    /// their leaves' prototypes) are touched, so a small page cache does
    /// not let them lapse just before they are needed.
    pub(super) fn precache(&self, w: &mut Walk) {
        for (i, c) in self.caches.iter().enumerate() {
            let Some(c) = c else { continue };
            if self.status[i] != Status::DrawCache {
                continue;
            }
            let life = self.life_span(&c.zone, w.camera.eye, w.options.life_cap);
            if life > w.options.precache_frames {
                continue;
            }
            self.want_leaves_under(w, i as u32, PRECACHE_RANK);
        }
    }

    /// The leaves the view will hold in `precache_frames` frames (the eye
    /// carried along its motion, the frustum widened by
    /// `entering_margin` for turns) that it culls now: their pages are
    /// wanted, nearest first, at most `entering_pages` a frame.
    pub(super) fn entering(&self, w: &mut Walk) {
        let o = w.options;
        // A margin under 1 (or NaN) would look for leaves in a narrower view.
        if o.entering_pages == 0 || o.entering_margin.is_nan() || o.entering_margin < 1.0 {
            return;
        }
        let ahead = f64::from(o.precache_frames);
        let eye = w.camera.eye + self.velocity * ahead + self.acceleration * (0.5 * ahead * ahead);
        let half = (w.camera.fov_y_deg.clamp(1.0, 170.0) * 0.5).to_radians();
        let widened = (half.tan() * o.entering_margin).atan().to_degrees() * 2.0;
        let future = Camera {
            eye,
            // The same direction, carried along.
            target: w.camera.target + (eye - w.camera.eye),
            fov_y_deg: widened.min(175.0),
            ..*w.camera
        }
        .view(1e-9);
        // (distance from the future eye, page, its priority there).
        let mut found: Vec<(f64, u32, (f64, f64))> = Vec::new();
        let mut stack = vec![0u32];
        while let Some(n) = stack.pop() {
            let Some(node) = w.s.nodes.get(n as usize).copied() else {
                continue;
            };
            if box_culled(&future, node.box_min, node.box_max) {
                continue;
            }
            match node.split {
                Split::Leaf { leaf } => {
                    let page = w.s.leaf_page(leaf);
                    let now_culled = box_culled(&w.view, node.box_min, node.box_max);
                    if now_culled && !w.h.is_resident(page as usize) {
                        let distance = ((node.box_min + node.box_max) * 0.5 - eye).length();
                        let priority = node_priority(&future, node.box_min, node.box_max);
                        found.push((distance, page, priority));
                    }
                }
                Split::Plane { back, front, .. } => stack.extend([back, front]),
            }
        }
        found.sort_by(|a, b| a.0.total_cmp(&b.0));
        for &(_, page, (size, off)) in found.iter().take(o.entering_pages) {
            w.pages.want(page, size * ENTERING_RANK, off);
        }
    }

    /// Wants the pages of the leaves under node `n` that are not resident,
    /// and touches those that are (with their prototypes' pages).
    fn want_leaves_under(&self, w: &mut Walk, n: u32, rank: f64) {
        let mut stack = vec![n];
        while let Some(n) = stack.pop() {
            let Some(node) = w.s.nodes.get(n as usize).copied() else {
                continue;
            };
            match node.split {
                Split::Leaf { leaf } => {
                    let page = w.s.leaf_page(leaf);
                    let (size, off) = node_priority(&w.view, node.box_min, node.box_max);
                    let Some(content) = leaf_page(w.h, page) else {
                        w.pages.want(page, size * rank, off);
                        continue;
                    };
                    w.pages.touch(page);
                    for p in &content.placements {
                        let proto = BspSkeleton::prototype_page(p.prototype);
                        if w.h.is_resident(proto as usize) {
                            w.pages.touch(proto);
                        } else {
                            w.pages.want(proto, size * rank, off);
                        }
                    }
                }
                Split::Plane { back, front, .. } => stack.extend([back, front]),
            }
        }
    }
}
