//! Just enough WebDriver (W3C) to drive headless Chromium: a session, a
//! page, scripts, pointer actions, screenshots.
//!
//! chromedriver runs as a child on a free port; the browser is Debian's
//! chromium, with the flags that give it a WebGPU adapter on a machine
//! without a GPU (SwiftShader) and keep it off the network.

use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use base64::Engine;
use serde_json::{Value, json};

/// How long fingers rest after touching down and before lifting (ms).
const TOUCH_HOLD_MS: u64 = 1000;
/// How long each step of a finger's path takes (ms).
const TOUCH_STEP_MS: u64 = 250;

/// A browser session; the browser and its driver end when dropped.
pub(crate) struct Browser {
    driver: Child,
    base: String,
    agent: ureq::Agent,
    _profile: std::path::PathBuf,
}

impl Drop for Browser {
    fn drop(&mut self) {
        let _ = self.agent.delete(&self.base).call();
        let _ = self.driver.kill();
        let _ = self.driver.wait();
    }
}

/// The `chromium` on `PATH` (Debian's is /usr/bin/chromium), which the
/// tests checked is there.
fn chromium() -> String {
    std::env::var_os("PATH")
        .into_iter()
        .flat_map(|p| std::env::split_paths(&p).collect::<Vec<_>>())
        .map(|dir| dir.join("chromium"))
        .find(|p| p.is_file())
        .map_or_else(|| "chromium".to_owned(), |p| p.display().to_string())
}

/// A port nothing listens on now.
fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("a free port")
}

/// What a test's browser can draw with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Graphics {
    /// WebGPU and WebGL2, on SwiftShader.
    Full,
    /// Neither.
    None,
    /// WebGPU whose device is lost once drawing starts (SwiftShader
    /// without the Vulkan flags), and WebGL2.
    LosesWebGpu,
}

impl Browser {
    /// Starts chromedriver and a headless chromium whose viewport is
    /// `width` x `height` CSS pixels at one device pixel each, with a
    /// WebGPU adapter and WebGL2 (both on SwiftShader).
    pub(crate) fn start(width: u32, height: u32) -> Self {
        Self::with_graphics(width, height, true)
    }

    /// [`Self::start`], or, with `graphics` false, a browser that has
    /// neither WebGPU nor WebGL.
    pub(crate) fn with_graphics(width: u32, height: u32, graphics: bool) -> Self {
        let graphics = if graphics {
            Graphics::Full
        } else {
            Graphics::None
        };
        Self::with(width, height, graphics)
    }

    /// [`Self::start`] with the graphics `graphics`.
    pub(crate) fn with(width: u32, height: u32, graphics: Graphics) -> Self {
        let port = free_port();
        let (quiet, on) = farfield_render::DEVICE_SELECT_OFF;
        let driver = Command::new("chromedriver")
            .arg(format!("--port={port}"))
            .env(quiet, on)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("start chromedriver");
        let agent: ureq::Agent = ureq::Agent::config_builder()
            .http_status_as_error(false)
            .timeout_global(Some(Duration::from_secs(120)))
            .build()
            .into();
        let root = format!("http://127.0.0.1:{port}");
        let started = Instant::now();
        while agent.get(format!("{root}/status")).call().is_err() {
            assert!(
                started.elapsed() < Duration::from_secs(20),
                "chromedriver did not start"
            );
            std::thread::sleep(Duration::from_millis(100));
        }
        let profile = std::env::temp_dir().join(format!("farfield-chromium-{port}"));
        let gpu = [
            "--enable-unsafe-webgpu",
            "--enable-unsafe-swiftshader",
            // Without these three a WebGPU canvas is never composited here:
            // the page draws, but screenshots and the canvas's pixels stay blank.
            "--use-angle=swiftshader",
            "--enable-features=Vulkan",
            "--use-vulkan=swiftshader",
        ];
        let none = ["--disable-3d-apis", "--disable-features=WebGPU"];
        let graphics_args = match graphics {
            Graphics::Full => &gpu[..],
            Graphics::None => &none[..],
            Graphics::LosesWebGpu => &gpu[..2],
        };
        let args = [
            "--headless=new".to_owned(),
            "--no-sandbox".to_owned(),
            "--disable-quic".to_owned(),
            "--no-first-run".to_owned(),
            "--disable-background-networking".to_owned(),
            "--disable-component-update".to_owned(),
            "--disable-sync".to_owned(),
            "--force-device-scale-factor=1".to_owned(),
            format!("--user-data-dir={}", profile.display()),
        ];
        let args: Vec<String> = args
            .into_iter()
            .chain(graphics_args.iter().map(|a| (*a).to_owned()))
            .collect();
        let caps = json!({
            "capabilities": { "alwaysMatch": {
                "browserName": "chrome",
                "goog:chromeOptions": { "binary": chromium(), "args": args },
            }}
        });
        let mut response = agent
            .post(format!("{root}/session"))
            .send_json(&caps)
            .expect("new session");
        let body: Value = response.body_mut().read_json().expect("session reply");
        let id = body["value"]["sessionId"]
            .as_str()
            .unwrap_or_else(|| panic!("no session: {body}"))
            .to_owned();
        let browser = Self {
            driver,
            base: format!("{root}/session/{id}"),
            agent,
            _profile: profile,
        };
        // The viewport exactly, whatever the window around it (headless
        // windows have a minimum width).
        browser.post(
            "goog/cdp/execute",
            json!({ "cmd": "Emulation.setDeviceMetricsOverride", "params": {
                "width": width, "height": height, "deviceScaleFactor": 1, "mobile": false,
            }}),
        );
        browser
    }

    fn post(&self, path: &str, body: Value) -> Value {
        self.try_post(path, body)
            .unwrap_or_else(|error| panic!("webdriver {path}: {error}"))
    }

    /// The reply's value, or WebDriver's error object.
    fn try_post(&self, path: &str, body: Value) -> Result<Value, Value> {
        let mut r = self
            .agent
            .post(format!("{}/{path}", self.base))
            .send_json(&body)
            .unwrap_or_else(|e| panic!("webdriver {path}: {e}"));
        let v: Value = r.body_mut().read_json().expect("webdriver reply");
        match v["value"].get("error") {
            Some(_) => Err(v["value"].clone()),
            None => Ok(v["value"].clone()),
        }
    }

    pub(crate) fn goto(&self, url: &str) {
        self.post("url", json!({ "url": url }));
    }

    /// Runs `script` (a function body) in the page; its `return` value.
    pub(crate) fn eval(&self, script: &str) -> Value {
        self.post("execute/sync", json!({ "script": script, "args": [] }))
    }

    /// Waits until `script` returns `true`, up to `wait`; the last value
    /// of `report` (a script) is in the failure message.
    pub(crate) fn wait_for(&self, what: &str, script: &str, report: &str, wait: Duration) {
        let started = Instant::now();
        loop {
            let args = json!({ "script": script, "args": [] });
            match self.try_post("execute/sync", args) {
                Ok(Value::Bool(true)) => return,
                Ok(_) => {}
                // A page busy drawing a large frame on a software GPU can
                // hold its main thread past the script timeout: not yet,
                // within `wait`.
                Err(error) if error["error"] == "script timeout" => {}
                Err(error) => panic!("{what}: {error}"),
            }
            if started.elapsed() > wait {
                panic!("{what}: not after {wait:?} ({})", self.eval(report));
            }
            std::thread::sleep(Duration::from_millis(200));
        }
    }

    /// A drag with the left button from (`x`, `y`) by (`dx`, `dy`) CSS
    /// pixels, in `steps` moves.
    pub(crate) fn drag(&self, (x, y): (i64, i64), (dx, dy): (i64, i64), steps: i64) {
        let mut actions = vec![
            json!({"type": "pointerMove", "duration": 0, "x": x, "y": y, "origin": "viewport"}),
            json!({"type": "pointerDown", "button": 0}),
        ];
        for i in 1..=steps {
            actions.push(json!({
                "type": "pointerMove", "duration": 30, "origin": "viewport",
                "x": x + dx * i / steps, "y": y + dy * i / steps,
            }));
        }
        actions.push(json!({"type": "pointerUp", "button": 0}));
        self.post(
            "actions",
            json!({ "actions": [{
                "type": "pointer", "id": "mouse",
                "parameters": { "pointerType": "mouse" },
                "actions": actions,
            }]}),
        );
    }

    /// A left click at (`x`, `y`) CSS pixels (which also gives the page focus).
    pub(crate) fn click(&self, x: i64, y: i64) {
        let actions = json!([
            {"type": "pointerMove", "duration": 0, "x": x, "y": y, "origin": "viewport"},
            {"type": "pointerDown", "button": 0},
            {"type": "pointerUp", "button": 0},
        ]);
        self.post(
            "actions",
            json!({ "actions": [{"type": "pointer", "id": "mouse",
                    "parameters": {"pointerType": "mouse"}, "actions": actions}]}),
        );
    }

    /// Holds the key `key` (a character) down for `ms` milliseconds.
    pub(crate) fn hold_key(&self, key: &str, ms: u64) {
        let actions = json!([
            {"type": "keyDown", "value": key},
            {"type": "pause", "duration": ms},
            {"type": "keyUp", "value": key},
        ]);
        self.post(
            "actions",
            json!({ "actions": [{"type": "key", "id": "keyboard", "actions": actions}]}),
        );
    }

    /// Fingers on a touch screen, each a path of CSS pixel points, moving
    /// together, lifted at the end.
    ///
    /// The fingers rest longer than egui's click time (0.8 s) before they
    /// move, as a hesitant user's do and as every gesture did on CI, where
    /// frames took 370 ms and each touch event waited for one: held that
    /// long, a touch became a long press and its drag moved nothing (the
    /// viewer now keeps a press a click until it moves). Each stage also
    /// outlasts a slow frame, so the viewer sees the fingers down, then
    /// moved.
    pub(crate) fn touch(&self, fingers: &[&[(i64, i64)]]) {
        let sources: Vec<Value> = fingers
            .iter()
            .enumerate()
            .map(|(i, path)| {
                let mut actions = vec![
                    json!({"type": "pointerMove", "duration": 0, "origin": "viewport",
                           "x": path[0].0, "y": path[0].1}),
                    json!({"type": "pointerDown", "button": 0}),
                    json!({"type": "pause", "duration": TOUCH_HOLD_MS}),
                ];
                for &(x, y) in &path[1..] {
                    actions.push(json!({"type": "pointerMove", "duration": TOUCH_STEP_MS,
                                        "origin": "viewport", "x": x, "y": y}));
                }
                actions.push(json!({"type": "pause", "duration": TOUCH_HOLD_MS}));
                actions.push(json!({"type": "pointerUp", "button": 0}));
                json!({"type": "pointer", "id": format!("finger{i}"),
                       "parameters": {"pointerType": "touch"}, "actions": actions})
            })
            .collect();
        self.post("actions", json!({ "actions": sources }));
    }

    /// The viewport as the user sees it: (width, height, RGBA).
    pub(crate) fn screenshot(&self) -> (u32, u32, Vec<u8>) {
        let mut r = self
            .agent
            .get(format!("{}/screenshot", self.base))
            .call()
            .expect("screenshot");
        let v: Value = r.body_mut().read_json().expect("screenshot reply");
        decode_png(v["value"].as_str().expect("base64 PNG"))
    }

    /// The PNG data URL in the viewer canvas's `data-NAME` attribute:
    /// (width, height, RGBA).
    pub(crate) fn data_png(&self, name: &str) -> (u32, u32, Vec<u8>) {
        let url = self.eval(&format!(
            "return document.getElementById('farfield').dataset.{name}"
        ));
        let url = url.as_str().unwrap_or_default();
        decode_png(url.split_once(',').map_or(url, |(_, b64)| b64))
    }

    /// The viewer's canvas as it drew its last frame (`farfield.capture_canvas()`,
    /// a PNG data URL): (width, height, RGBA).
    pub(crate) fn canvas_pixels(&self) -> (u32, u32, Vec<u8>) {
        self.eval(
            "const c = document.getElementById('farfield'); delete c.dataset.capture; \
             window.farfield.capture_canvas(); return null",
        );
        let captured = "return !!document.getElementById('farfield').dataset.capture";
        self.wait_for(
            "the canvas's pixels",
            captured,
            "return null",
            Duration::from_secs(30),
        );
        let url = self.eval("return document.getElementById('farfield').dataset.capture");
        let url = url.as_str().unwrap_or_default();
        decode_png(url.split_once(',').map_or(url, |(_, b64)| b64))
    }
}

/// A base64 PNG as (width, height, RGBA).
fn decode_png(b64: &str) -> (u32, u32, Vec<u8>) {
    let png = base64::engine::general_purpose::STANDARD
        .decode(b64)
        .expect("base64");
    let path = std::env::temp_dir().join(format!(
        "farfield-shot-{}-{:?}.png",
        std::process::id(),
        std::thread::current().id()
    ));
    std::fs::write(&path, png).unwrap();
    let image = farfield_image::read_png(&path).unwrap();
    let _ = std::fs::remove_file(&path);
    image
}
