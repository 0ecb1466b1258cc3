//! The color-cube octree's traversal (Chamberlain et al. 1995, section
//! 3.1, `Render(cell)`): resident pages + camera -> cube faces and leaf
//! geometry to draw.
//!
//! A cell outside the frustum is skipped. A cell whose projected size
//! (edge / depth, in pixels) is under `eps` is drawn as its color-cube: the
//! at most three faces that face the eye. A leaf that is not that small
//! draws its triangles. Otherwise the children are visited front to back;
//! where they are not resident yet, the cell's cube is drawn instead and
//! their page is wanted, so the far-field approximation doubles as the
//! placeholder while streaming.

use glam::DVec3;

use farfield_protocol::camera::{Camera, Containment, View};
use farfield_protocol::cube_codec::{Face, Rgba8};
use farfield_protocol::directory::Locate;
use farfield_protocol::file::HierarchyKind;
use farfield_protocol::hierarchy::{Hierarchy, ResidentPage};

use crate::wanted::{PageTracker, want_page_zero};
use farfield_protocol::messages::PageWish;

/// Knobs of one cube traversal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CubeOptions {
    /// Draw a cell as its cube when its projected edge is under this many
    /// pixels; 0 draws geometry everywhere (the reference).
    pub eps_px: f64,
    /// Faces with less coverage than this (0..=255) are left out: 1 drops
    /// only empty faces (alpha as transparency, 1996); a threshold such as
    /// 128 is the 1995 report's way to use coverage.
    pub min_alpha: u8,
    /// Near-plane distance as a fraction of the root cell's half edge. It
    /// only culls cells wholly behind it, so it can be tiny: a camera 30
    /// levels down, among cells a billionth of the root, still sees them.
    pub near_fraction: f64,
    /// Fill [`CubeCut::touched_pages`].
    pub record_pages: bool,
}

impl Default for CubeOptions {
    fn default() -> Self {
        Self {
            eps_px: 1.0,
            min_alpha: 1,
            near_fraction: 1e-12,
            record_pages: false,
        }
    }
}

/// One cube face to draw.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FaceDraw {
    /// The cube's minimum corner and edge, world units.
    pub min: DVec3,
    pub edge: f64,
    pub face: Face,
    /// Premultiplied RGBA.
    pub rgba: Rgba8,
    /// Octree level the cube stands at (clustered sub-cubes count deeper).
    pub level: u32,
}

impl FaceDraw {
    /// Center of the face, world units.
    pub fn center(&self) -> DVec3 {
        let half = self.edge * 0.5;
        let mut c = self.min + DVec3::splat(half);
        c[self.face.axis()] += if self.face.positive() { half } else { -half };
        c
    }
}

/// A leaf cell whose triangles are drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LeafDraw {
    pub page: u32,
    pub local: u32,
    pub min: DVec3,
    pub edge: f64,
    pub triangles: u32,
}

/// The result of one cube traversal.
#[derive(Debug, Clone, Default)]
pub struct CubeCut {
    pub faces: Vec<FaceDraw>,
    pub leaves: Vec<LeafDraw>,
    pub wanted: Vec<PageWish>,
    pub visited: u64,
    pub frustum_culled: u64,
    /// Triangles of the drawn leaves.
    pub triangles: u64,
    /// Faces drawn per octree level (index = level).
    pub faces_per_level: Vec<u64>,
    pub touched_pages: Vec<u32>,
}

#[derive(Clone, Copy)]
struct Item {
    page: u32,
    local: u32,
    min: DVec3,
    edge: f64,
    level: u32,
    inside: bool,
}

/// Traverses the resident cells of a cube hierarchy for `camera`.
pub fn traverse_cubes(h: &Hierarchy, camera: &Camera, options: &CubeOptions) -> CubeCut {
    let mut cut = CubeCut::default();
    traverse_cubes_into(h, camera, options, &mut cut);
    cut
}

/// [`traverse_cubes`] into a caller's cut, reusing its buffers.
pub fn traverse_cubes_into(
    h: &Hierarchy,
    camera: &Camera,
    options: &CubeOptions,
    cut: &mut CubeCut,
) {
    cut.faces.clear();
    cut.leaves.clear();
    cut.wanted.clear();
    cut.visited = 0;
    cut.frustum_culled = 0;
    cut.triangles = 0;
    cut.faces_per_level.clear();
    cut.touched_pages.clear();
    if h.header.kind != HierarchyKind::Cubes {
        return;
    }
    if h.page(0).is_none() {
        want_page_zero(&mut cut.wanted);
        return;
    }
    let half = h.header.root_radius;
    let view = camera.view(half * options.near_fraction);
    let cluster = u32::from(h.header.cluster.max(1));
    let cluster_levels = cluster.trailing_zeros();
    let mut pages = PageTracker::new(options.record_pages);
    let mut stack = vec![Item {
        page: 0,
        local: 0,
        min: h.header.root_center - DVec3::splat(half),
        edge: 2.0 * half,
        level: 0,
        inside: false,
    }];
    while let Some(mut item) = stack.pop() {
        let Some(page) = h.page(item.page as usize) else {
            continue;
        };
        let Some(cubes) = page.cubes() else {
            continue;
        };
        let Some(rec) = cubes.records.get(item.local as usize) else {
            continue;
        };
        cut.visited += 1;
        pages.touch(item.page);
        let center = item.min + DVec3::splat(item.edge * 0.5);
        let bounding_radius = item.edge * 0.5 * 3f64.sqrt();
        if !item.inside {
            match view.classify(center, bounding_radius) {
                Containment::Outside => {
                    cut.frustum_culled += 1;
                    continue;
                }
                Containment::Inside => item.inside = true,
                Containment::Intersecting => {}
            }
        }
        // Projected edge of the cubes this cell would draw (sub-cubes when
        // clustered); infinite when the eye is at or inside the cell.
        let size = projected_edge_px(
            &view,
            center,
            bounding_radius,
            item.edge / f64::from(cluster),
        );
        if size < options.eps_px {
            draw_cube(h, page, item, &view, options, cluster, cluster_levels, cut);
            continue;
        }
        if rec.is_leaf() {
            if let Some(g) = cubes
                .payload(item.local as usize)
                .and_then(|p| p.geometry.as_ref())
            {
                let triangles = g.triangles.len() as u32;
                cut.triangles += u64::from(triangles);
                cut.leaves.push(LeafDraw {
                    page: item.page,
                    local: item.local,
                    min: item.min,
                    edge: item.edge,
                    triangles,
                });
            }
            continue;
        }
        let first = Hierarchy::first_child(page, item.local as usize);
        let count = rec.child_count() as usize;
        let located = h.directory().locate(first);
        let resident = match located {
            Locate::Page(i) => h
                .page(i as usize)
                .filter(|p| Hierarchy::group_fits(p, first, count))
                .map(|p| (i as usize, p)),
            Locate::Missing(_) | Locate::Outside => None,
        };
        let Some((child_page_index, child_page)) = resident else {
            draw_cube(h, page, item, &view, options, cluster, cluster_levels, cut);
            // The children's page, or the directory page that places it.
            if let Locate::Page(i) | Locate::Missing(i) = located {
                pages.want(i, size, view.distance_from_center(center));
            }
            continue;
        };
        push_children(
            &mut stack,
            item,
            rec.children,
            first,
            child_page_index,
            child_page,
            view.eye,
        );
    }
    pages.finish(&mut cut.touched_pages, &mut cut.wanted);
}

/// Projected size in pixels of an edge `edge` at the depth of `center`.
fn projected_edge_px(view: &View, center: DVec3, bounding_radius: f64, edge: f64) -> f64 {
    let depth = (center - view.eye).dot(view.forward);
    if depth <= bounding_radius {
        return f64::INFINITY;
    }
    edge * view.pixels_per_unit_at_1 / depth
}

/// Pushes the children so that they pop front to back: with `e` the octant
/// the eye lies in, octant `e ^ k` for k = 0..8 is a front-to-back order
/// (a cell comes after every cell nearer the eye along each axis).
fn push_children(
    stack: &mut Vec<Item>,
    parent: Item,
    mask: u8,
    first: u64,
    page_index: usize,
    page: &ResidentPage,
    eye: DVec3,
) {
    let mid = parent.min + DVec3::splat(parent.edge * 0.5);
    let eye_octant =
        u8::from(eye.x >= mid.x) | u8::from(eye.y >= mid.y) << 1 | u8::from(eye.z >= mid.z) << 2;
    for k in (0..8u8).rev() {
        let octant = eye_octant ^ k;
        if mask & (1 << octant) == 0 {
            continue;
        }
        // Children are stored in octant order: this one's rank among them.
        let rank = (mask & ((1u8 << octant) - 1)).count_ones() as u64;
        let local = (first + rank - page.header.first_node) as u32;
        stack.push(Item {
            page: page_index as u32,
            local,
            min: farfield_protocol::cube_codec::child_min(parent.min, parent.edge, octant),
            edge: parent.edge * 0.5,
            level: parent.level + 1,
            inside: parent.inside,
        });
    }
}

/// Emits the faces of a cell's cube (or its cluster's sub-cubes) that face
/// the eye and are covered enough.
#[allow(clippy::too_many_arguments)]
fn draw_cube(
    h: &Hierarchy,
    page: &ResidentPage,
    item: Item,
    view: &View,
    options: &CubeOptions,
    cluster: u32,
    cluster_levels: u32,
    cut: &mut CubeCut,
) {
    let Some(cubes) = page.cubes() else {
        return;
    };
    let mut emit = |min: DVec3, edge: f64, faces: &[Rgba8; 6], level: u32| {
        let max = min + DVec3::splat(edge);
        for face in Face::ALL {
            let a = face.axis();
            let facing = if face.positive() {
                view.eye[a] > max[a]
            } else {
                view.eye[a] < min[a]
            };
            let rgba = faces[face.index()];
            if !facing || rgba[3] < options.min_alpha.max(1) {
                continue;
            }
            cut.faces.push(FaceDraw {
                min,
                edge,
                face,
                rgba,
                level,
            });
            let l = level as usize;
            if cut.faces_per_level.len() <= l {
                cut.faces_per_level.resize(l + 1, 0);
            }
            cut.faces_per_level[l] += 1;
        }
    };
    if cluster == 1 {
        if let Some(rec) = cubes.records.get(item.local as usize) {
            emit(item.min, item.edge, &rec.faces, item.level);
        }
        return;
    }
    let sub_edge = item.edge / f64::from(cluster);
    if let Some(payload) = cubes.payload(item.local as usize) {
        for s in &payload.sub_cubes {
            let [x, y, z] = s.coords(h.header.cluster);
            let min = item.min + DVec3::new(f64::from(x), f64::from(y), f64::from(z)) * sub_edge;
            emit(min, sub_edge, &s.faces, item.level + cluster_levels);
        }
    }
}

/// Registers the cube traversal (see [`crate::KINDS`]).
pub const REGISTERED: crate::Registered = crate::Registered {
    name: "cubes",
    hierarchy: HierarchyKind::Cubes,
    params: &["eps", "coverage"],
    reference_threshold_px: 0.0,
    reference: "the cube hierarchy's geometry (eps 0)",

    adaptive_threshold: true,
    measures_costs: false,
    make: || Box::new(CubeTraversal::default()),
};

/// [`traverse_cubes_into`] behind the [`crate::Traversal`] seam, with its
/// last cut.
#[derive(Debug, Default)]
pub struct CubeTraversal {
    pub cut: CubeCut,
}

impl crate::Traversal for CubeTraversal {
    fn registered(&self) -> &'static crate::Registered {
        &REGISTERED
    }

    fn traverse(&mut self, h: &Hierarchy, camera: &Camera, options: &crate::TraversalOptions) {
        let options = CubeOptions {
            eps_px: options.threshold_px,
            min_alpha: options.min_alpha,
            record_pages: options.record_pages,
            ..CubeOptions::default()
        };
        traverse_cubes_into(h, camera, &options, &mut self.cut);
    }

    fn draw_list(&self) -> crate::DrawList<'_> {
        crate::DrawList::Cubes(&self.cut)
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
            drawn: self.cut.faces.len() as u64 + self.cut.triangles,
            frustum_culled: self.cut.frustum_culled,
            backface_culled: 0,
        }
    }
}
