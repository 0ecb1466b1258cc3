//! Hierarchical image caching (Shade et al. 1996): far subtrees of a BSP
//! drawn from cached images on single quads while an error bound holds.
//!
//! - [`safety`]: section 3, the error metric and the safety zones that say
//!   how long a cache stays valid.
//! - [`plan`]: section 2, `UpdateCaches`, `UpdateNode` and `Render`: which
//!   nodes to cache, draw cached, draw as geometry or cull, back to front.
//! - [`atlas`]: where the images live (power-of-two blocks, a byte budget,
//!   least recently used eviction).
//! - [`cost`]: the measured cost model `UpdateNode` compares.
//!
//! [`ImpostorTraversal`] is the kind behind the [`crate::Traversal`] seam
//! (`--mode impostors`); its threshold is ε in pixels.

pub mod atlas;
pub mod cost;
pub mod plan;
pub mod safety;

use farfield_protocol::camera::Camera;
use farfield_protocol::file::HierarchyKind;
use farfield_protocol::hierarchy::Hierarchy;

pub use cost::CostModel;
pub use plan::{ImpostorCut, ImpostorOptions, Planner};

use crate::Counts;
use farfield_protocol::messages::PageWish;

/// Registers image caching (see [`crate::KINDS`]): the first kind for BSP
/// files.
pub const REGISTERED: crate::Registered = crate::Registered {
    name: "impostors",
    hierarchy: HierarchyKind::Bsp,
    params: &["epsilon"],
    // ε = 0 never caches: the culling baseline's image.
    reference_threshold_px: 0.0,
    reference: "every leaf in view as geometry (epsilon 0)",
    adaptive_threshold: false,
    measures_costs: true,
    make: || Box::new(ImpostorTraversal::default()),
};

/// The planner behind the [`crate::Traversal`] seam.
#[derive(Debug, Default)]
pub struct ImpostorTraversal {
    pub planner: Planner,
    pub cut: ImpostorCut,
    /// Everything but ε and the costs, which come with each frame's
    /// options.
    pub options: ImpostorOptions,
}

impl crate::Traversal for ImpostorTraversal {
    fn registered(&self) -> &'static crate::Registered {
        &REGISTERED
    }

    fn traverse(&mut self, h: &Hierarchy, camera: &Camera, options: &crate::TraversalOptions) {
        let frame = ImpostorOptions {
            epsilon_px: options.threshold_px,
            costs: options.costs,
            ..self.options
        };
        self.planner
            .plan(h, camera, &frame, options.record_pages, &mut self.cut);
    }

    fn draw_list(&self) -> crate::DrawList<'_> {
        crate::DrawList::Impostors(&self.cut)
    }

    fn wanted(&self) -> &[PageWish] {
        &self.cut.wanted
    }

    fn touched_pages(&self) -> &[u32] {
        &self.cut.touched_pages
    }

    fn set_known_path(&mut self, eyes: &[glam::DVec3]) {
        self.planner.set_known_path(eyes);
    }

    fn counts(&self) -> Counts {
        Counts {
            visited: self.cut.visited,
            drawn: self.cut.stats.geometry_triangles + self.cut.stats.caches_drawn,
            frustum_culled: self.cut.frustum_culled,
            backface_culled: 0,
        }
    }
}
