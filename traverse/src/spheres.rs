//! The reference traversal (QSplat 2.1): resident pages + camera -> a cut.
//!
//! Starting at the root, each node is frustum-culled (a node wholly inside
//! marks its subtree so no child is tested again), backface-culled by its
//! normal cone, and then either drawn as a splat (a leaf, small enough on
//! screen, or children not resident yet) or refined into its children.
//! Traversal neither draws nor fetches: it returns the splats and the pages
//! whose arrival would refine the picture, with a priority for each.

use glam::{DVec3, Vec3};

use farfield_protocol::camera::{Camera, Containment, View};
use farfield_protocol::directory::Locate;
use farfield_protocol::hierarchy::Hierarchy;
use farfield_protocol::sphere_codec::{self, NodeRecord};

use crate::wanted::{PageTracker, want_page_zero};
use farfield_protocol::messages::PageWish;

/// What to draw for one node.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Splat {
    pub center: DVec3,
    pub radius: f64,
    /// Unit normal, when the scene has normals.
    pub normal: Option<Vec3>,
    pub color: Option<[u8; 3]>,
    /// Breadth-first index of the node, for tests and statistics.
    pub node: u64,
}

/// Knobs of one traversal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TraverseOptions {
    /// Refine nodes whose projected diameter exceeds this many pixels.
    pub threshold_px: f64,
    /// Cull nodes whose normal cone faces wholly away from the eye.
    pub backface_culling: bool,
    /// Near-plane distance as a fraction of the root radius.
    pub near_fraction: f64,
    /// Fill [`Cut::touched_pages`] (for cache recency and overfetch).
    pub record_pages: bool,
}

impl Default for TraverseOptions {
    fn default() -> Self {
        Self {
            threshold_px: 1.0,
            backface_culling: true,
            near_fraction: 1e-4,
            record_pages: false,
        }
    }
}

/// The result of one traversal.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Cut {
    pub splats: Vec<Splat>,
    pub wanted: Vec<PageWish>,
    /// Nodes whose record was read.
    pub visited: u64,
    pub frustum_culled: u64,
    pub backface_culled: u64,
    /// With [`TraverseOptions::record_pages`]: every page a visited node
    /// lives in (the cut, its ancestors and culled siblings), ascending.
    pub touched_pages: Vec<u32>,
}

#[derive(Clone, Copy)]
struct Item {
    page: u32,
    local: u32,
    index: u64,
    center: DVec3,
    radius: f64,
    inside: bool,
    facing: bool,
}

/// Walks the resident part of `h` for one camera.
pub fn traverse(h: &Hierarchy, camera: &Camera, options: &TraverseOptions) -> Cut {
    let mut cut = Cut::default();
    traverse_into(h, camera, options, &mut cut);
    cut
}

/// [`traverse`] into a caller's [`Cut`], reusing its buffers: a renderer
/// traversing every frame then allocates nothing once warmed up.
pub fn traverse_into(h: &Hierarchy, camera: &Camera, options: &TraverseOptions, cut: &mut Cut) {
    let view = camera.view(h.header.root_radius * options.near_fraction);
    cut.splats.clear();
    cut.wanted.clear();
    cut.visited = 0;
    cut.frustum_culled = 0;
    cut.backface_culled = 0;
    cut.touched_pages.clear();
    // Another kind's pages keep no sphere records (a caller that picked
    // this traversal by name for another kind's file): nothing to walk.
    if h.header.kind != farfield_protocol::file::HierarchyKind::Spheres {
        return;
    }
    let mut pages = PageTracker::new(options.record_pages);
    // Table lookups hoisted out of the loop (each accessor checks a OnceLock).
    let spheres = sphere_codec::sphere_table();
    let normals = sphere_codec::normal_table();
    let decode = |c: DVec3, r: f64, code: u16| {
        let step = &spheres[usize::from(code)];
        (c + step.offset * r, step.radius * r)
    };
    if h.page(0).is_none() {
        want_page_zero(&mut cut.wanted);
        return;
    }
    let threshold = options.threshold_px.max(0.0);
    let cull_backfaces = options.backface_culling && h.layout.normals;
    let mut stack = vec![Item {
        page: 0,
        local: 0,
        index: 0,
        center: h.header.root_center,
        radius: h.header.root_radius,
        inside: false,
        facing: !cull_backfaces,
    }];
    // The root's own record may shrink it; decode it like any other node.
    if let Some(p) = h.page(0) {
        let rec = h.record(p, 0);
        let (c, r) = decode(h.header.root_center, h.header.root_radius, rec.sphere);
        stack[0].center = c;
        stack[0].radius = r;
    }
    while let Some(mut item) = stack.pop() {
        let Some(page) = h.page(item.page as usize) else {
            continue;
        };
        cut.visited += 1;
        pages.touch(item.page);
        if !item.inside {
            match view.classify(item.center, item.radius) {
                Containment::Outside => {
                    cut.frustum_culled += 1;
                    continue;
                }
                Containment::Inside => item.inside = true,
                Containment::Intersecting => {}
            }
        }
        let rec = h.record(page, item.local as usize);
        if !item.facing {
            match facing(&view, item.center, item.radius, &rec, normals) {
                Facing::Away => {
                    cut.backface_culled += 1;
                    continue;
                }
                Facing::Toward => item.facing = true,
                Facing::Either => {}
            }
        }
        let children = rec.children.get();
        let size = view.projected_diameter_px(item.center, item.radius);
        let mut draw = children == 0 || size <= threshold;
        if !draw {
            let first = Hierarchy::first_child(page, item.local as usize);
            match h.directory().locate(first) {
                Locate::Page(child_page_index) => match h.page(child_page_index as usize) {
                    Some(child_page) if Hierarchy::group_fits(child_page, first, children) => {
                        for c in 0..children as u64 {
                            let index = first + c;
                            let local = (index - child_page.header.first_node) as usize;
                            let child = h.record(child_page, local);
                            let (center, radius) = decode(item.center, item.radius, child.sphere);
                            stack.push(Item {
                                page: child_page_index,
                                local: local as u32,
                                index,
                                center,
                                radius,
                                ..item
                            });
                        }
                    }
                    Some(_) => draw = true,
                    None => {
                        draw = true;
                        let off_center = view.distance_from_center(item.center);
                        pages.want(child_page_index, size, off_center);
                    }
                },
                // The directory page that places the children first.
                Locate::Missing(directory) => {
                    draw = true;
                    pages.want(directory, size, view.distance_from_center(item.center));
                }
                Locate::Outside => draw = true,
            }
        }
        if draw {
            cut.splats.push(Splat {
                center: item.center,
                radius: item.radius,
                normal: h.layout.normals.then(|| normals[usize::from(rec.normal)]),
                color: h
                    .layout
                    .color
                    .then(|| sphere_codec::decode_color(rec.color)),
                node: item.index,
            });
        }
    }
    pages.finish(&mut cut.touched_pages, &mut cut.wanted);
}

enum Facing {
    Away,
    Toward,
    Either,
}

/// Normal-cone test: the directions from the sphere to the eye spread by
/// asin(r / d); the cone's normals spread by its half-angle. Away when every
/// such pair is more than 90 degrees apart, toward when every pair is less.
/// With `slack` = cone + asin(r/d), away means cos(angle) < -sin(slack) and
/// toward means cos(angle) > sin(slack); sin(slack) comes from the sum
/// formula, so the test needs one square root and no trigonometry.
fn facing(view: &View, center: DVec3, radius: f64, rec: &NodeRecord, normals: &[Vec3]) -> Facing {
    if rec.cone == 3 {
        return Facing::Either;
    }
    let to_eye = view.eye - center;
    let d2 = to_eye.length_squared();
    if d2 <= radius * radius {
        return Facing::Either;
    }
    let d = d2.sqrt();
    let q = radius / d;
    let cos_q = (1.0 - q * q).sqrt();
    let sin_cone = sphere_codec::CONE_SINES[usize::from(rec.cone)];
    let cos_cone = (1.0 - sin_cone * sin_cone).sqrt();
    // slack >= 90 degrees: nothing can be concluded.
    if cos_cone * cos_q - sin_cone * q <= 0.0 {
        return Facing::Either;
    }
    let sin_slack = sin_cone * cos_q + cos_cone * q;
    let cos_angle = f64::from(normals[usize::from(rec.normal)].dot((to_eye / d).as_vec3()));
    // A hair of margin for the f32 normal: culling must never drop a visible node.
    if cos_angle < -sin_slack - 1e-6 {
        Facing::Away
    } else if cos_angle > sin_slack {
        Facing::Toward
    } else {
        Facing::Either
    }
}

/// Registers the sphere traversal (see [`crate::KINDS`]).
pub const REGISTERED: crate::Registered = crate::Registered {
    name: "spheres",
    hierarchy: farfield_protocol::file::HierarchyKind::Spheres,
    params: &["threshold", "kernel"],
    reference_threshold_px: 1.0,
    reference: "the sphere hierarchy at 1 px",

    adaptive_threshold: true,
    measures_costs: false,
    make: || Box::new(SphereTraversal::default()),
};

/// [`traverse_into`] behind the [`crate::Traversal`] seam, with its last cut.
#[derive(Debug, Default)]
pub struct SphereTraversal {
    pub cut: Cut,
}

impl crate::Traversal for SphereTraversal {
    fn registered(&self) -> &'static crate::Registered {
        &REGISTERED
    }

    fn traverse(&mut self, h: &Hierarchy, camera: &Camera, options: &crate::TraversalOptions) {
        let options = TraverseOptions {
            threshold_px: options.threshold_px,
            record_pages: options.record_pages,
            ..TraverseOptions::default()
        };
        traverse_into(h, camera, &options, &mut self.cut);
    }

    fn draw_list(&self) -> crate::DrawList<'_> {
        crate::DrawList::Splats(&self.cut.splats)
    }

    fn wanted(&self) -> &[PageWish] {
        &self.cut.wanted
    }

    fn touched_pages(&self) -> &[u32] {
        &self.cut.touched_pages
    }

    fn counts(&self) -> crate::Counts {
        crate::Counts {
            visited: self.cut.visited,
            drawn: self.cut.splats.len() as u64,
            frustum_culled: self.cut.frustum_culled,
            backface_culled: self.cut.backface_culled,
        }
    }
}
