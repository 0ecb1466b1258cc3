//! Starting the viewer on the page, and what the page learns from it.

use std::cell::Cell;

use base64::Engine;

use farfield_client::camera_spec::CameraSpec;
use farfield_client::viewer::Viewer;
use farfield_net::SessionOptions;
use farfield_net::browser::BrowserTransport;
use farfield_viewer::flight::FlightReport;
use farfield_viewer::link::{camera_fragment, parse_fragment};
use farfield_viewer::status::Status;
use farfield_viewer::{Platform, ViewerApp};
use wasm_bindgen::JsCast;
use wasm_bindgen::prelude::*;
use web_sys::HtmlCanvasElement;

use crate::query::{self, Backend};

/// The most pixels on a side of the canvas: the largest texture every
/// WebGPU device draws (its `maxTextureDimension2D` is at least this).
const MAX_CANVAS_SIDE: u32 = 8192;

/// Starts the viewer of the scene this page's path names on the canvas
/// with id `canvas_id`. Fails (a rejected promise, which the page shows)
/// when the address is bad or the browser can draw with neither WebGPU
/// nor WebGL2.
#[wasm_bindgen]
pub async fn start(canvas_id: String) -> Result<(), JsValue> {
    // eframe's and wgpu's warnings go to the console (a second start keeps the first logger).
    let _ = eframe::WebLogger::init(log::LevelFilter::Warn);
    let window = web_sys::window().ok_or("no window")?;
    let location = window.location();
    let path = location.pathname()?;
    let scene = path
        .strip_prefix("/view/")
        .filter(|s| !s.is_empty() && !s.contains('/'))
        .ok_or_else(|| format!("{path} is not /view/<scene>"))?;
    let scene = js_sys::decode_uri_component(scene)?
        .as_string()
        .unwrap_or_default();
    let query = query::parse(&location.search()?)?;
    let mut options = query.options;
    // A damaged link opens the default view and says what was ignored.
    let hash = location.hash()?;
    match parse_fragment(&hash) {
        Ok(camera) => options.camera = camera,
        Err(e) => options.notice = Some(format!("the link's camera ({hash}) was ignored: {e}")),
    }
    let canvas = window
        .document()
        .ok_or("no document")?
        .get_element_by_id(&canvas_id)
        .ok_or_else(|| format!("no element #{canvas_id}"))?
        .dyn_into::<HtmlCanvasElement>()?;

    // The canvas's pixels are the surface's: no more on a side than a
    // WebGPU device allows at least (a larger window panicked the page).
    let most = (f64::from(MAX_CANVAS_SIDE) / window.device_pixel_ratio().max(1.0)).floor();
    let style = canvas.style();
    style.set_property("max-width", &format!("{most}px"))?;
    style.set_property("max-height", &format!("{most}px"))?;

    let session = SessionOptions {
        token: query.token,
        first_connect_grace: farfield_viewer::WAIT_FOR_SERVER,
        ..SessionOptions::default()
    };
    let viewer = Viewer::over(
        Box::new(BrowserTransport::new()),
        &location.origin()?,
        &scene,
        session,
        options.settings.cache_bytes(),
    );
    let mut web_options = eframe::WebOptions {
        dithering: false,
        ..Default::default()
    };
    if query.backend == Backend::WebGl
        && let eframe::egui_wgpu::WgpuSetup::CreateNew(create) =
            &mut web_options.wgpu_options.wgpu_setup
    {
        create.instance_descriptor.backends = wgpu::Backends::GL;
    }
    let page = WebPage {
        canvas: canvas.clone(),
        title: scene.clone(),
        drew: false,
        gl: query.backend == Backend::WebGl,
    };
    eframe::WebRunner::new()
        .start(
            canvas,
            web_options,
            Box::new(move |cc| {
                CONTEXT.with(|c| *c.borrow_mut() = Some(cc.egui_ctx.clone()));
                let app = ViewerApp::new(cc, viewer, options, Box::new(page))
                    .map_err(|e| format!("{e:#}"))?;
                Ok(Box::new(app))
            }),
        )
        .await
}

thread_local! {
    /// A script asked for the canvas's pixels ([`capture_canvas`]).
    static CAPTURE_ASKED: Cell<bool> = const { Cell::new(false) };
    /// A script pressed the screenshot button ([`screenshot`]).
    static SCREENSHOT_ASKED: Cell<bool> = const { Cell::new(false) };
    /// The viewer's egui context, to draw a frame for a script's request
    /// (at rest the page draws none by itself).
    static CONTEXT: std::cell::RefCell<Option<eframe::egui::Context>> =
        const { std::cell::RefCell::new(None) };
}

/// Has the viewer draw a frame soon.
fn wake_viewer() {
    CONTEXT.with(|c| {
        if let Some(ctx) = c.borrow().as_ref() {
            ctx.request_repaint();
        }
    });
}

/// Takes the screenshot the panel's button takes: the PNG is offered as a
/// download and left, as a data URL, in the canvas's `data-screenshot`
/// attribute (what the browser tests read).
#[wasm_bindgen]
pub fn screenshot() {
    SCREENSHOT_ASKED.with(|c| c.set(true));
    wake_viewer();
}

/// Asks for the canvas's pixels as the next frame draws them (panel and
/// all); they arrive as a PNG data URL in the canvas's `data-capture`
/// attribute. The browser tests read it, since headless Chromium's own
/// screenshot shows a WebGPU canvas blank.
#[wasm_bindgen]
pub fn capture_canvas() {
    CAPTURE_ASKED.with(|c| c.set(true));
    wake_viewer();
}

/// Bytes of the module's linear memory (resident pages and all): what
/// the memory benchmark samples, with the page's JS heap.
#[wasm_bindgen]
pub fn wasm_memory_bytes() -> f64 {
    wasm_bindgen::memory()
        .dyn_into::<js_sys::WebAssembly::Memory>()
        .map_or(0.0, |m| {
            m.buffer()
                .dyn_into::<js_sys::ArrayBuffer>()
                .map_or(0.0, |b| f64::from(b.byte_length()))
        })
}

/// The page's side of the viewer.
struct WebPage {
    canvas: HtmlCanvasElement,
    title: String,
    /// Whether the first image has been reported.
    drew: bool,
    /// Drawn with WebGL (the adapter's backend is GL).
    gl: bool,
}

impl WebPage {
    /// Reads the canvas once this frame is drawn and hands its PNG data
    /// URL to `then`. A WebGPU canvas holds its picture only until the
    /// browser presents it, so the read runs as a microtask: after the
    /// frame's callback has drawn (eframe paints after the app's `ui`) and
    /// before the page is composited. This also avoids mapping a buffer,
    /// which fails in Chromium's WebGPU here ("a valid external Instance
    /// reference no longer exists").
    fn after_this_frame(&self, then: impl FnOnce(&HtmlCanvasElement, String) + 'static) {
        let canvas = self.canvas.clone();
        wasm_bindgen_futures::spawn_local(async move {
            if let Ok(url) = canvas.to_data_url() {
                then(&canvas, url);
            }
        });
    }
}

impl Platform for WebPage {
    fn camera_rested(&mut self, camera: &CameraSpec) {
        let (Some(window), Some(fragment)) = (web_sys::window(), camera_fragment(camera)) else {
            return;
        };
        if let Ok(history) = window.history() {
            let url = format!("#{fragment}");
            let _ = history.replace_state_with_url(&JsValue::NULL, "", Some(&url));
        }
    }

    fn status(&mut self, status: &Status) {
        self.gl = status.adapter.contains(" / Gl");
        let data = self.canvas.dataset();
        if !self.drew && status.nodes_drawn > 0 {
            // Since the navigation began (HTML, wasm, GPU, stream, frame):
            // what the time-to-first-image benchmark reads.
            self.drew = true;
            if let Some(now) = web_sys::window().and_then(|w| w.performance()) {
                let _ = data.set("firstImageMs", &format!("{:.1}", now.now()));
            }
        }
        let _ = data.set("refined", if status.refined { "true" } else { "false" });
        let _ = data.set("progress", &format!("{:.4}", status.progress));
        let _ = data.set("connection", status.connection.label());
        if let Ok(json) = serde_json::to_string(status) {
            let _ = data.set("status", &json);
        }
        if CAPTURE_ASKED.with(|c| c.replace(false)) {
            self.after_this_frame(|canvas, url| {
                let _ = canvas.dataset().set("capture", &url);
            });
        }
    }

    fn flight_done(&mut self, report: &FlightReport, _ctx: &eframe::egui::Context) {
        if let Ok(json) = serde_json::to_string(report) {
            let _ = self.canvas.dataset().set("flight", &json);
        }
    }

    fn device_lost(&mut self, _message: &str) {
        if !self.gl {
            // Started again on WebGL2, at the same place (the link keeps
            // the camera); the message is the new page's notice.
            let _ = start_again_on_webgl();
        }
    }

    fn screenshot_asked(&mut self) -> bool {
        SCREENSHOT_ASKED.with(|c| c.replace(false))
    }

    fn screenshot_itself(&mut self) -> bool {
        // On WebGL the app reads the scene's texture back instead
        // (`Shot::Scene`): a click runs the app's frame in the browser's
        // event handler, before the canvas is drawn, and a read of the
        // canvas found it cleared (an all-transparent file). On WebGPU
        // reading a texture back fails in Chromium, and the canvas holds
        // its picture.
        if self.gl {
            return false;
        }
        let name = format!("{}.png", self.title);
        self.after_this_frame(move |canvas, url| {
            let _ = canvas.dataset().set("screenshot", &url);
            let _ = download(&url, &name);
        });
        true
    }

    fn screenshot(&mut self, width: u32, height: u32, rgba: Vec<u8>) {
        let Ok(png) = farfield_image::encode_png(width, height, &rgba) else {
            return;
        };
        let url = format!(
            "data:image/png;base64,{}",
            base64::engine::general_purpose::STANDARD.encode(&png)
        );
        let _ = self.canvas.dataset().set("screenshot", &url);
        let _ = download(&url, &format!("{}.png", self.title));
    }
}

/// Loads this page again with `backend=webgl` (and the other options
/// kept), saying why.
fn start_again_on_webgl() -> Result<(), JsValue> {
    let location = web_sys::window().ok_or("no window")?.location();
    let params = web_sys::UrlSearchParams::new_with_str(&location.search()?)?;
    if params.get("fallback").is_some() {
        // Started again once already: no loop of reloads.
        return Ok(());
    }
    params.set("backend", "webgl");
    params.set("fallback", query::WEBGPU_LOST);
    location.set_search(&String::from(params.to_string()))
}

/// Offers the data URL `url` to the user as a file named `name`.
fn download(url: &str, name: &str) -> Result<(), JsValue> {
    let document = web_sys::window()
        .and_then(|w| w.document())
        .ok_or("no document")?;
    let a = document
        .create_element("a")?
        .dyn_into::<web_sys::HtmlAnchorElement>()?;
    a.set_href(url);
    a.set_download(name);
    a.click();
    Ok(())
}
