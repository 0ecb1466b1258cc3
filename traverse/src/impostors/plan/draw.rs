//! What is drawn: a cache's contents (for the renderer to make it) and
//! the frame's items back to front (`Render`).

use farfield_protocol::bsp_codec::Split;

use super::{ImpostorCut, Item, Planner, Status, Walk, quad_item};
use crate::bsp::{InstanceSink, add_instances, eye_in_front, leaf_page, node_priority};

impl Planner {
    /// Appends node `n`'s contents to the job items, back to front: its
    /// children's caches and leaves (a leaf cached itself draws `all`).
    pub(super) fn contents(
        &mut self,
        w: &mut Walk,
        n: u32,
        top: bool,
        cut: &mut ImpostorCut,
        missing: &mut Vec<u32>,
    ) {
        let i = n as usize;
        let Some(node) = w.s.nodes.get(i).copied() else {
            return;
        };
        if !top && self.status[i] == Status::DrawCache {
            if let Some(c) = &self.caches[i] {
                missing.extend(&c.missing);
                cut.job_items.push(quad_item(n, c));
            }
            return;
        }
        match node.split {
            Split::Leaf { leaf } => {
                let page = w.s.leaf_page(leaf);
                let (size, off) = node_priority(&w.view, node.box_min, node.box_max);
                let Some(content) = leaf_page(w.h, page) else {
                    w.pages.want(page, size, off);
                    missing.push(page);
                    return;
                };
                w.pages.touch(page);
                let first = cut.instances.len() as u32;
                let all = top;
                let count = if all {
                    content.placements.len()
                } else {
                    content.own_placements as usize
                };
                let mut sink = InstanceSink {
                    instances: &mut cut.instances,
                    culled: 0,
                    triangles: 0,
                    missing: Vec::new(),
                };
                add_instances(w.h, w.s, None, content, count, &mut w.pages, &mut sink);
                for p in sink.missing {
                    w.pages.want(p, size, off);
                    missing.push(p);
                }
                cut.job_items.push(Item::Leaf {
                    leaf,
                    page,
                    all,
                    instances: first..cut.instances.len() as u32,
                });
            }
            Split::Plane {
                direction,
                offset,
                back,
                front,
            } => {
                let origin = w.h.header.root_center;
                let (far, near) = if eye_in_front(w.s, origin, w.camera.eye, direction, offset) {
                    (back, front)
                } else {
                    (front, back)
                };
                self.contents(w, far, false, cut, missing);
                self.contents(w, near, false, cut, missing);
            }
        }
    }

    /// `Render(node)`: the frame's items, back to front.
    pub(super) fn render(&mut self, w: &mut Walk, n: u32, cut: &mut ImpostorCut) {
        let i = n as usize;
        let Some(node) = w.s.nodes.get(i).copied() else {
            return;
        };
        match self.status[i] {
            Status::Cull => {}
            Status::DrawCache => {
                if let Some(c) = &self.caches[i] {
                    cut.items.push(quad_item(n, c));
                    cut.stats.caches_drawn += 1;
                }
            }
            Status::DrawGeometry => {
                let Split::Leaf { leaf } = node.split else {
                    return;
                };
                let page = w.s.leaf_page(leaf);
                let (size, off) = node_priority(&w.view, node.box_min, node.box_max);
                let Some(content) = leaf_page(w.h, page) else {
                    w.pages.want(page, size, off);
                    return;
                };
                w.pages.touch(page);
                let first = cut.instances.len() as u32;
                let mut sink = InstanceSink {
                    instances: &mut cut.instances,
                    culled: 0,
                    triangles: 0,
                    missing: Vec::new(),
                };
                let own = content.own_placements as usize;
                add_instances(
                    w.h,
                    w.s,
                    Some(&w.view),
                    content,
                    own,
                    &mut w.pages,
                    &mut sink,
                );
                cut.frustum_culled += sink.culled;
                cut.stats.geometry_triangles += u64::from(content.own_triangles) + sink.triangles;
                for p in sink.missing {
                    w.pages.want(p, size, off);
                }
                cut.stats.leaves_as_geometry += 1;
                cut.items.push(Item::Leaf {
                    leaf,
                    page,
                    all: false,
                    instances: first..cut.instances.len() as u32,
                });
            }
            Status::Recurse => {
                let Split::Plane {
                    direction,
                    offset,
                    back,
                    front,
                } = node.split
                else {
                    return;
                };
                let origin = w.h.header.root_center;
                if eye_in_front(w.s, origin, w.camera.eye, direction, offset) {
                    self.render(w, back, cut);
                    self.render(w, front, cut);
                } else {
                    self.render(w, front, cut);
                    self.render(w, back, cut);
                }
            }
        }
    }
}
