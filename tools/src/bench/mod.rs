//! `farfield bench` and `farfield report`: error against run time.
//!
//! Every rendering mode trades how wrong the image is against how long it
//! takes. The bench renders each camera of a path with a [`modes::Mode`]
//! at every value of a swept parameter, renders the same camera's
//! reference with the same renderer at the same size, and records the
//! error (RMSE, PSNR, wrong pixels), the frame time split into traverse,
//! upload and draw (medians of repeats, with their spread), the bytes that
//! had to arrive, and, when streaming, every frame of the refinement.
//!
//! - [`rows`]: the tidy tables (`bench.csv`, `progress.csv`) and their schema.
//! - [`modes`]: [`modes::Mode`]: every registered traversal kind, and `geometry`.
//! - [`plots`]: the SVG plots (plotters): the error/time frontier, error
//!   against bytes, error against time since connect, and time by threshold
//!   next to QSplat's Figure 1.
//! - [`report`]: one HTML page from one or more bench folders.
//! - [`visible`]: PLP's visible coverage ratio, for kinds that draw
//!   triangles.

pub mod modes;
pub mod plots;
pub mod report;
pub mod rows;
pub mod visible;

use std::path::PathBuf;
use std::rc::Rc;
use std::time::{Duration, Instant};

use anyhow::Context;
use farfield_protocol::camera::Camera;
use farfield_protocol::file::FileHeader;
use serde::{Deserialize, Serialize};

use crate::reference::Reference;
use farfield_client::frame_loop::{FrameState, draw_frame};
use farfield_client::path::CameraPath;
use farfield_client::render_job::Source;
use farfield_client::viewer::Viewer;
use farfield_image::compare;
use farfield_net::SessionOptions;
use farfield_render::{Coverage, Renderer, SplatStyle};
use rows::{ProgressRow, Row};

/// What to measure.
#[derive(Debug, Clone)]
pub struct BenchJob {
    pub source: Source,
    /// Cameras: keyframe times of this path; without one, an orbit at
    /// 1.75, 3.5 and 7 radii.
    pub path: Option<CameraPath>,
    pub mode: String,
    pub param: String,
    pub values: Vec<String>,
    /// Settings held fixed during the sweep (`--set kernel=square`).
    pub fixed: Vec<(String, String)>,
    /// The input geometry (files or `gen:` scenes), for the geometry mode
    /// and as the reference.
    pub inputs: Vec<String>,
    pub input_params: Vec<String>,
    pub width: u32,
    pub height: u32,
    pub repeats: u32,
    pub out: PathBuf,
    pub timeout: Duration,
}

/// Who measured what, written as `meta.json` beside the tables.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct BenchMeta {
    pub scene: String,
    pub mode: String,
    pub param: String,
    pub values: Vec<String>,
    pub fixed: Vec<(String, String)>,
    pub reference: String,
    pub adapter: String,
    pub cpu: String,
    pub cores: usize,
    pub width: u32,
    pub height: u32,
    pub repeats: u32,
    pub cameras: usize,
}

/// The cameras of a job for a scene header.
fn cameras(job: &BenchJob, header: &FileHeader) -> Vec<Camera> {
    match &job.path {
        Some(path) => path
            .key_times()
            .into_iter()
            .map(|t| path.camera_at(t, header, job.width, job.height))
            .collect(),
        None => [1.75, 3.5, 7.0]
            .iter()
            .map(|&d| {
                let (center, radius) = farfield_client::camera_spec::scene_sphere(header);
                Camera::orbit(center, radius, 30.0, 20.0, d, job.width, job.height)
            })
            .collect(),
    }
}

fn scene_name(source: &Source) -> String {
    match source {
        Source::File(p) => p.display().to_string(),
        Source::Server { url, scene } => format!("{url}/{scene}"),
    }
}

/// Opens the job's source fully resident (a file) or as a fresh session.
fn open(job: &BenchJob) -> anyhow::Result<Viewer> {
    match &job.source {
        Source::File(p) => Viewer::open_file(p),
        Source::Server { url, scene } => {
            Viewer::open_remote(url, scene, SessionOptions::default(), usize::MAX)
        }
    }
}

/// Waits for a session's header.
fn header_of(viewer: &mut Viewer, timeout: Duration) -> anyhow::Result<FileHeader> {
    let started = Instant::now();
    loop {
        if let Some(h) = viewer.header() {
            return Ok(h.clone());
        }
        anyhow::ensure!(
            started.elapsed() < timeout,
            "{}",
            viewer.no_header_error(timeout)
        );
        viewer.pump(Duration::from_millis(50))?;
    }
}

/// The reference: the input geometry when given, else the hierarchy at
/// its finest (spheres at 1 px, cubes at eps 0), fully refined.
struct ReferenceRenderer {
    geometry: Option<Rc<Reference>>,
    /// The fixed settings' style (a kernel, a coverage).
    style: SplatStyle,
    viewer: Viewer,
    cuts: FrameState,
    label: String,
}

/// A camera's reference: its image, and (for triangle kinds) the ids of
/// the triangles it shows.
struct ReferenceFrame {
    rgba: Vec<u8>,
    visible: Option<Vec<u32>>,
}

impl ReferenceRenderer {
    fn image(
        &mut self,
        renderer: &mut Renderer,
        camera: &Camera,
        timeout: Duration,
    ) -> anyhow::Result<ReferenceFrame> {
        if let Some(g) = &self.geometry {
            let mut vertices = Vec::new();
            g.pack(camera.eye, &mut vertices);
            let rgba = renderer
                .render_geometry(camera, &vertices, &[], Coverage::Alpha, [0; 3])?
                .rgba;
            return Ok(ReferenceFrame {
                rgba,
                visible: None,
            });
        }
        // The kind's finest setting (1 px splats; eps 0, all geometry).
        let threshold = self
            .viewer
            .header()
            .map_or(1.0, |h| kind_of(h).reference_threshold_px);
        let started = Instant::now();
        let mut rgba = Vec::new();
        loop {
            self.viewer.pump(Duration::ZERO)?;
            draw_frame(
                &mut self.viewer,
                renderer,
                camera,
                threshold,
                &self.style,
                &mut self.cuts,
                &mut rgba,
            )?;
            if self.cuts.wanted().is_empty() || started.elapsed() > timeout {
                let visible = match (self.viewer.hierarchy(), self.cuts.draw_list()) {
                    (Some(h), Some(list)) => visible::visible_set(renderer, h, camera, list)?,
                    _ => None,
                };
                return Ok(ReferenceFrame { rgba, visible });
            }
            self.viewer.pump(Duration::from_millis(100))?;
        }
    }
}

/// Runs the job; writes `bench.csv`, `progress.csv`, `meta.json` and the
/// plots into `job.out`.
pub fn run(
    job: &BenchJob,
    renderer: &mut Renderer,
) -> anyhow::Result<(Vec<Row>, Vec<ProgressRow>)> {
    std::fs::create_dir_all(&job.out).with_context(|| format!("creating {}", job.out.display()))?;
    renderer.resize(job.width, job.height);
    let geometry = if job.inputs.is_empty() {
        None
    } else {
        Some(Rc::new(Reference::load(&job.inputs, &job.input_params)?))
    };
    let mut mode = modes::Mode::named(&job.mode, geometry.clone())?;
    for p in std::iter::once(&job.param).chain(job.fixed.iter().map(|f| &f.0)) {
        anyhow::ensure!(
            mode.params().contains(&p.as_str()),
            "mode {} takes {}, not {p}",
            mode.name(),
            mode.params().join(" or "),
        );
    }
    let mut reference_viewer = open(job)?;
    let header = header_of(&mut reference_viewer, job.timeout)?;
    if let Some(kind) = mode.kind() {
        anyhow::ensure!(
            kind == header.kind,
            "mode {} draws {} hierarchies, and {} is a {} hierarchy",
            mode.name(),
            kind.name(),
            scene_name(&job.source),
            header.kind.name()
        );
    }
    let label = match &geometry {
        Some(_) => format!("input geometry ({})", job.inputs.join(" ")),
        None => kind_of(&header).reference.to_owned(),
    };
    anyhow::ensure!(
        mode.uses_hierarchy() || geometry.is_some(),
        "mode {} needs --input",
        mode.name()
    );
    let (_, style) = modes::hierarchy_settings(mode.name(), mode.params(), &job.fixed)?;
    let mut reference = ReferenceRenderer {
        geometry,
        style,
        viewer: reference_viewer,
        cuts: FrameState::default(),
        label,
    };
    let cams = cameras(job, &header);
    let mut references = Vec::new();
    for c in &cams {
        references.push(reference.image(renderer, c, job.timeout)?);
    }
    let streamed = matches!(job.source, Source::Server { .. }) && mode.uses_hierarchy();
    let (mut rows, mut progress) = (Vec::new(), Vec::new());
    for value in &job.values {
        let mut settings = job.fixed.clone();
        settings.push((job.param.clone(), value.clone()));
        for (k, camera) in cams.iter().enumerate() {
            let reference_rgba = &references[k].rgba;
            let visible = references[k].visible.as_deref();
            let error = |rgba: &[u8]| compare(reference_rgba, rgba, job.width, job.height, 8);
            // A streamed view starts from nothing in a fresh session; a
            // file (or geometry) reuses the reference's resident pages.
            let mut session;
            let viewer = if streamed {
                session = open(job)?;
                &mut session
            } else {
                &mut reference.viewer
            };
            if streamed {
                // Refine from nothing, recording every frame.
                let started = Instant::now();
                let mut frame = 0u32;
                loop {
                    viewer.pump(Duration::ZERO)?;
                    if viewer.header().is_none() {
                        anyhow::ensure!(
                            started.elapsed() < job.timeout,
                            "{}",
                            viewer.no_header_error(job.timeout)
                        );
                        viewer.pump(Duration::from_millis(20))?;
                        continue;
                    }
                    let f = mode.frame(viewer, renderer, camera, &settings)?;
                    let m = error(&f.rgba)?;
                    progress.push(ProgressRow {
                        mode: mode.name().to_owned(),
                        param: job.param.clone(),
                        value: value.clone(),
                        camera: k as u32,
                        frame,
                        ms_since_connect: started.elapsed().as_secs_f64() * 1e3,
                        bytes: viewer.stats().bytes_received,
                        rmse: m.rmse,
                        psnr_db: m.psnr_db,
                        wrong_fraction: m.wrong_fraction,
                        coverage: visible::coverage(visible, mode.draw_list()),
                    });
                    frame += 1;
                    if f.complete || started.elapsed() > job.timeout {
                        break;
                    }
                    viewer.pump(Duration::from_millis(30))?;
                }
            }
            // The timed repeats, after one warm-up frame.
            let mut last = ModeFrameTimes::default();
            let mut rgba = Vec::new();
            let mut drawn = 0;
            let mut touched = 0;
            for i in 0..=job.repeats.max(1) {
                let t = Instant::now();
                let f = mode.frame(viewer, renderer, camera, &settings)?;
                let ms = t.elapsed().as_secs_f64() * 1e3;
                if i > 0 {
                    last.push(ms, &f);
                }
                (rgba, drawn, touched) = (f.rgba, f.drawn, f.touched_bytes);
            }
            let m = error(&rgba)?;
            let bytes = if streamed {
                viewer.stats().bytes_received
            } else {
                touched
            };
            rows.push(Row {
                scene: scene_name(&job.source),
                mode: mode.name().to_owned(),
                param: job.param.clone(),
                value: value.clone(),
                camera: k as u32,
                rmse: m.rmse,
                psnr_db: m.psnr_db,
                wrong_fraction: m.wrong_fraction,
                frame_ms: median(&last.frame),
                frame_ms_min: last.frame.iter().copied().fold(f64::INFINITY, f64::min),
                frame_ms_max: last.frame.iter().copied().fold(0.0, f64::max),
                traverse_ms: median(&last.traverse),
                upload_ms: median(&last.upload),
                draw_ms: median(&last.draw),
                drawn,
                bytes,
                reference: reference.label.clone(),
                reference_empty: reference_rgba.chunks_exact(4).all(|p| p[..3] == [0, 0, 0]),
                width: job.width,
                height: job.height,
                repeats: job.repeats.max(1),
                coverage: visible::coverage(visible, mode.draw_list()),
            });
        }
    }
    let meta = BenchMeta {
        scene: scene_name(&job.source),
        mode: mode.name().to_owned(),
        param: job.param.clone(),
        values: job.values.clone(),
        fixed: job.fixed.clone(),
        reference: reference.label.clone(),
        adapter: renderer.adapter_description(),
        cpu: report::cpu_model(),
        cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
        width: job.width,
        height: job.height,
        repeats: job.repeats.max(1),
        cameras: cams.len(),
    };
    rows::write(&job.out.join("bench.csv"), &rows)?;
    rows::write(&job.out.join("progress.csv"), &progress)?;
    std::fs::write(
        job.out.join("meta.json"),
        serde_json::to_string_pretty(&meta)?,
    )?;
    plots::write_all(&job.out, &rows, &progress)?;
    Ok((rows, progress))
}

#[derive(Debug, Default)]
struct ModeFrameTimes {
    frame: Vec<f64>,
    traverse: Vec<f64>,
    upload: Vec<f64>,
    draw: Vec<f64>,
}

impl ModeFrameTimes {
    fn push(&mut self, ms: f64, f: &modes::ModeFrame) {
        self.frame.push(ms);
        self.traverse.push(f.traverse_ms);
        self.upload.push(f.upload_ms);
        self.draw.push(f.draw_ms);
    }
}

/// Median of samples (NaN for none).
pub fn median(samples: &[f64]) -> f64 {
    crate::stats::median(&mut samples.to_vec())
}

/// The registered traversal of a scene's hierarchy kind.
fn kind_of(header: &FileHeader) -> &'static farfield_traverse::Registered {
    farfield_traverse::for_hierarchy(header.kind).registered()
}
