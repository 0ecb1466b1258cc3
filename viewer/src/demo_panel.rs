//! The viewer's demo session: the panel's part (make or join a session,
//! follow or look around, hand over, leave) and what it does to the
//! camera each frame (a follower jumps to the presenter's view; a
//! presenter shows its own).

use farfield_client::demo_link::DemoLink;
use farfield_client::render_job::DemoRole;
use farfield_client::viewer::Viewer;
use farfield_protocol::camera::Camera;

use crate::rig::{CameraRig, Orbit};

/// The viewer's demo session, if any, and the panel's name field.
#[derive(Debug, Default)]
pub struct Demo {
    /// The session joined (or being joined).
    pub link: Option<DemoLink>,
    /// The name typed into the panel.
    pub name: String,
    /// The presenter's view last jumped to, so an unchanged one is not
    /// jumped to again (the user may be easing nothing).
    applied: Option<u64>,
}

/// What the panel's session buttons asked for.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct DemoActions {
    pub join: Option<DemoRole>,
    pub leave: bool,
    pub hand_over: Option<u64>,
    /// Follow the presenter again after looking around.
    pub attach: bool,
}

impl Demo {
    /// Starts in `role`'s session (from the command line or the page's address).
    pub fn starting(role: Option<&DemoRole>) -> Self {
        Self {
            name: role.map(|r| r.session.clone()).unwrap_or_default(),
            ..Self::default()
        }
    }

    /// Applies the panel's buttons.
    pub fn act(&mut self, viewer: &mut Viewer, actions: &DemoActions) {
        if let Some(role) = &actions.join {
            if let Some(old) = self.link.take() {
                old.leave(viewer);
            }
            self.link = DemoLink::join(viewer, &role.session, role.present);
            self.applied = None;
        }
        if actions.leave
            && let Some(link) = self.link.take()
        {
            link.leave(viewer);
        }
        if let (Some(to), Some(link)) = (actions.hand_over, self.link.as_mut()) {
            link.hand_over(viewer, to);
        }
        if actions.attach
            && let Some(link) = self.link.as_mut()
        {
            link.attached = true;
            self.applied = None;
        }
    }

    /// Takes the session's news (after each pump).
    pub fn update(&mut self, viewer: &mut Viewer) {
        if let Some(link) = self.link.as_mut() {
            link.update(viewer);
        }
    }

    /// A follower's camera for this frame: the user moving it detaches
    /// (looks around); attached, a new view of the presenter's is jumped to.
    pub fn steer(&mut self, rig: &mut CameraRig, user_moved: bool) {
        let Some(link) = self.link.as_mut() else {
            return;
        };
        if link.is_presenting() || link.state.is_none() {
            return;
        }
        if user_moved && link.attached {
            link.attached = false;
        }
        let Some((seq, ..)) = link.latest else {
            return;
        };
        if !link.attached || self.applied == Some(seq) {
            return;
        }
        // Size does not matter for the eye, target and field of view.
        if let Some(camera) = link.camera(1, 1) {
            rig.jump(Orbit::from_eye(camera.eye, camera.target, camera.fov_y_deg));
            self.applied = Some(seq);
        }
    }

    /// A presenter shows the frame's camera and drawing options.
    pub fn present(
        &mut self,
        viewer: &mut Viewer,
        camera: &Camera,
        options: Vec<(String, String)>,
    ) {
        if let Some(link) = self.link.as_mut() {
            link.show(viewer, camera, options);
        }
    }

    /// One line for the panel and the page's status.
    pub fn summary(&self) -> Option<String> {
        let link = self.link.as_ref()?;
        if let Some(reason) = &link.closed {
            return Some(format!("session {}: {reason}", link.name));
        }
        let Some(state) = &link.state else {
            return Some(format!("joining session {}…", link.name));
        };
        let role = if link.is_presenting() {
            "presenting".to_owned()
        } else if link.attached {
            "following".to_owned()
        } else {
            "looking around".to_owned()
        };
        let presenter = match (state.presenter_connected, state.closes_in_s) {
            (true, _) => "presenter here".to_owned(),
            (false, Some(s)) => format!("presenter away, closes in {s:.0} s"),
            (false, None) => "no presenter".to_owned(),
        };
        Some(format!(
            "{role} {} (member {}); {presenter}; {} following",
            link.name, state.you, state.follower_count
        ))
    }

    /// The session part of the panel.
    pub fn panel(&mut self, ui: &mut egui::Ui) -> DemoActions {
        let mut actions = DemoActions::default();
        ui.label("demo session");
        match self.link.as_ref() {
            None => {
                ui.horizontal(|ui| {
                    ui.add(egui::TextEdit::singleline(&mut self.name).desired_width(90.0));
                    let named = !self.name.trim().is_empty();
                    let role = |present| DemoRole {
                        session: self.name.trim().to_owned(),
                        present,
                    };
                    if ui
                        .add_enabled(named, egui::Button::new("present"))
                        .clicked()
                    {
                        actions.join = Some(role(true));
                    }
                    if ui.add_enabled(named, egui::Button::new("follow")).clicked() {
                        actions.join = Some(role(false));
                    }
                });
            }
            Some(link) => {
                if let Some(line) = self.summary() {
                    ui.small(line);
                }
                ui.horizontal(|ui| {
                    if !link.is_presenting()
                        && !link.attached
                        && ui.button("follow again").clicked()
                    {
                        actions.attach = true;
                    }
                    if ui.button("leave").clicked() {
                        actions.leave = true;
                    }
                });
                if link.is_presenting()
                    && let Some(state) = &link.state
                    && !state.followers.is_empty()
                {
                    ui.horizontal_wrapped(|ui| {
                        ui.label("hand over to");
                        for &f in &state.followers {
                            if ui.small_button(f.to_string()).clicked() {
                                actions.hand_over = Some(f);
                            }
                        }
                    });
                }
            }
        }
        actions
    }
}
