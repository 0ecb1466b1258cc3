//! The renderer drawing into a real window's surface (an X11 window on a
//! private Xvfb display): frames are presented and never read back.
//!
//! The test starts Xvfb (or, without it, uses the desktop's X display) and
//! re-runs this test binary on [`draw_into_a_window_child`] with `DISPLAY`
//! pointing at it (a test must not change its own process's environment).
//! With neither it fails and says what to install, unless
//! `FARFIELD_ALLOW_NO_GPU=1` lets GPU tests skip.

use std::sync::Arc;

use farfield_protocol::camera::Camera;
use farfield_render::{ALLOW_NO_GPU_ENV, Renderer, SplatStyle};
use farfield_traverse::spheres::Splat;
use glam::DVec3;

use crate::xvfb::start_xvfb;

/// Tells [`draw_into_a_window_child`] that it runs as the child.
const CHILD_ENV: &str = "FARFIELD_SURFACE_CHILD";
const SIZE: (u32, u32) = (96, 64);

#[test]
fn a_window_surface_is_drawn_and_presented_without_a_readback() {
    // A private Xvfb, or else the desktop's own X display.
    let xvfb = start_xvfb();
    let display = xvfb
        .as_ref()
        .map(|x| x.display().to_owned())
        .or_else(|| std::env::var("DISPLAY").ok().filter(|d| !d.is_empty()));
    let Some(display) = display else {
        let allowed = std::env::var(ALLOW_NO_GPU_ENV).is_ok_and(|v| v.trim() == "1");
        assert!(
            allowed,
            "the surface test needs Xvfb (apt-get install xvfb) or an X display; \
             {ALLOW_NO_GPU_ENV}=1 skips it"
        );
        eprintln!("skipping the surface test: no Xvfb and no X display");
        return;
    };
    let output = farfield_tests::child_test("surface::draw_into_a_window_child")
        .env(CHILD_ENV, "1")
        .env("DISPLAY", &display)
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .expect("spawn the child");
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success(),
        "child failed: {}{stdout}",
        String::from_utf8_lossy(&output.stderr)
    );
    let line = stdout.lines().find(|l| l.starts_with("presented 3 frames"));
    assert!(line.is_some(), "{stdout}");
    eprintln!("{}", line.unwrap_or_default());
}

/// The child: a window, its surface, a renderer on it, three frames.
#[test]
#[ignore = "subprocess entry point: run by its parent test"]
fn draw_into_a_window_child() {
    if std::env::var_os(CHILD_ENV).is_none() {
        return;
    }
    use winit::platform::x11::EventLoopBuilderExtX11;
    let event_loop = winit::event_loop::EventLoop::builder()
        .with_any_thread(true)
        .build()
        .expect("an X11 event loop");
    #[allow(deprecated)] // The 0.30 way needs an `ApplicationHandler`; a test needs one window.
    let window = Arc::new(
        event_loop
            .create_window(
                winit::window::Window::default_attributes()
                    .with_inner_size(winit::dpi::PhysicalSize::new(SIZE.0, SIZE.1)),
            )
            .expect("a window"),
    );
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_with_display_handle_from_env(
        Box::new(event_loop.owned_display_handle()),
    ));
    let surface = instance.create_surface(window.clone()).expect("a surface");
    let mut renderer =
        pollster::block_on(Renderer::for_surface(&instance, surface, SIZE.0, SIZE.1))
            .expect("a renderer on the surface");
    assert_eq!(renderer.size(), SIZE);
    let camera = Camera {
        eye: DVec3::new(0.0, -4.0, 0.0),
        target: DVec3::ZERO,
        up: DVec3::Z,
        fov_y_deg: 40.0,
        width: SIZE.0,
        height: SIZE.1,
    };
    let splats: Vec<Splat> = (0..50)
        .map(|i| Splat {
            center: DVec3::new(i as f64 * 0.02 - 0.5, 0.0, 0.0),
            radius: 0.05,
            normal: None,
            color: Some([200, 100, 50]),
            node: i,
        })
        .collect();
    for _ in 0..3 {
        let out = renderer
            .render(&camera, &splats, &SplatStyle::default())
            .expect("a frame on the surface");
        assert!(out.rgba.is_empty(), "a surface frame is not read back");
        assert_eq!((out.width, out.height), SIZE);
        let cubes = renderer
            .render_geometry(&camera, &[], &[], Default::default(), [0; 3])
            .expect("a geometry frame on the surface");
        assert!(cubes.rgba.is_empty());
    }
    println!("presented 3 frames on {}", renderer.adapter_description());
}
