//! A build reports its steps in order, and each step's parts add up to the
//! total it announced, so a progress bar ends at 100 %.

use std::sync::Mutex;

use farfield_builder::import::{Params, load_input};
use farfield_builder::scene::{Geometry, Primitives, Scene};
use farfield_builder::{BuildOptions, BuildStats, Progress, build_spheres_reporting};
use glam::DVec3;

/// A step begun: its name, its total, the sum of its parts, and how many
/// (non-empty) parts were reported.
type Step = (&'static str, u64, u64, usize);

/// Every step begun.
#[derive(Default)]
struct Recorder(Mutex<Vec<Step>>);

impl Progress for Recorder {
    fn begin(&self, step: &'static str, total: u64) {
        self.0.lock().unwrap().push((step, total, 0, 0));
    }
    fn advance(&self, done: u64) {
        let mut steps = self.0.lock().unwrap();
        let current = steps.last_mut().expect("advance before any step began");
        current.2 += done;
        current.3 += usize::from(done > 0);
    }
}

/// The steps a build reported, and its stats.
fn steps_of(scene: Scene) -> (Vec<Step>, BuildStats) {
    let recorder = Recorder::default();
    let (_, stats) =
        build_spheres_reporting(scene, &BuildOptions::default(), &recorder).expect("build");
    (recorder.0.into_inner().unwrap(), stats)
}

fn assert_complete(steps: &[Step], stats: &BuildStats) {
    let names: Vec<_> = steps.iter().map(|s| s.0).collect();
    assert_eq!(names, ["leaves", "tree", "layout"]);
    for &(step, total, done, _) in steps {
        assert_eq!(done, total, "{step}: parts add up to {done} of {total}");
    }
    assert_eq!(steps[0].1, stats.input_vertices, "leaves count vertices");
    assert_eq!(steps[2].1, stats.nodes, "layout counts the file's nodes");
}

#[test]
fn an_instanced_scene_reports_every_step_to_its_end() {
    let mut params = Params::default();
    params.set("size", 200);
    params.set("trees", 16);
    let (steps, stats) = steps_of(load_input("gen:island", &params).unwrap());
    assert_complete(&steps, &stats);
    // Big enough that the tree is built as several tasks.
    assert!(steps[1].1 > 100_000, "{steps:?}");
}

#[test]
fn a_single_mesh_reports_its_leaves_as_they_are_sized() {
    // 300 x 300 vertices, about 180,000 triangles, no normals: each of the
    // two vertex ranges (one per thread) walks the triangles twice, and reports
    // after each 64 Ki of them, so at least 2 x 2 x 3 parts.
    let scene = Scene::single(crate::extremes::grid_mesh(300, 1.0));
    let two_threads = rayon::ThreadPoolBuilder::new().num_threads(2).build();
    let (steps, stats) = two_threads.expect("pool").install(|| steps_of(scene));
    assert_complete(&steps, &stats);
    let (_, _, _, parts) = steps[0];
    assert!(parts >= 12, "the leaves step came in {parts} parts");
}

#[test]
fn duplicates_collapse_without_leaving_the_layout_short() {
    let mut positions: Vec<DVec3> = (0..5_000)
        .map(|i| DVec3::new(f64::from(i % 71), f64::from(i / 71), 0.0))
        .collect();
    positions.extend(std::iter::repeat_n(DVec3::new(3.0, 4.0, 0.0), 1_000));
    let scene = Scene::single(Geometry::new("points", positions, Primitives::Points));
    let (steps, stats) = steps_of(scene);
    // The tree is given every leaf; the layout places only those left after
    // collapsing, and its total must say so.
    assert_eq!(stats.collapsed_duplicates, 1_000);
    assert_complete(&steps, &stats);
}
