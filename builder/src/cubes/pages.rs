//! The octree in breadth-first order, cut into pages (the same paged file
//! as the sphere hierarchy; `FORMAT.md`): page 0 holds whole levels from
//! the root, every other page whole sibling groups up to the page size
//! (a group bigger than a page gets a page of its own). Each page's
//! payload section holds its cells' sub-cubes and leaf geometry, in order.

use farfield_protocol::FormatError;
use farfield_protocol::cube_codec::{self, CubeRecord, Rgba8, SubCube};
use farfield_protocol::file::{AttributeFlags, FileHeader, HierarchyKind};
use farfield_protocol::page::{PAGE_CHECKSUM_BYTES, PAGE_HEADER_BYTES, PageHeader};
use farfield_protocol::paged_file::PagedFile;
use glam::DVec3;

use super::composite::Faces;
use super::octree::Cell;
use crate::page_writer::PageWriter;

/// What the header needs besides the cells.
#[derive(Debug, Clone, Copy)]
pub struct LayoutInfo {
    pub page_bytes: usize,
    pub cluster: u8,
    pub attributes: AttributeFlags,
    pub input_vertices: u64,
    pub bounds_min: DVec3,
    pub bounds_max: DVec3,
    pub root_center: DVec3,
    pub root_half_edge: f64,
}

/// One cell, encoded, in breadth-first order.
struct Encoded {
    record: [u8; cube_codec::RECORD_BYTES],
    payload: Vec<u8>,
    level: u16,
    children: u32,
}

/// Premultiplied f32 faces to bytes (alpha clamped to 0..1, color to alpha).
pub fn to_rgba8(faces: &Faces) -> [Rgba8; 6] {
    faces.map(|f| {
        let a = f[3].clamp(0.0, 1.0);
        let q = |v: f32| (v.clamp(0.0, a) * 255.0).round() as u8;
        [q(f[0]), q(f[1]), q(f[2]), (a * 255.0).round() as u8]
    })
}

/// Encodes the cells breadth-first and cuts them into pages.
pub fn lay_out(root: &Cell, info: LayoutInfo) -> Result<PagedFile, FormatError> {
    let mut cells: Vec<Encoded> = Vec::new();
    let mut queue = std::collections::VecDeque::from([(root, 0u16)]);
    let (mut leaves, mut levels) = (0u64, 0u32);
    while let Some((cell, level)) = queue.pop_front() {
        levels = levels.max(u32::from(level) + 1);
        leaves += u64::from(cell.children.is_empty());
        let sub: Vec<SubCube> = cell
            .sub
            .iter()
            .map(|(i, f)| SubCube {
                cell: *i,
                faces: to_rgba8(f),
            })
            .collect();
        let payload = cube_codec::encode_payload(&sub, cell.geometry.as_ref());
        let record = CubeRecord {
            children: cell.mask,
            sub_cubes: sub.len() as u16,
            faces: to_rgba8(&cell.faces),
            payload_bytes: payload.len() as u32,
        };
        cells.push(Encoded {
            record: record.pack(),
            payload,
            level,
            children: cell.children.len() as u32,
        });
        for child in &cell.children {
            queue.push_back((child, level + 1));
        }
    }
    // first_child[n] = 1 + the children of every cell before n.
    let mut first_child = Vec::with_capacity(cells.len());
    let mut next = 1u64;
    for c in &cells {
        first_child.push(next);
        next += u64::from(c.children);
    }
    // Sibling groups: the root alone, then each parent's children.
    // The root is a group of its own.
    let mut groups: Vec<std::ops::Range<usize>> = Vec::with_capacity(cells.len() / 4 + 1);
    groups.push(0..1);
    let mut start = 1usize;
    for c in &cells {
        if c.children > 0 {
            groups.push(start..start + c.children as usize);
            start += c.children as usize;
        }
    }
    let bytes_of = |r: &std::ops::Range<usize>| -> usize {
        cells[r.clone()]
            .iter()
            .map(|c| cube_codec::RECORD_BYTES + c.payload.len())
            .sum()
    };
    let budget = info
        .page_bytes
        .saturating_sub(PAGE_HEADER_BYTES + PAGE_CHECKSUM_BYTES);
    // Page 0: whole levels while they fit (the root level always).
    let mut page0_end = 1usize;
    let mut level_start = 1usize;
    let mut used = bytes_of(&(0..1));
    while level_start < cells.len() {
        let level = cells[level_start].level;
        let level_end = level_start
            + cells[level_start..]
                .iter()
                .take_while(|c| c.level == level)
                .count();
        let add = bytes_of(&(level_start..level_end));
        if used + add > budget {
            break;
        }
        used += add;
        page0_end = level_end;
        level_start = level_end;
    }
    let mut ranges: Vec<std::ops::Range<usize>> = Vec::new();
    ranges.push(0..page0_end);
    let mut current: Option<std::ops::Range<usize>> = None;
    let mut current_bytes = 0usize;
    for g in groups.into_iter().filter(|g| g.start >= page0_end) {
        let b = bytes_of(&g);
        match current.as_mut() {
            Some(r) if current_bytes + b <= budget => {
                r.end = g.end;
                current_bytes += b;
            }
            _ => {
                if let Some(r) = current.take() {
                    ranges.push(r);
                }
                current = Some(g);
                current_bytes = b;
            }
        }
    }
    ranges.extend(current);
    let mut pages = PageWriter::default();
    for (i, r) in ranges.into_iter().enumerate() {
        let header = PageHeader {
            index: i as u32,
            first_node: r.start as u64,
            first_child: first_child[r.start],
            node_count: r.len() as u32,
            level_min: cells[r.start].level,
            level_max: cells[r.end - 1].level,
        };
        let mut records = Vec::with_capacity(r.len() * cube_codec::RECORD_BYTES);
        let mut payload = Vec::new();
        for c in &cells[r] {
            records.extend_from_slice(&c.record);
            payload.extend_from_slice(&c.payload);
        }
        pages.push(&header, &records, &payload);
    }
    pages.finish(FileHeader {
        kind: HierarchyKind::Cubes,
        attributes: info.attributes,
        node_bytes: cube_codec::RECORD_BYTES as u32,
        cluster: info.cluster,
        levels,
        nodes: cells.len() as u64,
        leaves,
        input_vertices: info.input_vertices,
        bounds_min: info.bounds_min,
        bounds_max: info.bounds_max,
        root_center: info.root_center,
        root_radius: info.root_half_edge,
        page_count: 0,
        directory_pages: 0,
        root_directory: Default::default(),
    })
}
