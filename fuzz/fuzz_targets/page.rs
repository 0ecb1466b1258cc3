//! One page as it arrives on the wire: `Page::parse` (spheres) or
//! `Page::parse_with_payload` (cubes, PLP), then `Hierarchy::insert_page`
//! into a hierarchy whose directory agrees with the page (which is where
//! the node codes, child counts, cube records, PLP skeletons and cell
//! pages and payloads are checked), then the reference decoder and a
//! traversal of what was inserted.
//!
//! Input: a flags byte (bit 0: cubes; bit 4: PLP; bits 1-3: color,
//! normals, leaf geometry; bit 7: keep the checksum as it is instead of
//! recomputing it), the cluster size, a u32 of nodes the directory puts
//! after the page (for its children), then the page.
#![no_main]

use farfield_protocol::cube_codec::RECORD_BYTES;
use farfield_protocol::file::{AttributeFlags, FileHeader, HierarchyKind, PageEntry};
use farfield_protocol::hierarchy::Hierarchy;
use farfield_protocol::page::{Page, claimed_index};
use farfield_protocol::sphere_codec::NodeLayout;
use glam::DVec3;
use libfuzzer_sys::fuzz_target;

/// Most pages put before the fuzzed one in the directory.
const MAX_INDEX: u32 = 64;

fuzz_target!(|data: &[u8]| {
    let Some((head, page)) = data.split_at_checked(6) else {
        return;
    };
    let (flags, cluster) = (head[0], head[1]);
    let after = u32::from_le_bytes(head[2..6].try_into().unwrap());
    let mut page = page.to_vec();
    if flags & 0x80 == 0 {
        farfield_fuzz::fix_page_checksum(&mut page);
    }
    let kind = if flags & 0x10 != 0 {
        HierarchyKind::Plp
    } else if flags & 1 == 0 {
        HierarchyKind::Spheres
    } else {
        HierarchyKind::Cubes
    };
    let attributes = AttributeFlags {
        color: flags & 2 != 0,
        normals: flags & 4 != 0,
        leaf_geometry: flags & 8 != 0,
    };
    let (node_bytes, cluster) = match kind {
        HierarchyKind::Spheres => {
            let layout = NodeLayout {
                normals: attributes.normals,
                color: attributes.color,
            };
            (layout.bytes(), 0)
        }
        HierarchyKind::Cubes => (RECORD_BYTES as u32, cluster),
        HierarchyKind::Plp => (farfield_protocol::plp_codec::NODE_BYTES as u32, 0),
        // Not generated yet: a BSP directory has a page per node.
        HierarchyKind::Bsp => (farfield_protocol::bsp_codec::NODE_BYTES as u32, 0),
    };
    let index = claimed_index(&page).unwrap_or(0);
    let parsed = match kind {
        HierarchyKind::Spheres => Page::parse(&page, index, node_bytes),
        HierarchyKind::Cubes | HierarchyKind::Plp | HierarchyKind::Bsp => {
            Page::parse_with_payload(&page, index, node_bytes)
        }
    };
    let Ok(parsed) = parsed else {
        return;
    };
    let h = parsed.header;
    // A directory the page agrees with: `index` pages before it holding
    // the nodes before its first, then it, then `after` nodes in one page.
    if index > MAX_INDEX || h.node_count == 0 || h.first_node < u64::from(index) {
        return;
    }
    if index == 0 && h.first_node != 0 {
        return;
    }
    let Some(nodes) = h
        .first_node
        .checked_add(u64::from(h.node_count) + u64::from(after))
    else {
        return;
    };
    let plp = kind == HierarchyKind::Plp;
    // A PLP directory: the root's page first (its child the first cell),
    // then cells, which have no children.
    let first_child = |first_node: u64| match (plp, first_node) {
        (false, _) => 0,
        (true, 0) => 1,
        (true, _) => nodes,
    };
    let entry = |first_node: u64, node_count: u32| PageEntry {
        offset: 0,
        length: 0,
        node_count,
        first_node,
        first_child: first_child(first_node),
        level_min: 0,
        level_max: 0,
        checksum: 0,
    };
    let mut pages = Vec::new();
    for i in 0..index {
        let count = if i + 1 < index {
            1
        } else {
            match u32::try_from(h.first_node - u64::from(index - 1)) {
                Ok(n) => n,
                Err(_) => return,
            }
        };
        pages.push(entry(u64::from(i), count));
    }
    // The directory's copy of the page's checksum is the one it carries
    // (a client compares the two before anything else).
    let carried = page
        .last_chunk::<4>()
        .map_or(0, |tail| u32::from_le_bytes(*tail));
    pages.push(PageEntry {
        offset: 0,
        length: page.len() as u32,
        node_count: h.node_count,
        first_node: h.first_node,
        first_child: h.first_child,
        level_min: h.level_min,
        level_max: h.level_max,
        checksum: carried,
    });
    if after > 0 {
        pages.push(entry(h.first_node + u64::from(h.node_count), after));
    }
    let mut header = FileHeader {
        kind,
        attributes,
        node_bytes,
        cluster,
        levels: if plp { 2 } else { u32::from(h.level_max) + 1 },
        nodes,
        leaves: if plp { nodes.saturating_sub(1) } else { 0 },
        input_vertices: 0,
        bounds_min: DVec3::splat(-1.0),
        bounds_max: DVec3::splat(1.0),
        root_center: DVec3::ZERO,
        root_radius: 1.0,
        page_count: 0,
        directory_pages: 0,
        root_directory: Default::default(),
    };
    let directory = farfield_protocol::directory::lay_out_for(&mut header, &mut pages);
    // Through the bytes, as a client gets it: only a header that decodes,
    // and a directory whose pages insert.
    let Ok(header) = FileHeader::decode(&header.encode()) else {
        return;
    };
    let Ok(mut hierarchy) = Hierarchy::new(header) else {
        return;
    };
    for (n, bytes) in directory.pages.iter().enumerate() {
        if hierarchy
            .insert_page(hierarchy.header.page_count + n as u32, bytes)
            .is_err()
        {
            return;
        }
    }
    if hierarchy.insert_page(index, &page).is_ok() {
        farfield_fuzz::exercise(&hierarchy);
        // Inserted twice (a page that arrives again) and evicted.
        hierarchy
            .insert_page(index, &page)
            .expect("the same page inserts again");
        hierarchy.evict_page(index);
        assert_eq!(hierarchy.resident_bytes(), 0);
    }
});
