//! The color-cube octree (hierarchy kind `cubes`) end to end: built from
//! scenes, read back through the page parser, streamed by a real server
//! and drawn by the real renderer against the full-geometry reference.

use std::time::Duration;

use farfield_builder::PagedFile;
use farfield_builder::cubes::octree::{Cell, Settings, build_cell};
use farfield_builder::cubes::source::Source as Primitives;
use farfield_builder::cubes::{Composite, CubeOptions as BuildCubes, build_cubes};
use farfield_builder::import::{Params, load_input};
use farfield_builder::scene::{Geometry, Instance, Primitives as Prims, Scene};
use farfield_client::camera_spec::CameraSpec;
use farfield_client::frame_loop::Until;
use farfield_client::render_job::{RenderJob, Source, run};
use farfield_image::compare;
use farfield_net::SessionOptions;
use farfield_protocol::camera::Camera;
use farfield_protocol::cube_codec::{self, Face};
use farfield_protocol::hierarchy::Hierarchy;
use farfield_render::{Coverage, Kernel, Renderer, headless_or_skip};
use farfield_store::write_atomic;
use farfield_tests::{scratch, shared_data};
use farfield_tools::reference::Reference;
use farfield_traverse::cubes::{CubeOptions, traverse_cubes};
use glam::{DAffine3, DVec3, Vec3};

use crate::resident;

const SIZE: (u32, u32) = (160, 160);

fn cubes(scene: Scene) -> PagedFile {
    build_cubes(scene, &BuildCubes::default())
        .expect("cube build")
        .0
}

fn tree(triangles: u32) -> Scene {
    let mut p = Params::default();
    p.set("triangles", triangles);
    load_input("gen:tree", &p).unwrap()
}

/// A generated tree of `triangles`, and the bunny when the shared data is there.
fn tree_and_bunny(triangles: u32) -> Vec<(&'static str, Scene)> {
    let mut scenes = vec![("tree", tree(triangles))];
    if let Some(data) = shared_data() {
        let bunny = data.join("stanford-bunny.obj");
        scenes.push((
            "bunny",
            load_input(bunny.to_str().unwrap(), &Params::default()).unwrap(),
        ));
    }
    scenes
}

fn orbit(h: &Hierarchy, azimuth: f64, distance: f64) -> Camera {
    let (center, radius) = farfield_client::camera_spec::scene_sphere(&h.header);
    Camera::orbit(center, radius, azimuth, 10.0, distance, SIZE.0, SIZE.1)
}

/// The geometry reference's image for `camera`.
fn reference_image(renderer: &mut Renderer, scene: &Scene, camera: &Camera) -> Vec<u8> {
    let reference = Reference::from_scene(scene).unwrap();
    let mut vertices = Vec::new();
    reference.pack(camera.eye, &mut vertices);
    renderer
        .render_geometry(camera, &vertices, &[], Coverage::Alpha, [0; 3])
        .unwrap()
        .rgba
}

/// The hierarchy's image at `eps` (every page resident).
fn cube_image(renderer: &mut Renderer, h: &Hierarchy, camera: &Camera, eps: f64) -> Vec<u8> {
    let cut = traverse_cubes(
        h,
        camera,
        &CubeOptions {
            eps_px: eps,
            ..CubeOptions::default()
        },
    );
    farfield_render::draw_cut(
        renderer,
        &farfield_render::CubeFrame {
            hierarchy: h,
            camera,
            cut: &cut,
            coverage: Coverage::Alpha,
            background: [0; 3],
        },
    )
    .unwrap()
    .rgba
}

fn psnr(a: &[u8], b: &[u8]) -> f64 {
    compare(a, b, SIZE.0, SIZE.1, 8).unwrap().psnr_db
}

fn not_blank(rgba: &[u8]) -> bool {
    rgba.chunks_exact(4).filter(|p| p[..3] != [0, 0, 0]).count() > 50
}

/// With eps tiny every leaf draws its geometry: the same surfaces as the
/// reference, up to the 16-bit cell-relative positions and the triangles
/// clipped at cell faces. Those move depths by a ten-thousandth of a pixel,
/// which is enough to flip which of two interpenetrating, nearly coplanar
/// leaves of the tree wins the depth test: measured 35.3 dB and 1.4 % of
/// pixels (in clusters where foliage crosses) on the tree, so the test asks
/// for 33 dB and at most 2.5 %; a wrong position, normal or color in the
/// leaf geometry costs far more.
#[test]
fn streamed_cubes_at_tiny_eps_equal_the_geometry_image() {
    let Some(mut renderer) = headless_or_skip(SIZE.0, SIZE.1).unwrap() else {
        return;
    };
    let dir = scratch("cubes-stream");
    let scenes = tree_and_bunny(8000);
    for (name, scene) in &scenes {
        write_atomic(&dir.join(format!("{name}.ff")), &cubes(scene.clone())).unwrap();
    }
    let (rt, server, url) = crate::serve_dir(&dir);
    let spec = CameraSpec::Orbit {
        azimuth_deg: 30.0,
        elevation_deg: 10.0,
        distance: 1.75,
    };
    for (name, scene) in &scenes {
        let job = RenderJob {
            source: Source::Server {
                url: url.clone(),
                scene: (*name).into(),
            },
            camera: spec,
            width: SIZE.0,
            height: SIZE.1,
            out: None,
            until: Until::Refined,
            threshold_px: 1e-9,
            kernel: Kernel::Square,
            edl: None,
            color_by: Default::default(),
            clip: None,
            coverage: Coverage::Alpha,
            session: SessionOptions::default(),
            cache_bytes: 256 << 20,
            timeout: Duration::from_secs(120),
            budget: Default::default(),
        };
        let streamed = run(&job, &mut renderer, false).unwrap();
        assert!(
            streamed.report.refined,
            "{name}: {:?}",
            streamed.report.last_error
        );
        // Streamed pages are the file's pages: the same image, bit for bit.
        let file_job = RenderJob {
            source: Source::File(dir.join(format!("{name}.ff"))),
            ..job.clone()
        };
        let from_file = run(&file_job, &mut renderer, false).unwrap();
        assert!(
            from_file.rgba == streamed.rgba,
            "{name}: streamed image differs from the file's"
        );
        assert!(streamed.report.triangles_drawn > 0 && streamed.report.cube_faces_drawn == 0);
        let file = crate::resident(&cubes(scene.clone()));
        let camera = spec.resolve(&file.header, SIZE.0, SIZE.1);
        let geometry = reference_image(&mut renderer, scene, &camera);
        assert!(not_blank(&geometry), "{name}: blank reference");
        let m = compare(&geometry, &streamed.rgba, SIZE.0, SIZE.1, 8).unwrap();
        assert!(
            m.psnr_db >= 33.0 && m.wrong_fraction <= 0.025,
            "{name}: streamed cubes at eps 0 differ from the geometry: {m:?}"
        );
    }
    rt.block_on(server.shutdown()).unwrap();
}

/// At eps = 1 px a cube stands only for geometry that covers at most one
/// pixel, so the error is confined to pixel-sized samples of the silhouette
/// and of the foliage's tone. Measured here (160 x 160, `farfield
/// bench-cubes`): 41.5 to 47.7 dB on a 20 000-triangle tree and 36.7 to
/// 46.2 dB on the bunny at 3.5 to 14 radii. The floor, 30 dB (RMSE 8 of 255),
/// leaves room for other drivers' rasterization rules; a cube placed a cell
/// off, faces swapped front for back, or compositing that lets opaque
/// foliage turn transparent each lose far more than that.
#[test]
fn one_pixel_eps_stays_above_the_error_floor() {
    let Some(mut renderer) = headless_or_skip(SIZE.0, SIZE.1).unwrap() else {
        return;
    };
    let scenes = tree_and_bunny(20000);
    for (name, scene) in &scenes {
        let h = resident(&cubes(scene.clone()));
        for distance in [3.5, 7.0, 14.0] {
            let camera = orbit(&h, 30.0, distance);
            let geometry = reference_image(&mut renderer, scene, &camera);
            let hierarchy = cube_image(&mut renderer, &h, &camera, 1.0);
            let p = psnr(&geometry, &hierarchy);
            assert!(p >= 30.0, "{name} at {distance} radii: PSNR {p:.2} dB");
            // Far enough, cubes really were drawn.
            if distance >= 14.0 {
                let cut = traverse_cubes(&h, &camera, &CubeOptions::default());
                assert!(!cut.faces.is_empty(), "{name}: no cubes at 14 radii");
            }
        }
    }
}

fn quad_x(x: f64, color: [u8; 3]) -> Geometry {
    let positions = vec![
        DVec3::new(x, 0.0, 0.0),
        DVec3::new(x, 1.0, 0.0),
        DVec3::new(x, 1.0, 1.0),
        DVec3::new(x, 0.0, 1.0),
    ];
    let mut g = Geometry::new(
        "quad",
        positions,
        Prims::Triangles(vec![[0, 1, 2], [0, 2, 3]]),
    );
    g.colors = Some(vec![color; 4]);
    g
}

/// One axis-aligned quad is one leaf: its color, fully covering, on the
/// two faces that see it; nothing on the four that see it edge-on.
#[test]
fn a_quad_colors_exactly_the_two_faces_that_see_it() {
    let color = [200, 100, 50];
    let h = resident(&cubes(Scene::single(quad_x(0.5, color))));
    assert_eq!(h.header.nodes, 1);
    let rec = h.page(0).unwrap().cubes().unwrap().records[0];
    let base = Vec3::from(color.map(|c| f32::from(c) / 255.0));
    for face in Face::ALL {
        let f = rec.faces[face.index()];
        if face.axis() == 0 {
            assert_eq!(f[3], 255, "{face:?}");
            let lit = farfield_protocol::shading::shade(base, Vec3::X, face.normal().as_vec3());
            for c in 0..3 {
                let expect = (lit[c] * 255.0).round();
                assert!(
                    (f32::from(f[c]) - expect).abs() <= 1.0,
                    "{face:?}: {f:?} vs {lit}"
                );
            }
        } else {
            assert_eq!(f, [0; 4], "{face:?} is edge-on");
        }
    }
}

fn wall_scene() -> Scene {
    // The wall at x = 0.3, wider than the root cube and cut into 2048
    // triangles so the octree subdivides along it; a speck at x = 1.
    let n = 32u32;
    let mut positions = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let t = |k: u32| -1.0 + 3.0 * f64::from(k) / f64::from(n);
            positions.push(DVec3::new(0.3, t(i), t(j)));
        }
    }
    let at = |i: u32, j: u32| j * (n + 1) + i;
    let tris = (0..n)
        .flat_map(|j| {
            (0..n).flat_map(move |i| {
                [
                    [at(i, j), at(i + 1, j), at(i + 1, j + 1)],
                    [at(i, j), at(i + 1, j + 1), at(i, j + 1)],
                ]
            })
        })
        .collect();
    let mut scene = Scene::single(Geometry::new("wall", positions, Prims::Triangles(tris)));
    let speck = Geometry::new(
        "speck",
        vec![
            DVec3::new(1.0, 0.5, 0.5),
            DVec3::new(1.0, 0.51, 0.5),
            DVec3::new(1.0, 0.5, 0.51),
        ],
        Prims::Triangles(vec![[0, 1, 2]]),
    );
    scene.merge(Scene::single(speck));
    scene
}

/// Every cell the wall crosses sees it wall to wall from +x and -x: those
/// faces must stay opaque at every level, whichever compositing is used,
/// while the wall makes the cells above it no less empty from the sides.
#[test]
fn an_opaque_wall_stays_opaque_at_every_level() {
    let scene = wall_scene();
    let src = Primitives::new(&scene).unwrap();
    let refs = src.refs();
    for composite in [Composite::Disjoint, Composite::Over] {
        let settings = Settings {
            cluster: 1,
            samples: 16,
            max_depth: 12,
            composite,
            cube_cost: 6.0,
            channels: Default::default(),
            root_min: DVec3::new(0.15, -0.005, -0.005),
        };
        // A root cube of edge 1.01 with the wall inside, off every split.
        let root = build_cell(&src, refs.clone(), settings.root_min, 1.01, 0, &settings).unwrap();
        let mut checked = 0;
        let mut stack = vec![(&root, settings.root_min, 1.01, 0u32)];
        let mut deepest = 0;
        while let Some((cell, min, edge, level)) = stack.pop() {
            deepest = deepest.max(level);
            let wall_inside = (min.x..min.x + edge).contains(&0.3);
            // The wall is wider than the root: every cell it crosses sees
            // it wall to wall.
            if wall_inside {
                for face in [Face::PosX, Face::NegX] {
                    let a = cell.faces[face.index()][3];
                    assert!(a > 0.999, "{composite:?} level {level}: {face:?} alpha {a}");
                }
                checked += 1;
            }
            push_children(&mut stack, cell, min, edge, level);
        }
        assert!(
            checked >= 4 && deepest >= 3,
            "{composite:?}: only {checked} cells"
        );
    }
}

fn push_children<'a>(
    stack: &mut Vec<(&'a Cell, DVec3, f64, u32)>,
    cell: &'a Cell,
    min: DVec3,
    edge: f64,
    level: u32,
) {
    let mut children = cell.children.iter();
    for octant in 0..8u8 {
        if cell.mask & (1 << octant) != 0 {
            let child = children.next().unwrap();
            stack.push((
                child,
                cube_codec::child_min(min, edge, octant),
                edge * 0.5,
                level + 1,
            ));
        }
    }
}

/// A cluster of tiny triangles 30 levels down: the build neither
/// overflows nor loses precision there (positions are cell-relative).
#[test]
fn thirty_levels_deep_keeps_cell_relative_precision() {
    let tiny = 1e-9;
    let base = DVec3::new(0.25, 0.25, 0.25);
    let mut positions = vec![DVec3::ZERO, DVec3::X, DVec3::Y];
    let mut tris = vec![[0, 1, 2]];
    for k in 0..40u32 {
        let o = base + DVec3::new(f64::from(k % 7), f64::from(k / 7), f64::from(k % 3)) * tiny;
        let i = positions.len() as u32;
        positions.extend([o, o + DVec3::X * tiny, o + DVec3::Z * tiny]);
        tris.push([i, i + 1, i + 2]);
    }
    let scene = Scene::single(Geometry::new(
        "deep",
        positions.clone(),
        Prims::Triangles(tris),
    ));
    let file = cubes(scene.clone());
    let h = resident(&file);
    assert!(h.header.levels >= 26, "only {} levels", h.header.levels);
    // Looking at the cluster from close by, every tiny triangle is drawn
    // from a leaf, and its corners come back within a step of their cell.
    let camera = Camera {
        eye: base + DVec3::new(3.0, 3.0, 20.0) * tiny,
        target: base + DVec3::new(3.0, 3.0, 0.0) * tiny,
        up: DVec3::Y,
        fov_y_deg: 60.0,
        width: SIZE.0,
        height: SIZE.1,
    };
    let cut = traverse_cubes(
        &h,
        &camera,
        &CubeOptions {
            eps_px: 0.0,
            ..CubeOptions::default()
        },
    );
    assert!(cut.triangles >= 40, "{} triangles drawn", cut.triangles);
    let mut matched = 0;
    for leaf in &cut.leaves {
        let g = h.page(leaf.page as usize).unwrap().cubes().unwrap();
        let geometry = g
            .payload(leaf.local as usize)
            .unwrap()
            .geometry
            .as_ref()
            .unwrap();
        let step = leaf.edge * cube_codec::POSITION_SPAN / cube_codec::POSITION_STEPS;
        for q in &geometry.positions {
            let p = cube_codec::dequantize_in_cell(*q, leaf.min, leaf.edge, DVec3::ZERO);
            let nearest = positions
                .iter()
                .map(|o| o.distance(p))
                .fold(f64::INFINITY, f64::min);
            if leaf.edge < 1e-6 {
                assert!(nearest <= 2.0 * step + 1e-15, "{nearest} vs step {step}");
                matched += 1;
            }
        }
    }
    assert!(matched >= 120, "{matched} deep corners checked");
}

/// Extreme scenes and settings draw or fail clearly, never panic.
#[test]
fn extremes_render_or_fail_clearly() {
    // Spheres all at one point: one leaf, not an explosion of cells.
    let atoms = Geometry::new(
        "atoms",
        vec![DVec3::splat(2.0); 200],
        Prims::Spheres(vec![1.0; 200]),
    );
    let file = cubes(Scene::single(atoms));
    assert!(
        file.header.nodes <= 9,
        "{} cells for one point",
        file.header.nodes
    );
    // A primitive larger than half the scene next to small ones.
    let mut scene = tree(2000);
    let big = Geometry::new(
        "big",
        vec![
            DVec3::new(-50.0, -50.0, 0.0),
            DVec3::new(50.0, -50.0, 0.0),
            DVec3::new(0.0, 50.0, 0.0),
        ],
        Prims::Triangles(vec![[0, 1, 2]]),
    );
    scene.merge(Scene::single(big));
    let h = resident(&cubes(scene.clone()));
    // A point cloud has no surfaces: a clear error naming the way out.
    let cloud = Geometry::new("cloud", vec![DVec3::ZERO, DVec3::X], Prims::Points);
    let e = build_cubes(Scene::single(cloud), &BuildCubes::default()).unwrap_err();
    assert!(e.to_string().contains("--kind spheres"), "{e}");
    let e = build_cubes(
        tree(1000),
        &BuildCubes {
            cluster: 3,
            ..BuildCubes::default()
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("cluster"), "{e}");

    let Some(mut renderer) = headless_or_skip(SIZE.0, SIZE.1).unwrap() else {
        return;
    };
    // The big triangle is there at eps 0, as in the geometry.
    let camera = orbit(&h, 30.0, 1.2);
    let geometry = reference_image(&mut renderer, &scene, &camera);
    let p = psnr(&geometry, &cube_image(&mut renderer, &h, &camera, 0.0));
    assert!(p >= 35.0, "big triangle scene: PSNR {p}");
    // A camera inside a cell (in the tree's crown) refines around itself.
    let inside = Camera {
        eye: DVec3::new(0.3, 0.2, 6.0),
        target: DVec3::new(2.0, 0.0, 6.0),
        up: DVec3::Z,
        fov_y_deg: 70.0,
        width: SIZE.0,
        height: SIZE.1,
    };
    let g = reference_image(&mut renderer, &scene, &inside);
    let c = cube_image(&mut renderer, &h, &inside, 1.0);
    assert!(psnr(&g, &c) >= 25.0, "inside: PSNR {}", psnr(&g, &c));
    // eps near zero draws geometry; eps huge draws the root cube alone.
    let camera = orbit(&h, 30.0, 5.0);
    for eps in [1e-12, 1e12] {
        let cut = traverse_cubes(
            &h,
            &camera,
            &CubeOptions {
                eps_px: eps,
                ..CubeOptions::default()
            },
        );
        if eps > 1.0 {
            assert!(
                cut.leaves.is_empty() && cut.faces.len() <= 3,
                "{} faces",
                cut.faces.len()
            );
            assert_eq!(cut.faces_per_level.len(), 1);
        } else {
            assert!(cut.faces.is_empty() && cut.triangles > 0);
        }
        assert!(
            not_blank(&cube_image(&mut renderer, &h, &camera, eps)),
            "eps {eps}: blank"
        );
    }
    // An instanced, translated scene far from the origin renders like the
    // same scene at the origin (camera-relative all the way).
    let mut far = tree(2000);
    far.instances = vec![Instance {
        geometry: 0,
        world_from_local: DAffine3::from_translation(DVec3::splat(1e7)),
    }];
    let near_h = resident(&cubes(tree(2000)));
    let far_h = resident(&cubes(far));
    let a = cube_image(&mut renderer, &near_h, &orbit(&near_h, 30.0, 3.0), 1.0);
    let b = cube_image(&mut renderer, &far_h, &orbit(&far_h, 30.0, 3.0), 1.0);
    assert!(
        psnr(&a, &b) >= 40.0,
        "far from the origin: PSNR {}",
        psnr(&a, &b)
    );
}

/// A flipped bit in a cube page is caught by `inspect`; a page whose
/// checksum is right but whose leaf geometry indexes past its vertices is
/// refused by the reader, never drawn.
#[test]
fn corrupt_cube_pages_are_refused() {
    let dir = scratch("cubes-corrupt");
    let path = dir.join("tree.ff");
    let file = cubes(tree(3000));
    write_atomic(&path, &file).unwrap();
    let mut bytes = std::fs::read(&path).unwrap();
    let last = file.directory.entries().last().unwrap().1;
    bytes[(last.offset + u64::from(last.length) / 2) as usize] ^= 0x10;
    std::fs::write(&path, &bytes).unwrap();
    let report = crate::cli(&["inspect", path.to_str().unwrap(), "--json"]).unwrap();
    assert_eq!(report.json["corrupt_pages"], 1);
    assert_ne!(report.exit_code, 0);

    // Re-encode page 0 with one triangle index out of range and a fresh CRC.
    let page = &file.pages[0];
    let parsed = farfield_protocol::page::Page::parse_with_payload(page, 0, 32).unwrap();
    let (records, mut payload) = (parsed.records().to_vec(), parsed.payload().to_vec());
    // The first leaf with geometry: its payload starts after the sub-cubes
    // and payloads of the cells before it.
    let mut at = 0usize;
    for rec in records.chunks_exact(32) {
        let r = cube_codec::CubeRecord::unpack(rec).unwrap();
        let count = |k: usize| u32::from_le_bytes(payload[at + k..at + k + 4].try_into().unwrap());
        if r.is_leaf() && r.payload_bytes > 0 && count(4) > 0 {
            let vertices = count(0);
            let end = at + r.payload_bytes as usize;
            // The last index of the leaf (16-bit indices in small leaves).
            payload[end - 2..end].copy_from_slice(&(vertices as u16).to_le_bytes());
            let (bad, crc) = farfield_protocol::page::encode_page_with_payload(
                &parsed.header,
                &records,
                &payload,
            )
            .unwrap();
            // A directory that agrees (a forged file), so the page reaches
            // the checks behind the checksums.
            let mut h = crate::forged(&file, 0, crc);
            let e = h.insert_page(0, &bad).unwrap_err();
            assert!(e.to_string().contains("past"), "{e}");
            assert!(!h.is_resident(0));
            return;
        }
        at += r.payload_bytes as usize;
    }
    panic!("page 0 holds no leaf with geometry");
}

/// While streaming, a cell whose children have not arrived is drawn as its
/// cube: the first image, from page 0 alone, is all cubes.
#[test]
fn the_first_streamed_image_is_made_of_cubes() {
    use farfield_client::frame_loop::{FrameState, draw_frame};
    use farfield_client::viewer::Viewer;
    use farfield_render::SplatStyle;
    use farfield_traverse::DrawList;
    let Some(mut renderer) = headless_or_skip(SIZE.0, SIZE.1).unwrap() else {
        return;
    };
    let dir = scratch("cubes-first");
    let options = BuildCubes {
        page_bytes: 4096,
        ..BuildCubes::default()
    };
    write_atomic(
        &dir.join("tree.ff"),
        &build_cubes(tree(8000), &options).unwrap().0,
    )
    .unwrap();
    let (rt, server, url) = crate::serve_dir(&dir);
    let mut viewer =
        Viewer::open_remote(&url, "tree", SessionOptions::default(), 64 << 20).unwrap();
    let started = std::time::Instant::now();
    while viewer.hierarchy().is_none_or(|h| !h.is_resident(0)) {
        assert!(started.elapsed() < Duration::from_secs(20), "no page 0");
        viewer.pump(Duration::from_millis(50)).unwrap();
    }
    assert_eq!(viewer.hierarchy().unwrap().resident_pages(), 1);
    let camera = orbit(viewer.hierarchy().unwrap(), 30.0, 1.75);
    let (mut cuts, mut rgba) = (FrameState::default(), Vec::new());
    draw_frame(
        &mut viewer,
        &mut renderer,
        &camera,
        1.0,
        &SplatStyle::default(),
        &mut cuts,
        &mut rgba,
    )
    .unwrap();
    let Some(DrawList::Cubes(cut)) = cuts.draw_list() else {
        panic!("a cube hierarchy draws cubes");
    };
    assert!(!cut.faces.is_empty(), "no placeholder cubes");
    assert!(!cut.wanted.is_empty(), "nothing asked for");
    assert!(not_blank(&rgba), "the first image is blank");
    drop(viewer);
    rt.block_on(server.shutdown()).unwrap();
}

/// k x k x k clusters (1995, section 4.2): a cell drawn as its cluster
/// draws sub-cubes a k-th of its edge, and the image stays above the same
/// floor as single cubes.
#[test]
fn clustered_cubes_draw_sub_cubes_and_keep_the_floor() {
    let scene = tree(8000);
    let options = BuildCubes {
        cluster: 2,
        ..BuildCubes::default()
    };
    let h = resident(&build_cubes(scene.clone(), &options).unwrap().0);
    assert_eq!(h.header.cluster, 2);
    let camera = orbit(&h, 30.0, 14.0);
    let cut = traverse_cubes(&h, &camera, &CubeOptions::default());
    assert!(!cut.faces.is_empty());
    // Every drawn cube is a sub-cube: half the edge of some cell's.
    let root_edge = 2.0 * h.header.root_radius;
    for f in &cut.faces {
        let level = (root_edge / f.edge).log2();
        assert!(
            (level - level.round()).abs() < 1e-9 && level >= 1.0,
            "edge {}",
            f.edge
        );
    }
    let Some(mut renderer) = headless_or_skip(SIZE.0, SIZE.1).unwrap() else {
        return;
    };
    for distance in [7.0, 14.0] {
        let camera = orbit(&h, 30.0, distance);
        let p = psnr(
            &reference_image(&mut renderer, &scene, &camera),
            &cube_image(&mut renderer, &h, &camera, 1.0),
        );
        assert!(p >= 30.0, "clustered at {distance} radii: PSNR {p:.2}");
    }
}

/// Flying through a cube hierarchy, eps follows the frame budget like the
/// splat threshold: a budget no frame can meet drives it up.
#[test]
fn eps_adapts_to_the_frame_budget_in_flight() {
    use farfield_client::flythrough::{FlyJob, fly};
    use farfield_client::path::{CameraPath, Keyframe, OrbitKey};
    use farfield_client::viewer::Viewer;
    use farfield_render::SplatStyle;
    let Some(mut renderer) = headless_or_skip(SIZE.0, SIZE.1).unwrap() else {
        return;
    };
    let dir = scratch("cubes-fly");
    let path = dir.join("tree.ff");
    write_atomic(&path, &cubes(tree(8000))).unwrap();
    let key = |t: f64, azimuth: f64| Keyframe {
        t,
        orbit: Some(OrbitKey {
            azimuth,
            elevation: 10.0,
            distance: 2.0,
        }),
        eye: None,
        target: None,
        fov: None,
    };
    let job = FlyJob {
        path: CameraPath::from_keyframes(&[key(0.0, 0.0), key(1.0, 90.0)]).unwrap(),
        fps: 8.0,
        width: SIZE.0,
        height: SIZE.1,
        final_threshold_px: 1.0,
        target_frame_ms: 1e-3,
        style: SplatStyle::default(),
        frames_dir: None,
        settle: false,
        timeout: Duration::from_secs(60),
        budget: Default::default(),
        known_path: false,
    };
    let mut viewer = Viewer::open_file(&path).unwrap();
    let (stats, _) = fly(&mut viewer, &mut renderer, &job, std::time::Instant::now()).unwrap();
    let first = stats.first().unwrap().threshold_px;
    let last = stats.last().unwrap().threshold_px;
    assert!(last > first, "eps stayed at {first} -> {last}");
    assert!(stats.iter().all(|s| s.nodes_drawn > 0));
}
