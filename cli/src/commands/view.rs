//! `farfield view`: the viewer in a native window (winit, through eframe),
//! the same app as the browser's.
//!
//! `--screenshot-when-refined PNG` saves the window each time the resting
//! view becomes refined and prints `refined camera=<camera> png=<PNG>`, so
//! a script (the window test) can move the camera with real input and
//! check what the window shows. `--flight SECONDS` flies the benchmark's
//! path ([`farfield_viewer::flight`]), prints `flight <JSON report>` and
//! closes the window.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use anyhow::Context;
use farfield_client::camera_spec::CameraSpec;
use farfield_client::render_job::Source;
use farfield_client::viewer::Viewer;
use farfield_net::SessionOptions;
use farfield_viewer::flight::FlightReport;
use farfield_viewer::link::camera_fragment;
use farfield_viewer::panel::Settings;
use farfield_viewer::status::Status;
use farfield_viewer::{AppOptions, Platform, Shot, ViewerApp};

/// What `farfield view` was asked.
#[derive(Debug)]
pub struct ViewJob {
    pub source: Source,
    pub camera: Option<CameraSpec>,
    pub size: (u32, u32),
    pub settings: Settings,
    pub show_panel: bool,
    pub token: Option<String>,
    pub ca_cert: Option<PathBuf>,
    pub screenshot_when_refined: Option<PathBuf>,
    /// Fly the benchmark's path this many seconds, print its report, close.
    pub flight_seconds: Option<f64>,
    /// A demo session to join at start.
    pub demo: Option<farfield_client::render_job::DemoRole>,
}

pub fn run(job: ViewJob) -> anyhow::Result<()> {
    let what = match &job.source {
        Source::File(path) => path.display().to_string(),
        Source::Server { url, scene } => format!("{scene} on {url}"),
    };
    let title = format!("farfield · {what}");
    let viewer = match &job.source {
        Source::File(path) => Viewer::open_file(path)?,
        Source::Server { url, scene } => {
            let session = SessionOptions {
                token: job.token.clone(),
                ca_cert: job.ca_cert.clone(),
                first_connect_grace: farfield_viewer::WAIT_FOR_SERVER,
                ..SessionOptions::default()
            };
            Viewer::open_remote(url, scene, session, job.settings.cache_bytes())?
        }
    };
    let (w, h) = job.size;
    let native = eframe::NativeOptions {
        viewport: eframe::egui::ViewportBuilder::default()
            .with_title(&title)
            .with_inner_size([w as f32, h as f32])
            // The surface is a texture: no larger than a device draws
            // (8192 is wgpu's default limit; past it the window went black).
            .with_max_inner_size([8192.0, 8192.0]),
        dithering: false,
        // Tests run the viewer on a thread of their own.
        #[cfg(target_os = "linux")]
        event_loop_builder: Some(Box::new(|builder| {
            use winit::platform::x11::EventLoopBuilderExtX11;
            builder.with_any_thread(true);
        })),
        ..Default::default()
    };
    let options = AppOptions {
        camera: job.camera,
        settings: job.settings,
        show_panel: job.show_panel,
        flight_seconds: job.flight_seconds,
        demo: job.demo,
        notice: None,
    };
    let failed: Arc<Mutex<Option<String>>> = Arc::default();
    let window = Window {
        save_to: job.screenshot_when_refined,
        was_refined: false,
        failed: failed.clone(),
    };
    eframe::run_native(
        &title,
        native,
        Box::new(move |cc| {
            let app = ViewerApp::new(cc, viewer, options, Box::new(window))?;
            Ok(Box::new(app))
        }),
    )
    .map_err(|e| anyhow::anyhow!("{e}"))
    .context("opening the viewer's window")?;
    match failed.lock().ok().and_then(|mut f| f.take()) {
        Some(message) => {
            Err(anyhow::anyhow!("{message}")).context(format!("{what}: no scene to show"))
        }
        None => Ok(()),
    }
}

/// The window's side of the viewer.
struct Window {
    save_to: Option<PathBuf>,
    was_refined: bool,
    /// Why the session ended before the scene came; the command then fails.
    failed: Arc<Mutex<Option<String>>>,
}

impl Platform for Window {
    fn session_failed(&mut self, message: &str, ctx: &eframe::egui::Context) {
        if let Ok(mut failed) = self.failed.lock() {
            *failed = Some(message.to_owned());
        }
        ctx.send_viewport_cmd(eframe::egui::ViewportCommand::Close);
    }

    fn wants_screenshot(&mut self, status: &Status) -> Shot {
        let newly = status.refined && !self.was_refined;
        self.was_refined = status.refined;
        if newly && self.save_to.is_some() {
            // What the window shows, as presented: the test's evidence.
            Shot::Window
        } else {
            Shot::None
        }
    }

    fn screenshot(&mut self, width: u32, height: u32, rgba: Vec<u8>) {
        let path = self
            .save_to
            .clone()
            .unwrap_or_else(|| PathBuf::from("farfield-screenshot.png"));
        match farfield_image::write_png(&path, width, height, &rgba) {
            Ok(()) => println!("saved png={}", path.display()),
            Err(e) => eprintln!("farfield: could not save the screenshot: {e}"),
        }
    }

    fn flight_done(&mut self, report: &FlightReport, ctx: &eframe::egui::Context) {
        println!(
            "flight {}",
            serde_json::to_string(report).unwrap_or_default()
        );
        ctx.send_viewport_cmd(eframe::egui::ViewportCommand::Close);
    }

    fn status(&mut self, status: &Status) {
        if status.refined && !self.was_refined {
            let camera = status.camera.as_ref().and_then(camera_fragment);
            println!("refined camera={}", camera.unwrap_or_default());
        }
    }
}
