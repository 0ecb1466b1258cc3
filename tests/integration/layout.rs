//! The breadth-first paged layout: page 0 is the coarse model, children
//! only point forward, and a flipped bit anywhere is caught.

use farfield_builder::PagedFile;
use farfield_builder::import::{Params, load_input};
use farfield_builder::scene::{Geometry, Primitives, Scene};
use farfield_protocol::file::FileHeader;
use farfield_tests::scratch;
use glam::DVec3;

use crate::{build, cli, resident, write_and_open};

fn island() -> PagedFile {
    island_of(128, 4)
}

/// `gen:island` with `size` x `size` terrain vertices and `trees` trees.
fn island_of(size: u32, trees: u32) -> PagedFile {
    let mut params = Params::default();
    params.set("size", size);
    params.set("trees", trees);
    build(load_input("gen:island", &params).expect("gen:island"))
}

/// Builds with `work` on 1 and on 3 threads, checks that the two files are
/// the same (header, pages and where each vertex landed) and returns one.
fn the_same_on_1_and_3_threads(work: impl Fn() -> PagedFile + Send + Sync) -> PagedFile {
    let on = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool")
            .install(&work)
    };
    let (one, three) = (on(1), on(3));
    assert!(
        one.header == three.header,
        "headers differ between 1 and 3 threads"
    );
    let differing = one
        .pages
        .iter()
        .zip(&three.pages)
        .filter(|(a, b)| a != b)
        .count();
    assert_eq!(differing, 0, "pages differ between 1 and 3 threads");
    assert!(
        one.leaf_sources == three.leaf_sources,
        "vertices land in other nodes on 1 and 3 threads"
    );
    one
}

#[test]
fn the_file_is_the_same_on_any_thread_count() {
    // The tree's tasks, the leaves' vertex ranges and the layout's task
    // sizes all depend on the thread count; the bytes must not.
    let one = the_same_on_1_and_3_threads(island);
    assert!(one.header.nodes > 50_000, "{} nodes", one.header.nodes);
}

#[test]
fn a_point_cloud_is_the_same_on_any_thread_count() {
    // Point clouds are sized by nearest neighbours: the k-d tree's halves
    // build on two threads from 16 Ki points, and the searches are split
    // into tasks. A wavy sheet with every tenth point doubled.
    let cloud = || {
        let positions: Vec<DVec3> = (0..60_000u32)
            .map(|i| {
                let (x, y) = (f64::from(i % 250), f64::from(i / 250 % 240));
                let jitter = f64::from(i.wrapping_mul(2_654_435_761) >> 20) / 4096.0;
                DVec3::new(x + jitter * 0.3, y, (x * 0.05).sin() * 4.0 + jitter * 0.1)
            })
            .flat_map(|p| {
                [p].into_iter()
                    .chain((p.x as u32).is_multiple_of(10).then_some(p))
            })
            .collect();
        build(Scene::single(Geometry::new(
            "cloud",
            positions,
            Primitives::Points,
        )))
    };
    let one = the_same_on_1_and_3_threads(cloud);
    assert!(one.header.nodes > 60_000, "{} nodes", one.header.nodes);
}

#[test]
fn the_header_counts_levels_with_the_root_as_one() {
    let one_point = Scene::single(Geometry::new("point", vec![DVec3::ONE], Primitives::Points));
    assert_eq!(build(one_point).header.levels, 1, "the root alone");
    let file = island();
    let deepest = resident(&file)
        .decode_all()
        .iter()
        .map(|n| n.level)
        .max()
        .expect("nodes");
    assert_eq!(file.header.levels, deepest + 1);
}

#[test]
fn levels_of_many_windows_are_the_same_on_any_thread_count() {
    // The layout quantizes a level in windows of 32 Ki parents and places
    // each while the next is quantized; on one thread the two take turns.
    // A terrain of 512 x 512 vertices has levels of more parents than that.
    let one = the_same_on_1_and_3_threads(|| island_of(512, 0));
    let mut parents_per_level = vec![0usize; one.header.levels as usize];
    for node in resident(&one).decode_all() {
        if node.children > 0 {
            parents_per_level[node.level as usize] += 1;
        }
    }
    let widest = parents_per_level.iter().copied().max().unwrap_or(0);
    assert!(widest > 2 * 32 * 1024, "widest level has {widest} parents");
}

#[test]
fn page_zero_holds_whole_first_levels_and_children_point_forward() {
    let file = island();
    let h = resident(&file);
    let nodes = h.decode_all();
    assert_eq!(
        nodes.len() as u64,
        file.header.nodes,
        "every node reachable"
    );
    let page0 = &file.directory.entry(0).unwrap();
    assert!(
        page0.level_max >= 3,
        "page 0 holds only levels 0..={}",
        page0.level_max
    );
    assert!(
        file.header.page_count > 1,
        "test scene should need several pages"
    );
    for n in &nodes {
        let in_page0 = n.index < u64::from(page0.node_count);
        assert_eq!(
            in_page0,
            n.level <= u32::from(page0.level_max),
            "node {} at level {}",
            n.index,
            n.level
        );
        if n.children > 0 {
            assert!(
                n.first_child > n.index,
                "node {} points back to {}",
                n.index,
                n.first_child
            );
        }
    }
    // Breadth-first: levels never decrease along the file.
    assert!(
        nodes
            .windows(2)
            .all(|w| w[0].index + 1 == w[1].index && w[0].level <= w[1].level)
    );
    for p in &file.pages {
        assert!(p.len() <= farfield_builder::DEFAULT_PAGE_BYTES);
    }
}

#[test]
fn a_flipped_bit_in_any_page_is_reported_by_inspect() {
    let dir = scratch("flip");
    let path = dir.join("island.ff");
    let file = island();
    let scene = write_and_open(&file, &path);
    let report = cli(&["inspect", path.to_str().unwrap(), "--json"]).unwrap();
    assert_eq!(report.json["corrupt_pages"], 0);
    assert_eq!(report.exit_code, 0);
    // How the pages are stored, counted from the file's own bytes.
    let pages = scene.header.page_count as usize;
    // The header has one size; the root directory page follows it, and
    // page 0 the root: the first image's bytes.
    assert_eq!(report.json["header_bytes"], FileHeader::ENCODED_LEN);
    let page0 = scene.directory.entry(0).unwrap();
    assert_eq!(
        report.json["first_image_bytes"],
        page0.offset + u64::from(page0.length)
    );
    let stored: u64 = file.pages.iter().map(|p| p.len() as u64 - 44).sum();
    assert_eq!(report.json["page_body_bytes_stored"], stored);
    let decoded = report.json["page_body_bytes_decoded"].as_u64().unwrap();
    let compressed = report.json["compressed_pages"].as_u64().unwrap() as usize;
    assert!(
        decoded > stored && compressed > pages / 2 && compressed <= pages,
        "{}",
        report.json
    );
    let original = std::fs::read(&path).unwrap();
    for (i, entry) in scene.directory.entries().map(|(i, e)| (i as usize, e)) {
        // A different bit in each page: header, records and checksum bytes.
        let byte = entry.offset as usize + (i * 7919) % entry.length as usize;
        let mut bytes = original.clone();
        bytes[byte] ^= 1 << (i % 8);
        let bad = dir.join(format!("bad{i}.ff"));
        std::fs::write(&bad, &bytes).unwrap();
        let report = cli(&["inspect", bad.to_str().unwrap(), "--json"]).unwrap();
        assert_eq!(report.json["corrupt_pages"], 1, "page {i}, byte {byte}");
        assert_eq!(report.json["corrupt"][0]["page"], i);
        assert_eq!(report.exit_code, 2);
    }
    // A flipped bit in the header is a clear error, not a misread.
    let mut bytes = original.clone();
    bytes[40] ^= 4;
    std::fs::write(dir.join("badheader.ff"), &bytes).unwrap();
    let err = cli(&["inspect", dir.join("badheader.ff").to_str().unwrap()]).unwrap_err();
    assert!(err.to_string().contains("header checksum"), "{err}");
}

#[test]
fn file_size_and_attribute_bits_follow_the_scene() {
    let file = island();
    assert!(file.header.attributes.color && file.header.attributes.normals);
    assert_eq!(file.header.node_bytes, 6);
    let bytes = file.to_bytes().len();
    let per_node = bytes as f64 / file.header.nodes as f64;
    assert!(per_node <= 6.5, "{per_node} bytes per node with color");
}
