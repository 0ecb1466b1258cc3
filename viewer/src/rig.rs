//! The viewer's camera: an orbit around a target, moved by input and
//! eased toward where the input put it.
//!
//! Input sets the *goal* ([`CameraRig::goal`]); each frame the shown camera
//! moves a share of the way there that depends only on the time passed
//! (exponential damping), so motion is smooth at any frame rate, and it
//! lands on the goal exactly once close enough: a camera at rest is the
//! goal itself, so a view opened from a link draws what the link says.
//! Orbit and fly are the same state seen from two ends: orbiting turns the
//! eye around the target, flying turns the target around the eye.

use farfield_protocol::camera::Camera;
use farfield_protocol::file::FileHeader;
use glam::DVec3;

use farfield_client::camera_spec::{CameraSpec, scene_sphere};

/// Steepest look up or down, so "up" stays defined (radians, 89 degrees).
const MAX_PITCH: f64 = 89.0 * std::f64::consts::PI / 180.0;
/// Time for the shown camera to cover 63 % of the way to the goal, seconds.
const DAMPING_S: f64 = 0.07;
/// One zoom step (a wheel notch) brings the camera this much closer, in
/// log distance: `exp(-0.15)`, 14 %.
pub const ZOOM_PER_STEP: f64 = 0.15;
/// The shown camera lands on the goal once this close (relative units).
const LANDED: f64 = 1e-4;

/// The views a panel button or a key gives (Potree's and CAD viewers'
/// preset views): the whole scene from above, from the front (-Y), from
/// the left (-X), or from the default direction.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Preset {
    Top,
    Front,
    Left,
    Fit,
}

impl Preset {
    /// Every preset, with its name and key, in the order a panel lists
    /// them (the keys are a numeric keypad's, as in Blender: 7 top, 1
    /// front, 3 the side; 0 fits).
    pub const ALL: [(Preset, &'static str, egui::Key); 4] = [
        (Preset::Top, "top (7)", egui::Key::Num7),
        (Preset::Front, "front (1)", egui::Key::Num1),
        (Preset::Left, "left (3)", egui::Key::Num3),
        (Preset::Fit, "fit (0)", egui::Key::Num0),
    ];
}

/// A camera as an orbit: where it looks, from how far, from which direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Orbit {
    pub target: DVec3,
    /// From the target to the eye, world units (positive).
    pub distance: f64,
    /// Around +Z, radians; 0 looks from +X.
    pub yaw: f64,
    /// Above the XY plane, radians.
    pub pitch: f64,
    pub fov_y_deg: f64,
}

impl Orbit {
    /// The unit vector from the target toward the eye.
    fn back(&self) -> DVec3 {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        DVec3::new(cp * cy, cp * sy, sp)
    }

    pub fn eye(&self) -> DVec3 {
        self.target + self.back() * self.distance
    }

    /// The orbit whose eye and target these are (up is +Z, as for every
    /// farfield camera).
    pub fn from_eye(eye: DVec3, target: DVec3, fov_y_deg: f64) -> Self {
        let offset = eye - target;
        let distance = offset.length().max(f64::MIN_POSITIVE);
        let back = offset / distance;
        Self {
            target,
            distance,
            yaw: back.y.atan2(back.x),
            pitch: back.z.clamp(-1.0, 1.0).asin().clamp(-MAX_PITCH, MAX_PITCH),
            fov_y_deg,
        }
    }

    /// The whole scene in view, from the default direction
    /// ([`CameraSpec::default`]'s azimuth and elevation).
    pub fn fit(header: &FileHeader, fov_y_deg: f64) -> Self {
        let (center, radius) = scene_sphere(header);
        let half_fov = (fov_y_deg.to_radians() * 0.5).clamp(0.01, 1.5);
        let (azimuth, elevation) = match CameraSpec::default() {
            CameraSpec::Orbit {
                azimuth_deg,
                elevation_deg,
                ..
            } => (azimuth_deg, elevation_deg),
            CameraSpec::Eye { .. } => (30.0, 25.0),
        };
        Self {
            target: center,
            distance: radius / half_fov.sin() * 1.05,
            yaw: azimuth.to_radians(),
            pitch: elevation.to_radians(),
            fov_y_deg,
        }
    }

    /// The whole scene in view from `preset`'s direction.
    pub fn preset(header: &FileHeader, fov_y_deg: f64, preset: Preset) -> Self {
        let fit = Self::fit(header, fov_y_deg);
        let quarter = std::f64::consts::FRAC_PI_2;
        let (yaw, pitch) = match preset {
            Preset::Fit => return fit,
            // Looking down, +Y up on screen.
            Preset::Top => (-quarter, MAX_PITCH),
            // From -Y toward +Y, and from -X toward +X.
            Preset::Front => (-quarter, 0.0),
            Preset::Left => (std::f64::consts::PI, 0.0),
        };
        Self { yaw, pitch, ..fit }
    }

    /// The orbit a camera spec resolves to for this scene.
    pub fn from_spec(spec: &CameraSpec, header: &FileHeader) -> Self {
        let c = spec.resolve(header, 1, 1);
        Self::from_eye(c.eye, c.target, c.fov_y_deg)
    }

    pub fn camera(&self, width: u32, height: u32) -> Camera {
        Camera {
            eye: self.eye(),
            target: self.target,
            up: DVec3::Z,
            fov_y_deg: self.fov_y_deg,
            width,
            height,
        }
    }

    /// The spec that reproduces this camera anywhere (a link's).
    pub fn spec(&self) -> CameraSpec {
        CameraSpec::Eye {
            eye: self.eye(),
            target: self.target,
            fov_deg: self.fov_y_deg,
        }
    }

    /// Screen axes in world units: right and up.
    fn axes(&self) -> (DVec3, DVec3) {
        let forward = -self.back();
        let right = forward.cross(DVec3::Z).try_normalize().unwrap_or(DVec3::X);
        (right, right.cross(forward))
    }

    /// World units per pixel at the target's depth, for a view `height` pixels tall.
    fn units_per_px(&self, height: f32) -> f64 {
        let half = (self.fov_y_deg.to_radians() * 0.5).tan();
        2.0 * self.distance * half / f64::from(height.max(1.0))
    }

    /// The point at the target's depth under pixel offset (`dx`, `dy`)
    /// from the view's centre (y down).
    fn point_at(&self, dx: f32, dy: f32, height: f32) -> DVec3 {
        let (right, up) = self.axes();
        let k = self.units_per_px(height);
        self.target + right * (f64::from(dx) * k) - up * (f64::from(dy) * k)
    }

    /// How far apart two orbits are, relative to their size.
    fn gap(&self, other: &Self) -> f64 {
        let scale = self.distance.max(other.distance).max(f64::MIN_POSITIVE);
        ((self.eye() - other.eye()).length() + (self.target - other.target).length()) / scale
            + (self.fov_y_deg - other.fov_y_deg).abs() / 180.0
    }

    /// `self` moved the share `t` of the way to `goal`.
    fn toward(&self, goal: &Self, t: f64) -> Self {
        let lerp = |a: f64, b: f64| a + (b - a) * t;
        // The short way round.
        let mut dyaw = (goal.yaw - self.yaw) % std::f64::consts::TAU;
        if dyaw > std::f64::consts::PI {
            dyaw -= std::f64::consts::TAU;
        } else if dyaw < -std::f64::consts::PI {
            dyaw += std::f64::consts::TAU;
        }
        Self {
            target: self.target.lerp(goal.target, t),
            // Zoom evenly in log space: each frame the same factor.
            distance: (lerp(self.distance.ln(), goal.distance.ln())).exp(),
            yaw: self.yaw + dyaw * t,
            pitch: lerp(self.pitch, goal.pitch),
            fov_y_deg: lerp(self.fov_y_deg, goal.fov_y_deg),
        }
    }
}

/// What the user did this frame, in the viewer's own terms (a front end
/// translates its toolkit's events to this).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Input {
    /// Orbit (or, flying, look) by this drag, pixels.
    pub rotate: [f32; 2],
    /// Pan by this drag, pixels.
    pub pan: [f32; 2],
    /// Zoom steps (wheel notches or pinch, positive is closer) and the
    /// cursor's offset from the view's centre, pixels (y down).
    pub zoom: f32,
    pub zoom_at: [f32; 2],
    /// Fly: forward, right, up, each -1..1, scaled by the time passed.
    pub fly: [f32; 3],
}

/// The viewer's camera: a goal moved by input, and the shown camera eased toward it.
#[derive(Debug, Clone)]
pub struct CameraRig {
    goal: Orbit,
    shown: Orbit,
    home: Orbit,
    /// The scene's radius, which sets the fly speed.
    scene_radius: f64,
}

impl CameraRig {
    /// A rig at `start`, which is also where reset returns to.
    pub fn new(start: Orbit, header: &FileHeader) -> Self {
        Self {
            goal: start,
            shown: start,
            home: start,
            scene_radius: scene_sphere(header).1,
        }
    }

    pub fn goal(&self) -> &Orbit {
        &self.goal
    }

    pub fn shown(&self) -> &Orbit {
        &self.shown
    }

    /// Whether the shown camera is at its goal (nothing left to ease).
    pub fn at_rest(&self) -> bool {
        self.shown == self.goal
    }

    /// Back to where the rig started (fit-to-scene, or the link's view).
    pub fn reset(&mut self) {
        self.goal = self.home;
    }

    /// Eases to `orbit` (a preset view).
    pub fn go_to(&mut self, orbit: Orbit) {
        self.goal = orbit;
    }

    /// Jumps (without easing) to `orbit`, e.g. a link's camera.
    pub fn jump(&mut self, orbit: Orbit) {
        self.goal = orbit;
        self.shown = orbit;
    }

    /// Moves the goal to look at `point` from the current direction, at a
    /// third of the distance (the double-click focus).
    pub fn focus(&mut self, point: DVec3) {
        let eye = self.goal.eye();
        let distance = ((point - eye).length() / 3.0).max(self.scene_radius * 1e-6);
        self.goal = Orbit {
            target: point,
            distance,
            ..self.goal
        };
        let back = (eye - point).try_normalize().unwrap_or(DVec3::Z);
        self.goal.yaw = back.y.atan2(back.x);
        self.goal.pitch = back.z.clamp(-1.0, 1.0).asin().clamp(-MAX_PITCH, MAX_PITCH);
    }

    /// Applies one frame's input to the goal. `flying` turns the view
    /// around the eye instead of the target; `height` is the view's height
    /// in pixels; `dt` the time since the last frame, seconds.
    pub fn apply(&mut self, input: &Input, flying: bool, height: f32, dt: f64) {
        let g = &mut self.goal;
        let per_px = 0.005;
        let [rx, ry] = input.rotate;
        if rx != 0.0 || ry != 0.0 {
            // Dragging right turns the view right; dragging down raises an
            // orbiting eye (the scene tips toward you) and lowers a flying
            // one's gaze: both are the same change of direction.
            let eye = g.eye();
            g.yaw -= f64::from(rx) * per_px;
            g.pitch = (g.pitch + f64::from(ry) * per_px).clamp(-MAX_PITCH, MAX_PITCH);
            if flying {
                // Mouse look: the eye stays, the target swings round it.
                g.target = eye - g.back() * g.distance;
            }
        }
        let [px, py] = input.pan;
        if px != 0.0 || py != 0.0 {
            let moved = g.point_at(px, py, height) - g.target;
            g.target -= moved;
        }
        if input.zoom != 0.0 {
            let factor = (-f64::from(input.zoom) * ZOOM_PER_STEP).exp();
            let cursor = g.point_at(input.zoom_at[0], input.zoom_at[1], height);
            // The point under the cursor stays under it.
            g.target = cursor + (g.target - cursor) * factor;
            g.distance = (g.distance * factor).max(self.scene_radius * 1e-6);
        }
        let [f, r, u] = input.fly.map(f64::from);
        if f != 0.0 || r != 0.0 || u != 0.0 {
            let (right, _) = g.axes();
            let forward = -g.back();
            let speed = self.scene_radius.max(g.distance * 0.5) * dt;
            g.target += (forward * f + right * r + DVec3::Z * u) * speed;
        }
    }

    /// Eases the shown camera toward the goal for `dt` seconds.
    pub fn ease(&mut self, dt: f64) {
        let t = 1.0 - (-dt.max(0.0) / DAMPING_S).exp();
        let next = self.shown.toward(&self.goal, t);
        self.shown = if next.gap(&self.goal) < LANDED {
            self.goal
        } else {
            next
        };
    }
}

#[cfg(test)]
#[path = "rig_tests.rs"]
mod tests;
