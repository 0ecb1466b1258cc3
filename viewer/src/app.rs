//! [`ViewerApp`]: the viewer as an eframe app, the same in a window and in
//! a browser tab.
//!
//! Each egui frame: take the pages that arrived (never waiting), turn the
//! input into camera motion, draw the scene into a texture on egui's own
//! device ([`farfield_render::Renderer::for_texture`]), show it under the
//! panel, and ask for another frame while anything can still change
//! (the camera is easing, the view is not refined, the server is away).
//! What differs between a window and a page (the URL, screenshots, what a
//! test script reads) is behind [`Platform`].

use std::sync::{Arc, Mutex};

use egui::{Color32, Rect, Sense, Vec2, pos2};
use farfield_client::camera_spec::CameraSpec;
use farfield_client::frame_loop::{FrameState, draw_frame};
use farfield_client::render_job::DemoRole;
use farfield_client::viewer::Viewer;
use farfield_render::{Renderer, SplatStyle};
use farfield_traverse::DrawList;
use web_time::Instant;

use crate::demo_panel::{Demo, DemoActions};
use crate::flight::{Flight, FlightReport};
use crate::input::read_input;
use crate::panel::{self, Settings};
use crate::pick::pick_splat;
use crate::refine::{CutState, Refinement};
use crate::rig::{CameraRig, Orbit};
use crate::status::{Connection, FrameClock, Status};

/// Time a frame may spend verifying and inserting arrived pages; the rest
/// wait for the next frame, so a burst never stalls the picture.
const PAGE_BUDGET: std::time::Duration = std::time::Duration::from_millis(4);

/// How long [`AppOptions::notice`] shows.
const NOTICE_FOR: std::time::Duration = std::time::Duration::from_secs(10);

/// How long a viewer's session keeps trying to reach a server it has never
/// reached (its `first_connect_grace`): as long as someone looks, since
/// the viewer says it is connecting; a server that went away after is
/// retried for as long anyway.
pub const WAIT_FOR_SERVER: std::time::Duration = std::time::Duration::from_secs(365 * 24 * 3600);

/// What a front end tells the viewer at start.
#[derive(Debug, Clone)]
pub struct AppOptions {
    /// The camera to open at (a link's, or the command line's); fit to the
    /// scene when `None`.
    pub camera: Option<CameraSpec>,
    pub settings: Settings,
    /// Show the panel at start (it can be toggled with Tab or its button).
    pub show_panel: bool,
    /// Fly the benchmark's path ([`crate::flight`]) for this many seconds
    /// once the scene is there, then report to [`Platform::flight_done`].
    pub flight_seconds: Option<f64>,
    /// Join this demo session at start, presenting or following.
    pub demo: Option<DemoRole>,
    /// Said to the user for a while after start (what was ignored of a
    /// damaged link).
    pub notice: Option<String>,
}

impl Default for AppOptions {
    fn default() -> Self {
        Self {
            camera: None,
            settings: Settings::default(),
            show_panel: true,
            flight_seconds: None,
            demo: None,
            notice: None,
        }
    }
}

/// A frame of `width` x `height` pixels, scaled down (keeping its shape)
/// so that neither side passes `max_side`, the device's largest texture:
/// a window larger than that is drawn at the largest size and stretched,
/// not refused.
pub(crate) fn fit_within(width: f32, height: f32, max_side: u32) -> (u32, u32) {
    let longest = width.max(height);
    let scale = if longest > max_side as f32 {
        max_side as f32 / longest
    } else {
        1.0
    };
    let side = |v: f32| ((v * scale).floor() as u32).clamp(1, max_side.max(1));
    (side(width), side(height))
}

/// What differs between a window and a browser page.
pub trait Platform {
    /// The camera came to rest here (a page writes it into its URL).
    fn camera_rested(&mut self, _camera: &CameraSpec) {}
    /// After every frame: what the panel shows (a page exposes it to scripts).
    fn status(&mut self, _status: &Status) {}
    /// Whether to take a screenshot now, unasked (a window told to save
    /// one whenever the view is refined, a script asking a page), and of what.
    fn wants_screenshot(&mut self, _status: &Status) -> Shot {
        Shot::None
    }
    /// A screenshot the user (or [`Self::wants_screenshot`]) asked for:
    /// RGBA rows, top first.
    fn screenshot(&mut self, width: u32, height: u32, rgba: Vec<u8>);
    /// The GPU device was lost (`message` says how): nothing is drawn any
    /// more. A page drawing with WebGPU starts again on WebGL2; a window
    /// shows the message (the default).
    fn device_lost(&mut self, _message: &str) {}
    /// A script pressed the screenshot button (a page's `screenshot()`).
    fn screenshot_asked(&mut self) -> bool {
        false
    }
    /// Takes the screenshot the user asked for itself, when the platform
    /// has a better way (a page reads its canvas); `false` leaves it to
    /// the app ([`Shot::Scene`]).
    fn screenshot_itself(&mut self) -> bool {
        false
    }
    /// A scripted flight ([`AppOptions::flight_seconds`]) ended.
    fn flight_done(&mut self, _report: &FlightReport, _ctx: &egui::Context) {}
    /// The session ended before the scene's header came (an unknown scene,
    /// a refused token, a server never reached): there is nothing to show
    /// and it will not come. A window closes and its command fails with
    /// `message`; a page leaves the message on screen (the default).
    fn session_failed(&mut self, _message: &str, _ctx: &egui::Context) {}
}

/// What a screenshot shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shot {
    None,
    /// The scene as drawn, without the panel (the screenshot button's):
    /// read back from the scene's texture.
    Scene,
    /// The whole window as presented, panel and all (egui's capture of
    /// the frame; in a browser on WebGPU this may fail, so pages use
    /// [`Shot::Scene`]).
    Window,
}

/// The viewer.
pub struct ViewerApp {
    viewer: Viewer,
    platform: Box<dyn Platform>,
    options: AppOptions,
    renderer: Option<Renderer>,
    /// The scene texture as egui knows it, and the renderer's generation of it.
    texture: Option<(egui::TextureId, u64)>,
    rig: Option<CameraRig>,
    refine: Refinement,
    cut: FrameState,
    rgba: Vec<u8>,
    show_panel: bool,
    flying: bool,
    /// The measuring tool and its points.
    measure: crate::measure::Measure,
    status: Status,
    last_frame: Instant,
    rested_at: Option<CameraSpec>,
    /// Validation errors the device reported (a browser's, mostly).
    gpu_error: Arc<Mutex<Option<String>>>,
    screenshots: Arc<Mutex<Vec<Arc<egui::ColorImage>>>>,
    /// The benchmark's flight, while it flies.
    flight: Option<Flight>,
    /// The demo session this viewer presents or follows.
    demo: Demo,
    /// The session's end was told to the platform.
    ended: bool,
    clock: FrameClock,
    /// The last frame asked for the next at once.
    busy: bool,
    /// [`AppOptions::notice`], and since when it shows.
    notice: Option<(String, Instant)>,
    /// The GPU device was lost: nothing is drawn any more.
    lost: Arc<std::sync::atomic::AtomicBool>,
    /// The loss was told to the platform.
    lost_told: bool,
    /// What the last frame drew.
    drawn: Option<DrawnView>,
    /// The session wakes the app when something arrives.
    woken: bool,
}

/// What a drawn frame showed (see [`ViewerApp::scene`]).
#[derive(Debug, Clone, PartialEq)]
struct DrawnView {
    spec: CameraSpec,
    size: (u32, u32),
    settings: Settings,
    threshold: f64,
    pages: usize,
    received: u64,
}

impl std::fmt::Debug for ViewerApp {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ViewerApp")
            .field("status", &self.status)
            .finish_non_exhaustive()
    }
}

impl ViewerApp {
    /// A viewer of `viewer`'s scene in the eframe app being created.
    pub fn new(
        cc: &eframe::CreationContext<'_>,
        viewer: Viewer,
        options: AppOptions,
        platform: Box<dyn Platform>,
    ) -> anyhow::Result<Self> {
        // A press held still for egui's click time (0.8 s) becomes a long
        // press, a secondary click on a touch screen, and a finger that
        // then moved dragged nothing: a slow frame (a phone, a loaded
        // machine) made every touch drag one, and the camera never moved.
        // The scene uses no long press, so a press stays a click until it
        // moves and a drag once it does, however long it was held.
        cc.egui_ctx
            .options_mut(|o| o.input_options.max_click_duration = f64::INFINITY);
        let state = cc
            .wgpu_render_state
            .as_ref()
            .ok_or_else(|| anyhow::anyhow!("the viewer needs eframe's wgpu renderer"))?;
        let gpu_error: Arc<Mutex<Option<String>>> = Arc::default();
        let lost: Arc<std::sync::atomic::AtomicBool> = Arc::default();
        {
            let gpu_error = gpu_error.clone();
            state.device.on_uncaptured_error(Arc::new(move |e| {
                tracing::error!("GPU: {e}");
                if let Ok(mut slot) = gpu_error.lock() {
                    slot.get_or_insert_with(|| e.to_string());
                }
            }));
        }
        {
            let gpu_error = gpu_error.clone();
            let lost = lost.clone();
            state
                .device
                .set_device_lost_callback(move |reason, message| {
                    tracing::error!("GPU device lost ({reason:?}): {message}");
                    lost.store(true, std::sync::atomic::Ordering::Relaxed);
                    if let Ok(mut slot) = gpu_error.lock() {
                        *slot = Some(format!("the GPU device was lost ({reason:?}): {message}"));
                    }
                });
        }
        let renderer = Renderer::for_texture(
            state.adapter.clone(),
            state.device.clone(),
            state.queue.clone(),
            1,
            1,
        )?;
        let s = &options.settings;
        let refine = Refinement::new(s.threshold, s.target_frame_ms, s.node_budget);
        let flight = options.flight_seconds.map(Flight::new);
        let demo = Demo::starting(options.demo.as_ref());
        let notice = options.notice.clone().map(|n| (n, Instant::now()));
        let mut viewer = viewer;
        let woken = {
            let ctx = cc.egui_ctx.clone();
            viewer.set_waker(move || ctx.request_repaint())
        };
        let status = Status {
            adapter: renderer.adapter_description(),
            ..Status::default()
        };
        Ok(Self {
            viewer,
            platform,
            show_panel: options.show_panel,
            options,
            renderer: Some(renderer),
            texture: None,
            rig: None,
            refine,
            cut: FrameState::default(),
            rgba: Vec::new(),
            flying: false,
            measure: Default::default(),
            status,
            last_frame: Instant::now(),
            rested_at: None,
            gpu_error,
            screenshots: Arc::default(),
            flight,
            demo,
            ended: false,
            clock: FrameClock::default(),
            busy: true,
            notice,
            lost,
            lost_told: false,
            drawn: None,
            woken,
        })
    }

    /// Takes what arrived, inserting pages for at most [`PAGE_BUDGET`] a
    /// frame. A session that ended is shown, and what is here stays; one
    /// that ended before the scene came is told to the platform.
    fn pump(&mut self, ctx: &egui::Context) {
        if let Err(e) = self.viewer.pump_for(PAGE_BUDGET) {
            let message = format!("{e:#}");
            if !self.ended && self.viewer.header().is_none() {
                self.ended = true;
                self.platform.session_failed(&message, ctx);
            }
            self.status.error = Some(message);
        }
    }

    /// Makes the rig when the scene's header first arrives.
    fn make_rig(&mut self) {
        if self.rig.is_none() {
            let Some(header) = self.viewer.header() else {
                return;
            };
            let fov = 45.0;
            let start = match &self.options.camera {
                Some(spec) => Orbit::from_spec(spec, header),
                None => Orbit::fit(header, fov),
            };
            self.rig = Some(CameraRig::new(start, header));
        }
    }

    /// Draws the scene for `rect` (points) and handles its input.
    /// `frame_s` is the time since the last frame as it was; `dt` the
    /// same, capped, for motion (a long stall must not fling the camera).
    fn scene(
        &mut self,
        ui: &mut egui::Ui,
        rect: Rect,
        frame: &eframe::Frame,
        frame_s: f64,
        dt: f64,
    ) {
        let response = ui.allocate_rect(rect, Sense::click_and_drag());
        let ppp = ui.ctx().pixels_per_point();
        let max_side = self.renderer.as_ref().map_or(u32::MAX, Renderer::max_side);
        let (width, height) = fit_within(
            (rect.width() * ppp).round().max(1.0),
            (rect.height() * ppp).round().max(1.0),
            max_side,
        );
        let input = read_input(ui, &response, rect, &mut self.flying);
        let flying = self.flying;
        // A click picks a point to measure while the tool is on (and a
        // double-click no longer focuses); a double-click focuses otherwise.
        let (pick, measured) = {
            let at = response.interact_pointer_pos();
            if self.measure.on {
                (None, response.clicked().then_some(at).flatten())
            } else {
                (response.double_clicked().then_some(at).flatten(), None)
            }
        };
        if ui.input(|i| i.key_pressed(egui::Key::M)) || self.status.measure_toggled {
            self.measure.toggle();
        }
        if ui.input(|i| i.key_pressed(egui::Key::Escape)) && self.measure.on {
            self.measure.toggle();
        }
        self.status.measure_toggled = false;
        let reset = ui.input(|i| i.key_pressed(egui::Key::R)) || self.status.reset_requested;
        self.status.reset_requested = false;
        let preset = ui
            .input(|i| {
                crate::rig::Preset::ALL
                    .into_iter()
                    .find(|(_, _, key)| i.key_pressed(*key))
                    .map(|(preset, _, _)| preset)
            })
            .or(self.status.preset_requested.take());
        self.make_rig();
        let Some(rig) = self.rig.as_mut() else {
            ui.painter().rect_filled(rect, 0.0, Color32::BLACK);
            return;
        };
        if reset {
            rig.reset();
        }
        if let (Some(preset), Some(header)) = (preset, self.viewer.header()) {
            let fov = rig.goal().fov_y_deg;
            rig.go_to(crate::rig::Orbit::preset(header, fov, preset));
        }
        rig.apply(&input, flying, rect.height() * ppp, dt);
        self.demo.steer(rig, input != Default::default());
        let flying_script = self.flight.is_some();
        if let Some(flight) = self.flight.as_mut() {
            let next = flight.next(rig.shown(), dt);
            rig.jump(next);
        }
        if let Some(at) = pick.or(measured)
            && let Some(DrawList::Splats(splats)) = self.cut.draw_list()
        {
            let camera = rig.shown().camera(width, height);
            let px = ((at - rect.min) * ppp).to_pos2();
            if measured.is_some() {
                if let Some(point) = crate::pick::pick_point(splats, &camera, px.x, px.y) {
                    self.measure.points.push(point);
                }
            } else if let Some(point) = pick_splat(splats, &camera, px.x, px.y) {
                rig.focus(point);
            }
        }
        let was_moving = !rig.at_rest();
        rig.ease(dt);
        let moving = was_moving || input != Default::default() || flying_script;
        let camera = rig.shown().camera(width, height);
        let rest_spec = (!moving).then(|| rig.shown().spec());
        let s = &self.options.settings;
        let shown_options = vec![
            ("threshold".to_owned(), s.threshold.to_string()),
            ("kernel".to_owned(), s.kernel.name().to_owned()),
        ];
        self.demo.present(&mut self.viewer, &camera, shown_options);

        // What the last drawn frame showed: when the view rests, refined,
        // on the same pages, drawing it again would change nothing.
        let view = DrawnView {
            spec: rig.shown().spec(),
            size: (width, height),
            settings: self.options.settings.clone(),
            threshold: self.refine.threshold(),
            pages: self.viewer.hierarchy().map_or(0, |h| h.resident_pages()),
            received: self.viewer.stats().bytes_received,
        };
        let Some(renderer) = self.renderer.as_mut() else {
            return;
        };
        if !moving
            && self.status.refined
            && !renderer.capture_pending()
            && self.drawn.as_ref() == Some(&view)
        {
            self.show_texture(ui, rect, frame);
            self.draw_measure(ui, rect, &camera, ppp);
            return;
        }
        renderer.resize(width, height);
        let s = &self.options.settings;
        let style = SplatStyle {
            kernel: s.kernel,
            edl: s.edl,
            color_by: s.color_by,
            clip: s.clip,
            coverage: s.coverage,
            outline_caches: s.outline_caches,
            ..SplatStyle::default()
        };
        s.apply_plp_budget(&mut self.cut);
        s.apply_epsilon(&mut self.cut);
        let started = Instant::now();
        match draw_frame(
            &mut self.viewer,
            renderer,
            &camera,
            self.refine.threshold(),
            &style,
            &mut self.cut,
            &mut self.rgba,
        ) {
            Ok(times) => {
                // The feedback needs the whole frame, GPU included. In a
                // browser, and on a surface, the draw returns before the
                // GPU is done, so the time between frames is the measure
                // (the draw's own time when that is longer).
                let frame_ms = (started.elapsed().as_secs_f64() * 1e3).max(frame_s * 1e3);
                let missing = self.cut.missing(&self.viewer);
                let cut = CutState {
                    drawn: self.cut.counts().drawn,
                    used_pages: self.cut.touched_pages().len(),
                    missing_pages: missing,
                    root: self.viewer.hierarchy().is_some_and(|h| h.is_resident(0)),
                };
                self.status.threshold = times.threshold_px;
                if let Some(flight) = self.flight.as_mut() {
                    let resident = self
                        .viewer
                        .hierarchy()
                        .map_or(0.0, |h| h.resident_bytes() as f64 / 1e6);
                    flight.record(frame_s * 1e3, self.status.threshold, resident);
                }
                self.refine.after_frame(moving, frame_ms, cut);
                self.status.draw_ms = times.traverse_ms + times.upload_ms + times.draw_ms;
                self.drawn = Some(view);
                self.status.nodes_drawn = cut.drawn;
                self.status.wanted_pages = missing;
            }
            Err(e) => self.status.error = Some(format!("{e:#}")),
        }
        self.show_texture(ui, rect, frame);
        self.draw_measure(ui, rect, &camera, ppp);
        if let Some(spec) = rest_spec
            && self.refine.refined()
            && self.rested_at != Some(spec)
        {
            self.platform.camera_rested(&spec);
            self.rested_at = Some(spec);
        }
    }

    /// Paints the renderer's texture over `rect`, registering it with egui
    /// first when it is new.
    fn show_texture(&mut self, ui: &egui::Ui, rect: Rect, frame: &eframe::Frame) {
        let (Some(renderer), Some(state)) = (self.renderer.as_ref(), frame.wgpu_render_state())
        else {
            return;
        };
        let Some((view, generation)) = renderer.shown_texture() else {
            return;
        };
        // egui's renderer is locked only when the texture is new (a resize).
        let id = match self.texture {
            Some((id, g)) if g == generation => id,
            Some((id, _)) => {
                state
                    .renderer
                    .write()
                    .update_egui_texture_from_wgpu_texture(
                        &state.device,
                        view,
                        wgpu::FilterMode::Nearest,
                        id,
                    );
                id
            }
            None => state.renderer.write().register_native_texture(
                &state.device,
                view,
                wgpu::FilterMode::Nearest,
            ),
        };
        self.texture = Some((id, generation));
        let uv = Rect::from_min_max(pos2(0.0, 0.0), pos2(1.0, 1.0));
        ui.painter().image(id, rect, uv, Color32::WHITE);
    }

    /// The measuring tool's path over the picture: its points and the
    /// lines between them.
    fn draw_measure(
        &self,
        ui: &egui::Ui,
        rect: Rect,
        camera: &farfield_protocol::camera::Camera,
        ppp: f32,
    ) {
        let on_screen: Vec<egui::Pos2> = self
            .measure
            .points
            .iter()
            .filter_map(|&p| crate::measure::project(camera, p))
            .map(|(x, y)| rect.min + egui::vec2(x as f32, y as f32) / ppp)
            .collect();
        let painter = ui.painter_at(rect);
        let stroke = egui::Stroke::new(2.0, Color32::from_rgb(255, 220, 40));
        for pair in on_screen.windows(2) {
            painter.line_segment([pair[0], pair[1]], stroke);
        }
        for &p in &on_screen {
            painter.circle_filled(p, 4.0, stroke.color);
        }
    }

    /// Refreshes the status the panel shows and the platform reads.
    fn update_status(&mut self, dt: f64) {
        let st = &mut self.status;
        // `busy` is still the last frame's: whether it asked for this one.
        self.clock.frame(dt, self.busy);
        st.frame_ms = self.clock.ms();
        st.fps = self.clock.fps();
        st.at_rest = !self.busy;
        st.notice = self.notice.as_ref().map(|(text, _)| text.clone());
        st.measure = self.measure.measured();
        st.measuring = self.measure.on;
        let stats = self.viewer.stats();
        st.mb_received = stats.bytes_received as f64 / 1e6;
        st.in_flight_pages = self.viewer.outstanding();
        st.resident_pages = self.viewer.hierarchy().map_or(0, |h| h.resident_pages());
        st.heights = self
            .viewer
            .header()
            .map(|h| [h.bounds_min.z, h.bounds_max.z]);
        st.resident_mb = self
            .viewer
            .hierarchy()
            .map_or(0.0, |h| h.resident_bytes() as f64 / 1e6);
        // A lost device draws nothing: the view is not refined, whatever
        // the cut says.
        let lost = self.lost.load(std::sync::atomic::Ordering::Relaxed);
        st.progress = self.refine.progress();
        st.refined = self.refine.refined() && !lost;
        st.connection = if !self.viewer.is_streamed() {
            Connection::File
        } else if self.viewer.is_connected() {
            Connection::Connected
        } else if self.viewer.header().is_some() {
            Connection::Reconnecting
        } else {
            Connection::Connecting
        };
        st.last_error = stats.last_error.clone();
        if let Ok(mut e) = self.gpu_error.lock()
            && let Some(e) = e.take()
        {
            st.error = Some(format!("GPU: {e}"));
        }
        if lost && !self.lost_told {
            self.lost_told = true;
            let message = st.error.clone().unwrap_or_default();
            self.platform.device_lost(&message);
        }
        if let Some(rig) = &self.rig {
            st.camera = Some(rig.shown().spec());
        }
        st.demo = self.demo.summary();
    }
}

impl eframe::App for ViewerApp {
    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        let now = Instant::now();
        let frame_s = now.duration_since(self.last_frame).as_secs_f64();
        let dt = frame_s.min(0.25);
        self.last_frame = now;
        self.pump(ui.ctx());
        if let Some(role) = self.options.demo.take() {
            let join = DemoActions {
                join: Some(role),
                ..DemoActions::default()
            };
            self.demo.act(&mut self.viewer, &join);
        }
        self.demo.update(&mut self.viewer);
        if ui.input(|i| i.key_pressed(egui::Key::Tab)) {
            self.show_panel = !self.show_panel;
        }
        let mut screenshot = self.platform.screenshot_asked();
        if self.show_panel {
            let before = self.options.settings.clone();
            let params = self
                .viewer
                .header()
                .map(|h| farfield_traverse::registered_for(h.kind).params);
            let controls = panel::Controls::of(params);
            let action = panel::show(
                ui,
                &self.status,
                controls,
                &mut self.options.settings,
                &mut self.demo,
            );
            self.demo.act(&mut self.viewer, &action.demo);
            let s = &self.options.settings;
            if *s != before {
                self.refine = Refinement::new(s.threshold, s.target_frame_ms, s.node_budget);
                self.viewer.set_cache_bytes(s.cache_bytes());
            }
            screenshot |= action.screenshot;
            self.status.screenshot_button = action
                .screenshot_button
                .map(|r| [r.min.x, r.min.y, r.width(), r.height()]);
            self.status.reset_requested |= action.reset;
            if action.preset.is_some() {
                self.status.preset_requested = action.preset;
            }
            self.status.measure_toggled |= action.measure;
            self.show_panel &= !action.hide;
        } else if ui.input(|i| {
            // The button to bring the panel back shows only while the
            // pointer is near it, so a hidden panel leaves the picture clean.
            i.pointer
                .hover_pos()
                .is_some_and(|p| p.x < 160.0 && p.y < 80.0)
        }) {
            let shown = egui::Area::new(egui::Id::unique("farfield show panel"))
                .fixed_pos(pos2(8.0, 8.0))
                .show(ui.ctx(), |ui| ui.button("☰ panel").clicked())
                .inner;
            self.show_panel |= shown;
        }
        if screenshot && !self.platform.screenshot_itself() {
            self.request_shot(ui.ctx(), Shot::Scene);
        }
        let rect = ui.available_rect_before_wrap();
        self.scene(ui, rect, frame, frame_s, dt);
        self.update_status(frame_s);
        if let Some(message) = self
            .status
            .error
            .clone()
            .or_else(|| self.waiting_message())
            .or_else(|| {
                let (text, since) = self.notice.as_ref()?;
                (since.elapsed() < NOTICE_FOR).then(|| text.clone())
            })
        {
            egui::Area::new(egui::Id::unique("farfield message"))
                .anchor(egui::Align2::CENTER_BOTTOM, Vec2::new(0.0, -16.0))
                .show(ui.ctx(), |ui| {
                    egui::Frame::popup(ui.style()).show(ui, |ui| ui.label(message));
                });
        }
        let shots: Vec<_> = self
            .screenshots
            .lock()
            .map(|mut s| std::mem::take(&mut *s))
            .unwrap_or_default();
        for image in shots {
            let [w, h] = image.size;
            let rgba = image.pixels.iter().flat_map(|c| c.to_array()).collect();
            self.platform.screenshot(w as u32, h as u32, rgba);
        }
        self.platform.status(&self.status);
        if let Some(mut report) = self.flight.as_ref().and_then(Flight::finished) {
            self.flight = None;
            report.adapter = self.status.adapter.clone();
            self.platform.flight_done(&report, ui.ctx());
        }
        let shot = self.platform.wants_screenshot(&self.status);
        self.request_shot(ui.ctx(), shot);
        let capturing = self.take_scene_capture();
        // Keep drawing while anything can still change on screen.
        let busy = !self.status.refined
            || capturing
            || self.flight.is_some()
            || self.viewer.pending_pages() > 0
            || self.rig.as_ref().is_some_and(|r| !r.at_rest());
        self.busy = busy;
        if busy {
            ui.ctx().request_repaint();
        } else if self.viewer.is_streamed() {
            // Nothing changes at rest but the network. Where the session
            // wakes the app, a quiet link needs a look only now and then
            // (its timers: a reconnect, a retry); elsewhere, soon. The
            // scene is not drawn again unless something came.
            let quiet = self.woken
                && self.viewer.is_connected()
                && self.viewer.outstanding() == 0
                && self.options.demo.is_none()
                && self.status.demo.is_none();
            let after = if quiet { 5000 } else { 250 };
            ui.ctx()
                .request_repaint_after(std::time::Duration::from_millis(after));
        } else if let Some((_, since)) = &self.notice
            && let Some(left) = NOTICE_FOR.checked_sub(since.elapsed())
        {
            // A file at rest draws nothing until input comes, but the
            // notice goes when its time is up.
            ui.ctx().request_repaint_after(left);
        }
    }

    #[cfg(target_arch = "wasm32")]
    fn as_any_mut(&mut self) -> Option<&mut dyn std::any::Any> {
        Some(&mut *self)
    }
}

impl ViewerApp {
    /// What to say while there is nothing to see yet, or the server is away.
    fn waiting_message(&self) -> Option<String> {
        match self.status.connection {
            Connection::Connecting => Some(match &self.status.last_error {
                Some(e) => format!("connecting to the server… ({e})"),
                None => "connecting to the server…".into(),
            }),
            Connection::Reconnecting => {
                Some("the server went away: showing what is here, reconnecting…".into())
            }
            _ => None,
        }
    }

    /// Starts a screenshot; it comes to [`Platform::screenshot`] a frame
    /// or two later.
    fn request_shot(&mut self, ctx: &egui::Context, shot: Shot) {
        match shot {
            Shot::None => {}
            Shot::Scene => {
                if let Some(Err(e)) = self.renderer.as_mut().map(Renderer::request_capture) {
                    self.status.error = Some(format!("screenshot: {e:#}"));
                }
            }
            Shot::Window => self.request_window_capture(ctx),
        }
    }

    /// Hands a finished scene capture to the platform; whether one is
    /// still under way (frames keep coming until it is back).
    fn take_scene_capture(&mut self) -> bool {
        let Some(renderer) = self.renderer.as_mut() else {
            return false;
        };
        match renderer.poll_capture() {
            None => renderer.capture_pending(),
            Some(Ok((w, h, mut rgba))) => {
                // The scene's alpha is not the picture's: opaque, as shown.
                rgba.chunks_mut(4).for_each(|p| p[3] = 255);
                self.platform.screenshot(w, h, rgba);
                false
            }
            Some(Err(e)) => {
                self.status.error = Some(format!("screenshot: {e:#}"));
                false
            }
        }
    }

    /// Asks egui for a picture of the next frame, window and all.
    fn request_window_capture(&self, ctx: &egui::Context) {
        let shots = self.screenshots.clone();
        let repaint = ctx.clone();
        ctx.send_viewport_cmd(egui::ViewportCommand::Screenshot(
            egui::ScreenshotCallback::new(move |image| {
                if let Ok(mut s) = shots.lock() {
                    s.push(image);
                }
                repaint.request_repaint();
            }),
        ));
    }

    /// The status the panel shows.
    pub fn status(&self) -> &Status {
        &self.status
    }
}
