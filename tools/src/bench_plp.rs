//! `farfield bench-plp`: PLP's Table 1 and Figures 8 and 9 (Klosowski &
//! Silva, section 5) on our scenes. Along a camera path, each frame is
//! drawn whole (every triangle that survives frustum and backface culling)
//! and its visible set `V` read from an item buffer (each triangle's id
//! drawn with depth test into an integer target); then PLP at each budget
//! and the centroid-sorted baseline draw their sets `T_k`. The visible
//! coverage ratio `ε_k = |V ∩ T_k| / |V|`, the wrong pixels against the
//! whole frame, and frame times (medians of repeats in this run) are
//! recorded per frame and summarized next to the paper's numbers.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use farfield_client::path::CameraPath;
use farfield_protocol::camera::Camera;
use farfield_protocol::file::HierarchyKind;
use farfield_protocol::hierarchy::Hierarchy;
use farfield_render::{Coverage, GpuVertex, Renderer, pack_plp, visible_ids};
use farfield_traverse::Budget;
use farfield_traverse::plp::{Order, PlpCut, PlpOptions, PlpState, Solidity, traverse_plp_into};
use serde::Serialize;

use crate::bench::visible::common_count;
use farfield_image::compare;

/// What to measure.
#[derive(Debug, Clone)]
pub struct PlpBenchJob {
    /// A PLP file.
    pub file: PathBuf,
    /// Its camera path: one frame per keyframe.
    pub path: CameraPath,
    /// PLP's budgets (the paper's 1, 2, 5 and 10 %).
    pub budgets: Vec<Budget>,
    /// The centroid baseline's budget (the paper's 10 %).
    pub centroid_budget: Budget,
    pub width: u32,
    pub height: u32,
    /// Timed repeats of each frame (the median is reported).
    pub repeats: usize,
    /// Every `stride`th keyframe (1 = all).
    pub stride: usize,
    /// The paper's coverage at the same budgets, for the table.
    pub paper: Option<PaperRow>,
    /// PLP's non-star-shaped penalty (`farfield_traverse::plp::PlpOptions`).
    pub star_penalty: f64,
    /// What a projected cell passes on: the paper's count, or coverage.
    pub solidity: Solidity,
}

/// Table 1's row and the worst wrong pixels for one of the paper's models.
#[derive(Debug, Clone, Serialize)]
pub struct PaperRow {
    pub model: String,
    /// ε at 1, 2, 5 and 10 %.
    pub coverage: Vec<(String, f64)>,
    pub worst_wrong_fraction: f64,
}

impl PaperRow {
    /// The paper's CITY (500K triangles).
    pub fn city() -> Self {
        Self::of("CITY", [0.51, 0.66, 0.80, 0.90], 0.04)
    }

    /// The paper's 5CBEM (810K triangles).
    pub fn cars() -> Self {
        Self::of("5CBEM", [0.44, 0.55, 0.67, 0.76], 0.12)
    }

    fn of(model: &str, coverage: [f64; 4], worst: f64) -> Self {
        Self {
            model: model.into(),
            coverage: ["1%", "2%", "5%", "10%"]
                .iter()
                .zip(coverage)
                .map(|(b, c)| ((*b).to_owned(), c))
                .collect(),
            worst_wrong_fraction: worst,
        }
    }
}

/// One way of drawing, on one frame.
#[derive(Debug, Clone, Serialize)]
pub struct Drawn {
    /// `plp 5%`, `centroid 10%`.
    pub label: String,
    pub triangles: usize,
    /// `|V ∩ T_k|`.
    pub visible_found: usize,
    /// `ε_k`; 1 when nothing is visible.
    pub coverage: f64,
    pub wrong_fraction: f64,
    /// Traversal, packing, upload and draw (median of repeats).
    pub frame_ms: f64,
    pub traverse_ms: f64,
}

/// One frame of the path.
#[derive(Debug, Clone, Serialize)]
pub struct FrameRow {
    pub frame: usize,
    pub path_s: f64,
    /// `|V|`: triangles covering at least one pixel of the whole frame.
    pub visible: usize,
    /// Triangles of the whole frame (after culling).
    pub whole_triangles: usize,
    pub whole_ms: f64,
    pub drawn: Vec<Drawn>,
}

/// A budget's summary over the path.
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    pub label: String,
    /// Mean of `ε_k` over the frames (the paper's Table 1 entry).
    pub mean_coverage: f64,
    pub min_coverage: f64,
    /// Worst frame's wrong pixels (the paper reports the worst).
    pub worst_wrong_fraction: f64,
    pub median_frame_ms: f64,
    /// Whole frame's median time over this one's.
    pub speedup: f64,
    /// The paper's ε at this budget, where it gives one.
    pub paper_coverage: Option<f64>,
}

/// The whole run.
#[derive(Debug, Clone, Serialize)]
pub struct PlpBenchReport {
    pub file: PathBuf,
    pub scene_triangles: u64,
    pub cells: usize,
    pub width: u32,
    pub height: u32,
    pub repeats: usize,
    pub adapter: String,
    pub median_whole_ms: f64,
    pub summaries: Vec<Summary>,
    pub paper: Option<PaperRow>,
    pub frames: Vec<FrameRow>,
}

/// Runs the bench on an already started renderer.
pub fn run(job: &PlpBenchJob, renderer: &mut Renderer) -> anyhow::Result<PlpBenchReport> {
    let h = farfield_client::viewer::load_file(&job.file)?;
    anyhow::ensure!(
        h.header.kind == HierarchyKind::Plp,
        "{} is a {} hierarchy; bench-plp needs one built with --kind plp",
        job.file.display(),
        h.header.kind.name()
    );
    let skeleton = h.plp_skeleton().context("the file has no skeleton")?;
    let (scene_triangles, cells) = (skeleton.scene_triangles, skeleton.cells.len());
    renderer.resize(job.width, job.height);
    let mut ways: Vec<(String, Order, Budget)> = job
        .budgets
        .iter()
        .map(|b| (format!("plp {b}"), Order::Solidity, *b))
        .collect();
    ways.push((
        format!("centroid {}", job.centroid_budget),
        Order::Centroid,
        job.centroid_budget,
    ));
    let times = job.path.key_times();
    let mut frames = Vec::new();
    let mut state = PlpState::default();
    let mut cut = PlpCut::default();
    let mut vertices = Vec::new();
    let repeats = job.repeats.max(1);
    for (frame, &t) in times.iter().enumerate().step_by(job.stride.max(1)) {
        let camera = job.path.camera_at(t, &h.header, job.width, job.height);
        // The whole frame: its image, its time and its visible set.
        let mut whole_times = Vec::new();
        let mut whole = Vec::new();
        for _ in 0..repeats {
            let (rgba, ms, _) = draw(
                &h,
                renderer,
                &camera,
                (
                    Order::Solidity,
                    Budget::Unlimited,
                    job.star_penalty,
                    job.solidity,
                ),
                (&mut state, &mut cut),
                &mut vertices,
            )?;
            whole = rgba;
            whole_times.push(ms);
        }
        let ids: Vec<u32> = cut.triangles.iter().map(|t| t.id).collect();
        let items = renderer.item_buffer(&camera, &vertices, &ids)?;
        let visible = visible_ids(&items);
        let whole_triangles = cut.triangles.len();
        let mut drawn = Vec::new();
        for (label, order, budget) in &ways {
            let mut samples = Vec::new();
            let mut traverse = Vec::new();
            let mut rgba = Vec::new();
            for _ in 0..repeats {
                let (image, ms, traverse_ms) = draw(
                    &h,
                    renderer,
                    &camera,
                    (*order, *budget, job.star_penalty, job.solidity),
                    (&mut state, &mut cut),
                    &mut vertices,
                )?;
                rgba = image;
                samples.push(ms);
                traverse.push(traverse_ms);
            }
            // Both id lists are ascending: count the common ones in one pass.
            let found = common_count(&visible, cut.triangles.iter().map(|t| t.id));
            let error = compare(&whole, &rgba, job.width, job.height, 0)?;
            drawn.push(Drawn {
                label: label.clone(),
                triangles: cut.triangles.len(),
                visible_found: found,
                coverage: if visible.is_empty() {
                    1.0
                } else {
                    found as f64 / visible.len() as f64
                },
                wrong_fraction: error.wrong_fraction,
                frame_ms: crate::bench::median(&samples),
                traverse_ms: crate::bench::median(&traverse),
            });
        }
        frames.push(FrameRow {
            frame,
            path_s: t,
            visible: visible.len(),
            whole_triangles,
            whole_ms: crate::bench::median(&whole_times),
            drawn,
        });
    }
    let median_whole_ms =
        crate::bench::median(&frames.iter().map(|f| f.whole_ms).collect::<Vec<_>>());
    let summaries = ways
        .iter()
        .enumerate()
        .map(|(i, (label, order, budget))| {
            let of = |f: &FrameRow| f.drawn[i].clone();
            let coverage: Vec<f64> = frames.iter().map(|f| of(f).coverage).collect();
            let ms: Vec<f64> = frames.iter().map(|f| of(f).frame_ms).collect();
            let median_frame_ms = crate::bench::median(&ms);
            let budget_name = budget.to_string();
            Summary {
                label: label.clone(),
                mean_coverage: coverage.iter().sum::<f64>() / coverage.len().max(1) as f64,
                min_coverage: coverage.iter().copied().fold(f64::INFINITY, f64::min),
                worst_wrong_fraction: frames
                    .iter()
                    .map(|f| of(f).wrong_fraction)
                    .fold(0.0, f64::max),
                median_frame_ms,
                speedup: if median_frame_ms > 0.0 {
                    median_whole_ms / median_frame_ms
                } else {
                    f64::NAN
                },
                paper_coverage: (*order == Order::Solidity)
                    .then(|| {
                        job.paper.as_ref().and_then(|p| {
                            p.coverage
                                .iter()
                                .find(|(b, _)| *b == budget_name)
                                .map(|(_, c)| *c)
                        })
                    })
                    .flatten(),
            }
        })
        .collect();
    Ok(PlpBenchReport {
        file: job.file.clone(),
        scene_triangles,
        cells,
        width: job.width,
        height: job.height,
        repeats,
        adapter: renderer.adapter_description(),
        median_whole_ms,
        summaries,
        paper: job.paper.clone(),
        frames,
    })
}

/// One traversal and draw; returns the image, the whole frame's time and
/// the traversal's. The cut and its packed vertices stay in the buffers.
fn draw(
    h: &Hierarchy,
    renderer: &mut Renderer,
    camera: &Camera,
    (order, budget, star_penalty, solidity): (Order, Budget, f64, Solidity),
    (state, cut): (&mut PlpState, &mut PlpCut),
    vertices: &mut Vec<GpuVertex>,
) -> anyhow::Result<(Vec<u8>, f64, f64)> {
    let started = Instant::now();
    let options = PlpOptions {
        budget,
        order,
        star_penalty,
        solidity,
        ..PlpOptions::default()
    };
    traverse_plp_into(h, camera, &options, state, cut);
    let traverse_ms = started.elapsed().as_secs_f64() * 1e3;
    vertices.clear();
    pack_plp(h, cut, camera.eye, vertices);
    let image = renderer.render_geometry(camera, vertices, &[], Coverage::Alpha, [0; 3])?;
    Ok((
        image.rgba,
        started.elapsed().as_secs_f64() * 1e3,
        traverse_ms,
    ))
}

/// Table 1 as text: our coverage next to the paper's, worst wrong pixels,
/// frame times and speedups.
pub fn format_table(r: &PlpBenchReport) -> String {
    let mut out = format!(
        "{}: {} triangles, {} cells, {}x{}, {} (median of {} repeats)\n",
        r.file.display(),
        r.scene_triangles,
        r.cells,
        r.width,
        r.height,
        r.adapter,
        r.repeats
    );
    out += &format!(
        "whole frame: median {:.2} ms over {} frames\n\n",
        r.median_whole_ms,
        r.frames.len()
    );
    let model = r.paper.as_ref().map_or("paper", |p| p.model.as_str());
    out += &format!(
        "| budget | coverage ε (mean) | min ε | {model} ε | worst wrong pixels | frame ms | speedup |\n|---|---|---|---|---|---|---|\n"
    );
    for s in &r.summaries {
        out += &format!(
            "| {} | {:.1} % | {:.1} % | {} | {:.2} % | {:.2} | {:.2}x |\n",
            s.label,
            100.0 * s.mean_coverage,
            100.0 * s.min_coverage,
            s.paper_coverage
                .map_or("-".into(), |c| format!("{:.0} %", 100.0 * c)),
            100.0 * s.worst_wrong_fraction,
            s.median_frame_ms,
            s.speedup
        );
    }
    if let Some(p) = &r.paper {
        out += &format!(
            "\n{}: worst wrong pixels {:.0} % in the paper\n",
            p.model,
            100.0 * p.worst_wrong_fraction
        );
    }
    out
}

/// The per-frame curves (Figures 8a/b and 9a/b) as CSV: one row per frame,
/// `visible`, then per way its triangles, visible found, coverage, wrong
/// pixels and frame time.
pub fn frames_csv(r: &PlpBenchReport) -> String {
    let mut out = String::from("frame,path_s,visible,whole_triangles,whole_ms");
    if let Some(f) = r.frames.first() {
        for d in &f.drawn {
            let l = d.label.replace(' ', "_");
            out +=
                &format!(",{l}_triangles,{l}_visible_found,{l}_coverage,{l}_wrong_fraction,{l}_ms");
        }
    }
    out.push('\n');
    for f in &r.frames {
        out += &format!(
            "{},{},{},{},{:.3}",
            f.frame, f.path_s, f.visible, f.whole_triangles, f.whole_ms
        );
        for d in &f.drawn {
            out += &format!(
                ",{},{},{:.5},{:.5},{:.3}",
                d.triangles, d.visible_found, d.coverage, d.wrong_fraction, d.frame_ms
            );
        }
        out.push('\n');
    }
    out
}

/// Figures 8 and 9 (a and b) as SVG: visible triangles found per frame
/// (the exact visible set, PLP at each budget, the baseline), and frame
/// time per frame (the whole frame and each budget).
pub fn write_figures(r: &PlpBenchReport, dir: &std::path::Path) -> anyhow::Result<()> {
    use std::collections::BTreeMap;
    let mut found: BTreeMap<String, Vec<(f64, f64)>> = BTreeMap::new();
    let mut times: BTreeMap<String, Vec<(f64, f64)>> = BTreeMap::new();
    for f in &r.frames {
        let x = f.frame as f64;
        found
            .entry("exact visible set".into())
            .or_default()
            .push((x, f.visible as f64));
        times
            .entry("every triangle".into())
            .or_default()
            .push((x, f.whole_ms));
        for d in &f.drawn {
            found
                .entry(d.label.clone())
                .or_default()
                .push((x, d.visible_found as f64));
            times
                .entry(d.label.clone())
                .or_default()
                .push((x, d.frame_ms));
        }
    }
    let name = r.file.display();
    crate::bench::plots::write_line_chart(
        &dir.join("visible.svg"),
        &format!("{name}: visible triangles found"),
        "frame",
        "visible triangles",
        &found,
    )?;
    crate::bench::plots::write_line_chart(
        &dir.join("frame_time.svg"),
        &format!("{name}: frame time"),
        "frame",
        "milliseconds",
        &times,
    )
}
