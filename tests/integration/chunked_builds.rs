//! Sphere builds out of core (`build --memory`): point clouds over the
//! budget built in chunks spilled to disk, against the same clouds built in
//! memory; a build killed at each phase; a build inside a memory cgroup
//! smaller than its in-memory build needs.

use std::path::{Path, PathBuf};
use std::time::Duration;

use farfield_builder::import::Params;
use farfield_builder::out_of_core::ABORT_AFTER_ENV;
use farfield_builder::scene::Primitives;
use farfield_builder::{BuildOptions, build_spheres};
use farfield_client::camera_spec::CameraSpec;
use farfield_client::frame_loop::Until;
use farfield_client::render_job::{RenderJob, Source, run};
use farfield_image::compare;
use farfield_net::SessionOptions;
use farfield_render::{Coverage, Kernel, headless_or_skip};
use farfield_store::{SceneFile, write_atomic};
use farfield_tests::{child_ran, child_test, scratch, shared_data};
use glam::DVec3;

use crate::cgroup::MemoryCgroup;

const SIZE: (u32, u32) = (320, 240);

/// Generated LAS tiles: `points` over a `grid` x `grid` survey.
fn tiles(dir: &Path, points: u64, grid: u32) -> PathBuf {
    let out = dir.join(format!("tiles-{points}"));
    crate::cli(&[
        "lidar-tiles",
        "--points",
        &points.to_string(),
        "--grid",
        &grid.to_string(),
        "--out",
        out.to_str().unwrap(),
    ])
    .expect("lidar-tiles");
    out
}

/// `build INPUT --out OUT --json` with `extra` arguments; its JSON report.
fn build(input: &Path, out: &Path, extra: &[&str]) -> serde_json::Value {
    let mut args = vec![
        "build",
        input.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--json",
    ];
    args.extend(extra);
    crate::cli(&args).expect("build").json
}

/// Two cameras looking down on the scene of `file` from outside, where an
/// extra point at `behind` is out of view.
fn cameras(file: &Path) -> Vec<(DVec3, DVec3)> {
    let h = SceneFile::open(file).expect("open").header;
    let center = (h.bounds_min + h.bounds_max) * 0.5;
    let extent = (h.bounds_max - h.bounds_min).max_element();
    [DVec3::new(0.6, -0.7, 0.5), DVec3::new(-0.25, 0.3, 0.15)]
        .into_iter()
        .map(|offset| {
            (
                center + offset * extent,
                center + DVec3::new(0.05, 0.0, 0.0) * extent,
            )
        })
        .collect()
}

/// The file's image from `eye` towards `target` at a 1-pixel threshold.
fn render(
    renderer: &mut farfield_render::Renderer,
    file: &Path,
    (eye, target): (DVec3, DVec3),
) -> Vec<u8> {
    let job = RenderJob {
        source: Source::File(file.to_owned()),
        camera: CameraSpec::Eye {
            eye,
            target,
            fov_deg: 50.0,
        },
        width: SIZE.0,
        height: SIZE.1,
        out: None,
        until: Until::Refined,
        threshold_px: 1.0,
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
    run(&job, renderer, false).expect("render").rgba
}

/// The in-memory build of `input` with one more point, at `far`: a tree
/// as valid as the first (its bisection planes all move), which no camera
/// here sees. How much two such builds' images differ is the measure an
/// out-of-core build's tree, also another valid tree, is held to.
fn with_far_point(input: &Path, far: DVec3, out: &Path) {
    let mut scene = farfield_builder::import::load_inputs(
        &[input.to_str().unwrap().to_string()],
        &Params::default(),
    )
    .expect("load");
    let g = &mut scene.geometries[0];
    // A mesh's unused vertex would be left out: it gets a triangle, as
    // small next to the scene as a cloud's point is.
    let side = g.positions.first().map_or(1.0, |&p| p.distance(far)) * 1e-5;
    let corners = match &mut g.primitives {
        Primitives::Triangles(triangles) => {
            let first = g.positions.len() as u32;
            triangles.push([first, first + 1, first + 2]);
            vec![far, far + DVec3::X * side, far + DVec3::Y * side]
        }
        _ => vec![far],
    };
    for corner in corners {
        g.positions.push(corner);
        if let Some(c) = &mut g.colors {
            c.push([255, 0, 0]);
        }
        if let Some(n) = &mut g.normals {
            n.push(glam::Vec3::Z);
        }
    }
    let (file, _) = build_spheres(scene, &BuildOptions::default()).expect("build");
    write_atomic(out, &file).expect("write");
}

/// Point clouds and meshes forced out of core by a budget far below
/// their needs against their in-memory builds: the same node record size
/// and bytes per node within 1 %, the same leaves, and images at a
/// 1-pixel threshold no further from the in-memory build's than the
/// in-memory build's own with one invisible point (or triangle) more (its
/// tree is as different; see docs/experiments.md).
#[test]
fn clouds_and_meshes_built_in_chunks_render_as_in_memory_builds_do() {
    let Some(mut renderer) = headless_or_skip(SIZE.0, SIZE.1).unwrap() else {
        return;
    };
    let dir = scratch("chunked");
    // Budgets far below the in-memory builds' (about 100 bytes a point):
    // chunks of the smallest size (1,000 points), and of about 10,000.
    let mut inputs = vec![
        ("tiles", tiles(&dir, 60_000, 3), "1"),
        ("tree", PathBuf::from("gen:tree"), "1"),
    ];
    match shared_data() {
        Some(data) => {
            inputs.push(("autzen", data.join("autzen_trim.las"), "4M"));
            inputs.push(("bunny", data.join("stanford-bunny.obj"), "1"));
            // Read as streams (the bunny too): normals; triangle strips. Chunks of a few
            // thousand vertices (of 1,000, the horse's tree is further
            // from the in-memory one than the other valid tree: 27.6 dB
            // against 30.1 at the first view).
            inputs.push(("horse", data.join("horse.ply"), "1M"));
            inputs.push(("igea", data.join("igea.ply"), "2M"));
        }
        None => eprintln!("SKIPPED the autzen, bunny, horse and igea parts: no shared data"),
    }
    for (name, input, budget) in inputs {
        let memory = dir.join(format!("{name}.memory.ff"));
        let chunked = dir.join(format!("{name}.chunked.ff"));
        let in_memory = build(&input, &memory, &[]);
        assert_eq!(in_memory["out_of_core"], false, "{in_memory}");
        let spill = dir.join("spill");
        let out_of_core = build(
            &input,
            &chunked,
            &["--memory", budget, "--tmp", spill.to_str().unwrap()],
        );
        assert_eq!(out_of_core["out_of_core"], true, "{out_of_core}");
        let chunks = out_of_core["stats"]["chunks"].as_u64().unwrap();
        assert!(chunks >= 20, "{name}: {chunks} chunks");
        assert!(
            std::fs::read_dir(&spill).unwrap().next().is_none(),
            "{name}: temporary files left behind"
        );
        let (a, b) = (&in_memory, &out_of_core);
        assert_eq!(a["input_vertices"], b["input_vertices"]);
        assert_eq!(a["stats"]["leaves"], b["stats"]["leaves"], "{name}: leaves");
        let per_node = |r: &serde_json::Value| r["bytes_per_node"].as_f64().unwrap();
        let ratio = per_node(b) / per_node(a);
        assert!(
            (0.99..1.01).contains(&ratio),
            "{name}: bytes per node {} against {}",
            per_node(b),
            per_node(a)
        );
        let views = cameras(&memory);
        let (eye, target) = views[0];
        let other = dir.join(format!("{name}.other-tree.ff"));
        with_far_point(&input, eye + (eye - target) * 2.0, &other);
        for (v, &view) in views.iter().enumerate() {
            let reference = render(&mut renderer, &memory, view);
            let psnr = |file: &Path, renderer: &mut farfield_render::Renderer| {
                compare(&reference, &render(renderer, file, view), SIZE.0, SIZE.1, 8)
                    .unwrap()
                    .psnr_db
            };
            let chunked_db = psnr(&chunked, &mut renderer);
            let other_db = psnr(&other, &mut renderer);
            eprintln!(
                "{name} view {v}: out of core {chunked_db:.2} dB from in memory; in memory with one unseen point more {other_db:.2} dB"
            );
            // The bound is the other valid tree's; the floor only catches
            // an image that is not the scene at all (the tree's thin
            // leaves, a pixel wide, differ most between valid trees: 18.7
            // dB at the second view).
            assert!(
                chunked_db >= 15.0 && chunked_db >= other_db - 1.0,
                "{name} view {v}: {chunked_db:.2} dB (another valid tree: {other_db:.2} dB)"
            );
        }
    }
}

/// A scene mixing meshes with point clouds over the budget is built in
/// memory, and the report says why; so does a kind other than spheres
/// given a budget.
#[test]
fn a_mixed_scene_over_the_budget_is_built_in_memory_with_a_note() {
    let dir = scratch("chunked-mixed");
    let out = dir.join("mixed.ff");
    let cloud = tiles(&dir, 2_000, 1);
    let report = crate::cli(&[
        "build",
        "gen:tree",
        cloud.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--memory",
        "1",
        "--json",
    ])
    .expect("build")
    .json;
    assert_eq!(report["out_of_core"], false);
    let note = report["note"].as_str().unwrap_or_default();
    assert!(note.contains("a mesh among point clouds"), "{report}");
    assert!(SceneFile::open(&out).is_ok());
    let cubes = crate::cli(&[
        "build",
        "gen:tree",
        "--kind",
        "cubes",
        "--out",
        dir.join("cubes.ff").to_str().unwrap(),
        "--memory",
        "1",
        "--json",
    ])
    .expect("build cubes")
    .json;
    let note = cubes["note"].as_str().unwrap_or_default();
    assert!(note.contains("sphere builds only"), "{cubes}");
}

/// The child process of the tests below: `farfield-server` with the
/// arguments in `FARFIELD_BUILD_CHILD_ARGS` (one a line). Ignored because
/// it is not a test of its own but an entry point: a build that must run
/// in a process of its own (to be killed, or to be put in a memory
/// cgroup) runs this test binary again on it alone, as the serve and
/// objects tests do (`farfield_tests::child_test`); the parent checks
/// that it ran (`child_ran`). Run by hand, it does nothing.
#[test]
#[ignore = "an entry point for child processes, run by the tests below"]
fn build_child() {
    let Ok(args) = std::env::var("FARFIELD_BUILD_CHILD_ARGS") else {
        return;
    };
    let args: Vec<&str> = args.lines().collect();
    let report = crate::cli(&args).expect("build");
    println!("{}", report.json);
}

/// Runs [`build_child`] with `args`, its environment added; its exit
/// status and standard output.
fn child(args: &[&str], envs: &[(&str, &str)], cgroup: Option<&MemoryCgroup>) -> (bool, String) {
    let mut command = child_test("chunked_builds::build_child");
    command
        .env("FARFIELD_BUILD_CHILD_ARGS", args.join("\n"))
        .envs(envs.iter().copied())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::null());
    let process = command.spawn().expect("spawn");
    if let Some(c) = cgroup {
        // Moved at once: the build has hardly begun importing.
        c.add(process.id());
    }
    let out = process.wait_with_output().expect("wait");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    (out.status.success() && child_ran(&out.stdout), stdout)
}

/// As [`child`], with its standard error too (where a failure says why).
fn child_output(args: &[&str], envs: &[(&str, &str)]) -> (bool, String, String) {
    let out = child_test("chunked_builds::build_child")
        .env("FARFIELD_BUILD_CHILD_ARGS", args.join("\n"))
        .envs(envs.iter().copied())
        .output()
        .expect("run");
    (
        out.status.success() && child_ran(&out.stdout),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn build_folders(tmp: &Path) -> Vec<PathBuf> {
    std::fs::read_dir(tmp)
        .map(|d| {
            d.flatten()
                .filter(|e| {
                    e.file_name()
                        .to_string_lossy()
                        .starts_with(".farfield-build-")
                })
                .map(|e| e.path())
                .collect()
        })
        .unwrap_or_default()
}

/// A build killed after each of its phases leaves no output, and its
/// temporary folder, left behind, is removed by the next build, which
/// succeeds; so is the file of a write killed before its rename.
#[test]
fn a_build_killed_at_any_phase_leaves_nothing_a_later_build_trips_over() {
    let dir = scratch("chunked-killed");
    let input = tiles(&dir, 20_000, 2);
    let tmp = dir.join("spill");
    let out = dir.join("out.ff");
    let args = [
        "build",
        input.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--memory",
        "1",
        "--tmp",
        tmp.to_str().unwrap(),
        "--json",
    ];
    // A write killed mid-way (the file before its rename, named by the
    // writer's process): gone once its process is, kept while it runs.
    let temp = |pid: u32| dir.join(format!(".out.ff.tmp-{pid}"));
    let mut dead = std::process::Command::new("true").spawn().unwrap();
    dead.wait().unwrap();
    let mut alive = std::process::Command::new("sleep")
        .arg("60")
        .spawn()
        .unwrap();
    std::fs::write(temp(dead.id()), b"half a file").unwrap();
    std::fs::write(temp(alive.id()), b"a file being written").unwrap();
    crate::cli(&args).expect("build");
    assert!(!temp(dead.id()).exists(), "a killed write's file is left");
    assert!(
        temp(alive.id()).exists(),
        "a running write's file was removed"
    );
    let _ = alive.kill();
    let _ = alive.wait();
    std::fs::remove_file(temp(alive.id())).unwrap();
    std::fs::remove_file(&out).unwrap();
    killed_at_each_phase(&args, &out, &tmp);
    // A mesh's build, which has phases of its own before the join.
    let mesh_args = [&["build", "gen:tree"], &args[2..]].concat();
    killed_at_each_phase(&mesh_args, &out, &tmp);
}

/// Runs the build of `args` killed after each phase, then whole.
fn killed_at_each_phase(args: &[&str], out: &Path, tmp: &Path) {
    for phase in ["count", "spread", "chunks", "top", "levels", "pages"] {
        let (ok, _) = child(args, &[(ABORT_AFTER_ENV, phase)], None);
        assert!(!ok, "{phase}: the build was not killed");
        assert!(!out.exists(), "{phase}: a killed build left an output");
        assert_eq!(
            build_folders(tmp).len(),
            1,
            "{phase}: no abandoned folder to clean"
        );
        let report = crate::cli(args).expect("the next build");
        assert_eq!(report.json["out_of_core"], true);
        assert!(
            build_folders(tmp).is_empty(),
            "{phase}: temporary files left"
        );
        assert!(SceneFile::open(out).is_ok());
        std::fs::remove_file(out).unwrap();
    }
}

/// All the memory the out-of-core build may hold.
const LIMIT: u64 = 112 << 20;

/// A cloud whose in-memory build peaks above a memory cgroup's limit is
/// built inside it out of core: not killed, the limit held, the file whole.
#[cfg(target_os = "linux")]
#[test]
fn a_cloud_builds_inside_a_cgroup_smaller_than_its_in_memory_build_needs() {
    let dir = scratch("chunked-cgroup");
    let input = tiles(&dir, 1_500_000, 4);
    builds_inside_a_cgroup("chunked-build", &dir, input.to_str().unwrap(), 1_500_000);
}

/// So is a mesh: 32 instances of a tree, 2.4 million vertices placed,
/// which the in-memory build holds as leaves all at once.
#[cfg(target_os = "linux")]
#[test]
fn a_mesh_builds_inside_a_cgroup_smaller_than_its_in_memory_build_needs() {
    let dir = scratch("chunked-cgroup-mesh");
    builds_inside_a_cgroup("chunked-build-mesh", &dir, "gen:forest?trees=32", 2_436_320);
}

/// So is a PLY mesh, read as a stream: a wavy grid of 1.5 million
/// vertices, whose import alone holds about 60 MiB.
#[cfg(target_os = "linux")]
#[test]
fn a_ply_mesh_builds_inside_a_cgroup_smaller_than_its_in_memory_build_needs() {
    let dir = scratch("chunked-cgroup-ply");
    let path = dir.join("grid.ply");
    write_grid_ply(&path, 1225);
    builds_inside_a_cgroup(
        "chunked-build-ply",
        &dir,
        path.to_str().unwrap(),
        1225 * 1225,
    );
}

/// So is an OBJ mesh, read as a stream after a survey of the whole file:
/// the same grid, with its normals given by face corners, which the
/// build gathers on disk.
#[cfg(target_os = "linux")]
#[test]
fn an_obj_mesh_builds_inside_a_cgroup_smaller_than_its_in_memory_build_needs() {
    let dir = scratch("chunked-cgroup-obj");
    let path = dir.join("grid.obj");
    write_grid_obj(&path, 1225);
    builds_inside_a_cgroup(
        "chunked-build-obj",
        &dir,
        path.to_str().unwrap(),
        1225 * 1225,
    );
}

/// A wavy `side` x `side` grid's vertices, and its triangles, two a cell.
fn grid(
    side: u32,
) -> (
    impl Iterator<Item = [f32; 3]>,
    impl Iterator<Item = [u32; 3]>,
) {
    let vertices = (0..side * side).map(move |i| {
        let (fx, fy) = ((i % side) as f32 * 0.1, (i / side) as f32 * 0.1);
        [fx, fy, (fx * 0.7).sin() + (fy * 0.4).cos()]
    });
    let triangles = (0..(side - 1) * (side - 1)).flat_map(move |c| {
        let i = (c / (side - 1)) * side + c % (side - 1);
        [[i, i + 1, i + side], [i + 1, i + side + 1, i + side]]
    });
    (vertices, triangles)
}

/// A binary PLY of [`grid`]: float positions and its faces.
fn write_grid_ply(path: &Path, side: u32) {
    use std::io::Write;
    let mut out = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let faces = 2 * (side - 1) * (side - 1);
    write!(
        out,
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nelement face {faces}\nproperty list uchar int vertex_indices\nend_header\n",
        side * side
    )
    .unwrap();
    let (vertices, triangles) = grid(side);
    for v in vertices.flatten() {
        out.write_all(&v.to_le_bytes()).unwrap();
    }
    for t in triangles {
        out.write_all(&[3]).unwrap();
        for v in t {
            out.write_all(&(v as i32).to_le_bytes()).unwrap();
        }
    }
    out.flush().unwrap();
}

/// An OBJ of [`grid`]: its vertices, one normal for every 7 vertices in
/// a table, and faces whose corners name the normals.
fn write_grid_obj(path: &Path, side: u32) {
    use std::io::Write;
    let mut out = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let (vertices, triangles) = grid(side);
    for [x, y, z] in vertices {
        writeln!(out, "v {x} {y} {z}").unwrap();
    }
    for k in 0..(side * side).div_ceil(7) {
        writeln!(out, "vn {} 0.1 1", (k % 10) as f32 * 0.05).unwrap();
    }
    for [a, b, c] in triangles {
        let corner = |v: u32| format!("{}//{}", v + 1, v / 7 + 1);
        writeln!(out, "f {} {} {}", corner(a), corner(b), corner(c)).unwrap();
    }
    out.flush().unwrap();
}

/// Builds `input` in memory (outside any cgroup: it must need more than
/// [`LIMIT`]) and out of core inside a cgroup of [`LIMIT`] bytes, which
/// must not kill it; `vertices`: the input's.
#[cfg(target_os = "linux")]
fn builds_inside_a_cgroup(name: &str, dir: &Path, input: &str, vertices: u64) {
    let Some(cgroup) = MemoryCgroup::create(name, LIMIT) else {
        return;
    };
    let (input, params): (&str, Vec<&str>) = match input.split_once('?') {
        Some((generator, param)) => (generator, vec!["--param", param]),
        None => (input, vec![]),
    };
    let memory_out = dir.join("memory.ff");
    let mut args = vec![
        "build",
        input,
        "--out",
        memory_out.to_str().unwrap(),
        "--json",
    ];
    args.extend(&params);
    let (ok, stdout) = child(&args, &[], None);
    assert!(ok, "the in-memory build failed");
    let in_memory: serde_json::Value =
        serde_json::from_str(stdout.lines().find(|l| l.starts_with('{')).unwrap()).unwrap();
    let peak = in_memory["peak_rss_bytes"].as_u64().unwrap();
    assert!(peak > LIMIT, "the in-memory build needs only {peak} bytes");
    let out = dir.join("chunked.ff");
    let budget = (LIMIT / 2).to_string();
    let mut args = vec![
        "build",
        input,
        "--out",
        out.to_str().unwrap(),
        "--memory",
        &budget,
        "--tmp",
        dir.to_str().unwrap(),
        "--json",
    ];
    args.extend(&params);
    let (ok, stdout) = child(&args, &[], Some(&cgroup));
    let kills = cgroup.oom_kills();
    eprintln!(
        "{name}: in memory: peak {} MiB; out of core inside {} MiB: cgroup peak {:?} MiB, {kills} OOM kills",
        peak >> 20,
        LIMIT >> 20,
        cgroup.peak().map(|p| p >> 20)
    );
    assert!(ok && kills == 0, "the out-of-core build failed: {stdout}");
    assert!(cgroup.peak().is_none_or(|p| p <= LIMIT));
    let report: serde_json::Value =
        serde_json::from_str(stdout.lines().find(|l| l.starts_with('{')).unwrap()).unwrap();
    assert_eq!(report["out_of_core"], true, "{report}");
    assert_eq!(report["input_vertices"], vertices);
    let scene = SceneFile::open(&out).expect("open");
    assert_eq!(scene.survey_pages().corrupt.len(), 0);
}

/// A build on many machines: 3 parts (`build --subset I/3`, built in any
/// order) merged are the whole out-of-core build with the same budget,
/// byte for byte, and within 1 % of the in-memory build's nodes; the
/// parts are left as they were. Parts that are not the N parts of one
/// build are refused, each with its reason.
#[test]
fn parts_built_apart_and_merged_are_the_whole_build() {
    let dir = scratch("chunked-parts");
    let input = tiles(&dir, 40_000, 3);
    let whole = dir.join("whole.ff");
    let report = build(&input, &whole, &["--memory", "1"]);
    assert_eq!(report["out_of_core"], true);
    let memory = build(&input, &dir.join("memory.ff"), &[]);
    let part = |i: u32| dir.join(format!("part{i}"));
    for i in [2, 3, 1] {
        let r = build(
            &input,
            &part(i),
            &["--memory", "1", "--subset", &format!("{i}/3")],
        );
        assert_eq!(r["part"]["chunks"], report["stats"]["chunks"], "{r}");
        assert!(r["part"]["part_points"].as_u64().unwrap() > 0, "{r}");
    }
    let merged = dir.join("merged.ff");
    let parts = |order: &[u32]| -> Vec<String> {
        order
            .iter()
            .map(|&i| part(i).display().to_string())
            .collect()
    };
    let merge = |order: &[u32], out: &Path| {
        let mut args = vec!["merge".to_string()];
        args.extend(parts(order));
        args.extend(["--out".into(), out.display().to_string(), "--json".into()]);
        crate::cli(&args.iter().map(String::as_str).collect::<Vec<_>>())
    };
    let r = merge(&[3, 1, 2], &merged).expect("merge").json;
    assert_eq!(
        std::fs::read(&merged).unwrap(),
        std::fs::read(&whole).unwrap(),
        "the merged parts are not the whole build"
    );
    let nodes = |r: &serde_json::Value| r["stats"]["nodes"].as_f64().unwrap();
    let ratio = nodes(&r) / nodes(&memory);
    assert!(
        (0.99..1.01).contains(&ratio),
        "nodes {} against {}",
        nodes(&r),
        nodes(&memory)
    );
    // The parts are as they were: merged again, the same file.
    let again = dir.join("again.ff");
    merge(&[1, 2, 3], &again).expect("merge again");
    assert_eq!(
        std::fs::read(&again).unwrap(),
        std::fs::read(&whole).unwrap()
    );

    let e = format!("{:#}", merge(&[1, 3], &dir.join("refused.ff")).unwrap_err());
    assert!(e.contains("part 2/3 is missing"), "{e}");
    let e = format!(
        "{:#}",
        merge(&[1, 2, 2, 3], &dir.join("refused.ff")).unwrap_err()
    );
    assert!(e.contains("again"), "{e}");
    // A part of another build: other points.
    let other_input = tiles(&dir, 30_000, 3);
    let other = dir.join("other2");
    build(&other_input, &other, &["--memory", "1", "--subset", "2/3"]);
    let mut args = vec!["merge".to_string(), part(1).display().to_string()];
    args.extend([other.display().to_string(), part(3).display().to_string()]);
    args.extend(["--out".into(), dir.join("refused.ff").display().to_string()]);
    let e = format!(
        "{:#}",
        crate::cli(&args.iter().map(String::as_str).collect::<Vec<_>>()).unwrap_err()
    );
    assert!(e.contains("another build"), "{e}");
    // Not a part at all; a part's folder taken; a subset out of range; a mesh.
    let empty = dir.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let mut args = vec!["merge".to_string(), empty.display().to_string()];
    args.extend(["--out".into(), dir.join("refused.ff").display().to_string()]);
    let e = format!(
        "{:#}",
        crate::cli(&args.iter().map(String::as_str).collect::<Vec<_>>()).unwrap_err()
    );
    assert!(e.contains("not a finished part"), "{e}");
    for (extra, why) in [
        (vec!["--subset", "1/3"], "already holds a part"),
        (vec!["--subset", "4/3"], "I/N"),
    ] {
        let mut args = vec!["build", input.to_str().unwrap(), "--out"];
        let out = part(1).display().to_string();
        args.push(&out);
        args.extend(extra);
        let e = format!("{:#}", crate::cli(&args).unwrap_err());
        assert!(e.contains(why), "{e}");
    }
    let e = format!(
        "{:#}",
        crate::cli(&[
            "build",
            "gen:tree",
            "--subset",
            "1/2",
            "--out",
            dir.join("mesh-part").to_str().unwrap()
        ])
        .unwrap_err()
    );
    assert!(e.contains("not a point cloud"), "{e}");
    assert!(!dir.join("refused.ff").exists());

    // Damaged parts: a manifest naming another part's chunk, and a leaf
    // whose position is not a number.
    let manifest = part(2).join("part.json");
    let good = std::fs::read_to_string(&manifest).unwrap();
    let mut m: serde_json::Value = serde_json::from_str(&good).unwrap();
    m["chunks"][0]["chunk"] = serde_json::json!(0);
    std::fs::write(&manifest, m.to_string()).unwrap();
    let e = format!(
        "{:#}",
        merge(&[1, 2, 3], &dir.join("refused.ff")).unwrap_err()
    );
    assert!(e.contains("not part 2/3's"), "{e}");
    std::fs::write(&manifest, good).unwrap();
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(part(3).join("part.json")).unwrap()).unwrap();
    let leaves = part(3).join(format!("chunk-{}.leaves", m["chunks"][0]["chunk"]));
    let mut bytes = std::fs::read(&leaves).unwrap();
    bytes[..8].copy_from_slice(&f64::NAN.to_le_bytes());
    std::fs::write(&leaves, bytes).unwrap();
    let e = format!(
        "{:#}",
        merge(&[1, 2, 3], &dir.join("refused.ff")).unwrap_err()
    );
    assert!(e.contains("not finite"), "{e}");
    assert!(!dir.join("refused.ff").exists());
}

/// A build on many machines through a store, as Entwine's subset builds
/// run: the parts read the survey's tiles from the store (`build
/// s3://bucket/tiles/ --subset I/N --out s3://bucket/parts/I`), the merge
/// reads the parts from it and publishes the scene to it; the stored scene
/// is the whole build from local files, byte for byte, and nothing
/// downloaded is left behind. Wrong addresses fail with what is wrong.
#[test]
fn parts_read_their_inputs_from_a_store_and_merge_through_it() {
    let dir = scratch("chunked-parts-store");
    let Some(store) = crate::s3::S3Store::start_or_skip(&dir.join("store"), &["scenes"]) else {
        return;
    };
    let input = tiles(&dir, 20_000, 2);
    let whole = dir.join("whole.ff");
    build(&input, &whole, &["--memory", "1"]);
    // The tiles put in the store as a survey is delivered into one.
    let mut tile_names = Vec::new();
    for entry in std::fs::read_dir(&input).unwrap() {
        let tile = entry.unwrap().path();
        let name = tile.file_name().unwrap().to_str().unwrap().to_owned();
        let object = store.object_file("scenes", &format!("tiles/{name}"));
        std::fs::create_dir_all(object.parent().unwrap()).unwrap();
        std::fs::copy(&tile, object).unwrap();
        tile_names.push(name);
    }
    assert_eq!(tile_names.len(), 4, "{tile_names:?}");
    let env = store.env();
    let envs: Vec<(&str, &str)> = env.iter().map(|(k, v)| (*k, v.as_str())).collect();
    let tmp = dir.join("tmp");
    let tmp_arg = tmp.display().to_string();
    let run = |args: &[&str]| {
        let mut all = args.to_vec();
        all.extend(["--tmp", &tmp_arg, "--json"]);
        child_output(&all, &envs)
    };
    for i in [1, 2] {
        let (ok, _, stderr) = run(&[
            "build",
            "s3://scenes/tiles/",
            "--memory",
            "1",
            "--subset",
            &format!("{i}/2"),
            "--out",
            &format!("s3://scenes/parts/{i}"),
        ]);
        assert!(ok, "part {i} failed: {stderr}");
        assert!(
            store
                .object_file("scenes", &format!("parts/{i}/part.json"))
                .exists(),
            "part {i} has no manifest in the store"
        );
    }
    let (ok, _, stderr) = run(&[
        "merge",
        "s3://scenes/parts/2",
        "s3://scenes/parts/1",
        "--out",
        "s3://scenes/survey.ff",
    ]);
    assert!(ok, "merge through the store failed: {stderr}");
    assert!(
        std::fs::read(store.object_file("scenes", "survey.ff")).unwrap()
            == std::fs::read(&whole).unwrap(),
        "the store holds other bytes than the whole build"
    );
    assert_eq!(
        build_folders(&tmp),
        Vec::<PathBuf>::new(),
        "downloads left behind"
    );

    // A whole build from one tile in the store is the build of the local tile.
    let one = dir.join("one.ff");
    build(&input.join(&tile_names[0]), &one, &[]);
    let from_store = dir.join("one-from-store.ff");
    let (ok, _, stderr) = run(&[
        "build",
        &format!("s3://scenes/tiles/{}", tile_names[0]),
        "--out",
        from_store.to_str().unwrap(),
    ]);
    assert!(ok, "a build of a stored tile failed: {stderr}");
    assert!(std::fs::read(&from_store).unwrap() == std::fs::read(&one).unwrap());

    // A part's prefix taken, a prefix that is no part, an input not there.
    for (args, why) in [
        (
            vec![
                "build",
                "s3://scenes/tiles/",
                "--subset",
                "1/2",
                "--out",
                "s3://scenes/parts/1",
            ],
            "already holds a part",
        ),
        (
            vec![
                "merge",
                "s3://scenes/tiles",
                "--out",
                "s3://scenes/refused.ff",
            ],
            "not a finished part",
        ),
        (
            vec![
                "build",
                "s3://scenes/nothing/",
                "--out",
                "s3://scenes/refused.ff",
            ],
            "no such object",
        ),
    ] {
        let (ok, _, stderr) = run(&args);
        assert!(!ok && stderr.contains(why), "{args:?}: {stderr}");
    }
    assert!(!store.object_file("scenes", "refused.ff").exists());
}
