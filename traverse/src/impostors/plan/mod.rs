//! The paper's two traversals a frame (section 2): `UpdateCaches` (cull,
//! keep the caches still valid, and decide per node by `UpdateNode`'s cost
//! comparison whether to make one) and `Render` (back to front: culled
//! nodes skipped, cached ones as one quad, leaves as geometry, the rest
//! recursed). The planner decides and lays out; the renderer makes the
//! caches it is told to (in the order given: children before parents) and
//! draws the items.
//!
//! Choices where the paper is silent or where this does more:
//! - A node is cached only when its screen rectangle is no larger than
//!   the viewport (the paper: "if the dimensions of the rectangle exceed
//!   those of the viewport, no image is cached") and every corner is in
//!   front of the eye. A rectangle partly off the screen is drawn whole:
//!   children the frustum culled are drawn into the cache as geometry.
//! - Validity is the eye inside the cache's zone, intersected with the
//!   zones of the children's caches it was drawn from; geometry drawn
//!   exactly asks nothing of an enclosing cache.
//! - Caches of nodes that leave the view stay in the atlas while valid
//!   (the paper's "persistent caches"), until evicted least recently used.
//! - A cache made while some of its pages were missing is *coarse*: it
//!   remembers the pages and is made again once any of them arrives.
//! - At most `max_caches_per_frame` caches are made a frame, so the first
//!   frame, which would make them all, never stalls.

mod draw;
mod life;
mod prefetch;
mod screen;
mod update;

pub use screen::{quad_corners, screen_rect};

use glam::DVec3;

use farfield_protocol::bsp_codec::BspSkeleton;
use farfield_protocol::camera::{Camera, View};
use farfield_protocol::file::HierarchyKind;
use farfield_protocol::hierarchy::Hierarchy;

use super::atlas::{Atlas, Block};
use super::cost::CostModel;
use super::safety::{QuadPlane, Zone, epsilon_angle};
use crate::bsp::InstanceDraw;
use crate::wanted::{PageTracker, want_page_zero};
use farfield_protocol::messages::PageWish;

/// Knobs of the impostor planner.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImpostorOptions {
    /// ε in pixels (turned into an angle from the view).
    pub epsilon_px: f64,
    pub costs: CostModel,
    /// Caches made in one frame at most.
    pub max_caches_per_frame: usize,
    /// The atlas's side in texels (its bytes are the texture budget).
    pub atlas_side: u32,
    /// The longest life span counted, in frames (a viewer standing still
    /// would make it infinite).
    pub life_cap: u32,
    /// Caches whose zone the eye leaves within this many frames have their
    /// pages prefetched (the paper's pre-caching), and leaves the view
    /// will hold this many frames ahead are too.
    pub precache_frames: u32,
    /// Leaves about to enter the view: the frustum they are looked for in
    /// is this much wider (the tangent of its half-angles), for turns.
    pub entering_margin: f64,
    /// Leaves about to enter the view: at most this many pages a frame
    /// (0: none).
    pub entering_pages: usize,
}

impl Default for ImpostorOptions {
    fn default() -> Self {
        Self {
            epsilon_px: 2.0,
            costs: CostModel::UNMEASURED,
            max_caches_per_frame: 32,
            atlas_side: 4096,
            life_cap: 1000,
            precache_frames: 8,
            entering_margin: 1.25,
            entering_pages: 16,
        }
    }
}

/// What a node does this frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Status {
    #[default]
    Cull,
    DrawCache,
    DrawGeometry,
    Recurse,
}

/// A cached image of a node.
#[derive(Debug, Clone, PartialEq)]
pub struct Cache {
    /// Unique over the planner's life: the renderer checks a block still
    /// holds the image it is asked to draw.
    pub serial: u64,
    pub block: Block,
    /// The image's size in texels (its rectangle on the screen it was made
    /// on); it sits one texel in from the block's corner, in a transparent
    /// border.
    pub width: u32,
    pub height: u32,
    /// The quad, world space: top-left, top-right, bottom-left,
    /// bottom-right as seen when made.
    pub corners: [DVec3; 4],
    pub quad: QuadPlane,
    /// The eyes it is valid for.
    pub zone: Zone,
    /// Pages that were missing when it was made (a coarse cache).
    pub missing: Vec<u32>,
    /// The frame it was last drawn or made in.
    pub last_used: u64,
}

/// One thing to draw, in order (back to front).
#[derive(Debug, Clone, PartialEq)]
pub enum Item {
    /// A leaf's triangles: its own, or (`all`, a leaf's own cache) with
    /// those borrowed for inflation; and its placements
    /// `instances` of the cut's list.
    Leaf {
        leaf: u32,
        page: u32,
        all: bool,
        instances: std::ops::Range<u32>,
    },
    /// A node's cached image on its quad.
    Quad {
        node: u32,
        serial: u64,
        block: Block,
        width: u32,
        height: u32,
        corners: [DVec3; 4],
    },
}

/// A cache to make before the frame: the node's contents, drawn from the
/// current eye with the frustum narrowed to `rect`, into `block`.
#[derive(Debug, Clone, PartialEq)]
pub struct CacheJob {
    pub node: u32,
    pub serial: u64,
    pub block: Block,
    /// The node's rectangle on the screen, pixels: x, y (top-left, y
    /// down, either may be off the screen), width, height (at least 1, at
    /// most the viewport's).
    pub rect: [i32; 4],
    /// Its contents: `job_items[items]`, back to front.
    pub items: std::ops::Range<usize>,
}

/// Figures of one frame.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct ImpostorStats {
    pub caches_made: u64,
    pub caches_drawn: u64,
    pub leaves_as_geometry: u64,
    /// Triangles drawn into the frame as geometry.
    pub geometry_triangles: u64,
    /// Valid caches kept in the atlas.
    pub caches_kept: u64,
    /// Bytes of the atlas's blocks in use.
    pub texture_bytes: u64,
    /// Caches made with pages missing, still held.
    pub coarse_caches: u64,
    /// Caches dropped to make room.
    pub evicted: u64,
}

/// The plan of one frame.
#[derive(Debug, Clone, Default)]
pub struct ImpostorCut {
    /// The frame's items, back to front.
    pub items: Vec<Item>,
    /// Caches to make first, children before parents.
    pub jobs: Vec<CacheJob>,
    pub job_items: Vec<Item>,
    /// Placements the items' ranges point into.
    pub instances: Vec<InstanceDraw>,
    pub wanted: Vec<PageWish>,
    pub touched_pages: Vec<u32>,
    pub visited: u64,
    pub frustum_culled: u64,
    pub stats: ImpostorStats,
    /// The atlas's side in texels.
    pub atlas_side: u32,
}

/// What cached images were made for: a change drops them all.
#[derive(Debug, Clone, Copy, PartialEq)]
struct ViewKey {
    width: u32,
    height: u32,
    fov_y_deg: f64,
    epsilon_px: f64,
    atlas_side: u32,
    nodes: usize,
    root_center: DVec3,
    /// Page 0's checksum: another file is another BSP.
    skeleton: u32,
}

/// The planner's state between frames.
#[derive(Debug, Default)]
pub struct Planner {
    caches: Vec<Option<Cache>>,
    atlas: Option<Atlas>,
    key: Option<ViewKey>,
    status: Vec<Status>,
    cost: Vec<f64>,
    zone: Vec<Zone>,
    frame: u64,
    serial: u64,
    last_eye: Option<DVec3>,
    velocity: DVec3,
    acceleration: DVec3,
    /// The eyes of a known path, one a frame (`set_known_path`), and
    /// where this frame's eye is on it.
    path: Vec<DVec3>,
    path_at: Option<usize>,
}

/// One frame's walk.
struct Walk<'a> {
    h: &'a Hierarchy,
    s: &'a BspSkeleton,
    camera: &'a Camera,
    view: View,
    epsilon: f64,
    options: &'a ImpostorOptions,
    pages: PageTracker,
    made: usize,
}

impl Planner {
    /// Plans the frame for `camera` into `cut`.
    pub fn plan(
        &mut self,
        h: &Hierarchy,
        camera: &Camera,
        options: &ImpostorOptions,
        record_pages: bool,
        cut: &mut ImpostorCut,
    ) {
        cut.items.clear();
        cut.jobs.clear();
        cut.job_items.clear();
        cut.instances.clear();
        cut.wanted.clear();
        cut.touched_pages.clear();
        cut.visited = 0;
        cut.frustum_culled = 0;
        cut.stats = ImpostorStats::default();
        if h.header.kind != HierarchyKind::Bsp {
            return;
        }
        let Some(s) = h.bsp_skeleton() else {
            want_page_zero(&mut cut.wanted);
            return;
        };
        self.frame += 1;
        self.track_motion(camera.eye);
        self.locate_on_path(camera.eye);
        self.reset_if_changed(h, s, camera, options);
        self.drop_refined(h);
        let n = s.nodes.len();
        self.status.clear();
        self.status.resize(n, Status::Cull);
        self.cost.clear();
        self.cost.resize(n, 0.0);
        self.zone.clear();
        self.zone.resize(n, Zone::EVERYWHERE);
        let mut walk = Walk {
            h,
            s,
            camera,
            view: camera.view(1e-9),
            epsilon: epsilon_angle(options.epsilon_px, camera.fov_y_deg, camera.height),
            options,
            pages: PageTracker::new(record_pages),
            made: 0,
        };
        walk.pages.touch(0);
        self.update_caches(&mut walk, 0, cut);
        self.render(&mut walk, 0, cut);
        self.precache(&mut walk);
        self.entering(&mut walk);
        let Walk { pages, .. } = walk;
        pages.finish(&mut cut.touched_pages, &mut cut.wanted);
        let atlas = self.atlas.as_ref();
        cut.atlas_side = atlas.map_or(0, Atlas::side);
        cut.stats.texture_bytes = atlas.map_or(0, Atlas::used_bytes);
        let held = self.caches.iter().flatten();
        cut.stats.caches_kept = held.clone().count() as u64;
        cut.stats.coarse_caches = held.filter(|c| !c.missing.is_empty()).count() as u64;
    }

    /// Per-frame velocity and acceleration of the eye.
    fn track_motion(&mut self, eye: DVec3) {
        let velocity = self.last_eye.map_or(DVec3::ZERO, |last| eye - last);
        self.acceleration = velocity - self.velocity;
        self.velocity = velocity;
        self.last_eye = Some(eye);
    }

    /// Drops every cache when the file, the image size, the field of view,
    /// ε or the atlas changed (a cache is valid only for what it was made
    /// with).
    fn reset_if_changed(
        &mut self,
        h: &Hierarchy,
        s: &BspSkeleton,
        camera: &Camera,
        options: &ImpostorOptions,
    ) {
        let key = ViewKey {
            width: camera.width,
            height: camera.height,
            fov_y_deg: camera.fov_y_deg,
            epsilon_px: options.epsilon_px,
            atlas_side: options.atlas_side,
            nodes: s.nodes.len(),
            root_center: h.header.root_center,
            skeleton: h.directory().entry(0).map_or(0, |p| p.checksum),
        };
        if self.key != Some(key) {
            self.key = Some(key);
            self.caches = vec![None; s.nodes.len()];
            self.atlas = Some(Atlas::new(options.atlas_side));
        }
    }

    /// Coarse caches one of whose missing pages has arrived are made
    /// again.
    fn drop_refined(&mut self, h: &Hierarchy) {
        for n in 0..self.caches.len() {
            let refined = self.caches[n]
                .as_ref()
                .is_some_and(|c| c.missing.iter().any(|&p| h.is_resident(p as usize)));
            if refined {
                self.drop_cache(n);
            }
        }
    }

    pub(super) fn drop_cache(&mut self, n: usize) {
        if let Some(c) = self.caches.get_mut(n).and_then(Option::take)
            && let Some(atlas) = self.atlas.as_mut()
        {
            atlas.free(c.block);
        }
    }

    /// The caches held (for tests and tools).
    pub fn caches(&self) -> impl Iterator<Item = (u32, &Cache)> {
        self.caches
            .iter()
            .enumerate()
            .filter_map(|(i, c)| c.as_ref().map(|c| (i as u32, c)))
    }

    /// Each node's status in the last frame.
    pub fn statuses(&self) -> &[Status] {
        &self.status
    }
}

/// A node that may be cached from the current eye.
struct Candidate {
    rect: [i32; 4],
    corners: [DVec3; 4],
    quad: QuadPlane,
    zone: Zone,
    life: u32,
}

fn quad_item(n: u32, c: &Cache) -> Item {
    Item::Quad {
        node: n,
        serial: c.serial,
        block: c.block,
        width: c.width,
        height: c.height,
        corners: c.corners,
    }
}
