//! Prioritized-Layered Projection (Klosowski & Silva, *Rendering on a
//! Budget*, Figures 5 and 6): the cells of the tessellation projected in
//! order of accumulated solidity, until the budget is spent.
//!
//! The front is a priority queue of cells, seeded with the cell holding
//! the eye (or, from outside, the hull cells whose outer face it sees).
//! The least solid cell is popped and projected: its triangles are drawn,
//! each once a frame, less those outside the frustum or facing away (the
//! paper's culling; culled triangles cost no budget). Each neighbour not
//! yet projected then receives solidity through the shared face,
//! `ρ_B = |A| / ρmax + (v · n_B) ρ_A` (Figure 6), plus a penalty when B's
//! centroid is not seen from the eye through that face (the star-shaped
//! criterion), and is (re)queued with that value, replacing any earlier
//! one. `v` is the direction from the eye through the shared face: the
//! view direction at that point of a perspective image. By default a
//! cell's own share, `|A| / ρmax` in the paper, is its triangles' area
//! over its cross-section instead ([`Solidity`]).
//!
//! Streamed, the skeleton (page 0) orders everything. A projected cell
//! whose page is missing is wanted, in projection order, while the
//! triangles drawn plus the missing cells' `|c|` stay within the budget;
//! the front advances past it and what has arrived is drawn.
//!
//! The baseline of section 4, [`Order::Centroid`], draws the resident
//! triangles nearest the eye first (by centroid) and wants cells' pages
//! nearest first.

use std::cmp::{Ordering, Reverse};
use std::collections::BinaryHeap;

use glam::DVec3;

use farfield_protocol::camera::{Camera, View};
use farfield_protocol::directory::Locate;
use farfield_protocol::file::HierarchyKind;
use farfield_protocol::hierarchy::{Hierarchy, PlpPage};
use farfield_protocol::plp_codec::{CellPage, NO_NEIGHBOUR, Skeleton, face_corners};

use crate::wanted::{PageTracker, want_page_zero};
use crate::{Budget, Counts};
use farfield_protocol::messages::PageWish;

/// Which order cells and triangles are drawn in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Order {
    /// PLP's solidity-driven front.
    #[default]
    Solidity,
    /// The centroid-sorted baseline: nearest triangles first.
    Centroid,
}

/// What a projected cell passes on to its neighbours.
///
/// The default is [`Solidity::Coverage`]: on `gen:cars` the paper's count
/// lets the front walk through a car's body into its engine (a shell cell
/// holds a few dozen triangles against the engine's `ρmax` of thousands,
/// so it passes almost nothing on), and its Table 1 coverage at 1 % was
/// 16.4 % against 45.1 % with coverage (built with `--leaf-fraction
/// 0.01`); on `gen:city` the two are within a few points of each other
/// (docs/experiments.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Solidity {
    /// The paper's `|A| / ρmax`: the cell's share of the fullest cell's
    /// triangle count.
    Count,
    /// The cell's triangles' area over its cross-section, at most 1: a thin
    /// shell of few large triangles is as opaque as a dense engine block
    /// (the paper's conclusion asks for a better measure than the count).
    #[default]
    Coverage,
}

impl std::str::FromStr for Solidity {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "count" => Ok(Self::Count),
            "coverage" => Ok(Self::Coverage),
            _ => Err(format!("solidity must be count or coverage, not {s}")),
        }
    }
}

/// Knobs of one PLP traversal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlpOptions {
    pub budget: Budget,
    pub order: Order,
    pub solidity: Solidity,
    /// Added to the solidity of a cell whose centroid the eye does not see
    /// through the face it is reached by (the non-star-shaped penalty), in
    /// units of a full cell (`ρmax` triangles). Added, not multiplied (the
    /// paper leaves the "penalty factor" open): empty space has solidity 0,
    /// which no factor would raise. 0 turns it off.
    pub star_penalty: f64,
    /// Leave out triangles that face away from the eye.
    pub backface_culling: bool,
    /// Fill [`PlpCut::touched_pages`].
    pub record_pages: bool,
}

impl Default for PlpOptions {
    fn default() -> Self {
        Self {
            budget: Budget::Unlimited,
            order: Order::Solidity,
            solidity: Solidity::default(),
            star_penalty: DEFAULT_STAR_PENALTY,
            backface_culling: true,
            record_pages: false,
        }
    }
}

/// Triangle ids kept in a dense table (64 MiB of stamps at most, whatever
/// ids a file claims); larger ones in a set.
const DENSE_IDS: usize = 1 << 24;

/// The default non-star-shaped penalty: two full cells. Measured on
/// `gen:city`'s walk (`farfield bench-plp --stride 8 --star-penalty P`,
/// mean coverage at 1, 2, 5 and 10 %): P = 0 gave 18.6, 54.0, 88.2 and
/// 99.8 %; 0.5 gave 54.6, 62.0, 94.5, 100; 1 gave 59.2, 72.9, 83.7, 99.9;
/// 2 gave 61.7, 75.3, 84.8, 100; 4 gave 67.1, 73.5, 87.0, 100.
pub const DEFAULT_STAR_PENALTY: f64 = 2.0;

/// A triangle to draw: where it is stored, and its scene-wide id.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub struct TriangleDraw {
    pub id: u32,
    pub page: u32,
    /// Index among the page's stored triangles.
    pub index: u32,
}

/// The result of one PLP traversal.
#[derive(Debug, Clone, Default)]
pub struct PlpCut {
    /// What to draw, sorted by id (so the same set always draws the same
    /// image, whatever order it was found in).
    pub triangles: Vec<TriangleDraw>,
    /// Cells in the order they were projected.
    pub projected: Vec<u32>,
    pub wanted: Vec<PageWish>,
    pub touched_pages: Vec<u32>,
    /// The budget in triangles this frame (`u64::MAX` unlimited).
    pub budget: u64,
    /// Whether the budget stopped the traversal.
    pub budget_reached: bool,
    pub frustum_culled: u64,
    pub backface_culled: u64,
    /// The cell the eye is in (`None` outside the hull).
    pub eye_cell: Option<u32>,
}

/// Per-traversal scratch kept between frames.
#[derive(Debug, Default)]
pub struct PlpState {
    /// Per triangle id below [`DENSE_IDS`], the frame that last drew or
    /// culled it.
    triangle_stamp: Vec<u32>,
    /// This frame's ids from [`DENSE_IDS`] up.
    sparse: std::collections::HashSet<u32>,
    /// Per cell, the frame that projected it.
    projected_stamp: Vec<u32>,
    /// Per cell, the generation of its live queue entry.
    generation: Vec<u32>,
    frame: u32,
    last_eye_cell: u32,
}

/// A queue entry: smallest solidity first; among equals (empty space is
/// all zero) the nearest to the eye, then the lowest cell.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Entry {
    solidity: f64,
    distance: f64,
    cell: u32,
    generation: u32,
}

impl Eq for Entry {}

impl Ord for Entry {
    fn cmp(&self, other: &Self) -> Ordering {
        self.solidity
            .total_cmp(&other.solidity)
            .then(self.distance.total_cmp(&other.distance))
            .then(self.cell.cmp(&other.cell))
            .then(self.generation.cmp(&other.generation))
    }
}

impl PartialOrd for Entry {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

/// Traverses a PLP hierarchy for `camera` into `cut`.
pub fn traverse_plp_into(
    h: &Hierarchy,
    camera: &Camera,
    options: &PlpOptions,
    state: &mut PlpState,
    cut: &mut PlpCut,
) {
    cut.triangles.clear();
    cut.projected.clear();
    cut.wanted.clear();
    cut.touched_pages.clear();
    cut.budget_reached = false;
    cut.frustum_culled = 0;
    cut.backface_culled = 0;
    cut.eye_cell = None;
    cut.budget = 0;
    if h.header.kind != HierarchyKind::Plp {
        return;
    }
    let Some(skeleton) = h.plp_skeleton() else {
        want_page_zero(&mut cut.wanted);
        return;
    };
    let view = camera.view(f64::MIN_POSITIVE);
    cut.budget = options.budget.triangles(skeleton.scene_triangles);
    let cells = skeleton.cells.len();
    state.frame = state.frame.wrapping_add(1);
    if state.frame == 0 {
        // Wrapped: old stamps could collide with the new frame numbers.
        state.triangle_stamp.fill(0);
        state.projected_stamp.fill(0);
        state.frame = 1;
    }
    state.sparse.clear();
    state.projected_stamp.resize(cells, 0);
    state.generation.resize(cells, 0);
    let mut pages = PageTracker::new(options.record_pages);
    pages.touch(0);
    let mut walk = Walk {
        h,
        skeleton,
        view: &view,
        options,
        state,
        cut,
        pages: &mut pages,
        pending: 0,
        found: 0,
        requests: 0,
    };
    match options.order {
        Order::Solidity => walk.solidity_order(),
        Order::Centroid => walk.centroid_order(),
    }
    cut.triangles.sort_unstable();
    pages.finish(&mut cut.touched_pages, &mut cut.wanted);
}

/// One frame's traversal state.
struct Walk<'a> {
    h: &'a Hierarchy,
    skeleton: &'a Skeleton,
    view: &'a View,
    options: &'a PlpOptions,
    state: &'a mut PlpState,
    cut: &'a mut PlpCut,
    pages: &'a mut PageTracker,
    /// `|c|` of the projected cells whose pages are missing.
    pending: u64,
    /// Resident triangles found but not yet in the cut: the centroid
    /// order sorts them all before taking the budget's worth, and they
    /// count against the budget when pages are wanted.
    found: u64,
    /// Pages wanted so far (their rank sets their priority).
    requests: u64,
}

impl<'a> Walk<'a> {
    fn solidity_order(&mut self) {
        let sk: &'a Skeleton = self.skeleton;
        let eye = self.view.eye;
        let mut front: BinaryHeap<Reverse<Entry>> = BinaryHeap::new();
        match self.eye_cell() {
            Some(c) => {
                self.cut.eye_cell = Some(c);
                self.state.last_eye_cell = c;
                self.enqueue(&mut front, c, 0.0);
            }
            None => {
                // From outside: the hull cells whose outer face the eye sees.
                for (c, cell) in sk.cells.iter().enumerate() {
                    for f in 0..4 {
                        if cell.neighbours[f] != NO_NEIGHBOUR {
                            continue;
                        }
                        let a = sk.vertices[face_corners(cell.vertices, f)[0] as usize];
                        if sk.normals[c][f].dot(eye - a) > 0.0 && self.in_view(c as u32) {
                            self.enqueue(&mut front, c as u32, 0.0);
                            break;
                        }
                    }
                }
            }
        }
        let rho_max = f64::from(sk.rho_max.max(1));
        while let Some(Reverse(entry)) = front.pop() {
            let a = entry.cell as usize;
            if self.state.generation[a] != entry.generation
                || self.state.projected_stamp[a] == self.state.frame
            {
                continue;
            }
            self.state.projected_stamp[a] = self.state.frame;
            self.cut.projected.push(entry.cell);
            self.project(entry.cell);
            if self.budget_spent() {
                self.cut.budget_reached = true;
                break;
            }
            let cell = sk.cells[a];
            let own = match self.options.solidity {
                Solidity::Count => f64::from(cell.triangles) / rho_max,
                Solidity::Coverage => f64::from(cell.coverage).min(1.0),
            };
            for f in 0..4 {
                let b = cell.neighbours[f];
                if b == NO_NEIGHBOUR || self.state.projected_stamp[b as usize] == self.state.frame {
                    continue;
                }
                // A cell wholly out of view is never queued: every triangle
                // is in every cell it meets, so what is in view is reached
                // through cells that are in view.
                if !self.in_view(b) {
                    continue;
                }
                let corners = face_corners(cell.vertices, f).map(|v| sk.vertices[v as usize]);
                let centre = (corners[0] + corners[1] + corners[2]) / 3.0;
                let v = (centre - eye).try_normalize().unwrap_or(self.view.forward);
                let mut rho = own + v.dot(sk.normals[a][f]) * entry.solidity;
                if self.options.star_penalty > 0.0 && !self.star_shaped(b, corners) {
                    rho += self.options.star_penalty;
                }
                // Normals are finite (zero for slivers), solidities start
                // at 0: no NaN can reach the queue, but never let one in.
                if rho.is_finite() {
                    self.enqueue(&mut front, b, rho);
                }
            }
        }
    }

    fn centroid_order(&mut self) {
        let sk: &'a Skeleton = self.skeleton;
        let eye = self.view.eye;
        // Cells in view, nearest centroid first: the order pages are wanted.
        let mut cells: Vec<(f64, u32)> = (0..sk.cells.len() as u32)
            .filter(|&c| self.in_view(c))
            .map(|c| (self.centroid(c).distance_squared(eye), c))
            .collect();
        cells.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
        // Every resident triangle that survives culling, nearest first.
        let mut candidates: Vec<(f64, TriangleDraw)> = Vec::new();
        for &(_, c) in &cells {
            self.cut.projected.push(c);
            let Some((page, cells_page, local)) = self.cell_page(c) else {
                self.want_missing(c);
                continue;
            };
            for (index, t) in cells_page.cell_indexed(local) {
                if !self.first_sight(t.id) {
                    continue;
                }
                let corners = t.corners.map(|p| cells_page.world(p));
                if self.culled(&corners) {
                    continue;
                }
                let centroid = (corners[0] + corners[1] + corners[2]) / 3.0;
                self.found += 1;
                candidates.push((
                    centroid.distance_squared(eye),
                    TriangleDraw {
                        id: t.id,
                        page,
                        index,
                    },
                ));
            }
        }
        candidates.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.id.cmp(&y.1.id)));
        let take = candidates
            .len()
            .min(self.cut.budget.min(usize::MAX as u64) as usize);
        self.cut.budget_reached = take < candidates.len();
        self.cut
            .triangles
            .extend(candidates[..take].iter().map(|(_, t)| *t));
    }

    /// Draws cell `c`'s triangles within the budget, or wants its page.
    fn project(&mut self, c: u32) {
        let Some((page, cells_page, local)) = self.cell_page(c) else {
            self.want_missing(c);
            return;
        };
        for (index, t) in cells_page.cell_indexed(local) {
            if self.budget_spent() {
                return;
            }
            if !self.first_sight(t.id) {
                continue;
            }
            let corners = t.corners.map(|p| cells_page.world(p));
            if self.culled(&corners) {
                continue;
            }
            self.cut.triangles.push(TriangleDraw {
                id: t.id,
                page,
                index,
            });
        }
    }

    fn budget_spent(&self) -> bool {
        self.cut.triangles.len() as u64 >= self.cut.budget
    }

    /// Wants the page of a cell that is to be drawn and is missing, while
    /// what is drawn and what is on its way fit the budget. The cell that
    /// crosses the budget is wanted too (the paper's loop also stops after
    /// the cell that reaches it): without it the budget could not be filled.
    fn want_missing(&mut self, c: u32) {
        let size = u64::from(self.skeleton.cells[c as usize].triangles);
        if size == 0 {
            return;
        }
        let committed = self.cut.triangles.len() as u64 + self.found + self.pending;
        if committed >= self.cut.budget {
            return;
        }
        self.pending += size;
        // The cell's page, or the directory page that places it.
        if let Locate::Page(page) | Locate::Missing(page) =
            self.h.directory().locate(1 + u64::from(c))
        {
            // Earlier in the order is more urgent.
            self.requests += 1;
            self.pages.want(page, 1e9 / self.requests as f64, 0.0);
        }
    }

    /// Cell `c`'s resident page: its index, cells and `c`'s place in it.
    fn cell_page(&mut self, c: u32) -> Option<(u32, &'a CellPage, usize)> {
        let h: &'a Hierarchy = self.h;
        let node = 1 + u64::from(c);
        let index = h.directory().page_of(node)? as usize;
        let page = h.page(index)?;
        let Some(PlpPage::Cells(cells)) = page.plp() else {
            return None;
        };
        self.pages.touch(index as u32);
        let local = (node - page.header.first_node) as usize;
        Some((index as u32, cells, local))
    }

    /// True the first time a frame sees triangle `id`; never for an id the
    /// skeleton says the scene does not have.
    fn first_sight(&mut self, id: u32) -> bool {
        if u64::from(id) >= self.skeleton.scene_triangles {
            return false;
        }
        let frame = self.state.frame;
        if (id as usize) >= DENSE_IDS {
            // Past the dense table a set holds the frame's ids, so memory
            // follows the triangles drawn, not an id a file may claim.
            return self.state.sparse.insert(id);
        }
        let stamps = &mut self.state.triangle_stamp;
        if stamps.len() <= id as usize {
            stamps.resize(id as usize + 1, 0);
        }
        if stamps[id as usize] == frame {
            return false;
        }
        stamps[id as usize] = frame;
        true
    }

    /// Frustum and backface culling of one triangle, counted.
    fn culled(&mut self, corners: &[DVec3; 3]) -> bool {
        if self.view.all_outside(corners) {
            self.cut.frustum_culled += 1;
            return true;
        }
        if self.options.backface_culling {
            let n = (corners[1] - corners[0]).cross(corners[2] - corners[0]);
            if n.dot(self.view.eye - corners[0]) <= 0.0 {
                self.cut.backface_culled += 1;
                return true;
            }
        }
        false
    }

    fn enqueue(&mut self, front: &mut BinaryHeap<Reverse<Entry>>, c: u32, solidity: f64) {
        let distance = self.centroid(c).distance_squared(self.view.eye);
        let g = &mut self.state.generation[c as usize];
        *g = g.wrapping_add(1);
        front.push(Reverse(Entry {
            solidity,
            distance,
            cell: c,
            generation: *g,
        }));
    }

    fn corners(&self, c: u32) -> [DVec3; 4] {
        self.skeleton.cells[c as usize]
            .vertices
            .map(|v| self.skeleton.vertices[v as usize])
    }

    fn centroid(&self, c: u32) -> DVec3 {
        self.corners(c).iter().sum::<DVec3>() / 4.0
    }

    /// Whether any of cell `c` may be in view.
    fn in_view(&self, c: u32) -> bool {
        !self.view.all_outside(&self.corners(c))
    }

    /// Whether the eye sees cell `b`'s centroid through the face `corners`
    /// (the segment from the eye to the centroid crosses the face).
    fn star_shaped(&self, b: u32, corners: [DVec3; 3]) -> bool {
        let e = self.view.eye;
        let p = self.centroid(b);
        let d = p - e;
        let side = |x: DVec3, y: DVec3| d.dot((x - e).cross(y - e));
        let s = [
            side(corners[0], corners[1]),
            side(corners[1], corners[2]),
            side(corners[2], corners[0]),
        ];
        let through = s.iter().all(|&x| x >= 0.0) || s.iter().all(|&x| x <= 0.0);
        // And the face lies between the eye and the centroid.
        let n = (corners[1] - corners[0]).cross(corners[2] - corners[0]);
        let eye_side = n.dot(e - corners[0]);
        let far_side = n.dot(p - corners[0]);
        through && eye_side * far_side <= 0.0
    }

    /// The cell holding the eye: the last frame's, a walk from it, or a
    /// search of all; `None` outside the hull.
    fn eye_cell(&self) -> Option<u32> {
        let sk = self.skeleton;
        let eye = self.view.eye;
        let beyond = |c: usize, f: usize| -> f64 {
            let a = sk.vertices[face_corners(sk.cells[c].vertices, f)[0] as usize];
            sk.normals[c][f].dot(eye - a)
        };
        // A hair of slack, so an eye on a face, edge or vertex belongs to a
        // cell either side instead of to none.
        let scale = (sk.vertices.first().copied().unwrap_or(DVec3::ZERO) - eye)
            .length()
            .max(1.0);
        let slack = 1e-12 * scale;
        let contains = |c: usize| (0..4).all(|f| beyond(c, f) <= slack);
        let mut c = self.state.last_eye_cell as usize;
        if c < sk.cells.len() {
            for _ in 0..256 {
                let Some(f) = (0..4).find(|&f| beyond(c, f) > slack) else {
                    return Some(c as u32);
                };
                let n = sk.cells[c].neighbours[f];
                if n == NO_NEIGHBOUR {
                    break;
                }
                c = n as usize;
            }
        }
        (0..sk.cells.len()).find(|&c| contains(c)).map(|c| c as u32)
    }
}

/// Registers PLP (see [`crate::KINDS`]).
pub const REGISTERED: crate::Registered = crate::Registered {
    name: "plp",
    hierarchy: HierarchyKind::Plp,
    params: &["budget"],
    reference_threshold_px: 0.0,
    reference: "every triangle (budget 100%)",
    adaptive_threshold: false,
    measures_costs: false,
    make: || Box::new(PlpTraversal::new(Order::Solidity)),
};

/// The centroid-sorted baseline of section 4, on the same files.
pub const CENTROID: crate::Registered = crate::Registered {
    name: "centroid",
    hierarchy: HierarchyKind::Plp,
    params: &["budget"],
    reference_threshold_px: 0.0,
    reference: "every triangle (budget 100%)",
    adaptive_threshold: false,
    measures_costs: false,
    make: || Box::new(PlpTraversal::new(Order::Centroid)),
};

/// [`traverse_plp_into`] behind the [`crate::Traversal`] seam.
#[derive(Debug, Default)]
pub struct PlpTraversal {
    pub order: Order,
    pub cut: PlpCut,
    pub state: PlpState,
}

impl PlpTraversal {
    pub fn new(order: Order) -> Self {
        Self {
            order,
            ..Self::default()
        }
    }
}

impl crate::Traversal for PlpTraversal {
    fn registered(&self) -> &'static crate::Registered {
        match self.order {
            Order::Solidity => &REGISTERED,
            Order::Centroid => &CENTROID,
        }
    }

    fn traverse(&mut self, h: &Hierarchy, camera: &Camera, options: &crate::TraversalOptions) {
        let options = PlpOptions {
            budget: options.budget,
            order: self.order,
            record_pages: options.record_pages,
            ..PlpOptions::default()
        };
        traverse_plp_into(h, camera, &options, &mut self.state, &mut self.cut);
    }

    fn draw_list(&self) -> crate::DrawList<'_> {
        crate::DrawList::Triangles(&self.cut)
    }

    fn wanted(&self) -> &[PageWish] {
        &self.cut.wanted
    }

    fn touched_pages(&self) -> &[u32] {
        &self.cut.touched_pages
    }

    fn counts(&self) -> Counts {
        Counts {
            visited: self.cut.projected.len() as u64,
            drawn: self.cut.triangles.len() as u64,
            frustum_culled: self.cut.frustum_culled,
            backface_culled: self.cut.backface_culled,
        }
    }
}
