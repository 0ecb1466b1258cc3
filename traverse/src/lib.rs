//! farfield-traverse: resident pages + a view -> what to draw and what to
//! fetch. One interface, [`Traversal`], one module per hierarchy kind.
//!
//! Traversal neither draws nor fetches: it reads a
//! [`Hierarchy`](farfield_protocol::hierarchy::Hierarchy) (whichever pages
//! are resident), walks it for one camera and yields a [`DrawList`] for the
//! renderer and the [`PageWish`](farfield_protocol::messages::PageWish)s, with priorities, for the client
//! session. The frame loop, the benches and the CLI drive every kind
//! through this interface and never name one.
//!
//! - [`spheres`]: QSplat's bounding-sphere traversal (splats).
//! - [`cubes`]: the color-cube octree's `Render(cell)` (cube faces and
//!   leaf triangles).
//! - [`plp`]: Prioritized-Layered Projection over a Delaunay tessellation
//!   (triangles in solidity order within a budget), and its
//!   centroid-sorted baseline.
//! - [`bsp`]: hierarchical frustum culling over image caching's BSP by
//!   gaps, leaves back to front (the baseline of the impostor cache).
//! - [`impostors`]: hierarchical image caching: cached images of far
//!   subtrees on quads, their error metric, safety zones and atlas.
//! - [`wanted`]: the pages a traversal asks for and the pages it read.
//!
//! A new kind is a new module with a [`Registered`] entry in [`KINDS`].

pub mod bsp;
pub mod budget;
pub mod cubes;
pub mod impostors;
pub mod plp;
pub mod spheres;
pub mod wanted;

use farfield_protocol::camera::Camera;
use farfield_protocol::file::HierarchyKind;
use farfield_protocol::hierarchy::Hierarchy;

pub use budget::Budget;

/// What every kind is asked besides the pages and the camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TraversalOptions {
    /// The refinement threshold in pixels: the largest splat for spheres,
    /// `eps` (the projected cell edge drawn as a color-cube) for cubes.
    pub threshold_px: f64,
    /// Cubes: faces covered less than this (0..=255) are left out.
    pub min_alpha: u8,
    /// Fill [`Traversal::touched_pages`] (cache recency, overfetch).
    pub record_pages: bool,
    /// Budgeted kinds (PLP): how many triangles a frame may draw.
    pub budget: Budget,
    /// Image caching: what drawing and caching cost on this machine
    /// (measured by the renderer).
    pub costs: impostors::CostModel,
}

impl Default for TraversalOptions {
    fn default() -> Self {
        Self {
            threshold_px: 1.0,
            min_alpha: 1,
            record_pages: false,
            budget: Budget::Unlimited,
            costs: impostors::CostModel::UNMEASURED,
        }
    }
}

/// What the last traversal yields for the renderer.
#[derive(Debug, Clone, Copy)]
pub enum DrawList<'a> {
    /// Splats, one per node of the cut.
    Splats(&'a [spheres::Splat]),
    /// Cube faces, and leaves whose triangles the renderer reads from the
    /// hierarchy's resident pages.
    Cubes(&'a cubes::CubeCut),
    /// Triangles stored in the hierarchy's resident pages (PLP).
    Triangles(&'a plp::PlpCut),
    /// BSP leaves' own triangles and placed prototypes, back to front.
    Bsp(&'a bsp::BspCut),
    /// Caches to make, then leaves and cached quads, back to front.
    Impostors(&'a impostors::ImpostorCut),
}

impl DrawList<'_> {
    /// Cube faces and triangles to draw, for reports: (0, 0) for splats;
    /// a kind that draws triangles counts its own.
    pub fn faces_and_triangles(&self) -> (usize, u64) {
        match self {
            DrawList::Splats(_) => (0, 0),
            DrawList::Cubes(cut) => (cut.faces.len(), cut.triangles),
            DrawList::Triangles(cut) => (0, cut.triangles.len() as u64),
            DrawList::Bsp(cut) => (0, cut.triangles),
            // (Its leaves' triangles are in its stats.)
            DrawList::Impostors(_) => (0, 0),
        }
    }

    /// Image caching's caches of this frame; `None` for other kinds.
    pub fn impostor_stats(&self) -> Option<impostors::plan::ImpostorStats> {
        match self {
            DrawList::Impostors(cut) => Some(cut.stats),
            _ => None,
        }
    }
}

/// How much of the hierarchy one traversal looked at.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct Counts {
    /// Nodes whose record was read.
    pub visited: u64,
    /// Primitives to draw: splats, or cube faces plus leaf triangles.
    pub drawn: u64,
    pub frustum_culled: u64,
    pub backface_culled: u64,
}

/// One hierarchy kind's traversal, holding its last cut (buffers are
/// reused from frame to frame).
pub trait Traversal: std::fmt::Debug {
    /// The kind's entry in [`KINDS`].
    fn registered(&self) -> &'static Registered;
    /// Walks the resident part of `h` for `camera`, replacing the last cut.
    fn traverse(&mut self, h: &Hierarchy, camera: &Camera, options: &TraversalOptions);
    /// What to draw.
    fn draw_list(&self) -> DrawList<'_>;
    /// Pages the cut would descend into, most urgent first.
    fn wanted(&self) -> &[farfield_protocol::messages::PageWish];
    /// Pages the cut read, ascending (with `record_pages`).
    fn touched_pages(&self) -> &[u32];
    fn counts(&self) -> Counts;
    /// The eyes of the frames to come, one a frame, when the path is known
    /// in advance (a recorded flythrough). Kinds that plan ahead use it
    /// (image caching counts its caches' life spans along it); the others
    /// ignore it.
    fn set_known_path(&mut self, _eyes: &[glam::DVec3]) {}
}

/// A kind as the rest of the client knows it: its names and a constructor.
#[derive(Debug)]
pub struct Registered {
    /// The name in tables, plots and `--mode` (`spheres`, `cubes`).
    pub name: &'static str,
    /// The files it walks.
    pub hierarchy: HierarchyKind,
    /// The settings a bench may sweep, the default first: the threshold's
    /// name for this kind, then the style setting it reads.
    pub params: &'static [&'static str],
    /// The threshold of the kind's finest image, a reference for its
    /// coarser ones (1 px splats; eps 0, geometry everywhere).
    pub reference_threshold_px: f64,
    /// That reference in words, for tables.
    pub reference: &'static str,
    /// Whether the threshold is a level of detail a frame loop may coarsen
    /// and refine (splat size, eps); `false` where it is an error bound
    /// every frame must hold (image caching's ε) or is not read.
    pub adaptive_threshold: bool,
    /// Whether the traversal reads what drawing costs on this machine
    /// ([`TraversalOptions::costs`]): a frame loop then has the renderer
    /// measure it once, before the first frame (image caching, which
    /// weighs a cached image against its geometry).
    pub measures_costs: bool,
    pub make: fn() -> Box<dyn Traversal>,
}

/// Kinds are one per name.
impl PartialEq for Registered {
    fn eq(&self, other: &Self) -> bool {
        self.name == other.name
    }
}

/// Every kind this client can draw. The first entry for a hierarchy kind
/// is the one its files are drawn with; later ones (PLP's centroid
/// baseline) are chosen by name.
pub const KINDS: &[Registered] = &[
    spheres::REGISTERED,
    cubes::REGISTERED,
    plp::REGISTERED,
    plp::CENTROID,
    impostors::REGISTERED,
    bsp::CULLING,
];

/// The traversal for a file of `kind`.
pub fn for_hierarchy(kind: HierarchyKind) -> Box<dyn Traversal> {
    (registered_for(kind).make)()
}

/// The kind a file of `kind` is drawn with.
pub fn registered_for(kind: HierarchyKind) -> &'static Registered {
    // Every hierarchy kind has a registered traversal (a test checks).
    KINDS
        .iter()
        .find(|k| k.hierarchy == kind)
        .unwrap_or(&KINDS[0])
}

/// The kind named `name` (`--mode`), if any.
pub fn named(name: &str) -> Option<&'static Registered> {
    KINDS.iter().find(|k| k.name == name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_hierarchy_kind_has_a_registered_traversal() {
        for kind in [
            HierarchyKind::Spheres,
            HierarchyKind::Cubes,
            HierarchyKind::Plp,
            HierarchyKind::Bsp,
        ] {
            let first = KINDS.iter().find(|k| k.hierarchy == kind).map(|k| k.name);
            assert!(first.is_some(), "{kind:?}");
            assert_eq!(for_hierarchy(kind).registered().hierarchy, kind);
            assert_eq!(Some(for_hierarchy(kind).registered().name), first);
        }
        assert_eq!(
            named("centroid").map(|k| k.hierarchy),
            Some(HierarchyKind::Plp)
        );
        for k in KINDS {
            assert_eq!(named(k.name).map(|r| r.hierarchy), Some(k.hierarchy));
        }
    }
}
