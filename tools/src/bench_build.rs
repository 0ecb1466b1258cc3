//! `farfield-server bench build` and `bench traverse`: build throughput and traversal rate, as medians
//! of repeats taken in one process (these machines are noisy; compare
//! ratios from one run, not absolute times across runs).

use std::path::Path;
use std::time::Instant;

use farfield_protocol::camera::Camera;
use farfield_traverse::TraversalOptions;
use serde_json::json;

use farfield_builder::import::{Params, load_inputs};
use farfield_builder::{BuildOptions, build_spheres};
use farfield_store::SceneFile;

use crate::Measured;
use crate::meters::cpu::CpuClock;
use crate::meters::memory;
use crate::stats::median;

pub fn build(inputs: &[String], params: &[String], repeats: usize) -> anyhow::Result<Measured> {
    let params = Params::parse(params).map_err(anyhow::Error::msg)?;
    // The worker threads, their stacks and allocator arenas are a fixed
    // cost of the process, like its code: start them before taking the
    // baseline, so that "above start" is what the build itself holds.
    rayon::broadcast(|_| std::hint::black_box(vec![0u8; 64]));
    let rss_start = memory::current_rss_bytes();
    let (mut total, mut build_only) = (Vec::new(), Vec::new());
    // Seconds of each step: import, leaves, tree, layout.
    let mut steps: [Vec<f64>; 4] = Default::default();
    let mut vertices = 0;
    let mut nodes = 0;
    // The peak of the first build alone: later repeats add what the
    // allocator kept from earlier ones, which no single build holds.
    let mut peak_first = None;
    let clock = CpuClock::now();
    for _ in 0..repeats.max(1) {
        let started = Instant::now();
        let scene = load_inputs(inputs, &params)?;
        vertices = scene.instanced_vertex_count();
        let build_started = Instant::now();
        let (file, stats) = build_spheres(scene, &BuildOptions::default())?;
        nodes = stats.nodes;
        let step_seconds = [
            build_started.duration_since(started).as_secs_f64(),
            stats.seconds_leaves,
            stats.seconds_tree,
            stats.seconds_layout,
        ];
        for (samples, s) in steps.iter_mut().zip(step_seconds) {
            samples.push(s);
        }
        build_only.push(build_started.elapsed().as_secs_f64());
        total.push(started.elapsed().as_secs_f64());
        drop(file);
        peak_first = peak_first.or_else(memory::peak_rss_bytes);
    }
    let cpu = clock.until(&CpuClock::now());
    // The first build pays for all its memory fresh from the kernel, as a
    // one-off `build` command does; later repeats reuse some of what the
    // allocator kept. Both are reported.
    let first = total.first().copied().unwrap_or(0.0);
    let first_steps = steps.each_ref().map(|s| s.first().copied().unwrap_or(0.0));
    let (t, b) = (median(&mut total), median(&mut build_only));
    let [import, leaves, tree, layout] = steps.map(|mut s| median(&mut s));
    let peak = peak_first;
    let above_start = peak
        .zip(rss_start)
        .map(|(p, s)| p.saturating_sub(s) as f64 / vertices as f64);
    let json = json!({
        "inputs": inputs,
        "repeats": repeats.max(1),
        "input_vertices": vertices,
        "nodes": nodes,
        "median_seconds_import_and_build": t,
        "median_seconds_build": b,
        "median_seconds_by_step": {"import": import, "leaves": leaves, "tree": tree, "layout": layout},
        "vertices_per_second_import_and_build": vertices as f64 / t,
        "vertices_per_second_build": vertices as f64 / b,
        "seconds_import_and_build_first": first,
        "seconds_by_step_first": {"import": first_steps[0], "leaves": first_steps[1], "tree": first_steps[2], "layout": first_steps[3]},
        "vertices_per_second_import_and_build_first": vertices as f64 / first,
        "threads": rayon::current_num_threads(),
        "rss_at_start_bytes": rss_start,
        "peak_rss_bytes_first_build": peak,
        "peak_rss_bytes_all_repeats": memory::peak_rss_bytes(),
        "peak_rss_bytes_per_vertex_first_build": peak.map(|p| p as f64 / vertices as f64),
        "peak_rss_above_start_bytes_per_vertex_first_build": above_start,
        "busy_threads": cpu.busy_threads,
        "host_steal_fraction": cpu.steal_fraction,
    });
    let text = format!(
        "{}: {} vertices, median {:.3} s import+build ({:.2} M vertices/s), {:.3} s build ({:.2} M vertices/s), first build {:.3} s import+build ({:.2} M vertices/s), peak RSS of the first build {} MiB ({:.1} bytes/vertex, {:.1} above the start); steps (ms): import {:.1}, leaves {:.1}, tree {:.1}, layout {:.1}; CPU time {:.2} s per second ({} worker threads), steal {:.1} %",
        inputs.join(" "),
        vertices,
        t,
        vertices as f64 / t / 1e6,
        b,
        vertices as f64 / b / 1e6,
        first,
        vertices as f64 / first / 1e6,
        peak.unwrap_or(0) / (1 << 20),
        peak.unwrap_or(0) as f64 / vertices as f64,
        above_start.unwrap_or(f64::NAN),
        import * 1e3,
        leaves * 1e3,
        tree * 1e3,
        layout * 1e3,
        cpu.busy_threads.unwrap_or(f64::NAN),
        rayon::current_num_threads(),
        cpu.steal_fraction.map_or(f64::NAN, |f| f * 100.0),
    );
    Ok(Measured { json, text })
}

pub fn traverse_file(file: &Path, repeats: usize) -> anyhow::Result<Measured> {
    let scene = SceneFile::open(file)?;
    let h = scene.load_all()?;
    let header = &h.header;
    let options = TraversalOptions {
        threshold_px: 1.0,
        ..TraversalOptions::default()
    };
    let mut rates = Vec::new();
    let mut visited = 0;
    let mut splats = 0;
    // An orbit at 3 radii: the whole model in view at a resolution where a
    // 1-pixel cut reaches the leaves of most of it.
    let camera = Camera::orbit(
        header.root_center,
        header.root_radius,
        30.0,
        25.0,
        3.0,
        4096,
        4096,
    );
    // One traversal (of the file's kind) reused across repeats, as a
    // renderer would from frame to frame.
    let mut traversal = farfield_traverse::for_hierarchy(header.kind);
    for _ in 0..repeats.max(1) {
        let started = Instant::now();
        traversal.traverse(&h, &camera, &options);
        let seconds = started.elapsed().as_secs_f64();
        let counts = traversal.counts();
        visited = counts.visited;
        splats = counts.drawn;
        rates.push(counts.visited as f64 / seconds);
    }
    let rate = median(&mut rates);
    let json = json!({
        "file": file,
        "nodes": header.nodes,
        "visited": visited,
        "splats": splats,
        "repeats": repeats.max(1),
        "median_nodes_per_second": rate,
        "min_nodes_per_second": rates.first(),
        "max_nodes_per_second": rates.last(),
    });
    let text = format!(
        "{}: visited {visited} of {} nodes, {splats} splats; median {:.1} M nodes/s (range {:.1}..{:.1})",
        file.display(),
        header.nodes,
        rate / 1e6,
        rates.first().copied().unwrap_or(0.0) / 1e6,
        rates.last().copied().unwrap_or(0.0) / 1e6
    );
    Ok(Measured { json, text })
}
