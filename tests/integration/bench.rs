//! The benchmarks end to end: `farfield bench` and `report` (a sweep over a
//! small scene, streamed from a real server, its tables, plots and page), and
//! `farfield-server bench build`'s summary.

use std::time::Duration;

use farfield_builder::import::{Params, load_input};
use farfield_client::render_job::Source;
use farfield_render::headless_or_skip;
use farfield_store::write_atomic;
use farfield_tests::scratch;
use farfield_tools::bench::rows::{ProgressRow, Row};
use farfield_tools::bench::{BenchJob, plots, report, rows, run};

use crate::build;

#[test]
fn a_streamed_sweep_writes_tables_plots_and_a_report() {
    let Some(mut renderer) = headless_or_skip(96, 72).unwrap() else {
        return;
    };
    let dir = scratch("bench-sweep");
    let scenes = dir.join("scenes");
    std::fs::create_dir_all(&scenes).unwrap();
    let mut params = Params::default();
    params.set("size", 64);
    params.set("trees", 2);
    params.set("tree_triangles", 2000);
    write_atomic(
        &scenes.join("island.ff"),
        &build(load_input("gen:island", &params).unwrap()),
    )
    .unwrap();
    let (rt, server, url) = crate::serve_dir(&scenes);
    let job = BenchJob {
        source: Source::Server {
            url,
            scene: "island".into(),
        },
        path: None,
        mode: "spheres".into(),
        param: "threshold".into(),
        values: vec!["1".into(), "8".into()],
        fixed: vec![("kernel".into(), "square".into())],
        inputs: Vec::new(),
        input_params: Vec::new(),
        width: 96,
        height: 72,
        repeats: 2,
        out: dir.join("bench"),
        timeout: Duration::from_secs(60),
    };
    let (table, progress) = run(&job, &mut renderer).unwrap();
    // Two values x three built-in cameras.
    assert_eq!(table.len(), 6);
    for r in &table {
        assert!(r.frame_ms > 0.0 && r.frame_ms_min <= r.frame_ms && r.frame_ms <= r.frame_ms_max);
        assert!(r.bytes > 0 && !r.reference_empty);
        assert_eq!(r.coverage, None, "splats have no visible triangles");
        if r.value == "1" {
            // The reference is this very mode at 1 px.
            assert!(r.psnr_db.is_infinite() && r.rmse == 0.0, "{r:?}");
        } else {
            assert!(r.psnr_db.is_finite() && r.rmse > 0.0, "{r:?}");
        }
    }
    // Streaming: every view refined from nothing, error never worse at the end.
    assert!(progress.len() >= 6, "{} progress frames", progress.len());
    let first = progress
        .iter()
        .find(|p| p.value == "1" && p.camera == 0)
        .unwrap();
    let last = progress
        .iter()
        .rev()
        .find(|p| p.value == "1" && p.camera == 0)
        .unwrap();
    assert!(last.rmse <= first.rmse && last.bytes >= first.bytes);
    // The files are the tables, and they read back.
    assert_eq!(
        rows::read::<Row>(&job.out.join("bench.csv")).unwrap(),
        table
    );
    assert_eq!(
        rows::read::<ProgressRow>(&job.out.join("progress.csv"))
            .unwrap()
            .len(),
        progress.len()
    );
    let page = report::write_report(std::slice::from_ref(&job.out), &dir.join("report")).unwrap();
    let html = std::fs::read_to_string(page).unwrap();
    for (file, _) in plots::ALL {
        assert!(
            html.contains(file) && dir.join("report").join(file).exists(),
            "{file}"
        );
    }
    assert!(html.contains("CPU") && html.contains(&renderer.adapter_description()));
    // Splats draw no triangles: no coverage plots.
    for (file, title) in plots::COVERAGE {
        assert!(!html.contains(title) && !dir.join("report").join(file).exists());
    }
    rt.block_on(server.shutdown()).unwrap();
}

/// PLP and its nearest-first baseline, streamed: every frame of the
/// refinement records the paper's visible coverage against bytes and time,
/// a whole budget ends covering everything, and a small one fetches less.
#[test]
fn a_streamed_plp_bench_records_coverage_against_bytes_and_time() {
    let Some(mut renderer) = headless_or_skip(96, 72).unwrap() else {
        return;
    };
    let dir = scratch("bench-plp-coverage");
    let scenes = dir.join("scenes");
    std::fs::create_dir_all(&scenes).unwrap();
    let file = crate::plp::build(&crate::plp::rows(), &crate::plp::small_pages());
    write_atomic(&scenes.join("rows.ff"), &file).unwrap();
    let (rt, server, url) = crate::serve_dir(&scenes);
    let mut outs = Vec::new();
    for mode in ["plp", "centroid"] {
        let job = BenchJob {
            source: Source::Server {
                url: url.clone(),
                scene: "rows".into(),
            },
            path: None,
            mode: mode.into(),
            param: "budget".into(),
            values: vec!["10%".into(), "100%".into()],
            fixed: Vec::new(),
            inputs: Vec::new(),
            input_params: Vec::new(),
            width: 96,
            height: 72,
            repeats: 1,
            out: dir.join(mode),
            timeout: Duration::from_secs(60),
        };
        let (table, progress) = run(&job, &mut renderer).unwrap();
        assert_eq!(table.len(), 6, "{mode}");
        for r in &table {
            let c = r
                .coverage
                .unwrap_or_else(|| panic!("{mode}: no coverage in {r:?}"));
            assert!((0.0..=1.0).contains(&c), "{mode}: {r:?}");
            if r.value == "100%" {
                assert_eq!(c, 1.0, "{mode}: a whole budget misses nothing: {r:?}");
            }
        }
        let whole_bytes = |camera: u32, value: &str| {
            table
                .iter()
                .find(|r| r.camera == camera && r.value == value)
                .unwrap()
                .bytes
        };
        // The nearest camera sees few of the boxes: a tenth of the scene
        // needs fewer pages than all of it.
        assert!(
            whole_bytes(0, "10%") < whole_bytes(0, "100%"),
            "{mode}: {} >= {}",
            whole_bytes(0, "10%"),
            whole_bytes(0, "100%")
        );
        for camera in 0..3 {
            let frames: Vec<&ProgressRow> = progress
                .iter()
                .filter(|p| p.camera == camera && p.value == "100%")
                .collect();
            assert!(frames.len() >= 2, "{mode}: {} frames", frames.len());
            // From nothing drawn to everything, never losing ground while
            // the pages that arrive stay resident.
            assert_eq!(frames[0].coverage, Some(0.0), "{mode} camera {camera}");
            assert_eq!(frames.last().unwrap().coverage, Some(1.0));
            for w in frames.windows(2) {
                assert!(w[1].coverage >= w[0].coverage && w[1].bytes >= w[0].bytes);
                assert!(w[1].ms_since_connect >= w[0].ms_since_connect);
            }
        }
        outs.push(job.out);
    }
    // Both modes' curves on one page, with the coverage plots.
    let page = report::write_report(&outs, &dir.join("report")).unwrap();
    let html = std::fs::read_to_string(page).unwrap();
    for (file, title) in plots::COVERAGE {
        assert!(html.contains(title), "{title}");
        let svg = std::fs::read_to_string(dir.join("report").join(file)).unwrap();
        assert!(svg.contains("plp budget=100%") && svg.contains("centroid budget=100%"));
    }
    rt.block_on(server.shutdown()).unwrap();
}

#[test]
fn bench_build_reports_throughput_memory_and_what_the_machine_gave() {
    let report = crate::cli(&[
        "bench",
        "build",
        "gen:tree",
        "--param",
        "triangles=3000",
        "--repeats",
        "3",
        "--json",
    ])
    .unwrap();
    let j = &report.json;
    let number = |key: &str| {
        j[key]
            .as_f64()
            .unwrap_or_else(|| panic!("{key} missing: {j}"))
    };
    assert_eq!(j["repeats"], 3);
    assert!(number("input_vertices") > 1000.0);
    let rate = number("vertices_per_second_import_and_build");
    assert!(rate > 0.0 && rate.is_finite());
    assert!(number("vertices_per_second_build") >= rate);
    assert!(number("peak_rss_bytes_first_build") > 0.0);
    // The first build's steps are its own: each took time, and together
    // they fit in its import-and-build time.
    let first = number("seconds_import_and_build_first");
    let first_steps: Vec<f64> = ["import", "leaves", "tree", "layout"]
        .map(|step| {
            j["seconds_by_step_first"][step]
                .as_f64()
                .unwrap_or_else(|| panic!("first build's {step} missing: {j}"))
        })
        .to_vec();
    assert!(first_steps.iter().all(|&s| s > 0.0), "{first_steps:?}");
    assert!(
        first_steps.iter().sum::<f64>() <= first,
        "{first_steps:?} > {first}"
    );
    // The machine's figures come from Linux's /proc and getrusage.
    if cfg!(target_os = "linux") {
        let threads = number("threads");
        let busy = number("busy_threads");
        // Other test threads share the process: up to every CPU, no more.
        let cpus = std::thread::available_parallelism().map_or(1, |n| n.get()) as f64;
        assert!(busy > 0.0 && busy <= cpus + 0.5, "{busy} of {threads}");
        // Absent only where /proc/stat is empty or frozen (some sandboxes).
        if let Some(steal) = j["host_steal_fraction"].as_f64() {
            assert!((0.0..=1.0).contains(&steal), "steal {steal}");
        }
    }
    assert!(
        report.text.contains("worker threads), steal"),
        "{}",
        report.text
    );
}
