//! Hierarchical frustum culling over image caching's BSP by gaps: the
//! baseline the impostor cache is measured against (Shade et al., section
//! 5: "the same walkthrough drawn with hierarchical culling alone").
//!
//! The skeleton (page 0) is walked from the root. A node whose box lies
//! wholly outside the view is culled with everything under it; a split's
//! two sides are visited far side first, so leaves come out back to front
//! (the order impostors are composited in, and the order a cached quad
//! must be drawn among geometry). A visible leaf draws its *own* geometry:
//! the borrowed part stored for inflation belongs to a neighbour's own
//! and would be drawn twice. Each own placement is culled by its
//! prototype's box carried into the world.
//!
//! Streamed: a visible leaf whose page is missing is wanted with the
//! priority of its projected size; a resident leaf's placements want
//! their prototypes' pages with the leaf's priority. Nothing of a missing
//! page is drawn.

use glam::{DAffine3, DVec3};

use farfield_protocol::bsp_codec::{BspSkeleton, ContentPage, LeafPage, Split};
use farfield_protocol::camera::{Camera, View};
use farfield_protocol::file::HierarchyKind;
use farfield_protocol::hierarchy::{BspPage, Hierarchy};

use crate::Counts;
use crate::wanted::{PageTracker, want_page_zero};
use farfield_protocol::messages::PageWish;

/// A leaf drawn as geometry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LeafDraw {
    pub leaf: u32,
    /// Its page (resident).
    pub page: u32,
}

/// One placement of a prototype to draw.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InstanceDraw {
    /// The prototype's page (resident).
    pub prototype_page: u32,
    /// World from the prototype's frame.
    pub world_from_local: DAffine3,
}

/// The result of one culling traversal.
#[derive(Debug, Clone, Default)]
pub struct BspCut {
    /// Leaves whose own triangles are drawn, back to front.
    pub leaves: Vec<LeafDraw>,
    /// Placements in view whose prototype is resident, in leaf order.
    pub instances: Vec<InstanceDraw>,
    pub wanted: Vec<PageWish>,
    pub touched_pages: Vec<u32>,
    /// BSP nodes visited.
    pub visited: u64,
    /// Triangles to draw: leaves' own, and instances' counted whole.
    pub triangles: u64,
    /// Nodes and placements culled by the frustum.
    pub frustum_culled: u64,
}

/// A box's eight corners.
pub fn box_corners(min: DVec3, max: DVec3) -> [DVec3; 8] {
    std::array::from_fn(|i| {
        DVec3::new(
            if i & 1 == 0 { min.x } else { max.x },
            if i & 2 == 0 { min.y } else { max.y },
            if i & 4 == 0 { min.z } else { max.z },
        )
    })
}

/// Whether the box is empty (a node that draws nothing) or wholly out of
/// view.
pub fn box_culled(view: &View, min: DVec3, max: DVec3) -> bool {
    !(min.cmple(max).all()) || view.all_outside(&box_corners(min, max))
}

/// Whether the eye is on the front side (above the plane) of a split.
pub fn eye_in_front(
    s: &BspSkeleton,
    origin: DVec3,
    eye: DVec3,
    direction: u8,
    offset: f64,
) -> bool {
    s.directions
        .get(direction as usize)
        .is_some_and(|d| d.dot(eye - origin) > offset)
}

/// A node's priority for its pages: its box's projected diameter, and how
/// far off-centre it is.
pub fn node_priority(view: &View, min: DVec3, max: DVec3) -> (f64, f64) {
    let centre = (min + max) * 0.5;
    let radius = (max - min).length() * 0.5;
    (
        // A box that is one point still wants its page.
        view.projected_diameter_px(centre, radius).max(1e-6),
        view.distance_from_center(centre),
    )
}

/// A resident leaf page, if `page` is one.
pub fn leaf_page(h: &Hierarchy, page: u32) -> Option<&LeafPage> {
    match h.page(page as usize)?.bsp()? {
        BspPage::Content(ContentPage::Leaf(l)) => Some(l),
        _ => None,
    }
}

/// Walks the skeleton for `camera`, culling by the frustum, into `cut`.
pub fn traverse_bsp_into(h: &Hierarchy, camera: &Camera, record_pages: bool, cut: &mut BspCut) {
    cut.leaves.clear();
    cut.instances.clear();
    cut.wanted.clear();
    cut.touched_pages.clear();
    cut.visited = 0;
    cut.triangles = 0;
    cut.frustum_culled = 0;
    if h.header.kind != HierarchyKind::Bsp {
        return;
    }
    let Some(s) = h.bsp_skeleton() else {
        want_page_zero(&mut cut.wanted);
        return;
    };
    let view = camera.view(1e-9);
    let origin = h.header.root_center;
    let mut pages = PageTracker::new(record_pages);
    pages.touch(0);
    let mut stack = vec![0u32];
    while let Some(n) = stack.pop() {
        let Some(node) = s.nodes.get(n as usize) else {
            continue;
        };
        cut.visited += 1;
        if box_culled(&view, node.box_min, node.box_max) {
            cut.frustum_culled += 1;
            continue;
        }
        match node.split {
            Split::Plane {
                direction,
                offset,
                back,
                front,
            } => {
                // Popped last is drawn last: push the near side first.
                if eye_in_front(s, origin, camera.eye, direction, offset) {
                    stack.extend([front, back]);
                } else {
                    stack.extend([back, front]);
                }
            }
            Split::Leaf { leaf } => {
                let page = s.leaf_page(leaf);
                let (size, off) = node_priority(&view, node.box_min, node.box_max);
                match leaf_page(h, page) {
                    Some(content) => {
                        pages.touch(page);
                        cut.leaves.push(LeafDraw { leaf, page });
                        cut.triangles += u64::from(content.own_triangles);
                        let mut sink = InstanceSink {
                            instances: &mut cut.instances,
                            culled: 0,
                            triangles: 0,
                            missing: Vec::new(),
                        };
                        let own = content.own_placements as usize;
                        add_instances(h, s, Some(&view), content, own, &mut pages, &mut sink);
                        cut.frustum_culled += sink.culled;
                        cut.triangles += sink.triangles;
                        for page in sink.missing {
                            pages.want(page, size, off);
                        }
                    }
                    None => pages.want(page, size, off),
                }
            }
        }
    }
    pages.finish(&mut cut.touched_pages, &mut cut.wanted);
}

/// Where a leaf's placements go: what to draw, and what is culled.
#[derive(Debug)]
pub struct InstanceSink<'a> {
    pub instances: &'a mut Vec<InstanceDraw>,
    /// Placements culled by the frustum.
    pub culled: u64,
    /// Triangles of the placements drawn.
    pub triangles: u64,
    /// Prototype pages wanted and not resident.
    pub missing: Vec<u32>,
}

/// The leaf's first `count` placements (its own, or all of them with the
/// borrowed): drawn when their prototype is resident and (with `view`)
/// they are in view; their prototype pages touched, or missing.
pub fn add_instances(
    h: &Hierarchy,
    s: &BspSkeleton,
    view: Option<&View>,
    leaf: &LeafPage,
    count: usize,
    pages: &mut PageTracker,
    sink: &mut InstanceSink,
) {
    for p in leaf.placements.iter().take(count) {
        let Some(info) = s.prototypes.get(p.prototype as usize) else {
            continue;
        };
        let world_from_local = p.world_from_local(leaf.anchor);
        if let Some(view) = view {
            let corners = box_corners(info.box_min, info.box_max)
                .map(|c| world_from_local.transform_point3(c));
            if view.all_outside(&corners) {
                sink.culled += 1;
                continue;
            }
        }
        let page = BspSkeleton::prototype_page(p.prototype);
        if h.is_resident(page as usize) {
            pages.touch(page);
            sink.instances.push(InstanceDraw {
                prototype_page: page,
                world_from_local,
            });
            sink.triangles += u64::from(info.triangles);
        } else {
            sink.missing.push(page);
        }
    }
}

/// Registers the culling baseline (see [`crate::KINDS`]).
pub const CULLING: crate::Registered = crate::Registered {
    name: "culling",
    hierarchy: HierarchyKind::Bsp,
    // Nothing to sweep: the threshold is accepted and changes nothing.
    params: &["threshold"],
    reference_threshold_px: 0.0,
    reference: "every leaf in view as geometry",
    adaptive_threshold: false,
    measures_costs: false,
    make: || Box::new(CullingTraversal::default()),
};

/// [`traverse_bsp_into`] behind the [`crate::Traversal`] seam.
#[derive(Debug, Default)]
pub struct CullingTraversal {
    pub cut: BspCut,
}

impl crate::Traversal for CullingTraversal {
    fn registered(&self) -> &'static crate::Registered {
        &CULLING
    }

    fn traverse(&mut self, h: &Hierarchy, camera: &Camera, options: &crate::TraversalOptions) {
        traverse_bsp_into(h, camera, options.record_pages, &mut self.cut);
    }

    fn draw_list(&self) -> crate::DrawList<'_> {
        crate::DrawList::Bsp(&self.cut)
    }

    fn wanted(&self) -> &[PageWish] {
        &self.cut.wanted
    }

    fn touched_pages(&self) -> &[u32] {
        &self.cut.touched_pages
    }

    fn counts(&self) -> Counts {
        Counts {
            visited: self.cut.visited,
            drawn: self.cut.triangles,
            frustum_culled: self.cut.frustum_culled,
            backface_culled: 0,
        }
    }
}
