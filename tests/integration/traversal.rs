//! The reference traversal: complete where nothing is culled, conservative
//! where backfaces are, and partial (with wanted pages) while streaming.

use farfield_builder::import::{Params, load_input};
use farfield_protocol::camera::Camera;
use farfield_protocol::hierarchy::Hierarchy;
use farfield_traverse::spheres::{TraverseOptions, traverse};

use crate::{build, resident};

fn island() -> farfield_builder::PagedFile {
    let mut params = Params::default();
    params.set("size", 96);
    params.set("trees", 3);
    build(load_input("gen:island", &params).expect("gen:island"))
}

fn camera(h: &Hierarchy) -> Camera {
    Camera::orbit(
        h.header.root_center,
        h.header.root_radius,
        30.0,
        35.0,
        3.0,
        800,
        600,
    )
}

#[test]
fn threshold_zero_without_culling_draws_every_leaf() {
    let file = island();
    let h = resident(&file);
    let options = TraverseOptions {
        threshold_px: 0.0,
        backface_culling: false,
        ..Default::default()
    };
    let cut = traverse(&h, &camera(&h), &options);
    assert_eq!(cut.splats.len() as u64, file.header.leaves);
    assert_eq!(cut.visited, file.header.nodes);
    assert!(cut.wanted.is_empty());
}

#[test]
fn backface_culling_keeps_every_leaf_that_faces_the_eye() {
    let file = island();
    let h = resident(&file);
    let cam = camera(&h);
    let options = TraverseOptions {
        threshold_px: 0.0,
        backface_culling: true,
        ..Default::default()
    };
    let cut = traverse(&h, &cam, &options);
    assert!(cut.backface_culled > 0, "nothing was culled");
    let drawn: std::collections::HashSet<u64> = cut.splats.iter().map(|s| s.node).collect();
    let mut facing = 0;
    for n in h.decode_all().iter().filter(|n| n.children == 0) {
        let normal = n.normal.unwrap().as_dvec3();
        if normal.dot(cam.eye - n.center) > 0.0 {
            facing += 1;
            assert!(
                drawn.contains(&n.index),
                "leaf {} faces the eye but was culled",
                n.index
            );
        }
    }
    assert!(facing > 0 && (cut.splats.len() as u64) < file.header.leaves);
}

#[test]
fn coarser_thresholds_draw_fewer_splats() {
    let file = island();
    let h = resident(&file);
    let cam = camera(&h);
    let counts: Vec<usize> = [0.5, 2.0, 8.0, 32.0]
        .iter()
        .map(|&t| {
            traverse(
                &h,
                &cam,
                &TraverseOptions {
                    threshold_px: t,
                    ..Default::default()
                },
            )
            .splats
            .len()
        })
        .collect();
    assert!(counts.windows(2).all(|w| w[0] > w[1]), "{counts:?}");
}

#[test]
fn page_zero_alone_gives_a_cut_and_asks_for_the_next_pages() {
    let file = island();
    let mut h = crate::with_directory(&file);
    let cam = camera(&h);
    let options = TraverseOptions {
        threshold_px: 1.0,
        ..Default::default()
    };
    // Nothing resident: the only wish is page 0.
    let cut = traverse(&h, &cam, &options);
    assert!(cut.splats.is_empty());
    assert_eq!(cut.wanted.first().map(|w| w.page), Some(0));
    h.insert_page(0, &file.pages[0]).unwrap();
    let cut = traverse(&h, &cam, &options);
    let page0_nodes = u64::from(file.directory.entry(0).unwrap().node_count);
    assert!(!cut.splats.is_empty());
    assert!(cut.splats.iter().all(|s| s.node < page0_nodes));
    assert!(!cut.wanted.is_empty() && cut.wanted.iter().all(|w| w.page > 0));
    assert!(
        cut.wanted
            .windows(2)
            .all(|w| w[0].priority >= w[1].priority)
    );
    // A corrupt page is refused and changes nothing.
    let mut bad = file.pages[1].clone();
    bad[40] ^= 0x10;
    assert!(h.insert_page(1, &bad).is_err());
    assert!(!h.is_resident(1));
}
