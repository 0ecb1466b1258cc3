//! `farfield render`: one camera, streamed or from a file, to a PNG.
//!
//! The loop is QSplat's (2.1) with the memory server in front: draw what is
//! resident, ask for what would refine it, and while the camera rests keep
//! halving the projected-size threshold until it reaches `--threshold`.
//! The first frame is drawn as soon as the header and page 0 are in.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use farfield_protocol::cube_traverse::{CubeCut, CubeOptions, traverse_cubes_into};
use farfield_protocol::file::HierarchyKind;
use farfield_protocol::traverse::{Cut, TraverseOptions, WantedPage, traverse_into};
use serde::Serialize;

use crate::args::CameraSpec;
use crate::net::SessionOptions;
use crate::render::{Coverage, Kernel, Renderer, SplatStyle, pack_leaves};
use crate::viewer::{FailedPage, NetStats, Viewer};

/// When a render stops.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Until {
    /// Every page the final cut needs is resident and drawn at the final threshold.
    Refined,
    Frames(u64),
    Millis(f64),
}

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
    /// Cubes: how face coverage is used.
    pub coverage: Coverage,
    pub session: SessionOptions,
    pub cache_bytes: usize,
    /// Give up (keeping the image so far) after this long.
    pub timeout: Duration,
}

/// What a render reports (`--json`).
#[derive(Debug, Clone, Serialize)]
pub struct RenderReport {
    pub out: Option<PathBuf>,
    pub width: u32,
    pub height: u32,
    pub time_to_first_image_ms: Option<f64>,
    pub time_to_refined_ms: Option<f64>,
    pub refined: bool,
    pub frames: u64,
    /// The session's counters (bytes and pages received, requested,
    /// cancelled, rejected; disconnects), flattened into the JSON.
    #[serde(flatten)]
    pub net: NetStats,
    /// Splats, or cube faces plus leaf triangles.
    pub nodes_drawn: usize,
    pub nodes_visited: u64,
    /// Cubes: faces and triangles of the last frame.
    pub cube_faces_drawn: usize,
    pub triangles_drawn: u64,
    pub threshold_px: f64,
    /// Bytes received / bytes of the pages the final cut touched.
    pub overfetch_ratio: Option<f64>,
    pub adapter: String,
    pub last_traverse_ms: f64,
    pub last_upload_ms: f64,
    pub last_draw_ms: f64,
    pub last_error: Option<String>,
    /// Pages given up on (corrupt on the server, or failing their checksum
    /// on arrival too often), with why: their parts are drawn from coarser
    /// pages.
    pub pages_failed: Vec<FailedPage>,
}

/// A finished render: the report and the last image.
#[derive(Debug)]
pub struct Rendered {
    pub report: RenderReport,
    pub rgba: Vec<u8>,
    /// Every frame's pixels, when asked for (tests of progressive refinement).
    pub frames: Vec<Vec<u8>>,
}

/// Starting threshold of the progressive refinement, in multiples of the final one.
const COARSE_FACTOR: f64 = 16.0;

/// Runs a render job with an already initialised renderer (so its start-up
/// is not counted in time to first image).
pub fn run(
    job: &RenderJob,
    renderer: &mut Renderer,
    keep_frames: bool,
) -> anyhow::Result<Rendered> {
    renderer.resize(job.width, job.height);
    let started = Instant::now();
    let mut viewer = open_viewer(job)?;
    let style = SplatStyle {
        kernel: job.kernel,
        coverage: job.coverage,
        ..SplatStyle::default()
    };
    let camera = job.camera;
    let (width, height) = (job.width, job.height);
    let mut settle = Settle::new(job.threshold_px, job.until, started, job.timeout);
    settle.keep_frames = keep_frames;
    settle.run(&mut viewer, renderer, &style, &|h| {
        camera.resolve(h, width, height)
    })?;
    let mut report = settle.report(
        &viewer,
        renderer,
        matches!(job.source, Source::Server { .. }),
    );
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
        crate::image::write_png(out, width, height, &settle.rgba)
            .with_context(|| format!("writing {}", out.display()))?;
    }
    Ok(Rendered {
        report,
        rgba: std::mem::take(&mut settle.rgba),
        frames: std::mem::take(&mut settle.frames),
    })
}

/// The viewer a job's source names: a file read whole, or a session with
/// a memory server.
pub fn open_viewer(job: &RenderJob) -> anyhow::Result<Viewer> {
    match &job.source {
        Source::File(path) => Viewer::open_file(path),
        Source::Server { url, scene } => {
            Viewer::open_remote(url, scene, job.session, job.cache_bytes)
        }
    }
}

/// The resting-camera loop: draw, ask, halve the threshold down to the
/// final one, then wait for pages until the cut is complete (or the job's
/// end condition or deadline comes first).
#[derive(Debug)]
pub struct Settle {
    final_threshold: f64,
    pub threshold: f64,
    until: Until,
    started: Instant,
    timeout: Duration,
    pub keep_frames: bool,
    pub cut: Cuts,
    pub rgba: Vec<u8>,
    pub frames: Vec<Vec<u8>>,
    pub frame_count: u64,
    pub time_to_first_image_ms: Option<f64>,
    pub time_to_refined_ms: Option<f64>,
    pub last: FrameTimes,
    pub error: Option<String>,
}

/// Where one frame's time went.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct FrameTimes {
    pub traverse_ms: f64,
    pub upload_ms: f64,
    pub draw_ms: f64,
}

impl Settle {
    pub fn new(final_threshold: f64, until: Until, started: Instant, timeout: Duration) -> Self {
        let final_threshold = final_threshold.max(0.0);
        Self {
            final_threshold,
            threshold: (final_threshold * COARSE_FACTOR)
                .max(1.0)
                .max(final_threshold),
            until,
            started,
            timeout,
            keep_frames: false,
            cut: Cuts::default(),
            rgba: Vec::new(),
            frames: Vec::new(),
            frame_count: 0,
            time_to_first_image_ms: None,
            time_to_refined_ms: None,
            last: FrameTimes::default(),
            error: None,
        }
    }

    /// Draws frames for the camera `camera_for(header)` until done.
    pub fn run(
        &mut self,
        viewer: &mut Viewer,
        renderer: &mut Renderer,
        style: &SplatStyle,
        camera_for: &dyn Fn(
            &farfield_protocol::file::FileHeader,
        ) -> farfield_protocol::camera::Camera,
    ) -> anyhow::Result<()> {
        let mut announced_disconnect = false;
        loop {
            let elapsed = self.started.elapsed();
            if elapsed > self.timeout {
                self.error = Some(if viewer.header().is_none() {
                    viewer.no_header_error(elapsed)
                } else {
                    let seconds = elapsed.as_secs_f64();
                    viewer.with_last_error(format!("not refined after {seconds:.1} s"))
                });
                return Ok(());
            }
            viewer.pump(Duration::ZERO)?;
            if !viewer.is_connected() && !announced_disconnect && self.frame_count > 0 {
                let why = viewer.stats.last_error.clone().unwrap_or_default();
                eprintln!("farfield: lost the server ({why}); keeping the image and reconnecting");
                announced_disconnect = true;
            }
            announced_disconnect &= !viewer.is_connected();
            let Some(header) = viewer.header().cloned() else {
                viewer.pump(Duration::from_millis(50))?;
                continue;
            };
            let camera = camera_for(&header);
            self.last = draw_frame(
                viewer,
                renderer,
                &camera,
                self.threshold,
                style,
                &mut self.cut,
                &mut self.rgba,
            )?;
            self.frame_count += 1;
            if self.time_to_first_image_ms.is_none() {
                self.time_to_first_image_ms = Some(self.started.elapsed().as_secs_f64() * 1e3);
            }
            if self.keep_frames {
                self.frames.push(self.rgba.clone());
            }
            let missing = self
                .cut
                .wanted()
                .iter()
                .filter(|w| !viewer.gave_up(w.page))
                .count();
            let refined = missing == 0 && self.threshold <= self.final_threshold;
            if refined && self.time_to_refined_ms.is_none() {
                self.time_to_refined_ms = Some(self.started.elapsed().as_secs_f64() * 1e3);
            }
            let done = match self.until {
                Until::Refined => refined,
                Until::Frames(n) => self.frame_count >= n,
                Until::Millis(ms) => self.started.elapsed().as_secs_f64() * 1e3 >= ms,
            };
            if done {
                return Ok(());
            }
            if self.threshold > self.final_threshold {
                // Halving never reaches 0 (`--eps 0`): go there from 1/32.
                let next = self.threshold * 0.5;
                self.threshold = if next < 1.0 / 32.0 {
                    self.final_threshold
                } else {
                    next.max(self.final_threshold)
                };
            } else if !refined {
                // Nothing to gain from redrawing before more pages arrive.
                viewer.pump(Duration::from_millis(200))?;
            } else {
                std::thread::sleep(Duration::from_millis(5));
            }
        }
    }

    /// The report of what happened, with the viewer's network counters.
    pub fn report(&self, viewer: &Viewer, renderer: &Renderer, streamed: bool) -> RenderReport {
        let stats = &viewer.stats;
        let overfetch_ratio = viewer.hierarchy().filter(|_| streamed).and_then(|h| {
            let needed: u64 = self
                .cut
                .touched_pages()
                .iter()
                .map(|&p| u64::from(h.header.pages[p as usize].length))
                .sum();
            (needed > 0).then(|| stats.bytes_received as f64 / needed as f64)
        });
        let (width, height) = renderer.size();
        RenderReport {
            out: None,
            width,
            height,
            time_to_first_image_ms: self.time_to_first_image_ms,
            time_to_refined_ms: self.time_to_refined_ms,
            refined: self.time_to_refined_ms.is_some(),
            frames: self.frame_count,
            net: stats.clone(),
            nodes_drawn: self.cut.drawn(),
            nodes_visited: self.cut.visited(),
            cube_faces_drawn: self.cut.cubes.faces.len(),
            triangles_drawn: self.cut.cubes.triangles,
            threshold_px: self.threshold,
            overfetch_ratio,
            adapter: renderer.adapter_description(),
            last_traverse_ms: self.last.traverse_ms,
            last_upload_ms: self.last.upload_ms,
            last_draw_ms: self.last.draw_ms,
            last_error: self.error.clone().or(stats.last_error.clone()),
            pages_failed: viewer.failed_pages(),
        }
    }
}

/// The last traversal, of whichever kind the scene is.
#[derive(Debug, Default)]
pub struct Cuts {
    pub kind: Option<HierarchyKind>,
    pub spheres: Cut,
    pub cubes: CubeCut,
}

impl Cuts {
    /// Pages the last traversal would have descended into, most urgent first.
    pub fn wanted(&self) -> &[WantedPage] {
        match self.kind {
            Some(HierarchyKind::Cubes) => &self.cubes.wanted,
            _ => &self.spheres.wanted,
        }
    }

    pub fn touched_pages(&self) -> &[u32] {
        match self.kind {
            Some(HierarchyKind::Cubes) => &self.cubes.touched_pages,
            _ => &self.spheres.touched_pages,
        }
    }

    /// Splats, or cube faces plus leaf triangles.
    pub fn drawn(&self) -> usize {
        match self.kind {
            Some(HierarchyKind::Cubes) => self.cubes.faces.len() + self.cubes.triangles as usize,
            _ => self.spheres.splats.len(),
        }
    }

    pub fn visited(&self) -> u64 {
        match self.kind {
            Some(HierarchyKind::Cubes) => self.cubes.visited,
            _ => self.spheres.visited,
        }
    }
}

/// One frame: traverse what is resident, mark what was used, ask for what
/// is missing, draw. The image lands in `rgba`. For a cube hierarchy
/// `threshold` is eps.
pub fn draw_frame(
    viewer: &mut Viewer,
    renderer: &mut Renderer,
    camera: &farfield_protocol::camera::Camera,
    threshold: f64,
    style: &SplatStyle,
    cut: &mut Cuts,
    rgba: &mut Vec<u8>,
) -> anyhow::Result<FrameTimes> {
    let Some(h) = viewer.hierarchy() else {
        bail!("no scene header yet");
    };
    cut.kind = Some(h.header.kind);
    let t = Instant::now();
    if h.header.kind == HierarchyKind::Cubes {
        let options = CubeOptions {
            eps_px: threshold,
            min_alpha: style.coverage.min_alpha(),
            record_pages: true,
            ..CubeOptions::default()
        };
        traverse_cubes_into(h, camera, &options, &mut cut.cubes);
        let traverse_ms = t.elapsed().as_secs_f64() * 1e3;
        let image = draw_cut(
            renderer,
            &CubeFrame {
                hierarchy: h,
                camera,
                cut: &cut.cubes,
                coverage: style.coverage,
                background: style.background,
            },
        )?;
        viewer.touch(&cut.cubes.touched_pages);
        viewer.request(&cut.cubes.wanted);
        *rgba = image.rgba;
        return Ok(FrameTimes {
            traverse_ms,
            upload_ms: image.upload_ms,
            draw_ms: image.draw_ms,
        });
    }
    let options = TraverseOptions {
        threshold_px: threshold,
        record_pages: true,
        ..TraverseOptions::default()
    };
    traverse_into(h, camera, &options, &mut cut.spheres);
    let traverse_ms = t.elapsed().as_secs_f64() * 1e3;
    viewer.touch(&cut.spheres.touched_pages);
    viewer.request(&cut.spheres.wanted);
    let image = renderer.render(camera, &cut.spheres.splats, style)?;
    *rgba = image.rgba;
    Ok(FrameTimes {
        traverse_ms,
        upload_ms: image.upload_ms,
        draw_ms: image.draw_ms,
    })
}

/// What drawing one cube cut needs.
#[derive(Debug, Clone, Copy)]
pub struct CubeFrame<'a> {
    pub hierarchy: &'a farfield_protocol::hierarchy::Hierarchy,
    pub camera: &'a farfield_protocol::camera::Camera,
    pub cut: &'a CubeCut,
    pub coverage: Coverage,
    pub background: [u8; 3],
}

/// Draws a cube cut: its leaves' triangles (packed camera-relative here,
/// counted in the upload time) and its faces.
pub fn draw_cut(
    renderer: &mut Renderer,
    frame: &CubeFrame,
) -> anyhow::Result<crate::render::RenderOutput> {
    let started = Instant::now();
    let mut vertices = Vec::new();
    pack_leaves(frame.hierarchy, frame.cut, frame.camera.eye, &mut vertices);
    let pack_ms = started.elapsed().as_secs_f64() * 1e3;
    let mut image = renderer.render_geometry(
        frame.camera,
        &vertices,
        &frame.cut.faces,
        frame.coverage,
        frame.background,
    )?;
    image.upload_ms += pack_ms;
    Ok(image)
}
