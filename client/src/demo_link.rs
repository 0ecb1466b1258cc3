//! A viewer's part in a demo session: presenting (its camera shown to the
//! followers) or following (the presenter's camera drawn, until it
//! detaches to look around and attaches again).
//!
//! [`DemoLink`] is the client's state; the [`Viewer`]'s session carries
//! the messages. Every caller (the render command, the viewers' panel, the
//! load test's followers) drives it the same way: [`DemoLink::update`]
//! after each pump, then [`DemoLink::camera`] (following) or
//! [`DemoLink::show`] (presenting).

use farfield_net::DemoEvent;
use farfield_protocol::camera::Camera;
use farfield_protocol::messages::{SessionState, SharedView};
use web_time::Instant;

use crate::viewer::Viewer;

/// One client's membership of a demo session.
#[derive(Debug, Clone)]
pub struct DemoLink {
    pub name: String,
    /// Who is in it, as the server last said.
    pub state: Option<SessionState>,
    /// The presenter's latest view, its number, and when it arrived.
    pub latest: Option<(u64, SharedView, Instant)>,
    /// While following: whether the presenter's view is drawn (`false`:
    /// this viewer looks around on its own).
    pub attached: bool,
    /// Why the session ended, or refused this client.
    pub closed: Option<String>,
    /// The last view shown, so an unchanged camera is not sent again.
    shown: Option<SharedView>,
}

impl DemoLink {
    /// Joins session `name` through `viewer`'s session (now, or once it
    /// connects). `None` for a viewer of a file, which has no server.
    pub fn join(viewer: &mut Viewer, name: &str, present: bool) -> Option<Self> {
        viewer.session_mut()?.join_demo(name, present);
        Some(Self {
            name: name.to_owned(),
            state: None,
            latest: None,
            attached: true,
            closed: None,
            shown: None,
        })
    }

    /// Takes the news the viewer's pumps brought.
    pub fn update(&mut self, viewer: &mut Viewer) {
        for event in viewer.take_demo_events() {
            match event {
                DemoEvent::State(state) if state.session == self.name => {
                    let presenting = state.presenter == Some(state.you);
                    if presenting
                        && !self.is_presenting()
                        && let Some(s) = viewer.session_mut()
                    {
                        // Handed over: rejoin as presenter after a reconnect.
                        s.took_over();
                    }
                    self.state = Some(state);
                    self.closed = None;
                }
                DemoEvent::View { seq, view, arrived } => {
                    self.latest = Some((seq, view, arrived));
                }
                DemoEvent::Closed { session, reason } if session == self.name => {
                    self.closed = Some(reason);
                    self.state = None;
                }
                _ => {}
            }
        }
    }

    /// Whether the server says this client presents.
    pub fn is_presenting(&self) -> bool {
        self.state
            .as_ref()
            .is_some_and(|s| s.presenter == Some(s.you))
    }

    /// The presenter's camera at `width` x `height`, while following and
    /// attached, once a (sane) view has come.
    pub fn camera(&self, width: u32, height: u32) -> Option<Camera> {
        if self.is_presenting() || !self.attached {
            return None;
        }
        camera_of(&self.latest.as_ref()?.1, width, height)
    }

    /// The presenter's options (threshold, kernel, ...), while following.
    pub fn options(&self) -> Option<&[(String, String)]> {
        Some(&self.latest.as_ref()?.1.options)
    }

    /// Shows `camera` and `options` to the followers when presenting and
    /// they changed since the last view shown. The camera's size goes
    /// with them (`size`, `WxH`): the server walks the presenter's view
    /// ahead of its motion at that size.
    pub fn show(
        &mut self,
        viewer: &mut Viewer,
        camera: &Camera,
        mut options: Vec<(String, String)>,
    ) {
        if !self.is_presenting() {
            return;
        }
        if !options.iter().any(|(key, _)| key == "size") {
            options.push(("size".into(), format!("{}x{}", camera.width, camera.height)));
        }
        let view = view_of(camera, options);
        if self.shown.as_ref() == Some(&view) {
            return;
        }
        if let Some(s) = viewer.session_mut() {
            s.show_view(view.clone());
            self.shown = Some(view);
        }
    }

    /// Gives the presenter's seat to member `to`.
    pub fn hand_over(&mut self, viewer: &mut Viewer, to: u64) {
        if let Some(s) = viewer.session_mut() {
            s.hand_over(to);
        }
    }

    /// Leaves the session.
    pub fn leave(self, viewer: &mut Viewer) {
        if let Some(s) = viewer.session_mut() {
            s.leave_demo();
        }
    }
}

/// A camera as a shared view.
pub fn view_of(camera: &Camera, options: Vec<(String, String)>) -> SharedView {
    SharedView {
        eye: camera.eye.to_array(),
        target: camera.target.to_array(),
        up: camera.up.to_array(),
        fov_y_deg: camera.fov_y_deg,
        options,
    }
}

/// A shared view as a camera of `width` x `height`, or `None` for a view
/// no camera can take ([`SharedView::camera`]).
pub fn camera_of(view: &SharedView, width: u32, height: u32) -> Option<Camera> {
    view.camera(width, height)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn views_and_cameras_round_trip_and_bad_views_are_refused() {
        let camera = Camera {
            eye: DVec3::new(1e7, 2.0, 3.0),
            target: DVec3::new(1e7 + 1.0, 2.0, 3.0),
            up: DVec3::Z,
            fov_y_deg: 50.0,
            width: 8,
            height: 6,
        };
        let view = view_of(&camera, vec![("threshold".into(), "2".into())]);
        assert_eq!(camera_of(&view, 8, 6), Some(camera));
        for bad in [
            SharedView {
                eye: [f64::NAN, 0.0, 0.0],
                ..view.clone()
            },
            SharedView {
                target: view.eye,
                ..view.clone()
            },
            SharedView {
                up: [1.0, 0.0, 0.0],
                ..view.clone()
            },
            SharedView {
                fov_y_deg: 0.0,
                ..view.clone()
            },
        ] {
            assert_eq!(camera_of(&bad, 8, 6), None, "{bad:?}");
        }
    }
}
