//! PLP end to end on built files: the budget's edges, the eye anywhere,
//! triangles drawn once, degenerate tessellations, and streaming in
//! projection order.

use farfield_builder::plp::{PlpOptions, build_plp};
use farfield_builder::scene::{Geometry, Instance, Primitives, Scene};
use farfield_builder::{BuildError, PagedFile};
use farfield_protocol::camera::Camera;
use farfield_protocol::hierarchy::{Hierarchy, PlpPage};
use farfield_protocol::plp_codec::face_corners;
use farfield_traverse::Budget;
use farfield_traverse::plp::{
    Order, PlpCut, PlpOptions as Walk, PlpState, Solidity, traverse_plp_into,
};
use glam::{DAffine3, DVec3};

use crate::resident;

/// Closed boxes, counter-clockwise seen from outside, one color each.
fn boxes(list: &[(DVec3, DVec3)]) -> Scene {
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    let mut colors = Vec::new();
    for (k, &(lo, hi)) in list.iter().enumerate() {
        let base = positions.len() as u32;
        for i in 0..8 {
            positions.push(DVec3::new(
                if i & 1 != 0 { hi.x } else { lo.x },
                if i & 2 != 0 { hi.y } else { lo.y },
                if i & 4 != 0 { hi.z } else { lo.z },
            ));
            colors.push([(40 + 30 * k % 200) as u8, 120, (200 - 17 * k % 150) as u8]);
        }
        // Each face's quad as (a, b, c, d), counter-clockwise from outside.
        for [a, b, c, d] in [
            [0, 2, 3, 1], // -z
            [4, 5, 7, 6], // +z
            [0, 1, 5, 4], // -y
            [2, 6, 7, 3], // +y
            [0, 4, 6, 2], // -x
            [1, 3, 7, 5], // +x
        ] {
            triangles.push([base + a, base + b, base + c]);
            triangles.push([base + a, base + c, base + d]);
        }
    }
    let mut g = Geometry::new("boxes", positions, Primitives::Triangles(triangles));
    g.colors = Some(colors);
    Scene::single(g)
}

/// Rows of boxes behind one another: most are hidden from the front.
pub fn rows() -> Scene {
    let mut list = Vec::new();
    for row in 0..6 {
        for col in 0..6 {
            let lo = DVec3::new(f64::from(col) * 3.0, f64::from(row) * 3.0, 0.0);
            list.push((lo, lo + DVec3::new(2.0, 2.0, 2.0)));
        }
    }
    boxes(&list)
}

pub fn build(scene: &Scene, options: &PlpOptions) -> PagedFile {
    build_plp(scene, options).expect("plp build").0
}

pub fn small_pages() -> PlpOptions {
    PlpOptions {
        page_bytes: 2048,
        ..PlpOptions::default()
    }
}

fn camera(eye: DVec3, target: DVec3) -> Camera {
    Camera {
        eye,
        target,
        up: DVec3::Z,
        fov_y_deg: 60.0,
        width: 160,
        height: 120,
    }
}

/// The front camera: in front of the first row, looking down the rows.
fn front() -> Camera {
    camera(DVec3::new(8.0, -6.0, 1.0), DVec3::new(8.0, 8.0, 1.0))
}

fn walk(h: &Hierarchy, camera: &Camera, budget: Budget, order: Order) -> PlpCut {
    walk_with(h, camera, budget, order, Solidity::Count)
}

fn walk_with(
    h: &Hierarchy,
    camera: &Camera,
    budget: Budget,
    order: Order,
    solidity: Solidity,
) -> PlpCut {
    let mut cut = PlpCut::default();
    let options = Walk {
        budget,
        order,
        solidity,
        ..Walk::default()
    };
    traverse_plp_into(h, camera, &options, &mut PlpState::default(), &mut cut);
    cut
}

fn ids(cut: &PlpCut) -> Vec<u32> {
    cut.triangles.iter().map(|t| t.id).collect()
}

/// PLP unlimited draws what the centroid baseline (which looks at every
/// cell in view) draws: nothing more, and at least every triangle with a
/// corner strictly inside the frustum. (Culling is conservative: a
/// triangle just outside, past two planes at once, is kept by the
/// baseline's per-triangle test but lies in cells the front need not
/// reach.)
fn assert_finds_what_is_in_view(h: &Hierarchy, camera: &Camera, plp: &PlpCut, what: &str) {
    let baseline = walk(h, camera, Budget::Unlimited, Order::Centroid);
    let found = ids(plp);
    let all = ids(&baseline);
    assert!(
        found.iter().all(|i| all.binary_search(i).is_ok()),
        "{what}: PLP drew what the baseline did not"
    );
    let view = camera.view(1e-9);
    let inside = |p: DVec3| {
        let rel = p - view.eye;
        let depth = rel.dot(view.forward);
        depth > 1e-9
            && rel.dot(view.right).abs() < depth * view.tan_half_x * 0.999
            && rel.dot(view.up).abs() < depth * view.tan_half_y * 0.999
    };
    for t in &baseline.triangles {
        let Some(PlpPage::Cells(page)) = h.page(t.page as usize).and_then(|p| p.plp()) else {
            panic!("not a cell page");
        };
        let corners = page.triangles[t.index as usize]
            .corners
            .map(|c| page.world(c));
        if corners.iter().any(|&c| inside(c)) {
            assert!(
                found.binary_search(&t.id).is_ok(),
                "{what}: PLP missed triangle {} in view",
                t.id
            );
        }
    }
}

fn scene_triangles(h: &Hierarchy) -> u64 {
    h.plp_skeleton().expect("skeleton").scene_triangles
}

#[test]
fn budget_zero_draws_nothing_and_a_whole_budget_draws_everything() {
    let file = build(&rows(), &small_pages());
    let h = resident(&file);
    let n = scene_triangles(&h);
    assert_eq!(n, 36 * 12);
    let full = walk(&h, &front(), Budget::Unlimited, Order::Solidity);
    assert!(!full.triangles.is_empty());
    assert!(!full.budget_reached);
    let zero = walk(&h, &front(), Budget::Triangles(0), Order::Solidity);
    assert!(
        zero.triangles.is_empty(),
        "budget 0 drew {}",
        zero.triangles.len()
    );
    let zero_share = walk(&h, &front(), Budget::Percent(0.0), Order::Solidity);
    assert!(zero_share.triangles.is_empty());
    for whole in [
        Budget::Triangles(n),
        Budget::Percent(100.0),
        Budget::Triangles(n * 10),
    ] {
        let cut = walk(&h, &front(), whole, Order::Solidity);
        assert_eq!(ids(&cut), ids(&full), "{whole}");
    }
    // Every front-facing triangle in view is in the full set.
    assert_finds_what_is_in_view(&h, &front(), &full, "front");
    // A small budget is honoured exactly, and finds less.
    for k in [1, 7, 50] {
        let cut = walk(&h, &front(), Budget::Triangles(k), Order::Solidity);
        assert_eq!(
            cut.triangles.len() as u64,
            k.min(full.triangles.len() as u64)
        );
        assert!(cut.budget_reached || k as usize >= full.triangles.len());
    }
    // Sorted by id, each once.
    let mut sorted = ids(&full);
    sorted.dedup();
    assert_eq!(sorted, ids(&full));
}

#[test]
fn the_front_rows_come_before_the_hidden_ones() {
    let file = build(&rows(), &small_pages());
    let h = resident(&file);
    // A budget of one row's front faces: PLP should spend it up front.
    let cut = walk(&h, &front(), Budget::Triangles(24), Order::Solidity);
    let depth_of = |t: &farfield_traverse::plp::TriangleDraw| {
        let Some(PlpPage::Cells(page)) = h.page(t.page as usize).and_then(|p| p.plp()) else {
            panic!("not a cell page");
        };
        let c = page.triangles[t.index as usize]
            .corners
            .map(|c| page.world(c));
        (c[0].y + c[1].y + c[2].y) / 3.0
    };
    let mean = cut.triangles.iter().map(depth_of).sum::<f64>() / cut.triangles.len() as f64;
    // Rows are 3 apart from y = 0; the scene's mean depth is about 8.5.
    assert!(
        mean < 5.0,
        "the budget went to triangles at mean depth {mean}"
    );
}

#[test]
fn the_eye_anywhere_outside_on_a_face_edge_or_vertex_and_looking_away() {
    let file = build(&rows(), &small_pages());
    let h = resident(&file);
    let sk = h.plp_skeleton().expect("skeleton");
    let target = DVec3::new(8.0, 8.0, 1.0);
    // Far outside the hull.
    let outside = walk(
        &h,
        &camera(DVec3::new(8.0, -200.0, 30.0), target),
        Budget::Unlimited,
        Order::Solidity,
    );
    assert_eq!(outside.eye_cell, None);
    assert!(!outside.triangles.is_empty());
    assert_finds_what_is_in_view(
        &h,
        &camera(DVec3::new(8.0, -200.0, 30.0), target),
        &outside,
        "outside",
    );
    // An inner cell's vertex, the middle of its edge, the centre of a face.
    let inner = sk
        .cells
        .iter()
        .position(|c| c.neighbours.iter().all(|&n| n != u32::MAX))
        .expect("an inner cell");
    let cell = sk.cells[inner];
    let v = |i: usize| sk.vertices[cell.vertices[i] as usize];
    let on_face = face_corners(cell.vertices, 0)
        .iter()
        .map(|&i| sk.vertices[i as usize])
        .sum::<DVec3>()
        / 3.0;
    for (what, eye) in [
        ("vertex", v(0)),
        ("edge", (v(0) + v(1)) * 0.5),
        ("face", on_face),
    ] {
        let look = camera(eye, target + DVec3::new(0.1, 0.0, 0.0));
        let cut = walk(&h, &look, Budget::Unlimited, Order::Solidity);
        assert!(cut.eye_cell.is_some(), "{what}: the eye found no cell");
        assert_finds_what_is_in_view(&h, &look, &cut, what);
    }
    // From outside, looking away from everything: nothing, and no wishes.
    let away = walk(
        &h,
        &camera(DVec3::new(8.0, -200.0, 30.0), DVec3::new(8.0, -400.0, 30.0)),
        Budget::Unlimited,
        Order::Solidity,
    );
    assert!(away.triangles.is_empty());
    assert!(away.projected.is_empty());
}

#[test]
fn a_huge_triangle_crossing_many_cells_is_drawn_once() {
    let mut scene = rows();
    let huge = Geometry::new(
        "huge",
        vec![
            DVec3::new(-1.0, -1.0, 1.5),
            DVec3::new(30.0, -1.0, 1.5),
            DVec3::new(-1.0, 30.0, 1.5),
        ],
        Primitives::Triangles(vec![[0, 1, 2]]),
    );
    scene.merge(Scene::single(huge));
    let (file, stats) = build_plp(&scene, &small_pages()).expect("builds");
    let h = resident(&file);
    let huge_id = (stats.triangles - 1) as u32;
    // Stored in many cells (and pages), drawn once.
    let mut cells = 0;
    for page in file.pages.iter().enumerate().skip(1).map(|(i, _)| i) {
        if let Some(PlpPage::Cells(p)) = h.page(page).and_then(|p| p.plp()) {
            for local in 0..p.starts.len() - 1 {
                cells += p.cell(local).filter(|t| t.id == huge_id).count();
            }
        }
    }
    assert!(cells > 10, "the huge triangle is in {cells} cells");
    let from_above = camera(DVec3::new(14.0, 14.0, 40.0), DVec3::new(14.0, 14.5, 0.0));
    let cut = walk(&h, &from_above, Budget::Unlimited, Order::Solidity);
    assert_eq!(ids(&cut).iter().filter(|&&i| i == huge_id).count(), 1);
    let mut all = ids(&cut);
    all.dedup();
    assert_eq!(all.len(), cut.triangles.len(), "a triangle was drawn twice");
}

#[test]
fn one_triangle_one_leaf_an_exact_lattice_and_an_empty_scene() {
    let single = Scene::single(Geometry::new(
        "one",
        vec![DVec3::ZERO, DVec3::X, DVec3::Y],
        Primitives::Triangles(vec![[0, 1, 2]]),
    ));
    let h = resident(&build(&single, &PlpOptions::default()));
    let above = camera(DVec3::new(0.3, 0.3, 2.0), DVec3::new(0.31, 0.3, 0.0));
    assert_eq!(
        ids(&walk(&h, &above, Budget::Unlimited, Order::Solidity)),
        vec![0]
    );
    let below = camera(DVec3::new(0.3, 0.3, -2.0), DVec3::new(0.31, 0.3, 0.0));
    assert!(
        walk(&h, &below, Budget::Unlimited, Order::Solidity)
            .triangles
            .is_empty(),
        "the back of the triangle is culled"
    );

    // Everything in a few leaves: big cells, a budget met inside a cell.
    let coarse = PlpOptions {
        leaf_fraction: 1.0,
        ..PlpOptions::default()
    };
    let h = resident(&build(&rows(), &coarse));
    assert!(h.plp_skeleton().expect("skeleton").cells.len() < 64);
    let cut = walk(&h, &front(), Budget::Triangles(5), Order::Solidity);
    assert_eq!(cut.triangles.len(), 5);

    // Leaf centres on an exact lattice, unperturbed: slivers and
    // cospherical cells everywhere; still valid, no NaN in the queue (the
    // full set equals the baseline's).
    let lattice = PlpOptions {
        jitter: 0.0,
        ..small_pages()
    };
    let flat = boxes(&[(DVec3::ZERO, DVec3::new(16.0, 16.0, 0.01))]);
    for scene in [rows(), flat] {
        let h = resident(&build(&scene, &lattice));
        for cam in [
            front(),
            camera(DVec3::new(3.0, 2.0, 5.0), DVec3::new(9.0, 9.0, 0.0)),
        ] {
            let cut = walk(&h, &cam, Budget::Unlimited, Order::Solidity);
            assert!(!cut.triangles.is_empty());
            assert_finds_what_is_in_view(&h, &cam, &cut, "lattice");
        }
    }

    assert!(matches!(
        build_plp(&Scene::default(), &PlpOptions::default()),
        Err(BuildError::Empty)
    ));
    // Zero-area triangles alone are no scene either.
    let degenerate = Scene::single(Geometry::new(
        "flat",
        vec![DVec3::ZERO, DVec3::X, DVec3::X * 2.0],
        Primitives::Triangles(vec![[0, 1, 2]]),
    ));
    assert!(matches!(
        build_plp(&degenerate, &PlpOptions::default()),
        Err(BuildError::Empty)
    ));
}

#[test]
fn streamed_pages_are_wanted_in_projection_order_and_within_the_budget() {
    let file = build(&rows(), &small_pages());
    assert!(file.pages.len() > 8, "{} pages", file.pages.len());
    let whole = resident(&file);
    let sk = whole.plp_skeleton().expect("skeleton");
    let budget = Budget::Triangles(40);
    let target = walk(&whole, &front(), budget, Order::Solidity);
    // Only the skeleton: PLP already orders everything.
    let mut h = crate::with_directory(&file);
    h.insert_page(0, &file.pages[0]).expect("page 0");
    let first = walk(&h, &front(), budget, Order::Solidity);
    assert!(first.triangles.is_empty());
    assert!(!first.wanted.is_empty());
    // The wanted cells' |c| stop at the first to reach the budget.
    let page_of = |c: u32| h.directory().page_of(1 + u64::from(c)).expect("a page");
    let mut committed = 0u64;
    let mut expected = Vec::new();
    for &c in &first.projected {
        let size = u64::from(sk.cells[c as usize].triangles);
        if size == 0 || committed >= 40 {
            continue;
        }
        committed += size;
        let p = page_of(c);
        if !expected.contains(&p) {
            expected.push(p);
        }
    }
    let wanted: Vec<u32> = first.wanted.iter().map(|w| w.page).collect();
    assert_eq!(wanted, expected, "pages in projection order");
    assert!(wanted.len() < file.pages.len() - 1, "wanted every page");
    // Pages arrive most urgent first; the front advances past the rest,
    // and the cut converges on the file's own.
    let mut fetched = 0;
    for _ in 0..file.pages.len() {
        let cut = walk(&h, &front(), budget, Order::Solidity);
        let Some(next) = cut.wanted.first() else {
            break;
        };
        h.insert_page(next.page, &file.pages[next.page as usize])
            .expect("page");
        fetched += 1;
    }
    let last = walk(&h, &front(), budget, Order::Solidity);
    assert!(last.wanted.is_empty());
    assert_eq!(ids(&last), ids(&target));
    assert!(
        fetched < file.pages.len() - 1,
        "fetched all {fetched} pages"
    );
    // Moving changes the order.
    let side = camera(DVec3::new(-8.0, 8.0, 1.0), DVec3::new(8.0, 8.0, 1.0));
    let mut h0 = crate::with_directory(&file);
    h0.insert_page(0, &file.pages[0]).expect("page 0");
    let moved: Vec<u32> = walk(&h0, &side, budget, Order::Solidity)
        .wanted
        .iter()
        .map(|w| w.page)
        .collect();
    assert_ne!(moved, wanted);
}

#[test]
fn a_corrupt_skeleton_or_cell_page_is_refused_whole() {
    let file = build(&rows(), &small_pages());
    let mut h = crate::with_directory(&file);
    let mut bad = file.pages[0].clone();
    let mid = bad.len() / 2;
    bad[mid] ^= 0x10;
    assert!(h.insert_page(0, &bad).is_err());
    let mut bad = file.pages[1].clone();
    bad[40] ^= 1;
    assert!(h.insert_page(1, &bad).is_err());
    assert_eq!(h.resident_pages(), 0);
}

/// The tessellation of an instanced scene equals that of the same scene
/// with the instances expanded by hand.
#[test]
fn instances_are_expanded_into_world_triangles() {
    let one = rows();
    let mut two = one.clone();
    two.instances.push(Instance {
        geometry: 0,
        world_from_local: DAffine3::from_translation(DVec3::new(0.0, 0.0, 10.0)),
    });
    let (_, a) = build_plp(&one, &PlpOptions::default()).expect("one");
    let (_, b) = build_plp(&two, &PlpOptions::default()).expect("two");
    assert_eq!(b.triangles, 2 * a.triangles);
}

/// Draws a cut; returns the image and the item buffer's visible ids.
fn render(
    renderer: &mut farfield_render::Renderer,
    h: &Hierarchy,
    camera: &Camera,
    cut: &PlpCut,
) -> (Vec<u8>, Vec<u32>) {
    let mut vertices = Vec::new();
    farfield_render::pack_plp(h, cut, camera.eye, &mut vertices);
    let image = renderer
        .render_geometry(camera, &vertices, &[], Default::default(), [0; 3])
        .expect("draws");
    let items = renderer
        .item_buffer(camera, &vertices, &ids(cut))
        .expect("item buffer");
    (image.rgba, farfield_render::visible_ids(&items))
}

#[test]
fn the_whole_budget_gives_the_full_render_and_coverage_one() {
    let Some(mut renderer) = farfield_render::headless_or_skip(160, 120).expect("adapter") else {
        return;
    };
    let file = build(&rows(), &small_pages());
    let h = resident(&file);
    let n = scene_triangles(&h);
    let cam = front();
    let full = walk(&h, &cam, Budget::Unlimited, Order::Solidity);
    let (full_image, visible) = render(&mut renderer, &h, &cam, &full);
    assert!(!visible.is_empty());
    // V is a subset of what the full cut drew, and it is much smaller:
    // most boxes hide behind the first row.
    assert!(visible.iter().all(|v| ids(&full).binary_search(v).is_ok()));
    assert!(visible.len() < full.triangles.len());
    let coverage = |cut: &PlpCut| {
        let t = ids(cut);
        visible
            .iter()
            .filter(|v| t.binary_search(v).is_ok())
            .count() as f64
            / visible.len() as f64
    };
    let whole = walk(&h, &cam, Budget::Triangles(n), Order::Solidity);
    let (image, _) = render(&mut renderer, &h, &cam, &whole);
    assert_eq!(coverage(&whole), 1.0);
    let wrong = farfield_image::compare(&full_image, &image, 160, 120, 0).expect("same size");
    assert_eq!(
        wrong.wrong_fraction, 0.0,
        "the whole budget is the full render"
    );
    // Budgets between: coverage grows with the budget, and PLP's beats
    // the nearest-centroid baseline's at the same small budget.
    let mut last = 0.0;
    for k in [0, 12, 48, 120] {
        let cut = walk(&h, &cam, Budget::Triangles(k), Order::Solidity);
        let c = coverage(&cut);
        assert!(c >= last, "coverage fell from {last} to {c} at budget {k}");
        last = c;
        if k == 0 {
            assert_eq!(c, 0.0);
            let (image, _) = render(&mut renderer, &h, &cam, &cut);
            assert!(
                image.chunks(4).all(|p| p[..3] == [0, 0, 0]),
                "budget 0 drew"
            );
        }
    }
    assert!(last > 0.5, "120 triangles found {last} of the visible set");
}

#[test]
fn streamed_plp_at_a_budget_equals_the_file_and_fetches_less() {
    use farfield_client::budget::BudgetSpec;
    use farfield_client::camera_spec::CameraSpec;
    use farfield_client::render_job::{RenderJob, Source, run};
    use farfield_render::headless_or_skip;

    let Some(mut renderer) = headless_or_skip(160, 120).expect("adapter") else {
        return;
    };
    let dir = farfield_tests::scratch("plp-stream");
    let file = build(&rows(), &small_pages());
    farfield_store::write_atomic(&dir.join("rows.ff"), &file).expect("writes");
    let rt = crate::streaming::runtime();
    let server = crate::streaming::serve(&rt, &dir, 0);
    let url = format!("http://{}", server.local_addr());
    let cam = front();
    let job = |source, budget| RenderJob {
        source,
        camera: CameraSpec::Eye {
            eye: cam.eye,
            target: cam.target,
            fov_deg: cam.fov_y_deg,
        },
        width: 160,
        height: 120,
        out: None,
        until: farfield_client::frame_loop::Until::Refined,
        threshold_px: 1.0,
        kernel: Default::default(),
        edl: None,
        color_by: Default::default(),
        clip: None,
        coverage: Default::default(),
        session: Default::default(),
        cache_bytes: 64 << 20,
        timeout: std::time::Duration::from_secs(60),
        budget: BudgetSpec {
            triangles: budget,
            ms: None,
            mode: None,
        },
    };
    for budget in [Budget::Triangles(40), Budget::Unlimited] {
        let from_file = run(
            &job(Source::File(dir.join("rows.ff")), budget),
            &mut renderer,
            false,
        )
        .expect("file render");
        let streamed = run(
            &job(
                Source::Server {
                    url: url.clone(),
                    scene: "rows".into(),
                },
                budget,
            ),
            &mut renderer,
            false,
        )
        .expect("streamed render");
        assert!(
            streamed.report.refined,
            "{budget}: {:?}",
            streamed.report.last_error
        );
        let wrong = farfield_image::compare(&from_file.rgba, &streamed.rgba, 160, 120, 0)
            .expect("same size");
        assert_eq!(wrong.wrong_fraction, 0.0, "{budget}: streamed differs");
        let pages = streamed.report.net.pages_received;
        if budget == Budget::Triangles(40) {
            assert!(
                (pages as usize) < file.pages.len() / 2,
                "a 40-triangle budget fetched {pages} of {} pages",
                file.pages.len()
            );
        }
    }
    rt.block_on(server.shutdown()).expect("shutdown");
}

#[test]
fn bench_plp_reports_coverage_wrong_pixels_and_the_papers_row() {
    use farfield_client::path::{CameraPath, Keyframe};
    use farfield_tools::bench_plp::{PaperRow, PlpBenchJob, format_table, frames_csv, run};

    let Some(mut renderer) = farfield_render::headless_or_skip(160, 120).expect("adapter") else {
        return;
    };
    let dir = farfield_tests::scratch("plp-bench");
    let file_path = dir.join("rows.ff");
    farfield_store::write_atomic(&file_path, &build(&rows(), &small_pages())).expect("writes");
    let key = |t: f64, x: f64| Keyframe {
        t,
        orbit: None,
        eye: Some([x, -6.0, 1.0]),
        target: Some([8.0, 8.0, 1.0]),
        fov: Some(60.0),
    };
    let path =
        CameraPath::from_keyframes(&[key(0.0, 2.0), key(1.0, 8.0), key(2.0, 14.0)]).expect("path");
    let job = PlpBenchJob {
        file: file_path,
        path,
        budgets: vec![
            Budget::Percent(2.0),
            Budget::Percent(10.0),
            Budget::Unlimited,
        ],
        centroid_budget: Budget::Percent(10.0),
        width: 160,
        height: 120,
        repeats: 1,
        stride: 1,
        paper: Some(PaperRow::city()),
        star_penalty: farfield_traverse::plp::DEFAULT_STAR_PENALTY,
        solidity: Default::default(),
    };
    let report = run(&job, &mut renderer).expect("bench runs");
    assert_eq!(report.frames.len(), 3);
    assert_eq!(report.summaries.len(), 4);
    let [small, ten, all, centroid] = &report.summaries[..] else {
        panic!("four summaries");
    };
    assert_eq!(all.mean_coverage, 1.0);
    assert_eq!(all.worst_wrong_fraction, 0.0);
    assert!(small.mean_coverage <= ten.mean_coverage);
    assert!(ten.mean_coverage < 1.0 || ten.worst_wrong_fraction == 0.0);
    assert!(small.worst_wrong_fraction > 0.0, "2 % drew every pixel");
    assert_eq!(ten.paper_coverage, Some(0.90));
    assert_eq!(centroid.paper_coverage, None);
    for f in &report.frames {
        assert!(f.visible > 0 && f.visible <= f.whole_triangles);
        for d in &f.drawn {
            assert!(d.visible_found <= d.triangles && d.visible_found <= f.visible);
        }
    }
    let table = format_table(&report);
    assert!(
        table.contains("| plp 10% |") && table.contains("90 %"),
        "{table}"
    );
    assert_eq!(frames_csv(&report).lines().count(), 4);
    farfield_tools::bench_plp::write_figures(&report, &dir).expect("figures");
    assert!(dir.join("visible.svg").exists() && dir.join("frame_time.svg").exists());
}

#[test]
fn the_coverage_solidity_sees_walls_and_keeps_the_budget() {
    let file = build(&rows(), &small_pages());
    let h = resident(&file);
    let sk = h.plp_skeleton().expect("skeleton");
    // Empty cells cover nothing; a cell a box passes through is covered.
    for c in &sk.cells {
        assert!(c.coverage.is_finite() && c.coverage >= 0.0);
        assert_eq!(c.triangles == 0, c.coverage == 0.0, "{c:?}");
    }
    assert!(
        sk.cells.iter().any(|c| c.coverage >= 1.0),
        "no cell is covered"
    );
    let full = walk(&h, &front(), Budget::Unlimited, Order::Solidity);
    let same = walk_with(
        &h,
        &front(),
        Budget::Unlimited,
        Order::Solidity,
        Solidity::Coverage,
    );
    assert_eq!(
        ids(&same),
        ids(&full),
        "an unlimited budget draws the same set"
    );
    for k in [0, 5, 60] {
        let cut = walk_with(
            &h,
            &front(),
            Budget::Triangles(k),
            Order::Solidity,
            Solidity::Coverage,
        );
        assert_eq!(
            cut.triangles.len() as u64,
            k.min(full.triangles.len() as u64)
        );
    }
    assert_eq!("coverage".parse::<Solidity>(), Ok(Solidity::Coverage));
    assert!("area".parse::<Solidity>().is_err());
}
