//! Laying the tessellation out in pages: the skeleton alone in page 0 (one
//! read after the header gives the whole traversal), then the cells in
//! Morton order of their centroids, cut into pages of about `page_bytes`,
//! so a page is a patch of space and the pages PLP asks for first are few.
//! A cell larger than a page gets a page of its own.

use std::collections::HashMap;

use farfield_protocol::FormatError;
use farfield_protocol::file::{AttributeFlags, HierarchyKind};
use farfield_protocol::plp_codec::{self, Cell, CellPage, NO_NEIGHBOUR, Skeleton, StoredTriangle};
use glam::DVec3;

use super::Triangles;
use super::delaunay::{NONE, Tetrahedralization, morton};
use crate::PagedFile;
use crate::page_writer::{SceneFacts, SkeletonFirst};

/// What the header records besides the tessellation.
#[derive(Debug, Clone, Copy)]
pub struct LayoutInfo {
    pub page_bytes: usize,
    pub input_vertices: u64,
    pub bounds_min: DVec3,
    pub bounds_max: DVec3,
    /// The enlarged box: the tessellation's hull.
    pub box_min: DVec3,
    pub box_max: DVec3,
    /// What the skeleton's f32 positions are relative to (the builder
    /// rounded every vertex to exactly that).
    pub root_center: DVec3,
}

/// The file and what laying it out counted.
#[derive(Debug)]
pub struct Laid {
    pub file: PagedFile,
    pub rho_max: u32,
    /// Triangles stored over all pages (a triangle is stored once per page
    /// holding a cell it meets).
    pub stored_triangles: u64,
}

/// Writes the tessellation `t`, whose cell lists `cells_of` (per triangle)
/// name its cells, as a paged file.
pub fn lay_out(
    t: &Tetrahedralization,
    tris: &Triangles,
    cells_of: &[Vec<u32>],
    info: &LayoutInfo,
) -> Result<Laid, FormatError> {
    // Cell -> its triangles, ascending.
    let mut lists: Vec<Vec<u32>> = vec![Vec::new(); t.cells.len()];
    for (tri, cells) in cells_of.iter().enumerate() {
        for &c in cells {
            lists[c as usize].push(tri as u32);
        }
    }
    // Cells in Morton order of their centroids; `rank[old] = new`.
    let (lo, hi) = (info.box_min, info.box_max);
    let mut order: Vec<(u64, u32)> = t
        .cells
        .iter()
        .enumerate()
        .map(|(c, cell)| {
            let centroid = cell.iter().map(|&v| t.points[v as usize]).sum::<DVec3>() / 4.0;
            (morton((centroid - lo) / (hi - lo)), c as u32)
        })
        .collect();
    order.sort_unstable();
    let mut rank = vec![0u32; t.cells.len()];
    for (new, &(_, old)) in order.iter().enumerate() {
        rank[old as usize] = new as u32;
    }
    let area: Vec<f64> = tris
        .corners
        .iter()
        .map(|[a, b, c]| (*b - *a).cross(*c - *a).length() * 0.5)
        .collect();
    let coverage = |old: u32| -> f32 {
        let [a, b, c, d] = t.cells[old as usize].map(|v| t.points[v as usize]);
        let volume = (b - a).cross(c - a).dot(d - a).abs() / 6.0;
        let sum: f64 = lists[old as usize].iter().map(|&i| area[i as usize]).sum();
        if volume > 0.0 {
            (sum / volume.powf(2.0 / 3.0)) as f32
        } else {
            0.0
        }
    };
    let cells: Vec<Cell> = order
        .iter()
        .map(|&(_, old)| Cell {
            coverage: coverage(old),
            vertices: t.cells[old as usize],
            neighbours: t.neighbours[old as usize].map(|n| {
                if n == NONE {
                    NO_NEIGHBOUR
                } else {
                    rank[n as usize]
                }
            }),
            triangles: lists[old as usize].len() as u32,
        })
        .collect();
    let rho_max = cells.iter().map(|c| c.triangles).max().unwrap_or(0).max(1);
    let root_center = info.root_center;
    let skeleton = Skeleton {
        vertices: t.points.clone(),
        cells,
        rho_max,
        scene_triangles: tris.corners.len() as u64,
        normals: Vec::new(),
    };
    let cell_count = skeleton.cells.len() as u64;
    let mut pages = SkeletonFirst::new(cell_count, &skeleton.encode(root_center));
    // Cut the cells into pages.
    let mut stored = 0u64;
    let mut start = 0usize;
    while start < order.len() {
        let mut page = PageBuilder::default();
        let mut end = start;
        while end < order.len() {
            let list = &lists[order[end].1 as usize];
            if end > start && page.bytes_with(list) > info.page_bytes {
                break;
            }
            page.add(list);
            end += 1;
        }
        let cell_page = page.finish(tris);
        stored += cell_page.triangles.len() as u64;
        let (records, payload) = cell_page.encode();
        pages.push_leaves((end - start) as u32, &records, &payload);
        start = end;
    }
    let file = pages.finish(SceneFacts {
        kind: HierarchyKind::Plp,
        attributes: AttributeFlags {
            color: true,
            normals: false,
            leaf_geometry: true,
        },
        node_bytes: plp_codec::NODE_BYTES as u32,
        input_vertices: info.input_vertices,
        bounds_min: info.bounds_min,
        bounds_max: info.bounds_max,
        root_center,
        root_radius: (hi - lo).length() * 0.5,
    })?;
    Ok(Laid {
        file,
        rho_max,
        stored_triangles: stored,
    })
}

/// One page's cells as they are added.
#[derive(Debug, Default)]
struct PageBuilder {
    /// Scene triangle id -> index among the page's triangles.
    local: HashMap<u32, u32>,
    ids: Vec<u32>,
    lists: Vec<u32>,
    starts: Vec<u32>,
}

impl PageBuilder {
    /// The page's bytes if a cell with triangles `list` were added.
    fn bytes_with(&self, list: &[u32]) -> usize {
        let new = list.iter().filter(|t| !self.local.contains_key(t)).count();
        let cells = self.starts.len() + 1;
        farfield_protocol::page::PAGE_HEADER_BYTES
            + 4
            + cells * plp_codec::NODE_BYTES
            + 28
            + (self.ids.len() + new) * plp_codec::TRIANGLE_BYTES
            + (self.lists.len() + list.len()) * 4
    }

    fn add(&mut self, list: &[u32]) {
        self.starts.push(self.lists.len() as u32);
        for &t in list {
            let next = self.ids.len() as u32;
            let local = *self.local.entry(t).or_insert(next);
            if local == next {
                self.ids.push(t);
            }
            self.lists.push(local);
        }
    }

    /// The page, its corners relative to the lowest corner among them.
    fn finish(mut self, tris: &Triangles) -> CellPage {
        self.starts.push(self.lists.len() as u32);
        let anchor = self
            .ids
            .iter()
            .flat_map(|&t| tris.corners[t as usize])
            .fold(DVec3::INFINITY, DVec3::min);
        let anchor = if anchor.is_finite() {
            anchor
        } else {
            DVec3::ZERO
        };
        let triangles = self
            .ids
            .iter()
            .map(|&t| StoredTriangle {
                id: t,
                corners: tris.corners[t as usize].map(|p| (p - anchor).as_vec3().to_array()),
                rgba: tris.rgba[t as usize],
            })
            .collect();
        CellPage {
            anchor,
            triangles,
            lists: self.lists,
            starts: self.starts,
        }
    }
}
