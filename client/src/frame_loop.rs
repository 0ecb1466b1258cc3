//! The frame loop: draw what is resident, ask for what would refine it.
//!
//! It is QSplat's (2.1) with the memory server in front. [`draw_frame`] is
//! one frame of any hierarchy kind: traverse (through the
//! [`farfield_traverse::Traversal`] the scene's header names), mark the
//! pages used, ask for the missing ones, draw. [`Settle`] is the resting
//! camera: keep halving the projected-size threshold until it reaches the
//! final one, then wait for pages until the cut is complete. The moving
//! camera, with frame-time feedback, is [`crate::flythrough`].

use std::time::Duration;

use anyhow::bail;
use farfield_protocol::camera::Camera;
use farfield_protocol::file::{FileHeader, HierarchyKind};
use farfield_protocol::messages::PageWish;
use farfield_render::{Renderer, SplatStyle};
use farfield_traverse::{Budget, Counts, DrawList, Registered, Traversal, TraversalOptions};
use serde::Serialize;
use web_time::Instant;

use crate::budget::TimeBudget;
use crate::viewer::Viewer;

/// When a render stops.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Until {
    /// Every page the final cut needs is resident and drawn at the final threshold.
    Refined,
    Frames(u64),
    Millis(f64),
}

/// Starting threshold of the progressive refinement, in multiples of the final one.
const COARSE_FACTOR: f64 = 16.0;

/// Where one frame's time went.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct FrameTimes {
    pub traverse_ms: f64,
    pub upload_ms: f64,
    pub draw_ms: f64,
    /// The threshold the frame was drawn at: the one asked for, or the
    /// final one for a kind whose threshold is an error bound it holds.
    pub threshold_px: f64,
}

/// What the frame loop keeps for one scene from frame to frame: the last
/// traversal, of whichever kind the scene is (made from the registry,
/// [`farfield_traverse::for_hierarchy`], on the first frame and reused with
/// its buffers after, so its cut is the last frame's), and what steers it:
/// the budget, the preferred kind, the final threshold, the measured
/// drawing costs and the path ahead.
#[derive(Debug, Default)]
pub struct FrameState {
    traversal: Option<Box<dyn Traversal>>,
    /// How many triangles a budgeted kind (PLP) may draw a frame.
    pub budget: Budget,
    /// A budget in milliseconds instead, turned into triangles each frame
    /// from the measured draw rate (it overrides `budget`).
    pub time_budget: Option<TimeBudget>,
    /// The registered kind to draw with, when the file's hierarchy is its;
    /// otherwise the hierarchy's first.
    prefer: Option<&'static Registered>,
    /// The threshold a kind whose threshold is an error bound (image
    /// caching's ε) keeps on every frame, whatever the loop asks while it
    /// refines or follows a frame time.
    pub final_threshold: Option<f64>,
    /// What drawing costs on this machine, measured by the renderer before
    /// the first frame of a kind that reads it (`Registered::measures_costs`;
    /// `None` until then).
    pub costs: Option<farfield_traverse::impostors::CostModel>,
    /// The eyes of the frames to come, when the path is known (see
    /// [`FrameState::set_known_path`]).
    known_path: Vec<glam::DVec3>,
}

impl FrameState {
    /// Draws with `kind` wherever the file's hierarchy is its.
    pub fn prefer(&mut self, kind: &'static Registered) {
        self.prefer = Some(kind);
    }

    /// Tells the traversal (now and whenever it is made again) the eyes of
    /// the frames to come, one a frame: a flythrough's path known in
    /// advance. Image caching counts life spans along it.
    pub fn set_known_path(&mut self, eyes: Vec<glam::DVec3>) {
        if let Some(t) = self.traversal.as_mut() {
            t.set_known_path(&eyes);
        }
        self.known_path = eyes;
    }

    /// The kind a file of hierarchy `kind` is drawn with.
    pub fn kind_for(&self, kind: HierarchyKind) -> &'static Registered {
        self.prefer
            .filter(|r| r.hierarchy == kind)
            .or_else(|| {
                farfield_traverse::KINDS
                    .iter()
                    .find(|k| k.hierarchy == kind)
            })
            .unwrap_or(&farfield_traverse::KINDS[0])
    }

    /// A cut that draws with the registered kind `kind` (PLP's centroid
    /// baseline, say) wherever the file's hierarchy is `kind`'s.
    pub fn of_kind(kind: &'static Registered) -> Self {
        Self {
            prefer: Some(kind),
            ..Self::default()
        }
    }

    /// The traversal for `kind`, made (or replaced) when needed.
    fn traversal_for(&mut self, kind: HierarchyKind) -> &mut dyn Traversal {
        let wanted = self.prefer.filter(|r| r.hierarchy == kind);
        let traversal = match self.traversal.take() {
            Some(t)
                if t.registered().hierarchy == kind
                    && wanted.is_none_or(|w| w.name == t.registered().name) =>
            {
                t
            }
            _ => {
                let mut made = match wanted {
                    Some(w) => (w.make)(),
                    None => farfield_traverse::for_hierarchy(kind),
                };
                if !self.known_path.is_empty() {
                    made.set_known_path(&self.known_path);
                }
                made
            }
        };
        self.traversal.insert(traversal).as_mut()
    }

    /// What the last traversal drew; `None` before the first frame.
    pub fn draw_list(&self) -> Option<DrawList<'_>> {
        self.traversal.as_ref().map(|t| t.draw_list())
    }

    /// Pages the last traversal would have descended into, most urgent first.
    pub fn wanted(&self) -> &[PageWish] {
        self.traversal.as_ref().map_or(&[], |t| t.wanted())
    }

    pub fn touched_pages(&self) -> &[u32] {
        self.traversal.as_ref().map_or(&[], |t| t.touched_pages())
    }

    pub fn counts(&self) -> Counts {
        self.traversal
            .as_ref()
            .map_or_else(Counts::default, |t| t.counts())
    }

    /// Splats, or cube faces plus leaf triangles.
    pub fn drawn(&self) -> usize {
        self.counts().drawn as usize
    }

    pub fn visited(&self) -> u64 {
        self.counts().visited
    }

    /// Pages the last traversal wanted that may still come (not given up).
    pub fn missing(&self, viewer: &Viewer) -> usize {
        self.wanted()
            .iter()
            .filter(|w| !viewer.gave_up(w.page))
            .count()
    }
}

/// Where progressive refinement starts: [`COARSE_FACTOR`] times the final
/// threshold, at least 1 (and never finer than the final one).
pub fn coarse_threshold(final_threshold: f64) -> f64 {
    (final_threshold * COARSE_FACTOR)
        .max(1.0)
        .max(final_threshold)
}

/// The next step of refinement at rest: half of `threshold`, not below
/// `finest`. Halving never reaches 0 (`--eps 0`): it goes there from 1/32.
pub fn finer_threshold(threshold: f64, finest: f64) -> f64 {
    let next = threshold * 0.5;
    if next < 1.0 / 32.0 {
        finest
    } else {
        next.max(finest)
    }
}

/// One frame's traversal without a draw: traverse what is resident, mark
/// what was used, ask for what is missing. What to draw is left in `cut`
/// ([`FrameState::draw_list`]). A headless client (the load test's) runs
/// only this; [`draw_frame`] draws after it. Returns the threshold used
/// and the traversal's milliseconds.
pub fn traverse_frame(
    viewer: &mut Viewer,
    camera: &Camera,
    threshold: f64,
    min_alpha: u8,
    cut: &mut FrameState,
) -> anyhow::Result<(f64, f64)> {
    let Some(h) = viewer.hierarchy() else {
        bail!("no scene header yet");
    };
    let threshold = match cut.final_threshold {
        Some(fixed) if !cut.kind_for(h.header.kind).adaptive_threshold => fixed,
        _ => threshold,
    };
    let options = TraversalOptions {
        threshold_px: threshold,
        min_alpha,
        record_pages: true,
        budget: cut.time_budget.map_or(cut.budget, |b| b.budget()),
        costs: cut.costs.unwrap_or_default(),
    };
    let traversal = cut.traversal_for(h.header.kind);
    let t = Instant::now();
    traversal.traverse(h, camera, &options);
    let traverse_ms = t.elapsed().as_secs_f64() * 1e3;
    viewer.touch(traversal.touched_pages());
    viewer.request(traversal.wanted());
    Ok((threshold, traverse_ms))
}

/// One frame: [`traverse_frame`], then draw (asking first, so pages
/// travel while the frame draws). The image lands in `rgba`. `threshold`
/// is the kind's threshold in pixels (the splat size for spheres, eps for
/// cubes).
pub fn draw_frame(
    viewer: &mut Viewer,
    renderer: &mut Renderer,
    camera: &Camera,
    threshold: f64,
    style: &SplatStyle,
    cut: &mut FrameState,
    rgba: &mut Vec<u8>,
) -> anyhow::Result<FrameTimes> {
    if viewer
        .header()
        .is_some_and(|h| cut.kind_for(h.kind).measures_costs)
        && cut.costs.is_none()
    {
        cut.costs = Some(renderer.measure_impostor_costs()?);
    }
    let time_budget = cut.time_budget;
    let (threshold, traverse_ms) =
        traverse_frame(viewer, camera, threshold, style.coverage.min_alpha(), cut)?;
    let drawn = cut.counts().drawn;
    let (Some(h), Some(list)) = (viewer.hierarchy(), cut.draw_list()) else {
        bail!("no scene header yet");
    };
    let image = renderer.draw(h, camera, list, style)?;
    *rgba = image.rgba;
    if let Some(mut b) = time_budget {
        // The upload and draw grow with the triangles; traversal is fixed.
        b.observe(
            drawn,
            traverse_ms + image.upload_ms + image.draw_ms,
            traverse_ms,
        );
        cut.time_budget = Some(b);
    }
    Ok(FrameTimes {
        threshold_px: threshold,
        traverse_ms,
        upload_ms: image.upload_ms,
        draw_ms: image.draw_ms,
    })
}

/// The resting-camera loop: draw, ask, halve the threshold down to the
/// final one, then wait for pages until the cut is complete (or the job's
/// end condition or deadline comes first).
#[derive(Debug)]
pub struct Settle {
    pub(crate) final_threshold: f64,
    pub threshold: f64,
    until: Until,
    started: Instant,
    timeout: Duration,
    pub keep_frames: bool,
    pub cut: FrameState,
    pub rgba: Vec<u8>,
    pub frames: Vec<Vec<u8>>,
    pub frame_count: u64,
    pub time_to_first_image_ms: Option<f64>,
    pub time_to_refined_ms: Option<f64>,
    pub last: FrameTimes,
    pub error: Option<String>,
}

impl Settle {
    pub fn new(final_threshold: f64, until: Until, started: Instant, timeout: Duration) -> Self {
        let final_threshold = final_threshold.max(0.0);
        Self {
            final_threshold,
            threshold: coarse_threshold(final_threshold),
            until,
            started,
            timeout,
            keep_frames: false,
            cut: FrameState::default(),
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
        camera_for: &dyn Fn(&FileHeader) -> Camera,
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
                let why = viewer.stats().last_error.clone().unwrap_or_default();
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
            // A kind that holds its final threshold is refined at once.
            self.threshold = self.last.threshold_px;
            self.frame_count += 1;
            if self.time_to_first_image_ms.is_none() {
                self.time_to_first_image_ms = Some(self.started.elapsed().as_secs_f64() * 1e3);
            }
            if self.keep_frames {
                self.frames.push(self.rgba.clone());
            }
            let missing = self.cut.missing(viewer);
            // Without the root nothing is drawn, however few pages are
            // missing; and once it is given up nothing more can come.
            let root = viewer.hierarchy().is_some_and(|h| h.is_resident(0));
            if !root && viewer.gave_up(0) {
                self.error = Some(viewer.with_last_error("page 0, the root, never arrived".into()));
                return Ok(());
            }
            let refined = root && missing == 0 && self.threshold <= self.final_threshold;
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
                self.threshold = finer_threshold(self.threshold, self.final_threshold);
            } else if !refined {
                // Nothing to gain from redrawing before more pages arrive.
                viewer.pump(Duration::from_millis(200))?;
            } else {
                std::thread::sleep(Duration::from_millis(5));
            }
        }
    }
}
