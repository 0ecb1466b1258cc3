use farfield_protocol::file::{AttributeFlags, FileHeader, HierarchyKind};
use glam::DVec3;

use super::*;

/// A scene in the unit cube around (10, 20, 30): away from the origin.
fn header() -> FileHeader {
    FileHeader {
        kind: HierarchyKind::Spheres,
        attributes: AttributeFlags::default(),
        node_bytes: 4,
        cluster: 0,
        levels: 1,
        nodes: 1,
        leaves: 1,
        input_vertices: 1,
        bounds_min: DVec3::new(9.5, 19.5, 29.5),
        bounds_max: DVec3::new(10.5, 20.5, 30.5),
        root_center: DVec3::new(10.0, 20.0, 30.0),
        root_radius: 0.9,
        page_count: 1,
        directory_pages: 1,
        root_directory: Default::default(),
    }
}

fn close(a: DVec3, b: DVec3) -> bool {
    (a - b).length() < 1e-9 * a.length().max(1.0)
}

#[test]
fn an_orbit_gives_back_the_eye_and_target_it_was_made_from() {
    let eye = DVec3::new(3.0, -4.0, 2.0);
    let target = DVec3::new(0.5, 0.25, -1.0);
    let o = Orbit::from_eye(eye, target, 50.0);
    assert!(close(o.eye(), eye), "{} vs {eye}", o.eye());
    assert_eq!(o.target, target);
    let c = o.camera(64, 48);
    assert!(close(c.eye, eye) && c.target == target && c.up == DVec3::Z);
}

#[test]
fn fit_to_scene_has_the_whole_scene_in_view() {
    let h = header();
    let o = Orbit::fit(&h, 45.0);
    let (center, radius) = scene_sphere(&h);
    assert_eq!(o.target, center);
    let half = (45.0f64.to_radians() / 2.0).sin();
    assert!(
        o.distance * half >= radius,
        "the sphere fits the vertical field of view"
    );
    assert!(o.distance * half < radius * 1.2, "and fills most of it");
}

#[test]
fn easing_lands_exactly_on_the_goal_at_any_frame_rate() {
    let h = header();
    let start = Orbit::fit(&h, 45.0);
    let mut slow = CameraRig::new(start, &h);
    let mut fast = slow.clone();
    let drag = Input {
        rotate: [120.0, -40.0],
        ..Input::default()
    };
    slow.apply(&drag, false, 480.0, 0.1);
    fast.apply(&drag, false, 480.0, 0.1);
    assert!(!slow.at_rest());
    // 0.1 s as one frame or as ten: the same place.
    slow.ease(0.1);
    for _ in 0..10 {
        fast.ease(0.01);
    }
    assert!(close(slow.shown().eye(), fast.shown().eye()));
    let part = slow.shown().gap(slow.goal());
    assert!(
        part > LANDED && part < start.gap(slow.goal()),
        "part of the way"
    );
    for _ in 0..100 {
        slow.ease(1.0 / 60.0);
    }
    assert!(slow.at_rest());
    assert_eq!(slow.shown(), slow.goal(), "landed exactly");
}

#[test]
fn dragging_orbits_around_the_target_and_stops_short_of_the_poles() {
    let h = header();
    let start = Orbit::fit(&h, 45.0);
    let mut rig = CameraRig::new(start, &h);
    rig.apply(
        &Input {
            rotate: [100.0, 0.0],
            ..Input::default()
        },
        false,
        480.0,
        0.016,
    );
    let g = *rig.goal();
    assert_eq!(g.target, start.target, "orbiting keeps the target");
    assert!((g.distance - start.distance).abs() < 1e-12);
    assert!(
        g.yaw < start.yaw,
        "dragging right turns the eye the other way round"
    );
    rig.apply(
        &Input {
            rotate: [0.0, 1e6],
            ..Input::default()
        },
        false,
        480.0,
        0.016,
    );
    assert!(
        (rig.goal().pitch - MAX_PITCH).abs() < 1e-12,
        "clamped below the pole"
    );
}

#[test]
fn flying_looks_around_the_eye_and_moves_along_the_view() {
    let h = header();
    let start = Orbit::fit(&h, 45.0);
    let mut rig = CameraRig::new(start, &h);
    let eye = start.eye();
    rig.apply(
        &Input {
            rotate: [80.0, 30.0],
            ..Input::default()
        },
        true,
        480.0,
        0.016,
    );
    assert!(close(rig.goal().eye(), eye), "mouse look keeps the eye");
    assert_ne!(rig.goal().target, start.target);
    let before = *rig.goal();
    rig.apply(
        &Input {
            fly: [1.0, 0.0, 0.0],
            ..Input::default()
        },
        true,
        480.0,
        0.5,
    );
    let moved = rig.goal().eye() - before.eye();
    let forward = (before.target - before.eye()).normalize();
    assert!(moved.length() > 0.0);
    assert!(moved.normalize().dot(forward) > 0.999, "W flies forward");
}

#[test]
fn zooming_keeps_the_point_under_the_cursor_in_place() {
    let h = header();
    let start = Orbit::fit(&h, 45.0);
    let mut rig = CameraRig::new(start, &h);
    let (dx, dy, height) = (90.0, -40.0, 480.0);
    let under = start.point_at(dx, dy, height);
    rig.apply(
        &Input {
            zoom: 2.0,
            zoom_at: [dx, dy],
            ..Input::default()
        },
        false,
        height,
        0.016,
    );
    let g = *rig.goal();
    assert!(g.distance < start.distance, "closer");
    // The zoomed camera has the same direction; the point is still at the
    // same offset from the view's centre.
    assert!(close(g.point_at(dx, dy, height), under));
}

#[test]
fn panning_slides_the_target_across_the_view() {
    let h = header();
    let start = Orbit::fit(&h, 45.0);
    let mut rig = CameraRig::new(start, &h);
    rig.apply(
        &Input {
            pan: [50.0, 0.0],
            ..Input::default()
        },
        false,
        480.0,
        0.016,
    );
    let moved = rig.goal().target - start.target;
    let forward = start.target - start.eye();
    assert!(moved.length() > 0.0);
    assert!(moved.dot(forward).abs() < 1e-9 * moved.length() * forward.length());
    assert_eq!(rig.goal().distance, start.distance);
}

#[test]
fn focus_and_reset() {
    let h = header();
    let start = Orbit::fit(&h, 45.0);
    let mut rig = CameraRig::new(start, &h);
    let point = DVec3::new(10.2, 20.1, 30.3);
    let eye = start.eye();
    rig.focus(point);
    assert_eq!(rig.goal().target, point);
    assert!((rig.goal().distance - (point - eye).length() / 3.0).abs() < 1e-9);
    rig.reset();
    assert_eq!(rig.goal(), &start);
}

/// Each preset frames the whole scene (the fit's distance, around its
/// center) from its own side: above, the front (-Y), the left (-X).
#[test]
fn preset_views_look_from_their_side_at_the_whole_scene() {
    let h = header();
    let fit = Orbit::fit(&h, 45.0);
    assert_eq!(Orbit::preset(&h, 45.0, Preset::Fit), fit);
    for (preset, side) in [
        (Preset::Top, DVec3::Z),
        (Preset::Front, -DVec3::Y),
        (Preset::Left, -DVec3::X),
    ] {
        let o = Orbit::preset(&h, 45.0, preset);
        assert_eq!((o.target, o.distance), (fit.target, fit.distance));
        let back = (o.eye() - o.target).normalize();
        assert!(back.dot(side) > 0.999, "{preset:?}: from {back}");
        // The screen's up stays +Z-ward, or (from above) +Y-ward.
        let c = o.camera(64, 48);
        assert!(c.eye.is_finite(), "{preset:?}");
    }
    let top = Orbit::preset(&h, 45.0, Preset::Top);
    let (_, up) = top.axes();
    assert!(up.dot(DVec3::Y) > 0.99, "top view's screen up: {up}");
}
