//! The PLP builder (Klosowski & Silva, *Rendering on a Budget*, section
//! 3.1): a [`Scene`] in, a paged file of hierarchy kind `plp` out.
//!
//! - [`octree`]: the occupancy octree over the input's vertices, whose
//!   jittered leaf centres are the tessellation's vertices.
//! - [`delaunay`]: their Delaunay tetrahedralization inside the enlarged
//!   bounding box (exact predicates).
//! - [`assign`]: every triangle to every cell it meets; `|c|` and `ρmax`.
//! - [`pages`]: the skeleton in page 0, cells in spatial order after it.

pub mod assign;
pub mod delaunay;
pub mod octree;
pub mod pages;

use std::time::Instant;

use glam::DVec3;

use super::{BuildError, PagedFile};
use crate::cubes::source::Source;
use crate::scene::Scene;

/// Default page size: a cell's triangles are larger than a sphere node.
pub const DEFAULT_PLP_PAGE_BYTES: usize = 32 * 1024;

/// The most octree leaves (tessellation vertices) a build accepts: the
/// paper's scenes need tens of thousands.
pub const MAX_LEAVES: usize = 4 << 20;

/// Knobs of a PLP build.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct PlpOptions {
    /// An occupied octree node splits while its side is at least this
    /// fraction of the bounding box's longest side (the paper's 5 %).
    pub leaf_fraction: f64,
    /// Each leaf centre moves by up to this fraction of its leaf's side
    /// per axis ("randomly perturbed").
    pub jitter: f64,
    /// The bounding box is grown by this fraction of its longest side on
    /// every side before its corners join the tessellation.
    pub margin: f64,
    pub seed: u64,
    pub page_bytes: usize,
}

impl Default for PlpOptions {
    fn default() -> Self {
        Self {
            leaf_fraction: 0.05,
            jitter: 0.05,
            margin: 0.05,
            seed: 1,
            page_bytes: DEFAULT_PLP_PAGE_BYTES,
        }
    }
}

/// What a PLP build did.
#[derive(Debug, Clone, serde::Serialize)]
pub struct PlpStats {
    pub input_vertices: u64,
    /// Triangles (zero-area ones left out): the scene's size for budgets.
    pub triangles: u64,
    pub octree_leaves: usize,
    pub occupied_leaves: usize,
    pub octree_depth: u32,
    pub tetrahedra: usize,
    /// `ρmax`: the most triangles in one cell.
    pub rho_max: u32,
    /// Cells per triangle on average (the paper: 1.80 for CITY, 2.13 for
    /// 5CBEM).
    pub cells_per_triangle: f64,
    /// Triangles stored per distinct triangle (a triangle meeting cells of
    /// two pages is stored in both).
    pub stored_per_triangle: f64,
    pub pages: usize,
    pub skeleton_bytes: u64,
    pub file_bytes: u64,
    pub options: PlpOptions,
    pub seconds_octree: f64,
    pub seconds_delaunay: f64,
    pub seconds_assign: f64,
    pub seconds_layout: f64,
}

/// The scene's triangles in world space with their colors.
pub struct Triangles {
    pub corners: Vec<[DVec3; 3]>,
    pub rgba: Vec<[u8; 4]>,
}

impl std::fmt::Debug for Triangles {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Triangles({})", self.corners.len())
    }
}

/// Every triangle of the scene (instances expanded, spheres tessellated
/// as the cube builder does, zero-area triangles left out).
pub fn scene_triangles(scene: &Scene) -> Result<Triangles, BuildError> {
    let src = Source::new(scene).map_err(BuildError::Invalid)?;
    let mut out = Triangles {
        corners: Vec::new(),
        rgba: Vec::new(),
    };
    let mut tris = Vec::new();
    for r in src.refs() {
        tris.clear();
        src.triangles(&r, &mut tris);
        for t in &tris {
            out.corners.push(t.map(|c| c.position));
            // Flat-shaded: the first corner's color stands for the face.
            let [r, g, b] = t[0].rgb8();
            out.rgba.push([r, g, b, 255]);
        }
    }
    Ok(out)
}

/// Builds the PLP tessellation of a scene.
pub fn build_plp(scene: &Scene, options: &PlpOptions) -> Result<(PagedFile, PlpStats), BuildError> {
    let fraction_ok = options.leaf_fraction.is_finite()
        && options.leaf_fraction > 0.0
        && options.leaf_fraction <= 1.0;
    // Below 1/1024 an octree over a dense scene has more leaves than a
    // tessellation for budgeting needs (and the Delaunay step the memory).
    let fraction_ok = fraction_ok && options.leaf_fraction >= 1.0 / 1024.0;
    if !fraction_ok {
        return Err(BuildError::Invalid(format!(
            "leaf fraction {} is not in [1/1024, 1]",
            options.leaf_fraction
        )));
    }
    if !(options.jitter.is_finite() && (0.0..0.5).contains(&options.jitter)) {
        return Err(BuildError::Invalid(format!(
            "jitter {} is not in [0, 0.5)",
            options.jitter
        )));
    }
    if !(options.margin.is_finite() && options.margin > 0.0 && options.margin <= 10.0) {
        return Err(BuildError::Invalid(format!(
            "margin {} is not in (0, 10]",
            options.margin
        )));
    }
    let tris = scene_triangles(scene)?;
    if tris.corners.is_empty() {
        return Err(BuildError::Empty);
    }
    if tris.corners.len() >= u32::MAX as usize {
        return Err(BuildError::TooLarge(tris.corners.len() as u64));
    }
    let started = Instant::now();
    let vertices: Vec<DVec3> = tris.corners.iter().flatten().copied().collect();
    let (lo, hi) = vertices
        .iter()
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(*p), hi.max(*p))
        });
    // The octree's root: a cube on the bounds' longest side (a unit cube
    // for a scene that is one point).
    let extent = (hi - lo).max_element();
    let side = if extent > 0.0 { extent } else { 1.0 };
    let centre = (lo + hi) * 0.5;
    let root_min = centre - DVec3::splat(side * 0.5);
    let leaves = octree::leaf_centres(
        &vertices,
        root_min,
        side,
        options.leaf_fraction,
        options.jitter,
        options.seed,
    );
    drop(vertices);
    if leaves.centres.len() > MAX_LEAVES {
        return Err(BuildError::Invalid(format!(
            "the octree has {} leaves, more than {MAX_LEAVES}: raise --leaf-fraction",
            leaves.centres.len()
        )));
    }
    let seconds_octree = started.elapsed().as_secs_f64();

    let started = Instant::now();
    // The enlarged box holds the octree's cube (and so every jittered
    // centre) with a margin, so the hull holds every primitive.
    let grow = side * (0.5 + options.margin);
    // The file stores vertices as f32 offsets from the centre: tetrahedralize
    // exactly those, so no cell can flip (or flatten) when it is stored.
    let stored = |p: DVec3| centre + (p - centre).as_vec3().as_dvec3();
    let (box_min, box_max) = (
        stored(centre - DVec3::splat(grow)),
        stored(centre + DVec3::splat(grow)),
    );
    let centres: Vec<DVec3> = leaves.centres.iter().map(|&p| stored(p)).collect();
    let tets = delaunay::tetrahedralize(box_min, box_max, &centres)
        .map_err(|e| BuildError::Invalid(format!("tetrahedralization: {e}")))?;
    let seconds_delaunay = started.elapsed().as_secs_f64();

    let started = Instant::now();
    let cells_of = assign::assign(&tets, &tris.corners)
        .map_err(|e| BuildError::Invalid(format!("assigning triangles: {e}")))?;
    let seconds_assign = started.elapsed().as_secs_f64();

    let started = Instant::now();
    let laid = pages::lay_out(
        &tets,
        &tris,
        &cells_of,
        &pages::LayoutInfo {
            page_bytes: options.page_bytes.max(1024),
            input_vertices: scene.instanced_vertex_count(),
            bounds_min: lo,
            bounds_max: hi,
            box_min,
            box_max,
            root_center: centre,
        },
    )?;
    let assignments: usize = cells_of.iter().map(Vec::len).sum();
    let n = tris.corners.len() as f64;
    let stats = PlpStats {
        input_vertices: scene.instanced_vertex_count(),
        triangles: tris.corners.len() as u64,
        octree_leaves: leaves.centres.len(),
        occupied_leaves: leaves.occupied,
        octree_depth: leaves.depth,
        tetrahedra: tets.cells.len(),
        rho_max: laid.rho_max,
        cells_per_triangle: assignments as f64 / n,
        stored_per_triangle: laid.stored_triangles as f64 / n,
        pages: laid.file.pages.len(),
        skeleton_bytes: laid.file.pages.first().map_or(0, |p| p.len() as u64),
        file_bytes: laid.file.directory.file_len(),
        options: *options,
        seconds_octree,
        seconds_delaunay,
        seconds_assign,
        seconds_layout: started.elapsed().as_secs_f64(),
    };
    Ok((laid.file, stats))
}
