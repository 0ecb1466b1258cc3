//! Image caching's BSP drawn with hierarchical culling alone (the
//! impostors' baseline): every triangle drawn once, leaves back to front,
//! placed prototypes drawn as the CPU would place them, and streaming that
//! asks only for what the view needs.

use farfield_builder::PagedFile;
use farfield_builder::bsp::{BspOptions, build_bsp};
use farfield_builder::import::{Params, load_input};
use farfield_protocol::bsp_codec::{ContentPage, Split};
use farfield_protocol::camera::Camera;
use farfield_protocol::hierarchy::{BspPage, Hierarchy};
use farfield_render::GpuVertex;
use farfield_traverse::TraversalOptions;
use farfield_traverse::bsp::{BspCut, leaf_page, traverse_bsp_into};
use glam::DVec3;

use crate::{resident, resident_where};

/// A small island: a terrain mesh and a few trees, one shared prototype.
fn island_file() -> PagedFile {
    let mut params = Params::default();
    params.set("trees", 12);
    params.set("size", 33);
    params.set("tree_triangles", 1000);
    let scene = load_input("gen:island", &params).expect("gen:island");
    let options = BspOptions {
        leaf_triangles: 200,
        ..BspOptions::default()
    };
    build_bsp(&scene, &options).expect("bsp").0
}

fn overview(h: &Hierarchy) -> Camera {
    let (c, r) = (h.header.root_center, h.header.root_radius);
    Camera::orbit(c, r, 35.0, 40.0, 2.2, 200, 150)
}

fn walk(h: &Hierarchy, camera: &Camera) -> BspCut {
    let mut cut = BspCut::default();
    traverse_bsp_into(h, camera, true, &mut cut);
    cut
}

/// Every leaf's own triangles and placements, expanded on the CPU in f64:
/// what the file holds, independent of the traversal and of instancing.
fn everything(h: &Hierarchy, eye: DVec3) -> Vec<GpuVertex> {
    let s = h.bsp_skeleton().expect("page 0");
    let mut out = Vec::new();
    let mut push = |corners: [DVec3; 3], rgba: [u8; 4]| {
        for c in corners {
            out.push(GpuVertex {
                position: (c - eye).as_vec3().to_array(),
                normal: [0; 4],
                color: rgba,
            });
        }
    };
    for leaf in 0..s.leaves {
        let page = leaf_page(h, s.leaf_page(leaf)).expect("resident");
        for t in page.triangles.iter().take(page.own_triangles as usize) {
            push(t.corners.map(|c| page.world(c)), t.rgba);
        }
        for p in page.placements.iter().take(page.own_placements as usize) {
            let world = p.world_from_local(page.anchor);
            let page = farfield_protocol::bsp_codec::BspSkeleton::prototype_page(p.prototype);
            let Some(BspPage::Content(ContentPage::Prototype(proto))) =
                h.page(page as usize).and_then(|p| p.bsp())
            else {
                panic!("prototype page {page} is not resident");
            };
            for t in &proto.triangles {
                push(
                    t.corners
                        .map(|c| world.transform_point3(DVec3::from(c.map(f64::from)))),
                    t.rgba,
                );
            }
        }
    }
    out
}

#[test]
fn culling_draws_every_triangle_once_as_the_file_holds_it() {
    let file = island_file();
    let h = resident(&file);
    let s = h.bsp_skeleton().expect("page 0");
    assert!(
        s.leaves > 8 && !s.prototypes.is_empty(),
        "{} leaves",
        s.leaves
    );
    let camera = overview(&h);
    let cut = walk(&h, &camera);
    // The whole island is in view: every triangle, each once (inflation
    // stores some twice; only the owner draws them).
    assert_eq!(cut.triangles, s.scene_triangles);
    assert_eq!(cut.leaves.len(), s.leaves as usize);
    assert!(cut.instances.len() >= 10, "{} trees", cut.instances.len());
    assert!(cut.wanted.is_empty());
    let Some(mut renderer) = farfield_render::headless_or_skip(200, 150).expect("adapter") else {
        return;
    };
    let mut traversal = (farfield_traverse::named("culling")
        .expect("registered")
        .make)();
    for camera in [
        camera,
        // Low, from the shore, part of the island out of view.
        Camera {
            eye: h.header.root_center + DVec3::new(h.header.root_radius * 0.8, 0.0, 30.0),
            target: h.header.root_center,
            up: DVec3::Z,
            fov_y_deg: 50.0,
            width: 200,
            height: 150,
        },
    ] {
        traversal.traverse(&h, &camera, &TraversalOptions::default());
        let image = renderer
            .draw(&h, &camera, traversal.draw_list(), &Default::default())
            .expect("draws");
        let vertices = everything(&h, camera.eye);
        let expected = renderer
            .render_geometry(&camera, &vertices, &[], Default::default(), [0; 3])
            .expect("draws");
        let drawn = image.rgba.chunks(4).filter(|p| p[..3] != [0, 0, 0]).count();
        assert!(drawn > 200 * 150 / 4, "drew {drawn} pixels");
        // Instances are placed on the GPU in f32 (the CPU's in f64): a
        // few edge pixels may differ, by a little.
        let m = farfield_image::compare(&expected.rgba, &image.rgba, 200, 150, 8).expect("size");
        assert!(
            m.wrong_fraction < 0.002,
            "{:.4} of the pixels differ from the file's geometry",
            m.wrong_fraction
        );
    }
}

#[test]
fn leaves_come_back_to_front_and_culled_views_draw_nothing() {
    let file = island_file();
    let h = resident(&file);
    let s = h.bsp_skeleton().expect("page 0");
    let (c, r) = (h.header.root_center, h.header.root_radius);
    // The leaves under each node, to check each split's order.
    let mut under: Vec<Vec<u32>> = vec![Vec::new(); s.nodes.len()];
    for i in (0..s.nodes.len()).rev() {
        under[i] = match s.nodes[i].split {
            Split::Leaf { leaf } => vec![leaf],
            Split::Plane { back, front, .. } => {
                let mut v = under[back as usize].clone();
                v.extend(&under[front as usize]);
                v
            }
        };
    }
    for (az, el, d) in [(0.0, 30.0, 1.5), (120.0, 10.0, 0.6), (250.0, 60.0, 0.3)] {
        let camera = Camera::orbit(c, r, az, el, d, 200, 150);
        let cut = walk(&h, &camera);
        assert!(!cut.leaves.is_empty());
        let rank = |leaf: u32| cut.leaves.iter().position(|l| l.leaf == leaf);
        for node in &s.nodes {
            let Split::Plane {
                direction,
                offset,
                back,
                front,
            } = node.split
            else {
                continue;
            };
            let d = s.directions[direction as usize];
            let eye_front = d.dot(camera.eye - c) > offset;
            let (far, near) = if eye_front {
                (back, front)
            } else {
                (front, back)
            };
            let last_far = under[far as usize].iter().filter_map(|&l| rank(l)).max();
            let first_near = under[near as usize].iter().filter_map(|&l| rank(l)).min();
            if let (Some(a), Some(b)) = (last_far, first_near) {
                assert!(a < b, "camera {az}: a far leaf drawn after a near one");
            }
        }
    }
    // Looking away from the island: nothing drawn, nothing wanted.
    let away = Camera {
        eye: c + DVec3::new(r * 3.0, 0.0, 0.0),
        target: c + DVec3::new(r * 6.0, 0.0, 0.0),
        up: DVec3::Z,
        fov_y_deg: 40.0,
        width: 200,
        height: 150,
    };
    let cut = walk(&h, &away);
    assert!(cut.leaves.is_empty() && cut.instances.is_empty());
    assert_eq!(cut.triangles, 0);
    assert!(cut.frustum_culled >= 1);
}

#[test]
fn streamed_the_view_wants_its_leaves_then_their_prototypes() {
    let file = island_file();
    let whole = resident(&file);
    let s = whole.bsp_skeleton().expect("page 0").clone();
    let prototypes = s.prototypes.len() as u32;
    let (c, r) = (whole.header.root_center, whole.header.root_radius);
    // From the shore, looking along the island: part of it out of view.
    let camera = Camera {
        eye: c + DVec3::new(-r * 0.9, 0.0, 20.0),
        target: c + DVec3::new(0.0, r * 0.3, 0.0),
        up: DVec3::Z,
        fov_y_deg: 40.0,
        width: 200,
        height: 150,
    };
    let in_view: Vec<u32> = walk(&whole, &camera)
        .leaves
        .iter()
        .map(|l| l.page)
        .collect();
    assert!(
        !in_view.is_empty() && in_view.len() < s.leaves as usize,
        "{} of {} leaves in view",
        in_view.len(),
        s.leaves
    );
    // Page 0 alone: the leaves in view are wanted, no others, nothing drawn.
    let only_zero = resident_where(&file, |i| i == 0);
    let cut = walk(&only_zero, &camera);
    let mut wanted: Vec<u32> = cut.wanted.iter().map(|w| w.page).collect();
    wanted.sort_unstable();
    let mut expected = in_view.clone();
    expected.sort_unstable();
    assert_eq!(wanted, expected);
    assert!(cut.leaves.is_empty() && cut.triangles == 0);
    // Leaves resident, prototypes not: the leaves draw their own
    // triangles, and their trees in view want the prototype's page.
    let leaves_only = resident_where(&file, |i| i == 0 || i as u32 > prototypes);
    let cut = walk(&leaves_only, &camera);
    assert_eq!(cut.leaves.len(), in_view.len());
    assert!(cut.instances.is_empty());
    let wanted: Vec<u32> = cut.wanted.iter().map(|w| w.page).collect();
    assert!(!wanted.is_empty());
    assert!(
        wanted.iter().all(|&p| p >= 1 && p <= prototypes),
        "{wanted:?}"
    );
    // With everything resident the same view wants nothing.
    assert!(walk(&whole, &camera).wanted.is_empty());
}
