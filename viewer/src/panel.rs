//! The panel: what the view is doing, and the settings a user changes
//! while looking (rerun's and Potree's side panels are the model).

use farfield_render::{Clip, ColorBy, Coverage, Edl, Keep, Kernel};

use crate::status::Status;

/// The user's settings.
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// The threshold a resting view refines to: pixels (spheres) or eps (cubes).
    pub threshold: f64,
    pub kernel: Kernel,
    /// Eye-dome lighting over splats (Potree's shading of point clouds),
    /// or none.
    pub edl: Option<Edl>,
    /// What colors splats: their RGB, or their height on a ramp.
    pub color_by: ColorBy,
    /// The clipping box (fractions of the scene's bounds), or none.
    pub clip: Option<Clip>,
    /// Cube hierarchies: how face coverage is used.
    pub coverage: Coverage,
    /// Most nodes a frame draws (Potree's point budget); 0 is none.
    pub node_budget: u64,
    /// The frame time the moving camera aims for, milliseconds.
    pub target_frame_ms: f64,
    /// Resident pages kept, MiB.
    pub cache_mib: u64,
    /// PLP files: the share of the scene's triangles a frame may draw,
    /// percent (100: all).
    pub plp_budget_percent: f64,
    /// PLP files: a frame time to hold instead, milliseconds (0: off). The
    /// paper's time-critical mode: the triangle budget follows the draw
    /// rate measured on the frames before.
    pub plp_budget_ms: f64,
    /// Image caching (BSP files): the error bound ε of a cached image,
    /// pixels. It is held on every frame (not refined): a cache made at
    /// one ε is valid only within that ε's safety zone.
    pub epsilon_px: f64,
    /// Image caching: outline each cached image on screen.
    pub outline_caches: bool,
}

impl Default for Settings {
    /// `farfield render`'s defaults, so both draw the same picture.
    fn default() -> Self {
        Self {
            threshold: 1.0,
            kernel: Kernel::Square,
            edl: None,
            color_by: ColorBy::Rgb,
            clip: None,
            coverage: Coverage::Alpha,
            node_budget: 0,
            target_frame_ms: 33.0,
            cache_mib: 512,
            plp_budget_percent: 100.0,
            plp_budget_ms: 0.0,
            epsilon_px: 1.0,
            outline_caches: false,
        }
    }
}

impl Settings {
    /// The PLP budget the slider gives.
    pub fn plp_budget(&self) -> farfield_traverse::Budget {
        if self.plp_budget_percent >= 100.0 {
            farfield_traverse::Budget::Unlimited
        } else {
            farfield_traverse::Budget::Percent(self.plp_budget_percent.max(0.0))
        }
    }

    /// Sets the frame loop's PLP budget: the slider's share, or the frame
    /// time when one is set. The measured draw rate is kept while the
    /// frame time stays the same (a fresh one would start from a guess).
    pub fn apply_plp_budget(&self, cut: &mut farfield_client::frame_loop::FrameState) {
        cut.budget = self.plp_budget();
        let ms = self.plp_budget_ms;
        cut.time_budget = if ms.is_finite() && ms > 0.0 {
            match cut.time_budget {
                Some(kept) if kept.target_ms == ms => Some(kept),
                _ => Some(farfield_client::budget::TimeBudget::new(ms)),
            }
        } else {
            None
        };
    }

    /// Sets the frame loop's image-caching ε: the kinds whose threshold is
    /// an error bound they hold (image caching) draw at it on every frame;
    /// the others keep refining. A bad value falls back to the default.
    pub fn apply_epsilon(&self, cut: &mut farfield_client::frame_loop::FrameState) {
        let eps = self.epsilon_px;
        cut.final_threshold = Some(if eps.is_finite() && eps >= 0.0 {
            eps
        } else {
            Settings::default().epsilon_px
        });
    }

    pub fn cache_bytes(&self) -> usize {
        usize::try_from(self.cache_mib.saturating_mul(1 << 20)).unwrap_or(usize::MAX)
    }
}

/// What the panel's buttons asked for this frame.
#[derive(Debug, Clone, Default)]
pub struct Actions {
    pub screenshot: bool,
    pub reset: bool,
    pub hide: bool,
    pub demo: crate::demo_panel::DemoActions,
    /// Where the panel is on screen, and its row of buttons (scrolled
    /// with it).
    pub panel: Option<egui::Rect>,
    pub buttons: Option<egui::Rect>,
    /// Where the panel's last line is (scrolled into reach, or not).
    pub end: Option<egui::Rect>,
    /// Where the screenshot button is on screen.
    pub screenshot_button: Option<egui::Rect>,
    /// A preset view asked for.
    pub preset: Option<crate::rig::Preset>,
    /// The measuring tool turned on or off.
    pub measure: bool,
}

/// Which of the panel's controls a scene's kind reads, from the settings
/// its traversal names (`farfield_traverse::Registered::params`); `None`
/// (no scene yet) shows none of them.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Controls {
    /// Square or round splats.
    pub kernel: bool,
    /// The threshold (splat size, or the cubes' eps).
    pub threshold: bool,
    /// The cubes' coverage.
    pub coverage: bool,
    /// PLP's budgets.
    pub plp: bool,
    /// Image caching's ε and outlines.
    pub epsilon: bool,
}

impl Controls {
    pub fn of(params: Option<&[&str]>) -> Self {
        let has = |name: &str| params.is_some_and(|p| p.contains(&name));
        Self {
            kernel: has("kernel"),
            threshold: has("threshold") || has("eps"),
            coverage: has("coverage"),
            plp: has("budget"),
            epsilon: has("epsilon"),
        }
    }
}

/// The widest the panel gets: a share of a narrow screen (a phone's),
/// so the scene stays in view beside it.
fn panel_width(screen_width: f32) -> f32 {
    (screen_width * 0.6).min(340.0)
}

/// Shows the panel on the left of `ui`: the status, then the settings
/// `controls` names and the demo session, each folding, all scrolling when
/// the window is too short for them.
pub fn show(
    ui: &mut egui::Ui,
    status: &Status,
    controls: Controls,
    settings: &mut Settings,
    demo: &mut crate::demo_panel::Demo,
) -> Actions {
    let mut actions = Actions::default();
    let width = panel_width(ui.available_width());
    let shown = egui::Panel::left("farfield panel")
        .resizable(false)
        .exact_size(width)
        .show(ui, |ui| {
            egui::ScrollArea::both()
                .auto_shrink([false, false])
                .show(ui, |ui| {
                    ui.heading("farfield");
                    stats(ui, status);
                    ui.separator();
                    // The buttons and tools first, where a short window
                    // shows them without scrolling; the settings after.
                    let row = ui.horizontal_wrapped(|ui| {
                        actions.reset = ui.button("reset (R)").clicked();
                        let screenshot = ui.button("screenshot");
                        actions.screenshot_button = Some(screenshot.rect);
                        actions.screenshot = screenshot.clicked();
                        actions.hide = ui.button("hide (Tab)").clicked();
                    });
                    actions.buttons = Some(row.response.rect);
                    ui.horizontal_wrapped(|ui| {
                        for (preset, name, _) in crate::rig::Preset::ALL {
                            if ui.button(name).clicked() {
                                actions.preset = Some(preset);
                            }
                        }
                    });
                    measure_ui(ui, status, &mut actions);
                    ui.separator();
                    egui::CollapsingHeader::new("view")
                        .default_open(true)
                        .show(ui, |ui| settings_ui(ui, controls, settings, status.heights));
                    egui::CollapsingHeader::new("demo")
                        .default_open(true)
                        .show(ui, |ui| actions.demo = demo.panel(ui));
                    let hint = ui.small("drag: orbit · right/shift drag: pan · wheel: zoom · F: fly (WASD, QE) · double-click: focus · M: measure");
                    actions.end = Some(hint.rect);
                });
        });
    actions.panel = Some(shown.response.rect);
    actions
}

/// The status lines and the progress bar.
fn stats(ui: &mut egui::Ui, status: &Status) {
    egui::Grid::new("stats").num_columns(2).show(ui, |ui| {
        let mut row = |name: &str, value: String| {
            ui.label(name);
            ui.monospace(value);
            ui.end_row();
        };
        row("frame", crate::status::frame_line(status));
        row("scene draw", format!("{:.1} ms", status.draw_ms));
        row("threshold", format!("{:.3}", status.threshold));
        row("nodes drawn", status.nodes_drawn.to_string());
        row(
            "pages resident",
            format!("{} ({:.1} MB)", status.resident_pages, status.resident_mb),
        );
        row("in flight", status.in_flight_pages.to_string());
        row("wanted", status.wanted_pages.to_string());
        row("received", format!("{:.1} MB", status.mb_received));
        row("server", status.connection.label().to_owned());
    });
    let label = if status.refined {
        "refined".to_owned()
    } else {
        format!("refining {:.1} %", status.progress * 100.0)
    };
    ui.add(egui::ProgressBar::new(status.progress as f32).text(label));
    if let Some(e) = &status.last_error {
        ui.small(format!("last error: {e}"));
    }
}

/// The clipping box: off, or which side is drawn, and its extent on each
/// axis as shares of the scene's bounds.
fn clip_ui(ui: &mut egui::Ui, clip: &mut Option<Clip>) {
    ui.horizontal(|ui| {
        ui.label("clip");
        let keep = clip.map(|c| c.keep);
        if ui.selectable_label(keep.is_none(), "off").clicked() {
            *clip = None;
        }
        for (side, name) in [(Keep::Inside, "inside"), (Keep::Outside, "outside")] {
            if ui.selectable_label(keep == Some(side), name).clicked() {
                let whole = Clip::fractions(glam::DVec3::ZERO, glam::DVec3::ONE, side);
                *clip = Some(Clip {
                    keep: side,
                    ..clip.unwrap_or(whole)
                });
            }
        }
    });
    if let Some(c) = clip {
        for (axis, name) in ["x", "y", "z"].into_iter().enumerate() {
            ui.horizontal(|ui| {
                ui.label(name);
                ui.add(egui::Slider::new(&mut c.lo[axis], 0.0..=1.0).show_value(false));
                ui.add(egui::Slider::new(&mut c.hi[axis], 0.0..=1.0).show_value(false));
            });
        }
        *c = Clip::fractions(c.lo, c.hi, c.keep);
    }
}

/// The measuring tool's switch, and what its points measure (in the
/// scene's units).
fn measure_ui(ui: &mut egui::Ui, status: &Status, actions: &mut Actions) {
    ui.horizontal_wrapped(|ui| {
        let label = if status.measuring {
            "stop measuring (M)"
        } else {
            "measure (M)"
        };
        actions.measure = ui.button(label).clicked();
        if status.measuring && status.measure.is_none() {
            ui.small("click points");
        }
    });
    if let Some(m) = &status.measure {
        ui.small(format!(
            "{} points · distance {:.3} · height {:+.3}",
            m.points.len(),
            m.distance,
            m.height
        ));
        if let Some(area) = m.area {
            ui.small(format!("area {area:.3} (closed)"));
        }
    }
}

/// What colors splats, and the elevation ramp's legend (its colors from
/// the lowest height of the scene to the highest) when it is chosen.
fn color_ui(ui: &mut egui::Ui, color_by: &mut ColorBy, heights: Option<[f64; 2]>) {
    ui.horizontal(|ui| {
        ui.label("colour");
        for mode in ColorBy::ALL {
            let on = color_by.name() == mode.name();
            if ui.selectable_label(on, mode.name()).clicked() {
                *color_by = mode;
            }
        }
    });
    if !matches!(color_by, ColorBy::Elevation(_)) {
        return;
    }
    let (rect, _) =
        ui.allocate_exact_size(egui::vec2(ui.available_width(), 12.0), egui::Sense::hover());
    let stops = farfield_render::RAMP.len();
    let step = rect.width() / stops as f32;
    for (i, [r, g, b]) in farfield_render::RAMP.into_iter().enumerate() {
        let left = rect.left() + step * i as f32;
        let cell = egui::Rect::from_min_max(
            egui::pos2(left, rect.top()),
            egui::pos2(left + step, rect.bottom()),
        );
        ui.painter()
            .rect_filled(cell, 0.0, egui::Color32::from_rgb(r, g, b));
    }
    if let Some([low, high]) = heights {
        ui.horizontal(|ui| {
            ui.small(format!("{low:.2}"));
            ui.with_layout(egui::Layout::right_to_left(egui::Align::Center), |ui| {
                ui.small(format!("{high:.2} (height)"));
            });
        });
    }
}

/// Eye-dome lighting on or off, and its strength and radius when on.
fn edl_ui(ui: &mut egui::Ui, edl: &mut Option<Edl>) {
    let mut on = edl.is_some();
    if ui.checkbox(&mut on, "eye-dome lighting").changed() {
        *edl = on.then(Edl::default);
    }
    if let Some(edl) = edl {
        ui.add(egui::Slider::new(&mut edl.strength, 0.0..=5.0).text("EDL strength"));
        ui.add(egui::Slider::new(&mut edl.radius_px, 0.5..=4.0).text("EDL radius (px)"));
    }
}

/// The settings the scene's kind reads, then those every kind has.
fn settings_ui(
    ui: &mut egui::Ui,
    controls: Controls,
    settings: &mut Settings,
    status_heights: Option<[f64; 2]>,
) {
    if controls.kernel {
        ui.horizontal(|ui| {
            ui.label("splats");
            for kernel in Kernel::ALL {
                ui.selectable_value(&mut settings.kernel, kernel, kernel.name());
            }
        });
        edl_ui(ui, &mut settings.edl);
        color_ui(ui, &mut settings.color_by, status_heights);
        clip_ui(ui, &mut settings.clip);
    }
    if controls.threshold {
        ui.add(egui::Slider::new(&mut settings.threshold, 0.0..=16.0).text("threshold / eps (px)"));
    }
    if controls.coverage {
        ui.horizontal(|ui| {
            ui.label("cube coverage");
            let alpha = matches!(settings.coverage, Coverage::Alpha);
            if ui.selectable_label(alpha, "alpha").clicked() {
                settings.coverage = Coverage::Alpha;
            }
            if ui.selectable_label(!alpha, "threshold").clicked() && alpha {
                settings.coverage = Coverage::Threshold(0.5);
            }
        });
        if let Coverage::Threshold(t) = &mut settings.coverage {
            ui.add(egui::Slider::new(t, 0.0..=1.0).text("coverage threshold"));
        }
    }
    if controls.plp {
        ui.add(
            egui::Slider::new(&mut settings.plp_budget_percent, 0.0..=100.0)
                .logarithmic(true)
                .text("PLP budget (% of triangles)"),
        );
        ui.add(
            egui::Slider::new(&mut settings.plp_budget_ms, 0.0..=200.0)
                .text("PLP frame time (ms, 0: off)"),
        );
    }
    if controls.epsilon {
        ui.add(egui::Slider::new(&mut settings.epsilon_px, 0.0..=16.0).text("image caches ε (px)"));
        ui.checkbox(&mut settings.outline_caches, "outlines");
    }
    ui.add(
        egui::Slider::new(&mut settings.node_budget, 0..=20_000_000)
            .logarithmic(true)
            .text("node budget (0: none)"),
    );
    ui.add(egui::Slider::new(&mut settings.target_frame_ms, 8.0..=200.0).text("target frame (ms)"));
    ui.add(
        egui::Slider::new(&mut settings.cache_mib, 16..=8192)
            .logarithmic(true)
            .text("memory (MiB)"),
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The panel in a headless egui of `width` x `height` points, after
    /// `frames` frames with the mouse wheel turned down over it in each.
    fn shown(width: f32, height: f32, frames: usize, wheel: f32) -> Actions {
        let ctx = egui::Context::default();
        let mut settings = Settings::default();
        let mut demo = crate::demo_panel::Demo::starting(None);
        let controls = Controls::of(Some(&["threshold", "kernel"]));
        let mut last = Actions::default();
        for frame in 0..frames {
            let mut input = egui::RawInput {
                screen_rect: Some(egui::Rect::from_min_size(
                    egui::Pos2::ZERO,
                    egui::vec2(width, height),
                )),
                predicted_dt: 1.0 / 30.0,
                time: Some(frame as f64 / 30.0),
                ..Default::default()
            };
            input
                .events
                .push(egui::Event::PointerMoved(egui::pos2(40.0, height / 2.0)));
            if wheel != 0.0 {
                input.events.push(egui::Event::MouseWheel {
                    unit: egui::MouseWheelUnit::Point,
                    delta: egui::vec2(0.0, -wheel),
                    phase: egui::TouchPhase::Move,
                    modifiers: egui::Modifiers::NONE,
                    source: egui::MouseWheelSource::Unknown,
                });
            }
            let mut output = ctx.run_ui(input, |ui| {
                last = show(ui, &Status::default(), controls, &mut settings, &mut demo);
            });
            // Nothing paints here: the font atlas's upload is dropped.
            output.textures_delta.clear();
        }
        last
    }

    #[test]
    fn the_panel_leaves_a_phone_most_of_its_screen() {
        let phone = shown(390.0, 844.0, 2, 0.0);
        let width = phone.panel.unwrap().width();
        assert!(
            width <= 0.62 * 390.0,
            "the panel is {width} of 390 points wide"
        );
        let desktop = shown(1280.0, 800.0, 2, 0.0).panel.unwrap().width();
        assert!(desktop >= 300.0, "{desktop}");
    }

    #[test]
    fn a_short_window_shows_the_buttons_and_scrolls_to_the_panel_s_end() {
        let height = 450.0;
        let unscrolled = shown(800.0, height, 3, 0.0);
        let buttons = unscrolled.buttons.unwrap();
        assert!(
            buttons.bottom() <= height,
            "the buttons are out of reach unscrolled: {buttons:?} in a window {height} high"
        );
        let end = unscrolled.end.unwrap();
        assert!(
            end.top() > height,
            "the test needs a panel taller than the window: its end at {end:?}"
        );
        let scrolled = shown(800.0, height, 60, 400.0).end.unwrap();
        assert!(
            scrolled.bottom() <= height && scrolled.top() >= 0.0,
            "the panel's end is out of reach: {scrolled:?} in a window {height} high"
        );
    }

    #[test]
    fn each_kind_shows_the_controls_it_reads() {
        let spheres = Controls::of(Some(&["threshold", "kernel"]));
        assert!(spheres.kernel && spheres.threshold);
        assert!(!spheres.coverage && !spheres.plp && !spheres.epsilon);
        let cubes = Controls::of(Some(&["eps", "coverage"]));
        assert!(cubes.threshold && cubes.coverage && !cubes.kernel && !cubes.plp);
        assert_eq!(
            Controls::of(Some(&["budget"])),
            Controls {
                plp: true,
                ..Controls::default()
            }
        );
        assert_eq!(
            Controls::of(Some(&["epsilon"])),
            Controls {
                epsilon: true,
                ..Controls::default()
            }
        );
        assert_eq!(Controls::of(None), Controls::default());
        // Every kind the client draws shows at least one of its own.
        for kind in farfield_traverse::KINDS {
            assert_ne!(
                Controls::of(Some(kind.params)),
                Controls::default(),
                "{}",
                kind.name
            );
        }
    }
    use farfield_client::frame_loop::FrameState;
    use farfield_traverse::Budget;

    #[test]
    fn the_epsilon_control_sets_the_bound_image_caching_holds() {
        let mut cut = FrameState::default();
        let mut s = Settings {
            epsilon_px: 4.0,
            ..Settings::default()
        };
        s.apply_epsilon(&mut cut);
        assert_eq!(cut.final_threshold, Some(4.0));
        s.epsilon_px = 0.0;
        s.apply_epsilon(&mut cut);
        assert_eq!(cut.final_threshold, Some(0.0), "0: never cache");
        for bad in [f64::NAN, -1.0, f64::INFINITY] {
            s.epsilon_px = bad;
            s.apply_epsilon(&mut cut);
            assert_eq!(
                cut.final_threshold,
                Some(Settings::default().epsilon_px),
                "{bad}"
            );
        }
    }

    #[test]
    fn the_plp_controls_set_the_frame_loops_budget() {
        let mut cut = FrameState::default();
        let mut s = Settings {
            plp_budget_percent: 5.0,
            ..Settings::default()
        };
        s.apply_plp_budget(&mut cut);
        assert_eq!(cut.budget, Budget::Percent(5.0));
        assert!(cut.time_budget.is_none());
        s.plp_budget_percent = 100.0;
        s.apply_plp_budget(&mut cut);
        assert_eq!(cut.budget, Budget::Unlimited);

        // A frame time: it learns a rate, keeps it while the target holds,
        // starts again when the target moves, and 0 turns it off.
        s.plp_budget_ms = 20.0;
        s.apply_plp_budget(&mut cut);
        let mut learned = cut.time_budget.expect("a time budget");
        let first_guess = learned.budget();
        learned.observe(1000, 12.0, 2.0);
        cut.time_budget = Some(learned);
        s.apply_plp_budget(&mut cut);
        // 0.01 ms a triangle: 20 ms hold at most 2000 of them, and at
        // least 1800 beside the 2 ms that do not grow with the count.
        let kept = cut.time_budget.expect("kept");
        let Budget::Triangles(n) = kept.budget() else {
            panic!("a time budget is a count");
        };
        assert!((1800..=2000).contains(&n), "{n}");
        assert_ne!(kept.budget(), first_guess);
        s.plp_budget_ms = 40.0;
        s.apply_plp_budget(&mut cut);
        let fresh = cut.time_budget.expect("a new one");
        assert_eq!((fresh.target_ms, fresh.budget()), (40.0, first_guess));
        for off in [0.0, f64::NAN, -3.0] {
            s.plp_budget_ms = off;
            s.apply_plp_budget(&mut cut);
            assert!(cut.time_budget.is_none(), "{off}");
        }
    }
}
