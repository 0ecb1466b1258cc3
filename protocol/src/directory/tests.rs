use super::*;
use crate::file::{AttributeFlags, FileHeader, HierarchyKind};
use glam::DVec3;

/// Entries of `pages` pages of `per_page` nodes each, breadth-first with
/// every node's children in the next page (a shape the lookups do not
/// care about beyond the order).
fn entries(pages: u32, per_page: u32) -> Vec<PageEntry> {
    (0..pages)
        .map(|i| PageEntry {
            offset: 0,
            length: 100 + i % 7,
            node_count: per_page,
            first_node: u64::from(i) * u64::from(per_page),
            first_child: (u64::from(i) * u64::from(per_page) + 1).min(u64::from(pages * per_page)),
            level_min: 0,
            level_max: 0,
            checksum: i.wrapping_mul(2654435761),
        })
        .collect()
}

fn header(pages: u32, nodes: u64, layout: &DirectoryLayout) -> FileHeader {
    FileHeader {
        kind: HierarchyKind::Spheres,
        attributes: AttributeFlags::default(),
        node_bytes: 2,
        cluster: 0,
        levels: 1,
        nodes,
        leaves: 1,
        input_vertices: 1,
        bounds_min: DVec3::ZERO,
        bounds_max: DVec3::ONE,
        root_center: DVec3::splat(0.5),
        root_radius: 1.0,
        page_count: pages,
        directory_pages: layout.count(),
        root_directory: layout.root,
    }
}

/// A whole file's directory for `pages` pages, and the entries placed.
fn whole(pages: u32) -> (Directory, Vec<PageEntry>, DirectoryLayout) {
    let mut e = entries(pages, 3);
    let nodes = u64::from(pages) * 3;
    let layout = lay_out(&mut e, nodes);
    let h = header(pages, nodes, &layout);
    // Where each directory page is: the root after the header, the others
    // after the scene's pages, in number order.
    let mut at = e.last().map_or(0, |x| x.offset + u64::from(x.length));
    let mut placed = vec![(layout.root.offset, layout.pages[0].clone())];
    for bytes in layout.tail() {
        placed.push((at, bytes.clone()));
        at += bytes.len() as u64;
    }
    let dir = Directory::read_all(&h, |offset, length| {
        placed
            .iter()
            .find(|(o, b)| *o == offset && b.len() == length as usize)
            .map(|(_, b)| b.clone())
            .ok_or(FormatError::BadHeader(format!(
                "no directory page at {offset}"
            )))
    })
    .unwrap();
    (dir, e, layout)
}

#[test]
fn a_small_scene_is_its_root_alone() {
    let (dir, e, layout) = whole(10);
    assert_eq!(layout.count(), 1);
    assert!(dir.is_complete());
    dir.check_whole().unwrap();
    for (i, entry) in e.iter().enumerate() {
        assert_eq!(dir.entry(i as u32), Some(*entry));
    }
    // The pages follow the header and the root.
    assert_eq!(
        e[0].offset,
        (FileHeader::ENCODED_LEN + layout.pages[0].len()) as u64
    );
}

#[test]
fn a_large_scene_is_reached_through_every_level() {
    // Enough pages for inner directory pages under the root.
    let pages = (ROOT_ENTRIES + ROOT_CHILDREN * FANOUT + 3 * FANOUT + 5) as u32;
    let (dir, e, layout) = whole(pages);
    assert!(
        layout.count() > 1 + ROOT_CHILDREN as u32,
        "{}",
        layout.count()
    );
    dir.check_whole().unwrap();
    let found: Vec<(u32, PageEntry)> = dir.entries().collect();
    assert_eq!(found.len(), e.len());
    for (i, entry) in e.iter().enumerate() {
        assert_eq!(found[i], (i as u32, *entry));
        assert_eq!(dir.locate(entry.first_node + 2), Locate::Page(i as u32));
    }
    assert_eq!(dir.locate(u64::from(pages) * 3), Locate::Outside);
    // The directory's pages lie after the scene's, one after another.
    let end = e.last().map(|x| x.offset + u64::from(x.length)).unwrap();
    let tail: u64 = layout.tail().iter().map(|b| b.len() as u64).sum();
    assert_eq!(dir.file_len(), end + tail);
    // The root is small whatever the scene.
    assert!(
        layout.pages[0].len() <= 24 << 10,
        "{}",
        layout.pages[0].len()
    );
}

#[test]
fn a_client_learns_the_directory_as_it_goes() {
    let pages = (ROOT_ENTRIES + 3 * FANOUT) as u32;
    let (whole_dir, e, layout) = whole(pages);
    let h = header(pages, u64::from(pages) * 3, &layout);
    let mut dir = Directory::new(&h);
    let deep = e.last().unwrap().first_node;
    assert_eq!(dir.locate(0), Locate::Missing(pages));
    dir.insert(pages, &layout.pages[0]).unwrap();
    assert_eq!(dir.locate(0), Locate::Page(0));
    let Locate::Missing(id) = dir.locate(deep) else {
        panic!("the deep page's directory page should be missing");
    };
    assert!(dir.entry(pages - 1).is_none());
    // The last directory page, its id after the scene's pages.
    assert_eq!(id, pages + layout.count() - 1);
    // A directory page whose parent has not arrived cannot be checked; here
    // the parent (the root) has arrived.
    dir.insert(id, &layout.pages[(id - pages) as usize])
        .unwrap();
    assert_eq!(dir.locate(deep), Locate::Page(pages - 1));
    assert_eq!(dir.entry(pages - 1), whole_dir.entry(pages - 1));
    assert_eq!(dir.children_end(pages - 1), Some(u64::from(pages) * 3));
    assert_eq!(dir.inserted(), 2);
    assert!(!dir.is_complete());
}

#[test]
fn damaged_directory_pages_are_refused() {
    let pages = (ROOT_ENTRIES + 2 * FANOUT) as u32;
    let (_, _, layout) = whole(pages);
    let h = header(pages, u64::from(pages) * 3, &layout);
    let mut dir = Directory::new(&h);
    // A flipped byte, a truncated page, another directory page in its place.
    let mut flipped = layout.pages[0].clone();
    flipped[100] ^= 1;
    assert!(dir.insert(pages, &flipped).is_err());
    assert!(dir.insert(pages, &layout.pages[0][..50]).is_err());
    assert!(dir.insert(pages, &layout.pages[1]).is_err());
    // A child before its parent.
    assert!(dir.insert(pages + 1, &layout.pages[1]).is_err());
    // No such page.
    assert!(
        dir.insert(pages + layout.count(), &layout.pages[0])
            .is_err()
    );
    assert_eq!(dir.inserted(), 0);
    dir.insert(pages, &layout.pages[0]).unwrap();
    // A child swapped for its sibling (right bytes, wrong place).
    assert!(dir.insert(pages + 1, &layout.pages[2]).is_err());
    dir.insert(pages + 1, &layout.pages[1]).unwrap();
}

#[test]
fn a_forged_page_with_a_fresh_checksum_is_still_refused() {
    // Checks a page's own consistency even when its checksum matches the
    // reference (a builder's mistake): an entry that skips nodes.
    let mut e = entries(4, 3);
    e[2].first_node += 1;
    let layout = lay_out(&mut e, 12);
    let h = header(4, 12, &layout);
    let mut dir = Directory::new(&h);
    let err = dir.insert(4, &layout.pages[0]).unwrap_err();
    assert!(err.to_string().contains("node order"), "{err}");
}

/// A clone (the server's whole directory, handed to each read-ahead
/// walker) shares the directory pages instead of copying them, and what
/// is inserted into one is not seen by the other.
#[test]
fn a_clone_shares_its_directory_pages_and_inserts_apart() {
    let pages = (ROOT_ENTRIES + 2 * FANOUT) as u32;
    let (whole_dir, _, layout) = whole(pages);
    let copy = whole_dir.clone();
    for n in 0..layout.count() {
        assert!(
            Arc::ptr_eq(&whole_dir.pages[&n], &copy.pages[&n]),
            "directory page {n} was copied"
        );
    }
    let h = header(pages, u64::from(pages) * 3, &layout);
    let mut partial = Directory::new(&h);
    partial.insert(pages, &layout.pages[0]).unwrap();
    let mut grown = partial.clone();
    grown.insert(pages + 1, &layout.pages[1]).unwrap();
    assert_eq!((partial.inserted(), grown.inserted()), (1, 2));
    assert!(!partial.has(pages + 1) && grown.has(pages + 1));
}
