//! The panel: what the view is doing, and the settings a user changes
//! while looking (rerun's and Potree's side panels are the model).

use farfield_render::{Coverage, Kernel};

use crate::status::Status;

/// The user's settings.
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// The threshold a resting view refines to: pixels (spheres) or eps (cubes).
    pub threshold: f64,
    pub kernel: Kernel,
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
}

impl Default for Settings {
    /// `farfield render`'s defaults, so both draw the same picture.
    fn default() -> Self {
        Self {
            threshold: 1.0,
            kernel: Kernel::Square,
            coverage: Coverage::Alpha,
            node_budget: 0,
            target_frame_ms: 33.0,
            cache_mib: 512,
            plp_budget_percent: 100.0,
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

    pub fn cache_bytes(&self) -> usize {
        usize::try_from(self.cache_mib.saturating_mul(1 << 20)).unwrap_or(usize::MAX)
    }
}

/// What the panel's buttons asked for this frame.
#[derive(Debug, Clone, Copy, Default)]
pub struct Actions {
    pub screenshot: bool,
    pub reset: bool,
    pub hide: bool,
}

/// Shows the panel on the left of `ui`.
pub fn show(ui: &mut egui::Ui, status: &Status, settings: &mut Settings) -> Actions {
    let mut actions = Actions::default();
    egui::Panel::left("farfield panel")
        .resizable(false)
        .show(ui, |ui| {
            ui.heading("farfield");
            egui::Grid::new("stats").num_columns(2).show(ui, |ui| {
                let mut row = |name: &str, value: String| {
                    ui.label(name);
                    ui.monospace(value);
                    ui.end_row();
                };
                row("frame", format!("{:.1} ms, {:.0} fps", status.frame_ms, status.fps));
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
            ui.separator();
            ui.horizontal(|ui| {
                ui.label("splats");
                ui.selectable_value(&mut settings.kernel, Kernel::Square, "square");
                ui.selectable_value(&mut settings.kernel, Kernel::Round, "round");
            });
            ui.add(
                egui::Slider::new(&mut settings.threshold, 0.0..=16.0)
                    .text("threshold / eps (px)"),
            );
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
            ui.add(
                egui::Slider::new(&mut settings.node_budget, 0..=20_000_000)
                    .logarithmic(true)
                    .text("node budget (0: none)"),
            );
            ui.add(
                egui::Slider::new(&mut settings.plp_budget_percent, 0.0..=100.0)
                    .logarithmic(true)
                    .text("PLP budget (% of triangles)"),
            );
            ui.add(
                egui::Slider::new(&mut settings.target_frame_ms, 8.0..=200.0)
                    .text("target frame (ms)"),
            );
            ui.add(
                egui::Slider::new(&mut settings.cache_mib, 16..=8192)
                    .logarithmic(true)
                    .text("memory (MiB)"),
            );
            ui.separator();
            ui.horizontal(|ui| {
                actions.reset = ui.button("reset (R)").clicked();
                actions.screenshot = ui.button("screenshot").clicked();
                actions.hide = ui.button("hide (Tab)").clicked();
            });
            ui.small("drag: orbit · right/shift drag: pan · wheel: zoom · F: fly (WASD, QE) · double-click: focus");
        });
    actions
}
