//! Flythroughs: a camera path rendered frame by frame while pages stream.
//!
//! The camera moves on a fixed clock (`fps` frames per path second) and
//! never waits for pages: it draws what is resident, and the projected-size
//! threshold follows the frame time (QSplat 2.1's feedback: the threshold
//! area scales with the ratio of actual to target frame time, so the
//! diameter threshold scales with its square root). At the end the camera
//! rests and the picture refines to the final threshold.

use std::io::Write;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::Context;
use farfield_render::{Renderer, SplatStyle};
use serde::Serialize;
use web_time::Instant;

use crate::budget::BudgetSpec;
use crate::frame_loop::{FrameState, FrameTimes, Settle, Until, draw_frame};
use crate::path::CameraPath;
use crate::viewer::Viewer;

/// Largest threshold the feedback may choose, in pixels.
pub const MAX_THRESHOLD_PX: f64 = 64.0;

/// The next frame's threshold after a frame of `frame_ms` aiming at
/// `target_ms` (QSplat 2.1): the threshold *area* scales with the ratio of
/// actual to target frame time (each step at most 4x either way), so the
/// diameter scales with its square root; never finer than the final
/// threshold (nor half a pixel), never coarser than [`MAX_THRESHOLD_PX`].
pub fn follow_frame_time(
    threshold: f64,
    frame_ms: f64,
    target_ms: f64,
    final_threshold: f64,
) -> f64 {
    let ratio = (frame_ms / target_ms.max(1e-3)).clamp(0.25, 4.0);
    (threshold * ratio.sqrt()).clamp(final_threshold.max(0.5), MAX_THRESHOLD_PX)
}

/// A flythrough's settings.
#[derive(Debug, Clone)]
pub struct FlyJob {
    pub path: CameraPath,
    pub fps: f64,
    pub width: u32,
    pub height: u32,
    /// The threshold the resting camera refines to.
    pub final_threshold_px: f64,
    /// The frame time the feedback aims for while moving.
    pub target_frame_ms: f64,
    pub style: SplatStyle,
    /// Write every frame as `frame_NNNN.png` here.
    pub frames_dir: Option<PathBuf>,
    /// Refine at the last camera after the path ends.
    pub settle: bool,
    pub timeout: Duration,
    /// Budgeted kinds (PLP): triangles or milliseconds a frame.
    pub budget: BudgetSpec,
    /// Tell the traversal the path's eyes in advance (image caching then
    /// counts its caches' life spans along the path instead of
    /// extrapolating the motion: the paper's offline estimate).
    pub known_path: bool,
}

/// One row of the per-frame CSV.
#[derive(Debug, Clone, Serialize)]
pub struct FrameStat {
    pub frame: u64,
    /// Path time of the camera, seconds.
    pub path_s: f64,
    /// Wall time since the session started, milliseconds.
    pub time_ms: f64,
    pub threshold_px: f64,
    pub nodes_drawn: usize,
    pub bytes_received: u64,
    pub resident_pages: usize,
    pub traverse_ms: f64,
    pub upload_ms: f64,
    pub draw_ms: f64,
    pub frame_ms: f64,
    pub resting: bool,
    /// Image caching: caches made and drawn this frame, and the atlas's
    /// bytes in use (0 for other kinds).
    pub caches_made: u64,
    pub caches_drawn: u64,
    pub texture_bytes: u64,
}

/// The CSV header matching [`FrameStat`]'s fields.
pub const CSV_HEADER: &str = "frame,path_s,time_ms,threshold_px,nodes_drawn,bytes_received,resident_pages,traverse_ms,upload_ms,draw_ms,frame_ms,resting,caches_made,caches_drawn,texture_bytes";

impl FrameStat {
    pub fn csv_row(&self) -> String {
        format!(
            "{},{:.3},{:.1},{:.3},{},{},{},{:.3},{:.3},{:.3},{:.3},{},{},{},{}",
            self.frame,
            self.path_s,
            self.time_ms,
            self.threshold_px,
            self.nodes_drawn,
            self.bytes_received,
            self.resident_pages,
            self.traverse_ms,
            self.upload_ms,
            self.draw_ms,
            self.frame_ms,
            self.resting,
            self.caches_made,
            self.caches_drawn,
            self.texture_bytes
        )
    }
}

/// Flies the path; returns per-frame stats and the settle phase's state.
pub fn fly(
    viewer: &mut Viewer,
    renderer: &mut Renderer,
    job: &FlyJob,
    started: Instant,
) -> anyhow::Result<(Vec<FrameStat>, Settle)> {
    renderer.resize(job.width, job.height);
    if let Some(dir) = &job.frames_dir {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    // Wait for the scene header before the clock starts.
    while viewer.header().is_none() {
        anyhow::ensure!(
            started.elapsed() < job.timeout,
            "{}",
            viewer.no_header_error(job.timeout)
        );
        viewer.pump(Duration::from_millis(100))?;
    }
    let final_threshold = job.final_threshold_px.max(0.0);
    let mut threshold = (final_threshold * 4.0).max(2.0);
    let frames = (job.path.duration() * job.fps).ceil().max(0.0) as u64 + 1;
    let mut stats = Vec::with_capacity(frames as usize + 16);
    let mut cut = FrameState::default();
    job.budget.apply(&mut cut);
    cut.final_threshold = Some(final_threshold);
    if job.known_path
        && let Some(header) = viewer.header().cloned()
    {
        let eyes = (0..frames)
            .map(|f| {
                let path_s = f as f64 / job.fps.max(1e-3);
                job.path
                    .camera_at(path_s, &header, job.width, job.height)
                    .eye
            })
            .collect();
        cut.set_known_path(eyes);
    }
    let mut rgba = Vec::new();
    for frame in 0..frames {
        viewer.pump(Duration::ZERO)?;
        let path_s = frame as f64 / job.fps.max(1e-3);
        let Some(header) = viewer.header().cloned() else {
            continue;
        };
        let camera = job.path.camera_at(path_s, &header, job.width, job.height);
        let t = Instant::now();
        let times = draw_frame(
            viewer, renderer, &camera, threshold, &job.style, &mut cut, &mut rgba,
        )?;
        let frame_ms = t.elapsed().as_secs_f64() * 1e3;
        // What the frame was drawn at (an error bound is held, not traded
        // for time).
        threshold = times.threshold_px;
        stats.push(stat(
            frame, path_s, started, threshold, &cut, viewer, times, frame_ms, false,
        ));
        write_frame(job, frame, &rgba)?;
        threshold = follow_frame_time(threshold, frame_ms, job.target_frame_ms, final_threshold);
    }
    let mut settle = Settle::new(final_threshold, Until::Refined, started, job.timeout);
    // The resting camera draws with the same kind and budget as the path.
    job.budget.apply(&mut settle.cut);
    settle.cut.final_threshold = Some(final_threshold);
    if job.settle {
        let last_t = job.path.duration();
        let path = job.path.clone();
        let (w, h) = (job.width, job.height);
        settle.threshold = threshold.max(final_threshold);
        let before = stats.len() as u64;
        settle.run(viewer, renderer, &job.style, &|header| {
            path.camera_at(last_t, header, w, h)
        })?;
        let t = settle.last;
        // A settle that drew nothing (out of time) adds no frame.
        if settle.frame_count == 0 {
            return Ok((stats, settle));
        }
        let frame = before + settle.frame_count - 1;
        stats.push(stat(
            frame,
            last_t,
            started,
            settle.threshold,
            &settle.cut,
            viewer,
            t,
            t.traverse_ms + t.upload_ms + t.draw_ms,
            true,
        ));
        write_frame(job, frame, &settle.rgba)?;
    }
    Ok((stats, settle))
}

#[allow(clippy::too_many_arguments)]
fn stat(
    frame: u64,
    path_s: f64,
    started: Instant,
    threshold: f64,
    cut: &FrameState,
    viewer: &Viewer,
    times: FrameTimes,
    frame_ms: f64,
    resting: bool,
) -> FrameStat {
    let impostors = cut.draw_list().and_then(|l| l.impostor_stats());
    FrameStat {
        frame,
        path_s,
        time_ms: started.elapsed().as_secs_f64() * 1e3,
        threshold_px: threshold,
        nodes_drawn: cut.drawn(),
        bytes_received: viewer.stats().bytes_received,
        resident_pages: viewer.hierarchy().map_or(0, |h| h.resident_pages()),
        traverse_ms: times.traverse_ms,
        upload_ms: times.upload_ms,
        draw_ms: times.draw_ms,
        frame_ms,
        resting,
        caches_made: impostors.map_or(0, |s| s.caches_made),
        caches_drawn: impostors.map_or(0, |s| s.caches_drawn),
        texture_bytes: impostors.map_or(0, |s| s.texture_bytes),
    }
}

fn write_frame(job: &FlyJob, frame: u64, rgba: &[u8]) -> anyhow::Result<()> {
    if let Some(dir) = &job.frames_dir {
        let path = dir.join(format!("frame_{frame:04}.png"));
        farfield_image::write_png(&path, job.width, job.height, rgba)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

/// Writes the per-frame CSV.
pub fn write_csv(path: &std::path::Path, stats: &[FrameStat]) -> anyhow::Result<()> {
    let mut out = std::io::BufWriter::new(
        std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?,
    );
    writeln!(out, "{CSV_HEADER}")?;
    for s in stats {
        writeln!(out, "{}", s.csv_row())?;
    }
    out.flush()?;
    Ok(())
}
