use farfield_protocol::bsp_codec::{BspSkeleton, ContentPage, Split};
use farfield_protocol::hierarchy::{BspPage, Hierarchy};
use farfield_protocol::paged_file::read_image;
use glam::{DAffine3, DMat3, DVec3};

use super::*;
use crate::scene::{Geometry, Instance, Primitives};

/// A flat `n x n` grid of quads over `[0, side]^2` at z = 0.
fn terrain(n: u32, side: f64) -> Geometry {
    let mut positions = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let s = side / f64::from(n);
            positions.push(DVec3::new(f64::from(i) * s, f64::from(j) * s, 0.0));
        }
    }
    let mut tris = Vec::new();
    let at = |i: u32, j: u32| j * (n + 1) + i;
    for j in 0..n {
        for i in 0..n {
            tris.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
            tris.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    Geometry::new("terrain", positions, Primitives::Triangles(tris))
}

/// A small tetrahedron-like "tree" of 4 triangles, 1 unit across and 2 tall.
fn tree() -> Geometry {
    let p = vec![
        DVec3::new(-0.5, -0.5, 0.0),
        DVec3::new(0.5, -0.5, 0.0),
        DVec3::new(0.0, 0.5, 0.0),
        DVec3::new(0.0, 0.0, 2.0),
    ];
    Geometry::new(
        "tree",
        p,
        Primitives::Triangles(vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [2, 0, 3]]),
    )
}

fn at(geometry: usize, x: f64, y: f64) -> Instance {
    Instance {
        geometry,
        world_from_local: DAffine3::from_translation(DVec3::new(x, y, 0.0)),
    }
}

/// A terrain with trees on a `k x k` lattice, `spacing` apart.
fn island(k: u32, spacing: f64) -> Scene {
    let side = spacing * f64::from(k);
    let mut scene = Scene::single(terrain(32, side));
    scene.geometries.push(tree());
    for j in 0..k {
        for i in 0..k {
            let c = |v: u32| (f64::from(v) + 0.5) * spacing;
            scene.instances.push(at(1, c(i), c(j)));
        }
    }
    scene
}

fn hierarchy(file: &PagedFile) -> Hierarchy {
    let bytes = file.to_bytes();
    read_image(&bytes).expect("the file reads back")
}

/// Every leaf's page, by leaf number.
fn leaf_pages(h: &Hierarchy) -> Vec<farfield_protocol::bsp_codec::LeafPage> {
    let s = h.bsp_skeleton().expect("page 0");
    (0..s.leaves)
        .map(|l| match h.page(s.leaf_page(l) as usize).unwrap().bsp() {
            Some(BspPage::Content(ContentPage::Leaf(p))) => {
                assert_eq!(p.leaf, l);
                p.clone()
            }
            other => panic!("leaf {l}: {other:?}"),
        })
        .collect()
}

fn contains(s: &BspSkeleton, node: usize, p: DVec3) -> bool {
    let n = &s.nodes[node];
    p.cmpge(n.box_min - 1e-4).all() && p.cmple(n.box_max + 1e-4).all()
}

#[test]
fn an_island_splits_in_the_gaps_between_trees_and_keeps_them_instances() {
    let scene = island(4, 10.0);
    let options = BspOptions {
        leaf_triangles: 1 << 20,
        ..BspOptions::default()
    };
    let (file, stats) = build_bsp(&scene, &options).expect("builds");
    assert_eq!(stats.prototypes, 1, "one tree stored once");
    assert_eq!(stats.placements, 16);
    assert_eq!(stats.leaves, 16, "a tree a leaf: {stats:?}");
    assert_eq!(stats.split.instances_crossed, 0, "no tree is cut");
    assert_eq!(stats.split.medians, 0, "every plane in a gap");
    assert!(stats.split.meshes_split > 0, "the terrain is split");
    let h = hierarchy(&file);
    let s = h.bsp_skeleton().unwrap();
    assert_eq!(s.directions, vec![DVec3::X, DVec3::Y]);
    assert_eq!(s.scene_triangles, 32 * 32 * 2 + 16 * 4);
    // The prototype's page holds the tree once.
    match h.page(1).unwrap().bsp() {
        Some(BspPage::Content(ContentPage::Prototype(p))) => assert_eq!(p.triangles.len(), 4),
        other => panic!("{other:?}"),
    }
    // Each leaf places its own tree (and, inflated, perhaps a neighbour's
    // whose centre is within 8.5 % of the region's width: none here).
    let pages = leaf_pages(&h);
    let mut placed: Vec<DVec3> = pages
        .iter()
        .flat_map(|p| {
            p.placements
                .iter()
                .map(|q| q.world_from_local(p.anchor).translation)
        })
        .collect();
    assert_eq!(placed.len(), 16);
    placed.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    assert_eq!(placed[0], DVec3::new(5.0, 5.0, 0.0));
    // Interior boxes hold their children's; leaf boxes hold their geometry.
    for (i, n) in s.nodes.iter().enumerate() {
        match n.split {
            Split::Plane { back, front, .. } => {
                for c in [back as usize, front as usize] {
                    assert!(
                        contains(s, i, s.nodes[c].box_min) && contains(s, i, s.nodes[c].box_max)
                    );
                    assert!(s.nodes[c].triangles <= n.triangles);
                }
                assert_eq!(
                    n.triangles,
                    s.nodes[back as usize].triangles + s.nodes[front as usize].triangles
                );
            }
            Split::Leaf { leaf } => {
                let page = &pages[leaf as usize];
                for t in &page.triangles {
                    for c in t.corners {
                        assert!(contains(s, i, page.world(c)), "leaf {leaf}");
                    }
                }
                let expected = u64::from(page.own_triangles) + 4 * u64::from(page.own_placements);
                assert_eq!(n.triangles, expected);
            }
        }
    }
}

#[test]
fn inflation_borrows_neighbouring_geometry_and_none_stores_each_triangle_once() {
    let scene = island(4, 10.0);
    let plain = BspOptions {
        inflation: 0.0,
        leaf_triangles: 1 << 20,
        ..BspOptions::default()
    };
    let (file, stats) = build_bsp(&scene, &plain).unwrap();
    // A centroid exactly on a plane would sit in both closed regions; the
    // grid's planes fall between centroids here.
    assert_eq!(stats.stored_per_mesh_triangle, 1.0, "{stats:?}");
    let pages = leaf_pages(&hierarchy(&file));
    let stored: usize = pages.iter().map(|p| p.triangles.len()).sum();
    assert_eq!(stored, 32 * 32 * 2);
    let (inflated_file, inflated) = build_bsp(
        &scene,
        &BspOptions {
            inflation: 0.17,
            ..plain
        },
    )
    .unwrap();
    // Inflated, every triangle and tree is still some leaf's own exactly
    // once: drawn as geometry, nothing is drawn twice.
    let pages = leaf_pages(&hierarchy(&inflated_file));
    let own: usize = pages.iter().map(|p| p.own_triangles as usize).sum();
    let own_trees: usize = pages.iter().map(|p| p.own_placements as usize).sum();
    let stored: usize = pages.iter().map(|p| p.triangles.len()).sum();
    assert_eq!((own, own_trees), (32 * 32 * 2, scene.instances.len() - 1));
    assert!(stored > own, "{stored}");
    // Regions 10 wide grow by 0.85 on each side: the grid's cells are
    // 1.25 wide, so about one row of triangles on each inner side.
    assert!(
        inflated.stored_per_mesh_triangle > 1.1 && inflated.stored_per_mesh_triangle < 1.6,
        "{inflated:?}"
    );
    assert!(inflated.file_bytes > stats.file_bytes);
}

#[test]
fn objects_in_one_place_fall_back_to_the_median_and_the_build_ends() {
    // Eight trees on one spot: identical extents, no gap.
    let mut scene = Scene::single(tree());
    scene.instances = (0..8).map(|_| at(0, 3.0, 4.0)).collect();
    let (file, stats) = build_bsp(&scene, &BspOptions::default()).expect("builds");
    assert_eq!(stats.leaves, 8, "{stats:?}");
    assert!(
        stats.split.medians >= 7 && stats.split.gaps == 0,
        "{stats:?}"
    );
    let pages = leaf_pages(&hierarchy(&file));
    assert!(pages.iter().all(|p| !p.placements.is_empty()));
    // Zero extents: trees scaled to a point, beside a terrain.
    let mut scene = island(1, 10.0);
    for _ in 0..5 {
        scene.instances.push(Instance {
            geometry: 1,
            world_from_local: DAffine3::from_mat3_translation(DMat3::ZERO, DVec3::splat(2.0)),
        });
    }
    let (_, stats) = build_bsp(&scene, &BspOptions::default()).expect("builds");
    assert_eq!(stats.placements, 6);
    assert!(stats.leaves >= 6, "{stats:?}");
}

#[test]
fn one_big_mesh_has_no_gap_and_is_cut_at_medians_into_small_leaves() {
    let scene = Scene::single(terrain(64, 100.0));
    let options = BspOptions {
        leaf_triangles: 512,
        inflation: 0.0,
        ..BspOptions::default()
    };
    let (file, stats) = build_bsp(&scene, &options).unwrap();
    assert_eq!(stats.split.gaps, 0);
    assert!(stats.leaves >= 16, "{stats:?}");
    let pages = leaf_pages(&hierarchy(&file));
    assert!(
        pages
            .iter()
            .all(|p| p.triangles.len() <= 512 && !p.triangles.is_empty())
    );
    assert_eq!(
        pages.iter().map(|p| p.triangles.len()).sum::<usize>(),
        64 * 64 * 2
    );
    // Balanced: the deepest leaf is not much deeper than log2(leaves).
    let balanced = (stats.leaves as f64).log2().ceil() as u32 + 2;
    assert!(stats.split.depth <= balanced, "{stats:?}");
}

#[test]
fn empty_and_point_scenes_and_bad_options_are_refused() {
    let empty = Scene::default();
    assert!(matches!(
        build_bsp(&empty, &BspOptions::default()),
        Err(BuildError::Empty)
    ));
    let points = Scene::single(Geometry::new(
        "scan",
        vec![DVec3::ZERO; 3],
        Primitives::Points,
    ));
    let e = build_bsp(&points, &BspOptions::default()).unwrap_err();
    assert!(e.to_string().contains("point cloud"), "{e}");
    let scene = island(1, 10.0);
    for bad in [
        BspOptions {
            directions: 0,
            ..BspOptions::default()
        },
        BspOptions {
            inflation: f64::NAN,
            ..BspOptions::default()
        },
        BspOptions {
            up: DVec3::ZERO,
            ..BspOptions::default()
        },
        BspOptions {
            leaf_triangles: 0,
            ..BspOptions::default()
        },
    ] {
        assert!(build_bsp(&scene, &bad).is_err(), "{bad:?}");
    }
}

#[test]
fn directions_divide_the_circle_around_the_up_axis() {
    assert_eq!(directions(2, DVec3::Z).unwrap(), vec![DVec3::X, DVec3::Y]);
    assert_eq!(directions(2, DVec3::Y).unwrap(), vec![DVec3::Z, DVec3::X]);
    let four = directions(4, DVec3::Z).unwrap();
    assert_eq!(four.len(), 4);
    let h = std::f64::consts::FRAC_1_SQRT_2;
    assert!(
        (four[1] - DVec3::new(h, h, 0.0)).length() < 1e-12,
        "{four:?}"
    );
    for d in directions(7, DVec3::new(1.0, 2.0, 3.0)).unwrap() {
        assert!((d.length() - 1.0).abs() < 1e-12);
        assert!(d.dot(DVec3::new(1.0, 2.0, 3.0)).abs() < 1e-12);
    }
    // Three directions around Z: planes at 60 degrees; still builds.
    let scene = island(3, 10.0);
    let (file, _) = build_bsp(
        &scene,
        &BspOptions {
            directions: 3,
            ..BspOptions::default()
        },
    )
    .unwrap();
    assert_eq!(hierarchy(&file).bsp_skeleton().unwrap().directions.len(), 3);
}
