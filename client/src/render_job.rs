//! One camera, streamed or from a file, refined to the final threshold: the
//! job behind `farfield render` (and the benchmarks' renders).
//!
//! The first frame is drawn as soon as the header and page 0 are in.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, bail};
use farfield_net::SessionOptions;
use farfield_render::{Clip, ColorBy, Coverage, Edl, Kernel, Renderer, SplatStyle};
use web_time::Instant;

use crate::budget::BudgetSpec;
use crate::camera_spec::CameraSpec;
use crate::demo_link::DemoLink;
use crate::frame_loop::{Settle, Until};
use crate::report::RenderReport;
use crate::viewer::Viewer;

/// Where the scene comes from.
#[derive(Debug, Clone)]
pub enum Source {
    File(PathBuf),
    Server { url: String, scene: String },
}

/// Everything one render needs.
#[derive(Debug, Clone)]
pub struct RenderJob {
    pub source: Source,
    pub camera: CameraSpec,
    pub width: u32,
    pub height: u32,
    pub out: Option<PathBuf>,
    pub until: Until,
    /// Spheres: the splat size threshold; cubes: eps, the projected cell
    /// edge under which a cell is drawn as its color-cube (pixels).
    pub threshold_px: f64,
    pub kernel: Kernel,
    /// Eye-dome lighting over splats, or none.
    pub edl: Option<Edl>,
    /// What colors splats.
    pub color_by: ColorBy,
    /// The clipping box over splats, or none.
    pub clip: Option<Clip>,
    /// Cubes: how face coverage is used.
    pub coverage: Coverage,
    pub session: SessionOptions,
    pub cache_bytes: usize,
    /// Give up (keeping the image so far) after this long.
    pub timeout: Duration,
    /// Budgeted kinds (PLP): triangles or milliseconds a frame.
    pub budget: BudgetSpec,
}

/// A finished render: the report and the last image.
#[derive(Debug)]
pub struct Rendered {
    pub report: RenderReport,
    pub rgba: Vec<u8>,
    /// Every frame's pixels, when asked for (tests of progressive refinement).
    pub frames: Vec<Vec<u8>>,
}

/// A render's part in a demo session (`render --session NAME --present`
/// or `--follow`).
#[derive(Debug, Clone, PartialEq)]
pub struct DemoRole {
    pub session: String,
    pub present: bool,
}

/// Runs a render job with an already initialised renderer (so its start-up
/// is not counted in time to first image).
pub fn run(
    job: &RenderJob,
    renderer: &mut Renderer,
    keep_frames: bool,
) -> anyhow::Result<Rendered> {
    run_with(job, renderer, keep_frames, None)
}

/// [`run`], in a demo session when `demo` says so: a presenter shows the
/// job's camera (and threshold and kernel) to the followers, then renders
/// it; a follower waits for the presenter's view and renders that, with
/// the presenter's threshold and kernel.
pub fn run_with(
    job: &RenderJob,
    renderer: &mut Renderer,
    keep_frames: bool,
    demo: Option<&DemoRole>,
) -> anyhow::Result<Rendered> {
    renderer.resize(job.width, job.height);
    let started = Instant::now();
    let mut viewer = open_viewer(job)?;
    let (width, height) = (job.width, job.height);
    let mut job = job.clone();
    let fixed = match demo {
        Some(role) => Some(join_demo(&mut viewer, &mut job, role, started)?),
        None => None,
    };
    let style = SplatStyle {
        kernel: job.kernel,
        edl: job.edl,
        color_by: job.color_by,
        clip: job.clip,
        coverage: job.coverage,
        ..SplatStyle::default()
    };
    let camera = job.camera;
    let mut settle = Settle::new(job.threshold_px, job.until, started, job.timeout);
    settle.keep_frames = keep_frames;
    job.budget.apply(&mut settle.cut);
    settle.cut.final_threshold = Some(job.threshold_px);
    settle.run(&mut viewer, renderer, &style, &|h| {
        fixed.unwrap_or_else(|| camera.resolve(h, width, height))
    })?;
    let mut report = settle.report(&viewer, renderer);
    report.out = job.out.clone();
    if let Some(out) = &job.out {
        if settle.rgba.is_empty() {
            bail!(
                "no image was drawn: {}",
                report
                    .last_error
                    .clone()
                    .unwrap_or_else(|| "no scene header arrived".into())
            );
        }
        farfield_image::write_png(out, width, height, &settle.rgba)
            .with_context(|| format!("writing {}", out.display()))?;
    }
    Ok(Rendered {
        report,
        rgba: std::mem::take(&mut settle.rgba),
        frames: std::mem::take(&mut settle.frames),
    })
}

/// Joins the demo session; a presenter shows the job's view, a follower
/// takes the presenter's (camera, threshold, kernel into `job`). Returns
/// the camera to render.
fn join_demo(
    viewer: &mut Viewer,
    job: &mut RenderJob,
    role: &DemoRole,
    started: Instant,
) -> anyhow::Result<farfield_protocol::camera::Camera> {
    let mut link = DemoLink::join(viewer, &role.session, role.present)
        .context("a demo session needs a server (--server), not a file")?;
    loop {
        anyhow::ensure!(
            started.elapsed() < job.timeout,
            "{}",
            viewer.with_last_error(format!(
                "demo session {:?}: no {} after {:.1} s",
                role.session,
                if role.present {
                    "presenter's seat"
                } else {
                    "view from its presenter"
                },
                started.elapsed().as_secs_f64()
            ))
        );
        viewer.pump(Duration::from_millis(20))?;
        link.update(viewer);
        if let Some(reason) = &link.closed {
            bail!("demo session {:?}: {reason}", role.session);
        }
        if role.present {
            if let (true, Some(header)) = (link.is_presenting(), viewer.header().cloned()) {
                let camera = job.camera.resolve(&header, job.width, job.height);
                let options = vec![
                    ("threshold".to_owned(), job.threshold_px.to_string()),
                    ("kernel".to_owned(), job.kernel.name().to_owned()),
                ];
                link.show(viewer, &camera, options);
                return Ok(camera);
            }
        } else if let Some(camera) = link.camera(job.width, job.height) {
            for (key, value) in link.options().unwrap_or_default() {
                match (key.as_str(), value.as_str()) {
                    ("threshold", v) => {
                        if let Ok(t) = v.parse::<f64>()
                            && t.is_finite()
                            && t > 0.0
                        {
                            job.threshold_px = t;
                        }
                    }
                    ("kernel", name) => {
                        if let Some(kernel) = Kernel::from_name(name) {
                            job.kernel = kernel;
                        }
                    }
                    _ => {}
                }
            }
            return Ok(camera);
        }
    }
}

/// The viewer a job's source names: a file read whole, or a session with
/// a memory server.
pub fn open_viewer(job: &RenderJob) -> anyhow::Result<Viewer> {
    match &job.source {
        Source::File(path) => Viewer::open_file(path),
        #[cfg(not(target_arch = "wasm32"))]
        Source::Server { url, scene } => {
            Viewer::open_remote(url, scene, job.session.clone(), job.cache_bytes)
        }
        #[cfg(target_arch = "wasm32")]
        Source::Server { .. } => bail!("a browser opens a session through its own transport"),
    }
}
