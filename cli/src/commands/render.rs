//! `farfield render`: one camera to a PNG, or a camera path flown with
//! per-frame statistics (`--path`), streamed from a server or read from a
//! file. The loops are the client core's ([`farfield_client`]).

use std::time::{Duration, Instant};

use anyhow::Context;
use farfield_client::budget::BudgetSpec;
use farfield_client::flythrough::{FlyJob, fly, write_csv};
use farfield_client::frame_loop::Until;
use farfield_client::path::CameraPath;
use farfield_client::render_job::{DemoRole, RenderJob, open_viewer};
use farfield_client::report::RenderReport;
use farfield_net::SessionOptions;
use farfield_render::{Renderer, SplatStyle};

use crate::cli::RenderArgs;

/// `farfield render`: one view to a PNG, or a flythrough with `--path`.
pub fn run(args: RenderArgs) -> anyhow::Result<()> {
    let source = args.source.into_source()?;
    let until = match (args.frames, args.ms) {
        (Some(n), _) => Until::Frames(n.max(1)),
        (_, Some(ms)) => Until::Millis(ms),
        _ => Until::Refined,
    };
    let threshold = args.epsilon_px.or(args.eps).unwrap_or(args.threshold);
    let mode = match &args.mode {
        Some(name) => Some(farfield_traverse::named(name).with_context(|| {
            let known: Vec<&str> = farfield_traverse::KINDS.iter().map(|k| k.name).collect();
            format!("unknown mode {name} (known: {})", known.join(", "))
        })?),
        None => None,
    };
    anyhow::ensure!(
        threshold.is_finite() && threshold >= 0.0,
        "--threshold and --eps must be non-negative numbers"
    );
    anyhow::ensure!(
        args.timeout_s.is_finite() && args.timeout_s > 0.0,
        "--timeout-s must be positive"
    );
    let job = RenderJob {
        source,
        camera: args.camera.spec().unwrap_or_default(),
        width: args.size.0,
        height: args.size.1,
        out: Some(args.out),
        until,
        threshold_px: threshold,
        kernel: args.splats.kernel.into(),
        edl: args.splats.edl.edl(),
        color_by: args.splats.color,
        clip: args.splats.clip.clip(),
        coverage: args.coverage,
        session: SessionOptions {
            allow_push: args.push,
            token: args.access.token.clone(),
            ca_cert: args.access.ca_cert.clone(),
            ..SessionOptions::default()
        },
        cache_bytes: (args.cache_mib.max(1) << 20) as usize,
        timeout: Duration::from_secs_f64(args.timeout_s),
        budget: BudgetSpec {
            triangles: args.budget,
            ms: args.budget_ms,
            mode,
        },
    };
    let mut renderer =
        Renderer::new_headless(job.width, job.height).context("starting the renderer")?;
    if let Some(path) = args.path {
        return fly_path(
            &job,
            &path,
            args.fps,
            args.write_frames,
            args.known_path,
            &mut renderer,
            args.json,
        );
    }
    let demo = args.session.map(|session| DemoRole {
        session,
        present: args.present,
    });
    let rendered =
        farfield_client::render_job::run_with(&job, &mut renderer, false, demo.as_ref())?;
    let r = &rendered.report;
    if args.json {
        println!("{}", serde_json::to_string(r)?);
    } else {
        println!(
            "{}: {} frames, first image {:.1} ms, refined {}, {} nodes drawn at {} px, {} bytes in {} pages, overfetch {}, on {}",
            job.out
                .as_deref()
                .map(|p| p.display().to_string())
                .unwrap_or_default(),
            r.frames,
            r.time_to_first_image_ms.unwrap_or(f64::NAN),
            r.time_to_refined_ms
                .map_or("no".to_owned(), |t| format!("in {t:.1} ms")),
            r.nodes_drawn,
            r.threshold_px,
            r.net.bytes_received,
            r.net.pages_received,
            r.overfetch_ratio
                .map_or("-".to_owned(), |o| format!("{o:.2}")),
            r.adapter
        );
    }
    render_outcome(r, until == Until::Refined)
}

/// The error a finished render exits with, if any: pages given up on (the
/// image is written, with their parts drawn coarser) and, when the job was
/// to refine, not having refined.
fn render_outcome(r: &RenderReport, until_refined: bool) -> anyhow::Result<()> {
    let mut problems = Vec::new();
    if !r.pages_failed.is_empty() {
        let pages: Vec<u32> = r.pages_failed.iter().map(|f| f.page).collect();
        let reasons: Vec<&str> = r.pages_failed.iter().map(|f| f.reason.as_str()).collect();
        problems.push(format!(
            "pages {pages:?} could not be loaded, their parts are drawn coarser ({})",
            reasons.join("; ")
        ));
    }
    if !r.refined && until_refined {
        problems.push(r.last_error.clone().unwrap_or_else(|| "not refined".into()));
    }
    anyhow::ensure!(problems.is_empty(), "{}", problems.join("; "));
    Ok(())
}

/// `render --path`: a flythrough with per-frame stats.
fn fly_path(
    job: &RenderJob,
    path: &std::path::Path,
    fps: f64,
    write_frames: bool,
    known_path: bool,
    renderer: &mut Renderer,
    json: bool,
) -> anyhow::Result<()> {
    anyhow::ensure!(fps.is_finite() && fps > 0.0, "--fps must be positive");
    let out = job.out.clone().unwrap_or_default();
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    let started = Instant::now();
    let mut viewer = open_viewer(job)?;
    let fly_job = FlyJob {
        path: CameraPath::load(path)?,
        fps,
        width: job.width,
        height: job.height,
        final_threshold_px: job.threshold_px,
        target_frame_ms: 100.0,
        style: SplatStyle {
            kernel: job.kernel,
            edl: job.edl,
            color_by: job.color_by,
            clip: job.clip,
            coverage: job.coverage,
            ..SplatStyle::default()
        },
        frames_dir: write_frames.then(|| out.join("frames")),
        settle: true,
        timeout: job.timeout,
        budget: job.budget,
        known_path,
    };
    let (stats, settle) = fly(&mut viewer, renderer, &fly_job, started)?;
    write_csv(&out.join("frames.csv"), &stats)?;
    let report = settle.report(&viewer, renderer);
    if json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        println!(
            "{}: {} frames, {} bytes received; per-frame stats in frames.csv",
            out.display(),
            stats.len(),
            report.net.bytes_received
        );
    }
    render_outcome(&report, false)
}
